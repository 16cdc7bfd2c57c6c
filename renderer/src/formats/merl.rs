//! MERL BRDF tables (Matusik et al. 2003): the `.binary` file format, its index functions and
//! look-ups.
//!
//! Layout: a header of three little-endian `i32` (90, 90, 180), then 90·90·180·3 little-endian
//! `f64`, channel-major (all red, then all green, then all blue); within a channel
//! `index = phi_d_idx + 180 · (theta_d_idx + 90 · theta_h_idx)`. Stored ("raw") values times
//! the per-channel [`SCALE`] give f_r in 1/sr. Negative entries mark bins that were not
//! measured.
//!
//! Index functions (angles in radians, see [`crate::brdf_coords`] for the coordinates):
//! `theta_h_idx = floor(sqrt(θh / (π/2)) · 90)`, `theta_d_idx = floor(θd / (π/2) · 90)`,
//! `phi_d_idx = floor(φd / π · 180)` after folding φd into [0, π); all clamped to the table.
//! Bin centres are the midpoints in these index coordinates, e.g.
//! θh = ((i + 0.5) / 90)² · π/2, so every centre indexes its own bin.

use crate::lanes::Real;
use crate::{Error, Result, Rgb};
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2 as FRAC_PI_2_F64, PI as PI_F64};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// Number of θh bins.
pub const THETA_H_BINS: usize = 90;
/// Number of θd bins.
pub const THETA_D_BINS: usize = 90;
/// Number of φd bins (over [0, π)).
pub const PHI_D_BINS: usize = 180;
/// Bins per channel.
pub const BIN_COUNT: usize = THETA_H_BINS * THETA_D_BINS * PHI_D_BINS;
/// Size of the header in bytes (three `i32`).
pub const HEADER_BYTES: u64 = 12;
/// Exact size of a valid `.binary` file in bytes (34,992,012).
pub const FILE_BYTES: u64 = HEADER_BYTES + 8 * 3 * BIN_COUNT as u64;
/// Raw value × scale = f_r (1/sr), per channel (red, green, blue), as in MERL's reference code.
pub const SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];

/// Largest f_r (1/sr) [`MerlTable::to_render_values`] keeps; measured peaks stay below 1e4.
pub const MAX_RENDER_VALUE: f32 = 1e30;

const CHANNEL_NAMES: [&str; 3] = ["red", "green", "blue"];

/// θh bin of a half-vector polar angle (radians): `floor(sqrt(θh / (π/2)) · 90)`, clamped.
/// Non-positive and NaN angles give bin 0.
#[inline]
pub fn theta_h_index(theta_h: f32) -> usize {
    if theta_h.is_nan() || theta_h <= 0.0 {
        return 0;
    }
    let u = (theta_h / std::f32::consts::FRAC_PI_2).sqrt() * THETA_H_BINS as f32;
    (u as usize).min(THETA_H_BINS - 1)
}

/// θd bin of a difference polar angle (radians): `floor(θd / (π/2) · 90)`, clamped.
#[inline]
pub fn theta_d_index(theta_d: f32) -> usize {
    let u = theta_d / std::f32::consts::FRAC_PI_2 * THETA_D_BINS as f32;
    (u.max(0.0) as usize).min(THETA_D_BINS - 1)
}

/// φd bin of a difference azimuth (radians, any range): folded into [0, π) by reciprocity,
/// then `floor(φd / π · 180)`, clamped.
#[inline]
pub fn phi_d_index(phi_d: f32) -> usize {
    let phi = crate::brdf_coords::fold_phi_d(phi_d);
    let u = phi / std::f32::consts::PI * PHI_D_BINS as f32;
    (u.max(0.0) as usize).min(PHI_D_BINS - 1)
}

/// Index of bin (θh, θd, φd) within one channel.
#[inline]
pub fn bin_index(theta_h_idx: usize, theta_d_idx: usize, phi_d_idx: usize) -> usize {
    debug_assert!(
        theta_h_idx < THETA_H_BINS && theta_d_idx < THETA_D_BINS && phi_d_idx < PHI_D_BINS
    );
    phi_d_idx + PHI_D_BINS * (theta_d_idx + THETA_D_BINS * theta_h_idx)
}

/// The (θh, θd, φd) bin indices of a within-channel index.
#[inline]
pub fn bin_indices(index: usize) -> (usize, usize, usize) {
    let phi_d = index % PHI_D_BINS;
    let theta_d = (index / PHI_D_BINS) % THETA_D_BINS;
    let theta_h = index / (PHI_D_BINS * THETA_D_BINS);
    (theta_h, theta_d, phi_d)
}

/// Bin-centre angles (θh, θd, φd) in radians of a within-channel index (f64 so they can be
/// rounded once by the caller).
pub fn bin_centre(index: usize) -> [f64; 3] {
    let (ih, id, ip) = bin_indices(index);
    let u = (ih as f64 + 0.5) / THETA_H_BINS as f64;
    [
        u * u * FRAC_PI_2_F64,
        (id as f64 + 0.5) / THETA_D_BINS as f64 * FRAC_PI_2_F64,
        (ip as f64 + 0.5) / PHI_D_BINS as f64 * PI_F64,
    ]
}

/// Continuous bin coordinates (bin centres at integers) of the isotropic angles; the look-ups
/// interpolate in these.
#[inline]
pub fn continuous_coordinates(theta_h: f32, theta_d: f32, phi_d: f32) -> [f32; 3] {
    folded_continuous_coordinates(theta_h, theta_d, crate::brdf_coords::fold_phi_d(phi_d))
}

/// [`continuous_coordinates`] of angles whose φd is already folded into [0, π), over
/// [`Real`] values (one point, or one per lane).
#[inline(always)]
pub fn folded_continuous_coordinates<R: Real>(theta_h: R, theta_d: R, phi_d: R) -> [R; 3] {
    use std::f32::consts::{FRAC_PI_2, PI};
    let uh = (theta_h.max(R::splat(0.0)) / FRAC_PI_2).sqrt() * THETA_H_BINS as f32 - 0.5;
    let ud = theta_d / FRAC_PI_2 * THETA_D_BINS as f32 - 0.5;
    let up = phi_d / PI * PHI_D_BINS as f32 - 0.5;
    [uh, ud, up]
}

/// Where a continuous coordinate falls between the table's bins, per axis: the two
/// neighbouring bins and the weight of the second. θh and θd are clamped at the table's ends
/// (both neighbours the end bin there), φd wraps with period π.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrilinearAxes {
    /// θh bins and the weight of `theta_h[1]`.
    pub theta_h: [usize; 2],
    pub fh: f32,
    /// θd bins and the weight of `theta_d[1]`.
    pub theta_d: [usize; 2],
    pub fd: f32,
    /// φd bins and the weight of `phi_d[1]`.
    pub phi_d: [usize; 2],
    pub fp: f32,
}

impl TrilinearAxes {
    /// The neighbouring bins of the isotropic angles (radians).
    #[inline]
    pub fn new(theta_h: f32, theta_d: f32, phi_d: f32) -> Self {
        Self::at(continuous_coordinates(theta_h, theta_d, phi_d))
    }

    /// The neighbouring bins of continuous coordinates ([`continuous_coordinates`]).
    #[inline]
    pub fn at([uh, ud, up]: [f32; 3]) -> Self {
        let clamp_axis = |u: f32, n: usize| -> ([usize; 2], f32) {
            let u = if u.is_nan() {
                0.0
            } else {
                u.clamp(0.0, (n - 1) as f32)
            };
            let i0 = (u as usize).min(n - 1);
            let i1 = (i0 + 1).min(n - 1);
            ([i0, i1], u - i0 as f32)
        };
        let (theta_h, fh) = clamp_axis(uh, THETA_H_BINS);
        let (theta_d, fd) = clamp_axis(ud, THETA_D_BINS);
        let up = if up.is_nan() { 0.0 } else { up };
        let pf = up.floor();
        let fp = up - pf;
        let p0 = (pf as i64).rem_euclid(PHI_D_BINS as i64) as usize;
        let p1 = (p0 + 1) % PHI_D_BINS;
        TrilinearAxes { theta_h, fh, theta_d, fd, phi_d: [p0, p1], fp }
    }

    /// The 8 corners (within-channel indices) and their trilinear weights, θh outermost and
    /// φd innermost (the corner order of every look-up).
    #[inline]
    pub fn corners(&self) -> ([usize; 8], [f32; 8]) {
        let mut idx = [0usize; 8];
        let mut k = 0;
        for ih in self.theta_h {
            for id in self.theta_d {
                for ip in self.phi_d {
                    idx[k] = bin_index(ih, id, ip);
                    k += 1;
                }
            }
        }
        (idx, self.weights())
    }

    /// The trilinear weights of the 8 corners in [`Self::corners`]' order.
    #[inline]
    pub fn weights(&self) -> [f32; 8] {
        let mut w = [0f32; 8];
        let mut k = 0;
        for wh in [1.0 - self.fh, self.fh] {
            for wd in [1.0 - self.fd, self.fd] {
                for wp in [1.0 - self.fp, self.fp] {
                    w[k] = wh * wd * wp;
                    k += 1;
                }
            }
        }
        w
    }
}

/// The 8 corners (within-channel indices) and trilinear weights around a continuous
/// coordinate ([`TrilinearAxes`]).
#[inline]
pub fn trilinear_corners(theta_h: f32, theta_d: f32, phi_d: f32) -> ([usize; 8], [f32; 8]) {
    TrilinearAxes::new(theta_h, theta_d, phi_d).corners()
}

/// Trilinear look-up in per-bin f32 RGB values (within-channel index order, a negative
/// channel marks the bin unmeasured) at the isotropic angles (radians): unmeasured corners
/// are left out and the weights of the others renormalised; `None` when all eight corners
/// are unmeasured. The look-up of f_ref in training and rendering.
#[inline]
pub fn lookup_trilinear_measured(values: &[[f32; 3]], theta_h: f32, theta_d: f32, phi_d: f32) -> Option<[f32; 3]> {
    let (idx, w) = trilinear_corners(theta_h, theta_d, phi_d);
    weigh_measured_corners(values, &idx, &w)
}

/// [`lookup_trilinear_measured`] at the corners and weights [`trilinear_corners`] found.
#[inline]
pub fn weigh_measured_corners(values: &[[f32; 3]], idx: &[usize; 8], w: &[f32; 8]) -> Option<[f32; 3]> {
    weigh_measured(idx.iter().zip(w).map(|(&i, &wk)| (values[i], wk)))
}

/// The weighted mean of the corners' values (each with its weight, in
/// [`TrilinearAxes::corners`]' order) over the measured ones (no negative channel) of
/// positive weight; `None` when there are none.
#[inline]
pub fn weigh_measured(corners: impl IntoIterator<Item = ([f32; 3], f32)>) -> Option<[f32; 3]> {
    let mut acc = [0f32; 3];
    let mut wsum = 0f32;
    for (v, wk) in corners {
        if wk > 0.0 && v[0] >= 0.0 && v[1] >= 0.0 && v[2] >= 0.0 {
            for c in 0..3 {
                acc[c] += wk * v[c];
            }
            wsum += wk;
        }
    }
    (wsum > 0.0).then(|| acc.map(|a| a / wsum))
}

/// Starts fetching into the cache the entries of `values` at the corners `idx` (of
/// [`trilinear_corners`]), so that look-ups of many points issued after their prefetches
/// overlap their memory latencies. No effect on values; a no-op where the CPU has no prefetch
/// hint.
///
/// The corners come in pairs of neighbours along φd: 24 contiguous bytes (except where φd
/// wraps around), so at most two cache lines, which the first channel of the first entry and
/// the last channel of the second fetch — also where an entry straddles two lines.
#[inline]
pub fn prefetch_corners(values: &[[f32; 3]], idx: &[usize; 8]) {
    for pair in idx.chunks_exact(2) {
        if let (Some(first), Some(second)) = (values.get(pair[0]), values.get(pair[1])) {
            crate::support::prefetch(&first[0]);
            crate::support::prefetch(&second[2]);
        }
    }
}

/// A MERL table in memory: the raw values exactly as in the file (so write → read is exact).
#[derive(Clone)]
pub struct MerlTable {
    /// Raw values, channel-major, `3 * BIN_COUNT` entries; scaled by [`SCALE`] on access.
    raw: Vec<f64>,
}

impl std::fmt::Debug for MerlTable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MerlTable")
            .field("values", &self.raw.len())
            .finish()
    }
}

impl MerlTable {
    /// Reads and validates a `.binary` file: header dims 90 90 180, exact length
    /// [`FILE_BYTES`], finite values. Errors name the file and the problem.
    pub fn read(path: impl AsRef<Path>) -> Result<Self> {
        let mut reader = MerlReader::open(path)?;
        let mut raw = vec![0f64; 3 * BIN_COUNT];
        reader.read_raw(0, &mut raw)?;
        Ok(MerlTable { raw })
    }

    /// Parses and validates the contents of a `.binary` file (the checks of
    /// [`MerlTable::read`]); `path` names the source in errors. The length is checked before
    /// anything is allocated, so a short or oversized input costs nothing.
    pub fn from_bytes(bytes: &[u8], path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let header: &[u8; HEADER_BYTES as usize] = bytes
            .first_chunk()
            .ok_or_else(|| truncated_header_error(path, bytes.len() as u64))?;
        check_layout(header, bytes.len() as u64, path)?;
        let mut raw = vec![0f64; 3 * BIN_COUNT];
        decode_raw(&bytes[HEADER_BYTES as usize..], 0, &mut raw, path)?;
        Ok(MerlTable { raw })
    }

    /// Builds a table from raw values (channel-major, `3 * BIN_COUNT` finite entries; negative
    /// = unmeasured). `what` names the source in error messages.
    pub fn from_raw(raw: Vec<f64>, what: impl Into<PathBuf>) -> Result<Self> {
        let what = what.into();
        if raw.len() != 3 * BIN_COUNT {
            return Err(Error::invalid_file(
                what,
                format!(
                    "{} raw values, a MERL table has {}",
                    raw.len(),
                    3 * BIN_COUNT
                ),
            ));
        }
        if let Some(i) = raw.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid_file(what, non_finite_message(i, raw[i])));
        }
        Ok(MerlTable { raw })
    }

    /// Tabulates a BRDF at the bin centres, in parallel (rayon). `brdf(θh, θd, φd)` returns
    /// f_r in 1/sr (radians, φd ∈ (0, π)); negative values mark a bin unmeasured and
    /// non-finite values are stored as unmeasured (−1).
    pub fn from_fn(brdf: impl Fn(f32, f32, f32) -> Rgb + Sync) -> Self {
        let values: Vec<Rgb> = (0..BIN_COUNT)
            .into_par_iter()
            .with_min_len(1024)
            .map(|i| {
                let [th, td, pd] = bin_centre(i);
                brdf(th as f32, td as f32, pd as f32)
            })
            .collect();
        let mut raw = vec![0f64; 3 * BIN_COUNT];
        raw.par_chunks_mut(BIN_COUNT)
            .enumerate()
            .for_each(|(c, channel)| {
                for (r, v) in channel.iter_mut().zip(&values) {
                    let f = v[c] as f64;
                    *r = if f.is_finite() { f / SCALE[c] } else { -1.0 };
                }
            });
        MerlTable { raw }
    }

    /// The raw values (channel-major, unscaled).
    pub fn raw(&self) -> &[f64] {
        &self.raw
    }

    /// f_r (1/sr) of one bin (within-channel index), scaled; negative channels are unmeasured.
    #[inline]
    pub fn value(&self, index: usize) -> [f64; 3] {
        [0, 1, 2].map(|c| self.raw[c * BIN_COUNT + index] * SCALE[c])
    }

    /// Whether every channel of a bin was measured (non-negative).
    #[inline]
    pub fn is_measured(&self, index: usize) -> bool {
        (0..3).all(|c| self.raw[c * BIN_COUNT + index] >= 0.0)
    }

    /// Nearest-bin look-up (MERL's reference look-up) at the isotropic angles (radians):
    /// f_r in 1/sr, negative where unmeasured.
    pub fn lookup_nearest(&self, theta_h: f32, theta_d: f32, phi_d: f32) -> [f64; 3] {
        self.value(bin_index(
            theta_h_index(theta_h),
            theta_d_index(theta_d),
            phi_d_index(phi_d),
        ))
    }

    /// The linear blend (1 − t) self + t other, bin by bin; a bin unmeasured in either is
    /// unmeasured in the blend. `t` in [0, 1]. (The table a material-editing sweep compares
    /// its interpolated latent codes with.)
    pub fn blend(&self, other: &MerlTable, t: f64) -> MerlTable {
        let raw: Vec<f64> = self
            .raw()
            .par_iter()
            .zip(other.raw())
            .map(|(&x, &y)| if x < 0.0 || y < 0.0 { -1.0 } else { (1.0 - t) * x + t * y })
            .collect();
        MerlTable::from_raw(raw, "blended table").expect("a blend of valid tables is valid")
    }

    /// The table as f_r in 1/sr per bin (within-channel index order), f32, with unmeasured
    /// channels −1 (and values beyond f32 capped at `f32::MAX`): the form the trainer and
    /// [`lookup_trilinear_measured`] read.
    pub fn measured_values(&self) -> Vec<[f32; 3]> {
        (0..BIN_COUNT)
            .into_par_iter()
            .with_min_len(4096)
            .map(|i| {
                [0, 1, 2].map(|c| measured_value(self.raw[c * BIN_COUNT + i], c))
            })
            .collect()
    }

    /// The table as f_r in 1/sr per bin (within-channel index order), f32, unmeasured (negative)
    /// entries set to 0 and values clamped to [`MAX_RENDER_VALUE`]: the form the renderer
    /// evaluates (finite, ≥ 0, and finite after interpolation and Monte Carlo weighting).
    pub fn to_render_values(&self) -> Vec<[f32; 3]> {
        (0..BIN_COUNT)
            .into_par_iter()
            .with_min_len(4096)
            .map(|i| {
                self.value(i).map(|v| {
                    if v > 0.0 {
                        v.min(MAX_RENDER_VALUE as f64) as f32
                    } else {
                        0.0
                    }
                })
            })
            .collect()
    }

    /// Number of bins with at least one unmeasured channel.
    pub fn unmeasured_count(&self) -> usize {
        (0..BIN_COUNT).filter(|&i| !self.is_measured(i)).count()
    }

    /// Writes the table in the `.binary` format to a writer.
    pub fn write_to(&self, w: &mut impl Write) -> std::io::Result<()> {
        for dim in [THETA_H_BINS, THETA_D_BINS, PHI_D_BINS] {
            w.write_all(&(dim as i32).to_le_bytes())?;
        }
        let mut buf = Vec::with_capacity(8 * 8192);
        for chunk in self.raw.chunks(8192) {
            buf.clear();
            for v in chunk {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            w.write_all(&buf)?;
        }
        Ok(())
    }

    /// Writes the table to a `.binary` file atomically ([`crate::support::write_atomically`]:
    /// an interrupted write never leaves a partial table under `path`).
    pub fn write(&self, path: impl AsRef<Path>) -> Result<()> {
        crate::support::write_atomically(path.as_ref(), |w| self.write_to(w))
    }
}

fn non_finite_message(raw_index: usize, value: f64) -> String {
    let channel = raw_index / BIN_COUNT;
    let (ih, id, ip) = bin_indices(raw_index % BIN_COUNT);
    format!(
        "non-finite value {value} in the {} channel at bin (theta_h {ih}, theta_d {id}, phi_d {ip})",
        CHANNEL_NAMES[channel.min(2)]
    )
}

fn truncated_header_error(path: &Path, len: u64) -> Error {
    Error::invalid_file(
        path,
        format!("truncated MERL file: {len} bytes, shorter than its {HEADER_BYTES}-byte header"),
    )
}

/// Checks a `.binary` file's header dims (90 90 180) and its total length `len`.
fn check_layout(header: &[u8; HEADER_BYTES as usize], len: u64, path: &Path) -> Result<()> {
    let dims: Vec<i32> = header
        .chunks_exact(4)
        .map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    if dims != [THETA_H_BINS as i32, THETA_D_BINS as i32, PHI_D_BINS as i32] {
        return Err(Error::invalid_file(
            path,
            format!(
                "MERL header dims {} {} {}, expected {THETA_H_BINS} {THETA_D_BINS} {PHI_D_BINS}",
                dims[0], dims[1], dims[2]
            ),
        ));
    }
    if len != FILE_BYTES {
        let what = if len < FILE_BYTES {
            "truncated"
        } else {
            "oversized"
        };
        return Err(Error::invalid_file(
            path,
            format!(
                "{what} MERL file: {len} bytes, expected {FILE_BYTES} (12-byte header + 90x90x180x3 float64)"
            ),
        ));
    }
    Ok(())
}

/// Decodes little-endian `f64`s from `src` into `out` (`src` holds at least `8 · out.len()`
/// bytes), checking that they are finite; `first` is the raw index of `out[0]`, for messages.
fn decode_raw(src: &[u8], first: usize, out: &mut [f64], path: &Path) -> Result<()> {
    debug_assert!(src.len() >= 8 * out.len());
    for (k, (v, b)) in out.iter_mut().zip(src.chunks_exact(8)).enumerate() {
        let x = f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]);
        if !x.is_finite() {
            return Err(Error::invalid_file(path, non_finite_message(first + k, x)));
        }
        *v = x;
    }
    Ok(())
}

/// The f_r (1/sr, f32) of a raw file value of `channel`: raw × [`SCALE`], clamped to the f32
/// range; −1 for an unmeasured (negative) entry.
#[inline]
pub fn measured_value(raw: f64, channel: usize) -> f32 {
    if raw < 0.0 {
        -1.0
    } else {
        (raw * SCALE[channel]).min(f32::MAX as f64) as f32
    }
}

/// A validated `.binary` file open for reading ranges of raw values, so that many tables can
/// be streamed through together (e.g. for a per-bin median) without holding them in memory.
#[derive(Debug)]
pub struct MerlReader {
    path: PathBuf,
    file: File,
}

impl MerlReader {
    /// Opens a file and checks its header dims (90 90 180) and its exact length.
    pub fn open(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        let mut file = File::open(&path).map_err(|e| Error::io(&path, e))?;
        let len = file.metadata().map_err(|e| Error::io(&path, e))?.len();
        if len < HEADER_BYTES {
            return Err(truncated_header_error(&path, len));
        }
        let mut header = [0u8; HEADER_BYTES as usize];
        file.read_exact(&mut header)
            .map_err(|e| Error::io(&path, e))?;
        check_layout(&header, len, &path)?;
        Ok(MerlReader { path, file })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Reads raw values `[first, first + out.len())` (channel-major order, unscaled) and checks
    /// that they are finite.
    pub fn read_raw(&mut self, first: usize, out: &mut [f64]) -> Result<()> {
        if first
            .checked_add(out.len())
            .is_none_or(|end| end > 3 * BIN_COUNT)
        {
            return Err(Error::InvalidArgument {
                flag: format!("MERL range of {}", self.path.display()),
                reason: format!(
                    "values {first}..{} exceed {}",
                    first.saturating_add(out.len()),
                    3 * BIN_COUNT
                ),
            });
        }
        let io = |e| Error::io(&self.path, e);
        self.file
            .seek(SeekFrom::Start(HEADER_BYTES + 8 * first as u64))
            .map_err(io)?;
        let mut bytes = vec![0u8; 8 * out.len().min(1 << 16)];
        for (chunk_index, chunk) in out.chunks_mut(1 << 16).enumerate() {
            let b = &mut bytes[..8 * chunk.len()];
            self.file
                .read_exact(b)
                .map_err(|e| Error::io(&self.path, e))?;
            decode_raw(b, first + (chunk_index << 16), chunk, &self.path)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::{FRAC_PI_2, PI};

    #[test]
    fn file_size_constant() {
        assert_eq!(FILE_BYTES, 34_992_012);
        assert_eq!(BIN_COUNT, 1_458_000);
    }

    #[test]
    fn index_functions_match_hand_computed_values() {
        // θh: floor(sqrt(θh/(π/2))·90): π/4 -> sqrt(0.5)·90 = 63.64; 0.1 -> 22.71;
        // 1e-4 -> 0.718; π/2 and beyond clamp to 89.
        assert_eq!(theta_h_index(0.0), 0);
        assert_eq!(theta_h_index(-0.3), 0);
        assert_eq!(theta_h_index(f32::NAN), 0);
        assert_eq!(theta_h_index(1e-4), 0);
        assert_eq!(theta_h_index(0.1), 22);
        assert_eq!(theta_h_index(PI / 4.0), 63);
        assert_eq!(theta_h_index(FRAC_PI_2), 89);
        assert_eq!(theta_h_index(2.0), 89);
        // θd: floor(θd/(π/2)·90): 0.3 -> 17.19; 1.0 -> 57.30; π/2 clamps.
        assert_eq!(theta_d_index(0.0), 0);
        assert_eq!(theta_d_index(0.3), 17);
        assert_eq!(theta_d_index(1.0), 57);
        assert_eq!(theta_d_index(FRAC_PI_2), 89);
        assert_eq!(theta_d_index(-0.1), 0);
        // φd: folded into [0, π) then floor(φd/π·180): 1.0 -> 57.30; -0.5 -> (π-0.5) -> 151.35;
        // 4.0 -> (4-π) -> 49.18; π folds to 0.
        assert_eq!(phi_d_index(0.0), 0);
        assert_eq!(phi_d_index(1.0), 57);
        assert_eq!(phi_d_index(-0.5), 151);
        assert_eq!(phi_d_index(4.0), 49);
        assert_eq!(phi_d_index(PI), 0);
        assert_eq!(phi_d_index(PI - 1e-4), 179);
        // index = φd + 180·(θd + 90·θh).
        assert_eq!(bin_index(0, 0, 0), 0);
        assert_eq!(bin_index(0, 0, 179), 179);
        assert_eq!(bin_index(0, 1, 0), 180);
        assert_eq!(bin_index(1, 0, 0), 16_200);
        assert_eq!(bin_index(89, 89, 179), BIN_COUNT - 1);
        assert_eq!(bin_index(22, 17, 57), 57 + 180 * (17 + 90 * 22));
        assert_eq!(bin_indices(57 + 180 * (17 + 90 * 22)), (22, 17, 57));
    }

    #[test]
    fn bin_centres_index_their_own_bin() {
        for i in (0..BIN_COUNT).step_by(997).chain([0, BIN_COUNT - 1]) {
            let [th, td, pd] = bin_centre(i);
            let j = bin_index(
                theta_h_index(th as f32),
                theta_d_index(td as f32),
                phi_d_index(pd as f32),
            );
            assert_eq!(i, j);
            let c = continuous_coordinates(th as f32, td as f32, pd as f32);
            let (ih, id, ip) = bin_indices(i);
            assert!((c[0] - ih as f32).abs() < 1e-3);
            assert!((c[1] - id as f32).abs() < 1e-3);
            assert!((c[2] - ip as f32).abs() < 1e-3);
        }
    }

    fn synthetic(th: f32, td: f32, pd: f32) -> Rgb {
        Rgb::new(1.0 + th, 2.0 + td, 3.0 + pd.cos())
    }

    #[test]
    fn write_read_round_trip_is_exact() {
        let table = MerlTable::from_fn(synthetic);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.binary");
        table.write(&path).unwrap();
        assert_eq!(std::fs::metadata(&path).unwrap().len(), FILE_BYTES);
        let back = MerlTable::read(&path).unwrap();
        assert!(back.raw() == table.raw());
        for i in [0, 12_345, BIN_COUNT - 1] {
            let [th, td, pd] = bin_centre(i);
            let want = synthetic(th as f32, td as f32, pd as f32);
            let got = back.lookup_nearest(th as f32, td as f32, pd as f32);
            for c in 0..3 {
                assert_eq!(got[c] as f32, want[c], "bin {i} channel {c}");
            }
        }
    }

    #[test]
    fn table_from_network_round_trips_to_f32_precision() {
        // A full table written from an NBRDF network and read back returns the network's
        // f32 values at every bin centre.
        let net = crate::testing::data::merl_network("alum-bronze");
        let eval = |i: usize| {
            let [th, td, pd] = bin_centre(i);
            net.eval_angles(th as f32, td as f32, pd as f32)
        };
        let table = MerlTable::from_fn(|th, td, pd| net.eval_angles(th, td, pd));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("alum-bronze.binary");
        table.write(&path).unwrap();
        let back = MerlTable::read(&path).unwrap();
        let worst = (0..BIN_COUNT)
            .into_par_iter()
            .map(|i| {
                let want = eval(i);
                let got = back.value(i);
                (0..3)
                    .map(|c| (got[c] as f32 - want[c]).abs() / want[c].abs().max(f32::MIN_POSITIVE))
                    .fold(0.0f32, f32::max)
            })
            .reduce(|| 0.0, f32::max);
        assert!(worst <= f32::EPSILON, "worst relative difference {worst:e}");
    }

    #[test]
    fn trilinear_reproduces_bin_centres_and_interpolates() {
        let table = MerlTable::from_fn(|th, td, _| Rgb::new(th, td, 1.0));
        let [th, td, pd] = bin_centre(bin_index(40, 30, 20));
        let values = table.measured_values();
        let v = lookup_trilinear_measured(&values, th as f32, td as f32, pd as f32).unwrap();
        assert!((v[0] as f64 - th).abs() < 1e-6 && (v[1] as f64 - td).abs() < 1e-6);
        // Halfway between two θd centres the value is their mean (linear in θd).
        let td_mid = (30.0 + 1.0) / 90.0 * std::f64::consts::FRAC_PI_2;
        let v = lookup_trilinear_measured(&values, th as f32, td_mid as f32, pd as f32).unwrap();
        assert!((v[1] as f64 - td_mid).abs() < 1e-6);
        // φd wraps: just below π interpolates between bins 179 and 0.
        assert!(lookup_trilinear_measured(&values, 0.3, 0.3, PI - 1e-3).is_some());
    }

    #[test]
    fn unmeasured_entries_are_negative_and_skipped() {
        let table = MerlTable::from_fn(|th, _, _| {
            if th > 0.5 {
                Rgb::splat(-1.0)
            } else {
                Rgb::splat(0.25)
            }
        });
        assert!(table.unmeasured_count() > 0);
        assert!(table.lookup_nearest(1.0, 0.2, 0.2)[0] < 0.0);
        let values = table.measured_values();
        let v = lookup_trilinear_measured(&values, 0.3, 0.2, 0.2).unwrap();
        assert!((v[0] - 0.25).abs() < 1e-6);
        assert!(lookup_trilinear_measured(&values, 1.2, 0.2, 0.2).is_none());
        let render = table.to_render_values();
        assert!(render
            .iter()
            .all(|v| v.iter().all(|&x| x >= 0.0 && x.is_finite())));
        let i = bin_index(theta_h_index(1.0), 10, 10);
        assert_eq!(render[i], [0.0; 3]);
        let huge = MerlTable::from_raw(vec![1e300; 3 * BIN_COUNT], "huge").unwrap();
        assert!(huge
            .to_render_values()
            .iter()
            .all(|v| v == &[MAX_RENDER_VALUE; 3]));
        // Non-finite values of the closure are stored as unmeasured.
        let nan = MerlTable::from_fn(|_, _, _| Rgb::splat(f32::NAN));
        assert_eq!(nan.unmeasured_count(), BIN_COUNT);
    }

    fn valid_bytes() -> Vec<u8> {
        let mut bytes = Vec::new();
        MerlTable::from_fn(|_, _, _| Rgb::ONE)
            .write_to(&mut bytes)
            .unwrap();
        bytes
    }

    fn read_err(dir: &Path, name: &str, bytes: &[u8]) -> String {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let e = MerlTable::read(&path).unwrap_err().to_string();
        assert!(e.contains(name), "error does not name the file: {e}");
        e
    }

    #[test]
    fn bad_files_give_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let good = valid_bytes();
        assert_eq!(good.len() as u64, FILE_BYTES);

        let e = read_err(dir.path(), "short.binary", &good[..7]);
        assert!(e.contains("truncated") && e.contains("7 bytes"), "{e}");

        let e = read_err(dir.path(), "truncated.binary", &good[..good.len() - 8]);
        assert!(e.contains("truncated") && e.contains("34992004"), "{e}");

        let mut long = good.clone();
        long.extend_from_slice(&[0u8; 8]);
        let e = read_err(dir.path(), "long.binary", &long);
        assert!(e.contains("oversized"), "{e}");

        let mut dims = good.clone();
        dims[8..12].copy_from_slice(&90i32.to_le_bytes());
        let e = read_err(dir.path(), "dims.binary", &dims);
        assert!(e.contains("header dims 90 90 90"), "{e}");

        let mut nan = good.clone();
        let at = HEADER_BYTES as usize + 8 * (BIN_COUNT + 181);
        nan[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        let e = read_err(dir.path(), "nan.binary", &nan);
        assert!(
            e.contains("NaN") && e.contains("green") && e.contains("theta_d 1, phi_d 1"),
            "{e}"
        );

        let e = MerlTable::read(dir.path().join("missing.binary"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing.binary"), "{e}");
    }

    #[test]
    fn reader_streams_ranges() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.binary");
        let table = MerlTable::from_fn(synthetic);
        table.write(&path).unwrap();
        let mut r = MerlReader::open(&path).unwrap();
        let mut buf = vec![0.0; 100_000];
        r.read_raw(BIN_COUNT - 50_000, &mut buf).unwrap();
        assert!(buf[..] == table.raw()[BIN_COUNT - 50_000..BIN_COUNT + 50_000]);
        assert!(r.read_raw(3 * BIN_COUNT - 10, &mut buf).is_err());
    }

    #[test]
    fn blend_is_linear_and_keeps_unmeasured_bins() {
        let a = MerlTable::from_fn(|_, _, _| glam::Vec3::splat(1.0));
        let b = MerlTable::from_fn(|th, _, _| if th > 1.5 { glam::Vec3::splat(-1.0) } else { glam::Vec3::splat(3.0) });
        let m = a.blend(&b, 0.25);
        let (i_measured, i_unmeasured) = (0, bin_index(89, 0, 0));
        let want = 0.75 * a.value(i_measured)[0] + 0.25 * b.value(i_measured)[0];
        assert!((m.value(i_measured)[0] - want).abs() < 1e-12);
        assert!(!m.is_measured(i_unmeasured));
    }
}
