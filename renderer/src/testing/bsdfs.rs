//! Checks shared by the tests of every BSDF made from data (MERL table, NBRDF network,
//! decoded latent code): the chi-square materials and viewing angles, the fitted tables,
//! chi-square and stability checks, and the tests that compare the three kinds.

use crate::bsdf::nbrdf::NbrdfBsdf;
use crate::bsdf::merl::MerlBsdf;
use crate::bsdf::Bxdf;
use crate::Rgb;
use glam::{Vec2, Vec3};
use crate::bsdf::tabulated_sampling::TabulatedSamplerConfig;
use crate::testing::chi2::{self, Chi2Config, Chi2Domain};
use crate::formats::merl::MerlTable;
use crate::testing::data::merl_network;
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
    let latents = crate::testing::data::shipped_latents();
    for name in CHI2_MATERIALS {
        let table = MerlBsdf::new(&merl_fitted_table(name), Interpolation::Trilinear, &TabulatedSamplerConfig::default());
        let network = nbrdf_bsdf(name);
        let neural = latents.decode(name).unwrap();
        let kinds: [(&str, &dyn Bxdf); 3] = [("table", &table), ("nbrdf", &network), ("frenbrdf", &neural)];
        for (kind, bsdf) in kinds {
            for degrees in [0.0f32, 30.0, 60.0, 80.0, 85.0] {
                let t = degrees.to_radians();
                let albedo = crate::bsdf::albedo::directional_albedo(bsdf, Vec3::new(t.sin(), 0.0, t.cos()), 50_000);
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
            crate::bsdf::merl::Interpolation::Trilinear,
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
    // ../shared/data/nbrdf/README.md: at θh = 0, θd = 0.3 chrome gives about (494, 538, 537) 1/sr.
    let table = merl_fitted_table("chrome");
    let merl = MerlBsdf::new(
        &table,
        crate::bsdf::merl::Interpolation::Trilinear,
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

