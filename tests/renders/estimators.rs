//! MIS on and off: for every BSDF that samples, `scenes/material-preview` (environment map,
//! key light, sphere on a ground plane) rendered with MIS, with BSDF sampling only and with
//! light sampling only has the same image mean within noise (a z-test from the variance
//! images). A BSDF whose `sample` and `pdf` disagree, or whose weights are wrong, fails it.
//! The MIS and light-only renders of each are also pinned images
//! (`tests/references/pinned/preview-*.exr`): the same seed gives the same image, so a 2 %
//! change of any BSDF's value fails one of them (of `sample`'s value the MIS image, of
//! `eval`'s, which MIS weighs little on a glossy lobe, the light-only image).
//! (The neural BSDF's case is in `neural_material.rs`.)

use neural_brdf_tests::{image_mean_z, mean_rgb, pinned, render, Rendered};
use renderer::integrator::{PathTracer, Strategy};
use renderer::material::Binding;
use renderer::formats::merl::MerlTable;
use renderer::neural::nbrdf::NbrdfNetwork;
use renderer::render_scene::RenderScene;
use renderer::scene::{SceneDescription, SurfaceModel};
use std::path::PathBuf;

const SIZE: u32 = 40;
const SPP: u32 = 64;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn render_with(model: &SurfaceModel, strategy: Strategy, seed: u64) -> Rendered {
    let mut description = SceneDescription::load(&root().join("scenes/material-preview/scene.gltf")).expect("scene");
    for m in description.materials.iter_mut().filter(|m| m.name == "preview") {
        m.model = model.clone();
    }
    let camera = description.camera(None).expect("camera").clone();
    let scene = RenderScene::new(description).expect("scene");
    let integrator = PathTracer {
        max_depth: 6,
        strategy,
        ..PathTracer::default()
    };
    render(&scene, &camera, SIZE, SIZE, SPP, integrator, seed)
}

fn check(label: &str, model: SurfaceModel) {
    let mis = render_with(&model, Strategy::Mis, 1);
    assert_eq!(mis.discarded, 0, "{label}");
    pinned::check(&format!("preview-{label}"), &mis);
    for (strategy, seed) in [(Strategy::BsdfOnly, 2), (Strategy::LightOnly, 3)] {
        let other = render_with(&model, strategy, seed);
        assert_eq!(other.discarded, 0, "{label} {strategy:?}");
        if strategy == Strategy::LightOnly {
            pinned::check(&format!("preview-{label}-light-only"), &other);
        }
        let z = image_mean_z(&mis, &other);
        assert!(z < 4.5, "{label} {strategy:?}: {} vs MIS {}, z = {z}", mean_rgb(&other.mean), mean_rgb(&mis.mean));
    }
}

#[test]
fn lambert() {
    check("lambert", SurfaceModel::Lambert);
}

#[test]
fn metallic_roughness() {
    check("metallic-roughness", SurfaceModel::MetallicRoughness);
}

#[test]
fn measured_table_and_network() {
    let net_prefix = root().join("../shared/data/nbrdf/merl/gold-metallic-paint");
    check("nbrdf", SurfaceModel::Bound(Binding::Nbrdf(net_prefix.clone())));
    let dir = tempfile::tempdir().expect("tempdir");
    let table = dir.path().join("gold-metallic-paint.binary");
    let net = NbrdfNetwork::load(&net_prefix).expect("network");
    MerlTable::from_fn(|th, td, pd| net.eval_angles(th, td, pd)).write(&table).expect("table");
    check("merl", SurfaceModel::Bound(Binding::Merl(table)));
}
