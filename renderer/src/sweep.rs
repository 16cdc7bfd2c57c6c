//! Material-editing sweeps: latent codes interpolated between two materials,
//! z(t) = (1 − t) z_A + t z_B, the linear blend of their measured tables to compare against,
//! and a labelled contact sheet of the frames.

use crate::latent_library::LatentCode;
use crate::merl::MerlTable;
use crate::{Error, Result};
use rayon::prelude::*;

/// A sweep from latent A to latent B in `steps` frames (`render --sweep A:B:STEPS`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SweepSpec {
    pub from: String,
    pub to: String,
    pub steps: usize,
}

impl std::str::FromStr for SweepSpec {
    type Err = String;

    /// Parses `A:B:STEPS` with STEPS in 2..=1000.
    fn from_str(s: &str) -> Result<Self, String> {
        let err = || format!("'{s}' is not A:B:STEPS (two latent names and 2 to 1000 frames)");
        let (names, steps) = s.rsplit_once(':').ok_or_else(err)?;
        let (from, to) = names.rsplit_once(':').ok_or_else(err)?;
        let steps: usize = steps.trim().parse().map_err(|_| err())?;
        if from.is_empty() || to.is_empty() || !(2..=1000).contains(&steps) {
            return Err(err());
        }
        Ok(SweepSpec {
            from: from.to_string(),
            to: to.to_string(),
            steps,
        })
    }
}

impl SweepSpec {
    /// The interpolation parameters of the frames: k / (steps − 1), from 0 to 1.
    pub fn times(&self) -> Vec<f32> {
        (0..self.steps).map(|k| k as f32 / (self.steps - 1) as f32).collect()
    }
}

/// z(t) = (1 − t) a + t b; both codes must come from the same file (one decoder).
pub fn lerp_code(a: &LatentCode, b: &LatentCode, t: f32) -> Result<LatentCode> {
    if a.file != b.file || a.z.len() != b.z.len() {
        return Err(Error::InvalidArgument {
            flag: "--sweep".to_string(),
            reason: "the two latent codes come from different latent files".to_string(),
        });
    }
    Ok(LatentCode {
        file: a.file,
        z: a.z.iter().zip(&b.z).map(|(x, y)| (1.0 - t) * x + t * y).collect(),
    })
}

/// The linear blend (1 − t) A + t B of two tables, bin by bin; a bin unmeasured in either is
/// unmeasured in the blend. `t` in [0, 1].
pub fn blend_tables(a: &MerlTable, b: &MerlTable, t: f64) -> MerlTable {
    let raw: Vec<f64> = a
        .raw()
        .par_iter()
        .zip(b.raw())
        .map(|(&x, &y)| if x < 0.0 || y < 0.0 { -1.0 } else { (1.0 - t) * x + t * y })
        .collect();
    MerlTable::from_raw(raw, "blended table").expect("a blend of valid tables is valid")
}

/// One picture of a contact sheet: 8-bit RGB pixels and the label drawn under it.
pub struct SheetFrame {
    pub label: String,
    pub rgb8: Vec<u8>,
}

/// Lays out frames of `width` × `height` in rows of `columns`, each with its label (8×8
/// bitmap font, scaled) underneath, on a dark background; returns (width, height, RGB8).
pub fn contact_sheet(frames: &[SheetFrame], width: u32, height: u32, columns: usize) -> (u32, u32, Vec<u8>) {
    const PAD: u32 = 8;
    let scale = (width / 128).clamp(1, 3);
    let label_h = 8 * scale + PAD;
    let columns = columns.clamp(1, frames.len().max(1)) as u32;
    let rows = (frames.len() as u32).div_ceil(columns).max(1);
    let (cell_w, cell_h) = (width + PAD, height + label_h + PAD);
    let (sheet_w, sheet_h) = (columns * cell_w + PAD, rows * cell_h + PAD);
    let mut pixels = vec![24u8; (sheet_w * sheet_h * 3) as usize];
    for (k, frame) in frames.iter().enumerate() {
        let (cx, cy) = (k as u32 % columns, k as u32 / columns);
        let (x0, y0) = (PAD + cx * cell_w, PAD + cy * cell_h);
        for y in 0..height {
            let src = (y * width * 3) as usize;
            let dst = (((y0 + y) * sheet_w + x0) * 3) as usize;
            pixels[dst..dst + (width * 3) as usize].copy_from_slice(&frame.rgb8[src..src + (width * 3) as usize]);
        }
        draw_text(&mut pixels, sheet_w, x0, y0 + height + PAD / 2, &frame.label, scale, width);
    }
    (sheet_w, sheet_h, pixels)
}

/// Draws `text` in light grey with its top-left corner at (x, y), clipped to `max_width`.
fn draw_text(pixels: &mut [u8], sheet_w: u32, x: u32, y: u32, text: &str, scale: u32, max_width: u32) {
    use font8x8::UnicodeFonts;
    for (i, ch) in text.chars().enumerate() {
        let glyph = font8x8::BASIC_FONTS.get(ch).or_else(|| font8x8::BASIC_FONTS.get('?')).unwrap_or([0; 8]);
        let gx = i as u32 * 8 * scale;
        if gx + 8 * scale > max_width {
            break;
        }
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8u32 {
                if bits >> col & 1 == 0 {
                    continue;
                }
                for dy in 0..scale {
                    for dx in 0..scale {
                        let px = x + gx + col * scale + dx;
                        let py = y + row as u32 * scale + dy;
                        let o = ((py * sheet_w + px) * 3) as usize;
                        if o + 3 <= pixels.len() {
                            pixels[o..o + 3].copy_from_slice(&[230, 230, 230]);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_sweep_specs() {
        let s: SweepSpec = "alum-bronze:chrome:5".parse().unwrap();
        assert_eq!(s.times(), vec![0.0, 0.25, 0.5, 0.75, 1.0]);
        assert_eq!((s.from.as_str(), s.to.as_str()), ("alum-bronze", "chrome"));
        for bad in ["a:b", "a:b:1", "a:b:x", ":b:3", "a::3", "a:b:100000"] {
            assert!(bad.parse::<SweepSpec>().is_err(), "{bad}");
        }
    }

    #[test]
    fn lerp_hits_the_end_points() {
        let a = LatentCode { file: 0, z: vec![1.0, -2.0] };
        let b = LatentCode { file: 0, z: vec![3.0, 2.0] };
        assert_eq!(lerp_code(&a, &b, 0.0).unwrap(), a);
        assert_eq!(lerp_code(&a, &b, 1.0).unwrap(), b);
        assert_eq!(lerp_code(&a, &b, 0.5).unwrap().z, vec![2.0, 0.0]);
        assert!(lerp_code(&a, &LatentCode { file: 1, z: vec![0.0, 0.0] }, 0.5).is_err());
    }

    #[test]
    fn blend_is_linear_and_keeps_unmeasured_bins() {
        let a = MerlTable::from_fn(|_, _, _| glam::Vec3::splat(1.0));
        let b = MerlTable::from_fn(|th, _, _| if th > 1.5 { glam::Vec3::splat(-1.0) } else { glam::Vec3::splat(3.0) });
        let m = blend_tables(&a, &b, 0.25);
        let (i_measured, i_unmeasured) = (0, crate::merl::bin_index(89, 0, 0));
        let want = 0.75 * a.value(i_measured)[0] + 0.25 * b.value(i_measured)[0];
        assert!((m.value(i_measured)[0] - want).abs() < 1e-12);
        assert!(!m.is_measured(i_unmeasured));
    }

    #[test]
    fn contact_sheet_places_frames_and_labels() {
        let frames: Vec<SheetFrame> = (0..3)
            .map(|k| SheetFrame {
                label: format!("t={k}"),
                rgb8: vec![100 + k as u8; 16 * 12 * 3],
            })
            .collect();
        let (w, h, px) = contact_sheet(&frames, 16, 12, 2);
        assert_eq!(px.len(), (w * h * 3) as usize);
        assert_eq!((w, h), (2 * 24 + 8, 2 * (12 + 16 + 8) + 8));
        // The first pixel of frame 1 (second column) and frame 2 (second row).
        assert_eq!(px[((8 * w + 8 + 24) * 3) as usize], 101);
        assert_eq!(px[(((8 + 36) * w + 8) * 3) as usize], 102);
        // Some label pixels are drawn below frame 0.
        let label_rows = &px[((8 + 12) * w * 3) as usize..((8 + 12 + 16) * w * 3) as usize];
        assert!(label_rows.contains(&230));
    }
}
