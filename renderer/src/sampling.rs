//! Warping functions from the unit square to directions, their densities (always in
//! named pairs: `sample_x` / `x_pdf`), piecewise-constant distributions and the MIS
//! heuristic.

use glam::{Vec2, Vec3};
use crate::lanes::{F32s, MaskOps, Real, Vec2s, LANES, V2, V3};
use std::f32::consts::{FRAC_1_PI, FRAC_PI_2, FRAC_PI_4};

/// The largest f32 below 1: where a number drawn in [0, 1) is clamped.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// Uniform point on the unit disk, concentric mapping (Shirley–Chiu), branch-free: the
/// angle within the octant is at most π/4, where [`sin_cos_octant`] is exact to about
/// one ulp.
#[inline]
pub fn sample_concentric_disk(u: Vec2) -> Vec2 {
    concentric_disk(V2::from(u)).into()
}

/// [`sample_concentric_disk`] over [`Real`] values (one point, or one per lane).
#[inline(always)]
pub(crate) fn concentric_disk<R: Real>(u: V2<R>) -> V2<R> {
    let zero = R::splat(0.0);
    let ox = u.x * 2.0 - 1.0;
    let oy = u.y * 2.0 - 1.0;
    let x_major = ox.abs().gt(oy.abs());
    let (r, minor) = x_major.select((ox, oy), (oy, ox));
    // |minor| ≤ |r|; r = 0 only at the centre, which maps to the origin.
    let ratio = R::select(r.eq(zero), zero, minor / r);
    let (sin, cos) = sin_cos_octant(ratio * FRAC_PI_4);
    // x-major: θ = π/4 · y/x; y-major: θ = π/2 − π/4 · x/y, so cos θ and sin θ swap.
    let (cos_theta, sin_theta) = x_major.select((cos, sin), (sin, cos));
    V2 { x: cos_theta * r, y: sin_theta * r }
}

/// (sin x, cos x) for |x| ≤ π/4 by the minimax polynomials of Cephes' `sinf`/`cosf`.
#[inline(always)]
pub fn sin_cos_octant<R: Real>(x: R) -> (R, R) {
    let x2 = x * x;
    let sin = x + x * x2 * (R::splat(-1.666_665_5e-1) + x2 * (R::splat(8.332_161e-3) + x2 * -1.951_529_6e-4));
    let cos = R::splat(1.0) - x2 * 0.5 + x2 * x2 * (R::splat(4.166_664_6e-2) + x2 * (R::splat(-1.388_731_6e-3) + x2 * 2.443_315_7e-5));
    (sin, cos)
}

/// (sin 2πu, cos 2πu) for 0 ≤ u < 2²¹, an angle given in turns, for one value or per lane:
/// reduced to the nearest quarter turn q (exactly: 4u − q needs no rounding there),
/// [`sin_cos_octant`] on the remaining |x| ≤ π/4, and the quarter turn applied by swapping
/// and negating. About one ulp from the exact values in [0, 1), several times faster than
/// libm's `sinf`/`cosf`.
#[inline(always)]
pub fn sin_cos_turns<R: Real>(u: R) -> (R, R) {
    let (x, q) = quarter_turns(u);
    let (s, c) = sin_cos_octant(x);
    let is = |k: f32| q.eq(R::splat(k));
    let swap = is(1.0) | is(3.0);
    let (s, c) = swap.select((c, s), (s, c));
    let s = R::select(q.ge(R::splat(2.0)), -s, s);
    let c = R::select(is(1.0) | is(2.0), -c, c);
    (s, c)
}

/// The angle 2πu as x + q π/2 with q ∈ {0, 1, 2, 3} the nearest quarter turn (modulo a
/// whole turn) and |x| ≤ π/4. Rounds by truncation (a conversion to `i32` and back, one
/// instruction each way without SSE4.1's `roundss`), which is the floor for the u ≥ −1/8 it
/// is meant for.
#[inline(always)]
fn quarter_turns<R: Real>(u: R) -> (R, R) {
    let t = u * 4.0;
    let nearest = (t + 0.5).truncate();
    let x = (t - nearest) * FRAC_PI_2;
    let q = nearest - (nearest * 0.25).truncate() * 4.0;
    (x, q)
}

/// Cosine-weighted direction on the upper (z ≥ 0) hemisphere.
#[inline]
pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3 {
    cosine_hemisphere(V2::from(u)).into()
}

/// [`sample_cosine_hemisphere`] over [`Real`] values (one direction, or one per lane).
#[inline(always)]
pub(crate) fn cosine_hemisphere<R: Real>(u: V2<R>) -> V3<R> {
    let d = concentric_disk(u);
    let z = (R::splat(1.0) - (d.x * d.x + d.y * d.y)).max(R::splat(0.0)).sqrt();
    V3::new(d.x, d.y, z)
}

/// Density of [`sample_cosine_hemisphere`] in 1/sr.
#[inline]
pub fn cosine_hemisphere_pdf<R: Real>(cos_theta: R) -> R {
    cos_theta.max(R::splat(0.0)) * FRAC_1_PI
}

/// Uniform direction on the unit sphere.
#[inline]
pub fn sample_uniform_sphere(u: Vec2) -> Vec3 {
    uniform_sphere(V2::from(u)).into()
}

/// [`sample_uniform_sphere`] over [`Real`] values (one direction, or one per lane).
#[inline(always)]
pub(crate) fn uniform_sphere<R: Real>(u: V2<R>) -> V3<R> {
    let z = R::splat(1.0) - u.x * 2.0;
    let r = (R::splat(1.0) - z * z).max(R::splat(0.0)).sqrt();
    let (sin_phi, cos_phi) = sin_cos_turns(u.y);
    V3::new(r * cos_phi, r * sin_phi, z)
}

/// Density of [`sample_uniform_sphere`] in 1/sr.
#[inline]
pub fn uniform_sphere_pdf() -> f32 {
    0.25 * FRAC_1_PI
}

/// Uniform barycentric coordinates (b1, b2) on a triangle (Heitz 2019, low distortion).
#[inline]
pub fn sample_uniform_triangle(u: Vec2) -> Vec2 {
    uniform_triangle(V2::from(u)).into()
}

/// [`sample_uniform_triangle`] over [`Real`] values (one point, or one per lane).
#[inline(always)]
pub(crate) fn uniform_triangle<R: Real>(u: V2<R>) -> V2<R> {
    // Selects rather than branches: which half u falls in is a coin flip per sample.
    let lower = u.x.lt(u.y);
    let b0 = R::select(lower, u.x * 0.5, u.x - u.y * 0.5);
    let b1 = R::select(lower, u.y - u.x * 0.5, u.y * 0.5);
    V2 { x: b1, y: R::splat(1.0) - b0 - b1 }
}

/// Power heuristic with β = 2 for MIS (Veach 1997); `f` and `g` are the two densities
/// (one pair, or one per lane).
#[inline(always)]
pub fn power_heuristic<R: Real>(f: R, g: R) -> R {
    let zero = R::splat(0.0);
    let (f2, g2) = (f * f, g * g);
    let sum = f2 + g2;
    let ratio = R::select(sum.eq(zero), zero, f2 / sum);
    R::select(f2.is_infinite(), R::splat(1.0), ratio)
}

/// A discrete distribution over `n` cells (a piecewise-constant density on [0, 1) over `n`
/// equal cells), sampled by inverting its cumulative distribution.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    /// Non-negative cell weights as given.
    func: Vec<f32>,
    /// Normalised CDF, `func.len() + 1` entries from 0 to 1, followed by [`SCAN_CELLS`]
    /// entries of +∞ so that a window of [`SCAN_CELLS`] entries from any index is in bounds.
    cdf: Vec<f32>,
    /// Guide table of the search (the cutpoint method), for more than [`SCAN_CELLS`] cells:
    /// `guide[k]` = number of CDF entries ≤ k / K for k = 0 … K, K = `guide.len() − 1` a power
    /// of two near an eighth of the cells (a search then spans a cache line or two of the CDF
    /// and the table stays small), so the entries ≤ u lie below `guide[k + 1]` and include
    /// the first `guide[k]` for u in [k / K, (k + 1) / K) (exact in f32: K is a power of two).
    /// Where those bounds are at most [`SCAN_CELLS`] apart (nearly always), the entries are
    /// counted in a fixed window without branches; else searched by bisection.
    guide: Vec<u32>,
    /// Integral of `func` over [0, 1).
    integral: f32,
}

/// Distributions of at most this many cells are searched by counting, without branches.
const SCAN_CELLS: usize = 16;

impl Distribution1D {
    /// Builds the distribution. Negative or non-finite weights count as zero; when all
    /// weights are zero the distribution is uniform (and `integral()` returns 0).
    pub fn new(weights: &[f32]) -> Self {
        assert!(!weights.is_empty(), "Distribution1D needs at least one cell");
        let n = weights.len();
        let func: Vec<f32> = weights
            .iter()
            .map(|&w| if w.is_finite() && w > 0.0 { w } else { 0.0 })
            .collect();
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0f32);
        let mut acc = 0.0f64;
        for &w in &func {
            acc += w as f64 / n as f64;
            cdf.push(acc as f32);
        }
        let integral = acc as f32;
        if acc > 0.0 {
            for c in cdf.iter_mut() {
                *c = (*c as f64 / acc) as f32;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n as f32;
            }
        }
        cdf[n] = 1.0;
        cdf.extend([f32::INFINITY; SCAN_CELLS]);
        let guide = if n > SCAN_CELLS {
            let k = (n / 8).next_power_of_two();
            (0..=k).map(|j| cdf[..=n].partition_point(|&c| c <= j as f32 / k as f32) as u32).collect()
        } else {
            Vec::new()
        };
        Distribution1D {
            func,
            cdf,
            guide,
            integral,
        }
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// Always false: a distribution has at least one cell.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Integral of the weights over [0, 1) (mean weight).
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// Weight of one cell.
    pub fn weight(&self, i: usize) -> f32 {
        self.func[i]
    }

    /// Samples a cell index; returns it and its probability mass ([`Self::sample_discrete`]
    /// without the remapped u, for callers that draw nothing more from it).
    #[inline]
    pub fn sample_cell(&self, u: f32) -> (usize, f32) {
        let i = self.find_cell(u);
        (i, self.pdf_cell(i))
    }

    /// Samples a cell index; returns (index, its probability mass, u remapped to [0, 1)).
    pub fn sample_discrete(&self, u: f32) -> (usize, f32, f32) {
        let i = self.find_cell(u);
        let (c0, c1) = (self.cdf[i], self.cdf[i + 1]);
        let remapped = if c1 > c0 {
            ((u - c0) / (c1 - c0)).clamp(0.0, ONE_MINUS_EPSILON)
        } else {
            0.5
        };
        (i, self.pdf_cell(i), remapped)
    }

    /// Probability mass of cell `i`.
    #[inline]
    pub fn pdf_cell(&self, i: usize) -> f32 {
        self.cdf[i + 1] - self.cdf[i]
    }

    #[inline(always)]
    fn find_cell(&self, u: f32) -> usize {
        // Last index with cdf[i] <= u, skipping zero-mass cells. A few cells (a scene's
        // lights) are counted without branches; many are searched between the guide table's
        // bounds (the same index as a search of the whole CDF).
        let n = self.func.len();
        let count = |window: &[f32]| window.iter().map(|&c| (c <= u) as usize).sum::<usize>();
        let at_most_u = if n <= SCAN_CELLS {
            count(&self.cdf[..=n])
        } else {
            let k = self.guide.len() - 1;
            let j = ((u * k as f32).max(0.0) as usize).min(k - 1);
            let (lo, hi) = (self.guide[j] as usize, self.guide[j + 1] as usize);
            if !(0.0..1.0).contains(&u) {
                self.cdf[..=n].partition_point(|&c| c <= u)
            } else if hi - lo <= SCAN_CELLS {
                // Entries from `hi` on (the CDF's or the +∞ padding) exceed u.
                lo + count(&self.cdf[lo..lo + SCAN_CELLS])
            } else {
                lo + self.cdf[lo..hi].partition_point(|&c| c <= u)
            }
        };
        let mut i = at_most_u.saturating_sub(1).min(n - 1);
        if self.pdf_cell(i) > 0.0 {
            return i;
        }
        while i > 0 && self.pdf_cell(i) == 0.0 {
            i -= 1;
        }
        while i + 1 < n && self.pdf_cell(i) == 0.0 {
            i += 1;
        }
        i
    }
}

/// One cell of an alias table: a draw that lands in the cell keeps it when the draw's
/// remainder within the cell is below `threshold`, else takes cell `alias`.
#[derive(Clone, Copy, Debug, Default)]
struct AliasEntry {
    threshold: f32,
    alias: u32,
}

/// Walker's alias table for the cells of `weights` (as Vose builds it, in f64), appended to
/// `entries`: every cell is drawn with probability weight / Σ weights in one look-up, without
/// a search. Negative or non-finite weights count as zero, and a zero-weight cell is never
/// drawn; when all weights are zero every cell is equally likely. Returns Σ weights (of the
/// cleaned weights, 0 when all are zero).
fn push_alias_table(weights: &[f32], entries: &mut Vec<AliasEntry>) -> f64 {
    let clean = |w: f32| if w.is_finite() && w > 0.0 { w as f64 } else { 0.0 };
    let n = weights.len();
    let sum: f64 = weights.iter().map(|&w| clean(w)).sum();
    let first = entries.len();
    entries.extend((0..n).map(|i| AliasEntry { threshold: 1.0, alias: i as u32 }));
    if sum == 0.0 {
        return 0.0;
    }
    let table = &mut entries[first..];
    // Each cell's probability × n: below 1 the cell lends the rest of its column to a cell
    // above 1, which then holds that much less.
    let mut scaled: Vec<f64> = weights.iter().map(|&w| clean(w) * n as f64 / sum).collect();
    let (mut small, mut large): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| scaled[i] < 1.0);
    while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
        small.pop();
        table[s] = AliasEntry {
            threshold: scaled[s] as f32,
            alias: l as u32,
        };
        scaled[l] -= 1.0 - scaled[s];
        if scaled[l] < 1.0 {
            large.pop();
            small.push(l);
        }
    }
    // What is left holds probability ≈ 1 / n by construction (up to rounding) and keeps its
    // whole column; a zero-weight cell left over by rounding gives its column to the
    // heaviest cell instead, so it is never drawn.
    let heaviest = (0..n).max_by(|&a, &b| clean(weights[a]).total_cmp(&clean(weights[b]))).unwrap_or(0);
    for i in small.into_iter().chain(large) {
        table[i] = if clean(weights[i]) > 0.0 {
            AliasEntry { threshold: 1.0, alias: i as u32 }
        } else {
            AliasEntry { threshold: 0.0, alias: heaviest as u32 }
        };
    }
    sum
}

/// The entry of an alias table of `n` entries that [`sample_alias`] of `u` reads, and u · n.
#[inline(always)]
fn alias_entry(n: usize, u: f32) -> (usize, f32) {
    let x = u * n as f32;
    ((x as usize).min(n - 1), x)
}

/// Draws a cell of the alias table `entries` with u in [0, 1): the cell and u's remainder
/// remapped to [0, 1), uniform and independent of the cell drawn (pbrt-v4's
/// `AliasTable::Sample`). Branch-free: the kept-or-aliased choice is a select.
#[inline]
fn sample_alias(entries: &[AliasEntry], u: f32) -> (usize, f32) {
    let (i, x) = alias_entry(entries.len(), u);
    let r = (x - i as f32).clamp(0.0, ONE_MINUS_EPSILON);
    let AliasEntry { threshold, alias } = entries[i];
    let keep = r < threshold;
    let cell = if keep { i } else { alias as usize };
    // Kept: r ∈ [0, threshold) with threshold > 0; aliased: r ∈ [threshold, 1) with
    // threshold < 1. Either width is positive.
    let (low, width) = if keep { (0.0, threshold) } else { (threshold, 1.0 - threshold) };
    (cell, ((r - low) / width).min(ONE_MINUS_EPSILON))
}

/// [`sample_alias`] per lane, with the same operations (so the same bits): lane k draws
/// from the table of `n` entries starting at `entries[offsets[k]]`, and gets a cell of that
/// table. Any u reads in bounds (indices are clamped as the scalar draw clamps them), so
/// lanes whose u is stale may be drawn and ignored.
#[inline(always)]
fn sample_alias_lanes(entries: &[AliasEntry], n: usize, offsets: [usize; LANES], u: F32s) -> ([usize; LANES], F32s) {
    let (mut index, mut r) = ([0usize; LANES], F32s::splat(0.0));
    let (mut threshold, mut alias) = (F32s::splat(0.0), [0usize; LANES]);
    for k in 0..LANES {
        let (i, x) = alias_entry(n, u.0[k]);
        index[k] = i;
        r.0[k] = (x - i as f32).clamp(0.0, ONE_MINUS_EPSILON);
        let entry = entries[offsets[k] + index[k]];
        (threshold.0[k], alias[k]) = (entry.threshold, entry.alias as usize);
    }
    let keep = r.lt(threshold);
    let mut cell = [0usize; LANES];
    for k in 0..LANES {
        cell[k] = if keep.0[k] { index[k] } else { alias[k] };
    }
    let low = keep.select(F32s::splat(0.0), threshold);
    let width = keep.select(threshold, 1.0 - threshold);
    (cell, ((r - low) / width).min(F32s::splat(ONE_MINUS_EPSILON)))
}

/// A piecewise-constant density on [0, 1)² given on a `width × height` grid (row-major,
/// row = v), sampled as a marginal in v and a conditional in u, each by an alias table: a
/// sample is two look-ups, not two searches. Each cell carries a payload `T` (an
/// environment's radiance) in one record with its density: a sample of a large image reads
/// an alias entry at random in its row (the rows' tables are kept apart from the records,
/// eight bytes per cell, so that a row's table spans few cache lines) and the record of the
/// cell drawn, mostly a heavy one and so likely cached; a density look-up reads one record.
/// Unlike an inverse CDF, the alias map from u to cells is not monotonic: it would break the
/// stratification of low-discrepancy samples, which the renderer's independent streams do
/// not have.
#[derive(Clone, Debug)]
pub struct Distribution2D<T: Copy = ()> {
    width: usize,
    height: usize,
    /// Alias table over the rows.
    marginal: Vec<AliasEntry>,
    /// Alias table of each row over its columns, row-major (aliases are columns).
    conditional: Vec<AliasEntry>,
    /// Per cell, row-major.
    cells: Vec<Cell<T>>,
    /// Mean weight (the integral over [0, 1)²).
    integral: f32,
}

/// A cell of a [`Distribution2D`]: its density with respect to area in [0, 1)², and its
/// payload.
#[derive(Clone, Copy, Debug)]
struct Cell<T> {
    density: f32,
    payload: T,
}

impl Distribution2D {
    /// Builds from `width * height` weights, row-major (index = u + width * v), without
    /// payloads. See [`Self::with_payloads`].
    pub fn new(weights: &[f32], width: usize, height: usize) -> Self {
        Self::with_payloads(weights, vec![(); weights.len()], width, height)
    }
}

impl<T: Copy> Distribution2D<T> {
    /// Builds from `width * height` weights and payloads, row-major (index = u + width * v).
    /// Negative or non-finite weights count as zero; when all are zero the density is
    /// uniform (and `integral()` returns 0).
    pub fn with_payloads(weights: &[f32], payloads: Vec<T>, width: usize, height: usize) -> Self {
        assert!(width > 0 && height > 0, "Distribution2D needs at least one cell");
        assert_eq!(weights.len(), width * height, "Distribution2D size mismatch");
        assert_eq!(payloads.len(), weights.len(), "Distribution2D payload count mismatch");
        let mut conditional = Vec::with_capacity(weights.len());
        let row_sums: Vec<f32> = weights
            .chunks_exact(width)
            .map(|row| push_alias_table(row, &mut conditional) as f32)
            .collect();
        let mut marginal = Vec::with_capacity(height);
        let total = push_alias_table(&row_sums, &mut marginal);
        let count = (width * height) as f64;
        let density = |w: f32| match total > 0.0 {
            true if w.is_finite() && w > 0.0 => (w as f64 * count / total) as f32,
            true => 0.0,
            false => 1.0,
        };
        let cells = weights
            .iter()
            .zip(payloads)
            .map(|(&w, payload)| Cell {
                density: density(w),
                payload,
            })
            .collect();
        Distribution2D {
            width,
            height,
            marginal,
            conditional,
            cells,
            integral: (total / count) as f32,
        }
    }

    /// Number of cells along u (columns) and v (rows).
    #[inline]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Integral of the weights over [0, 1)².
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// Samples a point in [0, 1)²; returns it, its density (with respect to area in the
    /// unit square) and the payload of the cell it was drawn in. The point is uniform within
    /// its cell.
    #[inline]
    pub fn sample_continuous(&self, u: Vec2) -> (Vec2, f32, T) {
        let (w, h) = (self.width, self.height);
        let (row, dv) = sample_alias(&self.marginal, u.y);
        let (col, du) = sample_alias(&self.conditional[row * w..(row + 1) * w], u.x);
        let cell = &self.cells[col + row * w];
        let p = Vec2::new((col as f32 + du) / w as f32, (row as f32 + dv) / h as f32).min(Vec2::splat(ONE_MINUS_EPSILON));
        (p, cell.density, cell.payload)
    }

    /// [`Self::sample_continuous`] per lane, with the same operations (so the same bits);
    /// every lane is drawn, whatever its u.
    #[inline(always)]
    pub fn sample_continuous_lanes(&self, u: Vec2s) -> (Vec2s, F32s, [T; LANES]) {
        let (w, h) = (self.width, self.height);
        let (row, dv) = sample_alias_lanes(&self.marginal, h, [0; LANES], u.y);
        let (col, du) = sample_alias_lanes(&self.conditional, w, row.map(|r| r * w), u.x);
        let mut density = F32s::splat(0.0);
        let mut payload = [self.cells[0].payload; LANES];
        for k in 0..LANES {
            let cell = &self.cells[col[k] + row[k] * w];
            density.0[k] = cell.density;
            payload[k] = cell.payload;
        }
        let one_minus = F32s::splat(ONE_MINUS_EPSILON);
        let column = F32s(col.map(|c| c as f32));
        let row = F32s(row.map(|r| r as f32));
        let p = Vec2s {
            x: ((column + du) / w as f32).min(one_minus),
            y: ((row + dv) / h as f32).min(one_minus),
        };
        (p, density, payload)
    }

    /// Density at a point of [0, 1)² of [`Self::sample_continuous`], and the payload of the
    /// cell there.
    #[inline]
    pub fn at(&self, p: Vec2) -> (f32, T) {
        let cell = &self.cells[self.cell_index(p)];
        (cell.density, cell.payload)
    }

    /// Starts fetching the record that [`Self::at`] of `p` reads into the cache, so that the
    /// look-ups of many points, issued after all their prefetches, overlap their misses. No
    /// effect on values.
    #[inline]
    pub fn prefetch_at(&self, p: Vec2) {
        crate::support::prefetch(&self.cells[self.cell_index(p)]);
    }

    /// The row-major index of the cell holding `p`.
    #[inline]
    fn cell_index(&self, p: Vec2) -> usize {
        let (w, h) = self.size();
        let row = ((p.y * h as f32) as usize).min(h - 1);
        let col = ((p.x * w as f32) as usize).min(w - 1);
        col + row * w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_hemisphere_is_normalised_and_upper() {
        let n = 64;
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let w = sample_cosine_hemisphere(u);
                assert!((w.length() - 1.0).abs() < 1e-4);
                assert!(w.z >= 0.0);
            }
        }
    }

    #[test]
    fn distribution1d_samples_match_weights() {
        let d = Distribution1D::new(&[0.0, 1.0, 3.0, 0.0]);
        assert!((d.integral() - 1.0).abs() < 1e-6);
        let mut counts = [0usize; 4];
        let n = 10_000;
        for k in 0..n {
            let (i, mass, remapped) = d.sample_discrete((k as f32 + 0.5) / n as f32);
            assert!(mass > 0.0);
            assert_eq!(mass, d.pdf_cell(i));
            assert!((0.0..1.0).contains(&remapped), "{remapped}");
            counts[i] += 1;
        }
        assert_eq!(counts[0], 0);
        assert_eq!(counts[3], 0);
        assert!((counts[2] as f32 / counts[1] as f32 - 3.0).abs() < 0.01);
        // Cell 2 holds three quarters of the mass: density 3 over its quarter of [0, 1).
        assert!((d.pdf_cell(2) * 4.0 - 3.0).abs() < 1e-5);
    }

    /// The guide table only narrows the search: every u finds the cell a search of the whole
    /// CDF finds, on spiky weights with runs of empty cells, at cell boundaries and at the
    /// ends of [0, 1).
    #[test]
    fn guided_search_finds_the_cell_of_a_full_search() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(3);
        for n in [17usize, 100, 1000, 4097] {
            let weights: Vec<f32> = (0..n)
                .map(|i| match i % 7 {
                    0 | 1 => 0.0,
                    2 => rng.random_range(0.0..1e-6),
                    3 => rng.random_range(0.0..1e4),
                    _ => rng.random_range(0.0..1.0),
                })
                .collect();
            let d = Distribution1D::new(&weights);
            let full = |u: f32| {
                let mut i = d.cdf[..=n].partition_point(|&c| c <= u).saturating_sub(1).min(n - 1);
                while i > 0 && d.pdf_cell(i) == 0.0 {
                    i -= 1;
                }
                while i + 1 < n && d.pdf_cell(i) == 0.0 {
                    i += 1;
                }
                i
            };
            let us = (0..20_000)
                .map(|_| rng.random::<f32>())
                .chain(d.cdf[..=n].iter().flat_map(|&c| [c, f32::from_bits(c.to_bits().saturating_sub(1)), c.next_up()]))
                .chain([0.0, ONE_MINUS_EPSILON, 1.0, -0.0, f32::NAN]);
            for u in us {
                assert_eq!(d.find_cell(u), full(u), "n {n}, u {u:e}");
            }
        }
    }

    /// The probability with which each cell of an alias table is drawn, from its entries:
    /// its own kept share and the shares other cells give it.
    fn alias_probabilities(entries: &[AliasEntry]) -> Vec<f64> {
        let n = entries.len() as f64;
        let mut p = vec![0.0f64; entries.len()];
        for (i, e) in entries.iter().enumerate() {
            p[i] += e.threshold as f64 / n;
            p[e.alias as usize] += (1.0 - e.threshold as f64) / n;
        }
        p
    }

    /// Every cell is drawn with probability weight / Σ weights (zero-weight, negative and
    /// non-finite cells never), on spiky weights over many magnitudes, one heavy cell among
    /// empty ones, all-zero weights (uniform) and a single cell.
    #[test]
    fn alias_tables_draw_each_cell_in_proportion_to_its_weight() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(5);
        let spiky: Vec<f32> = (0..1000)
            .map(|i| match i % 9 {
                0 => 0.0,
                1 => 1e6 * rng.random::<f32>(),
                2 => 1e-6 * rng.random::<f32>(),
                3 => -1.0,
                4 => f32::NAN,
                _ => rng.random(),
            })
            .collect();
        let mut one_heavy = vec![0.0f32; 257];
        one_heavy[100] = 3.0;
        for weights in [spiky, one_heavy, vec![0.0; 7], vec![2.5]] {
            let mut entries = Vec::new();
            let sum = push_alias_table(&weights, &mut entries);
            let clean: Vec<f64> = weights.iter().map(|&w| if w.is_finite() && w > 0.0 { w as f64 } else { 0.0 }).collect();
            assert_eq!(sum, clean.iter().sum::<f64>());
            let n = weights.len() as f64;
            for (i, p) in alias_probabilities(&entries).into_iter().enumerate() {
                let expected = if sum > 0.0 { clean[i] / sum } else { 1.0 / n };
                assert!((p - expected).abs() <= 1e-6 * expected + 1e-12, "cell {i}: {p} vs {expected}");
                if expected == 0.0 {
                    assert_eq!(p, 0.0, "cell {i}");
                }
            }
        }
    }

    /// Draws land in the cells the table says, never in a zero-weight one, and the
    /// remapped remainder is uniform over [0, 1) within each cell.
    #[test]
    fn alias_draws_follow_the_table_and_remap_u_uniformly() {
        let weights = [1.0f32, 0.0, 3.0, 0.5, 0.0, 2.0];
        let mut entries = Vec::new();
        push_alias_table(&weights, &mut entries);
        let probabilities = alias_probabilities(&entries);
        let m = 600_000;
        let mut counts = [0usize; 6];
        let mut remainder_sums = [0.0f64; 6];
        for k in 0..m {
            let (cell, r) = sample_alias(&entries, (k as f32 + 0.5) / m as f32);
            assert!((0.0..1.0).contains(&r), "{r}");
            counts[cell] += 1;
            remainder_sums[cell] += r as f64;
        }
        for cell in 0..6 {
            let frequency = counts[cell] as f64 / m as f64;
            assert!((frequency - probabilities[cell]).abs() < 1e-4, "cell {cell}: {frequency} vs {}", probabilities[cell]);
            if counts[cell] > 0 {
                let mean = remainder_sums[cell] / counts[cell] as f64;
                assert!((mean - 0.5).abs() < 1e-3, "cell {cell}: mean remainder {mean}");
            }
        }
        assert_eq!(counts[1] + counts[4], 0);
        // The ends of [0, 1) stay in range.
        for u in [0.0, ONE_MINUS_EPSILON] {
            let (cell, r) = sample_alias(&entries, u);
            assert!(cell < 6 && weights[cell] > 0.0 && (0.0..1.0).contains(&r));
        }
    }

    /// Points fall in the cell whose payload is reported, with that cell's density, which is its weight over
    /// the mean weight; the cells' frequencies over a fine grid of u follow the weights.
    #[test]
    fn distribution2d_samples_follow_the_weights() {
        let (w, h) = (5, 3);
        let weights: Vec<f32> = (0..w * h).map(|i| (i % 4) as f32 * (1.0 + i as f32)).collect();
        // Each cell's payload is its index.
        let d = Distribution2D::with_payloads(&weights, (0..w * h).collect(), w, h);
        let mean = weights.iter().sum::<f32>() / (w * h) as f32;
        assert!((d.integral() - mean).abs() < 1e-6 * mean);
        let n = 700;
        let mut counts = vec![0usize; w * h];
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let (p, pdf, cell) = d.sample_continuous(u);
                assert!(p.cmpge(Vec2::ZERO).all() && p.cmplt(Vec2::ONE).all(), "{p}");
                assert_eq!(cell, (p.x * w as f32) as usize + w * (p.y * h as f32) as usize, "{u}: {p}");
                assert_eq!((pdf, cell), d.at(p));
                assert!((pdf - weights[cell] / mean).abs() < 1e-5 * pdf, "{pdf}");
                counts[cell] += 1;
            }
        }
        for (cell, &count) in counts.iter().enumerate() {
            let expected = weights[cell] as f64 / (mean as f64 * (w * h) as f64);
            let frequency = count as f64 / (n * n) as f64;
            assert!((frequency - expected).abs() < 2e-3, "cell {cell}: {frequency} vs {expected}");
        }
        // Sixteen draws at once are the draws one by one, bit for bit, the extreme u (in and
        // out of [0, 1), NaN) included.
        let extremes = [0.0, ONE_MINUS_EPSILON, 1.0, -0.5, 2.0, f32::NAN, f32::INFINITY];
        for group in 0..40 {
            let u: [Vec2; LANES] = std::array::from_fn(|k| {
                let i = group * LANES + k;
                match i % 9 {
                    0 => Vec2::new(extremes[i % 7], extremes[(i / 7) % 7]),
                    _ => Vec2::new((i as f32 * 0.618_034).fract(), (i as f32 * 0.414_213_5).fract()),
                }
            });
            let mut lanes = Vec2s::default();
            for (k, &u) in u.iter().enumerate() {
                lanes.set(k, u);
            }
            let (p, pdf, cells) = d.sample_continuous_lanes(lanes);
            for (k, &u) in u.iter().enumerate() {
                let (expected_p, expected_pdf, expected_cell) = d.sample_continuous(u);
                let got = (p.x.0[k].to_bits(), p.y.0[k].to_bits(), pdf.0[k].to_bits(), cells[k]);
                let expected = (expected_p.x.to_bits(), expected_p.y.to_bits(), expected_pdf.to_bits(), expected_cell);
                assert_eq!(got, expected, "u = {u}");
            }
        }
        // All-zero weights: uniform.
        let uniform = Distribution2D::new(&[0.0; 6], 3, 2);
        assert_eq!(uniform.integral(), 0.0);
        assert_eq!(uniform.sample_continuous(Vec2::new(0.7, 0.2)).1, 1.0);
    }

    #[test]
    fn concentric_disk_matches_the_trigonometric_mapping() {
        for i in 0..=64 {
            for j in 0..=64 {
                let u = Vec2::new(i as f32 / 64.0, j as f32 / 64.0);
                let o = 2.0 * u - Vec2::ONE;
                let expected = if o == Vec2::ZERO {
                    Vec2::ZERO
                } else if o.x.abs() > o.y.abs() {
                    let theta = std::f32::consts::FRAC_PI_4 * (o.y / o.x);
                    Vec2::new(theta.cos(), theta.sin()) * o.x
                } else {
                    let theta = std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (o.x / o.y);
                    Vec2::new(theta.cos(), theta.sin()) * o.y
                };
                let d = sample_concentric_disk(u);
                assert!((d - expected).length() < 2e-7, "{u}: {d} vs {expected}");
                assert!(d.length() <= 1.0 + 1e-6);
            }
        }
        for k in -100..=100 {
            let x = k as f32 / 100.0 * std::f32::consts::FRAC_PI_4;
            let (s, c) = sin_cos_octant(x);
            assert!((s - x.sin()).abs() <= 1.2e-7 && (c - x.cos()).abs() <= 1.2e-7, "{x}");
        }
    }

    #[test]
    fn triangle_samples_stay_inside_and_cover_both_halves() {
        let mut inside_lower = 0;
        for i in 0..32 {
            for j in 0..32 {
                let u = Vec2::new((i as f32 + 0.5) / 32.0, (j as f32 + 0.5) / 32.0);
                let b = sample_uniform_triangle(u);
                assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0, "{u}: {b}");
                inside_lower += (b.x > b.y) as u32;
            }
        }
        // Uniform on the triangle: b1 > b2 on half the samples.
        assert!((inside_lower as i32 - 512).abs() < 40, "{inside_lower}");
    }

    /// Within two ulps of f64's sine and cosine of 2πu over [0, 1), exact at the quarter
    /// turns, and the same bits per lane as one at a time.
    #[test]
    fn sin_cos_turns_is_accurate_and_equal_per_lane() {
        let n = 1 << 16;
        let mut worst = 0.0f64;
        for k in 0..n {
            let u = (k as f32 + 0.37) / n as f32;
            let (s, c) = sin_cos_turns(u);
            let (es, ec) = (2.0 * std::f64::consts::PI * u as f64).sin_cos();
            worst = worst.max((s as f64 - es).abs()).max((c as f64 - ec).abs());
        }
        assert!(worst < 2.0 * f32::EPSILON as f64, "largest error {worst:e}");
        for (u, s, c) in [(0.0, 0.0, 1.0), (0.25, 1.0, 0.0), (0.5, 0.0, -1.0), (0.75, -1.0, 0.0)] {
            assert_eq!(sin_cos_turns(u), (s, c), "u = {u}");
        }
        let mut u = F32s::default();
        for start in (0..n).step_by(crate::lanes::LANES * 97) {
            for (i, x) in u.0.iter_mut().enumerate() {
                *x = (start + i) as f32 / n as f32;
            }
            let (s, c) = sin_cos_turns(u);
            for (i, &x) in u.0.iter().enumerate() {
                let (es, ec) = sin_cos_turns(x);
                assert_eq!((s.0[i].to_bits(), c.0[i].to_bits()), (es.to_bits(), ec.to_bits()), "u = {x}");
            }
        }
    }

    /// Uniform sphere directions per lane are the scalar ones bit for bit, poles included.
    #[test]
    fn uniform_sphere_lanes_equal_scalar_samples() {
        let mut rng = crate::sampler::Sampler::new(5, 2, 9);
        let mut u = Vec2s::default();
        for group in 0..64 {
            for lane in 0..crate::lanes::LANES {
                let v = if group == 0 { Vec2::new([0.0, 0.5, 0.999_999_94][lane % 3], 0.25) } else { rng.next_2d() };
                u.set(lane, v);
            }
            let d = uniform_sphere(u);
            for lane in 0..crate::lanes::LANES {
                let expected = sample_uniform_sphere(Vec2::new(u.x.0[lane], u.y.0[lane]));
                assert_eq!(d.get(lane).to_array().map(f32::to_bits), expected.to_array().map(f32::to_bits));
            }
        }
    }

    #[test]
    fn power_heuristic_limits() {
        assert_eq!(power_heuristic(1.0, 0.0), 1.0);
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
        assert_eq!(power_heuristic(f32::INFINITY, 1.0), 1.0);
        assert!((power_heuristic(1.0, 1.0) - 0.5).abs() < 1e-6);
    }
}
