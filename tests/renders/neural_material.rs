//! A neural material in a scene: `scenes/material-preview` with its sphere bound to the
//! alum-bronze latent code of the shipped `scenes/materials/latent.bin`, compared with a
//! committed reference (statistical test), with MIS, BSDF-only and light-only estimators
//! agreeing, and no NaN/Inf sample.

use neural_brdf_tests::regression::Case;
use neural_brdf_tests::{image_mean_z, mean_rgb, render, Rendered};
use renderer::integrator::{PathTracer, Strategy};
use renderer::neural::latent_library::LatentLibrary;
use renderer::material::{Binding, SharedBsdf};
use renderer::render_scene::RenderScene;
use renderer::scene::{SceneDescription, SurfaceModel};
use std::path::PathBuf;

const SIZE: u32 = 48;
const CASE: Case = Case {
    name: "neural-alum-bronze",
    test_spp: 64,
    reference_spp: 4096,
};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn render_preview(spp: u32, seed: u64, strategy: Strategy) -> Rendered {
    render_preview_towards(spp, seed, strategy, 0.0)
}

/// The preview with the code (1 − t) z_alum-bronze + t z_chrome.
fn render_preview_towards(spp: u32, seed: u64, strategy: Strategy, t: f32) -> Rendered {
    let mut description = SceneDescription::load(&root().join("scenes/material-preview/scene.gltf")).expect("scene");
    let m = description.materials.iter_mut().find(|m| m.name == "preview").expect("preview material");
    m.model = SurfaceModel::Bound(Binding::Neural("alum-bronze".into()));
    let camera = description.camera(None).expect("camera").clone();
    let latents = LatentLibrary::load(&[root().join("scenes/materials/latent.bin")]).expect("shipped latents");
    let mut scene = RenderScene::with_latents(description, &latents).expect("scene");
    if t != 0.0 {
        let (a, b) = (latents.latent("alum-bronze").unwrap(), latents.latent("chrome").unwrap());
        let code = a.lerp(&b, t).unwrap();
        for slot in scene.materials.neural_slots() {
            scene.materials.set_shared(slot, SharedBsdf::Neural(latents.decode_code(&code, "edited").unwrap()));
        }
    }
    let integrator = PathTracer {
        max_depth: 8,
        strategy,
        ..PathTracer::default()
    };
    render(&scene, &camera, SIZE, SIZE, spp, integrator, seed)
}

/// Re-bless on purpose (after re-training the shipped model) with
/// `BLESS=1 cargo test --release --test renders -- neural_material::regression`.
#[test]
fn regression_against_reference() {
    CASE.check(|spp, seed| render_preview(spp, seed, Strategy::Mis));
}

/// The test has power: moving the latent code 10 % of the way toward chrome fails it.
#[test]
fn regression_detects_an_edited_code() {
    let img = render_preview_towards(CASE.test_spp, 7, Strategy::Mis, 0.1);
    let (report, _) = CASE.compare(&img);
    assert!(!report.passed, "{:.4} % pass, mean p = {:.2e}", 100.0 * report.pass_fraction, report.mean_p_value);
}

/// MIS on and off (BSDF sampling only, light sampling only) give the same image mean within
/// noise (z < 4.5 per channel, from the variance images): the neural BSDF's sampling density
/// and values agree.
#[test]
fn estimators_agree() {
    let mis = render_preview(64, 1, Strategy::Mis);
    assert_eq!(mis.discarded, 0);
    for strategy in [Strategy::BsdfOnly, Strategy::LightOnly] {
        let other = render_preview(64, 2, strategy);
        assert_eq!(other.discarded, 0, "{strategy:?}");
        let z = image_mean_z(&mis, &other);
        assert!(z < 4.5, "{strategy:?}: {} vs MIS {}, z = {z}", mean_rgb(&other.mean), mean_rgb(&mis.mean));
    }
}
