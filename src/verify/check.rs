//! A row of `reeb verify`'s report, and what it checks: a backend at a
//! precision.

use crate::backend::Engine;
use crate::num::precision::Precision;
use crate::plan::observations::Observations;
use crate::plan::Plan;

/// What `reeb verify` checks: a backend at a precision.
pub struct Target {
    pub engine: Engine,
    pub precision: Precision,
}

impl Target {
    /// Integrates `plan`, observations widened to f64.
    pub(crate) fn run(&self, plan: &Plan) -> Result<Observations<f64>, String> {
        self.engine
            .run_f64(plan, self.precision)
            .map(|(o, _)| o)
            .map_err(|e| e.to_string())
    }
    pub(crate) fn precision(&self) -> Precision {
        self.precision
    }
    /// e.g. "cpu (2 threads)" or "gpu: llvmpipe …".
    pub fn describe(&self) -> String {
        self.engine.describe()
    }
}

/// One row of the report.
#[derive(Debug, Clone)]
pub struct Check {
    pub group: &'static str,
    pub name: String,
    pub expected: String,
    pub measured: String,
    pub tolerance: String,
    pub pass: bool,
}

pub(crate) fn check(
    group: &'static str,
    name: impl Into<String>,
    expected: f64,
    measured: f64,
    tol: f64,
) -> Check {
    Check {
        group,
        name: name.into(),
        expected: fmt(expected),
        measured: fmt(measured),
        tolerance: format!("±{}", fmt(tol)),
        pass: (measured - expected).abs() <= tol,
    }
}

pub(crate) fn bound(
    group: &'static str,
    name: impl Into<String>,
    what: &str,
    measured: f64,
    max: f64,
) -> Check {
    Check {
        group,
        name: name.into(),
        expected: what.into(),
        measured: fmt(measured),
        tolerance: format!("≤ {}", fmt(max)),
        pass: measured <= max,
    }
}

pub(crate) fn failed(group: &'static str, name: impl Into<String>, why: String) -> Check {
    Check {
        group,
        name: name.into(),
        expected: "-".into(),
        measured: why,
        tolerance: "-".into(),
        pass: false,
    }
}

pub(crate) fn fmt(x: f64) -> String {
    if x == 0.0 || (1e-3..1e5).contains(&x.abs()) {
        format!("{x:.8}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        format!("{x:.4e}")
    }
}

/// The largest difference of two runs' final values, relative to
/// max(1, |a|); infinite where one is finite and the other not, unless
/// `finite_only` (f32 and f64 may stop an escaping orbit at different steps).
pub(crate) fn largest_difference(
    a: &Observations<f64>,
    b: &Observations<f64>,
    finite_only: bool,
) -> f64 {
    let mut worst = 0.0f64;
    for ((_, a), (_, b)) in a.final_values.iter().zip(&b.final_values) {
        for (x, y) in a.iter().zip(b) {
            if x.is_finite() && y.is_finite() {
                worst = worst.max((x - y).abs() / x.abs().max(1.0));
            } else if x.is_finite() != y.is_finite() && !finite_only {
                worst = f64::INFINITY;
            }
        }
    }
    worst
}
