//! A dielectric interface (glass, water): smooth or rough (GGX microfacets), with reflection
//! and refraction, and a thin-walled form (a sheet of glass with parallel faces).
//!
//! Conventions are [`crate::bsdf`]'s: local shading frame, z the shading normal turned toward
//! the side the path arrives from, so `wo.z > 0` (values are zero and sampling fails
//! otherwise); `wi.z > 0` is reflection, `wi.z < 0` transmission; values in 1/sr without the
//! cosine, densities per steradian. η (`eta`) is the *relative* index of refraction
//! n_t / n_i across the interface as seen from `wo`'s side: the caller passes the material's
//! `ior` when the path arrives at the front face and `1/ior` when it arrives from behind.
//!
//! # Fresnel
//! [`fresnel_dielectric`] is the exact unpolarised reflectance of a dielectric interface
//! (pbrt-v4's `FrDielectric`): with cos θt from Snell's law, sin θt = sin θi / η,
//!
//! ```text
//! r∥ = (η cos θi − cos θt) / (η cos θi + cos θt),   r⊥ = (cos θi − η cos θt) / (cos θi + η cos θt)
//! Fr = (r∥² + r⊥²) / 2,      Fr = 1 under total internal reflection (sin θt ≥ 1)
//! ```
//!
//! # Smooth interface (α < 10⁻³, or η = 1)
//! Two delta lobes (pbrt-v4's rule `EffectivelySmooth`): the mirror direction
//! wi = (−wo.x, −wo.y, wo.z) with probability R = Fr(cos θo, η), and the refracted direction
//! (η sin θt = sin θo, azimuth opposite to `wo`'s) with probability T = 1 − R. [`Bxdf::sample`]
//! returns them with `delta: true`, `pdf` = the lobe's probability and
//! `f` = R / |cos θi| or T · tint / (η² |cos θi|), so that the Monte Carlo weight
//! f |cos θi| / pdf is 1 for reflection and tint / η² for transmission. [`Bxdf::eval`] and
//! [`Bxdf::pdf`] are zero. An index-matched interface (η = 1) lets light through unbent.
//!
//! # Rough interface (Walter et al. 2007, as pbrt-v4's `DielectricBxDF`)
//! With D, G the GGX distribution and height-correlated Smith masking-shadowing
//! ([`GgxDistribution::d`], [`GgxDistribution::g2`]; α = roughness², glTF's perceptual
//! roughness) and the generalised half vector wm = ±normalize(η' wi + wo) turned to +z
//! (η' = 1 for reflection, η for transmission), microfacets that face away from `wo` or from
//! `wi` (wo·wm ≤ 0, or wi·wm and cos θi of opposite signs) contribute nothing, and with
//! F = Fr(wo·wm, η):
//!
//! ```text
//! f_R = D(wm) G(wo, wi) F / (4 |cos θi cos θo|)
//! f_T = D(wm) G(wo, wi) (1 − F) |wi·wm| |wo·wm| / (|cos θi cos θo| (wi·wm + wo·wm/η)²) · tint / η²
//! ```
//!
//! Sampling draws wm from the normals visible from `wo` (density D_wo(wm) =
//! [`GgxDistribution::visible_normal_pdf`]), then reflects `wo` about wm with probability F
//! or refracts it with probability 1 − F. The densities over `wi` follow from the Jacobians
//! dwm/dwi = 1 / (4 |wo·wm|) (reflection) and |wi·wm| / (wi·wm + wo·wm/η)² (refraction):
//!
//! ```text
//! pdf_R = D_wo(wm) / (4 |wo·wm|) · F,      pdf_T = D_wo(wm) |wi·wm| / (wi·wm + wo·wm/η)² · (1 − F)
//! ```
//!
//! Samples whose direction ends on the wrong side (a reflection below the horizon, a
//! refraction above it) are lost (`None`), as are refractions under total internal
//! reflection, which the choice by F makes impossible except by rounding. Every sample's
//! energy weight (the weight times η² for transmission) is G(wo, wi) / G1(wo) ≤ 1: single
//! scattering, so rough glass loses the energy of light that would scatter between
//! microfacets more than once (at η = 1.5, roughness 0.3: 0.1 % at normal incidence,
//! about 5 % at θo = 80°).
//!
//! # Radiance scaling
//! Transmitted values are divided by η² (pbrt-v4's `TransportMode::Radiance`): radiance
//! entering a denser medium is compressed into a smaller solid angle. The BSDF is therefore
//! not symmetric in transmission; it satisfies the generalised reciprocity
//! η² f_T(wo, wi; η) = f_T(wi*, wo*; 1/η), with w* = (w.x, w.y, −w.z) the direction seen in
//! the frame turned toward the other side (Veach 1997, §5.2: f(wo, wi)/n_o² =
//! f(wi, wo)/n_i² with n_o = 1 and n_i = η). Reflection is symmetric, f_R(wo, wi) =
//! f_R(wi, wo).
//!
//! # Thin-walled form ([`Dielectric::thin`])
//! A sheet whose two faces are parallel and close (glTF's transmission without
//! `KHR_materials_volume`; Mitsuba's `thindielectric`): light enters and leaves the same
//! medium, so there is no bending and no η² factor, and the sheet looks the same from both
//! faces (η and 1/η give the same thin BSDF; it uses whichever is ≥ 1). Summing the
//! interreflections between the faces (Mitsuba's formula) with R = Fr(cos θo, η),
//!
//! ```text
//! R' = R + T² R / (1 − R²) = 2R / (1 + R),     T' = 1 − R'   (T = 1 − R; absorption ignored)
//! ```
//!
//! Smooth: the mirror direction with probability R' and weight 1; straight through,
//! wi = −wo, with probability T' and weight tint (both delta lobes).
//!
//! Rough (an approximation, as the glTF sample viewer's thin-walled model): the GGX
//! reflection lobe D G R'(wo·wm) / (4 |cos θi cos θo|) with wm = normalize(wo + wi), and
//! "transmission" as the same lobe mirrored through the surface: f_T(wo, wi) =
//! D G (1 − R'(wo·wm)) tint / (4 |cos θi cos θo|) with wm the half vector of `wo` and
//! wi* = (wi.x, wi.y, −wi.z). The transmitted light is blurred around −wo as if both faces
//! were one rough interface; the true two-interface spread (and its dependence on η) is
//! not modelled. Sampling reflects about a visible normal and keeps the reflection with
//! probability R'(wo·wm), mirrors it otherwise. The lobes' energy weights sum to at most 1
//! (that of a white GGX mirror).
//!
//! # One formulation
//! The formulas are written once over [`Real`] values (`DielectricLobes`, masks where one
//! point would branch): [`Dielectric`]'s [`Bxdf`] methods evaluate them for one point, the
//! path tracer's glass kernel for sixteen vertices at once, so each lane gets the scalar
//! bits.
//!
//! # References
//! - B. Walter, S. Marschner, H. Li, K. Torrance, "Microfacet Models for Refraction through
//!   Rough Surfaces", EGSR 2007.
//! - M. Pharr, W. Jakob, G. Humphreys, *Physically Based Rendering*, 4th ed., §9.3
//!   (`FrDielectric`), §9.5 (`DielectricBxDF`), §9.5.2 (`ThinDielectricBxDF`).
//! - E. Veach, *Robust Monte Carlo Methods for Light Transport Simulation*, PhD thesis, 1997,
//!   §5.2 (non-symmetric scattering due to refraction).
//! - Mitsuba 3, `thindielectric` plugin; Khronos glTF sample viewer, thin-walled
//!   transmission.
//!
//! # Example
//! ```
//! use glam::{Vec2, Vec3};
//! use renderer::bsdf::{Bxdf, Dielectric};
//!
//! let glass = Dielectric::new(1.5, 0.3);
//! let wo = Vec3::new(0.6, 0.0, 0.8);
//! if let Some(s) = glass.sample(wo, Vec2::new(0.3, 0.7), 0.9) {
//!     assert!(!s.delta);
//!     assert!((glass.pdf(wo, s.wi) - s.pdf).abs() <= 1e-3 * s.pdf);
//! }
//! // Smooth glass seen head-on reflects ((1.5 − 1) / (1.5 + 1))² = 4 %.
//! let smooth = Dielectric::new(1.5, 0.0);
//! let s = smooth.sample(Vec3::Z, Vec2::ZERO, 0.0).unwrap();
//! assert!(s.delta && s.wi == Vec3::Z && (s.pdf - 0.04).abs() < 1e-6);
//! ```

use super::microfacet::{reflect_about, Ggx, GgxDistribution};
use super::{BsdfSample, Bxdf, RealBxdf, RealSample};
use crate::lanes::{choose, F32s, Mask, MaskOps, Real, SetLane, V2, V3};
use crate::Rgb;
use glam::{Vec2, Vec3};

/// GGX roughness α below which the interface is treated as perfectly smooth (delta lobes),
/// pbrt-v4's `TrowbridgeReitzDistribution::EffectivelySmooth` (equal to
/// [`super::microfacet::MIN_ALPHA`], the smallest α a [`GgxDistribution`] accepts).
pub const SMOOTH_ALPHA: f32 = 1e-3;

/// Smallest relative index of refraction [`Dielectric::new`] accepts; larger ones are
/// capped at its inverse.
pub const MIN_ETA: f32 = 0.01;

/// Unpolarised Fresnel reflectance of a dielectric interface (dimensionless, in [0, 1]) for
/// light arriving at angle θi from the interface's normal, with η = n_t / n_i the relative
/// index of refraction (n_i on the side of the normal). pbrt-v4's `FrDielectric`:
/// `cos_theta_i` is clamped to [−1, 1]; a negative cosine means the light arrives from the
/// other side, which is the interface with 1/η. Returns 1 under total internal reflection
/// (and on the horizon, or for a NaN cosine), ((η − 1)/(η + 1))² at normal incidence, 0 for
/// η = 1 (no interface) at every angle.
#[inline]
pub fn fresnel_dielectric(cos_theta_i: f32, eta: f32) -> f32 {
    fresnel(cos_theta_i, eta)
}

/// [`fresnel_dielectric`] over [`Real`] values.
#[inline(always)]
fn fresnel<R: Real>(cos_theta_i: R, eta: R) -> R {
    let (zero, one) = (R::splat(0.0), R::splat(1.0));
    let cos = cos_theta_i.clamp(-1.0, 1.0);
    // Arriving from the other side: the interface with 1/η.
    let behind = cos.lt(zero);
    let eta_i = R::select(behind, one / eta, eta);
    let cos_i = R::select(behind, -cos, cos);
    let sin2_i = one - cos_i * cos_i;
    let sin2_t = sin2_i / (eta_i * eta_i);
    let cos_t = (one - sin2_t).max(zero).sqrt();
    let r_parallel = (eta_i * cos_i - cos_t) / (eta_i * cos_i + cos_t);
    let r_perpendicular = (cos_i - eta_i * cos_t) / (cos_i + eta_i * cos_t);
    let r = (R::splat(0.5) * (r_parallel * r_parallel + r_perpendicular * r_perpendicular)).clamp(0.0, 1.0);
    // Total internal reflection (and NaN inputs) reflect everything rather than propagate
    // NaN; η = 1 is no interface (also on the horizon, where the formulas are 0/0).
    R::select(eta.eq(one), zero, R::select(sin2_t.lt(one), r, one))
}

/// Reflectance R' = R + T² R / (1 − R²) = 2R / (1 + R) of a thin sheet with parallel faces
/// (both interreflections and both interfaces summed, no absorption; Mitsuba's
/// `thindielectric`), with R = [`fresnel_dielectric`]`(cos_theta, eta)` and η ≥ 1 the
/// sheet's index relative to the surrounding medium. Dimensionless, in [0, 1]; the sheet
/// transmits 1 − R'.
#[inline]
pub fn thin_reflectance(cos_theta: f32, eta: f32) -> f32 {
    sheet_reflectance(fresnel(cos_theta, eta))
}

/// R' = 2R / (1 + R) of a sheet whose faces reflect R each ([`thin_reflectance`]).
#[inline(always)]
fn sheet_reflectance<R: Real>(r: R) -> R {
    R::splat(2.0) * r / (R::splat(1.0) + r)
}

/// The direction refracted from `w` through an interface with unit normal `n` on `w`'s side
/// (w·n > 0) and relative index η = n_t / n_i (Snell's law, η sin θt = sin θi): pointing
/// away from the surface on the other side, unit length. `None` under total internal
/// reflection.
#[inline]
pub fn refract(w: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let (wt, ok) = refract_real(w.into(), n.into(), eta);
    ok.then(|| wt.into())
}

/// [`refract`] over [`Real`] values: the refracted direction, and where it exists.
#[inline(always)]
fn refract_real<R: Real>(w: V3<R>, n: V3<R>, eta: R) -> (V3<R>, R::Mask) {
    let (zero, one) = (R::splat(0.0), R::splat(1.0));
    let cos_i = w.dot(n);
    let sin2_i = (one - cos_i * cos_i).max(zero);
    let sin2_t = sin2_i / (eta * eta);
    let cos_t = (one - sin2_t).sqrt();
    let (wt, unit) = (-w / eta + n * (cos_i / eta - cos_t)).try_normalize();
    (wt, unit & sin2_t.lt(one))
}

/// `w` seen from the other side of the surface: z negated.
#[inline(always)]
fn flip_z<R: Real>(w: V3<R>) -> V3<R> {
    V3::new(w.x, w.y, -w.z)
}

/// Clamps to [0, 1]; NaN becomes 0.
#[inline]
fn clamp01(x: f32) -> f32 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(0.0, 1.0)
    }
}

/// A dielectric interface (glass): smooth or rough, bulk or thin-walled; see the
/// [module documentation](self) for the model.
///
/// Built with [`Dielectric::new`] and the builders [`Dielectric::with_tint`] and
/// [`Dielectric::thin`]; its parameters are read through accessors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dielectric {
    /// Relative index of refraction η = n_t / n_i seen from `wo`'s side, in
    /// [[`MIN_ETA`], 1/[`MIN_ETA`]].
    eta: f32,
    /// glTF perceptual roughness in [0, 1]; α = roughness².
    roughness: f32,
    /// The microfacet distribution (α clamped to [`super::microfacet::MIN_ALPHA`], 1).
    distribution: GgxDistribution,
    /// Factor of transmitted light per channel, in [0, 1] (linear RGB).
    tint: Rgb,
    /// Thin-walled (a sheet) rather than the boundary of a solid.
    thin: bool,
}

impl Dielectric {
    /// A clear dielectric boundary with relative index of refraction `eta` = n_t / n_i as
    /// seen from the side `wo` lies on (the material's ior from the front, 1/ior from
    /// behind), clamped to [[`MIN_ETA`], 1/[`MIN_ETA`]] (NaN, zero or negative become 1),
    /// and glTF perceptual `roughness` clamped to [0, 1] (NaN becomes 0); the GGX roughness
    /// is α = roughness², and α < [`SMOOTH_ALPHA`] (roughness < 0.0316) is a smooth
    /// interface.
    #[inline]
    pub fn new(eta: f32, roughness: f32) -> Self {
        let eta = if eta > 0.0 {
            eta.clamp(MIN_ETA, 1.0 / MIN_ETA)
        } else {
            1.0
        };
        let roughness = clamp01(roughness);
        Dielectric {
            eta,
            roughness,
            distribution: GgxDistribution::from_roughness(roughness),
            tint: Rgb::ONE,
            thin: false,
        }
    }

    /// The same interface with transmitted light multiplied by `tint` per channel (glTF's
    /// base colour for transmission; linear RGB), clamped to [0, 1] (NaN becomes 0).
    /// Reflection is untinted. The default is white.
    #[inline]
    pub fn with_tint(self, tint: Rgb) -> Self {
        Dielectric {
            tint: Rgb::new(clamp01(tint.x), clamp01(tint.y), clamp01(tint.z)),
            ..self
        }
    }

    /// The thin-walled form of the same material: a sheet with the same medium on both sides
    /// (module documentation).
    #[inline]
    pub fn thin(self) -> Self {
        Dielectric { thin: true, ..self }
    }

    /// The relative index of refraction η = n_t / n_i as given (after clamping).
    #[inline]
    pub fn eta(&self) -> f32 {
        self.eta
    }

    /// glTF perceptual roughness in [0, 1].
    #[inline]
    pub fn roughness(&self) -> f32 {
        self.roughness
    }

    /// GGX roughness α = roughness² (before the distribution's clamping).
    #[inline]
    pub fn alpha(&self) -> f32 {
        self.roughness * self.roughness
    }

    /// The microfacet distribution of the rough interface.
    #[inline]
    pub fn distribution(&self) -> GgxDistribution {
        self.distribution
    }

    /// Factor of transmitted light per channel, in [0, 1].
    #[inline]
    pub fn tint(&self) -> Rgb {
        self.tint
    }

    /// Whether this is the thin-walled form.
    #[inline]
    pub fn is_thin(&self) -> bool {
        self.thin
    }

    /// Whether the interface is treated as perfectly smooth (delta lobes only, so
    /// [`Bxdf::eval`] and [`Bxdf::pdf`] are zero): α < [`SMOOTH_ALPHA`], or η = 1 (an
    /// index-matched interface lets light through unbent).
    #[inline]
    pub fn is_smooth(&self) -> bool {
        self.alpha() < SMOOTH_ALPHA || self.eta == 1.0
    }

    /// The interface's formulas ([`DielectricLobes`]) for one shading point.
    #[inline(always)]
    pub(crate) fn lobes(&self) -> DielectricLobes<f32> {
        DielectricLobes {
            eta: self.eta,
            ggx: self.distribution.formulas(),
            tint: self.tint.into(),
            thin: self.thin,
            smooth: self.is_smooth(),
        }
    }
}

/// The dielectric's formulas over [`Real`] values (the module documentation has them): for
/// one shading point ([`Dielectric::lobes`], what its [`Bxdf`] implementation evaluates) or
/// for [`LANES`](crate::lanes::LANES) points with their own interfaces (the path tracer's
/// glass kernel fills one lane per vertex with [`DielectricLobes::set`]). Masks stand where
/// one point would branch, so each lane gets the scalar bits.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct DielectricLobes<R: Real> {
    /// Relative index of refraction η seen from `wo`'s side.
    eta: R,
    /// The rough interface's microfacet distribution.
    ggx: Ggx<R>,
    /// Factor of transmitted light per channel.
    tint: V3<R>,
    /// Thin-walled.
    thin: R::Mask,
    /// Delta lobes only ([`Dielectric::is_smooth`]).
    smooth: R::Mask,
}

impl DielectricLobes<F32s> {
    /// Sets lane `i` to one shading point's interface.
    #[inline]
    pub fn set(&mut self, i: usize, one: &DielectricLobes<f32>) {
        self.eta.set_lane(i, one.eta);
        self.ggx.alpha_x.set_lane(i, one.ggx.alpha_x);
        self.ggx.alpha_y.set_lane(i, one.ggx.alpha_y);
        self.tint.set_lane(i, one.tint);
        self.thin.0[i] = one.thin;
        self.smooth.0[i] = one.smooth;
    }

    /// Whether every lane's interface is smooth (delta lobes only).
    #[inline(always)]
    pub fn all_smooth(&self) -> bool {
        self.smooth.all()
    }

    /// `a`'s interface where `mask` is set, `b`'s elsewhere.
    #[inline(always)]
    pub fn select(mask: Mask, a: &Self, b: &Self) -> Self {
        DielectricLobes {
            eta: F32s::select(mask, a.eta, b.eta),
            ggx: Ggx {
                alpha_x: F32s::select(mask, a.ggx.alpha_x, b.ggx.alpha_x),
                alpha_y: F32s::select(mask, a.ggx.alpha_y, b.ggx.alpha_y),
            },
            tint: mask.select(a.tint, b.tint),
            thin: mask.select(a.thin, b.thin),
            smooth: mask.select(a.smooth, b.smooth),
        }
    }
}

impl<R: Real> DielectricLobes<R> {
    /// Fraction of light the interface reflects for the cosine `cos_theta` between `wo` and
    /// the (micro)normal: Fr, or R' for a thin sheet, which looks the same from both faces
    /// (its index max(η, 1/η) ≥ 1).
    #[inline(always)]
    fn reflectance(&self, cos_theta: R) -> R {
        let sheet_eta = self.eta.max(R::splat(1.0) / self.eta);
        let r = fresnel(cos_theta, R::select(self.thin, sheet_eta, self.eta));
        R::select(self.thin, sheet_reflectance(r), r)
    }

    /// [`Bxdf::sample`] of the smooth interface (delta lobes), `wo.z > 0`.
    #[inline(always)]
    fn sample_smooth(&self, wo: V3<R>, uc: R) -> RealSample<R> {
        let (zero, one) = (R::splat(0.0), R::splat(1.0));
        let r = self.reflectance(wo.z);
        let t = one - r;
        let reflection = uc.lt(r) | t.le(zero);
        let wr = V3::new(-wo.x, -wo.y, wo.z);
        let fr = r / wr.z;
        // Refraction (straight through a thin sheet), radiance scaled by 1/η² across a bulk
        // interface.
        let (refracted, refracts) = refract_real(wo, V3::new(zero, zero, one), self.eta);
        let wt = self.thin.select(-wo, refracted);
        let radiance_scale = R::select(self.thin, one, one / (self.eta * self.eta));
        let ft = self.tint * (t * radiance_scale / -wt.z);
        let transmits = (self.thin | refracts) & wt.z.lt(zero) & ft.is_finite();
        RealSample {
            ok: reflection | transmits,
            wi: reflection.select(wr, wt),
            f: reflection.select(V3::new(fr, fr, fr), ft),
            pdf: R::select(reflection, r, t),
            delta: R::Mask::splat(true),
        }
    }

    /// Value and density of the rough interface's refraction through the microfacet normal
    /// `wm`, with cos_om = wo·wm > 0, cos_im = wi·wm < 0 and `t` the Fresnel transmittance;
    /// zero where the Jacobian's denominator vanishes or either is not finite.
    #[inline(always)]
    fn rough_transmission(&self, wo: V3<R>, wi: V3<R>, wm: V3<R>, cos_om: R, cos_im: R, t: R) -> (V3<R>, R) {
        let zero = R::splat(0.0);
        let eta = self.eta;
        // (η wi·wm + wo·wm)² = η² (wi·wm + wo·wm/η)²: the Jacobian's denominator, which also
        // carries the radiance scaling 1/η² of the value.
        let s = eta * cos_im + cos_om;
        let s2 = s * s;
        // D G (1 − F) |wi·wm wo·wm| / (|cos θi cos θo| (η wi·wm + wo·wm)²), with
        // G / (|cos θi cos θo|) = 4 V.
        let value = self.ggx.d(wm) * 4.0 * self.ggx.visibility(wo, wi) * t * (cos_im * cos_om).abs() / s2;
        let dwm_dwi = eta * eta * cos_im.abs() / s2;
        let density = self.ggx.visible_normal_pdf(wo, wm) * dwm_dwi * t;
        let ok = s2.gt(zero) & t.gt(zero) & value.is_finite() & density.is_finite();
        (ok.select(self.tint * value, V3::default()), R::select(ok, density, zero))
    }

    /// [`Bxdf::sample`] of the rough interface, `wo.z > 0`.
    #[inline(always)]
    fn sample_rough(&self, wo: V3<R>, u: V2<R>, uc: R) -> RealSample<R> {
        let (zero, one) = (R::splat(0.0), R::splat(1.0));
        let wm = self.ggx.sample_visible_normal(wo, u);
        let cos_om = wo.dot(wm);
        let r = self.reflectance(cos_om);
        let t = one - r;
        let reflection = uc.lt(r) | r.ge(one);
        let wr = reflect_about(wo, wm);
        // Reflection about wm, and a thin sheet's transmission (the reflection mirrored).
        let value = self.ggx.d(wm) * self.ggx.visibility(wo, wr);
        let density = self.ggx.visible_normal_pdf(wo, wm) / (R::splat(4.0) * cos_om);
        let mirrored = reflection | self.thin;
        let (wi, (f, pdf), side) = choose!(
            mirrored,
            {
                let thin_transmission = (self.tint * (value * t), density * t);
                let reflected = (V3::new(value * r, value * r, value * r), density * r);
                (reflection.select(wr, flip_z(wr)), reflection.select(reflected, thin_transmission), !wr.z.le(zero))
            },
            {
                let (wi, refracts) = refract_real(wo, wm, self.eta);
                (wi, self.rough_transmission(wo, wi, wm, cos_om, wi.dot(wm), t), refracts & !wi.z.ge(zero))
            },
        );
        let ok = !cos_om.le(zero) & side & pdf.gt(zero) & pdf.is_finite() & f.is_finite();
        RealSample::new(ok, wi, f, pdf)
    }
}

impl<R: Real> RealBxdf<R> for DielectricLobes<R> {
    type AtWo = ();

    #[inline(always)]
    fn at_wo(&self, _wo: V3<R>) {}

    /// The rough interface's value and density (module documentation); zero for a smooth
    /// one (delta lobes only), where `wo.z ≤ 0`, `wi.z = 0` or `wi` is not finite.
    #[inline(always)]
    fn eval_pdf(&self, _at: (), wo: V3<R>, wi: V3<R>) -> (V3<R>, R) {
        let (zero, one) = (R::splat(0.0), R::splat(1.0));
        let valid = wo.z.gt(zero) & !self.smooth & !wi.z.eq(zero) & wi.is_finite();
        if !valid.any() {
            return (V3::default(), zero);
        }
        let reflection = wi.z.gt(zero);
        // A thin sheet's transmission is its reflection lobe mirrored through the surface:
        // the half vector of wo and the mirrored wi.
        let wr = reflection.select(wi, flip_z(wi));
        let (thin_half, thin_ok) = (wo + wr).try_normalize();
        // Elsewhere the generalised half vector, turned to +z.
        let eta_prime = R::select(reflection, one, self.eta);
        let (half, half_ok) = (wi * eta_prime + wo).try_normalize();
        let half = half.z.lt(zero).select(-half, half);
        let wm = self.thin.select(thin_half, half);
        let (cos_om, cos_im) = (wo.dot(wm), wi.dot(wm));
        // Microfacets facing away from either direction contribute nothing.
        let facing = !cos_om.le(zero) & (self.thin | !(cos_im * wi.z).le(zero));
        let ok = valid & self.thin.select(thin_ok, half_ok) & facing;
        let r = self.reflectance(cos_om);
        let t = one - r;
        let value = self.ggx.d(wm) * self.ggx.visibility(wo, wr);
        let density = self.ggx.visible_normal_pdf(wo, wm) / (R::splat(4.0) * cos_om);
        let reflected = (V3::new(value * r, value * r, value * r), density * r);
        let transmitted = choose!(self.thin, (self.tint * (value * t), density * t), self.rough_transmission(wo, wi, wm, cos_om, cos_im, t));
        let (f, pdf) = reflection.select(reflected, transmitted);
        (ok.select(f, V3::default()), R::select(ok, pdf, zero))
    }

    /// Smooth: a delta sample, reflection when `uc` < R (or R'), refraction (straight
    /// through a thin sheet) otherwise; `u` is unused. Rough: a GGX visible normal from
    /// `u`, then reflection when `uc` < F(wo·wm) (or R'), refraction otherwise. Not `ok`
    /// where `wo.z ≤ 0` or the drawn direction ends on the wrong side of the surface.
    #[inline(always)]
    fn sample(&self, _at: (), wo: V3<R>, u: V2<R>, uc: R) -> RealSample<R> {
        let mut s = choose!(self.smooth, self.sample_smooth(wo, uc), self.sample_rough(wo, u, uc));
        s.ok = s.ok & wo.z.gt(R::splat(0.0));
        s
    }
}

impl Bxdf for Dielectric {
    /// f(wo, wi) in 1/sr (module documentation), transmission included; zero for a smooth
    /// interface (delta lobes only) and when `wo.z ≤ 0` or `wi.z = 0`.
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.eval_pdf(wo, wi).0
    }

    /// Solid-angle density (1/sr) of [`Bxdf::sample`] over both hemispheres; zero for a
    /// smooth interface and when `wo.z ≤ 0` or `wi.z = 0`.
    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    /// [`DielectricLobes`]' sample for this interface: `None` when `wo.z ≤ 0` or the drawn
    /// direction ends on the wrong side of the surface.
    #[inline]
    fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        let above = wo.z > 0.0; // false for NaN too
        if !above {
            return None;
        }
        self.lobes().sample((), wo.into(), u.into(), uc).into_option()
    }

    #[inline]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        let above = wo.z > 0.0; // false for NaN too
        if !above || self.is_smooth() {
            return (Rgb::ZERO, 0.0);
        }
        let (f, pdf) = self.lobes().eval_pdf((), wo.into(), wi.into());
        (f.into(), pdf)
    }

    /// True: glass scatters into both hemispheres.
    #[inline]
    fn transmits(&self) -> bool {
        true
    }

    /// [`Self::is_smooth`].
    #[inline]
    fn is_delta(&self) -> bool {
        self.is_smooth()
    }
}


#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::sample_uniform_sphere;
    use crate::testing::chi2::{self, Chi2Config, Chi2Domain};
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg32;

    /// `w` seen from the other side of the surface: z negated.
    fn mirrored(w: Vec3) -> Vec3 {
        Vec3::new(w.x, w.y, -w.z)
    }

    /// Roughnesses of the chi-square tests (α = 0.09 and 0.49).
    const CHI2_ROUGHNESSES: [f32; 2] = [0.3, 0.7];
    /// Viewing angles θo of the chi-square tests, in degrees.
    const CHI2_THETAS: [f32; 3] = [1.0, 40.0, 80.0];
    /// Number of chi-square tests in this module, for the Šidák correction: rough glass from
    /// outside and from inside, and the rough thin sheet, at each roughness and θo.
    const CHI2_TESTS: usize = 3 * CHI2_ROUGHNESSES.len() * CHI2_THETAS.len();

    /// Relative indices of the stiff cases: nearly index-matched, dense, and both seen from
    /// inside.
    const STIFF_ETAS: [f32; 4] = [1.0001, 3.0, 1.0 / 1.0001, 1.0 / 3.0];

    /// The unit direction at polar angle `theta` and azimuth `phi` (radians).
    fn spherical(theta: f32, phi: f32) -> Vec3 {
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    /// `wo` at `degrees` from the normal, at an azimuth off the grid's cell boundaries.
    fn wo_at(degrees: f32) -> Vec3 {
        spherical(degrees.to_radians(), 0.3)
    }

    fn close(a: f32, b: f32, relative: f32) -> bool {
        (a - b).abs() <= relative * a.abs().max(b.abs()) + 1e-12
    }

    /// Reference Fresnel reflectance in f64 (textbook formulas).
    fn fresnel_f64(cos_i: f64, eta: f64) -> f64 {
        let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
        if sin2_t >= 1.0 {
            return 1.0;
        }
        let cos_t = (1.0 - sin2_t).sqrt();
        let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
        let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
        0.5 * (rs * rs + rp * rp)
    }

    #[test]
    fn fresnel_dielectric_known_values() {
        for eta in [1.0001f32, 1.33, 1.5, 3.0, 1.0 / 1.5, 1.0 / 3.0] {
            let normal = ((eta - 1.0) / (eta + 1.0)).powi(2);
            assert!(
                close(fresnel_dielectric(1.0, eta), normal, 1e-4),
                "η = {eta}"
            );
            // From the other side, at normal incidence: the same.
            assert!(
                close(fresnel_dielectric(-1.0, eta), normal, 1e-4),
                "η = {eta}"
            );
            for cos in [0.05f32, 0.3, 0.7, 0.95] {
                let expected = fresnel_f64(cos as f64, eta as f64) as f32;
                assert!(
                    close(fresnel_dielectric(cos, eta), expected, 1e-4),
                    "η = {eta}, cos = {cos}"
                );
            }
        }
        // η = 1.5 at 45°: Rs = 0.0920, Rp = 0.0085 (textbook).
        assert!((fresnel_dielectric(std::f32::consts::FRAC_1_SQRT_2, 1.5) - 0.05024).abs() < 1e-4);
        for cos in [0.0f32, 0.2, 0.5, 1.0] {
            assert!(fresnel_dielectric(cos, 1.0).abs() < 1e-6, "cos = {cos}");
        }
        // Total internal reflection: from glass (η = 1/1.5) beyond the critical angle 41.8°.
        let critical = (1.0f32 / 1.5).asin();
        for theta in [critical + 1e-3, 1.0, 1.5, 1.57] {
            assert_eq!(
                fresnel_dielectric(theta.cos(), 1.0 / 1.5),
                1.0,
                "θ = {theta}"
            );
        }
        assert!(fresnel_dielectric((critical - 1e-2).cos(), 1.0 / 1.5) < 1.0);
        // Grazing incidence reflects everything, from either side (continuity at cos = 0).
        for eta in [1.5f32, 1.0 / 1.5] {
            assert!(fresnel_dielectric(1e-6, eta) > 0.999);
            assert!(fresnel_dielectric(-1e-6, eta) > 0.999);
            assert_eq!(fresnel_dielectric(0.0, eta), 1.0);
        }
        // Cosines slightly outside [−1, 1] (rounding) are clamped.
        for cos in [1.000_001f32, -1.000_001, 1.1] {
            let r = fresnel_dielectric(cos, 1.5);
            assert!(r.is_finite() && (r - 0.04).abs() < 1e-6, "cos = {cos}: {r}");
        }
        assert_eq!(fresnel_dielectric(f32::NAN, 1.5), 1.0);
    }

    #[test]
    fn fresnel_dielectric_is_the_same_interface_from_both_sides() {
        // Fr(−cos, η) = Fr(cos, 1/η), and the refracted ray sees the same reflectance:
        // Fr(cos θi, η) = Fr(cos θt, 1/η) (Stokes relations).
        for eta in [1.0001f32, 1.5, 3.0] {
            for cos_i in [0.01f32, 0.2, 0.5, 0.8, 1.0] {
                assert_eq!(
                    fresnel_dielectric(-cos_i, eta),
                    fresnel_dielectric(cos_i, 1.0 / eta)
                );
                let sin_t = (1.0 - cos_i * cos_i).sqrt() / eta;
                let cos_t = (1.0 - sin_t * sin_t).sqrt();
                let (a, b) = (
                    fresnel_dielectric(cos_i, eta),
                    fresnel_dielectric(cos_t, 1.0 / eta),
                );
                assert!(
                    (a - b).abs() < 2e-4,
                    "η = {eta}, cos θi = {cos_i}: {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn construction_clamps_and_classifies() {
        let d = Dielectric::new(f32::NAN, f32::NAN).with_tint(Rgb::new(-1.0, 2.0, f32::NAN));
        assert_eq!(d.eta(), 1.0);
        assert_eq!(d.roughness(), 0.0);
        assert_eq!(d.tint(), Rgb::new(0.0, 1.0, 0.0));
        assert!(d.is_smooth() && !d.is_thin() && d.transmits());
        assert_eq!(Dielectric::new(-2.0, 0.5).eta(), 1.0);
        assert_eq!(Dielectric::new(1e9, 0.5).eta(), 1.0 / MIN_ETA);
        assert_eq!(Dielectric::new(1.5, 0.5).tint(), Rgb::ONE);
        // α = roughness² < 10⁻³ is smooth: roughness 0.001 and 0.01 are, 0.05 is not.
        assert!(Dielectric::new(1.5, 0.001).is_smooth());
        assert!(Dielectric::new(1.5, 0.01).is_smooth());
        assert!(!Dielectric::new(1.5, 0.05).is_smooth());
        assert!(Dielectric::new(1.0, 0.5).is_smooth());
        assert!(Dielectric::new(1.5, 0.5).thin().is_thin());
        assert!((Dielectric::new(1.5, 0.5).alpha() - 0.25).abs() < 1e-7);
    }

    #[test]
    fn smooth_samples_are_mirror_or_snell_in_fresnel_proportion() {
        let n = 20_000;
        let mut rng = Pcg32::seed_from_u64(1);
        for eta in [1.5f32, 1.0 / 1.5, 3.0] {
            let glass = Dielectric::new(eta, 0.0).with_tint(Rgb::new(0.9, 0.6, 0.3));
            for degrees in [0.0f32, 30.0, 40.0, 60.0] {
                let wo = wo_at(degrees);
                let r = fresnel_dielectric(wo.z, eta);
                let mut reflections = 0usize;
                for _ in 0..n {
                    let s = glass
                        .sample(wo, Vec2::new(rng.random(), rng.random()), rng.random())
                        .expect("smooth glass always scatters");
                    assert!(s.delta);
                    assert_eq!(glass.eval(wo, s.wi), Rgb::ZERO);
                    assert_eq!(glass.pdf(wo, s.wi), 0.0);
                    if s.wi.z > 0.0 {
                        reflections += 1;
                        assert!((s.wi - Vec3::new(-wo.x, -wo.y, wo.z)).length() < 1e-6);
                        assert!(close(s.pdf, r, 1e-6));
                        assert!((s.weight() - Rgb::ONE).abs().max_element() < 1e-5, "{s:?}");
                    } else {
                        // Snell: η sin θt = sin θo, in the plane of incidence, opposite azimuth.
                        let sin_o = (wo.x * wo.x + wo.y * wo.y).sqrt();
                        let sin_t = (s.wi.x * s.wi.x + s.wi.y * s.wi.y).sqrt();
                        assert!(
                            (eta * sin_t - sin_o).abs() < 1e-5,
                            "η = {eta}, θo = {degrees}°"
                        );
                        assert!(s.wi.truncate().dot(wo.truncate()) <= 0.0);
                        assert!(s.wi.truncate().perp_dot(wo.truncate()).abs() < 1e-6);
                        assert!((s.wi.length() - 1.0).abs() < 1e-5);
                        assert!(close(s.pdf, 1.0 - r, 1e-5));
                        let expected = glass.tint() / (eta * eta);
                        assert!((s.weight() - expected).abs().max_element() < 1e-4, "{s:?}");
                    }
                }
                // Binomial: the fraction of reflections is R within 4 standard deviations.
                let fraction = reflections as f64 / n as f64;
                let sigma = (r as f64 * (1.0 - r as f64) / n as f64).sqrt();
                assert!(
                    (fraction - r as f64).abs() <= 4.0 * sigma + 1e-9,
                    "η = {eta}, θo = {degrees}°: {fraction} reflected, R = {r}"
                );
            }
        }
    }

    #[test]
    fn smooth_total_internal_reflection_reflects_only() {
        // From inside glass (η = 1/1.5) beyond the critical angle 41.8°, grazing included.
        let glass = Dielectric::new(1.0 / 1.5, 0.0);
        for degrees in [45.0f32, 60.0, 89.99] {
            let wo = wo_at(degrees);
            for k in 0..64 {
                let s = glass.sample(wo, Vec2::splat(0.5), k as f32 / 64.0).unwrap();
                assert!(s.delta && s.wi.z > 0.0, "θo = {degrees}°: {s:?}");
                assert_eq!(s.pdf, 1.0);
                assert!((s.weight() - Rgb::ONE).abs().max_element() < 1e-5);
            }
        }
    }

    #[test]
    fn smooth_reflection_and_transmission_conserve_energy() {
        // R + T = 1: the reflected weight f |cos θi| = R and the transmitted one, with the
        // radiance scaling 1/η² removed, f |cos θi| η² = T.
        for eta in STIFF_ETAS.into_iter().chain([1.5, 1.0 / 1.5]) {
            for degrees in [0.0f32, 20.0, 45.0, 70.0, 89.0, 89.99] {
                let wo = wo_at(degrees);
                let glass = Dielectric::new(eta, 0.0);
                let reflected = glass.sample(wo, Vec2::ZERO, 0.0).unwrap();
                let mut energy = reflected.f.x * reflected.wi.z.abs();
                if let Some(t) = glass
                    .sample(wo, Vec2::ZERO, 1.0 - f32::EPSILON)
                    .filter(|s| s.wi.z < 0.0)
                {
                    energy += t.f.x * t.wi.z.abs() * eta * eta;
                }
                assert!(
                    (energy - 1.0).abs() < 1e-4,
                    "η = {eta}, θo = {degrees}°: {energy}"
                );
            }
        }
    }

    #[test]
    fn thin_smooth_sheet() {
        let tint = Rgb::new(0.8, 0.5, 0.2);
        for degrees in [0.0f32, 45.0, 80.0, 89.99] {
            let wo = wo_at(degrees);
            let r = fresnel_dielectric(wo.z, 1.5);
            let r_sheet = r + (1.0 - r) * (1.0 - r) * r / (1.0 - r * r);
            // The sheet is the same from both faces: η and 1/η (no total internal reflection).
            for eta in [1.5f32, 1.0 / 1.5] {
                let sheet = Dielectric::new(eta, 0.0).with_tint(tint).thin();
                let reflected = sheet.sample(wo, Vec2::ZERO, 0.0).unwrap();
                assert!(reflected.delta && reflected.wi.z > 0.0);
                assert!(
                    close(reflected.pdf, r_sheet, 1e-5),
                    "{} vs {r_sheet}",
                    reflected.pdf
                );
                assert!((reflected.weight() - Rgb::ONE).abs().max_element() < 1e-5);
                let through = sheet.sample(wo, Vec2::ZERO, 1.0 - f32::EPSILON).unwrap();
                assert!(through.delta && through.wi == -wo);
                assert!(close(through.pdf, 1.0 - r_sheet, 1e-5));
                assert!((through.weight() - tint).abs().max_element() < 1e-5);
                // No η² factor: reflected + transmitted energy (white) is 1.
                let energy = reflected.f.x * wo.z + through.f.x / tint.x * wo.z;
                assert!((energy - 1.0).abs() < 1e-4);
            }
        }
    }

    /// The chi-square test and the sample/eval/pdf consistency check at the chi-square
    /// angles and roughnesses.
    fn check_chi2(make: impl Fn(f32) -> Dielectric, name: &str) {
        let config = Chi2Config::default()
            .with_sample_count(200_000)
            .with_domain(Chi2Domain::ThetaPhi)
            .with_test_count(CHI2_TESTS);
        for (i, roughness) in CHI2_ROUGHNESSES.into_iter().enumerate() {
            let glass = make(roughness);
            for (j, degrees) in CHI2_THETAS.into_iter().enumerate() {
                let wo = wo_at(degrees);
                let config = config.clone().with_seed((3 * i + j) as u64);
                let result = chi2::test_bxdf(&glass, wo, &config);
                assert!(
                    result.passed(),
                    "{name}, roughness {roughness}, θo = {degrees}°\n{result}"
                );
                let report = chi2::check_sample_consistency(&glass, wo, 2_000);
                assert!(
                    report.passed(),
                    "{name}, roughness {roughness}, θo = {degrees}°\n{report}"
                );
                assert!(report.valid > 1_000, "{report}");
            }
        }
    }

    #[test]
    fn rough_glass_from_outside_passes_chi2() {
        check_chi2(
            |r| Dielectric::new(1.5, r).with_tint(Rgb::new(0.9, 0.7, 0.4)),
            "η = 1.5",
        );
    }

    #[test]
    fn rough_glass_from_inside_passes_chi2() {
        check_chi2(|r| Dielectric::new(1.0 / 1.5, r), "η = 1/1.5");
    }

    #[test]
    fn rough_thin_sheet_passes_chi2() {
        check_chi2(
            |r| {
                Dielectric::new(1.5, r)
                    .with_tint(Rgb::new(0.9, 0.7, 0.4))
                    .thin()
            },
            "thin η = 1.5",
        );
    }

    /// Directional albedo by importance sampling, as the fraction of energy: transmitted
    /// weights are multiplied by η² (the radiance scaling removed) unless `thin`.
    fn energy_albedo(glass: &Dielectric, wo: Vec3, n: usize) -> f64 {
        let mut rng = Pcg32::seed_from_u64(5);
        let scale = if glass.is_thin() {
            1.0
        } else {
            glass.eta() * glass.eta()
        };
        let mut sum = 0.0f64;
        for _ in 0..n {
            let u = Vec2::new(rng.random(), rng.random());
            if let Some(s) = glass.sample(wo, u, rng.random()) {
                let w = s.weight().x * if s.wi.z < 0.0 { scale } else { 1.0 };
                assert!(w.is_finite() && w >= 0.0, "{glass:?}, wo = {wo}: {s:?}");
                sum += w as f64;
            }
        }
        sum / n as f64
    }

    #[test]
    fn rough_glass_does_not_create_energy() {
        let n = 20_000;
        for eta in [1.5f32, 1.0 / 1.5, 3.0, 1.0 / 3.0, 1.0001] {
            for roughness in [0.1f32, 0.3, 0.7, 1.0] {
                for thin in [false, true] {
                    let glass = Dielectric::new(eta, roughness);
                    let glass = if thin { glass.thin() } else { glass };
                    for degrees in [0.0f32, 45.0, 80.0, 89.0] {
                        let albedo = energy_albedo(&glass, wo_at(degrees), n);
                        assert!(
                            albedo <= 1.0 + 1e-3,
                            "η = {eta}, roughness {roughness}, thin {thin}, θo = {degrees}°: {albedo}"
                        );
                        if eta == 1.5 && roughness == 0.3 && !thin {
                            println!("η = 1.5, roughness 0.3, θo = {degrees}°: energy albedo {albedo:.4}");
                            assert!(albedo >= 0.8, "θo = {degrees}°: {albedo}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn nearly_smooth_rough_glass_splits_energy_by_fresnel() {
        // At roughness 0.05 (α = 0.0025) the microfacets barely tilt: the energy reflected
        // is R = Fr(cos θo, η) (R' for a sheet) and the energy transmitted (η² removed) is
        // 1 − R, up to the little lost to shadowing, as for the smooth interface.
        let n = 20_000;
        for (eta, thin) in [
            (1.5f32, false),
            (1.0 / 1.5, false),
            (3.0, false),
            (1.5, true),
        ] {
            let glass = Dielectric::new(eta, 0.05).with_tint(Rgb::new(1.0, 0.5, 0.25));
            let glass = if thin { glass.thin() } else { glass };
            let scale = if thin { 1.0 } else { eta * eta };
            for degrees in [0.0f32, 30.0, 60.0] {
                let wo = wo_at(degrees);
                let expected = glass.lobes().reflectance(wo.z);
                let mut rng = Pcg32::seed_from_u64(9);
                let (mut reflected, mut transmitted) = (0.0f64, 0.0f64);
                for _ in 0..n {
                    let u = Vec2::new(rng.random(), rng.random());
                    let Some(s) = glass.sample(wo, u, rng.random()) else {
                        continue;
                    };
                    let w = s.weight();
                    if s.wi.z > 0.0 {
                        reflected += w.x as f64;
                    } else {
                        // The tint applies to transmission only.
                        assert!(
                            (w.y - 0.5 * w.x).abs() <= 1e-5 * w.x
                                && (w.z - 0.25 * w.x).abs() <= 1e-5 * w.x
                        );
                        transmitted += (w.x * scale) as f64;
                    }
                }
                let (reflected, transmitted) = (reflected / n as f64, transmitted / n as f64);
                let what = format!("η = {eta}, thin {thin}, θo = {degrees}°");
                assert!(
                    (reflected - expected as f64).abs() < 0.01,
                    "{what}: reflected {reflected}, R = {expected}"
                );
                assert!(
                    (transmitted - (1.0 - expected) as f64).abs() < 0.01,
                    "{what}: transmitted {transmitted}, 1 − R = {}",
                    1.0 - expected
                );
            }
        }
    }

    /// Random unit directions, uniform on the sphere.
    fn random_directions(seed: u64, n: usize) -> Vec<Vec3> {
        let mut rng = Pcg32::seed_from_u64(seed);
        (0..n)
            .map(|_| sample_uniform_sphere(Vec2::new(rng.random(), rng.random())))
            .collect()
    }

    #[test]
    fn rough_reflection_is_reciprocal() {
        let dirs = random_directions(11, 400);
        for glass in [
            Dielectric::new(1.5, 0.3),
            Dielectric::new(1.0 / 1.5, 0.7),
            Dielectric::new(1.5, 0.5).thin(),
        ] {
            let mut nonzero = 0;
            for pair in dirs.chunks_exact(2) {
                let wo = Vec3::new(pair[0].x, pair[0].y, pair[0].z.abs());
                let wi = Vec3::new(pair[1].x, pair[1].y, pair[1].z.abs());
                let (a, b) = (glass.eval(wo, wi).x, glass.eval(wi, wo).x);
                assert!(
                    close(a, b, 1e-4),
                    "{glass:?}, wo = {wo}, wi = {wi}: {a} vs {b}"
                );
                nonzero += (a > 0.0) as usize;
            }
            assert!(nonzero > 150, "{nonzero}");
        }
    }

    #[test]
    fn rough_transmission_satisfies_generalised_reciprocity() {
        // Veach's f(wo, wi) / n_o² = f(wi, wo) / n_i², here with n_o = 1, n_i = η and the
        // frame turned toward wi's side for the reverse direction (w* = w with z negated):
        // η² f_T(wo, wi; η) = f_T(wi*, wo*; 1/η). Where the microfacet is nearly grazing for
        // the less dense side (wo·wm < 0.1 for η > 1), the other side sees it near the
        // critical angle, where Fr has a square-root singularity that amplifies the f32
        // rounding of wm: those pairs get a 2 % tolerance, the others 0.1 %.
        let dirs = random_directions(12, 2_000);
        let tint = Rgb::new(0.9, 0.6, 0.3);
        for eta in [1.5f32, 3.0, 1.0 / 1.5] {
            for roughness in [0.3f32, 0.7] {
                let forward = Dielectric::new(eta, roughness).with_tint(tint);
                let backward = Dielectric::new(1.0 / eta, roughness).with_tint(tint);
                let mut nonzero = 0;
                for pair in dirs.chunks_exact(2) {
                    let wo = Vec3::new(pair[0].x, pair[0].y, pair[0].z.abs());
                    let wi = Vec3::new(pair[1].x, pair[1].y, -pair[1].z.abs());
                    let a = forward.eval(wo, wi) * (eta * eta);
                    let b = backward.eval(mirrored(wi), mirrored(wo));
                    let wm = (wi * eta + wo).normalize();
                    let grazing = wo.dot(wm).abs().min(wi.dot(wm).abs()) < 0.1;
                    let tolerance = if grazing { 2e-2 } else { 1e-3 };
                    for c in 0..3 {
                        assert!(
                            close(a[c], b[c], tolerance),
                            "η = {eta}, roughness {roughness}, wo = {wo}, wi = {wi}: {a} vs {b}"
                        );
                    }
                    nonzero += (a.x > 0.0) as usize;
                }
                assert!(
                    nonzero > 100,
                    "η = {eta}, roughness {roughness}: {nonzero} pairs transmit"
                );
            }
        }
        // The thin sheet's transmission is symmetric, and the same from both faces.
        let sheet = Dielectric::new(1.5, 0.5).with_tint(tint).thin();
        let sheet_behind = Dielectric::new(1.0 / 1.5, 0.5).with_tint(tint).thin();
        for pair in dirs.chunks_exact(2) {
            let wo = Vec3::new(pair[0].x, pair[0].y, pair[0].z.abs());
            let wi = Vec3::new(pair[1].x, pair[1].y, -pair[1].z.abs());
            let (a, b) = (
                sheet.eval(wo, wi),
                sheet_behind.eval(mirrored(wi), mirrored(wo)),
            );
            assert!(
                (0..3).all(|c| close(a[c], b[c], 1e-4)),
                "wo = {wo}, wi = {wi}: {a} vs {b}"
            );
        }
    }

    #[test]
    fn stiff_cases_stay_finite() {
        let mut wos = vec![Vec3::Z];
        for degrees in [1e-3f32, 30.0, 75.0, 89.0, 89.99] {
            wos.push(spherical(degrees.to_radians(), 0.7));
        }
        let mut probes = random_directions(13, 64);
        for &wo in &wos {
            probes.extend([
                -wo,
                mirrored(wo),
                Vec3::new(-wo.x, -wo.y, wo.z),
                wo,
                Vec3::Z,
                -Vec3::Z,
            ]);
        }
        probes.extend([
            Vec3::X,
            -Vec3::Y,
            Vec3::new(1.0, 0.0, 1e-7).normalize(),
            Vec3::new(1.0, 0.0, -1e-7).normalize(),
        ]);
        for eta in STIFF_ETAS {
            for roughness in [0.001f32, 0.01, 0.04, 0.3, 1.0] {
                for thin in [false, true] {
                    let glass = Dielectric::new(eta, roughness).with_tint(Rgb::new(1.0, 0.5, 0.0));
                    let glass = if thin { glass.thin() } else { glass };
                    let what = format!("η = {eta}, roughness {roughness}, thin {thin}");
                    for &wo in &wos {
                        let mut wis = probes.clone();
                        if let Some(t) = refract(wo, Vec3::Z, eta) {
                            wis.push(t);
                        }
                        for k in 0..512u32 {
                            let u = Vec2::new(
                                (k % 16) as f32 / 16.0 + 0.03,
                                (k / 16 % 16) as f32 / 16.0,
                            );
                            let uc = (k / 256) as f32 * 0.5 + (k % 7) as f32 / 14.0;
                            let Some(s) = glass.sample(wo, u, uc) else {
                                continue;
                            };
                            let w = s.weight();
                            assert!(
                                s.wi.is_finite() && (s.wi.length() - 1.0).abs() < 1e-3,
                                "{what}, wo = {wo}: {s:?}"
                            );
                            assert!(s.pdf > 0.0 && s.pdf.is_finite(), "{what}, wo = {wo}: {s:?}");
                            assert!(
                                s.f.is_finite() && s.f.min_element() >= 0.0,
                                "{what}, wo = {wo}: {s:?}"
                            );
                            assert!(
                                w.is_finite() && w.min_element() >= 0.0,
                                "{what}, wo = {wo}: {s:?}"
                            );
                            wis.push(s.wi);
                        }
                        for &wi in &wis {
                            let (f, pdf) = glass.eval_pdf(wo, wi);
                            assert!(
                                f.is_finite() && f.min_element() >= 0.0,
                                "{what}: f({wo}, {wi}) = {f}"
                            );
                            assert!(
                                pdf.is_finite() && pdf >= 0.0,
                                "{what}: pdf({wo}, {wi}) = {pdf}"
                            );
                        }
                        // Below the horizon and on it: nothing.
                        for below in [mirrored(wo), Vec3::X] {
                            assert!(glass.sample(below, Vec2::splat(0.5), 0.5).is_none());
                            assert_eq!(glass.eval_pdf(below, -wo), (Rgb::ZERO, 0.0));
                        }
                    }
                }
            }
        }
    }
}
