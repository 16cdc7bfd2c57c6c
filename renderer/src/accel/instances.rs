//! The top level of two-level acceleration: an `obvhs` CWBVH over the world-space bounds of
//! mesh instances. A ray reaching an instance's leaf is moved into the instance's object
//! space (by its world-to-object transform, direction not renormalised, so distances along
//! it stay world distances) and handed to the caller, who traces it through the mesh's own
//! [`super::Bvh`]. Memory grows with the unique meshes plus one record per instance.

use super::{node, to_bvh_ray, traverse_nodes, Ray};
use glam::{Affine3A, Vec3};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::{builder::build_cwbvh, CwBvh};
use obvhs::BvhBuildParams;
use std::time::Duration;

/// A CWBVH over instances, each a world-to-object transform of one mesh.
pub struct InstanceBvh {
    bvh: CwBvh,
    /// Per instance (in the caller's order): its world-to-object transform.
    world_to_object: Vec<Affine3A>,
}

impl InstanceBvh {
    /// Builds the hierarchy over instances given as (world-space bounds min and max,
    /// world-to-object transform); the caller's instance index is the position in `instances`.
    pub fn build(instances: impl ExactSizeIterator<Item = ((Vec3, Vec3), Affine3A)>) -> Self {
        let mut bounds = Vec::with_capacity(instances.len());
        let mut world_to_object = Vec::with_capacity(instances.len());
        for ((min, max), transform) in instances {
            bounds.push(Aabb::new(min.into(), max.into()));
            world_to_object.push(transform);
        }
        let bvh = if bounds.is_empty() {
            CwBvh::default()
        } else {
            let mut build_time = Duration::ZERO;
            build_cwbvh(&bounds, BvhBuildParams::medium_build(), &mut build_time)
        };
        InstanceBvh { bvh, world_to_object }
    }

    /// Number of instances.
    pub fn len(&self) -> usize {
        self.world_to_object.len()
    }

    /// True when there are no instances.
    pub fn is_empty(&self) -> bool {
        self.world_to_object.is_empty()
    }

    /// Visits the instances whose bounds `ray` crosses within (0, ray.t_max), nearest
    /// bounds first: `test(instance, object_ray)` gets the ray in the instance's object space
    /// with the current bound as `t_max`, and returns the distance of a closer hit it found
    /// (which becomes the bound), or `None`. Returns the final bound.
    #[inline]
    pub fn closest(&self, ray: &Ray, mut test: impl FnMut(u32, &Ray) -> Option<f32>) -> f32 {
        let mut bound = ray.t_max;
        if self.is_empty() {
            return bound;
        }
        let bvh_ray = to_bvh_ray(ray);
        let oct = node::octant_inv4(bvh_ray.direction);
        traverse_nodes(&self.bvh.nodes, 0, oct, ray.t_max, |n, t_max| node::intersect_portable(n, &bvh_ray, oct, t_max), |index, lanes, t_max| {
            let base = self.bvh.nodes[index].primitive_base_idx;
            for k in (0..24).filter(|k| lanes & (1 << k) != 0) {
                let instance = self.bvh.primitive_indices[(base + k) as usize];
                let object_ray = self.object_ray(instance, ray, *t_max);
                if let Some(t) = test(instance, &object_ray) {
                    *t_max = t;
                    bound = t;
                }
            }
            false
        });
        bound
    }

    /// Whether `test(instance, object_ray)` answers true for an instance whose bounds the ray
    /// crosses within (0, ray.t_max) (stopping at the first).
    #[inline]
    pub fn any(&self, ray: &Ray, mut test: impl FnMut(u32, &Ray) -> bool) -> bool {
        if self.is_empty() {
            return false;
        }
        let bvh_ray = to_bvh_ray(ray);
        let oct = node::octant_inv4(bvh_ray.direction);
        let mut found = false;
        traverse_nodes(&self.bvh.nodes, 0, oct, ray.t_max, |n, t_max| node::intersect_portable(n, &bvh_ray, oct, t_max), |index, lanes, _| {
            let base = self.bvh.nodes[index].primitive_base_idx;
            for k in (0..24).filter(|k| lanes & (1 << k) != 0) {
                let instance = self.bvh.primitive_indices[(base + k) as usize];
                if test(instance, &self.object_ray(instance, ray, ray.t_max)) {
                    found = true;
                    return true;
                }
            }
            false
        });
        found
    }

    #[inline]
    fn object_ray(&self, instance: u32, ray: &Ray, t_max: f32) -> Ray {
        let m = &self.world_to_object[instance as usize];
        Ray {
            origin: m.transform_point3(ray.origin),
            direction: m.transform_vector3(ray.direction),
            t_max,
        }
    }

    /// Number of CWBVH nodes.
    pub fn node_count(&self) -> usize {
        self.bvh.nodes.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Bvh;
    use glam::Mat4;

    /// A unit triangle instanced three times along x: the closest instance is found through
    /// object-space rays whose distances are world distances, and occlusion stops at any.
    #[test]
    fn instances_are_traced_in_object_space() {
        let mesh = Bvh::build([[Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(0.0, 1.0, 0.0)]].into_iter());
        let to_world: Vec<Mat4> = (0..3).map(|i| Mat4::from_translation(Vec3::new(0.0, 0.0, -2.0 * i as f32)) * Mat4::from_scale(Vec3::splat(1.0 + i as f32))).collect();
        let instances = InstanceBvh::build(to_world.iter().map(|m| {
            let (lo, hi) = (m.transform_point3(Vec3::new(-1.0, -1.0, 0.0)), m.transform_point3(Vec3::new(1.0, 1.0, 0.0)));
            ((lo.min(hi), lo.max(hi)), Affine3A::from_mat4(*m).inverse())
        }));
        assert_eq!(instances.len(), 3);
        let ray = Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::NEG_Z);
        let mut nearest = None;
        let t = instances.closest(&ray, |instance, object_ray| {
            let hit = mesh.intersect(object_ray)?;
            nearest = Some(instance);
            Some(hit.t)
        });
        assert_eq!(nearest, Some(0));
        assert!((t - 5.0).abs() < 1e-5, "{t}");
        // Off-centre at x = 1.2: only the instances scaled by 2 and 3 cover it; the nearer
        // (instance 1, at z = −2) wins, 7 units away.
        let ray = Ray::new(Vec3::new(1.2, -0.5, 5.0), Vec3::NEG_Z);
        let mut nearest = None;
        let t = instances.closest(&ray, |instance, object_ray| {
            let hit = mesh.intersect(object_ray)?;
            nearest = Some(instance);
            Some(hit.t)
        });
        assert_eq!(nearest, Some(1));
        assert!((t - 7.0).abs() < 1e-5, "{t}");
        assert!(instances.any(&ray, |_, r| mesh.occluded(r)));
        assert!(!instances.any(&Ray { t_max: 6.0, ..ray }, |_, r| mesh.occluded(r)));
    }
}
