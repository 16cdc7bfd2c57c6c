//! Images split across processes or machines: `render --region`/`--tile` writes one part
//! ([`ImagePart`]: an EXR with data and display windows and the settings that rendered it),
//! `render merge PARTS... --output FULL` assembles them ([`merge_parts`]).

use super::{Args, Job, ToneMapArg};
use anyhow::{bail, Context, Result};
use clap::Parser;
use renderer::film::Film;
use renderer::formats::image_io::{write_image, ImageFormat};
use renderer::render::Budget;
use renderer::formats::image_part::{merge_parts, ImagePart};
use renderer::support::fnv1a64;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A file's name and the FNV-1a hash of its bytes: the same input on every machine, whatever
/// its path there.
fn file_identity(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
    Ok(format!("{name} fnv1a64:{:016x}", fnv1a64(&bytes)))
}

/// The settings that decide a render's pixels, recorded in each part so that `merge` can
/// refuse parts of different renders.
pub(crate) fn settings(args: &Args, job: &Job) -> Result<BTreeMap<String, String>> {
    let materials: Vec<String> = args.material.iter().map(|p| file_identity(p)).collect::<Result<_>>()?;
    let binds: Vec<String> = args.bind.iter().map(|(m, b)| format!("{m}={b}")).collect();
    Ok(BTreeMap::from([
        ("renderer".into(), env!("CARGO_PKG_VERSION").into()),
        ("scene".into(), file_identity(&args.scene)?),
        ("materials".into(), materials.join("; ")),
        ("bind".into(), binds.join("; ")),
        ("camera".into(), args.camera.clone().unwrap_or_default()),
        ("resolution".into(), format!("{}x{}", job.width, job.height)),
        (
            "spp".into(),
            match job.budget {
                Budget::Spp(spp) => spp.to_string(),
                Budget::Time(t) => format!("{} s", t.as_secs_f64()),
            },
        ),
        ("seed".into(), args.seed.to_string()),
        ("max_depth".into(), args.max_depth.to_string()),
        ("flatten_instances".into(), args.flatten_instances.to_string()),
    ]))
}

/// Writes the film of a `--region`/`--tile` render to `--output` as a part (creating its
/// directory).
pub fn write_part(args: &Args, job: &Job, film: &Film) -> Result<()> {
    let part = ImagePart {
        full_width: film.full_width,
        full_height: film.full_height,
        region: film.region,
        pixels: film.mean(),
        settings: settings(args, job)?,
    };
    // Farm tasks write into a shared directory that the first of them may have to create.
    if let Some(dir) = args.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create the directory for the part", dir.display()))?;
    }
    part.write_exr(&args.output)?;
    Ok(())
}

/// `render merge PARTS... --output FULL`.
#[derive(Parser, Debug)]
#[command(name = "render merge", about = "Assemble the parts of an image rendered with --region or --tile")]
pub struct MergeArgs {
    /// Part files (.exr), or directories whose .exr files are all parts.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// The whole image: .exr (linear f32 RGB) or .png (8-bit sRGB, tone-mapped).
    #[arg(long, short)]
    output: PathBuf,
    /// Tone mapping for PNG output.
    #[arg(long, value_enum, default_value_t = ToneMapArg::Clamp)]
    tonemap: ToneMapArg,
    /// Exposure in stops applied before tone mapping (PNG output only).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = super::parse_finite)]
    exposure: f32,
}

/// The part files named: files as given, directories as their `.exr` files in name order
/// (leaving out the output, which may sit among them).
fn part_files(args: &MergeArgs) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for path in &args.parts {
        if !path.is_dir() {
            files.push(path.clone());
            continue;
        }
        let entries = std::fs::read_dir(path).with_context(|| format!("{}: cannot list the directory", path.display()))?;
        let mut found: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_file() && ImageFormat::from_path(p) == Some(ImageFormat::Exr) && *p != args.output)
            .filter(|p| !p.file_name().is_some_and(|n| n.to_string_lossy().starts_with('.')))
            .collect();
        if found.is_empty() {
            bail!("{}: no .exr parts in this directory", path.display());
        }
        found.sort();
        files.extend(found);
    }
    Ok(files)
}

pub fn run_merge(args: MergeArgs) -> Result<()> {
    if ImageFormat::from_path(&args.output).is_none() {
        bail!("invalid value for --output: {}: unsupported image extension (use .exr or .png)", args.output.display());
    }
    let files = part_files(&args)?;
    let parts: Vec<(PathBuf, ImagePart)> = files
        .into_iter()
        .map(|f| ImagePart::read_exr(&f).map(|p| (f, p)))
        .collect::<Result<_, _>>()?;
    let (width, height, pixels) = merge_parts(&parts)?;
    write_image(&args.output, width, height, &pixels, args.tonemap.into(), args.exposure)?;
    eprintln!("merged {} parts into {} ({width}x{height})", parts.len(), args.output.display());
    Ok(())
}
