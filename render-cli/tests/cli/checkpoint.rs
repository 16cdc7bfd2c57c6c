//! `render --checkpoint`: renders killed (SIGKILL) or stopped (SIGTERM, Ctrl-C) part-way
//! and started again end with the uninterrupted render's image bit for bit; checkpoints of
//! other settings, truncated or corrupted ones are refused with one line naming the file.

#![cfg(unix)]

use crate::common::{assert_clean_failure, cornell_box, render, repo_file};
use renderer::formats::image_io::read_image;
use renderer::formats::image_part::ImagePart;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Exit code of a render stopped after writing its checkpoint.
const INTERRUPTED: i32 = 75;

fn scene() -> String {
    cornell_box().to_string_lossy().into_owned()
}

/// The settings of the renders compared: a few seconds of work on one thread.
fn base(scene: &str) -> Vec<String> {
    [scene, "--spp", "384", "--resolution", "96x96", "--seed", "7", "--max-depth", "6"].iter().map(|s| s.to_string()).collect()
}

fn with(args: &[String], extra: &[&str]) -> Vec<String> {
    args.iter().cloned().chain(extra.iter().map(|s| s.to_string())).collect()
}

fn run_ok(args: &[String], dir: &Path) -> String {
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = render(&args, dir);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "render {args:?}: {stderr}");
    stderr
}

fn spawn(args: &[String], dir: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_render"))
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start render")
}

fn signal(child: &Child, name: &str) {
    let status = Command::new("kill").args([name, &child.id().to_string()]).status().expect("kill");
    assert!(status.success());
}

/// Waits until `path` exists (the first checkpoint), at most 20 s.
/// How long a wait may last before the test calls the render hung: only a guard against
/// waiting for ever, far above any render here (a loaded 2-core CI machine took over 30 s to
/// write one small frame of a debug build).
const HANG: Duration = Duration::from_secs(600);

fn wait_for(path: &Path, child: &mut Child) {
    let start = Instant::now();
    while !path.exists() {
        assert!(child.try_wait().expect("wait").is_none(), "the render ended before writing {}", path.display());
        assert!(start.elapsed() < HANG, "no checkpoint {} after {HANG:?}", path.display());
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The pixels of an EXR as bits (the files' bytes may differ: the EXR writer may store its
/// compressed blocks in any order).
/// Parts (--region, --tile) as their region and pixels.
fn pixel_bits(path: &Path) -> (String, Vec<[u32; 3]>) {
    let (place, pixels) = match ImagePart::read_exr(path) {
        Ok(part) => (format!("{} of {}x{}", part.region, part.full_width, part.full_height), part.pixels),
        Err(_) => {
            let (w, h, pixels) = read_image(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            (format!("{w}x{h}"), pixels)
        }
    };
    (place, pixels.iter().map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]).collect())
}

fn bytes(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A small pseudo-random generator seeded from the clock; the delays are printed so that a
/// failure can be replayed.
struct Delays(u64);

impl Delays {
    fn next_ms(&mut self, max: u64) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0 % max
    }
}

/// Killed with SIGKILL at three random moments (each after a checkpoint was written, with
/// a checkpoint after every pass) and started again each time, the render ends with the
/// uninterrupted render's EXR byte for byte, and removes its checkpoint.
#[test]
fn killed_three_times_resumes_to_the_same_image() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = scene();
    run_ok(&with(&base(&scene), &["--output", "whole.exr"]), dir.path());
    let ckpt = dir.path().join("render.ckpt");
    let args = with(&base(&scene), &["--threads", "1", "--output", "resumed.exr", "--checkpoint", "render.ckpt", "--checkpoint-every", "0"]);
    let seed = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).expect("clock").as_nanos() as u64 | 1;
    let mut delays = Delays(seed);
    for kill in 0..3 {
        let mut child = spawn(&args, dir.path());
        wait_for(&ckpt, &mut child);
        let delay = delays.next_ms(400);
        eprintln!("kill {kill}: {delay} ms after a checkpoint exists (seed {seed})");
        std::thread::sleep(Duration::from_millis(delay));
        child.kill().expect("SIGKILL");
        let status = child.wait().expect("wait");
        assert!(status.code().is_none() || kill > 0, "killed by the signal: {status:?}");
        assert!(!dir.path().join("resumed.exr").exists(), "kill {kill}: the render finished before it was killed");
        assert!(bytes(&ckpt).starts_with(b"RNDRCKPT"), "kill {kill}: a whole checkpoint is left");
    }
    let stderr = run_ok(&args, dir.path());
    assert!(stderr.contains("resuming from"), "{stderr}");
    assert!(pixel_bits(&dir.path().join("resumed.exr")) == pixel_bits(&dir.path().join("whole.exr")), "the resumed image differs");
    assert!(!ckpt.exists(), "the checkpoint is removed once the image is written");
}

/// SIGTERM writes a checkpoint and exits with the interrupted code; started again, the render
/// resumes to the uninterrupted image. Ctrl-C does the same for a band (--tile) of the image.
#[test]
fn sigterm_and_ctrl_c_write_a_checkpoint_and_resume() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = scene();
    let ckpt = dir.path().join("term.ckpt");
    for (signal_name, extra, name) in [("-TERM", &[][..], "term"), ("-INT", &["--tile", "2/3"][..], "int")] {
        run_ok(&with(&base(&scene), &[extra, &["--output", &format!("{name}-whole.exr")]].concat()), dir.path());
        let output = format!("{name}-resumed.exr");
        let args = with(&base(&scene), &[extra, &["--threads", "1", "--output", &output, "--checkpoint", "term.ckpt"]].concat());
        let child = spawn(&args, dir.path());
        // Well before the end (a third of the image takes over 1 s on one thread of the
        // 2-core Xeon at opt-level 3) and after the signal handler is installed.
        std::thread::sleep(Duration::from_millis(400));
        assert!(!ckpt.exists(), "no checkpoint before the interval (300 s) has passed");
        signal(&child, signal_name);
        let out = child.wait_with_output().expect("wait");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(INTERRUPTED), "{signal_name}: {stderr}");
        assert!(stderr.contains("interrupted: checkpoint written to term.ckpt"), "{stderr}");
        assert!(ckpt.exists() && !dir.path().join(&output).exists(), "{signal_name}: a checkpoint, no image");
        let stderr = run_ok(&args, dir.path());
        assert!(stderr.contains("resuming from"), "{stderr}");
        assert!(pixel_bits(&dir.path().join(&output)) == pixel_bits(&dir.path().join(format!("{name}-whole.exr"))), "{signal_name}: the resumed image differs");
        assert!(!ckpt.exists());
    }
}

/// A checkpoint is refused, with exit code 2 and one line naming the file and the problem,
/// when the settings differ (samples, seed, scene), when it is truncated or a byte of it is
/// flipped, and with a time budget.
#[test]
fn checkpoints_of_other_renders_and_damaged_ones_are_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = scene();
    let args = with(&base(&scene), &["--threads", "1", "--output", "out.exr", "--checkpoint", "c.ckpt", "--checkpoint-every", "0"]);
    let ckpt = dir.path().join("c.ckpt");
    let mut child = spawn(&args, dir.path());
    wait_for(&ckpt, &mut child);
    child.kill().expect("SIGKILL");
    child.wait().expect("wait");
    let _ = std::fs::remove_file(dir.path().join("out.exr"));
    let good = bytes(&ckpt);
    let refused = |args: &[String], needles: &[&str]| {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_clean_failure(&render(&args, dir.path()), needles, dir.path());
        assert!(bytes(&ckpt) == good, "a refused checkpoint is left as it was");
    };
    let change = |flag: &str, value: &str| -> Vec<String> {
        let mut a = args.clone();
        let i = a.iter().position(|s| s == flag).expect("flag");
        a[i + 1] = value.to_string();
        a
    };
    refused(&change("--spp", "383"), &["c.ckpt", "spp is '384' there but '383' here"]);
    refused(&change("--seed", "8"), &["c.ckpt", "seed is '7' there but '8' here"]);
    refused(&change("--resolution", "96x95"), &["c.ckpt", "'0,0,96,95' here"]);
    let other_scene = repo_file("scenes/material-preview/scene.gltf").to_string_lossy().into_owned();
    refused(&[vec![other_scene], args[1..].to_vec()].concat(), &["c.ckpt", "scene"]);
    let time: Vec<String> = args.iter().filter(|a| !["--spp", "384"].contains(&a.as_str())).cloned().chain(["--time".into(), "1".into()]).collect();
    refused(&time, &["--checkpoint", "--time"]);

    std::fs::write(&ckpt, &good[..good.len() / 2]).expect("write");
    let truncated = bytes(&ckpt);
    let refused_damaged = |needles: &[&str]| {
        let argv: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_clean_failure(&render(&argv, dir.path()), needles, dir.path());
    };
    refused_damaged(&["c.ckpt", "truncated"]);
    assert!(bytes(&ckpt) == truncated);
    let mut flipped = good.clone();
    let i = good.len() - 1000;
    flipped[i] ^= 0x01;
    std::fs::write(&ckpt, &flipped).expect("write");
    refused_damaged(&["c.ckpt", "corrupted"]);
    std::fs::write(&ckpt, b"not a checkpoint").expect("write");
    refused_damaged(&["c.ckpt", "not a render checkpoint"]);

    // The intact checkpoint still resumes.
    std::fs::write(&ckpt, &good).expect("write");
    let stderr = run_ok(&args, dir.path());
    assert!(stderr.contains("resuming from"), "{stderr}");
}

/// A sweep chunk (--frames) stopped with SIGTERM mid-way and started again writes the frames
/// of the uninterrupted chunk bit for bit, skipping those written before the checkpoint.
#[test]
fn an_interrupted_sweep_chunk_resumes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = repo_file("scenes/material-preview/scene.gltf").to_string_lossy().into_owned();
    let latents = repo_file("scenes/materials/latent.bin").to_string_lossy().into_owned();
    let sweep = |out: &str, extra: &[&str]| -> Vec<String> {
        let a = [scene.as_str(), "--material", &latents, "--bind", "preview=alum-bronze", "--sweep", "alum-bronze:chrome:5", "--frames", "1-3"];
        let b = ["--spp", "160", "--resolution", "48x48", "--threads", "1", "--output", out];
        a.iter().chain(&b).chain(extra).map(|s| s.to_string()).collect()
    };
    run_ok(&sweep("whole", &[]), dir.path());
    let args = sweep("resumed", &["--checkpoint", "sweep.ckpt", "--checkpoint-every", "0"]);
    let ckpt = dir.path().join("sweep.ckpt");
    let mut child = spawn(&args, dir.path());
    // Into the second frame of the chunk.
    let start = Instant::now();
    while !dir.path().join("resumed/frame-001.exr").exists() {
        assert!(child.try_wait().expect("wait").is_none() && start.elapsed() < HANG, "frame 1 not written after {HANG:?}");
        std::thread::sleep(Duration::from_millis(5));
    }
    std::fs::remove_file(&ckpt).ok();
    wait_for(&ckpt, &mut child);
    signal(&child, "-TERM");
    let out = child.wait_with_output().expect("wait");
    assert_eq!(out.status.code(), Some(INTERRUPTED), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(!dir.path().join("resumed/frame-003.exr").exists(), "the chunk was stopped before its end");
    let stderr = run_ok(&args, dir.path());
    assert!(stderr.contains("frames 1 to 1 were written before the checkpoint") || stderr.contains("frames 1 to 2 were written"), "{stderr}");
    for k in 1..=3 {
        let name = format!("frame-{k:03}.exr");
        assert!(pixel_bits(&dir.path().join("resumed").join(&name)) == pixel_bits(&dir.path().join("whole").join(&name)), "{name} differs");
    }
    assert!(!ckpt.exists());
}
