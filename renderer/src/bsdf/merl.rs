//! Tabulated measured BRDF in the MERL layout ([`crate::formats::merl`]).
//!
//! The table is converted once to f32 f_r values (scale applied, unmeasured entries set to 0)
//! and looked up at the isotropic angles (θh, θd, φd folded into [0, π)) of (wi, wo), so the
//! BRDF is reciprocal by construction. Look-up is trilinear between bin centres by default
//! (θh in the table's sqrt-warped coordinate, φd periodic), or nearest-bin as in MERL's
//! reference code. Importance sampling uses a [`TabulatedSampler`] fitted from the table.
//!
//! ```no_run
//! use renderer::bsdf::merl::MerlBsdf;
//! let bsdf = MerlBsdf::load("data/merl-fitted/alum-bronze.binary")?;
//! # Ok::<(), renderer::Error>(())
//! ```

use super::tabulated_sampling::{TabulatedBrdf, TabulatedSampler, TabulatedSamplerConfig};
use super::BatchEval;

use crate::formats::merl::{self, MerlTable};
use crate::{Result, Rgb};
use glam::Vec3;
use std::path::Path;

/// How a [`MerlBsdf`] reads between bin centres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Interpolation {
    /// The value of the bin the angles fall in (MERL's reference look-up).
    Nearest,
    /// Trilinear between the 8 surrounding bin centres.
    #[default]
    Trilinear,
}

/// A MERL-layout table as a BSDF.
#[derive(Clone)]
pub struct MerlBsdf {
    /// f_r in 1/sr per bin (within-channel index order), finite, ≥ 0.
    values: Vec<[f32; 3]>,
    interpolation: Interpolation,
    sampler: TabulatedSampler,
}

impl std::fmt::Debug for MerlBsdf {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MerlBsdf")
            .field("bins", &self.values.len())
            .field("interpolation", &self.interpolation)
            .finish_non_exhaustive()
    }
}

impl MerlBsdf {
    /// Bytes it holds: the values and the sampler's tables.
    pub fn heap_bytes(&self) -> usize {
        self.values.len() * std::mem::size_of::<[f32; 3]>() + self.sampler.heap_bytes()
    }

    /// Reads a `.binary` file (validated, see [`MerlTable::read`]) with the default look-up
    /// and sampler.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        Ok(Self::new(
            &MerlTable::read(path)?,
            Interpolation::default(),
            &TabulatedSamplerConfig::default(),
        ))
    }

    /// Builds the BSDF from a table; fits the sampler (≈ 0.1 M look-ups, parallel; ≈ 20 ms).
    pub fn new(
        table: &MerlTable,
        interpolation: Interpolation,
        sampling: &TabulatedSamplerConfig,
    ) -> Self {
        let values = table.to_render_values();
        let sampler = TabulatedSampler::new(
            |wo, wi| eval_values(&values, interpolation, wo, wi),
            sampling,
        );
        MerlBsdf {
            values,
            interpolation,
            sampler,
        }
    }

    /// f_r (1/sr) at the isotropic angles (radians, φd folded into [0, π) here).
    #[inline]
    pub fn lookup(&self, theta_h: f32, theta_d: f32, phi_d: f32) -> Rgb {
        lookup_values(&self.values, self.interpolation, theta_h, theta_d, phi_d)
    }

    /// The look-up in use.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// f_r in 1/sr per bin (within-channel index order, [`merl::bin_index`]; unmeasured bins
    /// are 0), what the look-ups interpolate.
    pub fn values(&self) -> &[[f32; 3]] {
        &self.values
    }
}

/// Look-up in render values (f_r per bin, within-channel index order).
#[inline]
fn lookup_values(
    values: &[[f32; 3]],
    interpolation: Interpolation,
    theta_h: f32,
    theta_d: f32,
    phi_d: f32,
) -> Rgb {
    weigh(values, interpolation, &corners(interpolation, theta_h, theta_d, phi_d))
}

/// The bins a look-up at the isotropic angles reads and their weights: the nearest bin
/// (first entry, weight 1) or the eight trilinear corners.
#[inline]
fn corners(interpolation: Interpolation, theta_h: f32, theta_d: f32, phi_d: f32) -> TablePoint {
    match interpolation {
        Interpolation::Nearest => {
            let bin = merl::bin_index(merl::theta_h_index(theta_h), merl::theta_d_index(theta_d), merl::phi_d_index(phi_d));
            let mut weights = [0.0; 8];
            weights[0] = 1.0;
            TablePoint {
                corners: [bin; 8],
                weights,
            }
        }
        Interpolation::Trilinear => {
            let (corners, weights) = merl::trilinear_corners(theta_h, theta_d, phi_d);
            TablePoint { corners, weights }
        }
    }
}

/// The value a look-up reads at `point`'s bins.
#[inline]
fn weigh(values: &[[f32; 3]], interpolation: Interpolation, point: &TablePoint) -> Rgb {
    match interpolation {
        Interpolation::Nearest => Rgb::from_array(values[point.corners[0]]),
        Interpolation::Trilinear => {
            let mut acc = Rgb::ZERO;
            for (&i, &wk) in point.corners.iter().zip(&point.weights) {
                acc += wk * Rgb::from_array(values[i]);
            }
            acc
        }
    }
}

/// A look-up prepared without reading the table ([`BatchEval`]): the bins it reads (already
/// being fetched into the cache) and their weights.
#[derive(Clone, Copy, Debug)]
pub struct TablePoint {
    corners: [usize; 8],
    weights: [f32; 8],
}

impl BatchEval for MerlBsdf {
    type Prepared = TablePoint;

    #[inline]
    fn prepare(&self, wo: Vec3, wi: Vec3) -> Option<TablePoint> {
        let point = table_point(self.interpolation, wo, wi)?;
        merl::prefetch_corners(&self.values, &point.corners);
        Some(point)
    }

    fn eval_prepared(&self, points: &[TablePoint], values: &mut [Rgb]) {
        assert_eq!(points.len(), values.len(), "one value per point");
        for (point, value) in points.iter().zip(values) {
            *value = weigh(&self.values, self.interpolation, point);
        }
    }
}

/// f_r(wo, wi) from render values; zero below either horizon.
#[inline]
fn eval_values(values: &[[f32; 3]], interpolation: Interpolation, wo: Vec3, wi: Vec3) -> Rgb {
    table_point(interpolation, wo, wi).map_or(Rgb::ZERO, |point| weigh(values, interpolation, &point))
}

/// The bins f_r(wo, wi) reads and their weights; `None` below either horizon (f_r is 0).
#[inline]
fn table_point(interpolation: Interpolation, wo: Vec3, wi: Vec3) -> Option<TablePoint> {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return None;
    }
    let [th, td, pd] = crate::brdf_coords::isotropic_angles(wi, wo);
    Some(corners(interpolation, th, td, pd))
}

impl TabulatedBrdf for MerlBsdf {
    #[inline]
    fn value(&self, wo: Vec3, wi: Vec3) -> Rgb {
        eval_values(&self.values, self.interpolation, wo, wi)
    }

    fn sampler(&self) -> &TabulatedSampler {
        &self.sampler
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::bsdf::Bxdf;
    use crate::testing::bsdfs::{
        check_chi2, check_stability, merl_fitted_table, CHI2_THETAS,
    };

    #[test]
    fn eval_matches_table_at_bin_centres() {
        let table = merl_fitted_table("alum-bronze");
        for interpolation in [Interpolation::Nearest, Interpolation::Trilinear] {
            let bsdf = MerlBsdf::new(&table, interpolation, &TabulatedSamplerConfig::default());
            for i in [
                merl::bin_index(3, 20, 40),
                merl::bin_index(50, 60, 100),
                merl::bin_index(80, 10, 170),
            ] {
                let [th, td, pd] = merl::bin_centre(i);
                let a = crate::brdf_coords::HalfDiffAngles {
                    theta_h: th as f32,
                    phi_h: 0.4,
                    theta_d: td as f32,
                    phi_d: pd as f32,
                };
                let (wi, wo) = crate::brdf_coords::directions_from_angles(&a);
                if wi.z <= 0.0 || wo.z <= 0.0 {
                    continue;
                }
                let want = table.value(i);
                let got = bsdf.eval(wo, wi);
                for c in 0..3 {
                    let rel = (got[c] as f64 - want[c]).abs() / want[c].max(1e-6);
                    assert!(rel < 2e-3, "{interpolation:?} bin {i}: {got:?} vs {want:?}");
                }
                let back = bsdf.eval(wi, wo);
                assert!(
                    (back - got).abs().max_element() <= 1e-3 * got.max_element(),
                    "reciprocity"
                );
            }
        }
    }

    #[test]
    fn unmeasured_entries_render_as_zero() {
        // Negative (unmeasured) entries at grazing θd, as in real MERL files.
        let table = MerlTable::from_fn(|_, td, _| {
            if td > 1.3 {
                Rgb::splat(-1.0)
            } else {
                Rgb::splat(0.2)
            }
        });
        let bsdf = MerlBsdf::new(
            &table,
            Interpolation::Trilinear,
            &TabulatedSamplerConfig::default(),
        );
        check_stability(&bsdf);
        let wo = Vec3::new(0.99, 0.0, 0.1).normalize();
        let wi = Vec3::new(-0.99, 0.05, 0.1).normalize();
        assert_eq!(bsdf.eval(wo, wi), Rgb::ZERO);
        assert!(
            (bsdf.eval(Vec3::Z, Vec3::Z) - Rgb::splat(0.2))
                .abs()
                .max_element()
                < 1e-6
        );
    }

    #[test]
    fn stability_on_difficult_materials() {
        for name in ["chrome", "black-obsidian", "black-phenolic"] {
            let bsdf = MerlBsdf::new(
                &merl_fitted_table(name),
                Interpolation::Trilinear,
                &TabulatedSamplerConfig::default(),
            );
            check_stability(&bsdf);
        }
    }

    #[test]
    fn sampling_passes_chi2() {
        for name in crate::testing::bsdfs::CHI2_MATERIALS {
            let bsdf = MerlBsdf::new(
                &merl_fitted_table(name),
                Interpolation::Trilinear,
                &TabulatedSamplerConfig::default(),
            );
            for theta_o in CHI2_THETAS {
                check_chi2(&bsdf, name, theta_o);
            }
        }
    }
}
