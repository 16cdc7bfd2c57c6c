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

/// The eight child boxes of a node decoded to floats in the node's quantised units (AVX2
/// vectors, child c in lane c), their faces ordered for one direction octant: per axis, the
/// face a ray of that octant enters by (`near`) and the one it leaves by (`far`).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub struct ChildSlabs {
    near: [std::arch::x86_64::__m256; 3],
    far: [std::arch::x86_64::__m256; 3],
}

/// Eight quantised faces as floats.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn decode(faces: &[u8; 8]) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::*;
    // SAFETY: reads exactly the 8 bytes of `faces`.
    _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(unsafe { _mm_loadl_epi64(faces.as_ptr().cast()) }))
}

#[cfg(target_arch = "x86_64")]
impl ChildSlabs {
    /// Decodes `node`'s child boxes for rays whose direction is negative along the axes of
    /// `negative` (bit a: axis a, as [`negative_axes`]).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub unsafe fn new(node: &CwBvhNode, negative: u32) -> Self {
        let faces = [
            (&node.child_min_x, &node.child_max_x),
            (&node.child_min_y, &node.child_max_y),
            (&node.child_min_z, &node.child_max_z),
        ];
        let oriented = |axis: usize| {
            let (lo, hi) = faces[axis];
            let (near, far) = if negative & (1 << axis) != 0 { (hi, lo) } else { (lo, hi) };
            // SAFETY: the caller guarantees AVX2.
            unsafe { (decode(near), decode(far)) }
        };
        let [(nx, fx), (ny, fy), (nz, fz)] = [oriented(0), oriented(1), oriented(2)];
        ChildSlabs {
            near: [nx, ny, nz],
            far: [fx, fy, fz],
        }
    }

    /// The children whose boxes the ray crosses within (T_MIN, t_max), as a vector mask
    /// (lane c all ones where child c is crossed). `extent` and `p` are the node's
    /// quantisation step and origin; the ray's direction must lie in the slabs' octant.
    /// Empty children never hit (their quantised lower face lies above the upper one), nor do
    /// NaN distances.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    pub unsafe fn crossed(&self, extent: Vec3A, p: Vec3A, origin: Vec3A, inv_direction: Vec3A, t_max: f32) -> std::arch::x86_64::__m256 {
        use std::arch::x86_64::*;
        let adj_dir_inv = extent * inv_direction;
        let adj_orig = (p - origin) * inv_direction;
        let t = |faces: &[__m256; 3], axis: usize| _mm256_fmadd_ps(faces[axis], _mm256_set1_ps(adj_dir_inv[axis]), _mm256_set1_ps(adj_orig[axis]));
        let t0 = _mm256_max_ps(_mm256_max_ps(t(&self.near, 0), t(&self.near, 1)), _mm256_max_ps(t(&self.near, 2), _mm256_set1_ps(T_MIN)));
        let t1 = _mm256_min_ps(_mm256_min_ps(t(&self.far, 0), t(&self.far, 1)), _mm256_min_ps(t(&self.far, 2), _mm256_set1_ps(t_max)));
        _mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1)
    }
}

/// A node's child boxes decoded once for rays of any octant (see [`ChildSlabs`]): a packet's
/// rays, whose octants differ, each take their slabs from it.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub struct ChildBoxes {
    /// Per axis, the lower faces then the upper ones.
    faces: [[std::arch::x86_64::__m256; 2]; 3],
}

#[cfg(target_arch = "x86_64")]
impl ChildBoxes {
    /// Decodes `node`'s child boxes.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub unsafe fn new(node: &CwBvhNode) -> Self {
        // SAFETY: the caller guarantees AVX2.
        unsafe {
            ChildBoxes {
                faces: [
                    [decode(&node.child_min_x), decode(&node.child_max_x)],
                    [decode(&node.child_min_y), decode(&node.child_max_y)],
                    [decode(&node.child_min_z), decode(&node.child_max_z)],
                ],
            }
        }
    }

    /// The slabs for directions negative along the axes of `negative` (as
    /// [`ChildSlabs::new`]), picked by index rather than by branches, which rays of mixed
    /// octants would mispredict.
    #[inline(always)]
    pub fn slabs(&self, negative: u32) -> ChildSlabs {
        let side = |axis: usize| ((negative >> axis) & 1) as usize;
        let [sx, sy, sz] = [side(0), side(1), side(2)];
        ChildSlabs {
            near: [self.faces[0][sx], self.faces[1][sy], self.faces[2][sz]],
            far: [self.faces[0][1 - sx], self.faces[1][1 - sy], self.faces[2][1 - sz]],
        }
    }
}

/// The axes along which `direction` is negative (bit a: axis a).
#[inline]
pub fn negative_axes(direction: Vec3A) -> u32 {
    direction.cmplt(Vec3A::ZERO).bitmask()
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
    // SAFETY: the caller guarantees AVX2 and FMA.
    let hit = unsafe {
        ChildSlabs::new(node, negative_axes(ray.direction)).crossed(node.compute_extent(), Vec3A::from(node.p), ray.origin, ray.inv_direction, t_max)
    };
    let hit = _mm256_castps_si256(hit);
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
