//! Tabulated importance sampling for measured and neural BRDFs, fitted once from the BRDF's
//! values and with an exact, continuous density.
//!
//! # Method
//! For `theta_o_nodes` viewing angles θo (equal steps over [0, π/2]; isotropy makes φo
//! irrelevant) a density over the half vector h is tabulated, with h expressed relative to
//! the azimuth of `wo`:
//! - x = |φh − φo| / π ∈ [0, 1], in `phi_h_cells` equal columns (isotropic BRDFs are
//!   mirror-symmetric about the plane of incidence, so the sign of φh − φo is drawn with
//!   probability ½ each);
//! - v = 1 − cos θh ∈ [0, 1], in `theta_h_cells` rows whose boundaries are equally spaced in
//!   sqrt(θh / (π/2)) (the MERL warp), so rows are finest at h = n, where every specular peak
//!   lies whatever θo (h = n is the mirror configuration).
//!
//! Since dωh = dv dφh, a density in (x, v) is a density in solid angle of h up to the constant
//! π. The density is bilinear within each cell between its four vertex values, which are
//! mean_rgb(f(wo, wi)) · cos θi · 4 (wo·h) at the vertex (averaged over both signs), with
//! wi = reflect(wo, h) — i.e. f cos θi per unit solid angle of h — and 0 where wi falls below
//! the horizon. It is therefore continuous and bounded everywhere, h = n included, and it is
//! sampled exactly by inversion: the row from the row masses, v within the row from its
//! linear marginal, x from the conditional whose cumulative distribution interpolates those
//! of the two vertex lines (Mitsuba's `Marginal2D` does the same on a uniform grid).
//!
//! Sampling mixes this with a cosine lobe: with probability `cosine_fraction` a
//! cosine-weighted direction (so the density is positive wherever f·cos θi is, whatever the
//! fit missed); otherwise the table of one of the two θo nodes around θo(wo), the upper one
//! with probability equal to the linear-interpolation weight (so the density varies
//! continuously with θo as well). [`TabulatedSampler::pdf`] returns the density of the whole
//! mixture, in 1/sr of wi, which is exactly the density of [`TabulatedSampler::sample`];
//! directions whose reflection falls below the horizon are returned as `None` and their mass
//! is lost, so the density integrates to at most 1 over the upper hemisphere.
//!
//! The BRDF is never asked for a density: only its values enter the fit.

use crate::sampling::{cosine_hemisphere_pdf, sample_cosine_hemisphere, sin_cos_turns, Distribution1D, ONE_MINUS_EPSILON};
use crate::lanes::{F32s, Vec3s, LANES};
use crate::trig::atan2;
use crate::bsdf::{BsdfSample, Bxdf};
use crate::Rgb;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::f32::consts::{FRAC_PI_2, PI};

/// A BRDF given by its values and importance-sampled by a [`TabulatedSampler`] fitted to
/// them (MERL tables, NBRDF networks, decoded latent codes). Implementing this implements
/// [`Bxdf`]: `eval` is the value, `pdf` the sampler's exact density, and `sample` draws from
/// the sampler and packs the value at the drawn direction.
pub trait TabulatedBrdf {
    /// f_r(wo, wi) in 1/sr, without the cosine; zero below either horizon.
    fn value(&self, wo: Vec3, wi: Vec3) -> Rgb;

    /// The sampler fitted to [`TabulatedBrdf::value`].
    fn sampler(&self) -> &TabulatedSampler;
}

impl<T: TabulatedBrdf> Bxdf for T {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.value(wo, wi)
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.sampler().pdf(wo, wi)
    }

    fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        let (wi, pdf) = self.sampler().sample_with_pdf(wo, u, uc)?;
        Some(BsdfSample::new(wi, self.value(wo, wi), pdf))
    }
}

/// Resolution and mixture of a [`TabulatedSampler`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TabulatedSamplerConfig {
    /// Viewing angles θo at which a table is fitted, equally spaced over [0, π/2] with both
    /// ends included (at least 2). The last node is evaluated at θo = π/2 − 10⁻³.
    pub theta_o_nodes: usize,
    /// Rows along θh (equal steps of sqrt(θh / (π/2))).
    pub theta_h_cells: usize,
    /// Columns along |φh − φo| ∈ [0, π].
    pub phi_h_cells: usize,
    /// Probability of drawing from the cosine lobe, in [0, 1]; values below ~0.05 lose the
    /// robustness the lobe gives.
    pub cosine_fraction: f32,
}

impl TabulatedSamplerConfig {
    /// The smallest sampler a BSDF made from data accepts (a few evaluations to fit): for
    /// BSDFs that are only evaluated (quadratures need no sampling). Rendering with it works
    /// but samples little better than a cosine lobe.
    pub const EVAL_ONLY: TabulatedSamplerConfig = TabulatedSamplerConfig {
        theta_o_nodes: 2,
        theta_h_cells: 1,
        phi_h_cells: 1,
        cosine_fraction: 1.0,
    };
}

impl Default for TabulatedSamplerConfig {
    /// 24 θo nodes, 64 × 32 cells (≈ 0.1 M BRDF evaluations per fit), a 10% cosine lobe.
    fn default() -> Self {
        TabulatedSamplerConfig {
            theta_o_nodes: 24,
            theta_h_cells: 64,
            phi_h_cells: 32,
            cosine_fraction: 0.1,
        }
    }
}

/// Largest θo at which a table is fitted (radians): just above the horizon, so `wo` stays a
/// valid outgoing direction.
const MAX_NODE_THETA_O: f32 = FRAC_PI_2 - 1e-3;

/// The fitted tables of a [`TabulatedSampler`], for renderers that draw from the same density
/// themselves (see the module documentation for what they mean).
#[derive(Clone, Debug, PartialEq)]
pub struct SamplerTables {
    /// θo of each node (radians), equally spaced over [0, π/2]; a direction between two nodes
    /// uses both, weighted linearly.
    pub theta_o: Vec<f32>,
    /// v = 1 − cos θh at the row boundaries (rows + 1 entries, 0 to 1).
    pub row_v: Vec<f32>,
    /// Columns per table (x = |φh − φo| / π in equal steps).
    pub columns: usize,
    /// Probability of the cosine lobe.
    pub cosine_fraction: f32,
    /// Per node, the vertex values of its bilinear density, `row_v.len()` lines of
    /// `columns + 1`, line-major, scaled to a maximum of 1 (unnormalised).
    pub values: Vec<Vec<f32>>,
}

/// The fitted sampler; see the module documentation.
#[derive(Clone)]
pub struct TabulatedSampler {
    /// One table per θo node.
    tables: Vec<BilinearTable>,
    /// v = 1 − cos θh at the row boundaries (`theta_h_cells + 1` entries, 0 to 1).
    row_v: Vec<f32>,
    /// Columns per table.
    phi_cells: usize,
    cosine_fraction: f32,
}

impl std::fmt::Debug for TabulatedSampler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TabulatedSampler")
            .field("theta_o_nodes", &self.tables.len())
            .field("theta_h_cells", &(self.row_v.len() - 1))
            .field("phi_h_cells", &self.phi_cells)
            .field("cosine_fraction", &self.cosine_fraction)
            .finish()
    }
}

/// What a [`TabulatedSampler`] needs of one `wo` (local frame): its two θo nodes and the
/// azimuth the tables are relative to, found once ([`TabulatedSampler::view`]) for all the
/// draws and densities of a shading point.
#[derive(Clone, Copy, Debug, Default)]
pub struct SamplerView {
    wo: Vec3,
    /// The lower θo node and the weight of the upper one.
    node: usize,
    upper_weight: f32,
    /// cos and sin of wo's azimuth.
    cos_phi: f32,
    sin_phi: f32,
}

/// Where a half vector falls in a [`TabulatedSampler`]'s tables: x = |φh − φo| / π, v = 1 −
/// cos θh, √(θh / (π/2)) (the rows' coordinate), and wo · h.
#[derive(Clone, Copy, Debug)]
struct HalfAngles {
    x: f32,
    v: f32,
    root_theta: f32,
    cos_oh: f32,
}

/// A density over [0, 1] × [0, 1] ∋ (x, v), bilinear in each cell of a grid with equal
/// columns in x and the sampler's row boundaries in v.
#[derive(Clone)]
struct BilinearTable {
    /// Vertex values, `rows + 1` lines of `columns + 1`, line-major; finite, ≥ 0.
    values: Vec<f32>,
    /// Per vertex line, ∫ from x = 0 to each vertex (`columns + 1` entries from 0).
    line_cdf: Vec<f32>,
    /// Row masses ∫∫ over each row.
    rows: Distribution1D,
    /// Sum of the row masses (> 0).
    total: f32,
}

/// s ∈ [0, 1] where the integral of the linear function (1 − t) a + t b over [0, s] is the
/// fraction `u` of its integral over [0, 1]; a, b ≥ 0.
#[inline]
fn invert_linear(a: f32, b: f32, u: f32) -> f32 {
    let (a, b, u) = (a as f64, b as f64, u as f64);
    let c = u * 0.5 * (a + b);
    let denominator = a + (a * a + 2.0 * (b - a) * c).max(0.0).sqrt();
    if denominator > 0.0 {
        (2.0 * c / denominator).clamp(0.0, 1.0) as f32
    } else {
        u as f32
    }
}

impl BilinearTable {
    /// Builds from vertex values (negative and non-finite count as 0; all zero becomes
    /// uniform). The values are rescaled to a maximum of 1, so sums cannot overflow.
    fn new(mut values: Vec<f32>, columns: usize, row_v: &[f32]) -> Self {
        let line = columns + 1;
        let max = values
            .iter()
            .filter(|v| v.is_finite())
            .fold(0.0f32, |m, &v| m.max(v));
        for v in values.iter_mut() {
            *v = if v.is_finite() && *v > 0.0 {
                *v / max
            } else {
                0.0
            };
        }
        if values.iter().all(|&v| v == 0.0) {
            values.fill(1.0);
        }
        let dx = 1.0 / columns as f32;
        let mut line_cdf = vec![0f32; values.len()];
        for (cdf, vals) in line_cdf
            .chunks_exact_mut(line)
            .zip(values.chunks_exact(line))
        {
            let mut acc = 0f64;
            for i in 0..columns {
                acc += 0.5 * (vals[i] + vals[i + 1]) as f64 * dx as f64;
                cdf[i + 1] = acc as f32;
            }
        }
        let line_total = |r: usize| line_cdf[r * line + columns];
        let masses: Vec<f32> = (0..row_v.len() - 1)
            .map(|r| (row_v[r + 1] - row_v[r]) * 0.5 * (line_total(r) + line_total(r + 1)))
            .collect();
        let total = masses.iter().map(|&m| m as f64).sum::<f64>() as f32;
        BilinearTable {
            values,
            line_cdf,
            rows: Distribution1D::new(&masses),
            total,
        }
    }

    /// Draws (x, v) from `u`.
    #[inline]
    fn sample(&self, u: Vec2, columns: usize, row_v: &[f32]) -> (f32, f32) {
        let line = columns + 1;
        let (r, _, u_row) = self.rows.sample_discrete(u.y);
        let (c0, c1) = (
            &self.line_cdf[r * line..(r + 1) * line],
            &self.line_cdf[(r + 1) * line..(r + 2) * line],
        );
        let s = invert_linear(c0[columns], c1[columns], u_row);
        let q_cdf = |i: usize| (1.0 - s) * c0[i] + s * c1[i];
        let target = u.x * q_cdf(columns);
        // The last column whose cumulative value is ≤ target (q_cdf(0) = 0): q_cdf rises
        // with i (rounded sums and products of non-negative, non-decreasing terms), so that
        // is the count of inner vertices ≤ target. Counted without branches (and in vector
        // lanes) rather than by bisection, whose branches a random target mispredicts.
        let lo = (1..columns).map(|i| (q_cdf(i) <= target) as usize).sum::<usize>();
        let (v0, v1) = (
            &self.values[r * line..(r + 1) * line],
            &self.values[(r + 1) * line..(r + 2) * line],
        );
        let q = |i: usize| (1.0 - s) * v0[i] + s * v1[i];
        let (qa, qb) = (q(lo), q(lo + 1));
        let segment = 0.5 * (qa + qb) / columns as f32;
        let fraction = if segment > 0.0 {
            ((target - q_cdf(lo)) / segment).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let tau = invert_linear(qa, qb, fraction);
        let x = (lo as f32 + tau) / columns as f32;
        let v = row_v[r] + s * (row_v[r + 1] - row_v[r]);
        (x, v)
    }

    /// Density at (x, v) in row `r` with respect to dx dv.
    #[inline]
    fn density(&self, x: f32, v: f32, r: usize, columns: usize, row_v: &[f32]) -> f32 {
        let line = columns + 1;
        let s = ((v - row_v[r]) / (row_v[r + 1] - row_v[r])).clamp(0.0, 1.0);
        let xc = (x * columns as f32).clamp(0.0, columns as f32);
        let i = (xc as usize).min(columns - 1);
        let tau = xc - i as f32;
        let at = |line_index: usize| {
            let vals = &self.values[line_index * line..(line_index + 1) * line];
            (1.0 - tau) * vals[i] + tau * vals[i + 1]
        };
        ((1.0 - s) * at(r) + s * at(r + 1)) / self.total
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

/// v = 1 − cos θh at the row boundary y = sqrt(θh / (π/2)), accurate near 0.
fn row_boundary_v(y: f64) -> f32 {
    let theta_h = y * y * std::f64::consts::FRAC_PI_2;
    let s = (theta_h / 2.0).sin();
    (2.0 * s * s) as f32
}

/// Half vector with 1 − cos θh = `v` and φh − φo = `sign` · `x` · π, in the frame where `wo`
/// has azimuth 0.
#[inline]
fn half_vector_at(v: f32, x: f32, sign: f32) -> Vec3 {
    let sin_h = (v * (2.0 - v)).max(0.0).sqrt();
    let (sp, cp) = sin_cos_turns(0.5 * x);
    Vec3::new(sin_h * cp, sin_h * (sign * sp), 1.0 - v)
}

impl TabulatedSampler {
    /// Bytes of its tables (values, cumulative sums and row distributions).
    pub fn heap_bytes(&self) -> usize {
        let per_table = |b: &BilinearTable| (b.values.len() + b.line_cdf.len() + 3 * b.rows.len()) * std::mem::size_of::<f32>();
        self.tables.iter().map(per_table).sum::<usize>() + self.row_v.len() * std::mem::size_of::<f32>()
    }

    /// Fits the tables from `brdf(wo, wi)` (f_r in 1/sr, local frame, as [`super::Bxdf::eval`]),
    /// the θo nodes in parallel. Negative and non-finite values count as 0.
    ///
    /// # Panics
    /// When the config has fewer than 2 θo nodes or a zero resolution (a programming error).
    pub fn new(brdf: impl Fn(Vec3, Vec3) -> Rgb + Sync, config: &TabulatedSamplerConfig) -> Self {
        let c = *config;
        assert!(
            c.theta_o_nodes >= 2 && c.theta_h_cells > 0 && c.phi_h_cells > 0,
            "invalid TabulatedSamplerConfig {c:?}"
        );
        let row_v: Vec<f32> = (0..=c.theta_h_cells)
            .map(|r| row_boundary_v(r as f64 / c.theta_h_cells as f64))
            .collect();
        let tables = (0..c.theta_o_nodes)
            .into_par_iter()
            .map(|k| {
                let theta_o =
                    (k as f32 / (c.theta_o_nodes - 1) as f32 * FRAC_PI_2).min(MAX_NODE_THETA_O);
                let (so, co) = theta_o.sin_cos();
                let wo = Vec3::new(so, 0.0, co);
                BilinearTable::new(
                    vertex_values(&brdf, wo, &row_v, c.phi_h_cells),
                    c.phi_h_cells,
                    &row_v,
                )
            })
            .collect();
        TabulatedSampler {
            tables,
            row_v,
            phi_cells: c.phi_h_cells,
            cosine_fraction: c.cosine_fraction.clamp(0.0, 1.0),
        }
    }

    /// What the draws and densities given `wo` (local frame) share: the two θo nodes around
    /// it, the weight of the upper one, and its azimuth.
    #[inline]
    pub fn view(&self, wo: Vec3) -> SamplerView {
        let n = self.tables.len();
        let s = crate::brdf_coords::polar_angle(wo) / FRAC_PI_2 * (n - 1) as f32;
        let node = (s.max(0.0) as usize).min(n - 2);
        let (cos_phi, sin_phi) = azimuth(wo);
        SamplerView {
            wo,
            node,
            upper_weight: (s - node as f32).clamp(0.0, 1.0),
            cos_phi,
            sin_phi,
        }
    }

    /// The fitted tables.
    pub fn tables(&self) -> SamplerTables {
        let n = self.tables.len();
        SamplerTables {
            theta_o: (0..n).map(|k| k as f32 / (n - 1) as f32 * FRAC_PI_2).collect(),
            row_v: self.row_v.clone(),
            columns: self.phi_cells,
            cosine_fraction: self.cosine_fraction,
            values: self.tables.iter().map(|t| t.values.clone()).collect(),
        }
    }

    /// Draws wi given `wo` (local frame, z > 0) from a 2D sample `u` and a 1D sample `uc`
    /// (which picks cosine lobe, θo node and the sign of φh − φo). `None` when `wo` is below
    /// the horizon or the drawn reflection is. The density of the result is [`Self::pdf`].
    pub fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<Vec3> {
        self.sample_in(&self.view(wo), u, uc)
    }

    /// [`Self::sample`] given the view of `wo`.
    #[inline]
    pub fn sample_in(&self, view: &SamplerView, u: Vec2, uc: f32) -> Option<Vec3> {
        if view.wo.z <= 0.0 {
            return None;
        }
        let (lobe, _) = self.choose(view, uc);
        self.sample_lobe(view, lobe, u)
    }

    /// [`Self::sample`] with its density [`Self::pdf`]; `None` also where the density is not
    /// positive and finite. What [`Bxdf::sample`] of a [`TabulatedBrdf`] draws.
    #[inline]
    pub fn sample_with_pdf(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<(Vec3, f32)> {
        self.sample_with_pdf_in(&self.view(wo), u, uc)
    }

    /// [`Self::sample_with_pdf`] given the view of `wo`.
    #[inline]
    pub fn sample_with_pdf_in(&self, view: &SamplerView, u: Vec2, uc: f32) -> Option<(Vec3, f32)> {
        let wi = self.sample_in(view, u, uc)?;
        let pdf = self.pdf_in(view, wi);
        (pdf > 0.0 && pdf.is_finite()).then_some((wi, pdf))
    }

    /// As [`Self::sample`] from one 2D sample: `u.x` picks the lobe, and what is left of it
    /// after the choice (uniform on [0, 1) again, independent of the choice) is the first
    /// coordinate of the direction. Same density, [`Self::pdf`].
    pub fn sample_2d(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        if wo.z <= 0.0 {
            return None;
        }
        let view = self.view(wo);
        let (lobe, rest) = self.choose(&view, u.x);
        self.sample_lobe(&view, lobe, Vec2::new(rest.min(ONE_MINUS_EPSILON), u.y))
    }

    /// The lobe `uc` picks given the view of `wo`, and `uc` rescaled to [0, 1) within its
    /// choice.
    #[inline]
    fn choose(&self, view: &SamplerView, uc: f32) -> (Lobe, f32) {
        let cf = self.cosine_fraction;
        if uc < cf || cf >= 1.0 {
            return (Lobe::Cosine, uc / cf.max(f32::MIN_POSITIVE));
        }
        let uc = (uc - cf) / (1.0 - cf);
        let (k, t) = (view.node, view.upper_weight);
        let (node, uc) = if uc < 1.0 - t {
            (k, uc / (1.0 - t))
        } else {
            (k + 1, (uc - (1.0 - t)) / t)
        };
        if uc < 0.5 {
            (Lobe::Table { node, sign: 1.0 }, 2.0 * uc)
        } else {
            (Lobe::Table { node, sign: -1.0 }, 2.0 * uc - 1.0)
        }
    }

    /// Draws wi from one lobe given the view of `wo` (z > 0) and a 2D sample.
    #[inline]
    fn sample_lobe(&self, view: &SamplerView, lobe: Lobe, u: Vec2) -> Option<Vec3> {
        let Lobe::Table { node, sign } = lobe else {
            let wi = sample_cosine_hemisphere(u);
            return (wi.z > 0.0).then_some(wi);
        };
        let (x, v) = self.tables[node].sample(u, self.phi_cells, &self.row_v);
        let hl = half_vector_at(v, x, sign);
        let (c, s, wo) = (view.cos_phi, view.sin_phi, view.wo);
        let h = Vec3::new(c * hl.x - s * hl.y, s * hl.x + c * hl.y, hl.z);
        let wi = crate::bsdf::microfacet::reflect(wo, h);
        (wi.z > 0.0 && wo.dot(h) > 0.0).then(|| wi.normalize())
    }

    /// Solid-angle density (1/sr) with which [`Self::sample`] draws `wi` given `wo`; 0 below
    /// either horizon.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.pdf_in(&self.view(wo), wi)
    }

    /// [`Self::pdf`] given the view of `wo`.
    #[inline]
    pub fn pdf_in(&self, view: &SamplerView, wi: Vec3) -> f32 {
        if view.wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        self.mixture(wi.z, self.table_pdf(view, wi))
    }

    /// The sampling mixture's density (1/sr) at a direction of cos θi `wi_z` whose tabulated
    /// part's density is `table`.
    #[inline(always)]
    fn mixture(&self, wi_z: f32, table: f32) -> f32 {
        let cf = self.cosine_fraction;
        cf * cosine_hemisphere_pdf(wi_z) + (1.0 - cf) * table
    }

    /// Density of the tabulated part alone (1/sr), both horizons already checked.
    #[inline]
    fn table_pdf(&self, view: &SamplerView, wi: Vec3) -> f32 {
        let wo = view.wo;
        let h = (wo + wi).normalize();
        let cos_oh = wo.dot(h);
        if cos_oh.is_nan() || cos_oh <= 0.0 {
            return 0.0;
        }
        let (c, s) = (view.cos_phi, view.sin_phi);
        let hx = c * h.x + s * h.y;
        let hy = -s * h.x + c * h.y;
        let sin2_h = hx * hx + hy * hy;
        let root_theta = (atan2(sin2_h.sqrt(), h.z) / FRAC_PI_2).sqrt();
        // 1 − cos θh as sin²θh / (1 + cos θh): no cancellation near h = n (h.z > 0 here).
        let v = sin2_h / (1.0 + h.z);
        let x = (atan2(hy, hx).abs() / PI).min(1.0);
        self.table_pdf_at(view, HalfAngles { x, v, root_theta, cos_oh })
    }

    /// [`Self::table_pdf`] from the half vector's coordinates, `cos_oh` > 0.
    #[inline]
    fn table_pdf_at(&self, view: &SamplerView, a: HalfAngles) -> f32 {
        let ny = self.row_v.len() - 1;
        let row = ((a.root_theta * ny as f32) as usize).min(ny - 1);
        let (k, t) = (view.node, view.upper_weight);
        let mut density = (1.0 - t) * self.tables[k].density(a.x, a.v, row, self.phi_cells, &self.row_v);
        if t > 0.0 {
            density += t * self.tables[k + 1].density(a.x, a.v, row, self.phi_cells, &self.row_v);
        }
        // Per dx dv of one sign -> per solid angle of h over both signs (dωh = π dv dx, ½ per
        // sign) -> per solid angle of wi (dωh / dωi = 1 / (4 wo·h)).
        let pdf = density / (2.0 * PI * 4.0 * a.cos_oh);
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }

    /// [`Self::pdf_in`] of [`LANES`] (view, `wi`) pairs at once, each lane with its own sampler
    /// (`samplers[lane]`, lanes without one give 0): the half vector's coordinates in lanes with
    /// the scalar operations, the tables read lane by lane — the same bits as `pdf_in`.
    #[inline(always)]
    pub fn pdf_in_lanes(samplers: &[Option<(&TabulatedSampler, SamplerView)>; LANES], wi: Vec3s) -> [f32; LANES] {
        let mut wo = Vec3s::splat(Vec3::Z);
        let (mut c, mut s) = (F32s::splat(1.0), F32s::splat(0.0));
        for (lane, entry) in samplers.iter().enumerate() {
            if let Some((_, view)) = entry {
                wo.set(lane, view.wo);
                (c.0[lane], s.0[lane]) = (view.cos_phi, view.sin_phi);
            }
        }
        let sum = wo + wi;
        let h = sum * (1.0 / sum.dot(sum).sqrt());
        let cos_oh = wo.dot(h);
        let hx = c * h.x + s * h.y;
        let hy = -s * h.x + c * h.y;
        let sin2_h = hx * hx + hy * hy;
        let root_theta = (atan2(sin2_h.sqrt(), h.z) / FRAC_PI_2).sqrt();
        let v = sin2_h / (1.0 + h.z);
        let x = (atan2(hy, hx).abs() / PI).min(F32s::splat(1.0));
        std::array::from_fn(|lane| match samplers[lane] {
            Some((sampler, view)) => {
                let wi_z = wi.z.0[lane];
                if view.wo.z <= 0.0 || wi_z <= 0.0 {
                    return 0.0;
                }
                let cos_oh = cos_oh.0[lane];
                let table = if cos_oh.is_nan() || cos_oh <= 0.0 {
                    0.0
                } else {
                    let a = HalfAngles { x: x.0[lane], v: v.0[lane], root_theta: root_theta.0[lane], cos_oh };
                    sampler.table_pdf_at(&view, a)
                };
                sampler.mixture(wi_z, table)
            }
            None => 0.0,
        })
    }

    /// The cosine-lobe probability in use.
    pub fn cosine_fraction(&self) -> f32 {
        self.cosine_fraction
    }
}

/// One component of the sampling mixture.
#[derive(Clone, Copy, Debug)]
enum Lobe {
    Cosine,
    /// The table of θo node `node`, with φh − φo of sign `sign` (±1).
    Table { node: usize, sign: f32 },
}

/// Vertex values of one θo node, line-major: f cos θi per unit solid angle of h, averaged
/// over both signs of φh − φo.
fn vertex_values(
    brdf: &impl Fn(Vec3, Vec3) -> Rgb,
    wo: Vec3,
    row_v: &[f32],
    columns: usize,
) -> Vec<f32> {
    let line = columns + 1;
    let mut values = vec![0f32; row_v.len() * line];
    for (r, &v) in row_v.iter().enumerate() {
        for i in 0..line {
            let x = i as f32 / columns as f32;
            let mut acc = 0f32;
            for sign in [1.0, -1.0] {
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
                    acc += 0.5 * mean * wi.z * 4.0 * cos_oh;
                }
            }
            values[r * line + i] = acc;
        }
    }
    values
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::microfacet::GgxDistribution;

    /// A GGX lobe over a small diffuse term: a BRDF with a known shape.
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

    /// ∫ pdf dωi over the upper hemisphere by the midpoint rule in (θ, φ).
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
    fn invert_linear_inverts() {
        for (a, b) in [
            (1.0f32, 1.0f32),
            (0.0, 2.0),
            (3.0, 0.0),
            (0.5, 4.0),
            (0.0, 0.0),
        ] {
            for k in 0..=10 {
                let u = k as f32 / 10.0;
                let s = invert_linear(a, b, u);
                let mass = a * s + 0.5 * (b - a) * s * s;
                let want = if a + b > 0.0 { u * 0.5 * (a + b) } else { 0.0 };
                assert!((mass - want).abs() < 1e-5, "a {a} b {b} u {u}: s {s}");
                assert!((0.0..=1.0).contains(&s));
            }
        }
    }

    #[test]
    fn bilinear_table_samples_its_density() {
        // A 2 × 2-cell table with uneven rows: the density of each sample equals the density
        // of the points around it (histogram check), and it integrates to 1.
        let row_v = [0.0f32, 0.2, 1.0];
        let values = vec![1.0, 3.0, 0.0, 2.0, 0.5, 1.0, 0.0, 4.0, 2.0];
        let table = BilinearTable::new(values, 2, &row_v);
        let n = 256;
        let mut hist = [0f64; 16];
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let (x, v) = table.sample(u, 2, &row_v);
                assert!((0.0..=1.0).contains(&x) && (0.0..=1.0).contains(&v));
                let cell = ((x * 4.0) as usize).min(3) + 4 * ((v * 4.0) as usize).min(3);
                hist[cell] += 1.0 / (n * n) as f64;
            }
        }
        let mut total = 0.0f64;
        for (cell, &sampled) in hist.iter().enumerate() {
            let (cx, cv) = (cell % 4, cell / 4);
            let mut mass = 0.0f64;
            let m = 64;
            for a in 0..m {
                for b in 0..m {
                    let x = (cx as f32 + (a as f32 + 0.5) / m as f32) / 4.0;
                    let v = (cv as f32 + (b as f32 + 0.5) / m as f32) / 4.0;
                    let r = if v < 0.2 { 0 } else { 1 };
                    mass += table.density(x, v, r, 2, &row_v) as f64 / (16 * m * m) as f64;
                }
            }
            total += mass;
            assert!(
                (sampled - mass).abs() < 3e-3,
                "cell {cell}: sampled {sampled} vs density {mass}"
            );
        }
        assert!((total - 1.0).abs() < 1e-3, "{total}");
    }

    /// Fraction of `sample` calls (stratified u, uc) that return a direction.
    fn success_rate(s: &TabulatedSampler, wo: Vec3) -> f64 {
        let n = 128u32;
        let mut ok = 0usize;
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let uc = ((i * 31 + j * 17) % 97) as f32 / 97.0;
                ok += s.sample(wo, u, uc).is_some() as usize;
            }
        }
        ok as f64 / (n * n) as f64
    }

    #[test]
    fn density_integrates_to_the_sampled_fraction() {
        let s = TabulatedSampler::new(ggx_brdf(0.3), &TabulatedSamplerConfig::default());
        for theta_o in [0.0f32, 0.7, 1.3, 1.55] {
            let wo = Vec3::new(theta_o.sin(), 0.0, theta_o.cos());
            let total = integrate_pdf(&s, wo);
            let rate = success_rate(&s, wo);
            assert!(total < 1.0 + 1e-3, "θo {theta_o}: ∫pdf = {total}");
            assert!(
                (total - rate).abs() < 5e-3,
                "θo {theta_o}: ∫pdf = {total}, sampled {rate}"
            );
        }
    }

    #[test]
    fn chi2_passes_and_detects_a_mismatched_density() {
        let config = crate::testing::chi2::Chi2Config::default()
            .with_sample_count(200_000)
            .with_domain(crate::testing::chi2::Chi2Domain::ThetaPhi)
            .with_test_count(2);
        let sampled = TabulatedSampler::new(ggx_brdf(0.1), &TabulatedSamplerConfig::default());
        let other = TabulatedSampler::new(ggx_brdf(0.13), &TabulatedSamplerConfig::default());
        let wo = Vec3::new(0.5, 0.3, 0.81).normalize();
        let good = crate::testing::chi2::test_sampler(
            |u, uc| sampled.sample(wo, u, uc),
            |wi| sampled.pdf(wo, wi),
            &config,
        );
        assert!(good.passed(), "{good}");
        let bad = crate::testing::chi2::test_sampler(
            |u, uc| sampled.sample(wo, u, uc),
            |wi| other.pdf(wo, wi),
            &config,
        );
        assert!(!bad.passed(), "{bad}");
    }

    #[test]
    fn huge_and_invalid_values_keep_the_density_exact() {
        let brdf = |wo: Vec3, wi: Vec3| {
            let h = (wo + wi).normalize();
            if h.z > 0.999 {
                Rgb::splat(1e37)
            } else if h.x > 0.5 {
                Rgb::splat(f32::NAN)
            } else {
                Rgb::splat(1.0)
            }
        };
        let s = TabulatedSampler::new(brdf, &TabulatedSamplerConfig::default());
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let total = integrate_pdf(&s, wo);
        let rate = success_rate(&s, wo);
        assert!(
            (total - rate).abs() < 5e-3,
            "∫pdf = {total}, sampled {rate}"
        );
    }

    #[test]
    fn samples_report_positive_finite_densities() {
        let s = TabulatedSampler::new(ggx_brdf(0.05), &TabulatedSamplerConfig::default());
        let wo = Vec3::new(0.5, -0.2, 0.8).normalize();
        let mut drawn = 0;
        for i in 0..4096u32 {
            let u = Vec2::new(
                (i as f32 + 0.5) / 4096.0,
                (i.wrapping_mul(2_654_435_761) >> 8) as f32 / 16_777_216.0,
            );
            let uc = ((i * 7919) % 4096) as f32 / 4096.0;
            if let Some(wi) = s.sample(wo, u, uc) {
                drawn += 1;
                assert!((wi.length() - 1.0).abs() < 1e-4 && wi.z > 0.0);
                let p = s.pdf(wo, wi);
                assert!(p > 0.0 && p.is_finite(), "{wi:?}: {p}");
            }
        }
        assert!(drawn > 3900, "{drawn}");
        assert!(s
            .sample(Vec3::new(0.0, 0.6, -0.8), Vec2::splat(0.5), 0.5)
            .is_none());
        assert_eq!(s.pdf(Vec3::Z, Vec3::new(0.0, 0.6, -0.8)), 0.0);
    }

    #[test]
    fn zero_brdf_falls_back_to_a_valid_density() {
        let s = TabulatedSampler::new(|_, _| Rgb::ZERO, &TabulatedSamplerConfig::default());
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let total = integrate_pdf(&s, wo);
        let rate = success_rate(&s, wo);
        assert!(
            total > 0.1 && (total - rate).abs() < 5e-3,
            "∫pdf = {total}, sampled {rate}"
        );
    }

    /// `pdf_in_lanes` gives `pdf_in`'s bits in every lane: two samplers mixed across the
    /// lanes, empty lanes, directions drawn from the sampler (h near n included), random
    /// ones, below either horizon, grazing, and wi = −wo (no half vector).
    #[test]
    fn lanes_give_the_scalar_densities() {
        use rand::{Rng, SeedableRng};
        let config = TabulatedSamplerConfig { theta_o_nodes: 8, theta_h_cells: 16, phi_h_cells: 8, cosine_fraction: 0.1 };
        let samplers = [TabulatedSampler::new(ggx_brdf(0.05), &config), TabulatedSampler::new(ggx_brdf(0.5), &config)];
        let mut rng = rand_pcg::Pcg32::seed_from_u64(5);
        let direction = |rng: &mut rand_pcg::Pcg32, lower: f32| {
            let z: f32 = rng.random_range(lower..1.0);
            let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let r = (1.0 - z * z).max(0.0).sqrt();
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        };
        for round in 0..400 {
            let mut lanes: [Option<(&TabulatedSampler, SamplerView)>; LANES] = [None; LANES];
            let mut wi = Vec3s::default();
            for lane in 0..LANES {
                if (round + lane) % 7 == 0 {
                    continue;
                }
                let sampler = &samplers[lane % 2];
                let wo = direction(&mut rng, if lane % 5 == 0 { -0.2 } else { 1e-4 });
                let view = sampler.view(wo);
                let w = match lane % 4 {
                    0 => sampler.sample_in(&view, Vec2::new(rng.random(), rng.random()), rng.random()).unwrap_or(Vec3::Z),
                    1 => -wo,
                    _ => direction(&mut rng, -0.3),
                };
                lanes[lane] = Some((sampler, view));
                wi.set(lane, w);
            }
            let got = TabulatedSampler::pdf_in_lanes(&lanes, wi);
            for lane in 0..LANES {
                let want = lanes[lane].map_or(0.0, |(sampler, view)| sampler.pdf_in(&view, wi.get(lane)));
                assert_eq!(got[lane].to_bits(), want.to_bits(), "lane {lane} of round {round}");
            }
        }
    }
}
