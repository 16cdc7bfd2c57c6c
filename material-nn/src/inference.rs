//! Using a trained model: encode materials (full tables or sparse sample sets) into latent
//! codes, refine those codes, and decode them.
//!
//! A [`Codec`] holds what encoding needs — the HyperBRDF network (set encoder and
//! hypernetwork) and the sampler of its training (f_ref, mapping, ε, θh distribution) — and
//! comes from a run directory ([`TrainedRun`]) or from a `latent.bin` that carries the set
//! encoder ([`Codec::from_latent_file`]).
//!
//! Encoding a material is two steps:
//! 1. the amortised encoder: z = mean over the samples of the set encoder (one pass);
//! 2. refinement ([`Codec::refine`]): z alone is optimised with Adam (decoder frozen) on the
//!    training objective L_rec (data term + λ1 generated-weight and λ2 latent penalties, the
//!    run's form; the data term's cos θi weight raised to [`RefineSettings::cos_power`], by
//!    default 0) over a fixed sample set of the material, projected onto z ≥ 0 after every
//!    step (the encoder's ReLU output never leaves that orthant, so refined codes stay in
//!    the latent space that editing interpolates). It brings a material the encoder has
//!    never seen to the decoder's best fit.
//!
//! With [`RefineSettings::fit_offset`] the refinement also fits the code's output offset δ
//! (one value per RGB channel added to the target net's output y; see
//! [`renderer::formats::latent_file::NamedLatent::offset`]): under the talk mapping a colour
//! gain e^δ on f_r + ε, which the shared decoder cannot always give a material it never saw
//! (a saturated paper decodes to the right shape at the wrong colour). With
//! [`RefineSettings::fit_residual`] it fits, with them, a residual ΔΘ on every other decoded
//! target-net parameter ([`renderer::formats::latent_file::NamedLatent::residual`]): the
//! decoder gives the shape it knows, the residual what it has no code for — colour that
//! changes with angle, a peak sharper than its training materials'. The residual starts at 0
//! and moves `residual_step` times as fast as z (Adam's step is per parameter; ΔΘ = s·r with
//! r the optimised variable), which keeps it a correction of the decoded net rather than a
//! refit from scratch: from 0 and with Adam's bounded steps it moves only as far as the data
//! asks, so it helps even on sparse sets of 100 samples, far fewer than its 11,580 values
//! (there 100 steps fit better than 300, so a set smaller than the refinement's sample count
//! gets [`SPARSE_REFINE_STEPS`] by default; docs/training.md measures both).

use crate::checkpoint::Checkpoint;
use crate::config::TrainConfig;
use crate::dataset::{MaterialTable, SampleSet, Sampler};
use crate::error::{Error, Result};
use crate::loss::ReconstructionLoss;
use crate::model::{to_vec, HyperBrdf, Mlp};
use crate::backend::{optimizer, training_device};
use crate::run::{load_model, read_json, RunDir, RunInfo};
use burn::module::{Module, Param};
use burn::optim::GradientsParams;
use burn::tensor::{Device, Tensor, TensorData};
use rand::SeedableRng;
use renderer::formats::latent_file::{LatentFile, NamedLatent};
use renderer::neural::energy::{balance_offsets, MATCH_QUADRATURE, MATCH_THETAS_DEG};
use glam::DVec3;
use renderer::neural::latent_library::LatentCode;
use std::path::Path;
use std::sync::Arc;

/// Samples drawn per material to encode it (z is a mean over them).
pub const ENCODE_SAMPLES: usize = 65_536;

/// How a material is encoded.
#[derive(Clone, Debug, PartialEq)]
pub struct EncodeSettings {
    /// Samples drawn from a table for the amortised encoder.
    pub samples: usize,
    /// Seed of the drawn samples.
    pub seed: u64,
    /// Refinement of the encoder's z.
    pub refine: RefineSettings,
}

impl Default for EncodeSettings {
    fn default() -> Self {
        EncodeSettings {
            samples: ENCODE_SAMPLES,
            seed: 1,
            refine: RefineSettings::default(),
        }
    }
}

/// Settings of the latent refinement ([`Codec::refine`]).
#[derive(Clone, Debug, PartialEq)]
pub struct RefineSettings {
    /// Adam steps (0: the encoder's z as it is).
    pub steps: usize,
    /// Samples of the material the objective is evaluated on (a fixed set; the first ones of
    /// the encoder's set, or all of a sparse set).
    pub samples: usize,
    /// Adam learning rate, decayed along a half cosine to 5 % over the steps.
    pub learning_rate: f64,
    /// Also fit the code's output offset δ per RGB channel (0 when false).
    pub fit_offset: bool,
    /// Also fit the residual ΔΘ of the decoded parameters (none when false).
    pub fit_residual: bool,
    /// Adam's step on the residual relative to its step on z.
    pub residual_step: f32,
    /// Power k of the cos θi factor on each sample's error in the refinement's data term
    /// (the error is (ŷ − y)·cos^k θi; 1 is the training objective's). Below 1 grazing
    /// light has more say: the training objective weights a squared error at θi = 75° by
    /// cos² = 0.07, which left chrome's decoded directional albedo at θo = 75° 17–25 % too
    /// bright in red. The default 0 weights every sample alike (the samples are already
    /// confined to the rendered domain); docs/training.md measures 1, 0.5, 0.25 and 0.
    pub cos_power: f32,
    /// Fit the residual after the latent code: `steps` steps on z and δ with no residual
    /// (z + δ becomes the latent space's own fit, what `--no-residual` gives), then `steps`
    /// on the residual alone with z and δ frozen, so that the residual is a correction of that
    /// fit rather than a share of it. False: all together in one stage of `steps`.
    pub residual_after_latent: bool,
    /// When encoding a table: once the latent fit (z and δ, no residual) is made — the whole
    /// refinement without a residual, the first stage with `residual_after_latent` — scale
    /// its colour (δ, per channel) so that its directional albedo, summed over
    /// [`MATCH_THETAS_DEG`], is the table's ([`Codec::match_albedo`]). A residual fitted
    /// after it corrects the shape alone, and a sweep's interior — z and δ interpolated —
    /// starts and ends with each material's own energy. No effect on a refinement that fits
    /// the residual together with z.
    pub match_albedo: bool,
}

/// δ of a latent fit, given its z and δ as refined (see [`Codec::refine_staged`]).
type StageOffset<'a> = dyn Fn(&[f32], [f32; 3]) -> [f32; 3] + 'a;

/// Default refinement steps on a sparse sample set, one smaller than
/// [`RefineSettings::samples`] (100 samples over-fit with more: docs/training.md).
pub const SPARSE_REFINE_STEPS: usize = 100;

impl RefineSettings {
    /// The default settings for a set of `samples` samples: [`SPARSE_REFINE_STEPS`] steps
    /// when it is smaller than the refinement's sample count, the default's otherwise.
    pub fn for_samples(samples: usize) -> Self {
        let settings = RefineSettings::default();
        match samples < settings.samples {
            true => RefineSettings { steps: SPARSE_REFINE_STEPS, ..settings },
            false => settings,
        }
    }
}

impl Default for RefineSettings {
    fn default() -> Self {
        RefineSettings {
            steps: 600,
            samples: 16_384,
            learning_rate: 3e-2,
            fit_offset: true,
            fit_residual: true,
            residual_step: 0.3,
            cos_power: 0.0,
            residual_after_latent: false,
            match_albedo: false,
        }
    }
}

/// A latent code being refined: z [1, latent_dim], the output offset δ [1, 3] and the
/// residual, one [1, numel] tensor per decoded target-net tensor but the output bias (in
/// units of 1/`residual_step`; none when not fitted).
#[derive(Module, Debug)]
struct CodeParams {
    z: Param<Tensor<2>>,
    offset: Param<Tensor<2>>,
    residual: Vec<Param<Tensor<2>>>,
}

/// A trained HyperBRDF model ready to encode and decode (see the module documentation).
#[derive(Debug)]
pub struct Codec {
    /// The network on the training device, every parameter frozen (refinement backpropagates
    /// through it to z).
    frozen: HyperBrdf,
    /// The same network for inference (no autodiff).
    pub model: HyperBrdf,
    /// Sampler with the model's f_ref, mapping and θh distribution.
    pub sampler: Sampler,
    /// L_rec the model was trained with (the objective of refinement).
    pub rec_loss: ReconstructionLoss,
    /// Device of `model`.
    pub device: Device,
}

/// A refined code and its objective before and after.
#[derive(Clone, Debug, PartialEq)]
pub struct Refined {
    /// The refined z.
    pub z: Vec<f32>,
    /// The output offset δ per RGB channel (0 unless [`RefineSettings::fit_offset`]).
    pub offset: [f32; 3],
    /// The residual of the decoded parameters in the latent file's layout (empty unless
    /// fitted).
    pub residual: Vec<f32>,
    /// L_rec (data term) of the encoder's z on the refinement set.
    pub initial_loss: f64,
    /// L_rec (data term) of the refined z on the same set.
    pub final_loss: f64,
}

impl Refined {
    /// The refined code under `name`, as a latent file stores it.
    pub fn into_named(self, name: &str) -> NamedLatent {
        NamedLatent {
            name: name.to_string(),
            z: self.z,
            offset: self.offset,
            residual: self.residual,
        }
    }

    /// The refined code as the renderer decodes it, from latent file `file` of a library.
    pub fn into_code(self, file: usize) -> LatentCode {
        LatentCode {
            file,
            z: self.z,
            offset: self.offset,
            residual: self.residual,
        }
    }
}

impl Codec {
    fn new(frozen: HyperBrdf, sampler: Sampler, rec_loss: ReconstructionLoss) -> Self {
        let frozen = frozen.freeze();
        let model = frozen.valid();
        let device = Device::flex();
        Codec {
            frozen,
            model,
            sampler,
            rec_loss,
            device,
        }
    }

    /// The codec of a latent file that carries its set encoder (format version 2, written by
    /// `material-nn export`); f_ref is the file's (f16). Errors name the file when it has no
    /// encoder.
    pub fn from_latent_file(file: &LatentFile, path: &Path) -> Result<Self> {
        let Some(encoder) = &file.encoder else {
            return Err(Error::invalid_file(
                path,
                "this latent file has no set encoder (format version 1, or exported without \
                 it); re-export the model with `material-nn export`, or encode with --run",
            ));
        };
        let device = training_device()?;
        let model = HyperBrdf {
            encoder: Mlp::from_dense(&encoder.layers, &device),
            heads: file
                .hypernetwork
                .iter()
                .map(|h| Mlp::from_dense(&h.layers, &device))
                .collect(),
        };
        let values = (0..renderer::formats::merl::BIN_COUNT).map(|i| file.f_ref(i)).collect();
        let sampler = Sampler {
            reference: Arc::new(MaterialTable {
                name: "reference".to_string(),
                values,
            }),
            mapping: file.mapping,
            epsilon: file.epsilon,
            peak_share: encoder.peak_share,
        };
        // Training's L_rec settings (the file does not record them; these are the defaults).
        Ok(Self::new(model, sampler, ReconstructionLoss::of(&TrainConfig::default())))
    }

    /// Size of z.
    pub fn latent_dim(&self) -> usize {
        self.model.encoder.output_width()
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

    /// `samples` samples of a table drawn with `seed`, as the model was trained on them.
    pub fn draw(&self, table: &MaterialTable, samples: usize, seed: u64) -> Result<SampleSet> {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        self.sampler.draw(table, samples, &mut rng)
    }

    /// z of a table from `samples` samples drawn with `seed` (the amortised encoder only).
    pub fn encode_table(
        &self,
        table: &MaterialTable,
        samples: usize,
        seed: u64,
    ) -> Result<Vec<f32>> {
        self.encode_samples(&self.draw(table, samples, seed)?)
    }

    /// Encodes a sample set and refines the code on its first `settings.refine.samples`
    /// samples (see the module documentation); `table` is the table the set was drawn from,
    /// if any, which [`RefineSettings::match_albedo`] needs (a sparse set has no albedo to
    /// match: an error).
    pub fn encode_and_refine(&self, set: &SampleSet, table: Option<&MaterialTable>, settings: &RefineSettings) -> Result<Refined> {
        let z = self.encode_samples(set)?;
        match (settings.match_albedo, table) {
            (false, _) => self.refine(&z, set, settings, &mut |_, _| {}),
            (true, Some(table)) => {
                let matched = |z: &[f32], offset: [f32; 3]| self.match_albedo(table, z, offset);
                self.refine_staged(&z, set, settings, &matched, &mut |_, _| {})
            }
            (true, None) => Err(Error::Invalid(
                "matching albedo needs the material's table (sparse samples have no albedo to match)".to_string(),
            )),
        }
    }

    /// Encodes a table as `settings` say: the amortised encoder on `settings.samples` samples,
    /// then refinement.
    pub fn encode(&self, table: &MaterialTable, settings: &EncodeSettings) -> Result<Refined> {
        let set = self.draw(table, settings.samples, settings.seed)?;
        self.encode_and_refine(&set, Some(table), &settings.refine)
    }

    /// The offset δ' that gives the code (z, δ') without residual the directional albedo of
    /// `table` per channel, summed over [`MATCH_THETAS_DEG`] (the quadrature
    /// [`MATCH_QUADRATURE`] over the half vector), to 10⁻⁵ in ln ρ or after eight steps of
    /// the renderer's offset solver ([`renderer::neural::energy::balance_offsets`]).
    /// Channels where either albedo is 0 keep their δ.
    pub fn match_albedo(&self, table: &MaterialTable, z: &[f32], offset: [f32; 3]) -> [f32; 3] {
        let (mapping, epsilon) = (self.sampler.mapping, self.sampler.epsilon);
        let reference = &self.sampler.reference;
        let mut points = Vec::new();
        for theta in MATCH_THETAS_DEG {
            let wo = renderer::neural::energy::view_direction(theta.to_radians());
            for (wi, weight) in MATCH_QUADRATURE.points(wo) {
                let (input, [h, d, p]) = renderer::brdf_coords::network_input_and_angles(wi, wo);
                if let (Some(f), Some(r)) = (table.lookup(h, d, p), reference.lookup(h, d, p)) {
                    points.push((input, f, r, weight));
                }
            }
        }
        let inputs: Vec<f32> = points.iter().flat_map(|p| p.0).collect();
        let table_albedo = DVec3::from_array([0, 1, 2].map(|c| points.iter().map(|p| p.1[c].max(0.0) as f64 * p.3).sum::<f64>()));
        let code_albedo = |offset: [f32; 3]| {
            let y = self.predict(z, offset, &[], &inputs);
            Ok::<_, std::convert::Infallible>(DVec3::from_array([0, 1, 2].map(|c| {
                points.iter().enumerate().map(|(k, p)| mapping.inverse(y[3 * k + c], p.2[c].max(0.0), epsilon).max(0.0) as f64 * p.3).sum::<f64>()
            })))
        };
        let Ok(offset) = balance_offsets(offset, table_albedo, 8, 1e-5, code_albedo);
        offset
    }

    /// Refines `z` on the first `settings.samples` samples of `set` (see the module
    /// documentation); `progress(step, loss)` is called after every step.
    pub fn refine(
        &self,
        z: &[f32],
        set: &SampleSet,
        settings: &RefineSettings,
        progress: &mut dyn FnMut(usize, f64),
    ) -> Result<Refined> {
        self.refine_staged(z, set, settings, &|_, offset| offset, progress)
    }

    /// [`Self::refine`], with `after_latent(z, δ)` giving δ of the latent fit once it is made
    /// (a residual stage after it keeps that δ); not called when z and the residual are
    /// fitted together.
    fn refine_staged(
        &self,
        z: &[f32],
        set: &SampleSet,
        settings: &RefineSettings,
        after_latent: &StageOffset<'_>,
        progress: &mut dyn FnMut(usize, f64),
    ) -> Result<Refined> {
        if z.len() != self.latent_dim() {
            return Err(Error::Invalid(format!(
                "latent code of size {}, the model's is {}",
                z.len(),
                self.latent_dim()
            )));
        }
        if set.is_empty() {
            return Err(Error::Invalid("cannot refine on an empty sample set".to_string()));
        }
        let device = training_device()?;
        let n = set.len().min(settings.samples.max(1));
        let tensor3 = |v: Vec<f32>, w: usize| Tensor::<3>::from_data(TensorData::new(v, [1, n, w]), &device);
        let x = tensor3(set.inputs[..6 * n].to_vec(), 6);
        let y = tensor3(set.values[..3 * n].to_vec(), 3);
        // Each sample's error weight cos^k θi, where L_rec takes cos θi.
        let weights = tensor3(set.cos_i[..n].iter().map(|c| c.powf(settings.cos_power)).collect(), 1);
        let step = settings.residual_step;
        let objective = |code: &CodeParams| {
            let z = code.z.val();
            let mut params = self.frozen.decode(z.clone());
            for (p, r) in params.iter_mut().zip(&code.residual) {
                *p = p.clone() + r.val() * step;
            }
            let pred = self.frozen.target_forward(&params, x.clone()) + code.offset.val().unsqueeze_dim::<3>(1);
            self.rec_loss.forward(pred, y.clone(), weights.clone(), &params, z)
        };
        // Without fit_offset the offset stays a constant 0 (no gradient, Adam leaves it).
        let fit_residual = settings.fit_residual && settings.steps > 0;
        // One tensor per hypernetwork head (W0 b0 W1 b1 …) but the output bias's.
        let heads = &self.model.heads;
        let residual_sizes: Vec<usize> = match fit_residual {
            true => heads[..heads.len() - 1].iter().map(Mlp::output_width).collect(),
            false => Vec::new(),
        };
        let mut code = CodeParams {
            z: Param::from_tensor(Tensor::from_data(TensorData::new(z.to_vec(), [1, z.len()]), &device)),
            offset: Param::from_tensor(Tensor::<2>::zeros([1, 3], &device)).set_require_grad(settings.fit_offset),
            residual: residual_sizes
                .iter()
                .map(|&numel| Param::from_tensor(Tensor::<2>::zeros([1, numel], &device)))
                .collect(),
        };
        let initial_loss = objective(&code).1.into_scalar::<f32>() as f64;
        // Stages: which of z, δ (as `fit_offset` says) and the residual each fits. Staged, the
        // residual comes last with z and δ frozen, so that z and δ stay the latent space's own
        // fit (what a sweep's interior decodes) and the residual corrects it alone.
        let fit_offset = settings.fit_offset;
        let stages: &[(bool, bool, bool)] = match (fit_residual, settings.residual_after_latent) {
            (true, true) => &[(true, fit_offset, false), (false, false, true)],
            _ => &[(true, fit_offset, fit_residual)],
        };
        let mut done = 0;
        for &(fit_z, fit_offset, fit_residual) in stages {
            code.z = code.z.map(|z| z.detach().set_require_grad(fit_z));
            code.offset = code.offset.map(|o| o.detach().set_require_grad(fit_offset));
            code.residual = code.residual.into_iter().map(|r| r.map(|r| r.detach().set_require_grad(fit_residual))).collect();
            let mut optim = optimizer();
            for step in 0..settings.steps {
                let t = step as f64 / settings.steps as f64;
                let lr = crate::config::half_cosine_decay(settings.learning_rate, 0.05, t);
                let (total, data) = objective(&code);
                let grads = GradientsParams::from_grads(total.backward(), &code);
                code = optim.step(lr, code, grads);
                if fit_z {
                    code.z = code.z.map(|z| z.clamp_min(0.0).detach().require_grad());
                }
                done += 1;
                progress(done, data.into_scalar::<f32>() as f64);
            }
            if fit_z && !fit_residual {
                // The latent fit is made.
                let offset = after_latent(&to_vec(code.z.val()), to_vec(code.offset.val()).try_into().expect("offset of 3 channels"));
                code.offset = Param::from_tensor(Tensor::from_data(TensorData::new(offset.to_vec(), [1, 3]), &device));
            }
        }
        let final_loss = objective(&code).1.into_scalar::<f32>() as f64;
        let z = to_vec(code.z.val());
        let offset: [f32; 3] = to_vec(code.offset.val()).try_into().expect("offset of 3 channels");
        let residual: Vec<f32> = code.residual.iter().flat_map(|r| to_vec(r.val() * step)).collect();
        if z.iter().chain(&offset).chain(&residual).any(|v| !v.is_finite()) {
            return Err(Error::Invalid("latent refinement diverged (non-finite code)".to_string()));
        }
        Ok(Refined {
            z,
            offset,
            residual,
            initial_loss,
            final_loss,
        })
    }

    /// The mapped predictions y [n, 3] of a code (z, output offset per RGB channel, residual
    /// in the latent file's layout or empty) at network inputs [n, 6].
    ///
    /// # Panics
    /// If the residual is neither empty nor of the latent file's residual length.
    pub fn predict(&self, z: &[f32], offset: [f32; 3], residual: &[f32], inputs: &[f32]) -> Vec<f32> {
        let n = inputs.len() / 6;
        let zt = Tensor::from_data(TensorData::new(z.to_vec(), [1, z.len()]), &self.device);
        let mut params = self.model.decode(zt);
        if !residual.is_empty() {
            // Every tensor but the output bias, in order.
            let last = params.len() - 1;
            let mut at = 0;
            for p in &mut params[..last] {
                let dims = p.dims();
                let r = residual[at..at + dims[1]].to_vec();
                *p = p.clone() + Tensor::from_data(TensorData::new(r, dims), &self.device);
                at += dims[1];
            }
        }
        let x = Tensor::from_data(TensorData::new(inputs.to_vec(), [1, n, 6]), &self.device);
        let mut y = to_vec(self.model.target_forward(&params, x));
        for (k, v) in y.iter_mut().enumerate() {
            *v += offset[k % 3];
        }
        y
    }
}

/// A trained run: its codec (the best epoch's model) and what it was trained on.
#[derive(Debug)]
pub struct TrainedRun {
    /// The run's configuration.
    pub config: TrainConfig,
    /// The model of the best epoch (or of the latest checkpoint when there is no best yet).
    pub codec: Codec,
    /// What the run was trained on.
    pub info: RunInfo,
    /// The run's split of the materials.
    pub split: crate::dataset::Split,
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
        let model = load_model(&ckpt.config, &ckpt.model, &training_device()?, &path)?;
        let reference = MaterialTable::read(&run.reference())?;
        let info: RunInfo = read_json(&run.info())?;
        let split: crate::dataset::Split = read_json(&run.split())?;
        let config = ckpt.config;
        let sampler = config.sampler(reference);
        let codec = Codec::new(model, sampler, ReconstructionLoss::of(&config));
        Ok(TrainedRun {
            config,
            codec,
            info,
            split,
        })
    }
}

/// Reads a sparse sample set from CSV: one sample per line `theta_h,theta_d,phi_d,r,g,b`
/// (radians; f_r in 1/sr); blank lines and lines starting with `#` are skipped, and a first
/// line that does not parse as numbers is taken as a header. Samples outside the rendered
/// domain (wi or wo at or below the horizon, [`renderer::brdf_coords::rendered_point`]) or
/// where f_ref is unmeasured are dropped.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::ModelConfig;
    use renderer::analytic::AnalyticBrdf;
    use renderer::formats::merl::{MerlTable, BIN_COUNT};
    use renderer::Rgb;

    fn small_codec() -> Codec {
        let config = ModelConfig {
            latent_dim: 8,
            encoder_hidden: vec![32],
            hyper_hidden: vec![32],
            target_widths: vec![6, 16, 3],
            // A decoder whose output depends strongly on z, as a trained one does.
            hyper_last_init_scale: 1.0,
        };
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let model = HyperBrdf::init(&config, &mut rng, &training_device().unwrap());
        let sampler = Sampler {
            reference: Arc::new(MaterialTable {
                name: "reference".to_string(),
                values: vec![[0.1; 3]; BIN_COUNT],
            }),
            mapping: renderer::neural::mapping::MappingForm::Code,
            epsilon: 0.002,
            peak_share: 0.5,
        };
        Codec::new(model, sampler, ReconstructionLoss { form: crate::config::RecForm::Code, lambda_weights: 0.1, lambda_latent: 0.1 })
    }

    /// A glossy orange material's table.
    fn glossy_table() -> MaterialTable {
        let brdf = AnalyticBrdf::LambertGgx {
            albedo: Rgb::new(0.5, 0.2, 0.1),
            specular: Rgb::splat(0.5),
            alpha: 0.1,
        };
        MaterialTable::from_merl("ggx", &MerlTable::from_fn(|h, d, p| brdf.eval_angles(h, d, p)))
    }

    /// The small codec, 2,048 samples of a glossy orange material and the encoder's z of them.
    fn glossy_encoded() -> (Codec, SampleSet, Vec<f32>) {
        let codec = small_codec();
        let table = glossy_table();
        let set = codec.draw(&table, 2048, 1).unwrap();
        let z = codec.encode_samples(&set).unwrap();
        (codec, set, z)
    }

    #[test]
    fn refinement_lowers_the_fit_error_and_stays_in_the_latent_orthant() {
        let (codec, set, z) = glossy_encoded();
        assert!(z.iter().all(|v| *v >= 0.0), "ReLU encoder: {z:?}");
        let settings = RefineSettings {
            steps: 40,
            samples: 2048,
            learning_rate: 0.1,
            fit_offset: false,
            fit_residual: false,
            ..RefineSettings::default()
        };
        let mut losses = Vec::new();
        let refined = codec.refine(&z, &set, &settings, &mut |_, l| losses.push(l)).unwrap();
        assert_eq!(losses.len(), 40);
        assert!(
            refined.final_loss < 0.8 * refined.initial_loss,
            "{} -> {}",
            refined.initial_loss,
            refined.final_loss
        );
        assert!(refined.z.iter().all(|v| *v >= 0.0), "{:?}", refined.z);
        assert_ne!(refined.z, z);
        assert_eq!(refined.offset, [0.0; 3], "z alone");
        // With the output offset the same steps fit further, and the offset is what makes
        // the difference (a colour gain the random decoder has no code for).
        let with_offset = RefineSettings { fit_offset: true, ..settings.clone() };
        let tinted = codec.refine(&z, &set, &with_offset, &mut |_, _| {}).unwrap();
        assert!(
            tinted.final_loss < 0.9 * refined.final_loss,
            "{} (offset {:?}) vs {} (z alone)",
            tinted.final_loss,
            tinted.offset,
            refined.final_loss
        );
        assert!(tinted.offset.iter().any(|d| d.abs() > 0.05), "{:?}", tinted.offset);
        assert!(tinted.residual.is_empty());
        // With the residual as well the fit goes further again.
        let full = RefineSettings { fit_residual: true, ..with_offset.clone() };
        let corrected = codec.refine(&z, &set, &full, &mut |_, _| {}).unwrap();
        assert_eq!(corrected.residual.len(), 6 * 16 + 16 + 16 * 3, "every tensor but the output bias");
        assert!(corrected.residual.iter().any(|r| *r != 0.0));
        assert!(
            corrected.final_loss < 0.9 * tinted.final_loss,
            "{} (residual) vs {} (offset)",
            corrected.final_loss,
            tinted.final_loss
        );
        // Its predictions are those of the decoded net with the residual added.
        let y = codec.predict(&corrected.z, corrected.offset, &corrected.residual, &set.inputs[..6]);
        let plain = codec.predict(&corrected.z, corrected.offset, &[], &set.inputs[..6]);
        assert_ne!(y, plain);
        // Staged: z is the fit without residual (the same steps, bit for bit), the residual a
        // correction on top of it that fits further still.
        let staged = codec
            .refine(&z, &set, &RefineSettings { residual_after_latent: true, ..full.clone() }, &mut |_, _| {})
            .unwrap();
        assert_eq!((&staged.z, staged.offset), (&tinted.z, tinted.offset), "z and δ of the staged fit are the latent space's own");
        assert!(staged.residual.iter().any(|r| *r != 0.0));
        assert!(staged.final_loss < 0.9 * tinted.final_loss, "{} vs {}", staged.final_loss, tinted.final_loss);
        let unrefined = RefineSettings { steps: 0, ..full };
        assert!(codec.refine(&z, &set, &unrefined, &mut |_, _| {}).unwrap().residual.is_empty(), "nothing fitted");
        let none = RefineSettings { steps: 0, ..settings };
        let same = codec.refine(&z, &set, &none, &mut |_, _| {}).unwrap();
        assert_eq!((same.z, same.final_loss), (z.clone(), same.initial_loss));
        let e = codec.refine(&z[..3], &set, &none, &mut |_, _| {}).unwrap_err();
        assert!(e.to_string().contains("size 3"), "{e}");
    }

    /// Matching albedo: the matched latent fit reflects what its table reflects (matching it
    /// again moves δ by less than 0.5 %), where the plain fit of the same z did not; a
    /// residual fitted after it keeps that z and δ.
    #[test]
    fn a_matched_latent_fit_reflects_what_its_table_reflects() {
        let codec = small_codec();
        let table = glossy_table();
        let encode = |match_albedo: bool, residual: bool| {
            let refine = RefineSettings {
                steps: 40,
                samples: 2048,
                learning_rate: 0.1,
                fit_residual: residual,
                residual_after_latent: residual,
                match_albedo,
                ..RefineSettings::default()
            };
            codec.encode(&table, &EncodeSettings { samples: 2048, seed: 1, refine }).unwrap()
        };
        let (plain, matched) = (encode(false, false), encode(true, false));
        assert_eq!(plain.z, matched.z, "matching changes δ only");
        let moved = |r: &Refined| {
            let again = codec.match_albedo(&table, &r.z, r.offset);
            (0..3).map(|c| (again[c] - r.offset[c]).abs()).fold(0.0, f32::max)
        };
        assert!(moved(&plain) > 0.02, "the plain fit's albedo is off: {}", moved(&plain));
        assert!(moved(&matched) < 5e-3, "{}", moved(&matched));
        let staged = encode(true, true);
        assert_eq!((&staged.z, staged.offset), (&matched.z, matched.offset));
        assert!(staged.residual.iter().any(|r| *r != 0.0));
    }

    /// The cos θi power of the refinement's data term decides how much grazing light counts:
    /// under the training objective's weight (power 1, a squared error weighted by cos² θi)
    /// the fit leaves grazing samples further off than with every sample weighted alike
    /// (power 0; 0.61× the error at cos θi < 0.3 here, the same elsewhere).
    #[test]
    fn a_lower_cos_power_fits_grazing_light_closer() {
        let (codec, set, z) = glossy_encoded();
        // Mean squared error of the mapped values over the samples with cos θi below / above 0.3.
        let errors = |refined: &Refined| {
            let y = codec.predict(&refined.z, refined.offset, &refined.residual, &set.inputs);
            let (mut sums, mut counts) = ([0.0f64; 2], [0usize; 2]);
            for (i, &c) in set.cos_i.iter().enumerate() {
                let k = usize::from(c >= 0.3);
                counts[k] += 3;
                sums[k] += (0..3).map(|ch| (y[3 * i + ch] - set.values[3 * i + ch]).powi(2) as f64).sum::<f64>();
            }
            [sums[0] / counts[0] as f64, sums[1] / counts[1] as f64]
        };
        let settings = |cos_power| RefineSettings { steps: 60, samples: 2048, learning_rate: 0.1, cos_power, ..RefineSettings::default() };
        let training = errors(&codec.refine(&z, &set, &settings(1.0), &mut |_, _| {}).unwrap());
        let equal = errors(&codec.refine(&z, &set, &settings(0.0), &mut |_, _| {}).unwrap());
        assert!(equal[0] < 0.8 * training[0], "grazing: {} (power 0) vs {} (power 1)", equal[0], training[0]);
        // …at little cost elsewhere.
        assert!(equal[1] < 1.2 * training[1], "the rest: {} (power 0) vs {} (power 1)", equal[1], training[1]);
    }
}
