//! BSDFs in the local shading frame.
//!
//! Convention (pbrt-v4's): z is the shading normal, turned toward the side the path arrives
//! from, so `wo` (toward the viewer) has z > 0; `wi` points toward the light; both are unit
//! vectors pointing away from the surface. [`Bxdf::eval`] returns f(wo, wi) in 1/sr
//! **without** the cosine factor; [`Bxdf::pdf`] is the solid-angle density (1/sr) with which
//! [`Bxdf::sample`] picks `wi`. Reflectors (every BSDF but the dielectric) return zero value
//! and zero density when `wo` or `wi` lies below the horizon (z ≤ 0); a transmitting BSDF
//! ([`Bxdf::transmits`]) also scatters into z < 0. Lobes concentrated on one direction
//! (smooth glass) are *delta* lobes: `eval` and `pdf` give them zero, and only `sample`
//! draws them ([`BsdfSample::delta`]).
//!
//! The integrator sees only [`Bsdf`], the one enum over the kinds (static dispatch in the
//! hot loop); each kind lives in a file of its own. The BSDFs made from data (MERL table,
//! NBRDF network, decoded latent code) share one implementation of sampling and density,
//! [`tabulated_sampling::TabulatedBrdf`]; which BSDF a material gets is decided in
//! [`crate::material`].

use crate::lanes::{Blend, MaskOps, Real, V2, V3};
use crate::Rgb;
use glam::{Vec2, Vec3};

pub mod albedo;
pub mod dielectric;
pub mod lambert;
pub mod layered;
pub mod merl;
pub mod metallic_roughness;
pub mod microfacet;
pub mod mixture;
pub mod nbrdf;
pub mod neural;
pub mod sheen;
pub mod tabulated_sampling;
pub mod transmission;

pub use dielectric::Dielectric;
pub use lambert::Lambert;
pub use layered::Layered;
pub use metallic_roughness::MetallicRoughness;
pub use mixture::Mixture;
pub use transmission::Transmission;

/// One direction drawn by [`Bxdf::sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Sampled direction toward the light, local frame, unit length; z > 0 for reflection,
    /// z < 0 for transmission.
    pub wi: Vec3,
    /// f(wo, wi) in 1/sr (no cosine).
    pub f: Rgb,
    /// Solid-angle density of `wi` in 1/sr; always > 0 and finite. For a delta lobe, the
    /// probability of having chosen it (and `f` the lobe's weight times that probability
    /// over |cos θi|, so that [`BsdfSample::weight`] holds for both).
    pub pdf: f32,
    /// Whether `wi` comes from a delta lobe (which `eval`/`pdf` do not see, so multiple
    /// importance sampling must not weigh it).
    pub delta: bool,
}

impl BsdfSample {
    /// A sample from a lobe that `eval` and `pdf` describe.
    #[inline]
    pub fn new(wi: Vec3, f: Rgb, pdf: f32) -> Self {
        BsdfSample { wi, f, pdf, delta: false }
    }

    /// The Monte Carlo weight f · |cos θi| / pdf.
    #[inline]
    pub fn weight(&self) -> Rgb {
        self.f * (self.wi.z.abs() / self.pdf)
    }
}

/// The interface every BSDF implements (pbrt's BxDF: f, Sample_f, PDF).
pub trait Bxdf {
    /// f_r(wo, wi) in 1/sr, without the cosine; zero below either horizon.
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb;

    /// Solid-angle density (1/sr) of sampling `wi` given `wo`; zero below either horizon.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32;

    /// Draws `wi` given `wo`, from a 2D sample `u` and a 1D sample `uc` (for choosing a
    /// lobe). `None` when no direction could be drawn (e.g. `wo` below the horizon).
    fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample>;

    /// Value and density together (one evaluation for BSDFs that share work between them).
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        (self.eval(wo, wi), self.pdf(wo, wi))
    }

    /// Whether the BSDF scatters below the horizon (wi.z < 0) too; light arriving from
    /// behind the surface is sampled only for such BSDFs.
    fn transmits(&self) -> bool {
        false
    }

    /// Whether every lobe is a delta lobe (smooth glass alone): `eval` and `pdf` are zero
    /// for every pair of directions, so next-event estimation cannot contribute and is
    /// skipped (pbrt-v4's `IsNonSpecular`, negated).
    fn is_delta(&self) -> bool {
        false
    }
}

/// The formulas of a BxDF written once over [`Real`] values: for one shading point (`f32`,
/// what its [`Bxdf`] implementation evaluates) and for [`LANES`](crate::lanes::LANES) shading
/// points with their own parameters at once (`F32s`, the path tracer's lane kernels). Masks
/// stand where one point would return early, so each lane gets the scalar bits.
pub(crate) trait RealBxdf<R: Real> {
    /// What the value, density and sample share for one `wo` (e.g. a lobe probability).
    type AtWo: Copy;

    /// The part of the evaluation that depends on `wo` alone.
    fn at_wo(&self, wo: V3<R>) -> Self::AtWo;

    /// [`Bxdf::eval_pdf`]: value (1/sr) and density (1/sr), zero below either horizon.
    fn eval_pdf(&self, at: Self::AtWo, wo: V3<R>, wi: V3<R>) -> (V3<R>, R);

    /// [`Bxdf::sample`]: where [`RealSample::ok`], the direction, its value and density.
    fn sample(&self, at: Self::AtWo, wo: V3<R>, u: V2<R>, uc: R) -> RealSample<R>;
}

/// A [`RealBxdf::sample`]: where `ok`, what [`Bxdf::sample`] gives as `Some` (`delta` its
/// [`BsdfSample::delta`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RealSample<R: Real> {
    pub ok: R::Mask,
    pub wi: V3<R>,
    pub f: V3<R>,
    pub pdf: R,
    pub delta: R::Mask,
}

impl<R: Real> RealSample<R> {
    /// A sample from lobes that `eval` and `pdf` describe (no delta lobe).
    #[inline(always)]
    pub fn new(ok: R::Mask, wi: V3<R>, f: V3<R>, pdf: R) -> Self {
        RealSample { ok, wi, f, pdf, delta: R::Mask::splat(false) }
    }
}

impl<R: Real> Blend<R::Mask> for RealSample<R> {
    #[inline(always)]
    fn blend(mask: R::Mask, a: Self, b: Self) -> Self {
        RealSample {
            ok: mask.select(a.ok, b.ok),
            wi: mask.select(a.wi, b.wi),
            f: mask.select(a.f, b.f),
            pdf: R::select(mask, a.pdf, b.pdf),
            delta: mask.select(a.delta, b.delta),
        }
    }
}

impl RealSample<f32> {
    /// The sample as [`Bxdf::sample`] returns it.
    #[inline(always)]
    pub fn into_option(self) -> Option<BsdfSample> {
        self.ok.then(|| BsdfSample {
            wi: self.wi.into(),
            f: self.f.into(),
            pdf: self.pdf,
            delta: self.delta,
        })
    }
}

/// BSDFs whose values are cheaper computed many at a time (a network's forward pass shares
/// every weight load between points). [`BatchEval::prepare`] does a point's work that needs
/// no batch; [`BatchEval::eval_prepared`] evaluates many prepared points at once. Together they
/// give exactly [`Bxdf::eval`], bit for bit.
pub trait BatchEval: Bxdf {
    /// A point ready for evaluation.
    type Prepared: Copy;

    /// Prepares f_r(wo, wi); `None` where it is zero without evaluation (below either
    /// horizon).
    fn prepare(&self, wo: Vec3, wi: Vec3) -> Option<Self::Prepared>;

    /// f_r (1/sr) of each prepared point into `values` (of the same length).
    fn eval_prepared(&self, points: &[Self::Prepared], values: &mut [Rgb]);
}

/// A BSDF at one shading point: the enum the integrator dispatches on. The BSDFs made from
/// data are shared by the scene (they live as long as it does) and taken by reference.
#[derive(Clone, Copy, Debug)]
pub enum Bsdf<'a> {
    Lambert(Lambert),
    MetallicRoughness(MetallicRoughness),
    /// A MERL-layout table.
    Merl(&'a merl::MerlBsdf),
    /// An NBRDF network.
    Nbrdf(&'a nbrdf::NbrdfBsdf),
    /// A decoded FreNBRDF/HyperBRDF latent code.
    Neural(&'a neural::NeuralBsdf),
    /// glTF metallic-roughness with transmission: glass mixed with an opaque part.
    Transmission(Transmission),
    /// Any of the others under glTF's sheen and clear coat.
    Layered(Layered<'a>),
    /// A texture-weighted, tinted mixture of BSDFs made from data.
    Mixture(Mixture<'a>),
}

macro_rules! dispatch {
    ($self:ident, $b:ident => $e:expr) => {
        match $self {
            Bsdf::Lambert($b) => $e,
            Bsdf::MetallicRoughness($b) => $e,
            Bsdf::Merl($b) => $e,
            Bsdf::Nbrdf($b) => $e,
            Bsdf::Neural($b) => $e,
            Bsdf::Transmission($b) => $e,
            Bsdf::Layered($b) => $e,
            Bsdf::Mixture($b) => $e,
        }
    };
}

impl Bxdf for Bsdf<'_> {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        dispatch!(self, b => b.eval(wo, wi))
    }
    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        dispatch!(self, b => b.pdf(wo, wi))
    }
    #[inline]
    fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        dispatch!(self, b => b.sample(wo, u, uc))
    }
    #[inline]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        dispatch!(self, b => b.eval_pdf(wo, wi))
    }
    #[inline]
    fn transmits(&self) -> bool {
        dispatch!(self, b => b.transmits())
    }
    #[inline]
    fn is_delta(&self) -> bool {
        dispatch!(self, b => b.is_delta())
    }
}
