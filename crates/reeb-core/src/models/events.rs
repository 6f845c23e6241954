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
    /// kept inside the shrinking bracket, 8 iterations written out (a GPU
    /// kernel's loops count against llvmpipe's limit of 65 535 iterations
    /// per dispatch, shared by all its loops; see `gpu/run.rs`).
    fn crossing_theta(y0: R, y1: R, d0: R, d1: R, h: R) -> R {
        let mut lo: R = 0.0;
        let mut hi: R = 1.0;
        let mut th: R = y0 / (y0 - y1);
        R::newton_in_bracket(y0, y1, d0, d1, h, &mut lo, &mut hi, &mut th);
        R::newton_in_bracket(y0, y1, d0, d1, h, &mut lo, &mut hi, &mut th);
        R::newton_in_bracket(y0, y1, d0, d1, h, &mut lo, &mut hi, &mut th);
        R::newton_in_bracket(y0, y1, d0, d1, h, &mut lo, &mut hi, &mut th);
        R::newton_in_bracket(y0, y1, d0, d1, h, &mut lo, &mut hi, &mut th);
        R::newton_in_bracket(y0, y1, d0, d1, h, &mut lo, &mut hi, &mut th);
        R::newton_in_bracket(y0, y1, d0, d1, h, &mut lo, &mut hi, &mut th);
        R::newton_in_bracket(y0, y1, d0, d1, h, &mut lo, &mut hi, &mut th);
        return th;
    }
    /// One iteration of `crossing_theta`: the bracket [lo, hi] shrunk to
    /// the side of θ where the sign changes, then a Newton step from θ, or
    /// the bracket's midpoint where Newton leaves it.
    fn newton_in_bracket(y0: R, y1: R, d0: R, d1: R, h: R, lo: &mut R, hi: &mut R, th: &mut R) {
        let f: R = R::hermite(y0, y1, d0, d1, h, *th);
        let same: bool = (f < 0.0) == (y0 < 0.0);
        *lo = R::select(*lo, *th, same);
        *hi = R::select(*th, *hi, same);
        let fp: R = R::hermite_slope(y0, y1, d0, d1, h, *th);
        let nx: R = *th - f / fp;
        let inside: bool = nx >= *lo && nx <= *hi;
        *th = R::select(0.5 * (*lo + *hi), nx, inside);
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
        return R::strobe_reached(x, n1);
    }
    /// Is the sample at position x (`strobe_position`) due after step n1?
    fn strobe_reached(x: R, n1: R) -> bool {
        return x <= n1 + 1e-4;
    }
    /// Event section: does y (the crossing variable minus its level) cross
    /// zero between the step ends y0 → y1 in `direction` (0 up, 1 down, 2 both)?
    fn crossing_due(y0: R, y1: R, direction: i32) -> bool {
        let up: bool = y0 < 0.0 && y1 >= 0.0;
        let down: bool = y0 > 0.0 && y1 <= 0.0;
        return (up && direction != 1) || (down && direction != 0);
    }
    /// The Poincaré section's next point in the step that ends at n1 (0:
    /// the initial state), and its θ inside the step: both backends call it
    /// until it says no, recording a point each time. `kind`
    /// (`plan/section.rs`): 0 stroboscopic sampled exactly (`every`,
    /// `first` from `strobe_exact_steps`), 1 stroboscopic interpolated
    /// (`k`: samples taken so far), 2 event crossing of y = variable − level
    /// (y0 → y1, slopes d0, d1) in `direction`. `done` starts false each step.
    fn section_next(kind: i32, n1: i32, initial: bool, every: i32, first: i32,
                    period: R, phase: R, dt: R, y0: R, y1: R, d0: R, d1: R,
                    direction: i32, k: &mut i32, done: &mut bool, th: &mut R) -> bool {
        if *done {
            return false;
        }
        *th = 1.0;
        if kind == 1 {
            let due: bool = R::strobe_due(R::from_i32(*k), period, phase, dt, R::from_i32(n1), initial, th);
            if due {
                *k = *k + 1;
            }
            *done = !due;
            return due;
        }
        *done = true;
        if kind == 0 {
            return R::strobe_exact_due(n1, every, first);
        }
        if initial || !R::crossing_due(y0, y1, direction) {
            return false;
        }
        *th = R::crossing_theta(y0, y1, d0, d1, dt);
        return true;
    }
    /// A Poincaré point was found: is it kept (fewer than `max_points` before
    /// it, its number the count before this call)? Counts it either way,
    /// saturating.
    fn point_kept(npoints: &mut i32, max_points: i32) -> bool {
        let kept: bool = *npoints < max_points;
        if *npoints < 2147483647 {
            *npoints = *npoints + 1;
        }
        return kept;
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
        R::cycle_extremes(x, cyc_max, cyc_min);
        if R::cycle_up(y0, y1) {
            R::cycle_upcrossing(y0, y1, d0, d1, dt, t_start, cyc_count, cyc_first, cyc_mean, cyc_com);
        }
    }
    /// The running extremes of `cycle_step`. (The CPU applies its three
    /// parts over a block's lanes apart: the extremes and the test on every
    /// lane at once, the crossing only on the lanes that cross.)
    fn cycle_extremes(x: R, cyc_max: &mut R, cyc_min: &mut R) {
        *cyc_max = R::select(*cyc_max, x, x > *cyc_max);
        *cyc_min = R::select(*cyc_min, x, x < *cyc_min);
    }
    /// Does the step y0 → y1 cross the level upwards (`cycle_step`)?
    fn cycle_up(y0: R, y1: R) -> bool {
        return y0 < 0.0 && y1 >= 0.0;
    }
    /// An upward crossing of `cycle_step`, located inside the step and
    /// counted.
    fn cycle_upcrossing(y0: R, y1: R, d0: R, d1: R, dt: R, t_start: R, cyc_count: &mut R,
                        cyc_first: &mut R, cyc_mean: &mut R, cyc_com: &mut R) {
        let th: R = R::crossing_theta(y0, y1, d0, d1, dt);
        let tc: R = t_start + th * dt;
        if *cyc_count == 0.0 {
            *cyc_first = tc;
        }
        R::cycle_crossing(*cyc_count, tc - *cyc_first, cyc_mean, cyc_com);
        *cyc_count = *cyc_count + 1.0;
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
    /// The max-norm distance `d` so far of a sample from the sample k
    /// before it, with one more component: x now, y then; an angle's
    /// difference (`wrap` > 0: its period) taken to the nearest turn
    /// (`plan/recurrence.rs`).
    fn recurrence_gap(x: R, y: R, wrap: R, d: R) -> R {
        let mut e: R = x - y;
        if wrap > 0.0 {
            e = e - wrap * R::rint(e / wrap);
        }
        return R::max(d, R::abs(e));
    }
    /// Period k's counter after sample n (0-based: the samples before it
    /// are `n`), at distance d from the sample k before it: where it does
    /// not recur within `tolerance`, the first sample that may still be on
    /// a cycle of period k, n − k + 1 (there is none k before while n < k).
    fn recurrence_held(d: R, tolerance: R, k: R, n: R, held: &mut R) {
        if n >= k && d > tolerance {
            *held = n + 1.0 - k;
        }
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

    /// Every point `section_next` finds in one step, as θs.
    fn points(kind: i32, n1: i32, k: &mut i32, ends: [f64; 4], direction: i32) -> Vec<f64> {
        let (mut done, mut th, mut found) = (false, 0.0, vec![]);
        let [y0, y1, d0, d1] = ends;
        let (every, first, period, phase, dt) = (3, 1, 2.5, 0.0, 1.0);
        while f64::section_next(
            kind,
            n1,
            n1 == 0,
            every,
            first,
            period,
            phase,
            dt,
            y0,
            y1,
            d0,
            d1,
            direction,
            k,
            &mut done,
            &mut th,
        ) {
            found.push(th);
        }
        found
    }

    #[test]
    fn sections_find_their_points() {
        let flat = [0.0; 4];
        // Exact stroboscopic, every 3 steps from step 1: steps 1, 4, 7.
        let due: Vec<i32> = (0..9)
            .filter(|n| points(0, *n, &mut 0, flat, 0) == [1.0])
            .collect();
        assert_eq!(due, [1, 4, 7]);
        // Interpolated, period 2.5 steps: t0 itself, then 2.5 in step 3 (θ
        // 0.5), 5 at the end of step 5, 7.5 in step 8; none in step 4.
        let mut k = 0;
        assert_eq!(points(1, 0, &mut k, flat, 0), [1.0]);
        for n in 1..3 {
            assert!(points(1, n, &mut k, flat, 0).is_empty());
        }
        assert_eq!(points(1, 3, &mut k, flat, 0), [0.5]);
        assert!(points(1, 4, &mut k, flat, 0).is_empty());
        assert_eq!(points(1, 5, &mut k, flat, 0), [1.0]);
        assert_eq!(k, 3);
        // Several samples in one long step: period 2.5 steps, a step of 6.
        let (mut done, mut th, mut k, mut thetas) = (false, 0.0, 1, vec![]);
        while f64::section_next(
            1, 1, false, 0, 0, 2.5, 0.0, 6.0, 0.0, 0.0, 0.0, 0.0, 0, &mut k, &mut done, &mut th,
        ) {
            thetas.push(th);
        }
        assert_eq!((thetas.len(), k), (2, 3));
        // Crossings of y = t − 0.25 over a unit step: θ 0.25, upward only.
        let up = [-0.25, 0.75, 1.0, 1.0];
        assert_eq!(points(2, 1, &mut 0, up, 0).len(), 1);
        assert!((points(2, 1, &mut 0, up, 2)[0] - 0.25).abs() < 1e-15);
        assert!(points(2, 1, &mut 0, up, 1).is_empty());
        assert!(
            points(2, 0, &mut 0, up, 2).is_empty(),
            "not at the initial state"
        );
    }

    #[test]
    fn points_are_kept_up_to_the_limit_and_counted_saturating() {
        let mut n = 0;
        assert!(f64::point_kept(&mut n, 2));
        assert!(f64::point_kept(&mut n, 2));
        assert!(!f64::point_kept(&mut n, 2));
        assert_eq!(n, 3);
        let mut n = i32::MAX;
        assert!(!f64::point_kept(&mut n, 2));
        assert_eq!(n, i32::MAX);
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
