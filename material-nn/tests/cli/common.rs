//! Helpers shared by the material-nn command-line tests.

use material_nn::checkpoint::Checkpoint;
use material_nn::config::{FreConfig, ModelConfig, TrainConfig};
use material_nn::run::load_model;
use renderer::analytic::AnalyticBrdf;
use renderer::Rgb;
use renderer::formats::merl::MerlTable;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A temporary path as a command-line argument.
pub fn path_str(p: &Path) -> &str {
    p.to_str().expect("UTF-8 temporary path")
}

/// The one-line error of a failed run (exit code 2).
pub fn error_line(out: &Output) -> String {
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let stderr = String::from_utf8_lossy(&out.stderr).trim().to_string();
    assert!(stderr.starts_with("error: ") && !stderr.contains('\n'), "{stderr}");
    stderr
}

/// Runs `material-nn` to completion.
pub fn material_nn(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_material-nn"))
        .args(args)
        .output()
        .expect("material-nn runs")
}

/// Analytic materials as MERL tables `dir/data/NAME.binary` (35 MB each; the temporary
/// directory of each test removes them); returns the data directory.
pub fn make_tables(dir: &Path, materials: &[(&str, AnalyticBrdf)]) -> PathBuf {
    let data = dir.join("data");
    std::fs::create_dir_all(&data).unwrap();
    for (name, brdf) in materials {
        let table = MerlTable::from_fn(|th, td, pd| brdf.eval_angles(th, td, pd));
        table.write(data.join(format!("{name}.binary"))).unwrap();
    }
    data
}

/// Every weight and bias of a checkpoint's encoder and hypernetwork, in order (burnpack
/// bytes carry per-run parameter ids, so runs are compared by their weights).
pub fn model_weights(c: &Checkpoint) -> Vec<f32> {
    let device = burn::tensor::Device::flex();
    let m = load_model(&c.config, &c.model, &device, Path::new("checkpoint")).unwrap();
    let mut all: Vec<f32> = m
        .encoder
        .to_dense()
        .iter()
        .flat_map(|l| l.weight.iter().chain(&l.bias).copied())
        .collect();
    for h in &m.heads {
        all.extend(h.to_dense().iter().flat_map(|l| l.weight.iter().chain(&l.bias).copied()));
    }
    all
}

/// Three analytic materials as MERL tables in `dir/data`.
pub fn make_data(dir: &Path) -> PathBuf {
    make_tables(
        dir,
        &[
            (
                "red-plastic",
                AnalyticBrdf::LambertGgx {
                    albedo: Rgb::new(0.6, 0.1, 0.1),
                    specular: Rgb::splat(0.04),
                    alpha: 0.15,
                },
            ),
            (
                "rough-gold",
                AnalyticBrdf::LambertGgx {
                    albedo: Rgb::new(0.05, 0.04, 0.02),
                    specular: Rgb::new(0.9, 0.7, 0.3),
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

/// A small, fast configuration: 2 training materials, 1 validation material.
pub fn small_config(epochs: usize) -> TrainConfig {
    TrainConfig {
        split: [0.6, 0.4, 0.0],
        samples_per_step: 1024,
        encoder_samples: 256,
        validation_samples: 512,
        epochs,
        patience: 100,
        learning_rate: 5e-3,
        fre: FreConfig {
            lmax: 8,
            ..FreConfig::default()
        },
        net: ModelConfig {
            latent_dim: 8,
            encoder_hidden: vec![32, 32],
            hyper_hidden: vec![32],
            target_widths: vec![6, 16, 16, 3],
            hyper_last_init_scale: 1e-2,
        },
        ..TrainConfig::default()
    }
}
