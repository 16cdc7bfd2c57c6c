//! Stiff and extreme inputs: tiny very bright emitters, degenerate and sliver triangles,
//! zero-area lights, a camera inside geometry, and a real HDR environment with a small, very
//! bright sun. Each must render without NaN/Inf pixels or panics, and where an answer is known
//! the estimators must agree on it.

use glam::{Vec2, Vec3};
use neural_brdf_tests::shapes::{add_floor, add_sphere, sphere_in_furnace};
use neural_brdf_tests::{look_at, mean_rgb, render};
use renderer::integrator::{PathTracer, Strategy};
use renderer::render_scene::RenderScene;
use renderer::scene::{EnvironmentSource, EnvironmentSpec, Geometry, Material, SceneDescription, SurfaceModel};
use renderer::Rgb;
use std::path::PathBuf;

fn material(name: &str, model: SurfaceModel, base: f32, emission: f32) -> Material {
    Material {
        name: name.into(),
        model,
        base_color: Rgb::splat(base),
        emission: Rgb::splat(emission),
        metallic: 1.0,
        roughness: 0.05,
        ..Material::default_diffuse(name)
    }
}

fn add_triangle(g: &mut Geometry, corners: [Vec3; 3], material: u32) {
    let base = g.positions.len() as u32;
    let n = (corners[1] - corners[0]).cross(corners[2] - corners[0]).try_normalize().unwrap_or(Vec3::Y);
    for c in corners {
        g.positions.push(c);
        g.normals.push(n);
        g.uvs.push(Vec2::ZERO);
    }
    g.triangles.push([base, base + 1, base + 2]);
    g.material_ids.push(material);
}

fn assert_finite(img: &neural_brdf_tests::Rendered, what: &str) {
    assert!(img.mean.iter().all(|p| p.is_finite() && p.min_element() >= 0.0), "{what}: non-finite or negative pixel");
}

/// A 1e6-radiance emitter of tiny area over a mirror-like metal and a diffuse floor, plus a
/// zero-area "light", degenerate and sliver triangles, all in one scene.
#[test]
fn tiny_bright_emitter_degenerate_and_sliver_triangles() {
    let mut g = Geometry::default();
    add_floor(&mut g, 0.0, 4.0, 0);
    add_sphere(&mut g, Vec3::new(0.0, 0.5, 0.0), 0.5, 16, 32, false, 1);
    let s = 1e-3;
    // Wound so its front (emitting) side faces down, toward the floor.
    add_triangle(&mut g, [Vec3::new(0.0, 2.0, 0.0), Vec3::new(s, 2.0, 0.0), Vec3::new(0.0, 2.0, s)], 2);
    // Zero-area emitter and degenerate (collinear, repeated-vertex) triangles.
    add_triangle(&mut g, [Vec3::new(1.0, 1.0, 1.0); 3], 2);
    add_triangle(&mut g, [Vec3::new(-1.0, 0.5, 0.0), Vec3::new(0.0, 0.5, 0.0), Vec3::new(1.0, 0.5, 0.0)], 0);
    // A sliver: 1e-7 wide, 2 long.
    add_triangle(&mut g, [Vec3::new(-1.0, 0.2, 1.0), Vec3::new(1.0, 0.2, 1.0), Vec3::new(0.0, 0.2, 1.0 + 1e-7)], 1);
    let description = SceneDescription {
        geometry: g,
        materials: vec![
            material("floor", SurfaceModel::Lambert, 0.5, 0.0),
            material("chrome", SurfaceModel::MetallicRoughness, 0.95, 0.0),
            material("light", SurfaceModel::Lambert, 0.0, 1e6),
        ],
        ..SceneDescription::default()
    };
    let scene = RenderScene::new(description).expect("scene");
    let cam = look_at(Vec3::new(0.0, 1.5, 3.0), Vec3::new(0.0, 0.4, 0.0), 45.0);
    for strategy in [Strategy::Mis, Strategy::BsdfOnly, Strategy::LightOnly] {
        let img = render(&scene, &cam, 24, 24, 16, PathTracer { max_depth: 6, strategy, ..PathTracer::default() }, 5);
        assert_finite(&img, &format!("{strategy:?}"));
        assert_eq!(img.discarded, 0, "{strategy:?}");
    }
    // Light sampling finds the tiny emitter: the floor under it is lit.
    let img = render(&scene, &cam, 24, 24, 16, PathTracer { max_depth: 2, ..PathTracer::default() }, 5);
    assert!(mean_rgb(&img.mean).x > 1e-3, "{}", mean_rgb(&img.mean));
}

/// A camera inside a closed object sees only its inside: finite, and black without emitters.
#[test]
fn camera_inside_geometry() {
    let description = sphere_in_furnace(material("white", SurfaceModel::Lambert, 0.8, 0.0), 12, 24);
    let scene = RenderScene::new(description).expect("scene");
    let img = render(&scene, &look_at(Vec3::ZERO, Vec3::Z, 45.0), 16, 16, 8, PathTracer::default(), 1);
    assert_finite(&img, "inside");
    assert!(mean_rgb(&img.mean).max_element() < 1e-6, "light leaked inside: {}", mean_rgb(&img.mean));
}

/// Under a real HDR map with a small, very bright sun (venice_sunset), environment importance
/// sampling (MIS) and BSDF sampling alone estimate the same image mean.
#[test]
fn bright_sun_environment_estimators_agree() {
    let envmap = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/envmaps/venice_sunset_1k.hdr");
    let mut g = Geometry::default();
    add_sphere(&mut g, Vec3::ZERO, 1.0, 16, 32, false, 0);
    let description = SceneDescription {
        geometry: g,
        materials: vec![material("white", SurfaceModel::Lambert, 0.8, 0.0)],
        environment: Some(EnvironmentSpec {
            source: EnvironmentSource::Image(envmap),
            strength: 1.0,
            rotation: 0.3,
        }),
        ..SceneDescription::default()
    };
    let scene = RenderScene::new(description).expect("scene");
    let cam = look_at(Vec3::new(0.0, 0.0, 2.2), Vec3::ZERO, 45.0);
    let run = |strategy, spp| {
        let img = render(&scene, &cam, 12, 12, spp, PathTracer { max_depth: 3, strategy, ..PathTracer::default() }, 11);
        assert_finite(&img, "sunset");
        img
    };
    let mis = run(Strategy::Mis, 256);
    let bsdf = run(Strategy::BsdfOnly, 2048);
    let (a, b) = (mean_rgb(&mis.mean), mean_rgb(&bsdf.mean));
    let sigma = |img: &neural_brdf_tests::Rendered| {
        (img.variance.iter().fold(Rgb::ZERO, |s, v| s + *v) / (img.variance.len() * img.variance.len()) as f32).powf(0.5)
    };
    let tolerance = (sigma(&mis) + sigma(&bsdf)) * 4.0 + a * 0.01;
    assert!(((a - b).abs() - tolerance).max_element() <= 0.0, "MIS {a}, BSDF-only {b}, tolerance {tolerance}");
    // Per sample, MIS has the lower variance on a tiny bright source.
    let per_sample = |img, spp: f32| sigma(img).max_element() * spp.sqrt();
    assert!(per_sample(&mis, 256.0) < per_sample(&bsdf, 2048.0));
}

/// What came after the cases above — glass, clear coats and sheens, and spatially varying
/// neural materials — under the same stiff light: a 1e6-radiance emitter of 1e-6 area above
/// a sphere of each material on a diffuse floor, for every estimator, with a path depth that
/// lets light bounce inside glass. No sample may be discarded as NaN, infinite or negative
/// (`Rendered::discarded`, the renderer's counter) and no pixel may be non-finite. The
/// mixture's weights texture holds NaN, infinite, negative, zero, huge and subnormal texels
/// (each must count as 0 or be normalised away); the latent blend's t texture holds the
/// same texels (t is clamped to [0, 1], NaN read as 0, before its palette is chosen).
#[test]
fn glass_coats_and_neural_mixtures_stay_finite_under_a_tiny_bright_emitter() {
    use renderer::neural::latent_library::LatentLibrary;
    use renderer::scene::texture::Filter;
    use renderer::scene::{Binding, Clearcoat, SheenLayer, Texture, TextureRef, Varying, VaryingForm, Volume};
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let latents = LatentLibrary::load(&[root.join("scenes/materials/latent.bin")]).expect("shipped latents");
    use crate::glass::glass;
    let clear = Volume::from_attenuation(Rgb::ONE, f32::INFINITY);
    let coat = |roughness: f32| Some(Clearcoat { factor: 1.0, texture: None, roughness, roughness_texture: None, normal_texture: None });
    let sheen = |roughness: f32| Some(SheenLayer { color: Rgb::ONE, color_texture: None, roughness, roughness_texture: None });
    let texture = || TextureRef { filter: Filter::Nearest, ..TextureRef::new(0) };
    let neural = |form: VaryingForm| Material { model: SurfaceModel::Varying(Varying { form, tint: None }), ..Material::default_diffuse("neural") };
    let codes = ["alum-bronze", "chrome", "blue-fabric"];
    let mix = VaryingForm::Mix { parts: codes.iter().map(|c| Binding::Neural(c.to_string())).collect(), weights: texture() };
    let blend = VaryingForm::Blend { ends: ["alum-bronze".into(), "blue-fabric".into()], t: texture(), channel: 0 };
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    let texels = vec![
        Rgb::new(nan, 1.0, 0.0),
        Rgb::new(inf, 1.0, 1.0),
        Rgb::new(-1.0, 0.0, 0.0),
        Rgb::ZERO,
        Rgb::new(1e30, 1e30, 1e30),
        Rgb::new(1e-45, 0.0, 0.0),
        Rgb::new(2.0, -inf, nan),
        Rgb::new(0.3, 0.3, 0.4),
    ];
    let cases = [
        ("smooth glass", glass(0.0, 1.5, clear), None),
        ("glass of index 3, roughness 0.001", glass(0.001, 3.0, clear), None),
        ("thin-walled glass of index 1.0001", glass(0.0, 1.0001, None), None),
        ("coated mirror", Material { clearcoat: coat(0.0), ..material("metal", SurfaceModel::MetallicRoughness, 0.95, 0.0) }, None),
        ("coat and sheen over rough glass", Material { clearcoat: coat(0.001), sheen: sheen(1.0), ..glass(0.3, 1.5, clear) }, None),
        ("coated neural code", Material { clearcoat: coat(0.0), sheen: sheen(0.0), model: SurfaceModel::Bound(Binding::Neural("chrome".into())), ..Material::default_diffuse("coated chrome") }, None),
        ("neural mixture, extreme weights", neural(mix), Some(texels.clone())),
        ("latent blend, extreme t", neural(blend), Some(texels.clone())),
    ];
    let cam = look_at(Vec3::new(0.0, 1.5, 3.0), Vec3::new(0.0, 0.4, 0.0), 45.0);
    for (name, sphere, texels) in cases {
        let mut g = Geometry::default();
        add_floor(&mut g, 0.0, 4.0, 0);
        add_sphere(&mut g, Vec3::new(0.0, 0.5, 0.0), 0.5, 16, 32, false, 1);
        add_triangle(&mut g, [Vec3::new(0.0, 1.2, 0.0), Vec3::new(1e-3, 1.2, 0.0), Vec3::new(0.0, 1.2, 1e-3)], 2);
        let textures = texels.map(|texels| Texture::from_linear(texels.len() as u32, 1, texels, Vec::new())).into_iter().collect();
        let description = SceneDescription {
            geometry: g,
            materials: vec![material("floor", SurfaceModel::Lambert, 0.5, 0.0), sphere, material("light", SurfaceModel::Lambert, 0.0, 1e6)],
            textures,
            ..SceneDescription::default()
        };
        let scene = RenderScene::with_latents(description, &latents).unwrap_or_else(|e| panic!("{name}: {e}"));
        for strategy in [Strategy::Mis, Strategy::BsdfOnly, Strategy::LightOnly] {
            let img = render(&scene, &cam, 16, 16, 8, PathTracer { max_depth: 12, strategy, ..PathTracer::default() }, 7);
            assert_finite(&img, &format!("{name}, {strategy:?}"));
            assert_eq!(img.discarded, 0, "{name}, {strategy:?}");
        }
    }
}
