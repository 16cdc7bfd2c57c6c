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
