//! `material-nn export`: a run's decoder, f_ref, set encoder and latent codes as one `latent.bin`.

use clap::Args;
use material_nn::inference::{EncodeSettings, RefineSettings, TrainedRun};
use renderer::formats::latent_file::WeightType;
use std::path::PathBuf;
use std::time::Instant;
use super::progress_bar;

#[derive(Args)]
pub struct ExportArgs {
    /// Run directory of `train`.
    #[arg(long, value_name = "RUN")]
    pub run: PathBuf,
    /// Output latent file.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Materials to encode (comma-separated names), default every material of the data.
    #[arg(long, value_name = "A,B,...", value_delimiter = ',')]
    pub materials: Option<Vec<String>>,
    /// Directory of the tables to encode (default: the run's data directory).
    #[arg(long, value_name = "DIR")]
    pub data: Option<PathBuf>,
    /// Store the hypernetwork weights as f16 (half the size).
    #[arg(long)]
    pub half_weights: bool,
    /// Refinement steps of each code, decoder frozen (0: the set encoder's codes as they are).
    #[arg(long, default_value_t = RefineSettings::default().steps)]
    pub refine_steps: usize,
}

pub fn run(args: ExportArgs) -> anyhow::Result<()> {
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
