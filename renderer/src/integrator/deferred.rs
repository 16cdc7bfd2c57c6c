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
use crate::bsdf::mixture::{Mixture, Part};
use crate::bsdf::{BatchEval, BsdfSample};
use crate::scene::MAX_MIX_PARTS;
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
    /// Its BSDF's parts (the first `count`; one of weight 1 for a BSDF that is not a
    /// [`Mixture`]) and the tint multiplying their mixed value (`None`: none).
    parts: [PendingPart; MAX_MIX_PARTS],
    count: u8,
    tint: Option<Rgb>,
    light: Option<PendingLight>,
    /// The u and selection probability of an environment sample still to draw (`light` is
    /// `None` until then).
    environment_draw: Option<(Vec2, f32)>,
    sample: Option<PendingSample>,
}

/// A part of a vertex's BSDF: the index of its material in [`DeferredScatter::materials`],
/// its weight and the sampler's view of wo.
#[derive(Clone, Copy, Debug)]
struct PendingPart {
    material: u32,
    weight: f32,
    view: SamplerView,
}

/// A vertex's parts ([`Pending`]'s fields) and its BSDF sample's direction, as drawn.
struct Drawn {
    parts: [PendingPart; MAX_MIX_PARTS],
    count: u8,
    tint: Option<Rgb>,
    sample: Option<Vec3>,
}

/// Where the values of a direction are, one per part (`None`: zero, below the horizon).
type Slots = Option<[Slot; MAX_MIX_PARTS]>;

/// A vertex's light sample: its direction (local frame), whether MIS weighs it (and so needs
/// the BSDF's density of that direction), and, filled in by [`DeferredScatter::scatter`], that
/// density and where the BSDF's values are.
#[derive(Clone, Copy, Debug)]
struct PendingLight {
    ls: LightSample,
    wi: Vec3,
    weighed: bool,
    pdf: f32,
    slots: Slots,
}

/// A vertex's BSDF sample: its direction (local frame) and, filled in by
/// [`DeferredScatter::scatter`], its density and where its values are (`None`: the sample is
/// dropped, its density not positive and finite or its value zero).
#[derive(Clone, Copy, Debug)]
struct PendingSample {
    wi: Vec3,
    pdf: f32,
    slots: Slots,
}

/// The BSDFs of a kind among the parts of a [`Mixture`].
pub(super) trait MixturePart<'s>: Sized {
    fn of(part: Part<'s>) -> Option<&'s Self>;
}

impl<'s> MixturePart<'s> for crate::bsdf::neural::NeuralBsdf {
    fn of(part: Part<'s>) -> Option<&'s Self> {
        match part {
            Part::Neural(b) => Some(b),
            _ => None,
        }
    }
}

impl<'s> MixturePart<'s> for crate::bsdf::nbrdf::NbrdfBsdf {
    fn of(part: Part<'s>) -> Option<&'s Self> {
        match part {
            Part::Nbrdf(b) => Some(b),
            _ => None,
        }
    }
}

impl<'s> MixturePart<'s> for crate::bsdf::merl::MerlBsdf {
    fn of(part: Part<'s>) -> Option<&'s Self> {
        match part {
            Part::Merl(b) => Some(b),
            _ => None,
        }
    }
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

    /// The index of `bsdf` in [`Self::materials`], added if it is not there.
    fn material(&mut self, bsdf: &'s B) -> u32 {
        let k = match self.materials.iter().position(|m| std::ptr::eq(m.bsdf, bsdf)) {
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
        k as u32
    }

    /// Draws vertex `v`'s light and BSDF samples (on `bsdf`, its BSDF) for path `path` of
    /// throughput `beta`; [`Self::scatter`] finishes it.
    pub fn push(&mut self, tracer: &PathTracer, scene: &'s RenderScene, path: u32, v: &Vertex, bsdf: &'s B, beta: Rgb) {
        let material = self.material(bsdf);
        // Both the sample and the densities read the sampler's view of wo, found once.
        let view = bsdf.sampler().view(v.wo);
        let sample = bsdf.sampler().sample_in(&view, v.u, v.uc);
        let part = PendingPart { material, weight: 1.0, view };
        self.push_parts(tracer, scene, path, v, beta, Drawn { parts: [part; MAX_MIX_PARTS], count: 1, tint: None, sample });
    }

    /// [`Self::push`] for a vertex whose BSDF is `mixture`; `false` (and nothing pushed)
    /// where one of its parts is not a `B`.
    pub fn push_mixture(&mut self, tracer: &PathTracer, scene: &'s RenderScene, path: u32, v: &Vertex, mixture: &Mixture<'s>, beta: Rgb) -> bool
    where
        B: MixturePart<'s>,
    {
        let mut bsdfs = [None; MAX_MIX_PARTS];
        for (k, (part, _)) in mixture.parts().enumerate() {
            match B::of(part) {
                Some(b) => bsdfs[k] = Some(b),
                None => return false,
            }
        }
        let mut parts = [PendingPart { material: 0, weight: 0.0, view: SamplerView::default() }; MAX_MIX_PARTS];
        let mut count = 0;
        for (k, (_, weight)) in mixture.parts().enumerate() {
            let bsdf = bsdfs[k].expect("every part is a B");
            parts[k] = PendingPart { material: self.material(bsdf), weight, view: bsdf.sampler().view(v.wo) };
            count += 1;
        }
        // As `Mixture::sample`: the part chosen by uc draws the direction.
        let (chosen, uc) = mixture.choose(v.uc);
        let sample = bsdfs[chosen].expect("a part").sampler().sample_in(&parts[chosen].view, v.u, uc);
        self.push_parts(tracer, scene, path, v, beta, Drawn { parts, count, tint: Some(mixture.tint()), sample });
        true
    }

    /// Pushes a vertex with its parts and its BSDF sample's direction.
    fn push_parts(&mut self, tracer: &PathTracer, scene: &'s RenderScene, path: u32, v: &Vertex, beta: Rgb, Drawn { parts, count, tint, sample }: Drawn) {
        // As `PathTracer::light_term` and `Bxdf::sample` of a tabulated BSDF, with the
        // densities (and the values) left to `scatter`.
        let environment_draw = tracer.environment_draw(scene, v);
        let light = match environment_draw {
            Some((environment, ..)) => {
                self.environment = Some(environment);
                None
            }
            None => tracer.light_sample(scene, v).and_then(|ls| pending_light(tracer, &v.sp, ls)),
        };
        self.vertices.push(Pending {
            path,
            sp: v.sp,
            beta,
            wo: v.wo,
            parts,
            count,
            tint,
            light,
            environment_draw: environment_draw.map(|(_, u, select_pdf)| (u, select_pdf)),
            sample: sample.map(|wi| PendingSample { wi, pdf: 0.0, slots: None }),
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
        let mut group: [(usize, bool, f32); LANES] = [(0, false, 0.0); LANES];
        let mut samplers: [Option<(&TabulatedSampler, SamplerView)>; LANES] = [None; LANES];
        let mut wi = Vec3s::default();
        let mut filled = 0;
        // Each part's density weighed by the part's weight, summed in the parts' order (the
        // lanes are flushed in the order they were filled), as `Mixture::eval_pdf` sums.
        let flush = |vertices: &mut Vec<Pending>, samplers: &mut [Option<(&TabulatedSampler, SamplerView)>; LANES], wi: &Vec3s, group: &[(usize, bool, f32)]| {
            let pdfs = TabulatedSampler::pdf_in_lanes(samplers, *wi);
            for (&(k, is_light, weight), pdf) in group.iter().zip(pdfs) {
                let p = &mut vertices[k];
                match (is_light, &mut p.light, &mut p.sample) {
                    (true, Some(light), _) => light.pdf += weight * pdf,
                    (false, _, Some(sample)) => sample.pdf += weight * pdf,
                    _ => unreachable!("a density is asked only for a sample that exists"),
                }
            }
            *samplers = [None; LANES];
        };
        for k in 0..vertices.len() {
            let p = &vertices[k];
            let (parts, count) = (p.parts, p.count as usize);
            let wanted = [p.light.filter(|l| l.weighed).map(|l| (true, l.wi)), p.sample.map(|s| (false, s.wi))];
            for (is_light, direction) in wanted.into_iter().flatten() {
                for part in &parts[..count] {
                    group[filled] = (k, is_light, part.weight);
                    samplers[filled] = Some((materials[part.material as usize].bsdf.sampler(), part.view));
                    wi.set(filled, direction);
                    filled += 1;
                    if filled == LANES {
                        flush(vertices, &mut samplers, &wi, &group);
                        filled = 0;
                    }
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
            let (wo, parts) = (p.wo, &p.parts[..p.count as usize]);
            // Every part's value of `wi` prepared; none where one is zero without evaluation
            // (below a horizon, the same for every part).
            let mut add = |wi: Vec3| -> Slots {
                let mut slots = [Slot { material: 0, point: 0 }; MAX_MIX_PARTS];
                for (slot, part) in slots.iter_mut().zip(parts) {
                    let m = &mut materials[part.material as usize];
                    m.points.push(m.bsdf.prepare(wo, wi)?);
                    *slot = Slot { material: part.material, point: m.points.len() as u32 - 1 };
                }
                Some(slots)
            };
            if let Some(light) = &mut p.light {
                light.slots = add(light.wi);
            }
            if let Some(sample) = &mut p.sample {
                sample.slots = if sample.pdf > 0.0 && sample.pdf.is_finite() { add(sample.wi) } else { None };
            }
        }
        for m in materials.iter_mut() {
            m.values.clear();
            m.values.resize(m.points.len(), Rgb::ZERO);
            m.bsdf.eval_prepared(&m.points, &mut m.values);
        }
        // The BSDF's value: its parts' values weighed and summed in order, then tinted (as
        // `Mixture::eval_pdf`); one part of weight 1 gives its value's bits.
        let value = |p: &Pending, slots: Slots| -> Option<Rgb> {
            let slots = slots?;
            let mut f = Rgb::ZERO;
            for (part, slot) in p.parts[..p.count as usize].iter().zip(slots) {
                f += part.weight * materials[slot.material as usize].values[slot.point as usize];
            }
            Some(p.tint.map_or(f, |tint| tint * f))
        };
        for p in vertices.iter() {
            let scattered = Scattered {
                shadow: p.light.and_then(|l| tracer.light_contribution(&p.sp, p.beta, &l.ls, l.wi, value(p, l.slots)?, l.pdf)),
                next: p
                    .sample
                    .and_then(|s| continuation(&p.sp, &BsdfSample::new(s.wi, value(p, s.slots)?, s.pdf), p.beta)),
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
    Some(PendingLight { ls, wi, weighed: tracer.weighs_light_sample(&ls), pdf: 0.0, slots: None })
}
