//! Point, spot and directional lights (delta distributions, sampled deterministically).

use crate::lanes::{Real, V3};
use crate::scene::PunctualLight;
use crate::Rgb;
use glam::Vec3;

/// Incident illumination from a punctual light at a point.
#[derive(Clone, Copy, Debug)]
pub struct PunctualSample {
    /// World-space unit direction from the shading point toward the light.
    pub direction: Vec3,
    /// Incident radiance-equivalent: intensity / distance² (W/m² per unit solid-angle
    /// measure of the delta), so that the contribution is f · value · |cos θ|.
    pub value: Rgb,
    /// Distance to the light (∞ for directional lights).
    pub distance: f32,
}

/// Smoothstep falloff between the outer and inner cone cosines (as glTF suggests): 1 inside
/// the inner cone, 0 outside the outer one (and for a cone whose inner cosine is not above
/// its outer one); over [`Real`] values.
#[inline(always)]
fn spot_falloff<R: Real>(cos_theta: R, cos_inner: R, cos_outer: R) -> R {
    let t = (cos_theta - cos_outer) / (cos_inner - cos_outer);
    let smooth = t * t * (R::splat(3.0) - t * 2.0);
    let dark = cos_theta.le(cos_outer) | cos_inner.le(cos_outer);
    R::select(cos_theta.ge(cos_inner), R::splat(1.0), R::select(dark, R::splat(0.0), smooth))
}

/// Illumination arriving at `p` from `light`; `None` where the light contributes nothing.
pub fn illuminate(light: &PunctualLight, p: Vec3) -> Option<PunctualSample> {
    match *light {
        PunctualLight::Point { position, intensity } => {
            let s = point_illumination(position.into(), intensity.into(), p.into());
            s.ok.then(|| PunctualSample {
                direction: s.direction.into(),
                value: s.value.into(),
                distance: s.distance,
            })
        }
        PunctualLight::Spot {
            position,
            direction,
            intensity,
            cos_inner,
            cos_outer,
        } => {
            let s = spot_illumination(position.into(), direction.into(), intensity.into(), (cos_inner, cos_outer), p.into());
            s.ok.then(|| PunctualSample {
                direction: s.direction.into(),
                value: s.value.into(),
                distance: s.distance,
            })
        }
        PunctualLight::Directional {
            direction,
            irradiance,
        } => Some(PunctualSample {
            direction: -direction,
            value: irradiance,
            distance: f32::INFINITY,
        }),
    }
}

/// Emitted power of a light (luminance, W), with `scene_radius` bounding the area a
/// directional light can reach. Used only to weigh light selection.
pub fn power_hint(light: &PunctualLight, scene_radius: f32) -> f32 {
    use crate::color::luminance;
    use std::f32::consts::PI;
    match *light {
        PunctualLight::Point { intensity, .. } => 4.0 * PI * luminance(intensity),
        PunctualLight::Spot {
            intensity,
            cos_inner,
            cos_outer,
            ..
        } => 2.0 * PI * (1.0 - 0.5 * (cos_inner + cos_outer)) * luminance(intensity),
        PunctualLight::Directional { irradiance, .. } => {
            PI * scene_radius * scene_radius * luminance(irradiance)
        }
    }
}

/// A point light's illumination over [`Real`] values: where `ok`, the unit direction toward
/// the light, the value (intensity / distance², W/(m² sr) per unit solid angle of a delta
/// light) and the distance.
pub(crate) struct PointIllumination<R: Real> {
    pub ok: R::Mask,
    pub direction: V3<R>,
    pub value: V3<R>,
    pub distance: R,
}

/// [`illuminate`] of a point light at `position` of intensity `intensity` (W/sr) at `p`,
/// written once (one shading point, or one per lane); not `ok` at the light itself.
#[inline(always)]
pub(crate) fn point_illumination<R: Real>(position: V3<R>, intensity: V3<R>, p: V3<R>) -> PointIllumination<R> {
    let to = position - p;
    let d2 = to.dot(to);
    let distance = d2.sqrt();
    PointIllumination {
        ok: d2.gt(R::splat(0.0)),
        direction: to / distance,
        value: intensity / d2,
        distance,
    }
}

/// [`illuminate`] of a spot light at `position` shining along `axis` (unit) with intensity
/// `intensity` (W/sr) on its axis and cone cosines `(inner, outer)`, at `p`, written once (one
/// shading point, or one per lane); not `ok` at the light itself or outside the cone.
#[inline(always)]
pub(crate) fn spot_illumination<R: Real>(position: V3<R>, axis: V3<R>, intensity: V3<R>, (cos_inner, cos_outer): (R, R), p: V3<R>) -> PointIllumination<R> {
    let to = position - p;
    let d2 = to.dot(to);
    let distance = d2.sqrt();
    let direction = to / distance;
    let falloff = spot_falloff((-direction).dot(axis), cos_inner, cos_outer);
    PointIllumination {
        ok: !d2.le(R::splat(0.0)) & falloff.gt(R::splat(0.0)),
        direction,
        value: intensity * (falloff / d2),
        distance,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_light_falls_off_with_distance_squared() {
        let l = PunctualLight::Point {
            position: Vec3::new(0.0, 2.0, 0.0),
            intensity: Rgb::splat(8.0),
        };
        let s = illuminate(&l, Vec3::ZERO).expect("lit");
        assert_eq!(s.direction, Vec3::Y);
        assert!((s.value - Rgb::splat(2.0)).length() < 1e-6);
        assert!((s.distance - 2.0).abs() < 1e-6);
    }

    #[test]
    fn spot_light_cone() {
        let l = PunctualLight::Spot {
            position: Vec3::new(0.0, 1.0, 0.0),
            direction: -Vec3::Y,
            intensity: Rgb::ONE,
            cos_inner: 0.9,
            cos_outer: 0.8,
        };
        assert!((illuminate(&l, Vec3::ZERO).expect("inside").value - Rgb::ONE).length() < 1e-6);
        assert!(illuminate(&l, Vec3::new(5.0, 0.0, 0.0)).is_none(), "outside the cone");
        let edge = illuminate(&l, Vec3::new(0.7, 0.0, 0.0)).expect("in the falloff");
        assert!(edge.value.x > 0.0 && edge.value.x < 1.0 / 1.49);
    }

    #[test]
    fn directional_light_comes_from_against_its_direction() {
        let l = PunctualLight::Directional {
            direction: -Vec3::Y,
            irradiance: Rgb::splat(3.0),
        };
        let s = illuminate(&l, Vec3::new(4.0, 5.0, 6.0)).expect("lit");
        assert_eq!(s.direction, Vec3::Y);
        assert!(s.distance.is_infinite());
    }
}
