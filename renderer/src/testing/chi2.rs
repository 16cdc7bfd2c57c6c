//! Statistical checks of BSDF implementations, meant for unit and integration tests of any
//! [`Bxdf`] (analytic, measured or neural):
//!
//! - [`test_bxdf`] / [`test_sampler`]: a chi-square goodness-of-fit test of a sampler against
//!   its claimed density, after Mitsuba 3's `ChiSquareTest` (`mitsuba/python/chi2.py`);
//! - [`check_sample_consistency`]: `sample` agrees with `eval` and `pdf`, and is finite.
//!
//! # The chi-square test
//! The sphere of directions is cut into `theta_cells × phi_cells` cells of a grid over
//! (cos θ, φ) (equal solid angle per cell, Mitsuba's spherical domain) or over (θ, φ)
//! ([`Chi2Domain`]); θ is measured from the local +z axis, φ ∈ [−π, π) from +x, and the
//! horizon (θ = π/2) is always a cell boundary. `sample_count` directions are drawn with a
//! seeded [`Pcg32`] and binned (the observed counts). The expected count of a cell is
//! `sample_count` times the integral of the pdf over the cell, computed in (θ, φ) by composite
//! Simpson's rule refined per cell (8, 16, 32, … sub-intervals per axis) until the change is
//! a small fraction of the cell's Poisson standard deviation. Cells are sorted by expected
//! count and those expected below `min_expected_count` (5) are pooled, exactly as Mitsuba's
//! `chi2` helper does; the statistic Σ (O − E)² / E with (cells − 1) degrees of freedom gives
//! the p-value. The null hypothesis ("the sampler draws from the pdf") is rejected when p is
//! below the Šidák-corrected significance 1 − (1 − `significance`)^(1 / `test_count`), with
//! `test_count` the number of chi-square tests in the family being run.
//!
//! Beyond the statistic the test fails when: a sample is not a finite unit vector; samples
//! land where the pdf integrates to zero; the pdf is negative or non-finite somewhere; the
//! pdf integrates to more than 1 + `pdf_integral_tolerance` over the sphere; or there are
//! too few degrees of freedom. Calls of the sampler that return `None` are lost samples: the
//! pdf must then integrate to less than 1 by the same fraction (checked cell by cell).
//!
//! # Example
//! ```
//! use glam::Vec3;
//! use renderer::bsdf::Lambert;
//! use renderer::testing::chi2::{self, Chi2Config};
//! use renderer::Rgb;
//!
//! let config = Chi2Config::default().with_sample_count(100_000);
//! let result = chi2::test_bxdf(&Lambert::new(Rgb::splat(0.5)), Vec3::Z, &config);
//! assert!(result.passed(), "{result}");
//! ```

use crate::bsdf::Bxdf;
use glam::{Vec2, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use statrs::distribution::{ChiSquared, ContinuousCDF};
use std::f64::consts::PI;
use std::fmt::{self, Write as _};


/// Parameterisation of the sphere on which the chi-square grid is laid out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Chi2Domain {
    /// Cells uniform in (cos θ ∈ [−1, 1], φ): every cell subtends the same solid angle
    /// (Mitsuba's `SphericalDomain`). The default.
    CosThetaPhi,
    /// Cells uniform in (θ ∈ [0, π], φ): smaller cells near the poles, which resolves lobes
    /// peaked around the normal better.
    ThetaPhi,
}

impl Chi2Domain {
    /// θ in radians at the normalised row coordinate t ∈ [0, 1] (t = 0 is +z).
    fn theta(self, t: f64) -> f64 {
        match self {
            Chi2Domain::CosThetaPhi => (1.0 - 2.0 * t).clamp(-1.0, 1.0).acos(),
            Chi2Domain::ThetaPhi => PI * t,
        }
    }

    /// The unit direction at normalised coordinates (s, t) ∈ [0, 1]²: φ = 2π s − π.
    fn direction(self, s: f64, t: f64) -> Vec3 {
        let phi = 2.0 * PI * s - PI;
        let (sin_theta, cos_theta) = self.theta(t).sin_cos();
        Vec3::new(
            (sin_theta * phi.cos()) as f32,
            (sin_theta * phi.sin()) as f32,
            cos_theta as f32,
        )
    }

    /// Normalised coordinates (s, t) ∈ [0, 1]² of a unit direction.
    fn coordinates(self, w: Vec3) -> (f64, f64) {
        let (x, y, z) = (w.x as f64, w.y as f64, (w.z as f64).clamp(-1.0, 1.0));
        let s = (y.atan2(x) + PI) / (2.0 * PI);
        let t = match self {
            Chi2Domain::CosThetaPhi => 0.5 * (1.0 - z),
            Chi2Domain::ThetaPhi => z.acos() / PI,
        };
        (s, t)
    }
}

/// Parameters of [`test_bxdf`] and [`test_sampler`]. The defaults follow Mitsuba 3's
/// `ChiSquareTest` (10⁶ samples, a grid of about 101 × 32 cells over (φ, cos θ), pooling
/// below 5 expected samples, significance 0.01).
#[derive(Clone, Debug, PartialEq)]
pub struct Chi2Config {
    /// Number of calls of the sampler (default 1,000,000). Fewer samples make faster but
    /// weaker tests; keep the mean expected count per populated cell above ~50.
    pub sample_count: usize,
    /// Cells along θ over the whole sphere (default 32); rounded up to an even number (at
    /// least 2) so that the horizon is a cell boundary.
    pub theta_cells: usize,
    /// Cells along φ (default 100, so φ = 0, ±π/2 are cell boundaries); at least 1.
    pub phi_cells: usize,
    /// How the grid is laid over the sphere (default [`Chi2Domain::CosThetaPhi`]).
    pub domain: Chi2Domain,
    /// Significance level of the whole family of tests (default 0.01).
    pub significance: f64,
    /// Number of chi-square tests in the family, for the Šidák correction (default 1).
    pub test_count: usize,
    /// Cells expected to receive fewer samples than this are pooled (default 5).
    pub min_expected_count: f64,
    /// Seed of the [`Pcg32`] that draws the samples (default 0).
    pub seed: u64,
    /// How much the pdf may integrate above 1 over the sphere (default 10⁻³), absorbing
    /// quadrature and f32 rounding errors.
    pub pdf_integral_tolerance: f64,
    /// A cell's integral is refined until successive estimates of its expected count differ
    /// by less than this fraction of its Poisson standard deviation √E (default 0.01).
    pub integration_tolerance: f64,
    /// Most Simpson sub-intervals per cell and axis (default 128); the refinement starts at 8
    /// and doubles.
    pub max_subdivisions: usize,
}

impl Default for Chi2Config {
    fn default() -> Self {
        Chi2Config {
            sample_count: 1_000_000,
            theta_cells: 32,
            phi_cells: 100,
            domain: Chi2Domain::CosThetaPhi,
            significance: 0.01,
            test_count: 1,
            min_expected_count: 5.0,
            seed: 0,
            pdf_integral_tolerance: 1e-3,
            integration_tolerance: 0.01,
            max_subdivisions: 128,
        }
    }
}

impl Chi2Config {
    /// Sets [`Chi2Config::sample_count`].
    pub fn with_sample_count(mut self, sample_count: usize) -> Self {
        self.sample_count = sample_count;
        self
    }

    /// Sets [`Chi2Config::test_count`], the number of tests in the family (Šidák).
    pub fn with_test_count(mut self, test_count: usize) -> Self {
        self.test_count = test_count;
        self
    }

    /// Sets the grid resolution ([`Chi2Config::theta_cells`], [`Chi2Config::phi_cells`]).
    pub fn with_resolution(mut self, theta_cells: usize, phi_cells: usize) -> Self {
        self.theta_cells = theta_cells;
        self.phi_cells = phi_cells;
        self
    }

    /// Sets [`Chi2Config::domain`].
    pub fn with_domain(mut self, domain: Chi2Domain) -> Self {
        self.domain = domain;
        self
    }

    /// Sets [`Chi2Config::seed`].
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// The per-test significance after the Šidák correction:
    /// 1 − (1 − significance)^(1 / test_count).
    pub fn corrected_significance(&self) -> f64 {
        let k = self.test_count.max(1) as f64;
        -((-self.significance.clamp(0.0, 1.0)).ln_1p() / k).exp_m1()
    }
}

/// Outcome of a chi-square test, with the tables needed to diagnose a failure. Its
/// [`fmt::Display`] prints [`Chi2Result::report`].
#[derive(Clone, Debug)]
pub struct Chi2Result {
    /// The pooled chi-square statistic Σ (O − E)² / E.
    pub statistic: f64,
    /// Degrees of freedom: the number of (pooled) cells minus one.
    pub degrees_of_freedom: usize,
    /// Probability of a statistic at least this large if the sampler matched the pdf
    /// (NaN when it could not be computed).
    pub p_value: f64,
    /// The Šidák-corrected significance the p-value was compared with.
    pub threshold: f64,
    /// ∫ pdf dω over the sphere (at most 1; less when the sampler may fail).
    pub pdf_integral: f64,
    /// Number of calls of the sampler.
    pub sample_count: usize,
    /// Calls that returned `None`.
    pub failed_samples: usize,
    /// Calls that returned a non-finite or non-unit direction (any makes the test fail).
    pub invalid_samples: usize,
    /// Number of cells merged into pooled cells.
    pub pooled_cells: usize,
    /// Why the test failed; empty when it passed.
    pub problems: Vec<String>,
    /// Grid layout of [`Chi2Result::observed`] and [`Chi2Result::expected`].
    pub domain: Chi2Domain,
    /// Rows of the grid (θ), row 0 around +z.
    pub theta_cells: usize,
    /// Columns of the grid (φ from −π).
    pub phi_cells: usize,
    /// Observed counts, row-major (index = φ cell + phi_cells · θ cell).
    pub observed: Vec<f64>,
    /// Expected counts, same layout as [`Chi2Result::observed`].
    pub expected: Vec<f64>,
}

/// Characters of the density maps, from empty to the maximum.
const DENSITY_RAMP: &[u8] = b" .:-=+*#%@";

impl Chi2Result {
    /// True when no problem was found (in particular p ≥ the corrected significance).
    pub fn passed(&self) -> bool {
        self.problems.is_empty()
    }

    /// One paragraph: verdict, statistic, p-value, pdf integral, sample counts, problems.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "chi-square test {}: statistic {:.2}, {} degrees of freedom, p = {:.3e} \
             (threshold {:.3e}); pdf integral {:.5}; {} samples, {} failed ({:.5} of all), \
             {} invalid; {} cells pooled",
            if self.passed() { "passed" } else { "FAILED" },
            self.statistic,
            self.degrees_of_freedom,
            self.p_value,
            self.threshold,
            self.pdf_integral,
            self.sample_count,
            self.failed_samples,
            self.failed_samples as f64 / self.sample_count.max(1) as f64,
            self.invalid_samples,
            self.pooled_cells,
        );
        for p in &self.problems {
            let _ = write!(s, "\n  - {p}");
        }
        s
    }

    /// θ range of row `row` in degrees.
    fn row_range_degrees(&self, row: usize) -> (f64, f64) {
        let n = self.theta_cells as f64;
        (
            self.domain.theta(row as f64 / n).to_degrees(),
            self.domain.theta((row + 1) as f64 / n).to_degrees(),
        )
    }

    /// φ range of column `column` in degrees.
    fn column_range_degrees(&self, column: usize) -> (f64, f64) {
        let n = self.phi_cells as f64;
        (
            360.0 * column as f64 / n - 180.0,
            360.0 * (column + 1) as f64 / n - 180.0,
        )
    }

    fn map(&self, title: &str, cell: impl Fn(usize) -> u8) -> String {
        let mut s = format!("{title}\n");
        for row in 0..self.theta_cells {
            let (t0, t1) = self.row_range_degrees(row);
            let _ = write!(s, "θ {t0:6.1}–{t1:6.1}° |");
            s.extend((0..self.phi_cells).map(|c| cell(c + self.phi_cells * row) as char));
            s.push_str("|\n");
        }
        s
    }

    /// Maps of `values` on the ramp " .:-=+*#%@", scaled to `max`; non-zero values show at
    /// least '.'.
    fn density_map(&self, title: &str, values: &[f64], max: f64) -> String {
        let top = (DENSITY_RAMP.len() - 1) as f64;
        self.map(title, |i| {
            let v = values[i];
            if v <= 0.0 || max <= 0.0 {
                DENSITY_RAMP[0]
            } else {
                DENSITY_RAMP[((v / max * top).ceil() as usize).clamp(1, DENSITY_RAMP.len() - 1)]
            }
        })
    }

    /// ASCII map of the observed counts (rows θ from +z, columns φ from −π), on the same
    /// scale as [`Chi2Result::expected_map`].
    pub fn observed_map(&self) -> String {
        self.density_map(
            "observed counts (rows θ, columns φ from -180°):",
            &self.observed,
            self.map_scale(),
        )
    }

    /// ASCII map of the expected counts, on the same scale as [`Chi2Result::observed_map`].
    pub fn expected_map(&self) -> String {
        self.density_map("expected counts:", &self.expected, self.map_scale())
    }

    fn map_scale(&self) -> f64 {
        self.observed
            .iter()
            .chain(&self.expected)
            .fold(0.0f64, |m, &v| m.max(v))
    }

    /// ASCII map of the residuals z = (O − E) / √E per cell: ' ' nothing expected or seen,
    /// '.' |z| < 2, '+' 2 ≤ z < 4, '#' z ≥ 4 (too many samples), '-' −4 < z ≤ −2,
    /// '=' z ≤ −4 (too few), '!' samples where nothing is expected.
    pub fn residual_map(&self) -> String {
        self.map(
            "residuals (O-E)/sqrt(E): '.' <2, '+'/'#' excess >=2/>=4, '-'/'=' deficit, \
             '!' unexpected samples:",
            |i| {
                let (o, e) = (self.observed[i], self.expected[i]);
                if e <= 0.0 {
                    return if o > 0.0 { b'!' } else { b' ' };
                }
                let z = (o - e) / e.sqrt();
                match z {
                    z if z >= 4.0 => b'#',
                    z if z >= 2.0 => b'+',
                    z if z <= -4.0 => b'=',
                    z if z <= -2.0 => b'-',
                    _ => b'.',
                }
            },
        )
    }

    /// A table of the `count` cells with the largest (O − E)² / E.
    pub fn worst_cells(&self, count: usize) -> String {
        let contribution = |i: usize| {
            let (o, e) = (self.observed[i], self.expected[i]);
            if e > 0.0 {
                (o - e) * (o - e) / e
            } else if o > 0.0 {
                f64::INFINITY
            } else {
                0.0
            }
        };
        let mut cells: Vec<usize> = (0..self.observed.len()).collect();
        cells.sort_by(|&a, &b| contribution(b).total_cmp(&contribution(a)));
        let mut s = String::from(
            "worst cells:   θ range (°)      φ range (°)    observed    expected   (O-E)²/E\n",
        );
        for &i in cells.iter().take(count) {
            let (row, column) = (i / self.phi_cells, i % self.phi_cells);
            let (t0, t1) = self.row_range_degrees(row);
            let (p0, p1) = self.column_range_degrees(column);
            let _ = writeln!(
                s,
                "  {t0:6.1}–{t1:6.1}  {p0:7.1}–{p1:7.1}  {:10.0}  {:10.2}  {:9.2}",
                self.observed[i],
                self.expected[i],
                contribution(i)
            );
        }
        s
    }

    /// Summary, the three maps and the ten worst cells.
    pub fn report(&self) -> String {
        format!(
            "{}\n{}{}{}{}",
            self.summary(),
            self.observed_map(),
            self.expected_map(),
            self.residual_map(),
            self.worst_cells(10)
        )
    }
}

impl fmt::Display for Chi2Result {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.report())
    }
}

/// Chi-square test of `bxdf.sample(wo, ·, ·)` against `bxdf.pdf(wo, ·)` for one outgoing
/// direction `wo` (local frame, unit vector); samples of delta lobes count as lost (the
/// density must miss their probability). See the [module documentation](self).
pub fn test_bxdf<B: Bxdf + ?Sized>(bxdf: &B, wo: Vec3, config: &Chi2Config) -> Chi2Result {
    test_sampler(
        // Delta samples are outside the density's support: lost samples to this test.
        |u, uc| bxdf.sample(wo, u, uc).filter(|s| !s.delta).map(|s| s.wi),
        |wi| bxdf.pdf(wo, wi),
        config,
    )
}

/// Chi-square test of any direction sampler against its density: `sample(u, uc)` maps a 2D
/// sample u ∈ [0, 1)² and a 1D sample uc ∈ [0, 1) to a unit direction (or `None`, a lost
/// sample) and `pdf(w)` is its claimed density in 1/sr. Useful for warps and microfacet
/// normal samplers that are not a [`Bxdf`]. See the [module documentation](self).
pub fn test_sampler<S, P>(mut sample: S, pdf: P, config: &Chi2Config) -> Chi2Result
where
    S: FnMut(Vec2, f32) -> Option<Vec3>,
    P: Fn(Vec3) -> f32,
{
    let theta_cells = config.theta_cells.max(2).next_multiple_of(2);
    let phi_cells = config.phi_cells.max(1);
    let domain = config.domain;
    let n = config.sample_count;
    let mut problems = Vec::new();

    // Observed counts.
    let mut observed = vec![0.0f64; theta_cells * phi_cells];
    let mut rng = Pcg32::seed_from_u64(config.seed);
    let (mut failed_samples, mut invalid_samples) = (0usize, 0usize);
    for _ in 0..n {
        let u = Vec2::new(rng.random(), rng.random());
        let uc: f32 = rng.random();
        match sample(u, uc) {
            None => failed_samples += 1,
            Some(w) if !w.is_finite() || (w.length() - 1.0).abs() > 1e-3 => {
                if invalid_samples == 0 {
                    problems.push(format!(
                        "the sampler returned a non-unit or non-finite direction {w} \
                         (u = {u}, uc = {uc}); more may follow"
                    ));
                }
                invalid_samples += 1;
            }
            Some(w) => {
                let (s, t) = domain.coordinates(w);
                let column = ((s * phi_cells as f64) as usize).min(phi_cells - 1);
                let row = ((t * theta_cells as f64) as usize).min(theta_cells - 1);
                observed[column + phi_cells * row] += 1.0;
            }
        }
    }
    if invalid_samples > 0 {
        problems.push(format!("{invalid_samples} invalid samples in all"));
    }

    // Expected counts.
    let mut integrator = CellIntegrator {
        pdf: &pdf,
        sample_count: n as f64,
        tolerance: config.integration_tolerance,
        max_subdivisions: config.max_subdivisions.max(8),
        bad_value: None,
    };
    let mut expected = vec![0.0f64; theta_cells * phi_cells];
    for row in 0..theta_cells {
        for column in 0..phi_cells {
            let theta = (
                domain.theta(row as f64 / theta_cells as f64),
                domain.theta((row + 1) as f64 / theta_cells as f64),
            );
            let phi = (
                2.0 * PI * column as f64 / phi_cells as f64 - PI,
                2.0 * PI * (column + 1) as f64 / phi_cells as f64 - PI,
            );
            expected[column + phi_cells * row] = n as f64 * integrator.integrate(theta, phi);
        }
    }
    if let Some((w, value)) = integrator.bad_value {
        problems.push(format!(
            "the pdf is negative or not finite: pdf({w}) = {value}"
        ));
    }
    let pdf_integral = if n > 0 {
        expected.iter().sum::<f64>() / n as f64
    } else {
        0.0
    };
    if pdf_integral.is_nan() || pdf_integral > 1.0 + config.pdf_integral_tolerance {
        problems.push(format!(
            "the pdf integrates to {pdf_integral:.6} > 1 over the sphere"
        ));
    }
    let unexpected: Vec<usize> = (0..expected.len())
        .filter(|&i| expected[i] <= 0.0 && observed[i] > 0.0)
        .collect();
    if let Some(&first) = unexpected.first() {
        let total: f64 = unexpected.iter().map(|&i| observed[i]).sum();
        let w = domain.direction(
            ((first % phi_cells) as f64 + 0.5) / phi_cells as f64,
            ((first / phi_cells) as f64 + 0.5) / theta_cells as f64,
        );
        problems.push(format!(
            "{total} samples landed in {} cells where the pdf integrates to zero \
             (e.g. the cell around {w})",
            unexpected.len()
        ));
    }

    // Pooled statistic (Mitsuba's `chi2`): cells in increasing order of expected count.
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let pooled = pooled_chi_square(
        order.iter().map(|&i| (observed[i], expected[i])),
        config.min_expected_count,
    );
    let threshold = config.corrected_significance();
    let p_value = if pooled.degrees_of_freedom < 1 {
        problems.push(format!(
            "too few degrees of freedom ({}): use more samples or cells",
            pooled.degrees_of_freedom
        ));
        f64::NAN
    } else {
        match ChiSquared::new(pooled.degrees_of_freedom as f64) {
            Ok(distribution) => distribution.sf(pooled.statistic),
            Err(e) => {
                problems.push(format!("chi-square distribution unavailable: {e}"));
                f64::NAN
            }
        }
    };
    if pooled.degrees_of_freedom >= 1 && (p_value.is_nan() || p_value < threshold) {
        problems.push(format!(
            "the samples do not follow the pdf: p = {p_value:.3e} < {threshold:.3e}"
        ));
    }

    Chi2Result {
        statistic: pooled.statistic,
        degrees_of_freedom: pooled.degrees_of_freedom,
        p_value,
        threshold,
        pdf_integral,
        sample_count: n,
        failed_samples,
        invalid_samples,
        pooled_cells: pooled.pooled_in,
        problems,
        domain,
        theta_cells,
        phi_cells,
        observed,
        expected,
    }
}

/// Result of [`pooled_chi_square`].
struct PooledChiSquare {
    statistic: f64,
    degrees_of_freedom: usize,
    pooled_in: usize,
}

/// Σ (O − E)² / E over (observed, expected) pairs given in increasing order of E; cells
/// with nothing expected and nothing observed are skipped, consecutive cells expected below
/// `threshold` are merged until their pool reaches it (Mitsuba's `chi2` in
/// `src/core/python/...`/`util.chi2`).
fn pooled_chi_square(cells: impl Iterator<Item = (f64, f64)>, threshold: f64) -> PooledChiSquare {
    let (mut statistic, mut cell_count, mut pooled_in) = (0.0f64, 0usize, 0usize);
    let (mut pool_observed, mut pool_expected) = (0.0f64, 0.0f64);
    let term = |o: f64, e: f64| {
        if e > 0.0 {
            (o - e) * (o - e) / e
        } else {
            f64::INFINITY
        }
    };
    for (o, e) in cells {
        if e <= 0.0 && o <= 0.0 {
            continue;
        }
        if e < threshold {
            pool_observed += o;
            pool_expected += e;
            pooled_in += 1;
            if pool_expected > threshold {
                statistic += term(pool_observed, pool_expected);
                cell_count += 1;
                pool_observed = 0.0;
                pool_expected = 0.0;
            }
        } else {
            statistic += term(o, e);
            cell_count += 1;
        }
    }
    if pool_observed > 0.0 || pool_expected > 0.0 {
        statistic += term(pool_observed, pool_expected);
        cell_count += 1;
    }
    PooledChiSquare {
        statistic,
        degrees_of_freedom: cell_count.saturating_sub(1),
        pooled_in,
    }
}

/// Integrates a pdf over grid cells with refined composite Simpson rules.
///
/// Whatever the grid's domain, each cell is integrated in (θ, φ) with dω = sin θ dθ dφ:
/// the integrand is then smooth at the poles, where in cos θ it would have a square-root
/// singularity that slows Simpson's rule down.
struct CellIntegrator<'a, P> {
    pdf: &'a P,
    sample_count: f64,
    tolerance: f64,
    max_subdivisions: usize,
    /// First direction where the pdf was negative or not finite, with the value.
    bad_value: Option<(Vec3, f32)>,
}

impl<P: Fn(Vec3) -> f32> CellIntegrator<'_, P> {
    /// ∫ pdf dω over θ ∈ [theta.0, theta.1], φ ∈ [phi.0, phi.1] (radians), refining from 8
    /// sub-intervals per axis until the expected count changes by less than
    /// `tolerance` · √E or `max_subdivisions` is reached.
    fn integrate(&mut self, theta: (f64, f64), phi: (f64, f64)) -> f64 {
        let mut subdivisions = 8;
        let mut previous = self.simpson(theta, phi, subdivisions);
        while subdivisions < self.max_subdivisions {
            subdivisions *= 2;
            let current = self.simpson(theta, phi, subdivisions);
            let count = self.sample_count * current;
            let change = self.sample_count * (current - previous).abs();
            previous = current;
            if change <= self.tolerance * count.max(1.0).sqrt() {
                break;
            }
        }
        previous
    }

    /// Composite Simpson's rule with `n` (even) sub-intervals per axis.
    fn simpson(&mut self, theta: (f64, f64), phi: (f64, f64), n: usize) -> f64 {
        let weight = |i: usize| match i {
            0 => 1.0,
            i if i == n => 1.0,
            i if i % 2 == 1 => 4.0,
            _ => 2.0,
        };
        let (d_theta, d_phi) = ((theta.1 - theta.0) / n as f64, (phi.1 - phi.0) / n as f64);
        let mut sum = 0.0f64;
        for j in 0..=n {
            let (sin_theta, cos_theta) = (theta.0 + d_theta * j as f64).sin_cos();
            let mut row = 0.0f64;
            for i in 0..=n {
                let (sin_phi, cos_phi) = (phi.0 + d_phi * i as f64).sin_cos();
                let w = Vec3::new(
                    (sin_theta * cos_phi) as f32,
                    (sin_theta * sin_phi) as f32,
                    cos_theta as f32,
                );
                let value = (self.pdf)(w);
                if !(value >= 0.0 && value.is_finite()) {
                    self.bad_value.get_or_insert((w, value));
                    continue;
                }
                row += weight(i) * value as f64;
            }
            sum += weight(j) * sin_theta * row;
        }
        sum * d_theta * d_phi / 9.0
    }
}

/// Seed of the directions drawn by [`check_sample_consistency`].
const CONSISTENCY_SEED: u64 = 0x05ee_da1b_ed00 ^ 1;

/// Most problems listed individually by [`ConsistencyReport`].
const MAX_LISTED_PROBLEMS: usize = 10;

/// Outcome of [`check_sample_consistency`]; its [`fmt::Display`] lists the problems.
#[derive(Clone, Debug, Default)]
pub struct ConsistencyReport {
    /// Number of calls of `sample`.
    pub samples: usize,
    /// Calls that returned a direction.
    pub valid: usize,
    /// Number of failed checks in all.
    pub problem_count: usize,
    /// Descriptions of the first failed checks (at most 10).
    pub problems: Vec<String>,
}

impl ConsistencyReport {
    /// True when every returned sample passed every check.
    pub fn passed(&self) -> bool {
        self.problem_count == 0
    }

    fn problem(&mut self, description: String) {
        self.problem_count += 1;
        if self.problems.len() < MAX_LISTED_PROBLEMS {
            self.problems.push(description);
        }
    }
}

impl fmt::Display for ConsistencyReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "sample consistency {}: {} samples, {} returned a direction, {} problems",
            if self.passed() { "passed" } else { "FAILED" },
            self.samples,
            self.valid,
            self.problem_count
        )?;
        for p in &self.problems {
            write!(f, "\n  - {p}")?;
        }
        Ok(())
    }
}

/// |a − b| ≤ 10⁻³ · max(|a|, |b|) + 10⁻⁹.
fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-3 * a.abs().max(b.abs()) + 1e-9
}

/// Draws `n` samples with `bxdf.sample(wo, ·, ·)` (seeded [`Pcg32`]) and checks each returned
/// one: `wi` is a finite unit vector with `wi.z > 0` (or any z ≠ 0 where the BSDF
/// [transmits](Bxdf::transmits)); `pdf` is finite and > 0; `f` is finite and ≥ 0; and, for
/// samples of lobes that are not delta lobes, `f` equals `eval(wo, wi)`, `pdf` equals
/// `pdf(wo, wi)` (relative tolerance 10⁻³) and `eval_pdf` agrees with both. `wo` is a unit
/// vector in the local frame.
pub fn check_sample_consistency<B: Bxdf + ?Sized>(
    bxdf: &B,
    wo: Vec3,
    n: usize,
) -> ConsistencyReport {
    let mut report = ConsistencyReport {
        samples: n,
        ..ConsistencyReport::default()
    };
    let mut rng = Pcg32::seed_from_u64(CONSISTENCY_SEED);
    for _ in 0..n {
        let u = Vec2::new(rng.random(), rng.random());
        let uc: f32 = rng.random();
        let Some(s) = bxdf.sample(wo, u, uc) else {
            continue;
        };
        report.valid += 1;
        let at = format!("wo = {wo}, u = {u}, uc = {uc}, wi = {}", s.wi);
        if !s.wi.is_finite() || (s.wi.length() - 1.0).abs() > 1e-3 {
            report.problem(format!("wi is not a finite unit vector ({at})"));
            continue;
        }
        if s.wi.z <= 0.0 && !bxdf.transmits() {
            report.problem(format!("wi is below the horizon ({at})"));
        }
        if !(s.pdf > 0.0 && s.pdf.is_finite()) {
            report.problem(format!(
                "sample pdf {} is not finite and positive ({at})",
                s.pdf
            ));
        }
        if !(s.f.is_finite() && s.f.min_element() >= 0.0) {
            report.problem(format!(
                "sample f {} is not finite and non-negative ({at})",
                s.f
            ));
        }
        if s.delta {
            continue;
        }
        let f = bxdf.eval(wo, s.wi);
        let pdf = bxdf.pdf(wo, s.wi);
        let (f_joint, pdf_joint) = bxdf.eval_pdf(wo, s.wi);
        if !(0..3).all(|c| close(f[c], s.f[c])) {
            report.problem(format!("sample f {} != eval {f} ({at})", s.f));
        }
        if !close(pdf, s.pdf) {
            report.problem(format!("sample pdf {} != pdf {pdf} ({at})", s.pdf));
        }
        if !(0..3).all(|c| close(f[c], f_joint[c])) || !close(pdf, pdf_joint) {
            report.problem(format!(
                "eval_pdf ({f_joint}, {pdf_joint}) != (eval, pdf) ({f}, {pdf}) ({at})"
            ));
        }
    }
    report
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{BsdfSample, Lambert};
    use crate::sampling::{sample_cosine_hemisphere, sample_uniform_sphere, uniform_sphere_pdf};
    use crate::Rgb;

    /// Number of chi-square tests in this module expected to pass, for the Šidák correction.
    const CHI2_TESTS: usize = 2;

    fn config() -> Chi2Config {
        Chi2Config::default()
            .with_sample_count(200_000)
            .with_test_count(CHI2_TESTS)
    }

    /// Lambert's sampler with a pdf that is deliberately wrong.
    struct WrongPdf {
        inner: Lambert,
        pdf: fn(Vec3) -> f32,
    }

    impl Bxdf for WrongPdf {
        fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
            self.inner.eval(wo, wi)
        }
        fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
            if wo.z <= 0.0 || wi.z <= 0.0 {
                0.0
            } else {
                (self.pdf)(wi)
            }
        }
        fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
            self.inner.sample(wo, u, uc).map(|s| BsdfSample {
                pdf: (self.pdf)(s.wi),
                ..s
            })
        }
    }

    #[test]
    fn uniform_sphere_passes_in_both_domains() {
        for domain in [Chi2Domain::CosThetaPhi, Chi2Domain::ThetaPhi] {
            let result = test_sampler(
                |u, _| Some(sample_uniform_sphere(u)),
                |_| uniform_sphere_pdf(),
                &config().with_domain(domain).with_resolution(17, 40),
            );
            assert_eq!(result.theta_cells, 18);
            assert!(result.passed(), "{domain:?}\n{result}");
            assert!(
                (result.pdf_integral - 1.0).abs() < 1e-4,
                "{}",
                result.pdf_integral
            );
            assert_eq!(result.failed_samples, 0);
        }
    }

    #[test]
    fn scaled_pdf_fails() {
        let b = WrongPdf {
            inner: Lambert::new(Rgb::ONE),
            pdf: |wi| 1.2 * wi.z * std::f32::consts::FRAC_1_PI,
        };
        let result = test_bxdf(&b, Vec3::Z, &config());
        assert!(!result.passed(), "{result}");
        assert!(result.pdf_integral > 1.19, "{}", result.pdf_integral);
        assert!(result.p_value < result.threshold);
        // The same BSDF fails the sample/pdf consistency check only if sample and pdf
        // disagree, which they do not here: the check is no substitute for the chi2 test.
        assert!(check_sample_consistency(&b, Vec3::Z, 100).passed());
    }

    #[test]
    fn skewed_pdf_fails() {
        // Cosine-weighted samples claimed to be uniform on the hemisphere: the pdf still
        // integrates to 1, so only the statistic can catch it.
        let b = WrongPdf {
            inner: Lambert::new(Rgb::ONE),
            pdf: |_| 0.5 * std::f32::consts::FRAC_1_PI,
        };
        let result = test_bxdf(&b, Vec3::Z, &config());
        assert!(!result.passed(), "{result}");
        assert!(
            (result.pdf_integral - 1.0).abs() < 1e-3,
            "{}",
            result.pdf_integral
        );
        assert!(result.p_value < result.threshold);
        assert!(result.residual_map().contains('#'));
    }

    #[test]
    fn samples_outside_the_pdf_support_fail() {
        let result = test_sampler(
            |u, _| Some(sample_uniform_sphere(u)),
            |w| {
                if w.z > 0.0 {
                    2.0 * uniform_sphere_pdf()
                } else {
                    0.0
                }
            },
            &config(),
        );
        assert!(!result.passed());
        assert!(result.residual_map().contains('!'));
        assert!(result
            .problems
            .iter()
            .any(|p| p.contains("integrates to zero")));
    }

    #[test]
    fn invalid_samples_fail() {
        let result = test_sampler(|_, _| Some(Vec3::new(0.0, 0.0, 2.0)), |_| 0.1, &config());
        assert!(!result.passed());
        assert_eq!(result.invalid_samples, result.sample_count);
    }

    #[test]
    fn lost_samples_are_accounted_for() {
        // A sampler that gives up half of the time, with a pdf that integrates to 1/2.
        let result = test_sampler(
            |u, uc| (uc < 0.5).then(|| sample_cosine_hemisphere(u)),
            |w| 0.5 * w.z.max(0.0) * std::f32::consts::FRAC_1_PI,
            &config(),
        );
        assert!(result.passed(), "{result}");
        assert!((result.pdf_integral - 0.5).abs() < 1e-4);
    }

    #[test]
    fn report_has_maps_and_table() {
        let result = test_bxdf(&Lambert::new(Rgb::ONE), Vec3::Z, &config());
        let text = result.to_string();
        assert!(text.starts_with("chi-square test passed"));
        assert!(text.contains("worst cells"));
        assert_eq!(
            result.observed_map().lines().count(),
            1 + result.theta_cells
        );
    }

    #[test]
    fn sidak_correction() {
        let c = Chi2Config::default().with_test_count(10);
        let expected = 1.0 - 0.99f64.powf(0.1);
        assert!((c.corrected_significance() - expected).abs() < 1e-12);
        assert!((Chi2Config::default().corrected_significance() - 0.01).abs() < 1e-12);
    }

    #[test]
    fn pooling_matches_mitsuba() {
        // Cells sorted by expected count: (0, 0) skipped, three small ones pooled to 6.
        let cells = [(0.0, 0.0), (1.0, 2.0), (3.0, 2.0), (2.0, 2.0), (10.0, 10.0)];
        let p = pooled_chi_square(cells.into_iter(), 5.0);
        assert_eq!(p.pooled_in, 3);
        assert_eq!(p.degrees_of_freedom, 1);
        assert!(p.statistic.abs() < 1e-12);
    }

    #[test]
    fn consistency_check_catches_mismatch() {
        struct Inconsistent;
        impl Bxdf for Inconsistent {
            fn eval(&self, _: Vec3, _: Vec3) -> Rgb {
                Rgb::splat(0.3)
            }
            fn pdf(&self, _: Vec3, wi: Vec3) -> f32 {
                wi.z
            }
            fn sample(&self, _: Vec3, u: Vec2, _: f32) -> Option<BsdfSample> {
                let wi = sample_cosine_hemisphere(u);
                Some(BsdfSample::new(wi, Rgb::splat(0.2), wi.z))
            }
        }
        let report = check_sample_consistency(&Inconsistent, Vec3::Z, 50);
        assert!(!report.passed());
        assert_eq!(report.problems.len(), MAX_LISTED_PROBLEMS);
        assert!(report.to_string().contains("!= eval"));
    }
}
