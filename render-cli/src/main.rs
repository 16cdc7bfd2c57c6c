//! `render`: renders a glTF or OBJ scene with the path tracer.
//!
//! Errors are reported once, here, as one line on stderr with exit code 2; no output file
//! is written when the render cannot start, and files are replaced atomically. A render
//! stopped by Ctrl-C or SIGTERM after writing its `--checkpoint` exits with
//! [`checkpoint::INTERRUPTED_EXIT`].

mod checkpoint;
mod contact_sheet;
mod energy;
mod parts;
mod report;
mod sweep;

use anyhow::{bail, Context, Result};
use clap::Parser;
use indicatif::{ProgressBar, ProgressStyle};
use renderer::camera::PinholeCamera;
use renderer::formats::image_io::{write_image, ImageFormat, ToneMap};
use renderer::integrator::PathTracer;
use renderer::metrics::{display_values, ImageError};
use renderer::film::Region;
use renderer::render::{Budget, Monitor, RenderState, RenderStats, Renderer};
use renderer::neural::latent_library::LatentLibrary;
use renderer::render_scene::RenderScene;
use renderer::scene::SceneDescription;
use sweep::{FrameRange, SweepSpec};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(Parser, Debug)]
#[command(name = "render", version, about = "Physically based path tracer for glTF and OBJ scenes with measured and neural BRDFs")]
struct Args {
    /// Scene file (.gltf, .glb or .obj).
    scene: PathBuf,
    /// Samples per pixel.
    #[arg(long, conflicts_with = "time", allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..))]
    spp: Option<u32>,
    /// Render for this many seconds (at least one sample per pixel; passes of one sample at
    /// first, growing to 16 as time allows).
    #[arg(long, allow_negative_numbers = true, value_parser = parse_seconds)]
    time: Option<f64>,
    /// Image size as WIDTHxHEIGHT (default: 512 wide, height from the camera's aspect ratio).
    #[arg(long, value_parser = renderer::support::parse_resolution)]
    resolution: Option<(u32, u32)>,
    /// Longest light path in segments, as Mitsuba 3's max_depth: 1 = emitters seen
    /// directly, 2 = direct lighting, ...; -1 = unlimited.
    #[arg(long, default_value_t = 8, allow_negative_numbers = true, value_parser = clap::value_parser!(i32).range(-1..))]
    max_depth: i32,
    /// Seed of the random streams; the same seed gives the same image for any thread count.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    seed: u64,
    /// Worker threads (0 = one per core).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    threads: usize,
    /// Camera name (default: the scene's first camera).
    #[arg(long)]
    camera: Option<String>,
    /// Output image: .exr (linear f32 RGB) or .png (8-bit sRGB, tone-mapped); with --sweep,
    /// the directory receiving the frames.
    #[arg(long, short, default_value = "render.exr")]
    output: PathBuf,
    /// Write render statistics as JSON to this file.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Latent file (latent.bin) whose codes materials may bind (repeatable; a name is taken
    /// from the first file holding it). Materials named like a latent code bind to it.
    #[arg(long)]
    material: Vec<PathBuf>,
    /// Bind a material: MATERIAL=LATENT_NAME (needs --material), or MATERIAL=BINDING with
    /// BINDING merl:PATH.binary or nbrdf:PATH_PREFIX (repeatable).
    #[arg(long, value_parser = parse_binding)]
    bind: Vec<(String, String)>,
    /// Editing sweep A:B:STEPS: renders STEPS frames with the latent code
    /// (1 − t) z_A + t z_B, t from 0 to 1, into the directory --output, with a contact sheet.
    #[arg(long, requires = "material", conflicts_with_all = ["reference", "error_log"])]
    sweep: Option<SweepSpec>,
    /// Directory of MERL tables A.binary and B.binary: sweep frames are also rendered with
    /// the linear blend of the tables and their error is written to sweep.csv.
    #[arg(long, requires = "sweep")]
    tables: Option<PathBuf>,
    /// With --sweep: render only frames A to B (or A alone), counted from 0 as the file names
    /// are, so that a farm can render a sweep in chunks into one directory; the contact sheet
    /// (and sweep.csv) is written by whichever chunk finds all frames there.
    #[arg(long, requires = "sweep")]
    frames: Option<FrameRange>,
    /// Render only this rectangle of the image, X0,Y0,X1,Y1 in pixels from the top-left
    /// corner, ends exclusive, into an EXR part (`render merge` assembles parts). With the
    /// same settings the parts equal the whole render bit for bit.
    #[arg(long, conflicts_with_all = ["tile", "sweep", "time", "reference", "error_log"])]
    region: Option<Region>,
    /// Render band K of N (K from 1) of horizontal bands of whole 16-pixel rows, as --region.
    #[arg(long, value_parser = parse_tile, conflicts_with_all = ["sweep", "time", "reference", "error_log"])]
    tile: Option<(u32, u32)>,
    /// Tone mapping for PNG output.
    #[arg(long, value_enum, default_value_t = ToneMapArg::Clamp)]
    tonemap: ToneMapArg,
    /// Reference image (.exr) to measure error against after every pass (needs --error-log).
    #[arg(long, requires = "error_log")]
    reference: Option<PathBuf>,
    /// CSV file receiving, after every pass: wall seconds (without the time spent measuring),
    /// spp, RMSE (linear), PSNR and SSIM (8-bit display images) against --reference.
    #[arg(long, requires = "reference")]
    error_log: Option<PathBuf>,
    /// Exposure in stops applied before tone mapping (PNG output only).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = parse_finite)]
    exposure: f32,
    /// Checkpoint file: the render's state is written there (atomically) at pass boundaries
    /// every --checkpoint-every seconds and when Ctrl-C or SIGTERM stops it (exit code 75);
    /// the same command started again with the file present resumes and gives the image of
    /// the uninterrupted render bit for bit. The file is removed once the output is written;
    /// one of other settings, truncated or corrupted is refused.
    #[arg(long, conflicts_with_all = ["time", "reference", "error_log"])]
    checkpoint: Option<PathBuf>,
    /// Seconds between checkpoints (written at the first pass boundary after this long; 0 =
    /// after every pass).
    #[arg(long, requires = "checkpoint", default_value_t = 300.0, allow_negative_numbers = true, value_parser = parse_interval)]
    checkpoint_every: f64,
    /// Copy every instanced mesh into world space (as if the file had no instancing): for
    /// comparing memory and speed with and without two-level acceleration.
    #[arg(long)]
    flatten_instances: bool,
    /// Report progress as lines `progress F` on stderr (F: the fraction done, 0.000 to
    /// 1.000, a line whenever another whole per cent is done) instead of the progress bar,
    /// for programs that run `render` (the Blender add-on).
    #[arg(long)]
    progress_lines: bool,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum ToneMapArg {
    Clamp,
    Aces,
}

impl From<ToneMapArg> for ToneMap {
    fn from(t: ToneMapArg) -> ToneMap {
        match t {
            ToneMapArg::Clamp => ToneMap::Clamp,
            ToneMapArg::Aces => ToneMap::Aces,
        }
    }
}

fn parse_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(t) if t.is_finite() && t > 0.0 => Ok(t),
        _ => Err(format!("'{s}' is not a positive number of seconds")),
    }
}

fn parse_interval(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(t) if t.is_finite() && t >= 0.0 => Ok(t),
        _ => Err(format!("'{s}' is not a number of seconds >= 0")),
    }
}

fn parse_finite(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("'{s}' is not a finite number")),
    }
}

fn parse_tile(s: &str) -> Result<(u32, u32), String> {
    let err = || format!("'{s}' is not K/N (band K of N, 1 <= K <= N)");
    let (k, n) = s.split_once('/').ok_or_else(err)?;
    match (k.trim().parse::<u32>(), n.trim().parse::<u32>()) {
        (Ok(k), Ok(n)) if 1 <= k && k <= n => Ok((k, n)),
        _ => Err(err()),
    }
}

fn parse_binding(s: &str) -> Result<(String, String), String> {
    match s.split_once('=') {
        Some((m, binding)) if !m.is_empty() && !binding.is_empty() => Ok((m.to_string(), binding.to_string())),
        _ => Err(format!("'{s}' is not MATERIAL=BINDING")),
    }
}

/// What `--stats` writes: the render's statistics plus load timing.
#[derive(Serialize)]
struct StatsFile<'a> {
    scene: &'a Path,
    /// Reading the scene file (and the latent files).
    parse_seconds: f64,
    /// Preparing it for rendering: BVHs, materials, lights.
    prepare_seconds: f64,
    /// The two together.
    load_seconds: f64,
    /// Triangles stored, and triangles in the world (each instance counting its mesh's).
    stored_triangles: usize,
    triangle_instances: u64,
    instances: usize,
    /// Neural BSDF evaluations whose value the inverse mapping sent below 0, clamped to 0.
    clamped_bsdf_values: u64,
    /// The BSDFs made from data opened for the scene: tables, networks and decoded latent
    /// codes (palettes of latent blends included), their memory and the time taken.
    materials: renderer::material::MaterialStats,
    #[serde(flatten)]
    render: &'a RenderStats,
}

/// `--progress-lines`: the fraction of a render done, one line per whole per cent.
struct ProgressLines {
    /// Samples in the render (or milliseconds of a time budget).
    total: u64,
    /// Samples done, and the last per cent printed (+1; 0 = none yet).
    state: std::sync::Mutex<(u64, u64)>,
}

impl ProgressLines {
    fn new(total: u64, done: u64) -> ProgressLines {
        let lines = ProgressLines { total: total.max(1), state: std::sync::Mutex::new((0, 0)) };
        lines.set(done);
        lines
    }

    /// Counts `n` more samples done (from any thread).
    fn add(&self, n: u64) {
        self.update(|done| *done += n);
    }

    /// Sets the amount done.
    fn set(&self, amount: u64) {
        self.update(|done| *done = amount);
    }

    /// Changes the amount done and prints a line when another whole per cent is done (under
    /// the lock, so that the lines come in order).
    fn update(&self, change: impl FnOnce(&mut u64)) {
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        change(&mut state.0);
        let fraction = (state.0 as f64 / self.total as f64).clamp(0.0, 1.0);
        let percent = (fraction * 100.0).floor() as u64;
        if percent + 1 > state.1 {
            state.1 = percent + 1;
            eprintln!("progress {fraction:.3}");
        }
    }
}

/// What every render of this invocation shares.
struct Job<'a> {
    args: &'a Args,
    camera: renderer::scene::Camera,
    width: u32,
    height: u32,
    /// The pixels to render (the whole image unless --region or --tile).
    region: Region,
    budget: Budget,
    tone_map: ToneMap,
    reference: Option<Vec<renderer::Rgb>>,
    cancel: Arc<AtomicBool>,
    pool: rayon::ThreadPool,
    /// `--checkpoint`.
    checkpoint: Option<checkpoint::Checkpointing>,
}

impl Job<'_> {
    /// Renders the scene once with a progress bar; returns the film, the statistics and the
    /// error-log CSV (empty without a reference). With `--checkpoint`, the render continues
    /// the checkpoint found at start-up if it is of this render (`frame` names a sweep's),
    /// writes checkpoints as it goes, and an interrupted render is an [`checkpoint::Interrupted`]
    /// error once its checkpoint is written.
    fn render(&self, scene: &RenderScene, frame: Option<&str>) -> Result<(renderer::film::Film, RenderStats, String)> {
        let (width, height, region) = (self.width, self.height, self.region);
        let pixels = region.pixel_count() as u64;
        let renderer = Renderer {
            scene,
            camera: PinholeCamera::new(&self.camera, width, height),
            integrator: PathTracer {
                max_depth: self.args.max_depth,
                ..PathTracer::default()
            },
            seed: self.args.seed,
        };
        let bar = match self.budget {
            _ if self.args.progress_lines => ProgressBar::hidden(),
            Budget::Spp(spp) => ProgressBar::new(pixels * spp as u64).with_style(
                ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {percent}% {per_sec} samples, eta {eta}")
                    .expect("valid template")
                    .progress_chars("=> "),
            ),
            Budget::Time(t) => ProgressBar::new(t.as_millis() as u64).with_style(
                ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {msg}")
                    .expect("valid template")
                    .progress_chars("=> "),
            ),
        };
        let start = match &self.checkpoint {
            Some(c) => c.start(frame, width, height, region),
            None => RenderState::new(width, height, region),
        };
        bar.set_position(pixels * start.samples_done as u64);
        let lines = self.args.progress_lines.then(|| match self.budget {
            Budget::Spp(spp) => ProgressLines::new(pixels * spp as u64, pixels * start.samples_done as u64),
            Budget::Time(t) => ProgressLines::new(t.as_millis() as u64, 0),
        });
        let progress = |n: u64| {
            if matches!(self.budget, Budget::Spp(_)) {
                bar.inc(n);
                if let Some(lines) = &lines {
                    lines.add(n);
                }
            }
        };
        let mut error_rows = String::new();
        if self.reference.is_some() {
            error_rows += "seconds,spp,rmse,psnr,ssim\n";
        }
        let mut measuring = Duration::ZERO;
        let mut after_pass = |film: &renderer::film::Film, elapsed: Duration| {
            if let Some(reference) = &self.reference {
                let start = Instant::now();
                let e = ImageError::between(&film.mean(), reference, width as usize, height as usize, |img| {
                    display_values(img, self.tone_map, self.args.exposure)
                });
                let spp = film.total_samples() as f64 / pixels as f64;
                let seconds = (elapsed - measuring).as_secs_f64();
                error_rows += &format!("{seconds:.6},{spp},{:.8e},{:.4},{:.6}\n", e.rmse, e.psnr, e.ssim);
                measuring += start.elapsed();
            }
            if matches!(self.budget, Budget::Time(_)) {
                if let Some(lines) = &lines {
                    lines.set(elapsed.as_millis() as u64);
                }
                bar.set_position(elapsed.as_millis() as u64);
                bar.set_message(format!("{:.1} spp", film.total_samples() as f64 / pixels as f64));
            }
        };
        let mut at_boundary = |state: &RenderState, interrupted: bool| {
            if let Some(c) = &self.checkpoint {
                if !c.at_boundary(frame, state, interrupted) {
                    // Stop: the failure is reported below.
                    self.cancel.store(true, Ordering::Relaxed);
                }
            }
        };
        let (film, stats) = self.pool.install(|| {
            let monitor = Monitor { cancel: &self.cancel, progress: &progress, after_pass: &mut after_pass };
            renderer.continue_region(start, self.budget, monitor, &mut at_boundary)
        });
        bar.finish_and_clear();
        if let Some(c) = &self.checkpoint {
            if let Some(e) = c.take_failure() {
                return Err(e.into());
            }
            if stats.interrupted {
                return Err(checkpoint::Interrupted(format!(
                    "interrupted: checkpoint written to {}; run the same command again to resume",
                    c.path.display()
                ))
                .into());
            }
        }
        Ok((film, stats, error_rows))
    }
}

/// One line summing up a render.
fn summary(stats: &RenderStats) -> String {
    let r = stats.region;
    let size = if r == Region::whole(stats.width, stats.height) {
        format!("{}x{}", stats.width, stats.height)
    } else {
        format!("region {r} ({}x{}) of {}x{}", r.width(), r.height(), stats.width, stats.height)
    };
    format!(
        "{size} {:.1} spp in {:.2} s: {:.3} M samples/s, {:.2} M rays/s{}",
        stats.spp,
        stats.wall_seconds,
        stats.samples_per_second * 1e-6,
        stats.rays_per_second * 1e-6,
        if stats.discarded_samples > 0 {
            format!(", {} NaN/Inf samples discarded", stats.discarded_samples)
        } else {
            String::new()
        }
    )
}

fn run(args: Args) -> Result<()> {
    if args.sweep.is_none() && ImageFormat::from_path(&args.output).is_none() {
        bail!(
            "invalid value for --output: {}: unsupported image extension (use .exr or .png)",
            args.output.display()
        );
    }
    if (args.region.is_some() || args.tile.is_some()) && ImageFormat::from_path(&args.output) != Some(ImageFormat::Exr) {
        bail!(
            "invalid value for --output: {}: a part of an image (--region, --tile) is written as .exr, which records where it lies",
            args.output.display()
        );
    }
    if args.sweep.is_some() && args.output.is_file() {
        bail!("invalid value for --output: {}: --sweep writes a directory of frames, and this is a file", args.output.display());
    }
    let load_start = Instant::now();
    let latents = LatentLibrary::load(&args.material)?;
    let mut description = SceneDescription::load(&args.scene)?;
    if args.flatten_instances {
        description = description.flatten_instances()?;
    }
    let geometry_counts = (description.geometry.triangle_count(), description.triangle_instance_count(), description.instances.len());
    for warning in &description.warnings {
        eprintln!("warning: {warning}");
    }
    renderer::material::bind_scene(&mut description, &args.bind, &latents)?;
    let aspect = args.resolution.map(|(w, h)| w as f32 / h as f32);
    let camera = description.camera_or_default(args.camera.as_deref(), aspect)?;
    let (width, height) = args.resolution.unwrap_or_else(|| {
        let aspect = camera.aspect_ratio.filter(|a| a.is_finite() && *a > 0.0).unwrap_or(1.0);
        (512, ((512.0 / aspect).round() as u32).clamp(1, renderer::support::MAX_RESOLUTION))
    });
    let region = match (args.region, args.tile) {
        (Some(r), _) if !r.is_within(width, height) => bail!("invalid value for --region: {r} lies outside the {width}x{height} image"),
        (Some(r), _) => r,
        (None, Some((k, n))) => Region::band(width, height, k, n).with_context(|| {
            format!(
                "invalid value for --tile: {k}/{n}: the {width}x{height} image has {} rows of {} pixels to share out",
                height.div_ceil(renderer::film::TILE_SIZE),
                renderer::film::TILE_SIZE
            )
        })?,
        (None, None) => Region::whole(width, height),
    };
    let reference = match &args.reference {
        Some(path) => {
            let (w, h, pixels) = renderer::formats::image_io::read_image(path)?;
            if (w, h) != (width, height) {
                bail!("{}: reference is {w}x{h} but the render is {width}x{height}", path.display());
            }
            Some(pixels)
        }
        None => None,
    };
    let parse_seconds = load_start.elapsed().as_secs_f64();

    let cancel = Arc::new(AtomicBool::new(false));
    {
        let cancel = cancel.clone();
        ctrlc::set_handler(move || cancel.store(true, Ordering::Relaxed)).context("cannot install the Ctrl-C handler")?;
    }
    if args.checkpoint.is_some() {
        checkpoint::cancel_on_sigterm(&cancel)?;
    }
    let mut job = Job {
        args: &args,
        camera,
        width,
        height,
        region,
        budget: match (args.spp, args.time) {
            (_, Some(t)) => Budget::Time(Duration::from_secs_f64(t)),
            (Some(spp), None) => Budget::Spp(spp),
            (None, None) => Budget::Spp(64),
        },
        tone_map: args.tonemap.into(),
        reference,
        cancel,
        pool: rayon::ThreadPoolBuilder::new()
            .num_threads(args.threads)
            .build()
            .context("cannot start the worker threads")?,
        checkpoint: None,
    };
    if let Some(path) = &args.checkpoint {
        let settings = checkpoint::settings(&args, &job)?;
        let every = Duration::from_secs_f64(args.checkpoint_every);
        job.checkpoint = Some(checkpoint::Checkpointing::open(path, every, settings, width, height, region, job.budget)?);
    }
    // After the checks above, so that a refused checkpoint costs no preparation.
    let prepare_start = Instant::now();
    let mut scene = RenderScene::with_latents(description, &latents)?;
    for (material, latent) in scene.materials.unbound_neural() {
        eprintln!("note: material '{material}' binds latent '{latent}' but no --material file was given: rendering its glTF parameters");
    }
    let load_seconds = parse_seconds + prepare_start.elapsed().as_secs_f64();
    if let Some(sweep) = &args.sweep {
        sweep::run(&job, &mut scene, &latents, sweep)?;
        if let Some(c) = &job.checkpoint {
            c.finish()?;
        }
        return Ok(());
    }

    let (film, stats, error_rows) = job.render(&scene, None)?;
    if let Some(path) = &args.error_log {
        renderer::formats::image_io::write_text(path, &error_rows)?;
    }
    if region == Region::whole(width, height) {
        write_image(&args.output, width, height, &film.mean(), job.tone_map, args.exposure)?;
    } else if stats.interrupted {
        // A farm task must not look done: a part with fewer samples would not merge.
        bail!("interrupted: {} not written (a part must have all its samples)", args.output.display());
    } else {
        parts::write_part(&args, &job, &film)?;
    }
    if let Some(c) = &job.checkpoint {
        c.finish()?;
    }
    if let Some(path) = &args.stats {
        let json = serde_json::to_string_pretty(&StatsFile {
            scene: &args.scene,
            parse_seconds,
            prepare_seconds: load_seconds - parse_seconds,
            load_seconds,
            stored_triangles: geometry_counts.0,
            triangle_instances: geometry_counts.1,
            instances: geometry_counts.2,
            clamped_bsdf_values: scene.materials.clamped_bsdf_values(),
            materials: scene.materials.stats(),
            render: &stats,
        })?;
        renderer::formats::image_io::write_text(path, &(json + "\n"))?;
    }
    if stats.interrupted {
        eprintln!("interrupted: wrote {} with {:.1} spp", args.output.display(), stats.spp);
    }
    eprintln!("{}", summary(&stats));
    Ok(())
}

/// Parses the command line; a usage error becomes one line (clap's message up to its usage
/// section) and exit code 2.
fn parse_args() -> Result<Args, ExitCode> {
    Args::try_parse().map_err(clap_exit)
}

/// Prints help or version (exit code 0) or a usage error as one line (exit code 2).
fn clap_exit(e: clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
        let _ = e.print();
        return ExitCode::SUCCESS;
    }
    let text = e.render().to_string();
    let message: Vec<&str> = text
        .lines()
        .map(str::trim)
        .take_while(|l| !l.is_empty() && !l.starts_with("Usage:"))
        .collect();
    eprintln!("{}", message.join(" "));
    ExitCode::from(2)
}

/// `render report CONFIG.toml`: the error-against-time report ([`renderer::report`]).
#[derive(Parser, Debug)]
#[command(name = "render report", about = "Error against render time of several material representations")]
struct ReportArgs {
    /// Report configuration (TOML; see the renderer::report documentation and docs/report/).
    config: PathBuf,
}

fn run_report(args: ReportArgs) -> Result<()> {
    let config = report::ReportConfig::read(&args.config)?;
    let cancel = Arc::new(AtomicBool::new(false));
    {
        let cancel = cancel.clone();
        ctrlc::set_handler(move || cancel.store(true, Ordering::Relaxed)).context("cannot install the Ctrl-C handler")?;
    }
    let bar = ProgressBar::new(1000).with_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {percent}% eta {eta} {msg}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    let progress = |message: &str, fraction: f64| {
        if message.starts_with("note:") {
            bar.suspend(|| eprintln!("{message}"));
        } else {
            bar.set_message(message.to_string());
        }
        bar.set_position((fraction * 1000.0) as u64);
    };
    let curves = report::run(&config, &cancel, &progress)?;
    bar.finish_and_clear();
    for c in &curves {
        let last = c.points.last();
        eprintln!(
            "{} / {}: {:.1} spp in {:.1} s, error {:.4}, floor {}",
            c.material,
            c.representation,
            last.map_or(0.0, |p| p.spp),
            last.map_or(0.0, |p| p.seconds),
            last.map_or(f64::NAN, |p| p.display_rmse()),
            c.floor.map_or("–".to_string(), |f| format!("{f:.4}"))
        );
    }
    eprintln!("wrote errors.csv, error-vs-time.png and report.md to {}", config.output.display());
    Ok(())
}

/// `render codes FILE...`: the latent codes of latent files, for pickers (the Blender add-on).
#[derive(Parser, Debug)]
#[command(name = "render codes", about = "List the latent codes of latent files: one name a line, in file order, each once")]
struct CodesArgs {
    /// Latent files (latent.bin).
    #[arg(required = true)]
    files: Vec<PathBuf>,
}

fn run_codes(args: CodesArgs) -> Result<()> {
    let names = LatentLibrary::load(&args.files)?.names();
    print!("{}", names.iter().map(|n| format!("{n}\n")).collect::<String>());
    Ok(())
}

fn main() -> ExitCode {
    renderer::support::exit_quietly_on_broken_pipe();
    if let Err(e) = renderer::support::cpu::check_build_features() {
        eprintln!("error: {e}");
        return ExitCode::from(2);
    }
    let subcommand = std::env::args_os().nth(1);
    let outcome = if subcommand.as_ref().is_some_and(|a| a == "report") {
        match ReportArgs::try_parse_from(std::env::args_os().skip(1)).map_err(clap_exit) {
            Ok(args) => run_report(args),
            Err(code) => return code,
        }
    } else if subcommand.as_ref().is_some_and(|a| a == "energy") {
        match energy::EnergyArgs::try_parse_from(std::env::args_os().skip(1)).map_err(clap_exit) {
            Ok(args) => energy::run(args),
            Err(code) => return code,
        }
    } else if subcommand.as_ref().is_some_and(|a| a == "codes") {
        match CodesArgs::try_parse_from(std::env::args_os().skip(1)).map_err(clap_exit) {
            Ok(args) => run_codes(args),
            Err(code) => return code,
        }
    } else if subcommand.as_ref().is_some_and(|a| a == "merge") {
        match parts::MergeArgs::try_parse_from(std::env::args_os().skip(1)).map_err(clap_exit) {
            Ok(args) => parts::run_merge(args),
            Err(code) => return code,
        }
    } else {
        match parse_args() {
            Ok(args) => run(args),
            Err(code) => return code,
        }
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is::<checkpoint::Interrupted>() => {
            eprintln!("{e}");
            ExitCode::from(checkpoint::INTERRUPTED_EXIT)
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}
