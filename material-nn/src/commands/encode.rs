//! `material-nn encode`: one material (a table or sparse samples) into a latent code,
//! optionally added to a latent file.

use anyhow::bail;
use clap::{ArgGroup, Args};
use material_nn::dataset::MaterialTable;
use material_nn::inference::RefineSettings;
use renderer::formats::latent_file::{LatentFile, NamedLatent};
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
    /// Refinement steps of the code, decoder frozen (0: the set encoder's code as it is).
    #[arg(long, default_value_t = RefineSettings::default().steps)]
    pub refine_steps: usize,
    /// Refine z alone: no output offset (the code's colour gain) is fitted.
    #[arg(long)]
    pub no_offset: bool,
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
    let refine = RefineSettings {
        steps: args.refine_steps,
        fit_offset: !args.no_offset,
        ..RefineSettings::default()
    };
    let refined = codec.encode_and_refine(&set, &refine)?;
    if let Some((path, mut file)) = library {
        file.latents.retain(|l| l.name != name);
        file.latents.push(NamedLatent {
            name: name.clone(),
            z: refined.z.clone(),
            offset: refined.offset,
        });
        file.write(path)?;
    }
    println!(
        "{}",
        serde_json::json!({
            "name": name,
            "z": refined.z,
            "offset": refined.offset,
            "samples": set.len(),
            "refine_steps": refine.steps,
            "loss_encoder": refined.initial_loss,
            "loss_refined": refined.final_loss,
            "seconds": start.elapsed().as_secs_f64(),
        })
    );
    Ok(())
}
