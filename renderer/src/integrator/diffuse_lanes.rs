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
use super::{Draws, Vertex};
use crate::lanes::{F32s, Mask, Vec2s, Vec3s, LANES};
use crate::render_scene::{flat_surface_points_lanes, FlatHit};
use crate::sampling::sample_cosine_hemisphere_lanes;
use crate::Rgb;
use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// Up to [`LANES`] diffuse vertices with their light samples, in structure-of-arrays form.
#[derive(Clone, Debug, Default)]
pub(crate) struct DiffuseLanes<'s> {
    len: usize,
    p: Vec3s,
    p_error: Vec3s,
    /// Geometric normal on the side of the arriving ray.
    ng: Vec3s,
    /// Shading frame.
    s: Vec3s,
    t: Vec3s,
    n: Vec3s,
    albedo: Vec3s,
    beta: Vec3s,
    u: Vec2s,
    light: LightLanes<'s>,
    /// Lanes pushed as their hit ([`DiffuseLanes::push_hit`]), whose surface point (the
    /// fields above it) the kernel finds from the hit's triangle, barycentric coordinates
    /// and ray direction; whether any lane is; and whether their material is double-sided.
    from_hit: [bool; LANES],
    any_from_hit: bool,
    corners: [Vec3s; 3],
    hit_ng: Vec3s,
    hit_normal: Vec3s,
    barycentric: Vec2s,
    direction: Vec3s,
    double_sided: [bool; LANES],
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
        let sp = &vertex.sp;
        self.p.set(i, sp.p);
        self.p_error.set(i, sp.p_error);
        self.ng.set(i, sp.ng_facing);
        self.s.set(i, sp.frame.s);
        self.t.set(i, sp.frame.t);
        self.n.set(i, sp.frame.n);
        self.albedo.set(i, albedo);
        self.beta.set(i, beta);
        self.u.set(i, vertex.u);
        self.light.set(i, light);
        self.from_hit[i] = false;
        self.len += 1;
    }

    /// Appends the vertex a ray of direction `direction` reaches at barycentric coordinates
    /// `barycentric` of `hit`'s triangle, on a [`SceneMaterials::plain_lambert`] material
    /// (albedo `albedo`, `double_sided`), for a path of throughput `beta`, with its random
    /// numbers `draws` and their light (a [`PathTracer::kernel_light`]): what
    /// [`PathTracer::begin`] and [`Self::push`] would give, the surface point found by the
    /// kernel (the vertex ends where `begin` ends the path: at the back of a single-sided
    /// material, or with the ray arriving below the shading hemisphere).
    ///
    /// [`SceneMaterials::plain_lambert`]: crate::material::SceneMaterials::plain_lambert
    /// [`PathTracer::kernel_light`]: super::PathTracer::kernel_light
    /// [`PathTracer::begin`]: super::PathTracer
    ///
    /// # Panics
    /// When all lanes are filled.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn push_hit(&mut self, hit: &FlatHit, barycentric: Vec2, direction: Vec3, albedo: Rgb, double_sided: bool, beta: Rgb, draws: &Draws, light: LaneLight<'s>) {
        let i = self.len;
        assert!(i < LANES, "diffuse lanes are full");
        for (corners, &corner) in self.corners.iter_mut().zip(&hit.corners) {
            corners.set(i, corner);
        }
        self.hit_ng.set(i, hit.ng);
        self.hit_normal.set(i, hit.normal);
        self.barycentric.set(i, barycentric);
        self.direction.set(i, direction);
        self.double_sided[i] = double_sided;
        self.albedo.set(i, albedo);
        self.beta.set(i, beta);
        self.u.set(i, draws.u);
        self.light.set(i, light);
        self.from_hit[i] = true;
        self.any_from_hit = true;
        self.len += 1;
    }

    /// The lanes' surface points (position, its error bound, geometric normal on the side
    /// of the arriving ray, shading frame) and the lanes whose vertex scatters: those
    /// pushed with it, and those pushed as their hit found here.
    #[inline(always)]
    fn surface_points(&self) -> ([Vec3s; 6], Mask) {
        let pushed = [self.p, self.p_error, self.ng, self.s, self.t, self.n];
        if !self.any_from_hit {
            return (pushed, Mask([true; LANES]));
        }
        let sp = flat_surface_points_lanes(self.corners, self.hit_ng, self.hit_normal, self.barycentric, self.direction);
        // `begin`: no BSDF at the back of a single-sided material; wo = to_local(−direction)
        // must lie above the shading hemisphere.
        let wo_z = (-self.direction).dot(sp.n);
        let scatters = (sp.front_face | Mask(self.double_sided)) & !wo_z.le(F32s::splat(0.0));
        let from_hit = Mask(self.from_hit);
        let found = [sp.p, sp.p_error, sp.ng_facing, sp.s, sp.t, sp.n];
        (std::array::from_fn(|k| from_hit.select3(found[k], pushed[k])), !from_hit | scatters)
    }
}

impl LaneKernel for DiffuseLanes<'_> {
    fn len(&self) -> usize {
        self.len
    }


    fn clear(&mut self) {
        self.len = 0;
        self.any_from_hit = false;
    }

    /// Scatters all lanes (the filled ones matter): next-event estimation weighted by the
    /// power heuristic (by 1 for punctual lights and with `light_only`), and a
    /// cosine-weighted continuation.
    #[inline(always)]
    fn scatter_lanes(&self, light_only: bool, out: &mut ScatteredLanes) {
        let zero = F32s::splat(0.0);
        let ([p, p_error, ng, s, t, n], scatters) = self.surface_points();
        let beta = self.beta;
        out.p = p;

        // Next-event estimation (PathTracer::light_term with Lambert::eval_pdf).
        let light = self.light.samples(p);
        let wi_z = light.direction.dot(n);
        let f = self.albedo * FRAC_1_PI;
        let bsdf_pdf = wi_z.max(zero) * FRAC_1_PI;
        next_event(&light, p, p_error, ng, wi_z, f, bsdf_pdf, beta, light_only, out);
        out.shadow_ok = (Mask(out.shadow_ok) & scatters).0;

        // BSDF sampling (Lambert::sample: cosine-weighted, concentric disk).
        let Vec3s { x: dx, y: dy, z: dz } = sample_cosine_hemisphere_lanes(self.u);
        let pdf = dz.max(zero) * FRAC_1_PI;
        // continuation(): world direction, throughput, offset origin.
        let wi_world = s * dx + t * dy + n * dz;
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
    use crate::scene::{EnvironmentSource, PunctualLight, SceneDescription};

    /// Every lane gives what the scalar `scatter` gives for its vertex, bit for bit, for
    /// full and partial groups, every strategy, lights behind the surface and zero
    /// throughputs: in the Cornell box (triangle lights) and on the material-preview's
    /// diffuse ground (a point light and an environment map or, in place of the map, a
    /// constant environment; or, in place of the point light, a spot light, whose samples
    /// are pushed drawn).
    #[test]
    fn lanes_equal_scalar_scatter_bit_for_bit() {
        let load = |name: &str| {
            let path = format!("{}/../scenes/{name}/scene.gltf", env!("CARGO_MANIFEST_DIR"));
            SceneDescription::load(path.as_ref()).expect("shipped scene")
        };
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

    /// Vertices pushed as their hit ([`DiffuseLanes::push_hit`]), alone or mixed in a group
    /// with vertices pushed begun, give what the scalar `begin` and `scatter` give, bit for
    /// bit (the position included), and end where `begin` ends the path: in the Cornell box
    /// with its single-sided walls seen from both sides and made double-sided, and on the
    /// preview's ground, under every strategy.
    #[test]
    fn hits_pushed_equal_scalar_begin_and_scatter() {
        let load = |name: &str| {
            let path = format!("{}/../scenes/{name}/scene.gltf", env!("CARGO_MANIFEST_DIR"));
            SceneDescription::load(path.as_ref()).expect("shipped scene")
        };
        let cornell = load("cornell-box");
        assert!(cornell.materials.iter().any(|m| !m.double_sided), "the box has single-sided walls");
        let mut double_sided = cornell.clone();
        for m in &mut double_sided.materials {
            m.double_sided = true;
        }
        for (description, single_sided) in [(cornell, true), (double_sided, false), (load("material-preview"), true)] {
            hits_pushed_equal_scalar_in(&RenderScene::new(description).expect("scene"), single_sided);
        }
    }

    fn hits_pushed_equal_scalar_in(scene: &RenderScene, single_sided: bool) {
        let mut rng = Sampler::new(9, 2, 6);
        for strategy in [Strategy::Mis, Strategy::LightOnly, Strategy::BsdfOnly] {
            let tracer = PathTracer {
                strategy,
                ..PathTracer::default()
            };
            // (path state before the vertex, hit, whether it is pushed as its hit)
            let mut cases = Vec::new();
            let mut tries = 0;
            while cases.len() < 16 * 10 + 9 {
                tries += 1;
                assert!(tries < 100_000, "{strategy:?}: too few plain diffuse hits");
                let origin = scene.bounds_centre + (rng.next_2d().extend(rng.next_1d()) - 0.5) * scene.bounds_radius;
                let ray = Ray::new(origin, sample_uniform_sphere(rng.next_2d()));
                let mut state = tracer.start(ray, rng.clone()).expect("depth allows a segment");
                rng.next_1d();
                state.beta = if cases.len() % 8 == 0 { Rgb::ZERO } else { rng.next_2d().extend(rng.next_1d()) * 2.0 };
                let Some(hit) = scene.intersect(&ray) else { continue };
                let mut drawn = state.clone();
                let draws = tracer.draw(scene, &mut drawn);
                if tracer.plain_diffuse(scene, &drawn, &hit, &draws).is_some() {
                    // Every third one pushed begun (where it scatters), the rest as hits.
                    cases.push((state, hit, cases.len() % 3 != 0));
                }
            }
            let (mut lanes, mut out) = (DiffuseLanes::default(), ScatteredLanes::default());
            let (mut from_hits, mut ended, mut shadows) = (0, 0, 0);
            for group in cases.chunks(LANES) {
                lanes.clear();
                let mut expected = Vec::new();
                for (state, hit, as_hit) in group {
                    let mut begun = state.clone();
                    let vertex = tracer.begin(scene, &mut begun, Some(*hit));
                    let scattered = vertex.map(|v| (tracer.scatter(scene, &v, state.beta), v.sp.p));
                    let mut drawn = state.clone();
                    let draws = tracer.draw(scene, &mut drawn);
                    assert_eq!(format!("{:?}", drawn.sampler), format!("{:?}", begun.sampler), "the same numbers drawn");
                    let (flat, albedo, double_sided, light) = tracer.plain_diffuse(scene, &drawn, hit, &draws).expect("plain");
                    match (vertex, as_hit) {
                        (Some(v), false) => lanes.push(&v, albedo, state.beta, tracer.lane_light(scene, &v)),
                        _ => {
                            lanes.push_hit(&flat, hit.barycentric, state.ray.direction, albedo, double_sided, state.beta, &draws, light);
                            from_hits += 1;
                        }
                    }
                    ended += scattered.is_none() as usize;
                    shadows += scattered.is_some_and(|(s, _)| s.shadow.is_some()) as usize;
                    expected.push(scattered);
                }
                crate::integrator::scattered_lanes::scatter(&lanes, strategy == Strategy::LightOnly, &mut out);
                for (lane, expected) in expected.iter().enumerate() {
                    let got = out.get(lane);
                    match expected {
                        Some((scattered, p)) => {
                            assert_eq!(format!("{got:?}"), format!("{scattered:?}"), "{strategy:?}, lane {lane}");
                            assert_eq!(out.p.get(lane).to_array().map(f32::to_bits), p.to_array().map(f32::to_bits));
                        }
                        None => assert!(got.shadow.is_none() && got.next.is_none(), "{strategy:?}, lane {lane}: the path ends"),
                    }
                }
            }
            assert!(from_hits > cases.len() / 2, "{strategy:?}: {from_hits} pushed as hits");
            // Single-sided surfaces seen from behind end paths; double-sided ones do not.
            assert!(ended < cases.len() && (ended > 0) == single_sided, "{strategy:?}: {ended} ended");
            if strategy != Strategy::BsdfOnly {
                assert!(shadows > 0, "{strategy:?}: lit lanes");
            }
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
