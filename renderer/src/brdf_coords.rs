//! Rusinkiewicz (1998) half/difference coordinates: the one place where a pair of directions
//! (wi, wo) is converted to and from (θh, φh, θd, φd), to the three isotropic angles of the
//! MERL tables and to the 6D input of NBRDF networks.
//!
//! Conventions:
//! - Directions are unit vectors in the local shading frame (z = normal), `wi` toward the
//!   light, `wo` toward the viewer, both pointing away from the surface.
//! - h = normalize(wi + wo) with polar angle θh ∈ [0, π/2] (for directions above the horizon)
//!   and azimuth φh ∈ (−π, π]; d is `wi` rotated by −φh about z and then by −θh about y, so
//!   that h becomes +z; θd ∈ [0, π] is its polar angle and φd ∈ (−π, π] its azimuth.
//! - When h ≈ n (sin θh < [`PHI_H_GUARD`]) φh is undefined; it is taken as 0, which keeps
//!   every conversion finite and invertible.
//! - Reciprocity: swapping wi and wo keeps h and maps d to (−dx, −dy, dz), i.e. φd → φd + π.
//!   Folding φd into [0, π) (as the MERL tables do) therefore makes any function of the folded
//!   coordinates reciprocal. [`isotropic_angles`] and [`network_input`] fold.
//! - Angles are in radians.

use crate::lanes::{MaskOps, Real, V3};
use crate::trig::atan2;
use glam::Vec3;
use std::f32::consts::PI;

/// Below this sin θh the half vector is taken as the normal and φh as 0.
pub const PHI_H_GUARD: f32 = 1e-7;

/// Half vector and difference vector of a pair of directions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfDiff {
    /// h = normalize(wi + wo), local frame (z = normal).
    pub h: Vec3,
    /// `wi` expressed in the frame where h is +z (rotated by −φh about z, then −θh about y).
    pub d: Vec3,
    /// cos φh and sin φh of the rotation used (1 and 0 when h ≈ n).
    pub cos_sin_phi_h: (f32, f32),
}

/// The four Rusinkiewicz angles, radians.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfDiffAngles {
    /// Polar angle of h, [0, π].
    pub theta_h: f32,
    /// Azimuth of h, (−π, π]; 0 when h ≈ n.
    pub phi_h: f32,
    /// Polar angle of d (angle between wi and h), [0, π].
    pub theta_d: f32,
    /// Azimuth of d, (−π, π] (not folded).
    pub phi_d: f32,
}

/// Polar angle of a unit vector, accurate near both poles (atan2 rather than acos).
#[inline]
pub fn polar_angle(v: Vec3) -> f32 {
    polar_angle_of(V3::from(v))
}

/// [`polar_angle`] over [`Real`] values (one vector, or one per lane).
#[inline(always)]
fn polar_angle_of<R: Real>(v: V3<R>) -> R {
    atan2((v.x * v.x + v.y * v.y).sqrt(), v.z)
}

/// Half and difference vectors of (wi, wo). When wi = −wo (no half vector) h is taken as +z.
#[inline]
pub fn half_diff(wi: Vec3, wo: Vec3) -> HalfDiff {
    let (h, d, (cp, sp)) = half_diff_of(V3::from(wi), V3::from(wo));
    HalfDiff {
        h: h.into(),
        d: d.into(),
        cos_sin_phi_h: (cp, sp),
    }
}

/// [`half_diff`] over [`Real`] values (one pair, or one per lane): h, d and (cos φh, sin φh).
#[inline(always)]
fn half_diff_of<R: Real>(wi: V3<R>, wo: V3<R>) -> (V3<R>, V3<R>, (R, R)) {
    let (zero, one) = (R::splat(0.0), R::splat(1.0));
    let s = wi + wo;
    let len2 = s.dot(s);
    let len = len2.sqrt();
    let h = len2.gt(R::splat(1e-20)).select(V3::new(s.x / len, s.y / len, s.z / len), V3::new(zero, zero, one));
    let sin_h = (h.x * h.x + h.y * h.y).sqrt();
    let (cp, sp) = sin_h.gt(R::splat(PHI_H_GUARD)).select((h.x / sin_h, h.y / sin_h), (one, zero));
    // Rotate wi by −φh about z, then by −θh about y (cos θh = h.z, sin θh = sin_h).
    let x1 = cp * wi.x + sp * wi.y;
    let y1 = -sp * wi.x + cp * wi.y;
    let (ct, st) = (h.z, sin_h);
    let d = V3::new(ct * x1 - st * wi.z, y1, st * x1 + ct * wi.z);
    (h, d, (cp, sp))
}

/// The four angles of (wi, wo); φd is not folded.
#[inline]
pub fn half_diff_angles(wi: Vec3, wo: Vec3) -> HalfDiffAngles {
    let hd = half_diff(wi, wo);
    HalfDiffAngles {
        theta_h: polar_angle(hd.h),
        phi_h: atan2(hd.cos_sin_phi_h.1, hd.cos_sin_phi_h.0),
        theta_d: polar_angle(hd.d),
        phi_d: atan2(hd.d.y, hd.d.x),
    }
}

/// The directions (wi, wo) with the given angles: inverse of [`half_diff_angles`].
#[inline]
pub fn directions_from_angles(a: &HalfDiffAngles) -> (Vec3, Vec3) {
    let (sd, cd) = a.theta_d.sin_cos();
    let (spd, cpd) = a.phi_d.sin_cos();
    let d = Vec3::new(sd * cpd, sd * spd, cd);
    let (st, ct) = a.theta_h.sin_cos();
    let (sp, cp) = a.phi_h.sin_cos();
    let to_local = |v: Vec3| {
        // Rotate by θh about y, then by φh about z.
        let x1 = ct * v.x + st * v.z;
        let z1 = -st * v.x + ct * v.z;
        Vec3::new(cp * x1 - sp * v.y, sp * x1 + cp * v.y, z1)
    };
    (to_local(d), to_local(Vec3::new(-d.x, -d.y, d.z)))
}

/// Folds an azimuth φd into [0, π) (reciprocity: φd and φd + π describe the same pair with
/// wi and wo swapped).
#[inline]
pub fn fold_phi_d(phi_d: f32) -> f32 {
    let mut r = phi_d % PI;
    if r < 0.0 {
        r += PI;
    }
    if r >= PI {
        r -= PI;
    }
    r
}

/// Whether the difference vector must be replaced by (−dx, −dy, dz) to bring φd into [0, π).
#[inline(always)]
fn needs_fold<R: Real>(d: V3<R>) -> R::Mask {
    let zero = R::splat(0.0);
    d.y.lt(zero) | (d.y.eq(zero) & d.x.lt(zero))
}

/// The isotropic angles (θh, θd, φd) of (wi, wo) with φd folded into [0, π): the coordinates
/// of the MERL tables. Symmetric in wi and wo (up to rounding).
#[inline]
pub fn isotropic_angles(wi: Vec3, wo: Vec3) -> [f32; 3] {
    let hd = half_diff(wi, wo);
    let phi_d = if needs_fold(V3::from(hd.d)) {
        atan2(-hd.d.y, -hd.d.x)
    } else {
        atan2(hd.d.y, hd.d.x)
    };
    [polar_angle(hd.h), polar_angle(hd.d), fold_phi_d(phi_d)]
}

/// The 6D NBRDF network input (sin θh, 0, cos θh, dx, dy, dz) of (wi, wo): h rotated to
/// φh = 0 (isotropy) and d folded to φd ∈ [0, π) (reciprocity), so the result is the same
/// for (wo, wi) up to rounding.
#[inline]
pub fn network_input(wi: Vec3, wo: Vec3) -> [f32; 6] {
    let hd = half_diff(wi, wo);
    let (sin_h, d) = sin_theta_h_and_folded_d(&hd);
    [sin_h, 0.0, hd.h.z, d.x, d.y, d.z]
}

/// sin θh and the difference vector with φd folded into [0, π), the two parts of the
/// network input that need more than a copy.
#[inline]
fn sin_theta_h_and_folded_d(hd: &HalfDiff) -> (f32, Vec3) {
    let (sin_h, d) = sin_theta_h_and_folded_d_of(V3::from(hd.h), V3::from(hd.d));
    (sin_h, d.into())
}

/// [`sin_theta_h_and_folded_d`] over [`Real`] values, of the half vector `h` and the
/// difference vector `d`.
#[inline(always)]
fn sin_theta_h_and_folded_d_of<R: Real>(h: V3<R>, d: V3<R>) -> (R, V3<R>) {
    let sin_h = (h.x * h.x + h.y * h.y).sqrt();
    (sin_h, needs_fold(d).select(V3::new(-d.x, -d.y, d.z), d))
}

/// [`network_input`] and [`isotropic_angles`] of (wi, wo) together, from one half/difference
/// computation: the network input and (θh, θd, φd) with φd folded into [0, π).
#[inline]
pub fn network_input_and_angles(wi: Vec3, wo: Vec3) -> ([f32; 6], [f32; 3]) {
    network_input_and_angles_of(V3::from(wi), V3::from(wo))
}

/// [`network_input_and_angles`] over [`Real`] values (one pair, or one per lane; φd folded
/// by [`fold_atan2_phi_d`], exact for the angles [`crate::trig::atan2`] gives).
#[inline(always)]
pub fn network_input_and_angles_of<R: Real>(wi: V3<R>, wo: V3<R>) -> ([R; 6], [R; 3]) {
    let (h, d, _) = half_diff_of(wi, wo);
    let (sin_h, d) = sin_theta_h_and_folded_d_of(h, d);
    let angles = [atan2(sin_h, h.z), polar_angle_of(d), fold_atan2_phi_d(atan2(d.y, d.x))];
    ([sin_h, R::splat(0.0), h.z, d.x, d.y, d.z], angles)
}

/// [`fold_phi_d`] for |φd| < 2π or NaN, which every angle from [`crate::trig::atan2`] is:
/// there `φd % π` is φd itself or φd ∓ π, which is exact (Sterbenz; the sign of a zero
/// remainder is φd's, as `%` gives it), so the remainder needs no division. For one value
/// or one per lane.
#[inline(always)]
pub fn fold_atan2_phi_d<R: Real>(phi_d: R) -> R {
    let pi = R::splat(PI);
    let r = R::select(phi_d.abs().ge(pi), (phi_d - pi.copysign(phi_d)).copysign(phi_d), phi_d);
    let r = R::select(r.lt(R::splat(0.0)), r + PI, r);
    R::select(r.ge(pi), r - PI, r)
}

/// Boxes that together hold every [`network_input`] of directions above the horizon: θh and
/// θd (each in [0, π/2] there) and the folded φd (in [0, π]) cut into `n` equal steps each,
/// every box one interval per input (low, high), widened by 10⁻⁵ for the inputs' f32
/// rounding. What [`crate::neural::mlp::Mlp::without_never_active_units`] proves over.
pub fn network_input_boxes(n: usize) -> Vec<[(f64, f64); 6]> {
    use std::f64::consts::{FRAC_PI_2, PI};
    const SLACK: f64 = 1e-5;
    let steps = |end: f64| (0..n).map(move |k| (end * k as f64 / n as f64, end * (k + 1) as f64 / n as f64));
    // sin and cos over [a, b] ⊂ [0, π]: sin rises to π/2 then falls, cos falls.
    let sin = |(a, b): (f64, f64)| {
        let top = if a <= FRAC_PI_2 && b >= FRAC_PI_2 { 1.0 } else { a.sin().max(b.sin()) };
        (a.sin().min(b.sin()), top)
    };
    let cos = |(a, b): (f64, f64)| (b.cos(), a.cos());
    let product = |(a, b): (f64, f64), (c, d): (f64, f64)| {
        let p = [a * c, a * d, b * c, b * d];
        (p.iter().copied().fold(f64::INFINITY, f64::min), p.iter().copied().fold(f64::NEG_INFINITY, f64::max))
    };
    let widen = |(a, b): (f64, f64)| (a - SLACK, b + SLACK);
    let mut boxes = Vec::with_capacity(n * n * n);
    for theta_h in steps(FRAC_PI_2) {
        for theta_d in steps(FRAC_PI_2) {
            for phi_d in steps(PI) {
                let sin_d = sin(theta_d);
                boxes.push([
                    widen(sin(theta_h)),
                    (0.0, 0.0),
                    widen(cos(theta_h)),
                    widen(product(sin_d, cos(phi_d))),
                    widen(product(sin_d, sin(phi_d))),
                    widen(cos(theta_d)),
                ]);
            }
        }
    }
    boxes
}

/// The 6D NBRDF network input of the isotropic angles (θh, θd, φd), radians; φd is used as
/// given (not folded).
#[inline]
pub fn network_input_from_angles(theta_h: f32, theta_d: f32, phi_d: f32) -> [f32; 6] {
    let (sh, ch) = theta_h.sin_cos();
    let (sd, cd) = theta_d.sin_cos();
    let (sp, cp) = phi_d.sin_cos();
    [sh, 0.0, ch, sd * cp, sd * sp, cd]
}

/// One configuration of the domain the renderer evaluates, as training and evaluation see it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderedPoint {
    /// The 6D network input of (wi, wo), exactly as the renderer computes it
    /// ([`network_input`]: φh = 0, φd folded into [0, π)).
    pub input: [f32; 6],
    /// (θh, θd, φd) with φd folded into [0, π): where the table and f_ref are looked up.
    pub angles: [f32; 3],
    /// cos θi = wi · n of the configuration drawn (before folding), in (0, 1].
    pub cos_i: f32,
}

/// The configuration (wi, wo) of the isotropic angles (θh, θd, φd) (radians; φh = 0; φd over
/// the whole circle, not folded) as the renderer evaluates it, or `None` when wi or wo lies at
/// or below the horizon, where every BSDF of the renderer is zero and nothing is ever
/// evaluated. The one definition of "the rendered domain" shared by rendering
/// ([`network_input_and_angles`]), training, fitting and evaluation: inputs are folded (so a
/// network learns only the reciprocal half it is evaluated on) and `cos_i` is that of the
/// unfolded wi, so drawing φd uniformly over the circle weights each folded point by the mean
/// of its two orientations' cosines.
#[inline]
pub fn rendered_point(theta_h: f32, theta_d: f32, phi_d: f32) -> Option<RenderedPoint> {
    let (wi, wo) = directions_from_angles(&HalfDiffAngles {
        theta_h,
        phi_h: 0.0,
        theta_d,
        phi_d,
    });
    if !(wi.z > 0.0 && wo.z > 0.0) {
        return None;
    }
    let (input, angles) = network_input_and_angles(wi, wo);
    Some(RenderedPoint {
        input,
        angles,
        cos_i: wi.z.min(1.0),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lanes::{F32s, Vec3s};
    use proptest::prelude::*;
    use std::f32::consts::FRAC_PI_2;

    fn unit(theta: f32, phi: f32) -> Vec3 {
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        Vec3::new(st * cp, st * sp, ct)
    }

    /// Distance between two azimuths on the circle of period `period`.
    fn circular_distance(a: f32, b: f32, period: f32) -> f32 {
        let r = (a - b).rem_euclid(period);
        r.min(period - r)
    }

    proptest! {
        #[test]
        fn input_and_angles_agree_with_separate_functions(
            ti in 0.0f32..1.5, pi in -3.1f32..3.1, to in 0.0f32..1.5, po in -3.1f32..3.1,
        ) {
            let (wi, wo) = (unit(ti, pi), unit(to, po));
            let (x, a) = network_input_and_angles(wi, wo);
            prop_assert_eq!(x, network_input(wi, wo));
            let b = isotropic_angles(wi, wo);
            prop_assert!((a[0] - b[0]).abs() < 1e-5 && (a[1] - b[1]).abs() < 1e-5);
            prop_assert!(circular_distance(a[2], b[2], PI) < 1e-4, "{:?} vs {:?}", a, b);
        }
    }

    #[test]
    fn mirror_configuration_has_zero_theta_h() {
        let wo = unit(0.7, 1.1);
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        let a = half_diff_angles(wi, wo);
        assert!(a.theta_h.abs() < 1e-6);
        assert_eq!(a.phi_h, 0.0, "φh is guarded to 0 when h = n");
        assert!((a.theta_d - 0.7).abs() < 1e-5);
    }

    #[test]
    fn normal_incidence_has_zero_theta_d() {
        let w = unit(0.4, -2.0);
        let a = half_diff_angles(w, w);
        assert!((a.theta_h - 0.4).abs() < 1e-6);
        assert!(a.theta_d.abs() < 1e-3);
        let hd = half_diff(w, w);
        assert!((hd.d - Vec3::Z).length() < 1e-6);
    }

    #[test]
    fn antiparallel_directions_stay_finite() {
        let w = unit(1.0, 0.3);
        let hd = half_diff(w, -w);
        assert_eq!(hd.h, Vec3::Z);
        assert!(hd.d.is_finite());
        assert!(network_input(w, -w).iter().all(|v| v.is_finite()));
    }

    #[test]
    fn network_input_matches_angles_form() {
        let a = HalfDiffAngles {
            theta_h: 0.3,
            phi_h: 2.2,
            theta_d: 0.9,
            phi_d: 1.2,
        };
        let (wi, wo) = directions_from_angles(&a);
        let x = network_input(wi, wo);
        let y = network_input_from_angles(0.3, 0.9, 1.2);
        for k in 0..6 {
            assert!((x[k] - y[k]).abs() < 1e-5, "{x:?} vs {y:?}");
        }
    }

    #[test]
    fn fold_phi_d_range() {
        for phi in [
            -PI,
            -3.0,
            -1e-9,
            0.0,
            1e-9,
            1.0,
            PI - 1e-7,
            PI,
            3.5,
            2.0 * PI,
        ] {
            let f = fold_phi_d(phi);
            assert!((0.0..PI).contains(&f), "{phi} -> {f}");
            assert!(circular_distance(f, phi, PI) < 1e-5);
        }
    }

    #[test]
    fn rendered_points_are_above_both_horizons_and_folded() {
        let mut kept = 0;
        for k in 0..4000 {
            let u = |a: f32| (k as f32 * a).fract();
            let (th, td, pd) = (u(0.618_034) * FRAC_PI_2, u(0.414_214) * FRAC_PI_2, u(0.732_051) * 2.0 * PI);
            let (wi, wo) = directions_from_angles(&HalfDiffAngles { theta_h: th, phi_h: 0.0, theta_d: td, phi_d: pd });
            match rendered_point(th, td, pd) {
                None => assert!(wi.z <= 0.0 || wo.z <= 0.0, "{th} {td} {pd}"),
                Some(p) => {
                    kept += 1;
                    assert!(wi.z > 0.0 && wo.z > 0.0);
                    assert_eq!(p.input, network_input(wi, wo), "the renderer's input");
                    assert!((0.0..PI).contains(&p.angles[2]) && p.input[4] >= 0.0);
                    assert!((p.cos_i - wi.z).abs() < 1e-6);
                    // The reciprocal configuration has the same input (up to rounding).
                    let q = network_input(wo, wi);
                    assert!(p.input.iter().zip(&q).all(|(a, b)| (a - b).abs() < 1e-4) || p.input[4] < 1e-4);
                }
            }
        }
        // θh, θd uniform on [0, π/2]²: wo is below the horizon for about 19 % of the
        // configurations, wi (by symmetry) for as many, both rarely: about 62 % are kept.
        assert!((2300..2700).contains(&kept), "{kept} of 4000 above both horizons");
    }

    proptest! {
        #[test]
        fn vectors_round_trip(
            ti in 0.0f32..3.1, pi_ in -PI..PI, to in 0.0f32..3.1, po in -PI..PI,
        ) {
            let (wi, wo) = (unit(ti, pi_), unit(to, po));
            prop_assume!((wi + wo).length() > 1e-2);
            let (wi2, wo2) = directions_from_angles(&half_diff_angles(wi, wo));
            prop_assert!((wi2 - wi).length() < 1e-4, "wi {wi:?} -> {wi2:?}");
            prop_assert!((wo2 - wo).length() < 1e-4, "wo {wo:?} -> {wo2:?}");
        }

        #[test]
        fn angles_round_trip(
            theta_h in 0.01f32..1.56, phi_h in -3.1f32..3.1f32,
            theta_d in 0.01f32..1.56, phi_d in -3.1f32..3.1f32,
        ) {
            let a = HalfDiffAngles { theta_h, phi_h, theta_d, phi_d };
            let (wi, wo) = directions_from_angles(&a);
            prop_assert!((wi.length() - 1.0).abs() < 1e-5 && (wo.length() - 1.0).abs() < 1e-5);
            let b = half_diff_angles(wi, wo);
            prop_assert!((b.theta_h - theta_h).abs() < 1e-4, "{a:?} -> {b:?}");
            prop_assert!((b.theta_d - theta_d).abs() < 1e-4, "{a:?} -> {b:?}");
            prop_assert!(circular_distance(b.phi_h, phi_h, 2.0 * PI) < 1e-3, "{a:?} -> {b:?}");
            prop_assert!(circular_distance(b.phi_d, phi_d, 2.0 * PI) < 1e-3, "{a:?} -> {b:?}");
        }

        #[test]
        fn folded_coordinates_are_reciprocal(
            ti in 0.0f32..FRAC_PI_2, pi_ in -PI..PI, to in 0.0f32..FRAC_PI_2, po in -PI..PI,
        ) {
            let (wi, wo) = (unit(ti, pi_), unit(to, po));
            let a = isotropic_angles(wi, wo);
            let b = isotropic_angles(wo, wi);
            prop_assert!((a[0] - b[0]).abs() < 1e-5 && (a[1] - b[1]).abs() < 1e-4);
            prop_assert!((0.0..PI).contains(&a[2]));
            // φd is undefined when θd ≈ 0, and the fold boundary 0 ≡ π may be crossed by
            // rounding: compare on the circle of period π.
            if a[1] > 1e-3 {
                prop_assert!(circular_distance(a[2], b[2], PI) < 1e-3, "{a:?} vs {b:?}");
            }
            let x = network_input(wi, wo);
            let y = network_input(wo, wi);
            prop_assert!(x[1] == 0.0 && (x[0] - y[0]).abs() < 1e-5 && (x[2] - y[2]).abs() < 1e-5);
            prop_assert!(x[4] >= 0.0);
            let same = (3..6).all(|k| (x[k] - y[k]).abs() < 1e-4);
            let boundary = x[4] < 1e-4 && y[4] < 1e-4;
            prop_assert!(same || boundary, "{x:?} vs {y:?}");
        }
    }

    /// The lane form gives the scalar bits in every lane, over random pairs, grazing ones,
    /// mirror pairs (h = n up to rounding), equal and opposite directions, and pairs whose
    /// difference vector lies on the fold's edge (d.y = 0).
    #[test]
    fn lanes_give_the_scalar_bits() {
        use crate::lanes::LANES;
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(11);
        let mut pairs: Vec<(Vec3, Vec3)> = Vec::new();
        for k in 0..20_000 {
            let theta_max = if k % 4 == 0 { FRAC_PI_2 * 1.01 } else { FRAC_PI_2 };
            let draw = |rng: &mut rand_pcg::Pcg32| unit(rng.random_range(0.0..theta_max), rng.random_range(-PI..PI));
            let wo = draw(&mut rng);
            let wi = match k % 5 {
                0 => Vec3::new(-wo.x, -wo.y, wo.z),
                1 => wo,
                2 => -wo,
                3 => Vec3::new(wo.x, -wo.y, wo.z),
                _ => draw(&mut rng),
            };
            pairs.push((wi, wo));
        }
        pairs.extend([(Vec3::Z, Vec3::Z), (Vec3::X, Vec3::Z), (Vec3::Z, Vec3::X), (Vec3::new(-1.0, 0.0, 0.0), Vec3::Z)]);
        for chunk in pairs.chunks(LANES) {
            let (mut wi, mut wo) = (Vec3s::splat(Vec3::Z), Vec3s::splat(Vec3::Z));
            for (i, &(a, b)) in chunk.iter().enumerate() {
                wi.set(i, a);
                wo.set(i, b);
            }
            let (x, angles) = network_input_and_angles_of(wi, wo);
            for (i, &(a, b)) in chunk.iter().enumerate() {
                let (want_x, want_angles) = network_input_and_angles(a, b);
                assert_eq!(x.map(|v| v.0[i].to_bits()), want_x.map(f32::to_bits), "input of ({a}, {b})");
                assert_eq!(angles.map(|v| v.0[i].to_bits()), want_angles.map(f32::to_bits), "angles of ({a}, {b})");
            }
        }
        // The fold alone over its whole range, zeros and ±π included.
        let phis: Vec<f32> = (0..=8000).map(|k| -PI + k as f32 * (PI / 4000.0)).chain([PI, -PI, 0.0, -0.0, f32::NAN, 6.25, -6.25, 3.5, -3.5]).collect();
        for chunk in phis.chunks(LANES) {
            let mut v = F32s::splat(0.0);
            for (i, &p) in chunk.iter().enumerate() {
                v.0[i] = p;
            }
            let folded = fold_atan2_phi_d(v);
            for (i, &p) in chunk.iter().enumerate() {
                assert_eq!(folded.0[i].to_bits(), fold_phi_d(p).to_bits(), "fold of {p}");
            }
        }
    }
}
