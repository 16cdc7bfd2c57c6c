//! Vertices on BSDFs whose values are evaluated in batches ([`BatchEval`]: the decoded
//! neural materials, the NBRDF networks and the MERL tables), scattered together. Each vertex's light sample and
//! BSDF sample are drawn one by one exactly as [`PathTracer::scatter`] draws them, and the two
//! values they need are prepared (a net's input or a table's corners, the table entries
//! prefetched); then every value of a material in the batch is evaluated in one call (one
//! batched forward pass of its net, many points per weight load); then each vertex is
//! finished with its values. The result is the same, bit for bit, as scattering the vertices
//! one by one.

use super::{continuation, light_direction, PathTracer, Scattered, Vertex};
use crate::bsdf::tabulated_sampling::TabulatedBrdf;
use crate::bsdf::{BatchEval, BsdfSample};
use crate::lights::LightSample;
use crate::render_scene::{RenderScene, SurfacePoint};
use crate::Rgb;
use glam::Vec3;

/// Where a prepared value lies: the material and the index among its points.
#[derive(Clone, Copy, Debug)]
struct Slot {
    material: u32,
    point: u32,
}

/// A vertex between its sampling and its evaluation.
#[derive(Clone, Copy, Debug)]
struct Pending {
    sp: SurfacePoint,
    beta: Rgb,
    /// The light sample, its direction (local frame), the BSDF's density of that direction
    /// and where its value will be.
    light: Option<(LightSample, Vec3, f32, Slot)>,
    /// The BSDF sample's direction (local frame), density and where its value will be.
    sample: Option<(Vec3, f32, Slot)>,
}

/// The points of one material in the batch and, once evaluated, their values.
struct Material<'s, B: BatchEval> {
    bsdf: &'s B,
    points: Vec<B::Prepared>,
    values: Vec<Rgb>,
}

/// Vertices of one BSDF type scattered together (see the module documentation).
pub(super) struct DeferredScatter<'s, B: BatchEval> {
    vertices: Vec<Pending>,
    /// The distinct materials of the batch (usually one or two: a linear search finds them).
    materials: Vec<Material<'s, B>>,
    /// The scattered vertices, in the order they were pushed (after [`Self::scatter`]).
    scattered: Vec<Scattered>,
}

impl<B: BatchEval> Default for DeferredScatter<'_, B> {
    fn default() -> Self {
        DeferredScatter {
            vertices: Vec::new(),
            materials: Vec::new(),
            scattered: Vec::new(),
        }
    }
}

impl<'s, B: BatchEval + TabulatedBrdf> DeferredScatter<'s, B> {
    /// Vertices pushed since the last [`Self::clear`].
    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    pub fn clear(&mut self) {
        self.vertices.clear();
        self.materials.clear();
    }

    /// Draws vertex `v`'s light and BSDF samples (on `bsdf`, its BSDF) for a path of
    /// throughput `beta` and prepares their values; [`Self::scatter`] finishes it.
    pub fn push(&mut self, tracer: &PathTracer, scene: &RenderScene, v: &Vertex, bsdf: &'s B, beta: Rgb) {
        let material = match self.materials.iter().position(|m| std::ptr::eq(m.bsdf, bsdf)) {
            Some(k) => k,
            None => {
                self.materials.push(Material {
                    bsdf,
                    points: Vec::new(),
                    values: Vec::new(),
                });
                self.materials.len() - 1
            }
        };
        let mut add = |point: B::Prepared| {
            let points = &mut self.materials[material].points;
            points.push(point);
            Slot {
                material: material as u32,
                point: points.len() as u32 - 1,
            }
        };
        // As `PathTracer::light_term`: a value `prepare` leaves out is zero, which contributes
        // nothing; the density is `Bxdf::pdf`, what `eval_pdf` gives for tabulated BSDFs, and
        // is left out (0) where MIS does not use it (a point light's sample).
        // Both read the sampler's view of wo, found once.
        let sampler = bsdf.sampler();
        let view = sampler.view(v.wo);
        let light = tracer.light_sample(scene, v).and_then(|ls| {
            let wi = light_direction(&v.sp, &ls)?;
            let pdf = if tracer.weighs_light_sample(&ls) { sampler.pdf_in(&view, wi) } else { 0.0 };
            Some((ls, wi, pdf, add(bsdf.prepare(v.wo, wi)?)))
        });
        // As `Bxdf::sample` of a tabulated BSDF; a zero value ends the path in `continuation`.
        let sample = sampler
            .sample_with_pdf_in(&view, v.u, v.uc)
            .and_then(|(wi, pdf)| Some((wi, pdf, add(bsdf.prepare(v.wo, wi)?))));
        self.vertices.push(Pending {
            sp: v.sp,
            beta,
            light,
            sample,
        });
    }

    /// Evaluates every prepared value, one call per material, and scatters the vertices
    /// ([`Self::get`] then returns them).
    pub fn scatter(&mut self, tracer: &PathTracer) {
        for m in &mut self.materials {
            m.values.clear();
            m.values.resize(m.points.len(), Rgb::ZERO);
            m.bsdf.eval_prepared(&m.points, &mut m.values);
        }
        let value = |slot: Slot| self.materials[slot.material as usize].values[slot.point as usize];
        self.scattered.clear();
        self.scattered.extend(self.vertices.iter().map(|p| Scattered {
            shadow: p
                .light
                .and_then(|(ls, wi, pdf, slot)| tracer.light_contribution(&p.sp, p.beta, &ls, wi, value(slot), pdf)),
            next: p
                .sample
                .and_then(|(wi, pdf, slot)| continuation(&p.sp, &BsdfSample { wi, f: value(slot), pdf }, p.beta)),
        }));
    }

    /// What the `k`-th vertex pushed scattered into (after [`Self::scatter`]).
    #[inline]
    pub fn get(&self, k: u32) -> Scattered {
        self.scattered[k as usize]
    }
}
