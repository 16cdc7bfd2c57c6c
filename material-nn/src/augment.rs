//! Training-time augmentation: synthetic variants of the training materials, made from them
//! on the fly, so that the decoder learns codes for colours and angle-dependent colour that
//! MERL's 100 materials do not hold (most are red, brown or grey; none changes hue with angle
//! as interference and "chromaflair" paints do).
//!
//! A variant of material A is, per bin, `(1 − s(θd)) · π_A(f_A) + s(θd) · π_B(f_B)`:
//! - `π` permutes the RGB channels (one of the six orders, drawn per material);
//! - with probability [`Augmentation::blend`], B is another training material and `s` a
//!   smooth step over the difference angle θd (radians): centre uniform in
//!   [`BLEND_CENTRE`], width uniform in [`BLEND_WIDTH`], rising or falling; otherwise `s ≡ 0`
//!   (A with its channels permuted).
//!
//! Both materials are physically plausible BRDFs and `s` depends on θd alone, so a variant is
//! reciprocal, and as a convex combination it reflects no more than the brighter of the two.
//! A bin is unmeasured in the variant where either material it draws on is unmeasured.
//! Variants exist for one step only; validation and evaluation never see them.

use crate::dataset::MaterialTable;
use rand::Rng;
use renderer::formats::merl::THETA_D_BINS;
use serde::{Deserialize, Serialize};
use std::f32::consts::FRAC_PI_2;
use std::ops::Range;

/// Range of the blend's centre over θd (radians: 15°–75°).
pub const BLEND_CENTRE: Range<f32> = 0.26..1.31;
/// Range of the blend's width over θd (radians: 5°–30°).
pub const BLEND_WIDTH: Range<f32> = 0.087..0.52;

/// The six orders of the RGB channels.
const PERMUTATIONS: [[usize; 3]; 6] = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];

/// How often training steps see a variant instead of the material itself.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Augmentation {
    /// Share of the steps whose material is replaced by a variant (0 = none).
    pub share: f32,
    /// Share of the variants that blend two materials over θd (the others permute one
    /// material's channels).
    pub blend: f32,
}

impl Default for Augmentation {
    fn default() -> Self {
        Augmentation { share: 0.0, blend: 0.5 }
    }
}

impl Augmentation {
    /// Checks ranges; the message names the field.
    pub fn check(&self) -> Result<(), String> {
        for (name, v) in [("augment.share", self.share), ("augment.blend", self.blend)] {
            if !(0.0..=1.0).contains(&v) {
                return Err(format!("{name} {v} must be in [0, 1]"));
            }
        }
        Ok(())
    }

    /// The recipe of this step's material: `None` (the material itself) or a variant of
    /// training material `a` of `n`, its partner (if it blends) drawn among the other `n − 1`.
    pub fn draw(&self, a: usize, n: usize, rng: &mut impl Rng) -> Option<Recipe> {
        if self.share == 0.0 || rng.random::<f32>() >= self.share {
            return None;
        }
        let partner = (n > 1 && rng.random::<f32>() < self.blend).then(|| {
            let index = rng.random_range(0..n - 1);
            Partner {
                index: if index >= a { index + 1 } else { index },
                order: rng.random_range(0..PERMUTATIONS.len()),
                centre: rng.random_range(BLEND_CENTRE),
                width: rng.random_range(BLEND_WIDTH),
                rising: rng.random(),
            }
        });
        // A variant of one material changes its channel order; a blend may keep both.
        let first = if partner.is_some() { 0 } else { 1 };
        Some(Recipe { order_a: rng.random_range(first..PERMUTATIONS.len()), partner })
    }
}

/// The second material of a blended variant and its blend over θd.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Partner {
    /// Index of material B among the training materials.
    pub index: usize,
    /// Index into the channel orders applied to B.
    pub order: usize,
    /// θd (radians) where s = 1/2.
    pub centre: f32,
    /// θd (radians) over which s goes from 0 to 1.
    pub width: f32,
    /// Whether s rises with θd (B at grazing angles) or falls (B near normal incidence).
    pub rising: bool,
}

/// How one variant is made (drawn by [`Augmentation::draw`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Recipe {
    /// Index into the channel orders applied to A.
    pub order_a: usize,
    /// The blended material, if any.
    pub partner: Option<Partner>,
}

impl Partner {
    /// s(θd) ∈ [0, 1]: a smooth step of width `width` centred on `centre`.
    pub fn weight(&self, theta_d: f32) -> f32 {
        let x = ((theta_d - self.centre) / self.width + 0.5).clamp(0.0, 1.0);
        let s = x * x * (3.0 - 2.0 * x);
        if self.rising { s } else { 1.0 - s }
    }
}

impl Recipe {
    /// The variant's table from material `a` and, for a blend, the partner's table `b`.
    pub fn apply(&self, a: &MaterialTable, b: Option<&MaterialTable>) -> MaterialTable {
        let pa = PERMUTATIONS[self.order_a];
        let permute = |v: [f32; 3], p: [usize; 3]| [v[p[0]], v[p[1]], v[p[2]]];
        let name = match (self.partner, b) {
            (Some(_), Some(b)) => format!("{}~{}", a.name, b.name),
            _ => format!("{}~{:?}", a.name, pa),
        };
        let a = MaterialTable {
            name: String::new(),
            values: a.values.iter().map(|&v| permute(v, pa)).collect(),
        };
        match (self.partner, b) {
            (Some(partner), Some(b)) => {
                let pb = PERMUTATIONS[partner.order];
                let b = MaterialTable {
                    name: String::new(),
                    values: b.values.iter().map(|&v| permute(v, pb)).collect(),
                };
                let weights: Vec<f32> = (0..THETA_D_BINS)
                    .map(|i| partner.weight((i as f32 + 0.5) / THETA_D_BINS as f32 * FRAC_PI_2))
                    .collect();
                a.blend(&b, name, |theta_d| weights[theta_d])
            }
            _ => MaterialTable { name, ..a },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use renderer::formats::merl::BIN_COUNT;

    fn table(name: &str, v: [f32; 3]) -> MaterialTable {
        let mut values = vec![v; BIN_COUNT];
        values[7] = [-1.0, v[1], v[2]];
        MaterialTable { name: name.into(), values }
    }

    #[test]
    fn variants_permute_and_blend_over_theta_d() {
        let (a, b) = (table("a", [1.0, 2.0, 3.0]), table("b", [10.0, 20.0, 30.0]));
        let permuted = Recipe { order_a: 5, partner: None }.apply(&a, None);
        assert_eq!(permuted.values[0], [3.0, 2.0, 1.0]);
        assert_eq!(permuted.values[7], [a.values[7][2], a.values[7][1], -1.0]);
        let partner = Partner { index: 1, order: 0, centre: 0.8, width: 0.2, rising: true };
        let blended = Recipe { order_a: 0, partner: Some(partner) }.apply(&a, Some(&b));
        // θd index 0 (0.5°) is all A, index 89 (89.5°) all B, and the step is monotone.
        let at = |id: usize| blended.values[renderer::formats::merl::bin_index(3, id, 5)];
        assert_eq!(at(0), [1.0, 2.0, 3.0]);
        assert_eq!(at(89), [10.0, 20.0, 30.0]);
        assert!((1..90).all(|id| at(id)[0] >= at(id - 1)[0]));
        assert_eq!(blended.values[7][0], -1.0, "unmeasured in A stays unmeasured");
        let falling = Partner { rising: false, ..partner };
        assert!((partner.weight(0.8) - 0.5).abs() < 1e-6 && (falling.weight(0.3) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn draws_follow_the_shares_and_the_seed() {
        let augment = Augmentation { share: 0.5, blend: 0.5 };
        let draw = |seed| {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
            (0..2000).map(|_| augment.draw(1, 3, &mut rng)).collect::<Vec<_>>()
        };
        let recipes = draw(3);
        assert_eq!(recipes, draw(3));
        let variants = recipes.iter().flatten().count();
        let blends = recipes.iter().flatten().filter(|r| r.partner.is_some()).count();
        assert!((900..1100).contains(&variants), "{variants} variants of 2000");
        assert!((400..600).contains(&blends), "{blends} blends of {variants}");
        assert!(recipes.iter().flatten().all(|r| r.partner.is_some() || r.order_a != 0));
        assert!(recipes.iter().flatten().filter_map(|r| r.partner).all(|p| p.index != 1 && p.index < 3));
        assert!(Augmentation::default().draw(0, 2, &mut rand_pcg::Pcg64::seed_from_u64(1)).is_none());
        assert!(Augmentation { share: 1.5, blend: 0.0 }.check().is_err());
    }
}
