//! Clear coats and sheens in the path tracer: white furnaces (a layered white sphere loses a
//! little energy and gains none, with every estimator), a coat over glass, and a coated
//! neural material (the layers sit over any base).

use glam::Vec3;
use neural_brdf_tests::shapes::sphere_in_furnace;
use neural_brdf_tests::{look_at, mean_rgb, render};
use renderer::integrator::{PathTracer, Strategy};
use renderer::render_scene::RenderScene;
use renderer::scene::{Clearcoat, Material, SheenLayer, SurfaceModel, Volume};
use renderer::Rgb;

fn coat(roughness: f32) -> Clearcoat {
    Clearcoat { factor: 1.0, texture: None, roughness, roughness_texture: None, normal_texture: None }
}

fn sheen(roughness: f32) -> SheenLayer {
    SheenLayer { color: Rgb::ONE, color_texture: None, roughness, roughness_texture: None }
}

fn white(clearcoat: Option<Clearcoat>, sheen: Option<SheenLayer>) -> Material {
    Material { base_color: Rgb::ONE, clearcoat, sheen, ..Material::default_diffuse("white") }
}

/// Mean radiance of a sphere of `material` in the unit furnace, seen whole, per estimator.
/// Light sampling alone is heavy-tailed against a sharp coat (it reads a few per cent off at
/// these sample counts), so it is checked on the broad lobes only (`light_only`).
fn furnace(material: Material, spp: u32, light_only: bool) -> Vec<(Strategy, Rgb, u64)> {
    let scene = RenderScene::new(sphere_in_furnace(material, 48, 96)).expect("scene");
    let camera = look_at(Vec3::new(0.0, 0.0, 3.5), Vec3::ZERO, 40.0);
    let strategies: &[Strategy] = if light_only { &[Strategy::Mis, Strategy::BsdfOnly, Strategy::LightOnly] } else { &[Strategy::Mis, Strategy::BsdfOnly] };
    strategies
        .iter()
        .copied()
        .map(|strategy| {
            let integrator = PathTracer { max_depth: -1, strategy, ..PathTracer::default() };
            let img = render(&scene, &camera, 24, 24, spp, integrator, 5);
            (strategy, mean_rgb(&img.mean), img.discarded)
        })
        .collect()
}

/// A white Lambertian sphere under a clear coat, a sheen, or both, in a uniform environment
/// of radiance 1: the layering takes from the base what the layers reflect, so the sphere
/// stays at most 1 (it loses what the coat's single-scattering lobe and the sheen's albedo
/// scaling drop: a few per cent).
#[test]
fn layered_white_spheres_in_a_white_furnace_gain_nothing() {
    for (name, material, light_only) in [
        ("smooth coat", white(Some(coat(0.0)), None), false),
        ("rough coat", white(Some(coat(0.5)), None), true),
        ("sheen", white(None, Some(sheen(0.5))), true),
        ("both", white(Some(coat(0.2)), Some(sheen(0.3))), false),
    ] {
        for (strategy, mean, discarded) in furnace(material, 64, light_only) {
            assert!(mean.max_element() < 1.01, "{name}, {strategy:?}: mean {mean}");
            assert!(mean.min_element() > 0.9, "{name}, {strategy:?}: mean {mean}");
            assert_eq!(discarded, 0, "{name}, {strategy:?}");
        }
    }
}

/// A clear coat over smooth glass (a varnished glass ball) in the furnace: the coat's
/// reflection and the glass's delta lobes together stay below 1 and lose little.
#[test]
fn a_coat_over_glass_gains_nothing() {
    let glass = Material {
        model: SurfaceModel::MetallicRoughness,
        base_color: Rgb::ONE,
        metallic: 0.0,
        roughness: 0.0,
        transmission: 1.0,
        volume: Volume::from_attenuation(Rgb::ONE, f32::INFINITY),
        clearcoat: Some(coat(0.1)),
        ..Material::default_diffuse("varnished glass")
    };
    for (strategy, mean, discarded) in furnace(glass, 32, false) {
        assert!(mean.max_element() < 1.01 && mean.min_element() > 0.9, "{strategy:?}: mean {mean}");
        assert_eq!(discarded, 0, "{strategy:?}");
    }
}

/// Emission under a clear coat (the Cornell box's ceiling light coated): darkened by the
/// coat's reflectance, 1 − c F_c(μ) (0.96 head-on for a full coat, less toward grazing, as
/// the specification stacks the coat over emission), and the same darkening seen by light
/// sampling as by paths that hit the light: the three estimators agree.
#[test]
fn emission_under_a_coat_is_darkened_alike_for_every_estimator() {
    use neural_brdf_tests::image_mean_z;
    use renderer::accel::Ray;
    use renderer::scene::SceneDescription;
    let load = |coated: bool| {
        let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
        let mut description = SceneDescription::load(&root.join("scenes/cornell-box/scene.gltf")).expect("scene");
        let light = description.materials.iter_mut().find(|m| m.name == "light").expect("the light's material");
        if coated {
            light.clearcoat = Some(coat(0.2));
        }
        RenderScene::new(description).expect("scene")
    };
    let (plain, coated) = (load(false), load(true));
    // Rays into the centre of the ceiling light (y = 0.99, facing down), head-on and at 80°
    // from its normal.
    let seen = |scene: &RenderScene, direction: Vec3| {
        let ray = Ray::new(Vec3::new(0.0, 0.99, 0.01) - direction * 0.5, direction);
        let hit = scene.intersect(&ray).expect("the ray reaches the light");
        let sp = scene.surface_point(&hit, ray.direction).expect("a surface point");
        scene.emission(&sp, -direction)
    };
    let grazing = 80f32.to_radians();
    for (direction, expected) in [(Vec3::Y, 0.96), (Vec3::new(grazing.sin(), grazing.cos(), 0.0), 1.0 - (0.04 + 0.96 * (1.0 - grazing.cos()).powi(5)))] {
        let (a, b) = (seen(&plain, direction), seen(&coated, direction));
        assert!(a.max_element() > 0.0, "{direction}: the ray sees the light");
        let ratio = b / a;
        assert!((ratio - Rgb::splat(expected)).abs().max_element() < 1e-5, "{direction}: {ratio} against {expected}");
    }
    // The floor and the boxes, the light out of view: lit through the coat over the light's
    // hemisphere, mostly from above (1 − F_c is 0.96 head-on).
    let camera = look_at(Vec3::new(0.0, -0.2, 2.5), Vec3::new(0.0, -0.8, 0.0), 30.0);
    let estimate = |scene: &RenderScene, strategy, seed| render(scene, &camera, 32, 32, 128, PathTracer { max_depth: 4, strategy, ..PathTracer::default() }, seed);
    let mis = estimate(&coated, Strategy::Mis, 1);
    let darker = mean_rgb(&mis.mean) / mean_rgb(&estimate(&plain, Strategy::Mis, 1).mean);
    assert!(darker.max_element() < 0.97 && darker.min_element() > 0.9, "the coated light lights the box less: {darker}");
    for (strategy, seed) in [(Strategy::BsdfOnly, 2), (Strategy::LightOnly, 3)] {
        let other = estimate(&coated, strategy, seed);
        let z = image_mean_z(&mis, &other);
        assert!(z < 4.5, "{strategy:?}: {} against MIS {}, z = {z}", mean_rgb(&other.mean), mean_rgb(&mis.mean));
    }
}
