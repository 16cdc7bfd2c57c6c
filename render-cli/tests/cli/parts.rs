//! Renders split into parts (`--region`, `--tile`) and assembled again (`render merge`):
//! the merged image equals the whole render, and parts that cannot make one image are
//! refused with one line naming the file.

use crate::common::{assert_clean_failure, render, repo_file};
use renderer::formats::image_io::read_image;
use std::path::Path;

fn scene() -> String {
    repo_file("scenes/material-preview/scene.gltf").to_string_lossy().into_owned()
}

fn run_ok<S: AsRef<str>>(args: &[S], dir: &Path) {
    let args: Vec<&str> = args.iter().map(|s| s.as_ref()).collect();
    let out = render(&args, dir);
    assert!(out.status.success(), "render {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn merged_parts_equal_the_whole_render() {
    let dir = tempfile::tempdir().expect("tempdir");
    let latents = repo_file("scenes/materials/latent.bin").to_string_lossy().into_owned();
    let scene = scene();
    let settings = |spp: &'static str, seed: &'static str, extra: &[&'static str]| -> Vec<String> {
        let base = [scene.as_str(), "--material", &latents, "--spp", spp, "--resolution", "45x37", "--seed", seed];
        base.iter().chain(extra).map(|s| s.to_string()).collect()
    };
    let with = |extra: &[&'static str]| settings("3", "9", extra);
    run_ok(&with(&["--output", "whole.exr"]), dir.path());
    // Bands of tile rows, and regions that cut through tiles.
    run_ok(&with(&["--tile", "1/2", "--output", "bands/a.exr"]), dir.path());
    run_ok(&with(&["--tile", "2/2", "--output", "bands/b.exr"]), dir.path());
    for (name, region) in [("r1.exr", "0,0,20,37"), ("r2.exr", "20,0,45,5"), ("r3.exr", "20,5,45,37")] {
        let output = format!("regions/{name}");
        let mut args = with(&["--region", region, "--output"]);
        args.push(output);
        run_ok(&args, dir.path());
    }
    run_ok(&["merge", "bands", "--output", "bands.exr"], dir.path());
    run_ok(&["merge", "regions/r3.exr", "regions/r1.exr", "regions/r2.exr", "--output", "regions.exr"], dir.path());
    let (w, h, whole) = read_image(&dir.path().join("whole.exr")).unwrap();
    assert_eq!((w, h), (45, 37));
    assert!(whole.iter().any(|p| p.max_element() > 0.0));
    for merged in ["bands.exr", "regions.exr"] {
        let (mw, mh, pixels) = read_image(&dir.path().join(merged)).unwrap();
        assert_eq!((mw, mh), (w, h), "{merged}");
        assert!(pixels == whole, "{merged} differs from the whole render");
    }
    // A PNG of the merged image.
    run_ok(&["merge", "bands", "--output", "bands.png"], dir.path());
    assert_eq!(image::open(dir.path().join("bands.png")).unwrap().width(), 45);

    // Parts that do not make one image.
    let fail = |args: &[&str], needles: &[&str]| assert_clean_failure(&render(args, dir.path()), needles, dir.path());
    fail(&["merge", "regions/r1.exr", "regions/r2.exr", "--output", "out.exr"], &["regions/r1.exr", "leave 800 of", "(20, 5)"]);
    fail(&["merge", "regions", "bands/a.exr", "--output", "out.exr"], &["bands/a.exr", "overlaps", "r1.exr"]);
    run_ok(&settings("3", "10", &["--region", "20,5,45,37", "--output", "other/r3.exr"]), dir.path());
    fail(&["merge", "regions/r1.exr", "regions/r2.exr", "other/r3.exr", "--output", "out.exr"], &["other/r3.exr", "seed is '10' here but '9'"]);
    run_ok(&settings("4", "9", &["--region", "20,5,45,37", "--output", "other/spp.exr"]), dir.path());
    fail(&["merge", "regions/r1.exr", "regions/r2.exr", "other/spp.exr", "--output", "out.exr"], &["spp is '4'"]);
    fail(&["merge", "regions/r1.exr", "whole.exr", "--output", "out.exr"], &["whole.exr", "no render settings"]);
    fail(&["merge", "regions/r1.exr", "missing.exr", "--output", "out.exr"], &["missing.exr"]);
    std::fs::create_dir(dir.path().join("empty")).unwrap();
    fail(&["merge", "empty", "--output", "out.exr"], &["empty", "no .exr parts"]);
    fail(&["merge", "bands", "--output", "out.tif"], &["out.tif", "extension"]);
}

#[test]
fn bad_regions_and_tiles_fail_cleanly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = scene();
    let cases: [(&[&str], &[&str]); 6] = [
        (&["--region", "0,0,80,10", "--resolution", "64x64"], &["--region", "outside the 64x64 image"]),
        (&["--region", "5,5,5,9"], &["--region", "X0,Y0,X1,Y1"]),
        (&["--tile", "5/5", "--resolution", "64x64"], &["--tile", "5/5", "4 rows of 16 pixels"]),
        (&["--tile", "0/3"], &["--tile", "K/N"]),
        (&["--tile", "1/2", "--time", "1"], &["--time"]),
        (&["--region", "0,0,8,8", "--tile", "1/2"], &["--tile"]),
    ];
    for (extra, needles) in cases {
        let args: Vec<&str> = [&[scene.as_str(), "--output", "out.exr"][..], extra].concat();
        assert_clean_failure(&render(&args, dir.path()), needles, dir.path());
    }
    let png = render(&[&scene, "--tile", "1/2", "--output", "out.png"], dir.path());
    assert_clean_failure(&png, &["out.png", ".exr"], dir.path());
}

/// Ctrl-C during a part's render writes no part and exits with an error, so that a farm
/// task does not look done.
#[cfg(unix)]
#[test]
fn an_interrupted_part_is_not_written() {
    let dir = tempfile::tempdir().expect("tempdir");
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_render"))
        .args([scene().as_str(), "--spp", "100000", "--resolution", "64x64", "--tile", "1/2", "--output", "part.exr"])
        .current_dir(dir.path())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start render");
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let status = std::process::Command::new("kill").args(["-INT", &child.id().to_string()]).status().expect("kill");
    assert!(status.success());
    let out = child.wait_with_output().expect("wait");
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("interrupted: part.exr not written"));
    assert!(!dir.path().join("part.exr").exists());
}
