//! reeb's own `exp`, `sin`, `cos`: range reduction and polynomial, written
//! once (as shared functions) for the CPU and the GPU.
//!
//! Why not the platform's: WGSL's builtins are loosely specified (`sin`/`cos`
//! may be off by 2⁻¹¹ absolute, `exp` by 3 + 2|x| ULP) and unreliable in f64
//! (lavapipe returns garbage for f64 `exp`/`sin` without any error); libm
//! calls do not vectorise. With these, both backends evaluate one formula,
//! branch-free, so the CPU loop over lanes vectorises.
//!
//! Accuracy (tested in `tests/math.rs` against the platform libm in f64):
//! `exp` ≤ 2 ULP over the whole finite range (f32 and f64), overflow to +∞,
//! underflow to 0, NaN propagates. `sin`/`cos` ≤ 2 ULP for |x| ≤ 8192 (f32) and
//! |x| ≤ 10⁶ (f64), where the Cody–Waite reduction by π/2 is exact enough;
//! beyond that accuracy degrades gradually, and the result stays in [−1, 1].

use crate::num::prims::Prims;

crate::shared_fns! {
    concrete, wgsl MATH_F32_WGSL;

    /// e^x in f32: x = n ln 2 + r with |r| ≤ ln2/2, e^r by Taylor of degree 7
    /// (truncation 5·10⁻⁹, below half an ULP), 2^n applied in two halves so that
    /// results down to the subnormal range round once.
    fn exp_f32(x: f32) -> f32 {
        // Clamp by select, not min/max, so that NaN passes through.
        let lo: f32 = f32::select(x, -104.0, x < -104.0);
        let xc: f32 = f32::select(lo, 89.0, x > 89.0);
        let nf: f32 = f32::floor(xc * 1.44269502 + 0.5);
        let r: f32 = (xc - nf * 0.693359375) - nf * -0.000212194442;
        let mut p: f32 = 0.000198412701;
        p = f32::fma(p, r, 0.00138888892);
        p = f32::fma(p, r, 0.00833333377);
        p = f32::fma(p, r, 0.0416666679);
        p = f32::fma(p, r, 0.166666672);
        p = f32::fma(p, r, 0.5);
        p = f32::fma(p, r, 1.0);
        p = f32::fma(p, r, 1.0);
        let n: i32 = f32::to_i32(nf);
        let n1: i32 = n >> 1;
        let res: f32 = p * f32::pow2i(n1) * f32::pow2i(n - n1);
        return f32::select(res, 0.0, x < -103.98);
    }

    /// sin x and cos x in f32: k = round(2x/π), r = x − kπ/2 in three parts
    /// (exact products for |k| < 2¹², hence |x| ≲ 8192), minimax polynomials of
    /// Cephes on |r| ≤ π/4, quadrant by k mod 4.
    fn sincos_f32(x: f32, sn: &mut f32, cs: &mut f32) {
        let k: f32 = f32::floor(x * 0.636619747 + 0.5);
        let r: f32 = ((x - k * 1.5703125) - k * 0.000483751297) - k * 7.54979013e-8;
        let z: f32 = r * r;
        let s: f32 = f32::fma(f32::fma(f32::fma(-0.000195152956, z, 0.00833216123), z, -0.166666552) * z, r, r);
        let hz: f32 = 0.5 * z;
        let w: f32 = 1.0 - hz;
        let c: f32 = w + (((1.0 - w) - hz)
            + z * z * f32::fma(f32::fma(0.0000244331568, z, -0.00138873165), z, 0.0416666456));
        let q: i32 = f32::to_i32(k) & 3;
        let odd: bool = (q & 1) == 1;
        let s1: f32 = f32::select(s, c, odd);
        let c1: f32 = f32::select(c, s, odd);
        let s2: f32 = f32::select(s1, -s1, q >= 2);
        let c2: f32 = f32::select(c1, -c1, q == 1 || q == 2);
        // Far beyond the accurate range r is not reduced; stay in [−1, 1].
        *sn = f32::select(f32::select(s2, 1.0, s2 > 1.0), -1.0, s2 < -1.0);
        *cs = f32::select(f32::select(c2, 1.0, c2 > 1.0), -1.0, c2 < -1.0);
    }
}

crate::shared_fns! {
    concrete, wgsl MATH_F64_WGSL;

    /// e^x in f64: x = n ln 2 + r (fdlibm's two-part ln 2), e^r by Taylor of
    /// degree 13 (truncation 4·10⁻¹⁸), 2^n in two halves.
    fn exp_f64(x: f64) -> f64 {
        let lo: f64 = f64::select(x, -746.0, x < -746.0);
        let xc: f64 = f64::select(lo, 710.0, x > 710.0);
        let nf: f64 = f64::floor(xc * 1.4426950408889634 + 0.5);
        let r: f64 = (xc - nf * 6.93147180369123816490e-01) - nf * 1.90821492927058770002e-10;
        let mut p: f64 = 1.6059043836821613e-10;
        p = f64::fma(p, r, 2.08767569878681e-09);
        p = f64::fma(p, r, 2.505210838544172e-08);
        p = f64::fma(p, r, 2.755731922398589e-07);
        p = f64::fma(p, r, 2.7557319223985893e-06);
        p = f64::fma(p, r, 2.48015873015873e-05);
        p = f64::fma(p, r, 0.0001984126984126984);
        p = f64::fma(p, r, 0.001388888888888889);
        p = f64::fma(p, r, 0.008333333333333333);
        p = f64::fma(p, r, 0.041666666666666664);
        p = f64::fma(p, r, 0.16666666666666666);
        p = f64::fma(p, r, 0.5);
        p = f64::fma(p, r, 1.0);
        p = f64::fma(p, r, 1.0);
        let n: i32 = f64::to_i32(nf);
        let n1: i32 = n >> 1;
        let res: f64 = p * f64::pow2i(n1) * f64::pow2i(n - n1);
        return f64::select(res, 0.0, x < -745.2);
    }

    /// sin x and cos x in f64: Cody–Waite reduction by π/2 with fdlibm's
    /// 33-bit pieces (exact products for |k| < 2²⁰, hence |x| ≲ 10⁶), fdlibm's
    /// kernel polynomials on |r| ≤ π/4.
    fn sincos_f64(x: f64, sn: &mut f64, cs: &mut f64) {
        let k: f64 = f64::floor(x * 0.63661977236758134308 + 0.5);
        let r: f64 = (((x - k * 1.57079632673412561417e+00) - k * 6.07710050630396597660e-11)
            - k * 2.02226624871116645580e-21) - k * 8.47842766036889956997e-32;
        let z: f64 = r * r;
        let ps: f64 = f64::fma(f64::fma(f64::fma(f64::fma(1.58969099521155010221e-10, z, -2.50507602534068634195e-08), z,
            2.75573137070700676789e-06), z, -1.98412698298579493134e-04), z, 8.33333333332248946124e-03);
        let s: f64 = f64::fma(z * r, f64::fma(z, ps, -1.66666666666666324348e-01), r);
        let pc: f64 = z * f64::fma(f64::fma(f64::fma(f64::fma(f64::fma(-1.13596475577881948265e-11, z, 2.08757232129817482790e-09), z,
            -2.75573143513906633035e-07), z, 2.48015872894767294178e-05), z, -1.38888888888741095749e-03), z,
            4.16666666666666019037e-02);
        let hz: f64 = 0.5 * z;
        let w: f64 = 1.0 - hz;
        let c: f64 = w + (((1.0 - w) - hz) + z * pc);
        let q: i32 = f64::to_i32(k) & 3;
        let odd: bool = (q & 1) == 1;
        let s1: f64 = f64::select(s, c, odd);
        let c1: f64 = f64::select(c, s, odd);
        let s2: f64 = f64::select(s1, -s1, q >= 2);
        let c2: f64 = f64::select(c1, -c1, q == 1 || q == 2);
        // Far beyond the accurate range r is not reduced; stay in [−1, 1].
        *sn = f64::select(f64::select(s2, 1.0, s2 > 1.0), -1.0, s2 < -1.0);
        *cs = f64::select(f64::select(c2, 1.0, c2 > 1.0), -1.0, c2 < -1.0);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spot_values() {
        assert_eq!(exp_f64(0.0), 1.0);
        assert!((exp_f64(1.0) - std::f64::consts::E).abs() < 1e-15);
        assert_eq!(exp_f64(800.0), f64::INFINITY);
        assert_eq!(exp_f64(-800.0), 0.0);
        assert!(exp_f64(f64::NAN).is_nan());
        assert!(exp_f32(f32::NAN).is_nan());
        assert_eq!(exp_f32(100.0), f32::INFINITY);
        let (mut s, mut c) = (0.0, 0.0);
        sincos_f64(1.0, &mut s, &mut c);
        assert!((s - 1f64.sin()).abs() < 1e-16 && (c - 1f64.cos()).abs() < 1e-16);
    }
}
