//! The working precision: `f32` or `f64`, with the primitives that shared
//! functions may call (see [`crate::dsl`]).

use std::fmt::{Debug, Display};
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

use crate::math::{exp_f32, exp_f64, sincos_f32, sincos_f64};

/// Primitives with one exact meaning, written by hand on each backend
/// (here and in `shaders/prelude_*.wgsl`). Everything numerical is built
/// from these in shared functions.
pub trait Prims: Sized {
    /// `t` where `c`, else `f` (argument order of WGSL's `select`).
    fn select(f: Self, t: Self, c: bool) -> Self;
    /// `2^n`, exact, for `n` in the normal exponent range of the type.
    fn pow2i(n: i32) -> Self;
    /// Truncation toward zero; callers keep `x` well inside the `i32` range.
    fn to_i32(x: Self) -> i32;
    /// Exact conversion of small integers.
    fn from_i32(n: i32) -> Self;
    /// Positive infinity.
    fn inf() -> Self;
    /// `a·b + c` with one rounding (WGSL's `fma`): the polynomials use it,
    /// so the AVX2/FMA kernels and GPUs evaluate them in fused steps.
    fn fma(a: Self, b: Self, c: Self) -> Self;
}

impl Prims for f32 {
    #[inline(always)]
    fn select(f: f32, t: f32, c: bool) -> f32 {
        if c {
            t
        } else {
            f
        }
    }
    #[inline(always)]
    fn pow2i(n: i32) -> f32 {
        f32::from_bits(((n + 127) as u32) << 23)
    }
    #[inline(always)]
    fn to_i32(x: f32) -> i32 {
        // `as` saturates lane by lane, which LLVM scalarises inside the lane
        // loops; this is the same for every input (NaN → 0, clamped) and
        // compiles to vector compares, blends and one truncating conversion.
        let y = if x.is_nan() {
            0.0
        } else {
            x.clamp(-2.0e9, 2.0e9)
        };
        // SAFETY: y is finite and within the range of i32.
        unsafe { y.to_int_unchecked::<i32>() }
    }
    #[inline(always)]
    fn from_i32(n: i32) -> f32 {
        n as f32
    }
    #[inline(always)]
    fn inf() -> f32 {
        f32::INFINITY
    }
    #[inline(always)]
    fn fma(a: f32, b: f32, c: f32) -> f32 {
        a.mul_add(b, c)
    }
}

impl Prims for f64 {
    #[inline(always)]
    fn select(f: f64, t: f64, c: bool) -> f64 {
        if c {
            t
        } else {
            f
        }
    }
    #[inline(always)]
    fn pow2i(n: i32) -> f64 {
        f64::from_bits(((n + 1023) as u64) << 52)
    }
    #[inline(always)]
    fn to_i32(x: f64) -> i32 {
        // As for f32: vectorisable, the same values as a saturating `as`.
        let y = if x.is_nan() {
            0.0
        } else {
            x.clamp(-2.0e9, 2.0e9)
        };
        // SAFETY: y is finite and within the range of i32.
        unsafe { y.to_int_unchecked::<i32>() }
    }
    #[inline(always)]
    fn from_i32(n: i32) -> f64 {
        n as f64
    }
    #[inline(always)]
    fn inf() -> f64 {
        f64::INFINITY
    }
    #[inline(always)]
    fn fma(a: f64, b: f64, c: f64) -> f64 {
        a.mul_add(b, c)
    }
}

/// Elementary functions of the working precision. Both backends use reeb's
/// own range-reduced polynomials ([`crate::math`]), never the platform's.
pub trait Math: Sized {
    fn exp_r(x: Self) -> Self;
    fn sincos_r(x: Self, s: &mut Self, c: &mut Self);
    #[inline(always)]
    fn sin_r(x: Self) -> Self
    where
        Self: Copy + Default,
    {
        let (mut s, mut c) = (Self::default(), Self::default());
        Self::sincos_r(x, &mut s, &mut c);
        s
    }
    #[inline(always)]
    fn cos_r(x: Self) -> Self
    where
        Self: Copy + Default,
    {
        let (mut s, mut c) = (Self::default(), Self::default());
        Self::sincos_r(x, &mut s, &mut c);
        c
    }
}

impl Math for f32 {
    #[inline(always)]
    fn exp_r(x: f32) -> f32 {
        exp_f32(x)
    }
    #[inline(always)]
    fn sincos_r(x: f32, s: &mut f32, c: &mut f32) {
        sincos_f32(x, s, c)
    }
}

impl Math for f64 {
    #[inline(always)]
    fn exp_r(x: f64) -> f64 {
        exp_f64(x)
    }
    #[inline(always)]
    fn sincos_r(x: f64, s: &mut f64, c: &mut f64) {
        sincos_f64(x, s, c)
    }
}

/// A floating-point working precision. Every shared-function trait is a
/// supertrait, so generic code calls `R::flow_name(..)`.
pub trait Real:
    Copy
    + Send
    + Sync
    + Default
    + Debug
    + Display
    + PartialOrd
    + PartialEq
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
    + bytemuck::Pod
    + npyz::Serialize
    + npyz::AutoSerialize
    + Prims
    + Math
    + crate::models::Flows
{
    /// `"f32"` or `"f64"`.
    const NAME: &'static str;
    /// Unit roundoff (half the machine epsilon).
    const UNIT_ROUNDOFF: f64;
    fn from_f64(x: f64) -> Self;
    fn to_f64(self) -> f64;
    fn finite(self) -> bool;
    fn nan() -> Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn floor(self) -> Self;
}

impl Real for f32 {
    const NAME: &'static str = "f32";
    const UNIT_ROUNDOFF: f64 = f32::EPSILON as f64 / 2.0;
    #[inline(always)]
    fn from_f64(x: f64) -> f32 {
        x as f32
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self as f64
    }
    #[inline(always)]
    fn finite(self) -> bool {
        self.is_finite()
    }
    #[inline(always)]
    fn nan() -> f32 {
        f32::NAN
    }
    #[inline(always)]
    fn sqrt(self) -> f32 {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> f32 {
        f32::abs(self)
    }
    #[inline(always)]
    fn floor(self) -> f32 {
        f32::floor(self)
    }
}

impl Real for f64 {
    const NAME: &'static str = "f64";
    const UNIT_ROUNDOFF: f64 = f64::EPSILON / 2.0;
    #[inline(always)]
    fn from_f64(x: f64) -> f64 {
        x
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline(always)]
    fn finite(self) -> bool {
        self.is_finite()
    }
    #[inline(always)]
    fn nan() -> f64 {
        f64::NAN
    }
    #[inline(always)]
    fn sqrt(self) -> f64 {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> f64 {
        f64::abs(self)
    }
    #[inline(always)]
    fn floor(self) -> f64 {
        f64::floor(self)
    }
}

/// Working precision chosen at run time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    F32,
    F64,
}

impl Precision {
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
    pub fn bytes(self) -> usize {
        match self {
            Precision::F32 => 4,
            Precision::F64 => 8,
        }
    }
}

impl std::str::FromStr for Precision {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "f32" => Ok(Precision::F32),
            "f64" => Ok(Precision::F64),
            _ => Err(format!("unknown precision `{s}` (expected f32 or f64)")),
        }
    }
}

impl std::fmt::Display for Precision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
