//! `neural_brdf._native`: the renderer's neural and measured BRDFs for Python (the package
//! `neural_brdf` re-exports it; see `python/neural_brdf/__init__.py` and the type stubs).
//!
//! Arrays in, arrays out: directions are `(N, 3)` arrays in the local shading frame of the
//! renderer (z = shading normal, `wo` toward the viewer, `wi` toward the light, both pointing
//! away from the surface), any float dtype (converted to float32). Values are f_r in 1/sr per
//! RGB channel without the cosine, densities solid-angle densities in 1/sr; both are zero
//! below either horizon. Batches run in parallel with the GIL released.
//!
//! Errors are raised with the one-line message the `render` command prints: `OSError` (a
//! file cannot be read), `InvalidFileError` (a `ValueError`: not a valid material file),
//! `UnknownNameError` (a `LookupError`: no code of that name) and `ValueError` (a bad
//! argument).

use numpy::ndarray::{Array2, Array3, Array4};
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLike1, PyArrayLike2};
use pyo3::create_exception;
use pyo3::exceptions::{PyLookupError, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use renderer::formats::merl::{PHI_D_BINS, THETA_D_BINS, THETA_H_BINS};
use renderer::material::standalone::Sample;
use renderer::material::{MaterialBsdf, SharedBsdf};
use renderer::neural::latent_library::LatentLibrary;
use renderer::neural::mapping::MappingForm;
use std::path::PathBuf;

/// Rows of 3 floats per direction or RGB value, (N, 3).
type Rows3<'py> = Bound<'py, PyArray2<f32>>;
/// One float per row, (N,).
type Column<'py> = Bound<'py, PyArray1<f32>>;
/// Directions as received: (N, 3), any float dtype.
type Directions<'py> = PyArrayLike2<'py, f32, AllowTypeChange>;
/// Direction pairs as read: (`wo`, `wi`).
type Pairs = (Vec<[f32; 3]>, Vec<[f32; 3]>);
/// A layer's weight matrix and bias.
type Layer<'py> = (Bound<'py, PyArray2<f32>>, Column<'py>);

create_exception!(_native, InvalidFileError, PyValueError, "A file was read but is not a valid material file.");
create_exception!(_native, UnknownNameError, PyLookupError, "The latent file has no code of that name.");

/// The renderer's error as the Python exception of its kind, with its one-line message.
fn to_py(e: renderer::Error) -> PyErr {
    let message = e.to_string();
    match e {
        renderer::Error::Io { .. } => PyOSError::new_err(message),
        renderer::Error::InvalidFile { .. } => InvalidFileError::new_err(message),
        renderer::Error::UnknownName { .. } => UnknownNameError::new_err(message),
        _ => PyValueError::new_err(message),
    }
}

/// Rows of an `(N, width)` array as fixed-size arrays; `what` names it in errors.
fn rows<const W: usize>(array: &Directions<'_>, what: &str) -> PyResult<Vec<[f32; W]>> {
    let view = array.as_array();
    if view.ncols() != W {
        return Err(PyValueError::new_err(format!(
            "{what} must have shape (N, {W}), got {:?}",
            view.shape()
        )));
    }
    Ok(view.rows().into_iter().map(|r| std::array::from_fn(|k| r[k])).collect())
}

/// Same-length `wo` and `wi` rows.
fn pairs(wo: &Directions<'_>, wi: &Directions<'_>) -> PyResult<Pairs> {
    let (wo, wi) = (rows::<3>(wo, "wo")?, rows::<3>(wi, "wi")?);
    if wo.len() != wi.len() {
        return Err(PyValueError::new_err(format!("wo has {} rows but wi has {}", wo.len(), wi.len())));
    }
    Ok((wo, wi))
}

fn rgb_array<'py>(py: Python<'py>, rgb: Vec<[f32; 3]>) -> Rows3<'py> {
    let n = rgb.len();
    let flat: Vec<f32> = rgb.into_iter().flatten().collect();
    Array2::from_shape_vec((n, 3), flat).expect("n × 3 values").into_pyarray(py)
}

/// One material's BSDF: a decoded latent code, a MERL table or an NBRDF network.
#[pyclass(frozen, module = "neural_brdf")]
struct Material {
    /// Boxed: the BSDF holds 64-byte-aligned counters, more than a Python object's alignment.
    bsdf: Box<MaterialBsdf>,
    label: String,
}

#[pymethods]
impl Material {
    /// Opens a latent file (`latent.bin`, with the code `name` to decode), a MERL table
    /// (`.binary`) or an NBRDF network (the prefix of its `.npy` files, or one of them).
    #[staticmethod]
    #[pyo3(signature = (path, name=None))]
    fn open(py: Python<'_>, path: PathBuf, name: Option<String>) -> PyResult<Self> {
        let bsdf = py.detach(|| MaterialBsdf::open(&path, name.as_deref())).map_err(to_py)?;
        let label = name.unwrap_or_else(|| path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default());
        Ok(Material { bsdf: Box::new(bsdf), label })
    }

    /// Opens a latent file and decodes the latent vector `z` (any code, e.g. an edited or
    /// interpolated one); `label` names it. `z` is a vector of `latent_codes`: the latent code
    /// followed by its 3 output offsets and its residual (or z and the offsets, no residual;
    /// or z alone, offsets 0).
    #[staticmethod]
    #[pyo3(signature = (path, z, label="latent vector".to_string()))]
    fn from_latent_vector(py: Python<'_>, path: PathBuf, z: PyArrayLike1<'_, f32, AllowTypeChange>, label: String) -> PyResult<Self> {
        let z = z.as_array().to_vec();
        let bsdf = py.detach(|| MaterialBsdf::open_latent_vector(&path, &z, &label)).map_err(to_py)?;
        Ok(Material { bsdf: Box::new(bsdf), label })
    }

    /// Opens a latent file and decodes the blend of its codes `a` and `b` at `t`: the latent
    /// interpolation (1 − t) A + t B of z and offsets, each end's residual faded out within
    /// t = 0.25 of its end, decoded exactly as
    /// `render --sweep` decodes its frames (t = 0 is A, t = 1 is B). `t` must be in [0, 1]
    /// (`ValueError` otherwise, NaN included: not clamped); an unknown code raises
    /// `UnknownNameError`.
    #[staticmethod]
    fn blend(py: Python<'_>, path: PathBuf, a: String, b: String, t: f32) -> PyResult<Self> {
        let bsdf = py.detach(|| MaterialBsdf::open_blend(&path, &a, &b, t)).map_err(to_py)?;
        Ok(Material { bsdf: Box::new(bsdf), label: format!("{a}>{b}@{t}") })
    }

    /// The renderer's palette for the blend of `a` and `b` (its glTF `blend` form):
    /// `PALETTE_SIZE` materials, entry k the blend at t = k / (PALETTE_SIZE − 1) (computed in
    /// float32 as the renderer does), decoded from one read of the file. The renderer's blend
    /// at t mixes entries k = min(floor(t (PALETTE_SIZE − 1)), PALETTE_SIZE − 2) and k + 1
    /// with weights (1 − a, a), a = t (PALETTE_SIZE − 1) − k.
    #[staticmethod]
    fn blend_palette(py: Python<'_>, path: PathBuf, a: String, b: String) -> PyResult<Vec<Self>> {
        let palette = py.detach(|| MaterialBsdf::open_blend_palette(&path, &a, &b)).map_err(to_py)?;
        let last = (palette.len() - 1) as f32;
        Ok(palette
            .into_iter()
            .enumerate()
            .map(|(k, bsdf)| Material { bsdf: Box::new(bsdf), label: format!("{a}>{b}@{}", k as f32 / last) })
            .collect())
    }

    /// The mixture f = Σ w_k f_k, pdf = Σ w_k pdf_k of 1 to 4 `materials` with `weights`
    /// (normalised to sum 1, parts of weight 0 dropped, sampling choosing a part by weight):
    /// the renderer's `mix` material at a texel of these weights, bit for bit. `ValueError`
    /// on no or more than 4 materials (a mixture counts its parts), different lengths, a
    /// weight negative or not finite, or weights all 0. The mixture shares the materials'
    /// data (they stay usable, and it outlives them).
    #[staticmethod]
    fn mix(py: Python<'_>, materials: Vec<Bound<'_, Material>>, weights: PyArrayLike1<'_, f32, AllowTypeChange>) -> PyResult<Self> {
        let weights = weights.as_array().to_vec();
        if weights.len() != materials.len() {
            return Err(PyValueError::new_err(format!("{} materials but {} weights", materials.len(), weights.len())));
        }
        let parts: Vec<(&MaterialBsdf, f32)> = materials.iter().map(|m| &*m.get().bsdf).zip(weights.iter().copied()).collect();
        let bsdf = py.detach(|| MaterialBsdf::mix(&parts)).map_err(to_py)?;
        let names: Vec<String> = materials.iter().zip(&weights).map(|(m, w)| format!("{} {w}", m.get().label)).collect();
        Ok(Material { bsdf: Box::new(bsdf), label: format!("mix({})", names.join(", ")) })
    }

    /// A mixture's weights as given (normalised when used); `None` for a single material.
    #[getter]
    fn weights(&self) -> Option<Vec<f32>> {
        self.bsdf.parts().map(|parts| parts.map(|(_, w)| w).collect())
    }

    /// The code's name (or label), or the file's stem for a table or network.
    #[getter]
    fn name(&self) -> &str {
        &self.label
    }

    /// `"neural"` (a latent code or a blend), `"merl"` (a MERL table), `"nbrdf"` (an NBRDF
    /// network) or `"mixture"`.
    #[getter]
    fn kind(&self) -> &'static str {
        match self.bsdf.shared() {
            Some(SharedBsdf::Neural(_)) => "neural",
            Some(SharedBsdf::Merl(_)) => "merl",
            Some(SharedBsdf::Nbrdf(_)) => "nbrdf",
            None => "mixture",
        }
    }

    /// f_r(wo, wi), shape (N, 3).
    fn eval<'py>(
        &self,
        py: Python<'py>,
        wo: Directions<'py>,
        wi: Directions<'py>,
    ) -> PyResult<Rows3<'py>> {
        let (wo, wi) = pairs(&wo, &wi)?;
        let mut f = vec![[0f32; 3]; wo.len()];
        py.detach(|| self.bsdf.eval_batch(&wo, &wi, &mut f)).map_err(to_py)?;
        Ok(rgb_array(py, f))
    }

    /// The density (1/sr) with which `sample` draws wi given wo, shape (N,).
    fn pdf<'py>(
        &self,
        py: Python<'py>,
        wo: Directions<'py>,
        wi: Directions<'py>,
    ) -> PyResult<Column<'py>> {
        let (wo, wi) = pairs(&wo, &wi)?;
        let mut pdf = vec![0f32; wo.len()];
        py.detach(|| self.bsdf.pdf_batch(&wo, &wi, &mut pdf)).map_err(to_py)?;
        Ok(PyArray1::from_vec(py, pdf))
    }

    /// `(eval(wo, wi), pdf(wo, wi))` from one evaluation per pair.
    fn eval_pdf<'py>(
        &self,
        py: Python<'py>,
        wo: Directions<'py>,
        wi: Directions<'py>,
    ) -> PyResult<(Rows3<'py>, Column<'py>)> {
        let (wo, wi) = pairs(&wo, &wi)?;
        let mut f = vec![[0f32; 3]; wo.len()];
        let mut pdf = vec![0f32; wo.len()];
        py.detach(|| self.bsdf.eval_pdf_batch(&wo, &wi, &mut f, &mut pdf)).map_err(to_py)?;
        Ok((rgb_array(py, f), PyArray1::from_vec(py, pdf)))
    }

    /// Draws wi given wo from uniform numbers `u` in [0, 1]: shape (N, 2) (the first number
    /// also picks the lobe) or (N, 3) (the third picks it). Returns `(wi, f, pdf)`, shapes
    /// (N, 3), (N, 3), (N,); a failed draw has wi = f = 0 and pdf = 0.
    fn sample<'py>(
        &self,
        py: Python<'py>,
        wo: Directions<'py>,
        u: Directions<'py>,
    ) -> PyResult<(Rows3<'py>, Rows3<'py>, Column<'py>)> {
        let wo = rows::<3>(&wo, "wo")?;
        let mut out = vec![None; wo.len()];
        let drawn = match u.as_array().ncols() {
            2 => {
                let u = rows::<2>(&u, "u")?;
                py.detach(|| self.bsdf.sample_batch(&wo, &u, &mut out))
            }
            _ => {
                let u = rows::<3>(&u, "u")?;
                py.detach(|| self.bsdf.sample_batch(&wo, &u, &mut out))
            }
        };
        drawn.map_err(to_py)?;
        let none = Sample { wi: [0.0; 3], f: [0.0; 3], pdf: 0.0 };
        let samples: Vec<Sample> = out.into_iter().map(|s| s.unwrap_or(none)).collect();
        Ok((
            rgb_array(py, samples.iter().map(|s| s.wi).collect()),
            rgb_array(py, samples.iter().map(|s| s.f).collect()),
            PyArray1::from_vec(py, samples.iter().map(|s| s.pdf).collect()),
        ))
    }

    /// For a latent code, the decoded target net as a list of `(W, b)` per layer, `W` of
    /// shape (d_in, d_out) (y = x @ W + b), ReLU after every layer but the last; its input
    /// is the 6D half/difference vector of DESIGN.md (φd folded), its output the mapped
    /// value y per RGB channel. `None` for a table or a network.
    #[getter]
    fn layers<'py>(&self, py: Python<'py>) -> PyResult<Option<Vec<Layer<'py>>>> {
        let Some(neural) = self.bsdf.neural() else {
            return Ok(None);
        };
        neural
            .decoded()
            .layers
            .iter()
            .map(|l| {
                let w = Array2::from_shape_vec((l.d_in, l.d_out), l.weight.clone())
                    .map_err(|e| PyValueError::new_err(e.to_string()))?;
                Ok((w.into_pyarray(py), PyArray1::from_vec(py, l.bias.clone())))
            })
            .collect::<PyResult<Vec<_>>>()
            .map(Some)
    }

    /// For a latent code, the reference BRDF f_ref (1/sr) per MERL bin, shape
    /// (90, 90, 180, 3) indexed [θh, θd, φd, channel]; a negative value marks a bin
    /// unmeasured. `None` for a table or a network.
    #[getter]
    fn f_ref<'py>(&self, py: Python<'py>) -> Option<Bound<'py, numpy::PyArray4<f32>>> {
        self.bsdf.neural().map(|n| bins_array(py, &n.reference().values()))
    }

    /// For a MERL table, f_r (1/sr) per bin as the renderer interpolates it (scale applied,
    /// unmeasured bins 0), shape (90, 90, 180, 3). `None` otherwise.
    #[getter]
    fn table<'py>(&self, py: Python<'py>) -> Option<Bound<'py, numpy::PyArray4<f32>>> {
        match self.bsdf.shared() {
            Some(SharedBsdf::Merl(m)) => Some(bins_array(py, m.values())),
            _ => None,
        }
    }

    /// For a latent code, `(form, epsilon)` of the mapping between f_r and y: form
    /// `"code"`, f = (e^y − 1)(f_ref + ε) − ε, or `"talk"`, f = e^y (f_ref + ε) − ε; the
    /// renderer clamps f to ≥ 0 and y to ≤ `MAX_LOG_VALUE`. `None` otherwise.
    #[getter]
    fn mapping(&self) -> Option<(&'static str, f32)> {
        self.bsdf.neural().map(|n| {
            let (form, epsilon) = n.mapping();
            let name = match form {
                MappingForm::Code => "code",
                MappingForm::Talk => "talk",
            };
            (name, epsilon)
        })
    }

    /// The importance sampler's fitted tables (see `renderer::bsdf::tabulated_sampling`):
    /// a dict with `theta_o` (nodes, radians), `row_v` (1 − cos θh at the row boundaries),
    /// `columns` (cells over |φh − φo| / π), `cosine_fraction` and `values` (shape
    /// (nodes, rows + 1, columns + 1), the bilinear density's vertex values, max 1).
    /// `ValueError` for a mixture (each part has its own).
    fn sampler_tables<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let t = self.bsdf.sampler_tables().ok_or_else(|| PyValueError::new_err(format!("{}: a mixture has no sampler tables of its own (each part has its own)", self.label)))?;
        let (nodes, lines) = (t.values.len(), t.row_v.len());
        let values = Array3::from_shape_vec((nodes, lines, t.columns + 1), t.values.concat())
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let dict = PyDict::new(py);
        dict.set_item("theta_o", PyArray1::from_vec(py, t.theta_o))?;
        dict.set_item("row_v", PyArray1::from_vec(py, t.row_v))?;
        dict.set_item("columns", t.columns)?;
        dict.set_item("cosine_fraction", t.cosine_fraction)?;
        dict.set_item("values", values.into_pyarray(py))?;
        Ok(dict)
    }

    fn __repr__(&self) -> String {
        format!("<neural_brdf.Material {} '{}'>", self.kind(), self.label)
    }
}

/// Per-bin RGB values (within-channel index order) as a [θh, θd, φd, channel] array.
fn bins_array<'py>(py: Python<'py>, values: &[[f32; 3]]) -> Bound<'py, numpy::PyArray4<f32>> {
    let flat: Vec<f32> = values.iter().flatten().copied().collect();
    Array4::from_shape_vec((THETA_H_BINS, THETA_D_BINS, PHI_D_BINS, 3), flat)
        .expect("one value per bin")
        .into_pyarray(py)
}

/// The latent codes of a latent file by name, each a float32 vector (z followed by the code's
/// 3 output offsets and its residual, zeros when it has none, so that every vector of a file
/// has one length: what to edit, interpolate and pass to `Material.from_latent_vector`), in
/// the file's order.
#[pyfunction]
fn latent_codes<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let latents = py.detach(|| LatentLibrary::load(&[&path])).map_err(to_py)?;
    let codes = PyDict::new(py);
    for name in latents.names() {
        let vector = latents.latent_vector(&name).map_err(to_py)?;
        codes.set_item(name, PyArray1::from_vec(py, vector))?;
    }
    Ok(codes)
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // A CPU older than the build's target fails the import with the reason, not later with
    // an illegal instruction.
    renderer::support::cpu::check_build_features().map_err(|e| pyo3::exceptions::PyImportError::new_err(e.to_string()))?;
    m.add_class::<Material>()?;
    m.add_function(wrap_pyfunction!(latent_codes, m)?)?;
    m.add("InvalidFileError", m.py().get_type::<InvalidFileError>())?;
    m.add("UnknownNameError", m.py().get_type::<UnknownNameError>())?;
    m.add("MAX_LOG_VALUE", renderer::neural::mapping::MAX_LOG_VALUE)?;
    m.add("PALETTE_SIZE", renderer::material::PALETTE_SIZE)?;
    m.add("MAX_MIX_PARTS", renderer::scene::MAX_MIX_PARTS)?;
    Ok(())
}
