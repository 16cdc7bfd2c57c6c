//! The number type the renderer's formulas are written over once — [`Real`]: one `f32`, or
//! [`LANES`] of them ([`F32s`]) for kernels that process that many path vertices together
//! (structure of arrays) — with its vectors ([`V3`], [`V2`]) and masks ([`MaskOps`]).
//!
//! Every lane operation applies the scalar `f32` operation to each lane, so a formula
//! instantiated for [`F32s`] gives bit for bit the values of the same formula instantiated for
//! `f32`, lane by lane (Rust never fuses a multiply and an add on its own). Where one value
//! would return early, a formula computes a mask and selects; `choose!` branches where all
//! lanes agree. The loops are fixed-length and branch-free, which LLVM turns into vector
//! instructions of the width the enclosing function is compiled for (SSE2 by default, AVX2
//! or AVX-512 under `#[target_feature]`).
//!
//! A formula over [`Real`] is named for what it computes (`sampling::cosine_hemisphere`,
//! `accel::offset_origin`); where callers outside the kernels want `glam` types, a function of
//! the same meaning (`sampling::sample_cosine_hemisphere`, `accel::offset_ray_origin`) is a
//! one-line call of it.

// Indexed fixed-length loops are the form LLVM vectorises most reliably here.
#![allow(clippy::needless_range_loop)]

use std::fmt::Debug;
use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

/// Number of lanes: one AVX-512 register of `f32`.
pub const LANES: usize = 16;

/// [`LANES`] `f32` values.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct F32s(pub [f32; LANES]);

/// [`LANES`] booleans, the result of a comparison.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Mask(pub [bool; LANES]);

/// Three [`F32s`]: a vector per lane.
pub type Vec3s = V3<F32s>;

/// Two [`F32s`]: a 2D point per lane.
pub type Vec2s = V2<F32s>;

/// A 3-vector of [`Real`] components: a `glam::Vec3`'s values for `f32`, a vector per lane
/// for [`F32s`] ([`Vec3s`]). Its operations are `glam::Vec3`'s, in the same order, so the
/// formulas written once with it give the bits of the scalar code for `f32` and for each
/// lane.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct V3<R> {
    pub x: R,
    pub y: R,
    pub z: R,
}

/// A 2-vector of [`Real`] components (`glam::Vec2`'s values for `f32`, [`Vec2s`] per lane).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct V2<R> {
    pub x: R,
    pub y: R,
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
        impl<R: Real> $trait for V3<R> {
            type Output = V3<R>;
            #[inline(always)]
            fn $method(self, o: V3<R>) -> V3<R> {
                V3 { x: self.x $op o.x, y: self.y $op o.y, z: self.z $op o.z }
            }
        }
        impl<R: Real> $trait<R> for V3<R> {
            type Output = V3<R>;
            #[inline(always)]
            fn $method(self, o: R) -> V3<R> {
                V3 { x: self.x $op o, y: self.y $op o, z: self.z $op o }
            }
        }
        impl $trait<f32> for Vec3s {
            type Output = Vec3s;
            #[inline(always)]
            fn $method(self, o: f32) -> Vec3s {
                V3 { x: self.x $op o, y: self.y $op o, z: self.z $op o }
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

impl<R: Real> Neg for V3<R> {
    type Output = V3<R>;
    #[inline(always)]
    fn neg(self) -> V3<R> {
        V3 {
            x: -self.x,
            y: -self.y,
            z: -self.z,
        }
    }
}

/// One `f32` or [`LANES`] of them ([`F32s`]): the number type the formulas of the BSDFs,
/// warps and integrator helpers are written over once, so that the scalar path (`f32`) and
/// the lane kernels (`F32s`) run the same operations in the same order — the same bits per
/// lane. Where scalar code would return early, a formula computes a [`Real::Mask`] and
/// selects ([`MaskOps::select`], `choose!`); `f32`'s mask is `bool`.
///
/// Constants on the left of an operator are written `R::splat(c) − x` (the bits of
/// `c − x`): Rust does not carry a trait's `f32: Sub<Self>` bound to its users.
pub trait Real:
    Copy
    + Default
    + Debug
    + PartialEq
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f32, Output = Self>
    + Sub<f32, Output = Self>
    + Mul<f32, Output = Self>
    + Div<f32, Output = Self>
{
    /// The result of a comparison: `bool`, or [`Mask`] per lane.
    type Mask: MaskOps + Blend<Self::Mask>;

    /// `v` (in every lane).
    fn splat(v: f32) -> Self;
    /// `a` where `mask` is set, `b` elsewhere.
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self;
    fn abs(self) -> Self;
    fn sqrt(self) -> Self;
    /// `f32::max` (a NaN takes the other operand).
    fn max(self, o: Self) -> Self;
    /// `f32::min` (a NaN takes the other operand).
    fn min(self, o: Self) -> Self;
    /// `f32::signum`: ±1 by the sign bit, NaN for NaN.
    fn signum(self) -> Self;
    /// `f32::copysign`: the magnitude of `self` with the sign of `sign`.
    fn copysign(self, sign: Self) -> Self;
    /// Rounding toward zero through `i32` (`x as i32 as f32`: saturating, NaN becomes 0).
    fn truncate(self) -> Self;
    fn lt(self, o: Self) -> Self::Mask;
    fn le(self, o: Self) -> Self::Mask;
    fn gt(self, o: Self) -> Self::Mask;
    fn ge(self, o: Self) -> Self::Mask;
    fn eq(self, o: Self) -> Self::Mask;
    fn is_finite(self) -> Self::Mask;
    fn is_infinite(self) -> Self::Mask;
    /// `f32::is_sign_negative` (NaNs and zeros by their sign bit).
    fn is_sign_negative(self) -> Self::Mask;
    /// `f32::acos` (libm's, lane by lane).
    fn acos(self) -> Self;

    /// `f32::clamp` (NaN stays NaN).
    #[inline(always)]
    fn clamp(self, min: f32, max: f32) -> Self {
        let x = Self::select(self.lt(Self::splat(min)), Self::splat(min), self);
        Self::select(x.gt(Self::splat(max)), Self::splat(max), x)
    }
}

/// A comparison's result: `bool` for one value, [`Mask`] for [`LANES`].
pub trait MaskOps: Copy + Debug + Default + BitAnd<Output = Self> + BitOr<Output = Self> + Not<Output = Self> {
    /// `v` in every lane.
    fn splat(v: bool) -> Self;
    /// Whether some lane is set.
    fn any(self) -> bool;
    /// Whether every lane is set.
    fn all(self) -> bool;

    /// `a` where the mask is set, `b` elsewhere (any [`Blend`] value: numbers, vectors and
    /// tuples of them).
    #[inline(always)]
    fn select<T: Blend<Self>>(self, a: T, b: T) -> T {
        T::blend(self, a, b)
    }
}

/// Values chosen between per lane by a mask `M`.
pub trait Blend<M>: Sized {
    /// `a` where `mask` is set, `b` elsewhere.
    fn blend(mask: M, a: Self, b: Self) -> Self;
}

/// `choose!(mask, a, b)`: `a` where `mask` is set, `b` elsewhere, evaluating an expression
/// only when some lane takes its value: a branch for one value, both and a select
/// ([`Blend`]) for lanes that differ. Each lane gets what it would alone. A macro rather than
/// a function of two closures, so that both expressions are always inlined into the lane
/// kernels (closures passed to a function were not, and ran without the kernels' AVX-512).
macro_rules! choose {
    ($mask:expr, $a:expr, $b:expr $(,)?) => {{
        let mask = $mask;
        if $crate::lanes::MaskOps::all(mask) {
            $a
        } else if !$crate::lanes::MaskOps::any(mask) {
            $b
        } else {
            $crate::lanes::Blend::blend(mask, $a, $b)
        }
    }};
}
pub(crate) use choose;

impl MaskOps for bool {
    #[inline(always)]
    fn splat(v: bool) -> bool {
        v
    }

    #[inline(always)]
    fn any(self) -> bool {
        self
    }

    #[inline(always)]
    fn all(self) -> bool {
        self
    }
}

impl MaskOps for Mask {
    #[inline(always)]
    fn splat(v: bool) -> Mask {
        Mask([v; LANES])
    }

    #[inline(always)]
    fn any(self) -> bool {
        let mut r = false;
        for i in 0..LANES {
            r |= self.0[i];
        }
        r
    }

    #[inline(always)]
    fn all(self) -> bool {
        let mut r = true;
        for i in 0..LANES {
            r &= self.0[i];
        }
        r
    }
}

impl Blend<bool> for bool {
    #[inline(always)]
    fn blend(mask: bool, a: bool, b: bool) -> bool {
        if mask {
            a
        } else {
            b
        }
    }
}

impl Blend<Mask> for Mask {
    #[inline(always)]
    fn blend(mask: Mask, a: Mask, b: Mask) -> Mask {
        (mask & a) | (!mask & b)
    }
}

impl<R: Real> Blend<R::Mask> for R {
    #[inline(always)]
    fn blend(mask: R::Mask, a: R, b: R) -> R {
        R::select(mask, a, b)
    }
}

impl<R: Real> Blend<R::Mask> for V3<R> {
    #[inline(always)]
    fn blend(mask: R::Mask, a: V3<R>, b: V3<R>) -> V3<R> {
        V3 {
            x: R::select(mask, a.x, b.x),
            y: R::select(mask, a.y, b.y),
            z: R::select(mask, a.z, b.z),
        }
    }
}

impl<R: Real> Blend<R::Mask> for V2<R> {
    #[inline(always)]
    fn blend(mask: R::Mask, a: V2<R>, b: V2<R>) -> V2<R> {
        V2 {
            x: R::select(mask, a.x, b.x),
            y: R::select(mask, a.y, b.y),
        }
    }
}

impl<M: Copy, A: Blend<M>, B: Blend<M>> Blend<M> for (A, B) {
    #[inline(always)]
    fn blend(mask: M, a: (A, B), b: (A, B)) -> (A, B) {
        (A::blend(mask, a.0, b.0), B::blend(mask, a.1, b.1))
    }
}

impl<M: Copy, A: Blend<M>, B: Blend<M>, C: Blend<M>> Blend<M> for (A, B, C) {
    #[inline(always)]
    fn blend(mask: M, a: (A, B, C), b: (A, B, C)) -> (A, B, C) {
        (A::blend(mask, a.0, b.0), B::blend(mask, a.1, b.1), C::blend(mask, a.2, b.2))
    }
}

impl Real for f32 {
    type Mask = bool;

    #[inline(always)]
    fn splat(v: f32) -> f32 {
        v
    }

    #[inline(always)]
    fn select(mask: bool, a: f32, b: f32) -> f32 {
        if mask {
            a
        } else {
            b
        }
    }

    #[inline(always)]
    fn abs(self) -> f32 {
        f32::abs(self)
    }

    #[inline(always)]
    fn sqrt(self) -> f32 {
        f32::sqrt(self)
    }

    #[inline(always)]
    fn max(self, o: f32) -> f32 {
        f32::max(self, o)
    }

    #[inline(always)]
    fn min(self, o: f32) -> f32 {
        f32::min(self, o)
    }

    #[inline(always)]
    fn signum(self) -> f32 {
        f32::signum(self)
    }

    #[inline(always)]
    fn copysign(self, sign: f32) -> f32 {
        f32::copysign(self, sign)
    }

    #[inline(always)]
    fn truncate(self) -> f32 {
        self as i32 as f32
    }

    #[inline(always)]
    fn lt(self, o: f32) -> bool {
        self < o
    }

    #[inline(always)]
    fn le(self, o: f32) -> bool {
        self <= o
    }

    #[inline(always)]
    fn gt(self, o: f32) -> bool {
        self > o
    }

    #[inline(always)]
    fn ge(self, o: f32) -> bool {
        self >= o
    }

    #[inline(always)]
    fn eq(self, o: f32) -> bool {
        self == o
    }

    #[inline(always)]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }

    #[inline(always)]
    fn is_infinite(self) -> bool {
        f32::is_infinite(self)
    }

    #[inline(always)]
    fn is_sign_negative(self) -> bool {
        f32::is_sign_negative(self)
    }

    #[inline(always)]
    fn acos(self) -> f32 {
        f32::acos(self)
    }
}

impl Real for F32s {
    type Mask = Mask;

    #[inline(always)]
    fn splat(v: f32) -> F32s {
        F32s([v; LANES])
    }

    #[inline(always)]
    fn select(mask: Mask, a: F32s, b: F32s) -> F32s {
        let mut r = [0.0; LANES];
        for i in 0..LANES {
            r[i] = if mask.0[i] { a.0[i] } else { b.0[i] };
        }
        F32s(r)
    }

    #[inline(always)]
    fn abs(self) -> F32s {
        F32s::abs(self)
    }

    #[inline(always)]
    fn sqrt(self) -> F32s {
        F32s::sqrt(self)
    }

    #[inline(always)]
    fn max(self, o: F32s) -> F32s {
        F32s::max(self, o)
    }

    #[inline(always)]
    fn min(self, o: F32s) -> F32s {
        F32s::min(self, o)
    }

    #[inline(always)]
    fn signum(self) -> F32s {
        F32s::signum(self)
    }

    #[inline(always)]
    fn copysign(self, sign: F32s) -> F32s {
        F32s::copysign(self, sign)
    }

    #[inline(always)]
    fn truncate(self) -> F32s {
        F32s::truncate(self)
    }

    #[inline(always)]
    fn lt(self, o: F32s) -> Mask {
        F32s::lt(self, o)
    }

    #[inline(always)]
    fn le(self, o: F32s) -> Mask {
        F32s::le(self, o)
    }

    #[inline(always)]
    fn gt(self, o: F32s) -> Mask {
        F32s::gt(self, o)
    }

    #[inline(always)]
    fn ge(self, o: F32s) -> Mask {
        F32s::ge(self, o)
    }

    #[inline(always)]
    fn eq(self, o: F32s) -> Mask {
        F32s::eq(self, o)
    }

    #[inline(always)]
    fn is_finite(self) -> Mask {
        F32s::is_finite(self)
    }

    #[inline(always)]
    fn is_infinite(self) -> Mask {
        F32s::is_infinite(self)
    }

    #[inline(always)]
    fn is_sign_negative(self) -> Mask {
        F32s::is_sign_negative(self)
    }

    #[inline(always)]
    fn acos(self) -> F32s {
        self.map(f32::acos)
    }
}

impl<R: Real> V3<R> {
    #[inline(always)]
    pub fn new(x: R, y: R, z: R) -> V3<R> {
        V3 { x, y, z }
    }

    /// `v` (in every lane).
    #[inline(always)]
    pub fn splat(v: glam::Vec3) -> V3<R> {
        V3 {
            x: R::splat(v.x),
            y: R::splat(v.y),
            z: R::splat(v.z),
        }
    }

    /// `glam::Vec3::try_normalize` (the same operations: the vector times the reciprocal of
    /// its length), with where that is `Some` (the reciprocal finite and positive); elsewhere
    /// the vector is meaningless.
    #[inline(always)]
    pub fn try_normalize(self) -> (V3<R>, R::Mask) {
        let rcp = R::splat(1.0) / self.dot(self).sqrt();
        (self * rcp, rcp.is_finite() & rcp.gt(R::splat(0.0)))
    }

    /// `glam::Vec3::try_normalize(v).unwrap_or(fallback)`.
    #[inline(always)]
    pub fn normalize_or(self, fallback: glam::Vec3) -> V3<R> {
        let (v, ok) = self.try_normalize();
        ok.select(v, V3::splat(fallback))
    }

    /// Dot product, summed in `glam::Vec3::dot`'s order (x, y, then z).
    #[inline(always)]
    pub fn dot(self, o: V3<R>) -> R {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// Cross product, with `glam::Vec3::cross`'s operations.
    #[inline(always)]
    pub fn cross(self, o: V3<R>) -> V3<R> {
        V3 {
            x: self.y * o.z - o.y * self.z,
            y: self.z * o.x - o.z * self.x,
            z: self.x * o.y - o.x * self.y,
        }
    }

    #[inline(always)]
    pub fn abs(self) -> V3<R> {
        V3 {
            x: self.x.abs(),
            y: self.y.abs(),
            z: self.z.abs(),
        }
    }

    /// `glam::Vec3::max_element` (`a > b ? a : b`, left to right).
    #[inline(always)]
    pub fn max_element(self) -> R {
        let max = |a: R, b: R| R::select(a.gt(b), a, b);
        max(max(self.x, self.y), self.z)
    }

    /// Whether all three components are finite.
    #[inline(always)]
    pub fn is_finite(self) -> R::Mask {
        self.x.is_finite() & self.y.is_finite() & self.z.is_finite()
    }
}

impl From<glam::Vec3> for V3<f32> {
    #[inline(always)]
    fn from(v: glam::Vec3) -> V3<f32> {
        V3 { x: v.x, y: v.y, z: v.z }
    }
}

impl From<V3<f32>> for glam::Vec3 {
    #[inline(always)]
    fn from(v: V3<f32>) -> glam::Vec3 {
        glam::Vec3::new(v.x, v.y, v.z)
    }
}

impl From<glam::Vec2> for V2<f32> {
    #[inline(always)]
    fn from(v: glam::Vec2) -> V2<f32> {
        V2 { x: v.x, y: v.y }
    }
}

impl From<V2<f32>> for glam::Vec2 {
    #[inline(always)]
    fn from(v: V2<f32>) -> glam::Vec2 {
        glam::Vec2::new(v.x, v.y)
    }
}

/// A lane type whose lane `i` can be set to one value: how the kernels fill formula
/// parameters ([`Real`] structures of `F32s`) from one shading point's (of `f32`).
pub trait SetLane {
    /// One lane's value.
    type One;
    /// Sets lane `i` to `v`.
    fn set_lane(&mut self, i: usize, v: Self::One);
}

impl SetLane for F32s {
    type One = f32;
    #[inline(always)]
    fn set_lane(&mut self, i: usize, v: f32) {
        self.0[i] = v;
    }
}

impl SetLane for Vec3s {
    type One = V3<f32>;
    #[inline(always)]
    fn set_lane(&mut self, i: usize, v: V3<f32>) {
        self.x.0[i] = v.x;
        self.y.0[i] = v.y;
        self.z.0[i] = v.z;
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
        // Bit for bit, except that any NaN equals any NaN: which NaN an operation on NaN or
        // inf − inf gives is the hardware's (x86: the negative quiet NaN) or, for the scalar
        // side folded at compile time, LLVM's (a positive one).
        let same = |x: F32s, f: &dyn Fn(usize) -> f32| (0..LANES).all(|i| x.0[i].to_bits() == f(i).to_bits() || (x.0[i].is_nan() && f(i).is_nan()));
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

    /// `choose` gives each lane its own side's value, and calls a side only when some lane
    /// takes it (so one value, or lanes that agree, cost one side).
    #[test]
    fn choose_takes_each_lanes_side_and_calls_only_what_is_taken() {
        let (a, b) = (F32s::splat(1.0), F32s::splat(2.0));
        let mut mask = [false; LANES];
        mask[3] = true;
        let mixed = choose!(Mask(mask), a, b);
        assert!((0..LANES).all(|i| mixed.0[i] == if i == 3 { 1.0 } else { 2.0 }));
        let calls = std::cell::Cell::new(0);
        let counted = |v: F32s| {
            calls.set(calls.get() + 1);
            v
        };
        assert_eq!(choose!(Mask([true; LANES]), a, counted(b)), a);
        assert_eq!(choose!(Mask([false; LANES]), counted(a), b), b);
        assert_eq!(calls.get(), 0);
        assert_eq!(choose!(false, 1.0f32, 2.0), 2.0);
        assert!(Mask(mask).any() && !Mask(mask).all() && Mask([true; LANES]).all());
    }
}
