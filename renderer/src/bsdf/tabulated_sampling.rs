//! Tabulated importance sampling for measured and neural BRDFs, fitted once from the BRDF
//! itself and with an exact density.
//!
//! # Method
//! For `theta_o_nodes` viewing angles θo (equal steps over [0, π/2]; isotropy makes φo
//! irrelevant) a 2D piecewise-constant distribution ([`Distribution2D`]) is fitted over the
//! half vector h, expressed relative to the azimuth of `wo`:
//! - y = sqrt(θh / (π/2)) ∈ [0, 1) (the MERL warp: resolution concentrates at h ≈ n, where
//!   every specular peak lies whatever θo, since h = n is the mirror configuration);
//! - x = |φh − φo| / π ∈ [0, 1) (isotropic BRDFs are mirror-symmetric about the plane of
//!   incidence, so the sign of φh − φo is drawn with probability ½ each).
//!
//! Within a cell h is uniform in solid angle (1 − cos θh and φh uniform), so the density is
//! piecewise constant in h and bounded, even at h = n. A cell's probability is proportional
//! to its solid angle Ω times the cell average (`supersampling`² points, both signs of
//! φh − φo) of mean_rgb(f(wo, wi)) · cos θi · 4 (wo·h), with wi = reflect(wo, h) — i.e. to
//! ∫ f cos θi dωi over the wi the cell reflects to; cells whose wi falls below the horizon
//! weigh 0.
//!
//! Sampling mixes three parts: with probability `cosine_fraction` a cosine-weighted
//! direction (so the density is positive wherever f·cos θi is, whatever the fit missed);
//! otherwise the table of one of the two θo nodes around θo(wo), the upper one with
//! probability equal to the linear-interpolation weight (so the density varies continuously
//! with θo). The density returned by [`TabulatedSampler::pdf`] is that of the whole mixture,
//! in 1/sr of wi, and is exactly the density of [`TabulatedSampler::sample`] (directions whose
//! reflection falls below the horizon are returned as `None` and their mass is lost, so the
//! density integrates to at most 1 over the upper hemisphere).
//!
//! The BRDF is never asked for a density: only its values enter the fit.

use crate::sampling::{cosine_hemisphere_pdf, sample_cosine_hemisphere, Distribution2D};
use crate::Rgb;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::f32::consts::{FRAC_PI_2, PI};

/// Resolution and mixture of a [`TabulatedSampler`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TabulatedSamplerConfig {
    /// Viewing angles θo at which a table is fitted, equally spaced over [0, π/2] with both
    /// ends included (at least 2). The last node is evaluated at θo = π/2 − 10⁻³.
    pub theta_o_nodes: usize,
    /// Cells along y = sqrt(θh / (π/2)).
    pub theta_h_cells: usize,
    /// Cells along |φh − φo| ∈ [0, π).
    pub phi_h_cells: usize,
    /// Points per cell and axis at which the BRDF is evaluated during the fit.
    pub supersampling: usize,
    /// Probability of drawing from the cosine lobe, in [0, 1]; values below ~0.05 lose the
    /// robustness the lobe gives.
    pub cosine_fraction: f32,
}

impl Default for TabulatedSamplerConfig {
    /// 24 θo nodes, 64 × 32 cells, 2 × 2 points per cell (393,216 BRDF evaluations per fit),
    /// a 10% cosine lobe.
    fn default() -> Self {
        TabulatedSamplerConfig {
            theta_o_nodes: 24,
            theta_h_cells: 64,
            phi_h_cells: 32,
            supersampling: 2,
            cosine_fraction: 0.1,
        }
    }
}

/// Largest θo at which a table is fitted (radians): just above the horizon, so `wo` stays a
/// valid outgoing direction.
const MAX_NODE_THETA_O: f32 = FRAC_PI_2 - 1e-3;

/// The fitted sampler; see the module documentation.
#[derive(Clone)]
pub struct TabulatedSampler {
    /// One distribution per θo node over the cells; x = |φh − φo| / π (width),
    /// y = sqrt(θh / (π/2)) (height).
    tables: Vec<Distribution2D>,
    /// 1 − cos θh at the row boundaries (`theta_h_cells + 1` entries, from 0).
    row_v: Vec<f32>,
    /// Columns per table (cells along |φh − φo|).
    phi_cells: usize,
    cosine_fraction: f32,
}

impl std::fmt::Debug for TabulatedSampler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TabulatedSampler")
            .field("theta_o_nodes", &self.tables.len())
            .field("cosine_fraction", &self.cosine_fraction)
            .finish_non_exhaustive()
    }
}

/// cos and sin of the azimuth of `v` (1 and 0 when `v` is along z).
#[inline]
fn azimuth(v: Vec3) -> (f32, f32) {
    let s = (v.x * v.x + v.y * v.y).sqrt();
    if s > 1e-7 {
        (v.x / s, v.y / s)
    } else {
        (1.0, 0.0)
    }
}

/// 1 − cos θh at the boundary y = sqrt(θh / (π/2)) of a row, accurate near 0.
fn one_minus_cos_theta_h(y: f64) -> f32 {
    let theta_h = y * y * std::f64::consts::FRAC_PI_2;
    let s = (theta_h / 2.0).sin();
    (2.0 * s * s) as f32
}

/// Half vector with 1 − cos θh = `v` and |φh − φo| = `x`·π with the given sign, in the frame
/// where `wo` has azimuth 0.
#[inline]
fn half_vector_at(v: f32, x: f32, sign: f32) -> Vec3 {
    let sin_h = (v * (2.0 - v)).max(0.0).sqrt();
    let (sp, cp) = (sign * x * PI).sin_cos();
    Vec3::new(sin_h * cp, sin_h * sp, 1.0 - v)
}

impl TabulatedSampler {
    /// Fits the tables from `brdf(wo, wi)` (f_r in 1/sr, local frame, as [`super::Bxdf::eval`]),
    /// the θo nodes in parallel. Negative and non-finite values count as 0.
    ///
    /// # Panics
    /// When the config has fewer than 2 θo nodes or a zero resolution (a programming error).
    pub fn new(brdf: impl Fn(Vec3, Vec3) -> Rgb + Sync, config: &TabulatedSamplerConfig) -> Self {
        let c = *config;
        assert!(
            c.theta_o_nodes >= 2 && c.theta_h_cells > 0 && c.phi_h_cells > 0 && c.supersampling > 0,
            "invalid TabulatedSamplerConfig {c:?}"
        );
        let row_v: Vec<f32> = (0..=c.theta_h_cells)
            .map(|r| one_minus_cos_theta_h(r as f64 / c.theta_h_cells as f64))
            .collect();
        let tables = (0..c.theta_o_nodes)
            .into_par_iter()
            .map(|k| {
                let theta_o = (k as f32 / (c.theta_o_nodes - 1) as f32 * FRAC_PI_2).min(MAX_NODE_THETA_O);
                let (so, co) = theta_o.sin_cos();
                let wo = Vec3::new(so, 0.0, co);
                let weights = fit_weights(&brdf, wo, &row_v, &c);
                Distribution2D::new(&weights, c.phi_h_cells, c.theta_h_cells)
            })
            .collect();
        TabulatedSampler {
            tables,
            row_v,
            phi_cells: c.phi_h_cells,
            cosine_fraction: c.cosine_fraction.clamp(0.0, 1.0),
        }
    }

    /// The two θo nodes around `wo` and the weight of the upper one.
    #[inline]
    fn nodes(&self, wo: Vec3) -> (usize, f32) {
        let n = self.tables.len();
        let s = crate::brdf_coords::polar_angle(wo) / FRAC_PI_2 * (n - 1) as f32;
        let k = (s.max(0.0) as usize).min(n - 2);
        (k, (s - k as f32).clamp(0.0, 1.0))
    }

    /// Draws wi given `wo` (local frame, z > 0) from a 2D sample `u` and a 1D sample `uc`
    /// (which picks cosine lobe, θo node and the sign of φh − φo). `None` when `wo` is below
    /// the horizon or the drawn reflection is. The density of the result is [`Self::pdf`].
    pub fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<Vec3> {
        if wo.z <= 0.0 {
            return None;
        }
        let cf = self.cosine_fraction;
        if uc < cf || cf >= 1.0 {
            let wi = sample_cosine_hemisphere(u);
            return (wi.z > 0.0).then_some(wi);
        }
        let uc = (uc - cf) / (1.0 - cf);
        let (k, t) = self.nodes(wo);
        let (node, uc) = if uc < 1.0 - t {
            (k, uc / (1.0 - t))
        } else {
            (k + 1, (uc - (1.0 - t)) / t)
        };
        let sign = if uc < 0.5 { 1.0 } else { -1.0 };
        let (p, _) = self.tables[node].sample_continuous(u);
        // Uniform in solid angle within the cell: 1 − cos θh linear in the row's fraction.
        let ny = self.row_v.len() - 1;
        let yc = p.y * ny as f32;
        let row = (yc as usize).min(ny - 1);
        let t_row = (yc - row as f32).clamp(0.0, 1.0);
        let v = self.row_v[row] + t_row * (self.row_v[row + 1] - self.row_v[row]);
        let hl = half_vector_at(v, p.x, sign);
        let (c, s) = azimuth(wo);
        let h = Vec3::new(c * hl.x - s * hl.y, s * hl.x + c * hl.y, hl.z);
        let wi = crate::bsdf::microfacet::reflect(wo, h);
        (wi.z > 0.0 && wo.dot(h) > 0.0).then(|| wi.normalize())
    }

    /// Solid-angle density (1/sr) with which [`Self::sample`] draws `wi` given `wo`; 0 below
    /// either horizon.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let cf = self.cosine_fraction;
        cf * cosine_hemisphere_pdf(wi.z) + (1.0 - cf) * self.table_pdf(wo, wi)
    }

    /// Density of the tabulated part alone (1/sr), both horizons already checked.
    #[inline]
    fn table_pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let h = (wo + wi).normalize();
        let cos_oh = wo.dot(h);
        if !(cos_oh > 0.0) {
            return 0.0;
        }
        let (c, s) = azimuth(wo);
        let hx = c * h.x + s * h.y;
        let hy = -s * h.x + c * h.y;
        let y = (hx.hypot(hy).atan2(h.z) / FRAC_PI_2).sqrt().min(1.0);
        let x = (hy.atan2(hx).abs() / PI).min(1.0);
        let (nx, ny) = (self.phi_cells, self.row_v.len() - 1);
        let row = ((y * ny as f32) as usize).min(ny - 1);
        let (k, t) = self.nodes(wo);
        let p = Vec2::new(x, y);
        let mut density_xy = (1.0 - t) * self.tables[k].pdf(p);
        if t > 0.0 {
            density_xy += t * self.tables[k + 1].pdf(p);
        }
        // Cell probability over the cell's solid angle (both signs of φh − φo: 2π/nx per
        // column), then the reflection Jacobian dωh/dωi = 1 / (4 wo·h).
        let cell_probability = density_xy / (nx * ny) as f32;
        let cell_solid_angle = (self.row_v[row + 1] - self.row_v[row]) * 2.0 * PI / nx as f32;
        let pdf = cell_probability / (cell_solid_angle * 4.0 * cos_oh);
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }

    /// The cosine-lobe probability in use.
    pub fn cosine_fraction(&self) -> f32 {
        self.cosine_fraction
    }
}

/// Cell weights of one θo node, row-major (x fastest): ∫ f cos θi dωi over each cell, up to
/// a constant factor.
fn fit_weights(brdf: &impl Fn(Vec3, Vec3) -> Rgb, wo: Vec3, row_v: &[f32], c: &TabulatedSamplerConfig) -> Vec<f32> {
    let (nx, ny, ss) = (c.phi_h_cells, c.theta_h_cells, c.supersampling);
    let mut weights = vec![0f32; nx * ny];
    for iy in 0..ny {
        let (v0, v1) = (row_v[iy], row_v[iy + 1]);
        for ix in 0..nx {
            let mut acc = 0f64;
            for a in 0..ss {
                for b in 0..ss {
                    let x = (ix as f32 + (a as f32 + 0.5) / ss as f32) / nx as f32;
                    let v = v0 + (b as f32 + 0.5) / ss as f32 * (v1 - v0);
                    let sign = if (a + b) % 2 == 0 { 1.0 } else { -1.0 };
                    let h = half_vector_at(v, x, sign);
                    let cos_oh = wo.dot(h);
                    if cos_oh <= 0.0 {
                        continue;
                    }
                    let wi = crate::bsdf::microfacet::reflect(wo, h);
                    if wi.z <= 0.0 {
                        continue;
                    }
                    let f = brdf(wo, wi.normalize());
                    let mean = (f.x + f.y + f.z) / 3.0;
                    if mean.is_finite() && mean > 0.0 {
                        acc += (mean * wi.z * 4.0 * cos_oh) as f64;
                    }
                }
            }
            weights[ix + nx * iy] = (acc / (ss * ss) as f64 * (v1 - v0) as f64) as f32;
        }
    }
    weights
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::microfacet::GgxDistribution;

    /// A rough GGX lobe over a small diffuse term: a BRDF with a known shape.
    fn ggx_brdf(alpha: f32) -> impl Fn(Vec3, Vec3) -> Rgb + Sync {
        let ggx = GgxDistribution::isotropic(alpha);
        move |wo: Vec3, wi: Vec3| {
            if wo.z <= 0.0 || wi.z <= 0.0 {
                return Rgb::ZERO;
            }
            let h = (wo + wi).normalize();
            Rgb::splat(ggx.d(h) * ggx.g2(wo, wi) / (4.0 * wo.z * wi.z) + 0.05)
        }
    }

    /// Numerical integral of the density over the upper hemisphere (θ, φ grid refined near
    /// the mirror direction is not needed for α ≥ 0.1).
    fn integrate_pdf(s: &TabulatedSampler, wo: Vec3) -> f64 {
        let (nt, np) = (400, 800);
        let mut sum = 0.0f64;
        for i in 0..nt {
            let theta = (i as f64 + 0.5) / nt as f64 * std::f64::consts::FRAC_PI_2;
            for j in 0..np {
                let phi = (j as f64 + 0.5) / np as f64 * 2.0 * std::f64::consts::PI;
                let wi = Vec3::new(
                    (theta.sin() * phi.cos()) as f32,
                    (theta.sin() * phi.sin()) as f32,
                    theta.cos() as f32,
                );
                sum += s.pdf(wo, wi) as f64 * theta.sin();
            }
        }
        sum * (std::f64::consts::FRAC_PI_2 / nt as f64) * (2.0 * std::f64::consts::PI / np as f64)
    }

    #[test]
    fn density_integrates_to_at_most_one() {
        let s = TabulatedSampler::new(ggx_brdf(0.3), &TabulatedSamplerConfig::default());
        for theta_o in [0.0f32, 0.7, 1.3, 1.55] {
            let wo = Vec3::new(theta_o.sin(), 0.0, theta_o.cos());
            let total = integrate_pdf(&s, wo);
            // The tabulated part loses only the mass of cells straddling the horizon.
            assert!(total > 0.9 && total < 1.0 + 2e-3, "θo {theta_o}: ∫pdf = {total}");
        }
    }

    #[test]
    fn samples_report_positive_finite_densities() {
        let s = TabulatedSampler::new(ggx_brdf(0.05), &TabulatedSamplerConfig::default());
        let wo = Vec3::new(0.5, -0.2, 0.8).normalize();
        let mut drawn = 0;
        for i in 0..4096u32 {
            let u = Vec2::new((i as f32 + 0.5) / 4096.0, (i.wrapping_mul(2654435761) >> 8) as f32 / 16_777_216.0);
            let uc = ((i * 7919) % 4096) as f32 / 4096.0;
            if let Some(wi) = s.sample(wo, u, uc) {
                drawn += 1;
                assert!((wi.length() - 1.0).abs() < 1e-4 && wi.z > 0.0);
                let p = s.pdf(wo, wi);
                assert!(p > 0.0 && p.is_finite(), "{wi:?}: {p}");
            }
        }
        assert!(drawn > 3900, "{drawn}");
        assert!(s.sample(Vec3::new(0.0, 0.6, -0.8), Vec2::splat(0.5), 0.5).is_none());
        assert_eq!(s.pdf(Vec3::Z, Vec3::new(0.0, 0.6, -0.8)), 0.0);
    }

    #[test]
    fn zero_brdf_falls_back_to_a_valid_density() {
        let s = TabulatedSampler::new(|_, _| Rgb::ZERO, &TabulatedSamplerConfig::default());
        let total = integrate_pdf(&s, Vec3::new(0.6, 0.0, 0.8));
        assert!(total > 0.5 && total < 1.0 + 2e-3, "{total}");
    }
}
