//! One material's BSDF on its own, for other renderers (the C, Python and Mitsuba 3 plugins):
//! opened from a file, evaluated and sampled one direction pair at a time or batched over
//! slices.
//!
//! Directions are in the local shading frame of the whole crate ([`crate::bsdf`]): z is the
//! shading normal, `wo` points toward the viewer and `wi` toward the light, both unit vectors
//! pointing away from the surface. Values are f_r in 1/sr **without** the cosine factor,
//! densities are solid-angle densities in 1/sr; below either horizon both are zero.
//!
//! Only what the material needs is loaded: a MERL table or an NBRDF network alone; for a
//! latent code, the latent file is read once and only that code is decoded (with its fitted
//! importance sampler).
//!
//! Besides one material, two of the scene forms of spatially varying materials at one point:
//! - a latent **blend** at a given t ([`MaterialBsdf::open_blend`]): the exact decode of
//!   [`LatentCode::lerp`](crate::neural::latent_library::LatentCode::lerp)(A, B, t), as
//!   `render --sweep` decodes its frames (the renderer's `blend` form interpolates between a
//!   palette of such decodes; see [`super::PALETTE_SIZE`]);
//! - a **mixture** of 1 to [`MAX_MIX_PARTS`] materials with given weights
//!   ([`MaterialBsdf::mix`]), evaluated and sampled through [`Mixture`] exactly as the
//!   renderer's `mix` form does at a texel with those weights (weights normalised, zero
//!   weights dropped), so values and densities equal the renderer's bit for bit.
//!
//! ```no_run
//! use renderer::material::MaterialBsdf;
//! let bronze = MaterialBsdf::open("scenes/materials/latent.bin".as_ref(), Some("alum-bronze"))?;
//! let f = bronze.eval([0.0, 0.6, 0.8], [0.0, -0.6, 0.8]);
//! # Ok::<(), renderer::Error>(())
//! ```

use super::{Binding, SharedBsdf};
use crate::bsdf::mixture::Part;
use crate::bsdf::neural::NeuralBsdf;
use crate::bsdf::tabulated_sampling::{SamplerTables, TabulatedBrdf, TabulatedSampler};
use crate::bsdf::{BatchEval, Bsdf, BsdfSample, Bxdf, Mixture};
use crate::neural::latent_library::LatentLibrary;
use crate::scene::MAX_MIX_PARTS;
use crate::{Error, Result, Rgb};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::path::Path;
use std::sync::Arc;

/// Directions per parallel work item of the batched calls.
const BATCH_CHUNK: usize = 1024;

/// One material's BSDF (see the module documentation). `Send + Sync`: share it between
/// threads by reference.
#[derive(Debug)]
pub struct MaterialBsdf {
    inner: Inner,
}

/// One BSDF, or a mixture of BSDFs with their weights as given (validated: finite, ≥ 0,
/// some > 0); [`Mixture::new`] normalises them at each call, as the renderer does with a
/// texel's weights. Parts are shared, so a mixture outlives the materials it was made of.
#[derive(Debug)]
enum Inner {
    One(Arc<SharedBsdf>),
    Mix(Vec<(Arc<SharedBsdf>, f32)>),
}

/// One drawn direction: wi (unit, z > 0), f_r(wo, wi) in 1/sr and the solid-angle density.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub wi: [f32; 3],
    pub f: [f32; 3],
    pub pdf: f32,
}

impl From<BsdfSample> for Sample {
    fn from(s: BsdfSample) -> Self {
        Sample {
            wi: s.wi.to_array(),
            f: s.f.to_array(),
            pdf: s.pdf,
        }
    }
}

impl MaterialBsdf {
    /// Opens a material file: a MERL table (`.binary`), an NBRDF network (the prefix of its
    /// six `.npy` files, or one of them), or a latent file (`latent.bin`), whose code `name`
    /// is decoded. A latent file needs `name`; a table or network must not get one. Errors
    /// name the file or the unknown code (listing the available ones).
    pub fn open(path: &Path, name: Option<&str>) -> Result<Self> {
        let binding = super::binding::file_binding(path, name)?;
        let latents = match binding {
            Binding::Neural(_) => LatentLibrary::load(&[path])?,
            Binding::Merl(_) | Binding::Nbrdf(_) => LatentLibrary::default(),
        };
        Self::from_binding(&binding, &latents)
    }

    /// Opens a latent file and decodes the blend of its codes `a` and `b` at `t`: the frame
    /// of the editing sweep [`LatentLibrary::sweep`] from A to B at t (z and offsets
    /// interpolated, each end's residual faded out near its end, the offsets balanced to the
    /// blend of the ends' albedo), decoded exactly as `render --sweep` decodes its
    /// frames (t = 0 is A, t = 1 is B, bit for bit). `t` must be finite and in [0, 1]: an
    /// error otherwise (not clamped). Errors name the file, an unknown code (listing the
    /// available ones) or `t`.
    pub fn open_blend(path: &Path, a: &str, b: &str, t: f32) -> Result<Self> {
        if !(0.0..=1.0).contains(&t) {
            return Err(Error::InvalidArgument {
                flag: "t".to_string(),
                reason: format!("{t} is not in [0, 1] (blend {a} → {b} of {})", path.display()),
            });
        }
        let latents = LatentLibrary::load(&[path])?;
        let code = latents.sweep(&latents.latent(a)?, &latents.latent(b)?)?.code(t)?;
        let label = format!("{a}>{b}@{t:.3}");
        Ok(MaterialBsdf {
            inner: Inner::One(Arc::new(SharedBsdf::Neural(latents.decode_code(&code, &label)?))),
        })
    }

    /// The renderer's palette of the blend of `a` and `b` (its glTF `blend` form): the
    /// [`PALETTE_SIZE`](super::PALETTE_SIZE) decodes at t = k / (PALETTE_SIZE − 1), t computed
    /// in f32 as the renderer does, from one read of the file. A blend at t mixes entries k
    /// and k + 1 around it, weighted (1 − a, a) by where t falls between them. Errors as
    /// [`MaterialBsdf::open_blend`].
    pub fn open_blend_palette(path: &Path, a: &str, b: &str) -> Result<Vec<Self>> {
        let latents = LatentLibrary::load(&[path])?;
        let sweep = latents.sweep(&latents.latent(a)?, &latents.latent(b)?)?;
        (0..super::PALETTE_SIZE)
            .map(|k| {
                let t = k as f32 / (super::PALETTE_SIZE - 1) as f32;
                let bsdf = latents.decode_code(&sweep.code(t)?, &format!("{a}>{b}@{t:.3}"))?;
                Ok(MaterialBsdf { inner: Inner::One(Arc::new(SharedBsdf::Neural(bsdf))) })
            })
            .collect()
    }

    /// The mixture f = Σ w_k f_k, pdf = Σ w_k pdf_k of `parts` (material, weight), 1 to
    /// [`MAX_MIX_PARTS`] of them, with the weights normalised to sum 1 and parts of weight 0
    /// dropped, sampled by choosing a part by weight ([`Mixture`]): what the renderer's `mix`
    /// form gives at a texel of these weights, bit for bit. A part may itself be a mixture
    /// (its parts then join this one's, weighted by its weight, when there are at most
    /// [`MAX_MIX_PARTS`] in all). The parts' data are shared, not copied: the materials
    /// may be dropped afterwards. Errors (naming the argument) on no or too many parts and
    /// on a weight that is negative or not finite, or weights that are all 0.
    pub fn mix(parts: &[(&MaterialBsdf, f32)]) -> Result<Self> {
        let invalid = |flag: &str, reason: String| Error::InvalidArgument { flag: flag.to_string(), reason };
        if parts.is_empty() || parts.len() > MAX_MIX_PARTS {
            return Err(invalid("parts", format!("a mixture has 1 to {MAX_MIX_PARTS} parts, not {}", parts.len())));
        }
        if let Some(k) = parts.iter().position(|&(_, w)| !(w.is_finite() && w >= 0.0)) {
            return Err(invalid("weights", format!("weight {k} is {}, not a finite number ≥ 0", parts[k].1)));
        }
        let total: f32 = parts.iter().map(|&(_, w)| w).sum();
        if !(total > 0.0 && total.is_finite()) {
            return Err(invalid("weights", format!("the weights sum to {total}, not a finite number > 0")));
        }
        let mut flat = Vec::with_capacity(MAX_MIX_PARTS);
        for &(m, w) in parts {
            match &m.inner {
                Inner::One(b) => flat.push((Arc::clone(b), w)),
                Inner::Mix(inner) => {
                    let sum: f32 = inner.iter().map(|&(_, v)| v).sum();
                    flat.extend(inner.iter().filter(|&&(_, v)| v > 0.0).map(|(b, v)| (Arc::clone(b), w * (v / sum))));
                }
            }
        }
        if flat.len() > MAX_MIX_PARTS {
            return Err(invalid("parts", format!("the parts' mixtures hold {} materials in all, more than {MAX_MIX_PARTS}", flat.len())));
        }
        Ok(MaterialBsdf { inner: Inner::Mix(flat) })
    }


    /// Opens a latent file and decodes the latent vector `v` (any code, e.g. an edited one)
    /// with its decoder; `label` names it. `v` is z, optionally followed by the code's 3
    /// output offsets and then by its residual
    /// ([`crate::neural::latent_library::LatentCode::from_vector`]). Errors
    /// name the file when `v` has the wrong size or a non-finite value.
    pub fn open_latent_vector(path: &Path, v: &[f32], label: &str) -> Result<Self> {
        let latents = LatentLibrary::load(&[path])?;
        let code = latents.code_from_vector(0, v)?;
        Ok(MaterialBsdf {
            inner: Inner::One(Arc::new(SharedBsdf::Neural(latents.decode_code(&code, label)?))),
        })
    }

    /// Opens the BSDF a [`Binding`] names (latent codes from `latents`).
    pub fn from_binding(binding: &Binding, latents: &LatentLibrary) -> Result<Self> {
        Ok(MaterialBsdf {
            inner: Inner::One(Arc::new(SharedBsdf::open(binding, latents)?)),
        })
    }

    /// The BSDF as the renderer holds it; `None` for a mixture ([`MaterialBsdf::parts`]).
    pub fn shared(&self) -> Option<&SharedBsdf> {
        match &self.inner {
            Inner::One(b) => Some(&**b),
            Inner::Mix(_) => None,
        }
    }

    /// A mixture's parts with their weights as given (normalised when used); `None` for a
    /// single material.
    pub fn parts(&self) -> Option<impl Iterator<Item = (&SharedBsdf, f32)> + '_> {
        match &self.inner {
            Inner::One(_) => None,
            Inner::Mix(parts) => Some(parts.iter().map(|(b, w)| (&**b, *w))),
        }
    }

    /// For a latent code (a blend included): its decoded target net, f_ref and mapping (what
    /// another renderer needs to evaluate it itself); `None` for a table, a network or a
    /// mixture.
    pub fn neural(&self) -> Option<&NeuralBsdf> {
        match self.shared()? {
            SharedBsdf::Neural(b) => Some(b),
            _ => None,
        }
    }

    /// The importance sampler's fitted tables (every single material has one); `None` for a
    /// mixture (each part has its own).
    pub fn sampler_tables(&self) -> Option<SamplerTables> {
        self.shared().map(|b| sampler_of(b).tables())
    }

    /// The BSDF to shade with: the single one, or the [`Mixture`] of the parts (made here,
    /// as the renderer makes it per shading point).
    #[inline]
    fn bsdf(&self) -> Bsdf<'_> {
        match &self.inner {
            Inner::One(b) => b.as_bsdf(),
            Inner::Mix(parts) => Bsdf::Mixture(self.mixture(parts)),
        }
    }

    #[inline]
    fn mixture<'a>(&self, parts: &'a [(Arc<SharedBsdf>, f32)]) -> Mixture<'a> {
        let all: [(Part<'a>, f32); MAX_MIX_PARTS] = std::array::from_fn(|k| {
            let (b, w) = &parts[k.min(parts.len() - 1)];
            (b.as_part(), *w)
        });
        Mixture::new(&all[..parts.len()], Rgb::ONE)
    }

    /// f_r(wo, wi) in 1/sr per RGB channel.
    #[inline]
    pub fn eval(&self, wo: [f32; 3], wi: [f32; 3]) -> [f32; 3] {
        self.bsdf().eval(direction(wo), direction(wi)).to_array()
    }

    /// The density (1/sr) with which [`MaterialBsdf::sample`] draws `wi` given `wo`.
    #[inline]
    pub fn pdf(&self, wo: [f32; 3], wi: [f32; 3]) -> f32 {
        self.bsdf().pdf(direction(wo), direction(wi))
    }

    /// Value and density together.
    #[inline]
    pub fn eval_pdf(&self, wo: [f32; 3], wi: [f32; 3]) -> ([f32; 3], f32) {
        let (f, pdf) = self.bsdf().eval_pdf(direction(wo), direction(wi));
        (f.to_array(), pdf)
    }

    /// Draws wi given `wo` from three uniform numbers in [0, 1) (`u[0..2]` for the direction,
    /// `u[2]` to choose a lobe, and for a mixture first its part); `None` when nothing can be
    /// drawn (e.g. `wo` below the horizon). The density of the result is exactly
    /// [`MaterialBsdf::pdf`].
    #[inline]
    pub fn sample(&self, wo: [f32; 3], u: [f32; 3]) -> Option<Sample> {
        self.bsdf().sample(direction(wo), Vec2::new(u[0], u[1]), u[2]).map(Sample::from)
    }

    /// As [`MaterialBsdf::sample`] from two uniform numbers: `u[0]` also chooses the lobe
    /// (and for a mixture first the part, as [`Mixture`] chooses it; what is left of it after
    /// each choice is reused). Same density.
    pub fn sample_2d(&self, wo: [f32; 3], u: [f32; 2]) -> Option<Sample> {
        let wo = direction(wo);
        let wi = match &self.inner {
            Inner::One(b) => sampler_of(b).sample_2d(wo, Vec2::from(u))?,
            Inner::Mix(parts) => {
                let (sampler, u0) = choose(&self.mixture(parts), u[0]);
                sampler.sample_2d(wo, Vec2::new(u0, u[1]))?
            }
        };
        let (f, pdf) = self.bsdf().eval_pdf(wo, wi);
        (pdf > 0.0 && pdf.is_finite()).then(|| Sample { wi: wi.to_array(), f: f.to_array(), pdf })
    }

    /// f_r(wo, wi) of many pairs into `out`: a decoded net's values in one batched forward
    /// pass, a table's look-ups prefetched together ([`BatchEval`]), an NBRDF network's and a
    /// mixture's one by one. The same values as [`MaterialBsdf::eval`], bit for bit.
    fn values(&self, pairs: &[(Vec3, Vec3)], out: &mut [Rgb]) {
        match &self.inner {
            Inner::One(b) => match &**b {
                SharedBsdf::Neural(b) => values_together(b, pairs, out),
                SharedBsdf::Merl(b) => values_together(b, pairs, out),
                SharedBsdf::Nbrdf(b) => {
                    for (o, &(wo, wi)) in out.iter_mut().zip(pairs) {
                        *o = b.eval(wo, wi);
                    }
                }
            },
            Inner::Mix(parts) => {
                let mixture = self.mixture(parts);
                for (o, &(wo, wi)) in out.iter_mut().zip(pairs) {
                    *o = mixture.eval(wo, wi);
                }
            }
        }
    }

    /// The density of one pair, as [`MaterialBsdf::pdf`].
    #[inline]
    fn density(&self, wo: Vec3, wi: Vec3) -> f32 {
        match &self.inner {
            Inner::One(b) => sampler_of(b).pdf(wo, wi),
            Inner::Mix(_) => self.bsdf().pdf(wo, wi),
        }
    }

    /// [`MaterialBsdf::eval`] for every pair (`wo[i]`, `wi[i]`) into `f[i]`, in parallel.
    /// Errors (naming the argument and index) on different lengths or a non-finite direction.
    pub fn eval_batch(&self, wo: &[[f32; 3]], wi: &[[f32; 3]], f: &mut [[f32; 3]]) -> Result<()> {
        self.eval_pdf_chunks(wo, wi, f, None)
    }

    /// [`MaterialBsdf::pdf`] for every pair into `pdf[i]`, in parallel; errors as
    /// [`MaterialBsdf::eval_batch`].
    pub fn pdf_batch(&self, wo: &[[f32; 3]], wi: &[[f32; 3]], pdf: &mut [f32]) -> Result<()> {
        check_batch(wo, "wo", pdf.len())?;
        check_batch(wi, "wi", pdf.len())?;
        batch(pdf, |i| self.pdf(wo[i], wi[i]));
        Ok(())
    }

    /// [`MaterialBsdf::eval_pdf`] for every pair into `f[i]` and `pdf[i]`, in parallel, one
    /// evaluation per pair; errors as [`MaterialBsdf::eval_batch`] (also when `pdf` and `f`
    /// differ in length).
    pub fn eval_pdf_batch(&self, wo: &[[f32; 3]], wi: &[[f32; 3]], f: &mut [[f32; 3]], pdf: &mut [f32]) -> Result<()> {
        if pdf.len() != f.len() {
            return Err(batch_error("pdf", format!("{} entries for {} outputs", pdf.len(), f.len())));
        }
        self.eval_pdf_chunks(wo, wi, f, Some(pdf))
    }

    /// Values (and densities) of every pair, in parallel chunks of [`BATCH_CHUNK`].
    fn eval_pdf_chunks(&self, wo: &[[f32; 3]], wi: &[[f32; 3]], f: &mut [[f32; 3]], pdf: Option<&mut [f32]>) -> Result<()> {
        check_batch(wo, "wo", f.len())?;
        check_batch(wi, "wi", f.len())?;
        let mut pdf_chunks: Vec<Option<&mut [f32]>> = match pdf {
            Some(pdf) => pdf.chunks_mut(BATCH_CHUNK).map(Some).collect(),
            None => f.chunks(BATCH_CHUNK).map(|_| None).collect(),
        };
        f.par_chunks_mut(BATCH_CHUNK).zip(pdf_chunks.par_iter_mut()).enumerate().for_each(|(c, (fc, pc))| {
            let first = c * BATCH_CHUNK;
            let pairs: Vec<(Vec3, Vec3)> =
                (first..first + fc.len()).map(|i| (direction(wo[i]), direction(wi[i]))).collect();
            let mut values = vec![Rgb::ZERO; pairs.len()];
            self.values(&pairs, &mut values);
            for (o, v) in fc.iter_mut().zip(&values) {
                *o = v.to_array();
            }
            if let Some(pc) = pc {
                for (o, &(wo, wi)) in pc.iter_mut().zip(&pairs) {
                    *o = self.density(wo, wi);
                }
            }
        });
        Ok(())
    }

    /// [`MaterialBsdf::sample`] (three numbers per direction) or [`MaterialBsdf::sample_2d`]
    /// (two) for every `wo[i]` with the numbers `u[i]`, in parallel; a draw that fails gives
    /// `None`. Errors on different lengths, a non-finite `wo` or a `u` outside [0, 1]. The
    /// directions of a chunk are drawn first, then their values evaluated together.
    pub fn sample_batch<U: UniformNumbers>(&self, wo: &[[f32; 3]], u: &[U], out: &mut [Option<Sample>]) -> Result<()> {
        check_batch(wo, "wo", out.len())?;
        if u.len() != out.len() {
            return Err(batch_error("u", format!("{} entries for {} directions", u.len(), out.len())));
        }
        if let Some(i) = u.iter().position(|v| !v.numbers().iter().all(|x| (0.0..=1.0).contains(x))) {
            return Err(batch_error("u", format!("entry {i} is {:?}, not in [0, 1]", u[i].numbers())));
        }
        let sampler = match &self.inner {
            Inner::One(b) => sampler_of(b),
            Inner::Mix(_) => {
                // One by one: each draw chooses its part first.
                batch(out, |i| u[i].draw(self, wo[i]));
                return Ok(());
            }
        };
        out.par_chunks_mut(BATCH_CHUNK).enumerate().for_each(|(c, chunk)| {
            let first = c * BATCH_CHUNK;
            let wos: Vec<Vec3> = (first..first + chunk.len()).map(|i| direction(wo[i])).collect();
            let drawn: Vec<Option<(Vec3, f32)>> = (first..first + chunk.len()).zip(&wos).map(|(i, &wo)| u[i].direction(sampler, wo)).collect();
            let pairs: Vec<(Vec3, Vec3)> = wos.iter().zip(&drawn).filter_map(|(&wo, d)| d.map(|(wi, _)| (wo, wi))).collect();
            let mut values = vec![Rgb::ZERO; pairs.len()];
            self.values(&pairs, &mut values);
            let mut values = values.into_iter();
            for (o, d) in chunk.iter_mut().zip(drawn) {
                *o = d.map(|(wi, pdf)| Sample {
                    wi: wi.to_array(),
                    f: values.next().expect("one value per drawn direction").to_array(),
                    pdf,
                });
            }
        });
        Ok(())
    }
}

/// The importance sampler of a single BSDF.
fn sampler_of(b: &SharedBsdf) -> &TabulatedSampler {
    match b {
        SharedBsdf::Merl(b) => b.sampler(),
        SharedBsdf::Nbrdf(b) => b.sampler(),
        SharedBsdf::Neural(b) => b.sampler(),
    }
}

/// The part of `mixture` a uniform number `u` chooses, as [`Mixture`]'s sampling chooses it
/// (by the cumulative weights), and `u` rescaled within the part's share.
fn choose<'a>(mixture: &Mixture<'a>, u: f32) -> (&'a TabulatedSampler, f32) {
    let parts: Vec<(Part<'a>, f32)> = mixture.parts().collect();
    let mut chosen = parts.len() - 1;
    let mut below = 0.0;
    for (k, &(_, w)) in parts.iter().enumerate().take(parts.len() - 1) {
        if u < below + w {
            chosen = k;
            break;
        }
        below += w;
    }
    let rest = ((u - below) / parts[chosen].1).clamp(0.0, 1.0 - f32::EPSILON / 2.0);
    let sampler = match parts[chosen].0 {
        Part::Merl(b) => b.sampler(),
        Part::Nbrdf(b) => b.sampler(),
        Part::Neural(b) => b.sampler(),
    };
    (sampler, rest)
}

/// [`BatchEval`]: every pair prepared, the prepared ones evaluated in one call; pairs it
/// leaves out (below either horizon) are zero.
fn values_together<B: BatchEval>(bsdf: &B, pairs: &[(Vec3, Vec3)], out: &mut [Rgb]) {
    let mut points = Vec::with_capacity(pairs.len());
    let mut slots = Vec::with_capacity(pairs.len());
    for (k, &(wo, wi)) in pairs.iter().enumerate() {
        out[k] = Rgb::ZERO;
        if let Some(p) = bsdf.prepare(wo, wi) {
            points.push(p);
            slots.push(k);
        }
    }
    let mut values = vec![Rgb::ZERO; points.len()];
    bsdf.eval_prepared(&points, &mut values);
    for (&k, v) in slots.iter().zip(values) {
        out[k] = v;
    }
}

/// The uniform numbers of one draw: `[f32; 3]` ([`MaterialBsdf::sample`]) or `[f32; 2]`
/// ([`MaterialBsdf::sample_2d`]).
pub trait UniformNumbers: Copy + Sync {
    /// The numbers, each in [0, 1].
    fn numbers(&self) -> &[f32];
    /// The direction and density the draw with these numbers gives from `sampler` (the
    /// material's) given `wo`, before its value: `None` where the draw fails or its density
    /// is not positive and finite.
    fn direction(self, sampler: &TabulatedSampler, wo: Vec3) -> Option<(Vec3, f32)>;
    /// The whole draw from `m` given `wo` with these numbers: [`MaterialBsdf::sample`] or
    /// [`MaterialBsdf::sample_2d`].
    fn draw(self, m: &MaterialBsdf, wo: [f32; 3]) -> Option<Sample>;
}

impl UniformNumbers for [f32; 3] {
    fn numbers(&self) -> &[f32] {
        self
    }
    fn direction(self, sampler: &TabulatedSampler, wo: Vec3) -> Option<(Vec3, f32)> {
        sampler.sample_with_pdf(wo, Vec2::new(self[0], self[1]), self[2])
    }
    fn draw(self, m: &MaterialBsdf, wo: [f32; 3]) -> Option<Sample> {
        m.sample(wo, self)
    }
}

impl UniformNumbers for [f32; 2] {
    fn numbers(&self) -> &[f32] {
        self
    }
    fn direction(self, sampler: &TabulatedSampler, wo: Vec3) -> Option<(Vec3, f32)> {
        let wi = sampler.sample_2d(wo, Vec2::from(self))?;
        let pdf = sampler.pdf(wo, wi);
        (pdf > 0.0 && pdf.is_finite()).then_some((wi, pdf))
    }
    fn draw(self, m: &MaterialBsdf, wo: [f32; 3]) -> Option<Sample> {
        m.sample_2d(wo, self)
    }
}

fn batch_error(what: &str, reason: String) -> Error {
    Error::InvalidArgument {
        flag: what.to_string(),
        reason,
    }
}

/// A direction as the BSDFs take it: unit length. Callers may pass any finite length: a
/// vector unit to within 10⁻⁴ in its squared length is used as given (bit for bit what the
/// renderer evaluates), any other is scaled by its largest component first and then
/// normalised, so that tiny (subnormal) or huge vectors keep their direction; the zero vector
/// stays zero (below every horizon: value and density 0).
#[inline]
fn direction(v: [f32; 3]) -> Vec3 {
    let v = Vec3::from(v);
    if (v.length_squared() - 1.0).abs() <= 1e-4 {
        return v;
    }
    let largest = v.abs().max_element();
    if largest > 0.0 && largest.is_finite() {
        (v / largest).normalize()
    } else {
        v
    }
}

/// Checks that `dirs` has `n` entries, all finite.
fn check_batch(dirs: &[[f32; 3]], what: &str, n: usize) -> Result<()> {
    if dirs.len() != n {
        return Err(batch_error(what, format!("{} entries for {n} outputs", dirs.len())));
    }
    match dirs.iter().position(|d| !d.iter().all(|x| x.is_finite())) {
        Some(i) => Err(batch_error(what, format!("entry {i} is {:?}, not finite", dirs[i]))),
        None => Ok(()),
    }
}

/// Fills `out[i] = value(i)` in parallel chunks.
fn batch<T: Send>(out: &mut [T], value: impl Fn(usize) -> T + Sync) {
    out.par_chunks_mut(BATCH_CHUNK).enumerate().for_each(|(c, chunk)| {
        for (k, o) in chunk.iter_mut().enumerate() {
            *o = value(c * BATCH_CHUNK + k);
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::data::data_dir;

    fn shipped() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/materials/latent.bin")
    }

    fn unit(theta: f32, phi: f32) -> [f32; 3] {
        [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()]
    }

    #[test]
    fn opens_each_kind_and_agrees_with_the_renderers_bsdf() {
        fn assert_send_sync<T: Send + Sync>() {}
        assert_send_sync::<MaterialBsdf>();
        let neural = MaterialBsdf::open(&shipped(), Some("alum-bronze")).unwrap();
        let latents = LatentLibrary::load(&[shipped()]).unwrap();
        let reference = latents.decode("alum-bronze").unwrap();
        let (wo, wi) = (unit(0.5, 0.2), unit(0.7, 2.5));
        assert_eq!(neural.eval(wo, wi), reference.eval(Vec3::from(wo), Vec3::from(wi)).to_array());
        assert_eq!(neural.pdf(wo, wi), reference.pdf(Vec3::from(wo), Vec3::from(wi)));
        let network = MaterialBsdf::open(&data_dir().join("merl/chrome"), None).unwrap();
        assert!(matches!(network.shared(), Some(SharedBsdf::Nbrdf(_))));
        let v = latents.latent_vector("alum-bronze").unwrap();
        let same = MaterialBsdf::open_latent_vector(&shipped(), &v, "copy").unwrap();
        assert_eq!(same.eval(wo, wi), neural.eval(wo, wi));
    }

    #[test]
    fn a_code_exposes_its_net_reference_and_sampler_tables() {
        let m = MaterialBsdf::open(&shipped(), Some("alum-bronze")).unwrap();
        let neural = m.neural().expect("a latent code");
        let widths: Vec<usize> = neural.decoded().layers.iter().map(|l| l.d_out).collect();
        assert_eq!(widths.last(), Some(&3));
        assert_eq!(neural.reference().len(), crate::formats::merl::BIN_COUNT);
        // The plain layers give the packed net's output.
        let x = crate::brdf_coords::network_input(Vec3::new(0.3, 0.1, 0.95).normalize(), Vec3::new(-0.2, 0.4, 0.89).normalize());
        let plain = neural.decoded().forward(&x);
        let packed = neural.net().forward(x);
        for c in 0..3 {
            assert!((plain[c] - packed[c]).abs() <= 1e-4 * (1.0 + plain[c].abs()), "{plain:?} vs {packed:?}");
        }
        let t = m.sampler_tables().unwrap();
        assert_eq!(t.values.len(), t.theta_o.len());
        assert!(t.values.iter().all(|v| v.len() == t.row_v.len() * (t.columns + 1)));
        assert!(t.values.iter().all(|v| v.iter().all(|x| x.is_finite() && *x >= 0.0) && v.contains(&1.0)));
        let table = MaterialBsdf::open(&data_dir().join("merl/chrome"), None).unwrap();
        assert!(table.neural().is_none());
        assert_eq!(table.sampler_tables().unwrap().row_v, t.row_v);
    }

    /// The batched calls give every pair exactly what the single calls give — their values
    /// evaluated together (a net's batched forward pass, a table's prefetched look-ups) —
    /// for a decoded code, a MERL table and an NBRDF network, with three and two numbers
    /// per draw; and drawn samples carry their density and value.
    #[test]
    fn batches_match_single_calls_and_samples_carry_their_density() {
        let dir = tempfile::tempdir().unwrap();
        let table = dir.path().join("alum-bronze.binary");
        crate::testing::bsdfs::merl_fitted_table("alum-bronze").write(&table).unwrap();
        let materials = [
            MaterialBsdf::open(&shipped(), Some("chrome")).unwrap(),
            MaterialBsdf::open(&table, None).unwrap(),
            MaterialBsdf::open(&data_dir().join("merl/alum-bronze"), None).unwrap(),
        ];
        assert!(matches!(materials[1].shared(), Some(SharedBsdf::Merl(_))));
        assert!(matches!(materials[2].shared(), Some(SharedBsdf::Nbrdf(_))));
        let [code, table, network] = materials;
        let mixture = MaterialBsdf::mix(&[(&code, 0.5), (&table, 0.3), (&network, 0.2)]).unwrap();
        let materials = [code, table, network, mixture];
        // More than one chunk, the last one partial; some directions below the horizon.
        let n = BATCH_CHUNK * 2 + 333;
        let wo: Vec<[f32; 3]> = (0..n).map(|i| unit(1.4 * (i as f32 / n as f32), i as f32 * 0.37)).collect();
        let wi: Vec<[f32; 3]> = (0..n).map(|i| unit(1.7 * ((i * 7 % n) as f32 / n as f32), i as f32 * 1.1)).collect();
        let u: Vec<[f32; 3]> = (0..n).map(|i| [(i as f32 * 0.618).fract(), (i as f32 * 0.414).fract(), (i as f32 * 0.732).fract()]).collect();
        let u2: Vec<[f32; 2]> = u.iter().map(|v| [v[0], v[1]]).collect();
        for (m, kind) in materials.iter().zip(["code", "table", "network", "mixture"]) {
            let mut f = vec![[0.0; 3]; n];
            let mut pdf = vec![0.0; n];
            let (mut f_joint, mut pdf_joint) = (vec![[0.0; 3]; n], vec![0.0; n]);
            let (mut samples, mut samples_2d) = (vec![None; n], vec![None; n]);
            m.eval_batch(&wo, &wi, &mut f).unwrap();
            m.pdf_batch(&wo, &wi, &mut pdf).unwrap();
            m.eval_pdf_batch(&wo, &wi, &mut f_joint, &mut pdf_joint).unwrap();
            m.sample_batch(&wo, &u, &mut samples).unwrap();
            m.sample_batch(&wo, &u2, &mut samples_2d).unwrap();
            assert_eq!((&f_joint, &pdf_joint), (&f, &pdf));
            for i in 0..n {
                assert_eq!(f[i], m.eval(wo[i], wi[i]), "{kind}: pair {i}");
                assert_eq!(pdf[i], m.pdf(wo[i], wi[i]));
                assert_eq!(samples[i], m.sample(wo[i], u[i]), "{kind}: draw {i}");
                assert_eq!(samples_2d[i], m.sample_2d(wo[i], u2[i]), "{kind}: two-number draw {i}");
            }
            assert!(f.iter().any(|v| v[0] > 0.0) && f.contains(&[0.0; 3]), "{kind}: lit and unlit pairs");
            let drawn: Vec<(usize, Sample)> = samples.iter().enumerate().filter_map(|(i, s)| Some((i, (*s)?))).collect();
            assert!(drawn.len() > n / 2);
            for &(i, s) in drawn.iter().step_by(53) {
                assert!((m.pdf(wo[i], s.wi) - s.pdf).abs() <= 1e-4 * s.pdf, "{s:?}");
                let f = m.eval(wo[i], s.wi);
                if kind == "mixture" {
                    // The drawn part's value first, then the others: the same sum in another order.
                    assert!((0..3).all(|c| (f[c] - s.f[c]).abs() <= 1e-5 * f[c]), "{f:?} vs {s:?}");
                } else {
                    assert_eq!(f, s.f);
                }
            }
        }
    }

    /// Drawing from two numbers (the lobe chosen by the first, its rest reused) has the
    /// density [`MaterialBsdf::pdf`], for a peaked code and a broad network.
    #[test]
    fn two_number_draws_pass_chi2() {
        /// The material with `sample` drawing from (u.x, u.y) alone.
        struct TwoNumbers<'a>(&'a MaterialBsdf);
        impl Bxdf for TwoNumbers<'_> {
            fn eval(&self, wo: Vec3, wi: Vec3) -> crate::Rgb {
                self.0.eval(wo.to_array(), wi.to_array()).into()
            }
            fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
                self.0.pdf(wo.to_array(), wi.to_array())
            }
            fn sample(&self, wo: Vec3, u: Vec2, _uc: f32) -> Option<BsdfSample> {
                let s = self.0.sample_2d(wo.to_array(), u.to_array())?;
                Some(BsdfSample::new(s.wi.into(), s.f.into(), s.pdf))
            }
        }
        let chrome = MaterialBsdf::open(&shipped(), Some("chrome")).unwrap();
        let paint = MaterialBsdf::open(&data_dir().join("merl/gold-metallic-paint3"), None).unwrap();
        let mixture = MaterialBsdf::mix(&[(&chrome, 0.4), (&paint, 0.6)]).unwrap();
        for (name, m) in [("chrome", &chrome), ("gold-metallic-paint3", &paint), ("mixture", &mixture)] {
            for theta in [0.3f32, 1.2] {
                crate::testing::bsdfs::check_chi2(&TwoNumbers(m), name, theta);
            }
        }
    }

    /// A blend at t is the exact decode of the latent interpolation at t (as `render --sweep`
    /// decodes it): its ends are the two codes bit for bit.
    #[test]
    fn blends_decode_the_interpolated_code() {
        let latents = LatentLibrary::load(&[shipped()]).unwrap();
        let (a, b) = ("alum-bronze", "chrome");
        let (wo, wi) = (unit(0.5, 0.2), unit(0.6, 2.9));
        let at = |t: f32| MaterialBsdf::open_blend(&shipped(), a, b, t).unwrap();
        assert_eq!(at(0.0).eval(wo, wi), MaterialBsdf::open(&shipped(), Some(a)).unwrap().eval(wo, wi));
        assert_eq!(at(1.0).eval(wo, wi), MaterialBsdf::open(&shipped(), Some(b)).unwrap().eval(wo, wi));
        let t = 0.37;
        let exact = latents.decode_code(&latents.sweep(&latents.latent(a).unwrap(), &latents.latent(b).unwrap()).unwrap().code(t).unwrap(), "sweep").unwrap();
        let blend = at(t);
        assert!(blend.neural().is_some() && blend.sampler_tables().is_some());
        assert_eq!(blend.eval(wo, wi), exact.eval(Vec3::from(wo), Vec3::from(wi)).to_array());
        assert_eq!(blend.pdf(wo, wi), exact.pdf(Vec3::from(wo), Vec3::from(wi)));
        assert_ne!(blend.eval(wo, wi), at(0.0).eval(wo, wi));
        let palette = MaterialBsdf::open_blend_palette(&shipped(), a, b).unwrap();
        assert_eq!(palette.len(), super::super::PALETTE_SIZE);
        let k = 9;
        let t = k as f32 / (super::super::PALETTE_SIZE - 1) as f32;
        assert_eq!(palette[k].eval(wo, wi), at(t).eval(wo, wi), "entry {k} is the blend at {t}");
    }

    /// A mixture evaluates, weighs and samples exactly as the renderer's [`Mixture`] of the
    /// same parts and (unnormalised) weights, as at a texel of those weights; zero weights
    /// drop parts; a mixture part joins its parts.
    #[test]
    fn mixtures_are_the_renderers_mixture_bit_for_bit() {
        let a = MaterialBsdf::open(&shipped(), Some("alum-bronze")).unwrap();
        let b = MaterialBsdf::open(&shipped(), Some("chrome")).unwrap();
        let c = MaterialBsdf::open(&data_dir().join("merl/gold-metallic-paint3"), None).unwrap();
        let weights = [0.7f32, 0.2, 0.4];
        let m = MaterialBsdf::mix(&[(&a, weights[0]), (&b, weights[1]), (&c, weights[2])]).unwrap();
        assert!(m.shared().is_none() && m.neural().is_none() && m.sampler_tables().is_none());
        assert_eq!(m.parts().unwrap().map(|(_, w)| w).collect::<Vec<_>>(), weights);
        let parts = [a.shared().unwrap().as_part(), b.shared().unwrap().as_part(), c.shared().unwrap().as_part()];
        let reference = Mixture::new(&[(parts[0], weights[0]), (parts[1], weights[1]), (parts[2], weights[2])], Rgb::ONE);
        for k in 0..20 {
            let (wo, wi) = (unit(0.07 * k as f32, 0.3 * k as f32), unit(1.5 - 0.07 * k as f32, 2.0 + 0.5 * k as f32));
            let (vo, vi) = (Vec3::from(wo), Vec3::from(wi));
            assert_eq!(m.eval(wo, wi), reference.eval(vo, vi).to_array());
            assert_eq!(m.pdf(wo, wi), reference.pdf(vo, vi));
            assert_eq!(m.eval_pdf(wo, wi), (reference.eval_pdf(vo, vi).0.to_array(), reference.eval_pdf(vo, vi).1));
            let u = [(k as f32 * 0.618).fract(), (k as f32 * 0.414).fract(), (k as f32 * 0.05).fract()];
            assert_eq!(m.sample(wo, u), reference.sample(vo, Vec2::new(u[0], u[1]), u[2]).map(Sample::from));
        }
        let (wo, wi) = (unit(0.4, 0.0), unit(0.7, 2.0));
        let only_b = MaterialBsdf::mix(&[(&a, 0.0), (&b, 2.0)]).unwrap();
        assert_eq!(only_b.eval(wo, wi), b.eval(wo, wi), "a zero weight drops its part");
        assert_eq!(only_b.pdf(wo, wi), b.pdf(wo, wi));
        // Nested: (a, b) 1:1, then with c 1:1 → a 0.25, b 0.25, c 0.5.
        let ab = MaterialBsdf::mix(&[(&a, 1.0), (&b, 1.0)]).unwrap();
        let nested = MaterialBsdf::mix(&[(&ab, 2.0), (&c, 2.0)]).unwrap();
        assert_eq!(nested.parts().unwrap().map(|(_, w)| w).collect::<Vec<_>>(), [1.0, 1.0, 2.0]);
        let flat = MaterialBsdf::mix(&[(&a, 0.25), (&b, 0.25), (&c, 0.5)]).unwrap();
        assert_eq!(nested.eval(wo, wi), flat.eval(wo, wi));
        // The mixture keeps its parts alive.
        drop((a, b, c, ab));
        assert_eq!(nested.eval(wo, wi), flat.eval(wo, wi));
    }

    #[test]
    fn bad_blends_and_mixtures_are_clear_errors() {
        for t in [f32::NAN, -0.1, 1.5, f32::INFINITY] {
            let e = MaterialBsdf::open_blend(&shipped(), "alum-bronze", "chrome", t).unwrap_err();
            let msg = e.to_string();
            assert!(matches!(e, Error::InvalidArgument { .. }) && msg.contains("t:") && msg.contains("latent.bin"), "{msg}");
        }
        let e = MaterialBsdf::open_blend(&shipped(), "alum-bronze", "no-such", 0.5).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, Error::UnknownName { .. }) && msg.contains("no-such") && msg.contains("chrome"), "{msg}");
        let e = MaterialBsdf::open_blend(Path::new("/nonexistent/latent.bin"), "a", "b", 0.5).unwrap_err().to_string();
        assert!(e.contains("/nonexistent/latent.bin"), "{e}");
        let a = MaterialBsdf::open(&shipped(), Some("chrome")).unwrap();
        let msg = |parts: &[(&MaterialBsdf, f32)]| MaterialBsdf::mix(parts).unwrap_err().to_string();
        assert!(msg(&[]).contains("1 to 4 parts, not 0"), "{}", msg(&[]));
        assert!(msg(&[(&a, 1.0); 5]).contains("1 to 4 parts, not 5"));
        assert!(msg(&[(&a, 1.0), (&a, -1.0)]).contains("weight 1 is -1"));
        assert!(msg(&[(&a, f32::NAN), (&a, 1.0)]).contains("weight 0 is NaN"));
        assert!(msg(&[(&a, 1.0), (&a, f32::INFINITY)]).contains("weight 1 is inf"));
        assert!(msg(&[(&a, 0.0), (&a, 0.0)]).contains("sum to 0"));
        let three = MaterialBsdf::mix(&[(&a, 1.0); 3]).unwrap();
        assert!(msg(&[(&three, 1.0), (&three, 1.0)]).contains("6 materials in all"));
    }

    #[test]
    fn bad_input_is_a_clear_error() {
        let e = MaterialBsdf::open(Path::new("/nonexistent/latent.bin"), Some("gold")).unwrap_err().to_string();
        assert!(e.contains("/nonexistent/latent.bin"), "{e}");
        let e = MaterialBsdf::open(&shipped(), Some("no-such")).unwrap_err().to_string();
        assert!(e.contains("no-such") && e.contains("alum-bronze"), "{e}");
        let e = MaterialBsdf::open(&shipped(), None).unwrap_err().to_string();
        assert!(e.contains("latent file"), "{e}");
        let e = MaterialBsdf::open_latent_vector(&shipped(), &[f32::NAN; 3], "bad").unwrap_err().to_string();
        assert!(e.contains("latent.bin") && e.contains("not 3"), "{e}");
        let mut v = LatentLibrary::load(&[shipped()]).unwrap().latent_vector("chrome").unwrap();
        v[2] = f32::NAN;
        let e = MaterialBsdf::open_latent_vector(&shipped(), &v, "bad").unwrap_err().to_string();
        assert!(e.contains("latent.bin") && e.contains("finite"), "{e}");
        let m = MaterialBsdf::open(&shipped(), Some("chrome")).unwrap();
        let mut f = vec![[0.0; 3]; 2];
        let e = m.eval_batch(&[[0.0, 0.0, 1.0], [f32::NAN, 0.0, 1.0]], &[[0.0, 0.0, 1.0]; 2], &mut f).unwrap_err().to_string();
        assert!(e.contains("wo") && e.contains("entry 1"), "{e}");
        let e = m.eval_batch(&[[0.0, 0.0, 1.0]], &[[0.0, 0.0, 1.0]; 2], &mut f).unwrap_err().to_string();
        assert!(e.contains("1 entries for 2"), "{e}");
        let mut s = vec![None; 1];
        let e = m.sample_batch(&[[0.0, 0.0, 1.0]], &[[0.5, 1.5, 0.0]], &mut s).unwrap_err().to_string();
        assert!(e.contains("not in [0, 1]"), "{e}");
    }

    /// Directions of any finite length are normalised first: a tiny (subnormal components),
    /// a huge and a short vector give what their unit vector gives, and drawn directions
    /// are unit vectors (found by the c_abi fuzz target: wo = (1.28e-22, 1.28e-22,
    /// 1.28e-22) drew a direction of length 0.989).
    #[test]
    fn directions_of_any_length_are_normalised() {
        let m = MaterialBsdf::open(crate::testing::latent::shipped_latent_path(), Some("alum-bronze")).unwrap();
        let unit = Vec3::new(1.0, 1.0, 1.0).normalize().to_array();
        let wi = Vec3::new(-0.3, 0.2, 0.9).normalize().to_array();
        for scale in [1.28e-22f32, 1e-40, 3e30, 0.5, 7.0] {
            let wo = unit.map(|c| c * scale);
            assert_eq!(m.eval(wo, wi), m.eval(unit, wi), "scale {scale}");
            assert_eq!(m.pdf(wo, wi).to_bits(), m.pdf(unit, wi).to_bits(), "scale {scale}");
            for k in 0..64 {
                let u = [(k as f32 * 0.618_034).fract(), (k as f32 * 0.414_214).fract(), (k as f32 + 0.5) / 64.0];
                if let Some(s) = m.sample(wo, u) {
                    let length = Vec3::from(s.wi).length();
                    assert!((length - 1.0).abs() < 1e-4, "scale {scale}: drawn {:?}", s.wi);
                }
            }
        }
        assert_eq!(m.eval([0.0; 3], wi), [0.0; 3]);
    }
}
