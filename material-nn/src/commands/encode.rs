//! `material-nn encode`: one material (a table or sparse samples) into a latent code,
//! optionally added to a latent file.

use anyhow::bail;
use clap::{ArgGroup, Args};
use material_nn::dataset::MaterialTable;
use renderer::formats::latent_file::LatentFile;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
#[command(group(ArgGroup::new("source").required(true).args(["run", "model"])))]
#[command(group(ArgGroup::new("input").required(true).args(["table", "samples"])))]
pub struct EncodeArgs {
    /// A latent file that carries its set encoder (written by `export`, e.g.
    /// scenes/materials/latent.bin).
    #[arg(long, value_name = "LATENT_BIN")]
    pub model: Option<PathBuf>,
    /// Run directory of `train`.
    #[arg(long, value_name = "RUN")]
    pub run: Option<PathBuf>,
    /// A MERL-layout table to encode.
    #[arg(long, value_name = "FILE")]
    pub table: Option<PathBuf>,
    /// A sparse sample set: CSV lines theta_h,theta_d,phi_d,r,g,b (radians, 1/sr).
    #[arg(long, value_name = "CSV")]
    pub samples: Option<PathBuf>,
    /// Samples drawn from --table.
    #[arg(long, default_value_t = material_nn::inference::ENCODE_SAMPLES)]
    pub count: usize,
    /// Seed of the samples drawn from --table.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[command(flatten)]
    pub refine: super::RefineArgs,
    /// Name of the latent code (default: the input's file stem).
    #[arg(long)]
    pub name: Option<String>,
    /// Add (or replace) the code in this latent file; created from the model (its decoder
    /// and encoder, this one code) when missing.
    #[arg(long, value_name = "LATENT_BIN")]
    pub add_to: Option<PathBuf>,
}

pub fn run(args: EncodeArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    // The codec and the decoder file a new --add-to library starts from.
    let super::Model { codec, file: model_file, .. } = super::load_model(args.model.as_deref(), args.run.as_deref())?;
    let (input, set, table) = match (&args.table, &args.samples) {
        (Some(path), _) => {
            let table = MaterialTable::read(path)?;
            (path, codec.draw(&table, args.count, args.seed)?, Some(table))
        }
        (None, Some(csv)) => (csv, material_nn::inference::read_sample_csv(csv, &codec.sampler)?, None),
        (None, None) => bail!("encode needs --table or --samples"),
    };
    let name = match args.name {
        Some(n) => n,
        None => material_nn::tables::material_name(input)?,
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
    let refine = args.refine.settings(set.len());
    let refined = codec.encode_and_refine(&set, table.as_ref(), &refine)?;
    if let Some((path, mut file)) = library {
        file.latents.retain(|l| l.name != name);
        file.latents.push(refined.clone().into_named(&name));
        file.write(path)?;
    }
    println!(
        "{}",
        serde_json::json!({
            "name": name,
            "z": refined.z,
            "offset": refined.offset,
            "residual_values": refined.residual.len(),
            "residual_rms": rms(&refined.residual),
            "samples": set.len(),
            "refine_steps": refine.steps,
            "loss_encoder": refined.initial_loss,
            "loss_refined": refined.final_loss,
            "seconds": start.elapsed().as_secs_f64(),
        })
    );
    Ok(())
}

/// Root mean square of `v` (0 when empty).
fn rms(v: &[f32]) -> f64 {
    (v.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>() / v.len().max(1) as f64).sqrt()
}
