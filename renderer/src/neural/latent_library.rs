//! The latent files given to the renderer (`render --material FILE`), read and validated
//! once; latent codes are decoded into [`NeuralBsdf`]s on demand, so a scene pays only for
//! the codes it binds. The f_ref table of a file (17.5 MB as f32) is converted on the first
//! decode from that file and shared by every code decoded from it.
//!
//! Names are searched in the files in the order given; the first file holding a name wins.
//! Which materials bind which codes is decided by the material module's binding rules.

use crate::bsdf::neural::{NeuralBsdf, ReferenceValues};
use crate::bsdf::tabulated_sampling::TabulatedSamplerConfig;
use crate::formats::latent_file::LatentFile;
use crate::neural::reference::ReferenceTable;
use crate::{Error, Result};
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// One file of the library.
#[derive(Debug)]
struct LibraryFile {
    path: PathBuf,
    file: LatentFile,
    reference: OnceLock<ReferenceValues>,
}

/// Latent files, searched in order.
#[derive(Debug, Default)]
pub struct LatentLibrary {
    files: Vec<LibraryFile>,
}

/// Where a latent code lives: the file's index in the library and the code.
#[derive(Clone, Debug, PartialEq)]
pub struct LatentCode {
    pub file: usize,
    /// z, the file's `latent_dim` values.
    pub z: Vec<f32>,
    /// Output offset δ per RGB channel ([`crate::formats::latent_file::NamedLatent::offset`]).
    pub offset: [f32; 3],
    /// Residual of the decoded parameters, empty for none
    /// ([`crate::formats::latent_file::NamedLatent::residual`]).
    pub residual: Vec<f32>,
}

impl LatentCode {
    /// The code of file `file` from a flat vector: z (`latent_dim` values), optionally
    /// followed by the 3 output offsets (0 when absent) and then by the residual
    /// (`residual_len` values; none when absent) — the vector [`LatentCode::to_vector`] gives
    /// and the C and Python interfaces pass.
    pub fn from_vector(file: usize, v: &[f32], latent_dim: usize, residual_len: usize) -> Option<LatentCode> {
        let offset = |v: &[f32]| [v[latent_dim], v[latent_dim + 1], v[latent_dim + 2]];
        let (offset, residual) = match v.len() {
            n if n == latent_dim => ([0.0; 3], Vec::new()),
            n if n == latent_dim + 3 => (offset(v), Vec::new()),
            n if n == latent_dim + 3 + residual_len => (offset(v), v[latent_dim + 3..].to_vec()),
            _ => return None,
        };
        Some(LatentCode { file, z: v[..latent_dim].to_vec(), offset, residual })
    }

    /// z, the 3 output offsets and the residual (`residual_len` zeros when the code has
    /// none, so that every code of a file gives a vector of one length): what editing
    /// interpolates, as one vector.
    pub fn to_vector(&self, residual_len: usize) -> Vec<f32> {
        let mut v: Vec<f32> = self.z.iter().chain(&self.offset).copied().collect();
        match self.residual.len() {
            0 => v.resize(v.len() + residual_len, 0.0),
            _ => v.extend(&self.residual),
        }
        v
    }

    /// The code at t of a material-editing sweep from `self` (t = 0) to `other` (t = 1):
    /// z(t) = (1 − t) z_self + t z_other and the same for the offsets; each end's residual
    /// faded out within [`RESIDUAL_FADE`] of its end, ΔΘ(t) = w(t) ΔΘ_self + w(1 − t) ΔΘ_other
    /// with w(d) = clamp(1 − d / τ, 0, 1)² (a missing residual counts as zeros). A residual
    /// corrects its own code's decoded network and means nothing at another point of the
    /// latent space (half of each of two unrelated corrections darkened the interior of metal
    /// sweeps to 0.37 of their ends' albedo, docs/training.md "Editing"), so inside the sweep
    /// a frame is a point of the latent space with interpolated offsets — one decoded network
    /// — and the ends keep their exact fit. A sweep from a code to itself is that code at
    /// every t. Both codes must come from the same file (one decoder).
    pub fn lerp(&self, other: &LatentCode, t: f32) -> Result<LatentCode> {
        if self.file != other.file || self.z.len() != other.z.len() {
            return Err(Error::InvalidArgument {
                flag: "latent codes".to_string(),
                reason: "the two latent codes come from different latent files".to_string(),
            });
        }
        if self == other {
            return Ok(self.clone());
        }
        let lerp = |x: f32, y: f32| (1.0 - t) * x + t * y;
        let fade = |distance: f32| (1.0 - distance / RESIDUAL_FADE).clamp(0.0, 1.0).powi(2);
        let (wa, wb) = (fade(t), fade(1.0 - t));
        let at = |r: &[f32], i: usize| r.get(i).copied().unwrap_or(0.0);
        let len = self.residual.len().max(other.residual.len());
        let residual = (0..len).map(|i| wa * at(&self.residual, i) + wb * at(&other.residual, i)).collect();
        Ok(LatentCode {
            file: self.file,
            z: self.z.iter().zip(&other.z).map(|(&x, &y)| lerp(x, y)).collect(),
            offset: [0, 1, 2].map(|c| lerp(self.offset[c], other.offset[c])),
            residual,
        })
    }
}

/// τ of [`LatentCode::lerp`]: how far along a sweep (in t) an end's residual reaches. Measured
/// on ten sweeps of the model trained with interpolated frames (docs/training.md "Editing"):
/// interpolating residuals across left the interior at 0.72 (mean) and 0.37 (worst) of the
/// ends' albedo, fading them within 0.25 at 0.88 and 0.57.
pub const RESIDUAL_FADE: f32 = 0.25;

impl LatentLibrary {
    /// Reads and validates every file (errors name the file).
    pub fn load(paths: &[impl AsRef<Path>]) -> Result<Self> {
        let files = paths
            .iter()
            .map(|p| {
                Ok(LibraryFile {
                    path: p.as_ref().to_path_buf(),
                    file: LatentFile::read(p)?,
                    reference: OnceLock::new(),
                })
            })
            .collect::<Result<_>>()?;
        Ok(LatentLibrary { files })
    }

    /// A library of one file already in memory (e.g. a trained run's decoder); `path` names
    /// it in errors.
    pub fn from_file(path: impl Into<PathBuf>, file: LatentFile) -> Self {
        LatentLibrary { files: vec![LibraryFile { path: path.into(), file, reference: OnceLock::new() }] }
    }

    /// True when no file was given.
    pub fn is_empty(&self) -> bool {
        self.files.is_empty()
    }

    /// The files' paths, in order.
    pub fn paths(&self) -> Vec<&Path> {
        self.files.iter().map(|f| f.path.as_path()).collect()
    }

    /// Every latent name, in file order, each once.
    pub fn names(&self) -> Vec<String> {
        let mut names: Vec<String> = Vec::new();
        for f in &self.files {
            for l in &f.file.latents {
                if !names.contains(&l.name) {
                    names.push(l.name.clone());
                }
            }
        }
        names
    }

    /// The code called `name`; an unknown name lists the available ones.
    pub fn latent(&self, name: &str) -> Result<LatentCode> {
        self.files
            .iter()
            .enumerate()
            .find_map(|(file, f)| {
                f.file.latent(name).map(|l| LatentCode {
                    file,
                    z: l.z.clone(),
                    offset: l.offset,
                    residual: l.residual.clone(),
                })
            })
            .ok_or_else(|| Error::UnknownName {
                what: "latent code",
                name: name.to_string(),
                available: self.names(),
            })
    }

    /// The code called `name` as one vector ([`LatentCode::to_vector`]).
    pub fn latent_vector(&self, name: &str) -> Result<Vec<f32>> {
        let code = self.latent(name)?;
        Ok(code.to_vector(self.files[code.file].file.residual_len()))
    }

    /// Decodes the code called `name` into a BSDF.
    pub fn decode(&self, name: &str) -> Result<NeuralBsdf> {
        let code = self.latent(name)?;
        self.decode_code(&code, name)
    }

    /// The code of file `file` from a flat vector ([`LatentCode::from_vector`]: z, optionally
    /// followed by the 3 output offsets and the residual); errors name the file when the size
    /// fits none.
    pub fn code_from_vector(&self, file: usize, v: &[f32]) -> Result<LatentCode> {
        let f = self.file(file)?;
        let (dim, residual) = (f.file.latent_dim, f.file.residual_len());
        LatentCode::from_vector(file, v, dim, residual).ok_or_else(|| {
            Error::invalid_file(
                &f.path,
                format!(
                    "a latent vector has {dim} values (z), {} (z and 3 offsets) or {} (z, offsets \
                     and residual), not {}",
                    dim + 3,
                    dim + 3 + residual,
                    v.len()
                ),
            )
        })
    }

    /// The contents of file `index` (its decoder, encoder, f_ref and codes).
    pub fn latent_file(&self, index: usize) -> Result<&LatentFile> {
        Ok(&self.file(index)?.file)
    }

    /// The f_ref table of file `index`, converted on first use and shared by every code
    /// decoded from the file.
    pub fn reference(&self, index: usize) -> Result<Arc<ReferenceTable>> {
        let f = self.file(index)?;
        Ok(f.reference.get_or_init(|| Arc::new(ReferenceTable::new(&f.file.f_ref))).clone())
    }

    fn file(&self, index: usize) -> Result<&LibraryFile> {
        self.files.get(index).ok_or_else(|| Error::InvalidArgument {
            flag: "latent code".to_string(),
            reason: format!("file index {index} out of range"),
        })
    }

    /// Decodes any code (e.g. an interpolated one) with the decoder of `code.file`; `label`
    /// names the result. Errors name the file when the code has the wrong size or a
    /// non-finite value.
    pub fn decode_code(&self, code: &LatentCode, label: &str) -> Result<NeuralBsdf> {
        self.decode_with(code, label, &TabulatedSamplerConfig::default())
    }

    /// [`LatentLibrary::decode_code`] for evaluation only (the sampler
    /// [`TabulatedSamplerConfig::EVAL_ONLY`], fitted in a few evaluations): the same values, for quadratures.
    pub fn decode_for_evaluation(&self, code: &LatentCode, label: &str) -> Result<NeuralBsdf> {
        self.decode_with(code, label, &TabulatedSamplerConfig::EVAL_ONLY)
    }

    fn decode_with(&self, code: &LatentCode, label: &str, sampling: &TabulatedSamplerConfig) -> Result<NeuralBsdf> {
        let f = self.file(code.file)?;
        let file = &f.file;
        let residual_ok = code.residual.is_empty() || code.residual.len() == file.residual_len();
        if code.z.len() != file.latent_dim
            || !residual_ok
            || code.z.iter().chain(&code.offset).chain(&code.residual).any(|v| !v.is_finite())
        {
            return Err(Error::invalid_file(
                &f.path,
                format!(
                    "latent '{label}' must be {} finite values (and a residual of {} or none)",
                    file.latent_dim,
                    file.residual_len()
                ),
            ));
        }
        let reference = self.reference(code.file)?;
        NeuralBsdf::new(label, file.decode(&code.z, code.offset, &code.residual), reference, file.mapping, file.epsilon, sampling)
            .map_err(|e| Error::invalid_file(&f.path, format!("decoding '{label}': {e}")))
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::bsdf::Bxdf;
    use crate::formats::latent_file::tests::small_file;
    use crate::formats::latent_file::WeightType;
    use glam::Vec3;

    /// The small test latent file written to a temporary directory (kept alive by the
    /// returned guard) and loaded.
    pub(crate) fn library() -> (tempfile::TempDir, LatentLibrary) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("latent.bin");
        small_file(WeightType::F32).write(&path).unwrap();
        let lib = LatentLibrary::load(&[&path]).unwrap();
        (dir, lib)
    }

    #[test]
    fn decodes_named_codes_and_rejects_unknown_or_bad_ones() {
        let (_dir, lib) = library();
        let names = lib.names();
        assert!(!names.is_empty());
        let bsdf = lib.decode(&names[0]).unwrap();
        let f = bsdf.eval(Vec3::new(0.3, 0.1, 0.95).normalize(), Vec3::new(-0.2, 0.4, 0.89).normalize());
        assert!(f.is_finite() && f.min_element() >= 0.0, "{f}");
        let err = lib.decode("no-such-material").unwrap_err().to_string();
        assert!(err.contains("no-such-material") && err.contains(&names[0]), "{err}");
        let mut code = lib.latent(&names[0]).unwrap();
        code.z[0] = f32::NAN;
        let err = lib.decode_code(&code, "bad").unwrap_err().to_string();
        assert!(err.contains("latent.bin") && err.contains("finite"), "{err}");
        code.z.pop();
        assert!(lib.decode_code(&code, "short").is_err());
    }

    #[test]
    fn lerp_hits_the_end_points() {
        let code = |file, z: Vec<f32>, offset, residual: Vec<f32>| LatentCode { file, z, offset, residual };
        let a = code(0, vec![1.0, -2.0], [0.0, 0.5, -1.0], vec![]);
        let b = code(0, vec![3.0, 2.0], [1.0, 0.5, 1.0], vec![2.0, -4.0]);
        assert_eq!(a.lerp(&b, 1.0).unwrap(), b);
        assert_eq!(b.lerp(&a, 1.0).unwrap(), LatentCode { residual: vec![0.0, 0.0], ..a.clone() });
        assert_eq!(a.lerp(&a, 0.5).unwrap(), a, "no residual stays none");
        let half = a.lerp(&b, 0.5).unwrap();
        assert_eq!((half.z, half.offset, half.residual), (vec![2.0, 0.0], [0.5, 0.5, 0.0], vec![0.0, 0.0]));
        // Within τ of an end that end's residual weighs (1 − d/τ)², the other's nothing.
        let near = a.lerp(&b, 1.0 - RESIDUAL_FADE / 2.0).unwrap();
        assert_eq!(near.residual, vec![0.5, -1.0]);
        assert_eq!(b.lerp(&b, 0.5).unwrap(), b, "a sweep from a code to itself");
        assert!(a.lerp(&code(1, vec![0.0, 0.0], [0.0; 3], vec![]), 0.5).is_err());
    }

    #[test]
    fn latent_vectors_carry_the_offsets_and_residuals_when_given() {
        let (_dir, lib) = library();
        let code = lib.latent("blue-acrylic").unwrap();
        assert_ne!(code.offset, [0.0; 3]);
        assert_eq!(code.residual.len(), 40);
        let v = lib.latent_vector("blue-acrylic").unwrap();
        assert_eq!(v.len(), 2 + 3 + 40);
        assert_eq!(lib.code_from_vector(0, &v).unwrap(), code);
        // A code without a residual gives a vector of the same length, zeros at the end.
        let gold = lib.latent_vector("gold").unwrap();
        assert_eq!(gold.len(), v.len());
        assert!(gold[5..].iter().all(|&x| x == 0.0));
        let tinted = lib.code_from_vector(0, &v[..5]).unwrap();
        assert_eq!((tinted.offset, tinted.residual.len()), (code.offset, 0));
        let bare = lib.code_from_vector(0, &code.z).unwrap();
        assert_eq!((bare.z, bare.offset), (code.z.clone(), [0.0; 3]));
        let e = lib.code_from_vector(0, &v[..4]).unwrap_err().to_string();
        assert!(e.contains("latent.bin") && e.contains("or 45") && e.contains("not 4"), "{e}");
        // The residual changes the decoded BSDF.
        let (wi, wo) = (Vec3::new(0.3, 0.1, 0.95).normalize(), Vec3::new(-0.2, 0.4, 0.89).normalize());
        let f = |c: &LatentCode| lib.decode_code(c, "x").unwrap().eval(wi, wo);
        assert_ne!(f(&code), f(&tinted));
        let mut bad = code.clone();
        bad.residual.pop();
        let e = lib.decode_code(&bad, "bad").unwrap_err().to_string();
        assert!(e.contains("residual of 40 or none"), "{e}");
    }
}
