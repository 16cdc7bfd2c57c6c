//! Ray–triangle acceleration: an `obvhs` compressed-wide BVH (CWBVH) over every triangle
//! of a scene, closest-hit and occlusion queries, and robust ray-origin offsets.

use glam::{Vec2, Vec3, Vec3A};
use obvhs::cwbvh::{builder::build_cwbvh_from_tris, CwBvh};
use obvhs::ray::{Ray as BvhRay, RayHit};
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;
use std::time::Duration;

/// A ray with a parametric interval.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3,
    /// Unit direction for [`Bvh::intersect`]; [`Bvh::occluded`] also takes an unnormalised
    /// direction, with `t_max` in units of its length (a segment from origin to
    /// origin + t_max · direction).
    pub direction: Vec3,
    /// Upper bound of the parametric interval (distance along `direction`).
    pub t_max: f32,
}

impl Ray {
    /// A ray of unbounded length (`t_max` = `f32::MAX`: obvhs reports a miss as t = ∞, so
    /// the bound itself must stay finite).
    #[inline]
    pub fn new(origin: Vec3, direction: Vec3) -> Self {
        Ray {
            origin,
            direction,
            t_max: f32::MAX,
        }
    }

    /// Point at distance `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.direction * t
    }
}

/// The closest intersection of a ray with the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray.
    pub t: f32,
    /// Index of the triangle in the scene's [`crate::scene::Geometry`].
    pub triangle: u32,
    /// Barycentric coordinates (b1, b2) of the hit: p = (1 − b1 − b2) v0 + b1 v1 + b2 v2.
    pub barycentric: Vec2,
}

/// Bounding volume hierarchy over a triangle soup.
pub struct Bvh {
    bvh: CwBvh,
    /// Triangles in BVH leaf order, so traversal reads them sequentially.
    triangles: Vec<Triangle>,
    /// Scene triangle index of each entry of `triangles`.
    scene_index: Vec<u32>,
}

impl Bvh {
    /// Builds the BVH with obvhs's `medium_build` preset (a good trade between build time and
    /// trace speed for offline rendering).
    pub fn build(corners: impl ExactSizeIterator<Item = [Vec3; 3]>) -> Self {
        Self::build_with(corners, BvhBuildParams::medium_build())
    }

    /// Builds the BVH with explicit obvhs build parameters.
    pub fn build_with(corners: impl ExactSizeIterator<Item = [Vec3; 3]>, params: BvhBuildParams) -> Self {
        let input: Vec<Triangle> = corners
            .map(|[a, b, c]| Triangle {
                v0: a.into(),
                v1: b.into(),
                v2: c.into(),
            })
            .collect();
        if input.is_empty() {
            return Bvh {
                bvh: CwBvh::default(),
                triangles: Vec::new(),
                scene_index: Vec::new(),
            };
        }
        let mut build_time = Duration::ZERO;
        let mut bvh = build_cwbvh_from_tris(&input, params, &mut build_time);
        // Reorder the triangles into leaf order and make primitive ids refer to the new slots.
        let scene_index = bvh.primitive_indices.clone();
        let triangles = scene_index.iter().map(|&i| input[i as usize]).collect();
        for (slot, id) in bvh.primitive_indices.iter_mut().enumerate() {
            *id = slot as u32;
        }
        Bvh {
            bvh,
            triangles,
            scene_index,
        }
    }

    /// Number of triangles (slots) in the hierarchy.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// True when the hierarchy holds no triangles.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Closest intersection with t in (0, ray.t_max), or `None`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if self.triangles.is_empty() {
            return None;
        }
        let bvh_ray = to_bvh_ray(ray);
        let mut hit = RayHit::none();
        let found = self.bvh.ray_traverse(bvh_ray, &mut hit, |r, slot| {
            self.triangles[self.bvh.primitive_indices[slot] as usize].intersect(r)
        });
        if !found {
            return None;
        }
        let slot = self.bvh.primitive_indices[hit.primitive_id as usize] as usize;
        let barycentric = barycentric(&self.triangles[slot], ray);
        Some(Hit {
            t: hit.t,
            triangle: self.scene_index[slot],
            barycentric,
        })
    }

    /// True when anything blocks the ray within (0, ray.t_max).
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        if self.triangles.is_empty() {
            return false;
        }
        let bvh_ray = to_bvh_ray(ray);
        !self.bvh.ray_traverse_miss(bvh_ray, |r, slot| {
            self.triangles[self.bvh.primitive_indices[slot] as usize].intersect(r)
        })
    }
}

/// The obvhs ray for a ray. Negative zeros in the direction become positive zeros: obvhs
/// derives the traversal octant from sign bits and misses everything along an axis-aligned
/// direction with a −0.0 component.
#[inline]
fn to_bvh_ray(ray: &Ray) -> BvhRay {
    BvhRay::new(
        Vec3A::from(ray.origin),
        Vec3A::from(ray.direction) + Vec3A::ZERO,
        0.0,
        ray.t_max,
    )
}

/// Barycentric coordinates (b1, b2) of where a ray crosses a triangle's plane
/// (Möller–Trumbore).
#[inline]
fn barycentric(tri: &Triangle, ray: &Ray) -> Vec2 {
    let (v0, v1, v2) = (Vec3::from(tri.v0), Vec3::from(tri.v1), Vec3::from(tri.v2));
    let (e1, e2) = (v1 - v0, v2 - v0);
    let p = ray.direction.cross(e2);
    let inv_det = 1.0 / e1.dot(p);
    let s = ray.origin - v0;
    let q = s.cross(e1);
    let b1 = (s.dot(p) * inv_det).clamp(0.0, 1.0);
    let b2 = (ray.direction.dot(q) * inv_det).clamp(0.0, 1.0 - b1);
    Vec2::new(b1, b2)
}

/// γ(n) of Higham's floating-point error analysis: a bound on the relative error of n
/// successive roundings.
#[inline]
fn gamma(n: f32) -> f32 {
    let e = f32::EPSILON * 0.5;
    n * e / (1.0 - n * e)
}

/// A point on a triangle interpolated from barycentric coordinates, with a conservative
/// bound on its absolute rounding error per axis (pbrt-v4's interpolation bound).
#[inline]
pub fn interpolate_point(corners: [Vec3; 3], barycentric: Vec2) -> (Vec3, Vec3) {
    let b0 = 1.0 - barycentric.x - barycentric.y;
    let [v0, v1, v2] = corners;
    let p = v0 * b0 + v1 * barycentric.x + v2 * barycentric.y;
    let abs_sum = (v0 * b0).abs() + (v1 * barycentric.x).abs() + (v2 * barycentric.y).abs();
    (p, abs_sum * gamma(7.0))
}

/// Moves a ray origin `p` (with absolute error bound `p_error`) off its surface along the
/// geometric normal `n`, to the side of the outgoing direction `w`, far enough that the new
/// ray cannot re-hit the surface it leaves (pbrt-v4's `OffsetRayOrigin`). The offset scales
/// with the magnitude of the coordinates, so it stays valid far from the origin.
#[inline]
pub fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error);
    let mut offset = n * d;
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    let po = p + offset;
    let round_away = |x: f32, o: f32| {
        if o > 0.0 {
            next_float_up(x)
        } else if o < 0.0 {
            next_float_down(x)
        } else {
            x
        }
    };
    Vec3::new(
        round_away(po.x, offset.x),
        round_away(po.y, offset.y),
        round_away(po.z, offset.z),
    )
}

/// The next representable float toward +∞.
#[inline]
pub fn next_float_up(x: f32) -> f32 {
    if x.is_infinite() && x > 0.0 {
        return x;
    }
    let x = if x == -0.0 { 0.0 } else { x };
    let bits = x.to_bits();
    f32::from_bits(if x >= 0.0 { bits + 1 } else { bits - 1 })
}

/// The next representable float toward −∞.
#[inline]
pub fn next_float_down(x: f32) -> f32 {
    -next_float_up(-x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(offset: Vec3) -> Vec<[Vec3; 3]> {
        let (a, b, c, d) = (
            Vec3::new(-1.0, 0.0, -1.0) + offset,
            Vec3::new(1.0, 0.0, -1.0) + offset,
            Vec3::new(1.0, 0.0, 1.0) + offset,
            Vec3::new(-1.0, 0.0, 1.0) + offset,
        );
        vec![[a, c, b], [a, d, c]]
    }

    #[test]
    fn closest_hit_reports_scene_triangle_and_barycentrics() {
        let mut tris = quad(Vec3::ZERO);
        tris.extend(quad(Vec3::new(0.0, 2.0, 0.0)));
        let bvh = Bvh::build(tris.clone().into_iter());
        // -Vec3::Y has negative-zero components: a case obvhs alone gets wrong.
        let ray = Ray::new(Vec3::new(0.3, 5.0, 0.2), -Vec3::Y);
        let hit = bvh.intersect(&ray).expect("hit");
        assert!((hit.t - 3.0).abs() < 1e-5);
        assert!(hit.triangle >= 2, "upper quad is closer");
        let [v0, v1, v2] = tris[hit.triangle as usize];
        let b = hit.barycentric;
        let p = v0 * (1.0 - b.x - b.y) + v1 * b.x + v2 * b.y;
        assert!((p - ray.at(hit.t)).length() < 1e-5, "{p} vs {}", ray.at(hit.t));
        assert!(bvh.occluded(&ray));
        let short = Ray { t_max: 2.5, ..ray };
        assert!(!bvh.occluded(&short));
        assert!(bvh.intersect(&Ray::new(Vec3::new(5.0, 5.0, 0.0), -Vec3::Y)).is_none());
    }

    #[test]
    fn offset_origins_do_not_self_intersect_far_from_origin() {
        for offset in [Vec3::ZERO, Vec3::splat(1e5), Vec3::new(-1e5, 3e4, 1e5)] {
            let bvh = Bvh::build(quad(offset).into_iter());
            let mut self_hits = 0;
            for i in 0..200 {
                let x = (i as f32 * 0.618_034).fract() * 1.8 - 0.9;
                let z = (i as f32 * 0.414_213).fract() * 1.8 - 0.9;
                let down = Ray::new(offset + Vec3::new(x, 1.0, z), -Vec3::Y);
                let hit = bvh.intersect(&down).expect("quad is below");
                let corners = quad(offset)[hit.triangle as usize];
                let (p, err) = interpolate_point(corners, hit.barycentric);
                assert!(err.max_element() < 0.1, "error bound stays small: {err}");
                let dir = Vec3::new(0.7, 0.002, 0.3).normalize();
                let out = Ray::new(offset_ray_origin(p, err, Vec3::Y, dir), dir);
                if bvh.intersect(&out).is_some() {
                    self_hits += 1;
                }
            }
            assert_eq!(self_hits, 0, "offset {offset}");
        }
    }

    #[test]
    fn empty_bvh_misses() {
        let bvh = Bvh::build(Vec::new().into_iter());
        assert!(bvh.is_empty());
        assert!(bvh.intersect(&Ray::new(Vec3::ZERO, Vec3::X)).is_none());
        assert!(!bvh.occluded(&Ray::new(Vec3::ZERO, Vec3::X)));
    }
}
