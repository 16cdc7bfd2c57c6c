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
use renderer::image_io::{to_srgb8, write_image, write_png_rgb8, write_text};
use renderer::latent_library::LatentLibrary;
use renderer::material::SharedBsdf;
use renderer::merl::MerlTable;
use renderer::metrics::{display_values, ImageError};
use renderer::render_scene::RenderScene;
use renderer::sweep::{blend_tables, contact_sheet, lerp_code, SheetFrame, SweepSpec};
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
        let code = lerp_code(&a, &b, t)?;
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
            let blend = blend_tables(ta, tb, t as f64);
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
