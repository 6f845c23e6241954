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
    /// `2^n` in two normal halves for n = round(y) (ties to even), |n| within
    /// the exponent range: `lo = 2^⌊n/2⌋`, `hi = 2^(n − ⌊n/2⌋)`, so that
    /// `v·lo·hi` rounds once even where `2^n` is subnormal. On the CPU one
    /// addition of 1.5·2^mantissa puts n in the low bits, and integer shifts
    /// make both exponents: no rounding instruction, no float-to-int
    /// conversion and none of its range checks. NaN `y` gives some values
    /// (callers carry the NaN on their float path).
    fn pow2_halves(y: Self, lo: &mut Self, hi: &mut Self);
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
    fn pow2_halves(y: f32, lo: &mut f32, hi: &mut f32) {
        // y + 1.5·2²³ has bits 0x4b40_0000 + n; u = n + 254 ≥ 0 makes the
        // halves' biased exponents u >> 1 = ⌊n/2⌋ + 127 and u − (u >> 1).
        let u = (y + 12582912.0).to_bits().wrapping_sub(0x4b40_0000 - 254);
        let e = u >> 1;
        *lo = f32::from_bits(e << 23);
        *hi = f32::from_bits(u.wrapping_sub(e) << 23);
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
    fn pow2_halves(y: f64, lo: &mut f64, hi: &mut f64) {
        // As for f32, with 1.5·2⁵² and the bias 1023: u = n + 2046.
        let u = (y + 6755399441055744.0)
            .to_bits()
            .wrapping_sub(0x4338_0000_0000_0000 - 2046);
        let e = u >> 1;
        *lo = f64::from_bits(e << 52);
        *hi = f64::from_bits(u.wrapping_sub(e) << 52);
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
