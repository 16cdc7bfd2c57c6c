//! Image error metrics, shared by `render --error-log` and material-nn's evaluation:
//! RMSE, PSNR and SSIM, on linear images or on 8-bit display images.

use crate::Rgb;

/// Root-mean-square error over all pixels and channels.
pub fn rmse(a: &[Rgb], b: &[Rgb]) -> f64 {
    assert_eq!(a.len(), b.len(), "images differ in size");
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).as_dvec3().length_squared())
        .sum();
    (sum / (3 * a.len()).max(1) as f64).sqrt()
}

/// Peak signal-to-noise ratio in dB for a given data range (1 for images in [0, 1], 255 for
/// 8-bit values); +∞ for identical images.
pub fn psnr(a: &[Rgb], b: &[Rgb], data_range: f64) -> f64 {
    let e = rmse(a, b);
    if e == 0.0 {
        f64::INFINITY
    } else {
        20.0 * (data_range / e).log10()
    }
}

/// Mean structural similarity (Wang et al. 2004) over the channels, with a uniform
/// `window × window` window (odd, ≥ 3) at every position where it fits, the usual constants
/// K1 = 0.01, K2 = 0.03 and the sample covariance, as scikit-image's `structural_similarity`
/// computes it. 1 for identical images.
pub fn ssim(a: &[Rgb], b: &[Rgb], width: usize, height: usize, window: usize, data_range: f64) -> f64 {
    assert_eq!(a.len(), width * height, "image a has the wrong size");
    assert_eq!(b.len(), width * height, "image b has the wrong size");
    assert!(window >= 3 && window % 2 == 1, "window must be odd and at least 3");
    if width < window || height < window {
        return if a == b { 1.0 } else { 0.0 };
    }
    let c1 = (0.01 * data_range).powi(2);
    let c2 = (0.03 * data_range).powi(2);
    let n = (window * window) as f64;
    let cov_norm = n / (n - 1.0);
    let mut total = 0.0;
    let mut count = 0usize;
    for c in 0..3 {
        for y0 in 0..=height - window {
            for x0 in 0..=width - window {
                let (mut sa, mut sb, mut saa, mut sbb, mut sab) = (0.0, 0.0, 0.0, 0.0, 0.0);
                for y in y0..y0 + window {
                    for x in x0..x0 + window {
                        let (va, vb) = (a[x + y * width][c] as f64, b[x + y * width][c] as f64);
                        sa += va;
                        sb += vb;
                        saa += va * va;
                        sbb += vb * vb;
                        sab += va * vb;
                    }
                }
                let (ma, mb) = (sa / n, sb / n);
                let va = cov_norm * (saa / n - ma * ma);
                let vb = cov_norm * (sbb / n - mb * mb);
                let vab = cov_norm * (sab / n - ma * mb);
                total += ((2.0 * ma * mb + c1) * (2.0 * vab + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2));
                count += 1;
            }
        }
    }
    total / count as f64
}

/// The error of `image` against `reference` in the three metrics at once.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ImageError {
    /// RMSE of linear radiance.
    pub rmse: f64,
    /// PSNR in dB of the 8-bit display images (data range 255).
    pub psnr: f64,
    /// SSIM of the 8-bit display images (7-pixel window, data range 255).
    pub ssim: f64,
}

/// Window of [`ImageError`]'s SSIM.
pub const SSIM_WINDOW: usize = 7;

impl ImageError {
    /// Compares two linear images; PSNR and SSIM use their display forms (`to_display`
    /// maps a linear image to 8-bit values as f32 triples).
    pub fn between(image: &[Rgb], reference: &[Rgb], width: usize, height: usize, to_display: impl Fn(&[Rgb]) -> Vec<Rgb>) -> Self {
        let (di, dr) = (to_display(image), to_display(reference));
        ImageError {
            rmse: rmse(image, reference),
            psnr: psnr(&di, &dr, 255.0),
            ssim: ssim(&di, &dr, width, height, SSIM_WINDOW, 255.0),
        }
    }
}

/// An image's 8-bit sRGB display values (as f32 triples in [0, 255]) under a tone map.
pub fn display_values(image: &[Rgb], tone_map: crate::formats::image_io::ToneMap, exposure: f32) -> Vec<Rgb> {
    crate::formats::image_io::to_srgb8(image, tone_map, exposure)
        .chunks_exact(3)
        .map(|c| Rgb::new(c[0] as f32, c[1] as f32, c[2] as f32))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize) -> Vec<Rgb> {
        (0..w * h).map(|i| Rgb::new((i % w) as f32 / w as f32, (i / w) as f32 / h as f32, 0.5)).collect()
    }

    #[test]
    fn identical_images() {
        let a = ramp(16, 12);
        assert_eq!(rmse(&a, &a), 0.0);
        assert!(psnr(&a, &a, 1.0).is_infinite());
        assert!((ssim(&a, &a, 16, 12, 7, 1.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn known_values() {
        let a = vec![Rgb::ZERO; 4];
        let b = vec![Rgb::splat(0.1); 4];
        assert!((rmse(&a, &b) - 0.1).abs() < 1e-7);
        assert!((psnr(&a, &b, 1.0) - 20.0).abs() < 1e-5);
        // A constant offset keeps structure but changes luminance: SSIM below 1, above 0.
        let a = ramp(16, 16);
        let b: Vec<Rgb> = a.iter().map(|p| *p + Rgb::splat(0.2)).collect();
        let s = ssim(&a, &b, 16, 16, 7, 1.0);
        assert!(s < 0.99 && s > 0.5, "{s}");
        // Noise lowers SSIM more than it lowers nothing.
        let noisy: Vec<Rgb> = a.iter().enumerate().map(|(i, p)| *p + Rgb::splat(if i % 2 == 0 { 0.1 } else { -0.1 })).collect();
        assert!(ssim(&a, &noisy, 16, 16, 7, 1.0) < 0.95);
    }
}
