//! Reproducible sets of rays through a scene's geometry, for traversal benchmarks and
//! side-by-side comparisons with other ray tracers (the `bvh` bench,
//! `examples/surface_rays.rs`).

use crate::accel::Ray;
use crate::sampler::Sampler;
use crate::sampling::sample_uniform_sphere;
use crate::scene::Geometry;
use glam::Vec3;

/// `n` rays from uniform points of the inner 80 % of the geometry's bounding box in uniform
/// directions (incoherent rays crossing the scene); none for empty geometry.
pub fn interior_rays(geometry: &Geometry, n: usize) -> Vec<Ray> {
    let Some((lo, hi)) = geometry.bounds() else {
        return Vec::new();
    };
    let mut s = Sampler::new(1, 2, 3);
    (0..n)
        .map(|_| {
            let t = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d());
            let origin = lo + (hi - lo) * (0.1 + 0.8 * t);
            Ray::new(origin, sample_uniform_sphere(s.next_2d()))
        })
        .collect()
}

/// `n` rays leaving the geometry's surfaces, as a path's continuation and shadow rays do: from
/// a uniform point of a uniformly chosen triangle, 10⁻⁴ off the surface along the triangle's
/// normal, into the hemisphere of that normal, uniformly; none for empty geometry.
pub fn surface_rays(geometry: &Geometry, n: usize) -> Vec<Ray> {
    let count = geometry.triangle_count();
    if count == 0 {
        return Vec::new();
    }
    let mut s = Sampler::new(4, 5, 6);
    (0..n)
        .map(|_| {
            let t = ((s.next_1d() * count as f32) as usize).min(count - 1);
            let [a, b, c] = geometry.triangle_positions(t);
            let (u, v) = (s.next_1d(), s.next_1d());
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            let normal = (b - a).cross(c - a).normalize();
            let d = sample_uniform_sphere(s.next_2d());
            let d = if d.dot(normal) < 0.0 { -d } else { d };
            Ray::new(a + (b - a) * u + (c - a) * v + normal * 1e-4, d)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Bvh;
    use crate::scene::SceneDescription;

    /// On the Cornell box (closed but for its front): interior rays start inside the box and
    /// all but those leaving through the open front hit; surface rays leave their surface
    /// (never hit within 10⁻⁴) and are reproducible.
    #[test]
    fn ray_sets_start_where_they_say() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box/scene.gltf");
        let scene = SceneDescription::load(&path).expect("shipped scene");
        let g = &scene.geometry;
        let bvh = Bvh::build((0..g.triangle_count()).map(|i| g.triangle_positions(i)));
        let (lo, hi) = g.bounds().unwrap();
        let interior = interior_rays(g, 500);
        assert_eq!(interior.len(), 500);
        assert!(interior.iter().all(|r| r.origin.cmpge(lo).all() && r.origin.cmple(hi).all()));
        let hits = interior.iter().filter(|r| bvh.intersect(r).is_some()).count();
        assert!(hits > 250 && hits < 500, "{hits}");
        let surface = surface_rays(g, 500);
        assert_eq!(surface.len(), 500);
        assert!(surface.iter().all(|r| (r.direction.length() - 1.0).abs() < 1e-5));
        assert!(surface.iter().all(|r| bvh.intersect(r).is_none_or(|h| h.t > 1e-4)));
        assert_eq!(surface_rays(g, 3).iter().map(|r| r.origin).collect::<Vec<_>>(), surface[..3].iter().map(|r| r.origin).collect::<Vec<_>>());
        assert!(surface_rays(&Geometry::default(), 4).is_empty());
    }
}
