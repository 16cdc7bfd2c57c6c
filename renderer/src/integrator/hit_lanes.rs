//! The surface points of a lane kernel's vertices: pushed found (by
//! [`PathTracer::begin`](super::PathTracer)), or pushed as their hit and found by the kernel
//! for all such lanes at once ([`crate::render_scene::surface_points_lanes`], the scalar
//! code's operations, so the same bits).

use super::Vertex;
use crate::lanes::{F32s, Mask, MaskOps, Vec2s, Vec3s, LANES};
use crate::render_scene::{surface_points_lanes, LaneHit, RenderScene, SurfaceLanes, TriangleLanes};
use glam::Vec3;

/// A hit whose surface point a lane kernel finds: a ray of direction `direction` reaching
/// `hit` in `scene`, on a material that is `double_sided` or not.
#[derive(Clone, Copy)]
pub(crate) struct HitAt<'a> {
    pub scene: &'a RenderScene,
    pub hit: &'a LaneHit,
    pub direction: Vec3,
    pub double_sided: bool,
}

/// The surface points of up to [`LANES`] vertices: those pushed found, and what finding
/// the others needs (their hit, ray direction and whether their material is double-sided).
#[derive(Clone, Debug, Default)]
pub(crate) struct HitLanes {
    found: SurfaceLanes,
    /// Lanes pushed as their hit, and whether any is.
    from_hit: [bool; LANES],
    any_from_hit: bool,
    triangles: TriangleLanes,
    barycentric: Vec2s,
    direction: Vec3s,
    double_sided: [bool; LANES],
}

impl HitLanes {
    /// Forgets which lanes were pushed as hits (their old values stay, unused).
    #[inline]
    pub fn clear(&mut self) {
        self.any_from_hit = false;
        self.triangles.clear();
    }

    /// Lane `i` is `vertex`'s surface point.
    #[inline(always)]
    pub fn set_vertex(&mut self, i: usize, vertex: &Vertex) {
        let sp = &vertex.sp;
        let found = &mut self.found;
        found.p.set(i, sp.p);
        found.p_error.set(i, sp.p_error);
        found.ng.set(i, sp.ng_facing);
        found.s.set(i, sp.frame.s);
        found.t.set(i, sp.frame.t);
        found.n.set(i, sp.frame.n);
        found.wo.set(i, vertex.wo);
        self.from_hit[i] = false;
    }

    /// Lane `i` is the point `at`'s ray reaches.
    #[inline(always)]
    pub fn set_hit(&mut self, i: usize, at: &HitAt) {
        let HitAt { scene, hit, direction, double_sided } = *at;
        self.triangles.set(i, scene, hit);
        self.barycentric.set(i, hit.hit.barycentric);
        self.direction.set(i, direction);
        self.double_sided[i] = double_sided;
        self.from_hit[i] = true;
        self.any_from_hit = true;
    }

    /// The lanes' surface points; the lanes whose vertex scatters: those pushed found, and
    /// those pushed as their hit where [`PathTracer::begin`](super::PathTracer) would not end
    /// the path (at the back of a single-sided material, with the ray arriving below the
    /// shading hemisphere, or on an instance whose transform leaves no normal); and the lanes
    /// pushed as their hit whose ray arrives at the front of the surface (set for those
    /// pushed found).
    #[inline(always)]
    pub fn surface_points(&self) -> (SurfaceLanes, Mask, Mask) {
        if !self.any_from_hit {
            return (self.found.clone(), Mask([true; LANES]), Mask([true; LANES]));
        }
        let (hit, front_face, valid) = surface_points_lanes(&self.triangles, self.barycentric, self.direction);
        let scatters = (front_face | Mask(self.double_sided)) & !hit.wo.z.le(F32s::splat(0.0)) & valid;
        let (from_hit, found) = (Mask(self.from_hit), &self.found);
        let surface = SurfaceLanes {
            p: from_hit.select(hit.p, found.p),
            p_error: from_hit.select(hit.p_error, found.p_error),
            ng: from_hit.select(hit.ng, found.ng),
            s: from_hit.select(hit.s, found.s),
            t: from_hit.select(hit.t, found.t),
            n: from_hit.select(hit.n, found.n),
            wo: from_hit.select(hit.wo, found.wo),
        };
        (surface, !from_hit | scatters, !from_hit | front_face)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::{Hit, Ray};
    use crate::bsdf::Bsdf;
    use crate::bsdf::lambert::LambertLobe;
    use crate::bsdf::metallic_roughness::MetallicRoughnessLobes;
    use crate::integrator::bxdf_lanes::{BxdfLanes, GlassFaces, GlassLobes, LaneBxdf};
    use crate::integrator::scattered_lanes::{scatter, LaneKernel, ScatteredLanes};
    use crate::integrator::{PathState, PathTracer, Strategy};
    use crate::render_scene::RenderScene;
    use crate::sampler::Sampler;
    use crate::sampling::sample_uniform_sphere;
    use crate::scene::SurfaceModel;
    use crate::Rgb;

    /// Vertices pushed as their hit, alone or mixed in a group with vertices pushed begun,
    /// give what the scalar `begin` and `scatter` give, bit for bit (the position included),
    /// and end where `begin` ends the path: on Lambertian surfaces (the Cornell box, whose
    /// single-sided walls are seen from both sides, and again made double-sided; the
    /// preview's flat ground, and its smooth-shaded sphere made Lambertian),
    /// metallic-roughness ones (the preview's sphere, and its ground made
    /// metallic-roughness) and glass (the glass-and-coats scene's, seen from outside and
    /// inside, and the same made thin-walled), and on the feature showcase's textured and
    /// normal-mapped materials, instanced rocks and textured emissive sign (Lambertian, then
    /// metallic-roughness; all hits, then only those on instances), under every strategy;
    /// the emission the path finds there is added as `begin` adds it.
    #[test]
    fn hits_pushed_equal_scalar_begin_and_scatter() {
        let load = crate::testing::data::shipped_scene;
        let cornell = load("cornell-box");
        assert!(cornell.materials.iter().all(|m| !m.double_sided), "the box's walls are single-sided");
        let mut double_sided = cornell.clone();
        for m in &mut double_sided.materials {
            m.double_sided = true;
        }
        let preview = load("material-preview");
        let with_model = |model: SurfaceModel| {
            let mut description = preview.clone();
            for m in &mut description.materials {
                m.model = model.clone();
            }
            description
        };
        let (glossy, diffuse) = (with_model(SurfaceModel::MetallicRoughness), with_model(SurfaceModel::Lambert));
        let glass = load("glass-and-coats");
        let mut thin = glass.clone();
        for m in thin.materials.iter_mut().filter(|m| m.transmits()) {
            m.volume = None;
        }
        let showcase = load("feature-showcase");
        assert!(!showcase.instances.is_empty(), "the showcase places its rocks by instances");
        assert!(showcase.materials.iter().any(|m| m.normal_texture.is_some() && m.metallic_roughness_texture.is_some()), "the showcase has textured, normal-mapped materials");
        assert!(showcase.materials.iter().all(|m| m.clearcoat.is_none() && m.sheen.is_none()), "layered materials do not begin in lanes");
        let opaque = |model: SurfaceModel| {
            let mut description = showcase.clone();
            for m in description.materials.iter_mut().filter(|m| !m.transmits()) {
                m.model = model.clone();
            }
            description
        };
        let (textured_diffuse, textured_glossy) = (opaque(SurfaceModel::Lambert), opaque(SurfaceModel::MetallicRoughness));
        // Per kernel (diffuse, glossy, glass): vertices, pushed as hits, ended, smooth-shaded,
        // lit, on instances, with their normals bent by a normal map, on an emitting surface.
        let mut totals = [[0usize; 8]; 3];
        // (scene, whether its materials are double-sided, whether only hits on instances are
        // taken).
        let scenes = [
            (cornell, false, false),
            (double_sided, true, false),
            (preview, false, false),
            (glossy, false, false),
            (diffuse, false, false),
            (glass, false, false),
            (thin, false, false),
            (textured_diffuse.clone(), false, false),
            (textured_glossy.clone(), false, false),
            (textured_diffuse, false, true),
            (textured_glossy, false, true),
        ];
        for (description, double_sided, on_instances) in scenes {
            let scene = RenderScene::new(description).expect("scene");
            for strategy in [Strategy::Mis, Strategy::LightOnly, Strategy::BsdfOnly] {
                let tracer = PathTracer {
                    strategy,
                    ..PathTracer::default()
                };
                for (kernel, cases) in cases(&scene, &tracer, on_instances).into_iter().enumerate() {
                    if cases.is_empty() {
                        continue;
                    }
                    let counts = match kernel {
                        0 => check::<LambertLobe<F32s>>(&scene, &tracer, &cases, |bsdf, _, _| match bsdf {
                            Bsdf::Lambert(b) => b.lobe(),
                            _ => unreachable!(),
                        }),
                        1 => check::<MetallicRoughnessLobes<F32s>>(&scene, &tracer, &cases, |bsdf, _, _| match bsdf {
                            Bsdf::MetallicRoughness(m) => m.lobes(),
                            _ => unreachable!(),
                        }),
                        _ => check::<GlassLobes>(&scene, &tracer, &cases, |bsdf, begun, material| match (bsdf, begun) {
                            // Begun: the glass of the side its path arrives on.
                            (_, Some(v)) => match v.bsdf {
                                Bsdf::Transmission(t) => GlassFaces::begun(t.glass_alone().expect("glass alone"), scene.materials.entered_volume(v.sp.material, v.sp.front_face)),
                                _ => unreachable!(),
                            },
                            (Bsdf::Transmission(t), None) => {
                                GlassFaces::plain(&scene.materials, material, t.glass_alone().expect("glass alone"))
                            }
                            _ => unreachable!(),
                        }),
                    };
                    let Counts { from_hits, ended, shadows, smooth, instanced, bent, emitting } = counts;
                    let n = cases.len();
                    assert!(from_hits > n / 2, "{strategy:?}: {from_hits} of {n} pushed as hits");
                    assert!(ended < n && (ended == 0 || !double_sided), "{strategy:?}: {ended} of {n} ended");
                    for (total, count) in totals[kernel].iter_mut().zip([n, from_hits, ended, smooth, shadows, instanced, bent, emitting]) {
                        *total += count;
                    }
                }
            }
        }
        for (kernel, [n, from_hits, ended, smooth, shadows, instanced, bent, emitting]) in totals.into_iter().enumerate() {
            assert!(n >= 1000 && from_hits > 0 && ended > 0 && smooth > 0 && shadows > 0, "kernel {kernel}: {:?}", totals[kernel]);
            // The showcase's rocks and normal-mapped materials are opaque: the glass kernel
            // meets neither.
            assert!(kernel == 2 || (instanced > 100 && bent > 100), "kernel {kernel}: {instanced} lanes on instances, {bent} normal-mapped");
            // The Cornell box's light is a Lambertian emitter (lane_begin adds the emission
            // the same way before every kernel; the showcase's sign is too rarely met to count).
            assert!(kernel != 0 || emitting > 10, "kernel {kernel}: {emitting} lanes on emitters");
        }
    }

    /// A vertex's path before it, its hit, and whether to push it as its hit.
    type Case = (PathState, Hit, bool);

    /// Up to 169 vertices each for the diffuse, the glossy and the glass kernel that can be
    /// begun in lanes (`on_instances`: only those on instances), from rays inside the scene's
    /// bounds in random directions or (every other ray) toward a random triangle (so mostly
    /// the dense meshes'), every eighth vertex with a zero throughput; 20,000 rays, 80,000
    /// where only hits on instances count.
    fn cases(scene: &RenderScene, tracer: &PathTracer, on_instances: bool) -> [Vec<Case>; 3] {
        let mut rng = Sampler::new(9, 2, 6);
        let (mut diffuse, mut glossy, mut glass) = (Vec::new(), Vec::new(), Vec::new());
        let triangles = scene.geometry.triangle_count();
        for k in 0..if on_instances { 80_000 } else { 20_000 } {
            let origin = scene.bounds_centre + (rng.next_2d().extend(rng.next_1d()) - 0.5) * scene.bounds_radius;
            let direction = if k % 2 == 0 {
                sample_uniform_sphere(rng.next_2d())
            } else {
                let tri = ((rng.next_1d() * triangles as f32) as usize).min(triangles - 1);
                let [a, b, c] = scene.geometry.triangle_positions(tri);
                let toward = (a + b + c) / 3.0 - origin;
                toward.normalize_or(Vec3::Z)
            };
            let ray = Ray::new(origin, direction);
            let mut state = tracer.start(ray, rng.clone()).expect("depth allows a segment");
            rng.next_1d();
            let Some(hit) = scene.intersect(&ray) else { continue };
            if on_instances && hit.instance == crate::accel::NO_INSTANCE {
                continue;
            }
            let mut drawn = state.clone();
            let draws = tracer.draw(scene, &mut drawn);
            let Some((_, (bsdf, _), _)) = tracer.lane_begin(scene, &drawn, &hit, &draws) else { continue };
            let cases = match bsdf {
                Bsdf::Lambert(_) => &mut diffuse,
                Bsdf::MetallicRoughness(_) => &mut glossy,
                _ => &mut glass,
            };
            if cases.len() < 16 * 10 + 9 {
                state.beta = if cases.len() % 8 == 0 { Rgb::ZERO } else { rng.next_2d().extend(rng.next_1d()) * 2.0 };
                // Every third one pushed begun (where it scatters), the rest as hits.
                cases.push((state, hit, cases.len() % 3 != 0));
            }
        }
        [diffuse, glossy, glass]
    }

    struct Counts {
        from_hits: usize,
        ended: usize,
        shadows: usize,
        smooth: usize,
        instanced: usize,
        bent: usize,
        emitting: usize,
    }

    /// Pushes `cases` into the kernel of BSDF `B` (`one` gives a vertex's parameters from its
    /// plain BSDF, the vertex where it is pushed begun, and its material) in
    /// groups, begun or as their hit, and compares each lane with the scalar code.
    fn check<'s, B: LaneBxdf>(scene: &'s RenderScene, tracer: &PathTracer, cases: &[Case], one: impl Fn(&Bsdf<'s>, Option<&Vertex<'s>>, u32) -> B::One) -> Counts {
        let strategy = tracer.strategy;
        let (mut lanes, mut out) = (BxdfLanes::<B>::default(), ScatteredLanes::default());
        let mut counts = Counts { from_hits: 0, ended: 0, shadows: 0, smooth: 0, instanced: 0, bent: 0, emitting: 0 };
        for group in cases.chunks(LANES) {
            lanes.clear();
            let mut expected = Vec::new();
            for (state, hit, as_hit) in group {
                let mut begun = state.clone();
                let vertex = tracer.begin(scene, &mut begun, Some(*hit));
                let scattered = vertex.map(|v| (tracer.scatter(scene, &v, state.beta), v.sp.p));
                let mut drawn = state.clone();
                drawn.attenuate(hit.t);
                let draws = tracer.draw(scene, &mut drawn);
                assert_eq!(format!("{:?}", drawn.sampler), format!("{:?}", begun.sampler), "the same numbers drawn");
                let (lane_hit, (bsdf, double_sided), light) = tracer.lane_begin(scene, &drawn, hit, &draws).expect("begins in lanes");
                // The emission found at the hit, as `begin` adds it.
                tracer.lane_emission(scene, &mut drawn, &lane_hit);
                assert_eq!(drawn.l.to_array().map(f32::to_bits), begun.l.to_array().map(f32::to_bits), "{strategy:?}: the emission found");
                counts.emitting += (drawn.l != state.l) as usize;
                match (vertex, as_hit) {
                    (Some(v), false) => lanes.push(&v, &one(&bsdf, Some(&v), lane_hit.material), state.beta, tracer.lane_light(scene, &v)),
                    _ => {
                        let at = HitAt { scene, hit: &lane_hit, direction: state.ray.direction, double_sided };
                        lanes.push_hit(&at, &one(&bsdf, None, lane_hit.material), state.beta, &draws, light);
                        counts.from_hits += 1;
                        counts.smooth += !lane_hit.flat(scene) as usize;
                        counts.instanced += lane_hit.placed(scene).is_some() as usize;
                        counts.bent += lane_hit.bend(scene).is_some() as usize;
                    }
                }
                counts.ended += scattered.is_none() as usize;
                counts.shadows += scattered.is_some_and(|(s, _)| s.shadow.is_some()) as usize;
                expected.push(scattered);
            }
            scatter(&lanes, strategy == Strategy::LightOnly, &mut out);
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
        counts
    }
}
