//! The shipped scene `scenes/glass-and-coats` (made by
//! `assets-scripts/make_glass_and_coats_scene.py`): clear and tinted solid glass, a frosted
//! pane, a clear-coated neural paint and a sheen cloth, read from their glTF extensions and
//! rendered as pinned, without a NaN or infinite sample.

use neural_brdf_tests::{pinned, render};
use renderer::integrator::{PathTracer, Strategy};
use renderer::neural::latent_library::LatentLibrary;
use renderer::render_scene::RenderScene;
use renderer::scene::{Binding, Material, SceneDescription, SurfaceModel};
use std::path::PathBuf;

fn description() -> SceneDescription {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    SceneDescription::load(&root.join("scenes/glass-and-coats/scene.gltf")).expect("scene")
}

fn material<'a>(scene: &'a SceneDescription, name: &str) -> &'a Material {
    scene.materials.iter().find(|m| m.name == name).unwrap_or_else(|| panic!("material {name}"))
}

/// Each material carries the extension it shows: solid glass (transmission with a volume;
/// the amber one absorbing most in blue), rough glass, a coat over a bound latent code, a
/// sheen; and the file loads without a warning (every extension it uses is read).
#[test]
fn the_shipped_scene_uses_each_layer_and_glass() {
    let scene = description();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    for name in ["clear-glass", "amber-glass", "frosted-glass"] {
        let glass = material(&scene, name);
        assert_eq!(glass.transmission, 1.0, "{name}");
        assert!(glass.volume.is_some(), "{name} is solid");
    }
    let amber = material(&scene, "amber-glass").volume.expect("volume").sigma_a;
    assert!(amber.z > amber.y && amber.y > amber.x && amber.x > 0.0, "amber absorbs blue most: {amber}");
    assert!(material(&scene, "frosted-glass").roughness > 0.2);
    let paint = material(&scene, "coated-paint");
    assert!(paint.clearcoat.is_some());
    assert!(matches!(&paint.model, SurfaceModel::Bound(Binding::Neural(code)) if code == "blue-metallic-paint"), "{:?}", paint.model);
    assert!(material(&scene, "velvet").sheen.is_some());
}

/// `scenes/glass-and-coats` with the shipped latent file, 96 × 48, 12 spp, as pinned.
#[test]
fn the_shipped_scene_renders_as_pinned() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let latents = LatentLibrary::load(&[root.join("scenes/materials/latent.bin")]).expect("shipped latents");
    let description = description();
    let camera = description.camera(None).expect("camera").clone();
    let scene = RenderScene::with_latents(description, &latents).expect("scene");
    let img = render(&scene, &camera, 96, 48, 12, PathTracer { max_depth: 8, strategy: Strategy::Mis, ..PathTracer::default() }, 1);
    assert_eq!(img.discarded, 0, "NaN or infinite samples");
    pinned::check("glass-and-coats", &img);
}
