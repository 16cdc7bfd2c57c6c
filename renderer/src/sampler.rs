//! Deterministic random streams: every (pixel, sample) pair gets its own PCG32 stream derived
//! from the render seed, so an image depends only on the seed and the sample counts, never on
//! the number of threads or the order in which tiles run.

use glam::Vec2;

/// Independent uniform samples in [0, 1) for one camera path: a PCG32 stream (O'Neill's
/// XSH-RR output of a 64-bit LCG; the same numbers as `rand_pcg::Pcg32::new(key, stream)`),
/// whose draws of a vertex are taken in one [`Sampler::next_block`].
#[derive(Clone, Debug)]
pub struct Sampler {
    state: u64,
    /// The LCG's odd increment: the stream.
    increment: u64,
}

/// PCG32's LCG multiplier.
const MULTIPLIER: u64 = 6_364_136_223_846_793_005;

/// The most draws one [`Sampler::next_block`] takes.
const MAX_BLOCK: usize = 8;

/// `JUMPS[k]` = (Mᵏ, 1 + M + … + Mᵏ⁻¹) for the multiplier M: k steps of the LCG take state s
/// with increment c to Mᵏ·s + (1 + … + Mᵏ⁻¹)·c (mod 2⁶⁴), so the states of a block are each
/// two independent multiplications from the first rather than a chain of them.
const JUMPS: [(u64, u64); MAX_BLOCK + 1] = {
    let mut jumps = [(1u64, 0u64); MAX_BLOCK + 1];
    let mut k = 1;
    while k <= MAX_BLOCK {
        let (m, p) = jumps[k - 1];
        jumps[k] = (m.wrapping_mul(MULTIPLIER), p.wrapping_mul(MULTIPLIER).wrapping_add(1));
        k += 1;
    }
    jumps
};

/// SplitMix64 finaliser: decorrelates the (seed, pixel) key.
#[inline]
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A number in [0, 1) that is a deterministic hash of `words` (pbrt-v4's `HashFloat`): a
/// random decision tied to what it is about (a ray and a triangle) rather than to a
/// sample stream, so it is the same however the work is ordered.
#[inline]
pub fn hash_float(words: &[u32]) -> f32 {
    let h = words.iter().fold(0x9e37_79b9_7f4a_7c15u64, |h, &w| mix64(h ^ u64::from(w)));
    (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

/// PCG32's output of LCG state `state` (XSH-RR: xorshift high, random rotation) as a
/// uniform number in [0, 1) from its top 24 bits.
#[inline(always)]
fn unit_output(state: u64) -> f32 {
    let rotation = (state >> 59) as u32;
    let bits = (((state >> 18) ^ state) >> 27) as u32;
    (bits.rotate_right(rotation) >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

impl Sampler {
    /// The stream of sample `sample_index` of pixel `pixel_index` under `seed`.
    #[inline]
    pub fn new(seed: u64, pixel_index: u64, sample_index: u64) -> Self {
        Self::of_pixel(Self::pixel_key(seed, pixel_index), sample_index)
    }

    /// What the streams of pixel `pixel_index` under `seed` share: [`Sampler::of_pixel`] of
    /// it is [`Sampler::new`], so a pixel's many samples need it once.
    #[inline]
    pub fn pixel_key(seed: u64, pixel_index: u64) -> u64 {
        mix64(seed ^ mix64(pixel_index.wrapping_add(0x9e37_79b9_7f4a_7c15)))
    }

    /// The stream of sample `sample_index` of the pixel whose [`Sampler::pixel_key`] is
    /// `key`: PCG32 seeded with state `key` on stream `sample_index` (its top bit unused).
    #[inline]
    pub fn of_pixel(key: u64, sample_index: u64) -> Self {
        let increment = (sample_index << 1) | 1;
        let state = key.wrapping_add(increment).wrapping_mul(MULTIPLIER).wrapping_add(increment);
        Sampler { state, increment }
    }

    /// The next `N` (at most 8) uniform samples in [0, 1), in order: the same numbers as `N`
    /// calls of [`Sampler::next_1d`], found without a chain of dependent multiplications.
    #[inline(always)]
    pub fn next_block<const N: usize>(&mut self) -> [f32; N] {
        const { assert!(N <= MAX_BLOCK) };
        let (state, increment) = (self.state, self.increment);
        let state_after = |k: usize| JUMPS[k].0.wrapping_mul(state).wrapping_add(JUMPS[k].1.wrapping_mul(increment));
        self.state = state_after(N);
        std::array::from_fn(|k| unit_output(state_after(k)))
    }

    /// A uniform sample in [0, 1).
    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        let [x] = self.next_block();
        x
    }

    /// Two uniform samples in [0, 1)².
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        Vec2::from_array(self.next_block())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: Vec<f32> = (0..8).map(|_| 0.0).scan(Sampler::new(7, 3, 1), |s, _| Some(s.next_1d())).collect();
        let b: Vec<f32> = (0..8).map(|_| 0.0).scan(Sampler::new(7, 3, 1), |s, _| Some(s.next_1d())).collect();
        let c: Vec<f32> = (0..8).map(|_| 0.0).scan(Sampler::new(7, 3, 2), |s, _| Some(s.next_1d())).collect();
        let d: Vec<f32> = (0..8).map(|_| 0.0).scan(Sampler::new(8, 3, 1), |s, _| Some(s.next_1d())).collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_ne!(a, d);
        assert!(a.iter().all(|&x| (0.0..1.0).contains(&x)));
    }

    #[test]
    fn hash_float_is_uniform_and_deterministic() {
        let n = 100_000u32;
        let values: Vec<f32> = (0..n).map(|i| hash_float(&[i, 7])).collect();
        assert!(values.iter().all(|&x| (0.0..1.0).contains(&x)));
        let mean = values.iter().map(|&x| x as f64).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.005, "{mean}");
        assert_eq!(hash_float(&[3, 7]), values[3]);
        assert_ne!(hash_float(&[3, 8]), values[3]);
    }

    #[test]
    fn streams_are_pcg32_and_blocks_are_the_same_draws() {
        use rand::RngCore;
        for (key, stream) in [(0, 0), (7, 3), (u64::MAX, u64::MAX), (0x1234_5678_9abc_def0, 1 << 40)] {
            let mut reference = rand_pcg::Pcg32::new(key, stream);
            let expected: Vec<f32> = (0..64).map(|_| (reference.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)).collect();
            let mut s = Sampler::of_pixel(key, stream);
            let ones: Vec<f32> = (0..64).map(|_| s.next_1d()).collect();
            assert_eq!(ones, expected);
            // Blocks of every size, mixed, draw the same sequence.
            let mut s = Sampler::of_pixel(key, stream);
            let mut blocks = Vec::new();
            blocks.extend(s.next_block::<6>());
            blocks.extend(s.next_block::<8>());
            blocks.extend(s.next_block::<1>());
            blocks.extend(s.next_2d().to_array());
            blocks.extend(s.next_block::<3>());
            blocks.extend(s.next_block::<0>());
            blocks.extend(s.next_block::<7>());
            assert_eq!(blocks, expected[..blocks.len()]);
        }
    }

    #[test]
    fn mean_is_one_half() {
        let mut s = Sampler::new(1, 2, 3);
        let n = 100_000;
        let mean: f64 = (0..n).map(|_| s.next_1d() as f64).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.005, "{mean}");
    }
}
