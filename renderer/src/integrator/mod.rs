//! Unidirectional path tracing with next-event estimation and multiple importance sampling
//! (power heuristic) between BSDF sampling and light sampling, and Russian roulette.
//!
//! Depth follows Mitsuba 3's `max_depth`: a path of k segments (camera → … → emitter) is
//! counted when k ≤ max_depth, so 1 renders directly visible emitters, 2 adds direct
//! lighting, and −1 is unlimited (Russian roulette ends paths).

mod batch;
mod bxdf_lanes;
mod deferred;
mod hit_lanes;
mod light_lanes;
mod scattered_lanes;

pub use batch::{BatchBuffers, StepResults};

use crate::accel::{offset_origin, Hit, Ray};
use crate::bsdf::{Bsdf, BsdfSample, Bxdf, RealSample};
use crate::lanes::{MaskOps, Real, V3};
use crate::lights::environment::MapPoint;
use crate::lights::LightSample;
use crate::render_scene::{RenderScene, SurfacePoint};
use crate::sampler::Sampler;
use crate::sampling::power_heuristic;
use crate::Rgb;
use glam::{Vec2, Vec3};

/// Which estimators gather light at each path vertex.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Strategy {
    /// Light sampling and BSDF sampling combined by MIS (power heuristic).
    #[default]
    Mis,
    /// BSDF sampling only: emitters count only when a path hits them (punctual lights,
    /// which cannot be hit, are still sampled).
    BsdfOnly,
    /// Light sampling only: emitters hit by BSDF-sampled rays are ignored (except those seen
    /// directly from the camera).
    LightOnly,
}

/// Settings of the path tracer.
#[derive(Clone, Copy, Debug)]
pub struct PathTracer {
    /// Longest path counted, in segments (Mitsuba 3's meaning); −1 = unlimited.
    pub max_depth: i32,
    /// Path depth (segments) from which Russian roulette may end paths (Mitsuba's default 5).
    pub rr_depth: u32,
    /// Estimators to combine; all give the same expected image.
    pub strategy: Strategy,
}

impl Default for PathTracer {
    fn default() -> Self {
        PathTracer {
            max_depth: -1,
            rr_depth: 5,
            strategy: Strategy::Mis,
        }
    }
}

/// Ray counts of one path, for statistics.
#[derive(Clone, Copy, Debug, Default)]
pub struct PathCounters {
    /// Closest-hit rays traced (camera and continuation rays).
    pub rays: u64,
    /// Shadow (occlusion) rays traced.
    pub shadow_rays: u64,
}

/// One path between vertices: its next ray, throughput, radiance gathered so far and
/// random stream.
#[derive(Clone, Debug)]
pub struct PathState {
    /// The ray to trace next.
    pub ray: Ray,
    /// Path throughput (product of BSDF weights and Russian-roulette factors).
    pub beta: Rgb,
    /// Radiance gathered so far.
    pub l: Rgb,
    /// Segments traced so far, including `ray`'s.
    segments: u32,
    /// Density of the BSDF sample that produced `ray` (None for the camera ray).
    prev_bsdf_pdf: Option<f32>,
    /// Origin of the vertex `ray` leaves.
    prev_p: Vec3,
    /// Absorption coefficient (1/m, per channel) of the volume `ray` travels through: zero
    /// outside every volume (see [`PathState::attenuate`]).
    sigma_a: Rgb,
    pub sampler: Sampler,
}

impl PathState {
    /// Beer–Lambert absorption along the segment just traced, `t` metres long (the closest
    /// hit's distance; `ray` directions are unit vectors): the throughput times
    /// exp(−σa t) inside a volume, unchanged outside.
    ///
    /// Volumes (glTF `KHR_materials_volume`) are entered by transmission through the front
    /// of a surface of their material and left by transmission through its back, into
    /// vacuum: a path inside a volume that crosses into another (nested or overlapping
    /// volumes) takes the inner one's absorption and, leaving it, none.
    #[inline(always)]
    pub(crate) fn attenuate(&mut self, t: f32) {
        if self.sigma_a != Rgb::ZERO {
            self.beta *= (-self.sigma_a * t).exp();
        }
    }
}

/// Light sampled at a vertex: its contribution counts when `ray` is unoccluded.
#[derive(Clone, Copy, Debug)]
pub struct ShadowTest {
    pub ray: Ray,
    pub contribution: Rgb,
}

/// A path vertex on a scattering surface, its random numbers drawn and its light chosen:
/// everything [`PathTracer::scatter`] needs besides the throughput.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Vertex<'s> {
    pub sp: SurfacePoint,
    pub bsdf: Bsdf<'s>,
    /// Direction toward the previous vertex, local shading frame, z > 0.
    pub wo: Vec3,
    /// The light chosen for next-event estimation and its selection probability.
    pub light: Option<(u32, f32)>,
    /// Sample for the point on the chosen light.
    pub u_light: Vec2,
    /// Samples for the BSDF: lobe choice and direction.
    pub uc: f32,
    pub u: Vec2,
}

/// A vertex's random numbers and chosen light ([`PathTracer::draw`]), as in [`Vertex`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Draws {
    pub light: Option<(u32, f32)>,
    pub u_light: Vec2,
    pub uc: f32,
    pub u: Vec2,
}

/// The ray a vertex continues the path with, drawn by BSDF sampling.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Continuation {
    pub ray: Ray,
    /// Throughput after the vertex (before Russian roulette): finite, some channel > 0.
    pub beta: Rgb,
    /// Density of the sampled direction, 1/sr.
    pub pdf: f32,
    /// Whether the direction comes from a delta lobe (emission it finds is not weighed by
    /// MIS: light sampling cannot find it).
    pub delta: bool,
    /// The absorption coefficient of the volume the ray enters (zero leaving one), where it
    /// crosses into or out of a volume; `None` where it stays in the same medium.
    pub sigma_a: Option<Rgb>,
}

/// What a vertex scatters into: a shadow test from the light sample and the continuation.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Scattered {
    pub shadow: Option<ShadowTest>,
    pub next: Option<Continuation>,
}

/// Fraction of a shadow ray's length left out at the light end (beyond the offset of the
/// light point by its error bound).
pub(crate) const SHADOW_EPSILON: f32 = 1e-4;

impl PathTracer {
    /// Whether a path of `segments` segments may be counted.
    #[inline]
    fn allows(&self, segments: u32) -> bool {
        self.max_depth < 0 || segments <= self.max_depth as u32
    }

    /// MIS weight of emission found by a ray: camera rays and BSDF-only rendering weigh it 1,
    /// light-only rendering 0, MIS by the power heuristic against the light-sampling density.
    #[inline]
    fn hit_weight(&self, bsdf_pdf: Option<f32>, light_pdf: impl FnOnce() -> f32) -> f32 {
        match (bsdf_pdf, self.strategy) {
            (None, _) | (Some(_), Strategy::BsdfOnly) => 1.0,
            (Some(_), Strategy::LightOnly) => 0.0,
            (Some(pdf), Strategy::Mis) => power_heuristic(pdf, light_pdf()),
        }
    }

    /// The state of a path starting with camera ray `ray`, or `None` when `max_depth`
    /// counts nothing (0).
    #[inline]
    pub fn start(&self, ray: Ray, sampler: Sampler) -> Option<PathState> {
        self.allows(1).then_some(PathState {
            ray,
            beta: Rgb::ONE,
            l: Rgb::ZERO,
            segments: 1,
            prev_bsdf_pdf: None,
            prev_p: ray.origin,
            sigma_a: Rgb::ZERO,
            sampler,
        })
    }

    /// One path vertex: takes the closest hit `hit` of `path.ray` (or its miss), adds the
    /// emission found, samples a light (returned as a shadow test whose contribution the
    /// caller adds to `path.l` when the shadow ray is unoccluded) and the BSDF, and sets
    /// `path.ray` to the continuation ray. Returns the shadow test and whether the path
    /// goes on. Paths stepped in any interleaving give the same values as stepped alone.
    ///
    /// Its three parts — `begin`, `scatter`, `advance` — are also what the batched loop
    /// ([`Self::step_batch`]) calls, scattering many vertices at once.
    #[inline(always)]
    pub fn step(&self, scene: &RenderScene, path: &mut PathState, hit: Option<Hit>) -> (Option<ShadowTest>, bool) {
        let Some(vertex) = self.begin(scene, path, hit) else {
            return (None, false);
        };
        let scattered = self.scatter(scene, &vertex, path.beta);
        let alive = self.advance(path, vertex.sp.p, scattered.next);
        (scattered.shadow, alive)
    }

    /// The end of a path whose ray left the scene: adds the environment's radiance along it
    /// (MIS-weighted against light sampling).
    #[inline(always)]
    fn escape(&self, scene: &RenderScene, path: &mut PathState) {
        if let Some(at) = scene.lights.locate_environment(path.ray.direction) {
            self.escape_at(scene, path, at);
        }
    }

    /// [`Self::escape`] where the ray's direction falls at `at` in the environment
    /// ([`crate::lights::LightSet::locate_environment`]).
    #[inline(always)]
    pub(crate) fn escape_at(&self, scene: &RenderScene, path: &mut PathState, at: MapPoint) {
        if let Some((le, pdf)) = scene.lights.environment_radiance_pdf_at(at) {
            let w = self.hit_weight(path.prev_bsdf_pdf, || pdf);
            path.l += path.beta * le * w;
        }
    }

    /// The first half of a vertex: adds the emission `path.ray` finds at `hit` (or, on a
    /// miss, in the environment) and, where the path may scatter there, draws the vertex's
    /// random numbers and chooses its light. `None` when the path ends here.
    #[inline(always)]
    fn begin<'s>(&self, scene: &'s RenderScene, path: &mut PathState, hit: Option<Hit>) -> Option<Vertex<'s>> {
        let Some(hit) = hit else {
            self.escape(scene, path);
            return None;
        };
        path.attenuate(hit.t);
        let draws = self.draw(scene, path);
        self.begin_drawn(scene, path, hit, draws)
    }

    /// The random numbers of the vertex `path` reaches and its chosen light. They are drawn
    /// first (a path that ends at the vertex draws nothing more, so drawing them early
    /// changes nothing).
    #[inline(always)]
    fn draw(&self, scene: &RenderScene, path: &mut PathState) -> Draws {
        let [u_select, u_light_x, u_light_y, uc, u_x, u_y] = path.sampler.next_block();
        Draws {
            light: scene.lights.choose(u_select),
            u_light: Vec2::new(u_light_x, u_light_y),
            uc,
            u: Vec2::new(u_x, u_y),
        }
    }

    /// [`Self::begin`] at `hit`, the vertex's random numbers drawn and the segment's
    /// absorption applied ([`PathState::attenuate`]).
    #[inline(always)]
    fn begin_drawn<'s>(&self, scene: &'s RenderScene, path: &mut PathState, hit: Hit, draws: Draws) -> Option<Vertex<'s>> {
        let ray = path.ray;
        let Draws { light, u_light, uc, u } = draws;
        let sp = scene.surface_point(&hit, ray.direction)?;
        self.add_emission(scene, path, &sp);
        if !self.allows(path.segments + 1) {
            return None;
        }
        let bsdf = scene.bsdf(&sp)?;
        let wo = sp.frame.to_local(-ray.direction);
        if wo.z <= 0.0 {
            return None;
        }
        // A latent blend's two palette neighbours: one drawn per vertex in proportion to its
        // weight (uc, rescaled), an unbiased estimate of their mixture at one network's cost.
        let (bsdf, uc) = match bsdf {
            Bsdf::Mixture(m) if m.drawn_per_vertex() => {
                let (one, uc) = m.draw(uc);
                (Bsdf::Mixture(one), uc)
            }
            _ => (bsdf, uc),
        };
        Some(Vertex {
            sp,
            bsdf,
            wo,
            light,
            u_light,
            uc,
            u,
        })
    }

    /// Adds the radiance emitted at `sp` (where `path.ray` hit) toward the ray's origin,
    /// weighed against the light sampling that could have found it.
    #[inline(always)]
    fn add_emission(&self, scene: &RenderScene, path: &mut PathState, sp: &SurfacePoint) {
        let le = scene.emission(sp, -path.ray.direction);
        if le.max_element() > 0.0 {
            let w = self.hit_weight(path.prev_bsdf_pdf, || scene.lights.pdf_triangle(sp.triangle, path.prev_p, sp.p));
            path.l += path.beta * le * w;
        }
    }

    /// The light-sampling and BSDF-sampling half of a vertex, a pure function of the vertex
    /// and the path throughput `beta`.
    #[inline(always)]
    fn scatter(&self, scene: &RenderScene, vertex: &Vertex, beta: Rgb) -> Scattered {
        let Vertex { sp, bsdf, wo, u, uc, .. } = *vertex;
        // A BSDF of delta lobes alone (smooth glass) has no value toward a light sample.
        let shadow = if bsdf.is_delta() {
            None
        } else {
            self.light_sample(scene, vertex).and_then(|ls| self.light_term(&bsdf, &sp, wo, beta, &ls))
        };
        let next = bsdf.sample(wo, u, uc).and_then(|bs| {
            let mut next = continuation(&sp, &bs, beta)?;
            if bs.wi.z < 0.0 {
                next.sigma_a = scene.materials.entered_volume(sp.material, sp.front_face);
            }
            Some(next)
        });
        Scattered { shadow, next }
    }

    /// The sample of the vertex's chosen light that next-event estimation uses (none for
    /// area lights and the environment when rendering by BSDF sampling only).
    #[inline(always)]
    fn light_sample(&self, scene: &RenderScene, vertex: &Vertex) -> Option<LightSample> {
        vertex
            .light
            .and_then(|(index, select_pdf)| scene.lights.sample_chosen(index, select_pdf, vertex.sp.p, vertex.u_light))
            .filter(|l| l.is_delta || self.strategy != Strategy::BsdfOnly)
    }

    /// Next-event estimation: the shadow test of light sample `ls` at `sp`, `None` where it
    /// cannot contribute.
    #[inline(always)]
    fn light_term<B: Bxdf>(&self, bsdf: &B, sp: &SurfacePoint, wo: Vec3, beta: Rgb, ls: &LightSample) -> Option<ShadowTest> {
        let wi = light_direction(sp, ls, bsdf.transmits())?;
        let (f, bsdf_pdf) = bsdf.eval_pdf(wo, wi);
        self.light_contribution(sp, beta, ls, wi, f, bsdf_pdf)
    }

    /// Whether light sample `ls` is weighed against BSDF sampling by MIS, i.e. whether
    /// [`Self::light_contribution`] uses the BSDF's density of its direction (not for delta
    /// lights, which BSDF sampling cannot hit, nor under [`Strategy::LightOnly`]).
    #[inline(always)]
    fn weighs_light_sample(&self, ls: &LightSample) -> bool {
        !ls.is_delta && self.strategy != Strategy::LightOnly
    }

    /// The shadow test of light sample `ls` arriving from `wi` (local frame) at `sp`, where
    /// the BSDF's value is `f` (1/sr) and its density of sampling `wi` `bsdf_pdf`; `None` where
    /// it cannot contribute (also where a NaN makes a test fail, hence the negated
    /// comparisons).
    #[inline(always)]
    #[allow(clippy::neg_cmp_op_on_partial_ord)]
    fn light_contribution(&self, sp: &SurfacePoint, beta: Rgb, ls: &LightSample, wi: Vec3, f: Rgb, bsdf_pdf: f32) -> Option<ShadowTest> {
        let light = RealLightSample {
            direction: ls.direction.into(),
            radiance: ls.radiance.into(),
            pdf: ls.pdf,
            delta: ls.is_delta,
            has_target: ls.shadow_target.is_some(),
            target: ls.shadow_target.unwrap_or(Vec3::ZERO).into(),
        };
        let at = (sp.p.into(), sp.p_error.into(), sp.ng_facing.into());
        let test = shadow_test(at, &light, wi.z, (f.into(), bsdf_pdf), beta.into(), self.strategy == Strategy::LightOnly);
        test.ok.then(|| ShadowTest {
            ray: Ray {
                origin: test.origin.into(),
                direction: test.direction.into(),
                t_max: test.t_max,
            },
            contribution: test.contribution.into(),
        })
    }

    /// The last half of a vertex at `p`: takes the continuation (or ends the path), plays
    /// Russian roulette and moves the path on. Returns whether it goes on.
    #[inline(always)]
    fn advance(&self, path: &mut PathState, p: Vec3, next: Option<Continuation>) -> bool {
        let Some(next) = next else {
            return false;
        };
        path.beta = next.beta;
        path.segments += 1;
        if path.segments > self.rr_depth {
            let q = path.beta.max_element().min(0.95);
            if path.sampler.next_1d() >= q {
                return false;
            }
            path.beta /= q;
        }
        path.prev_bsdf_pdf = (!next.delta).then_some(next.pdf);
        path.prev_p = p;
        if let Some(sigma_a) = next.sigma_a {
            path.sigma_a = sigma_a;
        }
        path.ray = next.ray;
        true
    }

    /// Radiance arriving along `ray` (a camera ray), estimated with one path.
    pub fn radiance(&self, scene: &RenderScene, ray: Ray, sampler: &mut Sampler, counters: &mut PathCounters) -> Rgb {
        let Some(mut path) = self.start(ray, sampler.clone()) else {
            return Rgb::ZERO;
        };
        loop {
            counters.rays += 1;
            let hit = scene.intersect(&path.ray);
            let (shadow, alive) = self.step(scene, &mut path, hit);
            if let Some(test) = shadow {
                counters.shadow_rays += 1;
                if !scene.occluded(&test.ray) {
                    path.l += test.contribution;
                }
            }
            if !alive {
                break;
            }
        }
        *sampler = path.sampler;
        path.l
    }
}

/// The direction of light sample `ls` in the local frame of `sp`, `None` where it leaves
/// below the geometric surface (also where a NaN makes the test fail) and the BSDF does not
/// transmit (`transmits` false).
#[inline(always)]
#[allow(clippy::neg_cmp_op_on_partial_ord)]
fn light_direction(sp: &SurfacePoint, ls: &LightSample, transmits: bool) -> Option<Vec3> {
    (transmits || ls.direction.dot(sp.ng_facing) > 0.0).then(|| sp.frame.to_local(ls.direction))
}

/// The continuation of BSDF sample `bs` at `sp` for a path of throughput `beta`, in the same
/// medium; `None` where the direction leaves on the other side of the geometric surface than
/// of the shading surface or the throughput becomes zero or not finite.
#[inline(always)]
fn continuation(sp: &SurfacePoint, bs: &BsdfSample, beta: Rgb) -> Option<Continuation> {
    let frame = &sp.frame;
    let wi_world = frame.to_world(bs.wi).into();
    let sample = RealSample {
        ok: true,
        wi: bs.wi.into(),
        f: bs.f.into(),
        pdf: bs.pdf,
        delta: bs.delta,
    };
    let next = continue_path((sp.p.into(), sp.p_error.into(), sp.ng_facing.into()), wi_world, &sample, beta.into());
    next.ok.then(|| Continuation {
        ray: Ray::new(next.origin.into(), wi_world.into()),
        beta: next.beta.into(),
        pdf: next.pdf,
        delta: bs.delta,
        sigma_a: None,
    })
}

/// A vertex's position, its rounding bound and its geometric normal facing the arriving ray:
/// where its shadow rays and continuation leave from.
pub(crate) type Leaving<R> = (V3<R>, V3<R>, V3<R>);

/// A light sample as next-event estimation weighs it, over [`Real`] values
/// ([`LightSample`]'s fields for one vertex, or one per lane).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RealLightSample<R: Real> {
    /// World-space unit direction toward the light.
    pub direction: V3<R>,
    pub radiance: V3<R>,
    /// Solid-angle density (1/sr), selection included; the selection probability of a delta
    /// light.
    pub pdf: R,
    pub delta: R::Mask,
    /// Where a shadow ray must end `target` (else at infinity).
    pub has_target: R::Mask,
    pub target: V3<R>,
}

/// A shadow test over [`Real`] values: where `ok`, the shadow ray and the contribution its
/// light adds when unoccluded.
pub(crate) struct RealShadowTest<R: Real> {
    pub ok: R::Mask,
    pub origin: V3<R>,
    pub direction: V3<R>,
    pub t_max: R,
    pub contribution: V3<R>,
}

/// Next-event estimation written once (the scalar path's `light_contribution` and the lane
/// kernels'): the shadow test of light sample `l` leaving `at`, where the light's local
/// direction has z `wi_z`, the BSDF's value toward it is `f` (1/sr) and its density of
/// sampling it `bsdf_pdf`, for a path of throughput `beta`. Weighted by the power heuristic,
/// by 1 for delta lights and with `light_only`; not `ok` where the light lies on different
/// sides of the geometric and the shading surface, on the shading horizon, or the BSDF gives
/// nothing (reflectors give nothing below the horizon; also where a NaN fails a test).
#[inline(always)]
pub(crate) fn shadow_test<R: Real>(at: Leaving<R>, l: &RealLightSample<R>, wi_z: R, (f, bsdf_pdf): (V3<R>, R), beta: V3<R>, light_only: bool) -> RealShadowTest<R> {
    let (p, p_error, ng) = at;
    let zero = R::splat(0.0);
    let ng_side = wi_z.lt(zero).select(-ng, ng);
    let cos_i = wi_z.abs();
    let ok = l.direction.dot(ng_side).gt(zero) & cos_i.gt(zero) & f.max_element().gt(zero);
    let origin = offset_origin(p, p_error, ng, l.direction);
    let w = if light_only { R::splat(1.0) } else { R::select(l.delta, R::splat(1.0), power_heuristic(l.pdf, bsdf_pdf)) };
    RealShadowTest {
        ok,
        origin,
        direction: l.has_target.select(l.target - origin, l.direction),
        t_max: R::select(l.has_target, R::splat(1.0 - SHADOW_EPSILON), R::splat(f32::MAX)),
        contribution: beta * f * l.radiance * (cos_i * w / l.pdf),
    }
}

/// A continuation over [`Real`] values: where `ok`, the next ray (from `origin` in the sampled
/// world direction), the throughput after the vertex and the sample's density.
pub(crate) struct RealContinuation<R: Real> {
    pub ok: R::Mask,
    pub origin: V3<R>,
    pub beta: V3<R>,
    pub pdf: R,
}

/// The continuation written once (the scalar path's `continuation` and the lane kernels'):
/// BSDF sample `sample` leaving `at` in world direction `wi_world`, for a path of throughput
/// `beta`; not `ok` where the sample failed, the direction leaves on another side of the
/// geometric surface than of the shading surface (below it for reflection, above it for
/// transmission) or the throughput is zero or not finite.
#[inline(always)]
pub(crate) fn continue_path<R: Real>(at: Leaving<R>, wi_world: V3<R>, sample: &RealSample<R>, beta: V3<R>) -> RealContinuation<R> {
    let (p, p_error, ng) = at;
    let zero = R::splat(0.0);
    let beta = beta * (sample.f * (sample.wi.z.abs() / sample.pdf));
    let ng_side = sample.wi.z.lt(zero).select(-ng, ng);
    let ok = sample.ok & !wi_world.dot(ng_side).le(zero) & beta.is_finite() & !beta.max_element().le(zero);
    RealContinuation {
        ok,
        origin: offset_origin(p, p_error, ng, wi_world),
        beta,
        pdf: sample.pdf,
    }
}

