//! NBRDF network ([`crate::neural::nbrdf`]) as a BSDF, evaluated natively per shading point.
//!
//! The network sees (sin θh, 0, cos θh, d) of (wi, wo) with φd folded into [0, π)
//! ([`crate::brdf_coords::network_input`]), which makes the BSDF reciprocal by construction at
//! the cost of one network evaluation; its output is clamped to f_r = max(exp(y) − 1, 0) and
//! kept finite, and it is zero below either horizon. The network is never asked for a
//! density: importance sampling uses a [`TabulatedSampler`] fitted from the network's values
//! at construction. In batched rendering its values are evaluated many points at a time
//! ([`BatchEval`]: one call per batch, each weight load shared by several points), the same
//! bits as one by one.
//!
//! ```no_run
//! use renderer::bsdf::nbrdf::NbrdfBsdf;
//! let bsdf = NbrdfBsdf::load("../shared/data/nbrdf/merl/alum-bronze")?;
//! # Ok::<(), renderer::Error>(())
//! ```

use super::tabulated_sampling::{TabulatedBrdf, TabulatedSampler, TabulatedSamplerConfig};
use super::BatchEval;
use crate::neural::nbrdf::{self as network, NbrdfNetwork};
use crate::{Result, Rgb};
use glam::Vec3;
use std::path::Path;

/// An NBRDF network as a BSDF.
#[derive(Clone, Debug)]
pub struct NbrdfBsdf {
    network: NbrdfNetwork,
    sampler: TabulatedSampler,
}

/// f_r(wo, wi) of a network; zero below either horizon.
#[inline]
fn eval_network(network: &NbrdfNetwork, wo: Vec3, wi: Vec3) -> Rgb {
    network_point(wo, wi).map_or(Rgb::ZERO, |x| network.eval_input(x))
}

/// The network input of (wo, wi); `None` below either horizon, where f_r is zero.
#[inline]
fn network_point(wo: Vec3, wi: Vec3) -> Option<[f32; network::INPUTS]> {
    (wo.z > 0.0 && wi.z > 0.0).then(|| crate::brdf_coords::network_input(wi, wo))
}

impl NbrdfBsdf {
    /// Bytes it holds: the network inline and the sampler's tables.
    pub fn heap_bytes(&self) -> usize {
        std::mem::size_of::<NbrdfNetwork>() + self.sampler.heap_bytes()
    }

    /// Loads `<prefix>_fc1.npy` ... `<prefix>_b3.npy` (see [`NbrdfNetwork::load`]) with the
    /// default sampler.
    pub fn load(prefix: impl AsRef<Path>) -> Result<Self> {
        Ok(Self::new(
            NbrdfNetwork::load(prefix)?,
            &TabulatedSamplerConfig::default(),
        ))
    }

    /// Wraps a network; fits the sampler (≈ 0.1 M network evaluations, parallel; ≈ 10 ms).
    pub fn new(network: NbrdfNetwork, sampling: &TabulatedSamplerConfig) -> Self {
        let sampler = TabulatedSampler::new(|wo, wi| eval_network(&network, wo, wi), sampling);
        NbrdfBsdf { network, sampler }
    }

    /// The network.
    pub fn network(&self) -> &NbrdfNetwork {
        &self.network
    }

}

impl BatchEval for NbrdfBsdf {
    type Prepared = [f32; network::INPUTS];

    #[inline]
    fn prepare(&self, wo: Vec3, wi: Vec3) -> Option<Self::Prepared> {
        network_point(wo, wi)
    }

    fn eval_prepared(&self, points: &[Self::Prepared], values: &mut [Rgb]) {
        assert_eq!(points.len(), values.len(), "one value per point");
        let mut outputs = vec![[0.0; network::OUTPUTS]; points.len()];
        self.network.forward_batch(points, &mut outputs);
        for (y, value) in outputs.into_iter().zip(values) {
            *value = network::output_value(y);
        }
    }
}

impl TabulatedBrdf for NbrdfBsdf {
    #[inline]
    fn value(&self, wo: Vec3, wi: Vec3) -> Rgb {
        eval_network(&self.network, wo, wi)
    }

    fn sampler(&self) -> &TabulatedSampler {
        &self.sampler
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::Bxdf;
    use crate::testing::bsdfs::{
        check_chi2, check_stability, nbrdf_bsdf, CHI2_MATERIALS, CHI2_THETAS,
    };

    #[test]
    fn eval_matches_network_and_is_reciprocal() {
        let bsdf = nbrdf_bsdf("alum-bronze");
        let a = crate::brdf_coords::HalfDiffAngles {
            theta_h: 0.3,
            phi_h: 1.0,
            theta_d: 0.5,
            phi_d: 2.0,
        };
        let (wi, wo) = crate::brdf_coords::directions_from_angles(&a);
        let want = bsdf.network().eval_angles(0.3, 0.5, 2.0);
        let got = bsdf.eval(wo, wi);
        assert!(
            (got - want).abs().max_element() < 1e-4 * want.max_element(),
            "{got} vs {want}"
        );
        // Swapping the directions maps φd to φd + π, folded back to the same input.
        let swapped = bsdf.eval(wi, wo);
        assert!((swapped - got).abs().max_element() < 1e-4 * got.max_element());
        assert_eq!(bsdf.eval(Vec3::new(0.0, 0.6, -0.8), wi), Rgb::ZERO);
        assert_eq!(bsdf.eval(wo, Vec3::new(0.0, 0.6, -0.8)), Rgb::ZERO);
    }

    /// Values evaluated in a batch (an odd and an even count, below-horizon pairs left out as the
    /// batched integrator leaves them) are the single evaluations' bits.
    #[test]
    fn batched_values_equal_single_ones_bit_for_bit() {
        let bsdf = nbrdf_bsdf("alum-bronze");
        let mut s = crate::sampler::Sampler::new(3, 4, 5);
        let mut pairs = Vec::new();
        for _ in 0..301 {
            let [a, b] = [s.next_2d(), s.next_2d()].map(crate::sampling::sample_uniform_sphere);
            pairs.push((a, b));
        }
        let (points, pairs): (Vec<_>, Vec<_>) = pairs.iter().filter_map(|&(wo, wi)| Some((bsdf.prepare(wo, wi)?, (wo, wi)))).unzip();
        assert!(points.len() > 50, "{} points above both horizons", points.len());
        for n in [points.len(), points.len() - 1, 1] {
            let mut values = vec![Rgb::ZERO; n];
            bsdf.eval_prepared(&points[..n], &mut values);
            for (&(wo, wi), v) in pairs.iter().zip(&values) {
                assert_eq!(v.to_array().map(f32::to_bits), bsdf.eval(wo, wi).to_array().map(f32::to_bits), "{wo} {wi}");
            }
        }
        assert!(pairs.iter().any(|&(wo, wi)| bsdf.eval(wo, wi).max_element() > 0.0));
    }

    #[test]
    fn stability_on_difficult_materials() {
        for name in ["chrome", "black-obsidian", "black-phenolic"] {
            check_stability(&nbrdf_bsdf(name));
        }
    }

    #[test]
    fn sampling_passes_chi2() {
        for name in CHI2_MATERIALS {
            let bsdf = nbrdf_bsdf(name);
            for theta_o in CHI2_THETAS {
                check_chi2(&bsdf, name, theta_o);
            }
        }
    }
}
