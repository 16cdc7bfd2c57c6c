//! [`PathTracer::scatter`] for [`LANES`] vertices at once on the BSDFs written over
//! [`Real`](crate::lanes::Real) values ([`RealBxdf`]: Lambertian and metallic-roughness
//! surfaces, glass), lit by any light ([`super::light_lanes`]: triangles', the environment's and
//! point lights' samples drawn by the kernel).
//!
//! The kernel does all of `scatter` for all lanes together — the light samples, the BSDF's
//! value and density toward the light, the multiple importance weight, the shadow ray, the
//! BSDF sample with its value and density, and the continuation — with the BSDF's own
//! formulas instantiated for lanes, so each lane's result is bit for bit what `scatter`
//! gives (tested below and by the batched render test). Compiled for AVX-512 or AVX2 where
//! the CPU has them ([`super::scattered_lanes::scatter`]).
//!
//! [`PathTracer::scatter`]: super::PathTracer

use super::hit_lanes::{HitAt, HitLanes};
use super::light_lanes::{next_event, LaneLight, LightLanes};
use super::scattered_lanes::{LaneKernel, ScatteredLanes};
use super::{continue_path, Draws, Vertex};
use crate::bsdf::dielectric::DielectricLobes;
use crate::bsdf::lambert::LambertLobe;
use crate::bsdf::metallic_roughness::MetallicRoughnessLobes;
use crate::bsdf::{Dielectric, RealBxdf};
use crate::material::SceneMaterials;
use crate::lanes::{F32s, Mask, Vec2s, Vec3s, LANES};
use crate::Rgb;
use glam::Vec2;
use std::fmt::Debug;

/// A BSDF the lane kernel scatters: how one shading point's parameters fill a lane, and its
/// formulas over [`F32s`] for the side of the surface each lane's path arrives on.
pub(crate) trait LaneBxdf: Default + Clone + Debug {
    /// One shading point's parameters (the formulas over `f32`).
    type One;

    /// The formulas of the lanes' BSDFs seen from the side their paths arrive on.
    type Faced: RealBxdf<F32s>;

    /// Whether the BSDF transmits ([`Bxdf::transmits`](crate::bsdf::Bxdf::transmits)):
    /// paths it sends below the surface may enter or leave a volume
    /// ([`Self::entered_volume`]).
    const TRANSMITS: bool = false;

    /// Sets lane `i` to `one`.
    fn set_lane(&mut self, i: usize, one: &Self::One);

    /// The lanes' formulas where the paths arrive at the front of the surface (`front_face`;
    /// [`HitLanes::surface_points`]) or its back.
    fn facing(&self, front_face: Mask) -> Self::Faced;

    /// Whether every lane's BSDF has delta lobes alone, so that no light sample can
    /// contribute (next-event estimation is skipped, as `scatter` skips it).
    #[inline(always)]
    fn all_delta(&self) -> bool {
        false
    }

    /// The absorption coefficient of the volume a path transmitted at lane `i`, arriving at
    /// the front of the surface or not (`front_face`), enters
    /// ([`Continuation::sigma_a`](super::Continuation::sigma_a)); read only where
    /// [`Self::TRANSMITS`].
    #[inline(always)]
    fn entered_volume(&self, _i: usize, _front_face: bool) -> Option<Rgb> {
        None
    }
}

/// The same on both sides of the surface (single-sided materials end paths at their back
/// before they scatter).
macro_rules! one_sided_lane_bxdf {
    ($lobes:ident) => {
        impl LaneBxdf for $lobes<F32s> {
            type One = $lobes<f32>;
            type Faced = $lobes<F32s>;

            #[inline(always)]
            fn set_lane(&mut self, i: usize, one: &$lobes<f32>) {
                self.set(i, one);
            }

            #[inline(always)]
            fn facing(&self, _front_face: Mask) -> $lobes<F32s> {
                self.clone()
            }
        }
    };
}

one_sided_lane_bxdf!(LambertLobe);
one_sided_lane_bxdf!(MetallicRoughnessLobes);

/// One glass vertex: its interface seen from the front and from the back of the surface,
/// and the absorption of the volume a path transmitted through either enters (`None` for
/// thin-walled glass). A vertex begun by the scalar code has both the same (its side).
#[derive(Clone, Copy, Debug)]
pub(crate) struct GlassFaces {
    pub front: DielectricLobes<f32>,
    pub back: DielectricLobes<f32>,
    pub enters_front: Option<Rgb>,
    pub enters_back: Option<Rgb>,
}

impl GlassFaces {
    /// The faces of a glass vertex begun on `glass`, a path transmitted there entering
    /// `enters` ([`SceneMaterials::entered_volume`] of its side).
    #[inline(always)]
    pub fn begun(glass: &Dielectric, enters: Option<Rgb>) -> Self {
        let lobes = glass.lobes();
        GlassFaces { front: lobes, back: lobes, enters_front: enters, enters_back: enters }
    }

    /// The faces of glass `material` begun in lanes ([`SceneMaterials::lane_bsdf`]), whose glass
    /// seen from the front is `front`: its back from [`SceneMaterials::glass_back`], the
    /// media entered through either from [`SceneMaterials::entered_volume`].
    #[inline(always)]
    pub fn plain(materials: &SceneMaterials, material: u32, front: &Dielectric) -> Self {
        let back = materials.glass_back(material).expect("glass begun in lanes has a back");
        GlassFaces {
            front: front.lobes(),
            back: back.lobes(),
            enters_front: materials.entered_volume(material, true),
            enters_back: materials.entered_volume(material, false),
        }
    }
}

/// Glass in lanes: per lane, the interfaces and volumes of [`GlassFaces`].
#[derive(Clone, Debug, Default)]
pub(crate) struct GlassLobes {
    front: DielectricLobes<F32s>,
    back: DielectricLobes<F32s>,
    enters_front: [Option<Rgb>; LANES],
    enters_back: [Option<Rgb>; LANES],
}

impl LaneBxdf for GlassLobes {
    type One = GlassFaces;
    type Faced = DielectricLobes<F32s>;

    const TRANSMITS: bool = true;

    #[inline(always)]
    fn set_lane(&mut self, i: usize, one: &GlassFaces) {
        self.front.set(i, &one.front);
        self.back.set(i, &one.back);
        self.enters_front[i] = one.enters_front;
        self.enters_back[i] = one.enters_back;
    }

    #[inline(always)]
    fn facing(&self, front_face: Mask) -> DielectricLobes<F32s> {
        DielectricLobes::select(front_face, &self.front, &self.back)
    }

    #[inline(always)]
    fn all_delta(&self) -> bool {
        // Both faces are smooth or neither.
        self.front.all_smooth()
    }

    #[inline(always)]
    fn entered_volume(&self, i: usize, front_face: bool) -> Option<Rgb> {
        if front_face {
            self.enters_front[i]
        } else {
            self.enters_back[i]
        }
    }
}

/// Lambertian vertices in lanes.
pub(crate) type DiffuseLanes<'s> = BxdfLanes<'s, LambertLobe<F32s>>;

/// Metallic-roughness vertices in lanes.
pub(crate) type GlossyLanes<'s> = BxdfLanes<'s, MetallicRoughnessLobes<F32s>>;

/// Vertices on glass alone (a transmitting material whose glass weight is 1), smooth or
/// rough, bulk or thin-walled, in lanes.
pub(crate) type GlassLanes<'s> = BxdfLanes<'s, GlassLobes>;

/// Up to [`LANES`] vertices on BSDF `B` with their light samples, in structure-of-arrays
/// form.
#[derive(Clone, Debug, Default)]
pub(crate) struct BxdfLanes<'s, B> {
    len: usize,
    bsdf: B,
    surface: HitLanes,
    beta: Vec3s,
    u: Vec2s,
    uc: F32s,
    light: LightLanes<'s>,
}

impl<'s, B: LaneBxdf> BxdfLanes<'s, B> {
    /// Appends a vertex whose BSDF is `bsdf`, with throughput `beta` and its light sample
    /// ([`PathTracer::lane_light`](super::PathTracer::lane_light)).
    ///
    /// # Panics
    /// When all lanes are filled.
    #[inline]
    pub fn push(&mut self, vertex: &Vertex, bsdf: &B::One, beta: Rgb, light: LaneLight<'s>) {
        let i = self.len;
        assert!(i < LANES, "lanes are full");
        self.surface.set_vertex(i, vertex);
        self.set(i, bsdf, beta, vertex.u, vertex.uc, light);
    }

    /// Appends the vertex `at`'s ray reaches, whose material's BSDF there is `bsdf`
    /// ([`SceneMaterials::lane_bsdf`]), for a path of throughput `beta`, with its random
    /// numbers `draws` and their light (a [`PathTracer::kernel_light`]): what
    /// [`PathTracer::begin`] and [`Self::push`] would give, the surface point found by the
    /// kernel ([`HitLanes`]).
    ///
    /// [`SceneMaterials::lane_bsdf`]: crate::material::SceneMaterials::lane_bsdf
    /// [`PathTracer::kernel_light`]: super::PathTracer::kernel_light
    /// [`PathTracer::begin`]: super::PathTracer
    ///
    /// # Panics
    /// When all lanes are filled.
    #[inline]
    pub fn push_hit(&mut self, at: &HitAt, bsdf: &B::One, beta: Rgb, draws: &Draws, light: LaneLight<'s>) {
        let i = self.len;
        assert!(i < LANES, "lanes are full");
        self.surface.set_hit(i, at);
        self.set(i, bsdf, beta, draws.u, draws.uc, light);
    }

    #[inline(always)]
    fn set(&mut self, i: usize, bsdf: &B::One, beta: Rgb, u: Vec2, uc: f32, light: LaneLight<'s>) {
        self.bsdf.set_lane(i, bsdf);
        self.beta.set(i, beta);
        self.u.set(i, u);
        self.uc.0[i] = uc;
        self.light.set(i, light);
        self.len += 1;
    }
}

impl<B: LaneBxdf> LaneKernel for BxdfLanes<'_, B> {
    fn len(&self) -> usize {
        self.len
    }

    fn clear(&mut self) {
        self.len = 0;
        self.surface.clear();
    }

    /// Scatters all lanes (the filled ones matter): next-event estimation weighted by the
    /// power heuristic (by 1 for punctual lights and with `light_only`), and a continuation
    /// drawn from the BSDF.
    #[inline(always)]
    fn scatter_lanes(&self, light_only: bool, out: &mut ScatteredLanes) {
        let (surface, scatters, front_face) = self.surface.surface_points();
        let (p, p_error, ng, wo, beta) = (surface.p, surface.p_error, surface.ng, surface.wo, self.beta);
        out.p = p;
        let bsdf = self.bsdf.facing(front_face);

        // Next-event estimation (PathTracer::light_term and light_contribution), where some
        // lane's BSDF has a lobe a light sample can reach.
        let at_wo = bsdf.at_wo(wo);
        if self.bsdf.all_delta() {
            out.shadow_ok = [false; LANES];
        } else {
            let light = self.light.samples(p);
            let wi = surface.to_local(light.sample.direction);
            let (f, bsdf_pdf) = bsdf.eval_pdf(at_wo, wo, wi);
            next_event(&light, &surface, wi.z, (f, bsdf_pdf), beta, light_only, out);
            out.shadow_ok = (Mask(out.shadow_ok) & scatters).0;
        }

        // BSDF sampling and the continuation.
        let sample = bsdf.sample(at_wo, wo, self.u, self.uc);
        let wi_world = surface.to_world(sample.wi);
        let next = continue_path((p, p_error, ng), wi_world, &sample, beta);
        out.next_ok = (scatters & next.ok).0;
        out.next_origin = next.origin;
        out.next_direction = wi_world;
        out.next_beta = next.beta;
        out.next_pdf = next.pdf;
        out.next_delta = sample.delta.0;
        if B::TRANSMITS {
            for i in 0..LANES {
                out.next_sigma_a[i] = if sample.wi.z.0[i] < 0.0 { self.bsdf.entered_volume(i, front_face.0[i]) } else { None };
            }
        }
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
    /// constant environment; or, in place of the point light, a spot light), and in the
    /// feature showcase made Lambertian (a directional light, pushed drawn, a point light and
    /// a triangle light with an emissive texture), and again with a clear coat over its
    /// emissive sign whose weight varies over the sign (the emissive texture's red).
    #[test]
    fn diffuse_lanes_equal_scalar_scatter_bit_for_bit() {
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
        let mut showcase = load("feature-showcase");
        for m in showcase.materials.iter_mut().filter(|m| !m.transmits()) {
            m.model = crate::scene::SurfaceModel::Lambert;
        }
        let mut coated = showcase.clone();
        let sign = coated.materials.iter_mut().find(|m| m.emissive_texture.is_some()).expect("the showcase has an emissive sign");
        sign.clearcoat = Some(crate::scene::Clearcoat { factor: 1.0, texture: sign.emissive_texture, roughness: 0.1, roughness_texture: None, normal_texture: None });
        for (description, drawn_light) in [(load("cornell-box"), false), (preview, false), (constant, false), (spot, false), (showcase, true), (coated, true)] {
            diffuse_lanes_equal_scalar_scatter_in(&RenderScene::new(description).expect("scene"), drawn_light);
        }
    }

    /// `drawn_light`: whether the scene has a directional light, whose samples are pushed
    /// drawn.
    fn diffuse_lanes_equal_scalar_scatter_in(scene: &RenderScene, drawn_light: bool) {
        let mut rng = Sampler::new(3, 1, 4);
        for strategy in [Strategy::Mis, Strategy::LightOnly, Strategy::BsdfOnly] {
            let tracer = PathTracer {
                strategy,
                ..PathTracer::default()
            };
            let cases = vertices(scene, &tracer, &mut rng, 16 * 12 + 5, |bsdf| match *bsdf {
                Bsdf::Lambert(b) => Some(b),
                _ => None,
            });
            let (mut lanes, mut out) = (DiffuseLanes::default(), ScatteredLanes::default());
            let (mut shadows, mut ended, mut drawn_by_kernel, mut points, mut spots, mut pushed_drawn, mut textured, mut coated) = (0, 0, 0, 0, 0, 0, 0, 0);
            for group in cases.chunks(LANES) {
                lanes.clear();
                for (vertex, bsdf, beta) in group {
                    let light = tracer.lane_light(scene, vertex);
                    drawn_by_kernel += matches!(light, LaneLight::Triangle { .. } | LaneLight::Environment { .. }) as usize;
                    points += matches!(light, LaneLight::Point { .. }) as usize;
                    spots += matches!(light, LaneLight::Spot { .. }) as usize;
                    pushed_drawn += matches!(light, LaneLight::Sampled(_)) as usize;
                    textured += matches!(light, LaneLight::Triangle { light, .. } if light.texture.is_some()) as usize;
                    coated += matches!(light, LaneLight::Triangle { light, textures, u, .. } if light.at_sample(u, textures).1 > 0.0) as usize;
                    lanes.push(vertex, &bsdf.lobe(), *beta, light);
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
            // The preview's key light is a point light (or a spot), illuminating under every
            // strategy.
            let has = |kind: fn(&PunctualLight) -> bool| (0..scene.lights.len() as u32).any(|l| scene.lights.punctual(l).is_some_and(kind));
            assert_eq!(points > 0, has(|l| matches!(l, PunctualLight::Point { .. })), "{strategy:?}: {points} lanes lit by a point light");
            assert_eq!(spots > 0, has(|l| matches!(l, PunctualLight::Spot { .. })), "{strategy:?}: {spots} lanes lit by a spot light");
            assert_eq!(pushed_drawn > 0, drawn_light, "{strategy:?}: {pushed_drawn} directional samples pushed drawn");
            let textured_lights = (0..scene.lights.len() as u32).any(|l| scene.lights.triangle(l).is_some_and(|t| t.texture.is_some()));
            assert_eq!(textured > 0, textured_lights && strategy != Strategy::BsdfOnly, "{strategy:?}: {textured} lanes sample a textured triangle");
            let coated_lights = (0..scene.lights.len() as u32).any(|l| scene.lights.triangle(l).is_some_and(|t| t.coat.is_some()));
            assert_eq!(coated > 0, coated_lights && strategy != Strategy::BsdfOnly, "{strategy:?}: {coated} lanes sample a coated triangle");
        }
    }

    /// Every lane gives what the scalar `scatter` gives for its vertex, bit for bit, on the
    /// material-preview's metallic-roughness surfaces lit by its point light and by its
    /// environment map or, in place of the map, a constant environment (the environment's
    /// samples drawn by the kernel), for full and partial groups, every strategy and zero
    /// throughputs.
    #[test]
    fn glossy_lanes_equal_scalar_scatter_bit_for_bit() {
        let description = crate::testing::data::shipped_scene("material-preview");
        let mut constant = description.clone();
        let spec = constant.environment.as_mut().expect("the preview has an environment");
        spec.source = EnvironmentSource::Constant(Rgb::new(0.8, 1.0, 1.3));
        for description in [description, constant] {
            glossy_lanes_equal_scalar_scatter_in(&RenderScene::new(description).expect("scene"));
        }
    }

    fn glossy_lanes_equal_scalar_scatter_in(scene: &RenderScene) {
        let mut rng = Sampler::new(5, 2, 7);
        for strategy in [Strategy::Mis, Strategy::LightOnly, Strategy::BsdfOnly] {
            let tracer = PathTracer {
                strategy,
                ..PathTracer::default()
            };
            let cases = vertices(scene, &tracer, &mut rng, 16 * 24 + 7, |bsdf| match *bsdf {
                Bsdf::MetallicRoughness(m) => Some(m),
                _ => None,
            });
            let (mut lanes, mut out) = (GlossyLanes::default(), ScatteredLanes::default());
            let (mut shadows, mut continued, mut delta, mut environment) = (0, 0, 0, 0);
            for group in cases.chunks(LANES) {
                lanes.clear();
                for (vertex, bsdf, beta) in group {
                    let light = tracer.lane_light(scene, vertex);
                    delta += matches!(light, LaneLight::Point { .. }) as usize;
                    environment += matches!(light, LaneLight::Environment { .. }) as usize;
                    lanes.push(vertex, &bsdf.lobes(), *beta, light);
                }
                crate::integrator::scattered_lanes::scatter(&lanes, strategy == Strategy::LightOnly, &mut out);
                for (lane, (vertex, _, beta)) in group.iter().enumerate() {
                    let expected = tracer.scatter(scene, vertex, *beta);
                    assert_eq!(format!("{:?}", out.get(lane)), format!("{expected:?}"), "{strategy:?}, lane {lane}");
                    shadows += expected.shadow.is_some() as usize;
                    continued += expected.next.is_some() as usize;
                }
            }
            assert!(shadows > 0 && shadows < cases.len(), "{strategy:?}: lit and unlit lanes: {shadows}");
            assert!(delta > 0, "{strategy:?}: the point light illuminates lanes");
            let kernel_draws = strategy != Strategy::BsdfOnly;
            assert_eq!(environment > 0, kernel_draws, "{strategy:?}: {environment} environment samples drawn in lanes");
            assert!(continued > cases.len() / 2 && continued < cases.len(), "{strategy:?}: {continued} continue");
        }
    }

    /// Every lane gives what the scalar `scatter` gives for its vertex, bit for bit, on the
    /// glass of the glass-and-coats scene (smooth clear and amber glass with absorbing
    /// volumes, frosted rough glass; seen from outside and from inside), and on the same
    /// glass thin-walled: continuations from delta lobes, transmitted paths entering and
    /// leaving volumes, every strategy, full and partial groups, zero throughputs.
    #[test]
    fn glass_lanes_equal_scalar_scatter_bit_for_bit() {
        let description = crate::testing::data::shipped_scene("glass-and-coats");
        let mut thin = description.clone();
        for m in thin.materials.iter_mut().filter(|m| m.transmits()) {
            m.volume = None;
        }
        for (description, thin_walled) in [(description, false), (thin, true)] {
            glass_lanes_equal_scalar_scatter_in(&RenderScene::new(description).expect("scene"), thin_walled);
        }
    }

    fn glass_lanes_equal_scalar_scatter_in(scene: &RenderScene, thin_walled: bool) {
        let mut rng = Sampler::new(9, 4, 2);
        for strategy in [Strategy::Mis, Strategy::LightOnly, Strategy::BsdfOnly] {
            let tracer = PathTracer {
                strategy,
                ..PathTracer::default()
            };
            let cases = vertices(scene, &tracer, &mut rng, 16 * 40 + 9, |bsdf| match *bsdf {
                Bsdf::Transmission(t) => t.glass_alone().copied(),
                _ => None,
            });
            let (mut lanes, mut out) = (GlassLanes::default(), ScatteredLanes::default());
            let (mut smooth, mut shadows, mut delta, mut entering, mut leaving, mut inside) = (0, 0, 0, 0, 0, 0);
            for group in cases.chunks(LANES) {
                lanes.clear();
                for (vertex, glass, beta) in group {
                    smooth += glass.is_smooth() as usize;
                    inside += !vertex.sp.front_face as usize;
                    lanes.push(vertex, &GlassFaces::begun(glass, scene.materials.entered_volume(vertex.sp.material, vertex.sp.front_face)), *beta, tracer.lane_light(scene, vertex));
                }
                crate::integrator::scattered_lanes::scatter(&lanes, strategy == Strategy::LightOnly, &mut out);
                for (lane, (vertex, _, beta)) in group.iter().enumerate() {
                    let expected = tracer.scatter(scene, vertex, *beta);
                    assert_eq!(format!("{:?}", out.get(lane)), format!("{expected:?}"), "{strategy:?}, lane {lane}");
                    shadows += expected.shadow.is_some() as usize;
                    if let Some(next) = expected.next {
                        delta += next.delta as usize;
                        entering += next.sigma_a.is_some_and(|s| s != Rgb::ZERO) as usize;
                        leaving += (next.sigma_a == Some(Rgb::ZERO)) as usize;
                    }
                }
            }
            let n = cases.len();
            assert!(smooth > n / 10 && smooth < n * 9 / 10, "{strategy:?}: smooth and rough glass: {smooth} of {n}");
            assert!(inside > 0, "{strategy:?}: vertices inside the glass: {inside} of {n}");
            assert!(delta > n / 10, "{strategy:?}: continuations from delta lobes: {delta}");
            if thin_walled {
                assert_eq!(entering + leaving, 0, "{strategy:?}: thin-walled glass has no volume");
            } else {
                assert!(entering > 0 && leaving > 0, "{strategy:?}: paths entering ({entering}) and leaving ({leaving}) volumes");
            }
            // Rough glass is lit, also through its back.
            if strategy != Strategy::BsdfOnly {
                assert!(shadows > 0, "{strategy:?}: {shadows} lit lanes");
            }
        }
    }

    /// `n` vertices whose BSDF `pick` takes (with what it gives), each with its path's
    /// throughput, begun by the scalar code from rays inside the scene's bounds in random
    /// directions; every eighth throughput is zero (the continuation must end there).
    fn vertices<'s, T>(scene: &'s RenderScene, tracer: &PathTracer, rng: &mut Sampler, n: usize, pick: impl Fn(&Bsdf<'s>) -> Option<T>) -> Vec<(Vertex<'s>, T, Rgb)> {
        let mut cases = Vec::new();
        while cases.len() < n {
            let origin = scene.bounds_centre + (rng.next_2d().extend(rng.next_1d()) - 0.5) * scene.bounds_radius;
            let ray = Ray::new(origin, sample_uniform_sphere(rng.next_2d()));
            let mut state = tracer.start(ray, rng.clone()).expect("depth allows a segment");
            rng.next_1d();
            state.beta = if cases.len() % 8 == 0 { Rgb::ZERO } else { rng.next_2d().extend(rng.next_1d()) * 2.0 };
            let hit = scene.intersect(&ray);
            let Some(vertex) = tracer.begin(scene, &mut state, hit) else { continue };
            if let Some(bsdf) = pick(&vertex.bsdf) {
                cases.push((vertex, bsdf, state.beta));
            }
        }
        cases
    }
}
