//! burn's wgpu backend (`--features wgpu`, selected with `MATERIAL_NN_DEVICE=wgpu`) trains as
//! the CPU backend does: the same run on both follows the same loss curve. Any Vulkan driver
//! serves; without a GPU, Mesa's software one (lavapipe, Debian `mesa-vulkan-drivers`):
//!
//!     cargo test --release -p material-nn --features wgpu --test cli -- wgpu_backend::
//!
//! Not part of `cargo test --workspace` (the wgpu stack adds about 10 minutes of build on two
//! cores); `assets-scripts/wgpu_check.sh` runs it with its set-up.

use crate::common::{make_data, path_str, small_config};
use material_nn::checkpoint::Checkpoint;
use material_nn::run::RunDir;
use std::path::Path;
use std::process::Command;

/// Trains `run` on `data` with the backend `device`; returns (train loss, L_fre, validation
/// loss) per epoch.
fn train_on(device: &str, data: &Path, config: &Path, run: &Path) -> Vec<[f64; 3]> {
    let out = Command::new(env!("CARGO_BIN_EXE_material-nn"))
        .args(["train", "--data", path_str(data), "--out", path_str(run), "--config", path_str(config)])
        .env("MATERIAL_NN_DEVICE", device)
        .output()
        .expect("material-nn runs");
    assert!(out.status.success(), "{device}: {}", String::from_utf8_lossy(&out.stderr));
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(log.contains(&format!("done, on {device}")), "not trained on {device}: {log}");
    let ckpt = Checkpoint::read(&RunDir(run.to_path_buf()).checkpoint()).expect("checkpoint");
    ckpt.state
        .history
        .iter()
        .map(|r| [r.train_loss, r.train_fre, r.validation.expect("validation loss")])
        .collect()
}

/// Relative tolerance of every epoch's losses, wgpu against flex. The two backends sum in
/// different orders (f32), so the runs part by rounding that training can amplify; over the
/// 20 epochs of this small run the largest difference measured on lavapipe is 7.6e-7.
const TOLERANCE: f64 = 1e-4;

#[test]
fn wgpu_training_follows_the_cpu_loss_curve() {
    let dir = tempfile::tempdir().unwrap();
    let data = make_data(dir.path());
    let config = dir.path().join("config.json");
    std::fs::write(&config, serde_json::to_string(&small_config(20)).unwrap()).unwrap();
    let cpu = train_on("flex", &data, &config, &dir.path().join("flex"));
    let gpu = train_on("wgpu", &data, &config, &dir.path().join("wgpu"));
    assert_eq!(cpu.len(), 20);
    assert_eq!(gpu.len(), cpu.len());
    assert!(cpu[19][0] < 0.9 * cpu[0][0], "the run learns: {:?} -> {:?}", cpu[0], cpu[19]);
    let mut worst = 0f64;
    for (epoch, (c, g)) in cpu.iter().zip(&gpu).enumerate() {
        for k in 0..3 {
            let rel = (g[k] - c[k]).abs() / c[k].abs().max(1e-12);
            worst = worst.max(rel);
            assert!(rel <= TOLERANCE, "epoch {}: wgpu {g:?} against flex {c:?}", epoch + 1);
        }
    }
    eprintln!("largest relative difference of the losses, wgpu against flex: {worst:.2e}");
}
