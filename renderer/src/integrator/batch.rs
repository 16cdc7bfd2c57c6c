//! [`PathTracer::step`] for a batch of paths: the vertices are begun one by one, the common
//! diffuse-surface-lit-by-a-triangle ones scattered [`LANES`] at a time
//! ([`DiffuseLanes`]), the others one by one, and all advanced in the batch's order.

use super::diffuse_lanes::{DiffuseLanes, DiffuseScattered};
use super::{PathState, PathTracer, Scattered, ShadowTest, Strategy, Vertex};
use crate::accel::Hit;
use crate::bsdf::Bsdf;
use crate::lanes::LANES;
use crate::render_scene::RenderScene;

/// Vertices begun and scattered together: small enough that their records stay in cache.
const CHUNK: usize = 256;

/// Reusable buffers of [`PathTracer::step_batch`].
#[derive(Default)]
pub struct BatchBuffers<'s> {
    vertices: Vec<Option<Vertex<'s>>>,
    scattered: Vec<Scattered>,
    /// Chunk positions of the vertices in `lanes`.
    lane_owners: [usize; LANES],
    lanes: DiffuseLanes,
    lanes_out: DiffuseScattered,
}

impl PathTracer {
    /// Steps paths `active` (indices into `paths`) whose rays found `hits` (in the same
    /// order), as [`Self::step`] would one by one: pushes each shadow test with its path
    /// index onto `shadows` and the paths that go on onto `next`, both in `active`'s order.
    pub fn step_batch<'s>(
        &self,
        scene: &'s RenderScene,
        paths: &mut [PathState],
        active: &[u32],
        hits: &[Option<Hit>],
        buffers: &mut BatchBuffers<'s>,
        shadows: &mut Vec<(u32, ShadowTest)>,
        next: &mut Vec<u32>,
    ) {
        let lanes_apply = self.strategy != Strategy::BsdfOnly;
        for (chunk, chunk_hits) in active.chunks(CHUNK).zip(hits.chunks(CHUNK)) {
            let BatchBuffers {
                vertices,
                scattered,
                lane_owners,
                lanes,
                lanes_out,
            } = buffers;
            vertices.clear();
            scattered.clear();
            scattered.resize(chunk.len(), Scattered::default());
            lanes.clear();
            for (k, (&i, &hit)) in chunk.iter().zip(chunk_hits).enumerate() {
                let path = &mut paths[i as usize];
                let vertex = self.begin(scene, path, hit);
                if let Some(v) = &vertex {
                    let diffuse_triangle = match (&v.bsdf, v.light) {
                        (Bsdf::Lambert(b), Some((light, select_pdf))) if lanes_apply => {
                            scene.lights.triangle(light).map(|t| (b.albedo, t, select_pdf))
                        }
                        _ => None,
                    };
                    if let Some((albedo, light, select_pdf)) = diffuse_triangle {
                        lane_owners[lanes.len()] = k;
                        lanes.push(v, albedo, path.beta, light, select_pdf);
                        if lanes.is_full() {
                            flush(self, lanes, lanes_out, lane_owners, scattered);
                        }
                    } else {
                        scattered[k] = self.scatter(scene, v, path.beta);
                    }
                }
                vertices.push(vertex);
            }
            flush(self, lanes, lanes_out, lane_owners, scattered);
            for ((&i, vertex), s) in chunk.iter().zip(vertices.iter()).zip(scattered.iter()) {
                let Some(vertex) = vertex else { continue };
                if let Some(test) = s.shadow {
                    shadows.push((i, test));
                }
                if self.advance(&mut paths[i as usize], vertex, s.next) {
                    next.push(i);
                }
            }
        }
    }
}

/// Scatters the filled lanes and stores their results at their owners' chunk positions.
fn flush(
    tracer: &PathTracer,
    lanes: &mut DiffuseLanes,
    out: &mut DiffuseScattered,
    owners: &[usize; LANES],
    scattered: &mut [Scattered],
) {
    if lanes.len() == 0 {
        return;
    }
    lanes.scatter(tracer.strategy == Strategy::LightOnly, out);
    for (lane, &k) in owners[..lanes.len()].iter().enumerate() {
        scattered[k] = out.get(lane);
    }
    lanes.clear();
}
