//! Image files: linear f32 RGB OpenEXR through `exr`, sRGB 8-bit PNG through `image`, and
//! reading EXR/HDR radiance images. Writes go to a temporary file in the target directory
//! that is renamed into place, so an interrupted or failed write never leaves a partial file
//! under the requested name.

use crate::error::{Error, Result};
use crate::support::write_via_temporary;
use crate::Rgb;
use std::path::Path;

/// How linear radiance becomes display values for 8-bit output.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ToneMap {
    /// Clamp to [0, 1] (what Mitsuba 3 writes for PNG).
    #[default]
    Clamp,
    /// The ACES filmic curve (Narkowicz's fit), for high-dynamic-range scenes.
    Aces,
}

/// The sRGB opto-electronic transfer function of a linear value in [0, 1].
#[inline]
pub fn linear_to_srgb(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// The inverse of [`linear_to_srgb`].
#[inline]
pub fn srgb_to_linear(x: f32) -> f32 {
    if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

impl ToneMap {
    /// Maps linear radiance (after exposure) to a display value in [0, 1].
    #[inline]
    pub fn apply(self, x: f32) -> f32 {
        let x = if x.is_finite() { x.max(0.0) } else { 0.0 };
        match self {
            ToneMap::Clamp => x.min(1.0),
            ToneMap::Aces => ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0),
        }
    }
}

/// 8-bit sRGB pixels (RGB interleaved) of a linear image.
pub fn to_srgb8(pixels: &[Rgb], tone_map: ToneMap, exposure: f32) -> Vec<u8> {
    let scale = 2f32.powf(exposure);
    pixels
        .iter()
        .flat_map(|p| p.to_array())
        .map(|c| (linear_to_srgb(tone_map.apply(c * scale)) * 255.0 + 0.5) as u8)
        .collect()
}

/// Writes a text file (statistics, logs) atomically.
pub fn write_text(path: &Path, text: &str) -> Result<()> {
    write_via_temporary(path, |tmp| std::fs::write(tmp, text).map_err(|e| Error::io(path, e)))
}

/// Writes a linear f32 RGB OpenEXR file.
pub fn write_exr(path: &Path, width: u32, height: u32, pixels: &[Rgb]) -> Result<()> {
    assert_eq!(pixels.len(), width as usize * height as usize);
    write_via_temporary(path, |tmp| {
        exr::prelude::write_rgb_file(tmp, width as usize, height as usize, |x, y| {
            let p = pixels[x + y * width as usize];
            (p.x, p.y, p.z)
        })
        .map_err(|e| Error::invalid_file(path, format!("cannot write EXR: {e}")))
    })
}

/// Writes an 8-bit sRGB PNG of a linear image.
pub fn write_png(path: &Path, width: u32, height: u32, pixels: &[Rgb], tone_map: ToneMap, exposure: f32) -> Result<()> {
    write_png_rgb8(path, width, height, &to_srgb8(pixels, tone_map, exposure))
}

/// Writes 8-bit RGB pixels (row-major, 3 bytes each) as a PNG, atomically.
pub fn write_png_rgb8(path: &Path, width: u32, height: u32, rgb8: &[u8]) -> Result<()> {
    write_via_temporary(path, |tmp| {
        image::save_buffer_with_format(tmp, rgb8, width, height, image::ColorType::Rgb8, image::ImageFormat::Png)
            .map_err(|e| Error::invalid_file(path, format!("cannot write PNG: {e}")))
    })
}

/// Output formats recognised from a file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    Exr,
    Png,
}

impl ImageFormat {
    /// The format named by `path`'s extension (`.exr` or `.png`, any case).
    pub fn from_path(path: &Path) -> Option<Self> {
        match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
            "exr" => Some(ImageFormat::Exr),
            "png" => Some(ImageFormat::Png),
            _ => None,
        }
    }
}

/// Writes `pixels` in the format of `path`'s extension.
pub fn write_image(path: &Path, width: u32, height: u32, pixels: &[Rgb], tone_map: ToneMap, exposure: f32) -> Result<()> {
    match ImageFormat::from_path(path) {
        Some(ImageFormat::Exr) => write_exr(path, width, height, pixels),
        Some(ImageFormat::Png) => write_png(path, width, height, pixels, tone_map, exposure),
        None => Err(Error::InvalidArgument {
            flag: "--output".into(),
            reason: format!("{}: unsupported image extension (use .exr or .png)", path.display()),
        }),
    }
}

/// Reads an 8-bit image (a PNG this program wrote): (width, height, RGB8 row-major).
pub fn read_png_rgb8(path: &Path) -> Result<(u32, u32, Vec<u8>)> {
    let img = image::ImageReader::open(path)
        .map_err(|e| Error::io(path, e))?
        .decode()
        .map_err(|e| Error::invalid_file(path, format!("cannot decode image: {e}")))?
        .into_rgb8();
    Ok((img.width(), img.height(), img.into_raw()))
}

/// Reads a linear RGB image (.exr or .hdr): (width, height, pixels row-major).
pub fn read_image(path: &Path) -> Result<(u32, u32, Vec<Rgb>)> {
    let (w, h, px) = crate::lights::environment::read_radiance_image(path)?;
    Ok((w as u32, h as u32, px))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trip_is_exact() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("x.exr");
        let px: Vec<Rgb> = (0..12).map(|i| Rgb::new(i as f32, 1e-5 * i as f32, 1e4)).collect();
        write_exr(&path, 4, 3, &px).expect("write");
        let (w, h, back) = read_image(&path).expect("read");
        assert_eq!((w, h), (4, 3));
        assert_eq!(back, px);
        assert_eq!(std::fs::read_dir(dir.path()).expect("ls").count(), 1, "no temporary left");
    }

    #[test]
    fn srgb_curve_round_trips() {
        for x in [0.0, 0.001, 0.02, 0.5, 1.0] {
            assert!((srgb_to_linear(linear_to_srgb(x)) - x).abs() < 1e-5);
        }
        assert_eq!(to_srgb8(&[Rgb::new(0.0, 1.0, 5.0)], ToneMap::Clamp, 0.0), vec![0, 255, 255]);
        assert!(ToneMap::Aces.apply(1e6) <= 1.0 && ToneMap::Aces.apply(f32::NAN) == 0.0);
    }

    #[test]
    fn unknown_extension_is_an_error() {
        let err = write_image(Path::new("out.bmp"), 1, 1, &[Rgb::ZERO], ToneMap::Clamp, 0.0).unwrap_err();
        assert!(err.to_string().contains("out.bmp"));
    }
}
