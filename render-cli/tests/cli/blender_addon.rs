//! The Blender add-on (`plugins/blender/neural_brdf_blender`) end to end, and what `render`
//! offers it: `render codes FILE` (the codes a material can bind) and `--progress-lines`
//! (progress for Blender's progress bar).
//!
//! The add-on test starts Blender twice (`blender` on PATH; `.ci/run` installs Debian's
//! package): `plugins/blender/tests/addon_scene.py` builds a scene by script, renders it
//! through the add-on and checks the errors of Esc, a missing binary, a missing latent file,
//! an unknown code and an incomplete binding; then `blender -b scene.blend -E NEURAL_BRDF -a`,
//! with the add-on installed from the zip that `plugins/blender/make_zip.py` packs, renders
//! the saved scene's two frames from the command line. Checked here: the images equal
//! `render` run on the add-on's exported glTF bit for bit (the sphere moves in frame 2),
//! binding a code changes the bound sphere's pixels only, and a glTF exported by hand with a
//! mix of codes renders.

use crate::common::{render, repo_file};
use renderer::formats::image_io::read_image;
use std::path::Path;
use std::process::{Command, Output};

fn path(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

/// Asserts a failed run: exit code 2 and one `error:` line on stderr holding `needle`.
fn assert_one_line_error(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert!(lines.len() == 1 && lines[0].starts_with("error:") && lines[0].contains(needle), "{stderr}");
    assert!(out.stdout.is_empty(), "{}", String::from_utf8_lossy(&out.stdout));
}

fn pixels(p: &Path) -> (u32, u32, Vec<renderer::Rgb>) {
    read_image(p).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn codes_lists_a_latent_files_codes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let latents = repo_file("scenes/materials/latent.bin");
    let out = render(&["codes", &path(&latents)], dir.path());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let names: Vec<String> = String::from_utf8_lossy(&out.stdout).lines().map(str::to_string).collect();
    let library = renderer::neural::latent_library::LatentLibrary::load(&[&latents]).expect("latent file");
    assert_eq!(names, library.names());
    assert!(names.iter().any(|n| n == "alum-bronze"), "{names:?}");

    assert_one_line_error(&render(&["codes", "missing.bin"], dir.path()), "missing.bin");
    std::fs::write(dir.path().join("bad.bin"), b"not a latent file").expect("write");
    assert_one_line_error(&render(&["codes", "bad.bin"], dir.path()), "bad.bin");
    assert_one_line_error(&render(&["codes"], dir.path()), "FILES");
}

#[test]
fn progress_lines_count_up_to_one() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = render(
        &[&path(&repo_file("scenes/cornell-box/scene.gltf")), "--resolution", "40x24", "--spp", "3", "--progress-lines", "--output", "out.exr"],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let fractions: Vec<f64> = stderr
        .lines()
        .filter_map(|l| l.strip_prefix("progress "))
        .map(|f| f.parse().unwrap_or_else(|_| panic!("not a fraction: {f}")))
        .collect();
    assert!(fractions.len() >= 2, "{stderr}");
    assert!(fractions.windows(2).all(|w| w[0] < w[1]), "not increasing: {fractions:?}");
    assert_eq!(fractions.last(), Some(&1.0), "{stderr}");
    assert!(!stderr.contains('\r') && !stderr.contains('\u{1b}'), "a bar was drawn: {stderr:?}");
}

/// Runs a Blender command in `dir`; panics with its output when it fails.
fn blender(command: &mut Command, dir: &Path) -> Output {
    let out = command
        .current_dir(dir)
        .output()
        .expect("run blender (Blender 3.4 or later on PATH: apt-get install blender python3-numpy; see .ci/run)");
    assert!(
        out.status.success(),
        "{command:?} failed ({}):\n{}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

#[test]
fn blender_addon_renders_like_render_on_its_export() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("out");
    let (binary, latents) = (env!("CARGO_BIN_EXE_render"), path(&repo_file("scenes/materials/latent.bin")));
    let plugins = repo_file("plugins/blender");
    let script = path(&plugins.join("tests/addon_scene.py"));
    blender(
        Command::new("blender").args([
            "-b", "--factory-startup", "--python-exit-code", "1", "--python", &script, "--", binary, &latents, &path(&out),
        ]),
        dir.path(),
    );
    // The second run installs the add-on as a user would, from the zip of make_zip.py, into
    // a user scripts directory of its own.
    let zip = dir.path().join("neural_brdf_blender.zip");
    let made = Command::new("python3").arg(plugins.join("make_zip.py")).arg(&zip).output().expect("run python3");
    assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
    let install = format!(
        "import bpy, addon_utils; bpy.ops.preferences.addon_install(filepath={:?}); \
         addon_utils.enable('neural_brdf_blender', default_set=True, handle_error=None)",
        path(&zip)
    );
    let blend = path(&out.join("scene.blend"));
    let mut command = Command::new("blender");
    command.env("BLENDER_USER_SCRIPTS", dir.path().join("user-scripts"));
    blender(
        command.args(["-b", "--factory-startup", &blend, "--python-expr", &install, "-E", "NEURAL_BRDF", "-a"]),
        dir.path(),
    );
    assert!(dir.path().join("user-scripts/addons/neural_brdf_blender/__init__.py").is_file(), "not installed from the zip");

    // `render` on an export of the add-on with the scene's settings (addon_scene.py's).
    let render_export = |export: &str, output: &str| {
        let gltf = path(&out.join(export).join("scene.gltf"));
        let settings = ["--resolution", "64x48", "--spp", "4", "--max-depth", "2", "--seed", "7"];
        let run = render(&[&[gltf.as_str(), "--material", &latents, "--output", output][..], &settings[..]].concat(), dir.path());
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        pixels(&dir.path().join(output))
    };
    let (w, h, expected) = render_export("bound-export", "direct.exr");
    assert_eq!((w, h), (64, 48));
    for image in ["bound.exr", "frame-0001.exr"] {
        let (iw, ih, through_blender) = pixels(&out.join(image));
        assert_eq!((iw, ih), (w, h), "{image}");
        assert!(through_blender == expected, "{image} differs from render on the add-on's glTF");
    }

    // The animation's frame 2 (the sphere moved) equals `render` on its export, kept in
    // frame-export/ (the last frame's).
    let (_, _, frame2) = pixels(&out.join("frame-0002.exr"));
    assert!(frame2 == render_export("frame-export", "moved.exr").2, "frame 2 differs from render on its export");
    assert!(frame2 != expected, "the sphere did not move in frame 2");

    // Binding the code changes the sphere's pixels and nothing else (direct light only).
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).expect("results.json")).expect("JSON");
    let b: Vec<usize> = results["metal_box"].as_array().expect("box").iter().map(|v| v.as_u64().expect("int") as usize).collect();
    assert!(b[2] - b[0] < 40 && b[3] - b[1] < 36, "the sphere fills the image: {b:?}");
    let (_, _, unbound) = pixels(&out.join("unbound.exr"));
    let (mut inside, mut changed) = (0, 0);
    for (i, (p, q)) in expected.iter().zip(&unbound).enumerate() {
        let (x, y) = (i % w as usize, i / w as usize);
        if (b[0]..b[2]).contains(&x) && (b[1]..b[3]).contains(&y) {
            inside += 1;
            changed += usize::from(p != q);
        } else {
            assert!(p == q, "pixel ({x}, {y}) outside the sphere's box {b:?} changed: {p:?} / {q:?}");
        }
    }
    assert!(changed * 3 > inside, "only {changed} of the {inside} pixels of the sphere's box changed");

    // A glTF exported by hand with a mix of two codes and a Lambertian ground renders.
    let mixed = render(
        &[&path(&out.join("mix.gltf")), "--material", &latents, "--resolution", "16x12", "--spp", "1", "--output", "mix.exr"],
        dir.path(),
    );
    let stderr = String::from_utf8_lossy(&mixed.stderr);
    assert!(mixed.status.success() && !stderr.contains("warning"), "{stderr}");
}
