//! Packets of up to 16 rays traced together through the CWBVH with AVX-512: each child box
//! and each leaf triangle is tested against all rays of the packet in one SIMD step, the
//! way Embree's packet kernels do. In a small scene every ray of a packet visits nearly the
//! same nodes, so a node or triangle costs a sixteenth of a single-ray test per ray. Where
//! rays diverge, subtrees entered by few of them are walked one ray at a time.
//!
//! The per-ray arithmetic is that of the single-ray kernels (box distances by the same
//! fused multiply-adds, triangles by the same Möller–Trumbore sequence without fused
//! operations), so a packet finds the same hits, bit for bit.

use super::{to_bvh_ray, Bvh, Hit, Ray, Stack, LANES};
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ray::Ray as BvhRay;
use std::arch::x86_64::*;

/// Rays per packet.
pub const PACKET: usize = 16;

/// A packet's rays, structure of arrays.
struct Rays {
    o: [__m512; 3],
    d: [__m512; 3],
    inv: [__m512; 3],
    /// Lanes whose direction component is negative, per axis.
    negative: [__mmask16; 3],
}

/// Per-lane closest hit so far.
struct Closest {
    t: __m512,
    slot: __m512i,
    b1: __m512,
    b2: __m512,
}

/// Lanes of `rays` (the first lane repeated into unused lanes, which are masked off), their
/// bounds, and the rays as single-ray traversal takes them.
#[target_feature(enable = "avx512f")]
fn load(rays: &[Ray]) -> (Rays, __m512, [BvhRay; PACKET]) {
    let mut a = [[0.0f32; PACKET]; 10];
    let singles = std::array::from_fn(|lane| to_bvh_ray(&rays[lane.min(rays.len() - 1)]));
    for (lane, r) in singles.iter().enumerate() {
        for axis in 0..3 {
            a[axis][lane] = r.origin[axis];
            a[3 + axis][lane] = r.direction[axis];
            a[6 + axis][lane] = r.inv_direction[axis];
        }
        a[9][lane] = r.tmax;
    }
    // SAFETY: each load reads the 16 floats of one array.
    let v = a.map(|x| unsafe { _mm512_loadu_ps(x.as_ptr()) });
    let zero = _mm512_setzero_ps();
    let rays = Rays {
        o: [v[0], v[1], v[2]],
        d: [v[3], v[4], v[5]],
        inv: [v[6], v[7], v[8]],
        negative: [3, 4, 5].map(|i| _mm512_cmp_ps_mask::<_CMP_LT_OQ>(v[i], zero)),
    };
    (rays, v[9], singles)
}

/// The lanes in `active` whose ray crosses child `c` of `node` within (T_MIN, t_max):
/// the arithmetic of [`super::node::intersect_avx2`] per lane.
#[inline]
#[target_feature(enable = "avx512f")]
fn child_hits(node: &CwBvhNode, c: usize, rays: &Rays, adj_dir_inv: &[__m512; 3], adj_orig: &[__m512; 3], t_max: __m512, active: __mmask16) -> __mmask16 {
    const T_MIN: f32 = 1e-4;
    let bounds = [
        (node.child_min_x[c], node.child_max_x[c]),
        (node.child_min_y[c], node.child_max_y[c]),
        (node.child_min_z[c], node.child_max_z[c]),
    ];
    let mut near = [_mm512_setzero_ps(); 3];
    let mut far = [_mm512_setzero_ps(); 3];
    for axis in 0..3 {
        let (lo, hi) = bounds[axis];
        let t_lo = _mm512_fmadd_ps(_mm512_set1_ps(lo as f32), adj_dir_inv[axis], adj_orig[axis]);
        let t_hi = _mm512_fmadd_ps(_mm512_set1_ps(hi as f32), adj_dir_inv[axis], adj_orig[axis]);
        near[axis] = _mm512_mask_blend_ps(rays.negative[axis], t_lo, t_hi);
        far[axis] = _mm512_mask_blend_ps(rays.negative[axis], t_hi, t_lo);
    }
    let t0 = _mm512_max_ps(_mm512_max_ps(near[0], near[1]), _mm512_max_ps(near[2], _mm512_set1_ps(T_MIN)));
    let t1 = _mm512_min_ps(_mm512_min_ps(far[0], far[1]), _mm512_min_ps(far[2], t_max));
    _mm512_mask_cmp_ps_mask::<_CMP_LE_OQ>(active, t0, t1)
}

/// Möller–Trumbore of one triangle against every lane, as [`super::triangle_pack`] computes
/// it: (t, b1, b2, lanes hit with t ∈ (0, t_max)).
#[inline]
#[target_feature(enable = "avx512f")]
fn triangle_hits(bvh: &Bvh, pack: usize, lane: usize, rays: &Rays, t_max: __m512, active: __mmask16) -> (__m512, __m512, __m512, __mmask16) {
    let p = &bvh.packs[pack];
    let s3 = |a: &[[f32; LANES]; 3]| [0, 1, 2].map(|axis| _mm512_set1_ps(a[axis][lane]));
    let (v0, e1, e2) = (s3(&p.v0), s3(&p.e1), s3(&p.e2));
    let (mul, sub, add) = (|a, b| _mm512_mul_ps(a, b), |a, b| _mm512_sub_ps(a, b), |a, b| _mm512_add_ps(a, b));
    let dot = |a: [__m512; 3], b: [__m512; 3]| add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]));
    let cross = |a: [__m512; 3], b: [__m512; 3]| {
        [
            sub(mul(a[1], b[2]), mul(a[2], b[1])),
            sub(mul(a[2], b[0]), mul(a[0], b[2])),
            sub(mul(a[0], b[1]), mul(a[1], b[0])),
        ]
    };
    let d = rays.d;
    let pv = cross(d, e2);
    let inv_det = _mm512_div_ps(_mm512_set1_ps(1.0), dot(e1, pv));
    let s = [sub(rays.o[0], v0[0]), sub(rays.o[1], v0[1]), sub(rays.o[2], v0[2])];
    let b1 = mul(dot(s, pv), inv_det);
    let q = cross(s, e1);
    let b2 = mul(dot(d, q), inv_det);
    let t = mul(dot(e2, q), inv_det);
    let zero = _mm512_setzero_ps();
    let mut hit = _mm512_mask_cmp_ps_mask::<_CMP_GE_OQ>(active, b1, zero);
    hit = _mm512_mask_cmp_ps_mask::<_CMP_GE_OQ>(hit, b2, zero);
    hit = _mm512_mask_cmp_ps_mask::<_CMP_LE_OQ>(hit, add(b1, b2), _mm512_set1_ps(1.0));
    hit = _mm512_mask_cmp_ps_mask::<_CMP_GT_OQ>(hit, t, zero);
    hit = _mm512_mask_cmp_ps_mask::<_CMP_LT_OQ>(hit, t, t_max);
    (t, b1, b2, hit)
}

/// Subtrees entered by fewer rays of a packet than this are traced one ray at a time
/// (Embree's hybrid traversal): a sixteen-wide test that serves a single ray costs more than
/// its single-ray walk. 2 measured best of 1, 2 and 4 on the shipped scenes.
const SINGLE_BELOW: u32 = 2;

/// A leaf triangle: lane `lane` of pack `pack`, obvhs primitive slot `slot`.
#[derive(Clone, Copy)]
struct LeafTriangle {
    pack: usize,
    lane: usize,
    slot: u32,
}

/// What a packet walk looks for: closest hits or occlusion.
trait PacketQuery {
    /// Tests one triangle for the rays in `lanes`, may lower their bounds `t_max`, and
    /// returns which of `lanes` still need tracing.
    fn leaf(&mut self, bvh: &Bvh, rays: &Rays, triangle: LeafTriangle, lanes: __mmask16, t_max: &mut __m512) -> __mmask16;

    /// Walks the subtree of `node` for ray `lane` alone; returns whether that ray is done.
    fn single(&mut self, bvh: &Bvh, node: u32, lane: usize, t_max: &mut __m512) -> bool;
}

/// Walks the tree for the lanes in `active`, whose bounds are `t_max`.
#[inline]
#[target_feature(enable = "avx512f")]
fn walk(bvh: &Bvh, rays: &Rays, mut active: __mmask16, t_max: &mut __m512, query: &mut impl PacketQuery) {
    let nodes = &bvh.bvh.nodes;
    let mut stack = Stack::new();
    stack.push((0, active));
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
                if query.single(bvh, index, lane, t_max) {
                    active &= !(1 << lane);
                }
            }
            if active == 0 {
                return;
            }
            continue;
        }
        let node = &nodes[index as usize];
        let e = node.compute_extent();
        let adj_dir_inv = [0, 1, 2].map(|a| _mm512_mul_ps(_mm512_set1_ps(e[a]), rays.inv[a]));
        let adj_orig = [0, 1, 2].map(|a| _mm512_mul_ps(_mm512_sub_ps(_mm512_set1_ps(node.p[a]), rays.o[a]), rays.inv[a]));
        for c in 0..8 {
            let meta = node.child_meta[c];
            if meta == 0 {
                continue;
            }
            let hits = child_hits(node, c, rays, &adj_dir_inv, &adj_orig, *t_max, lanes & active);
            if hits == 0 {
                continue;
            }
            if node.is_leaf(c) {
                let first = (meta & 0b1_1111) as usize;
                for local in first..first + (meta & 0b1110_0000).count_ones() as usize {
                    let triangle = LeafTriangle {
                        pack: bvh.node_packs[index as usize] as usize + local / LANES,
                        lane: local % LANES,
                        slot: node.primitive_base_idx + local as u32,
                    };
                    active = query.leaf(bvh, rays, triangle, hits & active, t_max) | (active & !hits);
                }
            } else {
                stack.push((node.child_node_index(c), hits));
            }
        }
        if active == 0 {
            return;
        }
    }
}

/// Closest hits: the per-lane best so far, and the rays for single-ray subtrees.
struct ClosestQuery {
    best: Closest,
    singles: [BvhRay; PACKET],
}

impl PacketQuery for ClosestQuery {
    #[inline(always)]
    fn leaf(&mut self, bvh: &Bvh, rays: &Rays, triangle: LeafTriangle, lanes: __mmask16, t_max: &mut __m512) -> __mmask16 {
        // SAFETY: only called from `walk`, which runs where AVX-512F exists.
        unsafe {
            let (t, b1, b2, hit) = triangle_hits(bvh, triangle.pack, triangle.lane, rays, *t_max, lanes);
            self.best.take(hit, t, b1, b2, triangle.slot);
        }
        *t_max = self.best.t;
        lanes
    }

    #[inline(always)]
    fn single(&mut self, bvh: &Bvh, node: u32, lane: usize, t_max: &mut __m512) -> bool {
        let mut bounds = [0.0f32; PACKET];
        // SAFETY: only called from `walk`, which runs where AVX-512F (and, as checked by
        // `packets_available`, AVX2 and FMA) exist; the store writes 16 lanes into 16.
        unsafe {
            _mm512_storeu_ps(bounds.as_mut_ptr(), *t_max);
            let ray = BvhRay { tmax: bounds[lane], ..self.singles[lane] };
            if let Some((t, slot, b)) = bvh.closest_below_avx2(node, &ray) {
                let splat = |x| _mm512_set1_ps(x);
                self.best.take(1 << lane, splat(t), splat(b.x), splat(b.y), slot);
            }
        }
        *t_max = self.best.t;
        false
    }
}

impl Closest {
    /// Takes the hits of `lanes`.
    #[inline]
    #[target_feature(enable = "avx512f")]
    fn take(&mut self, lanes: __mmask16, t: __m512, b1: __m512, b2: __m512, slot: u32) {
        self.t = _mm512_mask_mov_ps(self.t, lanes, t);
        self.b1 = _mm512_mask_mov_ps(self.b1, lanes, b1);
        self.b2 = _mm512_mask_mov_ps(self.b2, lanes, b2);
        self.slot = _mm512_mask_mov_epi32(self.slot, lanes, _mm512_set1_epi32(slot as i32));
    }
}

/// Occlusion: the lanes found blocked, and the rays for single-ray subtrees.
struct OcclusionQuery {
    blocked: __mmask16,
    singles: [BvhRay; PACKET],
}

impl PacketQuery for OcclusionQuery {
    #[inline(always)]
    fn leaf(&mut self, bvh: &Bvh, rays: &Rays, triangle: LeafTriangle, lanes: __mmask16, t_max: &mut __m512) -> __mmask16 {
        // SAFETY: only called from `walk`, which runs where AVX-512F exists.
        let hit = unsafe { triangle_hits(bvh, triangle.pack, triangle.lane, rays, *t_max, lanes) }.3;
        self.blocked |= hit;
        lanes & !hit
    }

    #[inline(always)]
    fn single(&mut self, bvh: &Bvh, node: u32, lane: usize, _t_max: &mut __m512) -> bool {
        // SAFETY: only called from `walk`, which runs where AVX2 and FMA exist
        // (`packets_available`).
        let hit = unsafe { bvh.any_below_avx2(node, &self.singles[lane]) };
        self.blocked |= (hit as __mmask16) << lane;
        hit
    }
}

impl Bvh {
    /// Closest hits of up to [`PACKET`] rays traced as one packet; `out[i]` as
    /// [`Bvh::intersect`] of `rays[i]`.
    ///
    /// # Safety
    /// The CPU must support AVX-512F, AVX2 and FMA; `rays` holds 1 to [`PACKET`] rays and
    /// `out` as many.
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn closest_packet(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        let (r, mut t_max, singles) = load(rays);
        let active = (((1u32 << rays.len()) - 1) & 0xffff) as __mmask16;
        let mut query = ClosestQuery {
            best: Closest {
                t: t_max,
                slot: _mm512_set1_epi32(-1),
                b1: _mm512_setzero_ps(),
                b2: _mm512_setzero_ps(),
            },
            singles,
        };
        walk(self, &r, active, &mut t_max, &mut query);
        let best = query.best;
        let mut t = [0.0f32; PACKET];
        let mut b1 = [0.0f32; PACKET];
        let mut b2 = [0.0f32; PACKET];
        let mut slot = [0i32; PACKET];
        // SAFETY: each store writes 16 lanes into a 16-lane array.
        unsafe {
            _mm512_storeu_ps(t.as_mut_ptr(), best.t);
            _mm512_storeu_ps(b1.as_mut_ptr(), best.b1);
            _mm512_storeu_ps(b2.as_mut_ptr(), best.b2);
            _mm512_storeu_si512(slot.as_mut_ptr().cast(), best.slot);
        }
        for (i, o) in out.iter_mut().enumerate().take(rays.len()) {
            *o = (slot[i] >= 0).then(|| Hit {
                t: t[i],
                triangle: self.scene_triangle(slot[i] as u32),
                barycentric: glam::Vec2::new(b1[i], b2[i]),
                instance: super::NO_INSTANCE,
            });
        }
    }

    /// Occlusion of up to [`PACKET`] rays traced as one packet; `out[i]` as
    /// [`Bvh::occluded`] of `rays[i]`.
    ///
    /// # Safety
    /// The CPU must support AVX-512F, AVX2 and FMA; `rays` holds 1 to [`PACKET`] rays and
    /// `out` as many.
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn occluded_packet(&self, rays: &[Ray], out: &mut [bool]) {
        let (r, mut t_max, singles) = load(rays);
        let active = (((1u32 << rays.len()) - 1) & 0xffff) as __mmask16;
        let mut query = OcclusionQuery { blocked: 0, singles };
        walk(self, &r, active, &mut t_max, &mut query);
        let blocked = query.blocked;
        for (i, o) in out.iter_mut().enumerate().take(rays.len()) {
            *o = blocked & (1 << i) != 0;
        }
    }
}
