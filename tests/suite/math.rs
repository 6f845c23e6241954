//! reeb's polynomial exp/sin/cos against the platform libm: ≤ 2 ULP over the
//! documented ranges, and the edges (overflow, underflow, NaN, large arguments).

use reeb::num::math::{
    atan_f32, atan_f64, exp_f32, exp_f64, log_f32, log_f64, sample_log_f32, sincos_f32, sincos_f64,
};

/// Distance in ULPs of `x` from the f64 reference `r`, in f32 units.
fn ulp32(x: f32, r: f64) -> f64 {
    if r == 0.0 {
        return (x as f64).abs() / f32::from_bits(1) as f64;
    }
    let rf = r as f32;
    let ulp = (f32::from_bits(rf.abs().to_bits() + 1) - rf.abs()) as f64;
    ((x as f64) - r).abs() / ulp
}

/// Distance in ULPs of `x` from the (≤ 1 ULP) libm value `r`, in f64 units.
fn ulp64(x: f64, r: f64) -> f64 {
    if x == r {
        return 0.0;
    }
    let ulp = f64::from_bits(r.abs().to_bits() + 1) - r.abs();
    (x - r).abs() / ulp
}

/// Deterministic sample of n points in [lo, hi] (SplitMix64).
fn sample(lo: f64, hi: f64, n: usize, seed: u64) -> Vec<f64> {
    let mut z = seed;
    (0..n)
        .map(|_| {
            z = z.wrapping_add(0x9e3779b97f4a7c15);
            let mut x = z;
            x = (x ^ (x >> 30)).wrapping_mul(0xbf58476d1ce4e5b9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94d049bb133111eb);
            x ^= x >> 31;
            lo + (hi - lo) * (x >> 11) as f64 / (1u64 << 53) as f64
        })
        .collect()
}

#[test]
fn exp_f32_within_2_ulp() {
    let mut worst = (0.0, 0.0);
    for x in sample(-87.3, 88.37, 200_000, 1)
        .into_iter()
        .chain(sample(-1.0, 1.0, 100_000, 2))
    {
        let x = x as f32;
        let e = ulp32(exp_f32(x), (x as f64).exp());
        if e > worst.0 {
            worst = (e, x as f64);
        }
    }
    assert!(worst.0 <= 2.0, "exp_f32: {} ULP at {}", worst.0, worst.1);
}

#[test]
fn exp_f64_within_2_ulp() {
    let mut worst = (0.0, 0.0);
    for x in sample(-708.0, 709.43, 200_000, 3)
        .into_iter()
        .chain(sample(-1.0, 1.0, 100_000, 4))
    {
        let e = ulp64(exp_f64(x), x.exp());
        if e > worst.0 {
            worst = (e, x);
        }
    }
    assert!(worst.0 <= 2.0, "exp_f64: {} ULP at {}", worst.0, worst.1);
}

#[test]
fn exp_edges() {
    assert_eq!(exp_f32(0.0), 1.0);
    assert_eq!(exp_f64(0.0), 1.0);
    assert_eq!(exp_f32(89.0), f32::INFINITY);
    assert_eq!(exp_f32(1e30), f32::INFINITY);
    assert_eq!(exp_f32(f32::INFINITY), f32::INFINITY);
    assert_eq!(exp_f32(-104.0), 0.0);
    assert_eq!(exp_f32(f32::NEG_INFINITY), 0.0);
    assert_eq!(exp_f64(710.0), f64::INFINITY);
    assert_eq!(exp_f64(f64::INFINITY), f64::INFINITY);
    assert_eq!(exp_f64(-746.0), 0.0);
    assert_eq!(exp_f64(f64::NEG_INFINITY), 0.0);
    assert!(exp_f32(f32::NAN).is_nan());
    assert!(exp_f64(f64::NAN).is_nan());
    // The largest finite results, and the first infinite ones (the exact
    // values are finite up to 88.72 and 709.78: one scale, not two halves).
    assert!(exp_f32(88.376).is_finite());
    assert_eq!(exp_f32(88.377), f32::INFINITY);
    assert!(exp_f64(709.43).is_finite());
    assert_eq!(exp_f64(709.44), f64::INFINITY);
}

/// Below the normal range the result flushes to 0 (n ≤ −127 in f32, −1023 in
/// f64); just above that, where 2^n is the smallest normal power, within one
/// and a half subnormal steps of the exact value.
#[test]
fn exp_flushes_below_the_normal_range() {
    for x in sample(-110.0, -87.0, 100_000, 11) {
        let x = x as f32;
        let (got, want) = (exp_f32(x) as f64, (x as f64).exp());
        if x <= -87.69 {
            assert_eq!(got, 0.0, "exp_f32({x})");
        } else if x >= -87.67 {
            let step = f32::from_bits(1) as f64;
            assert!(
                (got - want).abs() <= 1.5 * step,
                "exp_f32({x}) = {got}, not {want}"
            );
        }
    }
    for x in sample(-760.0, -708.0, 100_000, 12) {
        let (got, want) = (exp_f64(x), x.exp());
        if x <= -708.75 {
            assert_eq!(got, 0.0, "exp_f64({x})");
        } else if x >= -708.73 {
            let step = f64::from_bits(1);
            assert!(
                (got - want).abs() <= 1.5 * step,
                "exp_f64({x}) = {got}, not {want}"
            );
        }
    }
    assert_eq!(exp_f32(-88.0), 0.0);
    assert!(exp_f32(-87.3) >= f32::MIN_POSITIVE);
    assert_eq!(exp_f64(-709.0), 0.0);
    assert!(exp_f64(-708.3) >= f64::MIN_POSITIVE);
}

fn sincos32(x: f32) -> (f32, f32) {
    let (mut s, mut c) = (0.0, 0.0);
    sincos_f32(x, &mut s, &mut c);
    (s, c)
}

fn sincos64(x: f64) -> (f64, f64) {
    let (mut s, mut c) = (0.0, 0.0);
    sincos_f64(x, &mut s, &mut c);
    (s, c)
}

#[test]
fn sincos_f32_within_2_ulp() {
    let mut worst = (0.0, 0.0);
    for x in sample(-8192.0, 8192.0, 200_000, 5)
        .into_iter()
        .chain(sample(-4.0, 4.0, 100_000, 6))
    {
        let x = x as f32;
        let (s, c) = sincos32(x);
        let xd = x as f64;
        // Near zeros of sin/cos an ULP is tiny; measure against max(|f|, 2^-24)
        // scale there, as the reduction error is absolute (≈ 2^-24 · |r|).
        for (v, r) in [(s, xd.sin()), (c, xd.cos())] {
            let e = if r.abs() < 1e-3 {
                (v as f64 - r).abs() / (f32::EPSILON as f64 * 1e-3)
            } else {
                ulp32(v, r)
            };
            if e > worst.0 {
                worst = (e, xd);
            }
        }
    }
    assert!(worst.0 <= 2.0, "sincos_f32: {} ULP at {}", worst.0, worst.1);
}

#[test]
fn sincos_f64_within_2_ulp() {
    let mut worst = (0.0, 0.0);
    for x in sample(-1e6, 1e6, 200_000, 7)
        .into_iter()
        .chain(sample(-4.0, 4.0, 100_000, 8))
    {
        let (s, c) = sincos64(x);
        for (v, r) in [(s, x.sin()), (c, x.cos())] {
            let e = if r.abs() < 1e-3 {
                (v - r).abs() / (f64::EPSILON * 1e-3)
            } else {
                ulp64(v, r)
            };
            if e > worst.0 {
                worst = (e, x);
            }
        }
    }
    assert!(worst.0 <= 2.0, "sincos_f64: {} ULP at {}", worst.0, worst.1);
}

#[test]
fn sincos_edges() {
    assert_eq!(sincos32(0.0), (0.0, 1.0));
    assert_eq!(sincos64(0.0), (0.0, 1.0));
    // Beyond the accurate range the results stay bounded.
    for x in [1e5f32, 3.3e7, 1e20] {
        let (s, c) = sincos32(x);
        assert!(
            s.abs() <= 1.0 + 1e-6 && c.abs() <= 1.0 + 1e-6,
            "{x}: {s} {c}"
        );
    }
    for x in [1e8f64, 1e15] {
        let (s, c) = sincos64(x);
        assert!(
            s.abs() <= 1.0 + 1e-12 && c.abs() <= 1.0 + 1e-12,
            "{x}: {s} {c}"
        );
    }
    assert!(sincos32(f32::NAN).0.is_nan());
    assert!(sincos64(f64::NAN).1.is_nan());
    // Tiny arguments: sin x = x exactly for |x| far below the ULP of x²/6.
    assert_eq!(sincos32(1e-20).0, 1e-20);
    assert_eq!(sincos64(1e-200).0, 1e-200);
}

/// Worst ULP error of `f` against `reference` over `xs` (f64).
fn worst64(xs: &[f64], f: impl Fn(f64) -> f64, reference: impl Fn(f64) -> f64) -> (f64, f64) {
    xs.iter().fold((0.0, 0.0), |w, &x| {
        let e = ulp64(f(x), reference(x));
        if e > w.0 {
            (e, x)
        } else {
            w
        }
    })
}

/// Worst ULP error of `f` against the f64 `reference` over `xs` (f32).
fn worst32(xs: &[f64], f: impl Fn(f32) -> f32, reference: impl Fn(f64) -> f64) -> (f64, f64) {
    xs.iter().fold((0.0, 0.0), |w, &x| {
        let x = x as f32;
        let e = ulp32(f(x), reference(x as f64));
        if e > w.0 {
            (e, x as f64)
        } else {
            w
        }
    })
}

/// Log-uniform positive arguments from 2^lo to 2^hi.
fn positive(lo: f64, hi: f64, n: usize, seed: u64) -> Vec<f64> {
    sample(lo, hi, n, seed)
        .into_iter()
        .map(|e| e.exp2())
        .collect()
}

#[test]
fn log_within_2_ulp_everywhere() {
    let xs = positive(-1074.0, 1023.9, 200_000, 11);
    let near_one = sample(0.5, 2.0, 100_000, 12);
    for set in [&xs, &near_one] {
        let w = worst64(set, log_f64, f64::ln);
        assert!(w.0 <= 2.0, "log_f64: {} ULP at {:e}", w.0, w.1);
    }
    let xs32 = positive(-149.0, 127.9, 200_000, 13);
    for set in [&xs32, &near_one] {
        let w = worst32(set, log_f32, f64::ln);
        assert!(w.0 <= 2.0, "log_f32: {} ULP at {:e}", w.0, w.1);
    }
    assert_eq!(log_f64(1.0), 0.0);
    assert_eq!(log_f64(0.0), f64::NEG_INFINITY);
    assert_eq!(log_f64(f64::INFINITY), f64::INFINITY);
    assert!(log_f64(-1.0).is_nan() && log_f64(f64::NAN).is_nan());
    assert_eq!(log_f32(0.0), f32::NEG_INFINITY);
    assert!(log_f32(-2.0).is_nan());
}

reeb::with_fma! {
    /// The largest error in ULP of `sample_log_f32` (and its input's bits)
    /// over the 2¹⁶ f32 whose high bits are `hi`: at subnormals (below
    /// `normal`) and every 3rd normal up to `max`.
    /// (A plain loop: iterator adapters' closures would be compiled apart,
    /// without FMA.)
    fn worst_sample_log(hi: u32, normal: u32, max: u32) -> (f64, u32) {
        let mut worst = (0.0, 0);
        for lo in 0..1u32 << 16 {
            let b = hi << 16 | lo;
            if b > 0 && b <= max && (b < normal || b.is_multiple_of(3)) {
                let x = f32::from_bits(b);
                let e = ulp32(sample_log_f32(x), f64::from(x).ln());
                if e > worst.0 {
                    worst = (e, b);
                }
            }
        }
        worst
    }
}

/// The chaos indicators' f32 logarithm (division-free) is within 1.01
/// ULP of ln x at every subnormal and every 3rd positive normal f32, with
/// the cases of `log_r`: 0, < 0, ∞, NaN.
#[test]
fn sample_log_within_1_01_ulp_over_the_f32() {
    use rayon::prelude::*;
    let larger = |a: (f64, u32), b: (f64, u32)| if b.0 > a.0 { b } else { a };
    let (normal, max) = (f32::MIN_POSITIVE.to_bits(), f32::MAX.to_bits());
    let worst = (0u32..1 << 15)
        .into_par_iter()
        .map(|hi| worst_sample_log(hi, normal, max))
        .reduce(|| (0.0, 0), larger);
    let at = f32::from_bits(worst.1);
    assert!(worst.0 <= 1.01, "sample_log_f32: {} ULP at {at:e}", worst.0);
    assert_eq!(sample_log_f32(1.0), 0.0);
    assert_eq!(sample_log_f32(0.0), f32::NEG_INFINITY);
    assert_eq!(sample_log_f32(f32::INFINITY), f32::INFINITY);
    assert!(sample_log_f32(-1.0).is_nan() && sample_log_f32(f32::NAN).is_nan());
    assert!(sample_log_f32(f32::NEG_INFINITY).is_nan());
}

#[test]
fn atan_within_2_ulp() {
    let xs: Vec<f64> = sample(-4.0, 4.0, 200_000, 14)
        .into_iter()
        .chain(sample(-1e6, 1e6, 100_000, 15))
        .chain([1e300, -1e300, 1e-300])
        .collect();
    let w = worst64(&xs, atan_f64, f64::atan);
    assert!(w.0 <= 2.0, "atan_f64: {} ULP at {:e}", w.0, w.1);
    let w = worst32(&xs, atan_f32, f64::atan);
    assert!(w.0 <= 2.0, "atan_f32: {} ULP at {:e}", w.0, w.1);
    assert_eq!(atan_f64(f64::INFINITY), std::f64::consts::FRAC_PI_2);
    assert!(atan_f64(f64::NAN).is_nan());
}

#[test]
fn hyperbolic_tan_and_pow_within_bounds() {
    use reeb::num::math::Elementary;
    let xs: Vec<f64> = sample(-20.0, 20.0, 100_000, 16)
        .into_iter()
        .chain(sample(-0.6, 0.6, 100_000, 17))
        .collect();
    type Case = (&'static str, fn(f64) -> f64, fn(f64) -> f64, f64);
    let cases: [Case; 4] = [
        ("sinh", f64::sinh_r, f64::sinh, 3.0),
        ("cosh", f64::cosh_r, f64::cosh, 3.0),
        ("tanh", f64::tanh_r, f64::tanh, 4.0),
        ("tan", f64::tan_r, f64::tan, 4.0),
    ];
    for (name, f, r, bound) in cases {
        let xs: Vec<f64> = if name == "tan" {
            sample(-1.5, 1.5, 100_000, 18)
        } else {
            xs.clone()
        };
        let w = worst64(&xs, f, r);
        assert!(w.0 <= bound, "{name}_r f64: {} ULP at {:e}", w.0, w.1);
        let w = worst32(
            &xs,
            |x| match name {
                "sinh" => f32::sinh_r(x),
                "cosh" => f32::cosh_r(x),
                "tanh" => f32::tanh_r(x),
                _ => f32::tan_r(x),
            },
            r,
        );
        assert!(w.0 <= bound, "{name}_r f32: {} ULP at {:e}", w.0, w.1);
    }
    // x^y = e^{y ln x}: the error grows with |y ln x| (documented).
    let bases = sample(0.1, 10.0, 50_000, 19);
    for x in bases {
        let e = ulp64(f64::pow_r(x, 2.5), x.powf(2.5));
        let bound = 3.0 + 2.0 * (2.5 * x.ln()).abs();
        assert!(e <= bound, "pow_r({x}, 2.5): {e} ULP > {bound}");
    }
    assert!(f64::pow_r(-1.0, 0.5).is_nan());
    assert_eq!(f64::sign_r(-3.0), -1.0);
    assert_eq!(f64::sign_r(0.0), 0.0);
    assert_eq!(f64::min_r(1.0, 2.0), 1.0);
    assert_eq!(f64::max_r(1.0, 2.0), 2.0);
}
