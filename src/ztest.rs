//! Statistical comparison of a rendered image with a reference, as Mitsuba 3's render tests
//! do: per pixel and channel, a two-sided Z-test of the difference of the two means against
//! their estimated variances, at significance α with Šidák's correction for the number of
//! tests; the images agree when at least `min_pass_fraction` of the tests pass. Per-pixel
//! tests have little power against a small change spread over the whole image, so the
//! image means per channel must also agree (a Z-test at α with Šidák's correction over the
//! three channels).

use renderer::Rgb;
use statrs::distribution::{ContinuousCDF, Normal};

/// Outcome of [`compare`].
#[derive(Clone, Debug)]
pub struct ZTestReport {
    /// Fraction of pixel channels whose test passed.
    pub pass_fraction: f64,
    /// Per-test significance level after Šidák's correction.
    pub alpha_per_test: f64,
    /// Two-sided p-value per pixel (minimum over its channels).
    pub p_values: Vec<f32>,
    /// Pixel channels tested.
    pub tests: usize,
    /// Two-sided p-value of the difference of the image means (minimum over channels).
    pub mean_p_value: f64,
    /// Whether the images agree.
    pub passed: bool,
}

/// Compares `image` (mean, variance of the mean) to `reference` (same) at overall
/// significance `alpha`, passing when ≥ `min_pass_fraction` of pixel channels pass.
pub fn compare(image: &[Rgb], image_var: &[Rgb], reference: &[Rgb], reference_var: &[Rgb], alpha: f64, min_pass_fraction: f64) -> ZTestReport {
    assert_eq!(image.len(), reference.len(), "image sizes differ");
    let normal = Normal::standard();
    let tests = image.len() * 3;
    let alpha_per_test = 1.0 - (1.0 - alpha).powf(1.0 / tests as f64);
    let mut passed_tests = 0usize;
    let mut p_values = Vec::with_capacity(image.len());
    for i in 0..image.len() {
        let mut p_min = 1.0f64;
        for c in 0..3 {
            let diff = (image[i][c] - reference[i][c]) as f64;
            let var = (image_var[i][c] + reference_var[i][c]) as f64;
            let p = if var > 0.0 {
                2.0 * (1.0 - normal.cdf(diff.abs() / var.sqrt()))
            } else if diff.abs() <= 1e-5 * (reference[i][c].abs() as f64).max(1e-3) {
                1.0
            } else {
                0.0
            };
            if p > alpha_per_test {
                passed_tests += 1;
            }
            p_min = p_min.min(p);
        }
        p_values.push(p_min as f32);
    }
    let pass_fraction = passed_tests as f64 / tests as f64;
    let mut mean_p_value = 1.0f64;
    for c in 0..3 {
        let diff: f64 = image.iter().zip(reference).map(|(a, b)| (a[c] - b[c]) as f64).sum();
        let var: f64 = image_var.iter().zip(reference_var).map(|(a, b)| (a[c] + b[c]) as f64).sum();
        let p = if var > 0.0 { 2.0 * (1.0 - normal.cdf(diff.abs() / var.sqrt())) } else { 1.0 };
        mean_p_value = mean_p_value.min(p);
    }
    let alpha_mean = 1.0 - (1.0 - alpha).powf(1.0 / 3.0);
    ZTestReport {
        pass_fraction,
        alpha_per_test,
        p_values,
        tests,
        mean_p_value,
        passed: pass_fraction >= min_pass_fraction && mean_p_value > alpha_mean,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_means_pass_and_shifted_means_fail() {
        let n = 1000;
        let reference: Vec<Rgb> = (0..n).map(|i| Rgb::splat(1.0 + (i % 7) as f32 * 0.1)).collect();
        let var = vec![Rgb::splat(1e-4); n];
        // Deterministic "noise" of about one standard deviation (0.014).
        let noisy: Vec<Rgb> = reference.iter().enumerate().map(|(i, r)| *r + Rgb::splat(((i as f32 * 0.618).fract() - 0.5) * 0.02)).collect();
        assert!(compare(&noisy, &var, &reference, &var, 0.01, 0.9975).passed);
        let biased: Vec<Rgb> = noisy.iter().map(|p| *p * 1.2).collect();
        let report = compare(&biased, &var, &reference, &var, 0.01, 0.9975);
        assert!(!report.passed, "{}", report.pass_fraction);
    }
}
