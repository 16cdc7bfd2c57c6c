//! The `render` binary end to end: a good render writes its image and statistics; every kind
//! of bad input gives a one-line error naming the file or flag, exit code 2, no panic, and
//! no output file.

use crate::common::{assert_clean_failure, cornell_box, render, write};
use std::path::Path;
use std::process::Command;

/// A minimal glTF with one triangle whose JSON can be altered per test.
fn gltf_with(positions: [f32; 9], mode: u32) -> String {
    let bytes: Vec<u8> = positions.iter().flat_map(|f| f.to_le_bytes()).collect();
    let b64 = base64_encode(&bytes);
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"mode":{mode}}}]}}],
"buffers":[{{"byteLength":36,"uri":"data:application/octet-stream;base64,{b64}"}}],
"bufferViews":[{{"buffer":0,"byteLength":36}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[-1,-1,-1],"max":[1,1,1]}}]}}"#
    )
}

fn base64_encode(bytes: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            if i <= c.len() {
                s.push(T[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

#[test]
fn renders_png_and_stats() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = cornell_box();
    let out = render(
        &[scene.to_str().expect("utf-8"), "--spp", "2", "--resolution", "24x16", "--output", "img.png", "--stats", "s.json", "--threads", "2"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let img = std::fs::read(dir.path().join("img.png")).expect("png written");
    assert_eq!(&img[1..4], b"PNG");
    let stats: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("s.json")).expect("stats")).expect("json");
    assert_eq!(stats["spp"], 2.0);
    assert_eq!(stats["width"], 24);
    assert!(stats["samples_per_second"].as_f64().expect("number") > 0.0);
    assert_eq!(stats["discarded_samples"], 0);
}

#[test]
fn bad_flags_and_files_fail_cleanly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let scene = cornell_box();
    let scene = scene.to_str().expect("utf-8");
    let cases: Vec<(Vec<String>, Vec<&str>)> = vec![
        (vec!["missing.gltf".into()], vec!["missing.gltf"]),
        (vec![write(d, "malformed.gltf", "{ not json")], vec!["malformed.gltf"]),
        (vec![write(d, "lines.gltf", &gltf_with([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], 1))], vec!["lines.gltf", "primitive mode"]),
        (vec![write(d, "points.gltf", &gltf_with([0.0; 9], 0))], vec!["points.gltf"]),
        (vec![write(d, "nan.gltf", &gltf_with([f32::NAN, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], 4))], vec!["nan.gltf"]),
        (vec![scene.into(), "--camera".into(), "nope".into()], vec!["nope", "camera"]),
        (vec![scene.into(), "--spp".into(), "0".into()], vec!["--spp"]),
        (vec![scene.into(), "--spp".into(), "-3".into()], vec!["--spp"]),
        (vec![scene.into(), "--resolution".into(), "12".into()], vec!["--resolution"]),
        (vec![scene.into(), "--resolution".into(), "0x5".into()], vec!["--resolution"]),
        (vec![scene.into(), "--time".into(), "nan".into()], vec!["--time"]),
        (vec![scene.into(), "--max-depth".into(), "-2".into()], vec!["--max-depth"]),
        (vec![scene.into(), "--spp".into(), "4".into(), "--time".into(), "1".into()], vec!["--time"]),
        (vec![scene.into(), "--bind".into(), "nomaterial".into()], vec!["--bind"]),
        (vec![scene.into(), "--threads".into(), "-1".into()], vec!["--threads"]),
        (vec![], vec!["SCENE"]),
        (vec![scene.into(), "--bind".into(), "nosuch=merl:x.binary".into()], vec!["nosuch", "white"]),
        (vec![scene.into(), "--output".into(), "out.bmp".into()], vec!["out.bmp", "--output"]),
    ];
    for (args, needles) in cases {
        let mut args: Vec<&str> = args.iter().map(String::as_str).collect();
        if !args.contains(&"--output") {
            args.extend(["--output", "out.exr"]);
        }
        let out = render(&args, d);
        assert_clean_failure(&out, &needles, d);
    }
}

#[test]
fn zero_triangle_scene_fails_cleanly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let text = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{}]}"#;
    let path = write(dir.path(), "empty.gltf", text);
    let out = render(&[&path, "--output", "out.exr"], dir.path());
    assert_clean_failure(&out, &["empty.gltf", "no triangles"], dir.path());
}

/// Ctrl-C (SIGINT) stops the render and writes the image rendered so far, with the
/// statistics saying it was interrupted.
#[cfg(unix)]
#[test]
fn interrupt_writes_the_image_so_far() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = cornell_box();
    let mut child = Command::new(env!("CARGO_BIN_EXE_render"))
        .args([scene.to_str().expect("utf-8"), "--spp", "100000", "--resolution", "64x64", "--output", "partial.exr", "--stats", "s.json"])
        .current_dir(dir.path())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("start render");
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().expect("kill");
    assert!(status.success());
    let exit = child.wait().expect("wait");
    assert!(exit.success(), "{exit:?}");
    assert!(dir.path().join("partial.exr").exists());
    let stats: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("s.json")).expect("stats")).expect("json");
    assert_eq!(stats["interrupted"], true);
    let spp = stats["spp"].as_f64().expect("spp");
    assert!(spp > 0.0 && spp < 100000.0, "{spp}");
}

/// `--reference` + `--error-log` write one CSV row per pass; the error falls as samples
/// accumulate; a reference of another size is a clean error.
#[test]
fn error_log_against_a_reference() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = cornell_box();
    let scene = scene.to_str().expect("utf-8");
    let ok = |args: &[&str]| {
        let out = render(args, dir.path());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    };
    ok(&[scene, "--spp", "256", "--resolution", "32x32", "--output", "ref.exr", "--seed", "1"]);
    ok(&[scene, "--spp", "64", "--resolution", "32x32", "--output", "img.exr", "--reference", "ref.exr", "--error-log", "log.csv"]);
    let log = std::fs::read_to_string(dir.path().join("log.csv")).expect("log");
    let rows: Vec<Vec<f64>> = log
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().expect("number")).collect())
        .collect();
    assert!(rows.len() >= 8, "{log}");
    assert_eq!(rows.last().expect("rows")[1], 64.0);
    assert!(rows.windows(2).all(|w| w[1][0] >= w[0][0] && w[1][1] > w[0][1]), "time and spp grow: {log}");
    assert!(rows.last().expect("rows")[2] < rows[0][2], "RMSE falls: {log}");
    let out = render(&[scene, "--resolution", "16x16", "--output", "out.exr", "--reference", "ref.exr", "--error-log", "out.csv"], dir.path());
    assert_clean_failure(&out, &["ref.exr", "32x32"], dir.path());
}

/// A measured BRDF bound from the command line renders; a bad binding is a clean error.
#[test]
fn bind_measured_brdfs() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/material-preview/scene.gltf");
    let scene = scene.to_str().expect("utf-8");
    let nbrdf = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/nbrdf/merl/alum-bronze");
    let spec = format!("preview=nbrdf:{}", nbrdf.display());
    let out = render(&[scene, "--bind", &spec, "--spp", "2", "--resolution", "16x16", "--output", "bound.exr"], dir.path());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(dir.path().join("bound.exr").exists());
    for (spec, needles) in [
        ("preview=merl:missing.binary", vec!["missing.binary"]),
        ("preview=tabulated:x", vec!["tabulated:x"]),
        ("preview=nbrdf:nowhere/alum-bronze", vec!["nowhere"]),
    ] {
        let out = render(&[scene, "--bind", spec, "--output", "out.exr"], dir.path());
        assert_clean_failure(&out, &needles, dir.path());
    }
}

/// A scene using a glTF extension the renderer does not support renders, with one warning
/// naming it; one requiring it fails with a one-line error and writes nothing.
#[test]
fn unsupported_gltf_extensions_warn_or_fail() {
    let dir = tempfile::tempdir().expect("tempdir");
    let positions = [-1.0, -1.0, -3.0, 1.0, -1.0, -3.0, 0.0, 1.0, -3.0];
    let used = gltf_with(positions, 4).replacen('{', r#"{"extensionsUsed":["KHR_materials_anisotropy"],"#, 1);
    let scene = write(dir.path(), "used.gltf", &used);
    let out = render(&[&scene, "--spp", "1", "--resolution", "8x8", "--output", "used.png"], dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stderr.matches("warning:").count(), 1, "{stderr}");
    assert!(stderr.contains("KHR_materials_anisotropy is not supported"), "{stderr}");
    assert!(dir.path().join("used.png").is_file());

    let required = used.replacen('{', r#"{"extensionsRequired":["KHR_materials_anisotropy"],"#, 1);
    let scene = write(dir.path(), "required.gltf", &required);
    let out = render(&[&scene, "--spp", "1", "--resolution", "8x8", "--output", "required.png"], dir.path());
    assert_clean_failure(&out, &["required.gltf", "requires the glTF extension KHR_materials_anisotropy"], dir.path());
    assert!(!dir.path().join("required.png").exists());
}
