//! The shipped Cornell box: regression against a committed reference (statistical test),
//! bit-identical images for any thread count, and robustness far from the origin.

use glam::{Mat4, Vec3};
use neural_brdf_tests::regression::Case;
use neural_brdf_tests::{mean_rgb, render, Rendered};
use renderer::integrator::PathTracer;
use renderer::render_scene::RenderScene;
use renderer::scene::SceneDescription;
use std::path::PathBuf;

const SIZE: u32 = 48;
const TEST_SPP: u32 = 64;
const REFERENCE_SPP: u32 = 4096;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn cornell_box() -> SceneDescription {
    SceneDescription::load(&root().join("scenes/cornell-box/scene.gltf")).expect("shipped scene loads")
}

fn render_box(description: SceneDescription, spp: u32, seed: u64) -> Rendered {
    let camera = description.camera(None).expect("camera").clone();
    let scene = RenderScene::new(description).expect("scene");
    let integrator = PathTracer {
        max_depth: 8,
        ..PathTracer::default()
    };
    render(&scene, &camera, SIZE, SIZE, spp, integrator, seed)
}

const CASE: Case = Case {
    name: "cornell-box",
    test_spp: TEST_SPP,
    reference_spp: REFERENCE_SPP,
};

/// Compares a 48² render at 64 spp with the committed reference (4096 spp) by per-pixel
/// Z-tests at α = 0.01 with Šidák's correction; ≥ 99.75 % of pixel channels must pass,
/// and the image means must agree.
/// Re-bless on purpose with `BLESS=1 cargo test --test renders -- cornell_box::regression` (see
/// tests/README.md).
#[test]
fn regression_against_reference() {
    CASE.check(|spp, seed| render_box(cornell_box(), spp, seed));
}

/// The test has power: darkening the white walls by 3 % fails it.
#[test]
fn regression_detects_a_three_percent_albedo_change() {
    let mut darker = cornell_box();
    for m in darker.materials.iter_mut().filter(|m| m.name == "white") {
        m.base_color *= 0.97;
    }
    let img = render_box(darker, TEST_SPP, 7);
    let (report, _) = CASE.compare(&img);
    assert!(!report.passed, "{:.4} % pass, mean p = {:.2e}", 100.0 * report.pass_fraction, report.mean_p_value);
}

/// The same seed gives a bit-identical image with one, two and three worker threads (which
/// take the tiles in a different order each time).
#[test]
fn identical_for_one_two_and_three_threads() {
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
        pool.install(|| render_box(cornell_box(), 4, 99).mean)
    };
    let one = run(1);
    for threads in [2, 3] {
        let other = run(threads);
        assert!(one.iter().zip(&other).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)), "{threads} threads");
    }
}

/// Moved 1e5 units away from the origin, the box renders the same mean radiance (within
/// noise) and no sample is NaN: ray offsets scale with the coordinates.
#[test]
fn far_from_origin_renders_the_same() {
    let near = render_box(cornell_box(), 32, 3);
    let mut far = cornell_box();
    let shift = Vec3::new(1e5, -1e5, 1e5);
    for p in &mut far.geometry.positions {
        *p += shift;
    }
    for c in &mut far.cameras {
        c.camera_to_world = Mat4::from_translation(shift) * c.camera_to_world;
    }
    let far = render_box(far, 32, 3);
    assert_eq!(far.discarded, 0);
    let (a, b) = (mean_rgb(&near.mean), mean_rgb(&far.mean));
    assert!(((a - b) / a).abs().max_element() < 0.03, "near {a}, far {b}");
}
