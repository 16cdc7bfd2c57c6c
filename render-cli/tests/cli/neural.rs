//! `render --material latent.bin`: binding latent codes (extras, equal names, `--bind`),
//! editing sweeps, and clean errors for bad latent files and names.

use crate::common::{assert_clean_failure, render, repo_file};
use renderer::formats::merl::MerlTable;
use renderer::neural::nbrdf::NbrdfNetwork;
use std::path::Path;

fn shipped_latents() -> String {
    repo_file("scenes/materials/latent.bin").to_string_lossy().into_owned()
}

fn preview_scene() -> String {
    repo_file("scenes/material-preview/scene.gltf").to_string_lossy().into_owned()
}

fn mean_of(path: &Path) -> f32 {
    let (_, _, pixels) = renderer::formats::image_io::read_image(path).expect("image");
    pixels.iter().map(|p| p.x + p.y + p.z).sum::<f32>() / pixels.len() as f32
}

#[test]
fn binds_by_flag_and_by_equal_name() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (latents, scene) = (shipped_latents(), preview_scene());
    let base = ["--spp", "2", "--resolution", "24x24"];
    let run = |extra: &[&str]| {
        let mut args: Vec<&str> = vec![&scene];
        args.extend(base);
        args.extend(extra);
        let out = render(&args, dir.path());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    };
    run(&["--material", &latents, "--bind", "preview=alum-bronze", "--output", "flag.exr", "--stats", "s.json"]);
    let stats: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("s.json")).unwrap()).unwrap();
    assert!(stats["clamped_bsdf_values"].is_u64(), "{stats}");
    // The scene's extras bind the preview to alum-bronze; without a latent file it renders
    // its glTF parameters and says so.
    run(&["--material", &latents, "--output", "extras.exr"]);
    let out = render(&[&scene, "--spp", "2", "--resolution", "24x24", "--output", "plain.exr"], dir.path());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && stderr.contains("note: material 'preview' binds latent 'alum-bronze'"), "{stderr}");
    let (flag, extras, plain) = (mean_of(&dir.path().join("flag.exr")), mean_of(&dir.path().join("extras.exr")), mean_of(&dir.path().join("plain.exr")));
    assert_eq!(flag, extras);
    assert_ne!(flag, plain);

    // An OBJ whose material is called like a latent code binds to it by name.
    std::fs::write(dir.path().join("scene.mtl"), "newmtl chrome\nKd 0.5 0.5 0.5\nnewmtl light\nKe 4 4 4\n").unwrap();
    std::fs::write(
        dir.path().join("scene.obj"),
        "mtllib scene.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nv -1 -1 3\nv 1 -1 3\nv 0 1 3\n\
         usemtl chrome\nf 1 2 3\nf 1 3 4\nusemtl light\nf 5 7 6\n",
    )
    .unwrap();
    let obj = dir.path().join("scene.obj").to_string_lossy().into_owned();
    for (extra, out) in [(vec!["--material", latents.as_str()], "named.exr"), (vec![], "unnamed.exr")] {
        let mut args = vec![obj.as_str(), "--spp", "2", "--resolution", "16x16", "--output", out];
        args.extend(extra);
        let o = render(&args, dir.path());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert_ne!(mean_of(&dir.path().join("named.exr")), mean_of(&dir.path().join("unnamed.exr")));
}

#[test]
fn bad_latent_files_and_names_fail_cleanly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (latents, scene) = (shipped_latents(), preview_scene());
    let bytes = std::fs::read(&latents).unwrap();
    let mut wrong_version = bytes.clone();
    wrong_version[8..12].copy_from_slice(&99u32.to_le_bytes());
    std::fs::write(dir.path().join("version.bin"), &wrong_version).unwrap();
    std::fs::write(dir.path().join("short.bin"), &bytes[..bytes.len() / 2]).unwrap();
    std::fs::write(dir.path().join("foreign.bin"), b"not a latent file at all").unwrap();
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (vec!["--material", "version.bin"], vec!["version.bin", "version"]),
        (vec!["--material", "short.bin"], vec!["short.bin"]),
        (vec!["--material", "foreign.bin"], vec!["foreign.bin"]),
        (vec!["--material", "missing.bin"], vec!["missing.bin"]),
        (vec!["--material", &latents, "--bind", "preview=no-such-material"], vec!["no-such-material", "alum-bronze"]),
        (vec!["--bind", "preview=alum-bronze"], vec!["--bind", "--material"]),

        (vec!["--material", &latents, "--bind", "preview=alum-bronze", "--sweep", "alum-bronze:nothing:3"], vec!["nothing"]),
        (vec!["--material", &latents, "--sweep", "alum-bronze:chrome:1"], vec!["--sweep"]),
    ];
    let cornell = crate::common::cornell_box().to_string_lossy().into_owned();
    let out = render(
        &[&cornell, "--material", &latents, "--sweep", "alum-bronze:chrome:3", "--output", "out"],
        dir.path(),
    );
    assert_clean_failure(&out, &["--sweep", "bound"], dir.path());
    for (extra, needles) in cases {
        let mut args = vec![scene.as_str(), "--spp", "1", "--resolution", "8x8", "--output", "out.exr"];
        args.extend(extra.iter().copied());
        let out = render(&args, dir.path());
        assert_clean_failure(&out, &needles, dir.path());
    }
}

/// The MERL-layout table of a shipped NBRDF network (the data the latent file was trained on).
fn write_table(dir: &Path, name: &str) {
    let net = NbrdfNetwork::load(repo_file("../shared/data/nbrdf/merl").join(name)).expect("network");
    MerlTable::from_fn(|th, td, pd| net.eval_angles(th, td, pd))
        .write(dir.join(format!("{name}.binary")))
        .expect("write table");
}

#[test]
fn sweep_writes_frames_contact_sheet_and_errors() {
    let dir = tempfile::tempdir().expect("tempdir");
    let tables = dir.path().join("tables");
    std::fs::create_dir(&tables).unwrap();
    write_table(&tables, "alum-bronze");
    write_table(&tables, "chrome");
    let (latents, scene) = (shipped_latents(), preview_scene());
    let out = render(
        &[
            &scene, "--material", &latents, "--bind", "preview=alum-bronze", "--sweep", "alum-bronze:chrome:3",
            "--tables", tables.to_str().unwrap(), "--spp", "2", "--resolution", "24x24", "--output", "sweep",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let sweep = dir.path().join("sweep");
    for k in 0..3 {
        for kind in ["frame", "table"] {
            for ext in ["exr", "png"] {
                assert!(sweep.join(format!("{kind}-{k:03}.{ext}")).is_file(), "{kind}-{k:03}.{ext}");
            }
        }
    }
    let sheet = image::open(sweep.join("contact-sheet.png")).expect("contact sheet");
    assert!(sheet.width() > 3 * 24 && sheet.height() > 2 * 24);
    let csv = std::fs::read_to_string(sweep.join("sweep.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 3, "{csv}");
    for row in rows {
        let psnr: f64 = row.split(',').nth(3).unwrap().parse().unwrap();
        assert!(psnr.is_finite() && psnr > 10.0, "{row}");
    }
    // The end frames differ (the sweep moves from one material to the other).
    assert_ne!(mean_of(&sweep.join("frame-000.exr")), mean_of(&sweep.join("frame-002.exr")));

    // The same sweep in two chunks, as farm tasks run it: the last chunk to finish makes the
    // same contact sheet and CSV.
    let chunk = |frames: &str| {
        let out = render(
            &[
                &scene, "--material", &latents, "--bind", "preview=alum-bronze", "--sweep", "alum-bronze:chrome:3",
                "--tables", tables.to_str().unwrap(), "--spp", "2", "--resolution", "24x24", "--output", "chunks",
                "--frames", frames,
            ],
            dir.path(),
        );
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    };
    let chunks = dir.path().join("chunks");
    chunk("2");
    assert!(chunks.join("frame-002.exr").is_file() && !chunks.join("frame-000.exr").exists());
    assert!(!chunks.join("contact-sheet.png").exists(), "no sheet before every frame is there");
    chunk("0-1");
    let same = |name: &str| std::fs::read(sweep.join(name)).unwrap() == std::fs::read(chunks.join(name)).unwrap();
    assert!(same("contact-sheet.png") && same("sweep.csv") && same("frame-001.png"));
    let out = render(
        &[
            &scene, "--material", &latents, "--bind", "preview=alum-bronze", "--sweep", "alum-bronze:chrome:3",
            "--frames", "1-3", "--output", "out",
        ],
        dir.path(),
    );
    assert_clean_failure(&out, &["--frames", "1-3", "3 frames"], dir.path());
}

/// `render energy` refuses a missing or truncated latent file, a material with no network and
/// a bad flag value: one line naming the file, name or flag, exit code 2, and no output
/// directory.
#[test]
fn energy_refuses_bad_input_cleanly() {
    let dir = tempfile::tempdir().expect("tempdir");
    let inputs = tempfile::tempdir().expect("tempdir");
    let truncated = inputs.path().join("truncated.bin");
    let bytes = std::fs::read(repo_file("scenes/materials/latent.bin")).expect("shipped latents");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).expect("write");
    let truncated = truncated.to_string_lossy().into_owned();
    let nbrdf = repo_file("../shared/data/nbrdf").to_string_lossy().into_owned();
    let latents = shipped_latents();
    let cases: [(Vec<&str>, Vec<&str>); 4] = [
        (vec!["--material", "missing.bin"], vec!["missing.bin"]),
        (vec!["--material", &truncated], vec!["truncated.bin"]),
        (vec!["--material", &latents, "--nbrdf", &nbrdf, "--pairs", "nosuch:chrome"], vec!["nosuch"]),
        (vec!["--material", &latents, "--theta-o", "abc"], vec!["--theta-o", "abc"]),
    ];
    for (flags, needles) in cases {
        let mut args = vec!["energy", "--out", "study"];
        args.extend(flags);
        assert_clean_failure(&render(&args, dir.path()), &needles, dir.path());
    }
    // The default pairs, for scripts (assets-scripts/sweep_study.py): A:B per line, nothing
    // written.
    let out = render(&["energy", "--list-pairs"], dir.path());
    assert!(out.status.success(), "{out:?}");
    let listed = String::from_utf8_lossy(&out.stdout);
    let pairs: Vec<&str> = listed.lines().collect();
    assert!(pairs.len() >= 25 && pairs.iter().all(|p| p.split(':').filter(|m| !m.is_empty()).count() == 2), "{listed}");
    assert_eq!(pairs[0], "alum-bronze:chrome");
    assert!(!dir.path().join("study").exists());
}
