//! Ray–triangle acceleration: an `obvhs` compressed-wide BVH (CWBVH) over every triangle
//! of a scene, closest-hit and occlusion queries, and robust ray-origin offsets.

use glam::{UVec2, Vec2, Vec3, Vec3A};
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::{builder::build_cwbvh_from_tris, CwBvh};
use obvhs::ray::Ray as BvhRay;
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

/// A triangle stored for intersection: one corner and the two edges from it.
#[derive(Clone, Copy, Debug)]
struct EdgeTriangle {
    v0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
}

impl EdgeTriangle {
    fn new(t: &Triangle) -> Self {
        EdgeTriangle {
            v0: t.v0,
            e1: t.v1 - t.v0,
            e2: t.v2 - t.v0,
        }
    }

    /// Möller–Trumbore: the distance t ∈ (0, t_max) at which the ray crosses the triangle,
    /// or ∞; also the barycentric coordinates (b1, b2).
    #[inline(always)]
    fn intersect(&self, origin: Vec3A, direction: Vec3A, t_max: f32) -> (f32, Vec2) {
        let p = direction.cross(self.e2);
        let det = self.e1.dot(p);
        let inv_det = 1.0 / det;
        let s = origin - self.v0;
        let b1 = s.dot(p) * inv_det;
        let q = s.cross(self.e1);
        let b2 = direction.dot(q) * inv_det;
        let t = self.e2.dot(q) * inv_det;
        // NaN (det = 0) fails every comparison, so degenerate triangles never hit.
        if b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0 && t > 0.0 && t < t_max {
            (t, Vec2::new(b1, b2))
        } else {
            (f32::INFINITY, Vec2::ZERO)
        }
    }
}

/// Bounding volume hierarchy over a triangle soup.
pub struct Bvh {
    bvh: CwBvh,
    /// Triangles in BVH leaf order, so traversal reads them sequentially.
    triangles: Vec<EdgeTriangle>,
    /// Scene triangle index of each entry of `triangles`.
    scene_index: Vec<u32>,
}

/// Intersects a ray with the eight children of a CWBVH node, eight lanes at once (AVX2 +
/// FMA); returns the node hit mask in obvhs's encoding, as `CwBvhNode::intersect_ray` does.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn intersect_node_avx2(node: &CwBvhNode, ray: &BvhRay, oct_inv4: u32) -> u32 {
    use std::arch::x86_64::*;
    /// Box distances of SIMD node intersection are clamped below by this (as obvhs does).
    const T_MIN: f32 = 1e-4;
    let adj_dir_inv = node.compute_extent() * ray.inv_direction;
    let adj_orig = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
    let load = |v: &[u8; 8]| {
        // SAFETY: reads exactly the 8 bytes of `v`.
        _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(unsafe { _mm_loadl_epi64(v.as_ptr().cast()) }))
    };
    let slab = |lo: &[u8; 8], hi: &[u8; 8], negative: bool, d: f32, o: f32| {
        let (near, far) = if negative { (hi, lo) } else { (lo, hi) };
        let (d, o) = (_mm256_set1_ps(d), _mm256_set1_ps(o));
        (_mm256_fmadd_ps(load(near), d, o), _mm256_fmadd_ps(load(far), d, o))
    };
    let (x0, x1) = slab(&node.child_min_x, &node.child_max_x, ray.direction.x < 0.0, adj_dir_inv.x, adj_orig.x);
    let (y0, y1) = slab(&node.child_min_y, &node.child_max_y, ray.direction.y < 0.0, adj_dir_inv.y, adj_orig.y);
    let (z0, z1) = slab(&node.child_min_z, &node.child_max_z, ray.direction.z < 0.0, adj_dir_inv.z, adj_orig.z);
    let t0 = _mm256_max_ps(_mm256_max_ps(x0, y0), _mm256_max_ps(z0, _mm256_set1_ps(T_MIN)));
    let t1 = _mm256_min_ps(_mm256_min_ps(x1, y1), _mm256_min_ps(z1, _mm256_set1_ps(ray.tmax)));
    let mut hits = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1)) as u32;
    let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
    let mut hit_mask = 0u32;
    while hits != 0 {
        let j = hits.trailing_zeros() * 8;
        hits &= hits - 1;
        hit_mask |= (((child_bits8 >> j) & 0xff) as u32) << ((bit_index8 >> j) & 0xff);
    }
    hit_mask
}

/// Expands to a closest-hit or occlusion traversal of `$bvh` with the given node
/// intersection; shared by the AVX2 and the portable paths so both stay identical.
macro_rules! traverse_bvh {
    (closest, $self:ident, $ray:ident, $node:ident, $state:ident, $intersect_node:expr) => {{
        let mut t_max = $ray.tmax;
        let mut best = (u32::MAX, Vec2::ZERO);
        let mut $state = $self.bvh.new_traversal($ray.direction);
        let mut $node;
        obvhs::traverse!($self.bvh, $node, $state, $intersect_node, {
            let slot = $state.primitive_id as usize;
            let (t, b) = $self.triangles[slot].intersect($ray.origin, $ray.direction, t_max);
            if t < t_max {
                t_max = t;
                best = (slot as u32, b);
            }
        });
        (best.0 != u32::MAX).then(|| (t_max, best.0, best.1))
    }};
    (any, $self:ident, $ray:ident, $node:ident, $state:ident, $intersect_node:expr) => {{
        let mut $state = $self.bvh.new_traversal($ray.direction);
        let mut $node;
        let mut hit = false;
        obvhs::traverse!($self.bvh, $node, $state, $intersect_node, {
            let slot = $state.primitive_id as usize;
            if $self.triangles[slot].intersect($ray.origin, $ray.direction, $ray.tmax).0 < $ray.tmax {
                hit = true;
                break;
            }
        });
        hit
    }};
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
        let triangles = scene_index.iter().map(|&i| EdgeTriangle::new(&input[i as usize])).collect();
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
        #[cfg(target_arch = "x86_64")]
        let found = if has_avx2_fma() {
            // SAFETY: the CPU supports AVX2 and FMA.
            unsafe { self.closest_avx2(&bvh_ray) }
        } else {
            self.closest_portable(&bvh_ray)
        };
        #[cfg(not(target_arch = "x86_64"))]
        let found = self.closest_portable(&bvh_ray);
        found.map(|(t, slot, barycentric)| Hit {
            t,
            triangle: self.scene_index[slot as usize],
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
        #[cfg(target_arch = "x86_64")]
        if has_avx2_fma() {
            // SAFETY: the CPU supports AVX2 and FMA.
            return unsafe { self.any_avx2(&bvh_ray) };
        }
        self.any_portable(&bvh_ray)
    }

    fn closest_portable(&self, ray: &BvhRay) -> Option<(f32, u32, Vec2)> {
        traverse_bvh!(closest, self, ray, node, state, node.intersect_ray(ray, state.oct_inv4))
    }

    fn any_portable(&self, ray: &BvhRay) -> bool {
        traverse_bvh!(any, self, ray, node, state, node.intersect_ray(ray, state.oct_inv4))
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn closest_avx2(&self, ray: &BvhRay) -> Option<(f32, u32, Vec2)> {
        traverse_bvh!(closest, self, ray, node, state, intersect_node_avx2(node, ray, state.oct_inv4))
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn any_avx2(&self, ray: &BvhRay) -> bool {
        traverse_bvh!(any, self, ray, node, state, intersect_node_avx2(node, ray, state.oct_inv4))
    }
}

/// Whether this CPU runs the AVX2 + FMA traversal (detected once, then cached by std).
#[cfg(target_arch = "x86_64")]
#[inline]
fn has_avx2_fma() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

/// The obvhs ray for a ray. Negative zeros in the direction become positive zeros: obvhs
/// derives the traversal octant from sign bits and misses everything along an axis-aligned
/// direction with a −0.0 component.
/// The reciprocal direction replaces components within ε of zero by ±1/ε (as obvhs's
/// `Ray::new` does), computed branch-free.
#[inline]
fn to_bvh_ray(ray: &Ray) -> BvhRay {
    let direction = Vec3A::from(ray.direction) + Vec3A::ZERO;
    let tiny = direction.abs().cmple(Vec3A::splat(f32::EPSILON));
    let inv_direction = Vec3A::select(tiny, direction.signum() / f32::EPSILON, direction.recip());
    BvhRay {
        origin: Vec3A::from(ray.origin),
        direction,
        inv_direction,
        tmin: 0.0,
        tmax: ray.t_max,
    }
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
/// with the magnitude of the coordinates, so it stays valid far from the origin. Where
/// pbrt rounds each offset coordinate one float away from `p`, this adds |x|·ε (one to two
/// ulps) away from `p`: as conservative, and branch-free.
#[inline]
pub fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error);
    let offset = if w.dot(n) < 0.0 { -n * d } else { n * d };
    let po = p + offset;
    let away = Vec3::select(offset.cmpeq(Vec3::ZERO), Vec3::ZERO, offset.signum());
    po + away * (po.abs() * f32::EPSILON + Vec3::splat(f32::MIN_POSITIVE))
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
    fn simd_and_portable_traversals_agree() {
        // A box of quads plus a tilted one, rays from inside in many directions.
        let mut tris = Vec::new();
        for (axis, sign) in [(0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0), (2, 1.0), (2, -1.0)] {
            let q = quad(Vec3::ZERO).into_iter().map(|t| {
                t.map(|v| {
                    let v = Vec3::new(v.x, sign, v.z);
                    match axis {
                        0 => Vec3::new(v.y, v.x, v.z),
                        1 => v,
                        _ => Vec3::new(v.x, v.z, v.y),
                    }
                })
            });
            tris.extend(q);
        }
        tris.push([Vec3::new(-0.5, -0.2, 0.1), Vec3::new(0.4, 0.3, -0.2), Vec3::new(0.0, 0.5, 0.5)]);
        let bvh = Bvh::build(tris.into_iter());
        let mut s = crate::sampler::Sampler::new(4, 5, 6);
        for _ in 0..2000 {
            let o = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 1.6 - Vec3::splat(0.8);
            let d = crate::sampling::sample_uniform_sphere(s.next_2d());
            let ray = to_bvh_ray(&Ray::new(o, d));
            let portable = bvh.closest_portable(&ray);
            assert!(portable.is_some(), "inside a closed box every ray hits");
            #[cfg(target_arch = "x86_64")]
            if has_avx2_fma() {
                // SAFETY: checked above.
                let simd = unsafe { bvh.closest_avx2(&ray) };
                assert_eq!(simd.map(|h| h.1), portable.map(|h| h.1));
                let short = BvhRay { tmax: portable.map(|h| h.0 * 0.5).unwrap_or(1.0), ..ray };
                // SAFETY: checked above.
                assert_eq!(unsafe { bvh.any_avx2(&short) }, bvh.any_portable(&short));
            }
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
