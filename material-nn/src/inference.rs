//! Using a trained run: load its model, encode materials (full tables or sparse sample sets)
//! into latent codes, and decode latent codes.

use crate::checkpoint::Checkpoint;
use crate::config::TrainConfig;
use crate::dataset::{MaterialTable, SampleSet, Sampler};
use crate::error::{Error, Result};
use crate::model::{to_vec, HyperBrdf};
use crate::training::{load_model, read_json, RunDir, RunInfo};
use burn::tensor::{Device, Tensor, TensorData};
use rand::SeedableRng;
use std::path::Path;
use std::sync::Arc;

/// A trained run, ready for inference on the CPU (no autodiff).
#[derive(Debug)]
pub struct TrainedRun {
    /// The run's configuration.
    pub config: TrainConfig,
    /// The model of the best epoch (or of the latest checkpoint when there is no best yet).
    pub model: HyperBrdf,
    /// Sampler with the run's f_ref and mapping.
    pub sampler: Sampler,
    /// What the run was trained on.
    pub info: RunInfo,
    /// The run's split of the materials.
    pub split: crate::dataset::Split,
    /// Device of the model.
    pub device: Device,
}

impl TrainedRun {
    /// Loads `best.bin` (or `checkpoint.bin`), `reference.binary`, `run.json` and `split.json`.
    pub fn load(run_dir: &Path) -> Result<Self> {
        let run = RunDir(run_dir.to_path_buf());
        let path = if run.best().exists() {
            run.best()
        } else {
            run.checkpoint()
        };
        if !path.exists() {
            return Err(Error::invalid_file(
                run_dir,
                "no checkpoint in this run directory (train first)",
            ));
        }
        let ckpt = Checkpoint::read(&path)?;
        let device = Device::flex();
        let model = load_model(&ckpt.config, &ckpt.model, &device, &path)?;
        let reference = MaterialTable::read(&run.reference())?;
        let info: RunInfo = read_json(&run.info())?;
        let split: crate::dataset::Split = read_json(&run.split())?;
        Ok(TrainedRun {
            sampler: Sampler {
                reference: Arc::new(reference),
                mapping: ckpt.config.mapping,
                epsilon: ckpt.config.epsilon,
            },
            config: ckpt.config,
            model,
            info,
            split,
            device,
        })
    }

    /// z (latent_dim values) of a sample set: the set encoder's mean over all its samples.
    pub fn encode_samples(&self, set: &SampleSet) -> Result<Vec<f32>> {
        if set.is_empty() {
            return Err(Error::Invalid(
                "cannot encode an empty sample set".to_string(),
            ));
        }
        let n = set.len();
        let x = Tensor::from_data(
            TensorData::new(set.encoder_input(n), [1, n, 9]),
            &self.device,
        );
        Ok(to_vec(self.model.encode(x)))
    }

    /// z of a table from `samples` uniform samples drawn with `seed`.
    pub fn encode_table(
        &self,
        table: &MaterialTable,
        samples: usize,
        seed: u64,
    ) -> Result<Vec<f32>> {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let set = self.sampler.draw(table, samples, &mut rng)?;
        self.encode_samples(&set)
    }

    /// The mapped predictions y [n, 3] of latent `z` at network inputs [n, 6].
    pub fn predict(&self, z: &[f32], inputs: &[f32]) -> Vec<f32> {
        let n = inputs.len() / 6;
        let zt = Tensor::from_data(TensorData::new(z.to_vec(), [1, z.len()]), &self.device);
        let params = self.model.decode(zt);
        let x = Tensor::from_data(TensorData::new(inputs.to_vec(), [1, n, 6]), &self.device);
        to_vec(self.model.target_forward(&params, x))
    }
}

/// Reads a sparse sample set from CSV: one sample per line `theta_h,theta_d,phi_d,r,g,b`
/// (radians; f_r in 1/sr); blank lines and lines starting with `#` are skipped, and a first
/// line that does not parse as numbers is taken as a header. Samples where f_ref is
/// unmeasured are dropped.
pub fn read_sample_csv(path: &Path, sampler: &Sampler) -> Result<SampleSet> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut set = SampleSet::default();
    for (line_no, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: std::result::Result<Vec<f32>, _> =
            line.split(',').map(|f| f.trim().parse::<f32>()).collect();
        let v = match fields {
            Ok(v) if v.len() == 6 => v,
            Err(_) if line_no == 0 => continue,
            _ => {
                return Err(Error::invalid_file(
                    path,
                    format!("line {}: expected theta_h,theta_d,phi_d,r,g,b", line_no + 1),
                ))
            }
        };
        if v.iter().any(|x| !x.is_finite()) || v[3..].iter().any(|&x| x < 0.0) {
            return Err(Error::invalid_file(
                path,
                format!("line {}: non-finite or negative value", line_no + 1),
            ));
        }
        if let Some((x, y, c)) = sampler.sample_at(v[0], v[1], v[2], [v[3], v[4], v[5]]) {
            set.push(x, y, c);
        }
    }
    if set.is_empty() {
        return Err(Error::invalid_file(path, "no usable samples"));
    }
    Ok(set)
}
