//! Regression images: a render at few samples per pixel compared with a committed reference
//! (mean and variance-of-the-mean EXR images under `tests/references/`) by per-pixel Z-tests
//! (see [`crate::ztest`]). `BLESS=1` re-renders the reference first, on purpose.

use crate::{ztest, Rendered};
use renderer::formats::image_io::{read_image, write_exr};
use renderer::Rgb;
use std::path::{Path, PathBuf};

/// One regression case.
pub struct Case {
    /// File stem of the reference (`tests/references/NAME.exr`, `NAME.variance.exr`) and of
    /// the failure directory `target/regression-failures/NAME/`.
    pub name: &'static str,
    /// Samples per pixel of the test render and of the reference.
    pub test_spp: u32,
    pub reference_spp: u32,
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

impl Case {
    fn reference_paths(&self) -> (PathBuf, PathBuf) {
        let refs = root().join("tests/references");
        (refs.join(format!("{}.exr", self.name)), refs.join(format!("{}.variance.exr", self.name)))
    }

    /// Z-test of `img` (rendered at `test_spp`) against the committed reference; returns the
    /// report and the reference image. The test image's variance is the reference's
    /// per-sample variance scaled to `test_spp` (same estimator, fewer samples): few samples
    /// alone estimate it poorly where values are heavy-tailed.
    pub fn compare(&self, img: &Rendered) -> (ztest::ZTestReport, Vec<Rgb>) {
        let (mean_path, var_path) = self.reference_paths();
        let (w, h, reference) = read_image(&mean_path).expect("reference image");
        assert_eq!((w, h), (img.width, img.height), "reference size");
        let (_, _, reference_var) = read_image(&var_path).expect("reference variance");
        let scale = self.reference_spp as f32 / self.test_spp as f32;
        let image_var: Vec<Rgb> = reference_var.iter().map(|v| *v * scale).collect();
        let report = ztest::compare(&img.mean, &image_var, &reference, &reference_var, 0.01, 0.9975);
        (report, reference)
    }

    /// The regression test: with `BLESS` set, renders and writes the reference first
    /// (`render(reference_spp, 12345)`); then renders `render(test_spp, 7)` and panics with
    /// the metric, writing image, reference, error and p-value images, when it fails. The
    /// test render is also a pinned image (see [`crate::pinned`]), which sees changes far
    /// below the statistical test's noise.
    pub fn check(&self, render: impl Fn(u32, u64) -> Rendered) {
        if std::env::var_os("BLESS").is_some() {
            let (mean_path, var_path) = self.reference_paths();
            let reference = render(self.reference_spp, 12345);
            write_exr(&mean_path, reference.width, reference.height, &reference.mean).expect("write reference");
            write_exr(&var_path, reference.width, reference.height, &reference.variance).expect("write variance");
        }
        let img = render(self.test_spp, 7);
        let (report, reference) = self.compare(&img);
        if !report.passed {
            let dir = root().join("target/regression-failures").join(self.name);
            write_failure_images(&dir, &img, &reference, &report);
            panic!(
                "{}: {:.4} % of {} pixel channels pass (need 99.75 %), image-mean p = {:.2e}; images in {}",
                self.name,
                100.0 * report.pass_fraction,
                report.tests,
                report.mean_p_value,
                dir.display()
            );
        }
        crate::pinned::check(self.name, &img);
    }
}

fn write_failure_images(dir: &Path, img: &Rendered, reference: &[Rgb], report: &ztest::ZTestReport) {
    std::fs::create_dir_all(dir).expect("failure directory");
    let error: Vec<Rgb> = img.mean.iter().zip(reference).map(|(a, b)| (*a - *b).abs()).collect();
    let p: Vec<Rgb> = report.p_values.iter().map(|&p| Rgb::splat(p)).collect();
    for (name, px) in [("image", &img.mean), ("reference", &reference.to_vec()), ("error", &error), ("p-value", &p)] {
        write_exr(&dir.join(format!("{name}.exr")), img.width, img.height, px).expect("write failure image");
    }
}
