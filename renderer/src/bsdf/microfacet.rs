//! The Trowbridge–Reitz (GGX) microfacet distribution: normal distribution D, Smith masking
//! and shadowing (Λ, G1, height-correlated G2), visible-normal sampling and Schlick's
//! Fresnel approximation.
//!
//! Everything is written in the local shading frame of [`crate::bsdf`]: z is the
//! macrosurface normal, directions are unit vectors pointing away from the surface, angles
//! are in radians and densities are per steradian. The distribution may be anisotropic,
//! with roughness `alpha_x` along the frame's x axis and `alpha_y` along y.
//!
//! # Example
//! ```
//! use glam::{Vec2, Vec3};
//! use renderer::bsdf::microfacet::GgxDistribution;
//!
//! let ggx = GgxDistribution::from_roughness(0.5); // α = 0.25
//! let wo = Vec3::new(0.6, 0.0, 0.8);
//! if let Some(wi) = ggx.sample_reflection(wo, Vec2::new(0.3, 0.7)) {
//!     let pdf = ggx.reflection_pdf(wo, wi);
//!     assert!(pdf > 0.0 && pdf.is_finite());
//! }
//! ```

use crate::lanes::{MaskOps, Real, V2, V3};
use crate::sampling::sin_cos_turns;
use crate::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// Smallest roughness α a [`GgxDistribution`] accepts.
///
/// Smaller values (including glTF's roughness 0) are raised to it, so that no delta lobe
/// appears: D(h) then stays below 1 / (π · 10⁻⁶) ≈ 3.2 · 10⁵ sr⁻¹ and every value and
/// density stays finite in f32. α = 10⁻³ is already a visually perfect mirror.
pub const MIN_ALPHA: f32 = 1e-3;

/// Largest roughness α a [`GgxDistribution`] accepts (glTF's roughness 1). Keeping α ≤ 1
/// bounds D(h) by 1 / (π αx αy).
pub const MAX_ALPHA: f32 = 1.0;

/// Lower bound on the denominator of [`GgxDistribution::visibility`], so that it stays
/// finite when both directions lie on (or within 10⁻³⁰ of) the horizon.
pub(crate) const MIN_VISIBILITY_DENOMINATOR: f32 = 1e-30;

/// The GGX (Trowbridge–Reitz) distribution of microfacet normals with its Smith
/// masking-shadowing functions.
///
/// Conventions: `h` is a microfacet normal, `wo` and `wi` are the outgoing (viewer) and
/// incoming (light) directions; all are unit vectors in the local frame (z = macro normal).
/// The roughnesses are clamped to [`MIN_ALPHA`] ..= [`MAX_ALPHA`] at construction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GgxDistribution {
    /// Roughness α along the local x axis, in [`MIN_ALPHA`], [`MAX_ALPHA`].
    alpha_x: f32,
    /// Roughness α along the local y axis, in [`MIN_ALPHA`], [`MAX_ALPHA`].
    alpha_y: f32,
}

/// Clamps α to [`MIN_ALPHA`], [`MAX_ALPHA`]; NaN becomes [`MIN_ALPHA`].
#[inline]
fn clamp_alpha(alpha: f32) -> f32 {
    if alpha.is_nan() {
        MIN_ALPHA
    } else {
        alpha.clamp(MIN_ALPHA, MAX_ALPHA)
    }
}

impl GgxDistribution {
    /// Anisotropic distribution with roughness `alpha_x` along x and `alpha_y` along y
    /// (dimensionless slopes' scale). Each is clamped to [`MIN_ALPHA`] ..= [`MAX_ALPHA`]
    /// (NaN becomes [`MIN_ALPHA`]).
    #[inline]
    pub fn new(alpha_x: f32, alpha_y: f32) -> Self {
        GgxDistribution {
            alpha_x: clamp_alpha(alpha_x),
            alpha_y: clamp_alpha(alpha_y),
        }
    }

    /// Isotropic distribution with roughness `alpha` (clamped as in [`Self::new`]).
    #[inline]
    pub fn isotropic(alpha: f32) -> Self {
        Self::new(alpha, alpha)
    }

    /// Isotropic distribution from a perceptual roughness r ∈ [0, 1] with α = r² (glTF 2.0,
    /// Disney/Burley); α is then clamped as in [`Self::new`].
    #[inline]
    pub fn from_roughness(roughness: f32) -> Self {
        Self::isotropic(roughness * roughness)
    }

    /// Roughness α along x, after clamping.
    #[inline]
    pub fn alpha_x(&self) -> f32 {
        self.alpha_x
    }

    /// Roughness α along y, after clamping.
    #[inline]
    pub fn alpha_y(&self) -> f32 {
        self.alpha_y
    }

    /// The distribution's formulas ([`Ggx`]) for one direction.
    #[inline(always)]
    pub(crate) fn formulas(&self) -> Ggx<f32> {
        Ggx {
            alpha_x: self.alpha_x,
            alpha_y: self.alpha_y,
        }
    }

    /// The normal distribution D(h) in 1/sr, normalised so that ∫ D(h) h.z dω_h = 1 over the
    /// upper hemisphere; zero for `h.z ≤ 0`. `h` must be a unit vector. Bounded by
    /// 1 / (π αx αy).
    #[inline]
    pub fn d(&self, h: Vec3) -> f32 {
        self.formulas().d(h.into())
    }

    /// √(w.z² + αx² w.x² + αy² w.y²): |w.z| times √(1 + α² tan² θ), the common factor of
    /// Λ, G1, G2 and the visible-normal density. At least `min(1, α)` for unit `w`.
    #[inline]
    fn projected_length(&self, w: Vec3) -> f32 {
        self.formulas().projected_length(w.into())
    }

    /// Smith's auxiliary function Λ(w) = (√(1 + α² tan² θ) − 1) / 2, with α the roughness
    /// projected on w's azimuth. Uses |w.z| (the masking of whichever side `w` lies on);
    /// +∞ when `w` lies on the horizon.
    #[inline]
    pub fn lambda(&self, w: Vec3) -> f32 {
        let z = w.z.abs();
        if z == 0.0 {
            return f32::INFINITY;
        }
        0.5 * (self.projected_length(w) / z - 1.0).max(0.0)
    }

    /// Smith's masking function G1(w) = 1 / (1 + Λ(w)) ∈ [0, 1], written as
    /// 2|w.z| / (|w.z| + √(w.z² + α² |w_xy|²)) so it is exact and finite at grazing angles;
    /// zero on the horizon.
    #[inline]
    pub fn g1(&self, w: Vec3) -> f32 {
        let z = w.z.abs();
        let denominator = z + self.projected_length(w);
        if denominator > 0.0 {
            2.0 * z / denominator
        } else {
            0.0
        }
    }

    /// Height-correlated Smith masking-shadowing G2(wo, wi) = 1 / (1 + Λ(wo) + Λ(wi))
    /// (Heitz 2014) ∈ [0, 1]; uses |z| of both directions (reflection configuration).
    #[inline]
    pub fn g2(&self, wo: Vec3, wi: Vec3) -> f32 {
        let (zo, zi) = (wo.z.abs(), wi.z.abs());
        let denominator = zi * self.projected_length(wo) + zo * self.projected_length(wi);
        if denominator > 0.0 {
            2.0 * zo * zi / denominator
        } else {
            0.0
        }
    }

    /// The visibility term V = G2(wo, wi) / (4 |wo.z| |wi.z|) in the stable form
    /// 0.5 / (|wi.z| √(wo.z² + α² |wo_xy|²) + |wo.z| √(wi.z² + α² |wi_xy|²)) of the glTF
    /// specification (Appendix B); the specular BRDF is then D(h) F V. The denominator is
    /// bounded below by 10⁻³⁰, so V is finite even for directions on the horizon.
    #[inline]
    pub fn visibility(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.formulas().visibility(wo.into(), wi.into())
    }

    /// Draws a microfacet normal from the distribution of normals visible from `wo`,
    /// D_wo(h) = G1(wo) max(0, wo·h) D(h) / wo.z, with the spherical-cap method of
    /// Dupuy & Benyoub 2023 (equivalent to Heitz 2018, fewer operations).
    ///
    /// `wo` must be a unit vector with `wo.z ≥ 0`; `u` ∈ [0, 1)². The result is a unit
    /// vector with `h.z ≥ 0`; its density is [`Self::visible_normal_pdf`].
    #[inline]
    pub fn sample_visible_normal(&self, wo: Vec3, u: Vec2) -> Vec3 {
        self.formulas().sample_visible_normal(wo.into(), u.into()).into()
    }

    /// Density (1/sr, over microfacet normals `h`) of [`Self::sample_visible_normal`]:
    /// G1(wo) max(0, wo·h) D(h) / wo.z, evaluated as 2 max(0, wo·h) D(h) / (wo.z + √(wo.z² +
    /// α² |wo_xy|²)) so it stays finite at grazing `wo`. Zero when `wo.z < 0` or `h.z ≤ 0`.
    #[inline]
    pub fn visible_normal_pdf(&self, wo: Vec3, h: Vec3) -> f32 {
        self.formulas().visible_normal_pdf(wo.into(), h.into())
    }

    /// Draws an incident direction by reflecting `wo` about a visible normal
    /// ([`Self::sample_visible_normal`]); `None` when the reflection points below the
    /// horizon (`wi.z ≤ 0`), which happens with a probability that grows with roughness
    /// and grazing angle. The density of the result is [`Self::reflection_pdf`].
    #[inline]
    pub fn sample_reflection(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        let h = self.sample_visible_normal(wo, u);
        let wi = reflect(wo, h);
        (wi.z > 0.0).then_some(wi)
    }

    /// Density (1/sr, over `wi`) of [`Self::sample_reflection`]:
    /// D_wo(h) / (4 wo·h) = D(h) / (2 (wo.z + √(wo.z² + α² |wo_xy|²))) with h the half
    /// vector. Zero when `wo.z < 0` or `wi.z ≤ 0`. Integrates to at most 1 over the upper
    /// hemisphere (the missing mass is that of reflections below the horizon).
    #[inline]
    pub fn reflection_pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z < 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let (wo, wi) = (V3::from(wo), V3::from(wi));
        let (h, has_half) = half_vector_or_z(wo, wi);
        self.formulas().reflection_pdf(wo, wi, h, has_half)
    }
}

/// Mirror reflection of `w` about the unit normal `n`: 2 (w·n) n − w (both pointing away
/// from the surface).
#[inline]
pub fn reflect(w: Vec3, n: Vec3) -> Vec3 {
    reflect_about(V3::from(w), V3::from(n)).into()
}

/// The formulas of [`GgxDistribution`] over [`Real`] values, written once for one direction
/// (`f32`, what [`GgxDistribution`]'s methods evaluate) and for [`LANES`] of them (`F32s`,
/// the lane kernels), with masks where one direction would return early: the same bits per
/// lane. The roughnesses are taken as given (a [`GgxDistribution`]'s, already clamped).
///
/// [`LANES`]: crate::lanes::LANES
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Ggx<R> {
    pub alpha_x: R,
    pub alpha_y: R,
}

impl<R: Real> Ggx<R> {
    /// [`GgxDistribution::d`]: D(h) in 1/sr, 0 for h.z ≤ 0.
    #[inline(always)]
    pub fn d(&self, h: V3<R>) -> R {
        let sx = h.x / self.alpha_x;
        let sy = h.y / self.alpha_y;
        let e = sx * sx + sy * sy + h.z * h.z;
        let d = R::splat(1.0) / (R::splat(PI) * self.alpha_x * self.alpha_y * e * e);
        R::select(h.z.le(R::splat(0.0)), R::splat(0.0), d)
    }

    /// √(w.z² + αx² w.x² + αy² w.y²), the length of `w` in the stretched configuration.
    #[inline(always)]
    pub fn projected_length(&self, w: V3<R>) -> R {
        let ax = self.alpha_x * w.x;
        let ay = self.alpha_y * w.y;
        (w.z * w.z + ax * ax + ay * ay).sqrt()
    }

    /// [`GgxDistribution::visibility`]: G2 / (4 |wo.z| |wi.z|) in closed form.
    #[inline(always)]
    pub fn visibility(&self, wo: V3<R>, wi: V3<R>) -> R {
        let denominator = wi.z.abs() * self.projected_length(wo) + wo.z.abs() * self.projected_length(wi);
        R::splat(0.5) / denominator.max(R::splat(MIN_VISIBILITY_DENOMINATOR))
    }

    /// [`GgxDistribution::sample_visible_normal`]: a unit microfacet normal with z ≥ 0.
    #[inline(always)]
    pub fn sample_visible_normal(&self, wo: V3<R>, u: V2<R>) -> V3<R> {
        let zero = R::splat(0.0);
        let wo_std = V3::new(wo.x * self.alpha_x, wo.y * self.alpha_y, wo.z.max(zero)).normalize_or(Vec3::Z);
        let (sin_phi, cos_phi) = sin_cos_turns(u.x);
        let z = (R::splat(1.0) - u.y) * (R::splat(1.0) + wo_std.z) - wo_std.z;
        let sin_theta = (R::splat(1.0) - z * z).max(zero).sqrt();
        let h_std = V3::new(sin_theta * cos_phi, sin_theta * sin_phi, z) + wo_std;
        V3::new(h_std.x * self.alpha_x, h_std.y * self.alpha_y, h_std.z.max(zero)).normalize_or(Vec3::Z)
    }

    /// [`GgxDistribution::visible_normal_pdf`]: 2 max(0, wo·h) D(h) / (wo.z + |wo|_α), 0
    /// where wo.z < 0 or wo·h ≤ 0.
    #[inline(always)]
    pub fn visible_normal_pdf(&self, wo: V3<R>, h: V3<R>) -> R {
        let zero = R::splat(0.0);
        let cos_oh = wo.dot(h);
        let pdf = R::splat(2.0) * cos_oh * self.d(h) / (wo.z + self.projected_length(wo));
        R::select(wo.z.lt(zero) | cos_oh.le(zero), zero, pdf)
    }

    /// [`GgxDistribution::reflection_pdf`] given the half vector `h` of `wo` and `wi`, where
    /// `has_half` ([`half_vector_or_z`]): D(h) / (2 (wo.z + |wo|_α)), 0 where wo.z < 0,
    /// wi.z ≤ 0 or no half vector.
    #[inline(always)]
    pub fn reflection_pdf(&self, wo: V3<R>, wi: V3<R>, h: V3<R>, has_half: R::Mask) -> R {
        let zero = R::splat(0.0);
        let pdf = self.d(h) / (R::splat(2.0) * (wo.z + self.projected_length(wo)));
        R::select(has_half & !wo.z.lt(zero) & wi.z.gt(zero), pdf, zero)
    }
}

/// [`reflect`] over [`Real`] values: `w` mirrored about the unit normal `n`.
#[inline(always)]
pub(crate) fn reflect_about<R: Real>(w: V3<R>, n: V3<R>) -> V3<R> {
    n * (R::splat(2.0) * w.dot(n)) - w
}

/// [`half_vector`] over [`Real`] values: normalize(wo + wi) where it exists (the mask),
/// +z elsewhere (the scalar code's `unwrap_or(Vec3::Z)`).
#[inline(always)]
pub(crate) fn half_vector_or_z<R: Real>(wo: V3<R>, wi: V3<R>) -> (V3<R>, R::Mask) {
    let (h, has_half) = (wo + wi).try_normalize();
    (has_half.select(h, V3::splat(Vec3::Z)), has_half)
}

/// The reflection half vector normalize(wo + wi); `None` when `wo + wi` is (nearly) zero.
#[inline]
pub fn half_vector(wo: Vec3, wi: Vec3) -> Option<Vec3> {
    (wo + wi).try_normalize()
}

/// Schlick's weight (1 − cos θ)⁵ with cos θ clamped to [0, 1]; cos θ is the cosine between a
/// direction and the microfacet normal (wo·h).
#[inline]
pub fn schlick_weight<R: Real>(cos_theta: R) -> R {
    let m = (R::splat(1.0) - cos_theta).clamp(0.0, 1.0);
    let m2 = m * m;
    m2 * m2 * m
}

/// Schlick's Fresnel approximation F = F0 + (1 − F0)(1 − cos θ)⁵ per channel, with `f0`
/// the reflectance at normal incidence and `cos_theta` as in [`schlick_weight`].
#[inline]
pub fn fresnel_schlick(f0: Rgb, cos_theta: f32) -> Rgb {
    f0 + (Rgb::ONE - f0) * schlick_weight(cos_theta)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::chi2::{self, Chi2Config};
    use std::f64::consts::PI as PI64;

    /// Number of chi-square tests in this module, for the Šidák correction.
    const CHI2_TESTS: usize = 5;

    fn spherical(theta: f32, phi: f32) -> Vec3 {
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    /// ∫ g(ω) dω over the upper hemisphere by the midpoint rule in (t, φ) with
    /// θ = (π/2) t², which concentrates nodes around the normal.
    fn integrate_hemisphere(g: impl Fn(Vec3) -> f32, nt: usize, nphi: usize) -> f64 {
        let mut sum = 0.0f64;
        for i in 0..nt {
            let t = (i as f64 + 0.5) / nt as f64;
            let theta = 0.5 * PI64 * t * t;
            let jacobian = PI64 * t * theta.sin(); // dθ/dt · sin θ
            let mut row = 0.0f64;
            for j in 0..nphi {
                let phi = 2.0 * PI64 * (j as f64 + 0.5) / nphi as f64;
                row += g(spherical(theta as f32, phi as f32)) as f64;
            }
            sum += row * jacobian;
        }
        sum * (1.0 / nt as f64) * (2.0 * PI64 / nphi as f64)
    }

    #[test]
    fn alpha_is_clamped() {
        let g = GgxDistribution::new(0.0, f32::NAN);
        assert_eq!(g.alpha_x(), MIN_ALPHA);
        assert_eq!(g.alpha_y(), MIN_ALPHA);
        assert_eq!(GgxDistribution::isotropic(7.0).alpha_x(), MAX_ALPHA);
        assert_eq!(GgxDistribution::from_roughness(0.5).alpha_y(), 0.25);
    }

    #[test]
    fn d_is_normalised() {
        for (ax, ay) in [(0.05, 0.05), (0.3, 0.3), (1.0, 1.0), (0.1, 0.4)] {
            let g = GgxDistribution::new(ax, ay);
            let integral = integrate_hemisphere(|h| g.d(h) * h.z, 4000, 360);
            assert!(
                (integral - 1.0).abs() < 2e-3,
                "α = ({ax}, {ay}): {integral}"
            );
        }
    }

    #[test]
    fn d_known_value_at_normal() {
        let g = GgxDistribution::isotropic(0.5);
        assert!((g.d(Vec3::Z) - 1.0 / (PI * 0.25)).abs() < 1e-5);
        assert_eq!(g.d(-Vec3::Z), 0.0);
    }

    #[test]
    fn visible_normal_pdf_is_normalised() {
        for (ax, ay) in [(0.05, 0.05), (0.3, 0.3), (1.0, 1.0), (0.1, 0.4)] {
            let g = GgxDistribution::new(ax, ay);
            for theta_o in [0.0f32, 0.7, 1.3, 85f32.to_radians()] {
                let wo = spherical(theta_o, 0.4);
                let integral = integrate_hemisphere(|h| g.visible_normal_pdf(wo, h), 3000, 360);
                assert!(
                    (integral - 1.0).abs() < 3e-3,
                    "α = ({ax}, {ay}), θo = {theta_o}: {integral}"
                );
            }
        }
    }

    #[test]
    fn reflection_pdf_integrates_to_at_most_one() {
        for alpha in [0.05f32, 0.3, 1.0] {
            let g = GgxDistribution::isotropic(alpha);
            for theta_o in [0.0f32, 1.0, 85f32.to_radians()] {
                let wo = spherical(theta_o, 0.0);
                let integral = integrate_hemisphere(|wi| g.reflection_pdf(wo, wi), 3000, 360);
                assert!(integral <= 1.002, "α = {alpha}, θo = {theta_o}: {integral}");
                if theta_o == 0.0 {
                    // At normal incidence wi stays above the horizon iff θh < 45°, which
                    // has probability tan² 45° / (α² + tan² 45°) under D(h) cos θh.
                    let expected = 1.0 / (1.0 + (alpha * alpha) as f64);
                    assert!(
                        (integral - expected).abs() < 2e-3,
                        "α = {alpha}: {integral}"
                    );
                }
            }
        }
    }

    #[test]
    fn masking_relations() {
        let g = GgxDistribution::new(0.2, 0.6);
        for (wo, wi) in [
            (spherical(0.3, 0.1), spherical(1.2, 2.0)),
            (spherical(1.5, -1.0), spherical(0.1, 0.5)),
            (spherical(1.0, 0.7), spherical(1.0, 0.7)),
        ] {
            assert!((g.g1(wo) - 1.0 / (1.0 + g.lambda(wo))).abs() < 1e-5);
            let g2 = g.g2(wo, wi);
            assert!((g2 - 1.0 / (1.0 + g.lambda(wo) + g.lambda(wi))).abs() < 1e-5);
            assert!(g2 <= g.g1(wo).min(g.g1(wi)) + 1e-6);
            assert!(g2 >= g.g1(wo) * g.g1(wi) - 1e-6);
            let v = g.visibility(wo, wi);
            assert!((v - g2 / (4.0 * wo.z * wi.z)).abs() < 1e-4 * v);
        }
        assert_eq!(g.g1(Vec3::X), 0.0);
        assert_eq!(g.lambda(Vec3::X), f32::INFINITY);
        assert!(g.visibility(Vec3::X, Vec3::Y).is_finite());
    }

    #[test]
    fn visible_normals_are_unit_and_visible() {
        let g = GgxDistribution::new(0.05, 0.5);
        for wo in [
            Vec3::Z,
            spherical(1.0, 1.0),
            Vec3::new(1.0, 0.0, 1e-7).normalize(),
        ] {
            for i in 0..32 {
                for j in 0..32 {
                    let u = Vec2::new((i as f32 + 0.5) / 32.0, j as f32 / 32.0);
                    let h = g.sample_visible_normal(wo, u);
                    assert!((h.length() - 1.0).abs() < 1e-5, "{h}");
                    assert!(h.z >= 0.0 && wo.dot(h) > -1e-4, "{wo} {h}");
                    assert!(g.visible_normal_pdf(wo, h).is_finite());
                }
            }
        }
    }

    #[test]
    fn fresnel_schlick_limits() {
        let f0 = Rgb::new(0.04, 0.5, 1.0);
        assert!((fresnel_schlick(f0, 1.0) - f0).length() < 1e-6);
        assert!((fresnel_schlick(f0, 0.0) - Rgb::ONE).length() < 1e-6);
        assert_eq!(schlick_weight(2.0), 0.0);
        assert_eq!(schlick_weight(-1.0), 1.0);
    }

    fn vndf_config() -> Chi2Config {
        Chi2Config::default()
            .with_sample_count(500_000)
            .with_test_count(CHI2_TESTS)
    }

    #[test]
    fn vndf_sampling_passes_chi2() {
        for ((ax, ay), theta_o) in [
            ((0.3, 0.3), 0.5f32),
            ((0.1, 0.5), 1.2),
            ((0.05, 0.05), 85f32.to_radians()),
            ((1.0, 1.0), 0.0),
        ] {
            let g = GgxDistribution::new(ax, ay);
            let wo = spherical(theta_o, 0.8);
            let result = chi2::test_sampler(
                |u, _| Some(g.sample_visible_normal(wo, u)),
                |h| g.visible_normal_pdf(wo, h),
                &vndf_config(),
            );
            assert!(
                result.passed(),
                "α = ({ax}, {ay}), θo = {theta_o}\n{result}"
            );
        }
    }

    #[test]
    fn vndf_chi2_detects_wrong_roughness() {
        let sampled = GgxDistribution::isotropic(0.3);
        let claimed = GgxDistribution::isotropic(0.33);
        let wo = spherical(0.6, 0.0);
        let result = chi2::test_sampler(
            |u, _| Some(sampled.sample_visible_normal(wo, u)),
            |h| claimed.visible_normal_pdf(wo, h),
            &vndf_config(),
        );
        assert!(!result.passed(), "{result}");
    }
}
