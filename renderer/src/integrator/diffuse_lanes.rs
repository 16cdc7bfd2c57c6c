//! [`PathTracer::scatter`] for [`LANES`] vertices at once on Lambertian surfaces, lit by
//! any light ([`super::light_lanes`]: triangles', the environment's and point lights'
//! samples drawn by the kernel).
//!
//! The kernel evaluates the very formulas of the scalar path — the light's sample,
//! [`Lambert`]'s `eval_pdf` and `sample`, the power heuristic, [`offset_ray_origin`], the
//! frame conversions — in the same order, with masks where the scalar code returns early,
//! so each lane's result is bit for bit what `scatter` gives (tested below, and by the
//! batched render test against paths traced one by one). Compiled for AVX-512 or AVX2
//! where the CPU has them ([`super::scattered_lanes::scatter`]).
//!
//! [`PathTracer::scatter`]: super::PathTracer
//! [`Lambert`]: crate::bsdf::Lambert
//! [`offset_ray_origin`]: crate::accel::offset_ray_origin

use super::light_lanes::{next_event, LaneLight, LightLanes};
use super::scattered_lanes::{offset_ray_origin, LaneKernel, ScatteredLanes};
use super::hit_lanes::HitLanes;
use super::{Draws, Vertex};
use crate::lanes::{F32s, Mask, Vec2s, Vec3s, LANES};
use crate::render_scene::LaneHit;
use crate::sampling::sample_cosine_hemisphere_lanes;
use crate::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// Up to [`LANES`] diffuse vertices with their light samples, in structure-of-arrays form.
#[derive(Clone, Debug, Default)]
pub(crate) struct DiffuseLanes<'s> {
    len: usize,
    surface: HitLanes,
    albedo: Vec3s,
    beta: Vec3s,
    u: Vec2s,
    light: LightLanes<'s>,
}

impl<'s> DiffuseLanes<'s> {
    /// Appends a vertex with Lambertian albedo `albedo`, throughput `beta`, and its light
    /// sample ([`PathTracer::lane_light`](super::PathTracer::lane_light)).
    ///
    /// # Panics
    /// When all lanes are filled.
    #[inline]
    pub fn push(&mut self, vertex: &Vertex, albedo: Rgb, beta: Rgb, light: LaneLight<'s>) {
        let i = self.len;
        assert!(i < LANES, "diffuse lanes are full");
        self.surface.set_vertex(i, vertex);
        self.set(i, albedo, beta, vertex.u, light);
    }

    /// Appends the vertex a ray of direction `direction` reaches at barycentric coordinates
    /// `barycentric` of `hit`'s triangle, whose material is Lambertian with albedo `albedo`
    /// ([`SceneMaterials::plain_bsdf`], `double_sided` or not), for a path of throughput
    /// `beta`, with its random numbers `draws` and their light (a
    /// [`PathTracer::kernel_light`]): what [`PathTracer::begin`] and [`Self::push`] would
    /// give, the surface point found by the kernel ([`HitLanes`]).
    ///
    /// [`SceneMaterials::plain_bsdf`]: crate::material::SceneMaterials::plain_bsdf
    /// [`PathTracer::kernel_light`]: super::PathTracer::kernel_light
    /// [`PathTracer::begin`]: super::PathTracer
    ///
    /// # Panics
    /// When all lanes are filled.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn push_hit(&mut self, hit: &LaneHit, barycentric: Vec2, direction: Vec3, double_sided: bool, albedo: Rgb, beta: Rgb, draws: &Draws, light: LaneLight<'s>) {
        let i = self.len;
        assert!(i < LANES, "diffuse lanes are full");
        self.surface.set_hit(i, hit, barycentric, direction, double_sided);
        self.set(i, albedo, beta, draws.u, light);
    }

    #[inline(always)]
    fn set(&mut self, i: usize, albedo: Rgb, beta: Rgb, u: Vec2, light: LaneLight<'s>) {
        self.albedo.set(i, albedo);
        self.beta.set(i, beta);
        self.u.set(i, u);
        self.light.set(i, light);
        self.len += 1;
    }
}

impl LaneKernel for DiffuseLanes<'_> {
    fn len(&self) -> usize {
        self.len
    }

    fn clear(&mut self) {
        self.len = 0;
        self.surface.clear();
    }

    /// Scatters all lanes (the filled ones matter): next-event estimation weighted by the
    /// power heuristic (by 1 for punctual lights and with `light_only`), and a
    /// cosine-weighted continuation.
    #[inline(always)]
    fn scatter_lanes(&self, light_only: bool, out: &mut ScatteredLanes) {
        let zero = F32s::splat(0.0);
        let (surface, scatters) = self.surface.surface_points();
        let (p, p_error, ng, beta) = (surface.p, surface.p_error, surface.ng, self.beta);
        out.p = p;

        // Next-event estimation (PathTracer::light_term with Lambert::eval_pdf).
        let light = self.light.samples(p);
        let wi_z = light.direction.dot(surface.n);
        let f = self.albedo * FRAC_1_PI;
        let bsdf_pdf = wi_z.max(zero) * FRAC_1_PI;
        next_event(&light, p, p_error, ng, wi_z, f, bsdf_pdf, beta, light_only, out);
        out.shadow_ok = (Mask(out.shadow_ok) & scatters).0;

        // BSDF sampling (Lambert::sample: cosine-weighted, concentric disk).
        let wi = sample_cosine_hemisphere_lanes(self.u);
        let dz = wi.z;
        let pdf = dz.max(zero) * FRAC_1_PI;
        // continuation(): world direction, throughput, offset origin.
        let wi_world = surface.to_world(wi);
        let next_beta = beta * (f * (dz / pdf));
        let next_ok = scatters
            & !dz.le(zero)
            & !wi_world.dot(ng).le(zero)
            & next_beta.is_finite()
            & !next_beta.max_element().le(zero);
        out.next_ok = next_ok.0;
        out.next_origin = offset_ray_origin(p, p_error, ng, wi_world);
        out.next_direction = wi_world;
        out.next_beta = next_beta;
        out.next_pdf = pdf;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Ray;
    use crate::bsdf::Bsdf;
    use crate::integrator::{PathTracer, Strategy};
    use crate::render_scene::RenderScene;
    use crate::sampler::Sampler;
    use crate::sampling::sample_uniform_sphere;
    use crate::scene::{EnvironmentSource, PunctualLight};

    /// Every lane gives what the scalar `scatter` gives for its vertex, bit for bit, for
    /// full and partial groups, every strategy, lights behind the surface and zero
    /// throughputs: in the Cornell box (triangle lights) and on the material-preview's
    /// diffuse ground (a point light and an environment map or, in place of the map, a
    /// constant environment; or, in place of the point light, a spot light, whose samples
    /// are pushed drawn).
    #[test]
    fn lanes_equal_scalar_scatter_bit_for_bit() {
        let load = crate::testing::data::shipped_scene;
        let preview = load("material-preview");
        let mut constant = preview.clone();
        let spec = constant.environment.as_mut().expect("the preview has an environment");
        spec.source = EnvironmentSource::Constant(Rgb::new(0.8, 1.0, 1.3));
        let mut spot = preview.clone();
        for light in &mut spot.lights {
            if let PunctualLight::Point { position, intensity } = *light {
                *light = PunctualLight::Spot {
                    position,
                    direction: -position.normalize(),
                    intensity,
                    cos_inner: 0.9,
                    cos_outer: 0.2,
                };
            }
        }
        for (description, spot_light) in [(load("cornell-box"), false), (preview, false), (constant, false), (spot, true)] {
            lanes_equal_scalar_scatter_in(&RenderScene::new(description).expect("scene"), spot_light);
        }
    }

    fn lanes_equal_scalar_scatter_in(scene: &RenderScene, spot_light: bool) {
        let mut rng = Sampler::new(3, 1, 4);
        for strategy in [Strategy::Mis, Strategy::LightOnly, Strategy::BsdfOnly] {
            let tracer = PathTracer {
                strategy,
                ..PathTracer::default()
            };
            let mut cases = Vec::new();
            while cases.len() < 16 * 12 + 5 {
                let origin = scene.bounds_centre + (rng.next_2d().extend(rng.next_1d()) - 0.5) * scene.bounds_radius;
                let ray = Ray::new(origin, sample_uniform_sphere(rng.next_2d()));
                let mut state = tracer.start(ray, rng.clone()).expect("depth allows a segment");
                rng.next_1d();
                // Every eighth throughput is zero: the continuation must end there.
                state.beta = if cases.len() % 8 == 0 { Rgb::ZERO } else { rng.next_2d().extend(rng.next_1d()) * 2.0 };
                let hit = scene.intersect(&ray);
                let Some(vertex) = tracer.begin(scene, &mut state, hit) else { continue };
                if let Bsdf::Lambert(b) = vertex.bsdf {
                    cases.push((vertex, b.albedo, state.beta));
                }
            }
            let (mut lanes, mut out) = (DiffuseLanes::default(), ScatteredLanes::default());
            let (mut shadows, mut ended, mut drawn_by_kernel, mut points, mut pushed_drawn) = (0, 0, 0, 0, 0);
            for group in cases.chunks(LANES) {
                lanes.clear();
                for (vertex, albedo, beta) in group {
                    let light = tracer.lane_light(scene, vertex);
                    drawn_by_kernel += matches!(light, LaneLight::Triangle { .. } | LaneLight::Environment { .. }) as usize;
                    points += matches!(light, LaneLight::Point { .. }) as usize;
                    pushed_drawn += matches!(light, LaneLight::Sampled(_)) as usize;
                    lanes.push(vertex, *albedo, *beta, light);
                }
                crate::integrator::scattered_lanes::scatter(&lanes, strategy == Strategy::LightOnly, &mut out);
                for (lane, (vertex, _, beta)) in group.iter().enumerate() {
                    let expected = tracer.scatter(scene, vertex, *beta);
                    assert_eq!(format!("{:?}", out.get(lane)), format!("{expected:?}"), "{strategy:?}, lane {lane}");
                    shadows += expected.shadow.is_some() as usize;
                    ended += expected.next.is_none() as usize;
                }
            }
            if strategy == Strategy::BsdfOnly {
                assert_eq!(drawn_by_kernel, 0, "BSDF sampling alone samples no area light or environment");
            } else {
                assert!(shadows > 0 && shadows < cases.len(), "{strategy:?}: both lit and unlit lanes: {shadows}");
                assert!(drawn_by_kernel > cases.len() / 4, "{strategy:?}: {drawn_by_kernel} samples drawn in lanes");
            }
            assert!(ended >= cases.len() / 8, "{strategy:?}: zero throughputs end: {ended}");
            // The preview's key light is a point light, illuminating under every strategy.
            let has_point_light = (0..scene.lights.len() as u32).any(|l| scene.lights.point(l).is_some());
            assert_eq!(points > 0, has_point_light, "{strategy:?}: {points} lanes lit by a point light");
            assert_eq!(pushed_drawn > 0, spot_light, "{strategy:?}: {pushed_drawn} spot-light samples pushed drawn");
        }
    }
}
