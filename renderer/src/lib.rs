//! Physically based offline CPU path tracer whose materials may be measured or neural BRDFs.
//!
//! Conventions used throughout the crate:
//! - World space is right-handed, y up (glTF's convention); lengths are in scene units.
//! - Radiance and BRDF values are linear RGB ([`Rgb`]); BRDF values are f_r in 1/sr,
//!   without the cosine factor.
//! - BSDFs work in a local shading frame where z is the shading normal and both `wo`
//!   (toward the viewer) and `wi` (toward the light) point away from the surface
//!   (see [`bsdf`]).
//! - Angles are in radians, solid-angle densities in 1/sr.

pub mod accel;
pub mod analytic;
pub mod brdf_coords;
pub mod bsdf;
pub mod camera;
pub mod color;
pub mod error;
pub mod film;
pub mod formats;
pub mod frame;
pub mod integrator;
pub mod lanes;
pub mod lights;
pub mod material;
pub mod metrics;
pub mod neural;
pub mod render;
pub mod render_scene;
pub mod sampler;
pub mod sampling;
pub mod scene;
pub mod support;
#[cfg(any(test, feature = "testing"))]
pub mod testing;
pub mod trig;

pub use color::Rgb;
pub use error::{Error, Result};
