//! Pinhole camera ray generation.

use crate::accel::Ray;
use crate::lanes::{F32s, Vec2s, Vec3s};
use crate::scene::Camera;
use glam::{Vec2, Vec3};

/// A perspective pinhole camera set up for a given image resolution.
#[derive(Clone, Debug)]
pub struct PinholeCamera {
    origin: Vec3,
    /// World-space axes of the camera: right, up, and the view direction.
    right: Vec3,
    up: Vec3,
    forward: Vec3,
    /// tan(yfov / 2) · aspect and tan(yfov / 2).
    half_extent: Vec2,
    resolution: Vec2,
}

impl PinholeCamera {
    /// Sets up `camera` for an image of `width × height` pixels; the vertical field of view
    /// is kept and the horizontal one follows from the image's aspect ratio.
    pub fn new(camera: &Camera, width: u32, height: u32) -> Self {
        let m = camera.camera_to_world;
        let tan_half = (camera.yfov * 0.5).tan();
        let aspect = width as f32 / height as f32;
        PinholeCamera {
            origin: m.transform_point3(Vec3::ZERO),
            right: m.transform_vector3(Vec3::X).normalize(),
            up: m.transform_vector3(Vec3::Y).normalize(),
            forward: m.transform_vector3(-Vec3::Z).normalize(),
            half_extent: Vec2::new(tan_half * aspect, tan_half),
            resolution: Vec2::new(width as f32, height as f32),
        }
    }

    /// The primary ray through film position `film` in pixels (x right, y down; (0, 0) is
    /// the top-left corner of the image).
    #[inline]
    pub fn generate_ray(&self, film: Vec2) -> Ray {
        let ndc = Vec2::new(
            2.0 * film.x / self.resolution.x - 1.0,
            1.0 - 2.0 * film.y / self.resolution.y,
        ) * self.half_extent;
        let dir = (self.forward + self.right * ndc.x + self.up * ndc.y).normalize();
        Ray::new(self.origin, dir)
    }

    /// The primary rays' directions through [`LANES`](crate::lanes::LANES) film positions
    /// at once, each lane bit for bit [`PinholeCamera::generate_ray`]'s (the same operations
    /// in the same order; their origin is the camera's, [`PinholeCamera::origin`]). The
    /// divisions and square roots, latency-bound one sample at a time, run in vectors.
    #[inline]
    pub fn generate_directions(&self, film: &Vec2s) -> Vec3s {
        let ndc_x = (2.0 * film.x / self.resolution.x - 1.0) * self.half_extent.x;
        let ndc_y = (1.0 - 2.0 * film.y / self.resolution.y) * self.half_extent.y;
        let dir = Vec3s::splat(self.forward) + Vec3s::splat(self.right) * ndc_x + Vec3s::splat(self.up) * ndc_y;
        let rcp: F32s = 1.0 / dir.dot(dir).sqrt();
        dir * rcp
    }

    /// Where every primary ray starts.
    #[inline]
    pub fn origin(&self) -> Vec3 {
        self.origin
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Mat4;

    #[test]
    fn centre_ray_looks_down_minus_z_and_corners_span_the_fov() {
        let cam = Camera {
            name: "c".into(),
            camera_to_world: Mat4::from_translation(Vec3::new(0.0, 0.0, 4.0)),
            yfov: 60f32.to_radians(),
            aspect_ratio: None,
        };
        let pc = PinholeCamera::new(&cam, 200, 100);
        let centre = pc.generate_ray(Vec2::new(100.0, 50.0));
        assert!((centre.direction - -Vec3::Z).length() < 1e-6);
        assert_eq!(centre.origin, Vec3::new(0.0, 0.0, 4.0));
        let top = pc.generate_ray(Vec2::new(100.0, 0.0)).direction;
        assert!((top.y.atan2(-top.z) - 30f32.to_radians()).abs() < 1e-5);
        let right = pc.generate_ray(Vec2::new(200.0, 50.0)).direction;
        assert!(right.x > 0.0);
        assert!((right.x / -right.z - 2.0 * 30f32.to_radians().tan()).abs() < 1e-5);
    }

    /// Directions made in lanes are bit for bit the scalar rays', over the whole film and
    /// beyond its edges, for an oblique camera.
    #[test]
    fn lane_directions_equal_scalar_rays_bit_for_bit() {
        let cam = Camera {
            name: "c".into(),
            camera_to_world: Mat4::from_rotation_translation(glam::Quat::from_euler(glam::EulerRot::YXZ, 0.7, -0.4, 0.1), Vec3::new(1.0, 2.0, 3.0)),
            yfov: 0.7,
            aspect_ratio: None,
        };
        let pc = PinholeCamera::new(&cam, 37, 23);
        let mut film = Vec2s::default();
        let mut k = 0u32;
        for _ in 0..200 {
            for lane in 0..crate::lanes::LANES {
                // A scrambled walk over [-1, 39) x [-1, 25).
                k = k.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
                let (u, v) = ((k >> 8) as f32 / (1 << 24) as f32, (k & 0xffff) as f32 / 65536.0);
                film.set(lane, Vec2::new(u * 40.0 - 1.0, v * 26.0 - 1.0));
            }
            let dirs = pc.generate_directions(&film);
            for lane in 0..crate::lanes::LANES {
                let ray = pc.generate_ray(Vec2::new(film.x.0[lane], film.y.0[lane]));
                assert_eq!(ray.origin, pc.origin());
                assert_eq!(dirs.get(lane).to_array().map(f32::to_bits), ray.direction.to_array().map(f32::to_bits), "lane {lane}");
            }
        }
    }
}
