//! The networks, in burn: the HyperBRDF autoencoder (set encoder → latent z → hypernetwork →
//! target-net weights) used by HyperBRDF and FreNBRDF, and the per-material NBRDF baseline.
//!
//! Shapes (B materials, M encoder samples, N query samples):
//! - encoder: [B, M, 9] (6D input ‖ 3 mapped values) → Linear+ReLU per layer (9 → 128 → 128 →
//!   128 → 40, so z ≥ 0) → mean over M → z [B, 40];
//! - decoder: z [B, 40] → one head per target-net tensor (W0, b0, W1, b1, ...), each 40 → 128
//!   → 128 → numel with ReLU between and a linear last layer whose initial weights are scaled
//!   by 1e-2 → [B, numel];
//! - target net: x [B, N, 6] → 60 → 60 → 60 → 60 → 3 with ReLU between, linear output y
//!   [B, N, 3]; W reshaped row-major to [d_in, d_out] so that h' = h · W + b, the layout of
//!   [`renderer::formats::latent_file`].
//!
//! Initial weights come from the run's own seeded generator (not burn's), so a run is
//! reproducible: weights and biases U(−k, k) with k = 1/√d_in (PyTorch's `nn.Linear`).

use crate::config::ModelConfig;
use burn::module::{Module, Param};
use burn::nn::Linear;
use burn::tensor::{activation::relu, Device, Tensor, TensorData};
use rand::Rng;

/// Widths of the NBRDF baseline: 6 → 21 → 21 → 3.
pub const NBRDF_WIDTHS: [usize; 4] = [6, 21, 21, 3];

/// A Linear layer with weights and biases drawn U(−k, k), k = 1/√d_in, the weights then
/// multiplied by `weight_scale`.
pub fn init_linear(
    d_in: usize,
    d_out: usize,
    weight_scale: f32,
    rng: &mut impl Rng,
    device: &Device,
) -> Linear {
    let k = 1.0 / (d_in as f32).sqrt();
    let weight: Vec<f32> = (0..d_in * d_out)
        .map(|_| rng.random_range(-k..k) * weight_scale)
        .collect();
    let bias: Vec<f32> = (0..d_out).map(|_| rng.random_range(-k..k)).collect();
    Linear {
        weight: Param::from_tensor(Tensor::from_data(
            TensorData::new(weight, [d_in, d_out]),
            device,
        )),
        bias: Some(Param::from_tensor(Tensor::from_data(
            TensorData::new(bias, [d_out]),
            device,
        ))),
    }
}

/// A stack of Linear layers.
#[derive(Module, Debug)]
pub struct Mlp {
    /// Layers, input first.
    pub layers: Vec<Linear>,
}

impl Mlp {
    /// Layers between consecutive `widths`; the last layer's weights scaled by `last_scale`.
    pub fn init(widths: &[usize], last_scale: f32, rng: &mut impl Rng, device: &Device) -> Self {
        let n = widths.len() - 1;
        let layers = (0..n)
            .map(|i| {
                let scale = if i + 1 == n { last_scale } else { 1.0 };
                init_linear(widths[i], widths[i + 1], scale, rng, device)
            })
            .collect();
        Mlp { layers }
    }

    /// Forward pass over the last dimension; ReLU after every layer, or after every layer but
    /// the last when `linear_output`.
    pub fn forward<const D: usize>(&self, x: Tensor<D>, linear_output: bool) -> Tensor<D> {
        let n = self.layers.len();
        let mut h = x;
        for (i, layer) in self.layers.iter().enumerate() {
            h = layer.forward(h);
            if !(linear_output && i + 1 == n) {
                h = relu(h);
            }
        }
        h
    }

    /// Layers from plain f32 ones ([d_in, d_out] row-major weights), e.g. read from a
    /// latent file: the inverse of [`to_dense`](Self::to_dense).
    pub fn from_dense(layers: &[renderer::neural::mlp::DenseLayer], device: &Device) -> Self {
        let layers = layers
            .iter()
            .map(|l| Linear {
                weight: Param::from_tensor(Tensor::from_data(
                    TensorData::new(l.weight.clone(), [l.d_in, l.d_out]),
                    device,
                )),
                bias: Some(Param::from_tensor(Tensor::from_data(
                    TensorData::new(l.bias.clone(), [l.d_out]),
                    device,
                ))),
            })
            .collect();
        Mlp { layers }
    }

    /// Output width.
    pub fn output_width(&self) -> usize {
        self.layers.last().map_or(0, |l| l.weight.dims()[1])
    }

    /// The layers as plain f32 ([d_in, d_out] row-major weights), for export.
    pub fn to_dense(&self) -> Vec<renderer::neural::mlp::DenseLayer> {
        self.layers
            .iter()
            .map(|l| {
                let [d_in, d_out] = l.weight.dims();
                let weight = to_vec(l.weight.val());
                let bias = l
                    .bias
                    .as_ref()
                    .map_or_else(|| vec![0.0; d_out], |b| to_vec(b.val()));
                renderer::neural::mlp::DenseLayer {
                    d_in,
                    d_out,
                    weight,
                    bias,
                }
            })
            .collect()
    }
}

/// A tensor's values as f32 (row-major).
pub fn to_vec<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap_or_default()
}

/// The HyperBRDF autoencoder.
#[derive(Module, Debug)]
pub struct HyperBrdf {
    /// Set encoder: 9 → hidden... → latent_dim, ReLU after every layer, mean over samples.
    pub encoder: Mlp,
    /// One head per target-net tensor, in the order W0, b0, W1, b1, ...
    pub heads: Vec<Mlp>,
}

impl HyperBrdf {
    /// A freshly initialised model of the configured sizes.
    pub fn init(config: &ModelConfig, rng: &mut impl Rng, device: &Device) -> Self {
        let mut enc = vec![9];
        enc.extend(&config.encoder_hidden);
        enc.push(config.latent_dim);
        let encoder = Mlp::init(&enc, 1.0, rng, device);
        let mut heads = Vec::new();
        for w in config.target_widths.windows(2) {
            for numel in [w[0] * w[1], w[1]] {
                let mut widths = vec![config.latent_dim];
                widths.extend(&config.hyper_hidden);
                widths.push(numel);
                heads.push(Mlp::init(
                    &widths,
                    config.hyper_last_init_scale,
                    rng,
                    device,
                ));
            }
        }
        HyperBrdf { encoder, heads }
    }

    /// z [B, latent] of encoder inputs [B, M, 9].
    pub fn encode(&self, x: Tensor<3>) -> Tensor<2> {
        let [b, _, _] = x.dims();
        let h = self.encoder.forward(x, false).mean_dim(1);
        let latent = h.dims()[2];
        h.reshape([b, latent])
    }

    /// The target-net tensors of latent codes z [B, latent]: per tensor [B, numel].
    pub fn decode(&self, z: Tensor<2>) -> Vec<Tensor<2>> {
        self.heads
            .iter()
            .map(|h| h.forward(z.clone(), true))
            .collect()
    }

    /// (d_in, d_out) of each target-net layer.
    pub fn target_layers(&self) -> Vec<(usize, usize)> {
        self.heads
            .chunks(2)
            .map(|p| {
                let (w, b) = (p[0].output_width(), p[1].output_width());
                (w / b.max(1), b)
            })
            .collect()
    }

    /// Evaluates the target nets of `params` (from [`decode`](Self::decode)) on x [B, N, 6]:
    /// y [B, N, 3].
    pub fn target_forward(&self, params: &[Tensor<2>], x: Tensor<3>) -> Tensor<3> {
        let layers = self.target_layers();
        let b = x.dims()[0];
        let mut h = x;
        for (k, &(d_in, d_out)) in layers.iter().enumerate() {
            let w = params[2 * k].clone().reshape([b, d_in, d_out]);
            let bias = params[2 * k + 1].clone().reshape([b, 1, d_out]);
            h = h.matmul(w) + bias;
            if k + 1 < layers.len() {
                h = relu(h);
            }
        }
        h
    }

    /// Number of trainable scalars.
    pub fn parameter_count(&self) -> usize {
        self.num_params()
    }
}

/// The NBRDF baseline: one 6 → 21 → 21 → 3 network per material, f = max(e^y − 1, 0).
#[derive(Module, Debug)]
pub struct Nbrdf {
    /// The network (ReLU hidden layers, linear output y).
    pub net: Mlp,
}

impl Nbrdf {
    /// A freshly initialised network.
    pub fn init(rng: &mut impl Rng, device: &Device) -> Self {
        Nbrdf {
            net: Mlp::init(&NBRDF_WIDTHS, 1.0, rng, device),
        }
    }

    /// y [N, 3] of inputs [N, 6].
    pub fn forward(&self, x: Tensor<2>) -> Tensor<2> {
        self.net.forward(x, true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use renderer::neural::mlp::Mlp as PlainMlp;

    #[test]
    fn default_sizes_match_the_method() {
        let device = Device::flex();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
        let model = HyperBrdf::init(&ModelConfig::default(), &mut rng, &device);
        assert_eq!(
            model.target_layers(),
            vec![(6, 60), (60, 60), (60, 60), (60, 60), (60, 3)]
        );
        let target: usize = model.target_layers().iter().map(|(i, o)| i * o + o).sum();
        assert_eq!(target, 11_583);
        let hyper: usize = model.heads.iter().map(|h| h.num_params()).sum();
        assert!((1_700_000..1_720_000).contains(&hyper), "{hyper}");
        let nbrdf = Nbrdf::init(&mut rng, &device);
        assert_eq!(nbrdf.num_params(), 675);
        let y = nbrdf.forward(Tensor::from_data(
            TensorData::new(vec![0.5f32; 12], [2, 6]),
            &device,
        ));
        assert_eq!(y.dims(), [2, 3]);
    }

    #[test]
    fn burn_and_plain_forward_passes_agree() {
        let device = Device::flex();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(2);
        let config = ModelConfig {
            hyper_last_init_scale: 1.0,
            ..ModelConfig::default()
        };
        let model = HyperBrdf::init(&config, &mut rng, &device);
        let enc: Vec<f32> = (0..2 * 5 * 9).map(|i| (i as f32 * 0.37).sin()).collect();
        let z = model.encode(Tensor::from_data(TensorData::new(enc, [2, 5, 9]), &device));
        let params = model.decode(z.clone());
        let x: Vec<f32> = (0..2 * 4 * 6).map(|i| (i as f32 * 0.11).cos()).collect();
        let y = to_vec(model.target_forward(
            &params,
            Tensor::from_data(TensorData::new(x.clone(), [2, 4, 6]), &device),
        ));
        let z = to_vec(z);
        let heads: Vec<PlainMlp> = model
            .heads
            .iter()
            .map(|h| PlainMlp {
                layers: h.to_dense(),
            })
            .collect();
        for b in 0..2 {
            let outputs: Vec<Vec<f32>> = heads
                .iter()
                .map(|h| h.forward(&z[40 * b..40 * b + 40]))
                .collect();
            let layers = model
                .target_layers()
                .iter()
                .enumerate()
                .map(|(k, &(d_in, d_out))| renderer::neural::mlp::DenseLayer {
                    d_in,
                    d_out,
                    weight: outputs[2 * k].clone(),
                    bias: outputs[2 * k + 1].clone(),
                })
                .collect();
            let net = PlainMlp { layers };
            for n in 0..4 {
                let o = 24 * b + 6 * n;
                let plain = net.forward(&x[o..o + 6]);
                for c in 0..3 {
                    let t = y[12 * b + 3 * n + c];
                    assert!(
                        (plain[c] - t).abs() <= 1e-4 * t.abs().max(1.0),
                        "{plain:?} vs {t}"
                    );
                }
            }
        }
    }
}
