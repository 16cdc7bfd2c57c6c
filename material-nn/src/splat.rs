//! k-nearest-neighbour Gaussian splatting of scattered samples on the unit sphere onto fixed
//! target points (the talk's Eq. 4–7), through a uniform-grid spatial index (never a dense
//! distance matrix).
//!
//! For a target direction t the k samples s_i nearest in chordal distance
//! d_i = |t − s_i| = √(2 − 2 t·s_i) (Eq. 5) get the weights w'_i = exp(−d_i² / 2σ²) (Eq. 6),
//! normalised to sum to 1 (Eq. 7). The weights are computed as exp(−(d_i² − d_min²) / 2σ²),
//! which is the same after normalisation and never underflows to 0/0 when every neighbour is
//! far. The splat depends only on the coordinates, so it is a fixed sparse linear map
//! values → target values ([`SplatMap`]).

use crate::error::{Error, Result};

/// The sparse linear map of a splat: target p takes Σ_j `weights[p·k + j]` ·
/// value[`indices[p·k + j]`].
#[derive(Clone, Debug, PartialEq)]
pub struct SplatMap {
    /// Neighbours per target.
    pub k: usize,
    /// Sample indices, `targets × k`, nearest first.
    pub indices: Vec<u32>,
    /// Normalised weights, `targets × k` (each row sums to 1).
    pub weights: Vec<f32>,
}

impl SplatMap {
    /// Number of target points.
    pub fn targets(&self) -> usize {
        self.indices.len() / self.k.max(1)
    }

    /// Applies the map to per-sample values with `channels` interleaved channels
    /// (`values[i·channels + c]`), giving per-target values in the same layout.
    pub fn apply(&self, values: &[f64], channels: usize) -> Vec<f64> {
        let mut out = vec![0.0; self.targets() * channels];
        for (p, row) in out.chunks_mut(channels).enumerate() {
            for j in 0..self.k {
                let (i, w) = (
                    self.indices[p * self.k + j] as usize,
                    self.weights[p * self.k + j] as f64,
                );
                for (o, v) in row
                    .iter_mut()
                    .zip(&values[i * channels..(i + 1) * channels])
                {
                    *o += w * v;
                }
            }
        }
        out
    }
}

/// A uniform grid of cubic cells over [−1, 1]³ holding points (unit vectors), in compressed
/// form: the points of cell c are `order[start[c]..start[c + 1]]`.
struct CellIndex {
    cell: f64,
    n: usize,
    start: Vec<u32>,
    order: Vec<u32>,
}

impl CellIndex {
    fn new(points: &[[f32; 3]], cell: f64) -> Self {
        let n = (2.0 / cell).ceil() as usize;
        let coords: Vec<usize> = points
            .iter()
            .map(|p| Self::flat(n, cell, p.map(f64::from)))
            .collect();
        let mut start = vec![0u32; n * n * n + 1];
        for &c in &coords {
            start[c + 1] += 1;
        }
        for c in 0..n * n * n {
            start[c + 1] += start[c];
        }
        let mut fill = start.clone();
        let mut order = vec![0u32; points.len()];
        for (i, &c) in coords.iter().enumerate() {
            order[fill[c] as usize] = i as u32;
            fill[c] += 1;
        }
        CellIndex {
            cell,
            n,
            start,
            order,
        }
    }

    fn axis(n: usize, cell: f64, v: f64) -> usize {
        (((v + 1.0) / cell).floor().max(0.0) as usize).min(n - 1)
    }

    fn flat(n: usize, cell: f64, p: [f64; 3]) -> usize {
        let [i, j, k] = p.map(|v| Self::axis(n, cell, v));
        (i * n + j) * n + k
    }

    /// The k nearest points to `q` (squared distance, index), nearest first.
    fn nearest(&self, points: &[[f32; 3]], q: [f64; 3], k: usize, best: &mut Vec<(f64, u32)>) {
        best.clear();
        let centre = q.map(|v| Self::axis(self.n, self.cell, v) as i64);
        let n = self.n as i64;
        let consider = |c: usize, best: &mut Vec<(f64, u32)>| {
            for &i in &self.order[self.start[c] as usize..self.start[c + 1] as usize] {
                let p = points[i as usize];
                let d2: f64 = (0..3).map(|a| (q[a] - p[a] as f64).powi(2)).sum();
                if best.len() < k || d2 < best[best.len() - 1].0 {
                    let at = best.partition_point(|&(d, j)| (d, j) < (d2, i));
                    best.insert(at, (d2, i));
                    best.truncate(k);
                }
            }
        };
        for r in 0..=n {
            for di in -r..=r {
                for dj in -r..=r {
                    for dk in -r..=r {
                        if di.abs().max(dj.abs()).max(dk.abs()) != r {
                            continue;
                        }
                        let (i, j, l) = (centre[0] + di, centre[1] + dj, centre[2] + dk);
                        if (0..n).contains(&i) && (0..n).contains(&j) && (0..n).contains(&l) {
                            consider(((i * n + j) * n + l) as usize, best);
                        }
                    }
                }
            }
            // Every point not yet seen lies at least r whole cells away.
            let reach = r as f64 * self.cell;
            if best.len() == k && best[k - 1].0 <= reach * reach {
                break;
            }
        }
    }
}

/// The splat map from `samples` (unit vectors, f32) to `targets` (unit vectors) with `k`
/// neighbours and kernel width `sigma` (chordal distance units).
///
/// Errors when there are fewer than `k` samples or `k` is 0.
pub fn splat_map(
    samples: &[[f32; 3]],
    targets: &[[f64; 3]],
    k: usize,
    sigma: f64,
) -> Result<SplatMap> {
    if k == 0 || samples.len() < k {
        return Err(Error::Invalid(format!(
            "splatting needs at least k = {k} > 0 samples, got {}",
            samples.len()
        )));
    }
    // About four samples per occupied cell on the sphere (area ≤ 4π).
    let cell = (4.0 * std::f64::consts::PI * 4.0 / samples.len() as f64)
        .sqrt()
        .clamp(0.01, 0.5);
    let index = CellIndex::new(samples, cell);
    let mut indices = Vec::with_capacity(targets.len() * k);
    let mut weights = Vec::with_capacity(targets.len() * k);
    let mut best = Vec::with_capacity(k + 1);
    let inv = 1.0 / (2.0 * sigma * sigma);
    for &t in targets {
        index.nearest(samples, t, k, &mut best);
        let d0 = best[0].0;
        let w: Vec<f64> = best
            .iter()
            .map(|&(d2, _)| (-(d2 - d0) * inv).exp())
            .collect();
        let sum: f64 = w.iter().sum();
        for (&(_, i), w) in best.iter().zip(&w) {
            indices.push(i);
            weights.push((w / sum) as f32);
        }
    }
    Ok(SplatMap {
        k,
        indices,
        weights,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn random_unit(rng: &mut impl Rng) -> [f32; 3] {
        let z: f32 = rng.random_range(-1.0..1.0);
        let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
        let s = (1.0 - z * z).sqrt();
        [s * phi.cos(), s * phi.sin(), z]
    }

    #[test]
    fn matches_brute_force() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let samples: Vec<[f32; 3]> = (0..3000).map(|_| random_unit(&mut rng)).collect();
        let targets: Vec<[f64; 3]> = (0..400)
            .map(|_| random_unit(&mut rng).map(f64::from))
            .collect();
        let map = splat_map(&samples, &targets, 2, 0.05).unwrap();
        for (p, t) in targets.iter().enumerate() {
            let mut d: Vec<(f64, u32)> = samples
                .iter()
                .enumerate()
                .map(|(i, s)| ((0..3).map(|a| (t[a] - s[a] as f64).powi(2)).sum(), i as u32))
                .collect();
            d.sort_by(|a, b| a.partial_cmp(b).unwrap());
            assert_eq!(&map.indices[2 * p..2 * p + 2], &[d[0].1, d[1].1]);
            let w = (-(d[1].0 - d[0].0) / (2.0 * 0.05 * 0.05)).exp();
            assert!((map.weights[2 * p] as f64 - 1.0 / (1.0 + w)).abs() < 1e-6);
        }
    }

    #[test]
    fn far_neighbours_keep_finite_weights() {
        let samples = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]];
        let map = splat_map(&samples, &[[0.0, 0.0, -1.0]], 2, 0.05).unwrap();
        assert!(map.weights.iter().all(|w| w.is_finite()));
        assert!((map.weights.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        assert!(splat_map(&samples[..1], &[[0.0, 0.0, 1.0]], 2, 0.05).is_err());
    }
}
