//! Training configuration: every hyperparameter of a run, with the method's defaults
//! (docs/training.md, "Configuration"). Saved as `config.json` in the run directory and
//! inside every checkpoint; a JSON file given with `--config` may set any subset of the
//! fields.

use crate::augment::Augmentation;
use crate::interpolation::Interpolation;
use crate::dataset::{MaterialTable, Sampler};
use crate::error::{Error, Result};
use renderer::neural::mapping::MappingForm;
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::Arc;

/// Which model a run trains.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelKind {
    /// HyperBRDF (set encoder + hypernetwork + target net) trained with L_rec + η L_fre.
    Frenbrdf,
    /// The same autoencoder trained with L_rec only.
    Hyperbrdf,
}

/// Form of the reconstruction loss L_rec.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RecForm {
    /// The talk's Eq. 1: mean |(y − y') cos θi| + λ1 Σ w² + λ2 Σ z².
    Talk,
    /// The authors' code: mean ((y − y') cos θi)² + λ1 mean w² + λ2 mean z².
    Code,
}

/// `start` decayed along a half cosine to `start × final_fraction` as `t` goes from 0 to 1:
/// the learning-rate schedule of NBRDF fitting and of latent refinement.
pub fn half_cosine_decay(start: f64, final_fraction: f64, t: f64) -> f64 {
    let f = final_fraction;
    start * (f + (1.0 - f) * 0.5 * (1.0 + (std::f64::consts::PI * t).cos()))
}

/// How the learning rate changes over a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LrSchedule {
    /// `learning_rate` throughout.
    Constant,
    /// From `learning_rate` down to `learning_rate × final_lr_fraction` along a half cosine
    /// over all the run's steps.
    Cosine,
}

/// Where L_fre takes its spherical-harmonic coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FreForm {
    /// The talk's Eq. 3: the model and the table evaluated on a fixed grid of difference
    /// directions (θd, φd) at each of `theta_h_slices` (φh = 0), cos θi-weighted, zero
    /// outside the rendered domain ([`crate::loss::SlicedFre`]).
    Slices,
    /// The released code's: the step's own samples splatted onto the grid by their
    /// difference directions, all θh together ([`crate::loss::FreOperator`]).
    Splat,
}

/// Settings of the frequency-rectified loss L_fre.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FreConfig {
    /// Where the coefficients come from.
    pub form: FreForm,
    /// θh of the slices (degrees) of the `slices` form.
    pub theta_h_slices: Vec<f32>,
    /// Weight η of L_fre in the total loss (FreNBRDF only). When `eta_share` is set, a new
    /// run replaces it before its first step (and records the value in its configuration).
    pub eta: f32,
    /// If set, η is chosen at the start of a run so that η·L_fre is this share of the L_rec
    /// data term, both measured with the initial model on the validation materials (the
    /// training ones when there are none).
    pub eta_share: Option<f32>,
    /// Maximum SH degree L.
    pub lmax: usize,
    /// Neighbours per grid point in the splat.
    pub neighbours: usize,
    /// Width σ of the splat kernel, in chordal distance.
    pub splat_sigma: f64,
    /// Width σ of the Gaussian weighting of the SH coefficients over the degree l.
    pub degree_sigma: f64,
}

impl Default for FreConfig {
    fn default() -> Self {
        FreConfig {
            form: FreForm::Slices,
            theta_h_slices: vec![0.0, 1.0, 3.0, 6.0, 12.0, 22.0, 35.0, 50.0, 70.0],
            eta: 0.1,
            eta_share: Some(0.25),
            lmax: 49,
            neighbours: 2,
            splat_sigma: 0.05,
            degree_sigma: 50.0,
        }
    }
}

/// Sizes of the networks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ModelConfig {
    /// Size of the latent code z.
    pub latent_dim: usize,
    /// Hidden widths of the set encoder (9 → these → latent_dim, ReLU after every layer).
    pub encoder_hidden: Vec<usize>,
    /// Hidden widths of each hypernetwork head (latent_dim → these → numel).
    pub hyper_hidden: Vec<usize>,
    /// Target-net widths, input (6) first, output (3) last.
    pub target_widths: Vec<usize>,
    /// Factor on the initial weights of each head's last layer.
    pub hyper_last_init_scale: f32,
}

impl Default for ModelConfig {
    fn default() -> Self {
        ModelConfig {
            latent_dim: 40,
            encoder_hidden: vec![128, 128, 128],
            hyper_hidden: vec![128, 128],
            target_widths: vec![6, 60, 60, 60, 60, 3],
            hyper_last_init_scale: 1e-2,
        }
    }
}

/// All hyperparameters of a training run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrainConfig {
    /// The model trained.
    pub model: ModelKind,
    /// Seed of every random choice: split (unless `split_seed` is set), initial weights,
    /// samples.
    pub seed: u64,
    /// Seed of the split alone, when it should not follow `seed`: runs that differ only in
    /// their initial weights and samples then share their test materials (a study of the
    /// model's run-to-run spread on one split). `null` (default): `seed`.
    pub split_seed: Option<u64>,
    /// Fractions of the materials in the training, validation and test splits (sum 1).
    pub split: [f64; 3],
    /// Form of the log-relative mapping. Default: the talk's, which measured 2–4 dB better
    /// in preview PSNR than the code's (whose y ≈ f/f_ref below f_ref turns small errors in y
    /// into large relative errors of dark channels; docs/training.md).
    pub mapping: MappingForm,
    /// ε of the mapping.
    pub epsilon: f32,
    /// Share of each step's points (and so of the encoder's) whose θh is drawn with MERL's
    /// spacing θh = u²·π/2 instead of uniformly ([`crate::dataset::draw_angles`]). Default
    /// 0.5: with the talk's mapping it lowered the directional-albedo error of the test
    /// materials (mirror-like ones keep their energy) at equal PSNR (docs/training.md).
    pub peak_share: f32,
    /// Samples drawn per material per step (a fresh subset each step; the authors
    /// draw 1,458,000 per material once, which a CPU cannot afford per step). They feed the
    /// loss; the first `encoder_samples` of them also feed the set encoder.
    pub samples_per_step: usize,
    /// Samples the set encoder sees per step (≤ samples_per_step); the encoder dominates the
    /// cost of a step, and z is a mean, so a subset gives an unbiased estimate of it.
    pub encoder_samples: usize,
    /// Materials per optimiser step (the method uses 1).
    pub materials_per_step: usize,
    /// Passes over the training materials.
    pub epochs: usize,
    /// Adam learning rate (at the start of the run).
    pub learning_rate: f64,
    /// How the learning rate changes over the run.
    pub lr_schedule: LrSchedule,
    /// The cosine schedule's last learning rate, as a fraction of `learning_rate`.
    pub final_lr_fraction: f64,
    /// Form of L_rec. Default: the code's; with the talk's form the summed penalties dwarf
    /// the data term and the reconstruction does not improve (docs/training.md).
    pub rec_form: RecForm,
    /// λ1: weight of the target-net weights' penalty.
    pub lambda_weights: f32,
    /// λ2: weight of the latent code's penalty.
    pub lambda_latent: f32,
    /// Clip of the global gradient norm (none if absent).
    pub grad_clip_norm: Option<f32>,
    /// L_fre settings.
    pub fre: FreConfig,
    /// Network sizes.
    pub net: ModelConfig,
    /// Stop when the validation loss has not improved for this many epochs.
    pub patience: usize,
    /// Samples per validation material (drawn from a fixed seed, the same every epoch).
    pub validation_samples: usize,
    /// Synthetic variants of the training materials ([`crate::augment`]); none by default.
    pub augment: Augmentation,
    /// Interpolated frames between training materials ([`crate::interpolation`]); none by
    /// default.
    pub interpolation: Interpolation,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            model: ModelKind::Frenbrdf,
            seed: 1,
            split_seed: None,
            split: [0.7, 0.1, 0.2],
            mapping: MappingForm::Talk,
            epsilon: 0.002,
            peak_share: 0.5,
            samples_per_step: 16_384,
            encoder_samples: 4_096,
            materials_per_step: 1,
            epochs: 100,
            learning_rate: 5e-4,
            lr_schedule: LrSchedule::Cosine,
            final_lr_fraction: 0.05,
            rec_form: RecForm::Code,
            lambda_weights: 0.1,
            lambda_latent: 0.1,
            grad_clip_norm: Some(1.0),
            fre: FreConfig::default(),
            net: ModelConfig::default(),
            patience: 30,
            validation_samples: 16_384,
            augment: Augmentation::default(),
            interpolation: Interpolation::default(),
        }
    }
}

impl TrainConfig {
    /// Reads a (partial) configuration from JSON; missing fields take their defaults.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let config: TrainConfig = serde_json::from_str(&text)
            .map_err(|e| Error::invalid_file(path, format!("bad config: {e}")))?;
        config.check().map_err(|e| Error::invalid_file(path, e))?;
        Ok(config)
    }

    /// The sampler this run draws its sample sets with (mapping, ε, θh distribution) around
    /// f_ref, `reference`.
    pub fn sampler(&self, reference: MaterialTable) -> Sampler {
        Sampler {
            reference: Arc::new(reference),
            mapping: self.mapping,
            epsilon: self.epsilon,
            peak_share: self.peak_share,
        }
    }

    /// The learning rate of optimiser step `step` (0-based) of a run of `total_steps`.
    pub fn learning_rate_at(&self, step: u64, total_steps: u64) -> f64 {
        match self.lr_schedule {
            LrSchedule::Constant => self.learning_rate,
            LrSchedule::Cosine => {
                let t = (step as f64 / total_steps.max(1) as f64).min(1.0);
                let end = self.learning_rate * self.final_lr_fraction;
                end + (self.learning_rate - end) * 0.5 * (1.0 + (std::f64::consts::PI * t).cos())
            }
        }
    }

    /// The seed that draws the split: `split_seed`, or `seed` when unset.
    pub fn split_seed(&self) -> u64 {
        self.split_seed.unwrap_or(self.seed)
    }

    /// Whether L_fre is part of the loss.
    pub fn uses_fre(&self) -> bool {
        self.model == ModelKind::Frenbrdf && self.fre.eta > 0.0
    }

    /// Checks ranges; the message names the field.
    pub fn check(&self) -> std::result::Result<(), String> {
        let sum: f64 = self.split.iter().sum();
        if self.split.iter().any(|f| !(0.0..=1.0).contains(f))
            || (sum - 1.0).abs() > 1e-6
            || self.split[0] <= 0.0
        {
            return Err(format!(
                "split {:?} must be three fractions summing to 1 with training > 0",
                self.split
            ));
        }
        if !(self.epsilon > 0.0 && self.epsilon.is_finite()) {
            return Err(format!("epsilon {} must be positive", self.epsilon));
        }
        if self.samples_per_step < 16
            || self.encoder_samples == 0
            || self.encoder_samples > self.samples_per_step
        {
            return Err(
                "need samples_per_step ≥ 16 and 0 < encoder_samples ≤ samples_per_step".to_string(),
            );
        }
        if self.materials_per_step == 0 || self.epochs == 0 || self.validation_samples == 0 {
            return Err(
                "materials_per_step, epochs and validation_samples must be positive".to_string(),
            );
        }
        if !(0.0..=1.0).contains(&self.peak_share) {
            return Err(format!("peak_share {} must lie in [0, 1]", self.peak_share));
        }
        if !(0.0..=1.0).contains(&self.final_lr_fraction) {
            return Err(format!(
                "final_lr_fraction {} must lie in [0, 1]",
                self.final_lr_fraction
            ));
        }
        if !(self.learning_rate > 0.0 && self.learning_rate.is_finite()) {
            return Err(format!(
                "learning_rate {} must be positive",
                self.learning_rate
            ));
        }
        let n = &self.net;
        if n.latent_dim == 0
            || n.target_widths.len() < 2
            || n.target_widths[0] != 6
            || n.target_widths.last() != Some(&3)
            || n.target_widths
                .iter()
                .chain(&n.encoder_hidden)
                .chain(&n.hyper_hidden)
                .any(|&w| w == 0)
        {
            return Err("net: widths must be positive, target widths from 6 to 3".to_string());
        }
        if self.fre.form == FreForm::Slices
            && (self.fre.theta_h_slices.is_empty()
                || self.fre.theta_h_slices.iter().any(|t| !(0.0..90.0).contains(t)))
        {
            return Err("fre: theta_h_slices must be angles in [0, 90) degrees".to_string());
        }
        if self.fre.eta_share.is_some_and(|s| !(s > 0.0 && s.is_finite())) {
            return Err("fre: eta_share must be positive".to_string());
        }
        if self.fre.neighbours == 0
            || self.fre.lmax == 0
            || self.fre.splat_sigma <= 0.0
            || self.fre.degree_sigma <= 0.0
        {
            return Err(
                "fre: lmax, neighbours, splat_sigma and degree_sigma must be positive".to_string(),
            );
        }
        self.augment.check()?;
        self.interpolation.check()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_schedule_runs_from_the_rate_to_its_fraction() {
        let c = TrainConfig {
            learning_rate: 1e-3,
            final_lr_fraction: 0.1,
            ..TrainConfig::default()
        };
        assert_eq!(c.learning_rate_at(0, 100), 1e-3);
        assert!((c.learning_rate_at(50, 100) - 0.55e-3).abs() < 1e-12);
        assert!((c.learning_rate_at(100, 100) - 1e-4).abs() < 1e-12);
        let constant = TrainConfig {
            lr_schedule: LrSchedule::Constant,
            ..c.clone()
        };
        assert_eq!(constant.learning_rate_at(70, 100), 1e-3);
        let bad = TrainConfig {
            peak_share: 1.5,
            ..c
        };
        assert!(bad.check().unwrap_err().contains("peak_share"));
    }

    #[test]
    fn the_split_follows_the_seed_unless_split_seed_is_set() {
        let follows: TrainConfig = serde_json::from_str(r#"{"seed": 4}"#).unwrap();
        assert_eq!(follows.split_seed(), 4);
        let fixed: TrainConfig = serde_json::from_str(r#"{"seed": 4, "split_seed": 3}"#).unwrap();
        assert_eq!((fixed.seed, fixed.split_seed()), (4, 3));
    }
}
