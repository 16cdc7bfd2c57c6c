//! The burn device and optimiser of every learning step (training, NBRDF fitting, latent
//! refinement).

use crate::{Error, Result};
use burn::optim::{AdamConfig, ModuleOptimizer};
use burn::tensor::Device;
use std::sync::OnceLock;

/// Environment variable choosing the backend at run time: `flex` (the default, burn's CPU
/// backend), `wgpu` (builds with `--features wgpu`: Vulkan, Metal, DX12 or WebGPU, whichever
/// adapter wgpu prefers; Mesa's software lavapipe where there is no GPU) or `cuda` (builds
/// with `--features gpu`).
pub const DEVICE_VARIABLE: &str = "MATERIAL_NN_DEVICE";

/// The backends this build has, as [`DEVICE_VARIABLE`] names them.
pub fn available_backends() -> Vec<&'static str> {
    let mut names = vec!["flex"];
    if cfg!(feature = "wgpu") {
        names.push("wgpu");
    }
    if cfg!(feature = "gpu") {
        names.push("cuda");
    }
    names
}

/// The name of the backend [`training_device`] uses (as [`DEVICE_VARIABLE`] names it).
pub fn backend_name() -> String {
    match std::env::var(DEVICE_VARIABLE) {
        Ok(name) if !name.is_empty() => name,
        _ => "flex".to_string(),
    }
}

/// The device learning runs on, with autodiff: the backend [`DEVICE_VARIABLE`] names (the
/// CPU backend `flex` when unset). Initialised once per process; an unknown name, a backend
/// this build lacks or a GPU runtime that finds no adapter is an error.
pub fn training_device() -> Result<Device> {
    static DEVICE: OnceLock<std::result::Result<Device, String>> = OnceLock::new();
    DEVICE
        .get_or_init(|| {
            let device = match backend_name().as_str() {
                "flex" => Device::flex(),
                #[cfg(feature = "wgpu")]
                "wgpu" => Device::wgpu_options()
                    .init()
                    .map_err(|e| format!("{DEVICE_VARIABLE}=wgpu: no usable wgpu adapter ({e})"))?,
                #[cfg(feature = "gpu")]
                "cuda" => Device::cuda(0),
                other => {
                    return Err(format!(
                        "{DEVICE_VARIABLE}={other}: not a backend of this build (it has {}; wgpu needs --features wgpu, cuda --features gpu)",
                        available_backends().join(", ")
                    ))
                }
            };
            Ok(device.autodiff())
        })
        .clone()
        .map_err(Error::Invalid)
}

/// Adam as the method uses it (β = 0.9, 0.999; ε = 1e-8, PyTorch's).
pub fn optimizer() -> ModuleOptimizer {
    AdamConfig::new().with_epsilon(1e-8).init()
}
