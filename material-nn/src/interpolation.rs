//! Training on latent interpolations, so that the segment between two codes holds the
//! mixture of their materials (the editing of `render --sweep`, issue 49).
//!
//! With the talk's recipe alone, decoding (1 − t) z_A + t z_B gives about the geometric mean
//! of the two BRDFs (the mapped space is logarithmic and the decoder close to linear in y
//! along such a line), darker than both ends between dissimilar materials
//! (docs/training.md, "Editing"). Here a share of the steps adds an **interpolated frame** to
//! the step's material A: a partner B drawn among the other training materials, t uniform in
//! [0, 1], the frame's code the same blend of the two materials' encoder codes, and its
//! target the linear blend of their tables, (1 − t) f_A + t f_B (unmeasured where either
//! is). The frame is one more material of the step for the loss (L_rec, and L_fre against the
//! blend's own slices), so the decoder is trained to map straight lines between codes onto
//! arithmetic mixtures. It costs the partner's encoder pass and the frame's decode and
//! evaluation, about twice a plain step.

use rand::Rng;
use serde::{Deserialize, Serialize};

/// How often a step adds an interpolated frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Interpolation {
    /// Share of the steps that add one interpolated frame per material (0 = none: the talk's
    /// recipe).
    pub share: f32,
}

impl Default for Interpolation {
    fn default() -> Self {
        Interpolation { share: 0.0 }
    }
}

/// One interpolated frame between training materials A (the step's) and B.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Index of material B among the training materials.
    pub partner: usize,
    /// Position along the segment: the code (1 − t) z_A + t z_B, the target (1 − t) f_A + t f_B.
    pub t: f32,
}

impl Interpolation {
    /// Checks ranges; the message names the field.
    pub fn check(&self) -> Result<(), String> {
        if !(0.0..=1.0).contains(&self.share) {
            return Err(format!("interpolation.share {} must be in [0, 1]", self.share));
        }
        Ok(())
    }

    /// The frame this step adds to training material `a` of `n`, if any: the partner drawn
    /// among the other `n − 1`. Draws nothing from `rng` when the share is 0, so runs without
    /// interpolation are those of the talk's recipe.
    pub fn draw(&self, a: usize, n: usize, rng: &mut impl Rng) -> Option<Frame> {
        if self.share == 0.0 || n < 2 || rng.random::<f32>() >= self.share {
            return None;
        }
        let index = rng.random_range(0..n - 1);
        Some(Frame {
            partner: if index >= a { index + 1 } else { index },
            t: rng.random(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::MaterialTable;
    use rand::SeedableRng;

    #[test]
    fn frames_follow_the_share_and_never_pair_a_material_with_itself() {
        let every = Interpolation { share: 1.0 };
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let frames: Vec<Frame> = (0..3000).map(|i| every.draw(i % 4, 4, &mut rng).unwrap()).collect();
        assert!(frames.iter().enumerate().all(|(i, f)| f.partner != i % 4 && f.partner < 4));
        assert!(frames.iter().all(|f| (0.0..1.0).contains(&f.t)));
        let mean = frames.iter().map(|f| f.t as f64).sum::<f64>() / frames.len() as f64;
        assert!((mean - 0.5).abs() < 0.02, "t uniform: mean {mean}");
        let half = Interpolation { share: 0.5 };
        let drawn = (0..2000).filter(|_| half.draw(0, 3, &mut rng).is_some()).count();
        assert!((900..1100).contains(&drawn), "{drawn} frames of 2000");
        // No share, or no partner: nothing drawn, the generator untouched.
        let mut a = rand_pcg::Pcg64::seed_from_u64(1);
        assert!(Interpolation::default().draw(0, 5, &mut a).is_none());
        assert!(every.draw(0, 1, &mut a).is_none());
        assert_eq!(a.random::<u64>(), rand_pcg::Pcg64::seed_from_u64(1).random::<u64>());
        assert!(Interpolation { share: -0.1 }.check().unwrap_err().contains("interpolation.share"));
    }

    #[test]
    fn the_target_is_the_linear_blend_of_the_tables() {
        let n = renderer::formats::merl::BIN_COUNT;
        let a = MaterialTable { name: "a".into(), values: vec![[1.0, 2.0, -1.0]; n] };
        let b = MaterialTable { name: "b".into(), values: vec![[3.0, 0.0, 5.0]; n] };
        let frame = a.blend(&b, "a~b".into(), |_| 0.25);
        assert_eq!(frame.values[12345], [1.5, 1.5, -1.0]);
        assert_eq!(frame.name, "a~b");
    }
}
