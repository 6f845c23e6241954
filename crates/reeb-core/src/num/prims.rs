//! Primitives with one exact meaning on both backends: the operations that
//! shared functions (see [`crate::num::dsl`]) may call besides arithmetic,
//! written by hand here and in `shaders/prelude_*.wgsl`.

/// Primitives with one exact meaning, written by hand on each backend
/// (here and in `shaders/prelude_*.wgsl`). Everything numerical is built
/// from these in shared functions.
pub trait Prims: Sized {
    /// `t` where `c`, else `f` (argument order of WGSL's `select`).
    fn select(f: Self, t: Self, c: bool) -> Self;
    /// Truncation toward zero; callers keep `x` well inside the `i32` range.
    fn to_i32(x: Self) -> i32;
    /// The nearest integer, ties to even (WGSL's `round`; one instruction
    /// on SSE4.1 and later).
    fn rint(x: Self) -> Self;
    /// `2^n` for an integer-valued `n` from one below the smallest normal
    /// exponent to one above the largest (f32: −127 … 128, f64: −1023 …
    /// 1024): the normal powers exactly, `+0` at the low end and `+∞` at the
    /// high end. On the CPU one addition of 1.5·2^mantissa + bias puts the
    /// biased exponent in the low bits and one shift moves it into place: no
    /// float-to-int conversion and none of its range checks. NaN `n` gives
    /// some value (callers carry the NaN on their float path).
    fn pow2(n: Self) -> Self;
    /// Exact conversion of small integers.
    fn from_i32(n: i32) -> Self;
    /// Positive infinity.
    fn inf() -> Self;
    /// The quiet NaN, a constant (the bits rustc gave the shared functions'
    /// ∞·0, which it folded): lavapipe's shader compiler folds ∞·0 to 0
    /// (its x·0 → 0 rewrite), so a NaN made by arithmetic is lost there.
    fn quiet_nan() -> Self;
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
    fn rint(x: f32) -> f32 {
        x.round_ties_even()
    }
    #[inline(always)]
    fn pow2(n: f32) -> f32 {
        // n + 1.5·2²³ + 127 (exact) has bits 0x4b40_0000 + n + 127: shifted
        // left by 23, the low nine bits become sign and exponent, n + 127 in
        // 0 …= 255, and the constant's own bits fall off the top.
        f32::from_bits((n + 12583039.0).to_bits() << 23)
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
    fn quiet_nan() -> f32 {
        f32::NAN
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
    fn rint(x: f64) -> f64 {
        x.round_ties_even()
    }
    #[inline(always)]
    fn pow2(n: f64) -> f64 {
        // As for f32: 1.5·2⁵² + 1023, n + 1023 in 0 …= 2047 shifted by 52.
        f64::from_bits((n + 6755399441056767.0).to_bits() << 52)
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
    fn quiet_nan() -> f64 {
        f64::NAN
    }
    #[inline(always)]
    fn fma(a: f64, b: f64, c: f64) -> f64 {
        a.mul_add(b, c)
    }
}
