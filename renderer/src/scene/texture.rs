//! Textures as materials use them: decoded images ([`Texture`], once per image and encoding,
//! shared by every material that uses them) and references to them ([`TextureRef`]: the
//! glTF sampler's wrap and filter modes, the texture-coordinate set and
//! `KHR_texture_transform`).
//!
//! Texture coordinates follow glTF: u to the right, v down from the image's top row; texel
//! centres at half-integers (texel (0, 0) covers u, v ∈ [0, 1/width) × [0, 1/height)).

use crate::{Error, Result, Rgb};
use glam::{Mat3, Vec2};
use std::path::Path;
use std::sync::LazyLock;

/// A texture of linear RGB texels, row-major from the top row (glTF's v = 0), with the
/// image's alpha channel where it has one that is not opaque everywhere.
#[derive(Clone, Debug)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    texels: Texels,
    /// Whether some texel's alpha is below 1 (elsewhere alpha reads as 1 without a look-up).
    has_alpha: bool,
}

/// How a texture holds its texels.
#[derive(Clone, Debug)]
enum Texels {
    /// An 8-bit image's bytes (RGBA, alpha 255 where the image has none), decoded as they
    /// are read: colour through `rgb` (the image's encoding, [`byte_values`]), alpha
    /// linearly. A third of the memory of linear `f32` colour, the same values.
    Bytes { rgba: Vec<[u8; 4]>, rgb: &'static [f32; 256] },
    /// Linear colour and alpha (16-bit and floating-point images; alpha empty when
    /// opaque).
    Floats { rgb: Vec<Rgb>, alpha: Vec<f32> },
}

/// The linear value of each byte of a linear 8-bit channel, as the `image` crate converts
/// it (the `f32` values the texture had when it held them decoded).
static LINEAR_BYTES: LazyLock<[f32; 256]> = LazyLock::new(|| byte_values(|v| v));
/// The linear value of each byte of an sRGB-encoded 8-bit channel.
static SRGB_BYTES: LazyLock<[f32; 256]> = LazyLock::new(|| byte_values(srgb_to_linear));

/// `decode` of the value the `image` crate gives each byte of an RGB(A) image as `f32`
/// (x / 255 rounded once; its grey images' conversion can be an ulp off that).
fn byte_values(decode: fn(f32) -> f32) -> [f32; 256] {
    let bytes = image::RgbImage::from_fn(256, 1, |x, _| image::Rgb([x as u8; 3]));
    let values = image::DynamicImage::ImageRgb8(bytes).to_rgba32f();
    std::array::from_fn(|i| decode(values.get_pixel(i as u32, 0).0[0]))
}

/// How an image's 8- and 16-bit values map to linear values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Encoding {
    /// sRGB-encoded colour (glTF base-colour and emissive textures): decoded with the sRGB
    /// transfer function.
    Srgb,
    /// Linear data (glTF metallic-roughness, normal and occlusion textures): value / max.
    Linear,
}

/// What lies outside [0, 1] along one texture axis (glTF sampler `wrapS`/`wrapT`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Wrap {
    /// The texture tiles (glTF REPEAT, 10497; the default).
    #[default]
    Repeat,
    /// The edge texels extend (CLAMP_TO_EDGE, 33071).
    ClampToEdge,
    /// Every other tile is mirrored (MIRRORED_REPEAT, 33648).
    MirroredRepeat,
}

/// How texels are interpolated (glTF sampler `magFilter`; without mipmaps the minification
/// filter is taken to be the same).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Filter {
    /// The nearest texel (NEAREST, 9728).
    Nearest,
    /// Bilinear between the four nearest texel centres (LINEAR, 9729; the default).
    #[default]
    Linear,
}

/// A material's use of a texture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureRef {
    /// Index into the scene's textures.
    pub texture: usize,
    /// The texture-coordinate set it reads (0 or 1; glTF `texCoord`).
    pub tex_coord: u32,
    /// Wrap modes along u and v.
    pub wrap: [Wrap; 2],
    pub filter: Filter,
    /// `KHR_texture_transform`'s matrix (uv' = M · (u, v, 1)); `None` for the identity.
    pub transform: Option<Mat3>,
}

impl TextureRef {
    /// A reference with glTF's defaults: repeat, bilinear, no transform.
    pub fn new(texture: usize) -> Self {
        TextureRef {
            texture,
            tex_coord: 0,
            wrap: [Wrap::Repeat; 2],
            filter: Filter::Linear,
            transform: None,
        }
    }

    /// The texel value at the surface's texture coordinates `uv` of set
    /// [`TextureRef::tex_coord`] (before the transform).
    #[inline]
    pub fn lookup(&self, textures: &[Texture], uv: Vec2) -> Rgb {
        textures[self.texture].sample(self.transformed(uv), self.wrap, self.filter)
    }

    /// The texture's alpha at `uv` (as [`TextureRef::lookup`]); 1 where the image has none.
    #[inline]
    pub fn lookup_alpha(&self, textures: &[Texture], uv: Vec2) -> f32 {
        textures[self.texture].sample_alpha(self.transformed(uv), self.wrap, self.filter)
    }

    #[inline]
    fn transformed(&self, uv: Vec2) -> Vec2 {
        match &self.transform {
            Some(m) => m.transform_point2(uv),
            None => uv,
        }
    }
}

/// `KHR_texture_transform`'s matrix: uv' = T(offset) · R(rotation) · S(scale) · uv, with
/// u' = cos θ u + sin θ v, v' = −sin θ u + cos θ v for the rotation θ (radians): the
/// direction of the extension's JSON example and of Blender, three.js, Babylon.js and
/// cesium-native (the GLSL listing in the extension's README has it transposed, glTF issue
/// #1563; a Cycles render of `scenes/feature-showcase` confirmed this one).
pub fn texture_transform(offset: Vec2, rotation: f32, scale: Vec2) -> Mat3 {
    let (s, c) = rotation.sin_cos();
    let translation = Mat3::from_translation(offset);
    let rotation = Mat3::from_cols_array(&[c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0]);
    translation * rotation * Mat3::from_scale(scale)
}

/// Texel coordinate along an axis of `n` texels for an integer position `i` (possibly
/// outside [0, n)).
#[inline]
fn wrap_index(i: i64, n: usize, wrap: Wrap) -> usize {
    let n = n as i64;
    if (0..n).contains(&i) {
        // Inside the image every mode is the identity (no division).
        return i as usize;
    }
    // i mod m ≥ 0; a mask where m is a power of two (most textures: no division).
    let modulo = |m: i64| if m & (m - 1) == 0 { i & (m - 1) } else { i.rem_euclid(m) };
    match wrap {
        Wrap::Repeat => modulo(n) as usize,
        Wrap::ClampToEdge => i.clamp(0, n - 1) as usize,
        Wrap::MirroredRepeat => {
            let period = modulo(2 * n);
            (if period < n { period } else { 2 * n - 1 - period }) as usize
        }
    }
}

impl Texture {
    /// A texture of `width` × `height` linear texels `rgb` (row-major from the top row)
    /// with alpha `alpha` per texel, or none (empty: opaque).
    ///
    /// # Panics
    /// Where `rgb` (or a non-empty `alpha`) does not hold `width` × `height` values.
    pub fn from_linear(width: u32, height: u32, rgb: Vec<Rgb>, alpha: Vec<f32>) -> Texture {
        let n = width as usize * height as usize;
        assert!(rgb.len() == n && (alpha.is_empty() || alpha.len() == n), "{width} x {height} texels");
        let has_alpha = !alpha.iter().all(|&a| a >= 1.0);
        let alpha = if has_alpha { alpha } else { Vec::new() };
        Texture { width, height, texels: Texels::Floats { rgb, alpha }, has_alpha }
    }

    /// The linear colour of texel `i` (row-major from the top row).
    pub fn texel(&self, i: usize) -> Rgb {
        match &self.texels {
            Texels::Bytes { rgba, rgb } => decode_rgb(rgba[i], rgb),
            Texels::Floats { rgb, .. } => rgb[i],
        }
    }

    /// The bytes the texels take.
    pub fn heap_bytes(&self) -> usize {
        match &self.texels {
            Texels::Bytes { rgba, .. } => std::mem::size_of_val(rgba.as_slice()),
            Texels::Floats { rgb, alpha } => std::mem::size_of_val(rgb.as_slice()) + std::mem::size_of_val(alpha.as_slice()),
        }
    }

    /// Bilinear look-up with repeat wrapping (glTF's default sampler).
    pub fn lookup(&self, uv: Vec2) -> Rgb {
        self.sample(uv, [Wrap::Repeat; 2], Filter::Linear)
    }

    /// The value at `uv` with the given wrap modes (u, v) and filter. Non-finite coordinates
    /// are read as (0, 0).
    pub fn sample(&self, uv: Vec2, wrap: [Wrap; 2], filter: Filter) -> Rgb {
        match &self.texels {
            Texels::Bytes { rgba, rgb } => self.filtered(uv, wrap, filter, |i| decode_rgb(rgba[i], rgb), Rgb::lerp),
            Texels::Floats { rgb, .. } => self.filtered(uv, wrap, filter, |i| rgb[i], Rgb::lerp),
        }
    }

    /// The alpha at `uv`, filtered as [`Texture::sample`]; 1 when the texture has no alpha.
    pub fn sample_alpha(&self, uv: Vec2, wrap: [Wrap; 2], filter: Filter) -> f32 {
        if !self.has_alpha {
            return 1.0;
        }
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        match &self.texels {
            Texels::Bytes { rgba, .. } => self.filtered(uv, wrap, filter, |i| LINEAR_BYTES[rgba[i][3] as usize], lerp),
            Texels::Floats { alpha, .. } => self.filtered(uv, wrap, filter, |i| alpha[i], lerp),
        }
    }

    /// Texels fetched by `texel(index)` at `uv`, wrapped and filtered.
    #[inline]
    fn filtered<T: Copy>(&self, uv: Vec2, wrap: [Wrap; 2], filter: Filter, texel: impl Fn(usize) -> T, lerp: impl Fn(T, T, f32) -> T) -> T {
        let (w, h) = (self.width as usize, self.height as usize);
        let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
        // Continuous texel coordinates, texel centres at integers; kept in a range where the
        // f32 → i64 conversion is exact enough (every wrap mode is periodic or clamps).
        let x = (uv.x * w as f32 - 0.5).clamp(-1e9, 1e9);
        let y = (uv.y * h as f32 - 0.5).clamp(-1e9, 1e9);
        let column = |xx: i64| wrap_index(xx, w, wrap[0]);
        let row = |yy: i64| w * wrap_index(yy, h, wrap[1]);
        match filter {
            Filter::Nearest => texel(row(y.round() as i64) + column(x.round() as i64)),
            Filter::Linear => {
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let (xi, yi) = (x0 as i64, y0 as i64);
                let (c0, c1, r0, r1) = (column(xi), column(xi + 1), row(yi), row(yi + 1));
                let top = lerp(texel(r0 + c0), texel(r0 + c1), fx);
                let bottom = lerp(texel(r1 + c0), texel(r1 + c1), fx);
                lerp(top, bottom, fy)
            }
        }
    }


    /// Decodes an encoded image (PNG, JPEG, or the HDR/EXR formats the `image` crate is built
    /// with here) into linear texels.
    ///
    /// 8- and 16-bit images are decoded as `encoding` says; floating-point images are taken
    /// as linear already. Alpha is always linear (glTF) and kept only where some texel is
    /// not opaque. `file` and `what` only name the image in error messages (e.g. the scene
    /// file and "texture 'wood.png'").
    pub fn from_encoded(bytes: &[u8], encoding: Encoding, file: &Path, what: &str) -> Result<Texture> {
        let image = image::load_from_memory(bytes)
            .map_err(|e| Error::invalid_file(file, format!("cannot decode {what}: {e}")))?;
        let (width, height) = (image.width(), image.height());
        if width == 0 || height == 0 {
            return Err(Error::invalid_file(file, format!("{what} is empty")));
        }
        let is_float = matches!(
            image.color(),
            image::ColorType::Rgb32F | image::ColorType::Rgba32F
        );
        if matches!(image.color(), image::ColorType::L8 | image::ColorType::La8 | image::ColorType::Rgb8 | image::ColorType::Rgba8) {
            let rgba: Vec<[u8; 4]> = image.into_rgba8().pixels().map(|p| p.0).collect();
            let has_alpha = rgba.iter().any(|p| p[3] < u8::MAX);
            let rgb = if encoding == Encoding::Linear { &*LINEAR_BYTES } else { &*SRGB_BYTES };
            return Ok(Texture { width, height, texels: Texels::Bytes { rgba, rgb }, has_alpha });
        }
        let decode = |v: f32| if is_float || encoding == Encoding::Linear { v } else { srgb_to_linear(v) };
        let rgba = image.to_rgba32f();
        let texels = rgba
            .pixels()
            .map(|p| Rgb::new(decode(p.0[0]), decode(p.0[1]), decode(p.0[2])))
            .collect();
        let alpha: Vec<f32> = if image.color().has_alpha() {
            rgba.pixels().map(|p| p.0[3]).collect()
        } else {
            Vec::new()
        };
        Ok(Texture::from_linear(width, height, texels, alpha))
    }

    /// [`Texture::from_encoded`] for colour ([`Encoding::Srgb`]).
    pub fn from_encoded_srgb(bytes: &[u8], file: &Path, what: &str) -> Result<Texture> {
        Self::from_encoded(bytes, Encoding::Srgb, file, what)
    }
}

/// A byte texel's linear colour, its channels decoded by `table`.
#[inline(always)]
fn decode_rgb([r, g, b, _]: [u8; 4], table: &[f32; 256]) -> Rgb {
    Rgb::new(table[r as usize], table[g as usize], table[b as usize])
}

/// The sRGB electro-optical transfer function (IEC 61966-2-1): encoded value in [0, 1] to
/// linear.
fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4 × 1 texture with texels 0, 1, 2, 3 (all channels).
    fn ramp() -> Texture {
        Texture::from_linear(4, 1, (0..4).map(|i| Rgb::splat(i as f32)).collect(), Vec::new())
    }

    fn at(t: &Texture, u: f32, wrap: Wrap, filter: Filter) -> f32 {
        t.sample(Vec2::new(u, 0.5), [wrap, Wrap::Repeat], filter).x
    }

    #[test]
    fn wrap_modes_and_filters() {
        let t = ramp();
        // Texel centres at u = 0.125, 0.375, ...; u = 1.125 is texel 0 again when repeating,
        // the last texel when clamping, texel 0 of the mirrored tile (mirrored back) when
        // mirroring.
        assert_eq!(at(&t, 0.375, Wrap::Repeat, Filter::Nearest), 1.0);
        assert_eq!(at(&t, 1.125, Wrap::Repeat, Filter::Nearest), 0.0);
        assert_eq!(at(&t, 1.125, Wrap::ClampToEdge, Filter::Nearest), 3.0);
        assert_eq!(at(&t, 1.125, Wrap::MirroredRepeat, Filter::Nearest), 3.0);
        assert_eq!(at(&t, 1.375, Wrap::MirroredRepeat, Filter::Nearest), 2.0);
        assert_eq!(at(&t, -0.125, Wrap::MirroredRepeat, Filter::Nearest), 0.0);
        assert_eq!(at(&t, -0.125, Wrap::Repeat, Filter::Nearest), 3.0);
        // Halfway between texel centres 1 and 2.
        assert_eq!(at(&t, 0.5, Wrap::Repeat, Filter::Linear), 1.5);
        // A quarter past the last centre: repeat blends a quarter of texel 0 in, clamping
        // stays at 3.
        assert_eq!(at(&t, 0.9375, Wrap::Repeat, Filter::Linear), 2.25);
        assert_eq!(at(&t, 0.9375, Wrap::ClampToEdge, Filter::Linear), 3.0);
        assert_eq!(at(&t, f32::NAN, Wrap::Repeat, Filter::Linear), at(&t, 0.0, Wrap::Repeat, Filter::Linear));
        assert_eq!(t.lookup(Vec2::new(0.5, 0.5)), t.sample(Vec2::new(0.5, 0.5), [Wrap::Repeat; 2], Filter::Linear));
    }

    /// Wrapping by a mask (sizes that are powers of two) gives what the remainder gives.
    #[test]
    fn wrapping_by_mask_equals_the_remainder() {
        for n in [1usize, 2, 3, 4, 6, 64, 100, 128] {
            for i in -300i64..300 {
                let m = n as i64;
                let mirrored = |p: i64| if p < m { p } else { 2 * m - 1 - p };
                assert_eq!(wrap_index(i, n, Wrap::Repeat), i.rem_euclid(m) as usize, "n {n}, i {i}");
                assert_eq!(wrap_index(i, n, Wrap::MirroredRepeat), mirrored(i.rem_euclid(2 * m)) as usize, "n {n}, i {i}");
            }
        }
    }

    /// The extension's matrix T · R · S: offset (0, 1), rotation π/2, scale (0.5, 0.5) maps
    /// (1, 0) to (0, 0.5) and (0, 1) to (0.5, 1) (the extension's example: a quarter turn
    /// with offset (0, 1) keeps the unit square's image in the unit square).
    #[test]
    fn texture_transform_follows_the_extension() {
        let m = texture_transform(Vec2::new(0.0, 1.0), std::f32::consts::FRAC_PI_2, Vec2::splat(0.5));
        let close = |a: Vec2, b: Vec2| (a - b).length() < 1e-6;
        assert!(close(m.transform_point2(Vec2::new(1.0, 0.0)), Vec2::new(0.0, 0.5)), "{}", m.transform_point2(Vec2::new(1.0, 0.0)));
        assert!(close(m.transform_point2(Vec2::new(0.0, 1.0)), Vec2::new(0.5, 1.0)), "{}", m.transform_point2(Vec2::new(0.0, 1.0)));
        let quarter = texture_transform(Vec2::new(0.0, 1.0), std::f32::consts::FRAC_PI_2, Vec2::ONE);
        for corner in [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE] {
            let mapped = quarter.transform_point2(corner);
            assert!(mapped.cmpge(Vec2::splat(-1e-6)).all() && mapped.cmple(Vec2::splat(1.0 + 1e-6)).all(), "{corner} -> {mapped}");
        }
        let shift = texture_transform(Vec2::new(0.25, 0.0), 0.0, Vec2::ONE);
        let r = TextureRef { transform: Some(shift), ..TextureRef::new(0) };
        assert_eq!(r.lookup(&[ramp()], Vec2::new(0.125, 0.5)), Rgb::splat(1.0));
    }

    /// An 8-bit image's texels, held as bytes, read as the values decoding the whole image
    /// to `f32` gives (colour by its encoding, alpha linear), bit for bit, in a quarter of
    /// the bytes of `f32` RGBA.
    #[test]
    fn byte_texels_read_as_the_decoded_image() {
        let image = image::RgbaImage::from_fn(256, 1, |x, _| image::Rgba([x as u8, 255 - x as u8, (x / 2) as u8, x as u8]));
        let mut png = Vec::new();
        image.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).unwrap();
        let decoded = image::DynamicImage::ImageRgba8(image).to_rgba32f();
        for (encoding, decode) in [(Encoding::Linear, (|v| v) as fn(f32) -> f32), (Encoding::Srgb, srgb_to_linear)] {
            let t = Texture::from_encoded(&png, encoding, Path::new("a.gltf"), "png").unwrap();
            assert_eq!(t.heap_bytes(), 256 * 4);
            for (i, p) in decoded.pixels().enumerate() {
                let want = Rgb::new(decode(p.0[0]), decode(p.0[1]), decode(p.0[2]));
                assert_eq!(t.texel(i).to_array().map(f32::to_bits), want.to_array().map(f32::to_bits), "{encoding:?}, texel {i}");
                let centre = Vec2::new((i as f32 + 0.5) / 256.0, 0.5);
                assert_eq!(t.sample_alpha(centre, [Wrap::ClampToEdge; 2], Filter::Nearest).to_bits(), p.0[3].to_bits(), "alpha {i}");
            }
        }
    }

    #[test]
    fn linear_and_srgb_decoding_of_png_and_jpeg() {
        let mut png = Vec::new();
        let pixel = image::RgbImage::from_pixel(2, 2, image::Rgb([128, 128, 128]));
        pixel.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).unwrap();
        let path = Path::new("scene.gltf");
        let linear = Texture::from_encoded(&png, Encoding::Linear, path, "png").unwrap();
        let srgb = Texture::from_encoded(&png, Encoding::Srgb, path, "png").unwrap();
        assert!((linear.texel(0).x - 128.0 / 255.0).abs() < 1e-6);
        assert!((srgb.texel(0).x - 0.2158605).abs() < 1e-5, "{}", srgb.texel(0).x);
        let mut jpeg = Vec::new();
        pixel.write_to(&mut std::io::Cursor::new(&mut jpeg), image::ImageFormat::Jpeg).unwrap();
        let decoded = Texture::from_encoded(&jpeg, Encoding::Linear, path, "jpeg").unwrap();
        assert!((decoded.texel(3).y - 128.0 / 255.0).abs() < 3.0 / 255.0, "{:?}", decoded.texel(3));
        let e = Texture::from_encoded(&jpeg[..jpeg.len() / 2], Encoding::Srgb, path, "image 0").unwrap_err().to_string();
        assert!(e.contains("scene.gltf") && e.contains("cannot decode image 0"), "{e}");
    }
}
