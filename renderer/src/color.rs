//! Linear RGB colour.

/// Linear RGB triple (Rec. 709 primaries); radiance in W/(m² sr) per channel or a
/// dimensionless reflectance, depending on context.
pub type Rgb = glam::Vec3;

/// Rec. 709 luminance of a linear RGB value.
#[inline]
pub fn luminance(c: Rgb) -> f32 {
    0.212_671 * c.x + 0.715_160 * c.y + 0.072_169 * c.z
}

/// True when every channel is finite.
#[inline]
pub fn is_finite(c: Rgb) -> bool {
    c.is_finite()
}
