//! Observers: what a run records besides its final state, and the shared
//! functions both backends use to locate events inside a step.
//!
//! Inside a step, state is interpolated by the cubic Hermite polynomial through
//! the states at the step ends with the vector field there as slopes. Its
//! error, O(τ⁴) against the flow through the step's start, is below the step
//! error of every second-order scheme; crossing times are its roots, found by
//! safeguarded Newton iteration.

#[allow(unused_imports)]
use crate::models::prelude::*;

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

/// Direction of an event crossing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Direction {
    /// From below to above the value.
    #[default]
    Up,
    Down,
    Both,
}

/// A Poincaré section.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum Section {
    /// Sample at `t0 + phase + k·period`, k = 0, 1, …: exact when the period
    /// (and phase) are whole multiples of the step, else interpolated.
    Stroboscopic { period: f64, phase: f64 },
    /// Stroboscopic at each trajectory's forcing period 2π/ω (the model's
    /// forcing frequency, which may run along an axis), after `skip` periods.
    Forced { skip: f64 },
    /// Sample where `var` crosses `value` in `direction`, located inside the step.
    Crossing {
        var: String,
        value: f64,
        direction: Direction,
    },
}

/// Poincaré-section observer.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct PoincareObs {
    pub section: Section,
    /// Variables recorded at each point (state names or `t`).
    pub vars: Vec<String>,
    /// Points kept per trajectory (later ones are counted but dropped).
    pub max_points: usize,
}

/// Trajectory observer: the state every `every` steps, from step 0.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TrajectoryObs {
    pub every: u64,
    pub vars: Vec<String>,
}

/// Limit-cycle statistics over the last part of the run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CycleObs {
    /// The variable whose oscillation is measured.
    pub var: String,
    /// Crossing level for the period (upward crossings).
    pub level: f64,
    /// Fraction of the steps skipped before measuring (transient).
    pub skip: f64,
}

impl Default for CycleObs {
    fn default() -> Self {
        CycleObs {
            var: "q".into(),
            level: 0.0,
            skip: 0.5,
        }
    }
}

/// Everything a run records.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct Observers {
    /// Variables whose final value is recorded (state names or `t`).
    pub final_vars: Vec<String>,
    pub trajectory: Option<TrajectoryObs>,
    pub poincare: Option<PoincareObs>,
    pub cycle: Option<CycleObs>,
}

impl Observers {
    /// Every variable name an observer refers to.
    pub fn variables(&self) -> Vec<String> {
        let mut v: Vec<String> = self.final_vars.clone();
        if let Some(t) = &self.trajectory {
            v.extend(t.vars.iter().cloned());
        }
        if let Some(p) = &self.poincare {
            v.extend(p.vars.iter().cloned());
            if let Section::Crossing { var, .. } = &p.section {
                v.push(var.clone());
            }
        }
        if let Some(c) = &self.cycle {
            v.push(c.var.clone());
        }
        v
    }

    /// Checks values that do not depend on the model; errors name the field.
    pub fn validate(&self, steps: u64) -> Result<(), (String, String)> {
        let e = |f: &str, m: String| Err((f.to_string(), m));
        if let Some(t) = &self.trajectory {
            if t.every == 0 {
                return e("output.trajectory.every", "must be at least 1".into());
            }
            if t.every > steps {
                return e(
                    "output.trajectory.every",
                    format!("{} is more than the {steps} steps of the run", t.every),
                );
            }
            if t.vars.is_empty() {
                return e("output.trajectory.vars", "names no variable".into());
            }
        }
        if let Some(p) = &self.poincare {
            if p.max_points == 0 {
                return e("output.poincare.max_points", "must be at least 1".into());
            }
            if p.vars.is_empty() {
                return e("output.poincare.vars", "names no variable".into());
            }
            match &p.section {
                Section::Stroboscopic { period, phase } => {
                    if !(period.is_finite() && *period > 0.0) {
                        return e(
                            "output.poincare.period",
                            format!("{period} is not a finite number > 0"),
                        );
                    }
                    if !(phase.is_finite() && *phase >= 0.0) {
                        return e(
                            "output.poincare.phase",
                            format!("{phase} is not a finite number ≥ 0"),
                        );
                    }
                }
                Section::Forced { skip } => {
                    if !(skip.is_finite() && *skip >= 0.0) {
                        return e(
                            "output.poincare.skip",
                            format!("{skip} is not a number of periods ≥ 0"),
                        );
                    }
                }
                Section::Crossing { value, .. } => {
                    if !value.is_finite() {
                        return e("output.poincare.value", "is not a finite number".into());
                    }
                }
            }
        }
        if let Some(c) = &self.cycle {
            if !(0.0..1.0).contains(&c.skip) {
                return e("output.cycle.skip", format!("{} is not in [0, 1)", c.skip));
            }
            if !c.level.is_finite() {
                return e("output.cycle.level", "is not a finite number".into());
            }
        }
        Ok(())
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
