//! The glTF 2.0 metallic-roughness material (glTF 2.0 specification, Appendix B), with an
//! energy-conserving diffuse weighting in place of the specification's `fresnel_mix`.
//!
//! With c = `base_color`, m = `metallic`, α = `roughness`², h = normalize(wo + wi),
//! μo = wo.z, μi = wi.z (cosines to the macroscopic normal) and D, V the GGX distribution
//! and height-correlated Smith visibility ([`GgxDistribution::d`],
//! [`GgxDistribution::visibility`]):
//!
//! ```text
//! specular  = D(h) V(wo, wi)                          (the spec's specular_brdf, 1/sr)
//! F         = F0 + (1 − F0)(1 − wo·h)⁵,  F0 = mix(0.04, c, m)
//!                                   (the spec's conductor_fresnel and dielectric Fresnel,
//!                                    blended by m as the spec's mix does)
//! F_d(μ)    = 0.04 + 0.96 (1 − μ)⁵                    (dielectric Schlick Fresnel, ior 1.5)
//! T(μ)      = 1 − F_d(μ) = 0.96 (1 − (1 − μ)⁵)         (transmittance at the macro angle)
//! diffuse   = (1 − m) c / π · k T(μo) T(μi),  k = 0.995 / T̄ = 0.995 · 35/32 ≈ 1.0883
//!             with T̄ = 2 ∫₀¹ T(μ) μ dμ = 0.96 (1 − 2/42) = 32/35
//!             (the cosine-weighted hemispherical mean of T)
//! f_r       = F specular + diffuse
//! ```
//!
//! The specular lobe is the specification's: Fresnel uses the angle between `wo` and the
//! microfacet normal (wo·h = wi·h), so it is reciprocal, and a metal (m = 1) is exactly the
//! spec's `conductor_fresnel(c, specular_brdf)`. Single scattering only: rough surfaces lose
//! energy (no multiple-scattering compensation; white metal with roughness 1 reflects
//! 1 − ln 2 ≈ 0.31 at normal incidence).
//!
//! # Departure from the glTF specification
//! The specification's `fresnel_mix` weights the diffuse base by 1 − F_d(wo·h), at the half
//! vector. Most diffuse directions then see wo·h ≈ 1 and keep ≈ 96 % of the diffuse albedo
//! even when `wo` is grazing, while the specular lobe's own Fresnel grows towards 1: a
//! white dielectric reflects **more energy than it receives** at grazing view angles
//! (directional albedo ≈ 1.025 at θo = 60° and ≈ 1.22 at θo = 80° for roughness 0.3,
//! ≈ 1.045 at 80° for roughness 0.6, ≈ 1.010 at 89° for roughness 1). A path tracer must
//! not gain energy, so this model departs from the specification on purpose.
//!
//! The diffuse lobe is instead weighted by the interface's transmittance at *both*
//! macroscopic angles, T(μo) T(μi), as in the coupled diffuse terms of Ashikhmin & Shirley
//! (2000) and Kelemen & Szirmay-Kalos (2001). The product is symmetric in wo and wi, so f_r
//! stays reciprocal. Its energy balance for a white dielectric: ∫ diffuse cos θi dωi =
//! 0.995 T(μo), so the directional albedo is E_s(μo) + 0.995 (1 − F_d(μo)), with E_s the
//! albedo of the specular lobe. For a smooth surface E_s ≈ F_d(μo) (a mirror) and the albedo
//! is ≈ 0.995 + 0.005 F_d(μo) < 1. On rough surfaces E_s can exceed F_d(μo) slightly (Schlick's
//! Fresnel is convex in wo·h); a quadrature sweep over roughness ∈ [0, 1] in steps of
//! 0.02 and θo ∈ [0°, 89.9°] in steps of 1° or less found at most 0.0014 (1 − F_d(μo))
//! (roughness 0.28, θo = 55°, albedo 0.9966), so the 0.5 % the diffuse lobe keeps back (the
//! factor 0.995 in k) keeps the albedo below 1 everywhere. The largest values, ≈ 0.998, are
//! those of smooth surfaces near grazing angles, where 0.995 + 0.005 F_d(μo) tends to 1.
//! Coloured and partly metallic materials reflect less than the white ones (f_r grows with
//! every channel of c and is affine in m), and metals are unchanged.
//!
//! The price is energy *loss* towards grazing angles on rough dielectrics, where the
//! single-scattering specular lobe falls well short of F_d(μo): a white dielectric
//! reflects ≈ 0.995 at normal incidence (the spec's form ≈ 1.0), ≈ 0.864 at θo = 80° and
//! ≈ 0.505 at 89° for roughness 0.3, ≈ 0.629 at 80° and ≈ 0.156 at 89° for roughness 1.
//! Weighting by 1 − E_s (tabulated) instead of 1 − F_d would recover that energy; rough
//! metals lose energy at grazing angles in the same way.
//!
//! Sampling picks the specular lobe (GGX visible normals, [`GgxDistribution::sample_reflection`])
//! or the diffuse lobe (cosine-weighted) with the probability of
//! [`MetallicRoughness::specular_probability`]; [`Bxdf::pdf`] is the exact mixture density
//! of both, so multiple importance sampling is unbiased. Reflection only: value and density
//! are zero when `wo.z ≤ 0` or `wi.z ≤ 0`.
//!
//! # Example
//! ```
//! use glam::{Vec2, Vec3};
//! use renderer::bsdf::{Bxdf, MetallicRoughness};
//! use renderer::Rgb;
//!
//! let gold = MetallicRoughness::new(Rgb::new(1.0, 0.78, 0.34), 1.0, 0.3);
//! let wo = Vec3::new(0.0, 0.6, 0.8);
//! if let Some(s) = gold.sample(wo, Vec2::new(0.2, 0.9), 0.5) {
//!     assert!((gold.pdf(wo, s.wi) - s.pdf).abs() <= 1e-3 * s.pdf);
//! }
//! ```

use super::microfacet::{half_vector_or_z, reflect_about, schlick_weight, Ggx, GgxDistribution};
use super::{BsdfSample, Bxdf, RealBxdf, RealSample};
use crate::color::luminance_of;
use crate::lanes::{choose, F32s, MaskOps, Real, SetLane, V2, V3};
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use crate::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// Reflectance at normal incidence of glTF's dielectric (index of refraction 1.5).
pub const DIELECTRIC_F0: f32 = 0.04;

/// Cosine-weighted hemispherical mean of the dielectric's transmittance,
/// T̄ = 2 ∫₀¹ (1 − F_d(μ)) μ dμ = (1 − F0)(1 − 2 ∫₀¹ (1 − μ)⁵ μ dμ) = (1 − F0)(1 − 1/21)
/// = 32/35 for F0 = 0.04 (dimensionless): the fraction of uniformly diffuse light that
/// leaves through the interface.
const DIELECTRIC_MEAN_TRANSMITTANCE: f32 = (1.0 - DIELECTRIC_F0) * (20.0 / 21.0);

/// Fraction of the transmitted energy the diffuse lobe returns (dimensionless). Below 1 to
/// leave room for rough specular lobes, whose albedo exceeds F_d(μo) by up to 0.14 % of
/// 1 − F_d(μo) (module documentation).
pub(crate) const DIFFUSE_RETURN: f32 = 0.995;

/// The diffuse normalisation k = [`DIFFUSE_RETURN`] / T̄ ≈ 1.0883, so that a white diffuse
/// base returns 0.995 T(μo) of the light arriving from `wo` (dimensionless).
const DIFFUSE_SCALE: f32 = DIFFUSE_RETURN / DIELECTRIC_MEAN_TRANSMITTANCE;

/// Bounds of the probability of sampling the specular lobe when both lobes are non-zero,
/// so neither lobe is starved (its variance would grow without bound).
pub(crate) const MIN_LOBE_PROBABILITY: f32 = 0.1;

/// The glTF 2.0 metallic-roughness BRDF with an energy-conserving diffuse weighting (see
/// the module documentation for the formula and how it departs from the specification).
///
/// The fields are expected in [0, 1]; [`MetallicRoughness::new`] clamps them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetallicRoughness {
    /// Linear RGB base colour, each channel in [0, 1]: the diffuse colour of the dielectric
    /// (its albedo before the interface's transmittance) and the normal-incidence
    /// reflectance F0 of the metal.
    pub base_color: Rgb,
    /// Metalness in [0, 1]: 0 = dielectric (diffuse + 4 % specular), 1 = metal; values in
    /// between blend the two BRDFs linearly.
    pub metallic: f32,
    /// Perceptual roughness r in [0, 1]; the GGX roughness is α = r², raised to
    /// [`super::microfacet::MIN_ALPHA`] so that roughness 0 stays a finite (very sharp) lobe.
    pub roughness: f32,
    /// The dielectric's reflectance at normal incidence per channel, in [0, 1]
    /// ([`DIELECTRIC_F0`] by default; `KHR_materials_ior` and `KHR_materials_specular` set
    /// it: see [`MetallicRoughness::with_dielectric`]).
    pub dielectric_f0: Rgb,
    /// The dielectric's reflectance at grazing incidence, in [0, 1] (1 by default;
    /// `KHR_materials_specular`'s specular factor).
    pub dielectric_f90: f32,
}

/// Clamps to [0, 1]; NaN becomes 0.
#[inline]
fn clamp01(x: f32) -> f32 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(0.0, 1.0)
    }
}

impl MetallicRoughness {
    /// The material with `base_color` (per channel), `metallic` and `roughness` clamped to
    /// [0, 1]; NaN inputs become 0.
    #[inline]
    pub fn new(base_color: Rgb, metallic: f32, roughness: f32) -> Self {
        MetallicRoughness {
            base_color: base_color.max(Rgb::ZERO).min(Rgb::ONE),
            metallic: clamp01(metallic),
            roughness: clamp01(roughness),
            dielectric_f0: Rgb::splat(DIELECTRIC_F0),
            dielectric_f90: 1.0,
        }
    }

    /// The same material with the dielectric's Fresnel reflectance F_d(μ) = f0 + (f90 − f0)
    /// (1 − μ)⁵ (`KHR_materials_specular`: f0 = min(((ior − 1)/(ior + 1))² · specular
    /// colour, 1) · specular, f90 = specular), clamped to [0, 1] with f0 ≤ f90 per channel;
    /// NaN becomes 0. The diffuse lobe's normalisation follows (module documentation, with
    /// T̄ = (1 − f0) − (f90 − f0)/21), and so does the metal's F90, mix(f90, 1, metallic).
    #[inline]
    pub fn with_dielectric(self, f0: Rgb, f90: f32) -> Self {
        let f90 = clamp01(f90);
        let f0 = Rgb::new(clamp01(f0.x), clamp01(f0.y), clamp01(f0.z)).min(Rgb::splat(f90));
        MetallicRoughness {
            dielectric_f0: f0,
            dielectric_f90: f90,
            ..self
        }
    }

    /// The GGX distribution of the specular lobe: isotropic, α = roughness².
    #[inline]
    pub fn distribution(&self) -> GgxDistribution {
        GgxDistribution::from_roughness(self.roughness)
    }

    /// Reflectance at normal incidence, F0 = mix(dielectric f0 (0.04), base_color, metallic).
    #[inline]
    pub fn f0(&self) -> Rgb {
        self.dielectric_f0.lerp(self.base_color, self.metallic)
    }

    /// Reflectance at grazing incidence, F90 = mix(dielectric f90 (1), 1, metallic).
    #[inline]
    pub(crate) fn f90(&self) -> f32 {
        self.dielectric_f90 + (1.0 - self.dielectric_f90) * self.metallic
    }



    /// The diffuse normalisation per channel, k = 0.995 / T̄ with T̄ = (1 − f0) − (f90 − f0)/21
    /// the cosine-weighted mean of the dielectric's transmittance (zero where nothing is
    /// transmitted).
    #[inline]
    pub(crate) fn diffuse_scale(&self) -> Rgb {
        if self.dielectric_f0 == Rgb::splat(DIELECTRIC_F0) && self.dielectric_f90 == 1.0 {
            return Rgb::splat(DIFFUSE_SCALE);
        }
        let (f0, f90) = (self.dielectric_f0, Rgb::splat(self.dielectric_f90));
        let mean = Rgb::ONE - f0 - (f90 - f0) * (1.0 / 21.0);
        Rgb::select(mean.cmpgt(Rgb::ZERO), DIFFUSE_RETURN / mean, Rgb::ZERO)
    }

    /// The diffuse albedo before Fresnel weighting, (1 − metallic) · base_color.
    #[inline]
    pub(crate) fn diffuse_color(&self) -> Rgb {
        self.base_color * (1.0 - self.metallic)
    }



    /// Probability with which [`Bxdf::sample`] draws from the specular lobe given `wo`.
    ///
    /// Estimated lobe albedos (luminance): specular E_s = lum(F(wo.z)), with Schlick's
    /// Fresnel at the macroscopic angle, and diffuse E_d = 0.995 lum((1 − m) c) T(wo.z), the
    /// diffuse lobe's exact albedo; the probability is E_s / (E_s + E_d), clamped to
    /// [0.1, 0.9] so neither lobe is starved. It is exactly 1 when the diffuse lobe vanishes
    /// (metallic 1 or black base colour), so a pure metal spends no samples on it.
    #[inline]
    pub fn specular_probability(&self, wo: Vec3) -> f32 {
        self.lobes().specular_probability(wo.into())
    }

    /// The BSDF's parameters as its formulas use them ([`MetallicRoughnessLobes`]).
    #[inline(always)]
    pub(crate) fn lobes(&self) -> MetallicRoughnessLobes<f32> {
        let distribution = self.distribution();
        MetallicRoughnessLobes {
            ggx: distribution.formulas(),
            f0: self.f0().into(),
            f90: self.f90(),
            t_base: (Rgb::ONE - self.dielectric_f0).into(),
            t_slope: (Rgb::splat(self.dielectric_f90) - self.dielectric_f0).into(),
            diffuse_color: self.diffuse_color().into(),
            diffuse_scale_over_pi: (self.diffuse_scale() * FRAC_1_PI).into(),
        }
    }
}

impl Bxdf for MetallicRoughness {
    /// f_r in 1/sr (module documentation); zero when either direction is below the horizon.
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        let (wo, wi) = (V3::from(wo), V3::from(wi));
        let (h, _) = half_vector_or_z(wo, wi);
        self.lobes().value(wo, wi, h).into()
    }

    /// The exact mixture density p_s · pdf_GGX(wi) + (1 − p_s) · cos θi / π in 1/sr, with
    /// p_s = [`MetallicRoughness::specular_probability`] and pdf_GGX =
    /// [`GgxDistribution::reflection_pdf`]; zero below either horizon.
    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let lobes = self.lobes();
        let (wo, wi) = (V3::from(wo), V3::from(wi));
        let (h, has_half) = half_vector_or_z(wo, wi);
        lobes.density(lobes.specular_probability(wo), wo, wi, h, has_half)
    }

    /// Picks the specular lobe when `uc < p_s` (then `u` drives the visible-normal sample),
    /// the diffuse lobe otherwise (then `u` drives a cosine-weighted sample). `None` when
    /// `wo` is below the horizon or the specular reflection leaves the upper hemisphere.
    #[inline]
    fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let lobes = self.lobes();
        let wo = V3::from(wo);
        lobes.sample(lobes.at_wo(wo), wo, u.into(), uc).into_option()
    }

    /// Value and density in one call (the parameters are derived once).
    #[inline]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let lobes = self.lobes();
        let wo = V3::from(wo);
        let (f, pdf) = lobes.eval_pdf(lobes.at_wo(wo), wo, wi.into());
        (f.into(), pdf)
    }
}

/// The metallic-roughness BSDF's formulas over [`Real`] values, with its parameters as the
/// formulas use them: for one shading point ([`MetallicRoughness::lobes`]) or for
/// [`LANES`](crate::lanes::LANES) points with their own materials (the lane kernels fill
/// one lane per vertex with [`MetallicRoughnessLobes::set`]). The module documentation has
/// the formulas; conventions are [`crate::bsdf`]'s.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct MetallicRoughnessLobes<R> {
    /// The specular lobe's GGX distribution (isotropic, α = roughness², clamped).
    ggx: Ggx<R>,
    /// Reflectance at normal and at grazing incidence of the specular lobe.
    f0: V3<R>,
    f90: R,
    /// The dielectric's transmittance T(μ) = `t_base` − `t_slope` (1 − μ)⁵.
    t_base: V3<R>,
    t_slope: V3<R>,
    /// (1 − metallic) · base colour.
    diffuse_color: V3<R>,
    /// The diffuse normalisation k divided by π.
    diffuse_scale_over_pi: V3<R>,
}

impl MetallicRoughnessLobes<F32s> {
    /// Sets lane `i` to one shading point's parameters.
    #[inline]
    pub fn set(&mut self, i: usize, one: &MetallicRoughnessLobes<f32>) {
        self.ggx.alpha_x.set_lane(i, one.ggx.alpha_x);
        self.ggx.alpha_y.set_lane(i, one.ggx.alpha_y);
        self.f0.set_lane(i, one.f0);
        self.f90.set_lane(i, one.f90);
        self.t_base.set_lane(i, one.t_base);
        self.t_slope.set_lane(i, one.t_slope);
        self.diffuse_color.set_lane(i, one.diffuse_color);
        self.diffuse_scale_over_pi.set_lane(i, one.diffuse_scale_over_pi);
    }
}

impl<R: Real> MetallicRoughnessLobes<R> {
    /// The specular lobe's Fresnel factor F0 + (F90 − F0)(1 − cos θ)⁵.
    #[inline(always)]
    fn fresnel(&self, cos_theta: R) -> V3<R> {
        self.f0 + (V3::new(self.f90, self.f90, self.f90) - self.f0) * schlick_weight(cos_theta)
    }

    /// The dielectric interface's transmittance T(μ) = 1 − F_d(μ) per channel at the
    /// macroscopic cosine `cos_theta` (clamped to [0, 1] by the Schlick weight).
    #[inline(always)]
    fn transmittance(&self, cos_theta: R) -> V3<R> {
        self.t_base - self.t_slope * schlick_weight(cos_theta)
    }

    /// [`MetallicRoughness::specular_probability`]: E_s / (E_s + E_d) clamped to [0.1, 0.9],
    /// 1 where the diffuse lobe vanishes.
    #[inline(always)]
    pub fn specular_probability(&self, wo: V3<R>) -> R {
        let zero = R::splat(0.0);
        let cos_o = wo.z.clamp(0.0, 1.0);
        let specular = luminance_of(self.fresnel(cos_o));
        let diffuse = luminance_of(self.diffuse_color * self.transmittance(cos_o)) * DIFFUSE_RETURN;
        let total = specular + diffuse;
        let p = R::select(total.gt(zero), specular / total, R::splat(0.5));
        let p = p.clamp(MIN_LOBE_PROBABILITY, 1.0 - MIN_LOBE_PROBABILITY);
        R::select(self.diffuse_color.max_element().le(zero), R::splat(1.0), p)
    }

    /// f_r for directions above the horizon with half vector `h`: F D V + (1 − m) c k
    /// T(μo) T(μi) / π.
    #[inline(always)]
    pub fn value(&self, wo: V3<R>, wi: V3<R>, h: V3<R>) -> V3<R> {
        let specular = self.fresnel(wo.dot(h)) * (self.ggx.d(h) * self.ggx.visibility(wo, wi));
        let transmittance = self.transmittance(wo.z) * self.transmittance(wi.z);
        specular + self.diffuse_color * transmittance * self.diffuse_scale_over_pi
    }

    /// The mixture density p_s pdf_GGX + (1 − p_s) cos θi / π for directions above the
    /// horizon, with the half vector `h` (where `has_half`: [`half_vector_or_z`]).
    #[inline(always)]
    pub fn density(&self, p_specular: R, wo: V3<R>, wi: V3<R>, h: V3<R>, has_half: R::Mask) -> R {
        p_specular * self.ggx.reflection_pdf(wo, wi, h, has_half) + (R::splat(1.0) - p_specular) * cosine_hemisphere_pdf(wi.z)
    }
}

impl<R: Real> RealBxdf<R> for MetallicRoughnessLobes<R> {
    /// The probability of sampling the specular lobe.
    type AtWo = R;

    #[inline(always)]
    fn at_wo(&self, wo: V3<R>) -> R {
        self.specular_probability(wo)
    }

    #[inline(always)]
    fn eval_pdf(&self, p_specular: R, wo: V3<R>, wi: V3<R>) -> (V3<R>, R) {
        let zero = R::splat(0.0);
        let above = wo.z.gt(zero) & wi.z.gt(zero);
        if !above.any() {
            return (V3::default(), zero);
        }
        let (h, has_half) = half_vector_or_z(wo, wi);
        let f = self.value(wo, wi, h);
        let pdf = self.density(p_specular, wo, wi, h, has_half);
        (above.select(f, V3::default()), R::select(above, pdf, zero))
    }

    /// The specular lobe (visible normals) where `uc` is below `p_specular`, the
    /// cosine-weighted diffuse lobe elsewhere.
    #[inline(always)]
    fn sample(&self, p_specular: R, wo: V3<R>, u: V2<R>, uc: R) -> RealSample<R> {
        let zero = R::splat(0.0);
        let specular = uc.lt(p_specular) | p_specular.ge(R::splat(1.0));
        let wi = choose!(specular, reflect_about(wo, self.ggx.sample_visible_normal(wo, u)), cosine_hemisphere(u));
        let (h, has_half) = half_vector_or_z(wo, wi);
        let pdf = self.density(p_specular, wo, wi, h, has_half);
        let ok = wo.z.gt(zero) & wi.z.gt(zero) & pdf.gt(zero) & pdf.is_finite();
        RealSample::new(ok, wi, self.value(wo, wi, h), pdf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::microfacet::MIN_ALPHA;
    use crate::testing::chi2::{self, Chi2Config, Chi2Domain};
    use glam::DVec3;
    use std::f32::consts::PI;
    use std::f64::consts::PI as PI64;

    /// Number of chi-square tests in this module, for the Šidák correction.
    const CHI2_TESTS: usize = 18;

    fn direction(theta_degrees: f32, phi: f32) -> Vec3 {
        let theta = theta_degrees.to_radians();
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    /// Directional albedo ρ(θo) of one channel, with base colour `base`, of the model in the
    /// module documentation, by quadrature of the formula written out again in f64 (it does
    /// not call the implementation). `wo` lies in the xz plane at `theta_degrees` from z.
    ///
    /// Specular lobe, over half vectors: with wi = 2 (wo·h) h − wo, dωi = 4 (wo·h) dωh, and
    /// the substitution u = tan²θh / (α² + tan²θh) (the CDF of D(h) cos θh in θh) turns
    /// D(h) cos θh dωh into du dφ / 2π, so ρ_s = ∫∫ F V μi 4 (wo·h) / cos θh du dφ / 2π over
    /// wo·h > 0, μi > 0. At grazing `wo` that integrand grows like 1 / cos θh ∝ (1 − u)^(−½)
    /// as u → 1, so u = 1 − s² (du = 2s ds) makes it bounded; then the midpoint rule in s
    /// and φ ∈ [0, π] (the integrand is even in φ). Diffuse lobe:
    /// ρ_d = (1 − m) base k T(μo) ∫₀¹ T(μ) 2μ dμ with the midpoint rule in μ. Accurate to
    /// ≈ 10⁻⁵ (≈ 2 · 10⁻⁴ for sharp bright lobes at θo ≥ 89°, where the μi > 0 cut-off
    /// crosses the grid); checked against 1 − ln 2 in `reference_quadrature_anchors`.
    fn reference_albedo(base: f64, metallic: f64, roughness: f64, theta_degrees: f64) -> f64 {
        reference_albedo_with(base, metallic, roughness, theta_degrees, 0.04, 1.0)
    }

    /// [`reference_albedo`] with the dielectric's Fresnel F_d(μ) = f0 + (f90 − f0)(1 − μ)⁵
    /// (`with_dielectric`), the metal's F90 = mix(f90, 1, metallic) and the diffuse
    /// normalisation k = 0.995 / T̄ with T̄ by quadrature.
    fn reference_albedo_with(base: f64, metallic: f64, roughness: f64, theta_degrees: f64, dielectric_f0: f64, dielectric_f90: f64) -> f64 {
        const S_NODES: usize = 512;
        const PHI_NODES: usize = 96;
        const MU_NODES: usize = 2048;
        let alpha = (roughness * roughness).clamp(MIN_ALPHA as f64, 1.0);
        let alpha2 = alpha * alpha;
        let theta = theta_degrees.to_radians();
        let wo = DVec3::new(theta.sin(), 0.0, theta.cos());
        let f0 = dielectric_f0 * (1.0 - metallic) + base * metallic;
        let f90 = dielectric_f90 * (1.0 - metallic) + metallic;
        let projected = |w: DVec3| (w.z * w.z + alpha2 * (w.x * w.x + w.y * w.y)).sqrt();
        let azimuths: Vec<(f64, f64)> = (0..PHI_NODES)
            .map(|j| (PI64 * (j as f64 + 0.5) / PHI_NODES as f64).sin_cos())
            .collect();
        let mut specular = 0.0;
        for i in 0..S_NODES {
            let s = (i as f64 + 0.5) / S_NODES as f64;
            let u = 1.0 - s * s;
            let tan2 = alpha2 * u / (s * s);
            let cos_h = 1.0 / (1.0 + tan2).sqrt();
            let sin_h = tan2.sqrt() * cos_h;
            for &(sin_phi, cos_phi) in &azimuths {
                let h = DVec3::new(sin_h * cos_phi, sin_h * sin_phi, cos_h);
                let cos_oh = wo.dot(h);
                let wi = 2.0 * cos_oh * h - wo;
                if cos_oh <= 0.0 || wi.z <= 0.0 {
                    continue;
                }
                let v = 0.5 / (wi.z * projected(wo) + wo.z * projected(wi));
                let fresnel = f0 + (f90 - f0) * (1.0 - cos_oh).max(0.0).powi(5);
                specular += fresnel * v * wi.z * 4.0 * cos_oh / cos_h * 2.0 * s;
            }
        }
        specular /= (S_NODES * PHI_NODES) as f64;
        let transmittance = |mu: f64| 1.0 - dielectric_f0 - (dielectric_f90 - dielectric_f0) * (1.0 - mu).powi(5);
        let mean_transmittance = (0..MU_NODES)
            .map(|i| {
                let mu = (i as f64 + 0.5) / MU_NODES as f64;
                transmittance(mu) * 2.0 * mu
            })
            .sum::<f64>()
            / MU_NODES as f64;
        if mean_transmittance <= 0.0 {
            return specular;
        }
        let k = 0.995 / mean_transmittance;
        specular + (1.0 - metallic) * base * k * transmittance(wo.z) * mean_transmittance
    }

    fn chi2_config() -> Chi2Config {
        Chi2Config::default()
            .with_sample_count(400_000)
            .with_test_count(CHI2_TESTS)
    }

    #[test]
    fn new_clamps_inputs() {
        let m = MetallicRoughness::new(Rgb::new(-1.0, 2.0, f32::NAN), 3.0, f32::NAN);
        assert_eq!(m.base_color, Rgb::new(0.0, 1.0, 0.0));
        assert_eq!(m.metallic, 1.0);
        assert_eq!(m.roughness, 0.0);
    }

    #[test]
    fn known_values_at_normal_incidence() {
        let c = Rgb::new(0.9, 0.5, 0.2);
        let r = 0.5f32;
        let alpha2 = r.powi(4);
        // h = n, wo·h = 1: D = 1 / (π α²), V = 1/4, F = F0.
        let metal = MetallicRoughness::new(c, 1.0, r);
        let expected = c / (4.0 * PI * alpha2);
        assert!((metal.eval(Vec3::Z, Vec3::Z) - expected).length() < 1e-5 * expected.length());
        // Diffuse: T(1) = 0.96 at both angles and k = 0.995 · 35/32 = 1.088 281 25, so
        // (1 − m) c k T(1)² / π = c · 0.9216 · 1.088 281 25 / π = c · 1.002 96 / π.
        let plastic = MetallicRoughness::new(c, 0.0, r);
        let expected = Rgb::splat(0.04 / (4.0 * PI * alpha2)) + c * (1.002_96 / PI);
        assert!((plastic.eval(Vec3::Z, Vec3::Z) - expected).length() < 1e-5);
        // Opposite azimuths at 45°: h = n, wo·h = cos 45°, w = (1 − 1/√2)⁵ = 0.002 155 5, so
        // F_d = 0.04 + 0.96 w = 0.042 069; D = 1 / (π α²); V = 0.5 / (2 · √½ · √(½ + α² ½)).
        // Diffuse: T(cos 45°) = 0.96 (1 − w) = 0.957 931 at both angles, so
        // k T² / π = 1.088 281 25 · 0.917 631 / π = 0.998 641 / π.
        let wo = direction(45.0, 0.0);
        let wi = direction(45.0, PI);
        let w = (1.0 - 45f32.to_radians().cos()).powi(5);
        let d = 1.0 / (PI * alpha2);
        let s = 0.5f32.sqrt();
        let v = 0.5 / (2.0 * s * (0.5 + alpha2 * 0.5).sqrt());
        let fd = 0.04 + 0.96 * w;
        assert!((fd - 0.042_069).abs() < 1e-6, "{fd}");
        let expected = Rgb::splat(fd * d * v) + c * (0.998_641 / PI);
        assert!(
            (plastic.eval(wo, wi) - expected).length() < 1e-5,
            "{}",
            plastic.eval(wo, wi)
        );
    }

    #[test]
    fn zero_below_horizon() {
        let m = MetallicRoughness::new(Rgb::splat(0.5), 0.5, 0.5);
        let up = direction(30.0, 0.2);
        let down = Vec3::new(up.x, up.y, -up.z);
        for (wo, wi) in [(down, up), (up, down), (up, Vec3::X), (Vec3::X, up)] {
            assert_eq!(m.eval(wo, wi), Rgb::ZERO);
            assert_eq!(m.pdf(wo, wi), 0.0);
            assert_eq!(m.eval_pdf(wo, wi), (Rgb::ZERO, 0.0));
        }
        assert!(m.sample(down, Vec2::splat(0.4), 0.5).is_none());
    }

    #[test]
    fn reciprocal() {
        for m in [
            MetallicRoughness::new(Rgb::new(0.8, 0.4, 0.1), 0.3, 0.4),
            MetallicRoughness::new(Rgb::ONE, 0.0, 0.3),
            MetallicRoughness::new(Rgb::ONE, 0.0, 1.0),
            MetallicRoughness::new(Rgb::new(0.2, 0.9, 0.5), 0.7, 0.05),
        ] {
            for (a, b) in [
                (direction(10.0, 0.0), direction(70.0, 2.0)),
                (direction(85.0, 1.0), direction(30.0, -1.0)),
                (direction(0.0, 0.0), direction(89.9, 0.5)),
                (direction(60.0, 0.0), direction(60.0, PI)),
                (direction(45.0, 0.3), direction(80.0, 0.3)),
            ] {
                let (fab, fba) = (m.eval(a, b), m.eval(b, a));
                assert!(fab.min_element() > 0.0, "{m:?} {a} {b}: {fab}");
                assert!(
                    (fab - fba).length() <= 1e-5 * fab.length(),
                    "{m:?} {a} {b}: {fab} {fba}"
                );
            }
        }
    }

    #[test]
    fn outputs_finite_everywhere() {
        let thetas = [0.0f32, 30.0, 60.0, 89.0, 89.999_99];
        let mut directions: Vec<Vec3> = thetas
            .iter()
            .flat_map(|&t| [0.0f32, 1.0, 2.5, PI].map(|p| direction(t, p)))
            .collect();
        directions.push(Vec3::new(1.0, 0.0, 1e-7).normalize());
        directions.push(Vec3::new(-1.0, 0.0, 1e-7).normalize());
        directions.push(Vec3::new(0.0, 1.0, 1e-30).normalize());
        for base in [Rgb::ZERO, Rgb::ONE, Rgb::new(1.0, 0.0, 0.5)] {
            for metallic in [0.0, 0.5, 1.0] {
                for roughness in [0.0, 0.5, 1.0] {
                    let m = MetallicRoughness::new(base, metallic, roughness);
                    for &wo in &directions {
                        for &wi in &directions {
                            let (f, pdf) = m.eval_pdf(wo, wi);
                            assert!(f.is_finite() && f.min_element() >= 0.0, "{m:?} {wo} {wi}");
                            assert!(pdf.is_finite() && pdf >= 0.0, "{m:?} {wo} {wi}");
                        }
                        for k in 0..64 {
                            let u = Vec2::new((k % 8) as f32 / 8.0, (k / 8) as f32 / 8.0);
                            if let Some(s) = m.sample(wo, u, (k % 5) as f32 / 5.0) {
                                assert!(s.f.is_finite() && s.pdf > 0.0 && s.pdf.is_finite());
                                assert!(s.weight().is_finite(), "{m:?} {wo} {s:?}");
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn sampling_is_consistent() {
        for m in [
            MetallicRoughness::new(Rgb::new(0.9, 0.6, 0.3), 1.0, 0.0),
            MetallicRoughness::new(Rgb::new(0.9, 0.6, 0.3), 0.0, 0.5),
            MetallicRoughness::new(Rgb::ONE, 0.5, 1.0),
        ] {
            for wo in [
                Vec3::Z,
                direction(60.0, 0.3),
                Vec3::new(1.0, 0.0, 1e-7).normalize(),
            ] {
                let report = chi2::check_sample_consistency(&m, wo, 20_000);
                assert!(report.passed(), "{m:?} wo = {wo}\n{report}");
            }
        }
    }

    #[test]
    fn diffuse_normalisation() {
        // T̄ = 2 ∫₀¹ 0.96 (1 − (1 − μ)⁵) μ dμ = 0.96 (1 − 2 · B(2, 6)) = 0.96 (1 − 2/42)
        // = 32/35, by the midpoint rule.
        let n = 100_000;
        let mean: f64 = (0..n)
            .map(|i| {
                let mu = (i as f64 + 0.5) / n as f64;
                0.96 * (1.0 - (1.0 - mu).powi(5)) * 2.0 * mu
            })
            .sum::<f64>()
            / n as f64;
        assert!((mean - 32.0 / 35.0).abs() < 1e-9, "{mean}");
        assert!((DIELECTRIC_MEAN_TRANSMITTANCE as f64 - 32.0 / 35.0).abs() < 1e-7);
        assert!((DIFFUSE_SCALE as f64 - 0.995 * 35.0 / 32.0).abs() < 1e-6);
    }

    #[test]
    fn reference_quadrature_anchors() {
        // White metal, roughness 1, normal incidence: 1 − ln 2 in closed form.
        let metal = reference_albedo(1.0, 1.0, 1.0, 0.0);
        assert!((metal - (1.0 - 2f64.ln())).abs() < 1e-5, "{metal}");
        // White smooth dielectric at normal incidence: the mirror reflects F0 = 0.04 (less
        // the masking of α = 10⁻³, below 10⁻⁶) and the diffuse lobe 0.995 T(1) = 0.9552.
        let plastic = reference_albedo(1.0, 0.0, 0.0, 0.0);
        assert!((plastic - 0.9952).abs() < 1e-5, "{plastic}");
    }

    #[test]
    fn albedo_at_most_one_for_all_roughnesses_and_angles() {
        // The model itself (quadrature of the formula), including roughnesses too sharp for
        // the Monte Carlo estimator; white is the brightest base colour and f_r is affine in
        // metallic, so these two materials bound all others.
        let mut brightest_dielectric = (0.0, 0.0, 0.0);
        for roughness in [0.0, 0.05, 0.1, 0.2, 0.28, 0.4, 0.6, 0.8, 1.0] {
            for theta in [
                0.0, 15.0, 30.0, 45.0, 55.0, 60.0, 70.0, 80.0, 85.0, 89.0, 89.9,
            ] {
                for metallic in [0.0, 1.0] {
                    let albedo = reference_albedo(1.0, metallic, roughness, theta);
                    assert!(
                        albedo <= 1.0,
                        "metallic {metallic}, roughness {roughness}, θo = {theta}°: {albedo}"
                    );
                    if metallic == 0.0 && albedo > brightest_dielectric.0 {
                        brightest_dielectric = (albedo, roughness, theta);
                    }
                }
            }
        }
        // Not met by being too dark: a smooth dielectric at grazing angles reflects
        // 0.995 + 0.005 F_d(μo) → 1 (module documentation).
        assert!(
            brightest_dielectric.0 > 0.997,
            "largest albedo {brightest_dielectric:?}"
        );
    }

    /// Other dielectrics (`KHR_materials_ior` / `KHR_materials_specular`): a white base
    /// never reflects more than it receives, from f0 = 0 to a fully reflective interface
    /// and with f90 < 1, and the BSDF matches the quadrature.
    #[test]
    fn other_dielectrics_conserve_energy_and_match_quadrature() {
        let dielectrics = [(0.0, 1.0), (0.0816, 1.0), (0.25, 1.0), (0.04, 0.5), (0.5, 0.5), (1.0, 1.0)];
        for (f0, f90) in dielectrics {
            for roughness in [0.0, 0.1, 0.28, 0.6, 1.0] {
                for theta in [0.0, 45.0, 70.0, 85.0, 89.0] {
                    let albedo = reference_albedo_with(1.0, 0.0, roughness, theta, f0, f90);
                    assert!(albedo <= 1.0, "f0 {f0}, f90 {f90}, roughness {roughness}, θo = {theta}°: {albedo}");
                }
            }
        }
        // The default dielectric is the one of `new`.
        let plain = MetallicRoughness::new(Rgb::new(0.7, 0.4, 0.2), 0.3, 0.5);
        assert_eq!(plain.with_dielectric(Rgb::splat(DIELECTRIC_F0), 1.0), plain);
        for (f0, f90, metallic, roughness, theta) in [(0.25f32, 1.0f32, 0.0f32, 0.3f32, 30.0f32), (0.04, 0.5, 0.0, 0.5, 60.0), (0.5, 0.5, 0.5, 0.6, 45.0)] {
            let m = MetallicRoughness::new(Rgb::new(0.9, 0.5, 0.2), metallic, roughness).with_dielectric(Rgb::splat(f0), f90);
            let albedo = crate::bsdf::albedo::directional_albedo(&m, direction(theta, 0.0), 400_000);
            for channel in 0..3 {
                let reference = reference_albedo_with(m.base_color[channel].into(), metallic.into(), roughness.into(), theta.into(), f0.into(), f90.into());
                assert!((albedo[channel] as f64 - reference).abs() < 2e-3, "{m:?}, θo = {theta}°, channel {channel}: {albedo} vs {reference}");
            }
        }
        let clamped = MetallicRoughness::new(Rgb::ONE, 0.0, 0.5).with_dielectric(Rgb::new(2.0, 0.3, f32::NAN), 0.5);
        assert_eq!((clamped.dielectric_f0, clamped.dielectric_f90), (Rgb::new(0.5, 0.3, 0.0), 0.5));
    }

    #[test]
    fn no_energy_gain() {
        // White dielectric and white metal, at roughnesses the Monte Carlo estimator resolves
        // (α ≥ 0.09: accurate to a few 10⁻³ up to θo = 80°, ≈ 2 · 10⁻² at 89°). Agreement
        // with the quadrature shows the bound is not met by a BSDF that is simply too dark.
        let mut mismatches = Vec::new();
        for metallic in [0.0f32, 1.0] {
            for roughness in [0.3f32, 0.6, 1.0] {
                for theta in [0.0f32, 30.0, 60.0, 80.0, 89.0] {
                    let m = MetallicRoughness::new(Rgb::ONE, metallic, roughness);
                    let albedo = crate::bsdf::albedo::directional_albedo(&m, direction(theta, 0.0), 500_000);
                    let at = format!("metallic {metallic}, roughness {roughness}, θo = {theta}°");
                    assert!(albedo.max_element() <= 1.01, "{at}: {albedo}");
                    let reference =
                        reference_albedo(1.0, metallic.into(), roughness.into(), theta.into());
                    let tolerance = match theta {
                        t if t > 80.0 => 2.5e-2,
                        t if t > 60.0 => 5e-3,
                        _ => 2e-3,
                    };
                    if (albedo.x as f64 - reference).abs() >= tolerance {
                        mismatches.push(format!("{at}: {albedo} vs {reference}"));
                    }
                }
            }
        }
        assert!(mismatches.is_empty(), "{mismatches:#?}");
    }

    #[test]
    fn albedo_matches_independent_quadrature() {
        // (base colour, metallic, roughness, θo in degrees), per channel against
        // `reference_albedo`, where the estimator is accurate to ≈ 10⁻³.
        for (base, metallic, roughness, theta) in [
            (Rgb::ONE, 1.0f32, 1.0f32, 0.0f32),
            (Rgb::ONE, 1.0, 0.6, 60.0),
            (Rgb::ONE, 0.0, 0.3, 0.0),
            (Rgb::ONE, 0.0, 0.3, 60.0),
            (Rgb::ONE, 0.0, 0.3, 80.0),
            (Rgb::ONE, 0.0, 0.6, 80.0),
            (Rgb::ONE, 0.0, 1.0, 80.0),
            (Rgb::new(0.8, 0.3, 0.2), 0.5, 0.5, 45.0),
        ] {
            let m = MetallicRoughness::new(base, metallic, roughness);
            let albedo = crate::bsdf::albedo::directional_albedo(&m, direction(theta, 0.0), 500_000);
            for channel in 0..3 {
                let reference = reference_albedo(
                    base[channel].into(),
                    metallic.into(),
                    roughness.into(),
                    theta.into(),
                );
                assert!(
                    (albedo[channel] as f64 - reference).abs() < 2e-3,
                    "{m:?}, θo = {theta}°, channel {channel}: {albedo} vs {reference}"
                );
            }
        }
    }

    #[test]
    fn specular_only_passes_chi2() {
        for alpha in [0.05f32, 0.3, 1.0] {
            let m = MetallicRoughness::new(Rgb::new(0.95, 0.64, 0.54), 1.0, alpha.sqrt());
            assert_eq!(m.specular_probability(Vec3::Z), 1.0);
            for theta in [0.0, 45.0, 85.0] {
                let wo = direction(theta, 0.5);
                let result = chi2::test_bxdf(&m, wo, &chi2_config());
                assert!(result.passed(), "α = {alpha}, θo = {theta}°\n{result}");
            }
        }
    }

    #[test]
    fn sharp_specular_passes_chi2_on_theta_grid() {
        // Cells uniform in θ resolve the α = 0.05 lobe around the normal much better than
        // the equal-area grid.
        let m = MetallicRoughness::new(Rgb::ONE, 1.0, 0.05f32.sqrt());
        let config = chi2_config()
            .with_domain(Chi2Domain::ThetaPhi)
            .with_resolution(64, 100);
        for theta in [0.0, 45.0, 85.0] {
            let result = chi2::test_bxdf(&m, direction(theta, 2.0), &config);
            assert!(result.passed(), "θo = {theta}°\n{result}");
        }
    }

    #[test]
    fn mixed_lobes_pass_chi2() {
        for m in [
            MetallicRoughness::new(Rgb::new(0.8, 0.3, 0.2), 0.0, 0.5),
            MetallicRoughness::new(Rgb::new(0.2, 0.5, 0.9), 0.5, 0.25),
        ] {
            for theta in [0.0, 60.0, 85.0] {
                let wo = direction(theta, -1.0);
                let result = chi2::test_bxdf(&m, wo, &chi2_config());
                assert!(result.passed(), "{m:?}, θo = {theta}°\n{result}");
            }
        }
    }

    /// Bits of a vector, for comparisons that tell −0 from +0 and NaNs apart.
    fn bits(v: Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    /// Every lane's value, density and sample ([`MetallicRoughnessLobes`] over `F32s`)
    /// equal the scalar BSDF's bit for bit (where lanes take both lobes, and where a group
    /// is below the horizon as a whole), over
    /// materials from black dielectrics to mirrors (roughness 0), custom dielectric Fresnel,
    /// directions on and below the horizon, grazing views and NaN-free random ones.
    #[test]
    fn lanes_equal_the_scalar_bsdf_bit_for_bit() {
        use crate::lanes::{Vec2s, Vec3s, LANES};
        use crate::sampler::Sampler;
        use crate::sampling::sample_uniform_sphere;
        let mut rng = Sampler::new(11, 2, 5);
        let mut materials = vec![
            MetallicRoughness::new(Rgb::new(0.95, 0.64, 0.54), 1.0, 0.3),
            MetallicRoughness::new(Rgb::ZERO, 0.0, 0.5),
            MetallicRoughness::new(Rgb::ONE, 0.0, 0.0),
            MetallicRoughness::new(Rgb::new(0.2, 0.5, 0.9), 0.4, 1.0),
            MetallicRoughness::new(Rgb::new(0.8, 0.8, 0.8), 0.0, 0.05).with_dielectric(Rgb::new(0.1, 0.02, 0.0), 0.7),
        ];
        while materials.len() < 64 {
            let c = rng.next_2d().extend(rng.next_1d());
            let m = MetallicRoughness::new(c, rng.next_1d().round(), rng.next_1d());
            materials.push(if materials.len() % 3 == 0 { m.with_dielectric(c * 0.3, rng.next_1d()) } else { m });
        }
        let mut lanes = MetallicRoughnessLobes::<F32s>::default();
        let (mut sampled, mut evaluated) = (0, 0);
        for round in 0..400 {
            let (mut wo, mut wi, mut u, mut uc) = (Vec3s::default(), Vec3s::default(), Vec2s::default(), F32s::default());
            let mut cases = Vec::new();
            for i in 0..LANES {
                let bsdf = materials[(round * LANES + i) % materials.len()];
                let mut o = sample_uniform_sphere(rng.next_2d());
                match i % 8 {
                    0 => o.z = o.z.abs(),
                    1 => o = Vec3::new(o.x, o.y, 1e-4).normalize(),
                    2 => o = Vec3::Z,
                    _ => o.z = o.z.abs().max(0.05),
                }
                let l = if i % 5 == 0 { Vec3::new(-o.x, -o.y, o.z) } else { sample_uniform_sphere(rng.next_2d()) };
                let (s, c) = (rng.next_2d(), rng.next_1d());
                lanes.set(i, &bsdf.lobes());
                wo.set(i, o);
                wi.set(i, l);
                u.set(i, s);
                uc.0[i] = c;
                cases.push((bsdf, o, l, s, c));
            }
            let p_specular = lanes.at_wo(wo);
            let (f, pdf) = lanes.eval_pdf(p_specular, wo, wi);
            let sample = lanes.sample(p_specular, wo, u, uc);
            for (i, &(bsdf, o, l, s, c)) in cases.iter().enumerate() {
                let (ef, epdf) = bsdf.eval_pdf(o, l);
                assert_eq!((bits(f.get(i)), pdf.0[i].to_bits()), (bits(ef), epdf.to_bits()), "eval_pdf, lane {i}: {bsdf:?}");
                evaluated += (epdf > 0.0) as usize;
                let expected = bsdf.sample(o, Vec2::new(s.x, s.y), c);
                assert_eq!(sample.ok.0[i], expected.is_some(), "sample, lane {i}: {bsdf:?}, wo {o}");
                if let Some(e) = expected {
                    let got = (bits(sample.wi.get(i)), bits(sample.f.get(i)), sample.pdf.0[i].to_bits());
                    assert_eq!(got, (bits(e.wi), bits(e.f), e.pdf.to_bits()), "sample, lane {i}: {bsdf:?}");
                    sampled += 1;
                }
            }
        }
        assert!(sampled > 3000 && evaluated > 2000, "{sampled} samples, {evaluated} values");
    }
}
