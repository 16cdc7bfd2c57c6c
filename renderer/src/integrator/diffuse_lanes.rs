//! [`PathTracer::scatter`] for [`LANES`] vertices at once, for the most common vertex: a
//! Lambertian surface whose chosen light is an emissive triangle.
//!
//! The kernel evaluates the very formulas of the scalar path — [`TriangleLight::sample`],
//! [`Lambert`]'s `eval_pdf` and `sample`, the power heuristic, [`offset_ray_origin`], the
//! frame conversions — in the same order, with masks where the scalar code returns early,
//! so each lane's result is bit for bit what `scatter` gives (the batched render test checks
//! this against paths traced one by one). Compiled for AVX-512 or AVX2 where the CPU has them
//! ([`super::scattered_lanes::scatter`]).
//!
//! [`PathTracer::scatter`]: super::PathTracer
//! [`TriangleLight::sample`]: crate::lights::area::TriangleLight::sample
//! [`Lambert`]: crate::bsdf::Lambert
//! [`offset_ray_origin`]: crate::accel::offset_ray_origin

use super::scattered_lanes::{offset_ray_origin, power_heuristic, LaneKernel, ScatteredLanes};
use super::{Vertex, SHADOW_EPSILON};
use crate::accel::gamma;
use crate::lanes::{F32s, Vec2s, Vec3s, LANES};
use crate::lights::area::TriangleLight;
use crate::sampling::sample_cosine_hemisphere_lanes;
use crate::Rgb;
use std::f32::consts::FRAC_1_PI;

/// Up to [`LANES`] diffuse vertices lit by a triangle light, in structure-of-arrays form.
#[derive(Clone, Debug, Default)]
pub(crate) struct DiffuseLanes {
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
    corners: [Vec3s; 3],
    light_normal: Vec3s,
    light_area: F32s,
    light_radiance: Vec3s,
    select_pdf: F32s,
    u_light: Vec2s,
    u: Vec2s,
}

impl DiffuseLanes {
    /// Appends a vertex with Lambertian albedo `albedo`, throughput `beta`, whose chosen
    /// light is `light` (selected with probability `select_pdf`).
    ///
    /// # Panics
    /// When all lanes are filled.
    #[inline]
    pub fn push(&mut self, vertex: &Vertex, albedo: Rgb, beta: Rgb, light: &TriangleLight, select_pdf: f32) {
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
        for (c, &corner) in self.corners.iter_mut().zip(&light.corners) {
            c.set(i, corner);
        }
        self.light_normal.set(i, light.normal);
        self.light_area.0[i] = light.area;
        self.light_radiance.set(i, light.radiance);
        self.select_pdf.0[i] = select_pdf;
        self.u_light.set(i, vertex.u_light);
        self.u.set(i, vertex.u);
        self.len += 1;
    }
}

impl LaneKernel for DiffuseLanes {
    fn len(&self) -> usize {
        self.len
    }

    fn clear(&mut self) {
        self.len = 0;
    }

    /// Scatters all lanes (the filled ones matter): next-event estimation toward the
    /// triangle light, weighted by the power heuristic or, with `light_only`, by 1; and a
    /// cosine-weighted continuation.
    #[inline(always)]
    fn scatter_lanes(&self, light_only: bool, out: &mut ScatteredLanes) {
        let zero = F32s::splat(0.0);
        let (p, p_error, ng, beta) = (self.p, self.p_error, self.ng, self.beta);

        // The light point: TriangleLight::sample (uniform by area, Heitz's mapping).
        let (ux, uy) = (self.u_light.x, self.u_light.y);
        let lower = ux.lt(uy);
        let b0 = lower.select(ux * 0.5, ux - uy * 0.5);
        let b1 = lower.select(uy - ux * 0.5, uy * 0.5);
        let (bx, by) = (b1, 1.0 - b0 - b1);
        let w0 = 1.0 - bx - by;
        let [v0, v1, v2] = self.corners;
        let q = v0 * w0 + v1 * bx + v2 * by;
        let q_error = ((v0 * w0).abs() + (v1 * bx).abs() + (v2 * by).abs()) * gamma(7.0);
        let to = q - p;
        let d2 = to.dot(to);
        let distance = d2.sqrt();
        let direction = to / distance;
        let cos_light = -direction.dot(self.light_normal);
        let area_pdf = d2 / (cos_light * self.light_area);
        let light_ok = !d2.le(zero) & !cos_light.le(zero) & area_pdf.is_finite();
        let shadow_target = offset_ray_origin(q, q_error, self.light_normal, -direction);
        let light_pdf = area_pdf * self.select_pdf;

        // Next-event estimation (PathTracer::light_term with Lambert::eval_pdf).
        let wi_z = direction.dot(self.n);
        let f = self.albedo * FRAC_1_PI;
        let bsdf_pdf = wi_z.max(zero) * FRAC_1_PI;
        let shadow_ok = light_ok & direction.dot(ng).gt(zero) & wi_z.gt(zero) & f.max_element().gt(zero);
        let origin = offset_ray_origin(p, p_error, ng, direction);
        let w = if light_only {
            F32s::splat(1.0)
        } else {
            power_heuristic(light_pdf, bsdf_pdf)
        };
        out.shadow_ok = shadow_ok.0;
        out.shadow_origin = origin;
        out.shadow_direction = shadow_target - origin;
        out.shadow_t_max = F32s::splat(1.0 - SHADOW_EPSILON);
        out.contribution = beta * f * self.light_radiance * (wi_z * w / light_pdf);

        // BSDF sampling (Lambert::sample: cosine-weighted, concentric disk).
        let Vec3s { x: dx, y: dy, z: dz } = sample_cosine_hemisphere_lanes(self.u);
        let pdf = dz.max(zero) * FRAC_1_PI;
        // continuation(): world direction, throughput, offset origin.
        let wi_world = self.s * dx + self.t * dy + self.n * dz;
        let next_beta = beta * (f * (dz / pdf));
        let next_ok =
            !dz.le(zero) & !wi_world.dot(ng).le(zero) & next_beta.is_finite() & !next_beta.max_element().le(zero);
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
    use crate::scene::SceneDescription;

    /// Every lane gives what the scalar `scatter` gives for its vertex, bit for bit, for
    /// full and partial groups, lights behind the surface, and zero throughputs.
    #[test]
    fn lanes_equal_scalar_scatter_bit_for_bit() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/cornell-box/scene.gltf");
        let scene = RenderScene::new(SceneDescription::load(path.as_ref()).expect("shipped scene")).expect("scene");
        let mut rng = Sampler::new(3, 1, 4);
        for strategy in [Strategy::Mis, Strategy::LightOnly] {
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
                let Some(vertex) = tracer.begin(&scene, &mut state, hit) else { continue };
                if let (Bsdf::Lambert(b), Some((light, select_pdf))) = (vertex.bsdf, vertex.light) {
                    let triangle = scene.lights.triangle(light).expect("the box's lights are triangles").clone();
                    cases.push((vertex, b.albedo, state.beta, triangle, select_pdf));
                }
            }
            let (mut lanes, mut out) = (DiffuseLanes::default(), ScatteredLanes::default());
            let (mut shadows, mut ended) = (0, 0);
            for group in cases.chunks(LANES) {
                lanes.clear();
                for (vertex, albedo, beta, light, select_pdf) in group {
                    lanes.push(vertex, *albedo, *beta, light, *select_pdf);
                }
                crate::integrator::scattered_lanes::scatter(&lanes, strategy == Strategy::LightOnly, &mut out);
                for (lane, (vertex, _, beta, _, _)) in group.iter().enumerate() {
                    let expected = tracer.scatter(&scene, vertex, *beta);
                    assert_eq!(format!("{:?}", out.get(lane)), format!("{expected:?}"), "{strategy:?}, lane {lane}");
                    shadows += expected.shadow.is_some() as usize;
                    ended += expected.next.is_none() as usize;
                }
            }
            assert!(shadows > 0 && shadows < cases.len(), "both lit and unlit lanes: {shadows}");
            assert!(ended >= cases.len() / 8, "zero throughputs end: {ended}");
        }
    }
}
