//! Material-editing sweeps: the latent code at t of a sweep from one code to another, as
//! `render --sweep`, the glTF `blend` palettes and the plugins' blends decode it.
//!
//! **The rule.** Frame t is [`LatentCode::lerp`] of the ends (z and the output offsets δ
//! interpolated, each end's residual faded out near its end), with δ then moved per RGB
//! channel so that the frame's directional albedo — summed over the viewing angles
//! [`MATCH_THETAS_DEG`] on the quadrature [`MATCH_QUADRATURE`] — is (1 − t) ρ_A + t ρ_B, the
//! albedo a linear blend of the two materials has. A frame stays one decoded network, a point
//! of the latent space with its corrections; the ends (t = 0, 1) are the codes themselves.
//!
//! **Why.** Linear paths through the latent space lose energy between dissimilar materials:
//! the decoder's frames there reflect less than either end (docs/training.md "Editing": a
//! metal-to-metal sweep of the shipped model fell to 0.63 of its darker end's albedo, its
//! rendered sphere to 0.72). The colour offset is the code's exact energy control (under both
//! mappings ln f grows at least one for one with δ), so matching it to the blend's albedo
//! keeps every frame as bright as the materials it lies between, while z carries the shape.
//!
//! **Bounds.** Where a frame's albedo at one of the angles would exceed 1 in a channel, that
//! channel's δ is lowered by ln of the excess (ln ρ falls at least as fast as δ), so no
//! balanced frame reflects more than it receives at those angles.
//!
//! **Cost.** The ends' and the frame's albedo on 3 × ≤ 1,440 directions, up to
//! [`MAX_STEPS`] + 1 decodes of the hypernetwork a frame (the ends' two once per
//! [`Sweep`]): about 20,000 evaluations of the small net per frame, milliseconds beside the
//! frame's render.

use crate::neural::energy::{balance_offsets, MATCH_QUADRATURE, MATCH_THETAS_DEG};
use crate::neural::latent_library::{LatentCode, LatentLibrary};
use crate::Result;
use glam::DVec3;

/// Secant steps on each channel's ln ρ at most.
pub const MAX_STEPS: usize = 4;

/// |ln ρ − ln ρ_target| below which a channel is balanced.
const TOLERANCE: f64 = 1e-3;

/// An editing sweep from code `a` (t = 0) to code `b` (t = 1) of one library, with the ends'
/// albedos computed once: [`Sweep::code`] gives its frames (see the module documentation).
#[derive(Debug)]
pub struct Sweep<'a> {
    library: &'a LatentLibrary,
    a: LatentCode,
    b: LatentCode,
    /// The ends' directional albedo summed over [`MATCH_THETAS_DEG`]; `None` for a sweep
    /// from a code to itself.
    ends: Option<(DVec3, DVec3)>,
}

impl LatentLibrary {
    /// The editing sweep from `a` to `b` (codes of this library); decodes both ends once for
    /// their albedo. Errors name the file when a code cannot be decoded.
    pub fn sweep(&self, a: &LatentCode, b: &LatentCode) -> Result<Sweep<'_>> {
        let ends = match a == b {
            true => None,
            false => Some((albedo_sum(&self.albedos(a)?), albedo_sum(&self.albedos(b)?))),
        };
        Ok(Sweep { library: self, a: a.clone(), b: b.clone(), ends })
    }

    /// A code's directional albedo at each of [`MATCH_THETAS_DEG`].
    fn albedos(&self, code: &LatentCode) -> Result<[DVec3; 3]> {
        let bsdf = self.decode_for_evaluation(code, "sweep frame")?;
        Ok(MATCH_THETAS_DEG.map(|theta| MATCH_QUADRATURE.albedo_at(&bsdf, theta.to_radians())))
    }
}

fn albedo_sum(rho: &[DVec3; 3]) -> DVec3 {
    rho.iter().fold(DVec3::ZERO, |s, r| s + *r)
}

impl Sweep<'_> {
    /// The code at `t`: t = 0 and 1 give the ends themselves, `t` outside [0, 1] or a sweep
    /// from a code to itself the plain interpolation [`LatentCode::lerp`] (an extrapolation
    /// is not balanced). Errors name the file when a frame cannot be decoded.
    pub fn code(&self, t: f32) -> Result<LatentCode> {
        let mut frame = self.a.lerp(&self.b, t)?;
        if t == 0.0 || t == 1.0 {
            return Ok(if t == 0.0 { &self.a } else { &self.b }.clone());
        }
        let Some((ends_a, ends_b)) = self.ends.filter(|_| t > 0.0 && t < 1.0) else {
            return Ok(frame);
        };
        let target = ends_a * f64::from(1.0 - t) + ends_b * f64::from(t);
        let mut last = [DVec3::ZERO; 3];
        frame.offset = balance_offsets(frame.offset, target, MAX_STEPS, TOLERANCE, |offset| {
            last = self.library.albedos(&LatentCode { offset, ..frame.clone() })?;
            Ok(albedo_sum(&last))
        })?;
        // No channel above 1 at any of the angles (`last` is the albedo at the final offsets).
        let top = last.iter().fold(DVec3::ZERO, |m, r| m.max(*r));
        for c in 0..3 {
            if top[c] > 1.0 {
                frame.offset[c] -= top[c].ln() as f32;
            }
        }
        Ok(frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::neural::latent_library::tests::library;

    /// The balanced frames' albedo, summed over the matching angles, is the blend of the
    /// ends' to the tolerance (or capped at 1 per angle); the ends and a sweep from a code to
    /// itself are the codes unchanged; only the offsets differ from the plain interpolation.
    #[test]
    fn frames_carry_the_blend_of_the_ends_albedo() {
        let (_dir, lib) = library();
        let names = lib.names();
        let (a, b) = (lib.latent(&names[0]).unwrap(), lib.latent(&names[1]).unwrap());
        let sweep = lib.sweep(&a, &b).unwrap();
        assert_eq!(sweep.code(0.0).unwrap(), a);
        assert_eq!(sweep.code(1.0).unwrap(), b);
        assert_eq!(lib.sweep(&a, &a).unwrap().code(0.5).unwrap(), a);
        let albedo = |code: &LatentCode| {
            let bsdf = lib.decode_for_evaluation(code, "test").unwrap();
            MATCH_THETAS_DEG.map(|theta| MATCH_QUADRATURE.albedo_at(&bsdf, theta.to_radians()))
        };
        let sum = |r: [DVec3; 3]| r[0] + r[1] + r[2];
        let (ra, rb) = (sum(albedo(&a)), sum(albedo(&b)));
        for t in [0.1, 0.5, 0.8] {
            let frame = sweep.code(t).unwrap();
            let plain = a.lerp(&b, t).unwrap();
            assert_eq!((&frame.z, &frame.residual), (&plain.z, &plain.residual), "t = {t}");
            let per_angle = albedo(&frame);
            let (rho, target) = (sum(per_angle), ra * f64::from(1.0 - t) + rb * f64::from(t));
            for c in 0..3 {
                // Balanced, or lowered below the blend by the cap.
                let off = (rho[c] / target[c]).ln().abs();
                assert!(off < 5e-3 || rho[c] < target[c], "t = {t}, channel {c}: albedo {} against {}", rho[c], target[c]);
                assert!(per_angle.iter().all(|r| r[c] <= 1.0 + 1e-3), "t = {t}: {per_angle:?}");
            }
        }
    }
}
