//! glTF's layers over any base BSDF: a sheen (`KHR_materials_sheen`) and a clear coat
//! (`KHR_materials_clearcoat`), as the specifications stack them.
//!
//! With the base f_b (metallic-roughness, glass, or a measured or neural BRDF: a neural paint
//! can sit under a clear coat), the sheen lobe f_s ([`Sheen`]) and the coat lobe f_c:
//!
//! f = c F_c(μo) f_c + (1 − c F_c(μo)) · (f_s + s(μo, μi) f_b)
//!
//! - the coat (`KHR_materials_clearcoat`): weight c (factor × texture red), a GGX reflection
//!   lobe f_c = D G₂ / (4 |μo μi|) of α = clearcoatRoughness² about the coat normal n_c, and
//!   F_c(μ) = 0.04 + 0.96 (1 − |wo · n_c|)⁵, the specification's Fresnel of an index-1.5 coat
//!   taken at the viewing angle so that the layering conserves energy (the base keeps
//!   1 − c F_c, the coat reflects at most c F_c). The coat normal is the shading normal
//!   without the base's normal map, or the coat's own normal map;
//! - the sheen (`KHR_materials_sheen`): the Charlie lobe over the base, whose weight is the
//!   specification's albedo scaling s(μo, μi) = min(1 − max₃(C) E(μo), 1 − max₃(C) E(μi)).
//!
//! Both bounds make the layered albedo at most the base's (checked by quadrature in the
//! tests). Like the specification's formula the layering is not reciprocal (F_c and s take
//! the viewing angle).
//!
//! Sampling picks the coat with probability p_c = clamp(c F_c(μo), 0.2 c, 0.9) (a sharp coat
//! gets its share of samples even where it reflects little), the sheen with p_s = (1 − p_c)
//! max₃(C) E(μo) (a cosine-weighted hemisphere: the Charlie lobe is broad), else the base;
//! value and density are the whole layered BSDF's (multiple importance sampling sees all
//! lobes), except for samples of the base's delta lobes (smooth glass), which carry their
//! layer weights and lobe probability.

use super::merl::MerlBsdf;
use super::microfacet::GgxDistribution;
use super::nbrdf::NbrdfBsdf;
use super::neural::NeuralBsdf;
use super::sheen::Sheen;
use super::{Bsdf, BsdfSample, Bxdf, Lambert, MetallicRoughness, Mixture, Transmission};
use crate::frame::Frame;
use crate::lanes::Real;
use crate::sampling::{cosine_hemisphere_pdf, sample_cosine_hemisphere};
use crate::Rgb;
use glam::{Vec2, Vec3};

/// The clear coat's normal-incidence reflectance (index of refraction 1.5).
const COAT_F0: f32 = 0.04;

/// F_c(μ) = 0.04 + 0.96 (1 − μ)⁵ for μ = |cos| ≤ 1 to the coat's normal (the fifth power as
/// `powi(5)` evaluates it: x · (x² · x²)).
#[inline(always)]
fn coat_fresnel<R: Real>(mu: R) -> R {
    let x = R::splat(1.0) - mu;
    let x2 = x * x;
    x * (x2 * x2) * (1.0 - COAT_F0) + COAT_F0
}

/// 1 − c F_c(μ): the part of what a surface emits under a clear coat of weight `weight`
/// (clamped to [0, 1]; NaN counts as 0) that leaves through it in a direction at cosine `cos`
/// to the coat's normal. The specification puts the coat over emission, which it darkens by
/// the coat's reflectance ([`Coat::reflectance`]). Over [`Real`] values: the lane kernels
/// darken coated triangle lights' samples with it.
#[inline(always)]
pub fn coat_transmittance<R: Real>(weight: R, cos: R) -> R {
    let weight = R::select(weight.eq(weight), weight.clamp(0.0, 1.0), R::splat(0.0));
    R::splat(1.0) - weight * coat_fresnel(cos.abs().min(R::splat(1.0)))
}

/// The clear coat of [`Layered`]: a GGX reflection of a weight c in [0, 1] about its own
/// normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coat {
    weight: f32,
    ggx: GgxDistribution,
    /// The coat's frame in the base's local frame (`None`: the coat normal is the shading
    /// normal, z).
    frame: Option<Frame>,
}

impl Coat {
    /// A coat of `weight` (clamped to [0, 1]) and perceptual `roughness` (α = roughness²,
    /// raised to the GGX minimum as the metallic-roughness lobe's) about `normal`, a unit
    /// vector in the base's local frame on the side of the viewer (z where the coat has the
    /// shading normal).
    pub fn new(weight: f32, roughness: f32, normal: Vec3) -> Self {
        let weight = if weight.is_nan() { 0.0 } else { weight.clamp(0.0, 1.0) };
        let normal = normal.try_normalize().filter(|n| n.z > 0.0).unwrap_or(Vec3::Z);
        Coat {
            weight,
            ggx: GgxDistribution::from_roughness(if roughness.is_nan() { 0.0 } else { roughness.clamp(0.0, 1.0) }),
            frame: (normal != Vec3::Z).then(|| Frame::from_normal(normal)),
        }
    }

    /// `w` (base local frame) in the coat's frame.
    #[inline]
    fn to_coat(self, w: Vec3) -> Vec3 {
        match self.frame {
            Some(frame) => frame.to_local(w),
            None => w,
        }
    }

    /// c F_c(μo): the part of the light arriving from `wo` (base local frame) that the coat
    /// reflects, and what it takes from the layers below.
    #[inline]
    pub fn reflectance(&self, wo: Vec3) -> f32 {
        self.weight * coat_fresnel(self.to_coat(wo).z.abs().min(1.0))
    }

    /// The coat lobe's value D G₂ / (4 μo μi) (1/sr, without the weight and Fresnel) and
    /// density of [`Self::sample`] at (`wo`, `wi`) in the coat frame; zero below its horizon.
    #[inline]
    fn lobe(&self, wo_c: Vec3, wi_c: Vec3) -> (f32, f32) {
        if wo_c.z <= 0.0 || wi_c.z <= 0.0 {
            return (0.0, 0.0);
        }
        let Some(h) = (wo_c + wi_c).try_normalize() else {
            return (0.0, 0.0);
        };
        (self.ggx.d(h) * self.ggx.visibility(wo_c, wi_c), self.ggx.reflection_pdf(wo_c, wi_c))
    }

    /// A direction drawn from the coat lobe's visible normals, in the base local frame.
    #[inline]
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        let wo_c = self.to_coat(wo);
        if wo_c.z <= 0.0 {
            return None;
        }
        let wi_c = self.ggx.sample_reflection(wo_c, u)?;
        Some(match &self.frame {
            Some(frame) => frame.to_world(wi_c),
            None => wi_c,
        })
    }
}

/// The base under the layers: every BSDF kind but [`Layered`] itself.
#[derive(Clone, Copy, Debug)]
pub enum Base<'a> {
    Lambert(Lambert),
    MetallicRoughness(MetallicRoughness),
    Merl(&'a MerlBsdf),
    Nbrdf(&'a NbrdfBsdf),
    Neural(&'a NeuralBsdf),
    Transmission(Transmission),
    Mixture(Mixture<'a>),
}

macro_rules! dispatch_base {
    ($self:ident, $b:ident => $e:expr) => {
        match $self {
            Base::Lambert($b) => $e,
            Base::MetallicRoughness($b) => $e,
            Base::Merl($b) => $e,
            Base::Nbrdf($b) => $e,
            Base::Neural($b) => $e,
            Base::Transmission($b) => $e,
            Base::Mixture($b) => $e,
        }
    };
}

impl Bxdf for Base<'_> {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        dispatch_base!(self, b => b.eval(wo, wi))
    }
    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        dispatch_base!(self, b => b.pdf(wo, wi))
    }
    #[inline]
    fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        dispatch_base!(self, b => b.sample(wo, u, uc))
    }
    #[inline]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        dispatch_base!(self, b => b.eval_pdf(wo, wi))
    }
    #[inline]
    fn transmits(&self) -> bool {
        dispatch_base!(self, b => b.transmits())
    }
    #[inline]
    fn is_delta(&self) -> bool {
        dispatch_base!(self, b => b.is_delta())
    }
}

impl<'a> Base<'a> {
    /// The base a BSDF makes; `None` for a layered BSDF (layers do not nest).
    pub fn of(bsdf: Bsdf<'a>) -> Option<Self> {
        Some(match bsdf {
            Bsdf::Lambert(b) => Base::Lambert(b),
            Bsdf::MetallicRoughness(b) => Base::MetallicRoughness(b),
            Bsdf::Merl(b) => Base::Merl(b),
            Bsdf::Nbrdf(b) => Base::Nbrdf(b),
            Bsdf::Neural(b) => Base::Neural(b),
            Bsdf::Transmission(b) => Base::Transmission(b),
            Bsdf::Mixture(b) => Base::Mixture(b),
            Bsdf::Layered(_) => return None,
        })
    }
}

/// The layers above a base: a sheen and a clear coat (either may be absent). Their value
/// and density need only the base's value and density at the same pair of directions, so a
/// renderer that evaluates many bases together (the deferred batch of decoded networks and
/// tables) layers them afterwards with the same [`Layers::layer`].
#[derive(Clone, Copy, Debug)]
pub struct Layers {
    sheen: Option<Sheen>,
    coat: Option<Coat>,
}

/// The lobe probabilities of [`Layers`] for one `wo`: coat, sheen (the base has the rest).
#[derive(Clone, Copy, Debug)]
pub struct Choice {
    /// c F_c(μo) (0 without a coat).
    coat_reflectance: f32,
    p_coat: f32,
    p_sheen: f32,
}

impl Choice {
    /// The probability of drawing from the base.
    #[inline]
    pub fn p_base(&self) -> f32 {
        1.0 - self.p_coat - self.p_sheen
    }
}

/// The lobe [`Layers::draw`] chose for a sample.
#[derive(Clone, Copy, Debug)]
pub enum Draw {
    /// A layer's direction (base local frame; `None`: the coat could not draw one).
    Layer(Option<Vec3>),
    /// The base draws the direction, with this lobe-choice number (`uc` rescaled to [0, 1)).
    Base(f32),
}

impl Layers {
    /// A sheen and a coat (a black sheen or a coat of weight 0 is left out).
    pub fn new(sheen: Option<Sheen>, coat: Option<Coat>) -> Self {
        Layers {
            sheen: sheen.filter(|s| !s.is_black()),
            coat: coat.filter(|c| c.weight > 0.0),
        }
    }

    /// Whether there is no layer at all.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.sheen.is_none() && self.coat.is_none()
    }

    /// What the layers let through toward `wo`: 1 − c F_c(μo).
    #[inline]
    pub fn coat_transmittance(&self, wo: Vec3) -> f32 {
        1.0 - self.coat.map_or(0.0, |c| c.reflectance(wo))
    }

    /// The lobe probabilities for `wo` (z > 0).
    #[inline]
    pub fn choice(&self, wo: Vec3) -> Choice {
        let (coat_reflectance, p_coat) = match &self.coat {
            Some(c) => {
                let r = c.reflectance(wo);
                (r, r.max(0.2 * c.weight).min(0.9))
            }
            None => (0.0, 0.0),
        };
        let p_sheen = self.sheen.map_or(0.0, |s| (1.0 - p_coat) * s.albedo(wo.z).clamp(0.0, 0.9));
        Choice { coat_reflectance, p_coat, p_sheen }
    }

    /// Picks the lobe of a sample by `uc` and draws a layer's direction from `u`.
    #[inline]
    pub fn draw(&self, at: Choice, wo: Vec3, u: Vec2, uc: f32) -> Draw {
        if uc < at.p_coat {
            Draw::Layer(self.coat.as_ref().and_then(|c| c.sample(wo, u)))
        } else if uc < at.p_coat + at.p_sheen {
            Draw::Layer(Some(sample_cosine_hemisphere(u)))
        } else {
            Draw::Base(((uc - at.p_coat - at.p_sheen) / at.p_base()).min(1.0 - f32::EPSILON / 2.0))
        }
    }

    /// The layered value (1/sr) and density (1/sr) at (`wo`, `wi`) given the lobe choice and
    /// the base's value and density `(fb, pb)` there.
    #[inline]
    pub fn layer(&self, at: Choice, wo: Vec3, wi: Vec3, (fb, pb): (Rgb, f32)) -> (Rgb, f32) {
        let mut below = fb;
        let mut pdf = at.p_base() * pb;
        if let Some(sheen) = &self.sheen {
            below = fb * sheen.base_scaling(wo.z, wi.z.abs());
            if wi.z > 0.0 {
                below += sheen.eval(wo, wi);
                pdf += at.p_sheen * cosine_hemisphere_pdf(wi.z);
            }
        }
        let mut f = below * (1.0 - at.coat_reflectance);
        if let Some(coat) = &self.coat {
            let (fc, pc) = coat.lobe(coat.to_coat(wo), coat.to_coat(wi));
            f += Rgb::splat(at.coat_reflectance * fc);
            pdf += at.p_coat * pc;
        }
        (f, pdf)
    }

    /// A delta sample `s` of the base (smooth glass) through the layers: its value carries
    /// the layers' weights, its probability that of choosing the base.
    #[inline]
    pub fn pass_delta(&self, at: Choice, wo: Vec3, s: BsdfSample) -> BsdfSample {
        let scaling = self.sheen.map_or(1.0, |sh| sh.base_scaling(wo.z, s.wi.z.abs()));
        let f = s.f * (scaling * (1.0 - at.coat_reflectance));
        BsdfSample { f, pdf: s.pdf * at.p_base(), ..s }
    }
}

/// A sample's value and density as [`Bxdf::sample`] keeps them: `None` unless the density is
/// positive and finite and the value finite.
#[inline]
pub fn checked_sample(wi: Vec3, (f, pdf): (Rgb, f32)) -> Option<BsdfSample> {
    (pdf > 0.0 && pdf.is_finite() && f.is_finite()).then_some(BsdfSample::new(wi, f, pdf))
}

/// A base BSDF under a sheen and a clear coat (see the module documentation).
#[derive(Clone, Copy, Debug)]
pub struct Layered<'a> {
    base: Base<'a>,
    layers: Layers,
}

impl<'a> Layered<'a> {
    /// `base` under `sheen` and `coat` (either may be absent; a black sheen or a coat of
    /// weight 0 is left out).
    pub fn new(base: Base<'a>, sheen: Option<Sheen>, coat: Option<Coat>) -> Self {
        Layered { base, layers: Layers::new(sheen, coat) }
    }

    /// The base.
    pub fn base(&self) -> &Base<'a> {
        &self.base
    }

    /// The layers above the base.
    pub fn layers(&self) -> &Layers {
        &self.layers
    }

    /// What the layers above the base let through toward `wo`: 1 − c F_c(μo) (emission from
    /// under a clear coat is darkened by it, as the specification says).
    #[inline]
    pub fn coat_transmittance(&self, wo: Vec3) -> f32 {
        self.layers.coat_transmittance(wo)
    }

    /// Value and density given the lobe choice.
    #[inline]
    fn eval_pdf_with(&self, at: Choice, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        self.layers.layer(at, wo, wi, self.base.eval_pdf(wo, wi))
    }
}

impl Bxdf for Layered<'_> {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.eval_pdf(wo, wi).0
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval_pdf(wo, wi).1
    }

    #[inline]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        if wo.z <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        self.eval_pdf_with(self.layers.choice(wo), wo, wi)
    }

    fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let at = self.layers.choice(wo);
        let wi = match self.layers.draw(at, wo, u, uc) {
            Draw::Layer(wi) => wi?,
            Draw::Base(uc) => {
                let s = self.base.sample(wo, u, uc)?;
                if s.delta {
                    return Some(self.layers.pass_delta(at, wo, s));
                }
                if let Base::Merl(_) | Base::Nbrdf(_) | Base::Neural(_) = self.base {
                    // A tabulated base's sample carries its value and density at wi, the
                    // same bits as its eval_pdf: no second look-up or network pass.
                    return checked_sample(s.wi, self.layers.layer(at, wo, s.wi, (s.f, s.pdf)));
                }
                s.wi
            }
        };
        checked_sample(wi, self.eval_pdf_with(at, wo, wi))
    }

    fn transmits(&self) -> bool {
        self.base.transmits()
    }

    fn is_delta(&self) -> bool {
        self.layers.is_empty() && self.base.is_delta()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::Dielectric;
    use crate::testing::chi2::{check_sample_consistency, test_bxdf, Chi2Config, Chi2Domain};

    fn unit(theta_degrees: f32, phi: f32) -> Vec3 {
        let t = theta_degrees.to_radians();
        Vec3::new(t.sin() * phi.cos(), t.sin() * phi.sin(), t.cos())
    }

    /// What leaves through a coat is what the coat does not reflect, from both sides and at
    /// any weight; no coat (or a NaN weight) darkens nothing.
    #[test]
    fn coat_transmittance_is_what_the_coat_does_not_reflect() {
        for weight in [0.0, 0.3, 1.0] {
            for theta in [0.0, 30.0, 60.0, 85.0, 90.0] {
                let wo = unit(theta, 0.4);
                let reflected = Coat::new(weight, 0.2, Vec3::Z).reflectance(wo);
                assert_eq!(coat_transmittance(weight, wo.z), 1.0 - reflected, "weight {weight}, θ {theta}");
                assert_eq!(coat_transmittance(weight, -wo.z), 1.0 - reflected, "from below");
            }
        }
        assert_eq!(coat_transmittance(1.0, 1.0), 0.96);
        assert_eq!(coat_transmittance(f32::NAN, 0.5), 1.0);
        assert_eq!(coat_transmittance(2.0, 1.0), 0.96, "weights clamp to 1");
    }

    fn layered_bases() -> Vec<(&'static str, Base<'static>)> {
        let glass = Dielectric::new(1.5, 0.3).with_tint(Rgb::new(0.9, 0.8, 0.6));
        vec![
            ("lambert", Base::Lambert(Lambert::new(Rgb::new(0.8, 0.4, 0.2)))),
            ("metallic-roughness", Base::MetallicRoughness(MetallicRoughness::new(Rgb::new(0.9, 0.6, 0.3), 0.5, 0.4))),
            ("rough glass", Base::Transmission(Transmission::new(Rgb::ONE, 0.0, 0.3, 1.0, (Rgb::splat(0.04), 1.0), glass))),
        ]
    }

    /// Coated, sheened and both, over three bases and with a tilted coat normal: the sampler
    /// draws the layered density in both hemispheres, and samples agree with eval and pdf.
    #[test]
    fn layered_bsdfs_sample_their_density() {
        let tilted = Vec3::new(0.3, -0.2, 1.0).normalize();
        let variants = [
            ("coat", None, Some(Coat::new(1.0, 0.2, Vec3::Z))),
            ("sheen", Some(Sheen::new(Rgb::new(0.9, 0.7, 0.8), 0.5)), None),
            ("both, tilted coat", Some(Sheen::new(Rgb::splat(0.6), 0.3)), Some(Coat::new(0.7, 0.1, tilted))),
        ];
        let config = Chi2Config::default().with_sample_count(150_000).with_domain(Chi2Domain::ThetaPhi).with_test_count(2 * 3 * 3);
        for (base_name, base) in layered_bases() {
            for (name, sheen, coat) in variants {
                let bsdf = Layered::new(base, sheen, coat);
                for theta in [20.0, 70.0] {
                    let wo = unit(theta, 0.6);
                    let result = test_bxdf(&bsdf, wo, &config);
                    assert!(result.passed(), "{name} over {base_name}, θo = {theta}\n{result}");
                    let report = check_sample_consistency(&bsdf, wo, 5_000);
                    assert!(report.passed(), "{name} over {base_name}, θo = {theta}\n{report}");
                }
            }
        }
    }

    /// ∫ f |cos θi| dωi by quadrature over the sphere (θ × φ midpoints).
    fn albedo(bsdf: &impl Bxdf, wo: Vec3) -> Rgb {
        let (nt, np) = (400, 200);
        let mut sum = glam::DVec3::ZERO;
        for i in 0..nt {
            let theta = (i as f64 + 0.5) * std::f64::consts::PI / nt as f64;
            for j in 0..np {
                let phi = (j as f64 + 0.5) * std::f64::consts::TAU / np as f64;
                let wi = Vec3::new((theta.sin() * phi.cos()) as f32, (theta.sin() * phi.sin()) as f32, theta.cos() as f32);
                sum += (bsdf.eval(wo, wi) * wi.z.abs()).as_dvec3() * theta.sin();
            }
        }
        (sum * (std::f64::consts::PI / nt as f64) * (std::f64::consts::TAU / np as f64)).as_vec3()
    }

    /// Energy: a white Lambertian base under a full coat and a white sheen reflects at most
    /// what the base does (≤ 1), at every θo; the coat alone over black reflects c F_c at
    /// most (its lobe loses what falls below the horizon).
    #[test]
    fn layers_create_no_energy() {
        let white = Base::Lambert(Lambert::new(Rgb::ONE));
        for roughness in [0.3, 0.6] {
            let bsdf = Layered::new(white, Some(Sheen::new(Rgb::ONE, roughness)), Some(Coat::new(1.0, roughness, Vec3::Z)));
            for theta in [0.0, 30.0, 60.0, 80.0, 89.0] {
                let a = albedo(&bsdf, unit(theta, 0.0));
                assert!(a.max_element() < 1.0 + 2e-3, "roughness {roughness}, θo = {theta}: albedo {a}");
            }
            let black = Base::Lambert(Lambert::new(Rgb::ZERO));
            let coat = Coat::new(1.0, roughness, Vec3::Z);
            let coated = Layered::new(black, None, Some(coat));
            for theta in [0.0, 45.0, 80.0] {
                let wo = unit(theta, 0.0);
                let a = albedo(&coated, wo).x;
                assert!(a <= coat.reflectance(wo) + 1e-3 && a > 0.5 * coat.reflectance(wo), "θo = {theta}: coat albedo {a}, c F_c {}", coat.reflectance(wo));
            }
        }
    }

    /// No coat and no sheen is the base, bit for bit; the coat darkens the base by exactly
    /// 1 − c F_c(μo) away from its own lobe.
    #[test]
    fn layers_weigh_the_base_as_specified() {
        let mr = MetallicRoughness::new(Rgb::new(0.7, 0.5, 0.3), 0.2, 0.5);
        let base = Base::MetallicRoughness(mr);
        let plain = Layered::new(base, Some(Sheen::new(Rgb::ZERO, 0.5)), Some(Coat::new(0.0, 0.1, Vec3::Z)));
        let (wo, wi) = (unit(30.0, 0.0), unit(50.0, 2.5));
        assert_eq!(plain.eval_pdf(wo, wi).0, mr.eval(wo, wi));
        let coat = Coat::new(0.8, 0.05, Vec3::Z);
        let coated = Layered::new(base, None, Some(coat));
        let expected = mr.eval(wo, wi) * (1.0 - coat.reflectance(wo));
        // Far from the mirror direction the sharp coat's lobe adds only its GGX tail.
        assert!((coated.eval(wo, wi) - expected).abs().max_element() < 1e-3 * expected.max_element(), "{} vs {expected}", coated.eval(wo, wi));
        assert!((coat.reflectance(Vec3::Z) - 0.8 * 0.04).abs() < 1e-7);
    }

    /// Over a tabulated base (a decoded neural code) the base's draws reuse the value and
    /// density the base's sample carries instead of evaluating the network again: every
    /// sample, the coat's and the sheen's draws too, is `eval_pdf` at its direction bit for
    /// bit.
    #[test]
    fn samples_over_a_tabulated_base_are_eval_pdf_bit_for_bit() {
        let neural = crate::testing::data::shipped_latents().decode("alum-bronze").unwrap();
        let bsdf = Layered::new(Base::Neural(&neural), Some(Sheen::new(Rgb::splat(0.3), 0.5)), Some(Coat::new(1.0, 0.1, Vec3::Z)));
        let wo = unit(35.0, 0.4);
        let mut drawn = 0;
        for k in 0..500 {
            let u = Vec2::new((k as f32 * 0.618_034).fract(), (k as f32 * 0.414_214).fract());
            if let Some(s) = bsdf.sample(wo, u, (k as f32 + 0.5) / 500.0) {
                assert_eq!((s.f, s.pdf), bsdf.eval_pdf(wo, s.wi), "sample {k}");
                drawn += 1;
            }
        }
        assert!(drawn > 400, "{drawn} of 500 drawn");
    }

    /// Only a smooth dielectric alone is all delta lobes: a rough one, an opaque part or a
    /// layer above it has values that next-event estimation needs.
    #[test]
    fn only_smooth_glass_alone_is_delta() {
        let glass = |roughness, transmission| Transmission::new(Rgb::ONE, 0.0, roughness, transmission, (Rgb::splat(0.04), 1.0), Dielectric::new(1.5, roughness));
        assert!(glass(0.0, 1.0).is_delta() && Bsdf::Transmission(glass(0.0, 1.0)).is_delta());
        assert!(!glass(0.3, 1.0).is_delta() && !glass(0.0, 0.5).is_delta());
        assert!(Layered::new(Base::Transmission(glass(0.0, 1.0)), None, None).is_delta());
        assert!(!Layered::new(Base::Transmission(glass(0.0, 1.0)), None, Some(Coat::new(1.0, 0.1, Vec3::Z))).is_delta());
        assert!(!Bsdf::Lambert(Lambert::new(Rgb::ONE)).is_delta());
    }

    /// A smooth glass base under a coat: its delta samples carry the coat's transmittance
    /// over the probability of choosing the base, and the coat's own lobe is still sampled
    /// and evaluated; the expected weight is the glass's (R + T/η² ≤ 1) through the coat
    /// plus the coat's reflectance.
    #[test]
    fn delta_bases_pass_through_the_coat() {
        let glass = Transmission::new(Rgb::ONE, 0.0, 0.0, 1.0, (Rgb::splat(0.04), 1.0), Dielectric::new(1.5, 0.0));
        let coat = Coat::new(1.0, 0.1, Vec3::Z);
        let bsdf = Layered::new(Base::Transmission(glass), None, Some(coat));
        let wo = unit(40.0, 0.3);
        let (mut delta, mut lobe, mut sum) = (0, 0, 0.0f64);
        for k in 0..2000 {
            let u = Vec2::new((k as f32 * 0.618_034).fract(), (k as f32 * 0.414_214).fract());
            let uc = (k as f32 + 0.5) / 2000.0;
            if let Some(s) = bsdf.sample(wo, u, uc) {
                assert!(s.weight().is_finite() && s.weight().min_element() >= 0.0, "{s:?}");
                sum += s.weight().x as f64;
                if s.delta {
                    delta += 1;
                } else {
                    lobe += 1;
                }
            }
        }
        assert!(delta > 0 && lobe > 0, "delta {delta}, coat lobe {lobe}");
        // Outside glass (η = 1.5): R + T/η² is between 1/η² and 1; the coat takes c F_c from
        // it and reflects about as much.
        let mean = sum / 2000.0;
        assert!((1.0 / 2.25..=1.01).contains(&mean), "mean weight {mean}");
    }
}
