//! The top level of two-level acceleration: an `obvhs` CWBVH over the world-space bounds of
//! mesh instances. A ray reaching an instance's leaf is moved into the instance's object
//! space (by its world-to-object transform, direction not renormalised, so distances along
//! it stay world distances) and traced through the mesh's own [`super::Bvh`]; batches of rays go through both levels in packets
//! ([`InstanceBvh::intersect_all_with`]). Memory grows with the unique meshes plus one record
//! per instance.

use super::{node, to_bvh_ray, trace_chunks, traverse_nodes, Bvh, Hit, Ray};
use glam::{Affine3A, Vec3};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::{builder::build_cwbvh, CwBvh};
use obvhs::ray::Ray as BvhRay;
use obvhs::BvhBuildParams;
use std::time::Duration;

/// Which hits stop a ray where some surfaces let rays through (alpha cut-outs):
/// `accept(world ray, hit)`, a pure function of the two; `None` where every hit stops it.
pub type Accept<'a> = Option<&'a dyn Fn(&Ray, &Hit) -> bool>;

/// A CWBVH over instances, each a world-to-object transform of one mesh, and the meshes'
/// own BVHs.
pub struct InstanceBvh {
    pub(super) bvh: CwBvh,
    /// Per instance (in the caller's order): its world-to-object transform and its mesh.
    world_to_object: Vec<Affine3A>,
    mesh_of: Vec<u32>,
    /// Per mesh: its BVH in the mesh's space (hits index its triangles from 0) and the scene
    /// index of its first triangle.
    meshes: Vec<(Bvh, u32)>,
}

impl InstanceBvh {
    /// Builds the hierarchy over instances given as (world-space bounds min and max,
    /// world-to-object transform, index of its mesh in `meshes`); the caller's instance index
    /// is the position in `instances`. `meshes`: per mesh, its BVH and the scene index of its
    /// first triangle.
    pub fn build(instances: impl ExactSizeIterator<Item = ((Vec3, Vec3), Affine3A, u32)>, meshes: Vec<(Bvh, u32)>) -> Self {
        let mut bounds = Vec::with_capacity(instances.len());
        let mut world_to_object = Vec::with_capacity(instances.len());
        let mut mesh_of = Vec::with_capacity(instances.len());
        for ((min, max), transform, mesh) in instances {
            assert!((mesh as usize) < meshes.len(), "instance of mesh {mesh} of {}", meshes.len());
            bounds.push(Aabb::new(min.into(), max.into()));
            world_to_object.push(transform);
            mesh_of.push(mesh);
        }
        let bvh = if bounds.is_empty() {
            CwBvh::default()
        } else {
            let mut build_time = Duration::ZERO;
            build_cwbvh(&bounds, BvhBuildParams::medium_build(), &mut build_time)
        };
        InstanceBvh { bvh, world_to_object, mesh_of, meshes }
    }

    /// Number of instances.
    pub fn len(&self) -> usize {
        self.world_to_object.len()
    }

    /// True when there are no instances.
    pub fn is_empty(&self) -> bool {
        self.world_to_object.is_empty()
    }

    /// The closest hit of `ray` on the instances' meshes within (0, t), where t is `best`'s
    /// distance (a hit found elsewhere) or the ray's bound, that `accept` takes; `best` where
    /// there is none. Hits carry their instance and the scene index of their triangle.
    #[inline]
    pub fn intersect(&self, ray: &Ray, best: Option<Hit>, accept: Accept) -> Option<Hit> {
        self.closest_below(0, ray, best, accept)
    }

    /// Whether a hit on the instances' meshes that `accept` takes blocks `ray` within (0,
    /// ray.t_max).
    #[inline]
    pub fn occluded(&self, ray: &Ray, accept: Accept) -> bool {
        self.any_below(0, ray, accept)
    }

    /// [`InstanceBvh::intersect`] of many rays: `best[i]` holds the closest hit of `rays[i]`
    /// found elsewhere and is replaced by the closest over it and the instances; traced in
    /// packets where `packets` is asked for and the CPU has packet kernels, else one ray at a
    /// time (the same hits either way).
    pub fn intersect_all_with(&self, rays: &[Ray], best: &mut [Option<Hit>], packets: bool, accept: Accept) {
        // SAFETY: `trace_chunks` traces packets only where AVX2 and FMA exist.
        trace_chunks(rays, best, packets && !self.is_empty(), |r, b| unsafe { self.closest_packet(r, b, accept) }, |ray, best| *best = self.intersect(ray, *best, accept));
    }

    /// [`InstanceBvh::occluded`] of many rays: `blocked[i]` holds whether `rays[i]` is
    /// blocked elsewhere, and becomes true where an instance blocks it; traced as
    /// [`InstanceBvh::intersect_all_with`] chooses.
    pub fn occluded_all_with(&self, rays: &[Ray], blocked: &mut [bool], packets: bool, accept: Accept) {
        // SAFETY: as above.
        trace_chunks(rays, blocked, packets && !self.is_empty(), |r, b| unsafe { self.occluded_packet(r, b, accept) }, |ray, blocked| *blocked = *blocked || self.occluded(ray, accept));
    }

    /// [`InstanceBvh::intersect`] below node `root` of the top level.
    #[inline]
    pub(super) fn closest_below(&self, root: u32, ray: &Ray, mut best: Option<Hit>, accept: Accept) -> Option<Hit> {
        if self.is_empty() {
            return best;
        }
        let bounded = Ray { t_max: best.map_or(ray.t_max, |h| h.t), ..*ray };
        let bvh_ray = to_bvh_ray(&bounded);
        let oct = node::octant_inv4(bvh_ray.direction);
        traverse_nodes(&self.bvh.nodes, root, oct, bounded.t_max, |n, t_max| node_hits(n, &bvh_ray, oct, t_max), |index, lanes, t_max| {
            let base = self.bvh.nodes[index].primitive_base_idx;
            for k in (0..24).filter(|k| lanes & (1 << k) != 0) {
                let instance = self.bvh.primitive_indices[(base + k) as usize];
                if let Some(hit) = self.mesh_closest(instance, ray, &self.object_ray(instance, &bounded, *t_max), accept) {
                    *t_max = hit.t;
                    best = Some(hit);
                }
            }
            false
        });
        best
    }

    /// [`InstanceBvh::occluded`] below node `root` of the top level.
    #[inline]
    pub(super) fn any_below(&self, root: u32, ray: &Ray, accept: Accept) -> bool {
        if self.is_empty() {
            return false;
        }
        let bvh_ray = to_bvh_ray(ray);
        let oct = node::octant_inv4(bvh_ray.direction);
        let mut found = false;
        traverse_nodes(&self.bvh.nodes, root, oct, ray.t_max, |n, t_max| node_hits(n, &bvh_ray, oct, t_max), |index, lanes, _| {
            let base = self.bvh.nodes[index].primitive_base_idx;
            for k in (0..24).filter(|k| lanes & (1 << k) != 0) {
                let instance = self.bvh.primitive_indices[(base + k) as usize];
                if self.mesh_occluded(instance, ray, &self.object_ray(instance, ray, ray.t_max), accept) {
                    found = true;
                    return true;
                }
            }
            false
        });
        found
    }

    /// The closest hit of world ray `ray`, moved into `instance`'s space as `object_ray`, on
    /// the instance's mesh that `accept` takes, with its instance and scene triangle.
    #[inline]
    pub(super) fn mesh_closest(&self, instance: u32, ray: &Ray, object_ray: &Ray, accept: Accept) -> Option<Hit> {
        let (mesh, first) = self.mesh(instance);
        let hit = match accept {
            None => mesh.intersect(object_ray),
            Some(accept) => mesh.intersect_filtered(object_ray, |h| accept(ray, &placed(*h, first, instance))),
        }?;
        Some(placed(hit, first, instance))
    }

    /// Whether `instance`'s mesh blocks world ray `ray`, moved into the instance's space as
    /// `object_ray`, by a hit that `accept` takes.
    #[inline]
    pub(super) fn mesh_occluded(&self, instance: u32, ray: &Ray, object_ray: &Ray, accept: Accept) -> bool {
        let (mesh, first) = self.mesh(instance);
        match accept {
            None => mesh.occluded(object_ray),
            Some(accept) => mesh.occluded_filtered(object_ray, |h| accept(ray, &placed(*h, first, instance))),
        }
    }

    /// `instance`'s mesh: its BVH and the scene index of its first triangle ([`placed`]).
    #[inline]
    pub(super) fn mesh(&self, instance: u32) -> (&Bvh, u32) {
        let (mesh, first) = &self.meshes[self.mesh_of[instance as usize] as usize];
        (mesh, *first)
    }

    /// `ray` in `instance`'s object space with bound `t_max` (the direction not renormalised,
    /// so distances along it stay world distances).
    #[inline]
    pub(super) fn object_ray(&self, instance: u32, ray: &Ray, t_max: f32) -> Ray {
        let m = &self.world_to_object[instance as usize];
        Ray {
            origin: m.transform_point3(ray.origin),
            direction: m.transform_vector3(ray.direction),
            t_max,
        }
    }

    /// Number of CWBVH nodes of the top level.
    pub fn node_count(&self) -> usize {
        self.bvh.nodes.len()
    }
}

/// The children of a top-level node the ray crosses, with the AVX2 kernel where the CPU has
/// it (the arithmetic of the packet walk's box tests, so both admit the same instances).
#[inline(always)]
fn node_hits(node: &CwBvhNode, ray: &BvhRay, oct: u32, t_max: f32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if crate::support::cpu::has_avx2_fma() {
        // SAFETY: the CPU supports AVX2 and FMA.
        return unsafe { node::intersect_avx2(node, ray, oct, t_max) };
    }
    node::intersect_portable(node, ray, oct, t_max)
}

/// A hit on an instance's mesh (its triangle numbered in the mesh, whose first triangle is
/// scene triangle `first`) as the scene sees it: on scene triangle `first` + its own, of
/// instance `instance`.
#[inline(always)]
pub(super) fn placed(hit: Hit, first: u32, instance: u32) -> Hit {
    Hit { triangle: hit.triangle + first, instance, ..hit }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Bvh;
    use crate::sampler::Sampler;
    use glam::{Mat4, Quat};

    /// Instances of `meshes` (corner lists) placed by `to_world` as (transform, mesh).
    fn instanced(meshes: &[Vec<[Vec3; 3]>], to_world: &[(Mat4, u32)]) -> InstanceBvh {
        let mut first = 0;
        let bvhs = meshes
            .iter()
            .map(|corners| {
                let mesh = (Bvh::build(corners.iter().copied()), first);
                first += corners.len() as u32;
                mesh
            })
            .collect();
        InstanceBvh::build(
            to_world.iter().map(|&(m, mesh)| {
                let corners = meshes[mesh as usize].iter().flatten().map(|&c| m.transform_point3(c));
                let (lo, hi) = corners.fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), c| (lo.min(c), hi.max(c)));
                ((lo, hi), Affine3A::from_mat4(m).inverse(), mesh)
            }),
            bvhs,
        )
    }

    /// A unit triangle instanced three times along z: the closest instance is found through
    /// object-space rays whose distances are world distances, a hit found elsewhere bounds
    /// it, and occlusion stops at any.
    #[test]
    fn instances_are_traced_in_object_space() {
        let triangle = vec![[Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)]];
        let to_world: Vec<(Mat4, u32)> = (0..3).map(|i| (Mat4::from_translation(Vec3::new(0.0, 0.0, -2.0 * i as f32)) * Mat4::from_scale(Vec3::splat(1.0 + i as f32)), 0)).collect();
        let instances = instanced(&[triangle], &to_world);
        assert_eq!(instances.len(), 3);
        let ray = Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z);
        let hit = instances.intersect(&ray, None, None).expect("a hit");
        assert_eq!(hit.instance, 0);
        assert!((hit.t - 5.0).abs() < 1e-5, "{}", hit.t);
        // Off-centre at x = 1.2: only the instances scaled by 2 and 3 cover it; the nearer
        // (instance 1, at z = −2) wins, 7 units away.
        let ray = Ray::new(Vec3::new(1.2, -0.5, 5.0), Vec3::NEG_Z);
        let hit = instances.intersect(&ray, None, None).expect("a hit");
        assert_eq!(hit.instance, 1);
        assert!((hit.t - 7.0).abs() < 1e-5, "{}", hit.t);
        // A closer hit found elsewhere stays; a farther one is replaced.
        let elsewhere = |t| Some(Hit { t, triangle: 9, barycentric: glam::Vec2::ZERO, instance: crate::accel::NO_INSTANCE });
        assert_eq!(instances.intersect(&ray, elsewhere(6.5), None).map(|h| h.triangle), Some(9));
        assert_eq!(instances.intersect(&ray, elsewhere(7.5), None).map(|h| h.instance), Some(1));
        // A filter refusing instance 1 lets the ray on to instance 2.
        let skip_one = |_: &Ray, h: &Hit| h.instance != 1;
        assert_eq!(instances.intersect(&ray, None, Some(&skip_one)).map(|h| h.instance), Some(2));
        assert!(instances.occluded(&ray, None));
        assert!(!instances.occluded(&Ray { t_max: 6.0, ..ray }, None));
    }

    /// Batches traced in packets find what each ray finds alone, bit for bit (distance,
    /// triangle, barycentrics, instance), for closest hits and occlusion, with and without
    /// hits found elsewhere and a filter: 40 rotated, scaled and moved instances of two
    /// triangle soups, rays from inside and outside them (coherent and scattered).
    #[test]
    fn packets_through_instances_find_the_single_rays_hits_bit_for_bit() {
        let mut rng = Sampler::new(5, 1, 2);
        let mut point = |scale: f32| (rng.next_2d().extend(rng.next_1d()) - 0.5) * scale;
        let soup = |n: usize, point: &mut dyn FnMut(f32) -> Vec3| -> Vec<[Vec3; 3]> {
            (0..n).map(|_| {
                let c = point(4.0);
                [c + point(0.8), c + point(0.8), c + point(0.8)]
            }).collect()
        };
        let meshes = [soup(300, &mut point), soup(120, &mut point)];
        let to_world: Vec<(Mat4, u32)> = (0..40)
            .map(|i| {
                let axis = point(2.0).normalize_or(Vec3::Y);
                let m = Mat4::from_scale_rotation_translation(Vec3::splat(0.5 + point(1.0).x.abs()), Quat::from_axis_angle(axis, point(6.0).x), point(30.0));
                (m, i % 2)
            })
            .collect();
        let instances = instanced(&meshes, &to_world);
        let mut rays = Vec::new();
        for k in 0..512 {
            let (origin, direction) = if k < 256 {
                // Camera-like: 16 rays at a time from one point over a small cone.
                let o = if k % 16 == 0 { point(40.0) } else { rays.last().map_or(Vec3::ZERO, |r: &Ray| r.origin) };
                (o, (-o + point(3.0)).normalize())
            } else {
                (point(30.0), point(2.0).normalize_or(Vec3::X))
            };
            rays.push(Ray { t_max: if k % 5 == 0 { 20.0 } else { f32::MAX }, ..Ray::new(origin, direction) });
        }
        // Every third ray has a hit found elsewhere at a random distance.
        let elsewhere: Vec<Option<Hit>> = rays.iter().enumerate().map(|(k, _)| (k % 3 == 0).then(|| Hit { t: 5.0 + 40.0 * (k as f32 * 0.618).fract(), triangle: 7, barycentric: glam::Vec2::ZERO, instance: crate::accel::NO_INSTANCE })).collect();
        let filter = |ray: &Ray, h: &Hit| !h.triangle.wrapping_add(h.instance).wrapping_add(ray.origin.x.to_bits()).is_multiple_of(3);
        let mut hits = 0;
        for accept in [None, Some(&filter as &dyn Fn(&Ray, &Hit) -> bool)] {
            let mut expected = elsewhere.clone();
            instances.intersect_all_with(&rays, &mut expected, false, accept);
            let mut got = elsewhere.clone();
            instances.intersect_all_with(&rays, &mut got, true, accept);
            assert_eq!(format!("{got:?}"), format!("{expected:?}"));
            hits += expected.iter().filter(|h| h.is_some_and(|h| h.instance != crate::accel::NO_INSTANCE)).count();
            let blocked_elsewhere: Vec<bool> = (0..rays.len()).map(|k| k % 7 == 0).collect();
            let (mut expected, mut got) = (blocked_elsewhere.clone(), blocked_elsewhere);
            instances.occluded_all_with(&rays, &mut expected, false, accept);
            instances.occluded_all_with(&rays, &mut got, true, accept);
            assert_eq!(got, expected);
            assert!(expected.iter().filter(|&&b| b).count() > rays.len() / 4, "rays blocked: {expected:?}");
        }
        assert!(hits > 150, "instanced hits: {hits}");
    }
}
