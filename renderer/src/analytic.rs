//! Analytic isotropic BRDF models, used to make synthetic MERL-layout tables with known
//! properties (e.g. `material-nn tabulate --analytic`). Values are f_r in 1/sr, RGB, without
//! the cosine, in the local shading frame (z = normal); zero below either horizon.
//!
//! - [`AnalyticBrdf::LambertGgx`]: ρd/π + D·G2·F / (4 cos θi cos θo) with the GGX distribution
//!   and height-correlated Smith G2 of [`crate::bsdf::microfacet`], Schlick's Fresnel on
//!   wo·h with F0 = `specular`;
//! - [`AnalyticBrdf::LambertBeckmann`]: the same with Beckmann's
//!   D = exp(−tan²θh / α²) / (π α² cos⁴θh) and separable Smith G1 (Walter et al. 2007's
//!   rational approximation);
//! - [`AnalyticBrdf::Ward`]: ρd/π + ρs · exp(−tan²θh / α²) / (4π α² √(cos θi cos θo)) (Ward 1992,
//!   isotropic);
//! - [`AnalyticBrdf::OrenNayar`]: ρ/π · (A + B · max(0, cos(φi − φo)) · sin α · tan β) (the
//!   qualitative model of Oren & Nayar 1994) with σ the slope angle in radians.

use crate::bsdf::microfacet::{fresnel_schlick, GgxDistribution};
use crate::Rgb;
use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, PI};

/// An analytic isotropic BRDF; α are microfacet roughnesses (dimensionless), albedos and
/// reflectances per RGB channel in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AnalyticBrdf {
    LambertGgx {
        albedo: Rgb,
        specular: Rgb,
        alpha: f32,
    },
    LambertBeckmann {
        albedo: Rgb,
        specular: Rgb,
        alpha: f32,
    },
    Ward {
        albedo: Rgb,
        specular: Rgb,
        alpha: f32,
    },
    OrenNayar {
        albedo: Rgb,
        sigma: f32,
    },
}

/// Smallest α accepted by the models (avoids a delta lobe, as the GGX code does).
const MIN_ALPHA: f32 = 1e-3;

/// Smith G1 for Beckmann (Walter et al. 2007, rational approximation of the exact form).
fn beckmann_g1(w: Vec3, alpha: f32) -> f32 {
    let sin = (1.0 - w.z * w.z).max(0.0).sqrt();
    if sin == 0.0 {
        return 1.0;
    }
    let a = w.z / (alpha * sin);
    if a >= 1.6 {
        1.0
    } else {
        (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)
    }
}

/// tan² of the polar angle of a unit vector with z > 0.
fn tan2(h: Vec3) -> f32 {
    (h.x * h.x + h.y * h.y) / (h.z * h.z)
}

impl AnalyticBrdf {
    /// f_r(wo, wi) in 1/sr; zero below either horizon. Finite for every input.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        let h = (wo + wi).normalize();
        let f = match *self {
            AnalyticBrdf::LambertGgx {
                albedo,
                specular,
                alpha,
            } => {
                let ggx = GgxDistribution::isotropic(alpha);
                let spec = ggx.d(h) * ggx.g2(wo, wi) / (4.0 * wo.z * wi.z);
                albedo * FRAC_1_PI + fresnel_schlick(specular, wo.dot(h)) * spec
            }
            AnalyticBrdf::LambertBeckmann {
                albedo,
                specular,
                alpha,
            } => {
                let a = alpha.max(MIN_ALPHA);
                let c2 = h.z * h.z;
                let d = (-tan2(h) / (a * a)).exp() / (PI * a * a * c2 * c2);
                let g = beckmann_g1(wo, a) * beckmann_g1(wi, a);
                albedo * FRAC_1_PI
                    + fresnel_schlick(specular, wo.dot(h)) * (d * g / (4.0 * wo.z * wi.z))
            }
            AnalyticBrdf::Ward {
                albedo,
                specular,
                alpha,
            } => {
                let a = alpha.max(MIN_ALPHA);
                let lobe = (-tan2(h) / (a * a)).exp() / (4.0 * PI * a * a * (wo.z * wi.z).sqrt());
                albedo * FRAC_1_PI + specular * lobe
            }
            AnalyticBrdf::OrenNayar { albedo, sigma } => {
                let s2 = sigma * sigma;
                let a = 1.0 - 0.5 * s2 / (s2 + 0.33);
                let b = 0.45 * s2 / (s2 + 0.09);
                let (theta_i, theta_o) = (
                    crate::brdf_coords::polar_angle(wi),
                    crate::brdf_coords::polar_angle(wo),
                );
                let (si, so) = (
                    (wi.x * wi.x + wi.y * wi.y).sqrt(),
                    (wo.x * wo.x + wo.y * wo.y).sqrt(),
                );
                let cos_dphi = if si > 1e-7 && so > 1e-7 {
                    ((wi.x * wo.x + wi.y * wo.y) / (si * so)).clamp(-1.0, 1.0)
                } else {
                    0.0
                };
                let (alpha, beta) = (theta_i.max(theta_o), theta_i.min(theta_o));
                albedo * (FRAC_1_PI * (a + b * cos_dphi.max(0.0) * alpha.sin() * beta.tan()))
            }
        };
        if f.is_finite() {
            f.max(Rgb::ZERO)
        } else {
            Rgb::ZERO
        }
    }

    /// f_r at the isotropic angles (θh, θd, φd), radians (φh = 0).
    pub fn eval_angles(&self, theta_h: f32, theta_d: f32, phi_d: f32) -> Rgb {
        let (wi, wo) =
            crate::brdf_coords::directions_from_angles(&crate::brdf_coords::HalfDiffAngles {
                theta_h,
                phi_h: 0.0,
                theta_d,
                phi_d,
            });
        self.eval(wo, wi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(theta: f32, phi: f32) -> Vec3 {
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    /// Directional albedo by the midpoint rule over the hemisphere.
    fn albedo(b: &AnalyticBrdf, wo: Vec3) -> Rgb {
        let (nt, np) = (300, 300);
        let mut acc = Rgb::ZERO;
        for i in 0..nt {
            let t = (i as f32 + 0.5) / nt as f32 * std::f32::consts::FRAC_PI_2;
            for j in 0..np {
                let p = (j as f32 + 0.5) / np as f32 * 2.0 * PI;
                let wi = unit(t, p);
                acc += b.eval(wo, wi) * (wi.z * t.sin());
            }
        }
        acc * (std::f32::consts::FRAC_PI_2 / nt as f32) * (2.0 * PI / np as f32)
    }

    fn models() -> [AnalyticBrdf; 4] {
        let (albedo, specular) = (Rgb::new(0.5, 0.3, 0.1), Rgb::splat(0.04));
        [
            AnalyticBrdf::LambertGgx {
                albedo,
                specular,
                alpha: 0.3,
            },
            AnalyticBrdf::LambertBeckmann {
                albedo,
                specular,
                alpha: 0.3,
            },
            AnalyticBrdf::Ward {
                albedo,
                specular: Rgb::splat(0.05),
                alpha: 0.3,
            },
            AnalyticBrdf::OrenNayar { albedo, sigma: 0.5 },
        ]
    }

    #[test]
    fn models_are_reciprocal_finite_and_plausible() {
        for b in models() {
            for (wo, wi) in [
                (unit(0.3, 0.2), unit(1.0, 2.5)),
                (unit(1.5, 0.0), unit(0.1, 3.0)),
                (unit(1.2, 1.0), unit(1.2, 1.0 + PI)),
            ] {
                let (f, g) = (b.eval(wo, wi), b.eval(wi, wo));
                assert!(f.is_finite() && f.min_element() >= 0.0, "{b:?}: {f}");
                assert!(
                    (f - g).abs().max_element() <= 1e-4 * f.max_element().max(1.0),
                    "{b:?}: {f} vs {g}"
                );
            }
            assert_eq!(b.eval(unit(0.3, 0.0), Vec3::new(0.0, 0.6, -0.8)), Rgb::ZERO);
            let a = albedo(&b, unit(0.5, 0.0));
            assert!(a.max_element() < 1.0 && a.x > 0.3, "{b:?}: albedo {a}");
        }
    }

    #[test]
    fn lambert_limit_of_oren_nayar() {
        let b = AnalyticBrdf::OrenNayar {
            albedo: Rgb::ONE,
            sigma: 0.0,
        };
        assert!(
            (b.eval(unit(0.4, 0.0), unit(1.0, 1.0)) - Rgb::splat(FRAC_1_PI))
                .abs()
                .max_element()
                < 1e-6
        );
    }

    #[test]
    fn eval_angles_matches_directions() {
        let b = models()[0];
        let f = b.eval_angles(0.2, 0.5, 1.0);
        let (wi, wo) =
            crate::brdf_coords::directions_from_angles(&crate::brdf_coords::HalfDiffAngles {
                theta_h: 0.2,
                phi_h: 0.0,
                theta_d: 0.5,
                phi_d: 1.0,
            });
        assert_eq!(f, b.eval(wo, wi));
    }
}
