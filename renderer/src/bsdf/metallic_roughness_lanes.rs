//! [`MetallicRoughness`] for [`LANES`] shading points at once, each with its own material:
//! the value, density and sample of the scalar BSDF written with [`crate::lanes`] types, the
//! same formulas in the same order, with masks where the scalar code returns early. Each lane
//! gives the scalar result bit for bit (tested below); the path tracer's lane kernel
//! ([`crate::integrator`]) scatters metallic-roughness vertices with it.
//!
//! Conventions are those of [`crate::bsdf`]: local shading frame, z the normal, `wo` and
//! `wi` unit vectors pointing away from the surface, values in 1/sr without the cosine,
//! densities in 1/sr.

use super::metallic_roughness::{MetallicRoughness, MIN_LOBE_PROBABILITY};
use crate::color::LUMINANCE_WEIGHTS;
use crate::lanes::{F32s, Mask, Vec2s, Vec3s, LANES};
use crate::sampling::{sample_cosine_hemisphere_lanes, sin_cos_turns_lanes};
use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, PI};

/// The parameters of up to [`LANES`] metallic-roughness materials, as the scalar methods
/// derive them (structure of arrays).
#[derive(Clone, Debug, Default)]
pub(crate) struct MetallicRoughnessLanes {
    /// GGX roughness α (isotropic, clamped as [`super::microfacet::GgxDistribution`] does).
    alpha: F32s,
    /// Reflectance at normal and at grazing incidence of the specular lobe.
    f0: Vec3s,
    f90: F32s,
    /// The dielectric's transmittance T(μ) = `t_base` − `t_slope` (1 − μ)⁵.
    t_base: Vec3s,
    t_slope: Vec3s,
    /// (1 − metallic) · base colour.
    diffuse_color: Vec3s,
    /// The diffuse normalisation divided by π.
    diffuse_scale_over_pi: Vec3s,
}

/// A BSDF sample per lane: where `ok`, the direction, value and density of
/// [`super::Bxdf::sample`]'s result.
pub(crate) struct SampleLanes {
    pub ok: Mask,
    pub wi: Vec3s,
    pub f: Vec3s,
    pub pdf: F32s,
}

impl MetallicRoughnessLanes {
    /// Sets lane `i` to `bsdf`.
    #[inline]
    pub fn set(&mut self, i: usize, bsdf: &MetallicRoughness) {
        self.alpha.0[i] = bsdf.distribution().alpha_x();
        self.f0.set(i, bsdf.f0());
        self.f90.0[i] = bsdf.f90();
        self.t_base.set(i, Vec3::ONE - bsdf.dielectric_f0);
        self.t_slope.set(i, Vec3::splat(bsdf.dielectric_f90) - bsdf.dielectric_f0);
        self.diffuse_color.set(i, bsdf.diffuse_color());
        self.diffuse_scale_over_pi.set(i, bsdf.diffuse_scale() * FRAC_1_PI);
    }

    /// The specular lobe's Fresnel factor F0 + (F90 − F0)(1 − cos θ)⁵.
    #[inline(always)]
    fn fresnel(&self, cos_theta: F32s) -> Vec3s {
        let f90 = Vec3s { x: self.f90, y: self.f90, z: self.f90 };
        self.f0 + (f90 - self.f0) * schlick_weight(cos_theta)
    }

    /// The dielectric's transmittance at the macroscopic cosine `cos_theta`.
    #[inline(always)]
    fn transmittance(&self, cos_theta: F32s) -> Vec3s {
        self.t_base - self.t_slope * schlick_weight(cos_theta)
    }

    /// [`MetallicRoughness::specular_probability`]: depends on `wo` only, so a vertex's light
    /// evaluation and BSDF sample share it.
    #[inline(always)]
    pub fn specular_probability(&self, wo: Vec3s) -> F32s {
        let zero = F32s::splat(0.0);
        let cos_o = clamp(wo.z, 0.0, 1.0);
        let specular = luminance(self.fresnel(cos_o));
        let diffuse = luminance(self.diffuse_color * self.transmittance(cos_o)) * super::metallic_roughness::DIFFUSE_RETURN;
        let total = specular + diffuse;
        let p = total.gt(zero).select(specular / total, F32s::splat(0.5));
        let p = clamp(p, MIN_LOBE_PROBABILITY, 1.0 - MIN_LOBE_PROBABILITY);
        self.diffuse_color.max_element().le(zero).select(F32s::splat(1.0), p)
    }

    /// f_r for directions above the horizon with half vector `h`.
    #[inline(always)]
    fn value(&self, wo: Vec3s, wi: Vec3s, h: Vec3s) -> Vec3s {
        let specular = self.fresnel(wo.dot(h)) * (self.d(h) * self.visibility(wo, wi));
        let transmittance = self.transmittance(wo.z) * self.transmittance(wi.z);
        specular + self.diffuse_color * transmittance * self.diffuse_scale_over_pi
    }

    /// The mixture density for directions above the horizon, with the specular probability
    /// `p_specular` and the half vector `h` (where `has_half`: [`half_vector`]).
    #[inline(always)]
    fn density(&self, p_specular: F32s, wo: Vec3s, wi: Vec3s, h: Vec3s, has_half: Mask) -> F32s {
        let cosine_pdf = wi.z.max(F32s::splat(0.0)) * FRAC_1_PI;
        p_specular * self.reflection_pdf(wo, wi, h, has_half) + (1.0 - p_specular) * cosine_pdf
    }

    /// [`super::Bxdf::eval_pdf`]: value and density, with `p_specular` =
    /// [`Self::specular_probability`] of `wo`.
    #[inline(always)]
    pub fn eval_pdf(&self, p_specular: F32s, wo: Vec3s, wi: Vec3s) -> (Vec3s, F32s) {
        let zero = F32s::splat(0.0);
        let above = wo.z.gt(zero) & wi.z.gt(zero);
        let (h, has_half) = half_vector(wo, wi);
        let f = self.value(wo, wi, h);
        let pdf = self.density(p_specular, wo, wi, h, has_half);
        (above.select3(f, Vec3s::default()), above.select(pdf, zero))
    }

    /// [`super::Bxdf::sample`]: the specular lobe (visible normals) where `uc` is below
    /// `p_specular` ([`Self::specular_probability`] of `wo`), the cosine-weighted diffuse
    /// lobe elsewhere.
    #[inline(always)]
    pub fn sample(&self, p_specular: F32s, wo: Vec3s, u: Vec2s, uc: F32s) -> SampleLanes {
        let zero = F32s::splat(0.0);
        let specular = uc.lt(p_specular) | p_specular.ge(F32s::splat(1.0));
        let reflected = reflect(wo, self.sample_visible_normal(wo, u));
        let diffuse = sample_cosine_hemisphere_lanes(u);
        let wi = specular.select3(reflected, diffuse);
        let (h, has_half) = half_vector(wo, wi);
        let pdf = self.density(p_specular, wo, wi, h, has_half);
        let ok = wo.z.gt(zero) & wi.z.gt(zero) & pdf.gt(zero) & pdf.is_finite();
        SampleLanes {
            ok,
            wi,
            f: self.value(wo, wi, h),
            pdf,
        }
    }

    /// [`super::microfacet::GgxDistribution::d`].
    #[inline(always)]
    fn d(&self, h: Vec3s) -> F32s {
        let a = self.alpha;
        let sx = h.x / a;
        let sy = h.y / a;
        let e = sx * sx + sy * sy + h.z * h.z;
        let d = 1.0 / (PI * a * a * e * e);
        h.z.le(F32s::splat(0.0)).select(F32s::splat(0.0), d)
    }

    /// [`super::microfacet::GgxDistribution`]'s projected length √(w.z² + α² |w_xy|²).
    #[inline(always)]
    fn projected_length(&self, w: Vec3s) -> F32s {
        let ax = self.alpha * w.x;
        let ay = self.alpha * w.y;
        (w.z * w.z + ax * ax + ay * ay).sqrt()
    }

    /// [`super::microfacet::GgxDistribution::visibility`].
    #[inline(always)]
    fn visibility(&self, wo: Vec3s, wi: Vec3s) -> F32s {
        let denominator = wi.z.abs() * self.projected_length(wo) + wo.z.abs() * self.projected_length(wi);
        0.5 / denominator.max(F32s::splat(super::microfacet::MIN_VISIBILITY_DENOMINATOR))
    }

    /// [`super::microfacet::GgxDistribution::reflection_pdf`], given the half vector `h`
    /// (where `has_half`).
    #[inline(always)]
    fn reflection_pdf(&self, wo: Vec3s, wi: Vec3s, h: Vec3s, has_half: Mask) -> F32s {
        let zero = F32s::splat(0.0);
        let pdf = self.d(h) / (2.0 * (wo.z + self.projected_length(wo)));
        (has_half & !wo.z.lt(zero) & wi.z.gt(zero)).select(pdf, zero)
    }

    /// [`super::microfacet::GgxDistribution::sample_visible_normal`].
    #[inline(always)]
    fn sample_visible_normal(&self, wo: Vec3s, u: Vec2s) -> Vec3s {
        let zero = F32s::splat(0.0);
        let a = self.alpha;
        let wo_std = Vec3s { x: wo.x * a, y: wo.y * a, z: wo.z.max(zero) }.normalize_or(Vec3::Z);
        let (sin_phi, cos_phi) = sin_cos_turns_lanes(u.x);
        let z = (1.0 - u.y) * (1.0 + wo_std.z) - wo_std.z;
        let sin_theta = (1.0 - z * z).max(zero).sqrt();
        let h_std = Vec3s { x: sin_theta * cos_phi, y: sin_theta * sin_phi, z } + wo_std;
        Vec3s { x: h_std.x * a, y: h_std.y * a, z: h_std.z.max(zero) }.normalize_or(Vec3::Z)
    }
}

/// [`super::microfacet::half_vector`] per lane: normalize(wo + wi) where it exists (the
/// mask), +z elsewhere, as the scalar code's `unwrap_or(Vec3::Z)`.
#[inline(always)]
fn half_vector(wo: Vec3s, wi: Vec3s) -> (Vec3s, Mask) {
    let (h, has_half) = (wo + wi).try_normalize();
    (has_half.select3(h, Vec3s::splat(Vec3::Z)), has_half)
}

/// [`super::microfacet::schlick_weight`] per lane.
#[inline(always)]
fn schlick_weight(cos_theta: F32s) -> F32s {
    let m = clamp(1.0 - cos_theta, 0.0, 1.0);
    let m2 = m * m;
    m2 * m2 * m
}

/// [`super::microfacet::reflect`] per lane.
#[inline(always)]
fn reflect(w: Vec3s, n: Vec3s) -> Vec3s {
    n * (2.0 * w.dot(n)) - w
}

/// [`crate::color::luminance`] per lane.
#[inline(always)]
fn luminance(c: Vec3s) -> F32s {
    let [r, g, b] = LUMINANCE_WEIGHTS;
    r * c.x + g * c.y + b * c.z
}

/// `f32::clamp` per lane (NaN stays NaN).
#[inline(always)]
fn clamp(x: F32s, min: f32, max: f32) -> F32s {
    let x = x.lt(F32s::splat(min)).select(F32s::splat(min), x);
    x.gt(F32s::splat(max)).select(F32s::splat(max), x)
}

/// Whether `LANES` is what the kernels assume.
const _: () = assert!(LANES == 16);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::Bxdf;
    use crate::sampler::Sampler;
    use crate::sampling::sample_uniform_sphere;
    use crate::Rgb;
    use glam::Vec2;

    /// Bits of a vector, for comparisons that tell −0 from +0 and NaNs apart.
    fn bits(v: Vec3) -> [u32; 3] {
        v.to_array().map(f32::to_bits)
    }

    /// Every lane's value, density and sample equal the scalar BSDF's bit for bit, over
    /// materials from black dielectrics to mirrors (roughness 0), custom dielectric Fresnel,
    /// directions on and below the horizon, grazing views and NaN-free random ones.
    #[test]
    fn lanes_equal_the_scalar_bsdf_bit_for_bit() {
        let mut rng = Sampler::new(11, 2, 5);
        let mut materials = vec![
            MetallicRoughness::new(Rgb::new(0.95, 0.64, 0.54), 1.0, 0.3),
            MetallicRoughness::new(Rgb::ZERO, 0.0, 0.5),
            MetallicRoughness::new(Rgb::ONE, 0.0, 0.0),
            MetallicRoughness::new(Rgb::new(0.2, 0.5, 0.9), 0.4, 1.0),
            MetallicRoughness::new(Rgb::new(0.8, 0.8, 0.8), 0.0, 0.05).with_dielectric(Rgb::new(0.1, 0.02, 0.0), 0.7),
        ];
        while materials.len() < 64 {
            let c = rng.next_2d().extend(rng.next_1d());
            let m = MetallicRoughness::new(c, rng.next_1d().round(), rng.next_1d());
            materials.push(if materials.len() % 3 == 0 { m.with_dielectric(c * 0.3, rng.next_1d()) } else { m });
        }
        let mut lanes = MetallicRoughnessLanes::default();
        let (mut sampled, mut evaluated) = (0, 0);
        for round in 0..400 {
            let (mut wo, mut wi, mut u, mut uc) = (Vec3s::default(), Vec3s::default(), Vec2s::default(), F32s::default());
            let mut cases = Vec::new();
            for i in 0..LANES {
                let bsdf = materials[(round * LANES + i) % materials.len()];
                let mut o = sample_uniform_sphere(rng.next_2d());
                match i % 8 {
                    0 => o.z = o.z.abs(),
                    1 => o = Vec3::new(o.x, o.y, 1e-4).normalize(),
                    2 => o = Vec3::Z,
                    _ => o.z = o.z.abs().max(0.05),
                }
                let l = if i % 5 == 0 { Vec3::new(-o.x, -o.y, o.z) } else { sample_uniform_sphere(rng.next_2d()) };
                let (s, c) = (rng.next_2d(), rng.next_1d());
                lanes.set(i, &bsdf);
                wo.set(i, o);
                wi.set(i, l);
                u.set(i, s);
                uc.0[i] = c;
                cases.push((bsdf, o, l, s, c));
            }
            let p_specular = lanes.specular_probability(wo);
            let (f, pdf) = lanes.eval_pdf(p_specular, wo, wi);
            let sample = lanes.sample(p_specular, wo, u, uc);
            for (i, &(bsdf, o, l, s, c)) in cases.iter().enumerate() {
                let (ef, epdf) = bsdf.eval_pdf(o, l);
                assert_eq!((bits(f.get(i)), pdf.0[i].to_bits()), (bits(ef), epdf.to_bits()), "eval_pdf, lane {i}: {bsdf:?}");
                evaluated += (epdf > 0.0) as usize;
                let expected = bsdf.sample(o, Vec2::new(s.x, s.y), c);
                assert_eq!(sample.ok.0[i], expected.is_some(), "sample, lane {i}: {bsdf:?}, wo {o}");
                if let Some(e) = expected {
                    let got = (bits(sample.wi.get(i)), bits(sample.f.get(i)), sample.pdf.0[i].to_bits());
                    assert_eq!(got, (bits(e.wi), bits(e.f), e.pdf.to_bits()), "sample, lane {i}: {bsdf:?}");
                    sampled += 1;
                }
            }
        }
        assert!(sampled > 3000 && evaluated > 2000, "{sampled} samples, {evaluated} values");
    }
}
