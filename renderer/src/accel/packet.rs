//! Packets of rays traced together through the CWBVH: each child box and each leaf triangle
//! is tested against all rays of the packet in one SIMD step, the way Embree's packet
//! kernels do. In a small scene every ray of a packet visits nearly the same nodes, so a
//! node or triangle costs a fraction of a single-ray test per ray. Where rays diverge,
//! subtrees entered by few of them are walked one ray at a time.
//!
//! Two kernels share one walk, generic over the handful of vector operations it uses
//! ([`Simd`]): packets of 16 rays with AVX-512F ([`Avx512`]) and, on CPUs without AVX-512,
//! packets of 8 rays with AVX2 and FMA ([`Avx2`]).
//!
//! The per-ray arithmetic is that of the single-ray kernels (box distances by the same
//! fused multiply-adds, triangles by the same Möller–Trumbore sequence without fused
//! operations), so a packet of either width finds the same hits, bit for bit.

use super::node::ChildBoxes;
use super::instances::{placed, Accept, InstanceBvh};
use super::{to_bvh_ray, Bvh, Hit, Ray, Stack, LANES};
use glam::{Vec2, Vec3A};
use crate::support::cpu::has_avx512f;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ray::Ray as BvhRay;
use std::arch::x86_64::*;

/// Rays per packet of the widest kernel: per-lane buffers hold this many.
const MAX_WIDTH: usize = 16;

/// Rays per packet of the kernel that [`Bvh::closest_packet`] and [`Bvh::occluded_packet`]
/// run on this CPU: 16 with AVX-512F, else 8.
pub(super) fn width() -> usize {
    if has_avx512f() {
        Avx512::WIDTH
    } else {
        Avx2::WIDTH
    }
}

/// The vector operations of a packet walk at one width, one lane per ray. Implemented by
/// zero-sized tokens made only where the CPU has the instructions (and AVX2 and FMA, which
/// single-ray subtrees take), so the operations are safe to call.
trait Simd: Copy {
    /// Rays per packet (at most [`MAX_WIDTH`]).
    const WIDTH: usize;
    /// Whether a node's children are tested all at once for each ray ([`children_crossed`])
    /// rather than one at a time for all rays ([`child_entry`]).
    const CHILDREN_AT_ONCE: bool;
    /// One float per lane.
    type F: Copy;
    /// One flag per lane, as comparisons give it.
    type M: Copy;

    /// `x` in every lane.
    fn splat(self, x: f32) -> Self::F;
    fn add(self, a: Self::F, b: Self::F) -> Self::F;
    fn sub(self, a: Self::F, b: Self::F) -> Self::F;
    fn mul(self, a: Self::F, b: Self::F) -> Self::F;
    fn div(self, a: Self::F, b: Self::F) -> Self::F;
    /// x86's `min_ps` per lane: `b` where either is NaN.
    fn min(self, a: Self::F, b: Self::F) -> Self::F;
    /// x86's `max_ps` per lane: `b` where either is NaN.
    fn max(self, a: Self::F, b: Self::F) -> Self::F;
    /// a · b + c, rounded once.
    fn fmadd(self, a: Self::F, b: Self::F, c: Self::F) -> Self::F;
    /// The lanes where `a` and `b` satisfy comparison predicate `P` (`_CMP_LT_OQ`, …).
    fn cmp<const P: i32>(self, a: Self::F, b: Self::F) -> Self::M;
    /// The lanes in both `a` and `b`.
    fn and(self, a: Self::M, b: Self::M) -> Self::M;
    /// `b` in the lanes of `m`, `a` in the others, bit for bit.
    fn blend(self, m: Self::M, a: Self::F, b: Self::F) -> Self::F;
    /// The lanes of `m` as bits (lane i: bit i).
    fn bits(self, m: Self::M) -> u32;
    /// The lanes of `bits` (lane i: bit i).
    fn mask(self, bits: u32) -> Self::M;
    /// `v` into the first [`Simd::WIDTH`] floats of `a`.
    fn store(self, v: Self::F, a: &mut [f32; MAX_WIDTH]);
    /// Lane i: the float at `base + index[i]` (in floats).
    ///
    /// # Safety
    /// Every `base + index[i]` for i < [`Simd::WIDTH`] must be a readable float.
    unsafe fn gather(self, base: *const f32, index: &[i32; MAX_WIDTH]) -> Self::F;
}

// The walk below is generic and has no target features of its own: it is inlined, with
// every operation of [`Simd`], into the entry points at the end, which enable the features,
// and only there can the intrinsics themselves be inlined. Hence `#[inline(always)]`
// throughout, and no closures or `array::map` on the vector paths: a closure that is not
// inlined would call each intrinsic as a function.

/// Forwards binary float operations of [`Simd`] to intrinsics.
macro_rules! binary_ops {
    ($($op:ident => $intrinsic:ident),* $(,)?) => {$(
        #[inline(always)]
        fn $op(self, a: Self::F, b: Self::F) -> Self::F {
            // SAFETY: the token exists only where the CPU has the instructions (its `new`).
            unsafe { $intrinsic(a, b) }
        }
    )*};
}

/// 16 rays per packet with AVX-512F.
#[derive(Clone, Copy)]
struct Avx512(());

impl Avx512 {
    /// # Safety
    /// The CPU must support AVX-512F, AVX2 and FMA.
    #[inline(always)]
    unsafe fn new() -> Self {
        Avx512(())
    }
}

impl Simd for Avx512 {
    const WIDTH: usize = 16;
    // Measured where one-child-at-a-time paid with 16 lanes; children at once is measured
    // only on AVX2 machines so far.
    const CHILDREN_AT_ONCE: bool = false;
    type F = __m512;
    type M = __mmask16;

    binary_ops!(add => _mm512_add_ps, sub => _mm512_sub_ps, mul => _mm512_mul_ps, div => _mm512_div_ps, min => _mm512_min_ps, max => _mm512_max_ps);

    #[inline(always)]
    fn splat(self, x: f32) -> __m512 {
        // SAFETY: an `Avx512` exists only where the CPU has AVX-512F.
        unsafe { _mm512_set1_ps(x) }
    }

    #[inline(always)]
    fn fmadd(self, a: __m512, b: __m512, c: __m512) -> __m512 {
        // SAFETY: as in `splat`.
        unsafe { _mm512_fmadd_ps(a, b, c) }
    }

    #[inline(always)]
    fn cmp<const P: i32>(self, a: __m512, b: __m512) -> __mmask16 {
        // SAFETY: as in `splat`.
        unsafe { _mm512_cmp_ps_mask::<P>(a, b) }
    }

    #[inline(always)]
    fn and(self, a: __mmask16, b: __mmask16) -> __mmask16 {
        a & b
    }

    #[inline(always)]
    fn blend(self, m: __mmask16, a: __m512, b: __m512) -> __m512 {
        // SAFETY: as in `splat`.
        unsafe { _mm512_mask_blend_ps(m, a, b) }
    }

    #[inline(always)]
    fn bits(self, m: __mmask16) -> u32 {
        m as u32
    }

    #[inline(always)]
    fn mask(self, bits: u32) -> __mmask16 {
        bits as __mmask16
    }

    #[inline(always)]
    unsafe fn gather(self, base: *const f32, index: &[i32; MAX_WIDTH]) -> __m512 {
        // SAFETY: the caller guarantees the addresses; AVX-512F as in `splat`.
        unsafe { _mm512_i32gather_ps::<4>(_mm512_loadu_si512(index.as_ptr().cast()), base.cast()) }
    }

    #[inline(always)]
    fn store(self, v: __m512, a: &mut [f32; MAX_WIDTH]) {
        // SAFETY: as in `splat`; writes the 16 floats of `a`.
        unsafe { _mm512_storeu_ps(a.as_mut_ptr(), v) }
    }
}

/// 8 rays per packet with AVX2 and FMA. Masks are vectors of all-ones or all-zero lanes.
#[derive(Clone, Copy)]
struct Avx2(());

impl Avx2 {
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[inline(always)]
    unsafe fn new() -> Self {
        Avx2(())
    }
}

impl Simd for Avx2 {
    const WIDTH: usize = 8;
    const CHILDREN_AT_ONCE: bool = true;
    type F = __m256;
    type M = __m256;

    binary_ops!(add => _mm256_add_ps, sub => _mm256_sub_ps, mul => _mm256_mul_ps, div => _mm256_div_ps, min => _mm256_min_ps, max => _mm256_max_ps);

    #[inline(always)]
    fn splat(self, x: f32) -> __m256 {
        // SAFETY: an `Avx2` exists only where the CPU has AVX2 and FMA.
        unsafe { _mm256_set1_ps(x) }
    }

    #[inline(always)]
    fn fmadd(self, a: __m256, b: __m256, c: __m256) -> __m256 {
        // SAFETY: as in `splat`.
        unsafe { _mm256_fmadd_ps(a, b, c) }
    }

    #[inline(always)]
    fn cmp<const P: i32>(self, a: __m256, b: __m256) -> __m256 {
        // SAFETY: as in `splat`.
        unsafe { _mm256_cmp_ps::<P>(a, b) }
    }

    #[inline(always)]
    fn and(self, a: __m256, b: __m256) -> __m256 {
        // SAFETY: as in `splat`.
        unsafe { _mm256_and_ps(a, b) }
    }

    #[inline(always)]
    fn blend(self, m: __m256, a: __m256, b: __m256) -> __m256 {
        // SAFETY: as in `splat`.
        unsafe { _mm256_blendv_ps(a, b, m) }
    }

    #[inline(always)]
    fn bits(self, m: __m256) -> u32 {
        // SAFETY: as in `splat`.
        unsafe { _mm256_movemask_ps(m) as u32 }
    }

    #[inline(always)]
    fn mask(self, bits: u32) -> __m256 {
        // SAFETY: as in `splat`.
        unsafe {
            let lane_bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
            let set = _mm256_and_si256(_mm256_set1_epi32(bits as i32), lane_bits);
            _mm256_castsi256_ps(_mm256_cmpeq_epi32(set, lane_bits))
        }
    }

    #[inline(always)]
    unsafe fn gather(self, base: *const f32, index: &[i32; MAX_WIDTH]) -> __m256 {
        // SAFETY: the caller guarantees the addresses; AVX2 as in `splat`.
        unsafe { _mm256_i32gather_ps::<4>(base, _mm256_loadu_si256(index.as_ptr().cast())) }
    }

    #[inline(always)]
    fn store(self, v: __m256, a: &mut [f32; MAX_WIDTH]) {
        // SAFETY: as in `splat`; writes the first 8 of the 16 floats of `a`.
        unsafe { _mm256_storeu_ps(a.as_mut_ptr(), v) }
    }
}

/// A packet's rays, structure of arrays.
struct Rays<S: Simd> {
    o: [S::F; 3],
    d: [S::F; 3],
    inv: [S::F; 3],
    /// Lanes whose direction component is negative, per axis.
    negative: [S::M; 3],
    /// Each lane's ray alone (origin, reciprocal direction, negative axes as
    /// [`super::node::negative_axes`]), for tests that take one ray at a time.
    lane_origin: [Vec3A; MAX_WIDTH],
    lane_inv: [Vec3A; MAX_WIDTH],
    lane_negative: [u32; MAX_WIDTH],
}

/// Per-lane closest hit so far. Primitive slots are kept as the bits of floats (blends and
/// stores move them unchanged); `u32::MAX` where nothing is hit yet.
struct Closest<S: Simd> {
    t: S::F,
    slot: S::F,
    b1: S::F,
    b2: S::F,
}

/// The rays that lanes `0..S::WIDTH` hold (the first ray repeated into unused lanes, which
/// are masked off) as a packet, and their bounds: [`to_bvh_ray`]'s arithmetic per lane (the
/// direction with −0 turned into +0, its reciprocal with components within ε of zero
/// replaced by ±1/ε), so that the packet's rays are the single-ray walk's bit for bit.
#[inline(always)]
fn load<S: Simd>(s: S, rays: &[Ray]) -> (Rays<S>, S::F) {
    // Each of the seven floats of the lanes' rays in one gather (`Ray` is `repr(C)`, seven
    // floats): scalar stores read back as vectors would wait for every store to retire.
    const FLOATS: usize = std::mem::size_of::<Ray>() / 4;
    const _: () = assert!(FLOATS == 7 && std::mem::align_of::<Ray>() == 4);
    let mut index = [0i32; MAX_WIDTH];
    for (lane, index) in index.iter_mut().enumerate().take(S::WIDTH) {
        *index = (if lane < rays.len() { lane } else { 0 } * FLOATS) as i32;
    }
    let zero = s.splat(0.0);
    let mut v = [zero; 7];
    let base = rays.as_ptr().cast::<f32>();
    for (k, v) in v.iter_mut().enumerate() {
        // SAFETY: every index points at float k of one of `rays` (the first for lanes past
        // them), a readable `f32` of a `repr(C)` struct of seven.
        *v = unsafe { s.gather(base.add(k), &index) };
    }
    let (tiny, huge) = (s.splat(f32::EPSILON), s.splat(1.0 / f32::EPSILON));
    let mut d = [zero; 3];
    let mut inv = [zero; 3];
    let mut negative = [s.cmp::<_CMP_LT_OQ>(zero, zero); 3];
    for axis in 0..3 {
        d[axis] = s.add(v[3 + axis], zero);
        negative[axis] = s.cmp::<_CMP_LT_OQ>(d[axis], zero);
        let near_zero = s.and(s.cmp::<_CMP_LE_OQ>(d[axis], tiny), s.cmp::<_CMP_GE_OQ>(d[axis], s.sub(zero, tiny)));
        let signed_huge = s.blend(negative[axis], huge, s.sub(zero, huge));
        inv[axis] = s.blend(near_zero, s.div(s.splat(1.0), d[axis]), signed_huge);
    }
    let mut inv_lanes = [[0.0f32; MAX_WIDTH]; 3];
    for axis in 0..3 {
        s.store(inv[axis], &mut inv_lanes[axis]);
    }
    let negative_bits = negative.map(|m| s.bits(m));
    let mut packet = Rays {
        o: [v[0], v[1], v[2]],
        d,
        inv,
        negative,
        lane_origin: [Vec3A::ZERO; MAX_WIDTH],
        lane_inv: [Vec3A::ZERO; MAX_WIDTH],
        lane_negative: [0; MAX_WIDTH],
    };
    for lane in (0..S::WIDTH).filter(|_| S::CHILDREN_AT_ONCE) {
        packet.lane_origin[lane] = Vec3A::from(lane_ray(rays, lane).origin);
        packet.lane_inv[lane] = Vec3A::new(inv_lanes[0][lane], inv_lanes[1][lane], inv_lanes[2][lane]);
        packet.lane_negative[lane] = (0..3).map(|axis| ((negative_bits[axis] >> lane) & 1) << axis).sum();
    }
    (packet, v[6])
}

/// The ray lane `lane` of a packet of `rays` holds: its own, or the first ray in lanes beyond
/// the packet's rays.
#[inline(always)]
fn lane_ray(rays: &[Ray], lane: usize) -> &Ray {
    &rays[if lane < rays.len() { lane } else { 0 }]
}

/// The ray of `lane` as single-ray traversal takes it.
#[inline(always)]
fn single(rays: &[Ray], lane: usize) -> BvhRay {
    to_bvh_ray(lane_ray(rays, lane))
}

/// A node's quantised child faces as floats, decoded once per node visit (eight bytes to
/// eight floats per face in one vector conversion): a child's test then broadcasts its face
/// from memory rather than converting a byte per face and child. The conversion is exact, so
/// the distances are those of a byte-by-byte decoding.
struct ChildFaces {
    /// Per axis (x, y, z), each child's low and high face.
    lo: [[f32; 8]; 3],
    hi: [[f32; 8]; 3],
}

impl ChildFaces {
    #[inline(always)]
    fn new(node: &CwBvhNode) -> Self {
        let f = |b: [u8; 8]| b.map(f32::from);
        ChildFaces {
            lo: [f(node.child_min_x), f(node.child_min_y), f(node.child_min_z)],
            hi: [f(node.child_max_x), f(node.child_max_y), f(node.child_max_z)],
        }
    }
}

/// The distances at which the lanes' rays enter child `c` of the node whose faces are
/// `faces`, and the lanes whose ray crosses the child within (T_MIN, t_max) (bit i: lane i):
/// the arithmetic of [`super::node::intersect_avx2`] per lane. For a lower bound t'_max ≤
/// t_max, the lanes crossing within (T_MIN, t'_max) are those whose entry is also ≤ t'_max
/// (the distances are finite, so the `min` of the far faces and the bound is exact).
#[inline(always)]
fn child_entry<S: Simd>(s: S, faces: &ChildFaces, c: usize, rays: &Rays<S>, adj_dir_inv: &[S::F; 3], adj_orig: &[S::F; 3], t_max: S::F) -> (S::F, u32) {
    const T_MIN: f32 = 1e-4;
    let (near_x, far_x) = slab(s, faces.lo[0][c], faces.hi[0][c], rays.negative[0], adj_dir_inv[0], adj_orig[0]);
    let (near_y, far_y) = slab(s, faces.lo[1][c], faces.hi[1][c], rays.negative[1], adj_dir_inv[1], adj_orig[1]);
    let (near_z, far_z) = slab(s, faces.lo[2][c], faces.hi[2][c], rays.negative[2], adj_dir_inv[2], adj_orig[2]);
    let t0 = s.max(s.max(near_x, near_y), s.max(near_z, s.splat(T_MIN)));
    let t1 = s.min(s.min(far_x, far_y), s.min(far_z, t_max));
    (t0, s.bits(s.cmp::<_CMP_LE_OQ>(t0, t1)))
}

/// Per child c of `node`, the lanes of `lanes` whose ray crosses its box within (T_MIN,
/// t_max) (byte c, bit i: lane i; up to 8 lanes): each ray tests the eight children at once
/// with the arithmetic of [`super::node::intersect_avx2`], the boxes decoded once. Cheaper
/// than [`child_entry`] where a node is entered by few of the packet's rays, which is the rule
/// for rays scattered from a surface, and no dearer with all eight. All children see the
/// bounds at the node's entry, as in the single-ray walk (a leaf child's hits lower them
/// for the triangles tested after it, not for the boxes): a box admitted on a looser bound
/// only costs its visit, since its triangles are tested against the bounds of their time.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[inline(always)]
unsafe fn children_crossed<S: Simd>(s: S, node: &CwBvhNode, rays: &Rays<S>, lanes: u32, t_max: S::F) -> u64 {
    debug_assert!(lanes < 1 << 8);
    let mut bounds = [0.0f32; MAX_WIDTH];
    s.store(t_max, &mut bounds);
    let (extent, p) = (node.compute_extent(), Vec3A::from(node.p));
    // SAFETY: the caller guarantees AVX2 and FMA.
    let boxes = unsafe { ChildBoxes::new(node) };
    let mut by_lane = 0u64;
    let mut rest = lanes;
    while rest != 0 {
        let lane = rest.trailing_zeros() as usize;
        rest &= rest - 1;
        let slabs = boxes.slabs(rays.lane_negative[lane]);
        // SAFETY: as above.
        let crossed = unsafe { _mm256_movemask_ps(slabs.crossed(extent, p, rays.lane_origin[lane], rays.lane_inv[lane], bounds[lane])) };
        by_lane |= (crossed as u64) << (8 * lane);
    }
    transpose_bits8(by_lane)
}

/// The 8 × 8 bit matrix `m` (bit 8r + c: row r, column c) transposed (bit 8c + r), by
/// three exchanges of its off-diagonal blocks (Hacker's Delight, 7–3).
#[inline(always)]
fn transpose_bits8(mut m: u64) -> u64 {
    let mut t = (m ^ (m >> 7)) & 0x00AA_00AA_00AA_00AA;
    m ^= t ^ (t << 7);
    t = (m ^ (m >> 14)) & 0x0000_CCCC_0000_CCCC;
    m ^= t ^ (t << 14);
    t = (m ^ (m >> 28)) & 0x0000_0000_F0F0_F0F0;
    m ^ t ^ (t << 28)
}

/// The (near, far) distances of a child's quantised slab `lo`..`hi` along one axis, per
/// lane.
#[inline(always)]
fn slab<S: Simd>(s: S, lo: f32, hi: f32, negative: S::M, adj_dir_inv: S::F, adj_orig: S::F) -> (S::F, S::F) {
    let t_lo = s.fmadd(s.splat(lo), adj_dir_inv, adj_orig);
    let t_hi = s.fmadd(s.splat(hi), adj_dir_inv, adj_orig);
    (s.blend(negative, t_lo, t_hi), s.blend(negative, t_hi, t_lo))
}

/// a · b per lane, summed left to right without fused operations.
#[inline(always)]
fn dot<S: Simd>(s: S, a: [S::F; 3], b: [S::F; 3]) -> S::F {
    s.add(s.add(s.mul(a[0], b[0]), s.mul(a[1], b[1])), s.mul(a[2], b[2]))
}

/// a × b per lane, without fused operations.
#[inline(always)]
fn cross<S: Simd>(s: S, a: [S::F; 3], b: [S::F; 3]) -> [S::F; 3] {
    [
        s.sub(s.mul(a[1], b[2]), s.mul(a[2], b[1])),
        s.sub(s.mul(a[2], b[0]), s.mul(a[0], b[2])),
        s.sub(s.mul(a[0], b[1]), s.mul(a[1], b[0])),
    ]
}

/// Lane `lane` of a pack's per-axis arrays, in every lane.
#[inline(always)]
fn splat3<S: Simd>(s: S, a: &[[f32; LANES]; 3], lane: usize) -> [S::F; 3] {
    [s.splat(a[0][lane]), s.splat(a[1][lane]), s.splat(a[2][lane])]
}

/// Möller–Trumbore of one leaf triangle against every lane, as [`super::triangle_pack`] computes
/// it: (t, b1, b2, the lanes of `active` hit with t ∈ (0, t_max)).
#[inline(always)]
fn triangle_hits<S: Simd>(s: S, bvh: &Bvh, triangle: LeafTriangle, rays: &Rays<S>, t_max: S::F, active: u32) -> (S::F, S::F, S::F, u32) {
    let (p, lane) = (&bvh.packs[triangle.pack], triangle.lane);
    let (v0, e1, e2) = (splat3(s, &p.v0, lane), splat3(s, &p.e1, lane), splat3(s, &p.e2, lane));
    let d = rays.d;
    let pv = cross(s, d, e2);
    let inv_det = s.div(s.splat(1.0), dot(s, e1, pv));
    let o_v0 = [s.sub(rays.o[0], v0[0]), s.sub(rays.o[1], v0[1]), s.sub(rays.o[2], v0[2])];
    let b1 = s.mul(dot(s, o_v0, pv), inv_det);
    let q = cross(s, o_v0, e1);
    let b2 = s.mul(dot(s, d, q), inv_det);
    let t = s.mul(dot(s, e2, q), inv_det);
    let zero = s.splat(0.0);
    let inside = s.and(
        s.and(s.cmp::<_CMP_GE_OQ>(b1, zero), s.cmp::<_CMP_GE_OQ>(b2, zero)),
        s.cmp::<_CMP_LE_OQ>(s.add(b1, b2), s.splat(1.0)),
    );
    let in_range = s.and(s.cmp::<_CMP_GT_OQ>(t, zero), s.cmp::<_CMP_LT_OQ>(t, t_max));
    (t, b1, b2, s.bits(s.and(inside, in_range)) & active)
}

/// Subtrees entered by fewer rays of a packet than this are traced one ray at a time
/// (Embree's hybrid traversal): a packet-wide test that serves a single ray costs more than
/// its single-ray walk. 2 measured best of 1, 2 and 4 on the shipped scenes with 16 rays
/// (AVX-512). With 8 rays (AVX2), 3 was no faster than 2, and 1 (packets only) faster on
/// rays from inside the scenes but about 40% slower on rays scattered from surfaces.
const SINGLE_BELOW: u32 = 2;

/// Which hits stop a packet's rays (surfaces rays pass through: alpha cut-outs).
pub(super) trait HitFilter {
    /// Whether every hit stops its ray, so that no hit is asked about.
    const EVERY_HIT: bool = false;

    /// Whether the hit of the packet's ray `ray` (its index in the packet's rays) on obvhs
    /// primitive slot `slot` at distance `t` with barycentrics `barycentric` stops it: a pure
    /// function of these.
    fn accept(&self, ray: usize, slot: u32, t: f32, barycentric: Vec2) -> bool;
}

/// Every hit stops its ray.
pub(super) struct EveryHit;

impl HitFilter for EveryHit {
    const EVERY_HIT: bool = true;

    #[inline(always)]
    fn accept(&self, _ray: usize, _slot: u32, _t: f32, _barycentric: Vec2) -> bool {
        true
    }
}

/// The hits `.0(ray, slot, t, barycentric)` accepts stop their rays.
pub(super) struct Accepted<F>(pub F);

impl<F: Fn(usize, u32, f32, Vec2) -> bool> HitFilter for Accepted<F> {
    #[inline(always)]
    fn accept(&self, ray: usize, slot: u32, t: f32, barycentric: Vec2) -> bool {
        (self.0)(ray, slot, t, barycentric)
    }
}

/// The lanes of `hits` whose hit (`t`, `b1`, `b2` per lane, on slot `slot`) `filter` accepts.
#[inline(always)]
fn accepted<S: Simd, H: HitFilter>(s: S, filter: &H, hits: u32, slot: u32, t: S::F, b1: S::F, b2: S::F) -> u32 {
    if H::EVERY_HIT || hits == 0 {
        return hits;
    }
    let [mut ts, mut b1s, mut b2s] = [[0.0f32; MAX_WIDTH]; 3];
    s.store(t, &mut ts);
    s.store(b1, &mut b1s);
    s.store(b2, &mut b2s);
    let (mut kept, mut rest) = (hits, hits);
    while rest != 0 {
        let lane = rest.trailing_zeros() as usize;
        rest &= rest - 1;
        if !filter.accept(lane, slot, ts[lane], Vec2::new(b1s[lane], b2s[lane])) {
            kept &= !(1 << lane);
        }
    }
    kept
}

/// A leaf triangle: lane `lane` of pack `pack`, obvhs primitive slot `slot`.
#[derive(Clone, Copy)]
struct LeafTriangle {
    pack: usize,
    lane: usize,
    slot: u32,
}

impl LeafTriangle {
    #[inline(always)]
    fn of_slot(slot: u32) -> Self {
        let (pack, lane) = super::pack_and_lane(slot);
        LeafTriangle { pack, lane, slot }
    }
}

/// What a packet walk looks for (closest hits or occlusion) in what (triangles or
/// instances).
trait PacketQuery<S: Simd> {
    /// Tests the leaf primitive in obvhs slot `slot` for the rays in `lanes`, may lower their
    /// bounds `t_max`, and returns which of `lanes` still need tracing.
    fn leaf(&mut self, s: S, rays: &Rays<S>, slot: u32, lanes: u32, t_max: &mut S::F) -> u32;

    /// Walks the subtree of `node` for ray `lane` alone; returns whether that ray is done.
    fn single(&mut self, s: S, node: u32, lane: usize, t_max: &mut S::F) -> bool;
}

/// Per lane and axis, the node's quantisation step over the ray direction and its origin
/// relative to the ray's over the ray direction, as [`super::node::intersect_avx2`] has
/// them: box distances are then single fused multiply-adds.
#[inline(always)]
fn node_frame<S: Simd>(s: S, node: &CwBvhNode, rays: &Rays<S>) -> ([S::F; 3], [S::F; 3]) {
    let (e, p, o, inv) = (node.compute_extent(), node.p, &rays.o, &rays.inv);
    (
        [s.mul(s.splat(e.x), inv[0]), s.mul(s.splat(e.y), inv[1]), s.mul(s.splat(e.z), inv[2])],
        [
            s.mul(s.sub(s.splat(p[0]), o[0]), inv[0]),
            s.mul(s.sub(s.splat(p[1]), o[1]), inv[1]),
            s.mul(s.sub(s.splat(p[2]), o[2]), inv[2]),
        ],
    )
}

/// The traversal octant of a packet's rays in [`super::node::octant_inv4`]'s encoding (bit 2:
/// x ≥ 0, bit 1: y ≥ 0, bit 0: z ≥ 0) by the sign most of the lanes in `active` have per
/// axis: obvhs places a node's children so that, for rays of that octant, child `p ^ octant`
/// lies before child `q ^ octant` where p > q (the single-ray walk's order).
#[inline(always)]
fn majority_octant<S: Simd>(s: S, rays: &Rays<S>, active: u32) -> usize {
    let rays_in = active.count_ones();
    (0..3).fold(0, |octant, axis| {
        let negative = (s.bits(rays.negative[axis]) & active).count_ones();
        octant | (usize::from(2 * negative < rays_in) << (2 - axis))
    })
}

/// Walks the CWBVH `nodes` for the lanes in `active` (bit i: lane i), whose bounds are
/// `t_max`; `query` tests the leaves' primitives (triangles, or instances). A node's crossed
/// inner children are pushed so that they are popped nearest first for the
/// packet's majority octant, as the single-ray walk orders them for its ray's; its leaves are
/// tested in slot order (their triangles are tested for all the lanes crossing them in any
/// order).
#[inline(always)]
fn walk<S: Simd>(s: S, nodes: &[CwBvhNode], rays: &Rays<S>, mut active: u32, t_max: &mut S::F, query: &mut impl PacketQuery<S>) {
    let octant = majority_octant(s, rays, active);
    let mut stack = Stack::new();
    stack.push((0u32, active));
    while let Some((index, mask)) = stack.pop() {
        let lanes = mask & active;
        if lanes == 0 {
            continue;
        }
        if lanes.count_ones() < SINGLE_BELOW {
            let mut rest = lanes;
            while rest != 0 {
                let lane = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                if query.single(s, index, lane, t_max) {
                    active &= !(1 << lane);
                }
            }
            if active == 0 {
                return;
            }
            continue;
        }
        let node = &nodes[index as usize];
        // The per-lane node frame of `child_entry` (unused, and compiled out, where children
        // are tested at once).
        let (adj_dir_inv, adj_orig) = node_frame(s, node, rays);
        // SAFETY: the token `s` exists only where AVX2 and FMA exist (see `Simd`).
        let crossed = if S::CHILDREN_AT_ONCE { unsafe { children_crossed(s, node, rays, lanes, *t_max) } } else { 0 };
        let faces = if S::CHILDREN_AT_ONCE { None } else { Some(ChildFaces::new(node)) };
        // The inner children crossed, by their priority for the packet's octant (the
        // highest nearest): (node index, lanes) at `priority`, bit `priority` of `crossed_inner`.
        let mut inner = [(0u32, 0u32); 8];
        let mut crossed_inner = 0u32;
        // Every child's box first, at the bounds of the node's entry, in a loop of its own
        // (the leaves' triangle tests would otherwise crowd the boxes' registers out); a
        // leaf's hits then cull its later siblings by their entry distances, as a test at
        // the lowered bounds would.
        let entry_t_max = *t_max;
        let mut entry = [entry_t_max; 8];
        let mut crossing = [0u32; 8];
        for c in 0..8 {
            if node.child_meta[c] != 0 {
                crossing[c] = if S::CHILDREN_AT_ONCE {
                    (crossed >> (8 * c)) as u32 & 0xff
                } else {
                    // `faces` is decoded wherever children are tested one at a time.
                    faces.as_ref().map_or(0, |faces| {
                        let (t0, hits) = child_entry(s, faces, c, rays, &adj_dir_inv, &adj_orig, entry_t_max);
                        entry[c] = t0;
                        hits
                    })
                } & lanes;
            }
        }
        let mut lowered = false;
        for c in 0..8 {
            let meta = node.child_meta[c];
            let mut hits = crossing[c] & active;
            if !S::CHILDREN_AT_ONCE && lowered && hits != 0 {
                hits &= s.bits(s.cmp::<_CMP_LE_OQ>(entry[c], *t_max));
            }
            if hits == 0 {
                continue;
            }
            if node.is_leaf(c) {
                let first = (meta & 0b1_1111) as usize;
                for local in first..first + (meta & 0b1110_0000).count_ones() as usize {
                    let slot = node.primitive_base_idx + local as u32;
                    active = query.leaf(s, rays, slot, hits & active, t_max) | (active & !hits);
                }
                lowered = true;
            } else {
                let priority = c ^ octant;
                inner[priority] = (node.child_node_index(c), hits);
                crossed_inner |= 1 << priority;
            }
        }
        if active == 0 {
            return;
        }
        // Lowest priority first, so that the nearest is popped next.
        while crossed_inner != 0 {
            stack.push(inner[crossed_inner.trailing_zeros() as usize]);
            crossed_inner &= crossed_inner - 1;
        }
    }
}

/// Closest accepted hits in a triangle BVH: the per-lane best so far, the packet's rays (for
/// single-ray subtrees) and the filter.
struct ClosestQuery<'r, S: Simd, H> {
    bvh: &'r Bvh,
    best: Closest<S>,
    rays: &'r [Ray],
    filter: &'r H,
}

impl<S: Simd, H: HitFilter> PacketQuery<S> for ClosestQuery<'_, S, H> {
    #[inline(always)]
    fn leaf(&mut self, s: S, rays: &Rays<S>, slot: u32, lanes: u32, t_max: &mut S::F) -> u32 {
        let triangle = LeafTriangle::of_slot(slot);
        let (t, b1, b2, hit) = triangle_hits(s, self.bvh, triangle, rays, *t_max, lanes);
        let hit = accepted(s, self.filter, hit, triangle.slot, t, b1, b2);
        if hit != 0 {
            self.best.take(s, hit, t, b1, b2, triangle.slot);
            *t_max = self.best.t;
        }
        lanes
    }

    #[inline(always)]
    fn single(&mut self, s: S, node: u32, lane: usize, t_max: &mut S::F) -> bool {
        let bvh = self.bvh;
        let mut bounds = [0.0f32; MAX_WIDTH];
        s.store(*t_max, &mut bounds);
        let ray = BvhRay { tmax: bounds[lane], ..single(self.rays, lane) };
        // SAFETY (both): the token `s` exists only where AVX2 and FMA exist (see `Simd`).
        let found = if H::EVERY_HIT {
            unsafe { bvh.closest_below_avx2(node, &ray) }
        } else {
            unsafe { bvh.closest_filtered_below_avx2(node, &ray, &|slot, t, b| self.filter.accept(lane, slot, t, b)) }
        };
        if let Some((t, slot, b)) = found {
            self.best.take(s, 1 << lane, s.splat(t), s.splat(b.x), s.splat(b.y), slot);
            *t_max = self.best.t;
        }
        false
    }
}

impl<S: Simd> Closest<S> {
    /// Takes the hits of `lanes` (bit i: lane i).
    #[inline(always)]
    fn take(&mut self, s: S, lanes: u32, t: S::F, b1: S::F, b2: S::F, slot: u32) {
        let m = s.mask(lanes);
        self.t = s.blend(m, self.t, t);
        self.b1 = s.blend(m, self.b1, b1);
        self.b2 = s.blend(m, self.b2, b2);
        self.slot = s.blend(m, self.slot, s.splat(f32::from_bits(slot)));
    }
}

/// Occlusion in a triangle BVH: the lanes found blocked, the packet's rays (for single-ray
/// subtrees) and the filter.
struct OcclusionQuery<'r, H> {
    bvh: &'r Bvh,
    blocked: u32,
    rays: &'r [Ray],
    filter: &'r H,
}

impl<S: Simd, H: HitFilter> PacketQuery<S> for OcclusionQuery<'_, H> {
    #[inline(always)]
    fn leaf(&mut self, s: S, rays: &Rays<S>, slot: u32, lanes: u32, t_max: &mut S::F) -> u32 {
        let triangle = LeafTriangle::of_slot(slot);
        let (t, b1, b2, hit) = triangle_hits(s, self.bvh, triangle, rays, *t_max, lanes);
        let hit = accepted(s, self.filter, hit, triangle.slot, t, b1, b2);
        self.blocked |= hit;
        lanes & !hit
    }

    #[inline(always)]
    fn single(&mut self, _s: S, node: u32, lane: usize, _t_max: &mut S::F) -> bool {
        let (bvh, ray) = (self.bvh, single(self.rays, lane));
        // SAFETY (both): the token `_s` exists only where AVX2 and FMA exist (see `Simd`).
        let hit = if H::EVERY_HIT {
            unsafe { bvh.any_below_avx2(node, &ray) }
        } else {
            unsafe { bvh.any_filtered_below_avx2(node, &ray, &|slot, t, b| self.filter.accept(lane, slot, t, b)) }
        };
        self.blocked |= (hit as u32) << lane;
        hit
    }
}

/// The lanes of a packet of `n` rays (1 to `S::WIDTH`).
#[inline(always)]
fn lanes<S: Simd>(n: usize) -> u32 {
    assert!((1..=S::WIDTH).contains(&n), "{n} rays in a packet of {}", S::WIDTH);
    u32::MAX >> (32 - n)
}

/// [`Bvh::closest_packet`] with the kernel of token `s`.
#[inline(always)]
fn closest<S: Simd, H: HitFilter>(s: S, bvh: &Bvh, rays: &[Ray], out: &mut [Option<Hit>], filter: &H) {
    let active = lanes::<S>(rays.len());
    let (r, mut t_max) = load(s, rays);
    let mut query = ClosestQuery {
        best: Closest {
            t: t_max,
            slot: s.splat(f32::from_bits(u32::MAX)),
            b1: s.splat(0.0),
            b2: s.splat(0.0),
        },
        rays,
        filter,
        bvh,
    };
    walk(s, &bvh.bvh.nodes, &r, active, &mut t_max, &mut query);
    let best = query.best;
    let [mut t, mut b1, mut b2, mut slot] = [[0.0f32; MAX_WIDTH]; 4];
    s.store(best.t, &mut t);
    s.store(best.b1, &mut b1);
    s.store(best.b2, &mut b2);
    s.store(best.slot, &mut slot);
    for (i, o) in out.iter_mut().enumerate().take(rays.len()) {
        let slot = slot[i].to_bits();
        *o = (slot != u32::MAX).then(|| Hit {
            t: t[i],
            triangle: bvh.scene_triangle(slot),
            barycentric: glam::Vec2::new(b1[i], b2[i]),
            instance: super::NO_INSTANCE,
        });
    }
}

/// [`Bvh::occluded_packet`] with the kernel of token `s`.
#[inline(always)]
fn occluded<S: Simd, H: HitFilter>(s: S, bvh: &Bvh, rays: &[Ray], out: &mut [bool], filter: &H) {
    let active = lanes::<S>(rays.len());
    let (r, mut t_max) = load(s, rays);
    let mut query = OcclusionQuery { bvh, blocked: 0, rays, filter };
    walk(s, &bvh.bvh.nodes, &r, active, &mut t_max, &mut query);
    for (i, o) in out.iter_mut().enumerate().take(rays.len()) {
        *o = query.blocked & (1 << i) != 0;
    }
}

impl Bvh {
    /// Closest hits that `filter` accepts of up to [`width`] rays traced as one packet, with
    /// the 16-ray kernel where the CPU has AVX-512F, else the 8-ray one; `out[i]` as
    /// [`Bvh::intersect`] of `rays[i]` (with [`EveryHit`]) or [`Bvh::intersect_filtered`].
    ///
    /// `rays` must hold 1 to [`width`] rays (else this panics), `out` as many entries.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    pub(super) unsafe fn closest_packet<H: HitFilter>(&self, rays: &[Ray], out: &mut [Option<Hit>], filter: &H) {
        // SAFETY: the caller guarantees AVX2 and FMA; AVX-512F is checked.
        unsafe {
            if has_avx512f() {
                self.closest_packet16(rays, out, filter)
            } else {
                self.closest_packet8(rays, out, filter)
            }
        }
    }

    /// Occlusion by hits that `filter` accepts of up to [`width`] rays traced as one packet,
    /// as [`Bvh::closest_packet`] chooses the kernel; `out[i]` as [`Bvh::occluded`] of
    /// `rays[i]` (with [`EveryHit`]) or [`Bvh::occluded_filtered`].
    ///
    /// `rays` must hold 1 to [`width`] rays (else this panics), `out` as many entries.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    pub(super) unsafe fn occluded_packet<H: HitFilter>(&self, rays: &[Ray], out: &mut [bool], filter: &H) {
        // SAFETY: the caller guarantees AVX2 and FMA; AVX-512F is checked.
        unsafe {
            if has_avx512f() {
                self.occluded_packet16(rays, out, filter)
            } else {
                self.occluded_packet8(rays, out, filter)
            }
        }
    }

    /// [`Bvh::closest_packet`] of 1 to 16 rays with AVX-512F.
    ///
    /// # Safety
    /// The CPU must support AVX-512F, AVX2 and FMA.
    #[target_feature(enable = "avx512f,avx2,fma")]
    pub(super) unsafe fn closest_packet16<H: HitFilter>(&self, rays: &[Ray], out: &mut [Option<Hit>], filter: &H) {
        // SAFETY: this function runs only where AVX-512F, AVX2 and FMA exist.
        closest(unsafe { Avx512::new() }, self, rays, out, filter)
    }

    /// [`Bvh::occluded_packet`] of 1 to 16 rays with AVX-512F.
    ///
    /// # Safety
    /// The CPU must support AVX-512F, AVX2 and FMA.
    #[target_feature(enable = "avx512f,avx2,fma")]
    pub(super) unsafe fn occluded_packet16<H: HitFilter>(&self, rays: &[Ray], out: &mut [bool], filter: &H) {
        // SAFETY: this function runs only where AVX-512F, AVX2 and FMA exist.
        occluded(unsafe { Avx512::new() }, self, rays, out, filter)
    }

    /// [`Bvh::closest_packet`] of 1 to 8 rays with AVX2 and FMA.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn closest_packet8<H: HitFilter>(&self, rays: &[Ray], out: &mut [Option<Hit>], filter: &H) {
        // SAFETY: this function runs only where AVX2 and FMA exist.
        closest(unsafe { Avx2::new() }, self, rays, out, filter)
    }

    /// [`Bvh::occluded_packet`] of 1 to 8 rays with AVX2 and FMA.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn occluded_packet8<H: HitFilter>(&self, rays: &[Ray], out: &mut [bool], filter: &H) {
        // SAFETY: this function runs only where AVX2 and FMA exist.
        occluded(unsafe { Avx2::new() }, self, rays, out, filter)
    }
}

/// The rays lanes `0..rays.len()` hold, each bounded by its best hit so far: the rays a
/// single-ray [`InstanceBvh::intersect`] starts from.
#[inline(always)]
fn bounded(rays: &[Ray], best: &[Option<Hit>]) -> [Ray; MAX_WIDTH] {
    let mut out = [rays[0]; MAX_WIDTH];
    for ((o, r), b) in out.iter_mut().zip(rays).zip(best) {
        *o = Ray { t_max: b.map_or(r.t_max, |h| h.t), ..*r };
    }
    out
}

/// Up to [`MAX_WIDTH`] world rays moved into one instance's space: the object rays and the
/// lane each came from.
struct ObjectRays {
    rays: [Ray; MAX_WIDTH],
    lane: [usize; MAX_WIDTH],
    len: usize,
}

impl ObjectRays {
    /// `world` rays of `lanes` in `instance`'s space, lane i bounded by `bounds[i]`.
    #[inline(always)]
    fn new(instances: &InstanceBvh, instance: u32, world: &[Ray], lanes: u32, bounds: &[f32; MAX_WIDTH]) -> Self {
        let mut out = ObjectRays { rays: [world[0]; MAX_WIDTH], lane: [0; MAX_WIDTH], len: 0 };
        let mut rest = lanes;
        while rest != 0 {
            let lane = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            out.rays[out.len] = instances.object_ray(instance, &world[lane], bounds[lane]);
            out.lane[out.len] = lane;
            out.len += 1;
        }
        out
    }

    /// The packet kernel's hit filter for these rays in `instance`'s `mesh` (whose triangles
    /// start at `first` in the scene): `accept` asked with each lane's `world` ray and the
    /// hit as the scene sees it.
    #[inline(always)]
    fn accepted<'a>(&'a self, accept: &'a dyn Fn(&Ray, &Hit) -> bool, world: &'a [Ray], mesh: &'a Bvh, first: u32, instance: u32) -> Accepted<impl Fn(usize, u32, f32, Vec2) -> bool + 'a> {
        Accepted(move |i: usize, slot, t, b| accept(&world[self.lane[i]], &placed(Hit { t, triangle: mesh.scene_triangle(slot), barycentric: b, instance }, first, instance)))
    }
}

/// Closest hits through instances: each leaf of the top level is an instance, whose mesh
/// is traced by the packet kernel for the lanes reaching it (their rays moved into its
/// space, bounded by their best hits so far); `best` per lane, the world rays (`rays`, for
/// the filter), the same bounded by the hits found elsewhere (`bounded`).
struct InstanceClosestQuery<'r> {
    instances: &'r InstanceBvh,
    rays: &'r [Ray],
    bounded: &'r [Ray],
    best: &'r mut [Option<Hit>],
    accept: Accept<'r>,
}

impl<S: Simd> PacketQuery<S> for InstanceClosestQuery<'_> {
    #[inline(always)]
    fn leaf(&mut self, s: S, _rays: &Rays<S>, slot: u32, lanes: u32, t_max: &mut S::F) -> u32 {
        if lanes == 0 {
            // No lane reaches this instance.
            return 0;
        }
        let instance = self.instances.bvh.primitive_indices[slot as usize];
        let mut bounds = [0.0f32; MAX_WIDTH];
        s.store(*t_max, &mut bounds);
        let object = ObjectRays::new(self.instances, instance, self.bounded, lanes, &bounds);
        let mut found = [None; MAX_WIDTH];
        if object.len == 1 {
            found[0] = self.instances.mesh_closest(instance, &self.rays[object.lane[0]], &object.rays[0], self.accept);
        } else {
            let (mesh, first) = self.instances.mesh(instance);
            let (rays, out) = (&object.rays[..object.len], &mut found[..object.len]);
            // SAFETY (both): the token `s` exists only where AVX2 and FMA exist.
            match self.accept {
                None => unsafe { mesh.closest_packet(rays, out, &EveryHit) },
                Some(accept) => unsafe { mesh.closest_packet(rays, out, &object.accepted(accept, self.rays, mesh, first, instance)) },
            }
            for hit in out.iter_mut().flatten() {
                *hit = placed(*hit, first, instance);
            }
        }
        for (k, hit) in found[..object.len].iter().enumerate() {
            if let Some(hit) = *hit {
                let lane = object.lane[k];
                self.best[lane] = Some(hit);
                *t_max = s.blend(s.mask(1 << lane), *t_max, s.splat(hit.t));
            }
        }
        lanes
    }

    #[inline(always)]
    fn single(&mut self, s: S, node: u32, lane: usize, t_max: &mut S::F) -> bool {
        // The lane's bound is its best hit's distance, or its ray's own: as the walk has it.
        let best = self.instances.closest_below(node, &self.rays[lane], self.best[lane], self.accept);
        if let Some(hit) = best {
            self.best[lane] = Some(hit);
            *t_max = s.blend(s.mask(1 << lane), *t_max, s.splat(hit.t));
        }
        false
    }
}

/// Occlusion through instances: each instance reached is traced by the packet kernel for
/// the lanes not yet blocked; `blocked` per lane.
struct InstanceOcclusionQuery<'r> {
    instances: &'r InstanceBvh,
    rays: &'r [Ray],
    /// The rays' `t_max` (occlusion never lowers them).
    bounds: [f32; MAX_WIDTH],
    blocked: &'r mut [bool],
    accept: Accept<'r>,
}

impl<S: Simd> PacketQuery<S> for InstanceOcclusionQuery<'_> {
    #[inline(always)]
    fn leaf(&mut self, _s: S, _rays: &Rays<S>, slot: u32, lanes: u32, _t_max: &mut S::F) -> u32 {
        if lanes == 0 {
            // Every lane reaching this instance is already blocked (by an earlier one).
            return 0;
        }
        let instance = self.instances.bvh.primitive_indices[slot as usize];
        let object = ObjectRays::new(self.instances, instance, self.rays, lanes, &self.bounds);
        let mut blocked = [false; MAX_WIDTH];
        if object.len == 1 {
            blocked[0] = self.instances.mesh_occluded(instance, &self.rays[object.lane[0]], &object.rays[0], self.accept);
        } else {
            let (mesh, first) = self.instances.mesh(instance);
            let (rays, out) = (&object.rays[..object.len], &mut blocked[..object.len]);
            // SAFETY (both): the token `_s` exists only where AVX2 and FMA exist.
            match self.accept {
                None => unsafe { mesh.occluded_packet(rays, out, &EveryHit) },
                Some(accept) => unsafe { mesh.occluded_packet(rays, out, &object.accepted(accept, self.rays, mesh, first, instance)) },
            }
        }
        let mut still = lanes;
        for (k, &b) in blocked[..object.len].iter().enumerate() {
            if b {
                self.blocked[object.lane[k]] = true;
                still &= !(1 << object.lane[k]);
            }
        }
        still
    }

    #[inline(always)]
    fn single(&mut self, _s: S, node: u32, lane: usize, _t_max: &mut S::F) -> bool {
        let blocked = self.instances.any_below(node, &self.rays[lane], self.accept);
        self.blocked[lane] |= blocked;
        blocked
    }
}

/// [`InstanceBvh::closest_packet`] with the kernel of token `s`.
#[inline(always)]
fn instances_closest<S: Simd>(s: S, instances: &InstanceBvh, rays: &[Ray], best: &mut [Option<Hit>], accept: Accept) {
    let active = lanes::<S>(rays.len());
    let bounded = bounded(rays, best);
    let (r, mut t_max) = load(s, &bounded[..rays.len()]);
    let mut query = InstanceClosestQuery { instances, rays, bounded: &bounded, best, accept };
    walk(s, &instances.bvh.nodes, &r, active, &mut t_max, &mut query);
}

/// [`InstanceBvh::occluded_packet`] with the kernel of token `s`.
#[inline(always)]
fn instances_occluded<S: Simd>(s: S, instances: &InstanceBvh, rays: &[Ray], blocked: &mut [bool], accept: Accept) {
    let active = lanes::<S>(rays.len()) & !blocked.iter().enumerate().map(|(i, &b)| (b as u32) << i).sum::<u32>();
    if active == 0 {
        return;
    }
    let (r, mut t_max) = load(s, rays);
    let mut bounds = [0.0f32; MAX_WIDTH];
    for (b, r) in bounds.iter_mut().zip(rays) {
        *b = r.t_max;
    }
    let mut query = InstanceOcclusionQuery { instances, rays, bounds, blocked, accept };
    walk(s, &instances.bvh.nodes, &r, active, &mut t_max, &mut query);
}

impl InstanceBvh {
    /// Closest hits of up to [`width`] rays through the instances, traced as one packet at
    /// both levels: `best[i]` as [`InstanceBvh::intersect`] of `rays[i]` and `best[i]`.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    pub(super) unsafe fn closest_packet(&self, rays: &[Ray], best: &mut [Option<Hit>], accept: Accept) {
        // SAFETY: the caller guarantees AVX2 and FMA; AVX-512F is checked.
        unsafe {
            if has_avx512f() {
                self.closest_packet16(rays, best, accept)
            } else {
                self.closest_packet8(rays, best, accept)
            }
        }
    }

    /// Occlusion of up to [`width`] rays through the instances as one packet: `blocked[i]`
    /// becomes true where [`InstanceBvh::occluded`] of `rays[i]` is.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    pub(super) unsafe fn occluded_packet(&self, rays: &[Ray], blocked: &mut [bool], accept: Accept) {
        // SAFETY: the caller guarantees AVX2 and FMA; AVX-512F is checked.
        unsafe {
            if has_avx512f() {
                self.occluded_packet16(rays, blocked, accept)
            } else {
                self.occluded_packet8(rays, blocked, accept)
            }
        }
    }

    /// # Safety
    /// The CPU must support AVX-512F, AVX2 and FMA.
    #[target_feature(enable = "avx512f,avx2,fma")]
    unsafe fn closest_packet16(&self, rays: &[Ray], best: &mut [Option<Hit>], accept: Accept) {
        // SAFETY: this function runs only where AVX-512F, AVX2 and FMA exist.
        instances_closest(unsafe { Avx512::new() }, self, rays, best, accept)
    }

    /// # Safety
    /// The CPU must support AVX-512F, AVX2 and FMA.
    #[target_feature(enable = "avx512f,avx2,fma")]
    unsafe fn occluded_packet16(&self, rays: &[Ray], blocked: &mut [bool], accept: Accept) {
        // SAFETY: this function runs only where AVX-512F, AVX2 and FMA exist.
        instances_occluded(unsafe { Avx512::new() }, self, rays, blocked, accept)
    }

    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    unsafe fn closest_packet8(&self, rays: &[Ray], best: &mut [Option<Hit>], accept: Accept) {
        // SAFETY: this function runs only where AVX2 and FMA exist.
        instances_closest(unsafe { Avx2::new() }, self, rays, best, accept)
    }

    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    unsafe fn occluded_packet8(&self, rays: &[Ray], blocked: &mut [bool], accept: Accept) {
        // SAFETY: this function runs only where AVX2 and FMA exist.
        instances_occluded(unsafe { Avx2::new() }, self, rays, blocked, accept)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::support::cpu::has_avx2_fma;
    use glam::Vec3;

    /// Each ray's eight children at once give, child by child, the lanes of the
    /// one-child-at-a-time test, for rays of all octants (axis-parallel ones included) and
    /// any subset of lanes.
    #[test]
    fn children_at_once_cross_the_boxes_one_child_at_a_time_does() {
        if !has_avx2_fma() {
            return;
        }
        // SAFETY: AVX2 and FMA are present.
        let s = unsafe { Avx2::new() };
        let mut sampler = crate::sampler::Sampler::new(9, 0, 0);
        let mut point = |scale: f32| (Vec3::new(sampler.next_1d(), sampler.next_1d(), sampler.next_1d()) - Vec3::splat(0.5)) * scale;
        let corners: Vec<[Vec3; 3]> = (0..2000)
            .map(|_| {
                let c = point(20.0);
                [c + point(2.0), c + point(2.0), c + point(2.0)]
            })
            .collect();
        let bvh = Bvh::build(corners.into_iter());
        let mut compared = 0;
        for packet in 0..64 {
            let rays: Vec<Ray> = (0..8)
                .map(|i| {
                    let d = if i == 3 { [Vec3::X, -Vec3::Y, Vec3::Z][packet % 3] } else { point(2.0) };
                    Ray { t_max: if i % 2 == 0 { 6.0 } else { f32::MAX }, ..Ray::new(point(24.0), d.normalize()) }
                })
                .collect();
            let (r, t_max) = load(s, &rays);
            let lanes = (packet as u32 * 37 + 11) & 0xff;
            for node in &bvh.bvh.nodes {
                // SAFETY: AVX2 and FMA are present.
                let crossed = unsafe { children_crossed(s, node, &r, lanes, t_max) };
                let (adj_dir_inv, adj_orig) = node_frame(s, node, &r);
                for c in (0..8).filter(|&c| node.child_meta[c] != 0) {
                    let expected = child_entry(s, &ChildFaces::new(node), c, &r, &adj_dir_inv, &adj_orig, t_max).1 & lanes;
                    assert_eq!((crossed >> (8 * c)) as u32 & 0xff, expected, "packet {packet}, child {c}");
                    compared += expected.count_ones();
                }
            }
        }
        assert!(compared > 1000, "the rays cross boxes: {compared}");
    }

    #[test]
    fn transposing_bits_swaps_rows_and_columns() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..1000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let t = transpose_bits8(state);
            for (r, c) in (0..8).flat_map(|r| (0..8).map(move |c| (r, c))) {
                assert_eq!((t >> (8 * c + r)) & 1, (state >> (8 * r + c)) & 1, "row {r} column {c} of {state:#x}");
            }
            assert_eq!(transpose_bits8(t), state);
        }
    }
}
