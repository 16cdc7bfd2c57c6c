//! Deterministic random streams: every (pixel, sample) pair gets its own PCG32 stream derived
//! from the render seed, so an image depends only on the seed and the sample counts, never on
//! the number of threads or the order in which tiles run.

use glam::Vec2;
use rand::RngCore;
use rand_pcg::Pcg32;

/// Independent uniform samples in [0, 1) for one camera path.
#[derive(Clone, Debug)]
pub struct Sampler {
    rng: Pcg32,
}

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
    /// `key`.
    #[inline]
    pub fn of_pixel(key: u64, sample_index: u64) -> Self {
        Sampler {
            rng: Pcg32::new(key, sample_index),
        }
    }

    /// A uniform sample in [0, 1).
    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        (self.rng.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// Two uniform samples in [0, 1)².
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        let x = self.next_1d();
        Vec2::new(x, self.next_1d())
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
    fn mean_is_one_half() {
        let mut s = Sampler::new(1, 2, 3);
        let n = 100_000;
        let mean: f64 = (0..n).map(|_| s.next_1d() as f64).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.005, "{mean}");
    }
}
