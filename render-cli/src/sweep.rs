//! `render --sweep A:B:STEPS --output DIR`: frames rendered with the latent code
//! z(t) = (1 − t) z_A + t z_B bound to every neural material of the scene, written as
//! `DIR/frame-KKK.{exr,png}` as they finish, then `DIR/contact-sheet.png`. With
//! `--tables TDIR`, each frame is also rendered with the linear blend of `TDIR/A.binary` and
//! `TDIR/B.binary` (`DIR/table-KKK.{exr,png}`, a second row of the sheet) and the error of the
//! neural frame against it goes to `DIR/sweep.csv`.

use super::{summary, Job};
use anyhow::{bail, Context, Result};
use renderer::bsdf::merl::{Interpolation, MerlBsdf};
use renderer::bsdf::tabulated_sampling::TabulatedSamplerConfig;
use renderer::formats::image_io::{to_srgb8, write_image, write_png_rgb8, write_text};
use renderer::neural::latent_library::LatentLibrary;
use renderer::material::SharedBsdf;
use renderer::formats::merl::MerlTable;
use renderer::metrics::{display_values, ImageError};
use renderer::render_scene::RenderScene;
use crate::contact_sheet::{contact_sheet, SheetFrame};
use renderer::Rgb;

/// Renders the sweep (see the module documentation).
pub fn run(job: &Job, scene: &mut RenderScene, latents: &LatentLibrary, spec: &SweepSpec) -> Result<()> {
    let slots = scene.materials.neural_slots();
    if slots.is_empty() {
        bail!(
            "invalid value for --sweep: no material of the scene is bound to a latent code (bind one with --bind MATERIAL={})",
            spec.from
        );
    }
    let (a, b) = (latents.latent(&spec.from)?, latents.latent(&spec.to)?);
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
    let mut neural_frames = Vec::new();
    let mut table_frames = Vec::new();
    let mut csv = String::from("frame,t,rmse,psnr,ssim\n");
    let times = spec.times();
    for (k, &t) in times.iter().enumerate() {
        let code = a.lerp(&b, t)?;
        let label = format!("{}>{}@{t:.2}", spec.from, spec.to);
        for &slot in &slots {
            scene.materials.set_shared(slot, SharedBsdf::Neural(latents.decode_code(&code, &label)?));
        }
        let (film, stats, _) = job.render(scene);
        if stats.interrupted {
            eprintln!("interrupted: {k} of {} frames written to {}", times.len(), dir.display());
            return Ok(());
        }
        let pixels = film.mean();
        write_image(&dir.join(format!("frame-{k:03}.exr")), w, h, &pixels, job.tone_map, job.args.exposure)?;
        let rgb8 = display(&pixels);
        write_png_rgb8(&dir.join(format!("frame-{k:03}.png")), w, h, &rgb8)?;
        neural_frames.push(SheetFrame {
            label: format!("t={t:.2}"),
            rgb8,
        });
        let mut line = format!("frame {}/{} t={t:.3}: {}", k + 1, times.len(), summary(&stats));
        if let Some((ta, tb)) = &tables {
            let blend = ta.blend(tb, t as f64);
            let bsdf = MerlBsdf::new(&blend, Interpolation::default(), &TabulatedSamplerConfig::default());
            for &slot in &slots {
                scene.materials.set_shared(slot, SharedBsdf::Merl(bsdf.clone()));
            }
            let (film, stats, _) = job.render(scene);
            if stats.interrupted {
                eprintln!("interrupted: {} neural frames written to {}", k + 1, dir.display());
                return Ok(());
            }
            let table_pixels = film.mean();
            write_image(&dir.join(format!("table-{k:03}.exr")), w, h, &table_pixels, job.tone_map, job.args.exposure)?;
            let rgb8 = display(&table_pixels);
            write_png_rgb8(&dir.join(format!("table-{k:03}.png")), w, h, &rgb8)?;
            table_frames.push(SheetFrame {
                label: format!("table t={t:.2}"),
                rgb8,
            });
            let e = ImageError::between(&pixels, &table_pixels, w as usize, h as usize, |img| {
                display_values(img, job.tone_map, job.args.exposure)
            });
            csv += &format!("{k},{t},{:.8e},{:.4},{:.6}\n", e.rmse, e.psnr, e.ssim);
            line += &format!("; against the table blend: PSNR {:.2} dB, SSIM {:.4}", e.psnr, e.ssim);
        }
        eprintln!("{line}");
    }
    let columns = neural_frames.len();
    neural_frames.extend(table_frames);
    let (sw, sh, sheet) = contact_sheet(&neural_frames, w, h, columns);
    write_png_rgb8(&dir.join("contact-sheet.png"), sw, sh, &sheet)?;
    if tables.is_some() {
        write_text(&dir.join("sweep.csv"), &csv)?;
    }
    eprintln!("wrote {} frames and contact-sheet.png to {}", times.len(), dir.display());
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
}
