//! Training configuration: every hyperparameter of a run, with the method's defaults
//! (DESIGN.md, "FreNBRDF"). Saved as `config.json` in the run directory and inside every
//! checkpoint; a JSON file given with `--config` may set any subset of the fields.

use crate::error::{Error, Result};
use renderer::latent_file::MappingForm;
use serde::{Deserialize, Serialize};
use std::path::Path;

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

/// Settings of the frequency-rectified loss L_fre.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FreConfig {
    /// Weight η of L_fre in the total loss (FreNBRDF only).
    pub eta: f32,
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
            eta: 0.1,
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
    /// Seed of every random choice: split, initial weights, samples.
    pub seed: u64,
    /// Fractions of the materials in the training, validation and test splits (sum 1).
    pub split: [f64; 3],
    /// Form of the log-relative mapping.
    pub mapping: MappingForm,
    /// ε of the mapping.
    pub epsilon: f32,
    /// Samples drawn per material per step (a fresh uniform subset each step; the authors
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
    /// Adam learning rate.
    pub learning_rate: f64,
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
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig {
            model: ModelKind::Frenbrdf,
            seed: 1,
            split: [0.7, 0.1, 0.2],
            mapping: MappingForm::Talk,
            epsilon: 0.002,
            samples_per_step: 16_384,
            encoder_samples: 4_096,
            materials_per_step: 1,
            epochs: 100,
            learning_rate: 5e-4,
            rec_form: RecForm::Code,
            lambda_weights: 0.1,
            lambda_latent: 0.1,
            grad_clip_norm: Some(1.0),
            fre: FreConfig::default(),
            net: ModelConfig::default(),
            patience: 30,
            validation_samples: 16_384,
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
        if self.fre.neighbours == 0
            || self.fre.lmax == 0
            || self.fre.splat_sigma <= 0.0
            || self.fre.degree_sigma <= 0.0
        {
            return Err(
                "fre: lmax, neighbours, splat_sigma and degree_sigma must be positive".to_string(),
            );
        }
        Ok(())
    }
}
