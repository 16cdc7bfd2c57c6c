//! glTF's transmitting material (`KHR_materials_transmission`): a metallic-roughness surface
//! part of whose dielectric base is glass.
//!
//! The specification writes the material as
//!
//! f = m · f_metal + (1 − m) · fresnel_mix(f_specular, (1 − t) · f_diffuse + t · f_btdf),
//!
//! with m the metallic factor and t the transmission factor. `fresnel_mix` is linear in its
//! base, so the material is the exact mixture
//!
//! f = (1 − τ) · f_MR(m′) + τ · f_glass,   τ = t (1 − m),   m′ = m / (1 − τ),
//!
//! of the opaque metallic-roughness BSDF ([`MetallicRoughness`], metallic m′) and a
//! [`Dielectric`] (its specular reflection plus its transmission tinted by the base colour,
//! the specification's `fresnel_mix(f_specular, f_btdf)`). Sampling chooses the glass with
//! probability τ; value and density are the mixture's, so MIS sees the whole BSDF; samples of
//! the glass's delta lobes (smooth glass) carry τ times their probability.

use super::{Bsdf, BsdfSample, Bxdf, Dielectric, MetallicRoughness};
use crate::Rgb;
use glam::{Vec2, Vec3};

/// A metallic-roughness surface whose dielectric base transmits (see the module
/// documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transmission {
    /// The opaque part, weighed 1 − τ (unused where τ = 1).
    opaque: MetallicRoughness,
    /// The glass, weighed τ.
    glass: Dielectric,
    /// τ ∈ (0, 1]: the glass's weight.
    glass_weight: f32,
}

impl Transmission {
    /// The glTF material with base colour `base`, metallic factor `metallic`, perceptual
    /// roughness `roughness` and transmission factor `transmission` (all in [0, 1]), whose
    /// dielectric Fresnel is `(f0, f90)` ([`MetallicRoughness::with_dielectric`]) and whose
    /// glass is `glass` (its index of refraction, tint and thinness chosen by the caller).
    pub fn new(base: Rgb, metallic: f32, roughness: f32, transmission: f32, (f0, f90): (Rgb, f32), glass: Dielectric) -> Self {
        let glass_weight = (transmission * (1.0 - metallic)).clamp(0.0, 1.0);
        let opaque_metallic = if glass_weight < 1.0 { (metallic / (1.0 - glass_weight)).clamp(0.0, 1.0) } else { 0.0 };
        Transmission {
            opaque: MetallicRoughness::new(base, opaque_metallic, roughness).with_dielectric(f0, f90),
            glass,
            glass_weight,
        }
    }

    /// The glass's weight τ.
    pub fn glass_weight(&self) -> f32 {
        self.glass_weight
    }

    /// The glass, where it is the whole BSDF (τ = 1: value, density and samples are the
    /// glass's, bit for bit); `None` where an opaque part is mixed in.
    #[inline]
    pub fn glass_alone(&self) -> Option<&Dielectric> {
        (self.opaque_weight() == 0.0).then_some(&self.glass)
    }

    /// The part of the BSDF a shading point of it evaluates: the glass alone where τ = 1.
    #[inline]
    fn opaque_weight(&self) -> f32 {
        1.0 - self.glass_weight
    }
}

impl Bxdf for Transmission {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.eval_pdf(wo, wi).0
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    #[inline]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        let (fg, pg) = self.glass.eval_pdf(wo, wi);
        let (w_glass, w_opaque) = (self.glass_weight, self.opaque_weight());
        if w_opaque == 0.0 {
            return (fg, pg);
        }
        let (fo, po) = self.opaque.eval_pdf(wo, wi);
        (fg * w_glass + fo * w_opaque, pg * w_glass + po * w_opaque)
    }

    fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        let (w_glass, w_opaque) = (self.glass_weight, self.opaque_weight());
        if w_opaque == 0.0 {
            return self.glass.sample(wo, u, uc);
        }
        let s = if uc < w_glass {
            self.glass.sample(wo, u, (uc / w_glass).min(1.0 - f32::EPSILON / 2.0))?
        } else {
            self.opaque.sample(wo, u, ((uc - w_glass) / w_opaque).min(1.0 - f32::EPSILON / 2.0))?
        };
        if s.delta {
            // Only the glass has delta lobes: its probability times the choice's.
            return Some(BsdfSample { f: s.f * w_glass, pdf: s.pdf * w_glass, ..s });
        }
        let (f, pdf) = self.eval_pdf(wo, s.wi);
        (pdf > 0.0 && pdf.is_finite()).then_some(BsdfSample::new(s.wi, f, pdf))
    }

    fn transmits(&self) -> bool {
        true
    }

    fn is_delta(&self) -> bool {
        self.opaque_weight() == 0.0 && self.glass.is_smooth()
    }
}

impl<'a> From<Transmission> for Bsdf<'a> {
    fn from(t: Transmission) -> Self {
        Bsdf::Transmission(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::chi2::{check_sample_consistency, test_bxdf, Chi2Config, Chi2Domain};

    fn unit(theta_degrees: f32, phi: f32) -> Vec3 {
        let t = theta_degrees.to_radians();
        Vec3::new(t.sin() * phi.cos(), t.sin() * phi.sin(), t.cos())
    }

    const F0: (Rgb, f32) = (Rgb::splat(0.04), 1.0);

    /// Half-transmitting rough glass over a half-metallic base, seen from outside and from
    /// inside: sampling follows the mixture's density in both hemispheres, and samples agree
    /// with eval and pdf.
    #[test]
    fn the_mixture_samples_its_density() {
        let config = Chi2Config::default().with_sample_count(150_000).with_domain(Chi2Domain::ThetaPhi).with_test_count(4);
        for (eta, theta) in [(1.5, 30.0), (1.0 / 1.5, 60.0)] {
            for roughness in [0.4, 0.0] {
                let glass = Dielectric::new(eta, roughness).with_tint(Rgb::new(0.9, 0.7, 0.5));
                let m = Transmission::new(Rgb::new(0.8, 0.5, 0.3), 0.3, roughness.max(0.3), 0.6, F0, glass);
                let wo = unit(theta, 0.7);
                let result = test_bxdf(&m, wo, &config);
                assert!(result.passed(), "η {eta}, roughness {roughness}\n{result}");
                let report = check_sample_consistency(&m, wo, 5_000);
                assert!(report.passed(), "η {eta}, roughness {roughness}\n{report}");
            }
        }
    }

    /// Transmission 1 on a dielectric is the glass alone, and transmission 0 the opaque
    /// metallic-roughness BSDF, bit for bit.
    #[test]
    fn the_end_members_are_the_glass_and_the_opaque_surface() {
        let glass = Dielectric::new(1.5, 0.3);
        let base = Rgb::new(0.8, 0.5, 0.3);
        let all_glass = Transmission::new(base, 0.0, 0.3, 1.0, F0, glass);
        let opaque = Transmission::new(base, 0.4, 0.3, 0.0, F0, glass);
        let mr = MetallicRoughness::new(base, 0.4, 0.3).with_dielectric(F0.0, F0.1);
        let wo = unit(35.0, 0.2);
        for wi in [unit(50.0, 2.0), unit(150.0, 3.5), unit(10.0, -1.0)] {
            assert_eq!(all_glass.eval_pdf(wo, wi), glass.eval_pdf(wo, wi));
            assert_eq!(opaque.eval_pdf(wo, wi).0, mr.eval_pdf(wo, wi).0);
        }
        for k in 0..64 {
            let u = Vec2::new((k as f32 + 0.5) / 64.0, ((k * 29) % 64) as f32 / 64.0);
            assert_eq!(all_glass.sample(wo, u, 0.37), glass.sample(wo, u, 0.37));
        }
    }
}
