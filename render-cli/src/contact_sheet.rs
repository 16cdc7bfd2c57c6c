//! A labelled contact sheet of rendered frames (sweeps): frames in rows, each with its label
//! drawn in an 8×8 bitmap font underneath.

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
