//! Vertices on BSDFs whose values are evaluated in batches ([`BatchEval`]: the decoded
//! neural materials, the NBRDF networks and the MERL tables), scattered together. Each
//! vertex's light sample and BSDF sample are drawn one by one exactly as
//! [`PathTracer::scatter`] draws them, except the environment's light samples, drawn
//! [`LANES`] at a time afterwards ([`Environment::sample_lanes`]: the same bits, the table
//! look-ups of many draws issued together); then the sampler's densities of all their directions
//! are found sixteen at a time ([`TabulatedSampler::pdf_in_lanes`]: latency-bound arithmetic
//! with two arctangents each, which one vertex at a time leaves the CPU waiting on); then the
//! values they need are prepared (a net's input or a table's corners, the table entries
//! prefetched) and every value of a material in the batch is evaluated in one call (one
//! batched forward pass of its net, many points per weight load); then each vertex is
//! finished with its values. The result is the same, bit for bit, as scattering the vertices
//! one by one.

use super::{continuation, light_direction, PathTracer, Scattered, Vertex};
use crate::bsdf::tabulated_sampling::{SamplerView, TabulatedBrdf, TabulatedSampler};
use crate::lanes::{Vec2s, Vec3s, LANES};
use crate::lights::environment::Environment;
use crate::bsdf::{BatchEval, BsdfSample};
use crate::lights::LightSample;
use crate::render_scene::{RenderScene, SurfacePoint};
use crate::Rgb;
use glam::{Vec2, Vec3};

/// Where a prepared value lies: the material and the index among its points.
#[derive(Clone, Copy, Debug)]
struct Slot {
    material: u32,
    point: u32,
}

/// A vertex between its sampling and its evaluation.
#[derive(Clone, Copy, Debug)]
struct Pending {
    /// The path (index) the vertex belongs to.
    path: u32,
    sp: SurfacePoint,
    beta: Rgb,
    wo: Vec3,
    /// Index of its material in [`DeferredScatter::materials`], and the sampler's view of wo.
    material: u32,
    view: SamplerView,
    light: Option<PendingLight>,
    /// The u and selection probability of an environment sample still to draw (`light` is
    /// `None` until then).
    environment_draw: Option<(Vec2, f32)>,
    sample: Option<PendingSample>,
}

/// A vertex's light sample: its direction (local frame), whether MIS weighs it (and so needs
/// the BSDF's density of that direction), and, filled in by [`DeferredScatter::scatter`], that
/// density and where the BSDF's value is (`None`: zero, below the horizon).
#[derive(Clone, Copy, Debug)]
struct PendingLight {
    ls: LightSample,
    wi: Vec3,
    weighed: bool,
    pdf: f32,
    slot: Option<Slot>,
}

/// A vertex's BSDF sample: its direction (local frame) and, filled in by
/// [`DeferredScatter::scatter`], its density and where its value is (`None`: the sample is
/// dropped, its density not positive and finite or its value zero).
#[derive(Clone, Copy, Debug)]
struct PendingSample {
    wi: Vec3,
    pdf: f32,
    slot: Option<Slot>,
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
    /// The scene's environment, where a vertex samples it.
    environment: Option<&'s Environment>,
    /// The distinct materials of the batch (usually one or two: a linear search finds them).
    materials: Vec<Material<'s, B>>,
}

impl<B: BatchEval> Default for DeferredScatter<'_, B> {
    fn default() -> Self {
        DeferredScatter {
            vertices: Vec::new(),
            environment: None,
            materials: Vec::new(),
        }
    }
}

impl<'s, B: BatchEval + TabulatedBrdf> DeferredScatter<'s, B> {
    pub fn clear(&mut self) {
        self.vertices.clear();
        self.materials.clear();
    }

    /// Draws vertex `v`'s light and BSDF samples (on `bsdf`, its BSDF) for path `path` of
    /// throughput `beta`; [`Self::scatter`] finishes it.
    pub fn push(&mut self, tracer: &PathTracer, scene: &'s RenderScene, path: u32, v: &Vertex, bsdf: &'s B, beta: Rgb) {
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
        // As `PathTracer::light_term` and `Bxdf::sample` of a tabulated BSDF, with the
        // densities (and the values) left to `scatter`. Both read the sampler's view of wo,
        // found once.
        let sampler = bsdf.sampler();
        let view = sampler.view(v.wo);
        let environment_draw = tracer.environment_draw(scene, v);
        let light = match environment_draw {
            Some((environment, ..)) => {
                self.environment = Some(environment);
                None
            }
            None => tracer.light_sample(scene, v).and_then(|ls| pending_light(tracer, &v.sp, ls)),
        };
        let sample = sampler.sample_in(&view, v.u, v.uc).map(|wi| PendingSample { wi, pdf: 0.0, slot: None });
        self.vertices.push(Pending {
            path,
            sp: v.sp,
            beta,
            wo: v.wo,
            material: material as u32,
            view,
            light,
            environment_draw: environment_draw.map(|(_, u, select_pdf)| (u, select_pdf)),
            sample,
        });
    }

    /// Draws the environment's light samples of the vertices that have one to draw,
    /// [`LANES`] at a time.
    fn draw_environment(&mut self, tracer: &PathTracer) {
        let Some(environment) = self.environment else { return };
        let mut group = [0usize; LANES];
        let (mut u, mut select_pdf) = (Vec2s::default(), [0.0f32; LANES]);
        let mut filled = 0;
        let flush = |vertices: &mut Vec<Pending>, u: &Vec2s, select_pdf: &[f32; LANES], group: &[usize]| {
            let e = environment.sample_lanes(*u);
            for (lane, &k) in group.iter().enumerate() {
                let p = &mut vertices[k];
                p.light = e.get(lane).and_then(|s| pending_light(tracer, &p.sp, s.with_selection(select_pdf[lane])));
            }
        };
        for k in 0..self.vertices.len() {
            if let Some((draw_u, draw_select_pdf)) = self.vertices[k].environment_draw {
                group[filled] = k;
                u.set(filled, draw_u);
                select_pdf[filled] = draw_select_pdf;
                filled += 1;
                if filled == LANES {
                    flush(&mut self.vertices, &u, &select_pdf, &group);
                    filled = 0;
                }
            }
        }
        if filled > 0 {
            flush(&mut self.vertices, &u, &select_pdf, &group[..filled]);
        }
    }

    /// The BSDF densities the vertices need (a weighed light sample's, the BSDF sample's),
    /// [`LANES`] at a time ([`TabulatedSampler::pdf_in_lanes`]: the bits of `pdf_in`).
    fn densities(&mut self) {
        let Self { vertices, materials, .. } = self;
        // (vertex, whether it is the light sample's) per lane of the next group.
        let mut group: [(usize, bool); LANES] = [(0, false); LANES];
        let mut samplers: [Option<(&TabulatedSampler, SamplerView)>; LANES] = [None; LANES];
        let mut wi = Vec3s::default();
        let mut filled = 0;
        let flush = |vertices: &mut Vec<Pending>, samplers: &mut [Option<(&TabulatedSampler, SamplerView)>; LANES], wi: &Vec3s, group: &[(usize, bool)]| {
            let pdfs = TabulatedSampler::pdf_in_lanes(samplers, *wi);
            for (&(k, is_light), pdf) in group.iter().zip(pdfs) {
                let p = &mut vertices[k];
                match (is_light, &mut p.light, &mut p.sample) {
                    (true, Some(light), _) => light.pdf = pdf,
                    (false, _, Some(sample)) => sample.pdf = pdf,
                    _ => unreachable!("a density is asked only for a sample that exists"),
                }
            }
            *samplers = [None; LANES];
        };
        for k in 0..vertices.len() {
            let p = &vertices[k];
            let (sampler, view) = (materials[p.material as usize].bsdf.sampler(), p.view);
            let wanted = [p.light.filter(|l| l.weighed).map(|l| (true, l.wi)), p.sample.map(|s| (false, s.wi))];
            for (is_light, direction) in wanted.into_iter().flatten() {
                group[filled] = (k, is_light);
                samplers[filled] = Some((sampler, view));
                wi.set(filled, direction);
                filled += 1;
                if filled == LANES {
                    flush(vertices, &mut samplers, &wi, &group);
                    filled = 0;
                }
            }
        }
        if filled > 0 {
            flush(vertices, &mut samplers, &wi, &group[..filled]);
        }
    }

    /// Finds the densities, prepares and evaluates every value, one call per material, and
    /// scatters the vertices, calling `settle` with each one's path, position and result in
    /// the order they were pushed.
    pub fn scatter(&mut self, tracer: &PathTracer, mut settle: impl FnMut(u32, Vec3, Scattered)) {
        self.draw_environment(tracer);
        self.densities();
        let Self { vertices, materials, .. } = self;
        for p in vertices.iter_mut() {
            let m = &mut materials[p.material as usize];
            let mut add = |wi: Vec3| {
                let point = m.bsdf.prepare(p.wo, wi)?;
                m.points.push(point);
                Some(Slot {
                    material: p.material,
                    point: m.points.len() as u32 - 1,
                })
            };
            if let Some(light) = &mut p.light {
                light.slot = add(light.wi);
            }
            if let Some(sample) = &mut p.sample {
                sample.slot = if sample.pdf > 0.0 && sample.pdf.is_finite() { add(sample.wi) } else { None };
            }
        }
        for m in materials.iter_mut() {
            m.values.clear();
            m.values.resize(m.points.len(), Rgb::ZERO);
            m.bsdf.eval_prepared(&m.points, &mut m.values);
        }
        let value = |slot: Slot| materials[slot.material as usize].values[slot.point as usize];
        for p in vertices.iter() {
            let scattered = Scattered {
                shadow: p.light.and_then(|l| tracer.light_contribution(&p.sp, p.beta, &l.ls, l.wi, value(l.slot?), l.pdf)),
                next: p
                    .sample
                    .and_then(|s| continuation(&p.sp, &BsdfSample::new(s.wi, value(s.slot?), s.pdf), p.beta)),
            };
            settle(p.path, p.sp.p, scattered);
        }
    }
}

/// The pending light sample of light sample `ls` at `sp` (`PathTracer::light_term` up to
/// the BSDF's value and density); `None` where the light is below the geometric surface.
#[inline]
fn pending_light(tracer: &PathTracer, sp: &SurfacePoint, ls: LightSample) -> Option<PendingLight> {
    let wi = light_direction(sp, &ls, false)?;
    Some(PendingLight { ls, wi, weighed: tracer.weighs_light_sample(&ls), pdf: 0.0, slot: None })
}
