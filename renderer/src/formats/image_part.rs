//! Parts of one image rendered separately (`render --region` or `--tile`, e.g. on the
//! machines of a render farm) and their assembly (`render merge`).
//!
//! A part is an OpenEXR file (linear f32 RGB, lossless) whose *data window* is the part's
//! pixels and whose *display window* is the whole image, as OpenEXR defines the two (other
//! EXR readers place the part where it belongs in the frame). Custom string attributes
//! `render:KEY` record the settings that rendered it (scene, camera, samples, seed, ...);
//! merging refuses parts whose settings differ, that overlap, or that leave pixels out.

use crate::error::{Error, Result};
use crate::film::Region;
use crate::support::{write_via_temporary, MAX_RESOLUTION};
use crate::Rgb;
use exr::meta::attribute::{AttributeValue, IntegerBounds, Text};
use exr::meta::MetaData;
use exr::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Prefix of the EXR attributes holding a part's settings.
const SETTING_PREFIX: &str = "render:";

/// One rendered part of an image.
#[derive(Clone, Debug, PartialEq)]
pub struct ImagePart {
    /// Size of the whole image (the EXR display window).
    pub full_width: u32,
    pub full_height: u32,
    /// Where the part lies (the EXR data window).
    pub region: Region,
    /// The part's linear RGB radiance, row-major from the region's top-left pixel.
    pub pixels: Vec<Rgb>,
    /// What rendered it; every part of one image must carry the same settings.
    pub settings: BTreeMap<String, String>,
}

impl ImagePart {
    /// Writes the part as an OpenEXR file (atomically, see [`write_via_temporary`]).
    pub fn write_exr(&self, path: &Path) -> Result<()> {
        assert_eq!(self.pixels.len(), self.region.pixel_count(), "pixels of the region");
        assert!(self.region.is_within(self.full_width, self.full_height), "region inside the image");
        let r = self.region;
        let width = r.width() as usize;
        let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
            let p = self.pixels[x + y * width];
            (p.x, p.y, p.z)
        });
        let other = self.settings.iter().map(|(key, value)| {
            (Text::from(format!("{SETTING_PREFIX}{key}").as_str()), AttributeValue::Text(Text::from(value.as_str())))
        });
        let attributes = LayerAttributes {
            layer_position: Vec2(r.x0 as i32, r.y0 as i32),
            other: other.collect(),
            ..LayerAttributes::default()
        };
        let layer = Layer::new((width, r.height() as usize), attributes, Encoding::FAST_LOSSLESS, channels);
        let display = IntegerBounds::new(Vec2(0, 0), Vec2(self.full_width as usize, self.full_height as usize));
        let image = Image::new(ImageAttributes::new(display), layer);
        write_via_temporary(path, |tmp| {
            image
                .write()
                .to_file(tmp)
                .map_err(|e| Error::invalid_file(path, format!("cannot write EXR: {e}")))
        })
    }

    /// Reads a part written by [`ImagePart::write_exr`]: an RGB EXR whose data window lies
    /// inside a display window with its origin at (0, 0).
    pub fn read_exr(path: &Path) -> Result<ImagePart> {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        ImagePart::from_exr_bytes(&bytes, path)
    }

    /// [`ImagePart::read_exr`] of a file's bytes; errors name `path`. The windows are
    /// checked from the header before any pixel is read (a damaged header could otherwise
    /// ask for any amount of memory).
    pub fn from_exr_bytes(bytes: &[u8], path: &Path) -> Result<ImagePart> {
        let invalid = |reason: String| Error::invalid_file(path, reason);
        let meta = MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
            .map_err(|e| invalid(format!("not a readable RGB OpenEXR image ({e})")))?;
        // Every header (the reader takes the first with R, G and B): its windows, and its
        // block (tile) size, by which the reader sizes its buffers: a block may outsize a
        // small image, but not ask for more than the whole part or 1 MiB.
        let mut windows = None;
        for header in &meta.headers {
            let (w, h, region) = part_windows(header.shared_attributes.display_window, header.data_window()).map_err(invalid)?;
            let part_bytes = region.pixel_count().saturating_mul(header.channels.bytes_per_pixel);
            if header.deep || header.max_block_byte_size() > part_bytes.max(1 << 20) {
                return Err(invalid(format!(
                    "blocks of {} bytes for a part of {part_bytes} bytes: not a part of a render",
                    header.max_block_byte_size()
                )));
            }
            windows.get_or_insert((w, h, region));
        }
        let (full_width, full_height, region) = windows.ok_or_else(|| invalid("an OpenEXR file without a header".into()))?;
        let image = read()
            .no_deep_data()
            .largest_resolution_level()
            .specific_channels()
            .required("R")
            .required("G")
            .required("B")
            .collect_pixels(
                |size: Vec2<usize>, _| (size.width(), vec![Rgb::ZERO; size.area()]),
                |(width, pixels): &mut (usize, Vec<Rgb>), Vec2(x, y), (r, g, b): (f32, f32, f32)| {
                    pixels[x + y * *width] = Rgb::new(r, g, b)
                },
            )
            .first_valid_layer()
            .all_attributes()
            .from_buffered(std::io::Cursor::new(bytes))
            .map_err(|e| invalid(format!("not a readable RGB OpenEXR image ({e})")))?;
        let layer = image.layer_data;
        let data = IntegerBounds::new(layer.attributes.layer_position, layer.size);
        if part_windows(image.attributes.display_window, data) != Ok((full_width, full_height, region)) {
            return Err(invalid("its RGB layer is not its first header's (a file of several parts)".into()));
        }
        let settings = layer
            .attributes
            .other
            .iter()
            .chain(&image.attributes.other)
            .filter_map(|(key, value)| {
                let key = key.to_string().strip_prefix(SETTING_PREFIX)?.to_string();
                match value {
                    AttributeValue::Text(text) => Some((key, text.to_string())),
                    _ => None,
                }
            })
            .collect();
        Ok(ImagePart {
            full_width,
            full_height,
            region,
            pixels: layer.channel_data.pixels.1,
            settings,
        })
    }
}

/// The whole image's size and the part's region from an EXR's display and data windows: the
/// display window must start at (0, 0) and be at most [`MAX_RESOLUTION`] on a side, the data
/// window non-empty and inside it.
fn part_windows(display: IntegerBounds, data: IntegerBounds) -> std::result::Result<(u32, u32, Region), String> {
    let (dw, dh) = (display.size.width(), display.size.height());
    if display.position != Vec2(0, 0) {
        return Err(format!(
            "display window starts at ({}, {}), not (0, 0): not a part of a render",
            display.position.x(),
            display.position.y()
        ));
    }
    if dw == 0 || dh == 0 || dw > MAX_RESOLUTION as usize || dh > MAX_RESOLUTION as usize {
        return Err(format!("display window of {dw}x{dh} pixels: a render is 1 to {MAX_RESOLUTION} pixels on a side"));
    }
    let (x0, y0) = (data.position.x() as i64, data.position.y() as i64);
    let (x1, y1) = (x0 + data.size.width() as i64, y0 + data.size.height() as i64);
    if x0 < 0 || y0 < 0 || x1 > dw as i64 || y1 > dh as i64 || x0 >= x1 || y0 >= y1 {
        return Err(format!("data window ({x0}, {y0})-({x1}, {y1}) is not a part of the {dw}x{dh} image"));
    }
    let region = Region { x0: x0 as u32, y0: y0 as u32, x1: x1 as u32, y1: y1 as u32 };
    Ok((dw as u32, dh as u32, region))
}

/// The whole image assembled from parts that each cover a different region of it and
/// together cover all of it, with the same size and settings. Errors name the file at fault:
/// a part whose size or settings differ from the first's, two parts that overlap, or the
/// pixels no part covers.
pub fn merge_parts(parts: &[(PathBuf, ImagePart)]) -> Result<(u32, u32, Vec<Rgb>)> {
    let Some((first_path, first)) = parts.first() else {
        return Err(Error::InvalidArgument {
            flag: "merge".into(),
            reason: "no parts to merge".into(),
        });
    };
    let (width, height) = (first.full_width, first.full_height);
    for (path, part) in &parts[1..] {
        if (part.full_width, part.full_height) != (width, height) {
            return Err(Error::invalid_file(
                path,
                format!(
                    "a part of a {}x{} image, but {} is a part of a {width}x{height} image",
                    part.full_width,
                    part.full_height,
                    first_path.display()
                ),
            ));
        }
        if part.settings.is_empty() != first.settings.is_empty() {
            let (bare, other) = if part.settings.is_empty() { (path, first_path) } else { (first_path, path) };
            return Err(Error::invalid_file(
                bare,
                format!("records no render settings: not a part written by render --region or --tile (as {} is)", other.display()),
            ));
        }
        let keys = first.settings.keys().chain(part.settings.keys());
        if let Some(key) = keys.into_iter().find(|k| first.settings.get(*k) != part.settings.get(*k)) {
            let show = |v: Option<&String>| v.map_or("not recorded".to_string(), |v| format!("'{v}'"));
            return Err(Error::invalid_file(
                path,
                format!(
                    "rendered with other settings: {key} is {} here but {} in {}",
                    show(part.settings.get(key)),
                    show(first.settings.get(key)),
                    first_path.display()
                ),
            ));
        }
    }
    for (i, (path, part)) in parts.iter().enumerate() {
        if let Some((other, _)) = parts[..i].iter().find(|(_, p)| p.region.overlaps(&part.region)) {
            return Err(Error::invalid_file(
                path,
                format!("region {} overlaps {}'s", part.region, other.display()),
            ));
        }
    }
    // The parts do not overlap, so they cover the image exactly when their areas add up to it.
    let covered: u64 = parts.iter().map(|(_, p)| p.region.pixel_count() as u64).sum();
    if covered != width as u64 * height as u64 {
        let mut hit = vec![false; width as usize * height as usize];
        for (_, part) in parts {
            let r = part.region;
            for y in r.y0..r.y1 {
                hit[(r.x0 + y * width) as usize..(r.x1 + y * width) as usize].fill(true);
            }
        }
        let missing = hit.iter().filter(|&&h| !h).count();
        let index = hit.iter().position(|&h| !h).unwrap_or(0) as u32;
        return Err(Error::invalid_file(
            first_path,
            format!(
                "the parts leave {missing} of the {width}x{height} image's pixels out, the first at ({}, {}): a part is missing",
                index % width,
                index / width
            ),
        ));
    }
    let mut pixels = vec![Rgb::ZERO; width as usize * height as usize];
    for (_, part) in parts {
        let r = part.region;
        for (row, y) in part.pixels.chunks(r.width() as usize).zip(r.y0..r.y1) {
            pixels[(r.x0 + y * width) as usize..(r.x1 + y * width) as usize].copy_from_slice(row);
        }
    }
    Ok((width, height, pixels))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(region: &str, seed: &str) -> ImagePart {
        let region: Region = region.parse().unwrap();
        let pixels = (0..region.pixel_count()).map(|i| Rgb::new(i as f32, region.x0 as f32 + 0.5, 1e-7)).collect();
        ImagePart {
            full_width: 6,
            full_height: 4,
            region,
            pixels,
            settings: BTreeMap::from([("seed".to_string(), seed.to_string()), ("scene".to_string(), "a.gltf".to_string())]),
        }
    }

    #[test]
    fn parts_round_trip_through_exr_with_their_windows_and_settings() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.exr");
        let p = part("1,2,5,4", "7");
        p.write_exr(&path).unwrap();
        assert_eq!(ImagePart::read_exr(&path).unwrap(), p);
        // Other readers see the whole frame with the part in place.
        let (w, h, whole) = crate::formats::image_io::read_image(&path).unwrap();
        assert_eq!((w, h), (6, 4));
        assert_eq!(whole[1 + 2 * 6], p.pixels[0]);
    }

    #[test]
    fn merging_assembles_parts_and_refuses_gaps_overlaps_and_mismatches() {
        let named = |parts: Vec<ImagePart>| -> Vec<(PathBuf, ImagePart)> {
            parts.into_iter().enumerate().map(|(i, p)| (PathBuf::from(format!("part{i}.exr")), p)).collect()
        };
        let (w, h, pixels) = merge_parts(&named(vec![part("0,0,6,1", "7"), part("3,1,6,4", "7"), part("0,1,3,4", "7")])).unwrap();
        assert_eq!((w, h), (6, 4));
        assert_eq!(pixels[5], Rgb::new(5.0, 0.5, 1e-7));
        assert_eq!(pixels[4 + 2 * 6], Rgb::new(4.0, 3.5, 1e-7), "row 1 of part 1, column 1");
        let err = |parts| merge_parts(&named(parts)).unwrap_err().to_string();
        let missing = err(vec![part("0,0,6,1", "7"), part("3,1,6,4", "7")]);
        assert!(missing.contains("leave 9 of") && missing.contains("(0, 1)"), "{missing}");
        let overlap = err(vec![part("0,0,6,2", "7"), part("0,1,6,4", "7")]);
        assert!(overlap.starts_with("part1.exr:") && overlap.contains("overlaps part0.exr"), "{overlap}");
        let seed = err(vec![part("0,0,6,2", "7"), part("0,2,6,4", "8")]);
        assert!(seed.starts_with("part1.exr:") && seed.contains("seed is '8' here but '7'"), "{seed}");
        let mut other_size = part("0,2,6,4", "7");
        other_size.full_height = 5;
        assert!(err(vec![part("0,0,6,2", "7"), other_size]).contains("part of a 6x5 image"));
        assert!(merge_parts(&[]).is_err());
    }

    /// Windows are checked from the header before pixels are read: a data window far beyond
    /// the display window (found by the `image_part` fuzz target; the reader asked for 8 GB)
    /// and an oversized display window are refused.
    #[test]
    fn windows_are_checked_before_pixels_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.exr");
        part("0,0,6,4", "7").write_exr(&path).unwrap();
        let mut bytes = std::fs::read(&path).unwrap();
        let key = b"dataWindow\0box2i\0\x10\0\0\0";
        let at = bytes.windows(key.len()).position(|w| w == key).expect("data window attribute") + key.len();
        // box2i: xMin, yMin, xMax, yMax (i32, little-endian, inclusive).
        bytes[at + 8..at + 12].copy_from_slice(&0x0a00_0005i32.to_le_bytes());
        let e = ImagePart::from_exr_bytes(&bytes, &path).unwrap_err().to_string();
        assert!(e.contains("data window (0, 0)-(167772166, 4) is not a part of the 6x4 image"), "{e}");

        let mut wide = part("0,0,6,4", "7");
        wide.full_width = MAX_RESOLUTION + 1;
        wide.write_exr(&path).unwrap();
        let e = ImagePart::read_exr(&path).unwrap_err().to_string();
        assert!(e.contains("display window of 16385x4 pixels"), "{e}");
    }

    /// A tile size far beyond the image (the reader would size its buffers by it: a 500-byte
    /// file found by the fuzz target asked for 2 GB) is refused before pixels are read.
    #[test]
    fn oversized_blocks_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tiled.exr");
        let channels = SpecificChannels::rgb(|_: Vec2<usize>| (0.5f32, 0.5f32, 0.5f32));
        let encoding = Encoding { blocks: Blocks::Tiles(Vec2(512, 512)), ..Encoding::FAST_LOSSLESS };
        Image::from_layer(Layer::new((6, 4), LayerAttributes::default(), encoding, channels))
            .write()
            .to_file(&path)
            .unwrap();
        let e = ImagePart::read_exr(&path).unwrap_err().to_string();
        assert!(e.contains("blocks of 3145728 bytes for a part of 288 bytes"), "{e}");
    }

    #[test]
    fn images_that_are_not_parts_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.exr");
        std::fs::write(&path, b"not an exr").unwrap();
        let e = ImagePart::read_exr(&path).unwrap_err().to_string();
        assert!(e.starts_with(&path.display().to_string()) && e.contains("OpenEXR"), "{e}");
        assert!(ImagePart::read_exr(&dir.path().join("missing.exr")).is_err());
    }
}
