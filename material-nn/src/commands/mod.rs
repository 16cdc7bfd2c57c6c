//! The subcommands of `material-nn`, one module each (its arguments and what it runs), and what
//! they share: argument parsers, the progress bar and the stop flag Ctrl-C sets.

use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressStyle};
use material_nn::inference::{Codec, RefineSettings, TrainedRun};
use material_nn::run::RunInfo;
use renderer::formats::latent_file::{LatentFile, WeightType};
use renderer::Rgb;
use std::path::Path;
use std::sync::atomic::AtomicBool;

pub mod encode;
pub mod eval;
pub mod export;
pub mod nbrdf_fit;
pub mod search;
pub mod tabulate;
pub mod train;

/// How a material's code is refined after the set encoder (`encode`, `export`, `eval`).
#[derive(clap::Args, Debug, Clone)]
#[group(id = "refine")]
#[command(group(clap::ArgGroup::new("latent_fit").args(["no_residual", "residual_after_latent"])))]
pub struct RefineArgs {
    /// Refinement steps of each code, decoder frozen (0: the set encoder's code as it is);
    /// default 600, or 100 on a sparse set (fewer than 16,384 samples).
    #[arg(long)]
    pub refine_steps: Option<usize>,
    /// Fit no output offset (the code's colour gain).
    #[arg(long)]
    pub no_offset: bool,
    /// Fit no residual of the decoded network (with --no-offset: z alone, a point of the
    /// latent space).
    #[arg(long)]
    pub no_residual: bool,
    /// Adam's step on the residual relative to its step on z.
    #[arg(long, default_value_t = RefineSettings::default().residual_step, value_parser = parse_positive)]
    pub residual_step: f32,
    /// Power of cos θi on each sample's error while refining (1: the training objective's;
    /// lower gives grazing light more say).
    #[arg(long, default_value_t = RefineSettings::default().cos_power, value_parser = parse_non_negative)]
    pub cos_power: f32,
    /// Fit the residual after z and the offset (two stages of the steps each), so that z
    /// and the offset alone are the latent space's fit and the residual corrects it.
    #[arg(long, conflicts_with = "no_residual")]
    pub residual_after_latent: bool,
    /// From a table, with --no-residual or --residual-after-latent: scale the latent fit's
    /// colour (z and the offset, before any residual) so that its directional albedo
    /// (θo = 0°, 45°, 75°) is the table's.
    #[arg(long, requires = "latent_fit", conflicts_with = "no_offset")]
    pub match_albedo: bool,
}

impl RefineArgs {
    /// The refinement these arguments ask for, of a code encoded from `samples` samples.
    pub fn settings(&self, samples: usize) -> RefineSettings {
        let default = RefineSettings::for_samples(samples);
        RefineSettings {
            steps: self.refine_steps.unwrap_or(default.steps),
            fit_offset: !self.no_offset,
            fit_residual: !self.no_residual,
            residual_step: self.residual_step,
            cos_power: self.cos_power,
            residual_after_latent: self.residual_after_latent,
            match_albedo: self.match_albedo,
            ..default
        }
    }
}

/// `R,G,B` (or one grey value), each in [0, 1].
pub fn parse_rgb(s: &str) -> Result<Rgb, String> {
    let values: Vec<f32> = s
        .split(',')
        .map(|v| v.trim().parse::<f32>().map_err(|e| format!("'{v}': {e}")))
        .collect::<Result<_, _>>()?;
    let rgb = match values[..] {
        [g] => Rgb::splat(g),
        [r, g, b] => Rgb::new(r, g, b),
        _ => return Err(format!("'{s}': expected R,G,B or one value")),
    };
    if !(rgb.is_finite() && rgb.min_element() >= 0.0 && rgb.max_element() <= 1.0) {
        return Err(format!("'{s}': values must lie in [0, 1]"));
    }
    Ok(rgb)
}

/// A finite number > 0.
pub fn parse_positive(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}': expected a positive number")),
    }
}

/// A finite number ≥ 0.
pub fn parse_non_negative(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("'{s}': expected a non-negative number")),
    }
}

/// A progress bar of `len` steps labelled `what`.
pub fn progress_bar(len: usize, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len as u64);
    if let Ok(style) = ProgressStyle::with_template(
        "{prefix} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta} {msg}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_prefix(what.to_string());
    bar
}

/// The trained model a command encodes with (`encode`, `export`).
pub struct Model {
    /// Encodes and refines codes.
    pub codec: Codec,
    /// The model as a latent file: the file given (with its codes), or a run's decoder and
    /// encoder (no codes).
    pub file: LatentFile,
    /// When the model came from a run directory: what it was trained on, and its seed.
    pub run: Option<(RunInfo, u64)>,
}

/// The model of `--model FILE` (a latent file that carries its set encoder) or, without one,
/// of `--run DIR`.
pub fn load_model(model: Option<&Path>, run: Option<&Path>) -> anyhow::Result<Model> {
    match (model, run) {
        (Some(path), _) => {
            let file = LatentFile::read(path)?;
            let codec = Codec::from_latent_file(&file, path)?;
            Ok(Model { codec, file, run: None })
        }
        (None, Some(dir)) => {
            let run = TrainedRun::load(dir)?;
            let file = material_nn::export::latent_file(&run, WeightType::F32);
            let seed = run.config.seed;
            Ok(Model { codec: run.codec, file, run: Some((run.info, seed)) })
        }
        (None, None) => anyhow::bail!("give --model or --run"),
    }
}

/// Set by Ctrl-C once [`catch_ctrl_c`] is called: training stops after the current step, an
/// export before its next code.
pub static STOP: AtomicBool = AtomicBool::new(false);

/// Makes Ctrl-C set [`STOP`] instead of ending the process, for commands that stop cleanly.
pub fn catch_ctrl_c() -> anyhow::Result<()> {
    ctrlc::set_handler(|| STOP.store(true, std::sync::atomic::Ordering::SeqCst))
        .context("cannot install the Ctrl-C handler")
}
