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
//! ```no_run
//! use renderer::material::MaterialBsdf;
//! let bronze = MaterialBsdf::open("scenes/materials/latent.bin".as_ref(), Some("alum-bronze"))?;
//! let f = bronze.eval([0.0, 0.6, 0.8], [0.0, -0.6, 0.8]);
//! # Ok::<(), renderer::Error>(())
//! ```

use super::{Binding, SharedBsdf};
use crate::bsdf::neural::NeuralBsdf;
use crate::bsdf::tabulated_sampling::{SamplerTables, TabulatedBrdf, TabulatedSampler};
use crate::bsdf::{BatchEval, BsdfSample, Bxdf};
use crate::neural::latent_library::LatentLibrary;
use crate::{Error, Result, Rgb};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::path::Path;

/// Directions per parallel work item of the batched calls.
const BATCH_CHUNK: usize = 1024;

/// One material's BSDF (see the module documentation). `Send + Sync`: share it between
/// threads by reference.
#[derive(Debug)]
pub struct MaterialBsdf {
    bsdf: SharedBsdf,
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

    /// Opens a latent file and decodes the latent vector `v` (any code, e.g. an edited one)
    /// with its decoder; `label` names it. `v` is z, optionally followed by the code's 3
    /// output offsets and then by its residual
    /// ([`crate::neural::latent_library::LatentCode::from_vector`]). Errors
    /// name the file when `v` has the wrong size or a non-finite value.
    pub fn open_latent_vector(path: &Path, v: &[f32], label: &str) -> Result<Self> {
        let latents = LatentLibrary::load(&[path])?;
        let code = latents.code_from_vector(0, v)?;
        Ok(MaterialBsdf {
            bsdf: SharedBsdf::Neural(latents.decode_code(&code, label)?),
        })
    }

    /// Opens the BSDF a [`Binding`] names (latent codes from `latents`).
    pub fn from_binding(binding: &Binding, latents: &LatentLibrary) -> Result<Self> {
        Ok(MaterialBsdf {
            bsdf: SharedBsdf::open(binding, latents)?,
        })
    }

    /// The BSDF as the renderer holds it.
    pub fn shared(&self) -> &SharedBsdf {
        &self.bsdf
    }

    /// For a latent code: its decoded target net, f_ref and mapping (what another renderer
    /// needs to evaluate it itself); `None` for a table or a network.
    pub fn neural(&self) -> Option<&NeuralBsdf> {
        match &self.bsdf {
            SharedBsdf::Neural(b) => Some(b),
            _ => None,
        }
    }

    /// The importance sampler's fitted tables (every material of this kind has one).
    pub fn sampler_tables(&self) -> SamplerTables {
        self.sampler().tables()
    }

    /// f_r(wo, wi) in 1/sr per RGB channel.
    #[inline]
    pub fn eval(&self, wo: [f32; 3], wi: [f32; 3]) -> [f32; 3] {
        self.bsdf.as_bsdf().eval(Vec3::from(wo), Vec3::from(wi)).to_array()
    }

    /// The density (1/sr) with which [`MaterialBsdf::sample`] draws `wi` given `wo`.
    #[inline]
    pub fn pdf(&self, wo: [f32; 3], wi: [f32; 3]) -> f32 {
        self.bsdf.as_bsdf().pdf(Vec3::from(wo), Vec3::from(wi))
    }

    /// Value and density together.
    #[inline]
    pub fn eval_pdf(&self, wo: [f32; 3], wi: [f32; 3]) -> ([f32; 3], f32) {
        let (f, pdf) = self.bsdf.as_bsdf().eval_pdf(Vec3::from(wo), Vec3::from(wi));
        (f.to_array(), pdf)
    }

    /// Draws wi given `wo` from three uniform numbers in [0, 1) (`u[0..2]` for the direction,
    /// `u[2]` to choose a lobe); `None` when nothing can be drawn (e.g. `wo` below the
    /// horizon). The density of the result is exactly [`MaterialBsdf::pdf`].
    #[inline]
    pub fn sample(&self, wo: [f32; 3], u: [f32; 3]) -> Option<Sample> {
        self.bsdf.as_bsdf().sample(Vec3::from(wo), Vec2::new(u[0], u[1]), u[2]).map(Sample::from)
    }

    /// As [`MaterialBsdf::sample`] from two uniform numbers: `u[0]` also chooses the lobe (what
    /// is left of it after the choice is reused for the direction). Same density.
    pub fn sample_2d(&self, wo: [f32; 3], u: [f32; 2]) -> Option<Sample> {
        let wo = Vec3::from(wo);
        let wi = self.sampler().sample_2d(wo, Vec2::from(u))?;
        let (f, pdf) = self.bsdf.as_bsdf().eval_pdf(wo, wi);
        (pdf > 0.0 && pdf.is_finite()).then(|| Sample { wi: wi.to_array(), f: f.to_array(), pdf })
    }

    fn sampler(&self) -> &TabulatedSampler {
        match &self.bsdf {
            SharedBsdf::Merl(b) => b.sampler(),
            SharedBsdf::Nbrdf(b) => b.sampler(),
            SharedBsdf::Neural(b) => b.sampler(),
        }
    }

    /// f_r(wo, wi) of many pairs into `out`: a decoded net's values in one batched forward
    /// pass, a table's look-ups prefetched together ([`BatchEval`]), an NBRDF network's one
    /// by one. The same values as [`MaterialBsdf::eval`], bit for bit.
    fn values(&self, pairs: &[(Vec3, Vec3)], out: &mut [Rgb]) {
        match &self.bsdf {
            SharedBsdf::Neural(b) => values_together(b, pairs, out),
            SharedBsdf::Merl(b) => values_together(b, pairs, out),
            SharedBsdf::Nbrdf(b) => {
                for (o, &(wo, wi)) in out.iter_mut().zip(pairs) {
                    *o = b.eval(wo, wi);
                }
            }
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
                (first..first + fc.len()).map(|i| (Vec3::from(wo[i]), Vec3::from(wi[i]))).collect();
            let mut values = vec![Rgb::ZERO; pairs.len()];
            self.values(&pairs, &mut values);
            for (o, v) in fc.iter_mut().zip(&values) {
                *o = v.to_array();
            }
            if let Some(pc) = pc {
                for (o, &(wo, wi)) in pc.iter_mut().zip(&pairs) {
                    *o = self.sampler().pdf(wo, wi);
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
        out.par_chunks_mut(BATCH_CHUNK).enumerate().for_each(|(c, chunk)| {
            let first = c * BATCH_CHUNK;
            let drawn: Vec<Option<(Vec3, f32)>> =
                (first..first + chunk.len()).map(|i| u[i].direction(self.sampler(), Vec3::from(wo[i]))).collect();
            let pairs: Vec<(Vec3, Vec3)> = (first..first + chunk.len())
                .zip(&drawn)
                .filter_map(|(i, d)| d.map(|(wi, _)| (Vec3::from(wo[i]), wi)))
                .collect();
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
}

impl UniformNumbers for [f32; 3] {
    fn numbers(&self) -> &[f32] {
        self
    }
    fn direction(self, sampler: &TabulatedSampler, wo: Vec3) -> Option<(Vec3, f32)> {
        sampler.sample_with_pdf(wo, Vec2::new(self[0], self[1]), self[2])
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
}

fn batch_error(what: &str, reason: String) -> Error {
    Error::InvalidArgument {
        flag: what.to_string(),
        reason,
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
        assert!(matches!(network.shared(), SharedBsdf::Nbrdf(_)));
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
        let t = m.sampler_tables();
        assert_eq!(t.values.len(), t.theta_o.len());
        assert!(t.values.iter().all(|v| v.len() == t.row_v.len() * (t.columns + 1)));
        assert!(t.values.iter().all(|v| v.iter().all(|x| x.is_finite() && *x >= 0.0) && v.contains(&1.0)));
        let table = MaterialBsdf::open(&data_dir().join("merl/chrome"), None).unwrap();
        assert!(table.neural().is_none());
        assert_eq!(table.sampler_tables().row_v, t.row_v);
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
        assert!(matches!(materials[1].shared(), SharedBsdf::Merl(_)));
        assert!(matches!(materials[2].shared(), SharedBsdf::Nbrdf(_)));
        // More than one chunk, the last one partial; some directions below the horizon.
        let n = BATCH_CHUNK * 2 + 333;
        let wo: Vec<[f32; 3]> = (0..n).map(|i| unit(1.4 * (i as f32 / n as f32), i as f32 * 0.37)).collect();
        let wi: Vec<[f32; 3]> = (0..n).map(|i| unit(1.7 * ((i * 7 % n) as f32 / n as f32), i as f32 * 1.1)).collect();
        let u: Vec<[f32; 3]> = (0..n).map(|i| [(i as f32 * 0.618).fract(), (i as f32 * 0.414).fract(), (i as f32 * 0.732).fract()]).collect();
        let u2: Vec<[f32; 2]> = u.iter().map(|v| [v[0], v[1]]).collect();
        for (m, kind) in materials.iter().zip(["code", "table", "network"]) {
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
                assert_eq!(m.eval(wo[i], s.wi), s.f);
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
        for (name, m) in [("chrome", &chrome), ("gold-metallic-paint3", &paint)] {
            for theta in [0.3f32, 1.2] {
                crate::testing::bsdfs::check_chi2(&TwoNumbers(m), name, theta);
            }
        }
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
}
