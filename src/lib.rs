//! Shared helpers of the integration tests in `tests/`: procedural shapes, rendering a scene
//! description to mean and variance images, and the statistical image comparison used by the
//! regression tests.

pub mod pinned;
pub mod regression;
pub mod shapes;
pub mod ztest;

use renderer::camera::PinholeCamera;
use renderer::integrator::PathTracer;
use renderer::render::{Budget, Renderer};
use renderer::render_scene::RenderScene;
use glam::{Mat4, Vec3};
use renderer::scene::Camera;
use renderer::Rgb;
use std::sync::atomic::AtomicBool;

/// Mean and variance-of-the-mean images of a render.
pub struct Rendered {
    pub width: u32,
    pub height: u32,
    pub mean: Vec<Rgb>,
    pub variance: Vec<Rgb>,
    pub discarded: u64,
}

/// Renders `scene` through `camera` with `spp` samples per pixel on the current rayon pool.
pub fn render(scene: &RenderScene, camera: &Camera, width: u32, height: u32, spp: u32, integrator: PathTracer, seed: u64) -> Rendered {
    let renderer = Renderer {
        scene,
        camera: PinholeCamera::new(camera, width, height),
        integrator,
        seed,
    };
    let cancel = AtomicBool::new(false);
    let (film, stats) = renderer.render(width, height, Budget::Spp(spp), &cancel, &|_| {}, &mut |_, _| {});
    Rendered {
        width,
        height,
        mean: film.mean(),
        variance: film.variance_of_mean(),
        discarded: stats.discarded_samples,
    }
}

/// Mean of an image per channel.
pub fn mean_rgb(pixels: &[Rgb]) -> Rgb {
    let sum = pixels.iter().fold(glam::DVec3::ZERO, |a, p| a + p.as_dvec3());
    (sum / pixels.len() as f64).as_vec3()
}

/// The largest per-channel z-score of the difference of two renders' image means: the mean
/// difference over its standard error from the variance-of-the-mean images (pixels are
/// independent, so the variance of the image mean is the sum of pixel variances / N²).
pub fn image_mean_z(a: &Rendered, b: &Rendered) -> f32 {
    let n = a.mean.len() as f64;
    let var = |r: &Rendered| r.variance.iter().fold(glam::DVec3::ZERO, |s, v| s + v.as_dvec3()) / (n * n);
    let diff = (mean_rgb(&a.mean) - mean_rgb(&b.mean)).as_dvec3().abs();
    let se = (var(a) + var(b)).max(glam::DVec3::splat(1e-30)).powf(0.5);
    (diff / se).max_element() as f32
}

/// A camera at `position` looking at `target` (+y up) with a vertical field of view in degrees.
pub fn look_at(position: Vec3, target: Vec3, yfov_degrees: f32) -> Camera {
    let forward = (target - position).normalize();
    let right = forward.cross(Vec3::Y).normalize();
    let up = right.cross(forward);
    Camera {
        name: "camera".into(),
        camera_to_world: Mat4::from_cols(right.extend(0.0), up.extend(0.0), (-forward).extend(0.0), position.extend(1.0)),
        yfov: yfov_degrees.to_radians(),
        aspect_ratio: None,
    }
}
