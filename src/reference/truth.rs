//! Reference solutions of a plan's trajectory: the closed form where the
//! model has one (damped oscillator, Lane–Emden k = 0, 1, 5, the harmonic
//! limit of van der Pol), otherwise the adaptive DOP853 of
//! [`crate::reference::dop853`] on the model's own vector field (the same shared
//! functions both backends use), at tight tolerance, with dense output at the
//! comparison times.

use std::time::Instant;

use anyhow::{anyhow, bail, Result};

use crate::models::exact;
use crate::models::lanes::Lane;
use crate::models::{lane_emden, scalar_fn, Model};
use crate::plan::Plan;
use crate::reference::dop853::{dop853, Dop853Options};

/// A reference trajectory.
#[derive(Debug, Clone)]
pub struct Truth {
    /// `values[k][j]`: variable `j` of the plan at `times[k]`.
    pub values: Vec<Vec<f64>>,
    /// How it was obtained, for reports.
    pub method: String,
    /// Right-hand-side evaluations (0 for a closed form).
    pub evaluations: u64,
    pub seconds: f64,
}

/// The lane inputs of trajectory `traj` (parameters, initial state, t0, dt).
pub fn lane_of(plan: &Plan, traj: usize) -> Lane<f64> {
    let mut x = Lane::<f64>::default();
    for (name, src) in &plan.bindings {
        if let Some(f) = x.get_mut(name) {
            *f = src.value_at(plan.first + traj, &plan.strides);
        }
    }
    x
}

/// The closed form of `plan`'s trajectory `traj` at `t`, if the model has one
/// for every integrated variable.
pub fn exact_at(plan: &Plan, traj: usize, t: f64) -> Option<Vec<f64>> {
    let x = lane_of(plan, traj);
    let rel = t - x.t0;
    let values: Option<Vec<f64>> = match &plan.model {
        Model::DampedOscillator => {
            let (q, p) = exact::damped_oscillator(
                x.alpha,
                x.forcing_amplitude,
                x.forcing_frequency,
                x.q,
                x.p,
                t,
            );
            if x.t0 != 0.0 {
                return None;
            }
            plan.vars
                .iter()
                .map(|v| match *v {
                    "q" => Some(q),
                    "p" => Some(p),
                    "s" if x.forcing_amplitude == 0.0 && x.alpha != 0.0 => {
                        Some(exact::damped_oscillator_action(x.alpha, x.q, x.p, x.s, t))
                    }
                    _ => None,
                })
                .collect()
        }
        Model::LaneEmden => {
            if x.t0 != 0.0 || x.q != 1.0 || x.p != 0.0 {
                return None;
            }
            let (q, p) = lane_emden::exact(x.index as u32, t)?;
            plan.vars
                .iter()
                .map(|v| match *v {
                    "q" => Some(q),
                    "p" => Some(p),
                    _ => None,
                })
                .collect()
        }
        Model::VanDerPol if x.epsilon == 0.0 && x.forcing_amplitude == 0.0 => {
            let (q, s) = exact::harmonic(x.q, x.s, rel);
            plan.vars
                .iter()
                .map(|v| match *v {
                    "q" => Some(q),
                    "s" => Some(s),
                    _ => None,
                })
                .collect()
        }
        _ => None,
    };
    values
}

/// DOP853 on the plan's vector field for trajectory `traj`, at `times`.
pub fn dop853_of(plan: &Plan, traj: usize, times: &[f64], rtol: f64) -> Result<Truth> {
    let base = lane_of(plan, traj);
    let formula = plan.model.formula();
    let field: Vec<_> = match formula {
        Some(_) => vec![],
        None => plan
            .field_ops
            .iter()
            .map(|f| scalar_fn::<f64>(f).ok_or_else(|| anyhow!("no field op {f}")))
            .collect::<Result<_>>()?,
    };
    let vars = plan.vars.clone();
    let dvars: Vec<String> = vars.iter().map(|v| format!("d{v}")).collect();
    let y0: Vec<f64> = vars.iter().map(|v| base.get(v).unwrap_or(0.0)).collect();
    let f = |t: f64, y: &[f64], dy: &mut [f64]| {
        let mut x = base;
        for (v, val) in vars.iter().zip(y) {
            if let Some(slot) = x.get_mut(v) {
                *slot = *val;
            }
        }
        x.t = t;
        for op in &field {
            op(&mut x);
        }
        // A formula model's field: its DAG evaluated in f64.
        if let Some(m) = formula {
            for name in &plan.field_ops {
                m.apply_f64(name, &mut x);
            }
        }
        for (d, out) in dvars.iter().zip(dy.iter_mut()) {
            *out = x.get(d).unwrap_or(0.0);
        }
    };
    let opts = Dop853Options {
        rtol,
        atol: rtol * 1e-2,
        ..Dop853Options::default()
    };
    let started = Instant::now();
    let (values, stats) = dop853(f, base.t0, &y0, times, &opts)
        .map_err(|e| anyhow!("reference DOP853 for trajectory {traj}: {e}"))?;
    Ok(Truth {
        values,
        method: format!("DOP853, rtol {rtol:e}"),
        evaluations: stats.evaluations,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// The reference of trajectory `traj` at `times` (ascending, from t0):
/// closed form if the model has one, else DOP853 at `rtol`.
pub fn truth(plan: &Plan, traj: usize, times: &[f64], rtol: f64) -> Result<Truth> {
    let started = Instant::now();
    let exact: Option<Vec<Vec<f64>>> = times.iter().map(|t| exact_at(plan, traj, *t)).collect();
    match exact {
        Some(values) => Ok(Truth {
            values,
            method: "closed form".into(),
            evaluations: 0,
            seconds: started.elapsed().as_secs_f64(),
        }),
        None => {
            if plan.field_ops.is_empty() {
                bail!(
                    "model `{}` has no vector field for a reference",
                    plan.model.name()
                );
            }
            dop853_of(plan, traj, times, rtol)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::{Problem, Source};

    /// DOP853 on the single-source vector field agrees with the closed forms.
    #[test]
    fn dop853_on_model_fields_matches_closed_forms() {
        let times: Vec<f64> = (0..=20).map(|k| 0.5 * k as f64).collect();
        let mut p = Problem::new(Model::DampedOscillator, "s2")
            .unwrap()
            .param("alpha", Source::Const(0.3))
            .param("forcing_amplitude", Source::Const(0.5))
            .param("forcing_frequency", Source::Const(1.3))
            .initial("q", Source::Const(1.0))
            .initial("p", Source::Const(1.0));
        p.steps = 10;
        let plan = Plan::new(&p).unwrap();
        let e = truth(&plan, 0, &times, 1e-12).unwrap();
        assert_eq!(e.method, "closed form");
        let d = dop853_of(&plan, 0, &times, 1e-12).unwrap();
        for (a, b) in e.values.iter().zip(&d.values) {
            for (x, y) in a.iter().zip(b) {
                assert!((x - y).abs() < 1e-10, "{x} {y}");
            }
        }
        // Lane–Emden k = 5 from t = 0, through the regularised field.
        let mut p = Problem::new(Model::LaneEmden, "s2")
            .unwrap()
            .param("index", Source::Const(5.0));
        p.steps = 10;
        let plan = Plan::new(&p).unwrap();
        let d = dop853_of(&plan, 0, &times, 1e-12).unwrap();
        for (t, v) in times.iter().zip(&d.values) {
            assert!(
                (v[0] - lane_emden::exact(5, *t).unwrap().0).abs() < 1e-10,
                "t = {t}"
            );
        }
    }
}
