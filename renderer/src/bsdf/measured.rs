//! Measured BRDFs bound to materials: tabulated MERL ([`MerlBsdf`]), NBRDF networks
//! ([`NbrdfBsdf`]), loaded from a binding specification, and decoded FreNBRDF latent codes
//! ([`FrenbrdfBsdf`], made by [`crate::latent_library::LatentLibrary`] from `neural:NAME`).
//!
//! # Specifications
//! `KIND:PATH`, with relative paths resolved against the current directory (or a base
//! directory given to [`MeasuredBsdf::load_relative_to`], e.g. the scene file's):
//! - `merl:PATH.binary` — a MERL-layout table (`.binary` may be left out when the file has it);
//! - `nbrdf:PREFIX` — the network in `PREFIX_fc1.npy`, `PREFIX_b1.npy`, … `PREFIX_b3.npy`,
//!   i.e. `nbrdf:DIR/MATERIAL` names material MATERIAL of a directory of networks such as
//!   `../shared/data/nbrdf/merl`; `PREFIX_fc1.npy` (any of the six file names) is accepted for
//!   PREFIX, and a directory that holds exactly one network may be named by itself.
//!
//! Errors name the specification or the offending file: an unknown KIND gives
//! [`Error::UnknownName`], a missing `:` or path [`Error::InvalidArgument`], an unknown
//! material in an existing directory [`Error::UnknownName`] listing the available ones.
//!
//! ```no_run
//! use renderer::bsdf::MeasuredBsdf;
//! let bronze = MeasuredBsdf::load("nbrdf:../shared/data/nbrdf/merl/alum-bronze")?;
//! let table = MeasuredBsdf::load("merl:data/merl-fitted/alum-bronze.binary")?;
//! # Ok::<(), renderer::Error>(())
//! ```

use super::frenbrdf::FrenbrdfBsdf;
use super::merl::MerlBsdf;
use super::nbrdf::NbrdfBsdf;
use super::{BsdfSample, Bxdf};
use crate::{Error, Result, Rgb};
use glam::{Vec2, Vec3};
use std::path::{Path, PathBuf};

/// The specification kinds [`MeasuredBsdf::load`] understands, in the form they are written.
pub const SPEC_FORMS: [&str; 3] = ["merl:PATH.binary", "nbrdf:PATH_PREFIX", "neural:LATENT_NAME"];

/// A measured BSDF shared by every shading point of the materials bound to it.
///
/// The NBRDF variant holds its weights inline (≈ 3.5 KB) so evaluation needs no pointer
/// chase; scenes hold a handful of these, by reference.
#[derive(Debug)]
#[allow(clippy::large_enum_variant)]
pub enum MeasuredBsdf {
    /// A MERL-layout table.
    Merl(MerlBsdf),
    /// An NBRDF network.
    Nbrdf(NbrdfBsdf),
    /// A decoded FreNBRDF/HyperBRDF latent code.
    Neural(FrenbrdfBsdf),
}

impl MeasuredBsdf {
    /// Loads the BSDF named by a specification (see the [module documentation](self)),
    /// relative paths resolved against the current directory.
    pub fn load(spec: &str) -> Result<Self> {
        Self::load_relative_to(spec, None)
    }

    /// Loads the BSDF named by a specification, relative paths resolved against `base_dir`
    /// when given.
    pub fn load_relative_to(spec: &str, base_dir: Option<&Path>) -> Result<Self> {
        let Some((kind, rest)) = spec.split_once(':') else {
            return Err(Error::InvalidArgument {
                flag: format!("BRDF spec '{spec}'"),
                reason: format!("expected KIND:PATH, one of {}", SPEC_FORMS.join(", ")),
            });
        };
        if kind == "neural" {
            return Err(Error::InvalidArgument {
                flag: format!("BRDF spec '{spec}'"),
                reason: "a latent code needs a latent file (render --material FILE)".to_string(),
            });
        }
        if !["merl", "nbrdf"].contains(&kind) {
            return Err(Error::UnknownName {
                what: "BRDF spec kind",
                name: spec.to_string(),
                available: SPEC_FORMS.iter().map(|s| s.to_string()).collect(),
            });
        }
        if rest.is_empty() {
            return Err(Error::InvalidArgument {
                flag: format!("BRDF spec '{spec}'"),
                reason: "empty path".to_string(),
            });
        }
        let path = match base_dir {
            Some(base) if Path::new(rest).is_relative() => base.join(rest),
            _ => PathBuf::from(rest),
        };
        if kind == "merl" {
            Ok(MeasuredBsdf::Merl(MerlBsdf::load(resolve_merl_path(path))?))
        } else {
            Ok(MeasuredBsdf::Nbrdf(NbrdfBsdf::load(resolve_nbrdf_prefix(
                path,
            )?)?))
        }
    }
}

/// `PATH`, or `PATH.binary` when only that exists.
fn resolve_merl_path(path: PathBuf) -> PathBuf {
    if path.exists() {
        return path;
    }
    let mut with_extension = path.clone().into_os_string();
    with_extension.push(".binary");
    let with_extension = PathBuf::from(with_extension);
    if with_extension.is_file() {
        with_extension
    } else {
        path
    }
}

/// The network prefix a `nbrdf:` path names (see the module documentation).
fn resolve_nbrdf_prefix(path: PathBuf) -> Result<PathBuf> {
    let text = path.to_string_lossy();
    for suffix in [
        "_fc1.npy", "_b1.npy", "_fc2.npy", "_b2.npy", "_fc3.npy", "_b3.npy",
    ] {
        if let Some(prefix) = text.strip_suffix(suffix) {
            return Ok(PathBuf::from(prefix));
        }
    }
    if crate::nbrdf::tensor_paths(&path)[0].is_file() {
        return Ok(path);
    }
    if path.is_dir() {
        let names = crate::nbrdf::list_networks(&path)?;
        if let [name] = &names[..] {
            return Ok(path.join(name));
        }
        return Err(Error::invalid_file(
            &path,
            format!(
                "a directory of {} NBRDF networks: name one as DIR/MATERIAL",
                names.len()
            ),
        ));
    }
    if let Some(dir) = path.parent().filter(|d| d.is_dir()) {
        let available = crate::nbrdf::list_networks(dir)?;
        if !available.is_empty() {
            return Err(Error::UnknownName {
                what: "NBRDF network",
                name: path.display().to_string(),
                available,
            });
        }
    }
    // Loading reports the missing `_fc1.npy` with its path.
    Ok(path)
}

macro_rules! dispatch {
    ($self:ident, $b:ident => $e:expr) => {
        match $self {
            MeasuredBsdf::Merl($b) => $e,
            MeasuredBsdf::Nbrdf($b) => $e,
            MeasuredBsdf::Neural($b) => $e,
        }
    };
}

impl Bxdf for MeasuredBsdf {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        dispatch!(self, b => b.eval(wo, wi))
    }
    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        dispatch!(self, b => b.pdf(wo, wi))
    }
    #[inline]
    fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        dispatch!(self, b => b.sample(wo, u, uc))
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::bsdf::tabulated_sampling::TabulatedSamplerConfig;
    use crate::chi2::{self, Chi2Config, Chi2Domain};
    use crate::merl::MerlTable;
    use crate::nbrdf::tests::{data_dir, merl_network};
    use std::collections::HashMap;
    use std::sync::{Arc, Mutex, OnceLock};

    /// Materials of the chi-square tests: a mirror-like metal, a diffuse one, a rough metal,
    /// a metallic paint and a near-black glossy one.
    pub(crate) const CHI2_MATERIALS: [&str; 5] = [
        "chrome",
        "white-diffuse-bball",
        "alum-bronze",
        "gold-metallic-paint",
        "black-obsidian",
    ];
    /// Viewing angles θo (radians) of the chi-square tests: 0°, 45°, 80°.
    pub(crate) const CHI2_THETAS: [f32; 3] = [
        0.0,
        std::f32::consts::FRAC_PI_4,
        80.0 * std::f32::consts::PI / 180.0,
    ];
    /// Chi-square tests in the family (tabulated, NBRDF and FreNBRDF), for the Šidák
    /// correction.
    const CHI2_TESTS: usize = 3 * CHI2_MATERIALS.len() * CHI2_THETAS.len();

    /// The MERL-layout table of a merl/ network, tabulated in memory once per test process.
    pub(crate) fn merl_fitted_table(name: &str) -> Arc<MerlTable> {
        /// One slot per material, filled by the first test that needs it.
        type Slot = Arc<OnceLock<Arc<MerlTable>>>;
        static CACHE: OnceLock<Mutex<HashMap<String, Slot>>> = OnceLock::new();
        let slot = {
            let mut cache = CACHE.get_or_init(Default::default).lock().unwrap();
            cache.entry(name.to_string()).or_default().clone()
        };
        slot.get_or_init(|| {
            let net = merl_network(name);
            Arc::new(MerlTable::from_fn(|th, td, pd| net.eval_angles(th, td, pd)))
        })
        .clone()
    }

    /// The NBRDF BSDF of a merl/ network.
    pub(crate) fn nbrdf_bsdf(name: &str) -> NbrdfBsdf {
        NbrdfBsdf::new(merl_network(name), &TabulatedSamplerConfig::default())
    }

    pub(crate) fn check_chi2(bxdf: &(impl Bxdf + ?Sized), name: &str, theta_o: f32) {
        let wo = Vec3::new(theta_o.sin() * 0.6, theta_o.sin() * 0.8, theta_o.cos());
        // Tabulated samplers put rows 0.02° wide at h = n: a mirror-like material's density
        // is a spike there, which 128 Simpson steps per cell cannot integrate (1.027 for a
        // decoded chrome at θo = 80°); refine up to 1024.
        let config = Chi2Config {
            max_subdivisions: 1024,
            ..Chi2Config::default()
                .with_sample_count(200_000)
                .with_domain(Chi2Domain::ThetaPhi)
                .with_test_count(CHI2_TESTS)
        };
        let result = chi2::test_bxdf(bxdf, wo, &config);
        assert!(result.passed(), "{name}, θo = {theta_o}\n{result}");
        let report = chi2::check_sample_consistency(bxdf, wo, 2_000);
        assert!(report.passed(), "{name}, θo = {theta_o}\n{report}");
    }

    fn unit(theta: f32, phi: f32) -> Vec3 {
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    /// Energy (pbrt-v4's test): the directional albedo of the tabulated, NBRDF and decoded
    /// FreNBRDF BSDFs of the chi-square materials stays below 1.01 for θo from 0° to 85°
    /// (Monte Carlo with importance sampling, 50 k samples per direction).
    #[test]
    fn measured_brdfs_do_not_create_energy() {
        use crate::bsdf::merl::{Interpolation, MerlBsdf};
        let latents = crate::bsdf::frenbrdf::tests::shipped_latents();
        for name in CHI2_MATERIALS {
            let table = MerlBsdf::new(&merl_fitted_table(name), Interpolation::Trilinear, &TabulatedSamplerConfig::default());
            let network = nbrdf_bsdf(name);
            let neural = latents.decode(name).unwrap();
            let kinds: [(&str, &dyn Bxdf); 3] = [("table", &table), ("nbrdf", &network), ("frenbrdf", &neural)];
            for (kind, bsdf) in kinds {
                for degrees in [0.0f32, 30.0, 60.0, 80.0, 85.0] {
                    let t = degrees.to_radians();
                    let albedo = chi2::directional_albedo(bsdf, Vec3::new(t.sin(), 0.0, t.cos()), 50_000);
                    assert!(albedo.max_element() < 1.01, "{kind} {name} at θo = {degrees}°: albedo {albedo}");
                }
            }
        }
    }

    /// No NaN, Inf or negative value or density anywhere, including grazing angles
    /// (θ → 90°), the mirror configuration (h = n), retro-reflection and below the horizon.
    pub(crate) fn check_stability(bxdf: &(impl Bxdf + ?Sized)) {
        use std::f32::consts::FRAC_PI_2;
        let thetas = [
            0.0,
            1e-6,
            0.3,
            0.8,
            1.2,
            1.5,
            FRAC_PI_2 - 1e-3,
            FRAC_PI_2 - 1e-6,
            FRAC_PI_2,
            FRAC_PI_2 + 1e-3,
        ];
        let phis = [0.0, 0.5, 3.0, std::f32::consts::PI];
        let mut dirs: Vec<Vec3> = Vec::new();
        for &t in &thetas {
            for &p in &phis {
                dirs.push(unit(t, p));
            }
        }
        for &wo in &dirs {
            let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
            for wi in dirs.iter().copied().chain([mirror, wo]) {
                let f = bxdf.eval(wo, wi);
                let p = bxdf.pdf(wo, wi);
                assert!(
                    f.is_finite() && f.min_element() >= 0.0,
                    "f({wo}, {wi}) = {f}"
                );
                assert!(p.is_finite() && p >= 0.0, "pdf({wo}, {wi}) = {p}");
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    assert_eq!(f, Rgb::ZERO);
                    assert_eq!(p, 0.0);
                }
            }
            for k in 0..64u32 {
                let u = Vec2::new((k as f32 + 0.5) / 64.0, ((k * 37) % 64) as f32 / 64.0);
                if let Some(s) = bxdf.sample(wo, u, ((k * 11) % 64) as f32 / 64.0) {
                    assert!(s.wi.is_finite() && s.wi.z > 0.0 && wo.z > 0.0);
                    assert!(s.pdf.is_finite() && s.pdf > 0.0, "{s:?}");
                    assert!(s.f.is_finite() && s.f.min_element() >= 0.0, "{s:?}");
                    let w = s.weight();
                    assert!(w.is_finite(), "{s:?}");
                }
            }
        }
    }

    /// Mean and variance of the one-sample estimator of the directional albedo (mean over
    /// RGB) of f cos θi / pdf, with wi from `bxdf.sample` (`importance`) or from the cosine
    /// lobe, `n` independent samples.
    pub(crate) fn albedo_estimator(
        bxdf: &(impl Bxdf + ?Sized),
        wo: Vec3,
        n: usize,
        importance: bool,
    ) -> (f64, f64) {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(7);
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let u = Vec2::new(rng.random(), rng.random());
            let uc: f32 = rng.random();
            let x = if importance {
                bxdf.sample(wo, u, uc).map_or(0.0, |s| {
                    let w = s.weight();
                    (w.x + w.y + w.z) as f64 / 3.0
                })
            } else {
                let wi = crate::sampling::sample_cosine_hemisphere(u);
                if wi.z > 0.0 {
                    let f = bxdf.eval(wo, wi);
                    (f.x + f.y + f.z) as f64 / 3.0 * std::f64::consts::PI
                } else {
                    0.0
                }
            };
            sum += x;
            sum2 += x * x;
        }
        let mean = sum / n as f64;
        (mean, (sum2 / n as f64 - mean * mean).max(0.0))
    }

    #[test]
    fn importance_sampling_beats_cosine_sampling() {
        // Directional albedo at θo = 45°: both estimators agree (unbiased) and importance
        // sampling has a much lower variance for the peaky chrome, lower for the rough metal.
        let wo = Vec3::new(
            std::f32::consts::FRAC_1_SQRT_2,
            0.0,
            std::f32::consts::FRAC_1_SQRT_2,
        );
        let n = 200_000;
        for (name, min_ratio) in [("chrome", 20.0), ("alum-bronze", 2.0)] {
            let table = merl_fitted_table(name);
            let merl = MerlBsdf::new(
                &table,
                super::super::merl::Interpolation::Trilinear,
                &TabulatedSamplerConfig::default(),
            );
            let nbrdf = nbrdf_bsdf(name);
            for (kind, bxdf) in [("merl", &merl as &dyn Bxdf), ("nbrdf", &nbrdf as &dyn Bxdf)] {
                let (m_is, v_is) = albedo_estimator(bxdf, wo, n, true);
                let (m_cos, v_cos) = albedo_estimator(bxdf, wo, n, false);
                let ratio = v_cos / v_is;
                println!(
                    "{name} ({kind}) θo = 45°: albedo {m_is:.4} (importance) / {m_cos:.4} (cosine), variance {v_is:.3e} / {v_cos:.3e}, ratio {ratio:.1}"
                );
                let standard_error = ((v_is + v_cos) / n as f64).sqrt();
                assert!(
                    (m_is - m_cos).abs() < 5.0 * standard_error,
                    "{name} {kind}: biased?"
                );
                assert!(ratio > min_ratio, "{name} {kind}: variance ratio {ratio}");
            }
        }
    }

    #[test]
    fn chrome_peak_is_kept_finite_and_unclamped() {
        // README: at θh = 0, θd = 0.3 chrome gives about (494, 538, 537) 1/sr.
        let table = merl_fitted_table("chrome");
        let merl = MerlBsdf::new(
            &table,
            super::super::merl::Interpolation::Trilinear,
            &TabulatedSamplerConfig::default(),
        );
        let nbrdf = nbrdf_bsdf("chrome");
        let wo = unit(0.3, 1.0);
        let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
        for (kind, bxdf) in [("merl", &merl as &dyn Bxdf), ("nbrdf", &nbrdf as &dyn Bxdf)] {
            let f = bxdf.eval(wo, mirror);
            assert!(
                f.min_element() > 400.0 && f.max_element() < 650.0,
                "{kind}: {f}"
            );
            let p = bxdf.pdf(wo, mirror);
            assert!(p.is_finite() && p > 10.0, "{kind}: pdf {p}");
            check_stability(bxdf);
        }
    }

    #[test]
    fn specs_load_both_kinds() {
        let dir = data_dir().join("merl");
        let spec = format!("nbrdf:{}", dir.join("alum-bronze").display());
        assert!(matches!(
            MeasuredBsdf::load(&spec).unwrap(),
            MeasuredBsdf::Nbrdf(_)
        ));
        let spec = format!("nbrdf:{}", dir.join("alum-bronze_fc3.npy").display());
        assert!(matches!(
            MeasuredBsdf::load(&spec).unwrap(),
            MeasuredBsdf::Nbrdf(_)
        ));
        let b = MeasuredBsdf::load_relative_to("nbrdf:merl/chrome", Some(&data_dir())).unwrap();
        assert!(matches!(b, MeasuredBsdf::Nbrdf(_)));

        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("grey.binary");
        MerlTable::from_fn(|_, _, _| Rgb::splat(0.1))
            .write(&path)
            .unwrap();
        let b = MeasuredBsdf::load(&format!("merl:{}", path.display())).unwrap();
        assert!(matches!(b, MeasuredBsdf::Merl(_)));
        let b = MeasuredBsdf::load_relative_to("merl:grey", Some(tmp.path())).unwrap();
        let f = b.eval(Vec3::Z, Vec3::new(0.6, 0.0, 0.8));
        assert!((f - Rgb::splat(0.1)).abs().max_element() < 1e-6, "{f}");
    }

    #[test]
    fn bad_specs_name_the_spec_or_file() {
        let e = MeasuredBsdf::load("phong:foo.bin").unwrap_err();
        assert!(matches!(e, Error::UnknownName { .. }));
        let msg = e.to_string();
        assert!(
            msg.contains("phong:foo.bin") && msg.contains("merl:PATH.binary"),
            "{msg}"
        );

        let msg = MeasuredBsdf::load("just-a-path.binary")
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("just-a-path.binary") && msg.contains("KIND:PATH"),
            "{msg}"
        );

        let msg = MeasuredBsdf::load("merl:").unwrap_err().to_string();
        assert!(
            msg.contains("'merl:'") && msg.contains("empty path"),
            "{msg}"
        );

        let msg = MeasuredBsdf::load("merl:/nonexistent/x.binary")
            .unwrap_err()
            .to_string();
        assert!(msg.contains("/nonexistent/x.binary"), "{msg}");

        let spec = format!("nbrdf:{}", data_dir().join("merl/alum-bronz").display());
        let e = MeasuredBsdf::load(&spec).unwrap_err();
        let msg = e.to_string();
        assert!(
            matches!(e, Error::UnknownName { .. })
                && msg.contains("alum-bronz'")
                && msg.contains("alum-bronze,"),
            "{msg}"
        );

        let msg = MeasuredBsdf::load(&format!("nbrdf:{}", data_dir().join("merl").display()))
            .unwrap_err()
            .to_string();
        assert!(msg.contains("100 NBRDF networks"), "{msg}");

        let msg = MeasuredBsdf::load("nbrdf:/nonexistent/dir/x")
            .unwrap_err()
            .to_string();
        assert!(msg.contains("/nonexistent/dir/x_fc1.npy"), "{msg}");

        let tmp = tempfile::tempdir().unwrap();
        let bad = tmp.path().join("short.binary");
        let mut bytes: Vec<u8> = [90i32, 90, 180]
            .iter()
            .flat_map(|d| d.to_le_bytes())
            .collect();
        bytes.extend_from_slice(&[0u8; 88]);
        std::fs::write(&bad, bytes).unwrap();
        let msg = MeasuredBsdf::load(&format!("merl:{}", bad.display()))
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("short.binary") && msg.contains("truncated"),
            "{msg}"
        );
    }

    #[test]
    fn dispatch_matches_inner_bsdf() {
        let spec = format!("nbrdf:{}", data_dir().join("merl/alum-bronze").display());
        let m = MeasuredBsdf::load(&spec).unwrap();
        let MeasuredBsdf::Nbrdf(inner) = &m else {
            panic!("expected an NBRDF");
        };
        let (wo, wi) = (unit(0.5, 0.2), unit(0.7, 2.5));
        assert_eq!(m.eval(wo, wi), inner.eval(wo, wi));
        assert_eq!(m.pdf(wo, wi), inner.pdf(wo, wi));
        assert_eq!(
            m.sample(wo, Vec2::new(0.3, 0.6), 0.7),
            inner.sample(wo, Vec2::new(0.3, 0.6), 0.7)
        );
    }
}
