//! `material-nn export`: a model's decoder, f_ref, set encoder and latent codes as one
//! `latent.bin` — from a run directory, or from a latent file whose codes are made again
//! (e.g. the shipped model's codes with the current encoding settings). Ctrl-C stops before
//! the next code; the codes made are kept and the same command continues from them.

use clap::{ArgGroup, Args};
use material_nn::inference::EncodeSettings;
use renderer::formats::latent_file::WeightType;
use std::path::PathBuf;
use std::time::Instant;
use super::{progress_bar, STOP};
use material_nn::export::{ExportRequest, Exported};
use std::sync::atomic::Ordering;

#[derive(Args)]
#[command(group(ArgGroup::new("source").required(true).args(["run", "model"])))]
pub struct ExportArgs {
    /// Run directory of `train`.
    #[arg(long, value_name = "RUN")]
    pub run: Option<PathBuf>,
    /// A latent file that carries its set encoder: its decoder is kept and its materials
    /// (or --materials) encoded again from --data.
    #[arg(long, value_name = "LATENT_BIN", requires = "data")]
    pub model: Option<PathBuf>,
    /// Output latent file.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Materials to encode (comma-separated names), default every material of the run's data
    /// (with --model: every code of the file).
    #[arg(long, value_name = "A,B,...", value_delimiter = ',')]
    pub materials: Option<Vec<String>>,
    /// Directory of the tables to encode (default: the run's data directory).
    #[arg(long, value_name = "DIR")]
    pub data: Option<PathBuf>,
    /// Store the hypernetwork weights as f16 (half the size; with --model the file's type is
    /// kept unless this is given).
    #[arg(long)]
    pub half_weights: bool,
    #[command(flatten)]
    pub refine: super::RefineArgs,
    /// Stop after this many codes (as Ctrl-C would): the codes made are kept in
    /// OUT.partial/ and the same command continues from them.
    #[arg(long, value_name = "N")]
    pub stop_after: Option<usize>,
}

pub fn run(args: ExportArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    let refine = args.refine.settings(material_nn::inference::ENCODE_SAMPLES);
    let super::Model { codec, file: mut decoder, run } = super::load_model(args.model.as_deref(), args.run.as_deref())?;
    // Defaults: a run's data directory, materials and seed; a file's codes (--model requires
    // --data).
    let (data, names, seed) = match run {
        Some((info, seed)) => (info.data_dir, info.materials, seed),
        None => (PathBuf::new(), decoder.latent_names(), EncodeSettings::default().seed),
    };
    if args.half_weights {
        decoder.weight_type = WeightType::F16;
    }
    let data = args.data.clone().unwrap_or(data);
    let names = args.materials.clone().unwrap_or(names);
    let settings = EncodeSettings {
        seed,
        refine,
        ..EncodeSettings::default()
    };
    super::catch_ctrl_c()?;
    let stop = |done: usize| STOP.load(Ordering::SeqCst) || args.stop_after.is_some_and(|n| done >= n);
    let bar = progress_bar(names.len(), "encode");
    let exported = material_nn::export::export(&codec, decoder, &ExportRequest { data_dir: &data, names: &names, settings: &settings, out: &args.out }, &stop, &mut |name| {
        bar.set_message(name.to_string());
        bar.inc(1);
    });
    bar.finish_and_clear();
    let (file, resumed) = match exported? {
        Exported::Written { file, resumed } => (file, resumed),
        Exported::Interrupted { done, total } => anyhow::bail!(
            "{}: stopped after {done} of {total} codes, kept in {}; the same command continues from them",
            args.out.display(),
            material_nn::export::partial_dir(&args.out).display()
        ),
    };
    let size = std::fs::metadata(&args.out).map(|m| m.len()).unwrap_or(0);
    let resumed = if resumed > 0 { format!(" ({resumed} of them from an interrupted export)") } else { String::new() };
    println!(
        "{}: {} latent codes{resumed}, {:.1} MB, in {:.1} s",
        args.out.display(),
        file.latents.len(),
        size as f64 / 1e6,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
