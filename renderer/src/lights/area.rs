//! Emissive triangles: one-sided area lights sampled uniformly by area.

use super::LightSample;
use crate::accel::{barycentric_point, offset_origin};
use crate::lanes::{Real, V2, V3};
use crate::sampling::{sample_uniform_triangle, uniform_triangle};
use crate::bsdf::layered::coat_transmittance;
use crate::scene::{Clearcoat, Texture, TextureRef};
use crate::Rgb;
use glam::{Vec2, Vec3};

/// One emissive triangle.
#[derive(Clone, Debug)]
pub struct TriangleLight {
    pub corners: [Vec3; 3],
    /// Unit geometric normal from the winding (v1 − v0) × (v2 − v0): the emitting side.
    pub normal: Vec3,
    /// Area in scene units².
    pub area: f32,
    /// Emitted radiance, W/(m² sr) (times the texture's value where it has one).
    pub radiance: Rgb,
    /// An emissive texture over the triangle, if any.
    pub texture: Option<EmissionTexture>,
    /// The clear coat over the emitter, if any, which darkens what leaves through it (boxed:
    /// rare, and large beside the rest).
    pub coat: Option<Box<EmissionCoat>>,
}

/// The clear coat over an emissive triangle: the material's coat and the texture
/// coordinates (of the set its weight texture reads; zero without one) at the corners.
#[derive(Clone, Copy, Debug)]
pub struct EmissionCoat {
    pub coat: Clearcoat,
    pub uvs: [Vec2; 3],
}

impl EmissionCoat {
    /// 1 − c F_c(|cos|) at barycentric coordinates `b` for a direction at cosine `cos` to the
    /// triangle's normal ([`SceneMaterials::emission_toward`] at a hit on it).
    ///
    /// [`SceneMaterials::emission_toward`]: crate::material::SceneMaterials::emission_toward
    #[inline]
    fn transmittance(&self, textures: &[Texture], b: Vec2, cos: f32) -> f32 {
        coat_transmittance(self.weight(textures, b), cos)
    }

    /// The coat's weight c (factor × texture red, not yet clamped) at barycentric coordinates
    /// `b`.
    #[inline]
    fn weight(&self, textures: &[Texture], b: Vec2) -> f32 {
        let uv = self.uvs[0] * (1.0 - b.x - b.y) + self.uvs[1] * b.x + self.uvs[2] * b.y;
        self.coat.weight(|t| t.lookup(textures, uv))
    }
}

/// An emissive texture over a triangle: the material's texture reference and the texture
/// coordinates (of the set it reads) at the triangle's corners.
#[derive(Clone, Debug)]
pub struct EmissionTexture {
    pub texture: TextureRef,
    pub uvs: [Vec2; 3],
}

impl EmissionTexture {
    /// The texture coordinates at barycentric coordinates `b` (b1, b2).
    #[inline]
    fn uv(&self, b: Vec2) -> Vec2 {
        self.uvs[0] * (1.0 - b.x - b.y) + self.uvs[1] * b.x + self.uvs[2] * b.y
    }

    /// The texture's mean over the triangle, estimated from 36 points stratified by area
    /// (the light's power for choosing lights; only the choice's efficiency depends on it).
    pub fn mean_over_triangle(&self, textures: &[Texture]) -> Rgb {
        const N: u32 = 6;
        let mut sum = Rgb::ZERO;
        for i in 0..N {
            for j in 0..N {
                let u = Vec2::new((i as f32 + 0.5) / N as f32, (j as f32 + 0.5) / N as f32);
                sum += self.texture.lookup(textures, self.uv(sample_uniform_triangle(u)));
            }
        }
        sum / (N * N) as f32
    }
}

/// An emissive triangle of a scene, as the light set is built from it.
#[derive(Clone, Debug)]
pub struct Emitter {
    /// Index of the triangle in the scene's geometry.
    pub triangle: u32,
    pub corners: [Vec3; 3],
    /// Emitted radiance, W/(m² sr), times `texture` where given.
    pub radiance: Rgb,
    pub texture: Option<EmissionTexture>,
    /// The clear coat over it, if any.
    pub coat: Option<Box<EmissionCoat>>,
}

/// A point drawn on an emissive triangle as seen from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct AreaSample {
    /// World-space unit direction from the shading point to the light point.
    pub direction: Vec3,
    pub distance: f32,
    /// Radiance leaving the light toward the shading point (zero from its back side).
    pub radiance: Rgb,
    /// Solid-angle density at the shading point, 1/sr.
    pub pdf: f32,
    /// The light point moved off the light toward the shading point by its rounding-error
    /// bound: where a shadow ray must stop so it cannot hit the light itself.
    pub shadow_target: Vec3,
}

impl AreaSample {
    /// The sample as a [`LightSample`] of a light chosen with probability `select_pdf`.
    #[inline]
    pub fn with_selection(self, select_pdf: f32) -> LightSample {
        LightSample {
            direction: self.direction,
            distance: self.distance,
            radiance: self.radiance,
            pdf: self.pdf * select_pdf,
            is_delta: false,
            shadow_target: Some(self.shadow_target),
        }
    }
}

impl TriangleLight {
    /// The light for triangle `corners` emitting `radiance`; `None` for a degenerate
    /// (zero-area) triangle, which cannot emit.
    pub fn new(corners: [Vec3; 3], radiance: Rgb) -> Option<Self> {
        let cross = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
        let len = cross.length();
        (len > 0.0 && len.is_finite()).then(|| TriangleLight {
            corners,
            normal: cross / len,
            area: 0.5 * len,
            radiance,
            texture: None,
            coat: None,
        })
    }

    /// Uniform point by area, converted to a solid-angle density at `p`; `textures` are the
    /// scene's (read where the light has an emissive texture).
    #[inline]
    pub fn sample(&self, p: Vec3, u: Vec2, textures: &[Texture]) -> Option<AreaSample> {
        let s = triangle_sample(self.corners.map(V3::from), self.normal.into(), self.area, p.into(), u.into());
        s.ok.then(|| AreaSample {
            direction: s.direction.into(),
            distance: s.distance,
            radiance: {
                let b = Vec2::from(s.barycentric);
                let radiance = self.emitted(b, textures);
                match &self.coat {
                    Some(coat) => radiance * coat.transmittance(textures, b, s.cos_light),
                    None => radiance,
                }
            },
            pdf: s.pdf,
            shadow_target: s.target.into(),
        })
    }

    /// What [`Self::sample`]'s point drawn from `u` emits before its clear coat, and the
    /// coat's weight there (0 without a coat): the same from every shading point, so the
    /// lane kernels take them when a vertex is pushed and darken the radiance by the coat
    /// at the angle they find ([`coat_transmittance`]).
    #[inline(always)]
    pub fn at_sample(&self, u: Vec2, textures: &[Texture]) -> (Rgb, f32) {
        // The drawn point is found only where a texture or a coat is read there (every
        // vertex that chooses a plain light passes here: kept inline, the rest out of line).
        if self.texture.is_none() && self.coat.is_none() {
            return (self.radiance, 0.0);
        }
        self.at_drawn_point(u, textures)
    }

    /// [`Self::at_sample`] of a textured or coated light.
    #[inline(never)]
    fn at_drawn_point(&self, u: Vec2, textures: &[Texture]) -> (Rgb, f32) {
        let b = uniform_triangle(V2::from(u)).into();
        (self.emitted(b, textures), self.coat.as_ref().map_or(0.0, |coat| coat.weight(textures, b)))
    }

    /// The radiance emitted at barycentric coordinates `b` (b1, b2), before any coat: the
    /// emitted radiance times the emissive texture there.
    #[inline(always)]
    fn emitted(&self, b: Vec2, textures: &[Texture]) -> Rgb {
        match &self.texture {
            Some(t) => self.radiance * t.texture.lookup(textures, t.uv(b)),
            None => self.radiance,
        }
    }

    /// Solid-angle density of [`Self::sample`] at `p` for the light point `q`, 1/sr.
    #[inline]
    pub fn pdf(&self, p: Vec3, q: Vec3) -> f32 {
        let to = q - p;
        let d2 = to.length_squared();
        let cos_light = -to.dot(self.normal) / d2.sqrt();
        if cos_light <= 0.0 || d2 <= 0.0 {
            return 0.0;
        }
        d2 / (cos_light * self.area)
    }
}

/// A point drawn on a triangle light, seen from a shading point, over [`Real`] values: where
/// `ok`, the unit direction toward it, its distance, the solid-angle density (1/sr, without
/// the light's selection), the cosine of the direction back to the shading point to the
/// light's normal, the shadow ray's target (the point offset off the light) and its
/// barycentric coordinates (b1, b2).
pub(crate) struct TriangleSample<R: Real> {
    pub ok: R::Mask,
    pub direction: V3<R>,
    pub distance: R,
    pub pdf: R,
    pub cos_light: R,
    pub target: V3<R>,
    pub barycentric: V2<R>,
}

/// [`TriangleLight::sample`]'s geometry written once (one shading point, or one per lane):
/// a point uniform by area on the triangle (`corners`, unit emitting `normal`, `area`) from
/// `u` (Heitz's mapping), seen from `p`; not `ok` where it coincides with `p`, faces away or
/// gives no finite density.
#[inline(always)]
pub(crate) fn triangle_sample<R: Real>(corners: [V3<R>; 3], normal: V3<R>, area: R, p: V3<R>, u: V2<R>) -> TriangleSample<R> {
    let zero = R::splat(0.0);
    let b = uniform_triangle(u);
    let (q, q_error) = barycentric_point(corners, b);
    let to = q - p;
    let d2 = to.dot(to);
    let distance = d2.sqrt();
    let direction = to / distance;
    let cos_light = -direction.dot(normal);
    let pdf = d2 / (cos_light * area);
    TriangleSample {
        ok: !d2.le(zero) & !cos_light.le(zero) & pdf.is_finite(),
        direction,
        distance,
        pdf,
        cos_light,
        target: offset_origin(q, q_error, normal, -direction),
        barycentric: b,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solid_angle_pdf_matches_sample_and_back_side_is_dark() {
        let light = TriangleLight::new(
            [Vec3::new(0.0, 1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 1.0)],
            Rgb::ONE,
        )
        .expect("non-degenerate");
        assert!((light.normal - -Vec3::Y).length() < 1e-6, "emits downward");
        assert!((light.area - 0.5).abs() < 1e-6);
        let p = Vec3::new(0.2, 0.0, 0.3);
        let s = light.sample(p, Vec2::new(0.3, 0.6), &[]).expect("visible from below");
        let q = p + s.direction * s.distance;
        assert!((light.pdf(p, q) - s.pdf).abs() < 1e-4 * s.pdf);
        assert!(light.sample(Vec3::new(0.2, 2.0, 0.3), Vec2::new(0.3, 0.6), &[]).is_none());
        assert!(TriangleLight::new([Vec3::ZERO, Vec3::X, Vec3::X * 2.0], Rgb::ONE).is_none());
    }
}
