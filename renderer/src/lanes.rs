//! Arithmetic on [`LANES`] values at once, for kernels that process that many path vertices
//! together (structure of arrays).
//!
//! Every operation applies the scalar `f32` operation to each lane, so a kernel written with
//! these types gives bit for bit the values of the same formulas evaluated one lane at a time
//! (Rust never fuses a multiply and an add on its own). The loops are fixed-length and
//! branch-free, which LLVM turns into vector instructions of the width the enclosing
//! function is compiled for (SSE2 by default, AVX2 or AVX-512 under `#[target_feature]`).

// Indexed fixed-length loops are the form LLVM vectorises most reliably here.
#![allow(clippy::needless_range_loop)]

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

/// Number of lanes: one AVX-512 register of `f32`.
pub const LANES: usize = 16;

/// [`LANES`] `f32` values.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct F32s(pub [f32; LANES]);

/// [`LANES`] booleans, the result of a comparison.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mask(pub [bool; LANES]);

/// Three [`F32s`]: a vector per lane.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3s {
    pub x: F32s,
    pub y: F32s,
    pub z: F32s,
}

/// Two [`F32s`]: a 2D point per lane.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec2s {
    pub x: F32s,
    pub y: F32s,
}

impl Default for F32s {
    fn default() -> Self {
        F32s([0.0; LANES])
    }
}

impl F32s {
    #[inline(always)]
    pub fn splat(v: f32) -> Self {
        F32s([v; LANES])
    }

    #[inline(always)]
    fn map(self, f: impl Fn(f32) -> f32) -> Self {
        let mut r = [0.0; LANES];
        for i in 0..LANES {
            r[i] = f(self.0[i]);
        }
        F32s(r)
    }

    #[inline(always)]
    fn zip(self, o: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        let mut r = [0.0; LANES];
        for i in 0..LANES {
            r[i] = f(self.0[i], o.0[i]);
        }
        F32s(r)
    }

    #[inline(always)]
    fn test(self, o: Self, f: impl Fn(f32, f32) -> bool) -> Mask {
        let mut r = [false; LANES];
        for i in 0..LANES {
            r[i] = f(self.0[i], o.0[i]);
        }
        Mask(r)
    }

    #[inline(always)]
    pub fn abs(self) -> Self {
        self.map(f32::abs)
    }

    #[inline(always)]
    pub fn sqrt(self) -> Self {
        self.map(f32::sqrt)
    }

    /// Rounding toward zero through `i32` per lane (`x as i32 as f32`: saturating, NaN
    /// becomes 0).
    #[inline(always)]
    pub fn truncate(self) -> Self {
        self.map(|x| x as i32 as f32)
    }

    /// `f32::max` per lane (a NaN lane takes the other operand).
    #[inline(always)]
    pub fn max(self, o: Self) -> Self {
        self.zip(o, f32::max)
    }

    /// `f32::signum` per lane: ±1 by the sign bit, NaN for NaN.
    #[inline(always)]
    pub fn signum(self) -> Self {
        self.map(f32::signum)
    }

    #[inline(always)]
    pub fn lt(self, o: Self) -> Mask {
        self.test(o, |a, b| a < b)
    }

    #[inline(always)]
    pub fn le(self, o: Self) -> Mask {
        self.test(o, |a, b| a <= b)
    }

    #[inline(always)]
    pub fn ge(self, o: Self) -> Mask {
        self.test(o, |a, b| a >= b)
    }

    #[inline(always)]
    pub fn gt(self, o: Self) -> Mask {
        self.test(o, |a, b| a > b)
    }

    #[inline(always)]
    pub fn eq(self, o: Self) -> Mask {
        self.test(o, |a, b| a == b)
    }

    #[inline(always)]
    pub fn is_finite(self) -> Mask {
        self.test(self, |a, _| a.is_finite())
    }

    #[inline(always)]
    pub fn is_infinite(self) -> Mask {
        self.test(self, |a, _| a.is_infinite())
    }

    /// `f32::is_sign_negative` per lane (NaNs and zeros by their sign bit).
    #[inline(always)]
    pub fn is_sign_negative(self) -> Mask {
        self.test(self, |a, _| a.is_sign_negative())
    }

    /// `f32::copysign` per lane: the magnitude of `self` with the sign of `sign`.
    #[inline(always)]
    pub fn copysign(self, sign: Self) -> Self {
        self.zip(sign, f32::copysign)
    }

    /// `f32::min` per lane (a NaN lane takes the other operand).
    #[inline(always)]
    pub fn min(self, o: Self) -> Self {
        self.zip(o, f32::min)
    }
}

impl Mask {
    /// `a` where the mask is set, `b` elsewhere.
    #[inline(always)]
    pub fn select(self, a: F32s, b: F32s) -> F32s {
        let mut r = [0.0; LANES];
        for i in 0..LANES {
            r[i] = if self.0[i] { a.0[i] } else { b.0[i] };
        }
        F32s(r)
    }

    /// [`Mask::select`] on each component.
    #[inline(always)]
    pub fn select3(self, a: Vec3s, b: Vec3s) -> Vec3s {
        Vec3s {
            x: self.select(a.x, b.x),
            y: self.select(a.y, b.y),
            z: self.select(a.z, b.z),
        }
    }
}

macro_rules! mask_ops {
    ($($trait:ident $method:ident $op:tt),*) => {$(
        impl $trait for Mask {
            type Output = Mask;
            #[inline(always)]
            fn $method(self, o: Mask) -> Mask {
                let mut r = [false; LANES];
                for i in 0..LANES {
                    r[i] = self.0[i] $op o.0[i];
                }
                Mask(r)
            }
        }
    )*};
}

mask_ops!(BitAnd bitand &, BitOr bitor |);

impl Not for Mask {
    type Output = Mask;
    #[inline(always)]
    fn not(self) -> Mask {
        let mut r = [false; LANES];
        for i in 0..LANES {
            r[i] = !self.0[i];
        }
        Mask(r)
    }
}

macro_rules! binary_ops {
    ($($trait:ident $method:ident $op:tt),*) => {$(
        impl $trait for F32s {
            type Output = F32s;
            #[inline(always)]
            fn $method(self, o: F32s) -> F32s {
                self.zip(o, |a, b| a $op b)
            }
        }
        impl $trait<f32> for F32s {
            type Output = F32s;
            #[inline(always)]
            fn $method(self, o: f32) -> F32s {
                self.map(|a| a $op o)
            }
        }
        impl $trait<F32s> for f32 {
            type Output = F32s;
            #[inline(always)]
            fn $method(self, o: F32s) -> F32s {
                o.map(|b| self $op b)
            }
        }
        impl $trait for Vec3s {
            type Output = Vec3s;
            #[inline(always)]
            fn $method(self, o: Vec3s) -> Vec3s {
                Vec3s { x: self.x $op o.x, y: self.y $op o.y, z: self.z $op o.z }
            }
        }
        impl $trait<F32s> for Vec3s {
            type Output = Vec3s;
            #[inline(always)]
            fn $method(self, o: F32s) -> Vec3s {
                Vec3s { x: self.x $op o, y: self.y $op o, z: self.z $op o }
            }
        }
        impl $trait<f32> for Vec3s {
            type Output = Vec3s;
            #[inline(always)]
            fn $method(self, o: f32) -> Vec3s {
                Vec3s { x: self.x $op o, y: self.y $op o, z: self.z $op o }
            }
        }
    )*};
}

binary_ops!(Add add +, Sub sub -, Mul mul *, Div div /);

impl Neg for F32s {
    type Output = F32s;
    #[inline(always)]
    fn neg(self) -> F32s {
        self.map(|a| -a)
    }
}

impl Neg for Vec3s {
    type Output = Vec3s;
    #[inline(always)]
    fn neg(self) -> Vec3s {
        Vec3s {
            x: -self.x,
            y: -self.y,
            z: -self.z,
        }
    }
}

impl Vec3s {
    /// Lane `i` as a `glam::Vec3`.
    #[inline(always)]
    pub fn get(&self, i: usize) -> glam::Vec3 {
        glam::Vec3::new(self.x.0[i], self.y.0[i], self.z.0[i])
    }

    /// Sets lane `i`.
    #[inline(always)]
    pub fn set(&mut self, i: usize, v: glam::Vec3) {
        self.x.0[i] = v.x;
        self.y.0[i] = v.y;
        self.z.0[i] = v.z;
    }

    /// `v` in every lane.
    #[inline(always)]
    pub fn splat(v: glam::Vec3) -> Vec3s {
        Vec3s {
            x: F32s::splat(v.x),
            y: F32s::splat(v.y),
            z: F32s::splat(v.z),
        }
    }

    /// `glam::Vec3::try_normalize` per lane (the same operations: the vector times the
    /// reciprocal of its length), with the lanes where that is `Some` (the reciprocal finite
    /// and positive); the other lanes' vectors are meaningless.
    #[inline(always)]
    pub fn try_normalize(self) -> (Vec3s, Mask) {
        let rcp = 1.0 / self.dot(self).sqrt();
        (self * rcp, rcp.is_finite() & rcp.gt(F32s::splat(0.0)))
    }

    /// `glam::Vec3::try_normalize(v).unwrap_or(fallback)` per lane.
    #[inline(always)]
    pub fn normalize_or(self, fallback: glam::Vec3) -> Vec3s {
        let (v, ok) = self.try_normalize();
        ok.select3(v, Vec3s::splat(fallback))
    }

    /// Dot product per lane, summed in `glam::Vec3::dot`'s order (x, y, then z).
    #[inline(always)]
    pub fn dot(self, o: Vec3s) -> F32s {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    #[inline(always)]
    pub fn abs(self) -> Vec3s {
        Vec3s {
            x: self.x.abs(),
            y: self.y.abs(),
            z: self.z.abs(),
        }
    }

    /// `glam::Vec3::max_element` per lane (`a > b ? a : b`, left to right).
    #[inline(always)]
    pub fn max_element(self) -> F32s {
        let max = |a: F32s, b: F32s| a.gt(b).select(a, b);
        max(max(self.x, self.y), self.z)
    }

    /// Whether all three components of a lane are finite.
    #[inline(always)]
    pub fn is_finite(self) -> Mask {
        self.x.is_finite() & self.y.is_finite() & self.z.is_finite()
    }
}

impl Vec2s {
    /// Sets lane `i`.
    #[inline(always)]
    pub fn set(&mut self, i: usize, v: glam::Vec2) {
        self.x.0[i] = v.x;
        self.y.0[i] = v.y;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each operation equals the scalar one lane by lane, including NaN and infinities.
    #[test]
    fn lanes_equal_scalar_operations() {
        let specials = [0.0, -0.0, 1.0, -2.5, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 1e-40];
        let mut a = F32s::default();
        let mut b = F32s::default();
        for i in 0..LANES {
            a.0[i] = specials[i % specials.len()];
            b.0[i] = specials[(i * 3 + 1) % specials.len()];
        }
        let same = |x: F32s, f: &dyn Fn(usize) -> f32| (0..LANES).all(|i| x.0[i].to_bits() == f(i).to_bits());
        assert!(same(a + b, &|i| a.0[i] + b.0[i]));
        assert!(same(a / b, &|i| a.0[i] / b.0[i]));
        assert!(same(a.max(b), &|i| a.0[i].max(b.0[i])));
        assert!(same(a.signum(), &|i| a.0[i].signum()));
        assert!(same(a.sqrt(), &|i| a.0[i].sqrt()));
        assert!(same(a.gt(b).select(a, b), &|i| if a.0[i] > b.0[i] { a.0[i] } else { b.0[i] }));
        let v = Vec3s { x: a, y: b, z: a * b };
        assert!(same(v.dot(v), &|i| v.get(i).dot(v.get(i))));
        assert!(same(v.max_element(), &|i| v.get(i).max_element()));
        assert_eq!(v.is_finite().0.map(|m| m), std::array::from_fn(|i| v.get(i).is_finite()));
    }
}
