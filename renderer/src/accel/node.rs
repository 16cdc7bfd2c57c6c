//! Ray against the eight children of a compressed-wide BVH node.

use glam::Vec3A;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ray::Ray as BvhRay;

/// Box distances of node intersection are clamped below by this (as obvhs does).
const T_MIN: f32 = 1e-4;

/// The traversal octant of a direction in obvhs's encoding (each byte: 7 − octant).
#[inline]
pub fn octant_inv4(direction: Vec3A) -> u32 {
    (if direction.x < 0.0 { 0 } else { 0x0404_0404 })
        | (if direction.y < 0.0 { 0 } else { 0x0202_0202 })
        | (if direction.z < 0.0 { 0 } else { 0x0101_0101 })
}

/// The children of `node` whose boxes the ray crosses within (T_MIN, t_max), as a hit mask
/// in obvhs's encoding (inner children in the high byte by traversal priority, leaf
/// primitives in the low 24 bits), portable path.
#[inline(always)]
pub fn intersect_portable(node: &CwBvhNode, ray: &BvhRay, oct_inv4: u32, t_max: f32) -> u32 {
    node.intersect_ray(&BvhRay { tmax: t_max, ..*ray }, oct_inv4)
}

/// As [`intersect_portable`], eight children at once with AVX2 + FMA.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
pub unsafe fn intersect_avx2(node: &CwBvhNode, ray: &BvhRay, oct_inv4: u32, t_max: f32) -> u32 {
    use std::arch::x86_64::*;
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
    let t1 = _mm256_min_ps(_mm256_min_ps(x1, y1), _mm256_min_ps(z1, _mm256_set1_ps(t_max)));
    let hit = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1));
    // Branch-free expansion of the hit children into the mask: child bits (1 for inner
    // children, the unary primitive count for leaves) shifted to each child's bit index.
    let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
    let bytes = |v: u64| _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(v as i64));
    let shifted = _mm256_and_si256(_mm256_sllv_epi32(bytes(child_bits8), bytes(bit_index8)), hit);
    let or4 = _mm_or_si128(_mm256_castsi256_si128(shifted), _mm256_extracti128_si256::<1>(shifted));
    let or2 = _mm_or_si128(or4, _mm_shuffle_epi32::<0b01_00_11_10>(or4));
    let or1 = _mm_or_si128(or2, _mm_shuffle_epi32::<0b10_11_00_01>(or2));
    _mm_cvtsi128_si32(or1) as u32
}
