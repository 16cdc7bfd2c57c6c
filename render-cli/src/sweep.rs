//! `render --sweep A:B:STEPS --output DIR`: frames rendered with the latent code
//! z(t) = (1 − t) z_A + t z_B bound to every neural material of the scene, written as
//! `DIR/frame-KKK.{exr,png}` as they finish, then `DIR/contact-sheet.png`. With
//! `--tables TDIR`, each frame is also rendered with the linear blend of `TDIR/A.binary` and
//! `TDIR/B.binary` (`DIR/table-KKK.{exr,png}`, a second row of the sheet) and the error of the
//! neural frame against it goes to `DIR/sweep.csv`.
//!
//! `--frames A-B` renders a chunk of the frames only (a farm task); the contact sheet and
//! `sweep.csv` are assembled from the frame files in `DIR` by whichever run finds all of
//! them there, so chunks may finish in any order.
//!
//! With `--checkpoint FILE` one file serves the chunk: it holds the frame under way, and a
//! resumed run skips the frames of the chunk before it (written by the interrupted run),
//! continues that frame from the checkpoint and renders the rest.

use super::{summary, Job};
use anyhow::{bail, Context, Result};
use renderer::bsdf::merl::{Interpolation, MerlBsdf};
use renderer::bsdf::tabulated_sampling::TabulatedSamplerConfig;
use renderer::formats::image_io::{read_image, read_png_rgb8, to_srgb8, write_image, write_png_rgb8, write_text};
use renderer::neural::latent_library::LatentLibrary;
use renderer::material::SharedBsdf;
use renderer::formats::merl::MerlTable;
use renderer::metrics::{display_values, ImageError};
use renderer::render_scene::RenderScene;
use crate::contact_sheet::{contact_sheet, SheetFrame};
use renderer::Rgb;
use std::path::Path;

/// Renders the sweep (see the module documentation).
pub fn run(job: &Job, scene: &mut RenderScene, latents: &LatentLibrary, spec: &SweepSpec) -> Result<()> {
    let slots = scene.materials.neural_slots();
    if slots.is_empty() {
        bail!(
            "invalid value for --sweep: no material of the scene is bound to a latent code (bind one with --bind MATERIAL={})",
            spec.from
        );
    }
    let sweep = latents.sweep(&latents.latent(&spec.from)?, &latents.latent(&spec.to)?)?;
    let times = spec.times();
    let frames = job.args.frames.unwrap_or(FrameRange {
        first: 0,
        last: times.len() - 1,
    });
    if frames.last >= times.len() {
        bail!("invalid value for --frames: {frames}: the sweep has {} frames, 0-{}", times.len(), times.len() - 1);
    }
    let tables = match &job.args.tables {
        Some(dir) => Some((
            MerlTable::read(dir.join(format!("{}.binary", spec.from)))?,
            MerlTable::read(dir.join(format!("{}.binary", spec.to)))?,
        )),
        None => None,
    };
    let dir = &job.args.output;
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create the sweep directory", dir.display()))?;
    let (w, h) = (job.width, job.height);
    let display = |pixels: &[Rgb]| to_srgb8(pixels, job.tone_map, job.args.exposure);
    // A checkpoint of frame K (its neural render, or its table render once the neural
    // frame was written): frames before K are done.
    let resume = job.checkpoint.as_ref().and_then(|c| c.resume_frame());
    if let Some((k, _)) = resume {
        if !(frames.first..=frames.last).contains(&k) {
            bail!("{}: checkpoint of frame {k}, outside frames {frames}", job.checkpoint.as_ref().expect("resume").path.display());
        }
        if k > frames.first {
            eprintln!("frames {} to {} were written before the checkpoint", frames.first, k - 1);
        }
    }
    for k in resume.map_or(frames.first, |(k, _)| k)..=frames.last {
        let t = times[k];
        let code = sweep.code(t)?;
        let label = format!("{}>{}@{t:.2}", spec.from, spec.to);
        for &slot in &slots {
            scene.materials.set_shared(slot, SharedBsdf::Neural(latents.decode_code(&code, &label)?));
        }
        let neural_written = resume == Some((k, true)) && dir.join(format!("frame-{k:03}.exr")).is_file();
        let (pixels, mut line) = if neural_written {
            // Resuming the table render of frame k: its neural frame is on disk.
            let (_, _, pixels) = read_image(&dir.join(format!("frame-{k:03}.exr")))?;
            (pixels, format!("frame {}/{} t={t:.3}: written before the checkpoint", k + 1, times.len()))
        } else {
            let (film, stats, _) = job.render(scene, Some(&format!("{k} neural")))?;
            if stats.interrupted {
                // An error, so that a farm task (a chunk of frames) does not look done.
                let written = if k == frames.first { "no frame".to_string() } else { format!("frames {} to {}", frames.first, k - 1) };
                bail!("interrupted: {written} written to {}", dir.display());
            }
            let pixels = film.mean();
            write_image(&dir.join(format!("frame-{k:03}.exr")), w, h, &pixels, job.tone_map, job.args.exposure)?;
            write_png_rgb8(&dir.join(format!("frame-{k:03}.png")), w, h, &display(&pixels))?;
            (pixels, format!("frame {}/{} t={t:.3}: {}", k + 1, times.len(), summary(&stats)))
        };
        if let Some((ta, tb)) = &tables {
            let blend = ta.blend(tb, t as f64);
            let bsdf = MerlBsdf::new(&blend, Interpolation::default(), &TabulatedSamplerConfig::default());
            for &slot in &slots {
                scene.materials.set_shared(slot, SharedBsdf::Merl(bsdf.clone()));
            }
            let (film, stats, _) = job.render(scene, Some(&format!("{k} table")))?;
            if stats.interrupted {
                bail!("interrupted: neural frames {} to {k} written to {}", frames.first, dir.display());
            }
            let table_pixels = film.mean();
            write_image(&dir.join(format!("table-{k:03}.exr")), w, h, &table_pixels, job.tone_map, job.args.exposure)?;
            write_png_rgb8(&dir.join(format!("table-{k:03}.png")), w, h, &display(&table_pixels))?;
            let e = frame_error(job, &pixels, &table_pixels);
            line += &format!("; against the table blend: PSNR {:.2} dB, SSIM {:.4}", e.psnr, e.ssim);
        }
        eprintln!("{line}");
    }
    let all = (0..times.len()).all(|k| {
        dir.join(format!("frame-{k:03}.png")).is_file() && (tables.is_none() || dir.join(format!("table-{k:03}.png")).is_file())
    });
    if !all {
        eprintln!(
            "wrote frames {frames} to {}; the contact sheet is made by the run that finds all {} frames there",
            dir.display(),
            times.len()
        );
        return Ok(());
    }
    write_sheet(job, dir, &times, tables.is_some())?;
    eprintln!("wrote frames {frames} and contact-sheet.png to {}", dir.display());
    Ok(())
}

/// Error of a neural frame against the table blend's, on display values.
fn frame_error(job: &Job, neural: &[Rgb], table: &[Rgb]) -> ImageError {
    ImageError::between(neural, table, job.width as usize, job.height as usize, |img| {
        display_values(img, job.tone_map, job.args.exposure)
    })
}

/// Assembles `contact-sheet.png` (and with tables `sweep.csv`) from all frames of the sweep
/// in `dir`: neural frames in the first row, table blends in the second.
fn write_sheet(job: &Job, dir: &Path, times: &[f32], tables: bool) -> Result<()> {
    let (w, h) = (job.width, job.height);
    let read_frame = |name: String| -> Result<Vec<u8>> {
        let path = dir.join(name);
        let (fw, fh, rgb8) = read_png_rgb8(&path)?;
        if (fw, fh) != (w, h) {
            bail!("{}: a {fw}x{fh} frame among {w}x{h} ones (left from another sweep?)", path.display());
        }
        Ok(rgb8)
    };
    let mut sheet = Vec::new();
    for (k, t) in times.iter().enumerate() {
        sheet.push(SheetFrame {
            label: format!("t={t:.2}"),
            rgb8: read_frame(format!("frame-{k:03}.png"))?,
        });
    }
    if tables {
        let mut csv = String::from("frame,t,rmse,psnr,ssim\n");
        for (k, t) in times.iter().enumerate() {
            sheet.push(SheetFrame {
                label: format!("table t={t:.2}"),
                rgb8: read_frame(format!("table-{k:03}.png"))?,
            });
            let (_, _, neural) = read_image(&dir.join(format!("frame-{k:03}.exr")))?;
            let (_, _, table) = read_image(&dir.join(format!("table-{k:03}.exr")))?;
            let e = frame_error(job, &neural, &table);
            csv += &format!("{k},{t},{:.8e},{:.4},{:.6}\n", e.rmse, e.psnr, e.ssim);
        }
        write_text(&dir.join("sweep.csv"), &csv)?;
    }
    let (sw, sh, pixels) = contact_sheet(&sheet, w, h, times.len());
    write_png_rgb8(&dir.join("contact-sheet.png"), sw, sh, &pixels)?;
    Ok(())
}

/// A sweep from latent A to latent B in `steps` frames (`render --sweep A:B:STEPS`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SweepSpec {
    pub from: String,
    pub to: String,
    pub steps: usize,
}

impl std::str::FromStr for SweepSpec {
    type Err = String;

    /// Parses `A:B:STEPS` with STEPS in 2..=1000.
    fn from_str(s: &str) -> Result<Self, String> {
        let err = || format!("'{s}' is not A:B:STEPS (two latent names and 2 to 1000 frames)");
        let (names, steps) = s.rsplit_once(':').ok_or_else(err)?;
        let (from, to) = names.rsplit_once(':').ok_or_else(err)?;
        let steps: usize = steps.trim().parse().map_err(|_| err())?;
        if from.is_empty() || to.is_empty() || !(2..=1000).contains(&steps) {
            return Err(err());
        }
        Ok(SweepSpec {
            from: from.to_string(),
            to: to.to_string(),
            steps,
        })
    }
}

/// Frames `first..=last` of a sweep (`--frames A-B` or `--frames A`), counted from 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameRange {
    pub first: usize,
    pub last: usize,
}

impl std::str::FromStr for FrameRange {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let err = || format!("'{s}' is not A-B or A (frames counted from 0, A <= B)");
        let (a, b) = s.split_once('-').unwrap_or((s, s));
        match (a.trim().parse::<usize>(), b.trim().parse::<usize>()) {
            (Ok(first), Ok(last)) if first <= last => Ok(FrameRange { first, last }),
            _ => Err(err()),
        }
    }
}

impl std::fmt::Display for FrameRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.first == self.last {
            write!(f, "{}", self.first)
        } else {
            write!(f, "{}-{}", self.first, self.last)
        }
    }
}

impl SweepSpec {
    /// The interpolation parameters of the frames: k / (steps − 1), from 0 to 1.
    pub fn times(&self) -> Vec<f32> {
        (0..self.steps).map(|k| k as f32 / (self.steps - 1) as f32).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_sweep_specs() {
        let s: SweepSpec = "alum-bronze:chrome:5".parse().unwrap();
        assert_eq!(s.times(), vec![0.0, 0.25, 0.5, 0.75, 1.0]);
        assert_eq!((s.from.as_str(), s.to.as_str()), ("alum-bronze", "chrome"));
        for bad in ["a:b", "a:b:1", "a:b:x", ":b:3", "a::3", "a:b:100000"] {
            assert!(bad.parse::<SweepSpec>().is_err(), "{bad}");
        }
    }

    #[test]
    fn parses_frame_ranges() {
        assert_eq!("2-5".parse(), Ok(FrameRange { first: 2, last: 5 }));
        assert_eq!("7".parse(), Ok(FrameRange { first: 7, last: 7 }));
        for bad in ["5-2", "-1", "a-b", "1-", "", "1-2-3"] {
            assert!(bad.parse::<FrameRange>().is_err(), "{bad}");
        }
    }
}
