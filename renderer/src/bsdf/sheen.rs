//! The glTF `KHR_materials_sheen` lobe: Estevez and Kulla's "Charlie" microfibre sheen,
//! its directional albedo and the albedo scaling of the base layer under it.
//!
//! Everything is in the local shading frame of [`crate::bsdf`] (z is the shading normal on
//! the side of `wo`); μ = cos θ is a direction's z component, α is dimensionless, BRDF values
//! are in 1/sr **without** the cosine factor, albedos are dimensionless fractions.
//!
//! # The lobe
//!
//! With the extension's sheen roughness r ∈ [0, 1] (perceptual), α = r², clamped to
//! α ≥ [`MIN_ALPHA`] = 10⁻⁴ (r = 0, the extension's default, would make the exponent 1/α
//! below infinite; at α = 10⁻⁴ the distribution peaks at (2 + 10⁴)/(2π) ≈ 1.6 · 10³ sr⁻¹, a
//! fibre spread of about √α = 0.01 rad around the normal, visually the limit):
//!
//! ```text
//! f_sheen(wo, wi) = sheenColor · D(h) · V(μo, μi)                 [1/sr],  h = (wo + wi)/|wo + wi|
//! D(h)            = (2 + 1/α) · sin(θh)^(1/α) / (2π)              [1/sr],  ∫ D(h) cos θh dω_h = 1
//! V(μo, μi)       = 1 / ((1 + Λ(μo) + Λ(μi)) · 4 μo μi)          [dimensionless]
//! ```
//!
//! and zero when wo or wi lies below (or on) the horizon. There is no Fresnel factor (the
//! extension allows F = 1). Λ is Smith's masking function of D; the extension (after Estevez
//! and Kulla, Table 1) uses a fit: with t = (1 − α)² and mix(x, y, t) = x(1 − t) + y t,
//!
//! ```text
//! a = mix(21.5473, 25.3245, t)   b = mix(3.82987, 3.32435, t)   c = mix(0.19823, 0.16801, t)
//! d = mix(−1.97760, −1.27393, t) e = mix(−4.32054, −4.85967, t)
//! L(x)     = a / (1 + b x^c) + d x + e
//! Λ_fit(μ) = exp(L(μ))                  for μ < 0.5
//!          = exp(2 L(0.5) − L(1 − μ))   otherwise.
//! ```
//!
//! ## Where this file departs from the extension's sample code, and why
//!
//! Against Smith's Λ of D computed by quadrature (μ (1 + Λ(μ)) = ∫ D(h) max(0, ω·h) dω_h),
//! the fit is good for r ≳ 0.3 and far too small below (ratio fit/exact):
//!
//! ```text
//!            μ = 0.01   0.1    0.5    0.9
//! α = 1      1.01       1.00   1.02   1.05
//! α = 0.36   1.13       1.12   1.14   1.18
//! α = 0.09   1.00       0.98   0.98   0.88
//! α = 0.01   0.41       0.40   0.37   0.24
//! α = 1e-4   0.042      0.041  0.036  0.020
//! ```
//!
//! With too little masking the lobe reflects more than it receives at grazing angles: its
//! albedo E(μ) reaches 1.9 at r = 0.1, μ = 0.01 and 5 at r = 0, μ = 0.01, and the albedo
//! scaling below, which assumes E ≤ 1, cannot keep the layered material from creating energy.
//! Second, exp(L(μ)) tends to the constant exp(a + e) ≈ 10⁷ as μ → 0 instead of growing like
//! 1/μ, so V ∝ 1/μo at extreme grazing and E diverges for every α (E(10⁻⁶) = 1.1 at r = 0.6
//! and 26 at r = 0; E(10⁻⁷) = 3.9 at r = 1).
//!
//! Both are repaired with a rigorous bound. Seen from ω = (√(1 − μ²) t, μ) with t a horizontal
//! unit vector, ω·h ≥ √(1 − μ²) (t·h) for every h above the horizon, so
//!
//! ```text
//! μ Λ(μ) ≥ √(1 − μ²) K(α) − μ,
//! K(α) = ∫ D(h) max(0, t·h) dω_h = (2 + 1/α)/π · ∫₀^{π/2} sin^{1/α+2}θ dθ
//! ```
//!
//! (K is the microsurface's projected area seen edge-on, K(1) = 2/π; as α → 0, K → 1/√(2πα)
//! and the bound becomes the exact Λ: within 1 % at α = 10⁻⁴). This file uses
//!
//! ```text
//! μΛ(μ) = softmax(μ̄ Λ_fit(μ̄), √(1 − μ²) K(α) − μ),   μ̄ = softmax(μ, 0.01)
//! ```
//!
//! where softmax(a, b) is max(a, b) except where a and b are within a width w of each other,
//! there the parabola (a + b)/2 + ((a − b)² + w²)/(4w) (continuously differentiable, never
//! below the max, at most w/4 above it); w = 0.005 for μ̄ (so μ̄ = μ from μ = 0.015 up) and 10 %
//! of the fit for μΛ. That is: the published fit wherever it exceeds the bound by more than
//! 10 % and μ ≥ 0.015 (e.g. r ≥ 0.6 and μ ≥ 0.3: there this *is* the extension's lobe), the
//! bound where the fit falls below it (small α), and below μ = 0.01 the fit frozen (where it
//! still matches the exact Λ; below it has a 30 % bump near μ = 10⁻⁴ and then saturates),
//! never below the bound. The blends exist for the albedo table: a kink in Λ along the curve
//! where fit and bound cross (r ≈ 0.3) made bilinear look-ups err by up to 8 · 10⁻³; near
//! that curve the fit and the bound both fall short of the exact Λ, so the blend's excess
//! moves toward it. For r ≥ 0.3 and cosines ≥ 0.01, f differs from the extension's by at
//! most 2.7 % (a test measures it). V is evaluated as
//! 1 / (4 (μo μi + μi · μΛ(μo) + μo · μΛ(μi))), algebraically the same, and finite whenever one
//! of μo, μi is positive. With this Λ the albedo E(μ) stays ≤ 1 (at grazing it tends to
//! K(α)/μΛ(0) ≤ 1), which the tests check for r from 0.01 to 1.
//!
//! V is **not** clamped to [0, 1] as the Khronos sample viewer does (`clamp(…, 0.0, 1.0)` in
//! its `V_Sheen`). The clamp only removes energy and keeps reciprocity (V is symmetric), but
//! V > 1 is legitimate (Smith's V = G2/(4 μo μi) exceeds 1 when both directions graze): the
//! clamp darkens the double-grazing sheen (E at r = 0.3, μ = 0.01: 0.78 clamped against 0.91)
//! and hides, rather than fixes, the excess above (the clamped lobe still reaches E = 1.36
//! at r = 0.1, μ = 0.01, and 2.0 at r = 0, μ = 10⁻⁷). The only guard is the horizon
//! test: f = 0 when μo ≤ 0 or μi ≤ 0.
//!
//! # Directional albedo and albedo scaling
//!
//! E(μ, α) = ∫ D V cos θi dω_i over the upper hemisphere (the albedo of the lobe with colour
//! 1, seen from cos θo = μ). It is tabulated once, on first use ([`sheen_albedo`], a
//! `OnceLock`), by deterministic Gauss–Legendre quadrature over the half vector: θh (the
//! weight sin^{1/α+1}θh cut where it falls below 10⁻¹² of its largest value, and a square-root
//! substitution at the end where the azimuth range closes) and the azimuth range of h whose
//! reflection stays above the horizon, 12 × 12 nodes, with μΛ interpolated from 1025 samples
//! per α; this agrees with 64 × 64 nodes on the exact μΛ within 2.4 · 10⁻⁴. The table has
//! 48 × 48 nodes; its axes follow the lobe's shape: r = √α uniformly on [0.01, 1], and
//! x = √(μ (1 + r)/(μ + r)) uniformly on [0, 1] (for small α, E depends on μ/r alone, so the
//! nodes crowd toward grazing as the lobe narrows). Look-ups are bilinear, within 10⁻³ of
//! the quadrature between the nodes (tests: 9 · 10⁻⁴ on a dense grid, 6 · 10⁻⁴ against an
//! independent quadrature of [`Sheen::eval`] over directions). Building it takes 13–16 ms in
//! a release build on one core (2-core Xeon under load), about as long in the test profile.
//!
//! The base layer under the sheen is weighted (the extension's albedo scaling, Estevez and
//! Kulla §3) by
//!
//! ```text
//! s(μo, μi) = min(1 − max3(sheenColor) E(μo), 1 − max3(sheenColor) E(μi))  ∈ [0, 1]
//! ```
//!
//! so that f = f_sheen + s · f_base reflects at most E(μo) + (1 − E(μo)) ≤ 1 over a white
//! base (measured: at most 1.0006, the table's error). The lobe has no sampling routine of
//! its own: the layering samples it with cosine-weighted directions.
//!
//! # References
//!
//! - Khronos, `KHR_materials_sheen` (ratified), Implementation Notes: sheen distribution,
//!   visibility and albedo-scaling technique.
//! - A. Conty Estevez, C. Kulla, "Production Friendly Microfacet Sheen BRDF", SIGGRAPH 2017
//!   course *Physically Based Shading in Theory and Practice*.
//! - Khronos glTF Sample Viewer, `brdf.glsl` (`D_Charlie`, `V_Sheen`, `lambdaSheen`).
//! - E. Heitz, "Understanding the Masking-Shadowing Function in Microfacet-Based BRDFs",
//!   JCGT 3(2), 2014 (Smith's Λ and the projected-area identity used for the bound).
//!
//! # Example
//! ```
//! use glam::Vec3;
//! use renderer::bsdf::sheen::Sheen;
//! use renderer::Rgb;
//!
//! let velvet = Sheen::new(Rgb::new(0.9, 0.2, 0.2), 0.5);
//! let wo = Vec3::new(0.99, 0.0, 0.141).normalize();
//! let wi = Vec3::new(-0.6, 0.0, 0.8);
//! assert!(velvet.eval(wo, wi).min_element() >= 0.0);
//! let s = velvet.base_scaling(wo.z, wi.z);
//! assert!((0.0..=1.0).contains(&s));
//! ```

use crate::Rgb;
use glam::Vec3;
use std::f64::consts::{FRAC_PI_2, PI};
use std::sync::OnceLock;

/// Smallest α = sheenRoughness² a [`Sheen`] uses (see the module documentation).
pub const MIN_ALPHA: f32 = 1e-4;

/// Below this cosine the published fit of Λ is frozen at its value here (see the module
/// documentation), through a quadratic blend over ± [`FIT_MIN_COS_BLEND`].
const FIT_MIN_COS: f64 = 0.01;
const FIT_MIN_COS_BLEND: f64 = 0.005;

/// Relative width of the blend between the fit and the bound of μΛ: the larger is taken
/// exactly where they differ by more than this fraction of the fit.
const BOUND_BLEND: f64 = 0.1;

/// max(a, b) where |a − b| ≥ w, and the parabola (a + b)/2 + ((a − b)² + w²)/(4w) between:
/// continuously differentiable, never below max(a, b), at most w/4 above it.
#[inline]
fn soft_max(a: f64, b: f64, w: f64) -> f64 {
    let d = a - b;
    if d >= w {
        a
    } else if d <= -w {
        b
    } else {
        0.5 * (a + b) + (d * d + w * w) / (4.0 * w)
    }
}

/// Clamps α to [`MIN_ALPHA`] ..= 1; NaN becomes [`MIN_ALPHA`].
#[inline]
fn clamp_alpha(alpha: f32) -> f32 {
    if alpha.is_nan() {
        MIN_ALPHA
    } else {
        alpha.clamp(MIN_ALPHA, 1.0)
    }
}

/// A cosine clamped to [0, 1]; NaN becomes 0.
#[inline]
fn clamp_cos(mu: f32) -> f32 {
    if mu.is_nan() {
        0.0
    } else {
        mu.clamp(0.0, 1.0)
    }
}

/// The sheen lobe of one shading point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sheen {
    /// Linear RGB sheen colour, each channel in [0, 1].
    color: Rgb,
    /// α = sheenRoughness², in [`MIN_ALPHA`] ..= 1.
    alpha: f32,
}

impl Sheen {
    /// `color` linear RGB (clamped to [0, 1]), `roughness` perceptual (clamped to [0, 1]);
    /// α = r², ≥ 1e-4 ([`MIN_ALPHA`]).
    ///
    /// NaN channels of `color` become 0, a NaN `roughness` becomes 0.
    #[inline]
    pub fn new(color: Rgb, roughness: f32) -> Self {
        let r = clamp_cos(roughness);
        Sheen {
            color: color.max(Rgb::ZERO).min(Rgb::ONE),
            alpha: clamp_alpha(r * r),
        }
    }

    /// The sheen colour (linear RGB, each channel in [0, 1]).
    #[inline]
    pub fn color(&self) -> Rgb {
        self.color
    }

    /// α = sheenRoughness², in [`MIN_ALPHA`] ..= 1.
    #[inline]
    pub fn alpha(&self) -> f32 {
        self.alpha
    }

    /// Whether the sheen adds nothing (colour black): layering may skip it.
    #[inline]
    pub fn is_black(&self) -> bool {
        self.color.max_element() <= 0.0
    }

    /// f_sheen in 1/sr (no cosine); zero below either horizon.
    ///
    /// `wo` and `wi` are unit vectors in the local frame. Symmetric in its arguments.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if !(wo.z > 0.0 && wi.z > 0.0) || self.is_black() {
            return Rgb::ZERO;
        }
        let (wo, wi) = (wo.as_dvec3(), wi.as_dvec3());
        let h = wo + wi;
        // Both z > 0, so |h| ≥ h.z > 0; sin²θh without the cancellation of 1 − cos²θh.
        let sin2_h = (h.x * h.x + h.y * h.y) / h.length_squared();
        let lobe = Charlie::new(self.alpha as f64);
        let f = lobe.d_from_sin2(sin2_h) * lobe.visibility(wo.z, wi.z);
        self.color * f as f32
    }

    /// max3(colour) · E(μ): the fraction of light the sheen reflects seen from a direction
    /// with cosine μ.
    ///
    /// `cos_theta` is taken by absolute value (a direction below the surface crosses the sheen
    /// layer at the same angle) and clamped to 1; NaN counts as 0.
    #[inline]
    pub fn albedo(&self, cos_theta: f32) -> f32 {
        let m = self.color.max_element();
        if m <= 0.0 {
            return 0.0;
        }
        m * sheen_albedo(cos_theta.abs(), self.alpha)
    }

    /// The base's weight under the sheen, s(μo, μi) above, in [0, 1].
    ///
    /// The cosines are read as in [`Sheen::albedo`].
    #[inline]
    pub fn base_scaling(&self, cos_o: f32, cos_i: f32) -> f32 {
        let m = self.color.max_element();
        if m <= 0.0 {
            return 1.0;
        }
        let e = sheen_albedo(cos_o.abs(), self.alpha).max(sheen_albedo(cos_i.abs(), self.alpha));
        (1.0 - m * e).clamp(0.0, 1.0)
    }
}

/// The directional albedo E(μ, α) of the sheen lobe with colour 1 (dimensionless, in [0, 1]),
/// seen from a direction with cos θ = `mu`: ∫ D V cos θi dω_i over the upper hemisphere.
///
/// `mu` is clamped to [0, 1] (NaN → 0), `alpha` to [`MIN_ALPHA`] ..= 1 (NaN → [`MIN_ALPHA`]).
/// A bilinear look-up in a table built on first use (see the module documentation).
#[inline]
pub fn sheen_albedo(mu: f32, alpha: f32) -> f32 {
    albedo_table().lookup(clamp_cos(mu), clamp_alpha(alpha))
}

/// The Charlie distribution and its masking for one α, in f64 (shared by [`Sheen::eval`] and
/// the albedo quadrature).
#[derive(Clone, Copy, Debug)]
struct Charlie {
    /// The exponent 1/α of sin θh.
    inv_alpha: f64,
    /// D's normalisation (2 + 1/α)/(2π), 1/sr.
    norm: f64,
    /// The fit's coefficients a … e for this α.
    a: f64,
    b: f64,
    c: f64,
    d: f64,
    e: f64,
    /// L(0.5).
    l_half: f64,
    /// K(α), the projected area seen edge-on (dimensionless).
    edge_on: f64,
}

impl Charlie {
    /// The distribution for `alpha` (already clamped to [`MIN_ALPHA`] ..= 1).
    fn new(alpha: f64) -> Self {
        let t = (1.0 - alpha) * (1.0 - alpha);
        let mix = |x: f64, y: f64| x * (1.0 - t) + y * t;
        let inv_alpha = 1.0 / alpha;
        let mut lobe = Charlie {
            inv_alpha,
            norm: (2.0 + inv_alpha) / (2.0 * PI),
            a: mix(21.5473, 25.3245),
            b: mix(3.82987, 3.32435),
            c: mix(0.19823, 0.16801),
            d: mix(-1.97760, -1.27393),
            e: mix(-4.32054, -4.85967),
            l_half: 0.0,
            edge_on: edge_on_area(alpha),
        };
        lobe.l_half = lobe.l(0.5);
        lobe
    }

    /// D(h) in 1/sr from sin²θh ∈ [0, 1].
    #[inline]
    fn d_from_sin2(&self, sin2_h: f64) -> f64 {
        self.norm * sin2_h.max(0.0).powf(0.5 * self.inv_alpha)
    }

    /// D(h) in 1/sr from cos θh ∈ [0, 1].
    #[cfg(test)]
    fn d(&self, cos_h: f64) -> f64 {
        self.d_from_sin2(1.0 - cos_h * cos_h)
    }

    /// The fit's L(x), x ∈ [0, 1].
    #[inline]
    fn l(&self, x: f64) -> f64 {
        self.a / (1.0 + self.b * x.powf(self.c)) + self.d * x + self.e
    }

    /// The extension's Λ (Estevez and Kulla's fit) at μ ∈ [0, 1].
    #[inline]
    fn lambda_fit(&self, mu: f64) -> f64 {
        if mu < 0.5 {
            self.l(mu).exp()
        } else {
            (2.0 * self.l_half - self.l((1.0 - mu).max(0.0))).exp()
        }
    }

    /// The published fit of μΛ(μ), frozen below μ = [`FIT_MIN_COS`] (positive).
    #[inline]
    fn mu_lambda_fit(&self, mu: f64) -> f64 {
        let mu_fit = soft_max(mu, FIT_MIN_COS, FIT_MIN_COS_BLEND);
        mu_fit * self.lambda_fit(mu_fit)
    }

    /// The lower bound √(1 − μ²) K(α) − μ of Smith's μΛ(μ).
    #[inline]
    fn mu_lambda_bound(&self, mu: f64) -> f64 {
        (1.0 - mu * mu).sqrt() * self.edge_on - mu
    }

    /// μ Λ(μ) as used here: the larger of the (frozen) fit and the bound, blended (see the
    /// module documentation); positive and finite for every μ ∈ [0, 1], never below either.
    #[inline]
    fn mu_lambda(&self, mu: f64) -> f64 {
        let mu = mu.clamp(0.0, 1.0);
        let fit = self.mu_lambda_fit(mu);
        soft_max(fit, self.mu_lambda_bound(mu), BOUND_BLEND * fit)
    }

    /// Λ(μ) as used here, μ ∈ (0, 1].
    #[cfg(test)]
    fn lambda(&self, mu: f64) -> f64 {
        self.mu_lambda(mu) / mu
    }

    /// V(μo, μi) = 1/((1 + Λ(μo) + Λ(μi)) 4 μo μi); zero unless both cosines are positive.
    #[inline]
    fn visibility(&self, mu_o: f64, mu_i: f64) -> f64 {
        if !(mu_o > 0.0 && mu_i > 0.0) {
            return 0.0;
        }
        let (mu_o, mu_i) = (mu_o.min(1.0), mu_i.min(1.0));
        0.25 / (mu_o * mu_i + mu_i * self.mu_lambda(mu_o) + mu_o * self.mu_lambda(mu_i))
    }
}

/// K(α) = ∫ D(h) max(0, t·h) dω_h for a horizontal unit t: (2 + N)/π · W(N + 2) with N = 1/α
/// and Wallis' integral W(n) = ∫₀^{π/2} sinⁿθ dθ = (√π/2) Γ((n+1)/2)/Γ(n/2 + 1).
///
/// The ratio Γ(x + ½)/Γ(x + 1) is shifted to x ≥ 8 by its recurrence and then taken from its
/// asymptotic series (relative error below 10⁻⁷).
fn edge_on_area(alpha: f64) -> f64 {
    let n = 1.0 / alpha;
    let mut x = 0.5 * (n + 2.0);
    let mut factor = 1.0;
    while x < 8.0 {
        // Γ(x+½)/Γ(x+1) = Γ(x+3/2)/Γ(x+2) · (x+1)/(x+½).
        factor *= (x + 1.0) / (x + 0.5);
        x += 1.0;
    }
    let y = 1.0 / x;
    let series =
        1.0 - y / 8.0 + y * y / 128.0 + 5.0 * y * y * y / 1024.0 - 21.0 * y * y * y * y / 32768.0;
    let ratio = factor * series / x.sqrt();
    (2.0 + n) / (2.0 * PI.sqrt()) * ratio
}

/// The n-point Gauss–Legendre rule on [0, 1], as (node, weight) pairs with increasing nodes.
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    // P_n(x) and P_{n−1}(x) by the three-term recurrence.
    let legendre = |x: f64| {
        let (mut p0, mut p1) = (1.0, x);
        for k in 2..=n {
            let k = k as f64;
            let p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
            p0 = p1;
            p1 = p2;
        }
        (p1, p0)
    };
    let derivative = |x: f64, p: f64, q: f64| n as f64 * (x * p - q) / (x * x - 1.0);
    (0..n)
        .map(|i| {
            // Tricomi's initial guess for the i-th largest root, then Newton.
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            for _ in 0..100 {
                let (p, q) = legendre(x);
                let dx = p / derivative(x, p, q);
                x -= dx;
                if dx.abs() < 1e-15 {
                    break;
                }
            }
            let (p, q) = legendre(x);
            let dp = derivative(x, p, q);
            // Weight 2/((1 − x²) P'²) on [−1, 1], halved for [0, 1].
            ((1.0 - x) * 0.5, 1.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// Relative cut of the θh weight sin^{1/α+1}θh in [`albedo_quadrature`].
const THETA_WEIGHT_CUT: f64 = 1e-12;

/// E(μo) by quadrature over the half vector h = (sin θ cos φ, sin θ sin φ, cos θ), with wo in
/// the xz plane.
///
/// With dω_i = 4 (wo·h) dω_h, E = ∫ D(h) V μi 4 (wo·h) sin θ dθ dφ over the h whose mirror
/// direction wi = 2 (wo·h) h − wo lies above the horizon: θ ≤ θmax = (θo + π/2)/2 and, for
/// each θ, |φ| ≤ φmax(θ) where μi = 2 (wo·h) cos θ − μo = 0. θ runs over [θmin, θmax] (θmin
/// where the weight sin^{1/α+1}θ falls to [`THETA_WEIGHT_CUT`] of its value at θmax) with the
/// substitution θ = θmax − (θmax − θmin) v², which smooths the √(θmax − θ) of φmax; φ runs
/// over [0, φmax] (times 2, by symmetry). `theta_rule` and `phi_rule` are rules on [0, 1];
/// `mu_lambda` is the lobe's μΛ(μ) ([`Charlie::mu_lambda`] or samples of it).
fn albedo_quadrature(
    lobe: &Charlie,
    mu_lambda: impl Fn(f64) -> f64,
    mu_o: f64,
    theta_rule: &[(f64, f64)],
    phi_rule: &[(f64, f64)],
) -> f64 {
    let mu_o = mu_o.clamp(0.0, 1.0);
    let sin_o = (1.0 - mu_o * mu_o).sqrt();
    let theta_max = 0.5 * (mu_o.acos() + FRAC_PI_2);
    let exponent = lobe.inv_alpha + 1.0;
    let sin_max = theta_max.sin();
    let mu_lambda_o = mu_lambda(mu_o);
    // The integrand below is at most 2π · π/2 · norm · sin_max^exponent / μΛ(μo) (since
    // (wo·h) μi / (… + μi μΛ(μo) + …) ≤ 1/μΛ(μo)); skip what cannot reach 10⁻⁹.
    if PI * PI * lobe.norm * sin_max.powf(exponent) / mu_lambda_o < 1e-9 {
        return 0.0;
    }
    let theta_min = (sin_max * (THETA_WEIGHT_CUT.ln() / exponent).exp()).asin();
    let span = theta_max - theta_min;
    let mut sum = 0.0;
    for &(v, wv) in theta_rule {
        let theta = theta_max - span * v * v;
        let (s, c) = theta.sin_cos();
        // μi > 0 ⇔ cos φ > μo (1 − 2c²) / (2 sin θo s c).
        let num = mu_o * (1.0 - 2.0 * c * c);
        let den = 2.0 * sin_o * s * c;
        let phi_max = if den > 1e-300 {
            (num / den).clamp(-1.0, 1.0).acos()
        } else if num < 0.0 {
            PI
        } else {
            0.0
        };
        if phi_max <= 0.0 {
            continue;
        }
        let mut row = 0.0;
        for &(x, wx) in phi_rule {
            let wo_h = sin_o * s * (phi_max * x).cos() + mu_o * c;
            let mu_i = 2.0 * wo_h * c - mu_o;
            if mu_i <= 0.0 {
                continue;
            }
            // D V μi 4 (wo·h) sin θ = norm sin^{1/α+1}θ · (wo·h) μi / (μo μi + μi μΛo + μo μΛi).
            let denominator = mu_o * mu_i + mu_i * mu_lambda_o + mu_o * mu_lambda(mu_i);
            row += wx * wo_h * mu_i / denominator;
        }
        let weight = lobe.norm * s.powf(exponent);
        sum += wv * 2.0 * span * v * 2.0 * phi_max * weight * row;
    }
    sum
}

/// Nodes of the albedo table along x (the warped cosine) and along r = √α.
const TABLE_COS: usize = 48;
const TABLE_ROUGHNESS: usize = 48;
/// r = √α at the table's first roughness node.
const TABLE_MIN_R: f32 = 0.01;
/// Gauss–Legendre nodes per dimension in the table's quadrature.
const TABLE_RULE: usize = 12;
/// Intervals of the uniform samples of μΛ(μ) on [0, 1] that the table's quadrature
/// interpolates (the fit's powers and exponentials would otherwise dominate its cost).
const MU_LAMBDA_INTERVALS: usize = 1024;

/// E(μ, α) on the module documentation's grid, row-major by roughness.
struct AlbedoTable {
    values: Vec<f32>,
}

/// The table's cosine axis x(μ, r) = √(μ (1 + r)/(μ + r)) ∈ [0, 1].
#[inline]
fn cos_axis(mu: f32, r: f32) -> f32 {
    (mu * (1.0 + r) / (mu + r)).sqrt()
}

/// The inverse of [`cos_axis`]: the μ ∈ [0, 1] at `x` ∈ [0, 1] for this r.
fn cos_axis_inverse(x: f64, r: f64) -> f64 {
    // u = x² = μ (1 + r)/(μ + r) ⇒ μ = u r / (1 + r − u).
    let u = x * x;
    (u * r / (1.0 + r - u)).clamp(0.0, 1.0)
}

/// r = √α at roughness node `j`.
fn table_r(j: usize) -> f64 {
    TABLE_MIN_R as f64 + (1.0 - TABLE_MIN_R as f64) * j as f64 / (TABLE_ROUGHNESS - 1) as f64
}

/// [`Charlie::mu_lambda`] at [`MU_LAMBDA_INTERVALS`] + 1 uniform cosines, interpolated
/// linearly (absolute error below 10⁻⁵ of the denominator it enters).
fn sampled_mu_lambda(lobe: &Charlie) -> impl Fn(f64) -> f64 {
    let scale = MU_LAMBDA_INTERVALS as f64;
    let samples: Vec<f64> = (0..=MU_LAMBDA_INTERVALS)
        .map(|k| lobe.mu_lambda(k as f64 / scale))
        .collect();
    move |mu: f64| {
        let t = mu.clamp(0.0, 1.0) * scale;
        let k = (t as usize).min(MU_LAMBDA_INTERVALS - 1);
        samples[k] + (t - k as f64) * (samples[k + 1] - samples[k])
    }
}

impl AlbedoTable {
    fn build() -> Self {
        let rule = gauss_legendre(TABLE_RULE);
        let mut values = Vec::with_capacity(TABLE_COS * TABLE_ROUGHNESS);
        for j in 0..TABLE_ROUGHNESS {
            let r = table_r(j);
            let lobe = Charlie::new(r * r);
            let mu_lambda = sampled_mu_lambda(&lobe);
            for i in 0..TABLE_COS {
                let mu = cos_axis_inverse(i as f64 / (TABLE_COS - 1) as f64, r);
                // At most 1 (it reaches 1 at grazing for small α, up to rounding).
                let albedo = albedo_quadrature(&lobe, &mu_lambda, mu, &rule, &rule);
                values.push(albedo.min(1.0) as f32);
            }
        }
        AlbedoTable { values }
    }

    /// Bilinear look-up at μ ∈ [0, 1], α ∈ [`MIN_ALPHA`] ..= 1.
    #[inline]
    fn lookup(&self, mu: f32, alpha: f32) -> f32 {
        let r = alpha.sqrt();
        let y = ((r - TABLE_MIN_R) / (1.0 - TABLE_MIN_R)).clamp(0.0, 1.0)
            * (TABLE_ROUGHNESS - 1) as f32;
        let x = cos_axis(mu, r).clamp(0.0, 1.0) * (TABLE_COS - 1) as f32;
        let (j, i) = (
            (y as usize).min(TABLE_ROUGHNESS - 2),
            (x as usize).min(TABLE_COS - 2),
        );
        let (fy, fx) = (y - j as f32, x - i as f32);
        let at = |j: usize, i: usize| self.values[j * TABLE_COS + i];
        let row = |j: usize| at(j, i) + fx * (at(j, i + 1) - at(j, i));
        row(j) + fy * (row(j + 1) - row(j))
    }
}

static ALBEDO_TABLE: OnceLock<AlbedoTable> = OnceLock::new();

/// The albedo table, built on first use.
#[inline]
fn albedo_table() -> &'static AlbedoTable {
    ALBEDO_TABLE.get_or_init(AlbedoTable::build)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg32;

    /// ∫ f over [breaks[0], breaks[last]] by `rule` on each piece between consecutive breaks.
    fn integrate(breaks: &[f64], rule: &[(f64, f64)], mut f: impl FnMut(f64) -> f64) -> f64 {
        let mut sum = 0.0;
        for piece in breaks.windows(2) {
            let (a, b) = (piece[0], piece[1]);
            for &(x, w) in rule {
                sum += w * (b - a) * f(a + (b - a) * x);
            }
        }
        sum
    }

    /// Breaks of cos θi for [`hemisphere_cos_integral`], graded toward the horizon, where the
    /// narrow lobes live (a lobe of α = 10⁻⁴ spans μi ≲ 0.05).
    const MU_BREAKS: &[f64] = &[
        0.0, 1e-4, 1e-3, 3e-3, 0.01, 0.02, 0.03, 0.04, 0.06, 0.08, 0.1, 0.15, 0.2, 0.3, 0.45, 0.6,
        0.8, 1.0,
    ];

    /// ∫ g(wi) cos θi dω_i over the upper hemisphere, for a g symmetric under y → −y (wo in the
    /// xz plane): composite Gauss–Legendre in cos θi and in φi ∈ [0, π], doubled. Independent
    /// of the table's quadrature over the half vector.
    fn hemisphere_cos_integral(mut g: impl FnMut(Vec3) -> f64) -> f64 {
        let rule = gauss_legendre(12);
        let phi_breaks: Vec<f64> = (0..=8).map(|k| PI * k as f64 / 8.0).collect();
        2.0 * integrate(MU_BREAKS, &rule, |mu| {
            let sin = (1.0 - mu * mu).max(0.0).sqrt();
            mu * integrate(&phi_breaks, &rule, |phi| {
                let wi = Vec3::new(
                    (sin * phi.cos()) as f32,
                    (sin * phi.sin()) as f32,
                    mu as f32,
                );
                g(wi)
            })
        })
    }

    /// The direction in the xz plane with cos θ = `mu`.
    fn wo_at(mu: f64) -> Vec3 {
        Vec3::new((1.0 - mu * mu).max(0.0).sqrt() as f32, 0.0, mu as f32)
    }

    /// E(μo) of a white sheen of roughness r by [`hemisphere_cos_integral`] over `eval`.
    fn albedo_of_eval(mu_o: f64, r: f32) -> f64 {
        let sheen = Sheen::new(Rgb::ONE, r);
        let wo = wo_at(mu_o);
        hemisphere_cos_integral(|wi| sheen.eval(wo, wi).x as f64)
    }

    fn random_upper(rng: &mut Pcg32) -> Vec3 {
        let mu: f32 = rng.random::<f32>().max(1e-4);
        let phi = 2.0 * std::f32::consts::PI * rng.random::<f32>();
        let sin = (1.0 - mu * mu).sqrt();
        Vec3::new(sin * phi.cos(), sin * phi.sin(), mu)
    }

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        let rule = gauss_legendre(16);
        assert!((rule.iter().map(|p| p.1).sum::<f64>() - 1.0).abs() < 1e-14);
        for k in 0..32 {
            let integral: f64 = rule.iter().map(|&(x, w)| w * x.powi(k)).sum();
            assert!(
                (integral - 1.0 / (k as f64 + 1.0)).abs() < 1e-13,
                "x^{k}: {integral}"
            );
        }
    }

    /// The published fit's constants at α = 0.09 (r = 0.3), against values worked out by hand
    /// from the extension's GLSL: t = 0.91² = 0.8281, a = 24.675199, b = 3.4112489,
    /// c = 0.17320482, d = −1.3948909, e = −4.7669936; L(0.25) = 1.5838926,
    /// L(0.5) = 0.66553416; Λ(0.25) = e^L(0.25) = 4.8738910,
    /// Λ(0.75) = e^(2 L(0.5) − L(0.25)) = 0.77660434.
    #[test]
    fn lambda_fit_matches_hand_computed_values() {
        let lobe = Charlie::new(0.09);
        for (got, want) in [
            (lobe.a, 24.675199),
            (lobe.b, 3.4112489),
            (lobe.c, 0.17320482),
            (lobe.d, -1.3948909),
            (lobe.e, -4.7669936),
            (lobe.l(0.25), 1.5838926),
            (lobe.l_half, 0.66553416),
            (lobe.lambda_fit(0.25), 4.8738910),
            (lobe.lambda_fit(0.75), 0.77660434),
        ] {
            assert!((got - want).abs() <= 1e-6 * want.abs(), "{got} vs {want}");
        }
        // At μ = 0.75 the fit is far above the bound, so Λ is the fit itself.
        assert!((lobe.lambda(0.75) / lobe.lambda_fit(0.75) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn d_is_normalised() {
        // ∫ D(h) cos θh dω_h = 2π ∫ D(θ) cos θ sin θ dθ over [0, π/2]; panels of π/800 resolve
        // the 0.01 rad wide peak at α = 10⁻⁴.
        let rule = gauss_legendre(8);
        let breaks: Vec<f64> = (0..=400).map(|k| FRAC_PI_2 * k as f64 / 400.0).collect();
        for alpha in [1e-4, 1e-3, 0.01, 0.09, 0.36, 1.0] {
            let lobe = Charlie::new(alpha);
            let integral =
                2.0 * PI * integrate(&breaks, &rule, |t| lobe.d(t.cos()) * t.cos() * t.sin());
            assert!((integral - 1.0).abs() < 1e-3, "α = {alpha}: {integral}");
        }
    }

    #[test]
    fn edge_on_area_matches_closed_forms() {
        // K(α) = (2 + N)/π · W(N + 2), W(3) = 2/3, W(4) = 3π/16, W(5) = 8/15, W(6) = 5π/32.
        for (alpha, want) in [
            (1.0, 2.0 / PI),
            (0.5, 0.75),
            (1.0 / 3.0, 8.0 / (3.0 * PI)),
            (0.25, 0.9375),
        ] {
            let got = edge_on_area(alpha);
            assert!(
                (got - want).abs() < 1e-7 * want,
                "α = {alpha}: {got} vs {want}"
            );
        }
        // Small α: K → 1/√(2πα) (1 + O(α)).
        let got = edge_on_area(1e-4);
        let asymptote = 1.0 / (2.0 * PI * 1e-4f64).sqrt();
        assert!((got / asymptote - 1.0).abs() < 1e-4, "{got} vs {asymptote}");
    }

    /// μ (1 + Λ(μ)) = ∫ D(h) max(0, ω·h) dω_h, Smith's Λ of D computed by quadrature: the
    /// azimuthal integral of max(0, A cos φ + B) in closed form, θh by composite rules.
    fn exact_mu_lambda(alpha: f64, mu: f64) -> f64 {
        let lobe = Charlie::new(alpha);
        let sin_o = (1.0 - mu * mu).sqrt();
        let rule = gauss_legendre(8);
        let breaks: Vec<f64> = (0..=400).map(|k| FRAC_PI_2 * k as f64 / 400.0).collect();
        let area = integrate(&breaks, &rule, |t| {
            let (s, c) = t.sin_cos();
            let (a, b) = (sin_o * s, mu * c);
            let azimuthal = if b >= a {
                2.0 * PI * b
            } else {
                let phi0 = (-b / a).acos();
                2.0 * (b * phi0 + a * phi0.sin())
            };
            lobe.d(c) * azimuthal * s
        });
        area - mu
    }

    #[test]
    fn lambda_is_the_fit_or_a_lower_bound_of_smiths() {
        // K is the exact μΛ at μ = 0.
        for alpha in [1e-4, 0.01, 0.09, 1.0] {
            let exact = exact_mu_lambda(alpha, 0.0);
            let k = edge_on_area(alpha);
            assert!((exact - k).abs() < 1e-4 * k, "α = {alpha}: {exact} vs {k}");
        }
        let mut worst_fit = (1.0f64, 0.0, 0.0);
        for alpha in [1e-4, 1e-3, 0.01, 0.04, 0.09, 0.36, 1.0] {
            let lobe = Charlie::new(alpha);
            for mu in [0.01, 0.05, 0.1, 0.25, 0.5, 0.75, 0.95] {
                let exact = exact_mu_lambda(alpha, mu) / mu;
                let bound = lobe.mu_lambda_bound(mu) / mu;
                let used = lobe.lambda(mu);
                // The fit, frozen below μ = 0.01 (the same as the fit from 0.015 up).
                let fit = lobe.mu_lambda_fit(mu) / mu;
                if mu >= FIT_MIN_COS + FIT_MIN_COS_BLEND {
                    assert_eq!(fit, lobe.lambda_fit(mu) * mu / mu);
                }
                let larger = fit.max(bound);
                // The bound is a bound; Λ is the larger of it and the fit, exactly where they
                // differ by more than BOUND_BLEND of the fit, and never more than a quarter of
                // that above it.
                assert!(
                    bound <= exact * (1.0 + 1e-6),
                    "α = {alpha}, μ = {mu}: {bound} > {exact}"
                );
                assert!(
                    used >= larger * (1.0 - 1e-12),
                    "α = {alpha}, μ = {mu}: {used} < {larger}"
                );
                assert!(
                    used <= larger + 0.25 * BOUND_BLEND * fit * (1.0 + 1e-12),
                    "α = {alpha}, μ = {mu}"
                );
                if (bound - fit).abs() >= BOUND_BLEND * fit && mu >= FIT_MIN_COS + FIT_MIN_COS_BLEND
                {
                    assert!(
                        (used / larger - 1.0).abs() < 1e-12,
                        "α = {alpha}, μ = {mu}: {used} vs {larger}"
                    );
                }
                let raw_fit = lobe.lambda_fit(mu);
                if raw_fit / exact < worst_fit.0 {
                    worst_fit = (raw_fit / exact, alpha, mu);
                }
            }
        }
        // What the fit alone would have been (the reason for the bound).
        println!(
            "smallest fit/exact Λ: {:.4} at α = {}, μ = {}",
            worst_fit.0, worst_fit.1, worst_fit.2
        );
        assert!(worst_fit.0 < 0.1);
    }

    /// The extension's formula, literally (D · 1/((1 + Λo + Λi) · 4 μo μi) with the fit).
    fn spec_f(alpha: f64, wo: Vec3, wi: Vec3) -> f64 {
        let lobe = Charlie::new(alpha);
        let h = (wo.as_dvec3() + wi.as_dvec3()).normalize();
        let (mu_o, mu_i) = (wo.z as f64, wi.z as f64);
        let v = 1.0 / ((1.0 + lobe.lambda_fit(mu_o) + lobe.lambda_fit(mu_i)) * 4.0 * mu_o * mu_i);
        lobe.d(h.z) * v
    }

    #[test]
    fn matches_the_extension_where_its_fit_holds() {
        let mut rng = Pcg32::seed_from_u64(3);
        // r ≥ 0.6 and both cosines ≥ 0.3: the fit is far above the bound, nothing departs.
        for _ in 0..2000 {
            let r = 0.6 + 0.4 * rng.random::<f32>();
            let (wo, wi) = (random_upper(&mut rng), random_upper(&mut rng));
            if wo.z < 0.3 || wi.z < 0.3 {
                continue;
            }
            let sheen = Sheen::new(Rgb::ONE, r);
            let got = sheen.eval(wo, wi).x as f64;
            let want = spec_f(sheen.alpha() as f64, wo, wi);
            assert!(
                (got - want).abs() <= 1e-5 * want.max(1e-6),
                "r = {r}, {wo}, {wi}: {got} vs {want}"
            );
        }
        // r ≥ 0.3 and both cosines ≥ 0.01: where the blend with the bound acts, the value moves
        // by a few per cent at most.
        let mut worst = (0.0f64, 0.0, 0.0, 0.0);
        for _ in 0..20000 {
            let r = 0.3 + 0.7 * rng.random::<f32>();
            let (wo, wi) = (random_upper(&mut rng), random_upper(&mut rng));
            if wo.z < 0.01 || wi.z < 0.01 {
                continue;
            }
            let sheen = Sheen::new(Rgb::ONE, r);
            let want = spec_f(sheen.alpha() as f64, wo, wi);
            if want < 1e-6 {
                continue;
            }
            let deviation = (sheen.eval(wo, wi).x as f64 / want - 1.0).abs();
            if deviation > worst.0 {
                worst = (deviation, r as f64, wo.z as f64, wi.z as f64);
            }
        }
        println!(
            "r ≥ 0.3, μ ≥ 0.01: largest relative departure from the extension {:.4} \
             at r = {:.3}, μo = {:.3}, μi = {:.3}",
            worst.0, worst.1, worst.2, worst.3
        );
        assert!(worst.0 < 0.05);
    }

    #[test]
    fn reciprocity() {
        let mut rng = Pcg32::seed_from_u64(7);
        for _ in 0..5000 {
            let color = Rgb::new(rng.random(), rng.random(), rng.random());
            let sheen = Sheen::new(color, rng.random());
            let (wo, wi) = (random_upper(&mut rng), random_upper(&mut rng));
            let (a, b) = (sheen.eval(wo, wi), sheen.eval(wi, wo));
            assert!(
                (a - b).abs().max_element() <= 1e-6 * a.max_element().max(1e-3),
                "{sheen:?}, {wo}, {wi}: {a} vs {b}"
            );
        }
    }

    #[test]
    fn table_quadrature_converges() {
        // The table's rule on sampled μΛ against 64 × 64 nodes on the exact μΛ.
        let (coarse, fine) = (gauss_legendre(TABLE_RULE), gauss_legendre(64));
        let mut worst = 0.0f64;
        for alpha in [1e-4, 1e-3, 0.01, 0.05, 0.09, 0.36, 0.7, 1.0] {
            let lobe = Charlie::new(alpha);
            let sampled = sampled_mu_lambda(&lobe);
            for mu in [
                0.0, 1e-5, 1e-3, 0.005, 0.01, 0.02, 0.05, 0.1, 0.3, 0.6, 0.9, 1.0,
            ] {
                let a = albedo_quadrature(&lobe, &sampled, mu, &coarse, &coarse);
                let b = albedo_quadrature(&lobe, |m| lobe.mu_lambda(m), mu, &fine, &fine);
                worst = worst.max((a - b).abs());
                assert!((a - b).abs() < 3e-4, "α = {alpha}, μ = {mu}: {a} vs {b}");
            }
        }
        println!("table quadrature ({TABLE_RULE} nodes, sampled μΛ) against 64 nodes: max difference {worst:.2e}");
    }

    #[test]
    fn albedo_table_is_accurate_between_its_nodes() {
        // A denser check against the half-vector quadrature (24 nodes, exact μΛ): a grid
        // offset from the table's nodes, in μ crowded toward grazing.
        let rule = gauss_legendre(24);
        let mut worst = (0.0f64, 0.0, 0.0);
        for a in 0..25 {
            let r = 0.01 + 0.99 * (a as f64 + 0.37) / 25.0;
            let lobe = Charlie::new(r * r);
            for b in 0..25 {
                let t = (b as f64 + 0.41) / 25.0;
                let mu = t * t * t;
                let reference = albedo_quadrature(&lobe, |m| lobe.mu_lambda(m), mu, &rule, &rule);
                let error = (sheen_albedo(mu as f32, (r * r) as f32) as f64 - reference).abs();
                if error > worst.0 {
                    worst = (error, mu, r);
                }
            }
        }
        println!(
            "albedo table between its nodes: max error {:.2e} at μ = {:.2e}, r = {:.3}",
            worst.0, worst.1, worst.2
        );
        assert!(worst.0 < 2e-3);
    }

    #[test]
    fn albedo_table_matches_quadrature_of_eval() {
        let mut rng = Pcg32::seed_from_u64(11);
        // (μ, r): random inside, then the edges μ → 0, μ = 1, r = 0.01 (α = 10⁻⁴), r = 1.
        let mut points: Vec<(f64, f32)> = (0..20)
            .map(|k| {
                let u = rng.random::<f64>();
                // Half of them crowded toward grazing, where the lobes change fastest.
                let mu = if k % 2 == 0 { u } else { u * u * u };
                (mu, 0.01 + 0.99 * rng.random::<f32>())
            })
            .collect();
        for r in [0.01, 0.3, 1.0] {
            points.extend([(1e-6, r), (1.0, r)]);
        }
        for _ in 0..3 {
            let mu = rng.random::<f64>();
            points.extend([(mu * mu, 0.01), (mu, 1.0)]);
        }
        let mut worst = (0.0f64, 0.0, 0.0);
        for (mu, r) in points {
            let reference = albedo_of_eval(mu, r);
            let table = sheen_albedo(mu as f32, r * r) as f64;
            let error = (table - reference).abs();
            if error > worst.0 {
                worst = (error, mu, r);
            }
            assert!(
                error < 2e-3,
                "μ = {mu}, r = {r}: table {table}, quadrature {reference}"
            );
        }
        println!(
            "albedo table against quadrature of eval: max error {:.2e} at μ = {}, r = {}",
            worst.0, worst.1, worst.2
        );
    }

    #[test]
    fn table_is_deterministic_and_prints_its_build_time() {
        let start = std::time::Instant::now();
        let table = AlbedoTable::build();
        let elapsed = start.elapsed();
        println!("albedo table ({TABLE_COS} × {TABLE_ROUGHNESS}) built in {elapsed:?} (this build profile)");
        assert_eq!(table.values, albedo_table().values);
        assert!(table.values.iter().all(|v| v.is_finite() && *v >= 0.0));
    }

    #[test]
    fn sheen_alone_reflects_at_most_one() {
        let table_max = albedo_table().values.iter().cloned().fold(0.0f32, f32::max);
        println!("largest table entry: {table_max}");
        assert!(table_max <= 1.0 + 1e-3);
        let mut worst = (0.0f64, 0.0, 0.0);
        for r in [0.01f32, 0.1, 0.3, 0.6, 1.0] {
            for mu in [
                1e-6, 1e-4, 1e-3, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.4, 0.7, 1.0,
            ] {
                let e = albedo_of_eval(mu, r);
                if e > worst.0 {
                    worst = (e, mu, r as f64);
                }
                assert!(e <= 1.0 + 1e-3, "r = {r}, μ = {mu}: E = {e}");
            }
        }
        println!(
            "sheen alone: max E {:.5} at μ = {}, r = {}",
            worst.0, worst.1, worst.2
        );
    }

    #[test]
    fn sheen_over_white_lambert_reflects_at_most_one() {
        let mut worst = (0.0f64, 0.0, 0.0);
        for r in [0.01f32, 0.1, 0.3, 0.6, 1.0] {
            let sheen = Sheen::new(Rgb::ONE, r);
            for mu in [
                1e-6, 1e-4, 1e-3, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.4, 0.7, 1.0,
            ] {
                let wo = wo_at(mu);
                let total = hemisphere_cos_integral(|wi| {
                    let base = sheen.base_scaling(wo.z, wi.z) as f64 / PI;
                    sheen.eval(wo, wi).x as f64 + base
                });
                if total > worst.0 {
                    worst = (total, mu, r as f64);
                }
                assert!(total <= 1.0 + 1e-3, "r = {r}, μo = {mu}: {total}");
            }
        }
        println!(
            "sheen over white Lambert: max albedo {:.5} at μ = {}, r = {}",
            worst.0, worst.1, worst.2
        );
    }

    #[test]
    fn finite_and_non_negative_in_stiff_cases() {
        let grazing = [0.0f32, 1e-6, 1e-3];
        for r in [0.0f32, 0.01, 0.3, 1.0] {
            let sheen = Sheen::new(Rgb::ONE, r);
            let mut pairs = Vec::new();
            for &mu in &grazing {
                let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                let mirrored = Vec3::new(-wo.x, -wo.y, wo.z);
                let behind = Vec3::new(-wo.x, 0.0, wo.z);
                pairs.extend([
                    (wo, wo),
                    (wo, mirrored),
                    (wo, behind),
                    (wo, Vec3::Z),
                    (Vec3::Z, wo),
                ]);
                for &mu_i in &grazing {
                    let wi = Vec3::new(0.0, (1.0 - mu_i * mu_i).sqrt(), mu_i);
                    pairs.push((wo, wi));
                }
            }
            pairs.extend([
                (Vec3::Z, Vec3::Z),
                (Vec3::new(0.6, 0.0, 0.8), Vec3::new(-0.6, 0.0, 0.8)),
            ]);
            for (wo, wi) in pairs {
                let f = sheen.eval(wo, wi);
                assert!(
                    f.is_finite() && f.min_element() >= 0.0,
                    "r = {r}, {wo}, {wi}: {f}"
                );
                if wo.z <= 0.0 || wi.z <= 0.0 {
                    assert_eq!(f, Rgb::ZERO);
                }
            }
            for &mu in &grazing {
                for value in [
                    sheen.albedo(mu),
                    sheen.base_scaling(mu, 0.5),
                    sheen_albedo(mu, sheen.alpha()),
                ] {
                    assert!(
                        value.is_finite() && (0.0..=1.0 + 1e-3).contains(&value),
                        "r = {r}, μ = {mu}: {value}"
                    );
                }
            }
        }
        // The mirror direction has h = n, where D = 0; wo = wi gives cos θh = μo.
        let sheen = Sheen::new(Rgb::ONE, 0.5);
        let wo = Vec3::new(0.6, 0.0, 0.8);
        assert_eq!(sheen.eval(wo, Vec3::new(-0.6, 0.0, 0.8)), Rgb::ZERO);
        assert!(sheen.eval(wo, wo).x > 0.0);
        // Below either horizon.
        assert_eq!(sheen.eval(wo, Vec3::new(0.6, 0.0, -0.8)), Rgb::ZERO);
        assert_eq!(sheen.eval(Vec3::new(0.6, 0.0, -0.8), wo), Rgb::ZERO);
    }

    #[test]
    fn new_clamps_and_black_sheen_does_nothing() {
        let s = Sheen::new(Rgb::new(-1.0, 2.0, f32::NAN), f32::NAN);
        assert_eq!(s.color(), Rgb::new(0.0, 1.0, 0.0));
        assert_eq!(s.alpha(), MIN_ALPHA);
        assert_eq!(Sheen::new(Rgb::ONE, 0.5).alpha(), 0.25);
        assert_eq!(Sheen::new(Rgb::ONE, 3.0).alpha(), 1.0);
        assert_eq!(Sheen::new(Rgb::ONE, -1.0).alpha(), MIN_ALPHA);
        let black = Sheen::new(Rgb::ZERO, 0.5);
        assert!(black.is_black() && !s.is_black());
        let (wo, wi) = (
            Vec3::new(0.99, 0.0, 0.141).normalize(),
            Vec3::new(-0.99, 0.0, 0.141).normalize(),
        );
        assert_eq!(black.eval(wo, wi), Rgb::ZERO);
        assert_eq!(black.albedo(0.1), 0.0);
        assert_eq!(black.base_scaling(0.1, 0.2), 1.0);
    }

    #[test]
    fn albedo_scaling_follows_the_extension() {
        let sheen = Sheen::new(Rgb::new(0.2, 0.8, 0.5), 0.4);
        let alpha = sheen.alpha();
        for (mu_o, mu_i) in [(0.1f32, 0.9f32), (0.9, 0.1), (0.5, 0.5), (1.0, 0.02)] {
            let (eo, ei) = (sheen_albedo(mu_o, alpha), sheen_albedo(mu_i, alpha));
            let want = (1.0 - 0.8 * eo).min(1.0 - 0.8 * ei);
            assert!((sheen.base_scaling(mu_o, mu_i) - want).abs() < 1e-6);
            assert!((sheen.albedo(mu_o) - 0.8 * eo).abs() < 1e-6);
        }
        // Cosines are read by absolute value; NaN counts as grazing.
        assert_eq!(sheen.albedo(-0.3), sheen.albedo(0.3));
        assert_eq!(sheen.base_scaling(0.3, -0.7), sheen.base_scaling(0.3, 0.7));
        assert_eq!(sheen_albedo(f32::NAN, alpha), sheen_albedo(0.0, alpha));
        assert_eq!(sheen_albedo(0.5, f32::NAN), sheen_albedo(0.5, MIN_ALPHA));
    }
}
