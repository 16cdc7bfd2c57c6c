//! The shipped Cornell box: regression against a committed reference (statistical test),
//! bit-identical images for any thread count, and robustness far from the origin.

use glam::{Mat4, Vec3};
use neural_brdf_tests::{mean_rgb, render, ztest, Rendered};
use renderer::image_io::{read_image, write_exr};
use renderer::integrator::PathTracer;
use renderer::render_scene::RenderScene;
use renderer::scene::SceneDescription;
use renderer::Rgb;
use std::path::{Path, PathBuf};

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

fn write_failure_images(dir: &Path, img: &Rendered, reference: &[Rgb], report: &ztest::ZTestReport) {
    std::fs::create_dir_all(dir).expect("failure directory");
    let error: Vec<Rgb> = img.mean.iter().zip(reference).map(|(a, b)| (*a - *b).abs()).collect();
    let p: Vec<Rgb> = report.p_values.iter().map(|&p| Rgb::splat(p)).collect();
    for (name, px) in [("image", &img.mean), ("reference", &reference.to_vec()), ("error", &error), ("p-value", &p)] {
        write_exr(&dir.join(format!("{name}.exr")), SIZE, SIZE, px).expect("write failure image");
    }
}

fn reference_paths() -> (PathBuf, PathBuf) {
    let refs = root().join("tests/references");
    (refs.join("cornell-box.exr"), refs.join("cornell-box.variance.exr"))
}

/// Z-test of `img` (at TEST_SPP) against the committed reference; returns the report and
/// the reference image.
fn compare_with_reference(img: &Rendered) -> (ztest::ZTestReport, Vec<Rgb>) {
    let (mean_path, var_path) = reference_paths();
    let (_, _, reference) = read_image(&mean_path).expect("reference image");
    let (_, _, reference_var) = read_image(&var_path).expect("reference variance");
    // The test image's variance comes from the reference's per-sample variance (same
    // estimator, fewer samples): 64 samples alone estimate it poorly where values are
    // heavy-tailed (pixels that see the light's edge).
    let scale = REFERENCE_SPP as f32 / TEST_SPP as f32;
    let image_var: Vec<Rgb> = reference_var.iter().map(|v| *v * scale).collect();
    let report = ztest::compare(&img.mean, &image_var, &reference, &reference_var, 0.01, 0.9975);
    (report, reference)
}

/// Compares a 48² render at 64 spp with the committed reference (4096 spp) by per-pixel
/// Z-tests at α = 0.01 with Šidák's correction; ≥ 99.75 % of pixel channels must pass,
/// and the image means must agree.
/// Re-bless on purpose with `BLESS=1 cargo test --test cornell_box regression` (see
/// tests/README.md).
#[test]
fn regression_against_reference() {
    if std::env::var_os("BLESS").is_some() {
        let (mean_path, var_path) = reference_paths();
        let reference = render_box(cornell_box(), REFERENCE_SPP, 12345);
        write_exr(&mean_path, SIZE, SIZE, &reference.mean).expect("write reference");
        write_exr(&var_path, SIZE, SIZE, &reference.variance).expect("write variance");
    }
    let img = render_box(cornell_box(), TEST_SPP, 7);
    let (report, reference) = compare_with_reference(&img);
    if !report.passed {
        let dir = root().join("target/regression-failures/cornell-box");
        write_failure_images(&dir, &img, &reference, &report);
        panic!(
            "{:.4} % of {} pixel channels pass (need 99.75 %), image-mean p = {:.2e}; images in {}",
            100.0 * report.pass_fraction,
            report.tests,
            report.mean_p_value,
            dir.display()
        );
    }
}

/// The test has power: darkening the white walls by 3 % fails it.
#[test]
fn regression_detects_a_three_percent_albedo_change() {
    let mut darker = cornell_box();
    for m in darker.materials.iter_mut().filter(|m| m.name == "white") {
        m.base_color *= 0.97;
    }
    let img = render_box(darker, TEST_SPP, 7);
    let (report, _) = compare_with_reference(&img);
    assert!(!report.passed, "{:.4} % pass, mean p = {:.2e}", 100.0 * report.pass_fraction, report.mean_p_value);
}

/// The same seed gives a bit-identical image with one and with two worker threads.
#[test]
fn identical_for_one_and_two_threads() {
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("pool");
        pool.install(|| render_box(cornell_box(), 4, 99).mean)
    };
    let (one, two) = (run(1), run(2));
    assert!(one.iter().zip(&two).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)));
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
