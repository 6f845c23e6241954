//! The observers' shared functions: what both backends evaluate to locate
//! events inside a step and to update each observer's per-trajectory state.
//! (Which observers a run has is configured in `plan/observers.rs`.)
//!
//! Inside a step, state is interpolated by the cubic Hermite polynomial through
//! the states at the step ends with the vector field there as slopes. Its
//! error, O(τ⁴) against the flow through the step's start, is below the step
//! error of every second-order scheme; crossing times are its roots, found by
//! safeguarded Newton iteration.

#[allow(unused_imports)]
use crate::num::{math::Math, prims::Prims};

crate::shared_fns! {
    /// Interpolation inside a step.
    trait ObserveFlows, wgsl OBSERVE_WGSL;

    /// Cubic Hermite interpolant at θ ∈ [0, 1] of a step of length h from
    /// (y0, slope d0) to (y1, slope d1); slopes are time derivatives.
    fn hermite(y0: R, y1: R, d0: R, d1: R, h: R, th: R) -> R {
        let u: R = 1.0 - th;
        return u * u * ((1.0 + 2.0 * th) * y0 + th * h * d0) + th * th * ((3.0 - 2.0 * th) * y1 - u * h * d1);
    }
    /// dy/dθ of the same interpolant.
    fn hermite_slope(y0: R, y1: R, d0: R, d1: R, h: R, th: R) -> R {
        let u: R = 1.0 - th;
        return 6.0 * th * u * (y1 - y0) + u * (1.0 - 3.0 * th) * h * d0 + th * (3.0 * th - 2.0) * h * d1;
    }
    /// The θ ∈ [0, 1] where the interpolant of y crosses zero, given that y0
    /// and y1 have opposite signs (or y1 = 0): Newton from the secant guess,
    /// kept inside the shrinking bracket.
    fn crossing_theta(y0: R, y1: R, d0: R, d1: R, h: R) -> R {
        let mut lo: R = 0.0;
        let mut hi: R = 1.0;
        let mut th: R = y0 / (y0 - y1);
        let mut k: i32 = 0;
        while k < 8 {
            let f: R = R::hermite(y0, y1, d0, d1, h, th);
            let same: bool = (f < 0.0) == (y0 < 0.0);
            lo = R::select(lo, th, same);
            hi = R::select(th, hi, same);
            let fp: R = R::hermite_slope(y0, y1, d0, d1, h, th);
            let nx: R = th - f / fp;
            let inside: bool = nx >= lo && nx <= hi;
            th = R::select(0.5 * (lo + hi), nx, inside);
            k = k + 1;
        }
        return th;
    }
    /// Position, in steps from t0, of stroboscopic sample k (time
    /// t0 + phase + k·period); sample k is due after step n1 when the position
    /// is at most n1 (+ 10⁻⁴ of a step, so rounding never drops a sample).
    fn strobe_position(k: R, period: R, phase: R, dt: R) -> R {
        return (phase + k * period) / dt;
    }
    /// Adds crossing number k (0-based) at time u (relative to the first)
    /// to the running mean of u and the co-moment C = Σ (k − k̄)(u − ū), by
    /// Welford's update. The mean of the indices before this one is
    /// (k − 1)/2, so the index needs no state: its deviation is (k + 1)/2.
    fn cycle_crossing(k: R, u: R, mean_u: &mut R, comoment: &mut R) {
        let n: R = k + 1.0;
        *mean_u = *mean_u + (u - *mean_u) / n;
        *comoment = *comoment + 0.5 * n * (u - *mean_u);
    }
    /// Least-squares period from n ≥ 2 crossings: the slope C / Σ (k − k̄)²,
    /// with Σ (k − k̄)² = n(n² − 1)/12. Averaging over all crossings cancels
    /// the interpolation error of single crossings that endpoints keep.
    fn cycle_period(comoment: R, n: R) -> R {
        return 12.0 * comoment / (n * (n * n - 1.0));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hermite_reproduces_cubics_and_finds_roots() {
        // y = t³ − 2t + 0.5 on [0, 1]: the cubic Hermite interpolant is exact.
        let y = |t: f64| t * t * t - 2.0 * t + 0.5;
        let d = |t: f64| 3.0 * t * t - 2.0;
        for th in [0.0, 0.3, 0.77, 1.0] {
            assert!((f64::hermite(y(0.0), y(1.0), d(0.0), d(1.0), 1.0, th) - y(th)).abs() < 1e-15);
        }
        let th = f64::crossing_theta(y(0.0), y(1.0), d(0.0), d(1.0), 1.0);
        assert!(y(th).abs() < 1e-15, "{th}");
        // A step of length h = 0.5 from t = 2.
        let h = 0.5;
        let th = f64::crossing_theta(y(2.0) - 5.0, y(2.5) - 5.0, d(2.0), d(2.5), h);
        assert!((y(2.0 + th * h) - 5.0).abs() < 1e-13);
    }

    #[test]
    fn least_squares_period() {
        // Crossings at 3 + 2k with alternating jitter: slope exactly 2 for the
        // symmetric jitter pattern below, and 2 ± small otherwise.
        let times = [3.0, 5.1, 7.0, 9.1, 11.0, 13.1];
        let (mut m, mut c) = (0.0, 0.0);
        for (k, t) in times.iter().enumerate() {
            f64::cycle_crossing(k as f64, t - times[0], &mut m, &mut c);
        }
        let n = times.len() as f64;
        let kbar = (n - 1.0) / 2.0;
        let tbar = times.iter().sum::<f64>() / n;
        let sxy: f64 = times
            .iter()
            .enumerate()
            .map(|(k, t)| (k as f64 - kbar) * (t - tbar))
            .sum();
        let sxx: f64 = (0..times.len()).map(|k| (k as f64 - kbar).powi(2)).sum();
        assert!((f64::cycle_period(c, n) - sxy / sxx).abs() < 1e-14);
    }
}
