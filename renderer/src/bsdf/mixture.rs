//! A weighted mixture of BSDFs made from data, optionally tinted: how a material varies a
//! measured or neural BRDF across its surface ([`crate::scene::Varying`]).
//!
//! With weights w_k ≥ 0 normalised to Σ w_k = 1 and a tint c ∈ [0, 1]³ per channel,
//!
//! f(wo, wi) = c · Σ_k w_k f_k(wo, wi),  pdf(wo, wi) = Σ_k w_k pdf_k(wo, wi):
//!
//! the exact mixture. Sampling chooses part k with probability w_k (from the 1D sample,
//! rescaled for the part's own use) and draws from it; the sample's value and density are
//! the whole mixture's, so multiple importance sampling sees the mixture's density. Parts
//! of weight 0 are dropped when the mixture is made, so a texel that names one part costs
//! one evaluation. A tint ≤ 1 keeps the energy of the parts (the albedo scales by at most
//! the tint); the density ignores it (the lobe's shape is unchanged).
//!
//! The mixtures a scene uses: the glTF `mix` form (up to four codes weighted by a texture's
//! RGBA), the `blend` form (two neighbouring networks of a palette decoded along a latent
//! interpolation, weighted by where t falls between them) and the tint alone (one part).

use super::merl::MerlBsdf;
use super::nbrdf::NbrdfBsdf;
use super::neural::NeuralBsdf;
use super::{BsdfSample, Bxdf};
use crate::scene::MAX_MIX_PARTS;
use crate::Rgb;
use glam::{Vec2, Vec3};

/// A BSDF made from data, as a part of a [`Mixture`].
#[derive(Clone, Copy, Debug)]
pub enum Part<'a> {
    Merl(&'a MerlBsdf),
    Nbrdf(&'a NbrdfBsdf),
    Neural(&'a NeuralBsdf),
}

macro_rules! dispatch_part {
    ($self:expr, $b:ident => $e:expr) => {
        match $self {
            Part::Merl($b) => $e,
            Part::Nbrdf($b) => $e,
            Part::Neural($b) => $e,
        }
    };
}

impl Bxdf for Part<'_> {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        dispatch_part!(self, b => b.eval(wo, wi))
    }
    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        dispatch_part!(self, b => b.pdf(wo, wi))
    }
    #[inline]
    fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        dispatch_part!(self, b => b.sample(wo, u, uc))
    }
    #[inline]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        dispatch_part!(self, b => b.eval_pdf(wo, wi))
    }
}

/// The mixture of the module documentation.
#[derive(Clone, Copy, Debug)]
pub struct Mixture<'a> {
    /// The first `count` are the parts (the rest repeat the first, unused).
    parts: [Part<'a>; MAX_MIX_PARTS],
    /// Normalised weights of the parts, each > 0.
    weights: [f32; MAX_MIX_PARTS],
    count: u8,
    tint: Rgb,
    /// Whether the integrator draws one part per vertex ([`Mixture::draw`]).
    drawn: bool,
}

impl<'a> Mixture<'a> {
    /// The mixture of `parts` (BSDF, weight) with the weights normalised; weights that are
    /// not positive and finite count as 0, and when every weight does, the first part alone
    /// is the mixture. The tint is clamped to [0, 1] per channel (NaN to 0).
    ///
    /// # Panics
    /// If `parts` is empty or holds more than [`MAX_MIX_PARTS`].
    pub fn new(parts: &[(Part<'a>, f32)], tint: Rgb) -> Self {
        assert!(!parts.is_empty() && parts.len() <= MAX_MIX_PARTS, "a mixture has 1 to {MAX_MIX_PARTS} parts, not {}", parts.len());
        let mut mixture = Mixture { parts: [parts[0].0; MAX_MIX_PARTS], weights: [0.0; MAX_MIX_PARTS], count: 0, tint: Rgb::ZERO, drawn: false };
        // NaN to 0 (`clamp` would keep it).
        let unit = |x: f32| if x > 0.0 { x.min(1.0) } else { 0.0 };
        mixture.tint = Rgb::new(unit(tint.x), unit(tint.y), unit(tint.z));
        let total: f32 = parts.iter().map(|&(_, w)| usable(w)).sum();
        for &(part, w) in parts {
            if usable(w) > 0.0 {
                let k = mixture.count as usize;
                mixture.parts[k] = part;
                mixture.weights[k] = w / total;
                mixture.count += 1;
            }
        }
        if mixture.count == 0 || !total.is_finite() {
            mixture.weights = [1.0, 0.0, 0.0, 0.0];
            mixture.parts[0] = parts[0].0;
            mixture.count = 1;
        }
        mixture
    }

    /// [`Mixture::new`] of parts close to each other (a latent blend's palette neighbours),
    /// which the integrator estimates by drawing one part per vertex ([`Mixture::draw`])
    /// rather than evaluating all: unbiased (the path's contribution is linear in the
    /// vertex's BSDF), one evaluation per value, a little variance where the parts differ.
    /// As a [`Bxdf`] it is the same exact mixture.
    pub fn drawn_per_vertex_of(parts: &[(Part<'a>, f32)], tint: Rgb) -> Self {
        Mixture { drawn: true, ..Mixture::new(parts, tint) }
    }

    /// Whether the integrator draws one part per vertex ([`Mixture::drawn_per_vertex_of`]).
    #[inline]
    pub fn drawn_per_vertex(&self) -> bool {
        self.drawn
    }

    /// The part the 1D sample `uc` chooses (probability its weight, [`Mixture::choose`]), as
    /// a mixture of that part alone with the tint, and uc rescaled for its own use.
    #[inline]
    pub fn draw(&self, uc: f32) -> (Self, f32) {
        let (k, uc) = self.choose(uc);
        let mut one = *self;
        one.parts[0] = self.parts[k];
        one.weights = [1.0, 0.0, 0.0, 0.0];
        one.count = 1;
        one.drawn = false;
        (one, uc)
    }

    /// The parts with their normalised weights (those of weight > 0).
    pub fn parts(&self) -> impl Iterator<Item = (Part<'a>, f32)> + '_ {
        (0..self.count as usize).map(|k| (self.parts[k], self.weights[k]))
    }

    /// The tint, in [0, 1] per channel.
    pub fn tint(&self) -> Rgb {
        self.tint
    }
}

/// A weight as the mixture counts it: 0 unless positive and finite.
#[inline]
fn usable(w: f32) -> f32 {
    if w > 0.0 && w.is_finite() {
        w
    } else {
        0.0
    }
}

impl Bxdf for Mixture<'_> {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let mut f = Rgb::ZERO;
        for (part, w) in self.parts() {
            f += w * part.eval(wo, wi);
        }
        self.tint * f
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.parts().map(|(part, w)| w * part.pdf(wo, wi)).sum()
    }

    #[inline]
    fn eval_pdf(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        let (mut f, mut pdf) = (Rgb::ZERO, 0.0);
        for (part, w) in self.parts() {
            let (fk, pk) = part.eval_pdf(wo, wi);
            f += w * fk;
            pdf += w * pk;
        }
        (self.tint * f, pdf)
    }

    fn sample(&self, wo: Vec3, u: Vec2, uc: f32) -> Option<BsdfSample> {
        let (chosen, uc) = self.choose(uc);
        let s = self.parts[chosen].sample(wo, u, uc)?;
        // Summed in the parts' order, as `eval_pdf` sums (and the batched path).
        let (mut f, mut pdf) = (Rgb::ZERO, 0.0);
        for (k, (part, w)) in self.parts().enumerate() {
            let (fk, pk) = if k == chosen { (s.f, s.pdf) } else { part.eval_pdf(wo, s.wi) };
            f += w * fk;
            pdf += w * pk;
        }
        Some(BsdfSample::new(s.wi, self.tint * f, pdf))
    }
}

impl Mixture<'_> {
    /// The part that sampling with the 1D sample `uc` draws from (the one whose share of
    /// [0, 1) holds uc) and uc rescaled to [0, 1) within that share.
    #[inline]
    pub fn choose(&self, uc: f32) -> (usize, f32) {
        let mut chosen = self.count as usize - 1;
        let mut below = 0.0;
        for k in 0..self.count as usize - 1 {
            if uc < below + self.weights[k] {
                chosen = k;
                break;
            }
            below += self.weights[k];
        }
        (chosen, ((uc - below) / self.weights[chosen]).clamp(0.0, 1.0 - f32::EPSILON / 2.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::chi2::{check_sample_consistency, test_bxdf, Chi2Config};
    use crate::testing::data::shipped_latents;
    use std::f32::consts::FRAC_PI_2;

    fn unit(theta: f32, phi: f32) -> Vec3 {
        Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
    }

    /// Two shipped codes decoded.
    fn two_codes() -> [NeuralBsdf; 2] {
        let latents = shipped_latents();
        let names = latents.names();
        let pick = |wanted: &str| names.iter().find(|n| n.as_str() == wanted).cloned().unwrap_or_else(|| names[0].clone());
        [latents.decode(&pick("alum-bronze")).unwrap(), latents.decode(&pick("blue-fabric")).unwrap()]
    }

    #[test]
    fn the_mixture_is_the_weighted_sum_of_its_parts() {
        let [a, b] = two_codes();
        let tint = Rgb::new(0.9, 0.5, 0.2);
        let m = Mixture::new(&[(Part::Neural(&a), 3.0), (Part::Neural(&b), 1.0)], tint);
        for (wo, wi) in [(unit(0.3, 0.0), unit(0.5, 2.0)), (unit(1.2, 1.0), unit(0.1, 4.0)), (unit(0.7, 0.3), unit(0.7, 0.3 + std::f32::consts::PI))] {
            let f = tint * (0.75 * a.eval(wo, wi) + 0.25 * b.eval(wo, wi));
            let pdf = 0.75 * a.pdf(wo, wi) + 0.25 * b.pdf(wo, wi);
            assert!((m.eval(wo, wi) - f).abs().max_element() <= 1e-6 * f.max_element().max(1.0));
            assert!((m.pdf(wo, wi) - pdf).abs() <= 1e-6 * pdf.max(1.0));
            let (fe, pe) = m.eval_pdf(wo, wi);
            assert!((fe - f).abs().max_element() <= 1e-6 * f.max_element().max(1.0) && (pe - pdf).abs() <= 1e-6 * pdf.max(1.0));
        }
        let below = unit(FRAC_PI_2 + 0.1, 0.0);
        assert_eq!(m.eval_pdf(unit(0.3, 0.0), below), (Rgb::ZERO, 0.0));
    }

    #[test]
    fn zero_and_bad_weights_drop_parts_and_all_zero_keeps_the_first() {
        let [a, b] = two_codes();
        let (wo, wi) = (unit(0.4, 0.0), unit(0.6, 2.5));
        let only_b = Mixture::new(&[(Part::Neural(&a), 0.0), (Part::Neural(&b), 0.5)], Rgb::ONE);
        assert_eq!(only_b.parts().count(), 1);
        assert_eq!(only_b.eval(wo, wi), b.eval(wo, wi));
        for weights in [[0.0, 0.0], [f32::NAN, -1.0], [f32::INFINITY, 0.0]] {
            let m = Mixture::new(&[(Part::Neural(&a), weights[0]), (Part::Neural(&b), weights[1])], Rgb::ONE);
            assert_eq!(m.eval(wo, wi), a.eval(wo, wi), "{weights:?}");
        }
        let m = Mixture::new(&[(Part::Neural(&a), 1.0)], Rgb::new(2.0, f32::NAN, -1.0));
        assert_eq!(m.tint(), Rgb::new(1.0, 0.0, 0.0));
    }

    /// Sampling draws the mixture's density (chi-square), its samples carry the mixture's
    /// value and density, for two and for four parts, near the normal and at grazing. Each
    /// sample evaluates every part's network: 200,000 per test, as the tabulated BSDFs'
    /// chi-square tests draw (1 M made this test alone 4.5 min of the debug suite).
    #[test]
    fn sampling_matches_the_mixture_density() {
        let [a, b] = two_codes();
        let config = Chi2Config::default().with_sample_count(200_000);
        let two = Mixture::new(&[(Part::Neural(&a), 0.3), (Part::Neural(&b), 0.7)], Rgb::new(0.8, 0.6, 0.4));
        let four = Mixture::new(&[(Part::Neural(&a), 0.1), (Part::Neural(&b), 0.2), (Part::Neural(&a), 0.3), (Part::Neural(&b), 0.4)], Rgb::ONE);
        for (name, m) in [("two", &two), ("four", &four)] {
            for theta in [0.05f32, 0.8, 1.45] {
                let wo = unit(theta, 0.4);
                let result = test_bxdf(m, wo, &config);
                assert!(result.passed(), "{name} θo {theta}: {}", result.report());
                let consistency = check_sample_consistency(m, wo, 4096);
                assert!(consistency.passed(), "{name} θo {theta}: {consistency:?}");
            }
        }
    }
}
