//! The working precision: `f32` or `f64` ([`Real`] for generic code,
//! [`Precision`] chosen at run time).

use std::any::{Any, TypeId};
use std::fmt::{Debug, Display};
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

use crate::num::math::{Elementary, Math};
use crate::num::prims::Prims;

/// A floating-point working precision with its primitives and elementary
/// functions. The models' shared functions come on top of it, in
/// [`crate::models::Flows`].
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
    + Prims
    + Math
    + Elementary
{
    /// `"f32"` or `"f64"`.
    const NAME: &'static str;
    /// Unit roundoff (half the machine epsilon).
    const UNIT_ROUNDOFF: f64;
    /// An unsigned integer as wide as `Self`: the vectorised kernels
    /// accumulate per-lane conditions in it (a vector of booleans would be
    /// narrowed and widened again on every iteration).
    type Flag: Copy + Default + PartialEq + std::ops::BitOrAssign + From<bool>;
    fn from_f64(x: f64) -> Self;
    fn to_f64(self) -> f64;
    fn finite(self) -> bool;
    fn nan() -> Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn floor(self) -> Self;
    /// Whether it is a positive, normal, finite number (false for NaN).
    fn positive_normal(self) -> bool;
}

impl Real for f32 {
    const NAME: &'static str = "f32";
    const UNIT_ROUNDOFF: f64 = f32::EPSILON as f64 / 2.0;
    type Flag = u32;
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
    #[inline(always)]
    fn positive_normal(self) -> bool {
        (f32::MIN_POSITIVE..=f32::MAX).contains(&self)
    }
}

impl Real for f64 {
    const NAME: &'static str = "f64";
    const UNIT_ROUNDOFF: f64 = f64::EPSILON / 2.0;
    type Flag = u64;
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
    #[inline(always)]
    fn positive_normal(self) -> bool {
        (f64::MIN_POSITIVE..=f64::MAX).contains(&self)
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
    /// The precision of the type `R`.
    pub fn of<R: Real>() -> Precision {
        match R::NAME {
            "f64" => Precision::F64,
            _ => Precision::F32,
        }
    }

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

/// What `f32s` or `f64s` makes, whichever is `R`, as `Out` (their result
/// in `R`). Heavy code generic in the precision (the ~1300 kernels, the
/// runs) is compiled in this crate alone, through non-generic f32 and f64
/// twins: reached from a generic caller, every crate that calls it (each
/// test crate, the binary, the Python module) would monomorphise it again
/// (one test crate's rustc reached 13.7 GB). `Any` hands the result back
/// in `R`.
pub fn in_precision<R: Real, Out: Any, A: Any, B: Any>(
    f32s: impl FnOnce() -> A,
    f64s: impl FnOnce() -> B,
) -> Out {
    if is_f32::<R>() {
        handed_back(f32s())
    } else {
        handed_back(f64s())
    }
}

/// `x` as `Out`, the type it is: what [`in_precision`] does with the
/// twin's result, for callers that branch on [`is_f32`] themselves (whose
/// twins take the same `&mut`, which two closures cannot both hold).
/// Panics if `Out` is not `T`.
pub fn handed_back<Out: Any, T: Any>(x: T) -> Out {
    match (Box::new(x) as Box<dyn Any>).downcast::<Out>() {
        Ok(out) => *out,
        Err(_) => unreachable!("handed back as another type"),
    }
}

/// Whether `R` is `f32` (else, for a [`Real`], `f64`).
pub fn is_f32<R: Real>() -> bool {
    TypeId::of::<R>() == TypeId::of::<f32>()
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
