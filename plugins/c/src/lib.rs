//! The renderer's neural and measured BRDFs behind a C ABI (`libneural_brdf`, header
//! `include/neural_brdf.h`, generated from this file by cbindgen).
//!
//! - A material is an opaque handle, [`NbMaterial`], opened from a latent file and a code
//!   name (or a latent vector, or the blend of two codes at a t), a MERL table or an NBRDF
//!   network, or made as the mixture of up to four materials with weights, and freed with
//!   [`nb_material_free`]. A handle may be used from many threads at once.
//! - Every call returns an [`NbStatus`]; on an error, [`nb_last_error`] gives the one-line
//!   message (the same as the `render` command's) of the last failed call on this thread.
//! - Evaluation and sampling are batched over plain float arrays: `n` direction pairs as
//!   `3 n` floats (x, y, z of each), in the local shading frame (z = shading normal, `wo`
//!   toward the viewer, `wi` toward the light, both pointing away from the surface). Values
//!   are f_r in 1/sr per RGB channel without the cosine; densities are solid-angle densities
//!   in 1/sr; both are zero below either horizon. Large batches run in parallel.
//! - No panic crosses the boundary: one is caught and reported as [`NbStatus::Panic`].

use renderer::material::standalone::Sample;
use renderer::material::MaterialBsdf;
use renderer::Error;
use std::cell::RefCell;
use std::ffi::{c_char, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

/// The outcome of a call.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NbStatus {
    /// Success.
    Ok = 0,
    /// A file could not be opened or read.
    Io = 1,
    /// A file was read but is not a valid material file (or has the wrong version).
    InvalidFile = 2,
    /// The latent file has no code of that name.
    UnknownName = 3,
    /// An argument is invalid: a NULL pointer, a non-finite direction, a number outside
    /// [0, 1] (a uniform number, a blend's t), a latent vector of the wrong size, a mixture
    /// of no or more than 4 parts or with a weight negative or not finite (or all 0).
    InvalidArgument = 4,
    /// An internal error (a caught panic); please report it.
    Panic = 5,
    /// The CPU lacks instruction-set features the library was built for (x86-64-v3: AVX2,
    /// FMA, BMI); the message names them. Rebuild the library for this CPU.
    UnsupportedCpu = 6,
}

/// An opened material (opaque).
pub struct NbMaterial {
    bsdf: MaterialBsdf,
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_last_error(message: &str) {
    let message = CString::new(message.replace('\0', " ")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = message);
}

fn status_of(e: &Error) -> NbStatus {
    match e {
        Error::Io { .. } => NbStatus::Io,
        Error::InvalidFile { .. } => NbStatus::InvalidFile,
        Error::UnknownName { .. } => NbStatus::UnknownName,
        Error::InvalidArgument { .. } => NbStatus::InvalidArgument,
        Error::UnsupportedCpu { .. } => NbStatus::UnsupportedCpu,
    }
}

/// Runs a call's body: its error becomes a status and the last-error message, a panic is
/// caught.
fn guard(body: impl FnOnce() -> Result<(), Error>) -> NbStatus {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => NbStatus::Ok,
        Ok(Err(e)) => {
            set_last_error(&e.to_string());
            status_of(&e)
        }
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            set_last_error(&format!("internal error (please report): {what}"));
            NbStatus::Panic
        }
    }
}

fn invalid(what: &str, reason: &str) -> Error {
    Error::InvalidArgument {
        flag: what.to_string(),
        reason: reason.to_string(),
    }
}

/// A UTF-8 string argument; NULL is an error naming `what`.
unsafe fn string_arg<'a>(s: *const c_char, what: &str) -> Result<&'a str, Error> {
    if s.is_null() {
        return Err(invalid(what, "NULL"));
    }
    // SAFETY: the caller passes a NUL-terminated string (the header says so).
    unsafe { CStr::from_ptr(s) }.to_str().map_err(|_| invalid(what, "not UTF-8"))
}

/// `n` triples of floats at `p`; NULL is an error naming `what` (unless `n` is 0).
unsafe fn triples<'a>(p: *const f32, n: usize, what: &str) -> Result<&'a [[f32; 3]], Error> {
    if n == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return Err(invalid(what, "NULL"));
    }
    // SAFETY: the caller passes 3 n readable floats ([f32; 3] has the alignment of f32).
    Ok(unsafe { std::slice::from_raw_parts(p.cast::<[f32; 3]>(), n) })
}

/// `len` writable elements at `p`; NULL is an error naming `what` (unless `len` is 0).
unsafe fn output<'a, T>(p: *mut T, len: usize, what: &str) -> Result<&'a mut [T], Error> {
    if len == 0 {
        return Ok(&mut []);
    }
    if p.is_null() {
        return Err(invalid(what, "NULL"));
    }
    // SAFETY: the caller passes `len` writable elements.
    Ok(unsafe { std::slice::from_raw_parts_mut(p, len) })
}

/// The material behind a handle; NULL is an error.
unsafe fn material<'a>(m: *const NbMaterial) -> Result<&'a MaterialBsdf, Error> {
    if m.is_null() {
        return Err(invalid("material", "NULL"));
    }
    // SAFETY: a non-NULL handle comes from nb_material_open* and was not freed.
    Ok(&unsafe { &*m }.bsdf)
}

fn store(out: *mut *mut NbMaterial, bsdf: MaterialBsdf) -> Result<(), Error> {
    let handle = Box::into_raw(Box::new(NbMaterial { bsdf }));
    // SAFETY: `out` was checked to be non-NULL by the caller of `store`.
    unsafe { *out = handle };
    Ok(())
}

/// The message of the last failed call on this thread (empty when none failed yet). The
/// pointer stays valid until the next failed call on this thread.
#[no_mangle]
pub extern "C" fn nb_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// Opens a material file into `*out`: a latent file (`latent.bin`) with the code called
/// `name`, a MERL table (`*.binary`) or an NBRDF network (the prefix of its `.npy` files,
/// or one of them) with `name` NULL. `*out` is set only on success; free it with
/// nb_material_free.
///
/// # Safety
/// `path` and (when not NULL) `name` are NUL-terminated strings; `out` points to writable
/// storage for a handle.
#[no_mangle]
pub unsafe extern "C" fn nb_material_open(path: *const c_char, name: *const c_char, out: *mut *mut NbMaterial) -> NbStatus {
    guard(|| {
        renderer::support::cpu::check_build_features()?;
        let path = unsafe { string_arg(path, "path") }?;
        let name = if name.is_null() { None } else { Some(unsafe { string_arg(name, "name") }?) };
        if out.is_null() {
            return Err(invalid("out", "NULL"));
        }
        store(out, MaterialBsdf::open(Path::new(path), name)?)
    })
}

/// Opens a latent file and decodes the latent vector `z` into `*out`, e.g. an interpolated
/// or edited code: `len` floats, either the file's latent size (z alone), 3 more (z, then
/// the code's output offset per RGB channel) or the file's residual length more again (z, the
/// offsets, then the residual of the decoded network).
///
/// # Safety
/// `path` is a NUL-terminated string; `z` points to `len` floats; `out` points to writable
/// storage for a handle.
#[no_mangle]
pub unsafe extern "C" fn nb_material_open_latent_vector(path: *const c_char, z: *const f32, len: usize, out: *mut *mut NbMaterial) -> NbStatus {
    guard(|| {
        renderer::support::cpu::check_build_features()?;
        let path = unsafe { string_arg(path, "path") }?;
        if z.is_null() || len == 0 {
            return Err(invalid("z", "NULL or empty"));
        }
        if out.is_null() {
            return Err(invalid("out", "NULL"));
        }
        // SAFETY: the caller passes `len` readable floats.
        let z = unsafe { std::slice::from_raw_parts(z, len) };
        store(out, MaterialBsdf::open_latent_vector(Path::new(path), z, "latent vector")?)
    })
}

/// Opens a latent file and decodes the blend of its codes `a` and `b` at `t` into `*out`:
/// the latent interpolation (1 − t) A + t B of z and output offsets, each end's residual
/// faded out within t = 0.25 of its end, decoded
/// exactly as `render --sweep` decodes its frames (t = 0 gives A, t = 1 gives B). `t` must be
/// in [0, 1]: NaN or a value outside is NB_STATUS_INVALID_ARGUMENT (not clamped); an unknown
/// code is NB_STATUS_UNKNOWN_NAME. `*out` is set only on success; free it with
/// nb_material_free.
///
/// # Safety
/// `path`, `a` and `b` are NUL-terminated strings; `out` points to writable storage for a
/// handle.
#[no_mangle]
pub unsafe extern "C" fn nb_material_open_blend(path: *const c_char, a: *const c_char, b: *const c_char, t: f32, out: *mut *mut NbMaterial) -> NbStatus {
    guard(|| {
        renderer::support::cpu::check_build_features()?;
        let path = unsafe { string_arg(path, "path") }?;
        let (a, b) = unsafe { (string_arg(a, "a")?, string_arg(b, "b")?) };
        if out.is_null() {
            return Err(invalid("out", "NULL"));
        }
        store(out, MaterialBsdf::open_blend(Path::new(path), a, b, t)?)
    })
}

/// Makes the mixture f = Σ w_k f_k, pdf = Σ w_k pdf_k of `count` (1 to 4) materials
/// `parts[k]` with weights `weights[k]` into `*out`, as the renderer's `mix` material at a
/// texel of these weights: the weights are normalised to sum 1, parts of weight 0 dropped,
/// sampling chooses a part by weight. A weight that is negative or not finite, weights that
/// are all 0, a NULL part and more than 4 parts (a mixture part counts its own parts) are
/// NB_STATUS_INVALID_ARGUMENT. The mixture shares the parts' data: the part handles stay the
/// caller's, to free whenever it likes (before or after the mixture). `*out` is set only
/// on success; free it with nb_material_free.
///
/// # Safety
/// `parts` points to `count` handles (each from nb_material_open* and not freed), `weights`
/// to `count` floats; `out` points to writable storage for a handle.
#[no_mangle]
pub unsafe extern "C" fn nb_material_open_mix(parts: *const *const NbMaterial, weights: *const f32, count: usize, out: *mut *mut NbMaterial) -> NbStatus {
    guard(|| {
        if parts.is_null() || weights.is_null() {
            return Err(invalid(if parts.is_null() { "parts" } else { "weights" }, "NULL"));
        }
        if out.is_null() {
            return Err(invalid("out", "NULL"));
        }
        if count == 0 || count > 4 {
            return Err(invalid("count", &format!("a mixture has 1 to 4 parts, not {count}")));
        }
        // SAFETY: the caller passes `count` handles and `count` floats.
        let (handles, weights) = unsafe { (std::slice::from_raw_parts(parts, count), std::slice::from_raw_parts(weights, count)) };
        let mut mixed = Vec::with_capacity(count);
        for (k, (&h, &w)) in handles.iter().zip(weights).enumerate() {
            let m = unsafe { material(h) }.map_err(|_| invalid(&format!("parts[{k}]"), "NULL"))?;
            mixed.push((m, w));
        }
        store(out, MaterialBsdf::mix(&mixed)?)
    })
}

/// Frees a material (NULL is ignored).
///
/// # Safety
/// `m` is NULL or a handle from nb_material_open* not freed before.
#[no_mangle]
pub unsafe extern "C" fn nb_material_free(m: *mut NbMaterial) {
    if !m.is_null() {
        // SAFETY: see above; dropping cannot panic across the boundary (no Drop code
        // beyond freeing memory).
        drop(unsafe { Box::from_raw(m) });
    }
}

/// f_r(wo[i], wi[i]) for i < n into `f` (3 n floats, RGB).
///
/// # Safety
/// `wo`, `wi` and `f` point to 3 n floats each.
#[no_mangle]
pub unsafe extern "C" fn nb_material_eval(m: *const NbMaterial, n: usize, wo: *const f32, wi: *const f32, f: *mut f32) -> NbStatus {
    guard(|| {
        let m = unsafe { material(m) }?;
        let (wo, wi) = unsafe { (triples(wo, n, "wo")?, triples(wi, n, "wi")?) };
        let f = unsafe { output(f.cast::<[f32; 3]>(), n, "f") }?;
        m.eval_batch(wo, wi, f)
    })
}

/// The sampling density pdf(wo[i], wi[i]) (1/sr) for i < n into `pdf` (n floats).
///
/// # Safety
/// `wo` and `wi` point to 3 n floats, `pdf` to n.
#[no_mangle]
pub unsafe extern "C" fn nb_material_pdf(m: *const NbMaterial, n: usize, wo: *const f32, wi: *const f32, pdf: *mut f32) -> NbStatus {
    guard(|| {
        let m = unsafe { material(m) }?;
        let (wo, wi) = unsafe { (triples(wo, n, "wo")?, triples(wi, n, "wi")?) };
        let pdf = unsafe { output(pdf, n, "pdf") }?;
        m.pdf_batch(wo, wi, pdf)
    })
}

/// Value and density together: nb_material_eval into `f` and nb_material_pdf into `pdf`.
///
/// # Safety
/// `wo`, `wi` and `f` point to 3 n floats, `pdf` to n.
#[no_mangle]
pub unsafe extern "C" fn nb_material_eval_pdf(m: *const NbMaterial, n: usize, wo: *const f32, wi: *const f32, f: *mut f32, pdf: *mut f32) -> NbStatus {
    guard(|| {
        let m = unsafe { material(m) }?;
        let (wo, wi) = unsafe { (triples(wo, n, "wo")?, triples(wi, n, "wi")?) };
        let f = unsafe { output(f.cast::<[f32; 3]>(), n, "f") }?;
        let pdf = unsafe { output(pdf, n, "pdf") }?;
        m.eval_pdf_batch(wo, wi, f, pdf)
    })
}

/// Draws wi[i] given wo[i] from the three uniform numbers u[3i .. 3i+3] in [0, 1] for i < n:
/// the direction into `wi`, f_r(wo, wi) into `f` and its density into `pdf`. Where nothing
/// can be drawn (e.g. wo below the horizon) wi and f are 0 and pdf is 0.
///
/// # Safety
/// `wo`, `u`, `wi` and `f` point to 3 n floats, `pdf` to n.
#[no_mangle]
pub unsafe extern "C" fn nb_material_sample(m: *const NbMaterial, n: usize, wo: *const f32, u: *const f32, wi: *mut f32, f: *mut f32, pdf: *mut f32) -> NbStatus {
    guard(|| {
        let m = unsafe { material(m) }?;
        let (wo, u) = unsafe { (triples(wo, n, "wo")?, triples(u, n, "u")?) };
        let wi = unsafe { output(wi.cast::<[f32; 3]>(), n, "wi") }?;
        let f = unsafe { output(f.cast::<[f32; 3]>(), n, "f") }?;
        let pdf = unsafe { output(pdf, n, "pdf") }?;
        let mut samples = vec![None; n];
        m.sample_batch(wo, u, &mut samples)?;
        for (i, s) in samples.into_iter().enumerate() {
            let s = s.unwrap_or(Sample {
                wi: [0.0; 3],
                f: [0.0; 3],
                pdf: 0.0,
            });
            (wi[i], f[i], pdf[i]) = (s.wi, s.f, s.pdf);
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn panics_are_caught_and_reported() {
        let status = guard(|| panic!("boom"));
        assert_eq!(status, NbStatus::Panic);
        let message = unsafe { CStr::from_ptr(nb_last_error()) }.to_str().unwrap().to_string();
        assert!(message.contains("boom"), "{message}");
    }

    fn last_error() -> String {
        unsafe { CStr::from_ptr(nb_last_error()) }.to_str().unwrap().to_string()
    }

    #[test]
    fn blends_and_mixtures_open_and_reject_bad_input() {
        let latent = CString::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/materials/latent.bin")).unwrap();
        let (a, b, bad) = (CString::new("alum-bronze").unwrap(), CString::new("chrome").unwrap(), CString::new("no-such").unwrap());
        let mut blend: *mut NbMaterial = std::ptr::null_mut();
        assert_eq!(unsafe { nb_material_open_blend(latent.as_ptr(), a.as_ptr(), b.as_ptr(), 0.5, &mut blend) }, NbStatus::Ok);
        let mut code: *mut NbMaterial = std::ptr::null_mut();
        assert_eq!(unsafe { nb_material_open(latent.as_ptr(), a.as_ptr(), &mut code) }, NbStatus::Ok);
        let mut out: *mut NbMaterial = std::ptr::null_mut();
        for t in [f32::NAN, -0.5, 1.01] {
            assert_eq!(unsafe { nb_material_open_blend(latent.as_ptr(), a.as_ptr(), b.as_ptr(), t, &mut out) }, NbStatus::InvalidArgument);
            assert!(last_error().contains("invalid value for t"), "{}", last_error());
        }
        assert_eq!(unsafe { nb_material_open_blend(latent.as_ptr(), a.as_ptr(), bad.as_ptr(), 0.5, &mut out) }, NbStatus::UnknownName);
        assert_eq!(unsafe { nb_material_open_blend(latent.as_ptr(), std::ptr::null(), b.as_ptr(), 0.5, &mut out) }, NbStatus::InvalidArgument);
        assert!(out.is_null());

        let parts = [code.cast_const(), blend.cast_const()];
        let mut mix: *mut NbMaterial = std::ptr::null_mut();
        assert_eq!(unsafe { nb_material_open_mix(parts.as_ptr(), [1.0f32, 3.0].as_ptr(), 2, &mut mix) }, NbStatus::Ok);
        // The mixture outlives its parts and is 1/4 A + 3/4 the blend.
        let (wo, wi) = ([0.0f32, 0.6, 0.8], [0.3f32, -0.5, 0.812]);
        let f_of = |m: *const NbMaterial| {
            let mut f = [0f32; 3];
            assert_eq!(unsafe { nb_material_eval(m, 1, wo.as_ptr(), wi.as_ptr(), f.as_mut_ptr()) }, NbStatus::Ok);
            f
        };
        let (fa, fb) = (f_of(code), f_of(blend));
        unsafe { nb_material_free(code) };
        unsafe { nb_material_free(blend) };
        let f = f_of(mix);
        for c in 0..3 {
            let expected = 0.25 * fa[c] + 0.75 * fb[c];
            assert!((f[c] - expected).abs() <= 1e-5 * expected, "{f:?} vs {fa:?} {fb:?}");
        }
        let five = [mix.cast_const(); 5];
        let cases: [(&[*const NbMaterial], &[f32], &str); 6] = [
            (&five, &[1.0; 5], "1 to 4 parts, not 5"),
            (&five[..2], &[1.0, -1.0], "weight 1 is -1"),
            (&five[..2], &[f32::NAN, 1.0], "weight 0 is NaN"),
            (&five[..2], &[0.0, 0.0], "sum to 0"),
            (&[mix.cast_const(), std::ptr::null()], &[1.0, 1.0], "parts[1]: NULL"),
            (&five[..0], &[], "not 0"),
        ];
        for (parts, weights, message) in cases {
            let status = unsafe { nb_material_open_mix(parts.as_ptr(), weights.as_ptr(), parts.len(), &mut out) };
            assert_eq!(status, NbStatus::InvalidArgument, "{message}");
            assert!(last_error().contains(message), "{} lacks {message}", last_error());
            assert!(out.is_null());
        }
        assert_eq!(unsafe { nb_material_open_mix(std::ptr::null(), [1.0f32].as_ptr(), 1, &mut out) }, NbStatus::InvalidArgument);
        assert_eq!(unsafe { nb_material_open_mix(five.as_ptr(), std::ptr::null(), 1, &mut out) }, NbStatus::InvalidArgument);
        assert_eq!(unsafe { nb_material_open_mix(five.as_ptr(), [1.0f32].as_ptr(), 1, std::ptr::null_mut()) }, NbStatus::InvalidArgument);
        unsafe { nb_material_free(mix) };
    }

    #[test]
    fn null_arguments_are_errors() {
        let mut out: *mut NbMaterial = std::ptr::null_mut();
        assert_eq!(unsafe { nb_material_open(std::ptr::null(), std::ptr::null(), &mut out) }, NbStatus::InvalidArgument);
        assert!(out.is_null());
        let f = [0f32; 3];
        let status = unsafe { nb_material_eval(std::ptr::null(), 1, f.as_ptr(), f.as_ptr(), std::ptr::null_mut()) };
        assert_eq!(status, NbStatus::InvalidArgument);
        let message = unsafe { CStr::from_ptr(nb_last_error()) }.to_str().unwrap().to_string();
        assert!(message.contains("material") && message.contains("NULL"), "{message}");
    }
}
