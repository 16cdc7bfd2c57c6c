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
use crate::bsdf::layered::{checked_sample, Base, Choice, Draw, Layered, Layers};
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
    /// The layers above the parts ([`Layered`]) and their lobe choice at wo: the vertex's
    /// value and density are theirs over the parts' (`None`: no layers).
    layers: Option<(Layers, Choice)>,
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

/// A vertex's BSDF as the batch holds it: its parts ([`Pending`]'s fields) and the BSDFs
/// that draw their samples.
struct Parts<'s, B> {
    parts: [PendingPart; MAX_MIX_PARTS],
    count: u8,
    tint: Option<Rgb>,
    bsdfs: [Option<&'s B>; MAX_MIX_PARTS],
    /// The mixture that chooses the part drawing a sample (`None`: one part).
    mixture: Option<Mixture<'s>>,
}

impl<B: TabulatedBrdf> Parts<'_, B> {
    /// The direction `Bxdf::sample` of the parts draws from `u` and `uc` (a mixture's part
    /// chosen by `uc`, as `Mixture::sample`).
    fn draw(&self, u: Vec2, uc: f32) -> Option<Vec3> {
        let (chosen, uc) = self.mixture.map_or((0, uc), |m| m.choose(uc));
        let bsdf = self.bsdfs[chosen].expect("every part has its BSDF");
        bsdf.sampler().sample_in(&self.parts[chosen].view, u, uc)
    }
}

/// A vertex's BSDF as [`DeferredScatter::push_drawn`] takes it: its parts, the layers above
/// them with their lobe choice, and its sample's direction with whether a layer drew it.
struct Drawn<'s, B> {
    parts: Parts<'s, B>,
    layers: Option<(Layers, Choice)>,
    sample: Option<(Vec3, bool)>,
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
    /// Whether a layer above the parts drew it (their density may be zero there); else the
    /// parts drew it, and it is dropped where their density is not positive and finite.
    by_layer: bool,
    pdf: f32,
    slots: Slots,
}

/// The BSDFs of a kind among the parts of a [`Mixture`] and as the base of a [`Layered`].
pub(super) trait MixturePart<'s>: Sized {
    fn of(part: Part<'s>) -> Option<&'s Self>;
    fn of_base(base: Base<'s>) -> Option<&'s Self>;
}

impl<'s> MixturePart<'s> for crate::bsdf::neural::NeuralBsdf {
    fn of(part: Part<'s>) -> Option<&'s Self> {
        match part {
            Part::Neural(b) => Some(b),
            _ => None,
        }
    }

    fn of_base(base: Base<'s>) -> Option<&'s Self> {
        match base {
            Base::Neural(b) => Some(b),
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

    fn of_base(base: Base<'s>) -> Option<&'s Self> {
        match base {
            Base::Nbrdf(b) => Some(b),
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

    fn of_base(base: Base<'s>) -> Option<&'s Self> {
        match base {
            Base::Merl(b) => Some(b),
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

    /// The parts of a BSDF that is one `B`.
    fn single(&mut self, bsdf: &'s B, wo: Vec3) -> Parts<'s, B> {
        // Both the sample and the densities read the sampler's view of wo, found once.
        let part = PendingPart { material: self.material(bsdf), weight: 1.0, view: bsdf.sampler().view(wo) };
        let mut bsdfs = [None; MAX_MIX_PARTS];
        bsdfs[0] = Some(bsdf);
        Parts { parts: [part; MAX_MIX_PARTS], count: 1, tint: None, bsdfs, mixture: None }
    }

    /// The parts of `mixture`; `None` (and nothing added) where one of them is not a `B`.
    fn mixture(&mut self, mixture: &Mixture<'s>, wo: Vec3) -> Option<Parts<'s, B>>
    where
        B: MixturePart<'s>,
    {
        let mut bsdfs = [None; MAX_MIX_PARTS];
        for (k, (part, _)) in mixture.parts().enumerate() {
            bsdfs[k] = Some(B::of(part)?);
        }
        let mut parts = [PendingPart { material: 0, weight: 0.0, view: SamplerView::default() }; MAX_MIX_PARTS];
        let mut count = 0;
        for (k, (_, weight)) in mixture.parts().enumerate() {
            let bsdf = bsdfs[k].expect("every part is a B");
            parts[k] = PendingPart { material: self.material(bsdf), weight, view: bsdf.sampler().view(wo) };
            count += 1;
        }
        Some(Parts { parts, count, tint: Some(mixture.tint()), bsdfs, mixture: Some(*mixture) })
    }

    /// Draws vertex `v`'s light and BSDF samples (on `bsdf`, its BSDF) for path `path` of
    /// throughput `beta`; [`Self::scatter`] finishes it.
    pub fn push(&mut self, tracer: &PathTracer, scene: &'s RenderScene, path: u32, v: &Vertex, bsdf: &'s B, beta: Rgb) {
        let parts = self.single(bsdf, v.wo);
        let sample = parts.draw(v.u, v.uc).map(|wi| (wi, false));
        self.push_drawn(tracer, scene, path, v, beta, Drawn { parts, layers: None, sample });
    }

    /// [`Self::push`] for a vertex whose BSDF is `mixture`; `false` (and nothing pushed)
    /// where one of its parts is not a `B`.
    pub fn push_mixture(&mut self, tracer: &PathTracer, scene: &'s RenderScene, path: u32, v: &Vertex, mixture: &Mixture<'s>, beta: Rgb) -> bool
    where
        B: MixturePart<'s>,
    {
        let Some(parts) = self.mixture(mixture, v.wo) else { return false };
        let sample = parts.draw(v.u, v.uc).map(|wi| (wi, false));
        self.push_drawn(tracer, scene, path, v, beta, Drawn { parts, layers: None, sample });
        true
    }

    /// [`Self::push`] for a vertex whose BSDF is `layered`, over a `B` or a mixture of them;
    /// `false` (and nothing pushed) over any other base. Its sample is drawn as
    /// `Layered::sample` draws it, and its values and densities are the layers' over the
    /// base's, found in the batch.
    pub fn push_layered(&mut self, tracer: &PathTracer, scene: &'s RenderScene, path: u32, v: &Vertex, layered: &Layered<'s>, beta: Rgb) -> bool
    where
        B: MixturePart<'s>,
    {
        if v.wo.z <= 0.0 {
            return false;
        }
        let parts = match *layered.base() {
            Base::Mixture(m) => self.mixture(&m, v.wo),
            base => B::of_base(base).map(|b| self.single(b, v.wo)),
        };
        let Some(parts) = parts else { return false };
        let layers = *layered.layers();
        let at = layers.choice(v.wo);
        let sample = match layers.draw(at, v.wo, v.u, v.uc) {
            Draw::Layer(wi) => wi.map(|wi| (wi, true)),
            Draw::Base(uc) => parts.draw(v.u, uc).map(|wi| (wi, false)),
        };
        self.push_drawn(tracer, scene, path, v, beta, Drawn { parts, layers: Some((layers, at)), sample });
        true
    }

    /// Pushes a vertex with its BSDF as drawn.
    fn push_drawn(&mut self, tracer: &PathTracer, scene: &'s RenderScene, path: u32, v: &Vertex, beta: Rgb, drawn: Drawn<'s, B>) {
        let Drawn { parts: Parts { parts, count, tint, .. }, layers, sample } = drawn;
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
            layers,
            light,
            environment_draw: environment_draw.map(|(_, u, select_pdf)| (u, select_pdf)),
            sample: sample.map(|(wi, by_layer)| PendingSample { wi, by_layer, pdf: 0.0, slots: None }),
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
                // A layer's sample may lie where the parts' density is zero; their value
                // still counts.
                sample.slots = if sample.by_layer || (sample.pdf > 0.0 && sample.pdf.is_finite()) { add(sample.wi) } else { None };
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
            let scattered = match p.layers {
                None => Scattered {
                    shadow: p.light.and_then(|l| tracer.light_contribution(&p.sp, p.beta, &l.ls, l.wi, value(p, l.slots)?, l.pdf)),
                    next: p
                        .sample
                        .and_then(|s| continuation(&p.sp, &BsdfSample::new(s.wi, value(p, s.slots)?, s.pdf), p.beta)),
                },
                // As `Layered::eval_pdf` and `Layered::sample`: the layers over the parts'
                // value (zero below the horizon) and density.
                Some((layers, at)) => {
                    let layer = |wi: Vec3, slots: Slots, pdf: f32| layers.layer(at, p.wo, wi, (value(p, slots).unwrap_or(Rgb::ZERO), pdf));
                    Scattered {
                        shadow: p.light.and_then(|l| {
                            let (f, pdf) = layer(l.wi, l.slots, l.pdf);
                            tracer.light_contribution(&p.sp, p.beta, &l.ls, l.wi, f, pdf)
                        }),
                        next: p
                            .sample
                            .filter(|s| s.by_layer || s.slots.is_some())
                            .and_then(|s| continuation(&p.sp, &checked_sample(s.wi, layer(s.wi, s.slots, s.pdf))?, p.beta)),
                    }
                }
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
