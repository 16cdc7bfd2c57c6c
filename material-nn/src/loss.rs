//! The losses: L_rec (HyperBRDF, the talk's Eq. 1) and the frequency-rectified L_fre
//! (FreNBRDF, the talk's Eq. 3–10).
//!
//! L_fre of one sample set, in the released code's form (docs/training.md):
//! 1. each sample's difference direction d (φh = 0) is a point on the upper hemisphere;
//! 2. the cos θi-weighted values v = y · cos θi are splatted onto the upper-hemisphere points of
//!    the [`ShGrid`] of degree L with the k nearest samples ([`crate::splat`], σ = 0.05 chordal,
//!    normalised weights); the lower hemisphere, where no difference direction lies, is 0;
//! 3. SH coefficients c_lm by the grid's exact quadrature, each multiplied by the degree weight
//!    w_l = exp((L² − l²) / 2σ²) (σ = 50, so w_L = 1);
//! 4. L_fre = Σ over RGB of the mean over (l, m) of (w_l (c'_lm − c_lm))².
//!
//! Steps 2–3 depend only on the coordinates, so they form a fixed linear map of the values,
//! built once per sample set: a sparse gather (k entries per grid point) followed by a dense
//! [(L+1)², G] analysis matrix shared by every set (G = grid points on the hemisphere). Both are
//! burn tensor operations, so L_fre is differentiable in the predicted values. This is the
//! released code's form ([`FreOperator`]); by Parseval it is a re-weighted squared error of
//! the same points, all θh mixed on one sphere, and at η = 0.1 it is ≈ 0.1 % of the loss.
//!
//! The talk's form (Eq. 3, [`SlicedFre`]) takes the coefficients of the function of the
//! difference direction at fixed half-vector angles θh (φh = α = 0): the model and the table
//! are evaluated at the same fixed grid points of each slice — no splat, no dependence on the
//! step's samples — so L_fre compares the two functions' spectra slice by slice, including
//! the specular slice θh = 0.

use crate::config::{FreConfig, RecForm, TrainConfig};
use crate::error::Result;
use crate::sh::{coefficient_count, degree_weights, ShGrid};
use crate::splat::{splat_map, SplatMap};
use burn::tensor::{Device, Int, Tensor, TensorData};
use renderer::brdf_coords::{rendered_point, RenderedPoint};

/// L_rec (the talk's Eq. 1): its form and the weights of its two regularisers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReconstructionLoss {
    /// Talk form (absolute error, sums) or the released code's (squared error, means).
    pub form: RecForm,
    /// λ1: weight of the generated target-net weights' squared norm.
    pub lambda_weights: f32,
    /// λ2: weight of the latent code's squared norm.
    pub lambda_latent: f32,
}

impl ReconstructionLoss {
    /// The L_rec a run is configured with.
    pub fn of(config: &TrainConfig) -> Self {
        ReconstructionLoss {
            form: config.rec_form,
            lambda_weights: config.lambda_weights,
            lambda_latent: config.lambda_latent,
        }
    }

    /// L_rec of a batch.
    ///
    /// Shapes: `pred`, `target` [B, N, 3] (mapped values y), `cos_i` [B, N, 1]; `params` the
    /// target-net tensors [B, numel] of [`crate::model::HyperBrdf::decode`]; `z` [B, latent].
    /// Talk form: mean |(y − y') cos θi| over all B·N·3 entries + λ1 Σ w² + λ2 Σ z² (sums per
    /// material, averaged over the B materials; w = every generated weight and bias). Code
    /// form: squared error and means instead of sums. Returns (total, data term).
    pub fn forward(&self, pred: Tensor<3>, target: Tensor<3>, cos_i: Tensor<3>, params: &[Tensor<2>], z: Tensor<2>) -> (Tensor<1>, Tensor<1>) {
        let ReconstructionLoss { form, lambda_weights, lambda_latent } = *self;
        let b = pred.dims()[0] as f32;
        let diff = (pred - target) * cos_i;
        let data = match form {
            RecForm::Talk => diff.abs().mean(),
            RecForm::Code => diff.square().mean(),
        };
        let (weights, latent) = match form {
            RecForm::Talk => {
                let w = params
                    .iter()
                    .map(|p| p.clone().square().sum())
                    .reduce(|a, c| a + c)
                    .map(|s| s / b);
                (w, z.square().sum() / b)
            }
            RecForm::Code => {
                let count: usize = params.iter().map(|p| p.dims()[1]).sum();
                let w = params
                    .iter()
                    .map(|p| p.clone().square().sum())
                    .reduce(|a, c| a + c)
                    .map(|s| s / (b * count as f32));
                (w, z.square().mean())
            }
        };
        let mut total = data.clone() + latent * lambda_latent;
        if let Some(w) = weights {
            total = total + w * lambda_weights;
        }
        (total, data)
    }
}

/// The fixed part of L_fre: the grid and its weighted analysis matrix.
#[derive(Clone, Debug)]
pub struct FreOperator {
    config: FreConfig,
    /// Unit vectors of the grid points on the upper hemisphere (the splat targets).
    targets: Vec<[f64; 3]>,
    /// w_l · quadrature weight · Y_lm at each target, row-major [(L+1)², G] (f64, for the CPU
    /// reference).
    analysis: Vec<f64>,
    /// The same as a tensor [(L+1)², G].
    analysis_tensor: Tensor<2>,
}

/// The per-sample-set part of L_fre on a device: the splat as gather indices and weights.
#[derive(Clone, Debug)]
pub struct SplatTensors {
    /// The map itself.
    pub map: SplatMap,
    /// Sample index of each (grid point, neighbour), [G·k].
    indices: Tensor<1, Int>,
    /// Weight of each (grid point, neighbour), [G, k, 1].
    weights: Tensor<3>,
}

/// The grid of degree `config.lmax`, its upper-hemisphere points and their analysis matrix
/// with each coefficient's row multiplied by its degree weight: [(L+1)², G] row-major in f64
/// and as an f32 tensor on `device`. Shared by both forms of L_fre.
fn weighted_analysis(config: &FreConfig, device: &Device) -> (ShGrid, Vec<usize>, Vec<f64>, Tensor<2>) {
    let grid = ShGrid::new(config.lmax);
    let points = grid.upper_hemisphere();
    let mut analysis = grid.analysis_matrix(&points);
    let g = points.len();
    for (row, w) in analysis
        .chunks_mut(g)
        .zip(degree_weights(config.lmax, config.degree_sigma))
    {
        row.iter_mut().for_each(|v| *v *= w);
    }
    let c = coefficient_count(config.lmax);
    let as_f32: Vec<f32> = analysis.iter().map(|&v| v as f32).collect();
    let tensor = Tensor::from_data(TensorData::new(as_f32, [c, g]), device);
    (grid, points, analysis, tensor)
}

impl FreOperator {
    /// Builds the grid of degree `config.lmax` and its analysis matrix on `device`.
    pub fn new(config: &FreConfig, device: &Device) -> Self {
        let (grid, points, analysis, analysis_tensor) = weighted_analysis(config, device);
        let targets: Vec<[f64; 3]> = points.iter().map(|&i| grid.direction(i)).collect();
        FreOperator {
            config: config.clone(),
            targets,
            analysis,
            analysis_tensor,
        }
    }

    /// Number of grid points that receive values.
    pub fn grid_points(&self) -> usize {
        self.targets.len()
    }

    /// The splat map of a sample set with difference directions `directions` (unit
    /// vectors): which samples each grid point takes, with what weights.
    pub fn splat_map(&self, directions: &[[f32; 3]]) -> Result<SplatMap> {
        splat_map(directions, &self.targets, self.config.neighbours, self.config.splat_sigma)
    }

    /// The splat of a sample set with difference directions `directions` (unit vectors).
    pub fn splat(&self, directions: &[[f32; 3]], device: &Device) -> Result<SplatTensors> {
        let map = self.splat_map(directions)?;
        let idx: Vec<i64> = map.indices.iter().map(|&i| i as i64).collect();
        let n = idx.len();
        let indices = Tensor::from_data(TensorData::new(idx, [n]), device);
        let weights = Tensor::from_data(
            TensorData::new(map.weights.clone(), [self.targets.len(), map.k, 1]),
            device,
        );
        Ok(SplatTensors {
            map,
            indices,
            weights,
        })
    }

    /// Weighted SH coefficients [(L+1)², 3] of per-sample values [N, 3] (already cos-weighted).
    pub fn coefficients(&self, splat: &SplatTensors, values: Tensor<2>) -> Tensor<2> {
        let g = self.targets.len();
        let k = splat.map.k;
        let gathered = values.select(0, splat.indices.clone()).reshape([g, k, 3]);
        let on_grid = (gathered * splat.weights.clone())
            .sum_dim(1)
            .reshape([g, 3]);
        self.analysis_tensor.clone().matmul(on_grid)
    }

    /// L_fre between predicted and true cos-weighted values, both [N, 3] (true values carry no
    /// gradient): Σ_RGB mean_lm (c' − c)². Returns a one-element tensor.
    pub fn loss(&self, splat: &SplatTensors, pred: Tensor<2>, truth: Tensor<2>) -> Tensor<1> {
        let c_pred = self.coefficients(splat, pred);
        let c_true = self.coefficients(splat, truth).detach();
        (c_pred - c_true).square().mean_dim(0).sum()
    }

    /// The same loss in f64 on the CPU (reference for tests and evaluation); values are
    /// row-major [N, 3].
    pub fn loss_cpu(&self, map: &SplatMap, pred: &[f64], truth: &[f64]) -> f64 {
        let diff: Vec<f64> = pred.iter().zip(truth).map(|(a, b)| a - b).collect();
        let on_grid = map.apply(&diff, 3);
        let g = self.targets.len();
        let c = self.analysis.len() / g;
        let mut total = 0.0;
        for row in self.analysis.chunks(g) {
            let mut acc = [0.0; 3];
            for (a, v) in row.iter().zip(on_grid.chunks(3)) {
                for ch in 0..3 {
                    acc[ch] += a * v[ch];
                }
            }
            total += acc.iter().map(|x| x * x).sum::<f64>();
        }
        total / c as f64
    }
}

/// The talk's L_fre on fixed θh slices (see the module documentation): for each slice θh and
/// each upper-hemisphere point d = (θd, φd) of the [`ShGrid`] of degree L, the configuration
/// (θh, θd, φd) of the rendered domain ([`renderer::brdf_coords::rendered_point`]) with weight
/// cos θi (0 outside the domain, or where the table or f_ref is unmeasured). Per slice s:
/// c_s = A (w · y) with A the degree-weighted analysis matrix [(L+1)², G];
/// L_fre = mean over slices of Σ_RGB mean_lm (c'_s − c_s)².
#[derive(Clone, Debug)]
pub struct SlicedFre {
    /// Every (slice, grid point), slice-major: the configuration of the rendered domain, or
    /// `None` outside it.
    points: Vec<Option<RenderedPoint>>,
    /// Network inputs of the points, [1, S·G, 6] (zeros outside the domain).
    inputs: Tensor<3>,
    /// Degree-weighted analysis matrix [(L+1)², G].
    analysis: Tensor<2>,
    slices: usize,
    grid: usize,
}

/// What [`SlicedFre`] needs of one material: its weights and its coefficients, fixed.
#[derive(Clone, Debug)]
pub struct SliceTarget {
    /// cos θi where the material is measured inside the domain, else 0: [1, S·G, 1].
    weights: Tensor<3>,
    /// The table's weighted coefficients, [(L+1)², S·3] (slice-major columns).
    coefficients: Tensor<2>,
}

impl SlicedFre {
    /// The grid of degree `config.lmax` at `config.theta_h_slices` (degrees), on `device`.
    pub fn new(config: &FreConfig, device: &Device) -> Self {
        let (grid, upper, _, analysis) = weighted_analysis(config, device);
        let mut points = Vec::new();
        let mut inputs = Vec::new();
        for &deg in &config.theta_h_slices {
            for &i in &upper {
                let (theta_d, phi_d) = grid.angles(i);
                let point = rendered_point(deg.to_radians(), theta_d as f32, phi_d as f32);
                inputs.extend_from_slice(&point.map_or([0.0; 6], |p| p.input));
                points.push(point);
            }
        }
        let n = points.len();
        SlicedFre {
            points,
            inputs: Tensor::from_data(TensorData::new(inputs, [1, n, 6]), device),
            analysis,
            slices: config.theta_h_slices.len(),
            grid: upper.len(),
        }
    }

    /// Number of (slice, grid point) configurations the model is evaluated at.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The network inputs for a batch of `b` materials, [b, S·G, 6].
    pub fn inputs(&self, b: usize) -> Tensor<3> {
        if b == 1 {
            self.inputs.clone()
        } else {
            self.inputs.clone().repeat_dim(0, b)
        }
    }

    /// Weighted coefficients [(L+1)², S·3] of values [S·G, 3] already multiplied by weights.
    fn coefficients(&self, weighted: Tensor<2>) -> Tensor<2> {
        let (s, g) = (self.slices, self.grid);
        let columns = weighted.reshape([s, g, 3]).swap_dims(0, 1).reshape([g, s * 3]);
        self.analysis.clone().matmul(columns)
    }

    /// The fixed part of one material: `value(θh, θd, φd)` gives its mapped values y at a
    /// point of the domain (φd folded), or `None` where it is unmeasured.
    pub fn target(
        &self,
        value: impl Fn(&RenderedPoint) -> Option<[f32; 3]>,
        device: &Device,
    ) -> SliceTarget {
        let n = self.points.len();
        let mut weights = vec![0f32; n];
        let mut values = vec![0f32; 3 * n];
        for (i, point) in self.points.iter().enumerate() {
            let Some(point) = point else {
                continue;
            };
            if let Some(y) = value(point) {
                weights[i] = point.cos_i;
                for c in 0..3 {
                    values[3 * i + c] = y[c] * point.cos_i;
                }
            }
        }
        let values = Tensor::<2>::from_data(TensorData::new(values, [n, 3]), device);
        SliceTarget {
            weights: Tensor::from_data(TensorData::new(weights, [1, n, 1]), device),
            coefficients: self.coefficients(values),
        }
    }

    /// L_fre of predictions `pred` [1, S·G, 3] (the model at [`inputs`](Self::inputs)) against
    /// a material's target. Returns a one-element tensor.
    pub fn loss(&self, pred: Tensor<3>, target: &SliceTarget) -> Tensor<1> {
        let n = self.points.len();
        let weighted = (pred * target.weights.clone()).reshape([n, 3]);
        let c = self.coefficients(weighted);
        (c - target.coefficients.clone()).square().mean_dim(0).sum() / self.slices as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn hemisphere_samples(n: usize, rng: &mut impl Rng) -> Vec<[f32; 3]> {
        (0..n)
            .map(|_| {
                let z: f32 = rng.random_range(0.0..1.0);
                let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
                let s = (1.0 - z * z).sqrt();
                [s * phi.cos(), s * phi.sin(), z]
            })
            .collect()
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let device = Device::flex().autodiff();
        let config = FreConfig {
            lmax: 4,
            ..FreConfig::default()
        };
        let op = FreOperator::new(&config, &device);
        assert_eq!(op.grid_points(), 2 * 10);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let n = 40;
        let dirs = hemisphere_samples(n, &mut rng);
        let splat = op.splat(&dirs, &device).unwrap();
        let pred: Vec<f64> = (0..3 * n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let truth: Vec<f64> = (0..3 * n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let to_tensor = |v: &[f64]| {
            Tensor::<2>::from_data(
                TensorData::new(v.iter().map(|&x| x as f32).collect::<Vec<f32>>(), [n, 3]),
                &device,
            )
        };
        let p = to_tensor(&pred).require_grad();
        let loss = op.loss(&splat, p.clone(), to_tensor(&truth));
        let value: f32 = loss.clone().into_scalar();
        let reference = op.loss_cpu(&splat.map, &pred, &truth);
        assert!(
            (value as f64 - reference).abs() < 1e-5 * reference.max(1e-3),
            "{value} vs {reference}"
        );
        let grads = loss.backward();
        let grad = crate::model::to_vec(p.grad(&grads).expect("gradient of the predictions"));
        let h = 1e-6;
        let mut worst = 0f64;
        for i in 0..3 * n {
            let mut up = pred.clone();
            up[i] += h;
            let mut down = pred.clone();
            down[i] -= h;
            let fd = (op.loss_cpu(&splat.map, &up, &truth)
                - op.loss_cpu(&splat.map, &down, &truth))
                / (2.0 * h);
            worst = worst.max((fd - grad[i] as f64).abs());
        }
        let scale = grad.iter().fold(0f32, |m, g| m.max(g.abs())) as f64;
        assert!(scale > 0.0);
        assert!(
            worst < 1e-3 * scale.max(1e-3),
            "worst gradient error {worst} (scale {scale})"
        );
    }

    #[test]
    fn identical_values_give_zero_and_constant_offset_is_seen() {
        let device = Device::flex();
        let op = FreOperator::new(
            &FreConfig {
                lmax: 6,
                ..FreConfig::default()
            },
            &device,
        );
        let mut rng = rand_pcg::Pcg64::seed_from_u64(9);
        let dirs = hemisphere_samples(500, &mut rng);
        let splat = op.splat(&dirs, &device).unwrap();
        let v: Vec<f64> = (0..1500).map(|i| (i as f64 * 0.01).sin()).collect();
        assert_eq!(op.loss_cpu(&splat.map, &v, &v), 0.0);
        let shifted: Vec<f64> = v.iter().map(|x| x + 0.5).collect();
        assert!(op.loss_cpu(&splat.map, &shifted, &v) > 1e-3);
    }

    #[test]
    fn sliced_loss_is_zero_for_the_truth_and_sees_a_peak_change() {
        let device = Device::flex();
        let config = FreConfig {
            lmax: 8,
            theta_h_slices: vec![0.0, 10.0, 40.0],
            ..FreConfig::default()
        };
        let op = SlicedFre::new(&config, &device);
        assert_eq!(op.len(), 3 * 4 * 18);
        // A "material" peaked at θh = 0 and its copy with the peak halved.
        let peaked = |p: &RenderedPoint, k: f32| {
            let h = p.angles[0];
            Some([1.0 + k * (-h * h * 50.0).exp(), 0.5, 0.25])
        };
        let target = op.target(|p| peaked(p, 4.0), &device);
        let values = |k: f32| {
            let v: Vec<f32> = op
                .points
                .iter()
                .flat_map(|q| q.as_ref().and_then(|p| peaked(p, k)).unwrap_or([7.0; 3]))
                .collect();
            Tensor::<3>::from_data(TensorData::new(v, [1, op.len(), 3]), &device)
        };
        let same: f32 = op.loss(values(4.0), &target).into_scalar();
        assert!(same.abs() < 1e-8, "{same}");
        let halved: f32 = op.loss(values(2.0), &target).into_scalar();
        assert!(halved > 1e-3, "{halved}");
        // Outside the domain the weight is 0: values there do not matter.
        assert_eq!(op.inputs(2).dims(), [2, op.len(), 6]);
    }
}
