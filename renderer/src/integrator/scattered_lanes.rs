//! What the lane kernels ([`super::bxdf_lanes`]) give per lane, their dispatch to the
//! widest vector instructions the CPU has, and the grouping of vertices sixteen at a time.

use super::{Continuation, Scattered, ShadowTest};
use crate::accel::Ray;
use crate::lanes::{F32s, Vec3s, LANES};
use crate::Rgb;
use glam::Vec3;

/// [`Scattered`] for [`LANES`] vertices, structure of arrays.
#[derive(Clone, Debug, Default)]
pub(crate) struct ScatteredLanes {
    /// The vertices' positions.
    pub p: Vec3s,
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
    /// Whether the continuation comes from a delta lobe.
    pub next_delta: [bool; LANES],
    /// [`Continuation::sigma_a`] (set by transmitting kernels only).
    pub next_sigma_a: [Option<Rgb>; LANES],
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
                delta: self.next_delta[i],
                sigma_a: self.next_sigma_a[i],
            }),
        }
    }
}

/// A kernel over [`LANES`] vertices, run by [`scatter`] compiled for the widest vector
/// instructions the CPU has.
pub(crate) trait LaneKernel {
    /// Scatters every lane (the filled ones matter) into `out` (with the vertices'
    /// positions); `light_only` weighs light samples by 1 instead of the power heuristic.
    /// Written with [`crate::lanes`] types and `#[inline(always)]`, so that it is compiled
    /// into each of [`scatter`]'s copies.
    fn scatter_lanes(&self, light_only: bool, out: &mut ScatteredLanes);

    /// Number of lanes filled.
    fn len(&self) -> usize;

    /// Empties the lanes (their old values stay, unused).
    fn clear(&mut self);
}

/// The vertices of one lane kernel in a batch, gathered [`LANES`] at a time:
/// [`LaneGroup::push`] fills a lane and, once all are filled, scatters them and hands each
/// lane's result on; [`LaneGroup::finish`] does so for the last, partial group.
#[derive(Default)]
pub(crate) struct LaneGroup<K> {
    lanes: K,
    /// The path (index) of each filled lane's vertex.
    paths: [u32; LANES],
    out: ScatteredLanes,
}

impl<K: LaneKernel> LaneGroup<K> {
    /// Fills the next lane with the vertex of path `path` by `fill` (one push into the
    /// kernel's lanes); once all are filled, scatters them and calls `settle` with each
    /// lane's path, vertex position and result, in the order they were pushed.
    #[inline]
    pub fn push(&mut self, path: u32, light_only: bool, fill: impl FnOnce(&mut K), settle: impl FnMut(u32, Vec3, Scattered)) {
        let lane = self.lanes.len();
        self.paths[lane] = path;
        fill(&mut self.lanes);
        debug_assert_eq!(self.lanes.len(), lane + 1, "one vertex per push");
        if self.lanes.len() == LANES {
            self.flush(light_only, settle);
        }
    }

    /// Scatters and settles the lanes filled since the last full group, if any.
    pub fn finish(&mut self, light_only: bool, settle: impl FnMut(u32, Vec3, Scattered)) {
        if self.lanes.len() > 0 {
            self.flush(light_only, settle);
        }
    }

    #[inline]
    fn flush(&mut self, light_only: bool, mut settle: impl FnMut(u32, Vec3, Scattered)) {
        scatter(&self.lanes, light_only, &mut self.out);
        for (lane, &path) in self.paths[..self.lanes.len()].iter().enumerate() {
            settle(path, self.out.p.get(lane), self.out.get(lane));
        }
        self.lanes.clear();
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
