//! What the fuzz targets share: how each turns its input bytes into a loader's input, the
//! in-memory files the scene loaders may ask for (nothing is read from disk), and the check
//! every failed load must pass (a file error naming a file). See `docs/fuzzing.md`.

use renderer::formats::latent_file::LatentFile;
use renderer::formats::merl::{BIN_COUNT, FILE_BYTES, HEADER_BYTES, PHI_D_BINS, THETA_D_BINS, THETA_H_BINS};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The directory the fuzzed scene files pretend to live in. Nothing there is read: the
/// loaders get their referenced files from [`scene_file`].
pub const SCENE_DIR: &str = "/fuzz-scene";

/// The buffer of `scenes/cornell-box/scene.gltf`, served as `scene.bin` so that the seed
/// glTF file loads as it is.
pub const CORNELL_BIN: &[u8] = include_bytes!("../../scenes/cornell-box/scene.bin");

/// Separates the OBJ text from the MTL text in an input of the `obj` target.
pub const MTL_SEPARATOR: &[u8] = b"\n#--mtl--\n";

/// Marks where the f_ref table goes in mode 2 of the `latent` target.
pub const FREF_MARKER: &[u8] = b"FREF";

/// f_ref value (f16, 1/sr) filled in by mode 2 of the `latent` target.
pub const FREF_FILL: f32 = 0.25;

/// A 2×2 RGBA PNG (alpha 255, 0, 128 and 200, so cut-outs and blending have holes and
/// partial cover), served for every `.png` a scene asks for.
pub fn tiny_png() -> &'static [u8] {
    static PNG: OnceLock<Vec<u8>> = OnceLock::new();
    PNG.get_or_init(|| encode(image::DynamicImage::ImageRgba8(
        image::RgbaImage::from_raw(2, 2, vec![255, 0, 0, 255, 0, 255, 0, 0, 0, 0, 255, 128, 9, 9, 9, 200]).expect("2x2 image"),
    ), image::ImageFormat::Png))
}

/// A 2×2 RGB JPEG, served for every `.jpg` or `.jpeg` a scene asks for.
pub fn tiny_jpeg() -> &'static [u8] {
    static JPEG: OnceLock<Vec<u8>> = OnceLock::new();
    JPEG.get_or_init(|| encode(image::DynamicImage::ImageRgb8(
        image::RgbImage::from_raw(2, 2, vec![200, 100, 50, 20, 40, 60, 128, 128, 255, 250, 250, 250]).expect("2x2 image"),
    ), image::ImageFormat::Jpeg))
}

fn encode(image: image::DynamicImage, format: image::ImageFormat) -> Vec<u8> {
    let mut bytes = Vec::new();
    image.write_to(&mut std::io::Cursor::new(&mut bytes), format).expect("encode image");
    bytes
}

/// The in-memory files a fuzzed scene may refer to: `scene.bin` (the Cornell box buffer),
/// any `.png` ([`tiny_png`]), `.jpg`/`.jpeg` ([`tiny_jpeg`]) and any `.mtl` (`mtl`);
/// everything else is "not found".
pub fn scene_file(path: &Path, mtl: &[u8]) -> std::io::Result<Vec<u8>> {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    if name == "scene.bin" {
        Ok(CORNELL_BIN.to_vec())
    } else if name.ends_with(".png") {
        Ok(tiny_png().to_vec())
    } else if name.ends_with(".jpg") || name.ends_with(".jpeg") {
        Ok(tiny_jpeg().to_vec())
    } else if name.ends_with(".mtl") {
        Ok(mtl.to_vec())
    } else {
        Err(std::io::ErrorKind::NotFound.into())
    }
}

/// Prepares a loaded scene for rendering and traces a grid of camera rays through it (hits,
/// surface points with normal maps, alpha tests, BSDFs, textured emission, shadow rays),
/// which must give finite values. Bindings to data files and environment images are
/// replaced first (they would read the disk: a fuzzed path may name any file); scenes of
/// more than 4,096 triangles are only loaded, to keep inputs fast.
pub fn render_probe(mut scene: renderer::scene::SceneDescription) {
    use renderer::bsdf::Bxdf;
    use renderer::scene::{EnvironmentSource, SurfaceModel};
    if scene.geometry.triangle_count() > 4096 {
        return;
    }
    for m in &mut scene.materials {
        if matches!(m.model, SurfaceModel::Bound(_)) {
            m.model = SurfaceModel::MetallicRoughness;
        }
    }
    if let Some(env) = &mut scene.environment {
        if matches!(env.source, EnvironmentSource::Image(_)) {
            env.source = EnvironmentSource::Constant(renderer::Rgb::splat(0.5));
        }
    }
    let Ok(camera) = scene.camera_or_default(None, Some(1.0)) else { return };
    let scene = match renderer::render_scene::RenderScene::new(scene) {
        Ok(scene) => scene,
        Err(error) => return check_file_error(&error),
    };
    let camera = renderer::camera::PinholeCamera::new(&camera, 8, 8);
    for y in 0..8 {
        for x in 0..8 {
            let ray = camera.generate_ray(glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5));
            let Some(hit) = scene.intersect(&ray) else { continue };
            let Some(sp) = scene.surface_point(&hit, ray.direction) else { continue };
            assert!(sp.frame.n.is_finite() && sp.p.is_finite(), "surface point {sp:?}");
            assert!(scene.emission(&sp).is_finite(), "emission");
            if let Some(bsdf) = scene.bsdf(&sp) {
                let wo = sp.frame.to_local(-ray.direction);
                assert!(bsdf.eval(wo, glam::Vec3::Z).is_finite(), "BSDF value");
            }
            let toward = renderer::accel::Ray { t_max: 1.0, ..renderer::accel::Ray::new(sp.p + sp.ng_facing * 1e-3, glam::Vec3::Y) };
            let _ = scene.occluded(&toward);
        }
    }
}

/// Panics unless `error` is a file error ([`renderer::Error::InvalidFile`] or
/// [`renderer::Error::Io`]) whose message starts with the file's path.
pub fn check_file_error(error: &renderer::Error) {
    let message = error.to_string();
    match error {
        renderer::Error::InvalidFile { path, .. } | renderer::Error::Io { path, .. } => {
            assert!(
                !path.as_os_str().is_empty() && message.starts_with(&path.display().to_string()),
                "error does not name its file: {message}"
            );
        }
        other => panic!("a loader returned a non-file error: {other}"),
    }
}

/// Splits an `obj` target input into the OBJ text and the MTL text (empty without a
/// [`MTL_SEPARATOR`]).
pub fn split_obj_input(data: &[u8]) -> (&[u8], &[u8]) {
    match find(data, MTL_SEPARATOR) {
        Some(at) => (&data[..at], &data[at + MTL_SEPARATOR.len()..]),
        None => (data, &[]),
    }
}

/// The full-size `.binary` file a `merl` target input also stands for when it starts with
/// the valid header (90 90 180), is shorter than a full file and has a whole number of
/// `f64` values after the header: the header followed by those values repeated to the full
/// length (zeros if there are none), so that the value checks of a full-size table are
/// reached from short inputs. `None` otherwise: the input is then only loaded as it is
/// (which keeps most executions on the fast header and size checks).
pub fn merl_full_size(data: &[u8]) -> Option<Vec<u8>> {
    let header = merl_header();
    if !data.starts_with(&header) || data.len() as u64 >= FILE_BYTES {
        return None;
    }
    let body = &data[header.len()..];
    if !body.len().is_multiple_of(8) {
        return None;
    }
    let mut out = Vec::with_capacity(FILE_BYTES as usize);
    out.extend_from_slice(&header);
    if body.is_empty() {
        out.resize(FILE_BYTES as usize, 0);
    } else {
        while (out.len() as u64) < FILE_BYTES {
            let n = body.len().min(FILE_BYTES as usize - out.len());
            out.extend_from_slice(&body[..n]);
        }
    }
    Some(out)
}

/// The valid 12-byte header of a MERL `.binary` file.
pub fn merl_header() -> Vec<u8> {
    let header: Vec<u8> = [THETA_H_BINS, THETA_D_BINS, PHI_D_BINS]
        .iter()
        .flat_map(|&d| (d as i32).to_le_bytes())
        .collect();
    debug_assert_eq!(header.len() as u64, HEADER_BYTES);
    header
}

/// The `latent.bin` bytes a `latent` target input stands for; its first byte (mod 3) picks
/// the mode:
/// - 0: the rest as it is (the checksum is rarely right, so this mostly fuzzes the header
///   and checksum checks);
/// - 1: the rest with its FNV-1a checksum appended, so the parser runs past the checksum;
/// - 2: like 1, but the first [`FREF_MARKER`] in the rest is replaced by a full f_ref table
///   (90·90·180 bins × 3 f16 of [`FREF_FILL`]), so that short inputs reach the latent-code
///   and name sections behind the 8.7 MB table.
pub fn latent_bytes(data: &[u8]) -> Vec<u8> {
    let Some((&mode, rest)) = data.split_first() else {
        return Vec::new();
    };
    let mut out = match mode % 3 {
        0 => return rest.to_vec(),
        1 => rest.to_vec(),
        _ => match find(rest, FREF_MARKER) {
            Some(at) => {
                let fill = half::f16::from_f32(FREF_FILL).to_le_bytes();
                let mut out = Vec::with_capacity(rest.len() + 6 * BIN_COUNT + 8);
                out.extend_from_slice(&rest[..at]);
                for _ in 0..3 * BIN_COUNT {
                    out.extend_from_slice(&fill);
                }
                out.extend_from_slice(&rest[at + FREF_MARKER.len()..]);
                out
            }
            None => rest.to_vec(),
        },
    };
    let sum = fnv1a64(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// The mode-2 input of the `latent` target that stands for `file` (see [`latent_bytes`]).
pub fn latent_mode2_input(file: &LatentFile) -> Vec<u8> {
    let bytes = file.to_bytes();
    let body = &bytes[..bytes.len() - 8];
    let section = |n: &str| 4 + n.len();
    let tail_len = 4
        + file
            .latents
            .iter()
            .map(|l| section(&l.name) + 4 * l.z.len())
            .sum::<usize>()
        + 4
        + file
            .training_materials
            .iter()
            .map(|n| section(n))
            .sum::<usize>();
    let fref_end = body.len() - tail_len;
    let fref_start = fref_end - 6 * BIN_COUNT;
    let mut input = vec![2];
    input.extend_from_slice(&body[..fref_start]);
    input.extend_from_slice(FREF_MARKER);
    input.extend_from_slice(&body[fref_end..]);
    input
}

/// FNV-1a, 64 bit (the checksum of `latent.bin`).
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The file name an `npy` target input's first byte (mod 6) picks, and the tensor bytes.
pub fn split_npy_input(data: &[u8]) -> Option<(usize, &[u8])> {
    let (&which, rest) = data.split_first()?;
    Some((which as usize % 6, rest))
}

/// A version 1.0 `.npy` file of little-endian float32 with the given shape and values.
pub fn npy_f32(shape: &[usize], values: &[f32]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(usize::to_string).collect();
    let shape = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Valid `.npy` bytes of the six tensors of a small network (fc1, b1, fc2, b2, fc3, b3), so
/// that a fuzzed tensor can stand in for one of them in a whole network.
pub fn valid_npy_tensors() -> &'static [Vec<u8>; 6] {
    static FILES: OnceLock<[Vec<u8>; 6]> = OnceLock::new();
    FILES.get_or_init(|| {
        let shapes: [&[usize]; 6] = [&[6, 21], &[21], &[21, 21], &[21], &[21, 3], &[3]];
        shapes.map(|shape| {
            let n: usize = shape.iter().product();
            let values: Vec<f32> = (0..n).map(|i| ((i % 7) as f32 - 3.0) * 0.05).collect();
            npy_f32(shape, &values)
        })
    })
}

/// The path of a fuzzed file called `name` in [`SCENE_DIR`].
pub fn fuzz_path(name: &str) -> PathBuf {
    Path::new(SCENE_DIR).join(name)
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}
