//! The light samples of a lane kernel's vertices ([`super::bxdf_lanes`]) and their
//! next-event estimation, per lane with the scalar code's
//! operations (so the same bits).
//!
//! A vertex pushes its chosen light as a [`LaneLight`]: an emissive triangle (its emissive
//! texture and its clear coat's weight read at the point drawn, which does not depend on the
//! vertex) or the environment (constant or map) is sampled by the kernel and a point or spot
//! light illuminates the vertex there, all lanes at once — the triangle's point (Heitz's
//! mapping), solid-angle density and coat darkening, the environment's draw with its sixteen
//! alias-table look-ups issued together rather than one draw's dependent misses after
//! another's; a directional light's sample, the same at every point, is drawn when the
//! vertex is pushed. Every light kind is thus begun in lanes.

use super::scattered_lanes::ScatteredLanes;
use super::{shadow_test, PathTracer, RealLightSample, Strategy, Vertex};
use crate::lanes::{F32s, Mask, MaskOps, Vec2s, Vec3s, LANES};
use crate::bsdf::layered::coat_transmittance;
use crate::lights::area::{triangle_sample, TriangleLight};
use crate::lights::punctual::{point_illumination, spot_illumination};
use crate::lights::environment::Environment;
use crate::scene::Texture;
use crate::lights::LightSample;
use crate::render_scene::{RenderScene, SurfaceLanes};
use crate::scene::PunctualLight;
use crate::Rgb;
use glam::{Vec2, Vec3};

/// The light sample of a lane vertex as it is pushed.
#[derive(Clone, Copy, Debug)]
pub(crate) enum LaneLight<'s> {
    /// No light sample contributes (no light, or one `scatter` would not sample).
    None,
    /// Drawn one by one, as `scatter` draws it.
    Sampled(LightSample),
    /// An emissive triangle chosen with probability `select_pdf`, sampled by the kernel from
    /// `u` as `TriangleLight::sample` samples it; what the point drawn from `u` emits before
    /// its clear coat, and the coat's weight there, are read from the light's `textures` as
    /// the lane takes it ([`TriangleLight::at_sample`] in [`LightLanes::set`]).
    Triangle { light: &'s TriangleLight, textures: &'s [Texture], u: Vec2, select_pdf: f32 },
    /// The environment's sample, drawn by the kernel from `u`: the sample `scatter` would
    /// draw, its density times `select_pdf`.
    Environment { environment: &'s Environment, u: Vec2, select_pdf: f32 },
    /// A point light at `position` of intensity `intensity` (W/sr) chosen with probability
    /// `select_pdf`, illuminating the vertex as `punctual::illuminate` finds in the kernel.
    Point { position: Vec3, intensity: Rgb, select_pdf: f32 },
    /// A spot light, likewise: at `position`, shining along `axis` with `intensity` on it
    /// and cone cosines `cone` (inner, outer).
    Spot { position: Vec3, axis: Vec3, intensity: Rgb, cone: (f32, f32), select_pdf: f32 },
}

impl PathTracer {
    /// What vertex `v` pushes into a lane kernel as its light: a triangle's or
    /// the environment's sample, or a point or spot light's illumination, left to the kernel; any
    /// other drawn now ([`PathTracer::light_sample`]).
    #[inline(always)]
    pub(crate) fn lane_light<'s>(&self, scene: &'s RenderScene, v: &Vertex) -> LaneLight<'s> {
        self.kernel_light(scene, v.light, v.u_light)
            .unwrap_or_else(|| self.light_sample(scene, v).map_or(LaneLight::None, LaneLight::Sampled))
    }

    /// The [`LaneLight`] of a vertex whose chosen light is `light` (index, selection
    /// probability) and whose light sample's u is `u`, where it is known without the
    /// vertex's point: a triangle (textured, coated or not), the environment, a point or spot
    /// light (the kernel samples or illuminates it), a directional light (the same sample
    /// everywhere, drawn now), or no light; `None` where its sample must be drawn at the point
    /// first (no light kind today).
    #[inline(always)]
    pub(crate) fn kernel_light<'s>(&self, scene: &'s RenderScene, light: Option<(u32, f32)>, u: Vec2) -> Option<LaneLight<'s>> {
        let Some((index, select_pdf)) = light else {
            return Some(LaneLight::None);
        };
        // Delta lights are sampled under every strategy, the others (triangles, the
        // environment) where light sampling is (as `light_sample` filters them).
        match scene.lights.punctual(index) {
            Some(&PunctualLight::Point { position, intensity }) => return Some(LaneLight::Point { position, intensity, select_pdf }),
            Some(&PunctualLight::Spot { position, direction, intensity, cos_inner, cos_outer }) => {
                return Some(LaneLight::Spot { position, axis: direction, intensity, cone: (cos_inner, cos_outer), select_pdf })
            }
            // The same sample at every point: drawn now.
            Some(PunctualLight::Directional { .. }) => return scene.lights.sample_chosen(index, select_pdf, Vec3::ZERO, Vec2::ZERO).map(LaneLight::Sampled),
            None => {}
        }
        let sampled = self.strategy != Strategy::BsdfOnly;
        if let Some(light) = scene.lights.triangle(index) {
            if !sampled {
                return Some(LaneLight::None);
            }
            return Some(LaneLight::Triangle { light, textures: scene.lights.textures(), u, select_pdf });
        }
        let environment = scene.lights.environment_of(index)?;
        Some(if sampled { LaneLight::Environment { environment, u, select_pdf } } else { LaneLight::None })
    }

    /// Where vertex `v`'s light sample is the environment's: the environment, the sample's
    /// u and the selection probability, for a draw in lanes ([`Environment::sample_lanes`];
    /// [`PathTracer::light_sample`] would draw it from `u`).
    #[inline(always)]
    pub(crate) fn environment_draw<'s>(&self, scene: &'s RenderScene, v: &Vertex) -> Option<(&'s Environment, Vec2, f32)> {
        let (index, select_pdf) = v.light.filter(|_| self.strategy != Strategy::BsdfOnly)?;
        Some((scene.lights.environment_of(index)?, v.u_light, select_pdf))
    }
}

/// The [`LaneLight`]s of up to [`LANES`] vertices, structure of arrays.
#[derive(Clone, Debug, Default)]
pub(crate) struct LightLanes<'s> {
    /// The scene's environment, where a lane samples it.
    environment: Option<&'s Environment>,
    /// Lanes with a light sample, drawn or to draw.
    ok: [bool; LANES],
    /// Lanes the kernel samples: a triangle or the environment, from `u`; lanes it
    /// illuminates from a point light at `position`.
    triangle: [bool; LANES],
    from_environment: [bool; LANES],
    point: [bool; LANES],
    position: Vec3s,
    /// Lanes lit by a spot light at `position`, its axis and cone cosines.
    spot: [bool; LANES],
    axis: Vec3s,
    cos_inner: F32s,
    cos_outer: F32s,
    u: Vec2s,
    /// The triangles' corners, unit normals and areas, and their clear coats' weights at the
    /// points drawn (0 without).
    corners: [Vec3s; 3],
    normal: Vec3s,
    area: F32s,
    coat: F32s,
    /// Drawn samples; the triangles' radiance and the point lights' intensity; the
    /// selection probability where the kernel samples.
    direction: Vec3s,
    radiance: Vec3s,
    pdf: F32s,
    delta: [bool; LANES],
    /// Where the shadow ray ends, where it does not go to infinity (`has_target`).
    has_target: [bool; LANES],
    target: Vec3s,
}

/// The light samples of [`LANES`] vertices ([`LightLanes::samples`]): per lane what
/// [`LightSample`] holds, where `ok`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LightSamples {
    pub ok: Mask,
    pub sample: RealLightSample<F32s>,
}

impl<'s> LightLanes<'s> {
    /// Sets lane `i` to `light`.
    #[inline(always)]
    pub fn set(&mut self, i: usize, light: LaneLight<'s>) {
        self.ok[i] = !matches!(light, LaneLight::None);
        self.triangle[i] = matches!(light, LaneLight::Triangle { .. });
        self.from_environment[i] = matches!(light, LaneLight::Environment { .. });
        self.point[i] = matches!(light, LaneLight::Point { .. });
        self.spot[i] = matches!(light, LaneLight::Spot { .. });
        match light {
            LaneLight::None => {}
            LaneLight::Sampled(ls) => {
                self.direction.set(i, ls.direction);
                self.radiance.set(i, ls.radiance);
                self.pdf.0[i] = ls.pdf;
                self.delta[i] = ls.is_delta;
                self.has_target[i] = ls.shadow_target.is_some();
                self.target.set(i, ls.shadow_target.unwrap_or(Vec3::ZERO));
            }
            LaneLight::Triangle { light, textures, u, select_pdf } => {
                // Read here, into the lanes (returned with the light and moved, the values
                // stalled store forwarding).
                let (radiance, coat) = light.at_sample(u, textures);
                for (c, &corner) in self.corners.iter_mut().zip(&light.corners) {
                    c.set(i, corner);
                }
                self.normal.set(i, light.normal);
                self.area.0[i] = light.area;
                self.radiance.set(i, radiance);
                self.coat.0[i] = coat;
                self.u.set(i, u);
                self.pdf.0[i] = select_pdf;
                self.delta[i] = false;
                self.has_target[i] = true;
            }
            LaneLight::Point { position, intensity, select_pdf } => {
                self.position.set(i, position);
                self.radiance.set(i, intensity);
                self.pdf.0[i] = select_pdf;
                self.delta[i] = true;
            }
            LaneLight::Spot { position, axis, intensity, cone: (inner, outer), select_pdf } => {
                self.position.set(i, position);
                self.axis.set(i, axis);
                self.cos_inner.0[i] = inner;
                self.cos_outer.0[i] = outer;
                self.radiance.set(i, intensity);
                self.pdf.0[i] = select_pdf;
                self.delta[i] = true;
            }
            LaneLight::Environment { environment, u, select_pdf } => {
                self.environment = Some(environment);
                self.u.set(i, u);
                self.pdf.0[i] = select_pdf;
                self.delta[i] = false;
                self.has_target[i] = false;
            }
        }
    }

    /// Every lane's sample for shading points `p`: the triangles', the point lights' and the
    /// environment's found here, the others as pushed.
    #[inline(always)]
    pub fn samples(&self, p: Vec3s) -> LightSamples {
        let mut ok = Mask(self.ok);
        let mut l = RealLightSample {
            direction: self.direction,
            radiance: self.radiance,
            pdf: self.pdf,
            delta: Mask(self.delta),
            has_target: Mask(self.has_target),
            target: self.target,
        };
        let triangle = Mask(self.triangle);
        if triangle.0.iter().any(|&t| t) {
            // TriangleLight::sample's geometry and coat.
            let s = triangle_sample(self.corners, self.normal, self.area, p, self.u);
            ok = ok & (!triangle | s.ok);
            l.direction = triangle.select(s.direction, l.direction);
            l.pdf = triangle.select(s.pdf * self.pdf, l.pdf);
            if (triangle & self.coat.gt(F32s::splat(0.0))).any() {
                l.radiance = triangle.select(l.radiance * coat_transmittance(self.coat, s.cos_light), l.radiance);
            }
            l.target = triangle.select(s.target, l.target);
        }
        // punctual::illuminate of point and spot lights, and LightSet::sample_chosen's target.
        for (lanes, in_cone) in [(Mask(self.point), false), (Mask(self.spot), true)] {
            if !lanes.0.iter().any(|&l| l) {
                continue;
            }
            let s = if in_cone {
                spot_illumination(self.position, self.axis, self.radiance, (self.cos_inner, self.cos_outer), p)
            } else {
                point_illumination(self.position, self.radiance, p)
            };
            ok = ok & (!lanes | s.ok);
            l.direction = lanes.select(s.direction, l.direction);
            l.radiance = lanes.select(s.value, l.radiance);
            l.has_target = l.has_target & !lanes | (lanes & s.distance.is_finite());
            l.target = lanes.select(p + s.direction * s.distance, l.target);
        }
        let from_environment = Mask(self.from_environment);
        if let Some(environment) = self.environment.filter(|_| from_environment.0.iter().any(|&e| e)) {
            let e = environment.sample_lanes(self.u);
            ok = ok & (!from_environment | e.ok);
            l.direction = from_environment.select(e.direction, l.direction);
            l.radiance = from_environment.select(e.radiance, l.radiance);
            l.pdf = from_environment.select(e.pdf * self.pdf, l.pdf);
        }
        LightSamples { ok, sample: l }
    }
}

/// Next-event estimation (`PathTracer::light_term` and `light_contribution`) into `out`'s
/// shadow rays, per lane: light samples `l` at the `surface` points (their positions, rounding
/// bounds and geometric normals facing the arriving rays), where the BSDF's value toward the
/// light is `f` (1/sr) and its density `bsdf_pdf`, and the light's direction has local z
/// `wi_z`; `beta` the throughputs. `light_only` weighs samples by 1 instead of the power
/// heuristic (as delta lights always are).
#[inline(always)]
pub(crate) fn next_event(
    l: &LightSamples,
    surface: &SurfaceLanes,
    wi_z: F32s,
    (f, bsdf_pdf): (Vec3s, F32s),
    beta: Vec3s,
    light_only: bool,
    out: &mut ScatteredLanes,
) {
    let test = shadow_test((surface.p, surface.p_error, surface.ng), &l.sample, wi_z, (f, bsdf_pdf), beta, light_only);
    out.shadow_ok = (l.ok & test.ok).0;
    out.shadow_origin = test.origin;
    out.shadow_direction = test.direction;
    out.shadow_t_max = test.t_max;
    out.contribution = test.contribution;
}
