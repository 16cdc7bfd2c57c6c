//! `material-nn eval`: a model's (a run's or a latent file's) reconstruction, editing and
//! image errors on a split.

use anyhow::Context;
use clap::{ArgGroup, Args, ValueEnum};
use material_nn::eval::EvalModel;
use material_nn::inference::{EncodeSettings, TrainedRun};
use std::path::PathBuf;
use std::time::Instant;
use super::progress_bar;

/// Which split `eval` uses.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum SplitName {
    Train,
    Validation,
    Test,
    /// Every table of the data directory (e.g. materials from outside the training data).
    All,
}

#[derive(Args)]
#[command(group(ArgGroup::new("source").required(true).args(["run", "model"])))]
pub struct EvalArgs {
    /// Run directory of `train`.
    #[arg(long, value_name = "RUN")]
    pub run: Option<PathBuf>,
    /// A latent file that carries its set encoder (written by `export`, e.g.
    /// scenes/materials/latent.bin): its codes are evaluated as they are, materials it has no
    /// code for are encoded. Needs --data and --out.
    #[arg(long, value_name = "LATENT_BIN", requires_all = ["data", "out"])]
    pub model: Option<PathBuf>,
    /// Directory of the tables (default: the run's data directory).
    #[arg(long, value_name = "DIR")]
    pub data: Option<PathBuf>,
    /// The materials evaluated: a split of the run, or `all` tables of the data directory
    /// (`--data DIR --split all`: materials the model never saw, each encoded first). With
    /// --model, `train` is the file's training materials and `all` the only other choice
    /// (the file does not record the run's validation and test splits).
    #[arg(long, value_enum, default_value = "test")]
    pub split: SplitName,
    /// Output directory (default RUN/eval; needed with --model).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Comparison points per material.
    #[arg(long, default_value_t = 65_536)]
    pub samples: usize,
    /// Random editing pairs (the talk used 2,000).
    #[arg(long, default_value_t = 50)]
    pub pairs: usize,
    /// Render the first N editing pairs too (blended table, the model's z(t), the NBRDF
    /// networks' weight blend with --nbrdf): PSNR / SSIM of editing against the blended table
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub editing_images: usize,
    /// Seed of points, pairs, t and the preview renders.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Also evaluate the NBRDF baseline networks DIR/NAME (from nbrdf-fit) of the materials.
    #[arg(long, value_name = "DIR")]
    pub nbrdf: Option<PathBuf>,
    /// Preview scene (a glTF file with a material named "preview").
    #[arg(long, value_name = "PATH", default_value_os_t = default_preview_scene())]
    pub scene: PathBuf,
    /// Samples per pixel of the preview renders (at 256 spp the noise of the two renders
    /// alone limits PSNR to about 36 dB at 128x128).
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    pub spp: u32,
    /// Size of the preview renders, WxH pixels.
    #[arg(long, value_name = "WxH", default_value = "128x128", value_parser = renderer::support::parse_resolution)]
    pub resolution: (u32, u32),
    /// BRDF-space metrics only: render no previews (no PSNR / SSIM).
    #[arg(long)]
    pub no_images: bool,
    /// Directions per directional-albedo estimate (decoded against table at 0°, 45°, 75°).
    #[arg(long, default_value_t = 1 << 17)]
    pub albedo_samples: usize,
    #[command(flatten)]
    pub refine: super::RefineArgs,
    /// Keep the tables' preview renders in DIR and reuse them when scene, table, resolution,
    /// spp and seed are the same (e.g. two models of one seed); clear DIR after changing the
    /// renderer.
    #[arg(long, value_name = "DIR")]
    pub reference_cache: Option<PathBuf>,
}

/// scenes/material-preview/scene.gltf of the workspace this binary was built in.
fn default_preview_scene() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(PathBuf::new, PathBuf::from)
        .join("scenes/material-preview/scene.gltf")
}

pub fn run(args: EvalArgs) -> anyhow::Result<()> {
    use material_nn::eval;
    let start = Instant::now();
    // The model, the tables' directory, the split's names (None: every table) and where
    // the results go.
    let (model, data, names, out) = match (&args.run, &args.model) {
        (Some(dir), _) => {
            let run = TrainedRun::load(dir)?;
            let data = args.data.clone().unwrap_or_else(|| run.info.data_dir.clone());
            let names = match args.split {
                SplitName::Train => Some(run.split.train.clone()),
                SplitName::Validation => Some(run.split.validation.clone()),
                SplitName::Test => Some(run.split.test.clone()),
                SplitName::All => None,
            };
            let out = args.out.clone().unwrap_or_else(|| dir.join("eval"));
            (EvalModel::of_run(run, dir), data, names, out)
        }
        (None, Some(path)) => {
            let model = EvalModel::of_file(path)?;
            let names = match args.split {
                SplitName::Train => Some(model.library.latent_file(0)?.training_materials.clone()),
                SplitName::All => None,
                SplitName::Validation | SplitName::Test => anyhow::bail!(
                    "{}: a latent file records its training materials only, not the run's \
                     validation and test splits; use --split train or --split all",
                    path.display()
                ),
            };
            let (Some(data), Some(out)) = (args.data.clone(), args.out.clone()) else {
                anyhow::bail!("eval --model needs --data DIR and --out DIR");
            };
            (model, data, names, out)
        }
        (None, None) => anyhow::bail!("give --run or --model"),
    };
    let names = match names {
        Some(names) => names,
        None => material_nn::tables::list_tables(&data, None)?
            .iter()
            .map(|p| material_nn::tables::material_name(p))
            .collect::<Result<Vec<_>, _>>()?,
    };
    let stored = names.iter().filter(|n| model.stored_code(n).is_some()).count();
    let (width, height) = args.resolution;
    let images = (!args.no_images).then(|| eval::ImageSettings {
        scene: args.scene.clone(),
        width,
        height,
        spp: args.spp,
        out_dir: Some(out.join("images")),
        reference_cache: args.reference_cache.clone(),
    });
    let settings = eval::EvalSettings {
        samples: args.samples,
        pairs: args.pairs,
        seed: args.seed,
        nbrdf_dir: args.nbrdf.clone(),
        images,
        encode: EncodeSettings {
            refine: args.refine.settings(material_nn::inference::ENCODE_SAMPLES),
            ..EncodeSettings::default()
        },
        albedo_samples: args.albedo_samples,
        editing_images: if args.no_images { 0 } else { args.editing_images.min(args.pairs) },
    };
    std::fs::create_dir_all(&out).with_context(|| out.display().to_string())?;
    // A step per material encoded, per reconstruction and per editing pair.
    let bar = progress_bar(2 * names.len() - stored + args.pairs, "eval");
    let result = eval::evaluate(&model, &data, &names, &settings, &mut |what| {
        bar.set_message(what.to_string());
        bar.inc(1);
    });
    bar.finish_and_clear();
    let (reconstruction, editing) = result?;
    let codes = match stored {
        0 => "Every material encoded for this evaluation.".to_string(),
        n => format!("{n} of the {} materials evaluated at the codes the latent file carries, the rest encoded.", names.len()),
    };
    let image_note = (!args.no_images).then(|| {
        let editing = match settings.editing_images {
            0 => String::new(),
            n => format!(" Editing PSNR and SSIM: the first {n} pairs, against the blended table's render."),
        };
        format!(
            "PSNR and SSIM: previews of {} ({width}x{height}, {} spp, seed {}, path depth {}) \
             against the tabulated table's, 8-bit clamp-tone-mapped values (SSIM window {}); \
             images in {}.{editing}",
            args.scene.display(),
            args.spp,
            args.seed,
            eval::PREVIEW_MAX_DEPTH,
            renderer::metrics::SSIM_WINDOW,
            out.join("images").display(),
        )
    });
    let note = match image_note {
        Some(images) => format!("{codes} {images}"),
        None => codes,
    };
    let summary = eval::to_markdown(&reconstruction, &editing, Some(&note));
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
