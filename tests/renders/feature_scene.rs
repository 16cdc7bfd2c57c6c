//! `scenes/feature-showcase` (written by `assets-scripts/make_feature_scene.py`): one glTF
//! file with every glTF feature the renderer reads — JPEG and 16-bit PNG textures,
//! `KHR_texture_transform`, a second texture-coordinate set, sampler wrap and filter modes,
//! normal maps with file and MikkTSpace tangents, an alpha cut-out and a blended pane, an
//! emissive texture with `KHR_materials_emissive_strength`, `KHR_materials_ior` and
//! `KHR_materials_specular`, one mesh on 18 nodes, punctual lights in photometric units —
//! rendered with its sphere bound to the alum-bronze code of the shipped latent file.
//!
//! - A pinned image (`tests/references/pinned/feature-showcase.exr`) holds the render.
//! - MIS, BSDF-only and light-only renders agree within noise: light sampling of the
//!   textured emitter (the texel where the sample lands) and shadow rays through cut-outs
//!   see the same scene as the rays that hit it.

use neural_brdf_tests::{image_mean_z, mean_rgb, pinned, render, Rendered};
use renderer::integrator::{PathTracer, Strategy};
use renderer::material::SharedBsdf;
use renderer::neural::latent_library::LatentLibrary;
use renderer::render_scene::RenderScene;
use renderer::scene::{AlphaMode, Camera, SceneDescription};
use std::path::PathBuf;

const SIZE: u32 = 48;
const SPP: u32 = 64;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn scene() -> (RenderScene, Camera) {
    let description = SceneDescription::load(&root().join("scenes/feature-showcase/scene.gltf")).expect("feature scene");
    assert!(description.warnings.is_empty(), "every feature is supported: {:?}", description.warnings);
    let m = &description.materials;
    let find = |name: &str| m.iter().find(|m| m.name == name).unwrap_or_else(|| panic!("material {name}"));
    assert!(find("fence-cutout").base_color_texture.is_some() && matches!(find("fence-cutout").alpha_mode, AlphaMode::Mask { .. }));
    assert_eq!(find("stained-glass").alpha_mode, AlphaMode::Blend);
    assert!(find("emissive-sign").emissive_texture.is_some());
    assert!(find("brick").normal_texture.is_some() && find("ground-tiles").normal_texture.is_some());
    assert_eq!(find("glossy-plastic").ior, 1.8);
    let camera = description.camera(None).expect("camera").clone();
    let latents = LatentLibrary::load(&[root().join("scenes/materials/latent.bin")]).expect("shipped latents");
    let scene = RenderScene::with_latents(description, &latents).expect("scene");
    let slot = scene.materials.shared_slot("neural-sphere").expect("the sphere is bound");
    assert!(matches!(scene.materials.shared()[slot], SharedBsdf::Neural(_)), "bound to a latent code");
    (scene, camera)
}

fn render_with((scene, camera): &(RenderScene, Camera), strategy: Strategy, seed: u64) -> Rendered {
    let integrator = PathTracer { max_depth: 6, strategy, ..PathTracer::default() };
    render(scene, camera, SIZE, SIZE, SPP, integrator, seed)
}

/// Re-bless on purpose with `BLESS=1 cargo test --test renders -- feature_scene::`.
#[test]
fn feature_scene_renders_as_pinned_and_its_estimators_agree() {
    let scene = scene();
    let mis = render_with(&scene, Strategy::Mis, 1);
    assert_eq!(mis.discarded, 0);
    pinned::check("feature-showcase", &mis);
    for (strategy, seed) in [(Strategy::BsdfOnly, 2), (Strategy::LightOnly, 3)] {
        let other = render_with(&scene, strategy, seed);
        assert_eq!(other.discarded, 0, "{strategy:?}");
        let z = image_mean_z(&mis, &other);
        assert!(z < 4.5, "{strategy:?}: {} vs MIS {}, z = {z}", mean_rgb(&other.mean), mean_rgb(&mis.mean));
    }
}

/// The 18 rocks are one mesh stored once and placed by 18 instances (two-level
/// acceleration); rendered as 18 copies instead, the image with the same seed is the same
/// up to rounding (intersections computed in the mesh's space).
#[test]
fn instanced_meshes_render_like_their_copies() {
    let description = SceneDescription::load(&root().join("scenes/feature-showcase/scene.gltf")).expect("feature scene");
    assert_eq!((description.meshes.len(), description.instances.len()), (1, 18));
    let camera = description.camera(None).expect("camera").clone();
    let flat = description.clone().flatten_instances().expect("flatten");
    assert_eq!(flat.geometry.triangle_count() as u64, description.triangle_instance_count());
    let integrator = PathTracer { max_depth: 6, ..PathTracer::default() };
    let [instanced, copied] = [description, flat].map(|d| render(&RenderScene::new(d).expect("scene"), &camera, SIZE, SIZE, SPP, integrator, 5));
    let d = pinned::relative_difference(&instanced.mean, &copied.mean);
    assert!(d < 2e-3, "mean relative difference {:.3} %", 100.0 * d);
}
