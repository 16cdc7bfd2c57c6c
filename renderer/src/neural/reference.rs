//! The reference BRDF f_ref of a latent file, laid out for the renderer's trilinear look-ups.
//!
//! A latent file stores f_ref as f16 RGB per MERL bin ([`crate::formats::latent_file`]); the
//! mapping needs it trilinearly interpolated at every evaluation of a decoded net, with the
//! same corners and weights as training ([`crate::formats::merl::lookup_trilinear_measured`]).
//! The table (17.5 MB) lies far beyond the caches, so what a look-up costs is the cache lines
//! its eight corners fall in: in the file's order the two θd neighbours of a corner are a
//! whole φd row apart (2,160 bytes as f32), so a look-up touches four to eight lines.
//!
//! Here each bin holds its own value and its θd neighbour's (the next bin along θd, the
//! same bin at the table's end), both as the file's f16 bits: 12 bytes per bin, the size of
//! the f32 table, but a look-up reads two pairs of adjacent bins (θh neighbours × φd
//! neighbours, each pair 24 contiguous bytes), mostly two cache lines, and gets all eight
//! corners. The values are the file's exactly (f16 → f32 is exact), so the interpolated
//! f_ref is the one [`crate::formats::merl::weigh_measured_corners`] gives over the f32 values,
//! up to the order of summation.

use crate::formats::merl::{bin_index, bin_indices, weigh_measured, TrilinearAxes, BIN_COUNT, THETA_D_BINS};
use half::f16;

/// f_ref per MERL bin with each bin's θd neighbour beside it (see the module docs).
pub struct ReferenceTable {
    /// Per bin in [`bin_index`] order: RGB at the bin, then RGB at its θd neighbour; f_r in
    /// 1/sr, a negative channel marks a bin unmeasured.
    entries: Vec<[f16; 6]>,
}

impl std::fmt::Debug for ReferenceTable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReferenceTable").field("bins", &self.entries.len()).finish()
    }
}

impl ReferenceTable {
    /// The table of f16 RGB values per bin in [`bin_index`] order (a latent file's f_ref).
    ///
    /// # Panics
    /// Unless there is one value per MERL bin ([`BIN_COUNT`]); a latent file's reader checks
    /// that.
    pub fn new(values: &[[f16; 3]]) -> Self {
        assert_eq!(values.len(), BIN_COUNT, "one f_ref value per MERL bin");
        let entries = crate::support::collect_on_huge_pages(BIN_COUNT, |i| {
            // The θd neighbour as the look-up clamps it: the bin itself at θd's end.
            let (ih, id, ip) = bin_indices(i);
            let [a, b] = [values[i], values[bin_index(ih, (id + 1).min(THETA_D_BINS - 1), ip)]];
            [a[0], a[1], a[2], b[0], b[1], b[2]]
        });
        ReferenceTable { entries }
    }

    /// Bins in the table ([`BIN_COUNT`]).
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether the table has no bins (never, once built).
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// f_ref of a bin (within-channel index), RGB, 1/sr; negative channels unmeasured.
    pub fn value(&self, bin: usize) -> [f32; 3] {
        let e = &self.entries[bin];
        [e[0], e[1], e[2]].map(f16::to_f32)
    }

    /// f_ref of every bin ([`Self::value`]) in [`bin_index`] order.
    pub fn values(&self) -> Vec<[f32; 3]> {
        (0..self.len()).map(|bin| self.value(bin)).collect()
    }

    /// The entries of θh bin `ih` at the look-up's θd bin, one per φd neighbour.
    #[inline(always)]
    fn pair(&self, ih: usize, axes: &TrilinearAxes) -> [&[f16; 6]; 2] {
        let row = bin_index(ih, axes.theta_d[0], 0);
        [&self.entries[row + axes.phi_d[0]], &self.entries[row + axes.phi_d[1]]]
    }

    /// f_ref (RGB, 1/sr) interpolated at `axes` as
    /// [`crate::formats::merl::weigh_measured_corners`] does: unmeasured corners left out and
    /// the others' weights renormalised, 0 where no corner is measured.
    #[inline]
    pub fn lookup(&self, axes: &TrilinearAxes) -> [f32; 3] {
        // The eight corners' values in their order (θh, θd, then φd), from two pairs.
        let mut corners = [[0f32; 3]; 8];
        let mut k = 0;
        for ih in axes.theta_h {
            let pair = self.pair(ih, axes);
            for half in [0, 3] {
                for entry in pair {
                    corners[k] = [entry[half], entry[half + 1], entry[half + 2]].map(f16::to_f32);
                    k += 1;
                }
            }
        }
        weigh_measured(corners.into_iter().zip(axes.weights())).unwrap_or([0.0; 3])
    }

    /// Starts fetching the entries [`Self::lookup`] reads at `axes` into the cache (the
    /// first byte of each pair's first entry and the last byte of its second: the lines of
    /// both, also where the pair straddles a line or φd wraps around). No effect on values.
    #[inline]
    pub fn prefetch(&self, axes: &TrilinearAxes) {
        for ih in axes.theta_h {
            let [first, second] = self.pair(ih, axes);
            crate::support::prefetch(&first[0]);
            crate::support::prefetch(&second[5]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::merl::lookup_trilinear_measured;

    /// Every bin distinct and some unmeasured (a channel negative), as f16.
    fn table() -> Vec<[f16; 3]> {
        let mut s = crate::sampler::Sampler::new(7, 8, 9);
        (0..BIN_COUNT)
            .map(|i| {
                let v = [s.next_1d(), s.next_1d(), s.next_1d()].map(|u| u * 40.0);
                let v = if i % 97 == 3 { [v[0], -1.0, v[2]] } else { v };
                v.map(f16::from_f32)
            })
            .collect()
    }

    /// The look-up equals the f32 table's (the training look-up) bit for bit over the whole
    /// domain, its ends and unmeasured corners included; every bin's value is the file's.
    #[test]
    fn looks_up_what_the_f32_table_gives() {
        let values = table();
        let reference = ReferenceTable::new(&values);
        let wide: Vec<[f32; 3]> = values.iter().map(|v| v.map(f16::to_f32)).collect();
        assert_eq!(reference.values(), wide);
        let mut s = crate::sampler::Sampler::new(1, 2, 3);
        for k in 0..200_000 {
            let [a, b, c] = [s.next_1d(), s.next_1d(), s.next_1d()];
            // Interior points, the θ axes' ends and beyond, and φd across its wrap.
            let theta_h = if k % 5 == 0 { [0.0, std::f32::consts::FRAC_PI_2, 1.7][k % 3] } else { a * std::f32::consts::FRAC_PI_2 };
            let theta_d = if k % 7 == 0 { [0.0, std::f32::consts::FRAC_PI_2, -0.1][k % 3] } else { b * std::f32::consts::FRAC_PI_2 };
            let phi_d = (c - 0.5) * 4.0 * std::f32::consts::PI;
            let expected = lookup_trilinear_measured(&wide, theta_h, theta_d, phi_d).unwrap_or([0.0; 3]);
            let got = reference.lookup(&TrilinearAxes::new(theta_h, theta_d, phi_d));
            assert_eq!(got, expected, "at ({theta_h}, {theta_d}, {phi_d})");
        }
        // Where no corner is measured the look-up is 0, as the f32 one gives none.
        let unmeasured = vec![[f16::from_f32(-1.0); 3]; BIN_COUNT];
        let axes = TrilinearAxes::new(0.3, 0.4, 0.5);
        assert_eq!(ReferenceTable::new(&unmeasured).lookup(&axes), [0.0; 3]);
        assert_eq!(reference.len(), BIN_COUNT);
    }
}
