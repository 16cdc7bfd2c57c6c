//! `material-nn nbrdf-fit`: the per-material NBRDF baseline (Sztrajman et al. 2021) trained in
//! burn, one 6 → 21 → 21 → 3 MLP per MERL-layout table, written as the six `.npy` tensors the
//! renderer loads ([`renderer::neural::nbrdf::NbrdfNetwork::load`], `render --bind M=nbrdf:OUT/NAME`).
//!
//! Per material:
//! - **Samples.** Every step draws `samples_per_step` fresh points θh, θd uniform in [0, π/2],
//!   φd uniform in [0, 2π), kept only inside the rendered domain (wi and wo above the
//!   horizon) and turned into the renderer's own network input, φd folded into [0, π)
//!   ([`renderer::brdf_coords::rendered_point`], reciprocity), with trilinear look-ups in
//!   the table ([`MaterialTable::lookup`], unmeasured corners left out; points with no
//!   measured corner are dropped and redrawn), as [`crate::dataset`] samples.
//! - **Target** y = ln(1 + f) per channel (f in 1/sr, clamped ≥ 0), the inverse of the
//!   renderer's f = max(eᵞ − 1, 0).
//! - **Loss**: the cos θi-weighted mean squared error, mean over points and RGB of
//!   cos θi · (y' − y)², cos θi = wi · n of the drawn configuration.
//!   The original NBRDF uses mean |ln(1 + f' cos θi) − ln(1 + f cos θi)|; we keep the
//!   network's output in the space the renderer exponentiates and weight the error by how
//!   much the point contributes to a rendering (∝ cos θi). Points below either horizon never
//!   render and are not drawn; a linear rather than squared cosine keeps grazing
//!   light (where Fresnel peaks live) in play.
//! - **Optimiser**: Adam (β 0.9/0.999, ε 1e-8) for `epochs × steps_per_epoch` steps (an
//!   "epoch" is a fixed number of steps, each on fresh samples; there is no finite data set to
//!   pass over), the learning rate decayed along a half cosine to a fraction of its start.
//!   Initial weights U(−k, k), k = 1/√d_in (PyTorch's `nn.Linear`), from the material's seed.
//! - **Seed** of a material = `seed` mixed with a hash of its name, so a material's network
//!   does not depend on which other materials are fitted, in which order, or on resuming.
//! - **Reported loss**: the same loss on a fixed set of `validation_samples` points (own seed),
//!   computed from the written weights with the renderer's network, before and after training.
//!
//! Output directory: `NAME_fc1.npy`, `_b1`, `_fc2`, `_b2`, `_fc3`, `_b3` (little-endian
//! float32, C order, shapes 6×21, 21, 21×21, 21, 21×3, 3: row vector times matrix), each
//! written atomically with `_fc1.npy` last, as soon as the material is done; a material whose
//! six files all exist is skipped, so an interrupted run resumes. `fit.json` records each
//! fitted material's settings, losses and time ([`FitSummary`]).

use renderer::support::write_bytes_atomically;
use crate::dataset::{draw_points, MaterialTable, SampleSet};
use crate::tables::{list_tables, material_name};
use crate::error::{Error, Result};
use crate::model::Nbrdf;
use crate::backend::{optimizer, training_device};
use burn::module::Module;
use burn::optim::GradientsParams;
use burn::tensor::{Device, Tensor, TensorData};
use npyz::WriterBuilder;
use rand::{Rng, SeedableRng};
use renderer::neural::nbrdf::{tensor_paths, NbrdfNetwork, HIDDEN, INPUTS, OUTPUTS};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Name of the summary file in the output directory.
pub const SUMMARY_FILE: &str = "fit.json";

/// Settings of a fit (the same for every material).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitConfig {
    /// Epochs per material.
    pub epochs: usize,
    /// Adam steps per epoch.
    pub steps_per_epoch: usize,
    /// Fresh uniform samples per step.
    pub samples_per_step: usize,
    /// Adam learning rate of the first step.
    pub learning_rate: f64,
    /// Learning rate of the last step as a fraction of `learning_rate`; in between it follows
    /// a half cosine (1: constant).
    pub final_learning_rate_fraction: f64,
    /// Base seed (mixed with each material's name).
    pub seed: u64,
    /// Points of the fixed set on which the reported losses are computed.
    pub validation_samples: usize,
}

impl Default for FitConfig {
    /// 200 epochs × 100 steps × 512 samples (NBRDF's batch size; 10.2 M points in all),
    /// learning rate 5e-3 decayed to 2.5e-4, seed 1; 16,384 validation points. At equal cost,
    /// many small steps fit better than few large ones (measured in docs/training.md).
    fn default() -> Self {
        FitConfig {
            epochs: 200,
            steps_per_epoch: 100,
            samples_per_step: 512,
            learning_rate: 5e-3,
            final_learning_rate_fraction: 0.05,
            seed: 1,
            validation_samples: 16_384,
        }
    }
}

impl FitConfig {
    /// Checks the settings; the reason names the offending field.
    pub fn check(&self) -> Result<()> {
        let bad = |field: &str, reason: &str| {
            Err(Error::Invalid(format!(
                "invalid value for {field}: {reason}"
            )))
        };
        if self.epochs == 0 {
            return bad("--epochs", "must be at least 1");
        }
        if self.steps_per_epoch == 0 {
            return bad("--steps-per-epoch", "must be at least 1");
        }
        if self.samples_per_step == 0 {
            return bad("--samples-per-step", "must be at least 1");
        }
        if self.validation_samples == 0 {
            return bad("validation_samples", "must be at least 1");
        }
        if !(self.learning_rate.is_finite() && self.learning_rate > 0.0) {
            return bad("--learning-rate", "must be a positive number");
        }
        if !(self.final_learning_rate_fraction > 0.0 && self.final_learning_rate_fraction <= 1.0) {
            return bad("final_learning_rate_fraction", "must lie in (0, 1]");
        }
        Ok(())
    }

    /// Adam steps per material.
    pub fn total_steps(&self) -> u64 {
        (self.epochs * self.steps_per_epoch) as u64
    }

    /// The learning rate of step `step` (1-based) of `total_steps()`: `learning_rate` decayed
    /// along a half cosine to `learning_rate × final_learning_rate_fraction`.
    pub fn learning_rate_at(&self, step: u64) -> f64 {
        let total = self.total_steps();
        let t = if total > 1 {
            (step.saturating_sub(1)) as f64 / (total - 1) as f64
        } else {
            0.0
        };
        crate::config::half_cosine_decay(self.learning_rate, self.final_learning_rate_fraction, t)
    }
}

/// What one fitted material's record in `fit.json` holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialFit {
    /// The settings it was fitted with.
    pub config: FitConfig,
    /// The seed of its weights and samples (from `config.seed` and the name).
    pub material_seed: u64,
    /// Loss (cos θi-weighted MSE of y = ln(1 + f)) of the initial weights, validation set.
    pub initial_loss: f64,
    /// Loss of the written weights on the same set.
    pub final_loss: f64,
    /// Mean training loss of the first and of the last epoch.
    pub first_epoch_loss: f64,
    /// See `first_epoch_loss`.
    pub last_epoch_loss: f64,
    /// Wall time of the fit, seconds.
    pub seconds: f64,
}

/// `fit.json`: the record of every material fitted into the directory, by name.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FitSummary {
    /// Records by material name.
    pub materials: BTreeMap<String, MaterialFit>,
}

impl FitSummary {
    /// Reads `fit.json` (an empty summary when the file does not exist).
    pub fn read(path: &Path) -> Result<Self> {
        match std::fs::read_to_string(path) {
            Ok(text) => serde_json::from_str(&text)
                .map_err(|e| Error::invalid_file(path, format!("not a fit summary: {e}"))),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(FitSummary::default()),
            Err(e) => Err(Error::io(path, e)),
        }
    }

    /// Writes it atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self)
            .map_err(|e| Error::invalid_file(path, format!("cannot serialise: {e}")))?;
        Ok(write_bytes_atomically(path, text.as_bytes())?)
    }
}

/// The weights of one network as row-major f32 tensors of the renderer's shapes.
#[derive(Clone, Debug, PartialEq)]
pub struct NbrdfTensors {
    /// fc1 6×21, b1 21, fc2 21×21, b2 21, fc3 21×3, b3 3 (row-major), in file order.
    pub tensors: [Vec<f32>; 6],
}

/// Shapes of the six tensors, in file order (`fc1`, `b1`, `fc2`, `b2`, `fc3`, `b3`).
pub const TENSOR_SHAPES: [&[u64]; 6] = [
    &[INPUTS as u64, HIDDEN as u64],
    &[HIDDEN as u64],
    &[HIDDEN as u64, HIDDEN as u64],
    &[HIDDEN as u64],
    &[HIDDEN as u64, OUTPUTS as u64],
    &[OUTPUTS as u64],
];

impl NbrdfTensors {
    /// The weights of a burn model.
    pub fn from_model(model: &Nbrdf) -> Self {
        let dense = model.net.to_dense();
        let tensors = [
            dense[0].weight.clone(),
            dense[0].bias.clone(),
            dense[1].weight.clone(),
            dense[1].bias.clone(),
            dense[2].weight.clone(),
            dense[2].bias.clone(),
        ];
        NbrdfTensors { tensors }
    }

    /// The renderer's network of these weights.
    pub fn network(&self) -> NbrdfNetwork {
        let t = &self.tensors;
        NbrdfNetwork::from_tensors(&t[0], &t[1], &t[2], &t[3], &t[4], &t[5])
    }

    /// Writes `<prefix>_fc1.npy` ... `<prefix>_b3.npy`, each atomically, `_fc1.npy` last (the
    /// file by which directories of networks are listed).
    pub fn write(&self, prefix: &Path) -> Result<()> {
        let paths = tensor_paths(prefix);
        for i in (1..6).chain([0]) {
            let bytes = npy_bytes(TENSOR_SHAPES[i], &self.tensors[i])
                .map_err(|e| Error::io(&paths[i], e))?;
            write_bytes_atomically(&paths[i], &bytes)?;
        }
        Ok(())
    }
}

/// A little-endian float32 C-order `.npy` file of `values` with `shape`.
fn npy_bytes(shape: &[u64], values: &[f32]) -> std::io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    let mut w = npyz::WriteOptions::<f32>::new()
        .default_dtype()
        .shape(shape)
        .writer(&mut bytes)
        .begin_nd()?;
    w.extend(values.iter().copied())?;
    w.finish()?;
    Ok(bytes)
}

/// Whether all six tensor files of `prefix` exist (a finished material).
pub fn network_present(prefix: &Path) -> bool {
    tensor_paths(prefix).iter().all(|p| p.is_file())
}

/// A stable seed for material `name` under base seed `seed` (FNV-1a of the name, mixed).
pub fn material_seed(seed: u64, name: &str) -> u64 {
    renderer::support::fnv1a64(name.as_bytes()) ^ seed.wrapping_mul(0x9e37_79b9_7f4a_7c15)
}

/// `n` uniform points of `table` in the rendered domain (see the module documentation) as a
/// [`SampleSet`] whose values are the targets y = ln(1 + f); inputs as the renderer evaluates
/// them (φd folded into [0, π)). Errors when the table is (almost) entirely unmeasured.
pub fn draw_samples(table: &MaterialTable, n: usize, rng: &mut impl Rng) -> Result<SampleSet> {
    draw_points(table, n, 0.0, rng, |point, f| {
        Some((point.input, f.map(|v| v.max(0.0).ln_1p()), point.cos_i))
    })
}

/// The loss (mean over points and RGB of cos θi · (y' − y)²) of a network on a point set.
pub fn plain_loss(network: &NbrdfNetwork, samples: &SampleSet) -> f64 {
    let mut sum = 0f64;
    for i in 0..samples.len() {
        let mut x = [0f32; INPUTS];
        x.copy_from_slice(&samples.inputs[6 * i..6 * i + 6]);
        let y = network.forward(x);
        let c = samples.cos_i[i] as f64;
        for (ch, &v) in y.iter().enumerate() {
            sum += c * (v as f64 - samples.values[3 * i + ch] as f64).powi(2);
        }
    }
    sum / (3 * samples.len()).max(1) as f64
}

/// Per-step progress of [`fit_material`]: (steps done, loss of the step).
pub type StepCallback<'a> = dyn FnMut(u64, f64) + 'a;

/// Fits one material; `None` when `stop` was set before it finished.
pub fn fit_material(
    table: &MaterialTable,
    config: &FitConfig,
    stop: &AtomicBool,
    on_step: &mut StepCallback<'_>,
) -> Result<Option<(NbrdfTensors, MaterialFit)>> {
    config.check()?;
    let start = Instant::now();
    let seed = material_seed(config.seed, &table.name);
    let device: Device = training_device()?;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut model = Nbrdf::init(&mut rng, &device);
    let mut validation_rng = rand_pcg::Pcg64::seed_from_u64(seed ^ 0x7a11_da7e);
    let validation = draw_samples(table, config.validation_samples, &mut validation_rng)?;
    let initial_loss = plain_loss(
        &NbrdfTensors::from_model(&model.valid()).network(),
        &validation,
    );
    let mut optim = optimizer();
    let total = config.total_steps();
    let (mut first_epoch, mut epoch_sum) = (f64::NAN, 0f64);
    for step in 1..=total {
        if stop.load(Ordering::SeqCst) {
            return Ok(None);
        }
        let s = draw_samples(table, config.samples_per_step, &mut rng)?;
        let n = s.len();
        let x = Tensor::<2>::from_data(TensorData::new(s.inputs, [n, 6]), &device);
        let y = Tensor::<2>::from_data(TensorData::new(s.values, [n, 3]), &device);
        let c = Tensor::<2>::from_data(TensorData::new(s.cos_i, [n, 1]), &device);
        let loss = ((model.forward(x) - y).square() * c).mean();
        let grads = GradientsParams::from_grads(loss.backward(), &model);
        model = optim.step(config.learning_rate_at(step), model, grads);
        let value = loss.into_scalar::<f32>() as f64;
        if !value.is_finite() {
            return Err(Error::Invalid(format!(
                "material '{}': the loss became non-finite at step {step}; lower the learning rate",
                table.name
            )));
        }
        epoch_sum += value;
        if step % config.steps_per_epoch as u64 == 0 {
            if first_epoch.is_nan() {
                first_epoch = epoch_sum / config.steps_per_epoch as f64;
            }
            if step < total {
                epoch_sum = 0.0;
            }
        }
        on_step(step, value);
    }
    let tensors = NbrdfTensors::from_model(&model.valid());
    let final_loss = plain_loss(&tensors.network(), &validation);
    let fit = MaterialFit {
        config: config.clone(),
        material_seed: seed,
        initial_loss,
        final_loss,
        first_epoch_loss: first_epoch,
        last_epoch_loss: epoch_sum / config.steps_per_epoch as f64,
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok(Some((tensors, fit)))
}

/// The tables to fit: every `NAME.binary` of `data_dir`, or the `selected` names (each must
/// have a table). Returns (name, path) sorted by name for the whole directory, in the given
/// order for a selection.
pub fn select_tables(
    data_dir: &Path,
    selected: Option<&[String]>,
) -> Result<Vec<(String, PathBuf)>> {
    let paths = list_tables(data_dir, None)?;
    let available = paths
        .iter()
        .map(|p| Ok((material_name(p)?, p.clone())))
        .collect::<Result<Vec<_>>>()?;
    let Some(selected) = selected else {
        return Ok(available);
    };
    selected
        .iter()
        .map(|name| {
            available
                .iter()
                .find(|(n, _)| n == name)
                .cloned()
                .ok_or_else(|| {
                    renderer::Error::UnknownName {
                        what: "material table",
                        name: crate::tables::table_path(data_dir, name)
                            .display()
                            .to_string(),
                        available: available.iter().map(|(n, _)| n.clone()).collect(),
                    }
                    .into()
                })
        })
        .collect()
}

/// What `fit_all` did with one material.
#[derive(Clone, Debug, PartialEq)]
pub enum FitOutcome {
    /// Fitted now and written.
    Fitted(MaterialFit),
    /// Its six files existed already; left as they were.
    Skipped,
}

/// Progress of [`fit_all`].
#[derive(Debug)]
pub enum FitEvent<'a> {
    /// A material starts (or is skipped): its name.
    Material(&'a str),
    /// A step of the current material: (steps done, loss of the step).
    Step(u64, f64),
    /// A material is done (written or skipped).
    Done(&'a str, &'a FitOutcome),
}

/// How [`fit_all`] ended.
#[derive(Clone, Debug, PartialEq)]
pub struct FitReport {
    /// Outcomes of the materials finished, in order.
    pub outcomes: Vec<(String, FitOutcome)>,
    /// Whether `stop` ended it before every material was done.
    pub interrupted: bool,
}

/// Fits the `tables` (name, path) into `out_dir` one after another, skipping materials whose
/// files exist, writing each material's tensors and its `fit.json` record as soon as it is
/// done. A set `stop` ends it after the current step; the unfinished material is not written.
pub fn fit_all(
    tables: &[(String, PathBuf)],
    out_dir: &Path,
    config: &FitConfig,
    stop: &AtomicBool,
    on_event: &mut dyn FnMut(FitEvent<'_>),
) -> Result<FitReport> {
    config.check()?;
    std::fs::create_dir_all(out_dir).map_err(|e| Error::io(out_dir, e))?;
    let summary_path = out_dir.join(SUMMARY_FILE);
    let mut summary = FitSummary::read(&summary_path)?;
    let mut outcomes = Vec::new();
    for (name, path) in tables {
        on_event(FitEvent::Material(name));
        let prefix = out_dir.join(name);
        if network_present(&prefix) {
            let outcome = FitOutcome::Skipped;
            on_event(FitEvent::Done(name, &outcome));
            outcomes.push((name.clone(), outcome));
            continue;
        }
        let table = MaterialTable::read(path)?;
        let fitted = fit_material(&table, config, stop, &mut |step, loss| {
            on_event(FitEvent::Step(step, loss))
        })?;
        let Some((tensors, fit)) = fitted else {
            return Ok(FitReport {
                outcomes,
                interrupted: true,
            });
        };
        tensors.write(&prefix)?;
        summary.materials.insert(name.clone(), fit.clone());
        summary.write(&summary_path)?;
        let outcome = FitOutcome::Fitted(fit);
        on_event(FitEvent::Done(name, &outcome));
        outcomes.push((name.clone(), outcome));
    }
    Ok(FitReport {
        outcomes,
        interrupted: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::to_vec;
    use renderer::formats::merl::BIN_COUNT;

    /// y' [n, 3] of a burn model at inputs [n, 6].
    fn predict(model: &Nbrdf, inputs: &[f32], device: &Device) -> Vec<f32> {
        let n = inputs.len() / 6;
        let x = Tensor::<2>::from_data(TensorData::new(inputs.to_vec(), [n, 6]), device);
        to_vec(model.forward(x))
    }

    fn constant(name: &str, v: f32) -> MaterialTable {
        MaterialTable {
            name: name.into(),
            values: vec![[v, 2.0 * v, 0.5 * v]; BIN_COUNT],
        }
    }

    #[test]
    fn samples_fold_phi_d_and_map_to_ln_1_plus_f() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let s = draw_samples(&constant("c", 0.2), 500, &mut rng).unwrap();
        assert_eq!(s.len(), 500);
        for i in 0..s.len() {
            assert!((s.values[3 * i] - 0.2f32.ln_1p()).abs() < 1e-6);
            assert!((s.values[3 * i + 1] - 0.4f32.ln_1p()).abs() < 1e-6);
            // d = (sin θd cos φd, sin θd sin φd, cos θd) with φd ∈ [0, π): dy ≥ 0.
            assert!(s.inputs[6 * i + 4] >= -1e-6);
            // Only the rendered domain: wi above the horizon (and wo, checked by rendered_point).
            assert!(s.cos_i[i] > 0.0 && s.cos_i[i] <= 1.0);
        }
        assert!(s.cos_i.iter().any(|&c| c < 0.1) && s.cos_i.iter().any(|&c| c > 0.5));
    }

    #[test]
    fn tensors_round_trip_through_npy_files() {
        let dir = tempfile::tempdir().unwrap();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(4);
        let device = Device::flex();
        let model = Nbrdf::init(&mut rng, &device);
        let tensors = NbrdfTensors::from_model(&model);
        let prefix = dir.path().join("m");
        assert!(!network_present(&prefix));
        tensors.write(&prefix).unwrap();
        assert!(network_present(&prefix));
        let loaded = NbrdfNetwork::load(&prefix).unwrap();
        let x = renderer::brdf_coords::network_input_from_angles(0.4, 0.7, 1.2);
        let burn_y = predict(&model, &x, &device);
        let plain_y = loaded.forward(x);
        for c in 0..3 {
            assert!(
                (burn_y[c] - plain_y[c]).abs() < 1e-5,
                "{burn_y:?} {plain_y:?}"
            );
        }
    }

    #[test]
    fn material_seeds_differ_by_name_and_seed() {
        assert_eq!(material_seed(1, "a"), material_seed(1, "a"));
        assert_ne!(material_seed(1, "a"), material_seed(1, "b"));
        assert_ne!(material_seed(1, "a"), material_seed(2, "a"));
    }
}
