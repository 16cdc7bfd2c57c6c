//! Scenes with a known answer (as pbrt-v4's integrator tests): the white furnace and the
//! inside of a uniformly emitting, uniformly reflecting sphere, for every estimator.

use glam::Vec3;
use neural_brdf_tests::shapes::{add_sphere, sphere_in_furnace};
use neural_brdf_tests::{look_at, mean_rgb, render};
use renderer::integrator::{PathTracer, Strategy};
use renderer::render_scene::RenderScene;
use renderer::scene::{Geometry, Material, SceneDescription, SurfaceModel};
use renderer::Rgb;

fn lambert(name: &str, albedo: f32, emission: f32) -> Material {
    Material {
        name: name.into(),
        model: SurfaceModel::Lambert,
        base_color: Rgb::splat(albedo),
        emission: Rgb::splat(emission),
        ..Material::default_diffuse(name)
    }
}

/// A white Lambertian sphere under a uniform environment of radiance 1 reflects radiance 1
/// everywhere (white furnace), with unlimited depth.
#[test]
fn white_furnace_lambert() {
    let scene = RenderScene::new(sphere_in_furnace(lambert("white", 1.0, 0.0), 32, 64)).expect("scene");
    let camera = look_at(Vec3::new(0.0, 0.0, 3.5), Vec3::ZERO, 40.0);
    for strategy in [Strategy::Mis, Strategy::BsdfOnly, Strategy::LightOnly] {
        let integrator = PathTracer {
            max_depth: -1,
            strategy,
            ..PathTracer::default()
        };
        let img = render(&scene, &camera, 24, 24, 64, integrator, 1);
        let mean = mean_rgb(&img.mean);
        assert!((mean - Rgb::ONE).abs().max_element() < 0.01, "{strategy:?}: mean {mean}");
        assert_eq!(img.discarded, 0);
    }
}

/// A grey Lambertian sphere (albedo 0.5) under a uniform environment of radiance 1 reflects
/// radiance 0.5 everywhere, with Russian roulette from the first bounce on (`rr_depth` 0, so
/// every path past its first vertex plays it at survival 0.5): a roulette that forgets to
/// divide by the survival probability, or a Lambert value off by 2 %, fails it. The camera
/// sees only the sphere.
#[test]
fn grey_furnace_with_roulette_from_the_first_bounce() {
    let albedo = 0.5f32;
    let scene = RenderScene::new(sphere_in_furnace(lambert("grey", albedo, 0.0), 32, 64)).expect("scene");
    let camera = look_at(Vec3::new(0.0, 0.0, 3.5), Vec3::ZERO, 20.0);
    for strategy in [Strategy::Mis, Strategy::BsdfOnly, Strategy::LightOnly] {
        let integrator = PathTracer {
            max_depth: -1,
            rr_depth: 0,
            strategy,
        };
        let img = render(&scene, &camera, 32, 32, 256, integrator, 3);
        let mean = mean_rgb(&img.mean);
        assert!(((mean - Rgb::splat(albedo)) / albedo).abs().max_element() < 0.01, "{strategy:?}: mean {mean}, expected {albedo}");
        assert_eq!(img.discarded, 0);
    }
}

/// Inside a closed sphere whose surface emits Le and reflects with albedo a, the radiance
/// is Le / (1 − a) in every direction, whatever the estimator.
#[test]
fn emitting_sphere_interior_is_le_over_one_minus_albedo() {
    let (le, albedo) = (0.5f32, 0.6f32);
    let expected = le / (1.0 - albedo);
    let mut geometry = Geometry::default();
    add_sphere(&mut geometry, Vec3::ZERO, 1.0, 24, 48, true, 0);
    let description = SceneDescription {
        geometry,
        materials: vec![lambert("glow", albedo, le)],
        ..SceneDescription::default()
    };
    let scene = RenderScene::new(description).expect("scene");
    let camera = look_at(Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.5, -0.2, -0.4), 40.0);
    for strategy in [Strategy::Mis, Strategy::BsdfOnly, Strategy::LightOnly] {
        let integrator = PathTracer {
            max_depth: -1,
            strategy,
            ..PathTracer::default()
        };
        let img = render(&scene, &camera, 16, 16, 128, integrator, 2);
        let mean = mean_rgb(&img.mean);
        assert!(
            ((mean - Rgb::splat(expected)) / expected).abs().max_element() < 0.025,
            "{strategy:?}: mean {mean}, expected {expected}"
        );
    }
}
