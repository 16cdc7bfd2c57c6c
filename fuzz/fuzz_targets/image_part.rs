//! Bytes as a part of an image (`render merge`'s input) through
//! `renderer::formats::image_part::ImagePart::from_exr_bytes`; a part that loads is merged
//! with itself, which must be refused as an overlap, and alone, which must give its pixels
//! back where it covers the whole image. Headers declaring more than 2²² pixels are left out:
//! the reader checks the windows against the renderer's largest image (16384²), which may
//! legitimately take 3 GB, beyond the fuzzer's memory limit.
#![no_main]

use libfuzzer_sys::fuzz_target;
use renderer::formats::image_part::{merge_parts, ImagePart};
use renderer_fuzz::check_file_error;
use std::path::{Path, PathBuf};

fuzz_target!(|data: &[u8]| {
    let declared = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(data), false)
        .ok()
        .and_then(|m| m.headers.first().map(|h| h.shared_attributes.display_window.size.area()));
    if declared.is_some_and(|area| area > 1 << 22) {
        return;
    }
    match ImagePart::from_exr_bytes(data, Path::new("fuzz.exr")) {
        Ok(part) => {
            assert_eq!(part.pixels.len(), part.region.pixel_count());
            assert!(part.region.is_within(part.full_width, part.full_height));
            let twice = [(PathBuf::from("a.exr"), part.clone()), (PathBuf::from("b.exr"), part.clone())];
            assert!(merge_parts(&twice).is_err());
            match merge_parts(&twice[..1]) {
                Ok((w, h, pixels)) => {
                    assert_eq!((w, h), (part.full_width, part.full_height));
                    let same = pixels.iter().zip(&part.pixels).all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits));
                    assert!(same);
                }
                Err(error) => check_file_error(&error),
            }
        }
        Err(error) => check_file_error(&error),
    }
});
