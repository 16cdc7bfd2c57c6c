//! The distant environment: an equirectangular image or a constant colour, with importance
//! sampling proportional to luminance × sin θ for images.
//!
//! Mapping (world space, y up): a direction d ↔ image coordinates (u, v) ∈ [0, 1)² with
//! u = 0.5 + atan2(d.x, −d.z) / 2π and v = acos(d.y) / π; v = 0 is the top row (+y) and the
//! image centre looks toward −z. A rotation r (radians) turns the map about +y.
//! Texels are looked up nearest-neighbour, so the sampling density matches the radiance
//! exactly (piecewise constant per texel).

use crate::color::luminance;
use crate::error::{Error, Result};
use crate::lanes::{F32s, Mask, Real, Vec2s, Vec3s, LANES, V2, V3};
use crate::sampling::{
    sample_uniform_sphere, sin_cos_turns, uniform_sphere, uniform_sphere_pdf, Distribution2D,
};
use super::LightSample;
use crate::scene::{EnvironmentSource, EnvironmentSpec};
use crate::trig::atan2;
use crate::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::PI;
use std::path::Path;

/// An environment emitter ready for rendering.
pub struct Environment {
    kind: Kind,
    /// cos and sin of the rotation about +y.
    rotation: (f32, f32),
}

impl std::fmt::Debug for Environment {
    /// The kind and rotation, not the map's tables.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut d = f.debug_struct("Environment");
        match &self.kind {
            Kind::Constant(radiance) => d.field("constant", radiance),
            Kind::Image(distribution) => d.field("image_size", &distribution.size()),
        };
        d.field("rotation", &self.rotation).finish()
    }
}

enum Kind {
    Constant(Rgb),
    /// The image's sampling distribution over its texels, each carrying its radiance
    /// (strength applied), row-major from the top row.
    Image(Distribution2D<Rgb>),
}

/// Where a direction falls in an environment image ([`Environment::locate`]).
#[derive(Clone, Copy, Debug)]
pub struct MapPoint {
    /// Image coordinates in [0, 1)² (see [`direction_to_uv`]).
    uv: Vec2,
    /// sin θ of the direction in the map's frame.
    sin_theta: f32,
}

/// A direction drawn toward the environment.
#[derive(Clone, Copy, Debug)]
pub struct EnvironmentSample {
    /// World-space unit direction toward the environment.
    pub direction: Vec3,
    /// Radiance arriving from that direction, W/(m² sr).
    pub radiance: Rgb,
    /// Solid-angle density, 1/sr.
    pub pdf: f32,
}

impl EnvironmentSample {
    /// The sample as a [`LightSample`] of the environment chosen with probability
    /// `select_pdf`.
    #[inline]
    pub fn with_selection(self, select_pdf: f32) -> LightSample {
        LightSample {
            direction: self.direction,
            distance: f32::INFINITY,
            radiance: self.radiance,
            pdf: self.pdf * select_pdf,
            is_delta: false,
            shadow_target: None,
        }
    }
}

/// [`EnvironmentSample`]s of [`LANES`] draws ([`Environment::sample_lanes`]), structure of
/// arrays.
#[derive(Clone, Copy, Debug)]
pub struct EnvironmentSamples {
    /// Lanes that drew a sample (the others' values are meaningless).
    pub ok: Mask,
    pub direction: Vec3s,
    pub radiance: Vec3s,
    pub pdf: F32s,
}

impl EnvironmentSamples {
    /// Lane `k`'s sample, `None` where it drew none.
    #[inline(always)]
    pub fn get(&self, k: usize) -> Option<EnvironmentSample> {
        self.ok.0[k].then(|| EnvironmentSample {
            direction: self.direction.get(k),
            radiance: self.radiance.get(k),
            pdf: self.pdf.0[k],
        })
    }
}

impl Environment {
    /// Loads the image (if any) and builds its sampling distribution.
    pub fn load(spec: &EnvironmentSpec) -> Result<Self> {
        let kind = match &spec.source {
            EnvironmentSource::Constant(c) => Kind::Constant(*c * spec.strength),
            EnvironmentSource::Image(path) => {
                let (width, height, texels) = read_radiance_image(path)?;
                let texels: Vec<Rgb> = texels.into_iter().map(|t| t * spec.strength).collect();
                Self::image_kind(width, height, texels)
            }
        };
        Ok(Environment {
            kind,
            rotation: (spec.rotation.cos(), spec.rotation.sin()),
        })
    }

    /// An environment from texels in memory (row-major from the top row).
    pub fn from_texels(width: usize, height: usize, texels: Vec<Rgb>, rotation: f32) -> Self {
        assert_eq!(texels.len(), width * height);
        Environment {
            kind: Self::image_kind(width, height, texels),
            rotation: (rotation.cos(), rotation.sin()),
        }
    }

    /// A constant environment.
    pub fn constant(radiance: Rgb) -> Self {
        Environment {
            kind: Kind::Constant(radiance),
            rotation: (1.0, 0.0),
        }
    }

    fn image_kind(width: usize, height: usize, texels: Vec<Rgb>) -> Kind {
        let weights: Vec<f32> = texels
            .iter()
            .enumerate()
            .map(|(i, &t)| {
                let row = i / width;
                let sin_theta = (PI * (row as f32 + 0.5) / height as f32).sin();
                luminance(t).max(0.0) * sin_theta
            })
            .collect();
        Kind::Image(Distribution2D::with_payloads(&weights, texels, width, height))
    }

    /// Rough emitted power scale (mean radiance × π), used to weigh light selection.
    pub fn power_hint(&self) -> f32 {
        match &self.kind {
            Kind::Constant(c) => luminance(*c) * PI,
            Kind::Image(distribution) => {
                // distribution.integral() = mean of luminance·sinθ over the unit square;
                // the mean over the sphere is that × π/2.
                distribution.integral() * PI * 0.5 * PI
            }
        }
    }

    fn world_to_map(&self, d: Vec3) -> Vec3 {
        self.world_to_map_of(d.into()).into()
    }

    fn map_to_world(&self, d: Vec3) -> Vec3 {
        self.map_to_world_of(d.into()).into()
    }

    /// A world direction in the map's frame (its rotation about y undone), over [`Real`]
    /// values (one direction, or one per lane).
    #[inline(always)]
    fn world_to_map_of<R: Real>(&self, d: V3<R>) -> V3<R> {
        let (c, s) = self.rotation;
        V3::new(d.x * c - d.z * s, d.y, d.x * s + d.z * c)
    }

    /// A direction of the map's frame in world space, over [`Real`] values.
    #[inline(always)]
    fn map_to_world_of<R: Real>(&self, d: V3<R>) -> V3<R> {
        let (c, s) = self.rotation;
        V3::new(d.x * c + d.z * s, d.y, d.x * -s + d.z * c)
    }

    /// Radiance arriving from world direction `d` (unit), W/(m² sr).
    #[inline]
    pub fn radiance(&self, d: Vec3) -> Rgb {
        self.radiance_pdf(d).0
    }

    /// Radiance arriving from world direction `d` (unit), W/(m² sr), and the solid-angle
    /// density (1/sr) with which [`Self::sample`] draws `d`: both from one mapping of `d` to
    /// the image (an atan2 and an acos), as a ray that leaves the scene needs them.
    #[inline]
    pub fn radiance_pdf(&self, d: Vec3) -> (Rgb, f32) {
        self.radiance_pdf_at(self.locate(d))
    }

    /// The first half of [`Self::radiance_pdf`]: where world direction `d` (unit) falls in
    /// the image, its cell's record prefetched into the cache. Locating many directions
    /// before reading any ([`Self::radiance_pdf_at`]) overlaps their cache misses.
    #[inline]
    pub fn locate(&self, d: Vec3) -> MapPoint {
        match &self.kind {
            Kind::Constant(_) => MapPoint { uv: Vec2::ZERO, sin_theta: 1.0 },
            Kind::Image(distribution) => {
                let local = self.world_to_map(d);
                let uv = direction_to_uv(local);
                distribution.prefetch_at(uv);
                MapPoint {
                    uv,
                    sin_theta: sin_polar(local.y),
                }
            }
        }
    }

    /// [`Self::locate`] of each lane's direction, with the same operations (so the same
    /// bits), every lane's cell record prefetched.
    #[inline(always)]
    pub fn locate_lanes(&self, d: Vec3s) -> [MapPoint; LANES] {
        match &self.kind {
            Kind::Constant(_) => [MapPoint { uv: Vec2::ZERO, sin_theta: 1.0 }; LANES],
            Kind::Image(distribution) => {
                let local = self.world_to_map_of(d);
                let uv = direction_uv(local);
                let sin_theta = sin_polar(local.y);
                let mut points = [MapPoint { uv: Vec2::ZERO, sin_theta: 0.0 }; LANES];
                for (k, point) in points.iter_mut().enumerate() {
                    let uv = Vec2::new(uv.x.0[k], uv.y.0[k]);
                    distribution.prefetch_at(uv);
                    *point = MapPoint { uv, sin_theta: sin_theta.0[k] };
                }
                points
            }
        }
    }

    /// The second half of [`Self::radiance_pdf`]: radiance and solid-angle density at a
    /// point that [`Self::locate`] found.
    #[inline]
    pub fn radiance_pdf_at(&self, at: MapPoint) -> (Rgb, f32) {
        match &self.kind {
            Kind::Constant(c) => (*c, uniform_sphere_pdf()),
            Kind::Image(distribution) => {
                let (map_pdf, radiance) = distribution.at(at.uv);
                let pdf = if at.sin_theta > 0.0 { map_pdf / (2.0 * PI * PI * at.sin_theta) } else { 0.0 };
                (radiance, pdf)
            }
        }
    }

    /// Draws a direction toward the environment.
    pub fn sample(&self, u: Vec2) -> Option<EnvironmentSample> {
        match &self.kind {
            &Kind::Constant(radiance) => Some(EnvironmentSample {
                direction: sample_uniform_sphere(u),
                radiance,
                pdf: uniform_sphere_pdf(),
            }),
            Kind::Image(distribution) => {
                let (uv, map_pdf, radiance) = distribution.sample_continuous(u);
                if map_pdf <= 0.0 {
                    return None;
                }
                let local = uv_to_direction(uv);
                let sin_theta = sin_polar(local.y);
                if sin_theta <= 0.0 {
                    return None;
                }
                // The radiance of the texel drawn: the one whose density `pdf` is (looking
                // the direction up again would cost an atan2 and an acos, and could land
                // in the neighbouring texel by rounding).
                Some(EnvironmentSample {
                    direction: self.map_to_world(local),
                    radiance,
                    pdf: map_pdf / (2.0 * PI * PI * sin_theta),
                })
            }
        }
    }

    /// [`Self::sample`] of each lane's u, with the same operations (so the same bits): lane
    /// k's sample is `sample(u_k)` where `ok` is set, and `sample(u_k)` is `None` elsewhere.
    /// The draws of all lanes are made together, their table look-ups independent of one
    /// another.
    #[inline(always)]
    pub fn sample_lanes(&self, u: Vec2s) -> EnvironmentSamples {
        match &self.kind {
            &Kind::Constant(radiance) => EnvironmentSamples {
                ok: Mask([true; LANES]),
                direction: uniform_sphere(u),
                radiance: Vec3s::splat(radiance),
                pdf: F32s::splat(uniform_sphere_pdf()),
            },
            Kind::Image(distribution) => {
                let (uv, map_pdf, texels) = distribution.sample_continuous_lanes(u);
                let local = uv_direction(uv);
                let zero = F32s::splat(0.0);
                let sin_theta = sin_polar(local.y);
                let mut radiance = Vec3s::default();
                for (k, &texel) in texels.iter().enumerate() {
                    radiance.set(k, texel);
                }
                EnvironmentSamples {
                    ok: !map_pdf.le(zero) & !sin_theta.le(zero),
                    direction: self.map_to_world_of(local),
                    radiance,
                    pdf: map_pdf / (2.0 * PI * PI * sin_theta),
                }
            }
        }
    }

    /// Solid-angle density (1/sr) with which [`Self::sample`] draws world direction `d`.
    #[inline]
    pub fn pdf(&self, d: Vec3) -> f32 {
        self.radiance_pdf(d).1
    }
}

/// sin θ of a unit direction of the map's frame whose y (the map's pole) is `y`, over
/// [`Real`] values.
#[inline(always)]
fn sin_polar<R: Real>(y: R) -> R {
    (R::splat(1.0) - y * y).max(R::splat(0.0)).sqrt()
}

/// Image coordinates of a direction in the map's frame (see the module doc).
#[inline]
pub fn direction_to_uv(d: Vec3) -> Vec2 {
    direction_uv(V3::from(d)).into()
}

/// [`direction_to_uv`] over [`Real`] values (one direction, or one per lane): the arccosine
/// is libm's, and u's remainder modulo 1 (`f32::rem_euclid`, whose `%` is a call of `fmodf`)
/// is x − trunc(x) with x's sign, which is exactly fmod(x, 1) for finite |x| < 2³¹.
#[inline(always)]
pub(crate) fn direction_uv<R: Real>(d: V3<R>) -> V2<R> {
    let u = R::splat(0.5) + atan2(d.x, -d.z) * (0.5 / PI);
    let v = d.y.clamp(-1.0, 1.0).acos() / PI;
    let r = (u - u.truncate()).copysign(u);
    V2 {
        x: R::select(r.lt(R::splat(0.0)), r + 1.0, r),
        y: v,
    }
}

/// Direction in the map's frame of image coordinates (inverse of [`direction_to_uv`]):
/// θ = πv and φ = 2π(u − 0.5), whose sines and cosines are [`sin_cos_turns`] of v/2 and the
/// negated ones of u (about one ulp, several times faster than libm's).
#[inline]
pub fn uv_to_direction(uv: Vec2) -> Vec3 {
    uv_direction(V2::from(uv)).into()
}

/// [`uv_to_direction`] over [`Real`] values (one point, or one per lane).
#[inline(always)]
pub(crate) fn uv_direction<R: Real>(uv: V2<R>) -> V3<R> {
    let (st, ct) = sin_cos_turns(uv.y * 0.5);
    let (s, c) = sin_cos_turns(uv.x);
    // sin φ = −sin 2πu and cos φ = −cos 2πu.
    V3::new(st * -s, ct, st * c)
}

/// Reads an .exr or .hdr image as linear RGB radiance; rejects non-finite or negative texels.
pub fn read_radiance_image(path: &Path) -> Result<(usize, usize, Vec<Rgb>)> {
    let reader = image::ImageReader::open(path)
        .map_err(|e| Error::io(path, e))?
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    let img = reader
        .decode()
        .map_err(|e| Error::invalid_file(path, format!("cannot decode image: {e}")))?
        .into_rgb32f();
    let (w, h) = (img.width() as usize, img.height() as usize);
    if w == 0 || h == 0 {
        return Err(Error::invalid_file(path, "image is empty"));
    }
    let texels: Vec<Rgb> = img.pixels().map(|p| Rgb::new(p[0], p[1], p[2])).collect();
    if let Some(i) = texels.iter().position(|t| !t.is_finite() || t.min_element() < 0.0) {
        return Err(Error::invalid_file(
            path,
            format!("texel ({}, {}) is negative or not finite", i % w, i / w),
        ));
    }
    Ok((w, h, texels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uv_mapping_round_trips_and_centre_is_minus_z() {
        assert!((uv_to_direction(Vec2::new(0.5, 0.5)) - -Vec3::Z).length() < 1e-6);
        assert!((uv_to_direction(Vec2::new(0.3, 0.0)) - Vec3::Y).length() < 1e-6);
        for d in [Vec3::new(0.3, 0.4, -0.5), Vec3::new(-0.9, -0.1, 0.2), Vec3::new(0.1, 0.9, 0.8)] {
            let d = d.normalize();
            assert!((uv_to_direction(direction_to_uv(d)) - d).length() < 1e-5);
        }
    }

    /// [`Environment::sample_lanes`] and [`Environment::locate_lanes`] give every lane what
    /// `sample` and `locate` give it, bit for bit: a rotated map (a zero-weight row and
    /// column included) and a constant environment; u at the unit square's edges, directions
    /// along the axes, at the seam behind the map (u = 0 and 1) and at the poles.
    #[test]
    fn lanes_equal_scalar_samples_and_locations() {
        let (w, h) = (16, 8);
        let texels: Vec<Rgb> = (0..w * h)
            .map(|i| if i % w == 3 || i / w == 5 { Rgb::ZERO } else { Rgb::new(0.2 + (i % 5) as f32, 1.0, 0.5 + (i % 3) as f32) })
            .collect();
        let map = Environment::from_texels(w, h, texels, 0.7);
        let constant = Environment::load(&EnvironmentSpec {
            source: EnvironmentSource::Constant(Rgb::new(0.5, 1.0, 2.0)),
            strength: 1.5,
            rotation: 0.5,
        })
        .expect("constant environment");
        let seam = Vec3::new(-(0.7f32.sin()), 0.0, 0.7f32.cos());
        let special = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z, seam, -seam, Vec3::new(-0.0, 0.0, -1.0)];
        for env in [&map, &constant] {
            for group in 0..32 {
                let u: [Vec2; LANES] = std::array::from_fn(|k| {
                    let i = (group * LANES + k) as f32;
                    match k {
                        0 => Vec2::ZERO,
                        1 => Vec2::splat(crate::sampling::ONE_MINUS_EPSILON),
                        _ => Vec2::new((i * 0.618_034).fract(), (i * 0.414_213_5).fract()),
                    }
                });
                let d: [Vec3; LANES] = std::array::from_fn(|k| match special.get(k + group) {
                    Some(&d) => d,
                    None => sample_uniform_sphere(u[k]),
                });
                let (mut u_lanes, mut d_lanes) = (Vec2s::default(), Vec3s::default());
                for k in 0..LANES {
                    u_lanes.set(k, u[k]);
                    d_lanes.set(k, d[k]);
                }
                let samples = env.sample_lanes(u_lanes);
                let located = env.locate_lanes(d_lanes);
                for k in 0..LANES {
                    assert_eq!(format!("{:?}", samples.get(k)), format!("{:?}", env.sample(u[k])), "sample of {}", u[k]);
                    let (got, expected) = (located[k], env.locate(d[k]));
                    assert_eq!((got.uv.x.to_bits(), got.uv.y.to_bits(), got.sin_theta.to_bits()), (expected.uv.x.to_bits(), expected.uv.y.to_bits(), expected.sin_theta.to_bits()), "location of {}", d[k]);
                }
            }
        }
    }

    #[test]
    fn image_sampling_pdf_matches_pdf_and_integrates_to_one() {
        let (w, h) = (16, 8);
        let texels: Vec<Rgb> = (0..w * h)
            .map(|i| Rgb::splat(if i % 7 == 0 { 50.0 } else { 0.1 + (i % 3) as f32 }))
            .collect();
        let env = Environment::from_texels(w, h, texels, 0.7);
        let mut integral = 0.0f64;
        let n = 256;
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let s = env.sample(u).expect("sample");
                let pdf = env.pdf(s.direction);
                assert!((pdf - s.pdf).abs() <= 2e-3 * s.pdf, "{pdf} vs {}", s.pdf);
                assert_eq!(env.radiance(s.direction), s.radiance);
                // Uniform-sphere quadrature of the pdf.
                let d = sample_uniform_sphere(u);
                integral += env.pdf(d) as f64 / uniform_sphere_pdf() as f64;
            }
        }
        integral /= (n * n) as f64;
        assert!((integral - 1.0).abs() < 0.02, "{integral}");
    }
}
