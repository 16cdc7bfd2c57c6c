//! Linear RGB colour.

use crate::lanes::{Real, V3};

/// Linear RGB triple (Rec. 709 primaries); radiance in W/(m² sr) per channel or a
/// dimensionless reflectance, depending on context.
pub type Rgb = glam::Vec3;

/// Weights of R, G and B in Rec. 709 luminance.
pub const LUMINANCE_WEIGHTS: [f32; 3] = [0.212_671, 0.715_160, 0.072_169];

/// Rec. 709 luminance of a linear RGB value.
#[inline]
pub fn luminance(c: Rgb) -> f32 {
    luminance_of(V3::from(c))
}

/// [`luminance`] over [`Real`] values (one colour, or one per lane).
#[inline(always)]
pub(crate) fn luminance_of<R: Real>(c: V3<R>) -> R {
    let [r, g, b] = LUMINANCE_WEIGHTS;
    c.x * r + c.y * g + c.z * b
}

/// True when every channel is finite.
#[inline]
pub fn is_finite(c: Rgb) -> bool {
    c.is_finite()
}
