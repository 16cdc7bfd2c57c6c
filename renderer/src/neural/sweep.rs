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
//! [`MAX_STEPS`] + 3 decodes of the hypernetwork: about 30,000 evaluations of the small net
//! per frame, milliseconds beside the frame's render.

use crate::neural::energy::{MATCH_QUADRATURE, MATCH_THETAS_DEG};
use crate::neural::latent_library::{LatentCode, LatentLibrary};
use crate::Result;
use glam::DVec3;

/// Secant steps on each channel's ln ρ at most.
pub const MAX_STEPS: usize = 4;

/// |ln ρ − ln ρ_target| below which a channel is balanced.
const TOLERANCE: f64 = 1e-3;

/// The largest change of δ in one step (a factor e² in f).
const MAX_STEP: f64 = 2.0;

impl LatentLibrary {
    /// The code at `t` of the editing sweep from `a` (t = 0) to `b` (t = 1): see the module
    /// documentation. Both codes must come from one file; t = 0 and 1 give the codes
    /// themselves, `t` outside [0, 1] or a sweep from a code to itself the plain
    /// interpolation [`LatentCode::lerp`] (an extrapolation is not balanced). Errors name
    /// the file when a code cannot be decoded.
    pub fn sweep_code(&self, a: &LatentCode, b: &LatentCode, t: f32) -> Result<LatentCode> {
        let mut frame = a.lerp(b, t)?;
        if t == 0.0 || t == 1.0 {
            return Ok(if t == 0.0 { a } else { b }.clone());
        }
        if !(t > 0.0 && t < 1.0) || a == b {
            return Ok(frame);
        }
        let albedos = |code: &LatentCode| -> Result<[DVec3; 3]> {
            let bsdf = self.decode_for_evaluation(code, "sweep frame")?;
            Ok(MATCH_THETAS_DEG.map(|theta| MATCH_QUADRATURE.albedo_at(&bsdf, theta.to_radians())))
        };
        let sum = |rho: &[DVec3; 3]| rho.iter().fold(DVec3::ZERO, |s, r| s + *r);
        let (ends_a, ends_b) = (sum(&albedos(a)?), sum(&albedos(b)?));
        let target = ends_a * f64::from(1.0 - t) + ends_b * f64::from(t);
        let mut now = albedos(&frame)?;
        // Secant steps per channel (a channel's δ moves its own albedo only), from slope 1.
        let mut slope = DVec3::ONE;
        for _ in 0..MAX_STEPS {
            let rho = sum(&now);
            let error = DVec3::from_array([0, 1, 2].map(|c| match target[c] > 0.0 && rho[c] > 0.0 {
                true => (rho[c] / target[c]).ln(),
                false => 0.0,
            }));
            if error.abs().max_element() < TOLERANCE {
                break;
            }
            let step = DVec3::from_array([0, 1, 2].map(|c| (-error[c] / slope[c]).clamp(-MAX_STEP, MAX_STEP)));
            for c in 0..3 {
                frame.offset[c] += step[c] as f32;
            }
            let next = albedos(&frame)?;
            let (rho_next, rho_now) = (sum(&next), rho);
            for c in 0..3 {
                if step[c] != 0.0 && rho_next[c] > 0.0 && rho_now[c] > 0.0 {
                    slope[c] = ((rho_next[c] / rho_now[c]).ln() / step[c]).max(0.1);
                }
            }
            now = next;
        }
        // No channel above 1 at any of the angles.
        let top = now.iter().fold(DVec3::ZERO, |m, r| m.max(*r));
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
        assert_eq!(lib.sweep_code(&a, &b, 0.0).unwrap(), a);
        assert_eq!(lib.sweep_code(&a, &b, 1.0).unwrap(), b);
        assert_eq!(lib.sweep_code(&a, &a, 0.5).unwrap(), a);
        let albedo = |code: &LatentCode| {
            let bsdf = lib.decode_for_evaluation(code, "test").unwrap();
            MATCH_THETAS_DEG.map(|theta| MATCH_QUADRATURE.albedo_at(&bsdf, theta.to_radians()))
        };
        let sum = |r: [DVec3; 3]| r[0] + r[1] + r[2];
        let (ra, rb) = (sum(albedo(&a)), sum(albedo(&b)));
        for t in [0.1, 0.5, 0.8] {
            let frame = lib.sweep_code(&a, &b, t).unwrap();
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
