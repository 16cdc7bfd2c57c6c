//! The Lambertian (ideal diffuse) reflector.
//!
//! f_r(wo, wi) = albedo / π (1/sr) for `wo` and `wi` both above the horizon, zero otherwise;
//! its directional albedo equals `albedo` for every `wo`. Sampled with cosine-weighted
//! directions, which makes the Monte Carlo weight f cos θi / pdf exactly `albedo`.
//!
//! # Example
//! ```
//! use glam::{Vec2, Vec3};
//! use renderer::bsdf::{Bxdf, Lambert};
//! use renderer::Rgb;
//!
//! let white = Lambert::new(Rgb::ONE);
//! let s = white.sample(Vec3::Z, Vec2::new(0.25, 0.5), 0.0).expect("wo is above the horizon");
//! assert!((s.weight() - Rgb::ONE).length() < 1e-5);
//! ```

use super::{BsdfSample, Bxdf, RealBxdf, RealSample};
use crate::lanes::{F32s, MaskOps, Real, SetLane, V2, V3};
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use crate::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// An ideal diffuse reflector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    /// Hemispherical reflectance per channel, linear RGB, dimensionless; in [0, 1] for a
    /// physically plausible (energy-conserving) surface. The BRDF is `albedo / π` 1/sr.
    pub albedo: Rgb,
}

impl Lambert {
    /// A Lambertian reflector with each channel of `albedo` clamped to [0, 1] (NaN becomes 0).
    #[inline]
    pub fn new(albedo: Rgb) -> Self {
        Lambert {
            albedo: albedo.max(Rgb::ZERO).min(Rgb::ONE),
        }
    }
}

impl Lambert {
    /// The reflector's formulas ([`LambertLobe`]) for one shading point.
    #[inline(always)]
    pub(crate) fn lobe(&self) -> LambertLobe<f32> {
        LambertLobe {
            albedo: self.albedo.into(),
        }
    }
}

impl Bxdf for Lambert {
    /// `albedo / π` in 1/sr when both directions are above the horizon, zero otherwise.
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.eval_pdf(wo, wi).0
    }

    /// cos θi / π in 1/sr when both directions are above the horizon, zero otherwise.
    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// A cosine-weighted direction (concentric mapping of `u`; `uc` is unused). `None` when
    /// `wo` is below the horizon or `u` maps onto the horizon itself.
    #[inline]
    fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        self.lobe().sample((), wo.into(), u.into(), uc).into_option()
    }

    #[inline]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        let (f, pdf) = self.lobe().eval_pdf((), wo.into(), wi.into());
        (f.into(), pdf)
    }
}

/// [`Lambert`]'s formulas over [`Real`] values: for one shading point
/// ([`Lambert::lobe`]) or for [`LANES`](crate::lanes::LANES) points with their own albedos
/// (the lane kernels fill one lane per vertex with [`LambertLobe::set`]).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct LambertLobe<R> {
    /// Hemispherical reflectance per channel (already clamped to [0, 1]).
    pub albedo: V3<R>,
}

impl LambertLobe<F32s> {
    /// Sets lane `i` to one shading point's albedo.
    #[inline]
    pub fn set(&mut self, i: usize, one: &LambertLobe<f32>) {
        self.albedo.set_lane(i, one.albedo);
    }
}

impl<R: Real> RealBxdf<R> for LambertLobe<R> {
    type AtWo = ();

    #[inline(always)]
    fn at_wo(&self, _wo: V3<R>) {}

    #[inline(always)]
    fn eval_pdf(&self, _at: (), wo: V3<R>, wi: V3<R>) -> (V3<R>, R) {
        let zero = R::splat(0.0);
        let above = wo.z.gt(zero) & wi.z.gt(zero);
        let f = self.albedo * R::splat(FRAC_1_PI);
        (above.select(f, V3::default()), R::select(above, cosine_hemisphere_pdf(wi.z), zero))
    }

    #[inline(always)]
    fn sample(&self, _at: (), wo: V3<R>, u: V2<R>, _uc: R) -> RealSample<R> {
        let zero = R::splat(0.0);
        let wi = cosine_hemisphere(u);
        RealSample::new(wo.z.gt(zero) & wi.z.gt(zero), wi, self.albedo * R::splat(FRAC_1_PI), cosine_hemisphere_pdf(wi.z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::chi2::{self, Chi2Config};

    /// Number of chi-square tests in this module, for the Šidák correction.
    const CHI2_TESTS: usize = 2;

    #[test]
    fn eval_and_pdf_known_values() {
        let b = Lambert::new(Rgb::new(0.5, 0.25, 1.0));
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let wi = Vec3::new(0.0, 0.6, 0.8);
        assert!((b.eval(wo, wi) - Rgb::new(0.5, 0.25, 1.0) / std::f32::consts::PI).length() < 1e-7);
        assert!((b.pdf(wo, wi) - 0.8 / std::f32::consts::PI).abs() < 1e-7);
        assert!((b.pdf(wo, Vec3::Z) - FRAC_1_PI).abs() < 1e-7);
    }

    #[test]
    fn zero_below_horizon() {
        let b = Lambert::new(Rgb::ONE);
        let up = Vec3::new(0.0, 0.6, 0.8);
        let down = Vec3::new(0.0, 0.6, -0.8);
        assert_eq!(b.eval(down, up), Rgb::ZERO);
        assert_eq!(b.eval(up, down), Rgb::ZERO);
        assert_eq!(b.pdf(down, up), 0.0);
        assert_eq!(b.pdf(up, down), 0.0);
        assert_eq!(b.pdf(up, Vec3::X), 0.0);
        assert!(b.sample(down, Vec2::splat(0.3), 0.5).is_none());
    }

    #[test]
    fn new_clamps_albedo() {
        let b = Lambert::new(Rgb::new(-1.0, 2.0, f32::NAN));
        assert_eq!(b.albedo, Rgb::new(0.0, 1.0, 0.0));
    }

    #[test]
    fn white_furnace() {
        let b = Lambert::new(Rgb::ONE);
        for theta in [0.0f32, 0.5, 1.2, 1.55] {
            let wo = Vec3::new(theta.sin(), 0.0, theta.cos());
            let albedo = crate::bsdf::albedo::directional_albedo(&b, wo, 10_000);
            assert!(
                (albedo - Rgb::ONE).abs().max_element() < 1e-3,
                "θo = {theta}: {albedo}"
            );
        }
    }

    #[test]
    fn sampling_is_consistent() {
        let b = Lambert::new(Rgb::new(0.9, 0.5, 0.1));
        for wo in [Vec3::Z, Vec3::new(1.0, 0.0, 1e-7).normalize()] {
            let report = chi2::check_sample_consistency(&b, wo, 10_000);
            assert!(report.passed(), "{report}");
            assert!(report.valid > 9_990);
        }
    }

    #[test]
    fn sampling_passes_chi2() {
        let b = Lambert::new(Rgb::splat(0.7));
        let config = Chi2Config::default()
            .with_sample_count(500_000)
            .with_test_count(CHI2_TESTS);
        for (seed, wo) in [Vec3::Z, Vec3::new(0.8, 0.0, 0.6)].into_iter().enumerate() {
            let result = chi2::test_bxdf(&b, wo, &config.clone().with_seed(seed as u64));
            assert!(result.passed(), "wo = {wo}\n{result}");
        }
    }
}
