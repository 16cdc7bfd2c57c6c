//! What the lane kernels ([`super::diffuse_lanes`], [`super::glossy_lanes`]) give per lane,
//! and the integrator's helpers they share, per lane with the scalar code's operations (so
//! the same bits).

use super::{Continuation, Scattered, ShadowTest};
use crate::accel::Ray;
use crate::lanes::{F32s, Vec3s, LANES};

/// [`Scattered`] for [`LANES`] vertices, structure of arrays.
#[derive(Clone, Debug, Default)]
pub(crate) struct ScatteredLanes {
    pub shadow_ok: [bool; LANES],
    pub shadow_origin: Vec3s,
    pub shadow_direction: Vec3s,
    pub shadow_t_max: F32s,
    pub contribution: Vec3s,
    pub next_ok: [bool; LANES],
    pub next_origin: Vec3s,
    pub next_direction: Vec3s,
    pub next_beta: Vec3s,
    pub next_pdf: F32s,
}

impl ScatteredLanes {
    /// The result of lane `i`.
    #[inline]
    pub fn get(&self, i: usize) -> Scattered {
        Scattered {
            shadow: self.shadow_ok[i].then(|| ShadowTest {
                ray: Ray {
                    origin: self.shadow_origin.get(i),
                    direction: self.shadow_direction.get(i),
                    t_max: self.shadow_t_max.0[i],
                },
                contribution: self.contribution.get(i),
            }),
            next: self.next_ok[i].then(|| Continuation {
                ray: Ray::new(self.next_origin.get(i), self.next_direction.get(i)),
                beta: self.next_beta.get(i),
                pdf: self.next_pdf.0[i],
            }),
        }
    }
}

/// A kernel over [`LANES`] vertices, run by [`scatter`] compiled for the widest vector
/// instructions the CPU has.
pub(crate) trait LaneKernel {
    /// Scatters every lane (the filled ones matter) into `out`; `light_only` weighs light
    /// samples by 1 instead of the power heuristic. Written with [`crate::lanes`] types and
    /// `#[inline(always)]`, so that it is compiled into each of [`scatter`]'s copies.
    fn scatter_lanes(&self, light_only: bool, out: &mut ScatteredLanes);

    /// Number of lanes filled.
    fn len(&self) -> usize;

    /// Empties the lanes (their old values stay, unused).
    fn clear(&mut self);
}

/// The vertices of one lane kernel in a batch, gathered [`LANES`] at a time: the kernel's
/// lanes being filled and the results of the groups scattered so far. [`LaneGroups::push`]
/// fills a lane and scatters full groups; [`LaneGroups::finish`] scatters the last, partial
/// one.
#[derive(Default)]
pub(crate) struct LaneGroups<K> {
    lanes: K,
    groups: Vec<ScatteredLanes>,
    /// Groups scattered since the last [`LaneGroups::clear`].
    scattered: u32,
}

impl<K: LaneKernel> LaneGroups<K> {
    /// Starts a new batch.
    pub fn clear(&mut self) {
        self.lanes.clear();
        self.scattered = 0;
    }

    /// Fills the next lane with `fill` (one push into the kernel's lanes), scatters the lanes
    /// once all are filled, and returns the group and lane where the vertex's result will be.
    #[inline]
    pub fn push(&mut self, light_only: bool, fill: impl FnOnce(&mut K)) -> (u32, u32) {
        let slot = (self.scattered, self.lanes.len() as u32);
        fill(&mut self.lanes);
        debug_assert_eq!(self.lanes.len() as u32, slot.1 + 1, "one vertex per push");
        if self.lanes.len() == LANES {
            self.flush(light_only);
        }
        slot
    }

    /// Scatters the lanes filled since the last full group, if any.
    pub fn finish(&mut self, light_only: bool) {
        if self.lanes.len() > 0 {
            self.flush(light_only);
        }
    }

    fn flush(&mut self, light_only: bool) {
        let group = self.scattered as usize;
        if self.groups.len() <= group {
            self.groups.resize_with(group + 1, ScatteredLanes::default);
        }
        scatter(&self.lanes, light_only, &mut self.groups[group]);
        self.lanes.clear();
        self.scattered += 1;
    }

    /// The result of the vertex pushed at `slot` (after it was scattered).
    #[inline]
    pub fn get(&self, (group, lane): (u32, u32)) -> Scattered {
        self.groups[group as usize].get(lane as usize)
    }
}

/// Runs `kernel` compiled for AVX-512 or AVX2 where the CPU has them, portable code
/// elsewhere (the same values: the lane operations are the scalar ones).
pub(crate) fn scatter<K: LaneKernel>(kernel: &K, light_only: bool, out: &mut ScatteredLanes) {
    #[cfg(target_arch = "x86_64")]
    {
        if crate::support::cpu::has_avx512f() {
            // SAFETY: the CPU has AVX-512F.
            return unsafe { scatter_avx512(kernel, light_only, out) };
        }
        if crate::support::cpu::has_avx2() {
            // SAFETY: the CPU has AVX2.
            return unsafe { scatter_avx2(kernel, light_only, out) };
        }
    }
    kernel.scatter_lanes(light_only, out)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn scatter_avx512<K: LaneKernel>(kernel: &K, light_only: bool, out: &mut ScatteredLanes) {
    kernel.scatter_lanes(light_only, out)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn scatter_avx2<K: LaneKernel>(kernel: &K, light_only: bool, out: &mut ScatteredLanes) {
    kernel.scatter_lanes(light_only, out)
}

/// [`crate::accel::offset_ray_origin`] per lane.
#[inline(always)]
pub(crate) fn offset_ray_origin(p: Vec3s, p_error: Vec3s, n: Vec3s, w: Vec3s) -> Vec3s {
    let zero = F32s::splat(0.0);
    let d = n.abs().dot(p_error);
    let offset = w.dot(n).lt(zero).select3(-n * d, n * d);
    let po = p + offset;
    let away = |o: F32s| o.eq(zero).select(zero, o.signum());
    let away = Vec3s {
        x: away(offset.x),
        y: away(offset.y),
        z: away(offset.z),
    };
    po + away * (po.abs() * f32::EPSILON + f32::MIN_POSITIVE)
}

/// [`crate::sampling::power_heuristic`] per lane.
#[inline(always)]
pub(crate) fn power_heuristic(f: F32s, g: F32s) -> F32s {
    let (f2, g2) = (f * f, g * g);
    let sum = f2 + g2;
    let ratio = sum.eq(F32s::splat(0.0)).select(F32s::splat(0.0), f2 / sum);
    f2.is_infinite().select(F32s::splat(1.0), ratio)
}
