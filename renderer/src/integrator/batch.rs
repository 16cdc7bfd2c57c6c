//! [`PathTracer::step`] for a batch of paths: the vertices are begun one by one, those on
//! Lambertian and metallic-roughness surfaces scattered [`LANES`](crate::lanes::LANES) at a
//! time under any light ([`DiffuseLanes`], [`GlossyLanes`]), those on decoded neural
//! materials, NBRDF networks and MERL tables with their values evaluated together after all
//! were sampled ([`DeferredScatter`]: one batched forward pass per net, table entries
//! prefetched), the others one by one, and all advanced in the batch's order.

use super::deferred::DeferredScatter;
use super::diffuse_lanes::DiffuseLanes;
use super::glossy_lanes::GlossyLanes;
use super::scattered_lanes::LaneGroups;
use super::{PathState, PathTracer, Scattered, ShadowTest, Strategy};
use crate::accel::Hit;
use crate::bsdf::merl::MerlBsdf;
use crate::bsdf::nbrdf::NbrdfBsdf;
use crate::bsdf::neural::NeuralBsdf;
use crate::bsdf::Bsdf;
use crate::lights::environment::MapPoint;
use crate::render_scene::RenderScene;
use crate::lanes::{Vec3s, LANES};
use glam::Vec3;

/// Vertices begun and scattered together: small enough that their records stay in cache.
const CHUNK: usize = 256;

/// Where a vertex's scattering result is.
#[derive(Clone, Copy, Debug)]
enum Outcome {
    /// The path ended at the vertex.
    Ended,
    /// Scattered alone: index into [`BatchBuffers::scattered`].
    Alone(u32),
    /// Scattered in diffuse lanes: group and lane in [`BatchBuffers::diffuse`].
    Diffuse((u32, u32)),
    /// Scattered in glossy lanes: group and lane in [`BatchBuffers::glossy`].
    Glossy((u32, u32)),
    /// A decoded neural vertex: index into [`BatchBuffers::neural`].
    Neural(u32),
    /// An NBRDF vertex: index into [`BatchBuffers::nbrdf`].
    Nbrdf(u32),
    /// A MERL-table vertex: index into [`BatchBuffers::merl`].
    Merl(u32),
}

/// Reusable buffers of [`PathTracer::step_batch`] for the scene `'s`.
#[derive(Default)]
pub struct BatchBuffers<'s> {
    /// Per vertex of the chunk: its outcome, and its position (unused where it ended). Two
    /// vectors rather than one of pairs: a pair is assembled on the stack in pieces and read
    /// back whole, which stalls store forwarding once per vertex.
    outcomes: Vec<Outcome>,
    positions: Vec<Vec3>,
    scattered: Vec<Scattered>,
    diffuse: LaneGroups<DiffuseLanes<'s>>,
    glossy: LaneGroups<GlossyLanes<'s>>,
    neural: DeferredScatter<'s, NeuralBsdf>,
    nbrdf: DeferredScatter<'s, NbrdfBsdf>,
    merl: DeferredScatter<'s, MerlBsdf>,
    /// The chunk's rays that left the scene (path index) and where they fall in the
    /// environment.
    escapes: Vec<(u32, MapPoint)>,
}

/// What one batch step produces, both in the order of the active paths: the shadow tests
/// with the index of their path, and the paths that go on.
#[derive(Default)]
pub struct StepResults {
    pub shadows: Vec<(u32, ShadowTest)>,
    pub next: Vec<u32>,
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
        let StepResults { shadows, next } = results;
        shadows.clear();
        next.clear();
        let light_only = self.strategy == Strategy::LightOnly;
        let BatchBuffers {
            outcomes,
            positions,
            scattered,
            diffuse,
            glossy,
            neural,
            nbrdf,
            merl,
            escapes,
        } = buffers;
        for (chunk, chunk_hits) in active.chunks(CHUNK).zip(hits.chunks(CHUNK)) {
            outcomes.clear();
            positions.clear();
            scattered.clear();
            diffuse.clear();
            glossy.clear();
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
                let path = &mut paths[i as usize];
                // Escaped rays were ended above: `begin` of a miss would add the environment
                // again.
                let Some(v) = hit.and_then(|hit| self.begin(scene, path, Some(hit))) else {
                    outcomes.push(Outcome::Ended);
                    positions.push(Vec3::ZERO);
                    continue;
                };
                positions.push(v.sp.p);
                if let Bsdf::Lambert(b) = &v.bsdf {
                    let slot = diffuse.push(light_only, |lanes| lanes.push(&v, b.albedo, path.beta, self.lane_light(scene, &v)));
                    outcomes.push(Outcome::Diffuse(slot));
                } else if let Bsdf::MetallicRoughness(bsdf) = &v.bsdf {
                    let slot = glossy.push(light_only, |lanes| lanes.push(&v, bsdf, path.beta, self.lane_light(scene, &v)));
                    outcomes.push(Outcome::Glossy(slot));
                } else if let Bsdf::Neural(bsdf) = v.bsdf {
                    outcomes.push(Outcome::Neural(neural.len() as u32));
                    neural.push(self, scene, &v, bsdf, path.beta);
                } else if let Bsdf::Nbrdf(bsdf) = v.bsdf {
                    outcomes.push(Outcome::Nbrdf(nbrdf.len() as u32));
                    nbrdf.push(self, scene, &v, bsdf, path.beta);
                } else if let Bsdf::Merl(bsdf) = v.bsdf {
                    outcomes.push(Outcome::Merl(merl.len() as u32));
                    merl.push(self, scene, &v, bsdf, path.beta);
                } else {
                    outcomes.push(Outcome::Alone(scattered.len() as u32));
                    scattered.push(self.scatter(scene, &v, path.beta));
                }
            }
            diffuse.finish(light_only);
            glossy.finish(light_only);
            neural.scatter(self);
            nbrdf.scatter(self);
            merl.scatter(self);
            for ((&i, &outcome), &p) in chunk.iter().zip(outcomes.iter()).zip(positions.iter()) {
                let s = match outcome {
                    Outcome::Ended => continue,
                    Outcome::Alone(k) => scattered[k as usize],
                    Outcome::Diffuse(slot) => diffuse.get(slot),
                    Outcome::Glossy(slot) => glossy.get(slot),
                    Outcome::Neural(k) => neural.get(k),
                    Outcome::Nbrdf(k) => nbrdf.get(k),
                    Outcome::Merl(k) => merl.get(k),
                };
                if let Some(test) = s.shadow {
                    shadows.push((i, test));
                }
                if self.advance(&mut paths[i as usize], p, s.next) {
                    next.push(i);
                }
            }
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
