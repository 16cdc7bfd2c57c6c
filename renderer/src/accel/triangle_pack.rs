//! Eight triangles stored structure-of-arrays and intersected with one ray in one pass
//! (Möller–Trumbore per lane), with an AVX2 kernel and a portable one that computes the same
//! operations in the same order, so both give bit-identical hits.

use glam::{Vec2, Vec3A};

/// Lanes per pack.
pub const LANES: usize = 8;

/// Eight triangles as corner v0 and edges e1 = v1 − v0, e2 = v2 − v0, one lane each, per
/// axis. Unused lanes hold zero edges (determinant 0: never hit).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(32))]
pub struct TrianglePack {
    pub(super) v0: [[f32; LANES]; 3],
    pub(super) e1: [[f32; LANES]; 3],
    pub(super) e2: [[f32; LANES]; 3],
}

/// A hit within a pack: distance, lane and barycentric coordinates (b1, b2).
pub type PackHit = (f32, u32, Vec2);

impl TrianglePack {
    /// Stores triangle `[v0, v1, v2]` in `lane`.
    pub fn set(&mut self, lane: usize, [v0, v1, v2]: [Vec3A; 3]) {
        let (e1, e2) = (v1 - v0, v2 - v0);
        for axis in 0..3 {
            self.v0[axis][lane] = v0[axis];
            self.e1[axis][lane] = e1[axis];
            self.e2[axis][lane] = e2[axis];
        }
    }

    /// The closest hit with t ∈ (0, t_max) among the lanes set in `lanes` (ties go to the
    /// lowest lane), or `None`.
    #[inline(always)]
    pub fn closest_portable(&self, origin: Vec3A, direction: Vec3A, lanes: u32, t_max: f32) -> Option<PackHit> {
        let mut best: Option<PackHit> = None;
        let mut bound = t_max;
        for lane in 0..LANES {
            if lanes & (1 << lane) == 0 {
                continue;
            }
            if let Some((t, b)) = self.lane_hit(lane, origin, direction, bound) {
                bound = t;
                best = Some((t, lane as u32, b));
            }
        }
        best
    }

    /// Whether any lane set in `lanes` is hit with t ∈ (0, t_max).
    #[inline(always)]
    pub fn any_portable(&self, origin: Vec3A, direction: Vec3A, lanes: u32, t_max: f32) -> bool {
        (0..LANES).any(|lane| lanes & (1 << lane) != 0 && self.lane_hit(lane, origin, direction, t_max).is_some())
    }

    /// One lane, with exactly the arithmetic of the SIMD kernel (no fused operations).
    #[inline(always)]
    pub(super) fn lane_hit(&self, lane: usize, o: Vec3A, d: Vec3A, t_max: f32) -> Option<(f32, Vec2)> {
        let [v0, e1, e2] = [self.v0, self.e1, self.e2].map(|a| [a[0][lane], a[1][lane], a[2][lane]]);
        let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let cross = |a: [f32; 3], b: [f32; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
        let d = [d.x, d.y, d.z];
        let p = cross(d, e2);
        let inv_det = 1.0 / dot(e1, p);
        let s = [o.x - v0[0], o.y - v0[1], o.z - v0[2]];
        let b1 = dot(s, p) * inv_det;
        let q = cross(s, e1);
        let b2 = dot(d, q) * inv_det;
        let t = dot(e2, q) * inv_det;
        // NaN (determinant 0) fails every comparison, so degenerate triangles never hit.
        (b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0 && t > 0.0 && t < t_max).then(|| (t, Vec2::new(b1, b2)))
    }
}

/// AVX2 kernels of [`TrianglePack`].
#[cfg(target_arch = "x86_64")]
pub mod avx2 {
    use super::{PackHit, TrianglePack};
    use glam::{Vec2, Vec3A};
    use std::arch::x86_64::*;

    /// Per-lane distances, barycentrics and the mask of lanes hit within (0, t_max).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn lanes_hit(pack: &TrianglePack, o: Vec3A, d: Vec3A, lanes: u32, t_max: f32) -> (__m256, __m256, __m256, u32) {
        let load = |a: &[f32; 8]| {
            // SAFETY: reads the 8 floats of `a` (unaligned load).
            unsafe { _mm256_loadu_ps(a.as_ptr()) }
        };
        let [v0x, v0y, v0z] = pack.v0.each_ref().map(load);
        let [e1x, e1y, e1z] = pack.e1.each_ref().map(load);
        let [e2x, e2y, e2z] = pack.e2.each_ref().map(load);
        let (dx, dy, dz) = (_mm256_set1_ps(d.x), _mm256_set1_ps(d.y), _mm256_set1_ps(d.z));
        let (mul, sub, add) = (
            |a, b| _mm256_mul_ps(a, b),
            |a, b| _mm256_sub_ps(a, b),
            |a, b| _mm256_add_ps(a, b),
        );
        let dot = |ax, ay, az, bx, by, bz| add(add(mul(ax, bx), mul(ay, by)), mul(az, bz));
        // p = d × e2
        let px = sub(mul(dy, e2z), mul(dz, e2y));
        let py = sub(mul(dz, e2x), mul(dx, e2z));
        let pz = sub(mul(dx, e2y), mul(dy, e2x));
        let inv_det = _mm256_div_ps(_mm256_set1_ps(1.0), dot(e1x, e1y, e1z, px, py, pz));
        let sx = sub(_mm256_set1_ps(o.x), v0x);
        let sy = sub(_mm256_set1_ps(o.y), v0y);
        let sz = sub(_mm256_set1_ps(o.z), v0z);
        let b1 = mul(dot(sx, sy, sz, px, py, pz), inv_det);
        // q = s × e1
        let qx = sub(mul(sy, e1z), mul(sz, e1y));
        let qy = sub(mul(sz, e1x), mul(sx, e1z));
        let qz = sub(mul(sx, e1y), mul(sy, e1x));
        let b2 = mul(dot(dx, dy, dz, qx, qy, qz), inv_det);
        let t = mul(dot(e2x, e2y, e2z, qx, qy, qz), inv_det);
        let zero = _mm256_setzero_ps();
        let inside = _mm256_and_ps(
            _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(b1, zero), _mm256_cmp_ps::<_CMP_GE_OQ>(b2, zero)),
            _mm256_cmp_ps::<_CMP_LE_OQ>(add(b1, b2), _mm256_set1_ps(1.0)),
        );
        let in_range = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GT_OQ>(t, zero),
            _mm256_cmp_ps::<_CMP_LT_OQ>(t, _mm256_set1_ps(t_max)),
        );
        let mask = _mm256_movemask_ps(_mm256_and_ps(inside, in_range)) as u32 & lanes;
        (t, b1, b2, mask)
    }

    /// As [`TrianglePack::closest_portable`].
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn closest(pack: &TrianglePack, o: Vec3A, d: Vec3A, lanes: u32, t_max: f32) -> Option<PackHit> {
        // SAFETY: the caller guarantees AVX2.
        let (t, b1, b2, mask) = unsafe { lanes_hit(pack, o, d, lanes, t_max) };
        if mask == 0 {
            return None;
        }
        let lane = if mask & (mask - 1) == 0 {
            mask.trailing_zeros()
        } else {
            // Smallest t over the hit lanes: misses become +∞, then a horizontal minimum.
            let keep = _mm256_castsi256_ps(_mm256_cmpgt_epi32(
                _mm256_and_si256(_mm256_set1_epi32(mask as i32), _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128)),
                _mm256_setzero_si256(),
            ));
            let tm = _mm256_blendv_ps(_mm256_set1_ps(f32::INFINITY), t, keep);
            let m = _mm256_min_ps(tm, _mm256_permute2f128_ps::<1>(tm, tm));
            let m = _mm256_min_ps(m, _mm256_permute_ps::<0b01_00_11_10>(m));
            let m = _mm256_min_ps(m, _mm256_permute_ps::<0b10_11_00_01>(m));
            let at_min = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(tm, m)) as u32 & mask;
            at_min.trailing_zeros()
        };
        let mut ts = [0.0f32; 8];
        let mut b1s = [0.0f32; 8];
        let mut b2s = [0.0f32; 8];
        // SAFETY: each store writes 8 floats into an 8-float array.
        unsafe {
            _mm256_storeu_ps(ts.as_mut_ptr(), t);
            _mm256_storeu_ps(b1s.as_mut_ptr(), b1);
            _mm256_storeu_ps(b2s.as_mut_ptr(), b2);
        }
        let l = lane as usize;
        Some((ts[l], lane, Vec2::new(b1s[l], b2s[l])))
    }

    /// As [`TrianglePack::any_portable`].
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn any(pack: &TrianglePack, o: Vec3A, d: Vec3A, lanes: u32, t_max: f32) -> bool {
        // SAFETY: the caller guarantees AVX2.
        unsafe { lanes_hit(pack, o, d, lanes, t_max) }.3 != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::Sampler;

    fn random_pack(s: &mut Sampler) -> TrianglePack {
        let mut pack = TrianglePack::default();
        for lane in 0..LANES {
            let corner = |s: &mut Sampler| Vec3A::new(s.next_1d(), s.next_1d(), s.next_1d()) * 2.0 - Vec3A::ONE;
            pack.set(lane, [corner(s), corner(s), corner(s)]);
        }
        pack
    }

    #[test]
    fn portable_lanes_match_a_direct_moller_trumbore() {
        let mut s = Sampler::new(1, 2, 3);
        let mut hits = 0;
        for _ in 0..500 {
            let pack = random_pack(&mut s);
            let o = Vec3A::new(s.next_1d(), s.next_1d(), 3.0);
            let d = Vec3A::new(s.next_1d() - 0.5, s.next_1d() - 0.5, -1.0).normalize();
            let found = pack.closest_portable(o, d, 0xff, f32::MAX);
            // The closest hit by brute force over the lanes, with glam vector algebra.
            let mut best = f32::INFINITY;
            for lane in 0..LANES {
                let v0 = Vec3A::new(pack.v0[0][lane], pack.v0[1][lane], pack.v0[2][lane]);
                let e1 = Vec3A::new(pack.e1[0][lane], pack.e1[1][lane], pack.e1[2][lane]);
                let e2 = Vec3A::new(pack.e2[0][lane], pack.e2[1][lane], pack.e2[2][lane]);
                let n = e1.cross(e2);
                let t = (v0 - o).dot(n) / d.dot(n);
                let p = o + d * t - v0;
                // Barycentrics by areas.
                let b1 = p.cross(e2).dot(n) / n.length_squared();
                let b2 = e1.cross(p).dot(n) / n.length_squared();
                if t > 0.0 && b1 > 1e-4 && b2 > 1e-4 && b1 + b2 < 1.0 - 1e-4 {
                    best = best.min(t);
                }
            }
            if best.is_finite() {
                hits += 1;
                let (t, _, _) = found.expect("a lane is hit");
                assert!((t - best).abs() < 1e-4 * best.max(1.0), "{t} vs {best}");
            }
        }
        assert!(hits > 50, "the test exercises hits: {hits}");
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_equals_portable_bit_for_bit() {
        if !crate::support::cpu::has_avx2_fma() {
            return;
        }
        let mut s = Sampler::new(4, 5, 6);
        for i in 0..2000 {
            let pack = random_pack(&mut s);
            let o = Vec3A::new(s.next_1d(), s.next_1d(), s.next_1d()) * 4.0 - Vec3A::splat(2.0);
            let d = Vec3A::from(crate::sampling::sample_uniform_sphere(s.next_2d()));
            let lanes = (i * 37 % 255 + 1) as u32;
            let t_max = if i % 3 == 0 { 1.5 } else { f32::MAX };
            let portable = pack.closest_portable(o, d, lanes, t_max);
            // SAFETY: checked above.
            let simd = unsafe { avx2::closest(&pack, o, d, lanes, t_max) };
            assert_eq!(portable.map(|h| (h.0.to_bits(), h.1, h.2.x.to_bits(), h.2.y.to_bits())), simd.map(|h| (h.0.to_bits(), h.1, h.2.x.to_bits(), h.2.y.to_bits())));
            // SAFETY: checked above.
            assert_eq!(pack.any_portable(o, d, lanes, t_max), unsafe { avx2::any(&pack, o, d, lanes, t_max) });
        }
    }
}
