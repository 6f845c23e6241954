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
    /// The observers' per-step logic, and interpolation inside a step.
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
    /// Trajectory observer: is the state after step n1 frame number n1/every?
    fn frame_due(n1: i32, every: i32) -> bool {
        return n1 % every == 0;
    }
    /// Stroboscopic section sampled exactly (period and phase whole numbers of
    /// steps): the sampling interval and the first sample, in steps.
    fn strobe_exact_steps(period: R, phase: R, dt: R, every: &mut i32, first: &mut i32) {
        *every = R::to_i32(R::floor(period / dt + 0.5));
        *first = R::to_i32(R::floor(phase / dt + 0.5));
    }
    /// Exact stroboscopic section: is the state after step n1 a sample?
    fn strobe_exact_due(n1: i32, every: i32, first: i32) -> bool {
        return every > 0 && n1 >= first && (n1 - first) % every == 0;
    }
    /// Interpolated stroboscopic section: is sample k due in the step that
    /// ends at n1 (every sample in (t_{n1−1}, t_{n1}], and t0 itself at the
    /// initial state), and at which θ of the step?
    fn strobe_due(k: R, period: R, phase: R, dt: R, n1: R, initial: bool, th: &mut R) -> bool {
        let x: R = R::strobe_position(k, period, phase, dt);
        *th = R::select(R::max(R::min(x - n1 + 1.0, 1.0), 0.0), 1.0, initial);
        return x <= n1 + 1e-4;
    }
    /// Event section: does y (the crossing variable minus its level) cross
    /// zero between the step ends y0 → y1 in `direction` (0 up, 1 down, 2 both)?
    fn crossing_due(y0: R, y1: R, direction: i32) -> bool {
        let up: bool = y0 < 0.0 && y1 >= 0.0;
        let down: bool = y0 > 0.0 && y1 <= 0.0;
        return (up && direction != 1) || (down && direction != 0);
    }
    /// An observed state variable at θ inside the step y0 → y1 (θ = 1: the
    /// step's end, exactly).
    fn observed_state(y0: R, y1: R, d0: R, d1: R, h: R, th: R) -> R {
        return R::select(R::hermite(y0, y1, d0, d1, h, th), y1, th == 1.0);
    }
    /// Time at θ inside the step that ends at step n1.
    fn observed_time(t0: R, n1: R, dt: R, th: R) -> R {
        return (t0 + n1 * dt) - (1.0 - th) * dt;
    }
    /// Cycle statistics over one step of the measuring window: the running
    /// extremes of x, and each upward crossing of the level (y0 → y1 relative
    /// to it, slopes d0, d1) located inside the step, which starts at time
    /// `t_start`, counted and added to the least-squares period.
    fn cycle_step(x: R, y0: R, y1: R, d0: R, d1: R, dt: R, t_start: R,
                  cyc_max: &mut R, cyc_min: &mut R, cyc_count: &mut R,
                  cyc_first: &mut R, cyc_mean: &mut R, cyc_com: &mut R) {
        *cyc_max = R::select(*cyc_max, x, x > *cyc_max);
        *cyc_min = R::select(*cyc_min, x, x < *cyc_min);
        if y0 < 0.0 && y1 >= 0.0 {
            let th: R = R::crossing_theta(y0, y1, d0, d1, dt);
            let tc: R = t_start + th * dt;
            if *cyc_count == 0.0 {
                *cyc_first = tc;
            }
            R::cycle_crossing(*cyc_count, tc - *cyc_first, cyc_mean, cyc_com);
            *cyc_count = *cyc_count + 1.0;
        }
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
    /// A time average's running mean after its k-th value x (k ≥ 1): the
    /// mean of k values without their sum, which in f32 would lose the
    /// digits of the later ones.
    fn mean_step(x: R, k: R, mean: &mut R) {
        *mean = *mean + (x - *mean) / k;
    }
    /// Half the peak-to-peak range of the cycle variable.
    fn cycle_amplitude(cyc_max: R, cyc_min: R) -> R {
        return 0.5 * (cyc_max - cyc_min);
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
