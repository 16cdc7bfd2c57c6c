//! Error against run time (`render report CONFIG.toml`): for a scene and a set of materials,
//! a high-spp reference rendered with the reference representation (the tabulated MERL BSDF),
//! then every representation (tabulated MERL, NBRDF, FreNBRDF latent, HyperBRDF latent, an
//! analytic fit, ...) rendered progressively for the same time budget, its error against the
//! reference logged after every pass. Writes `OUTPUT/errors.csv`, a log-log plot
//! `OUTPUT/error-vs-time.png`, and `OUTPUT/report.md` with a table at fixed budgets and each
//! curve's floor.
//!
//! **Error**: the RMSE of the 8-bit sRGB display images (clamp tone mapping) in units of
//! the display range, 10^(−PSNR/20): bounded per pixel, so rare very bright samples (a small
//! light seen in a mirror) move it by little, unlike the RMSE of linear radiance (also in the
//! CSV with PSNR and SSIM).
//!
//! **Floor**: the error more samples cannot remove (the representation's own error). Monte
//! Carlo noise falls as 1/spp in squared error, so each curve's passes are fitted by least
//! squares with error² = floor² + c / spp (passes from 4 spp on); floor = √max(intercept, 0).
//! The reference's own noise is part of every floor.
//!
//! The configuration (TOML; relative paths are relative to the working directory; `{name}`
//! in `reference` and `bind` stands for the material):
//!
//! ```toml
//! scene = "scenes/material-preview/scene.gltf"
//! material = "preview"            # the scene material the representations bind to
//! materials = ["alum-bronze", "chrome"]
//! resolution = [128, 128]
//! max_depth = 8
//! seed = 1
//! reference = "merl:data/merl-fitted/{name}.binary"
//! reference_spp = 1024
//! time_budget = 60.0              # seconds per representation and material
//! table_budgets = [1.0, 10.0, 60.0]
//! output = "docs/report"
//!
//! [[representations]]
//! label = "MERL table"
//! bind = "merl:data/merl-fitted/{name}.binary"
//!
//! [[representations]]
//! label = "FreNBRDF"
//! latent = "scenes/materials/latent.bin"   # bind names a latent code of this file
//! bind = "{name}"
//! optional = true                          # skipped (with a note) when its file is missing
//! ```

use renderer::camera::PinholeCamera;
use renderer::formats::image_io::{write_png_rgb8, write_text, ToneMap};
use renderer::integrator::PathTracer;
use renderer::neural::latent_library::LatentLibrary;
use renderer::material::Binding;
use renderer::metrics::{display_values, ImageError};
use renderer::render::{Budget, Renderer};
use renderer::render_scene::RenderScene;
use renderer::scene::{SceneDescription, SurfaceModel};
use renderer::{Error, Result};
use serde::Deserialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// One representation of the materials.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Representation {
    /// Name in the table, plot and CSV.
    pub label: String,
    /// Binding of the material: a [`Binding`] (`merl:…`, `nbrdf:…`) or, with `latent`, a
    /// latent name; `{name}` is replaced by the material.
    pub bind: String,
    /// Latent file the binding's name is looked up in.
    #[serde(default)]
    pub latent: Option<PathBuf>,
    /// Skip the representation (with a note) when a file it needs is missing.
    #[serde(default)]
    pub optional: bool,
}

/// The report's configuration (see the module documentation).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReportConfig {
    pub scene: PathBuf,
    pub material: String,
    pub materials: Vec<String>,
    pub resolution: [u32; 2],
    #[serde(default = "default_max_depth")]
    pub max_depth: i32,
    #[serde(default)]
    pub seed: u64,
    pub reference: String,
    pub reference_spp: u32,
    /// Seconds per representation and material.
    pub time_budget: f64,
    /// Budgets (seconds) of the markdown table.
    pub table_budgets: Vec<f64>,
    pub output: PathBuf,
    pub representations: Vec<Representation>,
}

fn default_max_depth() -> i32 {
    8
}

impl ReportConfig {
    /// Reads and checks a configuration file; errors name the file.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let config: ReportConfig = toml::from_str(&text).map_err(|e| Error::invalid_file(path, e.message().to_string()))?;
        let bad = |reason: &str| Err(Error::invalid_file(path, reason.to_string()));
        if config.materials.is_empty() || config.representations.is_empty() {
            return bad("needs at least one material and one representation");
        }
        if config.resolution.contains(&0) || config.resolution.iter().any(|&r| r > renderer::support::MAX_RESOLUTION) {
            return bad("resolution must be in 1..=16384");
        }
        if config.reference_spp == 0 || !(config.time_budget > 0.0 && config.time_budget.is_finite()) {
            return bad("reference_spp and time_budget must be positive");
        }
        if config.table_budgets.iter().any(|b| !(*b > 0.0 && b.is_finite())) {
            return bad("table_budgets must be positive seconds");
        }
        Ok(config)
    }
}

/// The error of one pass of one curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Wall seconds of rendering (without the time spent measuring).
    pub seconds: f64,
    pub spp: f64,
    pub error: ImageError,
}

impl Point {
    /// The report's error: RMSE of the display images as a fraction of their range.
    pub fn display_rmse(&self) -> f64 {
        10f64.powf(-self.error.psnr / 20.0)
    }
}

/// The error curve of one representation on one material.
#[derive(Clone, Debug)]
pub struct Curve {
    pub material: String,
    pub representation: String,
    pub points: Vec<Point>,
    /// RMSE floor (see the module documentation); `None` with fewer than two usable passes.
    pub floor: Option<f64>,
}

/// Least-squares floor of RMSE² = floor² + c / spp over the points from 4 spp on.
pub fn fit_floor(points: &[Point]) -> Option<f64> {
    let xy: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.spp >= 4.0 && p.display_rmse().is_finite())
        .map(|p| (1.0 / p.spp, p.display_rmse().powi(2)))
        .collect();
    if xy.len() < 2 {
        return None;
    }
    let n = xy.len() as f64;
    let (mx, my) = (xy.iter().map(|p| p.0).sum::<f64>() / n, xy.iter().map(|p| p.1).sum::<f64>() / n);
    let sxx: f64 = xy.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = xy.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    Some((my - slope * mx).max(0.0).sqrt())
}

/// What the report calls back with as it goes: a one-line status and the fraction done.
pub type Progress<'a> = dyn Fn(&str, f64) + 'a;

/// Runs the report: renders, measures, writes the CSV, plot and markdown. `cancel` stops it
/// after the current pass (the files are then not written).
pub fn run(config: &ReportConfig, cancel: &AtomicBool, progress: &Progress) -> Result<Vec<Curve>> {
    let [w, h] = config.resolution;
    let base = SceneDescription::load(&config.scene)?;
    if !base.materials.iter().any(|m| m.name == config.material) {
        return Err(Error::UnknownName {
            what: "material (report `material`)",
            name: config.material.clone(),
            available: base.materials.iter().map(|m| m.name.clone()).collect(),
        });
    }
    let camera = base.camera_or_default(None, Some(w as f32 / h as f32))?;
    let integrator = PathTracer {
        max_depth: config.max_depth,
        ..PathTracer::default()
    };
    let scene_with = |binding: Binding, latents: &LatentLibrary| -> Result<RenderScene> {
        let mut description = base.clone();
        for m in description.materials.iter_mut().filter(|m| m.name == config.material) {
            m.model = SurfaceModel::Bound(binding.clone());
        }
        RenderScene::with_latents(description, latents)
    };
    let mut representations = Vec::new();
    for r in &config.representations {
        let latents = match &r.latent {
            Some(path) if r.optional && !path.is_file() => {
                progress(&format!("note: skipping {}: {} is missing", r.label, path.display()), 0.0);
                continue;
            }
            Some(path) => LatentLibrary::load(&[path])?,
            None => LatentLibrary::default(),
        };
        representations.push((r, latents));
    }
    let renders = config.materials.len() * (1 + representations.len());
    let mut done = 0usize;
    let mut curves = Vec::new();
    for name in &config.materials {
        let reference_scene = scene_with(Binding::parse(&config.reference.replace("{name}", name), Path::new(""))?, &LatentLibrary::default())?;
        let renderer = Renderer {
            scene: &reference_scene,
            camera: PinholeCamera::new(&camera, w, h),
            integrator,
            seed: config.seed.wrapping_add(1_000_003),
        };
        progress(&format!("{name}: reference, {} spp", config.reference_spp), done as f64 / renders as f64);
        let (film, _) = renderer.render(w, h, Budget::Spp(config.reference_spp), cancel, &|_| {}, &mut |_, _| {});
        if cancel.load(Ordering::Relaxed) {
            return Err(interrupted());
        }
        let reference = film.mean();
        done += 1;
        for (r, latents) in &representations {
            let bind = r.bind.replace("{name}", name);
            let binding = if r.latent.is_some() { Ok(Binding::Neural(bind)) } else { Binding::parse(&bind, Path::new("")) };
            let scene = match binding.and_then(|b| scene_with(b, latents)) {
                Err(e) if r.optional => {
                    progress(&format!("note: skipping {} for {name}: {e}", r.label), done as f64 / renders as f64);
                    done += 1;
                    continue;
                }
                other => other?,
            };
            let renderer = Renderer {
                scene: &scene,
                camera: PinholeCamera::new(&camera, w, h),
                integrator,
                seed: config.seed,
            };
            let mut points = Vec::new();
            let mut measuring = Duration::ZERO;
            let mut after_pass = |film: &renderer::film::Film, elapsed: Duration| {
                let start = std::time::Instant::now();
                let image = film.mean();
                let error = ImageError::between(&image, &reference, w as usize, h as usize, |img| display_values(img, ToneMap::Clamp, 0.0));
                let seconds = (elapsed - measuring).as_secs_f64();
                points.push(Point {
                    seconds,
                    spp: film.total_samples() as f64 / (w as f64 * h as f64),
                    error,
                });
                measuring += start.elapsed();
                let fraction = (done as f64 + (seconds / config.time_budget).min(1.0)) / renders as f64;
                progress(&format!("{name}: {} {seconds:.1}/{:.0} s", r.label, config.time_budget), fraction);
            };
            renderer.render(w, h, Budget::Time(Duration::from_secs_f64(config.time_budget)), cancel, &|_| {}, &mut after_pass);
            if cancel.load(Ordering::Relaxed) {
                return Err(interrupted());
            }
            done += 1;
            curves.push(Curve {
                material: name.clone(),
                representation: r.label.clone(),
                floor: fit_floor(&points),
                points,
            });
        }
    }
    std::fs::create_dir_all(&config.output).map_err(|e| Error::io(&config.output, e))?;
    write_text(&config.output.join("errors.csv"), &csv(&curves))?;
    write_text(&config.output.join("report.md"), &markdown(config, &curves))?;
    let (pw, ph, png) = plot(config, &curves)?;
    write_png_rgb8(&config.output.join("error-vs-time.png"), pw, ph, &png)?;
    Ok(curves)
}

fn interrupted() -> Error {
    Error::InvalidArgument {
        flag: "report".to_string(),
        reason: "interrupted before it finished; no report written".to_string(),
    }
}

/// All points of all curves: material, representation, seconds, spp, display RMSE, linear
/// RMSE, PSNR, SSIM.
pub fn csv(curves: &[Curve]) -> String {
    let mut s = String::from("material,representation,seconds,spp,display_rmse,rmse,psnr,ssim\n");
    for c in curves {
        for p in &c.points {
            let _ = writeln!(
                s,
                "{},{},{:.4},{},{:.6e},{:.6e},{:.3},{:.5}",
                c.material,
                c.representation,
                p.seconds,
                p.spp,
                p.display_rmse(),
                p.error.rmse,
                p.error.psnr,
                p.error.ssim
            );
        }
    }
    s
}

/// The last point of a curve within `budget` seconds.
fn at_budget(curve: &Curve, budget: f64) -> Option<&Point> {
    curve.points.iter().take_while(|p| p.seconds <= budget).last()
}

/// The markdown report: per material, RMSE (PSNR) of every representation at each budget
/// with the winner, and the floors.
pub fn markdown(config: &ReportConfig, curves: &[Curve]) -> String {
    let mut s = format!(
        "# Error against render time\n\nScene `{}` ({}x{}, max depth {}), material `{}` bound to each representation; \
         reference: `{}` at {} spp. Error: RMSE of the 8-bit sRGB display images as a fraction of their range \
         (10^(−PSNR/20); linear-radiance RMSE, PSNR and SSIM are in errors.csv); floor: the error more samples \
         cannot remove (least-squares fit of error² = floor² + c/spp); a dash: the first pass took longer than the budget.\n",
        config.scene.display(),
        config.resolution[0],
        config.resolution[1],
        config.max_depth,
        config.material,
        config.reference,
        config.reference_spp
    );
    for name in &config.materials {
        let mine: Vec<&Curve> = curves.iter().filter(|c| &c.material == name).collect();
        let _ = write!(s, "\n## {name}\n\n| representation |");
        for b in &config.table_budgets {
            let _ = write!(s, " error at {b} s |");
        }
        s += " floor |\n|---|";
        for _ in 0..=config.table_budgets.len() {
            s += "---|";
        }
        s += "\n";
        for c in &mine {
            let _ = write!(s, "| {} |", c.representation);
            for &b in &config.table_budgets {
                match at_budget(c, b) {
                    Some(p) => {
                        let _ = write!(s, " {:.4} ({} spp) |", p.display_rmse(), p.spp);
                    }
                    None => s += " – |",
                }
            }
            match c.floor {
                Some(f) => {
                    let _ = writeln!(s, " {f:.4} |");
                }
                None => s += " – |\n",
            }
        }
        s += "\n";
        for &b in &config.table_budgets {
            let best = mine
                .iter()
                .filter_map(|c| at_budget(c, b).map(|p| (c.representation.as_str(), p.display_rmse())))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((label, rmse)) = best {
                let _ = writeln!(s, "- at {b} s: **{label}** (error {rmse:.4})");
            }
        }
    }
    s
}

/// Colours of the curves, in representation order.
const COLOURS: [(u8, u8, u8); 6] = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75)];

/// A TrueType font for the plot's labels, from common system locations (or `REPORT_FONT`).
fn find_font() -> Option<Vec<u8>> {
    let candidates = std::env::var_os("REPORT_FONT").map(PathBuf::from).into_iter().chain(
        [
            "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
            "/usr/share/fonts/dejavu/DejaVuSans.ttf",
            "/usr/share/fonts/TTF/DejaVuSans.ttf",
            "/System/Library/Fonts/Supplemental/Arial.ttf",
            "C:\\Windows\\Fonts\\arial.ttf",
        ]
        .iter()
        .map(PathBuf::from),
    );
    candidates.into_iter().find_map(|p| std::fs::read(p).ok())
}

/// The log-log plot of RMSE against seconds, one panel per material, floors dashed. Labels
/// need a TrueType font (see [`find_font`]); without one the curves are drawn unlabelled.
pub fn plot(config: &ReportConfig, curves: &[Curve]) -> Result<(u32, u32, Vec<u8>)> {
    use plotters::prelude::*;
    static FONT: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let have_font = *FONT.get_or_init(|| {
        find_font().is_some_and(|bytes| {
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok()
        })
    });
    let panels = config.materials.len() as u32;
    let (pw, ph) = (640u32, 480u32);
    let (width, height) = (pw * panels, ph);
    let mut buffer = vec![255u8; (width * height * 3) as usize];
    let labels: Vec<&str> = {
        let mut l: Vec<&str> = Vec::new();
        for c in curves {
            if !l.contains(&c.representation.as_str()) {
                l.push(&c.representation);
            }
        }
        l
    };
    let plot_error = |e: &dyn std::fmt::Display| Error::invalid_file(config.output.join("error-vs-time.png"), format!("cannot draw the plot: {e}"));
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (width, height)).into_drawing_area();
        let areas = root.split_evenly((1, panels as usize));
        for (area, name) in areas.iter().zip(&config.materials) {
            let mine: Vec<&Curve> = curves.iter().filter(|c| &c.material == name).collect();
            let points = mine.iter().flat_map(|c| c.points.iter());
            let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
            for p in points.clone().filter(|p| p.seconds > 0.0 && p.display_rmse() > 0.0) {
                x0 = x0.min(p.seconds);
                x1 = x1.max(p.seconds);
                y0 = y0.min(p.display_rmse());
                y1 = y1.max(p.display_rmse());
            }
            for f in mine.iter().filter_map(|c| c.floor).filter(|f| *f > 0.0) {
                y0 = y0.min(f);
            }
            if x0 >= x1 || y0 >= y1 {
                continue;
            }
            let mut builder = ChartBuilder::on(area);
            builder.margin(12);
            if have_font {
                builder.caption(format!("{name}: error vs render time"), ("sans-serif", 20)).x_label_area_size(40).y_label_area_size(70);
            }
            let mut chart = builder
                .build_cartesian_2d((x0 * 0.8..x1 * 1.25).log_scale(), (y0 * 0.7..y1 * 1.4).log_scale())
                .map_err(|e| plot_error(&e))?;
            let mut mesh = chart.configure_mesh();
            mesh.light_line_style(RGBColor(238, 238, 238));
            if have_font {
                mesh.x_desc("seconds")
                    .y_desc("RMSE of the display image")
                    .label_style(("sans-serif", 13))
                    .x_label_formatter(&|v| format!("{v}"))
                    .y_label_formatter(&|v| format!("{v:.3}"));
            } else {
                mesh.x_labels(0).y_labels(0);
            }
            mesh.draw().map_err(|e| plot_error(&e))?;
            for c in &mine {
                let k = labels.iter().position(|l| *l == c.representation).unwrap_or(0) % COLOURS.len();
                let (r, g, b) = COLOURS[k];
                let colour = RGBColor(r, g, b);
                let series = chart
                    .draw_series(LineSeries::new(
                        c.points.iter().filter(|p| p.seconds > 0.0 && p.display_rmse() > 0.0).map(|p| (p.seconds, p.display_rmse())),
                        colour.stroke_width(2),
                    ))
                    .map_err(|e| plot_error(&e))?;
                if have_font {
                    series
                        .label(c.representation.clone())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2)));
                }
                if let Some(f) = c.floor.filter(|f| *f > 0.0) {
                    let dashes = (0..24).map(|i| {
                        let t = |i: f64| x0 * 0.8 * ((x1 * 1.25) / (x0 * 0.8)).powf(i / 24.0);
                        (t(i as f64), t(i as f64 + 0.5))
                    });
                    for (a, b) in dashes {
                        chart.draw_series(std::iter::once(PathElement::new(vec![(a, f), (b, f)], colour.mix(0.7)))).map_err(|e| plot_error(&e))?;
                    }
                }
            }
            if have_font {
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .label_font(("sans-serif", 13))
                    .draw()
                    .map_err(|e| plot_error(&e))?;
            }
        }
        root.present().map_err(|e| plot_error(&e))?;
    }
    Ok((width, height, buffer))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(spp: f64, rmse: f64) -> Point {
        Point {
            seconds: spp / 10.0,
            spp,
            error: ImageError {
                rmse,
                psnr: -20.0 * rmse.log10(),
                ssim: 0.9,
            },
        }
    }

    #[test]
    fn floor_fit_recovers_a_known_floor() {
        let (floor, c) = (0.02f64, 0.5f64);
        let points: Vec<Point> = [1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0]
            .iter()
            .map(|&spp| point(spp, (floor * floor + c / spp).sqrt()))
            .collect();
        assert!((fit_floor(&points).unwrap() - floor).abs() < 1e-9);
        // Pure noise has no floor.
        let noise: Vec<Point> = [4.0, 8.0, 16.0].iter().map(|&spp| point(spp, (c / spp).sqrt())).collect();
        assert!(fit_floor(&noise).unwrap() < 1e-6);
        assert_eq!(fit_floor(&noise[..1]), None);
    }

    #[test]
    fn markdown_marks_winners_at_each_budget() {
        let config: ReportConfig = toml::from_str(
            r#"scene = "s.gltf"
material = "preview"
materials = ["m"]
resolution = [8, 8]
reference = "merl:{name}"
reference_spp = 4
time_budget = 2.0
table_budgets = [0.5, 2.0]
output = "out"
[[representations]]
label = "A"
bind = "merl:{name}"
"#,
        )
        .unwrap();
        let curve = |label: &str, rmse: [f64; 3]| Curve {
            material: "m".into(),
            representation: label.into(),
            points: [4.0, 8.0, 16.0].iter().zip(rmse).map(|(&spp, r)| point(spp, r)).collect(),
            floor: Some(0.01),
        };
        let md = markdown(&config, &[curve("fast", [0.1, 0.05, 0.04]), curve("exact", [0.2, 0.06, 0.03])]);
        assert!(md.contains("at 0.5 s: **fast**"), "{md}");
        assert!(md.contains("at 2 s: **exact**"), "{md}");
        let (w, h, png) = plot(&config, &[curve("fast", [0.1, 0.05, 0.04])]).unwrap();
        assert_eq!(png.len(), (w * h * 3) as usize);
        assert!(png.iter().any(|&v| v < 128), "something is drawn");
    }
}
