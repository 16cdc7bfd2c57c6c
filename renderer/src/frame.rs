//! Orthonormal shading frames: conversion between world space and the local shading frame
//! (z = normal) in which every BSDF is written.

use crate::lanes::{Real, V3};
use glam::Vec3;

/// An orthonormal basis (s, t, n); `n` is the local z axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    pub s: Vec3,
    pub t: Vec3,
    pub n: Vec3,
}

impl Frame {
    /// Builds a frame around a unit normal (Duff et al. 2017, branchless and continuous
    /// except at one point).
    #[inline]
    pub fn from_normal(n: Vec3) -> Self {
        let (s, t) = tangents(V3::from(n));
        Frame { s: s.into(), t: t.into(), n }
    }

    /// World direction to local coordinates.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        to_local(self.s.into(), self.t.into(), self.n.into(), v.into()).into()
    }

    /// Local direction to world coordinates.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        to_world(self.s.into(), self.t.into(), self.n.into(), v.into()).into()
    }
}

/// The (s, t) of [`Frame::from_normal`] around the unit normal `n`, over [`Real`] values
/// (one frame, or one per lane).
#[inline(always)]
pub(crate) fn tangents<R: Real>(n: V3<R>) -> (V3<R>, V3<R>) {
    let sign = R::splat(1.0).copysign(n.z);
    let a = R::splat(-1.0) / (sign + n.z);
    let b = n.x * n.y * a;
    let s = V3::new(R::splat(1.0) + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let t = V3::new(b, sign + n.y * n.y * a, -n.y);
    (s, t)
}

/// [`Frame::to_local`] over [`Real`] values: world direction `v` in the frame (s, t, n).
#[inline(always)]
pub(crate) fn to_local<R: Real>(s: V3<R>, t: V3<R>, n: V3<R>, v: V3<R>) -> V3<R> {
    V3::new(v.dot(s), v.dot(t), v.dot(n))
}

/// [`Frame::to_world`] over [`Real`] values: local direction `v` of the frame (s, t, n) in
/// world space.
#[inline(always)]
pub(crate) fn to_world<R: Real>(s: V3<R>, t: V3<R>, n: V3<R>, v: V3<R>) -> V3<R> {
    s * v.x + t * v.y + n * v.z
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal_and_invert() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.4, 0.866).normalize(),
            Vec3::new(1e-7, 0.0, -1.0).normalize(),
        ] {
            let f = Frame::from_normal(n);
            assert!((f.s.length() - 1.0).abs() < 1e-5);
            assert!((f.t.length() - 1.0).abs() < 1e-5);
            assert!(f.s.dot(f.t).abs() < 1e-5 && f.s.dot(n).abs() < 1e-5 && f.t.dot(n).abs() < 1e-5);
            assert!(f.s.cross(f.t).dot(n) > 0.999, "right-handed");
            let v = Vec3::new(0.2, 0.5, -0.7).normalize();
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-5);
        }
    }
}
