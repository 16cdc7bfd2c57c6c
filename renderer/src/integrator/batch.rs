//! [`PathTracer::step`] for a batch of paths: each vertex's random numbers are drawn and
//! its light chosen one by one; those on Lambertian and metallic-roughness surfaces and on
//! glass are scattered [`LANES`](crate::lanes::LANES) at a time under any light
//! ([`DiffuseLanes`], [`GlossyLanes`], [`GlassLanes`]: their formulas instantiated for
//! lanes; on uniform opaque materials pushed as their hits, the kernel finding their surface
//! points, elsewhere begun one by one), those on decoded neural materials, NBRDF networks and
//! MERL tables with their values evaluated together after all were sampled
//! ([`DeferredScatter`]: one batched forward pass per net, table entries prefetched), layers
//! over those joining their base's batch, the others (glass mixed with an opaque part, layers
//! over analytic bases) one by one. Each vertex's path is advanced as soon as its vertex is
//! scattered (a lane group's paths right after the group), while its result is still in
//! cache.

use super::deferred::DeferredScatter;
use super::bxdf_lanes::{DiffuseLanes, GlassFaces, GlassLanes, GlossyLanes};
use super::hit_lanes::HitAt;
use super::scattered_lanes::LaneGroup;
use super::light_lanes::LaneLight;
use super::{Draws, PathState, PathTracer, Scattered, Strategy};
use crate::accel::{Hit, Ray};
use crate::Rgb;
use crate::bsdf::merl::MerlBsdf;
use crate::bsdf::nbrdf::NbrdfBsdf;
use crate::bsdf::neural::NeuralBsdf;
use crate::bsdf::Bsdf;
use crate::lights::environment::MapPoint;
use crate::render_scene::{LaneHit, RenderScene};
use crate::lanes::{Vec3s, LANES};
use glam::Vec3;

/// Vertices begun together, and the deferred ones among them scattered together: small
/// enough that their records stay in cache. Lane groups fill across chunks (fewer partial
/// groups).
const CHUNK: usize = 256;

/// Reusable buffers of [`PathTracer::step_batch`] for the scene `'s`.
#[derive(Default)]
pub struct BatchBuffers<'s> {
    diffuse: LaneGroup<DiffuseLanes<'s>>,
    glossy: LaneGroup<GlossyLanes<'s>>,
    glass: LaneGroup<GlassLanes<'s>>,
    neural: DeferredScatter<'s, NeuralBsdf>,
    nbrdf: DeferredScatter<'s, NbrdfBsdf>,
    merl: DeferredScatter<'s, MerlBsdf>,
    /// The chunk's rays that left the scene (path index) and where they fall in the
    /// environment.
    escapes: Vec<(u32, MapPoint)>,
}

/// What one batch step produces: the shadow tests (their rays, ready to trace, and the index
/// of their path with the contribution each adds where its ray is unoccluded), and the paths
/// that go on, both in the order their vertices were scattered (the order of the active
/// paths within each kind of vertex; the order changes no path's values).
#[derive(Default)]
pub struct StepResults {
    pub shadow_rays: Vec<Ray>,
    pub shadows: Vec<(u32, Rgb)>,
    pub next: Vec<u32>,
}

impl StepResults {
    fn clear(&mut self) {
        self.shadow_rays.clear();
        self.shadows.clear();
        self.next.clear();
    }
}

impl PathTracer {
    /// Steps paths `active` (indices into `paths`) whose rays found `hits` (in the same
    /// order), as [`Self::step`] would one by one, replacing `results`.
    pub fn step_batch<'s>(
        &self,
        scene: &'s RenderScene,
        paths: &mut [PathState],
        active: &[u32],
        hits: &[Option<Hit>],
        buffers: &mut BatchBuffers<'s>,
        results: &mut StepResults,
    ) {
        results.clear();
        let light_only = self.strategy == Strategy::LightOnly;
        let BatchBuffers {
            diffuse,
            glossy,
            glass,
            neural,
            nbrdf,
            merl,
            escapes,
        } = buffers;
        for (chunk, chunk_hits) in active.chunks(CHUNK).zip(hits.chunks(CHUNK)) {
            neural.clear();
            nbrdf.clear();
            merl.clear();
            // Rays that left the scene first: all located in the environment, sixteen at a
            // time (which prefetches their image records), then all looked up, so that their
            // cache misses overlap; the hits' triangle records are prefetched on the way.
            escapes.clear();
            let mut missed = [0u32; LANES];
            let mut directions = Vec3s::default();
            let mut filled = 0;
            for (&i, hit) in chunk.iter().zip(chunk_hits) {
                match hit {
                    Some(hit) => scene.prefetch_hit(hit),
                    None => {
                        missed[filled] = i;
                        directions.set(filled, paths[i as usize].ray.direction);
                        filled += 1;
                        if filled == LANES {
                            locate(scene, &missed, directions, escapes);
                            filled = 0;
                        }
                    }
                }
            }
            if filled > 0 {
                locate(scene, &missed[..filled], directions, escapes);
            }
            for &(i, at) in escapes.iter() {
                self.escape_at(scene, &mut paths[i as usize], at);
            }
            for (&i, &hit) in chunk.iter().zip(chunk_hits) {
                // Escaped rays were ended above: `begin` of a miss would add the environment
                // again.
                let Some(hit) = hit else { continue };
                let path = &mut paths[i as usize];
                path.attenuate(hit.t);
                let draws = self.draw(scene, path);
                let beta = path.beta;
                if let Some((lane_hit, (bsdf, double_sided), light)) = self.lane_begin(scene, path, &hit, &draws) {
                    self.lane_emission(scene, path, &lane_hit);
                    let at = HitAt { scene, hit: &lane_hit, direction: path.ray.direction, double_sided };
                    let settle = |i, p, s| self.settle(paths, results, i, p, s);
                    match bsdf {
                        Bsdf::Lambert(l) => diffuse.push(i, light_only, |lanes| lanes.push_hit(&at, &l.lobe(), beta, &draws, light), settle),
                        Bsdf::MetallicRoughness(m) => glossy.push(i, light_only, |lanes| lanes.push_hit(&at, &m.lobes(), beta, &draws, light), settle),
                        Bsdf::Transmission(t) => {
                            let faces = GlassFaces::plain(&scene.materials, lane_hit.material, t.glass_alone().expect("plain glass is glass alone"));
                            glass.push(i, light_only, |lanes| lanes.push_hit(&at, &faces, beta, &draws, light), settle)
                        }
                        Bsdf::Merl(_) | Bsdf::Nbrdf(_) | Bsdf::Neural(_) | Bsdf::Layered(_) | Bsdf::Mixture(_) => unreachable!("a BSDF begun in lanes is Lambertian, metallic-roughness or glass"),
                    }
                    continue;
                }
                let Some(v) = self.begin_drawn(scene, path, hit, draws) else {
                    continue;
                };
                // Every kind's route, in one exhaustive match: a kind added to `Bsdf` does not
                // compile until it is given one (lanes, deferred batch, or one by one).
                let mut settle = |i, p, s| self.settle(paths, results, i, p, s);
                match v.bsdf {
                    Bsdf::Lambert(b) => diffuse.push(i, light_only, |lanes| lanes.push(&v, &b.lobe(), beta, self.lane_light(scene, &v)), settle),
                    Bsdf::MetallicRoughness(b) => glossy.push(i, light_only, |lanes| lanes.push(&v, &b.lobes(), beta, self.lane_light(scene, &v)), settle),
                    // Glass alone in lanes; mixed with an opaque part, one by one.
                    Bsdf::Transmission(t) => match t.glass_alone() {
                        Some(g) => glass.push(i, light_only, |lanes| lanes.push(&v, &GlassFaces::begun(g, scene.materials.entered_volume(v.sp.material, v.sp.front_face)), beta, self.lane_light(scene, &v)), settle),
                        None => settle(i, v.sp.p, self.scatter(scene, &v, beta)),
                    },
                    Bsdf::Neural(b) => neural.push(self, scene, i, &v, b, beta),
                    Bsdf::Nbrdf(b) => nbrdf.push(self, scene, i, &v, b, beta),
                    Bsdf::Merl(b) => merl.push(self, scene, i, &v, b, beta),
                    // A mixture of one kind of parts joins their batch; of several, one by one.
                    Bsdf::Mixture(m) if neural.push_mixture(self, scene, i, &v, &m, beta) || nbrdf.push_mixture(self, scene, i, &v, &m, beta) || merl.push_mixture(self, scene, i, &v, &m, beta) => {}
                    // Layers over such a base (or mixture) join the base's batch.
                    Bsdf::Layered(l) if neural.push_layered(self, scene, i, &v, &l, beta) || nbrdf.push_layered(self, scene, i, &v, &l, beta) || merl.push_layered(self, scene, i, &v, &l, beta) => {}
                    Bsdf::Layered(_) | Bsdf::Mixture(_) => settle(i, v.sp.p, self.scatter(scene, &v, beta)),
                }
            }
            neural.scatter(self, |i, p, s| self.settle(paths, results, i, p, s));
            nbrdf.scatter(self, |i, p, s| self.settle(paths, results, i, p, s));
            merl.scatter(self, |i, p, s| self.settle(paths, results, i, p, s));
        }
        diffuse.finish(light_only, |i, p, s| self.settle(paths, results, i, p, s));
        glossy.finish(light_only, |i, p, s| self.settle(paths, results, i, p, s));
        glass.finish(light_only, |i, p, s| self.settle(paths, results, i, p, s));
    }

    /// What beginning the vertex of `path` at `hit` (its random numbers `draws`) in a lane
    /// kernel needs — the hit's triangle, its material's BSDF there and double-sidedness
    /// ([`RenderScene::lane_hit`]) and its light ([`Self::kernel_light`]) — where the kernel
    /// can find its surface point and light sample (the emission the path finds there is
    /// [`Self::lane_emission`]'s); `None` where [`Self::begin_drawn`] must begin it (also
    /// where the path may not scatter there).
    #[inline(always)]
    #[allow(clippy::type_complexity)]
    pub(super) fn lane_begin<'s>(&self, scene: &'s RenderScene, path: &PathState, hit: &Hit, draws: &Draws) -> Option<(LaneHit, (Bsdf<'s>, bool), LaneLight<'s>)> {
        if !self.allows(path.segments + 1) {
            return None;
        }
        // The light first: finding a textured material's BSDF is wasted where `begin_drawn`
        // must begin the vertex anyway.
        let light = self.kernel_light(scene, draws.light, draws.u_light)?;
        let (lane_hit, bsdf, double_sided) = scene.lane_hit(hit)?;
        Some((lane_hit, (bsdf, double_sided), light))
    }

    /// Adds to `path` the emission it finds at `hit` (on its triangle's material), for a
    /// vertex [`Self::lane_begin`] begins in lanes (as [`Self::begin_drawn`] adds it): the
    /// surface point found once more, one by one, on emitting materials only (the lights' own
    /// surfaces). `lane_hit` found the triangle sound, so a surface point exists unless an
    /// instance's placement fails, where the kernel ends the path as `begin_drawn` would,
    /// before its emission.
    #[inline(always)]
    pub(super) fn lane_emission(&self, scene: &RenderScene, path: &mut PathState, hit: &LaneHit) {
        if scene.materials.emits(hit.material) {
            self.add_emission_at(scene, path, &hit.hit);
        }
    }

    /// [`Self::add_emission`] at `hit` (kept out of line: the batch step's loop stays small).
    #[inline(never)]
    fn add_emission_at(&self, scene: &RenderScene, path: &mut PathState, hit: &Hit) {
        if let Some(sp) = scene.surface_point(hit, path.ray.direction) {
            self.add_emission(scene, path, &sp);
        }
    }

    /// Hands path `i`'s vertex at `p`, scattered into `s`, on: its shadow test to the
    /// results, and the path to its next ray (listed in the results) or its end.
    #[inline(always)]
    fn settle(&self, paths: &mut [PathState], results: &mut StepResults, i: u32, p: Vec3, s: Scattered) {
        if let Some(test) = s.shadow {
            results.shadow_rays.push(test.ray);
            results.shadows.push((i, test.contribution));
        }
        if self.advance(&mut paths[i as usize], p, s.next) {
            results.next.push(i);
        }
    }
}

/// Appends the paths `missed` whose rays left the scene in directions `directions` (lane k
/// for path k) with where they fall in the environment, if there is one.
#[inline(always)]
fn locate(scene: &RenderScene, missed: &[u32], directions: Vec3s, escapes: &mut Vec<(u32, MapPoint)>) {
    if let Some(at) = scene.lights.locate_environment_lanes(directions) {
        escapes.extend(missed.iter().copied().zip(at));
    }
}
