//! `material-nn`: learns neural materials from measured BRDFs; see the crate README.
//!
//! Errors are reported as one line `error: ...` naming the file and the problem, exit code 2.

use anyhow::{bail, Context};
use clap::{ArgGroup, Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use material_nn::config::TrainConfig;
use material_nn::dataset::MaterialTable;
use material_nn::inference::{Codec, EncodeSettings, RefineSettings, TrainedRun};
use material_nn::nbrdf_fit::{self, FitConfig, FitEvent, FitOutcome};
use material_nn::tabulate::{self, TableOutcome};
use material_nn::training::{self, Event, Outcome, TrainRequest};
use renderer::analytic::AnalyticBrdf;
use renderer::formats::latent_file::{LatentFile, NamedLatent, WeightType};
use renderer::Rgb;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "material-nn",
    version,
    about = "Neural materials from measured BRDFs"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Write MERL-layout `.binary` tables (90 x 90 x 180 bins, f64) from NBRDF networks, as the
    /// per-bin median of other tables, or from an analytic model.
    ///
    ///   material-nn tabulate --nbrdf ../shared/data/nbrdf/merl --out data/merl-fitted
    ///   material-nn tabulate --median-of data/merl-fitted --out data/merl-median.binary
    ///   material-nn tabulate --analytic ggx --albedo 0.5,0.3,0.1 --alpha 0.2 --out ggx.binary
    #[command(verbatim_doc_comment)]
    Tabulate(TabulateArgs),
    /// Train HyperBRDF / FreNBRDF on the MERL-layout tables of a directory (see docs/training.md).
    ///
    ///   material-nn train --data data/merl-fitted --out runs/frenbrdf [--config cfg.json]
    ///   material-nn train --data data/merl-fitted --out runs/frenbrdf --resume
    ///
    /// Ctrl-C stops after the current step with a checkpoint; --resume goes on from it.
    #[command(verbatim_doc_comment)]
    Train(TrainArgs),
    /// Write a run's decoder, f_ref and the latent codes of materials to one latent.bin.
    ///
    ///   material-nn export --run runs/frenbrdf --out scenes/materials/latent.bin
    #[command(verbatim_doc_comment)]
    Export(ExportArgs),
    /// Encode one material (a table or a sparse CSV sample set) into a latent code: the set
    /// encoder's code, refined with the decoder frozen; prints it as JSON.
    ///
    ///   material-nn encode --model scenes/materials/latent.bin --table gold.binary --add-to lib.bin
    ///   material-nn encode --model scenes/materials/latent.bin --samples measured.csv --name mine --add-to lib.bin
    ///   material-nn encode --run runs/frenbrdf --table gold.binary [--refine-steps 0]
    #[command(verbatim_doc_comment)]
    Encode(EncodeArgs),
    /// Evaluation of a run on its test split: reconstruction and editing (RMSE of cos-weighted
    /// f_r, L_rec data term, L_fre) and PSNR / SSIM of material-preview renders against the
    /// tables', optionally beside NBRDF networks; writes RUN/eval/*.csv, summary.md, images/.
    ///
    ///   material-nn eval --run runs/frenbrdf [--pairs 200] [--nbrdf runs/nbrdf] [--no-images]
    #[command(verbatim_doc_comment)]
    Eval(EvalArgs),
    /// Learning-rate search as in the talk: grid 1e-1, 1e-3, 1e-5, then random trials within a
    /// decade of the best; short runs under --out, results in --out/search.csv and
    /// --out/best-config.json.
    ///
    ///   material-nn search --data data/merl-fitted --out runs/search --epochs 3 --trials 4
    #[command(verbatim_doc_comment)]
    Search(SearchArgs),
    /// Fit the per-material NBRDF baseline (6-21-21-3 MLP, Sztrajman et al.) to each table of
    /// --data; writes OUT/NAME_fc1.npy ... NAME_b3.npy (render --bind M=nbrdf:OUT/NAME) and
    /// OUT/fit.json. Materials already written are skipped; Ctrl-C keeps every finished one.
    ///
    ///   material-nn nbrdf-fit --data data/merl-fitted --out runs/nbrdf [--materials a,b]
    #[command(verbatim_doc_comment)]
    NbrdfFit(NbrdfFitArgs),
}

#[derive(Args)]
struct NbrdfFitArgs {
    /// Directory of MERL-layout tables (NAME.binary).
    #[arg(long, value_name = "DIR")]
    data: PathBuf,
    /// Output directory of the networks (created).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Only these materials (comma-separated names), default every table of --data.
    #[arg(long, value_name = "A,B,...", value_delimiter = ',')]
    materials: Option<Vec<String>>,
    /// Epochs per material (each --steps-per-epoch Adam steps).
    #[arg(long, default_value_t = FitConfig::default().epochs)]
    epochs: usize,
    /// Adam steps per epoch.
    #[arg(long, default_value_t = FitConfig::default().steps_per_epoch)]
    steps_per_epoch: usize,
    /// Fresh uniform samples per step.
    #[arg(long, default_value_t = FitConfig::default().samples_per_step)]
    samples_per_step: usize,
    /// Seed (mixed with each material's name).
    #[arg(long, default_value_t = FitConfig::default().seed)]
    seed: u64,
    /// Adam learning rate.
    #[arg(long, default_value_t = FitConfig::default().learning_rate)]
    learning_rate: f64,
}

#[derive(Args)]
struct SearchArgs {
    /// Directory of MERL-layout tables.
    #[arg(long, value_name = "DIR")]
    data: PathBuf,
    /// Search directory (one run directory per trial).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Base configuration (its learning rate is replaced by each trial's).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Epochs per trial.
    #[arg(long, default_value_t = 3)]
    epochs: usize,
    /// Random trials after the grid.
    #[arg(long, default_value_t = 4)]
    trials: usize,
}

/// Which split `eval` uses.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum SplitName {
    Train,
    Validation,
    Test,
    /// Every table of the data directory (e.g. materials from outside the training data).
    All,
}

#[derive(Args)]
struct EvalArgs {
    /// Run directory of `train`.
    #[arg(long, value_name = "RUN")]
    run: PathBuf,
    /// Directory of the tables (default: the run's data directory).
    #[arg(long, value_name = "DIR")]
    data: Option<PathBuf>,
    /// The materials evaluated: a split of the run, or `all` tables of the data directory
    /// (`--data DIR --split all`: materials the model never saw, each encoded first).
    #[arg(long, value_enum, default_value = "test")]
    split: SplitName,
    /// Output directory (default RUN/eval).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Comparison points per material.
    #[arg(long, default_value_t = 65_536)]
    samples: usize,
    /// Random editing pairs (the talk used 2,000).
    #[arg(long, default_value_t = 50)]
    pairs: usize,
    /// Seed of points, pairs, t and the preview renders.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Also evaluate the NBRDF baseline networks DIR/NAME (from nbrdf-fit) of the materials.
    #[arg(long, value_name = "DIR")]
    nbrdf: Option<PathBuf>,
    /// Preview scene (a glTF file with a material named "preview").
    #[arg(long, value_name = "PATH", default_value_os_t = default_preview_scene())]
    scene: PathBuf,
    /// Samples per pixel of the preview renders (at 256 spp the noise of the two renders
    /// alone limits PSNR to about 36 dB at 128x128).
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    spp: u32,
    /// Size of the preview renders, WxH pixels.
    #[arg(long, value_name = "WxH", default_value = "128x128", value_parser = renderer::support::parse_resolution)]
    resolution: (u32, u32),
    /// BRDF-space metrics only: render no previews (no PSNR / SSIM).
    #[arg(long)]
    no_images: bool,
    /// Directions per directional-albedo estimate (decoded against table at 0°, 45°, 75°).
    #[arg(long, default_value_t = 1 << 17)]
    albedo_samples: usize,
    /// Refinement steps of each material's code, as `encode` refines (0: the set encoder's
    /// codes as they are).
    #[arg(long, default_value_t = RefineSettings::default().steps)]
    refine_steps: usize,
}

/// scenes/material-preview/scene.gltf of the workspace this binary was built in.
fn default_preview_scene() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(PathBuf::new, PathBuf::from)
        .join("scenes/material-preview/scene.gltf")
}

#[derive(Args)]
struct TrainArgs {
    /// Directory of MERL-layout tables (NAME.binary).
    #[arg(long, value_name = "DIR")]
    data: PathBuf,
    /// Run directory (created): configuration, split, f_ref, checkpoints.
    #[arg(long, value_name = "RUN")]
    out: PathBuf,
    /// Configuration JSON (any subset of the fields; defaults otherwise).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Continue the run from its checkpoint.
    #[arg(long)]
    resume: bool,
    /// Stop with a checkpoint after this many optimiser steps in all (as Ctrl-C would).
    #[arg(long, value_name = "N")]
    stop_after_steps: Option<u64>,
}

#[derive(Args)]
struct ExportArgs {
    /// Run directory of `train`.
    #[arg(long, value_name = "RUN")]
    run: PathBuf,
    /// Output latent file.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Materials to encode (comma-separated names), default every material of the data.
    #[arg(long, value_name = "A,B,...", value_delimiter = ',')]
    materials: Option<Vec<String>>,
    /// Directory of the tables to encode (default: the run's data directory).
    #[arg(long, value_name = "DIR")]
    data: Option<PathBuf>,
    /// Store the hypernetwork weights as f16 (half the size).
    #[arg(long)]
    half_weights: bool,
    /// Refinement steps of each code, decoder frozen (0: the set encoder's codes as they are).
    #[arg(long, default_value_t = RefineSettings::default().steps)]
    refine_steps: usize,
}

#[derive(Args)]
#[command(group(ArgGroup::new("source").required(true).args(["run", "model"])))]
#[command(group(ArgGroup::new("input").required(true).args(["table", "samples"])))]
struct EncodeArgs {
    /// A latent file that carries its set encoder (written by `export`, e.g.
    /// scenes/materials/latent.bin).
    #[arg(long, value_name = "LATENT_BIN")]
    model: Option<PathBuf>,
    /// Run directory of `train`.
    #[arg(long, value_name = "RUN")]
    run: Option<PathBuf>,
    /// A MERL-layout table to encode.
    #[arg(long, value_name = "FILE")]
    table: Option<PathBuf>,
    /// A sparse sample set: CSV lines theta_h,theta_d,phi_d,r,g,b (radians, 1/sr).
    #[arg(long, value_name = "CSV")]
    samples: Option<PathBuf>,
    /// Samples drawn from --table.
    #[arg(long, default_value_t = material_nn::inference::ENCODE_SAMPLES)]
    count: usize,
    /// Seed of the samples drawn from --table.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Refinement steps of the code, decoder frozen (0: the set encoder's code as it is).
    #[arg(long, default_value_t = RefineSettings::default().steps)]
    refine_steps: usize,
    /// Name of the latent code (default: the input's file stem).
    #[arg(long)]
    name: Option<String>,
    /// Add (or replace) the code in this latent file; created from the model (its decoder
    /// and encoder, this one code) when missing.
    #[arg(long, value_name = "LATENT_BIN")]
    add_to: Option<PathBuf>,
}

/// Analytic model families for `tabulate --analytic`.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum AnalyticKind {
    /// Lambert + GGX microfacet (height-correlated Smith, Schlick Fresnel with F0 = --specular).
    Ggx,
    /// Lambert + Beckmann microfacet (Smith, Schlick Fresnel with F0 = --specular).
    Beckmann,
    /// Lambert + isotropic Ward lobe of reflectance --specular.
    Ward,
    /// Oren-Nayar diffuse with slope angle --sigma.
    OrenNayar,
}

#[derive(Args)]
#[command(group(ArgGroup::new("mode").required(true).args(["nbrdf", "median", "median_of", "analytic"])))]
struct TabulateArgs {
    /// Tabulate the NBRDF networks (`NAME_fc1.npy` ...) of this directory into --out (a
    /// directory) as NAME.binary; tables already present are skipped, so a run resumes.
    #[arg(long, value_name = "DIR")]
    nbrdf: Option<PathBuf>,
    /// With --nbrdf: only these networks (comma-separated names), default all.
    #[arg(
        long,
        value_name = "A,B,...",
        value_delimiter = ',',
        requires = "nbrdf"
    )]
    materials: Option<Vec<String>>,
    /// Write the per-bin median of the TABLE files to --out (unmeasured entries left out).
    #[arg(long, requires = "tables")]
    median: bool,
    /// Write the per-bin median of every .binary table in DIR (except --out) to --out.
    #[arg(long, value_name = "DIR")]
    median_of: Option<PathBuf>,
    /// Write the table of an analytic model to --out.
    #[arg(long, value_enum, value_name = "KIND")]
    analytic: Option<AnalyticKind>,
    /// Diffuse albedo (analytic models): R,G,B or one grey value.
    #[arg(long, value_parser = parse_rgb, default_value = "0.5")]
    albedo: Rgb,
    /// Specular reflectance (analytic models: F0 for ggx/beckmann, rho_s for ward): R,G,B or
    /// one grey value.
    #[arg(long, value_parser = parse_rgb, default_value = "0.04")]
    specular: Rgb,
    /// Microfacet roughness alpha (ggx, beckmann, ward).
    #[arg(long, default_value_t = 0.2, value_parser = parse_positive)]
    alpha: f32,
    /// Oren-Nayar slope angle sigma in radians.
    #[arg(long, default_value_t = 0.3, value_parser = parse_non_negative)]
    sigma: f32,
    /// Output: a directory for --nbrdf, a file otherwise.
    #[arg(long, value_name = "PATH")]
    out: PathBuf,
    /// Input tables of --median.
    #[arg(value_name = "TABLE")]
    tables: Vec<PathBuf>,
}

fn parse_rgb(s: &str) -> Result<Rgb, String> {
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

fn parse_positive(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}': expected a positive number")),
    }
}

fn parse_non_negative(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("'{s}': expected a non-negative number")),
    }
}

fn progress_bar(len: usize, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len as u64);
    if let Ok(style) = ProgressStyle::with_template(
        "{prefix} [{bar:40}] {pos}/{len} {elapsed_precise} eta {eta} {msg}",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_prefix(what.to_string());
    bar
}

fn tabulate(args: TabulateArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    if let Some(dir) = &args.nbrdf {
        let names = tabulate::select_networks(dir, args.materials.as_deref())?;
        let bar = progress_bar(names.len(), "tabulate");
        let outcomes = tabulate::tabulate_networks(dir, &names, &args.out, |outcome| {
            let (TableOutcome::Written(p) | TableOutcome::Skipped(p)) = outcome;
            bar.set_message(
                p.file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default(),
            );
            bar.inc(1);
        });
        bar.finish_and_clear();
        let outcomes = outcomes?;
        let written = outcomes
            .iter()
            .filter(|o| matches!(o, TableOutcome::Written(_)))
            .count();
        println!(
            "{}: wrote {written} tables, {} already present, in {:.1} s",
            args.out.display(),
            outcomes.len() - written,
            start.elapsed().as_secs_f64()
        );
        return Ok(());
    }
    let table = if args.median || args.median_of.is_some() {
        let inputs = match &args.median_of {
            Some(dir) => tabulate::tables_in(dir, Some(&args.out))?,
            None => args.tables.clone(),
        };
        let bar = progress_bar(0, "median");
        let table = tabulate::median_table(&inputs, |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        });
        bar.finish_and_clear();
        println!("median of {} tables", inputs.len());
        table?
    } else if let Some(kind) = args.analytic {
        let brdf = match kind {
            AnalyticKind::Ggx => AnalyticBrdf::LambertGgx {
                albedo: args.albedo,
                specular: args.specular,
                alpha: args.alpha,
            },
            AnalyticKind::Beckmann => AnalyticBrdf::LambertBeckmann {
                albedo: args.albedo,
                specular: args.specular,
                alpha: args.alpha,
            },
            AnalyticKind::Ward => AnalyticBrdf::Ward {
                albedo: args.albedo,
                specular: args.specular,
                alpha: args.alpha,
            },
            AnalyticKind::OrenNayar => AnalyticBrdf::OrenNayar {
                albedo: args.albedo,
                sigma: args.sigma,
            },
        };
        tabulate::table_from_analytic(&brdf)
    } else {
        bail!("tabulate needs one of --nbrdf, --median, --median-of, --analytic");
    };
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).with_context(|| parent.display().to_string())?;
    }
    table.write(&args.out)?;
    println!(
        "{}: written in {:.1} s",
        args.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Set by Ctrl-C; the training loop stops after the current step.
static STOP: AtomicBool = AtomicBool::new(false);

fn train(args: TrainArgs) -> anyhow::Result<()> {
    let config = args.config.as_deref().map(TrainConfig::read).transpose()?;
    ctrlc::set_handler(|| STOP.store(true, Ordering::SeqCst))
        .context("cannot install the Ctrl-C handler")?;
    let request = TrainRequest {
        data_dir: args.data,
        run_dir: args.out.clone(),
        config,
        resume: args.resume,
        stop_after_steps: args.stop_after_steps,
    };
    let bar = progress_bar(0, "train");
    let mut last_epoch = String::new();
    let start = Instant::now();
    let outcome = training::train(&request, &STOP, &mut |event| match event {
        Event::Start {
            total_steps,
            done,
            parameters,
        } => {
            bar.set_length(total_steps);
            bar.set_position(done);
            bar.suspend(|| println!("{parameters} parameters, {total_steps} steps, {done} done"));
        }
        Event::Step { step, losses } => {
            bar.set_position(step);
            bar.set_message(format!(
                "loss {:.4} rec {:.4} fre {:.2e}{last_epoch}",
                losses[0], losses[1], losses[2]
            ));
        }
        Event::Epoch(r) => {
            let val = r.validation.map_or("-".to_string(), |v| format!("{v:.4}"));
            last_epoch = format!(" | epoch {} val {val}", r.epoch);
            bar.suspend(|| {
                println!(
                    "epoch {:>3}: train {:.5} (rec {:.5}, fre {:.3e}), validation {val}, {:.1} s",
                    r.epoch, r.train_loss, r.train_rec, r.train_fre, r.seconds
                )
            });
        }
    });
    bar.finish_and_clear();
    let outcome = outcome?;
    let what = match outcome {
        Outcome::Completed => "completed".to_string(),
        Outcome::EarlyStopped { best_epoch } => format!("stopped early (best epoch {best_epoch})"),
        Outcome::Interrupted { step } => {
            format!("stopped after step {step}; continue with --resume")
        }
    };
    println!(
        "{}: {what} in {:.1} s",
        args.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn export(args: ExportArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    let run = TrainedRun::load(&args.run)?;
    let data = args
        .data
        .clone()
        .unwrap_or_else(|| run.info.data_dir.clone());
    let names = args
        .materials
        .clone()
        .unwrap_or_else(|| run.info.materials.clone());
    let weight_type = if args.half_weights {
        WeightType::F16
    } else {
        WeightType::F32
    };
    let settings = EncodeSettings {
        seed: run.config.seed,
        refine: RefineSettings {
            steps: args.refine_steps,
            ..RefineSettings::default()
        },
        ..EncodeSettings::default()
    };
    let bar = progress_bar(names.len(), "encode");
    let file = material_nn::export::export(
        &run,
        &data,
        &names,
        weight_type,
        &settings,
        &args.out,
        &mut |name| {
            bar.set_message(name.to_string());
            bar.inc(1);
        },
    );
    bar.finish_and_clear();
    let file = file?;
    let size = std::fs::metadata(&args.out).map(|m| m.len()).unwrap_or(0);
    println!(
        "{}: {} latent codes, {:.1} MB, in {:.1} s",
        args.out.display(),
        file.latents.len(),
        size as f64 / 1e6,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn encode(args: EncodeArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    // The codec and the decoder file a new --add-to library starts from.
    let (codec, model_file) = match (&args.model, &args.run) {
        (Some(path), _) => {
            let file = LatentFile::read(path)?;
            (Codec::from_latent_file(&file, path)?, file)
        }
        (None, Some(run)) => {
            let run = TrainedRun::load(run)?;
            let file = material_nn::export::latent_file(&run, WeightType::F32);
            (run.codec, file)
        }
        (None, None) => bail!("encode needs --model or --run"),
    };
    let (input, set) = match (&args.table, &args.samples) {
        (Some(table), _) => {
            let t = MaterialTable::read(table)?;
            (table, codec.draw(&t, args.count, args.seed)?)
        }
        (None, Some(csv)) => (csv, material_nn::inference::read_sample_csv(csv, &codec.sampler)?),
        (None, None) => bail!("encode needs --table or --samples"),
    };
    let name = match args.name {
        Some(n) => n,
        None => material_nn::dataset::material_name(input)?,
    };
    let library = match &args.add_to {
        Some(path) if path.exists() => {
            let file = LatentFile::read(path)?;
            material_nn::export::check_same_decoder(&file, &model_file, path)?;
            Some((path, file))
        }
        Some(path) => Some((
            path,
            LatentFile {
                latents: Vec::new(),
                ..model_file
            },
        )),
        None => None,
    };
    let refine = RefineSettings {
        steps: args.refine_steps,
        ..RefineSettings::default()
    };
    let refined = codec.encode_and_refine(&set, &refine)?;
    if let Some((path, mut file)) = library {
        file.latents.retain(|l| l.name != name);
        file.latents.push(NamedLatent {
            name: name.clone(),
            z: refined.z.clone(),
        });
        file.write(path)?;
    }
    println!(
        "{}",
        serde_json::json!({
            "name": name,
            "z": refined.z,
            "samples": set.len(),
            "refine_steps": refine.steps,
            "loss_encoder": refined.initial_loss,
            "loss_refined": refined.final_loss,
            "seconds": start.elapsed().as_secs_f64(),
        })
    );
    Ok(())
}

fn eval(args: EvalArgs) -> anyhow::Result<()> {
    use material_nn::eval;
    let start = Instant::now();
    let run = TrainedRun::load(&args.run)?;
    let data = args
        .data
        .clone()
        .unwrap_or_else(|| run.info.data_dir.clone());
    let names = match args.split {
        SplitName::Train => run.split.train.clone(),
        SplitName::Validation => run.split.validation.clone(),
        SplitName::Test => run.split.test.clone(),
        SplitName::All => material_nn::dataset::list_tables(&data)?
            .iter()
            .map(|p| material_nn::dataset::material_name(p))
            .collect::<Result<Vec<_>, _>>()?,
    };
    let out = args.out.clone().unwrap_or_else(|| args.run.join("eval"));
    let (width, height) = args.resolution;
    let images = (!args.no_images).then(|| eval::ImageSettings {
        scene: args.scene.clone(),
        width,
        height,
        spp: args.spp,
        out_dir: Some(out.join("images")),
    });
    let settings = eval::EvalSettings {
        samples: args.samples,
        pairs: args.pairs,
        seed: args.seed,
        nbrdf_dir: args.nbrdf.clone(),
        images,
        encode: EncodeSettings {
            refine: RefineSettings {
                steps: args.refine_steps,
                ..RefineSettings::default()
            },
            ..EncodeSettings::default()
        },
        albedo_samples: args.albedo_samples,
    };
    std::fs::create_dir_all(&out).with_context(|| out.display().to_string())?;
    let bar = progress_bar(2 * names.len() + args.pairs, "eval");
    let result = eval::evaluate(&run, &data, &names, &settings, &mut |what| {
        bar.set_message(what.to_string());
        bar.inc(1);
    });
    bar.finish_and_clear();
    let (reconstruction, editing) = result?;
    let note = (!args.no_images).then(|| {
        format!(
            "PSNR and SSIM: previews of {} ({width}x{height}, {} spp, seed {}, path depth {}) \
             against the tabulated table's, 8-bit clamp-tone-mapped values (SSIM window {}); \
             images in eval/images/.",
            args.scene.display(),
            args.spp,
            args.seed,
            eval::PREVIEW_MAX_DEPTH,
            renderer::metrics::SSIM_WINDOW
        )
    });
    let summary = eval::to_markdown(&reconstruction, &editing, note.as_deref());
    for (file, text) in [
        ("reconstruction.csv", eval::to_csv(&reconstruction)),
        ("editing.csv", eval::to_csv(&editing)),
        ("summary.md", summary.clone()),
    ] {
        let path = out.join(file);
        std::fs::write(&path, text).with_context(|| path.display().to_string())?;
    }
    print!("{summary}");
    println!(
        "{}: written in {:.1} s",
        out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn search(args: SearchArgs) -> anyhow::Result<()> {
    let mut base = match &args.config {
        Some(path) => TrainConfig::read(path)?,
        None => TrainConfig::default(),
    };
    base.epochs = args.epochs.max(1);
    ctrlc::set_handler(|| STOP.store(true, Ordering::SeqCst))
        .context("cannot install the Ctrl-C handler")?;
    let trials =
        material_nn::search::search(&args.data, &args.out, &base, args.trials, &STOP, &mut |t| {
            let how = t
                .failure
                .as_deref()
                .map_or(String::new(), |f| format!(" ({f})"));
            println!("lr {:.3e}: score {:.5}{how}", t.learning_rate, t.score);
        })?;
    if let Some(best) = trials.first() {
        println!(
            "best: lr {:.3e}, score {:.5} ({})",
            best.learning_rate,
            best.score,
            best.run.display()
        );
    }
    Ok(())
}

fn nbrdf_fit(args: NbrdfFitArgs) -> anyhow::Result<()> {
    let config = FitConfig {
        epochs: args.epochs,
        steps_per_epoch: args.steps_per_epoch,
        samples_per_step: args.samples_per_step,
        learning_rate: args.learning_rate,
        seed: args.seed,
        ..FitConfig::default()
    };
    config.check()?;
    let tables = nbrdf_fit::select_tables(&args.data, args.materials.as_deref())?;
    ctrlc::set_handler(|| STOP.store(true, Ordering::SeqCst))
        .context("cannot install the Ctrl-C handler")?;
    let start = Instant::now();
    let epochs = config.epochs as u64;
    let steps_per_epoch = config.steps_per_epoch as u64;
    let bar = progress_bar(tables.len() * config.epochs, "nbrdf-fit");
    let (mut base, mut current) = (0u64, String::new());
    let report = nbrdf_fit::fit_all(
        &tables,
        &args.out,
        &config,
        &STOP,
        &mut |event| match event {
            FitEvent::Material(name) => current = name.to_string(),
            FitEvent::Step(step, loss) => {
                bar.set_position(base + step / steps_per_epoch);
                bar.set_message(format!("{current}: loss {loss:.4e}"));
            }
            FitEvent::Done(name, outcome) => {
                base += epochs;
                bar.set_position(base);
                bar.suspend(|| match outcome {
                    FitOutcome::Fitted(f) => println!(
                        "{name}: loss {:.4e} -> {:.4e} in {:.1} s",
                        f.initial_loss, f.final_loss, f.seconds
                    ),
                    FitOutcome::Skipped => println!("{name}: already fitted, skipped"),
                });
            }
        },
    );
    bar.finish_and_clear();
    let report = report?;
    let fitted = report
        .outcomes
        .iter()
        .filter(|(_, o)| matches!(o, FitOutcome::Fitted(_)))
        .count();
    let skipped = report.outcomes.len() - fitted;
    let what = if report.interrupted {
        format!(
            "stopped after {fitted} fitted, {skipped} skipped, {} left; run again to go on",
            tables.len() - report.outcomes.len()
        )
    } else {
        format!("{fitted} fitted, {skipped} already present")
    };
    println!(
        "{}: {what} in {:.1} s",
        args.out.display(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Tabulate(args) => tabulate(args),
        Command::Train(args) => train(args),
        Command::Export(args) => export(args),
        Command::Encode(args) => encode(args),
        Command::Eval(args) => eval(args),
        Command::Search(args) => search(args),
        Command::NbrdfFit(args) => nbrdf_fit(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
