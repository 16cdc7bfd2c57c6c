//! The Open Job Description templates of `farm/` run as a scheduler would run them: each task
//! a separate `render` process started by the OpenJD runtime (`openjd run`, the reference
//! implementation AWS Deadline Cloud's workers use; `.ci/run` installs it), and the result
//! equals the same render done in one process.

use crate::common::{render, repo_file};
use renderer::formats::image_io::read_image;
use std::path::Path;
use std::process::Command;

/// Runs `step` of `template` (with the steps it depends on) through `openjd run`; returns
/// its log.
fn openjd_run(template: &str, step: &str, params: &[(&str, String)], dir: &Path) -> String {
    let mut command = Command::new("openjd");
    command.arg("run").arg(repo_file(&format!("farm/{template}/template.yaml"))).args(["--step", step, "--run-dependencies"]);
    command.args(["-p", &format!("RenderCommand={}", env!("CARGO_BIN_EXE_render"))]);
    for (name, value) in params {
        command.args(["-p", &format!("{name}={value}")]);
    }
    let out = command.current_dir(dir).output().expect("run openjd (pip install openjd-cli; see .ci/run)");
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "openjd run {template} --step {step} failed:\n{log}\n{}", String::from_utf8_lossy(&out.stderr));
    log.into_owned()
}

fn path(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

fn pixels(p: &Path) -> Vec<renderer::Rgb> {
    read_image(p).unwrap_or_else(|e| panic!("{e}")).2
}

#[test]
fn tiled_still_template_merges_to_the_whole_render() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (scene, latents) = (repo_file("scenes/material-preview/scene.gltf"), repo_file("scenes/materials/latent.bin"));
    let out = dir.path().join("job");
    let params = [
        ("Scene", path(&scene)),
        ("Material", path(&latents)),
        ("OutputDir", path(&out)),
        ("OutputName", "still.exr".to_string()),
        ("Resolution", "45x37".to_string()),
        ("Spp", "3".to_string()),
        ("Seed", "4".to_string()),
        ("Tiles", "3".to_string()),
    ];
    openjd_run("tiled-still", "Merge", &params, dir.path());
    for k in 1..=3 {
        assert!(out.join(format!("parts/band-{k}.exr")).is_file(), "band {k} written by its own task");
    }
    let whole = render(
        &[&path(&scene), "--material", &path(&latents), "--resolution", "45x37", "--spp", "3", "--seed", "4", "--output", "whole.exr"],
        dir.path(),
    );
    assert!(whole.status.success(), "{}", String::from_utf8_lossy(&whole.stderr));
    let expected = pixels(&dir.path().join("whole.exr"));
    assert!(expected.iter().any(|p| p.max_element() > 0.0));
    assert!(pixels(&out.join("still.exr")) == expected, "the merged job output differs from the whole render");
}

#[test]
fn sweep_template_renders_chunks_that_make_the_whole_sweep() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (scene, latents) = (repo_file("scenes/material-preview/scene.gltf"), repo_file("scenes/materials/latent.bin"));
    let out = dir.path().join("job");
    let params = [
        ("Scene", path(&scene)),
        ("Material", path(&latents)),
        ("Bind", "preview=alum-bronze".to_string()),
        ("From", "alum-bronze".to_string()),
        ("To", "chrome".to_string()),
        ("Steps", "5".to_string()),
        ("Frames", "0-4".to_string()),
        // Chunks 0-1, 2-3 and 4: the contact sheet waits for the last.
        ("FramesPerTask", "2".to_string()),
        ("OutputDir", path(&out)),
        ("Resolution", "24x20".to_string()),
        ("Spp", "2".to_string()),
    ];
    openjd_run("material-sweep", "RenderFrames", &params, dir.path());
    let whole = render(
        &[
            &path(&scene), "--material", &path(&latents), "--bind", "preview=alum-bronze", "--sweep", "alum-bronze:chrome:5",
            "--resolution", "24x20", "--spp", "2", "--output", "whole",
        ],
        dir.path(),
    );
    assert!(whole.status.success(), "{}", String::from_utf8_lossy(&whole.stderr));
    let expected = dir.path().join("whole");
    for k in 0..5 {
        let name = format!("frame-{k:03}.exr");
        assert!(pixels(&out.join(&name)) == pixels(&expected.join(&name)), "{name}");
    }
    let sheet = |d: &Path| std::fs::read(d.join("contact-sheet.png")).expect("contact sheet");
    assert!(sheet(&out) == sheet(&expected), "the chunked sweep's contact sheet differs");
}

/// A task of the tiled-still job stopped mid-way (the OpenJD runtime interrupted: it cancels
/// the task with SIGTERM, as a farm does when it preempts or requeues one) leaves its
/// checkpoint; the job run again resumes that band from it, and the merged image still equals
/// the whole render.
#[cfg(unix)]
#[test]
fn an_interrupted_tile_task_resumes_from_its_checkpoint() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (scene, latents) = (repo_file("scenes/material-preview/scene.gltf"), repo_file("scenes/materials/latent.bin"));
    let out = dir.path().join("job");
    let params = [
        ("Scene", path(&scene)),
        ("Material", path(&latents)),
        ("OutputDir", path(&out)),
        ("OutputName", "still.exr".to_string()),
        ("Resolution", "64x64".to_string()),
        ("Spp", "512".to_string()),
        ("Seed", "2".to_string()),
        ("Tiles", "2".to_string()),
        ("CheckpointEvery", "0".to_string()),
    ];
    let mut command = Command::new("openjd");
    command.arg("run").arg(repo_file("farm/tiled-still/template.yaml")).args(["--step", "RenderTiles", "--task-param", "Tile=1"]);
    command.args(["-p", &format!("RenderCommand={}", env!("CARGO_BIN_EXE_render"))]);
    for (name, value) in &params {
        command.args(["-p", &format!("{name}={value}")]);
    }
    let mut child = command
        .current_dir(dir.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run openjd (pip install openjd-cli; see .ci/run)");
    let checkpoint = out.join("checkpoints/band-1-of-2.ckpt");
    let start = std::time::Instant::now();
    while !checkpoint.exists() {
        assert!(child.try_wait().expect("wait").is_none(), "the task ended before its first checkpoint");
        assert!(start.elapsed().as_secs() < 600, "no checkpoint after 600 s (a guard against hanging only)");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().expect("kill");
    assert!(status.success());
    let interrupted = child.wait_with_output().expect("wait");
    let log = String::from_utf8_lossy(&interrupted.stdout);
    assert!(!interrupted.status.success(), "{log}");
    assert!(log.contains("exited with code: 75") && log.contains("interrupted: checkpoint written"), "{log}");
    assert!(checkpoint.is_file() && !out.join("parts/band-1.exr").exists(), "a checkpoint, no part");

    let log = openjd_run("tiled-still", "Merge", &params, dir.path());
    assert!(log.contains("resuming from"), "{log}");
    assert!(!checkpoint.exists(), "the checkpoint is removed once the part is written");
    let whole = render(
        &[&path(&scene), "--material", &path(&latents), "--resolution", "64x64", "--spp", "512", "--seed", "2", "--output", "whole.exr"],
        dir.path(),
    );
    assert!(whole.status.success(), "{}", String::from_utf8_lossy(&whole.stderr));
    assert!(pixels(&out.join("still.exr")) == pixels(&dir.path().join("whole.exr")), "the resumed job's image differs from the whole render");
}
