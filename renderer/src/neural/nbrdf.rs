//! NBRDF networks (Sztrajman et al. 2021): 6 → 21 → 21 → 3 MLPs, one per material, read from
//! the six `.npy` files `<prefix>_fc1.npy`, `_b1`, `_fc2`, `_b2`, `_fc3`, `_b3` (float32,
//! little-endian, C order, shapes 6×21, 21, 21×21, 21, 21×3, 3; row vector times matrix).
//!
//! Evaluation: x ∈ R⁶ (see [`crate::brdf_coords::network_input`]) → relu(x·fc1 + b1) →
//! relu(·fc2 + b2) → ·fc3 + b3 = y; f_r = max(exp(y) − 1, 0) in 1/sr, RGB, without the cosine.
//!
//! The forward pass runs in f32 with the hidden layers padded to [`PADDED`] lanes (zero
//! weights). On x86-64 CPUs with AVX2 and FMA (checked once, at construction) it runs on
//! explicit 256-bit vectors; elsewhere a portable loop is used. (Left to the auto-vectoriser,
//! the 24-wide accumulators are scalarised between iterations: 4–5× slower.)

use crate::{Error, Result, Rgb};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// Input width.
pub const INPUTS: usize = 6;
/// Hidden width of the shipped networks.
pub const HIDDEN: usize = 21;
/// Output width (RGB).
pub const OUTPUTS: usize = 3;
/// Hidden width padded to a multiple of 8 lanes (the padding weights are zero).
pub const PADDED: usize = 24;
use crate::neural::mapping::MAX_LOG_VALUE;

/// The tensor files of a network, with their expected shapes, in file-name order.
const TENSORS: [(&str, &[u64]); 6] = [
    ("fc1", &[INPUTS as u64, HIDDEN as u64]),
    ("b1", &[HIDDEN as u64]),
    ("fc2", &[HIDDEN as u64, HIDDEN as u64]),
    ("b2", &[HIDDEN as u64]),
    ("fc3", &[HIDDEN as u64, OUTPUTS as u64]),
    ("b3", &[OUTPUTS as u64]),
];

/// One NBRDF network's weights, padded for vectorised evaluation.
#[derive(Clone, Debug)]
pub struct NbrdfNetwork {
    /// fc1, `w1[input][hidden]`.
    w1: [[f32; PADDED]; INPUTS],
    b1: [f32; PADDED],
    /// fc2, `w2[from][to]`.
    w2: [[f32; PADDED]; PADDED],
    b2: [f32; PADDED],
    /// fc3 transposed, `w3[channel][hidden]`.
    w3: [[f32; PADDED]; OUTPUTS],
    b3: [f32; OUTPUTS],
    /// Whether the AVX2 + FMA copy of the forward pass may run on this CPU.
    fma: bool,
}

/// Paths of the six tensor files of a network prefix (`<prefix>_fc1.npy`, ...).
pub fn tensor_paths(prefix: &Path) -> [PathBuf; 6] {
    TENSORS.map(|(name, _)| {
        let mut s = prefix.as_os_str().to_owned();
        s.push(format!("_{name}.npy"));
        PathBuf::from(s)
    })
}

/// Names of the networks in a directory (prefixes that have an `_fc1.npy`), sorted.
pub fn list_networks(dir: &Path) -> Result<Vec<String>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut names = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        if let Some(name) = entry
            .file_name()
            .to_str()
            .and_then(|n| n.strip_suffix("_fc1.npy"))
        {
            names.push(name.to_string());
        }
    }
    names.sort();
    Ok(names)
}

/// Names of the six tensors of a network (`fc1`, `b1`, `fc2`, `b2`, `fc3`, `b3`), in the
/// order of [`tensor_paths`].
pub const TENSOR_NAMES: [&str; 6] = ["fc1", "b1", "fc2", "b2", "fc3", "b3"];

/// Parses the contents of one tensor file: `name` is one of [`TENSOR_NAMES`] and chooses the
/// expected shape; `path` names the file in errors. Checks dtype (little-endian float32),
/// shape, C order and finiteness; returns the values in row-major order.
///
/// # Panics
/// If `name` is not one of [`TENSOR_NAMES`] (a programming error).
pub fn tensor_from_bytes(bytes: &[u8], name: &str, path: &Path) -> Result<Vec<f32>> {
    let (_, shape) = TENSORS
        .iter()
        .find(|(n, _)| *n == name)
        .unwrap_or_else(|| panic!("unknown NBRDF tensor name '{name}'"));
    crate::formats::npy::read_f32(bytes, shape, path)
}

impl NbrdfNetwork {
    /// Loads the six tensors `<prefix>_fc1.npy` ... `<prefix>_b3.npy`, checking dtype
    /// (little-endian float32), shapes and finiteness; errors name the offending file.
    pub fn load(prefix: impl AsRef<Path>) -> Result<Self> {
        let prefix = prefix.as_ref();
        let mut files: Vec<Vec<u8>> = Vec::with_capacity(6);
        for path in tensor_paths(prefix) {
            files.push(std::fs::read(&path).map_err(|e| Error::io(&path, e))?);
        }
        let files: [&[u8]; 6] = std::array::from_fn(|i| files[i].as_slice());
        Self::from_npy_bytes(files, prefix)
    }

    /// Builds a network from the contents of its six `.npy` files, in [`TENSOR_NAMES`]
    /// order, with the checks of [`Self::load`]; errors name the file of `prefix` (see
    /// [`tensor_paths`]) that the offending bytes stand for.
    pub fn from_npy_bytes(files: [&[u8]; 6], prefix: &Path) -> Result<Self> {
        let paths = tensor_paths(prefix);
        let mut t: Vec<Vec<f32>> = Vec::with_capacity(6);
        for ((bytes, path), (_, shape)) in files.iter().zip(&paths).zip(TENSORS) {
            t.push(crate::formats::npy::read_f32(bytes, shape, path)?);
        }
        Ok(Self::from_tensors(&t[0], &t[1], &t[2], &t[3], &t[4], &t[5]))
    }

    /// Builds a network from row-major tensors of the shipped shapes: fc1 6×21, b1 21,
    /// fc2 21×21, b2 21, fc3 21×3, b3 3.
    ///
    /// # Panics
    /// When a slice has the wrong length (a programming error; files are checked by
    /// [`Self::load`]).
    pub fn from_tensors(
        fc1: &[f32],
        b1: &[f32],
        fc2: &[f32],
        b2: &[f32],
        fc3: &[f32],
        b3: &[f32],
    ) -> Self {
        assert!(
            fc1.len() == INPUTS * HIDDEN
                && b1.len() == HIDDEN
                && fc2.len() == HIDDEN * HIDDEN
                && b2.len() == HIDDEN
                && fc3.len() == HIDDEN * OUTPUTS
                && b3.len() == OUTPUTS,
            "NBRDF tensors of the wrong size"
        );
        let mut net = NbrdfNetwork {
            w1: [[0.0; PADDED]; INPUTS],
            b1: [0.0; PADDED],
            w2: [[0.0; PADDED]; PADDED],
            b2: [0.0; PADDED],
            w3: [[0.0; PADDED]; OUTPUTS],
            b3: [0.0; OUTPUTS],
            fma: crate::support::cpu::has_avx2_fma(),
        };
        for i in 0..INPUTS {
            net.w1[i][..HIDDEN].copy_from_slice(&fc1[i * HIDDEN..(i + 1) * HIDDEN]);
        }
        net.b1[..HIDDEN].copy_from_slice(b1);
        for i in 0..HIDDEN {
            net.w2[i][..HIDDEN].copy_from_slice(&fc2[i * HIDDEN..(i + 1) * HIDDEN]);
        }
        net.b2[..HIDDEN].copy_from_slice(b2);
        for i in 0..HIDDEN {
            for c in 0..OUTPUTS {
                net.w3[c][i] = fc3[i * OUTPUTS + c];
            }
        }
        net.b3.copy_from_slice(b3);
        net
    }

    /// The network whose every weight and bias is (1 − t)·self + t·other: the only edit two
    /// NBRDF networks allow (each is fitted to one material on its own, so there is no
    /// latent space between them); the naive baseline of material editing.
    pub fn lerp(&self, other: &NbrdfNetwork, t: f32) -> NbrdfNetwork {
        fn mix<const N: usize>(a: &[f32; N], b: &[f32; N], t: f32) -> [f32; N] {
            std::array::from_fn(|i| (1.0 - t) * a[i] + t * b[i])
        }
        NbrdfNetwork {
            w1: std::array::from_fn(|i| mix(&self.w1[i], &other.w1[i], t)),
            b1: mix(&self.b1, &other.b1, t),
            w2: std::array::from_fn(|i| mix(&self.w2[i], &other.w2[i], t)),
            b2: mix(&self.b2, &other.b2, t),
            w3: std::array::from_fn(|i| mix(&self.w3[i], &other.w3[i], t)),
            b3: mix(&self.b3, &other.b3, t),
            fma: self.fma,
        }
    }

    /// The raw network output y (before the exp) for a 6D input.
    #[inline]
    pub fn forward(&self, x: [f32; INPUTS]) -> [f32; OUTPUTS] {
        #[cfg(target_arch = "x86_64")]
        if self.fma {
            // SAFETY: `fma` is true only when the CPU reported AVX2 and FMA at construction.
            return unsafe { forward_avx2_fma(self, &[x]) }[0];
        }
        forward_portable(self, x)
    }

    /// The raw outputs for many inputs (`outputs.len()` must equal `inputs.len()`), each bit
    /// for bit what [`NbrdfNetwork::forward`] gives for its input. With AVX2 and FMA,
    /// [`BATCH`] points share each pass over the weights.
    pub fn forward_batch(&self, inputs: &[[f32; INPUTS]], outputs: &mut [[f32; OUTPUTS]]) {
        assert_eq!(inputs.len(), outputs.len(), "one output per input");
        #[cfg(target_arch = "x86_64")]
        if self.fma {
            let mut ins = inputs.chunks_exact(BATCH);
            let mut outs = outputs.chunks_exact_mut(BATCH);
            for (x, y) in (&mut ins).zip(&mut outs) {
                // SAFETY: as in `forward`.
                y.copy_from_slice(&unsafe { forward_avx2_fma::<BATCH>(self, x.try_into().expect("a full batch")) });
            }
            for (x, y) in ins.remainder().iter().zip(outs.into_remainder()) {
                *y = self.forward(*x);
            }
            return;
        }
        for (x, y) in inputs.iter().zip(outputs) {
            *y = forward_portable(self, *x);
        }
    }

    /// f_r in 1/sr for a 6D input: max(exp(y) − 1, 0), finite.
    #[inline]
    pub fn eval_input(&self, x: [f32; INPUTS]) -> Rgb {
        output_value(self.forward(x))
    }

    /// f_r in 1/sr at the isotropic angles (θh, θd, φd), radians, φd as given.
    #[inline]
    pub fn eval_angles(&self, theta_h: f32, theta_d: f32, phi_d: f32) -> Rgb {
        self.eval_input(crate::brdf_coords::network_input_from_angles(
            theta_h, theta_d, phi_d,
        ))
    }
}

/// f_r in 1/sr of a raw network output y: max(exp(y) − 1, 0) per channel, finite (y is
/// capped at [`MAX_LOG_VALUE`]).
#[inline]
pub fn output_value(y: [f32; OUTPUTS]) -> Rgb {
    let f = |v: f32| {
        let r = v.min(MAX_LOG_VALUE).exp_m1();
        if r > 0.0 {
            r
        } else {
            0.0
        }
    };
    Vec3::new(f(y[0]), f(y[1]), f(y[2]))
}

/// Points per pass of the AVX2 kernel in [`NbrdfNetwork::forward_batch`]: two points'
/// twelve second-layer accumulators and the three weight registers they share fill the
/// sixteen vector registers.
pub const BATCH: usize = 2;

/// The forward pass with AVX2 + FMA for `P` points at once, each weight row loaded once for
/// all of them: each 24-wide layer is three 256-bit registers per point; the second layer
/// accumulates even and odd inputs separately to halve the FMA dependency chain. Every point
/// goes through the same operations in the same order whatever `P` is, so its output is the
/// same bits alone and in a batch.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn forward_avx2_fma<const P: usize>(net: &NbrdfNetwork, x: &[[f32; INPUTS]; P]) -> [[f32; OUTPUTS]; P] {
    use std::arch::x86_64::*;
    const GROUPS: usize = PADDED / 8;
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn load(a: &[f32; PADDED]) -> [__m256; GROUPS] {
        // SAFETY: g < PADDED / 8, so the 8 floats from 8 · g lie inside `a`.
        [0, 1, 2].map(|g| unsafe { _mm256_loadu_ps(a.as_ptr().add(8 * g)) })
    }
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn store(v: [__m256; GROUPS]) -> [f32; PADDED] {
        let mut out = [0f32; PADDED];
        for (g, r) in v.iter().enumerate() {
            // SAFETY: g < PADDED / 8, so the 8 floats from 8 · g lie inside `out`.
            unsafe { _mm256_storeu_ps(out.as_mut_ptr().add(8 * g), *r) };
        }
        out
    }
    /// acc[g] += a · w[g] for each register group.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn fmadd(a: f32, w: &[__m256; GROUPS], acc: &mut [__m256; GROUPS]) {
        let av = _mm256_set1_ps(a);
        for (h, w) in acc.iter_mut().zip(w) {
            *h = _mm256_fmadd_ps(av, *w, *h);
        }
    }
    let zero = _mm256_setzero_ps();
    let mut h1 = [load(&net.b1); P];
    for (i, row) in net.w1.iter().enumerate() {
        let w = load(row);
        for (h, x) in h1.iter_mut().zip(x) {
            fmadd(x[i], &w, h);
        }
    }
    let a1 = h1.map(|h| store(h.map(|v| _mm256_max_ps(v, zero))));
    let mut even = [load(&net.b2); P];
    let mut odd = [[zero; GROUPS]; P];
    for k in (0..HIDDEN).step_by(2) {
        let w = load(&net.w2[k]);
        for (e, a) in even.iter_mut().zip(&a1) {
            fmadd(a[k], &w, e);
        }
        if k + 1 < HIDDEN {
            let w = load(&net.w2[k + 1]);
            for (o, a) in odd.iter_mut().zip(&a1) {
                fmadd(a[k + 1], &w, o);
            }
        }
    }
    let mut y = [[0f32; OUTPUTS]; P];
    for p in 0..P {
        let h2 = [0, 1, 2].map(|g| _mm256_max_ps(_mm256_add_ps(even[p][g], odd[p][g]), zero));
        for (c, yc) in y[p].iter_mut().enumerate() {
            let w = load(&net.w3[c]);
            let mut acc = _mm256_mul_ps(h2[0], w[0]);
            for g in 1..GROUPS {
                acc = _mm256_fmadd_ps(h2[g], w[g], acc);
            }
            // Horizontal sum of the 8 lanes.
            let quad = _mm_add_ps(_mm256_castps256_ps128(acc), _mm256_extractf128_ps(acc, 1));
            let pair = _mm_add_ps(quad, _mm_movehl_ps(quad, quad));
            let single = _mm_add_ss(pair, _mm_shuffle_ps(pair, pair, 1));
            *yc = net.b3[c] + _mm_cvtss_f32(single);
        }
    }
    y
}

/// The portable forward pass (any CPU).
#[inline]
fn forward_portable(net: &NbrdfNetwork, x: [f32; INPUTS]) -> [f32; OUTPUTS] {
    let mut a1 = net.b1;
    for (xi, row) in x.iter().zip(&net.w1) {
        for j in 0..PADDED {
            a1[j] += xi * row[j];
        }
    }
    let mut a2 = net.b2;
    for (ai, row) in a1.iter().zip(&net.w2) {
        let ai = ai.max(0.0);
        for j in 0..PADDED {
            a2[j] += ai * row[j];
        }
    }
    let mut y = net.b3;
    for (yc, w3) in y.iter_mut().zip(&net.w3) {
        for (a, w) in a2.iter().zip(w3) {
            *yc += a.max(0.0) * w;
        }
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::data::{data_dir, merl_network};
    use std::path::PathBuf;

    #[test]
    fn golden_vectors_match() {
        let text = std::fs::read_to_string(data_dir().join("golden-vectors.json")).unwrap();
        let json: serde_json::Value = serde_json::from_str(&text).unwrap();
        let angles = json["inputs_theta_h_theta_d_phi_d"].as_array().unwrap();
        let inputs = json["inputs_6d"].as_array().unwrap();
        let outputs = json["outputs_rgb"].as_object().unwrap();
        assert_eq!(outputs.len(), 10);
        let mut worst = 0.0f64;
        for (name, rows) in outputs {
            let net = merl_network(name);
            for (k, row) in rows.as_array().unwrap().iter().enumerate() {
                let a: Vec<f32> = angles[k]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_f64().unwrap() as f32)
                    .collect();
                let x6: Vec<f32> = inputs[k]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_f64().unwrap() as f32)
                    .collect();
                let ours = crate::brdf_coords::network_input_from_angles(a[0], a[1], a[2]);
                for i in 0..6 {
                    assert!(
                        (ours[i] - x6[i]).abs() < 1e-6,
                        "input {k}: {ours:?} vs {x6:?}"
                    );
                }
                let got = net.eval_angles(a[0], a[1], a[2]);
                for c in 0..3 {
                    let want = row[c].as_f64().unwrap();
                    let err = (got[c] as f64 - want).abs() / want.abs().max(1e-3);
                    worst = worst.max(err);
                    assert!(err < 1e-4, "{name} #{k} channel {c}: {} vs {want}", got[c]);
                }
            }
        }
        println!("golden vectors: worst relative error {worst:.2e}");
    }

    /// A batch's outputs are each input's single forward pass, bit for bit, whatever the
    /// batch's length (full passes and a remainder).
    #[test]
    fn batched_forward_equals_single_bit_for_bit() {
        let net = merl_network("alum-bronze");
        let inputs: Vec<[f32; INPUTS]> = (0..37)
            .map(|k| {
                let t = k as f32 / 37.0;
                crate::brdf_coords::network_input_from_angles(1.5 * t, 1.5 * (1.0 - t), 3.0 * t)
            })
            .collect();
        for n in [37, 36, 1, 0] {
            let mut outputs = vec![[0.0; OUTPUTS]; n];
            net.forward_batch(&inputs[..n], &mut outputs);
            for (x, y) in inputs.iter().zip(&outputs) {
                assert_eq!(y.map(f32::to_bits), net.forward(*x).map(f32::to_bits), "{x:?}");
            }
        }
    }

    #[test]
    fn generic_and_dispatched_forward_agree() {
        let net = merl_network("alum-bronze");
        for k in 0..50 {
            let t = k as f32 / 50.0;
            let x =
                crate::brdf_coords::network_input_from_angles(1.5 * t, 1.5 * (1.0 - t), 3.0 * t);
            let a = net.forward(x);
            let b = forward_portable(&net, x);
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() <= 1e-5 * (1.0 + b[c].abs()));
            }
        }
    }

    /// The ends of a weight blend are its two networks bit for bit; inside, every weight is
    /// blended (the middle network's first-layer pre-activations are the mean of the ends').
    #[test]
    fn weight_blends_keep_their_ends() {
        let (a, b) = (merl_network("alum-bronze"), merl_network("blue-fabric"));
        let x = crate::brdf_coords::network_input_from_angles(0.4, 0.7, 1.2);
        assert_eq!(a.lerp(&b, 0.0).forward(x), a.forward(x));
        assert_eq!(b.lerp(&a, 1.0).forward(x), a.forward(x));
        let mid = a.lerp(&b, 0.5);
        let first = |n: &NbrdfNetwork, j: usize| n.b1[j] + (0..INPUTS).map(|i| n.w1[i][j] * x[i]).sum::<f32>();
        for j in 0..HIDDEN {
            let want = 0.5 * (first(&a, j) + first(&b, j));
            assert!((first(&mid, j) - want).abs() <= 1e-5 * (1.0 + want.abs()), "unit {j}");
        }
        assert_ne!(mid.forward(x), a.forward(x));
    }

    #[test]
    fn chrome_sanity_value() {
        // ../shared/data/nbrdf/README.md: at θh = 0, θd = 0.3 chrome gives about (494, 538, 537).
        let f = merl_network("chrome").eval_angles(0.0, 0.3, 0.0);
        for (got, want) in [(f.x, 494.0), (f.y, 538.0), (f.z, 537.0)] {
            assert!((got - want).abs() / want < 0.02, "{f:?}");
        }
    }

    #[test]
    fn all_shipped_networks_load() {
        let mut total = 0;
        for (folder, count) in [("merl", 100), ("rgl-isotropic", 51), ("nielsen", 8)] {
            let dir = data_dir().join(folder);
            let names = list_networks(&dir).unwrap();
            assert_eq!(names.len(), count, "{folder}");
            for name in names {
                let net = NbrdfNetwork::load(dir.join(&name)).unwrap();
                let f = net.eval_angles(0.2, 0.4, 1.0);
                assert!(
                    f.is_finite() && f.min_element() >= 0.0,
                    "{folder}/{name}: {f:?}"
                );
                total += 1;
            }
        }
        assert_eq!(total, 159);
    }

    /// Copies a network's six files into `dir` under `name`.
    fn copy_network(dir: &Path, name: &str) -> PathBuf {
        let src = tensor_paths(&data_dir().join("merl").join("chrome"));
        let prefix = dir.join(name);
        for (s, d) in src.iter().zip(tensor_paths(&prefix)) {
            std::fs::copy(s, d).unwrap();
        }
        prefix
    }

    fn write_npy<T: npyz::AutoSerialize>(
        path: &Path,
        shape: &[u64],
        values: impl IntoIterator<Item = T>,
    ) {
        use npyz::WriterBuilder;
        let mut bytes = Vec::new();
        let mut w = npyz::WriteOptions::<T>::new()
            .default_dtype()
            .shape(shape)
            .writer(&mut bytes)
            .begin_nd()
            .unwrap();
        w.extend(values).unwrap();
        w.finish().unwrap();
        std::fs::write(path, bytes).unwrap();
    }

    #[test]
    fn bad_npy_files_give_clear_errors() {
        let dir = tempfile::tempdir().unwrap();

        let prefix = copy_network(dir.path(), "shape");
        write_npy(&tensor_paths(&prefix)[2], &[21, 20], [0f32; 420]);
        let e = NbrdfNetwork::load(&prefix).unwrap_err().to_string();
        assert!(
            e.contains("shape_fc2.npy") && e.contains("shape [21, 20], expected [21, 21]"),
            "{e}"
        );

        let prefix = copy_network(dir.path(), "dtype");
        write_npy(&tensor_paths(&prefix)[1], &[21], [0f64; 21]);
        let e = NbrdfNetwork::load(&prefix).unwrap_err().to_string();
        assert!(
            e.contains("dtype_b1.npy") && e.contains("<f8") && e.contains("float32"),
            "{e}"
        );

        let prefix = copy_network(dir.path(), "nan");
        write_npy(&tensor_paths(&prefix)[5], &[3], [0.0, f32::NAN, 0.0]);
        let e = NbrdfNetwork::load(&prefix).unwrap_err().to_string();
        assert!(e.contains("nan_b3.npy") && e.contains("non-finite"), "{e}");

        let prefix = copy_network(dir.path(), "garbage");
        std::fs::write(&tensor_paths(&prefix)[0], b"not numpy").unwrap();
        let e = NbrdfNetwork::load(&prefix).unwrap_err().to_string();
        assert!(
            e.contains("garbage_fc1.npy") && e.contains("not a valid .npy"),
            "{e}"
        );

        let prefix = copy_network(dir.path(), "cut");
        let p = &tensor_paths(&prefix)[2];
        let bytes = std::fs::read(p).unwrap();
        std::fs::write(p, &bytes[..bytes.len() - 10]).unwrap();
        let e = NbrdfNetwork::load(&prefix).unwrap_err().to_string();
        assert!(e.contains("cut_fc2.npy"), "{e}");

        let e = NbrdfNetwork::load(dir.path().join("absent"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("absent_fc1.npy"), "{e}");
    }
}
