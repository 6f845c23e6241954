//! reeb's own `exp`, `sin`, `cos`: range reduction and polynomial, written
//! once (as shared functions) for the CPU and the GPU.
//!
//! Why not the platform's: WGSL's builtins are loosely specified (`sin`/`cos`
//! may be off by 2⁻¹¹ absolute, `exp` by 3 + 2|x| ULP) and unreliable in f64
//! (lavapipe returns garbage for f64 `exp`/`sin` without any error); libm
//! calls do not vectorise. With these, both backends evaluate one formula,
//! branch-free, so the CPU loop over lanes vectorises.
//!
//! Accuracy (tested in `tests/suite/math.rs` against the platform libm in f64):
//! `exp` ≤ 2 ULP wherever its result is a normal number (f32 and f64), +∞
//! above that, 0 below (no gradual underflow), NaN propagates. `sin`/`cos`
//! ≤ 2 ULP for |x| ≤ 8192 (f32) and |x| ≤ 10⁶ (f64), where the Cody–Waite
//! reduction by π/2 is exact enough; beyond that accuracy degrades
//! gradually, and the result stays in [−1, 1].

use crate::num::prims::Prims;

crate::shared_fns! {
    concrete, wgsl MATH_F32_WGSL;

    /// e^x in f32: x = n ln 2 + r with |r| ≤ ln2/2, e^r = 1 + w with
    /// w = r + r²·(½ + r/6) + r⁴·(c₄ + c₅r + c₆r²), the coefficients of a degree-5
    /// P fitted to (e^r − 1)/r on Chebyshev nodes with P(0) = 1 (error 5·10⁻⁹
    /// relative, a tenth of an ULP; Taylor's needs degree 6), by Estrin's
    /// scheme with the 1 added last: a dependent chain of 4 operations instead
    /// of Horner's 6, which is what bounds the AVX2 step (van der Pol S2 +13 %
    /// at AVX2 on Zen 4). Then times 2^n in one scale, which costs five
    /// operations fewer than two halves (+11 % at AVX2, +5 % at AVX-512 with
    /// Estrin's). Every f32 result in the normal range is within 1.32 ULP of
    /// the exact value (checked exhaustively; Horner's: 0.98). Below that
    /// range the result flushes to 0, as GPUs flush subnormals anyway
    /// (x < −87.68; between there and −87.34 it is subnormal, rounded once
    /// from the normal scale 2⁻¹²⁶), and from x > 88.376 (n = 128) it is +∞
    /// (the exact values up to 88.72 are finite).
    fn exp_f32(x: f32) -> f32 {
        // Clamp by select, not min/max, so that NaN passes through: to where
        // n = −127 (scale +0) and n = 128 (scale +∞; the scale is applied
        // last, since w·∞ + ∞ would be NaN where w < 0).
        let lo: f32 = f32::select(x, -88.0, x < -88.0);
        let xc: f32 = f32::select(lo, 89.0, lo > 89.0);
        let nf: f32 = f32::rint(xc * 1.44269502);
        let s: f32 = f32::pow2(nf);
        // nf·0.693359375 is exact (9 bits times at most 8); fma would cost the
        // baseline kernels, which call libm for it, two more calls.
        let r: f32 = (xc - nf * 0.693359375) - nf * -0.000212194442;
        let z: f32 = r * r;
        let a1: f32 = f32::fma(r, 0.166665763, 0.5);
        let a2: f32 = f32::fma(r, 0.00836317521, 0.0416664667);
        let b1: f32 = f32::fma(z, 0.00139336439, a2);
        let w: f32 = f32::fma(z * z, b1, f32::fma(z, a1, r));
        return (1.0 + w) * s;
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

    /// e^x in f64: x = n ln 2 + r (fdlibm's two-part ln 2), e^r = 1 + r·P(r)
    /// with P of degree 10 fitted to (e^r − 1)/r in 50 digits on Chebyshev
    /// nodes with P(0) = 1 (error 1.2·10⁻¹⁷, a tenth of an ULP; Taylor's needs
    /// degree 12), 2^n in one scale as in `exp_f32` (AVX2 +4 %, AVX-512 +8 %):
    /// 0 below the normal range (x < −708.74; subnormal, rounded once, up to
    /// −708.40), +∞ from x > 709.44 (n = 1024). P as E(r²) + r·O(r²), each half by
    /// Horner's scheme: one operation more than Horner's on P and a dependent
    /// chain of 7 instead of 10, which is what bounds the AVX2 step in f64
    /// (van der Pol S2 +12 % at AVX2 on Zen 4, AVX-512 −2 %; Estrin's scheme
    /// in r² as well: AVX2 the same, AVX-512 −6 %). On 2·10⁷ random
    /// arguments within 1 ULP of glibc's `exp` (off by one in 8.9 %; Horner's
    /// on P: 6.1 %; Taylor's degree 12 by Estrin: 8.6 % of 2·10⁸).
    fn exp_f64(x: f64) -> f64 {
        // As in exp_f32: n = −1023 gives the scale +0, n = 1024 +∞.
        let lo: f64 = f64::select(x, -709.0, x < -709.0);
        let xc: f64 = f64::select(lo, 710.0, lo > 710.0);
        let nf: f64 = f64::rint(xc * 1.4426950408889634);
        let s: f64 = f64::pow2(nf);
        let r: f64 = (xc - nf * 6.93147180369123816490e-01) - nf * 1.90821492927058770002e-10;
        // P(r) = E(z) + r·O(z), z = r².
        let z: f64 = r * r;
        let e4: f64 = f64::fma(z, 2.50246452096493e-08, 2.755750728541229e-06);
        let e3: f64 = f64::fma(z, e4, 0.00019841269597118904);
        let e2: f64 = f64::fma(z, e3, 0.008333333333451433);
        let e1: f64 = f64::fma(z, e2, 0.16666666666666483);
        let e0: f64 = f64::fma(z, e1, 1.0);
        let o3: f64 = f64::fma(z, 2.7631125446226205e-07, 2.480149034623507e-05);
        let o2: f64 = f64::fma(z, o3, 0.0013888888946678828);
        let o1: f64 = f64::fma(z, o2, 0.04166666666651632);
        let o0: f64 = f64::fma(z, o1, 0.5000000000000012);
        let pr: f64 = f64::fma(r, o0, e0);
        return f64::fma(r, pr, 1.0) * s;
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
        // The quadrant k mod 4 in floating point (exact for every k), so the
        // selects take their masks from compares of the working precision:
        // spin–orbit S2 +7 % at AVX2, where an i32 quadrant's masks must be
        // widened to 64 bits (sincos_f32 keeps its i32 one: lanes match).
        let q: f64 = k - 4.0 * f64::floor(k * 0.25);
        let odd: bool = q == 1.0 || q == 3.0;
        let s1: f64 = f64::select(s, c, odd);
        let c1: f64 = f64::select(c, s, odd);
        let s2: f64 = f64::select(s1, -s1, q >= 2.0);
        let c2: f64 = f64::select(c1, -c1, q == 1.0 || q == 2.0);
        // Far beyond the accurate range r is not reduced; stay in [−1, 1].
        *sn = f64::select(f64::select(s2, 1.0, s2 > 1.0), -1.0, s2 < -1.0);
        *cs = f64::select(f64::select(c2, 1.0, c2 > 1.0), -1.0, c2 < -1.0);
    }
}

crate::shared_fns! {
    concrete, wgsl LOG_ATAN_F32_WGSL;

    /// ln x in f32: x = 2^e·m with m in [√½, √2) found by exact scalings
    /// (a branch-free ladder of powers of two, no bit access: WGSL has none
    /// in f64), then fdlibm's logf kernel on f = m − 1.
    fn log_f32(x: f32) -> f32 {
        let mut m: f32 = x;
        let mut e: f32 = 0.0;
        // Subnormals first, so that the ladder's 127 reaches every input.
        let tiny: bool = m < 7.888609052210118e-31;
        m = f32::select(m, m * 4294967296.0, tiny);
        e = f32::select(e, -32.0, tiny);
        let up64: bool = m >= 1.8446744073709552e+19;
        m = f32::select(m, m * 5.421010862427522e-20, up64);
        e = f32::select(e, e + 64.0, up64);
        let up32: bool = m >= 4294967296.0;
        m = f32::select(m, m * 2.3283064365386963e-10, up32);
        e = f32::select(e, e + 32.0, up32);
        let up16: bool = m >= 65536.0;
        m = f32::select(m, m * 1.52587890625e-05, up16);
        e = f32::select(e, e + 16.0, up16);
        let up8: bool = m >= 256.0;
        m = f32::select(m, m * 0.00390625, up8);
        e = f32::select(e, e + 8.0, up8);
        let up4: bool = m >= 16.0;
        m = f32::select(m, m * 0.0625, up4);
        e = f32::select(e, e + 4.0, up4);
        let up2: bool = m >= 4.0;
        m = f32::select(m, m * 0.25, up2);
        e = f32::select(e, e + 2.0, up2);
        let up1: bool = m >= 2.0;
        m = f32::select(m, m * 0.5, up1);
        e = f32::select(e, e + 1.0, up1);
        let dn64: bool = m < 1.0842021724855044e-19;
        m = f32::select(m, m * 1.8446744073709552e+19, dn64);
        e = f32::select(e, e - 64.0, dn64);
        let dn32: bool = m < 4.656612873077393e-10;
        m = f32::select(m, m * 4294967296.0, dn32);
        e = f32::select(e, e - 32.0, dn32);
        let dn16: bool = m < 3.0517578125e-05;
        m = f32::select(m, m * 65536.0, dn16);
        e = f32::select(e, e - 16.0, dn16);
        let dn8: bool = m < 0.0078125;
        m = f32::select(m, m * 256.0, dn8);
        e = f32::select(e, e - 8.0, dn8);
        let dn4: bool = m < 0.125;
        m = f32::select(m, m * 16.0, dn4);
        e = f32::select(e, e - 4.0, dn4);
        let dn2: bool = m < 0.5;
        m = f32::select(m, m * 4.0, dn2);
        e = f32::select(e, e - 2.0, dn2);
        let dn1: bool = m < 1.0;
        m = f32::select(m, m * 2.0, dn1);
        e = f32::select(e, e - 1.0, dn1);
        return log_kernel_f32(x, m, e);
    }

    /// ln(2^e·m) for m in [1, 2): fdlibm's logf kernel on f = m − 1 after
    /// m is brought into [√½, √2).
    fn log_core_f32(m0: f32, e0: f32) -> f32 {
        let mut m: f32 = m0;
        let mut e: f32 = e0;
        let hi: bool = m > 1.41421356;
        m = f32::select(m, m * 0.5, hi);
        e = f32::select(e, e + 1.0, hi);
        let f: f32 = m - 1.0;
        let s: f32 = f / (2.0 + f);
        let z: f32 = s * s;
        let w: f32 = z * z;
        let t1: f32 = w * f32::fma(w, 0.24279078841, 0.40000972152);
        let t2: f32 = z * f32::fma(w, 0.28498786688, 0.66666662693);
        let r: f32 = t2 + t1;
        let hfsq: f32 = 0.5 * f * f;
        return e * 0.693138123 - ((hfsq - (s * (hfsq + r) + e * 0.00000905525081)) - f);
    }

    /// ln x from x = 2^e·m, m in [1, 2) (m = x, e = 0 where x is not
    /// positive and finite): `log_core_f32`, then the cases of 0, < 0, ∞.
    fn log_kernel_f32(x: f32, m0: f32, e0: f32) -> f32 {
        let res: f32 = log_core_f32(m0, e0);
        // ln 0 = −∞, ln x = NaN below 0, ln ∞ = ∞, NaN stays.
        let neg: f32 = f32::quiet_nan();
        let r1: f32 = f32::select(res, x, x > 3.40282347e38);
        let r2: f32 = f32::select(r1, -f32::inf(), x == 0.0);
        return f32::select(r2, neg, x < 0.0);
    }

    /// ln(1 + f) + k ln 2 for f in [√½ − 1, √2 − 1], the kernel of the
    /// chaos indicators' logarithm (`sample_log_f32`): no division, so a
    /// dependent chain half as long as `log_core_f32`'s (the samples are
    /// bound by it). ln(1 + f) = f + f²·Q(f), Q of degree 8 fitted to
    /// (ln(1 + f) − f)/f² for relative error, by Estrin's scheme; ln 2 in
    /// two parts as in `exp_f32`. Within 1.01 ULP of ln x over every
    /// positive normal f32, non-decreasing on the band where the
    /// indicators keep ‖u‖² (tested).
    fn sample_log_core_f32(f: f32, k: f32) -> f32 {
        let f2: f32 = f * f;
        let f4: f32 = f2 * f2;
        let p01: f32 = f32::fma(f, 0.33333325, -0.49999988);
        let p23: f32 = f32::fma(f, 0.2000198, -0.25001583);
        let p45: f32 = f32::fma(f, 0.14181718, -0.16609074);
        let p67: f32 = f32::fma(f, 0.12905002, -0.13242927);
        let p03: f32 = f32::fma(f2, p23, p01);
        let p47: f32 = f32::fma(f2, p67, p45);
        let q: f32 = f32::fma(f4 * f4, -0.07622591, f32::fma(f4, p47, p03));
        let r: f32 = f32::fma(f2, q, f);
        return f32::fma(k, 0.693359375, f32::fma(k, -0.00021219444, r));
    }

    /// ln x from `res`, its kernel's value where x is positive and finite:
    /// the cases of 0, < 0, ∞ and NaN as in `log_kernel_f32`.
    fn sample_log_cases_f32(x: f32, res: f32) -> f32 {
        let neg: f32 = f32::quiet_nan();
        let r1: f32 = f32::select(x, res, x > 0.0 && x <= 3.40282347e38);
        let r2: f32 = f32::select(r1, -f32::inf(), x == 0.0);
        return f32::select(r2, neg, x < 0.0);
    }

    /// atan x in f32: fdlibm's atanf (reduction to |x'| ≤ 7/16 around
    /// 0.5, 1, 1.5 or ∞ by selects, odd polynomial of degree 11).
    fn atan_f32(x: f32) -> f32 {
        let a: f32 = f32::abs(x);
        let id0: bool = a >= 0.4375;
        let id1: bool = a >= 0.6875;
        let id2: bool = a >= 1.1875;
        let id3: bool = a >= 2.4375;
        let c: f32 = f32::select(f32::select(0.5, 1.0, id1), 1.5, id2);
        let hi: f32 = f32::select(f32::select(f32::select(0.0, 0.46364760399, id0), 0.78539812565, id1), 0.98279368877, id2);
        let lo: f32 = f32::select(f32::select(f32::select(0.0, 5.0121582440e-09, id0), 3.7748947079e-08, id1), 3.4473217170e-08, id2);
        let xr0: f32 = f32::select(a, (a - c) / (1.0 + c * a), id0);
        let xr: f32 = f32::select(xr0, -1.0 / a, id3);
        let hi3: f32 = f32::select(hi, 1.5707962513, id3);
        let lo3: f32 = f32::select(lo, 7.5497894159e-08, id3);
        let z: f32 = xr * xr;
        let w: f32 = z * z;
        let s1: f32 = z * f32::fma(w, f32::fma(w, 0.061687607318, 0.14253635705), 0.33333328366);
        let s2: f32 = w * f32::fma(w, -0.10648017377, -0.19999158382);
        let small: f32 = xr - xr * (s1 + s2);
        let big: f32 = hi3 - ((xr * (s1 + s2) - lo3) - xr);
        let r: f32 = f32::select(small, big, id0);
        return f32::select(r, -r, x < 0.0);
    }
}

crate::shared_fns! {
    concrete, wgsl LOG_ATAN_F64_WGSL;

    /// ln x in f64: as `log_f32`, with fdlibm's log kernel (degree 14 in s).
    fn log_f64(x: f64) -> f64 {
        let mut m: f64 = x;
        let mut e: f64 = 0.0;
        let tiny: bool = m < 9.332636185032189e-302;
        m = f64::select(m, m * 1.8446744073709552e19, tiny);
        e = f64::select(e, -64.0, tiny);
        let up512: bool = m >= 1.3407807929942597e+154;
        m = f64::select(m, m * 7.458340731200207e-155, up512);
        e = f64::select(e, e + 512.0, up512);
        let up256: bool = m >= 1.157920892373162e+77;
        m = f64::select(m, m * 8.636168555094445e-78, up256);
        e = f64::select(e, e + 256.0, up256);
        let up128: bool = m >= 3.402823669209385e+38;
        m = f64::select(m, m * 2.938735877055719e-39, up128);
        e = f64::select(e, e + 128.0, up128);
        let up64: bool = m >= 1.8446744073709552e+19;
        m = f64::select(m, m * 5.421010862427522e-20, up64);
        e = f64::select(e, e + 64.0, up64);
        let up32: bool = m >= 4294967296.0;
        m = f64::select(m, m * 2.3283064365386963e-10, up32);
        e = f64::select(e, e + 32.0, up32);
        let up16: bool = m >= 65536.0;
        m = f64::select(m, m * 1.52587890625e-05, up16);
        e = f64::select(e, e + 16.0, up16);
        let up8: bool = m >= 256.0;
        m = f64::select(m, m * 0.00390625, up8);
        e = f64::select(e, e + 8.0, up8);
        let up4: bool = m >= 16.0;
        m = f64::select(m, m * 0.0625, up4);
        e = f64::select(e, e + 4.0, up4);
        let up2: bool = m >= 4.0;
        m = f64::select(m, m * 0.25, up2);
        e = f64::select(e, e + 2.0, up2);
        let up1: bool = m >= 2.0;
        m = f64::select(m, m * 0.5, up1);
        e = f64::select(e, e + 1.0, up1);
        let dn512: bool = m < 1.4916681462400413e-154;
        m = f64::select(m, m * 1.3407807929942597e+154, dn512);
        e = f64::select(e, e - 512.0, dn512);
        let dn256: bool = m < 1.727233711018889e-77;
        m = f64::select(m, m * 1.157920892373162e+77, dn256);
        e = f64::select(e, e - 256.0, dn256);
        let dn128: bool = m < 5.877471754111438e-39;
        m = f64::select(m, m * 3.402823669209385e+38, dn128);
        e = f64::select(e, e - 128.0, dn128);
        let dn64: bool = m < 1.0842021724855044e-19;
        m = f64::select(m, m * 1.8446744073709552e+19, dn64);
        e = f64::select(e, e - 64.0, dn64);
        let dn32: bool = m < 4.656612873077393e-10;
        m = f64::select(m, m * 4294967296.0, dn32);
        e = f64::select(e, e - 32.0, dn32);
        let dn16: bool = m < 3.0517578125e-05;
        m = f64::select(m, m * 65536.0, dn16);
        e = f64::select(e, e - 16.0, dn16);
        let dn8: bool = m < 0.0078125;
        m = f64::select(m, m * 256.0, dn8);
        e = f64::select(e, e - 8.0, dn8);
        let dn4: bool = m < 0.125;
        m = f64::select(m, m * 16.0, dn4);
        e = f64::select(e, e - 4.0, dn4);
        let dn2: bool = m < 0.5;
        m = f64::select(m, m * 4.0, dn2);
        e = f64::select(e, e - 2.0, dn2);
        let dn1: bool = m < 1.0;
        m = f64::select(m, m * 2.0, dn1);
        e = f64::select(e, e - 1.0, dn1);
        return log_kernel_f64(x, m, e);
    }

    /// ln(2^e·m) for m in [1, 2), as `log_core_f32`, with fdlibm's log
    /// kernel (degree 14 in s).
    fn log_core_f64(m0: f64, e0: f64) -> f64 {
        let hi: bool = m0 > 1.4142135623730951;
        return log_reduced_f64(f64::select(m0, m0 * 0.5, hi), f64::select(e0, e0 + 1.0, hi));
    }

    /// ln(2^e·m) for m in [√½, √2): fdlibm's kernel, which `log_core_f64`
    /// brings m into (exactly: m/2 and e + 1 where m is above √2's double).
    fn log_reduced_f64(m: f64, e: f64) -> f64 {
        let f: f64 = m - 1.0;
        let s: f64 = f / (2.0 + f);
        let z: f64 = s * s;
        let w: f64 = z * z;
        let t1: f64 = w * f64::fma(w, f64::fma(w, 1.531383769920937332e-01, 2.222219843214978396e-01), 3.999999999940941908e-01);
        let t2: f64 = z * f64::fma(w, f64::fma(w, f64::fma(w, 1.479819860511658591e-01, 1.818357216161805012e-01), 2.857142874366239149e-01), 6.666666666666735130e-01);
        let r: f64 = t2 + t1;
        let hfsq: f64 = 0.5 * f * f;
        return e * 6.93147180369123816490e-01 - ((hfsq - (s * (hfsq + r) + e * 1.90821492927058770002e-10)) - f);
    }

    /// ln x from x = 2^e·m, as `log_kernel_f32`.
    fn log_kernel_f64(x: f64, m0: f64, e0: f64) -> f64 {
        let res: f64 = log_core_f64(m0, e0);
        let neg: f64 = f64::quiet_nan();
        let r1: f64 = f64::select(res, x, x > 1.7976931348623157e308);
        let r2: f64 = f64::select(r1, -f64::inf(), x == 0.0);
        return f64::select(r2, neg, x < 0.0);
    }

    /// atan x in f64: fdlibm's atan (as `atan_f32`, degree 22).
    fn atan_f64(x: f64) -> f64 {
        let a: f64 = f64::abs(x);
        let id0: bool = a >= 0.4375;
        let id1: bool = a >= 0.6875;
        let id2: bool = a >= 1.1875;
        let id3: bool = a >= 2.4375;
        // Typed first operands: WGSL would make a select of two literals f32.
        let zero: f64 = 0.0;
        let half: f64 = 0.5;
        let c: f64 = f64::select(f64::select(half, 1.0, id1), 1.5, id2);
        let hi: f64 = f64::select(f64::select(f64::select(zero, 4.63647609000806093515e-01, id0), 7.85398163397448278999e-01, id1), 9.82793723247329054082e-01, id2);
        let lo: f64 = f64::select(f64::select(f64::select(zero, 2.26987774529616870924e-17, id0), 3.06161699786838301793e-17, id1), 1.39033110312309984516e-17, id2);
        let xr0: f64 = f64::select(a, (a - c) / (1.0 + c * a), id0);
        let xr: f64 = f64::select(xr0, -1.0 / a, id3);
        let hi3: f64 = f64::select(hi, 1.57079632679489655800e+00, id3);
        let lo3: f64 = f64::select(lo, 6.12323399573676603587e-17, id3);
        let z: f64 = xr * xr;
        let w: f64 = z * z;
        let s1: f64 = z * f64::fma(w, f64::fma(w, f64::fma(w, f64::fma(w, f64::fma(w, 1.62858201153657823623e-02, 4.97687799461593236017e-02), 6.66107313738753120669e-02), 9.09088713343650656196e-02), 1.42857142725034663711e-01), 3.33333333333329318027e-01);
        let s2: f64 = w * f64::fma(w, f64::fma(w, f64::fma(w, f64::fma(w, -3.65315727442169155270e-02, -5.83357013379057348645e-02), -7.69187620504482999495e-02), -1.11111104054623557880e-01), -1.99999999998764832476e-01);
        let small: f64 = xr - xr * (s1 + s2);
        let big: f64 = hi3 - ((xr * (s1 + s2) - lo3) - xr);
        let r: f64 = f64::select(small, big, id0);
        return f64::select(r, -r, x < 0.0);
    }
}

crate::shared_fns! {
    /// The formula functions built on `exp_r`, `sincos_r`, `log_r` (both
    /// backends evaluate these same texts; see `num/formula/lower.rs`).
    trait Elementary, wgsl ELEMENTARY_WGSL;

    fn tan_r(x: R) -> R {
        let mut s: R = 0.0;
        let mut c: R = 0.0;
        R::sincos_r(x, &mut s, &mut c);
        return s / c;
    }
    /// sinh x: Taylor to x¹³ below |x| = ½ (no cancellation), else from e^|x|.
    fn sinh_r(x: R) -> R {
        let a: R = R::abs(x);
        let z: R = x * x;
        let mut p: R = 1.6059043836821613e-10;
        p = R::fma(p, z, 2.505210838544172e-08);
        p = R::fma(p, z, 2.7557319223985893e-06);
        p = R::fma(p, z, 0.0001984126984126984);
        p = R::fma(p, z, 0.008333333333333333);
        p = R::fma(p, z, 0.16666666666666666);
        let series: R = R::fma(p * z, x, x);
        let e: R = R::exp_r(a);
        let big: R = 0.5 * (e - 1.0 / e);
        return R::select(series, R::select(big, -big, x < 0.0), a >= 0.5);
    }
    fn cosh_r(x: R) -> R {
        let e: R = R::exp_r(R::abs(x));
        return 0.5 * (e + 1.0 / e);
    }
    /// tanh x: sinh/cosh below |x| = ½, else (1 − e^{−2|x|})/(1 + e^{−2|x|}).
    fn tanh_r(x: R) -> R {
        let a: R = R::abs(x);
        let u: R = R::exp_r(-2.0 * a);
        let big: R = (1.0 - u) / (1.0 + u);
        let small: R = R::sinh_r(x) / R::cosh_r(x);
        return R::select(small, R::select(big, -big, x < 0.0), a >= 0.5);
    }
    /// x^y for real y, as e^{y ln x}: NaN below 0, like a real power.
    fn pow_r(x: R, y: R) -> R {
        return R::exp_r(y * R::log_r(x));
    }
    /// The derivative of |x| (0 at 0).
    fn sign_r(x: R) -> R {
        let one: R = 1.0;
        return R::select(R::select(x, -one, x < 0.0), one, x > 0.0);
    }
    /// The power of two a that brings a vector of squared norm n2 back
    /// inside [2⁻⁴⁰, 2⁶⁰] when multiplied by 2^a: −30 above that band, 20
    /// below it, else 0 (one rung: a vector that grows by more than 2³⁰ or
    /// shrinks by more than 2²⁰ from sample to sample drifts out of the
    /// band, without harm until ‖u‖ nears the precision's range); NaN
    /// unless n2 > 0 (a vector collapsed to 0, or NaN). The chaos
    /// indicators keep their vectors in range with it. The band reaches
    /// higher than it reaches lower, since chaotic vectors grow and a
    /// block of lanes with one lane out of the band takes the slower path:
    /// with the upper edge at 2⁶⁰ rather than 2⁴⁰, spin–orbit's cost scene
    /// in f32 ran in 0.93× the time with the FLI, 0.96× with one exponent
    /// (whole runs, 7 alternating pairs, Zen 3 AVX2). Higher still would
    /// eat f32's headroom between samples (‖u‖ may grow by 2³⁴ from the
    /// edge before ‖u‖² overflows).
    fn octave_r(n2: R) -> R {
        // Typed constants: WGSL's select takes no abstract literal for f64.
        let none: R = 0.0;
        let up: R = 20.0;
        let down: R = -30.0;
        let nan: R = R::quiet_nan();
        let a: R = R::select(R::select(none, up, n2 < 9.094947017729282e-13), down, n2 > 1152921504606846976.0);
        return R::select(nan, a, n2 > 0.0);
    }
    /// Whether a vector of squared norm n2 is inside [2⁻³⁹, 2⁵⁹]: there
    /// [`octave_r`] is 0, with a margin for how n2 was rounded, so the
    /// sample of one Lyapunov vector changes nothing but ‖u‖² and may wait
    /// (false for NaN).
    fn in_band_r(n2: R) -> bool {
        return n2 >= 1.8189894035458565e-12 && n2 <= 576460752303423488.0;
    }
    /// 2^a for a of [`octave_r`]: −30, 0 or 20 (NaN stays NaN).
    fn rescale_r(a: R) -> R {
        let one: R = 1.0;
        let up: R = 1048576.0;
        let down: R = 9.313225746154785e-10;
        let s: R = R::select(R::select(one, up, a > 0.0), down, a < 0.0);
        return R::select(a, s, a > -64.0);
    }
    fn min_r(x: R, y: R) -> R {
        return R::select(y, x, x < y);
    }
    fn max_r(x: R, y: R) -> R {
        return R::select(y, x, x > y);
    }
}

/// Elementary functions of the working precision. Both backends use reeb's
/// own range-reduced polynomials ([`crate::math`]), never the platform's.
pub trait Math: Sized {
    fn exp_r(x: Self) -> Self;
    fn log_r(x: Self) -> Self;
    /// The chaos indicators' ln x: `log_r` in f64, [`sample_log_f32`] in
    /// f32 (a function of its own, so formulas, which call `log_r`, keep
    /// their bits).
    fn sample_log_r(x: Self) -> Self;
    /// `sample_log_r` where x is known positive, normal and finite: the
    /// same bits.
    fn sample_log_normal_r(x: Self) -> Self;
    fn atan_r(x: Self) -> Self;
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

/// ln x on the CPU: `log_f32`'s kernel with x = 2^e·m read from the bits
/// rather than found by its ladder of scalings (a third of the cost). Both
/// are exact, so m, e and the result are the same bits (tested over the
/// f32 and the f64). WGSL reads the bits in f32 too (`prelude_f32.wgsl`)
/// and keeps the ladder in f64, having no bit access there.
#[inline(always)]
pub fn log_f32_bits(x: f32) -> f32 {
    // Subnormals are scaled into the normal range first, exactly.
    let tiny = x < f32::MIN_POSITIVE;
    let bits = f32::select(x, x * 4294967296.0, tiny).to_bits();
    let e = ((bits >> 23) & 0xff) as i32 - 127 - 32 * i32::from(tiny);
    let m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    // Elsewhere (0, negative, ∞, NaN) the kernel's selects decide, and a
    // NaN's payload flows from m = x as in the ladder.
    let normal = x > 0.0 && x <= f32::MAX;
    log_kernel_f32(
        x,
        f32::select(x, m, normal),
        f32::select(0.0, e as f32, normal),
    )
}

/// ln x on the CPU in f64, as [`log_f32_bits`] (the same bits as `log_f64`).
#[inline(always)]
pub fn log_f64_bits(x: f64) -> f64 {
    let tiny = x < f64::MIN_POSITIVE;
    let bits = f64::select(x, x * 1.8446744073709552e19, tiny).to_bits();
    // The biased exponent as a float by the 2^52 trick (AVX2 has no packed
    // 64-bit integer conversion), exact.
    let biased = f64::from_bits((bits >> 52 & 0x7ff) | 0x4330_0000_0000_0000) - 4503599627370496.0;
    let e = biased - f64::select(1023.0, 1087.0, tiny);
    let m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    let normal = x > 0.0 && x <= f64::MAX;
    log_kernel_f64(x, f64::select(x, m, normal), f64::select(0.0, e, normal))
}

/// The chaos indicators' ln x in f32 ([`sample_log_core_f32`]), on the
/// CPU and in WGSL (`prelude_f32.wgsl`) by the same operations:
/// x = 2^k·(1 + f) with 1 + f in [√½, √2) read from the bits, offset by
/// √½'s as musl's `logf` does, so that a subtraction, a shift and a mask
/// give k and f without a select; subnormals scaled into the normal range
/// first.
#[inline(always)]
pub fn sample_log_f32(x: f32) -> f32 {
    let tiny = x < f32::MIN_POSITIVE;
    let (f, k) = sample_log_split(f32::select(x, x * 4294967296.0, tiny));
    let res = sample_log_core_f32(f, k - f32::select(0.0, 32.0, tiny));
    sample_log_cases_f32(x, res)
}

/// [`sample_log_f32`] for a positive normal finite x (the FLI/MEGNO sample
/// of a vector in the band of `in_band_r`): without the cases it would not
/// take there, so the same bits.
#[inline(always)]
pub fn sample_log_normal_f32(x: f32) -> f32 {
    let (f, k) = sample_log_split(x);
    sample_log_core_f32(f, k)
}

/// (f, k) with x = 2^k·(1 + f), 1 + f in [√½, √2), for a positive normal x.
#[inline(always)]
fn sample_log_split(x: f32) -> (f32, f32) {
    const SQRT_HALF: u32 = 0x3f35_04f3;
    let ix = x.to_bits().wrapping_sub(SQRT_HALF);
    let k = ((ix as i32) >> 23) as f32;
    (f32::from_bits((ix & 0x007f_ffff) + SQRT_HALF) - 1.0, k)
}

/// ln x for a positive normal finite x: the bits of [`log_f64_bits`] (the
/// chaos indicators' logarithm in f64; a division-free one would need a
/// polynomial of degree about 20). x = 2^k·m with m in [√½, √2) read from
/// the bits offset by √½'s mantissa, as [`sample_log_split`] does, so that
/// `log_core_f64`'s compare, selects and halving fall away: the same m
/// and k, exactly, so the same bits.
#[inline(always)]
pub fn log_normal_f64(x: f64) -> f64 {
    // √½ = 0x1.6a09e667f3bcdp−1, one ULP up: `log_core_f64` halves m
    // only above √2's double. Its mantissa alone is subtracted, so that
    // the subtraction never wraps for a normal x (bits ≥ 2⁵²).
    const SQRT_HALF: u64 = 0x3fe6_a09e_667f_3bce;
    const MANT: u64 = 0x000f_ffff_ffff_ffff;
    let ix = x.to_bits().wrapping_sub(SQRT_HALF & MANT);
    // ix's exponent field is k + 1022; as a float by the 2^52 trick (AVX2
    // has no packed 64-bit integer conversion), exact.
    let k = f64::from_bits((ix >> 52) | 0x4330_0000_0000_0000) - (4503599627370496.0 + 1022.0);
    let m = f64::from_bits((ix & MANT) + SQRT_HALF);
    log_reduced_f64(m, k)
}

impl Math for f32 {
    #[inline(always)]
    fn exp_r(x: f32) -> f32 {
        exp_f32(x)
    }
    #[inline(always)]
    fn log_r(x: f32) -> f32 {
        log_f32_bits(x)
    }
    #[inline(always)]
    fn sample_log_r(x: f32) -> f32 {
        sample_log_f32(x)
    }
    #[inline(always)]
    fn sample_log_normal_r(x: f32) -> f32 {
        sample_log_normal_f32(x)
    }
    #[inline(always)]
    fn atan_r(x: f32) -> f32 {
        atan_f32(x)
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
    fn log_r(x: f64) -> f64 {
        log_f64_bits(x)
    }
    #[inline(always)]
    fn sample_log_r(x: f64) -> f64 {
        log_f64_bits(x)
    }
    #[inline(always)]
    fn sample_log_normal_r(x: f64) -> f64 {
        log_normal_f64(x)
    }
    #[inline(always)]
    fn atan_r(x: f64) -> f64 {
        atan_f64(x)
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

    /// The CPU's logarithm reads x = 2^e·m from the bits, the shared text's
    /// (WGSL's) finds it by a ladder of exact scalings: the same bits over
    /// every 7th f32 (all of them took a minute) and every f32 of the
    /// exponents where the two could part: zeros and subnormals, the
    /// smallest normals, the largest and ∞/NaN, both signs.
    #[test]
    fn log_from_the_bits_is_the_ladder_over_the_f32() {
        use rayon::prelude::*;
        let bad = (0u32..1 << 16).into_par_iter().find_map_any(|hi| {
            let strided = (0..1u32 << 16)
                .map(|lo| hi << 16 | lo)
                .filter(|b| b % 7 == 0);
            // The biased exponent: bits 30…23 of the f32, 14…7 of `hi`.
            let edge = [0, 1, 254, 255].contains(&(hi >> 7 & 0xff));
            let all = (0..1u32 << 16).map(|lo| hi << 16 | lo).filter(|_| edge);
            let xs: Vec<f32> = strided.chain(all).map(f32::from_bits).collect();
            let mut fast = vec![0f32; xs.len()];
            let mut ladder = vec![0f32; xs.len()];
            for i in 0..xs.len() {
                fast[i] = log_f32_bits(xs[i]);
                ladder[i] = log_f32(xs[i]);
            }
            (0..xs.len())
                .find(|&i| fast[i].to_bits() != ladder[i].to_bits())
                .map(|i| (xs[i], fast[i], ladder[i]))
        });
        assert_eq!(bad, None, "x, from the bits, by the ladder");
    }

    /// As above in f64: every power of two and its neighbours, subnormals,
    /// special values and ten million random bit patterns.
    #[test]
    fn log_from_the_bits_is_the_ladder_in_f64() {
        let mut xs: Vec<f64> = vec![
            0.0,
            -0.0,
            f64::INFINITY,
            -f64::INFINITY,
            f64::NAN,
            -f64::NAN,
        ];
        xs.extend([f64::MIN_POSITIVE, f64::MAX, f64::EPSILON, 5e-324, 1.0, -1.0]);
        for k in -1074..=1023 {
            let p = 2f64.powi(k);
            xs.extend([p, p.next_up(), p.next_down(), p * std::f64::consts::SQRT_2]);
        }
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..10_000_000 {
            // xorshift64*: every bit pattern reachable.
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            xs.push(f64::from_bits(state.wrapping_mul(0x2545_f491_4f6c_dd1d)));
        }
        for x in xs {
            let (fast, ladder) = (log_f64_bits(x), log_f64(x));
            assert_eq!(
                fast.to_bits(),
                ladder.to_bits(),
                "ln {x:e}: {fast:e} vs {ladder:e}"
            );
        }
    }

    crate::with_fma! {
        /// `f32::sample_log_r` does not decrease over `bits`.
        fn sample_log_rises(bits: std::ops::RangeInclusive<u32>) {
            let mut prev = f32::NEG_INFINITY;
            for b in bits {
                let y = f32::sample_log_r(f32::from_bits(b));
                assert!(y >= prev, "ln {:e}", f32::from_bits(b));
                prev = y;
            }
        }
    }

    /// The indicators' ln is non-decreasing on the band [2⁻⁴⁰, 2⁶⁰] where
    /// they keep ‖u‖², so the largest ‖u‖² of some steps gives the largest
    /// ln‖u‖ (a run of steps keeps the FLI that way): every f32 there; in
    /// f64 10⁴ neighbours on each side of each power of two and of the
    /// kernel's switch at √2 times one, and 10⁶ from random places.
    #[test]
    fn log_is_monotone_on_the_band() {
        let (lo, hi) = (2f32.powi(-40).to_bits(), 2f32.powi(60).to_bits());
        sample_log_rises(lo..=hi);
        let run = |from: f64, count: u64| {
            let start = from.to_bits() - count / 2;
            let mut prev = f64::NEG_INFINITY;
            for b in start..start + count {
                let y = log_f64_bits(f64::from_bits(b));
                assert!(y >= prev, "ln {:e}", f64::from_bits(b));
                prev = y;
            }
        };
        for e in -40..60 {
            let p = 2f64.powi(e);
            run(p, 20_000);
            run(p * std::f64::consts::SQRT_2, 20_000);
        }
        let mut x = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..100 {
            // xorshift: a place in the band.
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            run(2f64.powf((x % 100_000) as f64 / 1000.0 - 40.0), 10_000);
        }
    }

    crate::with_fma! {
        /// `sample_log_normal_f32` is `sample_log_f32` at every f32 of `bits`.
        fn same_sample_logs(bits: std::ops::RangeInclusive<u32>) {
            for b in bits {
                let x = f32::from_bits(b);
                assert_eq!(
                    sample_log_normal_f32(x).to_bits(),
                    sample_log_f32(x).to_bits(),
                    "ln {x:e}"
                );
            }
        }
    }

    /// `sample_log_normal_r` is `sample_log_r` bit for bit on positive
    /// normal numbers: every f32 of the band [2⁻⁴⁰, 2⁶⁰] (where the samples
    /// call it) and 10⁶ at each end of the normal range; in f64 10⁴
    /// neighbours of each power of two from 2⁻¹⁰²² to 2¹⁰²³ and of its √2
    /// multiple (the kernel's switch).
    #[test]
    fn log_normal_is_log_on_normal_numbers() {
        let (lo, hi) = (f32::MIN_POSITIVE.to_bits(), f32::MAX.to_bits());
        let band = 2f32.powi(-40).to_bits()..=2f32.powi(60).to_bits();
        for bits in [band, lo..=lo + 999_999, hi - 999_999..=hi] {
            same_sample_logs(bits);
        }
        for e in -1022..=1023 {
            for p in [2f64.powi(e), 2f64.powi(e) * std::f64::consts::SQRT_2] {
                let start = p
                    .to_bits()
                    .saturating_sub(5_000)
                    .max(f64::MIN_POSITIVE.to_bits());
                let end = (start + 10_000).min(f64::MAX.to_bits());
                for b in start..=end {
                    let x = f64::from_bits(b);
                    assert_eq!(
                        f64::sample_log_normal_r(x).to_bits(),
                        f64::sample_log_r(x).to_bits(),
                        "ln {x:e}"
                    );
                }
            }
        }
    }

    /// The indicators' rescaling: a vector of squared norm n2 times 2^a
    /// has n2·4^a back in [2⁻⁴⁰, 2⁶⁰] from a rung beyond it, exactly (a
    /// power of two), nothing moves inside it, and a collapsed or NaN
    /// vector gets NaN (so that it is flagged).
    #[test]
    fn octaves_rescale_exactly_into_the_band() {
        fn check<R: Elementary + Copy + PartialOrd + std::fmt::Debug + Into<f64>>(
            from: impl Fn(f64) -> R,
        ) {
            for e in -100..=100 {
                let n2 = from(2f64.powi(e) * 1.375);
                let a: f64 = R::octave_r(n2).into();
                let s: f64 = R::rescale_r(from(a)).into();
                assert_eq!(s, 2f64.powf(a), "2^{a}");
                let band = (-40..60).contains(&e);
                assert_eq!(a == 0.0, band, "n2 = 2^{e}·1.375: a = {a}");
                let moved = Into::<f64>::into(n2) * s * s;
                let closer = (moved.log2().abs() < (e as f64 + 0.46).abs()) || band;
                assert!(closer, "n2 = 2^{e}·1.375 moved to {moved:e}");
            }
            for bad in [0.0, f64::NAN] {
                let a: f64 = R::octave_r(from(bad)).into();
                assert!(a.is_nan() && Into::<f64>::into(R::rescale_r(from(a))).is_nan());
            }
        }
        check::<f32>(|x| x as f32);
        check::<f64>(|x| x);
    }
}
