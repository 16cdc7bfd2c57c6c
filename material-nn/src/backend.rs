//! The burn device and optimiser of every learning step (training, NBRDF fitting, latent
//! refinement).

use burn::optim::{AdamConfig, ModuleOptimizer};
use burn::tensor::Device;

/// The device training runs on: burn's CPU backend `flex` (or, with the `gpu` feature, the
/// CUDA device when `MATERIAL_NN_DEVICE=cuda`), with autodiff.
pub fn training_device() -> Device {
    #[cfg(feature = "gpu")]
    {
        if std::env::var("MATERIAL_NN_DEVICE").is_ok_and(|v| v == "cuda") {
            return Device::cuda(0).autodiff();
        }
    }
    Device::flex().autodiff()
}

/// Adam as the method uses it (β = 0.9, 0.999; ε = 1e-8, PyTorch's).
pub fn optimizer() -> ModuleOptimizer {
    AdamConfig::new().with_epsilon(1e-8).init()
}
