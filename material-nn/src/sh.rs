//! Real spherical harmonics and an exact quadrature on an equiangular-in-φ sphere grid.
//!
//! Conventions:
//! - Directions are given by the polar angle θ ∈ [0, π] (from +z) and the azimuth φ ∈ [0, 2π);
//!   x = sin θ cos φ, y = sin θ sin φ, z = cos θ. Angles in radians.
//! - Real, orthonormal SH over the unit sphere (∫ Y_lm Y_l'm' dω = δ δ), without the
//!   Condon–Shortley phase:
//!   Y_l0 = P̄_l0(cos θ), Y_lm = √2 P̄_lm(cos θ) cos(mφ) (m > 0),
//!   Y_lm = √2 P̄_l|m|(cos θ) sin(|m|φ) (m < 0), where P̄_lm = N_lm P_lm is the associated
//!   Legendre function with its normalisation N_lm = √((2l+1)/(4π) · (l−m)!/(l+m)!) folded in.
//! - Coefficients are stored in the order `index = l² + l + m` ([`sh_index`]), so degree L has
//!   (L+1)² of them.
//! - P̄_lm is computed by the standard three-term recurrences on the *normalised* functions,
//!   so no factorial is ever formed and degrees in the hundreds stay finite (f64).
//!
//! The grid ([`ShGrid`]) has L+1 Gauss–Legendre nodes in cos θ and 2L+2 uniform azimuths: the
//! quadrature is exact for every product Y_lm · Y_l'm' with l, l' ≤ L, so the coefficients
//! of a function band-limited to degree L are recovered exactly (up to rounding).

use std::f64::consts::PI;

/// Number of coefficients of a degree-`lmax` expansion: (L+1)².
pub fn coefficient_count(lmax: usize) -> usize {
    (lmax + 1) * (lmax + 1)
}

/// Index of coefficient (l, m), |m| ≤ l, in the order l² + l + m.
pub fn sh_index(l: usize, m: i64) -> usize {
    debug_assert!(m.unsigned_abs() as usize <= l);
    ((l * l + l) as i64 + m) as usize
}

/// Degree l of a coefficient index (inverse of [`sh_index`] in l).
pub fn degree_of(index: usize) -> usize {
    let mut l = (index as f64).sqrt() as usize;
    while (l + 1) * (l + 1) <= index {
        l += 1;
    }
    while l * l > index {
        l -= 1;
    }
    l
}

/// The normalised associated Legendre functions P̄_lm(x) for 0 ≤ m ≤ l ≤ `lmax`, written to
/// `out[l(l+1)/2 + m]` (length (L+1)(L+2)/2). `x` = cos θ ∈ [−1, 1].
///
/// Recurrences (Holmes & Featherstone 2002, in the unit-sphere normalisation):
/// P̄_00 = 1/√(4π); P̄_mm = √((2m+1)/(2m)) · sin θ · P̄_(m−1)(m−1);
/// P̄_(m+1)m = √(2m+3) · x · P̄_mm;
/// P̄_lm = a_lm (x P̄_(l−1)m − b_lm P̄_(l−2)m), a_lm = √((4l²−1)/(l²−m²)),
/// b_lm = √(((l−1)²−m²)/(4(l−1)²−1)).
pub fn legendre_normalised(lmax: usize, x: f64, out: &mut [f64]) {
    let tri = |l: usize, m: usize| l * (l + 1) / 2 + m;
    debug_assert!(out.len() > tri(lmax, lmax));
    let s = (1.0 - x * x).max(0.0).sqrt();
    let mut pmm = 1.0 / (4.0 * PI).sqrt();
    for m in 0..=lmax {
        if m > 0 {
            pmm *= ((2 * m + 1) as f64 / (2 * m) as f64).sqrt() * s;
        }
        out[tri(m, m)] = pmm;
        if m < lmax {
            out[tri(m + 1, m)] = ((2 * m + 3) as f64).sqrt() * x * pmm;
        }
        for l in m + 2..=lmax {
            let (lf, mf) = (l as f64, m as f64);
            let a = ((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf)).sqrt();
            let b = (((lf - 1.0) * (lf - 1.0) - mf * mf) / (4.0 * (lf - 1.0) * (lf - 1.0) - 1.0))
                .sqrt();
            out[tri(l, m)] = a * (x * out[tri(l - 1, m)] - b * out[tri(l - 2, m)]);
        }
    }
}

/// All real SH Y_lm(θ, φ), l ≤ `lmax`, in [`sh_index`] order (length (L+1)²).
pub fn real_sh(lmax: usize, theta: f64, phi: f64) -> Vec<f64> {
    let mut p = vec![0.0; (lmax + 1) * (lmax + 2) / 2];
    legendre_normalised(lmax, theta.cos(), &mut p);
    let mut out = vec![0.0; coefficient_count(lmax)];
    fill_real_sh(lmax, &p, phi, &mut out);
    out
}

/// Combines P̄_lm (from [`legendre_normalised`]) with the azimuthal factors into Y_lm.
fn fill_real_sh(lmax: usize, p: &[f64], phi: f64, out: &mut [f64]) {
    let sqrt2 = std::f64::consts::SQRT_2;
    for l in 0..=lmax {
        let base = l * (l + 1) / 2;
        out[l * l + l] = p[base];
        for m in 1..=l {
            let (s, c) = (m as f64 * phi).sin_cos();
            let v = sqrt2 * p[base + m];
            out[l * l + l + m] = v * c;
            out[l * l + l - m] = v * s;
        }
    }
}

/// P_n(z) and P_(n−1)(z) of the (unnormalised) Legendre polynomials, n ≥ 1, by Bonnet's
/// recurrence.
fn legendre_pair(n: usize, z: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, z);
    for k in 2..=n {
        let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
        p0 = p1;
        p1 = p2;
    }
    (p1, p0)
}

/// Gauss–Legendre nodes and weights on [−1, 1] (n ≥ 1 nodes, exact for polynomials of degree
/// ≤ 2n − 1). Nodes in decreasing order (so θ = acos(x) increases); Newton iteration in f64
/// from Tricomi's initial guesses.
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    let derivative = |z: f64| {
        let (pn, pn1) = legendre_pair(n, z);
        (pn, n as f64 * (z * pn - pn1) / (z * z - 1.0))
    };
    for i in 0..n.div_ceil(2) {
        let mut z = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        for _ in 0..100 {
            let (pn, dp) = derivative(z);
            let dz = pn / dp;
            z -= dz;
            if dz.abs() < 1e-15 {
                break;
            }
        }
        let (_, dp) = derivative(z);
        x[i] = z;
        x[n - 1 - i] = -z;
        w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
        w[n - 1 - i] = w[i];
    }
    (x, w)
}

/// The quadrature grid of degree L: `theta_count` = L+1 Gauss–Legendre rings in cos θ times
/// `phi_count` = 2L+2 azimuths φ_k = 2πk / (2L+2). Point (j, k) has index j · phi_count + k.
#[derive(Clone, Debug)]
pub struct ShGrid {
    /// Maximum degree L.
    pub lmax: usize,
    /// cos θ_j of the rings, decreasing (θ increasing from the north pole).
    pub cos_theta: Vec<f64>,
    /// Quadrature weight of each point of ring j: GL weight × 2π / phi_count (they sum to 4π).
    pub ring_weight: Vec<f64>,
    /// Number of azimuths per ring.
    pub phi_count: usize,
}

impl ShGrid {
    /// The grid that integrates products of SH of degree ≤ `lmax` exactly.
    pub fn new(lmax: usize) -> Self {
        let (x, w) = gauss_legendre(lmax + 1);
        let phi_count = 2 * lmax + 2;
        let dphi = 2.0 * PI / phi_count as f64;
        ShGrid {
            lmax,
            cos_theta: x,
            ring_weight: w.iter().map(|w| w * dphi).collect(),
            phi_count,
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.cos_theta.len() * self.phi_count
    }

    /// Whether the grid has no points (never, for a grid made by [`ShGrid::new`]).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Azimuth of column k, radians.
    pub fn phi(&self, k: usize) -> f64 {
        2.0 * PI * k as f64 / self.phi_count as f64
    }

    /// (θ, φ) of point `index`, radians.
    pub fn angles(&self, index: usize) -> (f64, f64) {
        let (j, k) = (index / self.phi_count, index % self.phi_count);
        (self.cos_theta[j].clamp(-1.0, 1.0).acos(), self.phi(k))
    }

    /// Unit vector of point `index`.
    pub fn direction(&self, index: usize) -> [f64; 3] {
        let (theta, phi) = self.angles(index);
        let s = theta.sin();
        [s * phi.cos(), s * phi.sin(), theta.cos()]
    }

    /// Quadrature weight of point `index` (steradians).
    pub fn weight(&self, index: usize) -> f64 {
        self.ring_weight[index / self.phi_count]
    }

    /// Indices of the points of the upper hemisphere (cos θ > 0), in grid order: where
    /// difference directions live. With L+1 rings symmetric about the equator there are
    /// ⌊(L+1)/2⌋ such rings (no ring lies on the equator when L+1 is even).
    pub fn upper_hemisphere(&self) -> Vec<usize> {
        (0..self.len())
            .filter(|&i| self.cos_theta[i / self.phi_count] > 0.0)
            .collect()
    }

    /// Y_lm at every point in `points`: row-major [points.len(), (L+1)²].
    pub fn basis_at(&self, points: &[usize]) -> Vec<f64> {
        let c = coefficient_count(self.lmax);
        let mut out = vec![0.0; points.len() * c];
        let mut p = vec![0.0; (self.lmax + 1) * (self.lmax + 2) / 2];
        let mut ring = usize::MAX;
        for (row, &i) in out.chunks_mut(c).zip(points) {
            let j = i / self.phi_count;
            if j != ring {
                legendre_normalised(self.lmax, self.cos_theta[j], &mut p);
                ring = j;
            }
            fill_real_sh(self.lmax, &p, self.phi(i % self.phi_count), row);
        }
        out
    }

    /// The analysis matrix restricted to `points`: row-major [(L+1)², points.len()] with entry
    /// (lm, p) = weight(p) · Y_lm(p), so coefficients = matrix · values for a function that is
    /// zero on the grid points left out.
    pub fn analysis_matrix(&self, points: &[usize]) -> Vec<f64> {
        let c = coefficient_count(self.lmax);
        let basis = self.basis_at(points);
        let n = points.len();
        let mut out = vec![0.0; c * n];
        for (p, (&i, row)) in points.iter().zip(basis.chunks(c)).enumerate() {
            let w = self.weight(i);
            for (lm, y) in row.iter().enumerate() {
                out[lm * n + p] = w * y;
            }
        }
        out
    }

    /// SH coefficients (length (L+1)²) of a function given by its values at every grid point
    /// (length [`len`](Self::len), grid order), by the quadrature.
    pub fn coefficients(&self, values: &[f64]) -> Vec<f64> {
        debug_assert_eq!(values.len(), self.len());
        let all: Vec<usize> = (0..self.len()).collect();
        let c = coefficient_count(self.lmax);
        let basis = self.basis_at(&all);
        let mut out = vec![0.0; c];
        for ((i, row), v) in basis.chunks(c).enumerate().zip(values) {
            let wv = self.weight(i) * v;
            for (o, y) in out.iter_mut().zip(row) {
                *o += wv * y;
            }
        }
        out
    }
}

/// Per-degree weights of the frequency-rectified loss: a Gaussian in l of width `sigma`,
/// normalised to 1 at l = `lmax`: w_l = exp((L² − l²) / (2σ²)). Returned per coefficient
/// (length (L+1)², [`sh_index`] order).
pub fn degree_weights(lmax: usize, sigma: f64) -> Vec<f64> {
    let ll = (lmax * lmax) as f64;
    (0..coefficient_count(lmax))
        .map(|i| {
            let l = degree_of(i) as f64;
            ((ll - l * l) / (2.0 * sigma * sigma)).exp()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_polynomials() {
        let (x, w) = gauss_legendre(7);
        assert!((w.iter().sum::<f64>() - 2.0).abs() < 1e-13);
        // ∫ x^12 dx over [-1, 1] = 2/13: degree 12 ≤ 2·7 − 1.
        let i: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(12)).sum();
        assert!((i - 2.0 / 13.0).abs() < 1e-13, "{i}");
        assert!(x.windows(2).all(|p| p[0] > p[1]));
    }

    #[test]
    fn indices_round_trip() {
        for l in 0..20 {
            for m in -(l as i64)..=l as i64 {
                assert_eq!(degree_of(sh_index(l, m)), l);
            }
        }
        assert_eq!(sh_index(0, 0), 0);
        assert_eq!(sh_index(1, -1), 1);
        assert_eq!(sh_index(2, 2), 8);
    }

    #[test]
    fn low_order_closed_forms() {
        let (theta, phi) = (0.7f64, 1.9f64);
        let y = real_sh(2, theta, phi);
        let (x, yy, z) = (
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        );
        let c1 = (3.0 / (4.0 * PI)).sqrt();
        let expect = [
            0.5 / PI.sqrt(),
            c1 * yy,
            c1 * z,
            c1 * x,
            0.5 * (15.0 / PI).sqrt() * x * yy,
            0.5 * (15.0 / PI).sqrt() * yy * z,
            0.25 * (5.0 / PI).sqrt() * (3.0 * z * z - 1.0),
            0.5 * (15.0 / PI).sqrt() * x * z,
            0.25 * (15.0 / PI).sqrt() * (x * x - yy * yy),
        ];
        for (a, b) in y.iter().zip(expect) {
            assert!((a - b).abs() < 1e-12, "{y:?}");
        }
    }

    /// Largest |⟨Y_a, Y_b⟩ − δ_ab| on the grid of degree `lmax` over the index pairs `pairs`.
    fn gram_deviation(lmax: usize, pairs: impl Iterator<Item = (usize, usize)>) -> f64 {
        let grid = ShGrid::new(lmax);
        let all: Vec<usize> = (0..grid.len()).collect();
        let c = coefficient_count(lmax);
        let basis = grid.basis_at(&all);
        assert!(basis.iter().all(|v| v.is_finite()));
        let weights: Vec<f64> = all.iter().map(|&i| grid.weight(i)).collect();
        pairs
            .map(|(a, b)| {
                let g: f64 = (0..all.len())
                    .map(|p| weights[p] * basis[p * c + a] * basis[p * c + b])
                    .sum();
                (g - if a == b { 1.0 } else { 0.0 }).abs()
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn orthonormal_on_the_grid() {
        // Every pair at degree 16; at degree 49 every diagonal entry, every pair of equal order
        // m (the ones the azimuthal sum does not cancel) among degrees 40..49, and the pairs of a
        // fixed stride through the whole matrix.
        let c16 = coefficient_count(16);
        let worst = gram_deviation(16, (0..c16).flat_map(|a| (a..c16).map(move |b| (a, b))));
        assert!(worst < 1e-10, "degree 16: {worst}");
        let c = coefficient_count(49);
        let same_m = (40..50usize).flat_map(|l| {
            (40..50usize).flat_map(move |l2| {
                (-(l.min(l2) as i64)..=l.min(l2) as i64)
                    .map(move |m| (sh_index(l, m), sh_index(l2, m)))
            })
        });
        let pairs = (0..c)
            .map(|a| (a, a))
            .chain(same_m)
            .chain((0..c).step_by(7).map(|a| (a, (a * 31 + 5) % c)));
        let worst = gram_deviation(49, pairs);
        assert!(worst < 1e-5, "degree 49: {worst}");
    }

    #[test]
    fn coefficients_of_known_functions() {
        let grid = ShGrid::new(8);
        // A single Y_3,-2 is recovered as a unit coefficient.
        let target = sh_index(3, -2);
        let values: Vec<f64> = (0..grid.len())
            .map(|i| {
                let (t, p) = grid.angles(i);
                real_sh(8, t, p)[target]
            })
            .collect();
        let c = grid.coefficients(&values);
        for (i, v) in c.iter().enumerate() {
            let expect = if i == target { 1.0 } else { 0.0 };
            assert!((v - expect).abs() < 1e-12, "coefficient {i}: {v}");
        }
        // cos θ = √(4π/3) Y_10.
        let values: Vec<f64> = (0..grid.len()).map(|i| grid.angles(i).0.cos()).collect();
        let c = grid.coefficients(&values);
        assert!((c[sh_index(1, 0)] - (4.0 * PI / 3.0).sqrt()).abs() < 1e-12);
        assert!(c
            .iter()
            .enumerate()
            .all(|(i, v)| i == sh_index(1, 0) || v.abs() < 1e-12));
    }

    #[test]
    fn legendre_is_finite_at_high_degree() {
        let l = 400;
        let mut p = vec![0.0; (l + 1) * (l + 2) / 2];
        for x in [-1.0, -0.3, 0.0, 0.999_999, 1.0] {
            legendre_normalised(l, x, &mut p);
            assert!(p.iter().all(|v| v.is_finite()), "x = {x}");
        }
    }

    #[test]
    fn degree_weights_are_one_at_lmax() {
        let w = degree_weights(49, 50.0);
        assert!((w[sh_index(49, 3)] - 1.0).abs() < 1e-12);
        assert!((w[0] - (49.0f64 * 49.0 / 5000.0).exp()).abs() < 1e-12);
    }

    #[test]
    fn upper_hemisphere_is_half_the_grid() {
        let grid = ShGrid::new(49);
        assert_eq!(grid.upper_hemisphere().len(), grid.len() / 2);
    }
}
