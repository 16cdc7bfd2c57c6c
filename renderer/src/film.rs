//! The image being accumulated: per-pixel sums of radiance samples and of their squares
//! (for a per-pixel variance estimate) and the number of samples taken.

use crate::Rgb;

/// Accumulated samples of an image, row-major from the top-left pixel.
#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    sum: Vec<[f64; 3]>,
    sum_sq: Vec<[f64; 3]>,
    count: Vec<u32>,
}

/// The samples one pixel received in one pass.
#[derive(Clone, Copy, Debug, Default)]
pub struct PixelAccumulator {
    pub sum: [f64; 3],
    pub sum_sq: [f64; 3],
    pub count: u32,
}

impl PixelAccumulator {
    /// Adds one radiance sample.
    #[inline]
    pub fn add(&mut self, l: Rgb) {
        for c in 0..3 {
            let v = l[c] as f64;
            self.sum[c] += v;
            self.sum_sq[c] += v * v;
        }
        self.count += 1;
    }
}

impl Film {
    /// An empty film.
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Film {
            width,
            height,
            sum: vec![[0.0; 3]; n],
            sum_sq: vec![[0.0; 3]; n],
            count: vec![0; n],
        }
    }

    /// Adds a pass's samples of pixel `index`.
    #[inline]
    pub fn merge(&mut self, index: usize, acc: &PixelAccumulator) {
        for c in 0..3 {
            self.sum[index][c] += acc.sum[c];
            self.sum_sq[index][c] += acc.sum_sq[c];
        }
        self.count[index] += acc.count;
    }

    /// Samples taken in pixel `index`.
    pub fn samples(&self, index: usize) -> u32 {
        self.count[index]
    }

    /// Total samples over all pixels.
    pub fn total_samples(&self) -> u64 {
        self.count.iter().map(|&c| c as u64).sum()
    }

    /// The mean radiance per pixel (zero where no sample was taken).
    pub fn mean(&self) -> Vec<Rgb> {
        self.sum
            .iter()
            .zip(&self.count)
            .map(|(s, &n)| {
                if n == 0 {
                    Rgb::ZERO
                } else {
                    let k = 1.0 / n as f64;
                    Rgb::new((s[0] * k) as f32, (s[1] * k) as f32, (s[2] * k) as f32)
                }
            })
            .collect()
    }

    /// Estimated variance of each pixel's mean (sample variance / n), per channel; zero
    /// where fewer than two samples were taken.
    pub fn variance_of_mean(&self) -> Vec<Rgb> {
        self.sum
            .iter()
            .zip(&self.sum_sq)
            .zip(&self.count)
            .map(|((s, s2), &n)| {
                if n < 2 {
                    return Rgb::ZERO;
                }
                let n = n as f64;
                let v = |c: usize| {
                    let mean = s[c] / n;
                    (((s2[c] / n - mean * mean) * n / (n - 1.0)).max(0.0) / n) as f32
                };
                Rgb::new(v(0), v(1), v(2))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_and_variance_of_known_samples() {
        let mut film = Film::new(2, 1);
        let mut acc = PixelAccumulator::default();
        for v in [1.0, 2.0, 3.0, 4.0] {
            acc.add(Rgb::splat(v));
        }
        film.merge(1, &acc);
        let mean = film.mean();
        assert_eq!(mean[0], Rgb::ZERO);
        assert!((mean[1] - Rgb::splat(2.5)).length() < 1e-6);
        // Sample variance 5/3, variance of the mean 5/12.
        assert!((film.variance_of_mean()[1].x - 5.0 / 12.0).abs() < 1e-6);
        assert_eq!(film.total_samples(), 4);
    }
}
