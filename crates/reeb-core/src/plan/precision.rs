//! What the working precision can hold. [`Plan::new`] checks a problem in
//! f64; the precision a run works in may still change after that (`reeb run
//! --precision`), so what depends on it is checked here, for a plan and a
//! precision: a value beyond the precision's range, and a step that is 0 (or
//! subnormal) in it, are refused; a value that underflows, a step below the
//! resolution of time at the run's time scale, and a section that starts
//! after the run ends are merely surprising: warnings.

use crate::models::Model;
use crate::num::precision::Precision;

use super::observed::ObsVar;
use super::observers::Section;
use super::problem::{err, warn, PlanError, PlanWarning};
use super::Plan;

/// The numbers of a working precision, as f64.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits(pub Precision);

impl Limits {
    /// `x` rounded to the precision (beyond its range: ±∞).
    pub fn round(self, x: f64) -> f64 {
        match self.0 {
            Precision::F32 => x as f32 as f64,
            Precision::F64 => x,
        }
    }
    /// The largest finite magnitude.
    pub fn max(self) -> f64 {
        match self.0 {
            Precision::F32 => f32::MAX as f64,
            Precision::F64 => f64::MAX,
        }
    }
    /// The smallest normal magnitude (below it, numbers lose digits and GPUs
    /// flush them to 0).
    pub fn min_normal(self) -> f64 {
        match self.0 {
            Precision::F32 => f32::MIN_POSITIVE as f64,
            Precision::F64 => f64::MIN_POSITIVE,
        }
    }
    /// The smallest nonzero magnitude (a subnormal).
    pub fn min_subnormal(self) -> f64 {
        match self.0 {
            Precision::F32 => f32::from_bits(1) as f64,
            Precision::F64 => f64::from_bits(1),
        }
    }
    /// Machine epsilon: the spacing of the numbers in [1, 2).
    pub fn epsilon(self) -> f64 {
        match self.0 {
            Precision::F32 => f32::EPSILON as f64,
            Precision::F64 => f64::EPSILON,
        }
    }
    /// The gap between |x| (rounded to the precision) and the next larger
    /// number of the precision.
    pub fn spacing(self, x: f64) -> f64 {
        match self.0 {
            Precision::F32 => {
                let y = x.abs() as f32;
                if !y.is_finite() {
                    return f64::INFINITY;
                }
                f32::from_bits(y.to_bits() + 1) as f64 - y as f64
            }
            Precision::F64 => {
                let y = x.abs();
                if !y.is_finite() {
                    return f64::INFINITY;
                }
                f64::from_bits(y.to_bits() + 1) - y
            }
        }
    }
    /// `x` as the precision prints it (3.4028235e38 in f32).
    pub fn show(self, x: f64) -> String {
        match self.0 {
            Precision::F32 => format!("{:?}", x as f32),
            Precision::F64 => format!("{x:?}"),
        }
    }
    /// What to do about a value the precision cannot hold.
    fn remedy(self, otherwise: &str) -> String {
        match self.0 {
            Precision::F32 => format!(
                "use f64 (run.precision = \"f64\" or --precision f64){}",
                if otherwise.is_empty() {
                    String::new()
                } else {
                    format!(" or {otherwise}")
                }
            ),
            Precision::F64 if otherwise.is_empty() => "use a smaller value".into(),
            Precision::F64 => format!("use {otherwise}"),
        }
    }
}

/// `x` with at most `digits` significant digits, as short as Rust prints it.
pub fn short(x: f64, digits: usize) -> String {
    let r: f64 = format!("{x:.*e}", digits.saturating_sub(1))
        .parse()
        .unwrap_or(x);
    format!("{r:?}")
}

/// `x` with the fewest significant digits (at least 6) that tell it from
/// `other`: 9.9 from 10, 200.00005 from 200.
pub fn apart(x: f64, other: f64) -> String {
    (6..=17)
        .map(|d| (short(x, d), short(other, d)))
        .find(|(a, b)| a != b)
        .map_or_else(|| format!("{x:?}"), |(a, _)| a)
}

/// "keeps about 4 significant digits" of a subnormal `v`.
fn digits_kept(lim: Limits, v: f64) -> String {
    let d = (lim.round(v).abs() / lim.min_subnormal()).log10().floor();
    match d as i64 {
        i64::MIN..=0 => "keeps less than one significant digit".into(),
        1 => "keeps about 1 significant digit".into(),
        d => format!("keeps about {d} significant digits"),
    }
}

/// Refusals and warnings of `plan` in `precision`; see the module
/// documentation. Errors and warnings name the scene's field.
pub fn check(plan: &Plan, precision: Precision) -> Result<Vec<PlanWarning>, PlanError> {
    let lim = Limits(precision);
    let mut out = vec![];
    for (name, source) in &plan.bindings {
        let values = source.as_slice();
        if *name == "dt" {
            check_step(lim, values)?;
        }
        let (field, derived) = binding_field(plan, name);
        check_values(lim, &field, derived.as_deref(), values, &mut out)?;
    }
    let section = plan.observers.poincare.as_ref().map(|p| &p.section);
    if let Some(Section::Crossing { value, .. }) = section {
        check_values(lim, "output.poincare.value", None, &[*value], &mut out)?;
    }
    if let Some(c) = &plan.observers.cycle {
        check_values(lim, "output.cycle.level", None, &[c.level], &mut out)?;
    }
    if let Some(why) = time_use(plan) {
        check_time(lim, plan, why, &mut out)?;
    }
    check_section_start(plan, &mut out);
    Ok(out)
}

/// The scene field a lane input comes from, and the name of the value when
/// it is derived from that field (spin–orbit weights, the forcing period).
fn binding_field(plan: &Plan, name: &str) -> (String, Option<String>) {
    let spec = plan.model.spec();
    let forced = matches!(
        plan.observers.poincare.as_ref().map(|p| &p.section),
        Some(Section::Forced { .. })
    );
    match name {
        "dt" => ("integrator.dt".into(), None),
        "t0" => ("initial.t0".into(), None),
        "strobe_period" if forced => (
            "output.poincare.period".into(),
            Some("the forcing period 2π/ω".into()),
        ),
        "strobe_period" => ("output.poincare.period".into(), None),
        "strobe_phase" if forced => (
            "output.poincare.skip".into(),
            Some("the section's start skip·2π/ω".into()),
        ),
        "strobe_phase" => (
            "output.poincare".into(),
            Some("the section's start phase + skip·period".into()),
        ),
        v if spec.vars.contains(&v) => (format!("initial.{v}"), None),
        p if spec.param(p).is_some() => (format!("params.{p}"), None),
        d => match spec
            .derived
            .iter()
            .find(|x| x.name == d)
            .and_then(|x| x.from)
        {
            Some((base, _)) => (format!("params.{base}"), Some(d.to_string())),
            None if matches!(plan.model, Model::Lienard { .. }) => (
                format!("params.{}", &d[..1]),
                Some(format!("the coefficient {d}")),
            ),
            None => (format!("params.{d}"), None),
        },
    }
}

/// A step that the precision holds: not 0 in it, not subnormal.
fn check_step(lim: Limits, dts: &[f64]) -> Result<(), PlanError> {
    let p = lim.0;
    for (k, dt) in dts.iter().enumerate() {
        let at = along(k, dts.len());
        let r = lim.round(*dt);
        if r == 0.0 {
            return Err(err(
                "integrator.dt",
                format!(
                    "dt = {dt:?}{at} is 0 in {p} (smallest step {p} can hold: {}); {}",
                    lim.show(lim.min_normal()),
                    lim.remedy("a larger dt")
                ),
            ));
        }
        if r < lim.min_normal() {
            return Err(err(
                "integrator.dt",
                format!(
                    "dt = {dt:?}{at} is below the smallest normal {p} number, {}: it {}, and GPUs flush it to 0; {}",
                    lim.show(lim.min_normal()),
                    digits_kept(lim, *dt),
                    lim.remedy("a larger dt")
                ),
            ));
        }
    }
    Ok(())
}

/// " (value 3 of 5 along its axis)" for axis values, nothing for a constant.
fn along(k: usize, n: usize) -> String {
    if n > 1 {
        format!(" (value {} of {n} along its axis)", k + 1)
    } else {
        String::new()
    }
}

/// The values of `field` (or the value `derived` from it) in the precision:
/// beyond its range is refused; rounding to 0 or to a subnormal is a warning.
pub fn check_values(
    lim: Limits,
    field: &str,
    derived: Option<&str>,
    values: &[f64],
    out: &mut Vec<PlanWarning>,
) -> Result<(), PlanError> {
    let p = lim.0;
    let n = values.len();
    let what = |k: usize| match derived {
        Some(d) => format!("gives {d} = {:?}{}, which", values[k], along(k, n)),
        None => format!("{:?}{}", values[k], along(k, n)),
    };
    let more = |c: usize| match c {
        0 | 1 => String::new(),
        2 => "; so is 1 more of its values".to_string(),
        c => format!("; so are {} more of its values", c - 1),
    };
    if let Some(k) = values.iter().position(|v| lim.round(*v).is_infinite()) {
        return Err(err(
            field,
            format!(
                "{} is beyond the range of {p} (largest magnitude {}); {}",
                what(k),
                lim.show(lim.max()),
                lim.remedy("")
            ),
        ));
    }
    let zero: Vec<usize> = (0..n)
        .filter(|k| values[*k] != 0.0 && lim.round(values[*k]) == 0.0)
        .collect();
    if let Some(k) = zero.first() {
        out.push(warn(
            field,
            format!(
                "{} is 0 in {p} (the smallest nonzero {p} is {}){}",
                what(*k),
                lim.show(lim.min_subnormal()),
                more(zero.len())
            ),
        ));
    }
    let sub: Vec<usize> = (0..n)
        .filter(|k| {
            let r = lim.round(values[*k]).abs();
            r != 0.0 && r < lim.min_normal()
        })
        .collect();
    if let Some(k) = sub.first() {
        out.push(warn(
            field,
            format!(
                "{} is below the smallest normal {p} number, {}: it {}, and GPUs may flush it to 0{}",
                what(*k),
                lim.show(lim.min_normal()),
                digits_kept(lim, values[*k]),
                more(sub.len())
            ),
        ));
    }
    Ok(())
}

/// What reads the time of the run, if anything does: the step (forcing),
/// an observer that records `t`, the cycle statistics, a stroboscopic section.
fn time_use(plan: &Plan) -> Option<&'static str> {
    let records_t = [&plan.final_vars, &plan.trajectory_vars, &plan.poincare_vars]
        .iter()
        .any(|vs| vs.contains(&ObsVar::Time));
    if plan.time {
        Some("which the model reads")
    } else if records_t {
        Some("which the output records")
    } else if plan.cycle_var.is_some() {
        Some("which times the cycle statistics")
    } else if plan.observers.stroboscopic() {
        Some("which places the section's samples")
    } else {
        None
    }
}

/// The time t0 + n·dt, when something reads it: its end within the
/// precision's range (refused otherwise) and dt above its resolution there
/// (a warning otherwise, for the worst trajectory).
fn check_time(
    lim: Limits,
    plan: &Plan,
    why: &str,
    out: &mut Vec<PlanWarning>,
) -> Result<(), PlanError> {
    let p = lim.0;
    let dts = plan.binding("dt").values();
    // The time scale max(|t0|, |t0 + steps·dt|) is largest at an extreme t0.
    let t0s = plan.binding("t0").values();
    let t0s = [
        t0s.iter().copied().fold(f64::INFINITY, f64::min),
        t0s.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    ];
    let steps = plan.steps as f64;
    // (dt / spacing, dt, time scale) of the worst trajectory.
    let mut worst: Option<(f64, f64, f64)> = None;
    for dt in &dts {
        for t0 in &t0s {
            let end = t0 + steps * dt;
            if lim.round(end).is_infinite() {
                return Err(err(
                    "integrator.steps",
                    format!(
                        "{} steps of dt = {dt:?} from t0 = {t0:?} end at t = {end:?}, beyond the range of {p} (largest magnitude {}): the time t0 + n·dt, {why}, overflows; {}",
                        plan.steps,
                        lim.show(lim.max()),
                        lim.remedy("fewer steps")
                    ),
                ));
            }
            let t = t0.abs().max(end.abs());
            let ratio = dt / lim.spacing(t);
            if *dt < lim.epsilon() * t && worst.is_none_or(|w| ratio < w.0) {
                worst = Some((ratio, *dt, t));
            }
        }
    }
    if let Some((ratio, dt, t)) = worst {
        let gap = lim.show(lim.spacing(t));
        let t = short(t, 6);
        let fix = lim.remedy("a larger dt");
        out.push(warn(
            "integrator.dt",
            if ratio < 0.5 {
                format!(
                    "dt = {dt:?} is less than half the spacing of {p} numbers at t = {t} ({gap}): t + dt rounds back to t, so the time t0 + n·dt, {why}, moves in jumps of {gap} instead of by dt; {fix}"
                )
            } else {
                format!(
                    "dt = {dt:?} keeps less than one significant digit at t = {t} in {p} (numbers there are {gap} apart): the time t0 + n·dt, {why}, is rounded to that spacing; {fix}"
                )
            },
        ));
    }
    Ok(())
}

/// A stroboscopic section whose first sample comes after the run's end, for
/// every trajectory: it records no point.
fn check_section_start(plan: &Plan, out: &mut Vec<PlanWarning>) {
    let field = match plan.observers.poincare.as_ref().map(|p| &p.section) {
        Some(Section::Stroboscopic { .. }) => "output.poincare",
        Some(Section::Forced { .. }) => "output.poincare.skip",
        _ => return,
    };
    let first = plan
        .binding("strobe_phase")
        .values()
        .into_iter()
        .fold(f64::INFINITY, f64::min);
    let longest = plan.binding("dt").values().into_iter().fold(0.0, f64::max) * plan.steps as f64;
    if first > longest {
        out.push(warn(
            field,
            format!(
                "the section's first sample comes {} after t0, after the run ends ({} steps: {} after t0): no point will be recorded; lower skip or phase, or run longer",
                short(first, 6),
                plan.steps,
                short(longest, 6)
            ),
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_of_f32_and_f64() {
        let f = Limits(Precision::F32);
        assert!(f.round(1e39).is_infinite());
        assert_eq!(f.round(1e-50), 0.0);
        assert_eq!(f.spacing(1.0), f32::EPSILON as f64);
        assert_eq!(f.spacing(200.0), 2f64.powi(-16));
        assert_eq!(f.show(f.max()), "3.4028235e38");
        assert_eq!(f.show(f.min_normal()), "1.1754944e-38");
        let d = Limits(Precision::F64);
        assert_eq!(d.round(1e39), 1e39);
        assert_eq!(d.spacing(1.0), f64::EPSILON);
    }

    #[test]
    fn numbers_shown_apart() {
        assert_eq!(apart(33.0 * 0.3, 10.0), "9.9");
        assert_eq!(apart(200.00005, 200.0), "200.00005");
        assert_eq!(short(0.1 + 0.2, 10), "0.3");
    }
}
