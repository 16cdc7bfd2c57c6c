//! Materials as training data: MERL-layout tables from a directory, the split by material,
//! the reference BRDF f_ref, and uniform samples with log-relative mapped values.
//!
//! - A data directory holds `NAME.binary` tables (MERL layout, read by [`renderer::formats::merl`]);
//!   the material's name is the file stem. Tables are used in memory as f32 f_r (1/sr),
//!   bin-major RGB (17.5 MB each, [`TABLE_BYTES`]); negative entries are unmeasured. A
//!   [`MaterialDataset`] keeps as many as its cache holds and reads the others when they are
//!   needed (streaming), so the number of materials is not bounded by memory.
//! - Split: the names, sorted, are shuffled with the run's seed and cut by the configured
//!   fractions (at least one training material); recorded in the run as `split.json`.
//! - f_ref: the per-bin, per-channel median of the training split's tables, unmeasured
//!   entries left out (Nielsen et al. 2015), streamed from the files.
//! - Samples: θd uniform in [0, π/2], φd uniform in [0, 2π), θh uniform in [0, π/2] or, for
//!   a share `peak_share` of the points, with MERL's own spacing θh = u²·π/2 (u uniform),
//!   which puts ten times more points within 1° of the specular peak
//!   ([`draw_angles`]). Only the rendered domain is kept: configurations with wi or wo at
//!   or below the horizon are redrawn, and the network input is the renderer's, φd folded
//!   into [0, π) ([`renderer::brdf_coords::rendered_point`]). f and f_ref by trilinear look-up
//!   between bin centres at the folded angles (unmeasured corners left out); samples where
//!   either is unmeasured are redrawn. Value y = mapping(f, f_ref) per channel; weight
//!   cos θi = wi · n of the drawn (unfolded) configuration.

use crate::error::{Error, Result};
use burn::data::dataset::Dataset;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use renderer::brdf_coords::{rendered_point, RenderedPoint};
use renderer::neural::mapping::MappingForm;
use renderer::formats::merl::{bin_indices, lookup_trilinear_measured, measured_value, MerlReader, MerlTable, BIN_COUNT, SCALE};
use serde::{Deserialize, Serialize};
use std::f32::consts::{FRAC_PI_2, TAU};
use crate::tables::{material_name, median_values, table_path};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

/// Bytes of one table in memory: f32 RGB per bin.
pub const TABLE_BYTES: u64 = BIN_COUNT as u64 * 12;

/// One material's table in memory.
#[derive(Clone, Debug)]
pub struct MaterialTable {
    /// Material name (file stem).
    pub name: String,
    /// f_r per bin (within-channel MERL index), RGB, 1/sr; negative = unmeasured.
    pub values: Vec<[f32; 3]>,
}

impl MaterialTable {
    /// From a MERL table (values scaled to 1/sr; beyond-f32 values clamped).
    pub fn from_merl(name: impl Into<String>, table: &MerlTable) -> Self {
        let values = table.measured_values();
        MaterialTable {
            name: name.into(),
            values,
        }
    }

    /// Reads a `.binary` table; errors name the file (and, for a non-finite value, the channel
    /// and bin).
    pub fn read(path: &Path) -> Result<Self> {
        let name = material_name(path)?;
        Ok(Self::from_merl(name, &MerlTable::read(path)?))
    }

    /// Trilinear look-up at (θh, θd, φd) (radians): f_r (1/sr), or `None` where every corner
    /// is unmeasured.
    pub fn lookup(&self, theta_h: f32, theta_d: f32, phi_d: f32) -> Option<[f32; 3]> {
        lookup_trilinear_measured(&self.values, theta_h, theta_d, phi_d)
    }

    /// The per-bin, per-channel median of the tables of `dataset` (of their f32 values as
    /// [`MaterialTable::read`] makes them; unmeasured entries left out, −1 where no table is
    /// measured), streamed from the files: memory stays at about 0.5 MiB per table. Errors
    /// on an empty dataset.
    pub fn median(name: &str, dataset: &MaterialDataset) -> Result<MaterialTable> {
        let medians = median_values(dataset.paths(), |c, raw| measured_value(raw, c) as f64, |_, _| {})?;
        let values = (0..BIN_COUNT)
            .map(|i| [0, 1, 2].map(|c| medians[c * BIN_COUNT + i] as f32))
            .collect();
        Ok(MaterialTable {
            name: name.to_string(),
            values,
        })
    }

    /// The linear blend (1 − s) f_self + s f_other, bin by bin, with `s` of each bin's θd
    /// index ([`blend_value`]); named `name`.
    pub fn blend(&self, other: &MaterialTable, name: String, s: impl Fn(usize) -> f32) -> MaterialTable {
        let values = self
            .values
            .iter()
            .zip(&other.values)
            .enumerate()
            .map(|(i, (&a, &b))| blend_value(a, b, s(bin_indices(i).1)))
            .collect();
        MaterialTable { name, values }
    }

    /// As a MERL table (raw values = f_r / scale), for writing.
    pub fn to_merl(&self) -> Result<MerlTable> {
        let mut raw = vec![0f64; 3 * BIN_COUNT];
        for (i, v) in self.values.iter().enumerate() {
            for c in 0..3 {
                raw[c * BIN_COUNT + i] = if v[c] < 0.0 {
                    -1.0
                } else {
                    v[c] as f64 / SCALE[c]
                };
            }
        }
        Ok(MerlTable::from_raw(raw, &self.name)?)
    }
}

/// (1 − s) a + s b per channel; unmeasured (−1) where either is.
pub fn blend_value(a: [f32; 3], b: [f32; 3], s: f32) -> [f32; 3] {
    [0, 1, 2].map(|c| if a[c] < 0.0 || b[c] < 0.0 { -1.0 } else { (1.0 - s) * a[c] + s * b[c] })
}

/// The split of the materials by name.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Split {
    /// Seed that made it.
    pub seed: u64,
    /// Training materials.
    pub train: Vec<String>,
    /// Validation materials (early stopping).
    pub validation: Vec<String>,
    /// Test materials (evaluation only).
    pub test: Vec<String>,
}

impl Split {
    /// Shuffles the sorted `names` with `seed` and cuts them by `fractions` (train, validation,
    /// test): validation and test take round(fraction · n) each (test first), training keeps
    /// the rest and at least one.
    pub fn new(names: &[String], fractions: [f64; 3], seed: u64) -> Self {
        let mut names = names.to_vec();
        names.sort();
        names.shuffle(&mut rand_pcg::Pcg64::seed_from_u64(seed ^ 0x5eed_5911));
        let n = names.len();
        let test = ((fractions[2] * n as f64).round() as usize).min(n.saturating_sub(1));
        let validation =
            ((fractions[1] * n as f64).round() as usize).min(n.saturating_sub(1 + test));
        let train = n - test - validation;
        Split {
            seed,
            test: names[train + validation..].to_vec(),
            validation: names[train..train + validation].to_vec(),
            train: names[..train].to_vec(),
        }
    }
}

/// A burn [`Dataset`] of materials: tables read from their files when first needed and kept in
/// a cache of a bounded number of tables (least recently used out first). When all of them
/// fit they are read once, in parallel, when the dataset is opened; otherwise the training
/// loop [`prefetch`](MaterialDataset::prefetch)es the next step's tables on a thread while
/// the current step computes. A table's values do not depend on the cache, so training is the
/// same with any cache size. Cloning shares the cache.
#[derive(Clone, Debug)]
pub struct MaterialDataset {
    store: Arc<TableStore>,
}

#[derive(Debug)]
struct TableStore {
    names: Vec<String>,
    paths: Vec<PathBuf>,
    /// The cached table of each material; a reader holds the slot's lock while it reads, so
    /// a second request for the same table waits for it instead of reading it again.
    slots: Vec<Mutex<Option<Arc<MaterialTable>>>>,
    /// Indices of the cached tables, least recently used first.
    recent: Mutex<VecDeque<usize>>,
    capacity: usize,
}

/// Locks a mutex whose data stays consistent even if a holder panicked.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl MaterialDataset {
    /// The named materials' tables in `dir` (`NAME.binary`), each checked now (header and
    /// length), with a cache of `cache_bytes` (at least one table). When every table fits
    /// they are all read now, in parallel.
    pub fn open(dir: &Path, names: &[String], cache_bytes: u64) -> Result<Self> {
        let paths: Vec<PathBuf> = names.iter().map(|n| table_path(dir, n)).collect();
        paths.par_iter().try_for_each(|p| MerlReader::open(p).map(|_| ()))?;
        let capacity = (cache_bytes / TABLE_BYTES).max(1) as usize;
        let dataset = MaterialDataset {
            store: Arc::new(TableStore {
                names: names.to_vec(),
                slots: paths.iter().map(|_| Mutex::new(None)).collect(),
                paths,
                recent: Mutex::new(VecDeque::new()),
                capacity,
            }),
        };
        if dataset.is_resident() {
            (0..names.len()).into_par_iter().try_for_each(|i| dataset.table(i).map(|_| ()))?;
        }
        Ok(dataset)
    }

    /// Materials in the dataset.
    pub fn len(&self) -> usize {
        self.store.names.len()
    }

    pub fn is_empty(&self) -> bool {
        self.store.names.is_empty()
    }

    /// The material names, in dataset order.
    pub fn names(&self) -> &[String] {
        &self.store.names
    }

    /// The table files, in dataset order.
    pub fn paths(&self) -> &[PathBuf] {
        &self.store.paths
    }

    /// True when the cache holds every table (nothing is streamed).
    pub fn is_resident(&self) -> bool {
        self.store.capacity >= self.len()
    }

    /// Tables in the cache now.
    pub fn cached(&self) -> usize {
        lock(&self.store.recent).len()
    }

    /// The table of material `index`, from the cache or read from its file (then cached,
    /// evicting the least recently used beyond the capacity).
    ///
    /// # Panics
    /// If `index >= len()`.
    pub fn table(&self, index: usize) -> Result<Arc<MaterialTable>> {
        let store = &self.store;
        let mut slot = lock(&store.slots[index]);
        let table = match &*slot {
            Some(t) => t.clone(),
            None => {
                let t = Arc::new(MaterialTable::read(&store.paths[index])?);
                *slot = Some(t.clone());
                t
            }
        };
        // The slot is released before the list of recent tables is locked (never the other
        // way round), and the evicted slots after it.
        drop(slot);
        let evicted: Vec<usize> = {
            let mut recent = lock(&store.recent);
            recent.retain(|&i| i != index);
            recent.push_back(index);
            let excess = recent.len().saturating_sub(store.capacity);
            recent.drain(..excess).collect()
        };
        for i in evicted {
            *lock(&store.slots[i]) = None;
        }
        Ok(table)
    }

    /// Starts reading the tables `indices` into the cache on a background thread (when the
    /// dataset streams; a no-op when every table is resident). Errors are left for
    /// [`MaterialDataset::table`] to report.
    pub fn prefetch(&self, indices: Vec<usize>) {
        if self.is_resident() || indices.is_empty() {
            return;
        }
        let dataset = self.clone();
        std::thread::spawn(move || {
            for i in indices {
                let _ = dataset.table(i);
            }
        });
    }
}

impl Dataset<Arc<MaterialTable>, Error> for MaterialDataset {
    /// The table at `index` (see [`MaterialDataset::table`]).
    ///
    /// # Panics
    /// If `index >= len()`, as burn's `Dataset` contract specifies.
    fn get(&self, index: usize) -> Result<Arc<MaterialTable>> {
        self.table(index)
    }

    fn len(&self) -> usize {
        self.store.names.len()
    }
}

/// Samples of one material, as the networks consume them (row-major).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SampleSet {
    /// 6D network inputs, [n, 6].
    pub inputs: Vec<f32>,
    /// Mapped values y, [n, 3].
    pub values: Vec<f32>,
    /// cos θi of each sample, [n].
    pub cos_i: Vec<f32>,
}

impl SampleSet {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.cos_i.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.cos_i.is_empty()
    }

    /// The set encoder's input of the first `n` samples: [n, 9] = [inputs | values].
    pub fn encoder_input(&self, n: usize) -> Vec<f32> {
        let n = n.min(self.len());
        let mut out = Vec::with_capacity(n * 9);
        for i in 0..n {
            out.extend_from_slice(&self.inputs[6 * i..6 * i + 6]);
            out.extend_from_slice(&self.values[3 * i..3 * i + 3]);
        }
        out
    }

    /// The difference directions (unit vectors, = inputs 3..6) of the samples.
    pub fn directions(&self) -> Vec<[f32; 3]> {
        self.inputs
            .chunks_exact(6)
            .map(|x| [x[3], x[4], x[5]])
            .collect()
    }

    /// Appends one sample.
    pub fn push(&mut self, input: [f32; 6], value: [f32; 3], cos_i: f32) {
        self.inputs.extend_from_slice(&input);
        self.values.extend_from_slice(&value);
        self.cos_i.push(cos_i);
    }
}

/// Draws samples of materials and maps their values relative to f_ref.
#[derive(Clone, Debug)]
pub struct Sampler {
    /// The reference BRDF f_ref.
    pub reference: Arc<MaterialTable>,
    /// Form of the mapping.
    pub mapping: MappingForm,
    /// ε of the mapping.
    pub epsilon: f32,
    /// Share of the points whose θh is drawn with MERL's spacing (see [`draw_angles`]).
    pub peak_share: f32,
}

/// Attempts per requested sample before giving up on a (mostly unmeasured) table.
const MAX_ATTEMPTS_PER_SAMPLE: usize = 64;

impl Sampler {
    /// The sample of a rendered point with measured value `f` (1/sr): (network input,
    /// mapped value, cos θi); `None` where f_ref is unmeasured.
    pub fn sample_of(&self, point: &RenderedPoint, f: [f32; 3]) -> Option<([f32; 6], [f32; 3], f32)> {
        let [theta_h, theta_d, phi_d] = point.angles;
        let r = self.reference.lookup(theta_h, theta_d, phi_d)?;
        let y = [0, 1, 2].map(|c| self.mapping.forward(f[c].max(0.0), r[c].max(0.0), self.epsilon));
        Some((point.input, y, point.cos_i))
    }

    /// The sample at (θh, θd, φd) (radians, φh = 0) with measured value `f` (1/sr); `None`
    /// outside the rendered domain or where f_ref is unmeasured.
    pub fn sample_at(
        &self,
        theta_h: f32,
        theta_d: f32,
        phi_d: f32,
        f: [f32; 3],
    ) -> Option<([f32; 6], [f32; 3], f32)> {
        self.sample_of(&rendered_point(theta_h, theta_d, phi_d)?, f)
    }

    /// `n` samples of `table` (see the module documentation). Errors when the table is
    /// (almost) entirely unmeasured.
    pub fn draw(&self, table: &MaterialTable, n: usize, rng: &mut impl Rng) -> Result<SampleSet> {
        draw_points(table, n, self.peak_share, rng, |point, f| self.sample_of(point, f))
    }
}

/// (θh, θd, φd) of one point: θd uniform in [0, π/2], φd uniform in [0, 2π), θh with MERL's
/// spacing θh = u²·π/2 with probability `peak_share` and uniform in [0, π/2] otherwise.
/// Uniform θh puts 1.1 % of the points within 1° of the specular peak (θh = 0), MERL's
/// spacing 10.5 %; mirror-like materials hold almost all their energy there.
pub fn draw_angles(peak_share: f32, rng: &mut impl Rng) -> [f32; 3] {
    let peak = rng.random::<f32>() < peak_share;
    let u = rng.random::<f32>();
    let theta_h = if peak { u * u } else { u } * FRAC_PI_2;
    [theta_h, rng.random::<f32>() * FRAC_PI_2, rng.random::<f32>() * TAU]
}

/// `n` samples of `table` at points of [`draw_angles`] inside the rendered domain
/// ([`rendered_point`]), with f looked up trilinearly at the folded angles (points with no
/// measured corner skipped); `to_sample(point, f)` turns a point into (network input, value,
/// cos θi) or rejects it. Errors when the table is (almost) entirely unmeasured.
pub fn draw_points(
    table: &MaterialTable,
    n: usize,
    peak_share: f32,
    rng: &mut impl Rng,
    mut to_sample: impl FnMut(&RenderedPoint, [f32; 3]) -> Option<([f32; 6], [f32; 3], f32)>,
) -> Result<SampleSet> {
    let mut set = SampleSet::default();
    set.inputs.reserve(6 * n);
    set.values.reserve(3 * n);
    set.cos_i.reserve(n);
    let mut attempts = 0usize;
    while set.len() < n {
        attempts += 1;
        if attempts > n.max(16) * MAX_ATTEMPTS_PER_SAMPLE {
            return Err(Error::Invalid(format!(
                "material '{}': too few measured bins to draw {n} samples",
                table.name
            )));
        }
        let [theta_h, theta_d, phi_d] = draw_angles(peak_share, rng);
        let Some(point) = rendered_point(theta_h, theta_d, phi_d) else {
            continue;
        };
        let [th, td, pd] = point.angles;
        let Some(f) = table.lookup(th, td, pd) else {
            continue;
        };
        if let Some((x, y, c)) = to_sample(&point, f) {
            set.push(x, y, c);
        }
    }
    Ok(set)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn constant(name: &str, v: f32) -> MaterialTable {
        MaterialTable {
            name: name.into(),
            values: vec![[v, 2.0 * v, 0.5 * v]; BIN_COUNT],
        }
    }

    #[test]
    fn split_is_seeded_and_complete() {
        let names: Vec<String> = (0..100).map(|i| format!("m{i:03}")).collect();
        let a = Split::new(&names, [0.7, 0.1, 0.2], 7);
        assert_eq!(
            (a.train.len(), a.validation.len(), a.test.len()),
            (70, 10, 20)
        );
        assert_eq!(a, Split::new(&names, [0.7, 0.1, 0.2], 7));
        assert_ne!(a.train, Split::new(&names, [0.7, 0.1, 0.2], 8).train);
        let mut all: Vec<String> = a
            .train
            .iter()
            .chain(&a.validation)
            .chain(&a.test)
            .cloned()
            .collect();
        all.sort();
        assert_eq!(all, names);
        let three = Split::new(&names[..3], [0.7, 0.1, 0.2], 1);
        assert_eq!(
            (three.train.len(), three.validation.len(), three.test.len()),
            (2, 0, 1)
        );
        let one = Split::new(&names[..1], [0.7, 0.1, 0.2], 1);
        assert_eq!(one.train.len(), 1);
    }

    #[test]
    fn samples_map_relative_to_the_reference() {
        let reference = Arc::new(constant("ref", 0.1));
        let sampler = Sampler {
            reference,
            mapping: MappingForm::Talk,
            epsilon: 0.002,
            peak_share: 0.5,
        };
        let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
        let set = sampler.draw(&constant("same", 0.1), 100, &mut rng).unwrap();
        assert_eq!(set.len(), 100);
        assert!(set.values.iter().all(|y| y.abs() < 1e-5));
        assert!(set.cos_i.iter().all(|c| (0.0..=1.0).contains(c)));
        assert_eq!(set.encoder_input(10).len(), 90);
        let d = set.directions();
        assert!(d.iter().all(
            |v| ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) - 1.0).abs() < 1e-5 && v[2] >= -1e-6
        ));

        let mut unmeasured = constant("hole", 0.1);
        unmeasured.values.iter_mut().for_each(|v| *v = [-1.0; 3]);
        let e = sampler
            .draw(&unmeasured, 10, &mut rng)
            .unwrap_err()
            .to_string();
        assert!(e.contains("'hole'"), "{e}");
    }

    /// Tables `t0.binary` ... in a temporary directory, table k constant `values[k]` except
    /// bin 5 of table 1, unmeasured.
    fn table_files(values: &[f32]) -> (tempfile::TempDir, Vec<String>) {
        let dir = tempfile::tempdir().unwrap();
        let mut names = Vec::new();
        for (k, &v) in values.iter().enumerate() {
            let mut t = constant(&format!("t{k}"), v);
            if k == 1 {
                t.values[5] = [-1.0; 3];
            }
            t.to_merl().unwrap().write(dir.path().join(format!("t{k}.binary"))).unwrap();
            names.push(format!("t{k}"));
        }
        (dir, names)
    }

    #[test]
    fn median_leaves_out_unmeasured() {
        let (dir, names) = table_files(&[0.1, 0.3, 0.2]);
        let dataset = MaterialDataset::open(dir.path(), &names, 0).unwrap();
        assert!(!dataset.is_resident() && dataset.cached() == 0, "the median reads no table whole");
        let m = MaterialTable::median("m", &dataset).unwrap();
        assert!((m.values[0][0] - 0.2).abs() < 1e-7);
        assert!((m.values[5][0] - 0.15).abs() < 1e-7);
    }

    #[test]
    fn a_small_cache_streams_the_same_tables() {
        let (dir, names) = table_files(&[0.1, 0.3, 0.2, 0.4]);
        let resident = MaterialDataset::open(dir.path(), &names, u64::MAX).unwrap();
        assert!(resident.is_resident() && resident.cached() == 4);
        // Room for two tables.
        let streamed = MaterialDataset::open(dir.path(), &names, 2 * TABLE_BYTES).unwrap();
        assert!(!streamed.is_resident() && streamed.cached() == 0);
        streamed.prefetch(vec![3, 2]);
        for i in [0, 1, 2, 3, 1, 0, 3] {
            let (a, b) = (streamed.table(i).unwrap(), resident.table(i).unwrap());
            assert_eq!((&a.name, &a.values), (&b.name, &b.values));
            assert!(streamed.cached() <= 2);
        }
        // A missing file is found when the dataset is opened.
        std::fs::remove_file(dir.path().join("t2.binary")).unwrap();
        let e = MaterialDataset::open(dir.path(), &names, 0).unwrap_err().to_string();
        assert!(e.contains("t2.binary"), "{e}");
    }

    #[test]
    fn peak_share_puts_points_near_the_specular_peak() {
        let near = |share: f32| {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(2);
            let n = 200_000;
            let hits = (0..n)
                .filter(|_| draw_angles(share, &mut rng)[0] < 1f32.to_radians())
                .count();
            hits as f64 / n as f64
        };
        // Uniform θh: 1/90 of the points within 1°; MERL's spacing: √(1/90) of them.
        assert!((near(0.0) - 1.0 / 90.0).abs() < 0.002, "{}", near(0.0));
        assert!((near(1.0) - (1.0f64 / 90.0).sqrt()).abs() < 0.005, "{}", near(1.0));
        let half = near(0.5);
        assert!((half - 0.5 * (1.0 / 90.0 + (1.0f64 / 90.0).sqrt())).abs() < 0.005, "{half}");
    }

    #[test]
    fn samples_lie_in_the_rendered_domain() {
        let sampler = Sampler {
            reference: Arc::new(constant("ref", 0.1)),
            mapping: MappingForm::Code,
            epsilon: 0.002,
            peak_share: 0.5,
        };
        let mut rng = rand_pcg::Pcg64::seed_from_u64(4);
        let set = sampler.draw(&constant("m", 0.2), 5000, &mut rng).unwrap();
        for (x, &c) in set.inputs.chunks_exact(6).zip(&set.cos_i) {
            // Folded (dy ≥ 0), wi above the horizon; the renderer's own input.
            assert!(x[4] >= 0.0 && c > 0.0 && c <= 1.0, "{x:?} {c}");
            let h = glam::Vec3::new(x[0], x[1], x[2]);
            assert!((h.length() - 1.0).abs() < 1e-5 && h.z >= 0.0);
        }
        // A sample outside the domain (wo below the horizon) is refused.
        assert!(sampler.sample_at(1.4, 1.4, 0.0, [0.2; 3]).is_none());
        assert!(sampler.sample_at(0.1, 0.3, 0.5, [0.2; 3]).is_some());
    }
}
