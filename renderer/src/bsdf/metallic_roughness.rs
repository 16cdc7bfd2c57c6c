//! The glTF 2.0 metallic-roughness material (glTF 2.0 specification, Appendix B).
//!
//! With c = `base_color`, m = `metallic`, α = `roughness`², h = normalize(wo + wi) and
//! D, V the GGX distribution and height-correlated Smith visibility
//! ([`GgxDistribution::d`], [`GgxDistribution::visibility`]):
//!
//! ```text
//! specular  = D(h) V(wo, wi)                              (the spec's specular_brdf, 1/sr)
//! F_metal   = c + (1 − c)(1 − wo·h)⁵                      (conductor_fresnel)
//! F_diel    = 0.04 + 0.96 (1 − wo·h)⁵                     (fresnel_mix with ior 1.5)
//! metal     = F_metal specular
//! dielectric= (1 − F_diel) c / π + F_diel specular        (fresnel_mix(diffuse, specular))
//! f_r       = m metal + (1 − m) dielectric
//!           = F specular + (1 − m)(1 − F_diel) c / π,  F = F0 + (1 − F0)(1 − wo·h)⁵,
//!                                                       F0 = mix(0.04, c, m)
//! ```
//!
//! The diffuse lobe is thus weighted by the *dielectric's* scalar Fresnel (1 − F_diel), as
//! the spec's `fresnel_mix` does, not by the coloured mixed F. Fresnel uses the angle between
//! `wo` and the microfacet normal (wo·h = wi·h), so f_r is reciprocal. Single scattering
//! only: rough metals lose energy (no multiple-scattering compensation; white metal with
//! roughness 1 reflects 1 − ln 2 ≈ 0.31 at normal incidence).
//!
//! **Energy caveat of the spec's form.** Because the diffuse weight 1 − F_diel(wo·h) is
//! taken at the half vector, most diffuse directions see wo·h ≈ 1 and keep ≈ 96 % of the
//! diffuse albedo even when `wo` is grazing, while the specular lobe's own Fresnel grows
//! towards 1 there. A white dielectric therefore reflects *more* than it receives at grazing
//! view angles: directional albedo ≈ 1.025 at θo = 60° and ≈ 1.22 at θo = 80° for
//! roughness 0.3, ≈ 1.045 at 80° for roughness 0.6, ≈ 1.010 at 89° for roughness 1
//! (below 1 at θo ≤ 30° for every roughness). This is the model as specified (and as
//! rasterisers implement it); a path tracer may see slightly brightened grazing
//! reflections on white plastics. Metals conserve energy at every angle.
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

use super::microfacet::{fresnel_schlick, half_vector, schlick_weight, GgxDistribution};
use super::{BsdfSample, Bxdf};
use crate::color::luminance;
use crate::sampling::{cosine_hemisphere_pdf, sample_cosine_hemisphere};
use crate::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// Reflectance at normal incidence of glTF's dielectric (index of refraction 1.5).
pub const DIELECTRIC_F0: f32 = 0.04;

/// Bounds of the probability of sampling the specular lobe when both lobes are non-zero,
/// so neither lobe is starved (its variance would grow without bound).
const MIN_LOBE_PROBABILITY: f32 = 0.1;

/// The glTF 2.0 metallic-roughness BRDF (see the module documentation for the formula).
///
/// The fields are expected in [0, 1]; [`MetallicRoughness::new`] clamps them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetallicRoughness {
    /// Linear RGB base colour, each channel in [0, 1]: the diffuse albedo of the dielectric
    /// and the normal-incidence reflectance F0 of the metal.
    pub base_color: Rgb,
    /// Metalness in [0, 1]: 0 = dielectric (diffuse + 4 % specular), 1 = metal; values in
    /// between blend the two BRDFs linearly.
    pub metallic: f32,
    /// Perceptual roughness r in [0, 1]; the GGX roughness is α = r², raised to
    /// [`super::microfacet::MIN_ALPHA`] so that roughness 0 stays a finite (very sharp) lobe.
    pub roughness: f32,
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
        }
    }

    /// The GGX distribution of the specular lobe: isotropic, α = roughness².
    #[inline]
    pub fn distribution(&self) -> GgxDistribution {
        GgxDistribution::from_roughness(self.roughness)
    }

    /// Reflectance at normal incidence, F0 = mix(0.04, base_color, metallic).
    #[inline]
    pub fn f0(&self) -> Rgb {
        Rgb::splat(DIELECTRIC_F0).lerp(self.base_color, self.metallic)
    }

    /// The diffuse albedo before Fresnel weighting, (1 − metallic) · base_color.
    #[inline]
    fn diffuse_color(&self) -> Rgb {
        self.base_color * (1.0 - self.metallic)
    }

    /// Probability with which [`Bxdf::sample`] draws from the specular lobe given `wo`.
    ///
    /// Estimated lobe albedos (luminance): specular E_s = lum(F(wo.z)), diffuse
    /// E_d = lum((1 − m) c) (1 − F_diel(wo.z)), both with Schlick's Fresnel at the
    /// macroscopic angle; the probability is E_s / (E_s + E_d), clamped to [0.1, 0.9] so
    /// neither lobe is starved. It is exactly 1 when the diffuse lobe vanishes (metallic 1
    /// or black base colour), so a pure metal spends no samples on it.
    #[inline]
    pub fn specular_probability(&self, wo: Vec3) -> f32 {
        let diffuse = self.diffuse_color();
        if diffuse.max_element() <= 0.0 {
            return 1.0;
        }
        let cos_o = wo.z.clamp(0.0, 1.0);
        let specular_albedo = luminance(fresnel_schlick(self.f0(), cos_o));
        let dielectric_fresnel = DIELECTRIC_F0 + (1.0 - DIELECTRIC_F0) * schlick_weight(cos_o);
        let diffuse_albedo = luminance(diffuse) * (1.0 - dielectric_fresnel);
        let total = specular_albedo + diffuse_albedo;
        let p = if total > 0.0 {
            specular_albedo / total
        } else {
            0.5
        };
        p.clamp(MIN_LOBE_PROBABILITY, 1.0 - MIN_LOBE_PROBABILITY)
    }
}

impl MetallicRoughness {
    /// f_r for directions already known to lie above the horizon, with the GGX distribution
    /// and the half vector.
    #[inline]
    fn value(&self, ggx: &GgxDistribution, wo: Vec3, wi: Vec3, h: Vec3) -> Rgb {
        let cos_oh = wo.dot(h);
        let specular = fresnel_schlick(self.f0(), cos_oh) * (ggx.d(h) * ggx.visibility(wo, wi));
        let dielectric_fresnel = DIELECTRIC_F0 + (1.0 - DIELECTRIC_F0) * schlick_weight(cos_oh);
        specular + self.diffuse_color() * ((1.0 - dielectric_fresnel) * FRAC_1_PI)
    }

    /// The mixture density for directions already known to lie above the horizon.
    #[inline]
    fn density(&self, ggx: &GgxDistribution, wo: Vec3, wi: Vec3) -> f32 {
        let p_specular = self.specular_probability(wo);
        p_specular * ggx.reflection_pdf(wo, wi) + (1.0 - p_specular) * cosine_hemisphere_pdf(wi.z)
    }
}

impl Bxdf for MetallicRoughness {
    /// f_r in 1/sr (module documentation); zero when either direction is below the horizon.
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        let h = half_vector(wo, wi).unwrap_or(Vec3::Z);
        self.value(&self.distribution(), wo, wi, h)
    }

    /// The exact mixture density p_s · pdf_GGX(wi) + (1 − p_s) · cos θi / π in 1/sr, with
    /// p_s = [`MetallicRoughness::specular_probability`] and pdf_GGX =
    /// [`GgxDistribution::reflection_pdf`]; zero below either horizon.
    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        self.density(&self.distribution(), wo, wi)
    }

    /// Picks the specular lobe when `uc < p_s` (then `u` drives the visible-normal sample),
    /// the diffuse lobe otherwise (then `u` drives a cosine-weighted sample). `None` when
    /// `wo` is below the horizon or the specular reflection leaves the upper hemisphere.
    #[inline]
    fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let ggx = self.distribution();
        let p_specular = self.specular_probability(wo);
        let wi = if uc < p_specular || p_specular >= 1.0 {
            ggx.sample_reflection(wo, u)?
        } else {
            sample_cosine_hemisphere(u)
        };
        if wi.z <= 0.0 {
            return None;
        }
        let h = half_vector(wo, wi).unwrap_or(Vec3::Z);
        let pdf = self.density(&ggx, wo, wi);
        (pdf > 0.0 && pdf.is_finite()).then(|| BsdfSample {
            wi,
            f: self.value(&ggx, wo, wi, h),
            pdf,
        })
    }

    /// Value and density in one call (the distribution is built once).
    #[inline]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let ggx = self.distribution();
        let h = half_vector(wo, wi).unwrap_or(Vec3::Z);
        (self.value(&ggx, wo, wi, h), self.density(&ggx, wo, wi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chi2::{self, Chi2Config, Chi2Domain};
    use std::f32::consts::PI;

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
        let plastic = MetallicRoughness::new(c, 0.0, r);
        let expected = Rgb::splat(0.04 / (4.0 * PI * alpha2)) + c * (0.96 / PI);
        assert!((plastic.eval(Vec3::Z, Vec3::Z) - expected).length() < 1e-5);
        // Opposite azimuths at 45°: h = n, wo·h = cos 45°.
        let wo = direction(45.0, 0.0);
        let wi = direction(45.0, PI);
        let w = (1.0 - 45f32.to_radians().cos()).powi(5);
        let d = 1.0 / (PI * alpha2);
        let s = 0.5f32.sqrt();
        let v = 0.5 / (2.0 * s * (0.5 + alpha2 * 0.5).sqrt());
        let fd = 0.04 + 0.96 * w;
        let expected = Rgb::splat(fd * d * v) + c * ((1.0 - fd) / PI);
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
        let m = MetallicRoughness::new(Rgb::new(0.8, 0.4, 0.1), 0.3, 0.4);
        for (a, b) in [
            (direction(10.0, 0.0), direction(70.0, 2.0)),
            (direction(85.0, 1.0), direction(30.0, -1.0)),
        ] {
            let (fab, fba) = (m.eval(a, b), m.eval(b, a));
            assert!((fab - fba).length() <= 1e-5 * fab.length(), "{fab} {fba}");
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
    fn no_energy_gain() {
        // White metals at every angle; the white dielectric wherever the spec's form
        // conserves energy (it gains energy towards grazing angles: see the module
        // documentation and `albedo_matches_independent_quadrature`).
        let mut cases = Vec::new();
        for roughness in [0.3, 0.6, 1.0] {
            for theta in [0.0, 30.0, 60.0, 80.0, 89.0] {
                cases.push((1.0, roughness, theta));
            }
            for theta in [0.0, 30.0] {
                cases.push((0.0, roughness, theta));
            }
        }
        cases.extend([(0.0, 0.6, 60.0), (0.0, 1.0, 60.0), (0.0, 1.0, 80.0)]);
        for (metallic, roughness, theta) in cases {
            let m = MetallicRoughness::new(Rgb::ONE, metallic, roughness);
            let albedo = chi2::directional_albedo(&m, direction(theta, 0.0), 500_000);
            assert!(
                albedo.max_element() <= 1.01,
                "metallic {metallic}, roughness {roughness}, θo = {theta}°: {albedo}"
            );
            assert!(
                albedo.min_element() > 0.3,
                "{metallic} {roughness} {theta}: {albedo}"
            );
        }
    }

    #[test]
    fn albedo_matches_independent_quadrature() {
        // (metallic, roughness, θo in degrees, albedo of the white material) from a separate
        // f64 midpoint quadrature of the same formula (8000 × 2880 nodes); the first is
        // 1 − ln 2 in closed form. The last four document the spec form's energy gain.
        for (metallic, roughness, theta, reference) in [
            (1.0, 1.0, 0.0, 0.306_853),
            (1.0, 0.6, 60.0, 0.782_123),
            (0.0, 0.3, 0.0, 0.999_553),
            (0.0, 0.3, 60.0, 1.025_359),
            (0.0, 0.3, 80.0, 1.221_262),
            (0.0, 0.6, 80.0, 1.045_335),
            (0.0, 1.0, 89.0, 1.010_054),
        ] {
            let m = MetallicRoughness::new(Rgb::ONE, metallic, roughness);
            let albedo = chi2::directional_albedo(&m, direction(theta, 0.0), 500_000);
            assert!(
                (albedo.x - reference).abs() < 2e-3,
                "metallic {metallic}, roughness {roughness}, θo = {theta}°: {albedo} vs {reference}"
            );
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
}
