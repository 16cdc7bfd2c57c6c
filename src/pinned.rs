//! Pinned images: the exact render of a test (its scene, sample count and seed), committed
//! as `tests/references/pinned/NAME.exr`. A statistical regression test cannot see a change
//! smaller than its noise (a BSDF's value scaled by 5 % passes a 64-spp Z-test); a render
//! with the same seed can: the renderer is deterministic for a seed whatever the thread
//! count, so an unchanged renderer gives the same image up to the last bits, and a refactoring
//! slip shows as a difference of the size of the change. The measure is the mean relative
//! pixel difference, [`relative_difference`]; it tolerates the rare path that a
//! different CPU's rounding sends another way (a few pixels), not a scaled BSDF value over
//! the part of the image it covers. `BLESS=1` rewrites the pinned image, on purpose.

use crate::Rendered;
use renderer::formats::image_io::{read_image, write_exr};
use renderer::Rgb;
use std::path::PathBuf;

/// The largest [`relative_difference`] a pinned image may show: a 2 % change of a BSDF's
/// value over a third of the image gives about three times this.
pub const TOLERANCE: f64 = 2e-3;

fn path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/references/pinned").join(format!("{name}.exr"))
}

/// Mean over pixel channels of |a − b| / max(|b|, floor), with the floor 1 % of the
/// reference's mean (dark pixels do not dominate).
pub fn relative_difference(image: &[Rgb], reference: &[Rgb]) -> f64 {
    assert_eq!(image.len(), reference.len(), "image sizes differ");
    let n = (reference.len() * 3) as f64;
    let mean: f64 = reference.iter().flat_map(|p| p.to_array()).map(|c| c.abs() as f64).sum::<f64>() / n;
    let floor = (0.01 * mean).max(1e-6);
    let sum: f64 = image
        .iter()
        .zip(reference)
        .flat_map(|(a, b)| (0..3).map(move |c| (a[c] as f64, b[c] as f64)))
        .map(|(a, b)| (a - b).abs() / b.abs().max(floor))
        .sum();
    sum / n
}

/// Compares `img` with the pinned image `NAME` (writing it first under `BLESS`) and panics
/// with the measured difference when it exceeds [`TOLERANCE`].
pub fn check(name: &str, img: &Rendered) {
    let path = path(name);
    if std::env::var_os("BLESS").is_some() {
        std::fs::create_dir_all(path.parent().expect("pinned directory")).expect("pinned directory");
        write_exr(&path, img.width, img.height, &img.mean).expect("write pinned image");
    }
    let (w, h, reference) = read_image(&path).unwrap_or_else(|e| panic!("pinned image {name}: {e}"));
    assert_eq!((w, h), (img.width, img.height), "pinned image {name}: size");
    let d = relative_difference(&img.mean, &reference);
    if d > 0.0 {
        eprintln!("pinned image {name}: mean relative difference {d:e} (not bit for bit)");
    }
    assert!(
        d <= TOLERANCE,
        "pinned image {name}: mean relative difference {:.3} % (tolerance {:.2} %); the renderer's output changed for the same seed. If that is meant, re-bless with BLESS=1 (tests/README.md)",
        100.0 * d,
        100.0 * TOLERANCE
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_two_percent_scale_of_a_third_of_the_image_exceeds_the_tolerance() {
        let reference: Vec<Rgb> = (0..300).map(|i| Rgb::splat(0.1 + (i % 13) as f32 * 0.05)).collect();
        assert_eq!(relative_difference(&reference, &reference), 0.0);
        let scaled: Vec<Rgb> = reference.iter().enumerate().map(|(i, p)| if i % 3 == 0 { *p * 1.02 } else { *p }).collect();
        assert!(relative_difference(&scaled, &reference) > 3.0 * TOLERANCE);
    }
}
