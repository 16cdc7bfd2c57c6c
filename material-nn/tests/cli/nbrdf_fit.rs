//! `material-nn nbrdf-fit` end to end on two small synthetic materials: the networks load in
//! the renderer and lower the loss, a second run skips finished materials and a refit is
//! bit-identical, a stop request writes nothing unfinished, and bad input gives one-line
//! errors with exit code 2.

use crate::common::{error_line, make_tables, material_nn, path_str};
use material_nn::nbrdf_fit::{self, FitConfig, FitOutcome, FitSummary};
use renderer::analytic::AnalyticBrdf;
use renderer::neural::latent_library::LatentLibrary;
use renderer::material::{Binding, SharedBsdf};
use renderer::neural::nbrdf::{tensor_paths, NbrdfNetwork};
use renderer::Rgb;
use std::path::{Path, PathBuf};
use std::process::Output;
use std::sync::atomic::AtomicBool;

/// Two analytic materials as MERL tables in `dir/data`.
fn make_data(dir: &Path) -> PathBuf {
    make_tables(
        dir,
        &[
            (
                "red-plastic",
                AnalyticBrdf::LambertGgx {
                    albedo: Rgb::new(0.6, 0.1, 0.1),
                    specular: Rgb::splat(0.04),
                    alpha: 0.3,
                },
            ),
            (
                "grey-clay",
                AnalyticBrdf::OrenNayar {
                    albedo: Rgb::splat(0.4),
                    sigma: 0.5,
                },
            ),
        ],
    )
}

/// A short fit: 4 epochs of 50 steps of 512 samples.
const SHORT: [&str; 6] = [
    "--epochs",
    "4",
    "--steps-per-epoch",
    "50",
    "--samples-per-step",
    "512",
];

fn fit(data: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "nbrdf-fit",
        "--data",
        path_str(data),
        "--out",
        path_str(out),
    ];
    args.extend(SHORT);
    args.extend(extra);
    material_nn(&args)
}

fn file_bytes(prefix: &Path) -> Vec<Vec<u8>> {
    tensor_paths(prefix)
        .iter()
        .map(|p| std::fs::read(p).unwrap())
        .collect()
}

#[test]
fn fits_load_in_the_renderer_lower_the_loss_and_resume() {
    let dir = tempfile::tempdir().unwrap();
    let data = make_data(dir.path());
    let out = dir.path().join("nbrdf");
    let o = fit(&data, &out, &[]);
    assert!(o.status.success(), "{o:?}");

    let summary = FitSummary::read(&out.join("fit.json")).unwrap();
    assert_eq!(
        summary.materials.keys().collect::<Vec<_>>(),
        ["grey-clay", "red-plastic"]
    );
    for (name, f) in &summary.materials {
        assert!(
            f.final_loss.is_finite() && f.final_loss < 0.5 * f.initial_loss,
            "{name}: loss {} -> {}",
            f.initial_loss,
            f.final_loss
        );
        assert!(f.last_epoch_loss < f.first_epoch_loss, "{name}: {f:?}");
        assert_eq!(f.config.epochs, 4);
        let prefix = out.join(name);
        let net = NbrdfNetwork::load(&prefix).unwrap();
        // The diffuse grey clay: close to the table's value away from grazing angles.
        if name == "grey-clay" {
            let f = net.eval_angles(0.3, 0.4, 1.0);
            let brdf = AnalyticBrdf::OrenNayar {
                albedo: Rgb::splat(0.4),
                sigma: 0.5,
            };
            let truth = brdf.eval_angles(0.3, 0.4, 1.0);
            assert!(
                (f - truth).abs().max_element() < 0.3 * truth.max_element(),
                "{f} vs {truth}"
            );
        }
        // What `render --bind M=nbrdf:OUT/NAME` loads.
        let binding = Binding::parse(&format!("nbrdf:{}", prefix.display()), std::path::Path::new("")).unwrap();
        assert!(matches!(
            SharedBsdf::open(&binding, &LatentLibrary::default()).unwrap(),
            SharedBsdf::Nbrdf(_)
        ));
    }

    // A second run skips both; removing one material's first file refits it, identically.
    let before = file_bytes(&out.join("red-plastic"));
    let o = fit(&data, &out, &[]);
    assert!(o.status.success(), "{o:?}");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("0 fitted, 2 already present"), "{stdout}");
    std::fs::remove_file(&tensor_paths(&out.join("red-plastic"))[0]).unwrap();
    let o = fit(&data, &out, &["--materials", "red-plastic"]);
    assert!(o.status.success(), "{o:?}");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("1 fitted, 0 already present"), "{stdout}");
    assert!(
        before == file_bytes(&out.join("red-plastic")),
        "refit differs"
    );
    assert_eq!(
        FitSummary::read(&out.join("fit.json"))
            .unwrap()
            .materials
            .len(),
        2
    );

    // A stop request before the first step writes nothing.
    let stopped = dir.path().join("stopped");
    let tables = nbrdf_fit::select_tables(&data, None).unwrap();
    let config = FitConfig {
        epochs: 1,
        steps_per_epoch: 10,
        ..FitConfig::default()
    };
    let report = nbrdf_fit::fit_all(
        &tables,
        &stopped,
        &config,
        &AtomicBool::new(true),
        &mut |_| {},
    )
    .unwrap();
    assert!(report.interrupted && report.outcomes.is_empty());
    assert!(nbrdf_fit::network_present(&out.join("grey-clay")));
    assert!(!stopped.join("grey-clay_fc1.npy").exists());
    assert!(!stopped.join("fit.json").exists());

    // Through the library, a finished directory reports skips.
    let report =
        nbrdf_fit::fit_all(&tables, &out, &config, &AtomicBool::new(false), &mut |_| {}).unwrap();
    assert!(report
        .outcomes
        .iter()
        .all(|(_, o)| *o == FitOutcome::Skipped));
}

#[test]
fn bad_input_gives_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");

    let missing = dir.path().join("no-such-dir");
    let e = error_line(&fit(&missing, &out, &[]));
    assert!(e.contains("no-such-dir"), "{e}");

    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let e = error_line(&fit(&empty, &out, &[]));
    assert!(e.contains("empty") && e.contains("no MERL tables"), "{e}");

    // A table that is not one.
    let junk = dir.path().join("junk");
    std::fs::create_dir(&junk).unwrap();
    std::fs::write(junk.join("broken.binary"), b"not a table").unwrap();
    let e = error_line(&fit(&junk, &out, &[]));
    assert!(e.contains("broken.binary"), "{e}");
    assert!(!out.join("broken_fc1.npy").exists());

    // An unknown material lists the available ones.
    let e = error_line(&fit(&junk, &out, &["--materials", "gold"]));
    assert!(e.contains("gold") && e.contains("broken"), "{e}");

    // Out-of-range settings.
    let e = error_line(&material_nn(&[
        "nbrdf-fit",
        "--data",
        path_str(&junk),
        "--out",
        path_str(&out),
        "--epochs",
        "0",
    ]));
    assert!(e.contains("--epochs"), "{e}");
    let e = error_line(&material_nn(&[
        "nbrdf-fit",
        "--data",
        path_str(&junk),
        "--out",
        path_str(&out),
        "--learning-rate",
        "0",
    ]));
    assert!(e.contains("--learning-rate"), "{e}");
}
