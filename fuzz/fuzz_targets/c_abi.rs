//! The C ABI of `libneural_brdf` (plugins/c) from arbitrary bytes: every call through its
//! `extern "C"` functions, as a C program would make it. The first byte (mod 8) picks the
//! call:
//!
//! - 0–3: `nb_material_eval`, `_pdf`, `_eval_pdf`, `_sample` on one of five materials opened
//!   once (a decoded code, a blend, an NBRDF network, a MERL table, a mixture of three),
//!   with n pairs (0 to 64, or up to 2,600 so that batches span parallel chunks) of floats
//!   read from the input in one of four styles (raw bits; special values: NaN, ±inf, ±0,
//!   denormals, ±f32::MAX...; unit directions from angles; a tag byte per float choosing);
//! - 4: `nb_material_open` of a file written from the bytes (a latent file, a MERL table or
//!   one `.npy` tensor of a network whose five others are valid), a code name from the bytes
//!   or NULL;
//! - 5: `nb_material_open_latent_vector` with a vector of any length (the file's sizes and
//!   arbitrary ones) and any values;
//! - 6: `nb_material_open_blend` at any t and `nb_material_open_mix` of 0 to 6 parts with any
//!   weights;
//! - 7: NULL pointers in every position (with n = 0 and n > 0).
//!
//! Speed (a million inputs in well under an hour): the calls that open a latent file read a
//! cheap one (`renderer::testing::latent`: a 6-4-3 net, latent size 2, the shipped f_ref),
//! and those that would decode a code, fit a network's sampler or read a whole latent file
//! run on one input in [`RARE`] (always on the first input of a process, so a crash found
//! there replays); the others check only what is refused.
//!
//! Checked: no call returns `NbStatus::Panic` (a panic caught at the boundary) or crashes;
//! a failed call leaves a message; a call that succeeds gives finite values ≥ 0 (and
//! unit directions for samples), the batch equal to one call per pair bit for bit; bad input
//! (a non-finite direction, a uniform number outside [0, 1], a latent vector of the wrong
//! size) is refused. See docs/fuzzing.md.
#![no_main]

use libfuzzer_sys::fuzz_target;
use neural_brdf::*;
use renderer_fuzz::{split_npy_input, valid_npy_tensors};
use std::ffi::{CStr, CString};
use std::path::{Path, PathBuf};
use std::ptr::{null, null_mut};
use std::sync::OnceLock;

/// The materials opened once (handles; never freed).
struct Materials {
    handles: Vec<*mut NbMaterial>,
}

// SAFETY: handles may be used from many threads at once (the header says so); the fuzzer
// runs one input at a time anyway.
unsafe impl Send for Materials {}
unsafe impl Sync for Materials {}

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("repository root")
}

fn shipped_latent() -> CString {
    c_path(&repo().join("scenes/materials/latent.bin"))
}

/// The cheap latent file (written once per process): codes `alum-bronze` and `chrome`.
fn cheap_latent() -> &'static CString {
    static PATH: OnceLock<CString> = OnceLock::new();
    PATH.get_or_init(|| {
        let path = scratch().join("cheap.bin");
        renderer::testing::latent::write_cheap_latent_file(&path).expect("write the cheap latent file");
        c_path(&path)
    })
}

/// The cheap latent file's valid vector lengths: z, z + offsets, z + offsets + residual.
fn cheap_lengths() -> [usize; 3] {
    static LENGTHS: OnceLock<[usize; 3]> = OnceLock::new();
    *LENGTHS.get_or_init(|| {
        let path = std::path::PathBuf::from(cheap_latent().to_str().expect("UTF-8"));
        let file = renderer::formats::latent_file::LatentFile::read(&path).expect("the cheap latent file");
        [file.latent_dim, file.latent_dim + 3, file.latent_dim + 3 + file.residual_len()]
    })
}

/// One input in this many may decode, fit a sampler or read a latent file.
const RARE: u64 = 256;

/// Whether this input may make the expensive calls (the first input always may).
fn rare_turn() -> bool {
    static INPUTS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    INPUTS.fetch_add(1, std::sync::atomic::Ordering::Relaxed) % RARE == 0
}

fn c_path(path: &Path) -> CString {
    CString::new(path.to_str().expect("UTF-8 path")).expect("no NUL in the path")
}

/// A directory of this process's own for the files written from inputs.
fn scratch() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("c_abi-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create the scratch directory");
        dir
    })
}

fn open_ok(status: NbStatus, m: *mut NbMaterial, what: &str) -> *mut NbMaterial {
    assert_eq!(status, NbStatus::Ok, "{what}: {}", last_error());
    assert!(!m.is_null());
    m
}

fn materials() -> &'static [*mut NbMaterial] {
    static MATERIALS: OnceLock<Materials> = OnceLock::new();
    &MATERIALS
        .get_or_init(|| {
            let latent = shipped_latent();
            let (a, b) = (CString::new("alum-bronze").unwrap(), CString::new("chrome").unwrap());
            let mut code = null_mut();
            let code = open_ok(unsafe { nb_material_open(latent.as_ptr(), a.as_ptr(), &mut code) }, code, "code");
            let mut blend = null_mut();
            let blend = open_ok(unsafe { nb_material_open_blend(latent.as_ptr(), a.as_ptr(), b.as_ptr(), 0.5, &mut blend) }, blend, "blend");
            let network_path = repo().join("../shared/data/nbrdf/merl/chrome");
            let mut network = null_mut();
            let network = open_ok(unsafe { nb_material_open(c_path(&network_path).as_ptr(), null(), &mut network) }, network, "network");
            // A MERL table tabulated from the network (about a minute under AddressSanitizer):
            // made once per machine and shared by later processes (libFuzzer's -jobs and
            // -fork start many), written to a file of this process's and renamed into place.
            let table_path = std::env::temp_dir().join("c_abi-fuzz-chrome.binary");
            if !table_path.is_file() {
                let net = renderer::neural::nbrdf::NbrdfNetwork::load(&network_path).expect("the shared NBRDF network");
                let mine = scratch().join("chrome.binary");
                renderer::formats::merl::MerlTable::from_fn(|th, td, pd| net.eval_angles(th, td, pd)).write(&mine).expect("write the table");
                std::fs::rename(&mine, &table_path).expect("move the table into place");
            }
            let mut table = null_mut();
            let table = open_ok(unsafe { nb_material_open(c_path(&table_path).as_ptr(), null(), &mut table) }, table, "table");
            let parts = [code.cast_const(), network.cast_const(), table.cast_const()];
            let mut mix = null_mut();
            let mix = open_ok(unsafe { nb_material_open_mix(parts.as_ptr(), [0.5f32, 0.3, 0.2].as_ptr(), 3, &mut mix) }, mix, "mix");
            Materials { handles: vec![code, blend, network, table, mix] }
        })
        .handles
}

fn last_error() -> String {
    unsafe { CStr::from_ptr(nb_last_error()) }.to_string_lossy().into_owned()
}

/// Checks a failed call: not a caught panic, and a message.
fn check_failure(status: NbStatus, what: &str) {
    assert_ne!(status, NbStatus::Panic, "{what}: {}", last_error());
    if status != NbStatus::Ok {
        assert!(!last_error().is_empty(), "{what}: status {status:?} without a message");
    }
}

/// Special values: what a careless caller passes.
const SPECIALS: [f32; 20] = [
    0.0,
    -0.0,
    1.0,
    -1.0,
    0.5,
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::MIN_POSITIVE,
    1e-45,
    -1e-45,
    1e-40,
    f32::MAX,
    f32::MIN,
    1e20,
    -1e20,
    f32::EPSILON,
    1.0 - f32::EPSILON / 2.0,
    1.0 + f32::EPSILON,
    0.999_999,
];

/// Reads the input as a stream; past its end it gives zeros.
struct Reader<'a> {
    data: &'a [u8],
}

impl Reader<'_> {
    fn byte(&mut self) -> u8 {
        match self.data.split_first() {
            Some((&b, rest)) => {
                self.data = rest;
                b
            }
            None => 0,
        }
    }

    fn u16(&mut self) -> u16 {
        u16::from_le_bytes([self.byte(), self.byte()])
    }

    fn raw(&mut self) -> f32 {
        f32::from_le_bytes([self.byte(), self.byte(), self.byte(), self.byte()])
    }

    fn special(&mut self) -> f32 {
        SPECIALS[self.byte() as usize % SPECIALS.len()]
    }

    /// A float in the given style (0 raw, 1 special, 2 a byte / 255, 3 tagged).
    fn float(&mut self, style: u8) -> f32 {
        match style % 4 {
            0 => self.raw(),
            1 => self.special(),
            2 => self.byte() as f32 / 255.0,
            _ => match self.byte() % 4 {
                0 => self.raw(),
                1 => self.special(),
                _ => self.byte() as f32 / 255.0,
            },
        }
    }

    /// `n` directions as 3 n floats: in `style`, or (style 2) unit vectors from two angle
    /// bytes each, over the whole sphere so that some lie below the horizon.
    fn directions(&mut self, n: usize, style: u8) -> Vec<f32> {
        let mut out = Vec::with_capacity(3 * n);
        for _ in 0..n {
            if style % 4 == 2 {
                let theta = self.byte() as f32 / 255.0 * std::f32::consts::PI;
                let phi = self.byte() as f32 / 255.0 * std::f32::consts::TAU;
                out.extend_from_slice(&[theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()]);
            } else {
                for _ in 0..3 {
                    out.push(self.float(style));
                }
            }
        }
        out
    }

    /// A batch size: mostly small, sometimes beyond one parallel chunk (1,024).
    fn count(&mut self) -> usize {
        match self.byte() {
            b @ 0..=247 => b as usize % 65,
            _ => self.u16() as usize % 2600,
        }
    }

    fn rest(&mut self) -> &[u8] {
        std::mem::take(&mut self.data)
    }
}

fn all_finite(v: &[f32]) -> bool {
    v.iter().all(|x| x.is_finite())
}

fn check_values(f: &[f32], what: &str) {
    assert!(f.iter().all(|x| x.is_finite() && *x >= 0.0), "{what}: {f:?}");
}

fn evaluate(m: *const NbMaterial, op: u8, r: &mut Reader) {
    let n = r.count();
    let (style_o, style_i) = (r.byte(), r.byte());
    let wo = r.directions(n, style_o);
    let wi = if op == 3 {
        // Uniform numbers: mostly in [0, 1] (style 2), else any.
        (0..3 * n).map(|_| r.float(style_i)).collect()
    } else {
        r.directions(n, style_i)
    };
    let mut f = vec![-1.0f32; 3 * n];
    let mut pdf = vec![-1.0f32; n];
    let status = unsafe {
        match op {
            0 => nb_material_eval(m, n, wo.as_ptr(), wi.as_ptr(), f.as_mut_ptr()),
            1 => nb_material_pdf(m, n, wo.as_ptr(), wi.as_ptr(), pdf.as_mut_ptr()),
            2 => nb_material_eval_pdf(m, n, wo.as_ptr(), wi.as_ptr(), f.as_mut_ptr(), pdf.as_mut_ptr()),
            _ => {
                let mut drawn = vec![-1.0f32; 3 * n];
                let status = nb_material_sample(m, n, wo.as_ptr(), wi.as_ptr(), drawn.as_mut_ptr(), f.as_mut_ptr(), pdf.as_mut_ptr());
                if status == NbStatus::Ok {
                    check_values(&f, "sample f");
                    check_values(&pdf, "sample pdf");
                    for (k, d) in drawn.chunks(3).enumerate() {
                        let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                        if pdf[k] > 0.0 {
                            assert!((length - 1.0).abs() < 1e-3 && d[2] >= 0.0, "drawn {d:?} with pdf {}", pdf[k]);
                        } else {
                            assert!(d == [0.0; 3] && f[3 * k..3 * k + 3] == [0.0; 3], "failed draw {d:?}");
                        }
                    }
                }
                status
            }
        }
    };
    check_failure(status, "evaluate");
    let u_ok = op != 3 || wi.iter().all(|x| (0.0..=1.0).contains(x));
    let valid = all_finite(&wo) && (op == 3 || all_finite(&wi)) && u_ok;
    assert_eq!(status == NbStatus::Ok, valid, "op {op}, n {n}: status {status:?} ({}), wo {wo:?}, wi/u {wi:?}", last_error());
    if status != NbStatus::Ok {
        return;
    }
    match op {
        0 | 2 => check_values(&f, "eval"),
        _ => {}
    }
    if op != 0 {
        check_values(&pdf, "pdf");
    }
    // One call per pair gives the batch's values bit for bit.
    if op == 2 && n <= 64 {
        for k in 0..n {
            let (mut f1, mut pdf1) = ([0f32; 3], 0f32);
            let s = unsafe { nb_material_eval_pdf(m, 1, wo[3 * k..].as_ptr(), wi[3 * k..].as_ptr(), f1.as_mut_ptr(), &mut pdf1) };
            assert_eq!(s, NbStatus::Ok);
            assert_eq!((f1.to_vec(), pdf1.to_bits()), (f[3 * k..3 * k + 3].to_vec(), pdf[k].to_bits()), "pair {k}");
        }
    }
}

/// Evaluates a freshly opened material at a few pairs and frees it.
fn probe_and_free(m: *mut NbMaterial) {
    let wo = [0.0f32, 0.6, 0.8, 0.3, 0.0, 0.954, 0.0, 0.0, 1.0];
    let wi = [0.0f32, -0.6, 0.8, -0.5, 0.1, 0.86, 0.0, 0.0, -1.0];
    let (mut f, mut pdf) = ([0f32; 9], [0f32; 3]);
    let status = unsafe { nb_material_eval_pdf(m, 3, wo.as_ptr(), wi.as_ptr(), f.as_mut_ptr(), pdf.as_mut_ptr()) };
    assert_eq!(status, NbStatus::Ok, "{}", last_error());
    check_values(&f, "opened f");
    check_values(&pdf, "opened pdf");
    unsafe { nb_material_free(m) };
}

/// A C string from bytes up to the first NUL.
fn c_string(bytes: &[u8]) -> CString {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    CString::new(&bytes[..end]).expect("no NUL")
}

fn open_file(r: &mut Reader, rare: bool) {
    let kind = r.byte() % 3;
    if kind == 2 && !rare {
        // A valid network fits its sampler (0.1 M evaluations); the `npy` target fuzzes
        // the tensors' parsing at full speed.
        return;
    }
    let name_len = r.byte() as usize % 16;
    let name: Vec<u8> = (0..name_len).map(|_| r.byte()).collect();
    let name = match name.first() {
        None => None,
        Some(0) => Some(CString::new("alum-bronze").unwrap()),
        Some(_) => Some(c_string(&name)),
    };
    let bytes = r.rest();
    let path = match kind {
        0 => {
            // As the `latent` target's modes 0 and 1: the bytes, or with their checksum.
            let path = scratch().join("fuzz.bin");
            let mut file = bytes.to_vec();
            if bytes.first().is_some_and(|b| b % 2 == 1) {
                file.extend_from_slice(&renderer_fuzz::fnv1a64(bytes).to_le_bytes());
            }
            std::fs::write(&path, file).expect("write the file");
            path
        }
        1 => {
            let path = scratch().join("fuzz.binary");
            std::fs::write(&path, bytes).expect("write the file");
            path
        }
        _ => {
            let Some((which, tensor)) = split_npy_input(bytes) else {
                return;
            };
            let prefix = scratch().join("net");
            for (k, name) in renderer::neural::nbrdf::TENSOR_NAMES.iter().enumerate() {
                let file = if k == which { tensor } else { &valid_npy_tensors()[k][..] };
                std::fs::write(scratch().join(format!("net_{name}.npy")), file).expect("write a tensor");
            }
            prefix
        }
    };
    let path = c_path(&path);
    let mut m = null_mut();
    let status = unsafe { nb_material_open(path.as_ptr(), name.as_ref().map_or(null(), |n| n.as_ptr()), &mut m) };
    check_failure(status, "open");
    if status == NbStatus::Ok {
        probe_and_free(m);
    } else {
        assert!(m.is_null());
    }
}

fn open_latent_vector(r: &mut Reader, rare: bool) {
    let lengths = cheap_lengths();
    let len = match r.byte() % 5 {
        0 => lengths[0],
        1 => lengths[1],
        2 => lengths[2],
        3 => r.byte() as usize,
        _ => r.u16() as usize % 16_000,
    };
    let style = r.byte();
    // Long vectors repeat the input's floats (a real code's residual is 11,580 long).
    let head: Vec<f32> = (0..len.min(256)).map(|_| r.float(style)).collect();
    let z: Vec<f32> = (0..len).map(|k| head.get(k % 256).copied().unwrap_or(0.0) * if k >= 256 { 1e-3 } else { 1.0 }).collect();
    let valid = lengths.contains(&len) && all_finite(&z);
    if len > 0 && !rare {
        // A valid vector decodes (and fits a sampler), an invalid one is refused once the
        // file is read: rare turns; NULL and empty are refused first, always checked.
        return;
    }
    let mut m = null_mut();
    let status = unsafe { nb_material_open_latent_vector(cheap_latent().as_ptr(), if len == 0 { null() } else { z.as_ptr() }, len, &mut m) };
    check_failure(status, "open_latent_vector");
    if !valid {
        assert_ne!(status, NbStatus::Ok, "a vector of {len} values, finite: {}", all_finite(&z));
    }
    if status == NbStatus::Ok {
        probe_and_free(m);
    }
}

fn open_blend_or_mix(r: &mut Reader, all: &[*mut NbMaterial], rare: bool) {
    let style = r.byte();
    if r.byte() % 2 == 0 {
        let t = r.float(style);
        let names = [c"alum-bronze", c"chrome", c"no-such", c""];
        let (a, b) = (names[r.byte() as usize % 4], names[r.byte() as usize % 4]);
        if !rare && (0.0..=1.0).contains(&t) {
            // Decodes (known codes) or reads the file to find a code unknown: rare turns.
            return;
        }
        let mut m = null_mut();
        let status = unsafe { nb_material_open_blend(cheap_latent().as_ptr(), a.as_ptr(), b.as_ptr(), t, &mut m) };
        check_failure(status, "open_blend");
        if !(0.0..=1.0).contains(&t) {
            assert_eq!(status, NbStatus::InvalidArgument, "t {t}");
        }
        if status == NbStatus::Ok {
            probe_and_free(m);
        }
    } else {
        let count = r.byte() as usize % 7;
        let parts: Vec<*const NbMaterial> = (0..count)
            .map(|_| match r.byte() as usize % (all.len() + 1) {
                k if k < all.len() => all[k].cast_const(),
                _ => null(),
            })
            .collect();
        let weights: Vec<f32> = (0..count).map(|_| r.float(style)).collect();
        let mut m = null_mut();
        let status = unsafe { nb_material_open_mix(parts.as_ptr(), weights.as_ptr(), count, &mut m) };
        check_failure(status, "open_mix");
        let sum: f32 = weights.iter().sum();
        let weights_ok = weights.iter().all(|w| w.is_finite() && *w >= 0.0) && sum > 0.0 && sum.is_finite();
        if !weights_ok || count == 0 || count > 4 || parts.contains(&null()) {
            assert_eq!(status, NbStatus::InvalidArgument, "{count} parts, weights {weights:?}");
        }
        if status == NbStatus::Ok {
            probe_and_free(m);
        }
    }
}

fn null_pointers(r: &mut Reader, m: *const NbMaterial, rare: bool) {
    let n = r.byte() as usize % 3;
    let which = r.byte();
    let buf = [0.5f32; 9];
    let mut out = [0f32; 9];
    let pick = |bit: u8| -> bool { which & (1 << bit) != 0 };
    let m = if pick(0) { null() } else { m };
    let wo = if pick(1) { null() } else { buf.as_ptr() };
    let wi = if pick(2) { null() } else { buf.as_ptr() };
    let o1: *mut f32 = if pick(3) { null_mut() } else { out.as_mut_ptr() };
    let mut out2 = [0f32; 9];
    let o2: *mut f32 = if pick(4) { null_mut() } else { out2.as_mut_ptr() };
    let mut out3 = [0f32; 3];
    let o3: *mut f32 = if pick(5) { null_mut() } else { out3.as_mut_ptr() };
    let statuses = unsafe {
        [
            nb_material_eval(m, n, wo, wi, o1),
            nb_material_pdf(m, n, wo, wi, o3),
            nb_material_eval_pdf(m, n, wo, wi, o1, o3),
            nb_material_sample(m, n, wo, wi, o1, o2, o3),
        ]
    };
    for s in statuses {
        check_failure(s, "NULL pointers");
    }
    if m.is_null() {
        assert!(statuses.iter().all(|&s| s == NbStatus::InvalidArgument));
    }
    let mut h = null_mut();
    let latent = cheap_latent();
    // A latent file without a code name is refused once the file is read: rare turns.
    let nameless = if rare { latent.as_ptr() } else { null() };
    for s in unsafe {
        [
            nb_material_open(null(), null(), &mut h),
            nb_material_open(nameless, null(), &mut h),
            nb_material_open(latent.as_ptr(), c"chrome".as_ptr(), null_mut()),
            nb_material_open_blend(latent.as_ptr(), null(), c"chrome".as_ptr(), 0.5, &mut h),
            nb_material_open_latent_vector(latent.as_ptr(), null(), 40, &mut h),
            nb_material_open_mix(null(), null(), 1, &mut h),
        ]
    } {
        assert_eq!(s, NbStatus::InvalidArgument, "{}", last_error());
    }
    assert!(h.is_null());
    unsafe { nb_material_free(null_mut()) };
}

fuzz_target!(|data: &[u8]| {
    let all = materials();
    let rare = rare_turn();
    let mut r = Reader { data };
    let op = r.byte() % 8;
    let m = all[r.byte() as usize % all.len()];
    match op {
        0..=3 => evaluate(m, op, &mut r),
        4 => open_file(&mut r, rare),
        5 => open_latent_vector(&mut r, rare),
        6 => open_blend_or_mix(&mut r, all, rare),
        _ => null_pointers(&mut r, m, rare),
    }
});
