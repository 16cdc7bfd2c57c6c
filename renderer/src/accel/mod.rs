//! Ray–triangle acceleration: an `obvhs` compressed-wide BVH (CWBVH) over every triangle
//! of a scene, closest-hit and occlusion queries (eight children and up to eight leaf
//! triangles per SIMD step), and robust ray-origin offsets.

mod instances;
mod node;

pub(crate) use node::negative_axes;
#[cfg(target_arch = "x86_64")]
mod packet;
mod policy;
mod triangle_pack;

pub use instances::InstanceBvh;
pub use policy::TracePolicy;

use crate::lanes::{MaskOps, Real, V2, V3};
use crate::support::cpu::has_avx2_fma;
use glam::{UVec2, Vec2, Vec3, Vec3A};
use obvhs::cwbvh::node::CwBvhNode;
use triangle_pack::{PackHit, TrianglePack, LANES};
use obvhs::cwbvh::{builder::build_cwbvh_from_tris, CwBvh};
use obvhs::ray::Ray as BvhRay;
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;
use std::mem::MaybeUninit;
use std::time::Duration;

/// A ray with a parametric interval. Seven floats in declaration order (`repr(C)`), which
/// the packet kernels gather lane by lane.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
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
    /// The instance whose mesh the triangle belongs to ([`NO_INSTANCE`] for triangles stored
    /// in world space).
    pub instance: u32,
}

/// [`Hit::instance`] of a triangle stored in world space.
pub const NO_INSTANCE: u32 = u32::MAX;

/// Bounding volume hierarchy over a triangle soup: an obvhs CWBVH whose leaf triangles are
/// stored in packs of eight, so up to eight of a node's leaf triangles are tested in one SIMD
/// pass.
pub struct Bvh {
    bvh: CwBvh,
    /// The triangles of obvhs's primitive slots, eight per pack: slot s is lane s % 8 of
    /// pack s / 8. A node's leaf slots are contiguous from its `primitive_base_idx`, so they
    /// span up to four packs, which they may share with the neighbouring nodes' slots
    /// (unpadded: a pack per eight triangles, 16 % fewer than packs per node on the
    /// material-preview's sphere, and no look-up of a node's first pack).
    packs: Vec<TrianglePack>,
    /// How batches of closest-hit and of occlusion queries are traced, per class of path
    /// depth (see [`DEPTH_CLASSES`]).
    closest_policies: [TracePolicy; DEPTH_CLASSES],
    occluded_policies: [TracePolicy; DEPTH_CLASSES],
}

/// Classes of batches whose trace mode is chosen apart, by the depth of their rays' paths
/// (0: rays from the camera or to lights from its hits), the last class taking every deeper
/// batch. Rays that leave the camera together stay together and suit packets; rays scattered
/// from surfaces spread, and on dense meshes one at a time is faster for them — one policy
/// for both would give one of them the wrong mode.
pub const DEPTH_CLASSES: usize = 3;

/// The class of batches at path depth `depth`.
#[inline]
pub(crate) fn depth_class(depth: usize) -> usize {
    depth.min(DEPTH_CLASSES - 1)
}

/// A traversal stack: 64 entries in place (left uninitialised until pushed); deeper trees
/// spill to the heap.
struct Stack<T: Copy> {
    inline: [MaybeUninit<T>; 64],
    len: usize,
    spill: Vec<T>,
}

impl<T: Copy> Stack<T> {
    #[inline(always)]
    fn new() -> Self {
        Stack {
            inline: [MaybeUninit::uninit(); 64],
            len: 0,
            spill: Vec::new(),
        }
    }

    #[inline(always)]
    fn push(&mut self, entry: T) {
        if self.len < self.inline.len() {
            self.inline[self.len].write(entry);
            self.len += 1;
        } else {
            self.spill.push(entry);
        }
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<T> {
        if let Some(entry) = self.spill.pop() {
            return Some(entry);
        }
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: entries below `len` were written by `push`.
        Some(unsafe { self.inline[self.len].assume_init() })
    }
}

/// A closest hit found in traversal: distance, primitive slot, barycentrics.
type SlotHit = (f32, u32, Vec2);

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
                packs: Vec::new(),
                closest_policies: std::array::from_fn(|_| TracePolicy::new(false)),
                occluded_policies: std::array::from_fn(|_| TracePolicy::new(false)),
            };
        }
        let mut build_time = Duration::ZERO;
        let bvh = build_cwbvh_from_tris(&input, params, &mut build_time);
        let packs = bvh
            .primitive_indices
            .chunks(LANES)
            .map(|slots| {
                let mut pack = TrianglePack::default();
                for (lane, &triangle) in slots.iter().enumerate() {
                    let t = &input[triangle as usize];
                    pack.set(lane, [t.v0, t.v1, t.v2]);
                }
                pack
            })
            .collect();
        Bvh {
            closest_policies: std::array::from_fn(|_| TracePolicy::new(packets_available())),
            occluded_policies: std::array::from_fn(|_| TracePolicy::new(packets_available())),
            bvh,
            packs,
        }
    }

    /// Number of triangles (slots) in the hierarchy.
    pub fn len(&self) -> usize {
        self.bvh.primitive_indices.len()
    }

    /// True when the hierarchy holds no triangles.
    pub fn is_empty(&self) -> bool {
        self.bvh.primitive_indices.is_empty()
    }

    /// The scene triangle index of obvhs primitive slot `slot`.
    #[inline]
    fn scene_triangle(&self, slot: u32) -> u32 {
        self.bvh.primitive_indices[slot as usize]
    }

    /// The hit at distance `t` with barycentrics `barycentric` on primitive slot `slot`.
    #[inline]
    fn slot_hit(&self, slot: u32, t: f32, barycentric: Vec2) -> Hit {
        Hit { t, triangle: self.scene_triangle(slot), barycentric, instance: NO_INSTANCE }
    }

    /// Closest intersection with t in (0, ray.t_max), or `None`.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if self.is_empty() {
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
        found.map(|(t, slot, barycentric)| self.slot_hit(slot, t, barycentric))
    }

    /// Closest hits of many rays at path depth `depth` (0 for camera rays): `out[i]` =
    /// [`Bvh::intersect`] of `rays[i]`, traced in packets or one by one as the closest-hit
    /// [`TracePolicy`] of the depth's class ([`DEPTH_CLASSES`]) has found faster.
    pub fn intersect_all(&self, rays: &[Ray], out: &mut Vec<Option<Hit>>, depth: usize) {
        self.closest_policies[depth_class(depth)].trace(rays.len(), |packets| self.intersect_all_with(rays, out, packets));
    }

    /// As [`Bvh::intersect_all`], in packets whenever the CPU has a packet kernel
    /// (`packets`; see [`Bvh::packet_width`]) or one ray at a time: for benchmarks comparing
    /// the two.
    pub fn intersect_all_with(&self, rays: &[Ray], out: &mut Vec<Option<Hit>>, packets: bool) {
        // SAFETY: `trace_all` traces packets only where AVX2 and FMA exist.
        self.trace_all(rays, out, packets, |r, o| unsafe { self.closest_packet(r, o, &packet::EveryHit) }, |r| self.intersect(r));
    }

    /// [`Bvh::intersect_filtered`] of many rays at path depth `depth`, `accept(ray, hit)`
    /// deciding which hits stop a ray: traced in packets or one by one as the closest-hit
    /// [`TracePolicy`] of the depth's class has found faster.
    pub fn intersect_all_filtered(&self, rays: &[Ray], out: &mut Vec<Option<Hit>>, depth: usize, accept: impl Fn(&Ray, &Hit) -> bool) {
        self.closest_policies[depth_class(depth)].trace(rays.len(), |packets| self.intersect_all_filtered_with(rays, out, packets, &accept));
    }

    /// As [`Bvh::intersect_all_filtered`], in packets where `packets` is asked for and the
    /// CPU has a packet kernel, or one ray at a time.
    pub fn intersect_all_filtered_with(&self, rays: &[Ray], out: &mut Vec<Option<Hit>>, packets: bool, accept: impl Fn(&Ray, &Hit) -> bool) {
        let packet = |r: &[Ray], o: &mut [_]| {
            let filter = packet::Accepted(|i: usize, slot, t, b| accept(&r[i], &self.slot_hit(slot, t, b)));
            // SAFETY: `trace_all` traces packets only where AVX2 and FMA exist.
            unsafe { self.closest_packet(r, o, &filter) }
        };
        self.trace_all(rays, out, packets, packet, |r| self.intersect_filtered(r, |h| accept(r, h)))
    }

    /// Fills `out[i]` with the answer for `rays[i]`, as [`trace_chunks`] (packets only in a
    /// BVH with triangles), `single` giving one ray's.
    #[inline]
    fn trace_all<T: Clone + Default>(&self, rays: &[Ray], out: &mut Vec<T>, packets: bool, packet: impl FnMut(&[Ray], &mut [T]), single: impl Fn(&Ray) -> T) {
        out.clear();
        out.resize(rays.len(), T::default());
        trace_chunks(rays, out, packets && !self.is_empty(), packet, |r, o| *o = single(r));
    }

    /// Occlusion of many rays from vertices at path depth `depth` (0 for the camera's
    /// hits): `out[i]` = [`Bvh::occluded`] of `rays[i]`, traced in packets or one by one as
    /// the occlusion [`TracePolicy`] of the depth's class has found faster.
    pub fn occluded_all(&self, rays: &[Ray], out: &mut Vec<bool>, depth: usize) {
        self.occluded_policies[depth_class(depth)].trace(rays.len(), |packets| self.occluded_all_with(rays, out, packets));
    }

    /// Per class of depth ([`DEPTH_CLASSES`]), the traversal modes its closest-hit and
    /// occlusion batches use now (true: packets), or `None` before the first measurement.
    pub fn trace_modes(&self) -> [(Option<bool>, Option<bool>); DEPTH_CLASSES] {
        std::array::from_fn(|c| (self.closest_policies[c].choice(), self.occluded_policies[c].choice()))
    }

    /// As [`Bvh::occluded_all`], in packets whenever the CPU has a packet kernel (`packets`)
    /// or one ray at a time.
    pub fn occluded_all_with(&self, rays: &[Ray], out: &mut Vec<bool>, packets: bool) {
        // SAFETY: `trace_all` traces packets only where AVX2 and FMA exist.
        self.trace_all(rays, out, packets, |r, o| unsafe { self.occluded_packet(r, o, &packet::EveryHit) }, |r| self.occluded(r));
    }

    /// [`Bvh::occluded_filtered`] of many rays at path depth `depth`, `accept(ray, hit)`
    /// deciding which hits block a ray, traced as the occlusion [`TracePolicy`] of the
    /// depth's class has found faster.
    pub fn occluded_all_filtered(&self, rays: &[Ray], out: &mut Vec<bool>, depth: usize, accept: impl Fn(&Ray, &Hit) -> bool) {
        self.occluded_policies[depth_class(depth)].trace(rays.len(), |packets| self.occluded_all_filtered_with(rays, out, packets, &accept));
    }

    /// As [`Bvh::occluded_all_filtered`], in packets where `packets` is asked for and the CPU
    /// has a packet kernel, or one ray at a time.
    pub fn occluded_all_filtered_with(&self, rays: &[Ray], out: &mut Vec<bool>, packets: bool, accept: impl Fn(&Ray, &Hit) -> bool) {
        let packet = |r: &[Ray], o: &mut [_]| {
            let filter = packet::Accepted(|i: usize, slot, t, b| accept(&r[i], &self.slot_hit(slot, t, b)));
            // SAFETY: `trace_all` traces packets only where AVX2 and FMA exist.
            unsafe { self.occluded_packet(r, o, &filter) }
        };
        self.trace_all(rays, out, packets, packet, |r| self.occluded_filtered(r, |h| accept(r, h)))
    }

    /// Rays per packet of [`Bvh::intersect_all`] and [`Bvh::occluded_all`] on this CPU:
    /// 16 with AVX-512F, 8 with AVX2 and FMA, `None` without packet kernels.
    pub fn packet_width() -> Option<usize> {
        #[cfg(target_arch = "x86_64")]
        if packets_available() {
            return Some(packet::width());
        }
        None
    }

    /// Number of CWBVH nodes.
    pub fn node_count(&self) -> usize {
        self.bvh.nodes.len()
    }

    /// True when anything blocks the ray within (0, ray.t_max).
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        if self.is_empty() {
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

    /// The closest hit with t in (0, ray.t_max) that `accept` takes, or `None`: for surfaces
    /// rays can pass through (alpha cut-outs), `accept` decides for each hit triangle on the
    /// way whether the ray stops there. It is asked only about hits closer than the closest
    /// accepted one so far, in no particular order, and must be a pure function of its hit
    /// (and of the ray it was made for).
    pub fn intersect_filtered(&self, ray: &Ray, accept: impl Fn(&Hit) -> bool) -> Option<Hit> {
        if self.is_empty() {
            return None;
        }
        let bvh_ray = to_bvh_ray(ray);
        let accept_slot = |slot: u32, t: f32, barycentric: Vec2| accept(&self.slot_hit(slot, t, barycentric));
        #[cfg(target_arch = "x86_64")]
        let found = if has_avx2_fma() {
            // SAFETY: the CPU supports AVX2 and FMA.
            unsafe { self.closest_filtered_below_avx2(0, &bvh_ray, &accept_slot) }
        } else {
            self.closest_filtered_portable(&bvh_ray, &accept_slot)
        };
        #[cfg(not(target_arch = "x86_64"))]
        let found = self.closest_filtered_portable(&bvh_ray, &accept_slot);
        found.map(|(t, slot, barycentric)| self.slot_hit(slot, t, barycentric))
    }

    /// True when a hit that `accept` takes (see [`Bvh::intersect_filtered`]) blocks the ray
    /// within (0, ray.t_max).
    pub fn occluded_filtered(&self, ray: &Ray, accept: impl Fn(&Hit) -> bool) -> bool {
        if self.is_empty() {
            return false;
        }
        let bvh_ray = to_bvh_ray(ray);
        let accept_slot = |slot: u32, t: f32, barycentric: Vec2| accept(&self.slot_hit(slot, t, barycentric));
        #[cfg(target_arch = "x86_64")]
        if has_avx2_fma() {
            // SAFETY: the CPU supports AVX2 and FMA.
            return unsafe { self.any_filtered_below_avx2(0, &bvh_ray, &accept_slot) };
        }
        let oct = node::octant_inv4(bvh_ray.direction);
        self.any_filtered_with(0, &bvh_ray, |n, t_max| node::intersect_portable(n, &bvh_ray, oct, t_max), &accept_slot)
    }

    /// Whether a hit that `accept` takes blocks the ray below node `root`, with the given node
    /// kernel (triangles one at a time: each hit is asked about).
    #[inline(always)]
    fn any_filtered_with(&self, root: u32, ray: &BvhRay, intersect_node: impl FnMut(&CwBvhNode, f32) -> u32, accept: &impl Fn(u32, f32, Vec2) -> bool) -> bool {
        let mut hit = false;
        self.traverse(root, node::octant_inv4(ray.direction), ray.tmax, intersect_node, |index, lanes, _| {
            let slot_base = self.bvh.nodes[index].primitive_base_idx;
            let mut rest = lanes;
            while rest != 0 {
                let slot = slot_base + rest.trailing_zeros();
                rest &= rest - 1;
                let (pack, lane) = pack_and_lane(slot);
                if let Some((t, barycentric)) = self.packs[pack].lane_hit(lane, ray.origin, ray.direction, ray.tmax) {
                    if accept(slot, t, barycentric) {
                        hit = true;
                        return true;
                    }
                }
            }
            false
        });
        hit
    }

    /// [`Bvh::occluded_filtered`] below node `root` with AVX2 and FMA.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn any_filtered_below_avx2(&self, root: u32, ray: &BvhRay, accept: &impl Fn(u32, f32, Vec2) -> bool) -> bool {
        let oct = node::octant_inv4(ray.direction);
        // SAFETY: this function runs only where AVX2 and FMA exist.
        self.any_filtered_with(root, ray, |n, t_max| unsafe { node::intersect_avx2(n, ray, oct, t_max) }, accept)
    }

    /// Closest accepted hit with the given node and pack kernels: each pack's closest hit
    /// from `pack_closest`, and where `accept` refuses it, the pack's lanes one by one.
    #[inline(always)]
    fn closest_filtered_with(
        &self,
        root: u32,
        ray: &BvhRay,
        intersect_node: impl FnMut(&CwBvhNode, f32) -> u32,
        mut pack_closest: impl FnMut(&TrianglePack, u32, f32) -> Option<PackHit>,
        accept: &impl Fn(u32, f32, Vec2) -> bool,
    ) -> Option<SlotHit> {
        let mut best: Option<SlotHit> = None;
        self.traverse(root, node::octant_inv4(ray.direction), ray.tmax, intersect_node, |index, lanes, t_max| {
            let (mut pack, mut slot_base, mut lanes) = slots_in_packs(self.bvh.nodes[index].primitive_base_idx, lanes);
            while lanes != 0 {
                let pack_lanes = lanes & 0xff;
                if pack_lanes != 0 {
                    let p = &self.packs[pack];
                    if let Some((t, lane, b)) = pack_closest(p, pack_lanes, *t_max) {
                        if accept(slot_base + lane, t, b) {
                            *t_max = t;
                            best = Some((t, slot_base + lane, b));
                        } else {
                            for lane in (0..LANES as u32).filter(|l| pack_lanes & (1 << l) != 0) {
                                if let Some((t, b)) = p.lane_hit(lane as usize, ray.origin, ray.direction, *t_max) {
                                    if accept(slot_base + lane, t, b) {
                                        *t_max = t;
                                        best = Some((t, slot_base + lane, b));
                                    }
                                }
                            }
                        }
                    }
                }
                lanes >>= LANES;
                pack += 1;
                slot_base += LANES as u32;
            }
            false
        });
        best
    }

    fn closest_filtered_portable(&self, ray: &BvhRay, accept: &impl Fn(u32, f32, Vec2) -> bool) -> Option<SlotHit> {
        let oct = node::octant_inv4(ray.direction);
        self.closest_filtered_with(
            0,
            ray,
            |n, t_max| node::intersect_portable(n, ray, oct, t_max),
            |p, lanes, t_max| p.closest_portable(ray.origin, ray.direction, lanes, t_max),
            accept,
        )
    }

    /// [`Bvh::intersect_filtered`] below node `root` with AVX2 and FMA.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn closest_filtered_below_avx2(&self, root: u32, ray: &BvhRay, accept: &impl Fn(u32, f32, Vec2) -> bool) -> Option<SlotHit> {
        let oct = node::octant_inv4(ray.direction);
        self.closest_filtered_with(
            root,
            ray,
            // SAFETY (both kernels): this function runs only where AVX2 and FMA exist.
            |n, t_max| unsafe { node::intersect_avx2(n, ray, oct, t_max) },
            |p, lanes, t_max| unsafe { triangle_pack::avx2::closest(p, ray.origin, ray.direction, lanes, t_max) },
            accept,
        )
    }

    /// [`traverse_nodes`] over this hierarchy's nodes.
    #[inline(always)]
    fn traverse(
        &self,
        root: u32,
        oct_inv4: u32,
        t_max: f32,
        intersect_node: impl FnMut(&CwBvhNode, f32) -> u32,
        leaves: impl FnMut(usize, u32, &mut f32) -> bool,
    ) {
        traverse_nodes(&self.bvh.nodes, root, oct_inv4, t_max, intersect_node, leaves)
    }

    /// Closest hit with the given node and pack kernels.
    #[inline(always)]
    fn closest_with(
        &self,
        root: u32,
        ray: &BvhRay,
        intersect_node: impl FnMut(&CwBvhNode, f32) -> u32,
        pack_closest: impl FnMut(&TrianglePack, u32, f32) -> Option<PackHit>,
    ) -> Option<SlotHit> {
        self.closest_filtered_with(root, ray, intersect_node, pack_closest, &|_, _, _| true)
    }

    /// Whether anything is hit, with the given node and pack kernels.
    #[inline(always)]
    fn any_with(
        &self,
        root: u32,
        ray: &BvhRay,
        intersect_node: impl FnMut(&CwBvhNode, f32) -> u32,
        mut pack_any: impl FnMut(&TrianglePack, u32) -> bool,
    ) -> bool {
        let mut hit = false;
        self.traverse(root, node::octant_inv4(ray.direction), ray.tmax, intersect_node, |index, lanes, _| {
            let (mut pack, _, mut lanes) = slots_in_packs(self.bvh.nodes[index].primitive_base_idx, lanes);
            while lanes != 0 {
                if lanes & 0xff != 0 && pack_any(&self.packs[pack], lanes & 0xff) {
                    hit = true;
                    return true;
                }
                lanes >>= LANES;
                pack += 1;
            }
            false
        });
        hit
    }

    fn closest_portable(&self, ray: &BvhRay) -> Option<SlotHit> {
        let oct = node::octant_inv4(ray.direction);
        self.closest_with(
            0,
            ray,
            |n, t_max| node::intersect_portable(n, ray, oct, t_max),
            |p, lanes, t_max| p.closest_portable(ray.origin, ray.direction, lanes, t_max),
        )
    }

    fn any_portable(&self, ray: &BvhRay) -> bool {
        let oct = node::octant_inv4(ray.direction);
        self.any_with(
            0,
            ray,
            |n, t_max| node::intersect_portable(n, ray, oct, t_max),
            |p, lanes| p.any_portable(ray.origin, ray.direction, lanes, ray.tmax),
        )
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn closest_avx2(&self, ray: &BvhRay) -> Option<SlotHit> {
        // SAFETY: this function runs only where AVX2 and FMA exist.
        unsafe { self.closest_below_avx2(0, ray) }
    }

    /// The closest hit below node `root` with t < ray.tmax.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn closest_below_avx2(&self, root: u32, ray: &BvhRay) -> Option<SlotHit> {
        let oct = node::octant_inv4(ray.direction);
        self.closest_with(
            root,
            ray,
            // SAFETY (both kernels): this function runs only where AVX2 and FMA exist.
            |n, t_max| unsafe { node::intersect_avx2(n, ray, oct, t_max) },
            |p, lanes, t_max| unsafe { triangle_pack::avx2::closest(p, ray.origin, ray.direction, lanes, t_max) },
        )
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn any_avx2(&self, ray: &BvhRay) -> bool {
        // SAFETY: this function runs only where AVX2 and FMA exist.
        unsafe { self.any_below_avx2(0, ray) }
    }

    /// Whether anything below node `root` blocks the ray.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn any_below_avx2(&self, root: u32, ray: &BvhRay) -> bool {
        let oct = node::octant_inv4(ray.direction);
        self.any_with(
            root,
            ray,
            // SAFETY (both kernels): this function runs only where AVX2 and FMA exist.
            |n, t_max| unsafe { node::intersect_avx2(n, ray, oct, t_max) },
            |p, lanes| unsafe { triangle_pack::avx2::any(p, ray.origin, ray.direction, lanes, ray.tmax) },
        )
    }
}

/// Walks the CWBVH `nodes` below node `root` front to back by octant order (as obvhs's
/// `traverse!`), culling children beyond the current `t_max`. `intersect_node(node, t_max)`
/// returns the hit mask of a node; `leaves(node_index, primitive_mask, t_max)` tests the
/// node's hit leaf primitives (bits of slots from the node's primitive base), may lower
/// `t_max`, and returns true to stop.
#[inline(always)]
fn traverse_nodes(
    nodes: &[CwBvhNode],
    root: u32,
    oct_inv4: u32,
    mut t_max: f32,
    mut intersect_node: impl FnMut(&CwBvhNode, f32) -> u32,
    mut leaves: impl FnMut(usize, u32, &mut f32) -> bool,
) {
    let mut stack = Stack::<UVec2>::new();
    // (first child index, inner-child hit bits in the high byte | inner-child mask).
    let mut group = UVec2::new(root, 0x8000_0000);
    loop {
        if group.y & 0xff00_0000 != 0 {
            let hits = group.y;
            let child_bit = 31 - hits.leading_zeros();
            group.y &= !(1 << child_bit);
            if group.y & 0xff00_0000 != 0 {
                stack.push(group);
            }
            let slot = (child_bit - 24) ^ (oct_inv4 & 0xff);
            let index = (group.x + (hits & !(u32::MAX << slot)).count_ones()) as usize;
            let node = &nodes[index];
            let hit_mask = intersect_node(node, t_max);
            group = UVec2::new(node.child_base_idx, (hit_mask & 0xff00_0000) | node.imask as u32);
            let primitives = hit_mask & 0x00ff_ffff;
            if primitives != 0 && leaves(index, primitives, &mut t_max) {
                return;
            }
        }
        if group.y & 0xff00_0000 == 0 {
            match stack.pop() {
                Some(g) => group = g,
                None => return,
            }
        }
    }
}

/// The pack and lane holding obvhs primitive slot `slot` ([`Bvh::packs`]).
#[inline(always)]
fn pack_and_lane(slot: u32) -> (usize, usize) {
    (slot as usize / LANES, slot as usize % LANES)
}

/// Where the leaf slots `lanes` (bits from slot `slot_base`, a node's primitive base) lie in
/// the packs: the first pack, its first slot, and the bits from that slot (one byte per pack).
#[inline(always)]
fn slots_in_packs(slot_base: u32, lanes: u32) -> (usize, u32, u32) {
    let (pack, lane) = pack_and_lane(slot_base);
    // 24 leaf bits shifted by at most 7: within the word.
    (pack, (pack * LANES) as u32, lanes << lane)
}

/// Answers every ray of `rays` in `out` (one answer each, updated in place): through
/// `packet(rays, out)` in chunks of 1 to [`packet::width`] where `packets` is asked for and
/// the CPU has a packet kernel (AVX2 and FMA, which `packet` may take as given), else through
/// `single(ray, answer)` one ray at a time. Both BVH levels' batches (`Bvh::trace_all`,
/// `InstanceBvh::intersect_all_with`) go through it.
#[inline]
fn trace_chunks<T>(rays: &[Ray], out: &mut [T], packets: bool, mut packet: impl FnMut(&[Ray], &mut [T]), mut single: impl FnMut(&Ray, &mut T)) {
    assert_eq!(rays.len(), out.len(), "one answer per ray");
    #[cfg(target_arch = "x86_64")]
    if packets && packets_available() {
        let width = packet::width();
        for (r, o) in rays.chunks(width).zip(out.chunks_mut(width)) {
            packet(r, o);
        }
        return;
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (packets, &mut packet); // no packet kernels off x86-64
    for (r, o) in rays.iter().zip(out.iter_mut()) {
        single(r, o);
    }
}

/// Whether this CPU traces packets: of 16 rays with AVX-512F, else of 8 with AVX2 and FMA
/// (which single-ray subtrees take in both).
#[inline]
fn packets_available() -> bool {
    has_avx2_fma()
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
pub(crate) fn gamma(n: f32) -> f32 {
    let e = f32::EPSILON * 0.5;
    n * e / (1.0 - n * e)
}

/// A point on a triangle interpolated from barycentric coordinates, with a conservative
/// bound on its absolute rounding error per axis (pbrt-v4's interpolation bound).
#[inline]
pub fn interpolate_point(corners: [Vec3; 3], barycentric: Vec2) -> (Vec3, Vec3) {
    let (p, error) = barycentric_point(corners.map(V3::from), V2::from(barycentric));
    (p.into(), error.into())
}

/// [`interpolate_point`] over [`Real`] values (one point, or one per lane).
#[inline(always)]
pub(crate) fn barycentric_point<R: Real>(corners: [V3<R>; 3], barycentric: V2<R>) -> (V3<R>, V3<R>) {
    let b0 = R::splat(1.0) - barycentric.x - barycentric.y;
    let [v0, v1, v2] = corners;
    let p = v0 * b0 + v1 * barycentric.x + v2 * barycentric.y;
    let abs_sum = (v0 * b0).abs() + (v1 * barycentric.x).abs() + (v2 * barycentric.y).abs();
    (p, abs_sum * R::splat(gamma(7.0)))
}

/// Moves a ray origin `p` (with absolute error bound `p_error`) off its surface along the
/// geometric normal `n`, to the side of the outgoing direction `w`, far enough that the new
/// ray cannot re-hit the surface it leaves (pbrt-v4's `OffsetRayOrigin`). The offset scales
/// with the magnitude of the coordinates, so it stays valid far from the origin. Where
/// pbrt rounds each offset coordinate one float away from `p`, this adds |x|·ε (one to two
/// ulps) away from `p`: as conservative, and branch-free.
#[inline]
pub fn offset_ray_origin(p: Vec3, p_error: Vec3, n: Vec3, w: Vec3) -> Vec3 {
    offset_origin(p.into(), p_error.into(), n.into(), w.into()).into()
}

/// [`offset_ray_origin`] over [`Real`] values (one origin, or one per lane).
#[inline(always)]
pub(crate) fn offset_origin<R: Real>(p: V3<R>, p_error: V3<R>, n: V3<R>, w: V3<R>) -> V3<R> {
    let zero = R::splat(0.0);
    let d = n.abs().dot(p_error);
    let offset = w.dot(n).lt(zero).select(-n * d, n * d);
    let po = p + offset;
    let away = |o: R| R::select(o.eq(zero), zero, o.signum());
    let away = V3::new(away(offset.x), away(offset.y), away(offset.z));
    po + away * (po.abs() * R::splat(f32::EPSILON) + V3::splat(Vec3::splat(f32::MIN_POSITIVE)))
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

    /// The six faces of the cube [−1, 1]³ as quads.
    fn closed_box() -> Vec<[Vec3; 3]> {
        let mut tris = Vec::new();
        for (axis, sign) in [(0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0), (2, 1.0), (2, -1.0)] {
            tris.extend(quad(Vec3::ZERO).into_iter().map(|t| {
                t.map(|v| {
                    let v = Vec3::new(v.x, sign, v.z);
                    match axis {
                        0 => Vec3::new(v.y, v.x, v.z),
                        1 => v,
                        _ => Vec3::new(v.x, v.z, v.y),
                    }
                })
            }));
        }
        tris
    }

    /// `n` random triangles with corners spread over `size` around centres in [−10, 10]³.
    fn random_soup(seed: u64, n: usize, size: f32) -> Vec<[Vec3; 3]> {
        let mut s = crate::sampler::Sampler::new(seed, 0, 0);
        let mut point = |scale: f32| Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * scale;
        (0..n)
            .map(|_| {
                let c = point(20.0) - Vec3::splat(10.0);
                [c + point(size), c + point(size), c + point(size)]
            })
            .collect()
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
        let mut tris = closed_box();
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
                let bits = |h: Option<SlotHit>| h.map(|(t, slot, b)| (t.to_bits(), slot, b.x.to_bits(), b.y.to_bits()));
                assert_eq!(bits(simd), bits(portable));
                let short = BvhRay { tmax: portable.map(|h| h.0 * 0.5).unwrap_or(1.0), ..ray };
                // SAFETY: checked above.
                assert_eq!(unsafe { bvh.any_avx2(&short) }, bvh.any_portable(&short));
            }
        }
    }

    #[test]
    fn traversal_finds_the_brute_force_closest_hit() {
        // Random triangles, enough for a multi-level tree and nodes with several packs.
        let tris = random_soup(9, 3000, 1.5);
        let bvh = Bvh::build(tris.clone().into_iter());
        let mut s = crate::sampler::Sampler::new(1, 1, 1);
        let mut hits = 0;
        for i in 0..1000 {
            let o = Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 24.0 - Vec3::splat(12.0);
            let d = crate::sampling::sample_uniform_sphere(s.next_2d());
            let t_max = if i % 4 == 0 { 5.0 } else { f32::MAX };
            let ray = Ray { t_max, ..Ray::new(o, d) };
            let brute = tris
                .iter()
                .enumerate()
                .filter_map(|(k, &[a, b, c])| {
                    let mut pack = TrianglePack::default();
                    pack.set(0, [a.into(), b.into(), c.into()]);
                    pack.closest_portable(o.into(), d.into(), 1, t_max).map(|h| (h.0, k as u32))
                })
                .min_by(|x, y| x.0.total_cmp(&y.0));
            let found = bvh.intersect(&ray);
            assert_eq!(found.map(|h| (h.t, h.triangle)), brute, "ray {i}");
            assert_eq!(bvh.occluded(&ray), brute.is_some(), "ray {i}");
            hits += brute.is_some() as u32;
        }
        assert!(hits > 200 && hits < 1000, "a mix of hits and misses: {hits}");
    }

    /// A packet kernel under test: name, rays per packet, closest hits, occlusion.
    #[cfg(target_arch = "x86_64")]
    type Kernel = (&'static str, usize, unsafe fn(&Bvh, &[Ray], &mut [Option<Hit>]), unsafe fn(&Bvh, &[Ray], &mut [bool]));

    /// The packet kernels this CPU runs: the 8-ray AVX2 kernel, the 16-ray AVX-512 one
    /// where the CPU has AVX-512F, and the entry points that choose between them.
    #[cfg(target_arch = "x86_64")]
    fn packet_kernels() -> Vec<Kernel> {
        let mut kernels: Vec<Kernel> = Vec::new();
        if !packets_available() {
            return kernels;
        }
        // SAFETY (each): the caller guarantees what the kernel needs, as the `Kernel` type's
        // `unsafe fn` says.
        kernels.push(("8 rays, AVX2", 8, |b, r, o| unsafe { b.closest_packet8(r, o, &packet::EveryHit) }, |b, r, o| unsafe { b.occluded_packet8(r, o, &packet::EveryHit) }));
        if crate::support::cpu::has_avx512f() {
            kernels.push(("16 rays, AVX-512", 16, |b, r, o| unsafe { b.closest_packet16(r, o, &packet::EveryHit) }, |b, r, o| unsafe { b.occluded_packet16(r, o, &packet::EveryHit) }));
        }
        kernels.push(("chosen for this CPU", packet::width(), |b, r, o| unsafe { b.closest_packet(r, o, &packet::EveryHit) }, |b, r, o| unsafe { b.occluded_packet(r, o, &packet::EveryHit) }));
        kernels
    }

    /// `n` rays from points in [−scale/2, scale/2]³, every third bounded to scale/5.
    /// Incoherent rays go in random directions; coherent ones share an origin and point
    /// within a narrow cone, or (one packet in four) go along the coordinate axes from nearby
    /// origins (directions with negative zeros).
    fn packet_rays(s: &mut crate::sampler::Sampler, n: usize, scale: f32, coherent: bool) -> Vec<Ray> {
        let point = |s: &mut crate::sampler::Sampler| (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - Vec3::splat(0.5)) * scale;
        let (origin, axis) = (point(s), (s.next_1d() * 4.0) as usize);
        let centre = crate::sampling::sample_uniform_sphere(s.next_2d());
        (0..n)
            .map(|i| {
                let (o, d) = match (coherent, axis) {
                    (false, _) => (point(s), crate::sampling::sample_uniform_sphere(s.next_2d())),
                    (true, 0) => {
                        let d = [-Vec3::Y, Vec3::X, -Vec3::Z][i % 3];
                        (origin + Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) * 0.1 * scale, d)
                    }
                    (true, _) => (origin, (centre + (Vec3::new(s.next_1d(), s.next_1d(), s.next_1d()) - Vec3::splat(0.5)) * 0.1).normalize()),
                };
                let t_max = if i % 3 == 0 { scale * 0.2 } else { f32::MAX };
                Ray { t_max, ..Ray::new(o, d) }
            })
            .collect()
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn packets_find_the_single_ray_hits_bit_for_bit() {
        // A deep random tree with incoherent and coherent rays, and a closed box with rays
        // from inside; full packets and every partial size, through each kernel.
        let (random, boxed) = (random_soup(3, 2000, 2.0), closed_box());
        let scenes = [("random", Bvh::build(random.into_iter()), 24.0), ("box", Bvh::build(boxed.into_iter()), 1.8)];
        let bits = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.triangle, h.barycentric.x.to_bits(), h.barycentric.y.to_bits()));
        for (kernel, width, closest_packet, occluded_packet) in packet_kernels() {
            let mut s = crate::sampler::Sampler::new(8, 8, 8);
            for ((scene, bvh, scale), coherent) in scenes.iter().flat_map(|scene| [(scene, false), (scene, true)]) {
                let (mut rays_traced, mut hits, mut blocked_rays) = (0, 0, 0);
                for chunk in 0..200 {
                    let n = if chunk % 5 == 0 { 1 + chunk % width } else { width };
                    let rays = packet_rays(&mut s, n, *scale, coherent);
                    let mut closest = vec![None; n];
                    let mut blocked = vec![false; n];
                    // SAFETY: the kernels are those this CPU runs; 1 to `width` rays.
                    unsafe {
                        closest_packet(bvh, &rays, &mut closest);
                        occluded_packet(bvh, &rays, &mut blocked);
                    }
                    for (i, ray) in rays.iter().enumerate() {
                        let single = bvh.intersect(ray);
                        let at = || format!("{kernel}, {scene}, coherent: {coherent}, chunk {chunk}, ray {i}");
                        assert_eq!(bits(closest[i]), bits(single), "{}", at());
                        assert_eq!(blocked[i], bvh.occluded(ray), "{}", at());
                        hits += single.is_some() as u32;
                        blocked_rays += blocked[i] as u32;
                    }
                    rays_traced += n as u32;
                }
                let context = format!("{kernel}, {scene}, coherent: {coherent}");
                assert!(hits * 10 > rays_traced, "the rays hit something: {hits} of {rays_traced}, {context}");
                assert!(blocked_rays < rays_traced, "and some are not blocked: {context}");
            }
        }
    }

    /// Whether `hit` stops `ray` in the filtered tests: passes through about a third of the
    /// hits, by the ray and the triangle (as a partly covering surface does).
    fn passes_through(ray: &Ray, hit: &Hit) -> bool {
        (ray.origin.x.to_bits() ^ hit.triangle.wrapping_mul(0x9e37_79b9)).count_ones().is_multiple_of(3)
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn filtered_packets_find_the_single_ray_accepted_hits_bit_for_bit() {
        if !packets_available() {
            return;
        }
        let bvh = Bvh::build(random_soup(3, 2000, 2.0).into_iter());
        let bits = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.triangle, h.barycentric.x.to_bits(), h.barycentric.y.to_bits()));
        let widths = if crate::support::cpu::has_avx512f() { vec![8, 16] } else { vec![8] };
        for width in widths {
            let mut s = crate::sampler::Sampler::new(6, 1, 2);
            let (mut rays_traced, mut changed, mut hits) = (0, 0, 0);
            for chunk in 0..200 {
                let n = if chunk % 5 == 0 { 1 + chunk % width } else { width };
                let rays = packet_rays(&mut s, n, 24.0, chunk % 2 == 0);
                let filter = packet::Accepted(|i: usize, slot, t, barycentric| !passes_through(&rays[i], &bvh.slot_hit(slot, t, barycentric)));
                let (mut closest, mut blocked) = (vec![None; n], vec![false; n]);
                // SAFETY: AVX2 and FMA are present (and AVX-512F where width is 16); 1 to
                // `width` rays.
                unsafe {
                    if width == 16 {
                        bvh.closest_packet16(&rays, &mut closest, &filter);
                        bvh.occluded_packet16(&rays, &mut blocked, &filter);
                    } else {
                        bvh.closest_packet8(&rays, &mut closest, &filter);
                        bvh.occluded_packet8(&rays, &mut blocked, &filter);
                    }
                }
                for (i, ray) in rays.iter().enumerate() {
                    let single = bvh.intersect_filtered(ray, |h| !passes_through(ray, h));
                    assert_eq!(bits(closest[i]), bits(single), "{width} rays, chunk {chunk}, ray {i}");
                    assert_eq!(blocked[i], bvh.occluded_filtered(ray, |h| !passes_through(ray, h)), "{width} rays, chunk {chunk}, ray {i}");
                    changed += (bits(single) != bits(bvh.intersect(ray))) as u32;
                    hits += single.is_some() as u32;
                }
                rays_traced += n as u32;
            }
            assert!(changed * 20 > rays_traced && hits * 10 > rays_traced, "the filter decides some hits: {changed} changed, {hits} hits of {rays_traced}");
        }
    }

    #[test]
    fn filtered_batches_match_single_rays() {
        // The policy traces its first batches both ways (the later of the two answers is
        // kept, alternating): packets' answers are checked in about half of them.
        let bvh = Bvh::build(random_soup(5, 1500, 2.0).into_iter());
        let mut s = crate::sampler::Sampler::new(3, 7, 1);
        let (mut hits, mut blocked) = (Vec::new(), Vec::new());
        for (batch, n) in [1, 7, 9, 17, 203, 64, 33, 100].into_iter().enumerate() {
            let rays = packet_rays(&mut s, n, 24.0, batch % 2 == 1);
            bvh.intersect_all_filtered(&rays, &mut hits, 1, |r, h| !passes_through(r, h));
            bvh.occluded_all_filtered(&rays, &mut blocked, 1, |r, h| !passes_through(r, h));
            for (i, ray) in rays.iter().enumerate() {
                assert_eq!(hits[i], bvh.intersect_filtered(ray, |h| !passes_through(ray, h)), "batch of {n}, ray {i}");
                assert_eq!(blocked[i], bvh.occluded_filtered(ray, |h| !passes_through(ray, h)), "batch of {n}, ray {i}");
            }
        }
    }

    #[test]
    fn batches_traced_in_packets_match_single_rays() {
        // Batch sizes that leave a partial packet at the end, for either width.
        let bvh = Bvh::build(random_soup(5, 1500, 2.0).into_iter());
        let mut s = crate::sampler::Sampler::new(2, 7, 1);
        let (mut packet_hits, mut single_hits, mut packet_blocked, mut single_blocked) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (batch, n) in [1, 7, 9, 17, 203].into_iter().enumerate() {
            let rays = packet_rays(&mut s, n, 24.0, batch % 2 == 1);
            bvh.intersect_all_with(&rays, &mut packet_hits, true);
            bvh.intersect_all_with(&rays, &mut single_hits, false);
            bvh.occluded_all_with(&rays, &mut packet_blocked, true);
            bvh.occluded_all_with(&rays, &mut single_blocked, false);
            assert_eq!(packet_hits, single_hits, "batch of {n}");
            assert_eq!(packet_blocked, single_blocked, "batch of {n}");
            bvh.intersect_all(&rays, &mut packet_hits, batch);
            bvh.occluded_all(&rays, &mut packet_blocked, batch);
            assert_eq!(packet_hits, single_hits, "batch of {n}, as the policy traces it");
            assert_eq!(packet_blocked, single_blocked, "batch of {n}, as the policy traces it");
        }
        #[cfg(target_arch = "x86_64")]
        assert_eq!(Bvh::packet_width().is_some(), has_avx2_fma());
    }

    #[test]
    fn each_depth_class_chooses_its_trace_mode_apart() {
        let bvh = Bvh::build(random_soup(3, 500, 2.0).into_iter());
        let mut s = crate::sampler::Sampler::new(4, 0, 0);
        let rays = packet_rays(&mut s, 64, 24.0, true);
        let (mut hits, mut blocked) = (Vec::new(), Vec::new());
        bvh.intersect_all(&rays, &mut hits, 1);
        bvh.occluded_all(&rays, &mut blocked, DEPTH_CLASSES + 5);
        let modes = bvh.trace_modes();
        if Bvh::packet_width().is_none() {
            assert!(modes.iter().all(|&m| m == (Some(false), Some(false))), "{modes:?}");
            return;
        }
        assert_eq!(modes[0], (None, None), "depth 0 not measured yet");
        assert!(modes[1].0.is_some() && modes[1].1.is_none(), "only depth 1's closest hits measured: {modes:?}");
        assert!(modes[DEPTH_CLASSES - 1].0.is_none() && modes[DEPTH_CLASSES - 1].1.is_some(), "deeper batches share the last class: {modes:?}");
    }

    #[test]
    fn empty_bvh_misses() {
        let bvh = Bvh::build(Vec::new().into_iter());
        assert!(bvh.is_empty());
        assert!(bvh.intersect(&Ray::new(Vec3::ZERO, Vec3::X)).is_none());
        assert!(!bvh.occluded(&Ray::new(Vec3::ZERO, Vec3::X)));
    }
}
