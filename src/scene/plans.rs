//! A scene's plans: one, or one per value of the axes that change the step
//! count (`dt` or `t0` with `t_end`), each a [`Plan`] of the scene's
//! problem with those axes held fixed.

use crate::models::formula::{FormulaModel, Function};
use crate::models::lanes::Lane;
use crate::num::order::ascending;
use crate::num::precision::Precision;
use crate::plan::observers::Section;
use crate::plan::precision::{self as fits, apart, short, Limits};
use crate::plan::{Plan, PlanError, PlanWarning, Problem, Source};
use crate::reference::truth::lane_of;

use super::{Horizon, Input, Scene, SceneError, SceneWarning, SubRun};

impl Scene {
    pub(crate) fn t0_input(&self) -> Input {
        self.initial.get("t0").cloned().unwrap_or(Input::Const(0.0))
    }

    /// The axes that change the step count (dt and t0 with t_end): each plan
    /// holds them at one value.
    fn step_axes(&self) -> Vec<usize> {
        let mut v = vec![];
        if let Horizon::TEnd(_) = self.horizon {
            for input in [&self.dt, &self.t0_input()] {
                if let Input::Axis(k) = input {
                    if !v.contains(k) {
                        v.push(*k);
                    }
                }
            }
        }
        v
    }

    /// The plans that make up the scene: one, or one per value combination of
    /// the axes that change the step count.
    pub fn sub_runs(&self) -> Result<Vec<SubRun>, SceneError> {
        let step_axes = self.step_axes();
        let combos: usize = step_axes
            .iter()
            .map(|k| self.axes[*k].values.len())
            .product();
        let mut out = vec![];
        for c in 0..combos {
            let mut fixed = vec![];
            let mut rem = c;
            for k in step_axes.iter().rev() {
                let len = self.axes[*k].values.len();
                fixed.push((*k, rem % len));
                rem /= len;
            }
            fixed.reverse();
            out.push(SubRun {
                plan: self.plan_for(&fixed)?,
                fixed,
            });
        }
        Ok(out)
    }

    /// The checks that depend on the working precision, which `reeb run
    /// --precision` may change after the scene is read: what `precision`
    /// cannot hold is refused (a value beyond its range, a `dt` that is 0 in
    /// it); what is merely surprising comes back as warnings (a value that
    /// underflows, axis values that become equal, a `dt` below the resolution
    /// of time at the run's time scale, a `t_end` that is not a multiple of
    /// `dt`, a section that starts after the run ends), in line order.
    pub fn checks(&self, precision: Precision) -> Result<Vec<SceneWarning>, SceneError> {
        self.checks_of(&self.sub_runs()?, precision)
    }

    /// [`Scene::checks`] of the scene's sub-runs `subs` (made once by a
    /// run, which goes on with them).
    pub fn checks_of(
        &self,
        subs: &[SubRun],
        precision: Precision,
    ) -> Result<Vec<SceneWarning>, SceneError> {
        let lim = Limits(precision);
        let mut found: Vec<PlanWarning> = vec![];
        if let Horizon::TEnd(t_end) = self.horizon {
            fits::check_values(lim, "integrator.t_end", None, &[t_end], &mut found)
                .map_err(|e| self.plan_error(e))?;
        }
        let mut per_plan: Vec<Vec<PlanWarning>> = vec![];
        for sub in subs {
            per_plan.push(fits::check(&sub.plan, precision).map_err(|e| self.plan_error(e))?);
        }
        self.formulas_defined(subs)?;
        found.extend(self.merged(per_plan));
        found.extend(self.equal_in(lim));
        found.extend(self.t_end_missed(subs)?);
        if let Some(r) = &self.observers.resonance {
            found.extend(r.overlaps().into_iter().map(|(k, j)| PlanWarning {
                field: "output.resonance.ratios".into(),
                message: format!(
                    "the windows of {} and {} (each ± tolerance {}) overlap: a mean in both is counted as {}, the earlier one",
                    r.label(k),
                    r.label(j),
                    r.tolerance,
                    r.label(k)
                ),
            }));
        }
        if let Some(m) = self.model.formula() {
            found.extend(m.unused.iter().map(|u| PlanWarning {
                field: format!("params.{u}"),
                message: "given, but no formula uses it".into(),
            }));
        }
        let mut out: Vec<SceneWarning> = found
            .into_iter()
            .map(|w| SceneWarning {
                path: self.path.clone(),
                line: self.line_of(&w.field),
                field: w.field,
                message: w.message,
            })
            .collect();
        out.sort_by_key(|w| w.line.unwrap_or(usize::MAX));
        Ok(out)
    }

    /// A plan's error at the scene's line (the final time of a `t_end`
    /// scene is its `t_end`).
    fn plan_error(&self, e: PlanError) -> SceneError {
        let field = match (e.field.as_str(), self.horizon) {
            ("integrator.steps", Horizon::TEnd(_)) => "integrator.t_end",
            (f, _) => f,
        };
        self.error(field, e.message)
    }

    /// The plans' warnings, each once: plans that differ only in their `dt`
    /// or `t0` warn alike (the same field, the same words, other numbers), so
    /// the first stands for the others.
    fn merged(&self, per_plan: Vec<Vec<PlanWarning>>) -> Vec<PlanWarning> {
        // The message without its numbers.
        let shape = |m: &str| {
            let mut out = String::new();
            for c in m.chars() {
                if "0123456789.e+-".contains(c) {
                    if !out.ends_with('#') {
                        out.push('#');
                    }
                } else {
                    out.push(c);
                }
            }
            out
        };
        let mut out: Vec<(PlanWarning, usize)> = vec![];
        for w in per_plan.into_iter().flatten() {
            let like =
                |o: &PlanWarning| o.field == w.field && shape(&o.message) == shape(&w.message);
            match out.iter_mut().find(|(o, _)| like(o)) {
                Some((o, n)) if *o != w => *n += 1,
                Some(_) => {}
                None => out.push((w, 0)),
            }
        }
        let names: Vec<&str> = self
            .step_axes()
            .iter()
            .map(|k| self.axes[*k].name.as_str())
            .collect();
        out.into_iter()
            .map(|(mut w, n)| {
                if n > 0 {
                    w.message += &format!(
                        " (and {n} more like it for other values of {})",
                        names.join(" and ")
                    );
                }
                w
            })
            .collect()
    }

    /// Axes whose distinct values are fewer in the precision than in the
    /// file: trajectories meant to differ that are the same.
    fn equal_in(&self, lim: Limits) -> Vec<PlanWarning> {
        let mut out = vec![];
        for a in &self.axes {
            let rounded = |x: &f64| lim.round(*x);
            // Values that become 0 have their own warning.
            let kept = |x: &f64| *x == 0.0 || rounded(x) != 0.0;
            let Distinct {
                values,
                rounded: r,
                pair,
            } = distinct(&a.values, kept, rounded);
            if r < values {
                let example = pair.map_or(String::new(), |w| {
                    format!(
                        " ({:?} and {:?} are both {})",
                        w[0],
                        w[1],
                        lim.show(rounded(&w[0]))
                    )
                });
                out.push(PlanWarning {
                    field: a.field.clone(),
                    message: format!(
                        "its {} distinct values are only {} in {}{example}: trajectories meant to differ are the same; {}",
                        values,
                        match r {
                            1 => "1 number".to_string(),
                            n => format!("{n} distinct numbers"),
                        },
                        lim.0,
                        if lim.0 == Precision::F32 {
                            "use f64 or spread the values"
                        } else {
                            "spread the values"
                        }
                    ),
                });
            }
        }
        out
    }

    /// Refuses a formula model whose functions (the formulas and the
    /// derivatives its pieces take) are not finite where some trajectory
    /// starts: its steps would be NaN, or silently outside the model's domain
    /// (`log(q - 1)` at q = 0.5 has a finite gradient).
    fn formulas_defined(&self, subs: &[SubRun]) -> Result<(), SceneError> {
        let Some(m) = self.model.formula() else {
            return Ok(());
        };
        for sub in subs {
            for f in m.functions() {
                if let Some(x) = first_nonfinite(m, f, &sub.plan) {
                    let lane = |v: &str| x.get(v).unwrap_or(f64::NAN);
                    let state = sub.plan.vars.iter().chain(&["t"]).map(|v| (*v, lane(v)));
                    let params = m
                        .source
                        .params
                        .iter()
                        .map(|p| (p.as_str(), m.param_lane(p).map_or(f64::NAN, lane)));
                    let at: Vec<String> = state
                        .chain(params)
                        .map(|(name, v)| format!("{name} = {v}"))
                        .collect();
                    return Err(self.error(
                        &f.field,
                        format!(
                            "{} is {} where a trajectory starts ({}): the formula is not defined there; change the formula or the initial values",
                            f.name,
                            m.value(f, &x),
                            at.join(", ")
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// `t_end` that a whole number of steps `dt` from `t0` does not reach:
    /// the run ends at `t0 + steps·dt`, the nearest (for the plan with the
    /// largest miss, when `dt` or `t0` runs along an axis).
    fn t_end_missed(&self, subs: &[SubRun]) -> Result<Vec<PlanWarning>, SceneError> {
        let Horizon::TEnd(t_end) = self.horizon else {
            return Ok(vec![]);
        };
        // dt and t0 are fixed in every sub-run of a t_end scene (an axis
        // of them splits the scene); NaN, which warns of nothing, otherwise.
        let constant = |name: &str, sub: &SubRun| match sub.plan.binding(name) {
            Source::Const(v) => *v,
            Source::Axis { .. } => f64::NAN,
        };
        // (t0, dt, steps, final time) of the plans that miss t_end.
        let mut missed: Vec<(f64, f64, u64, f64)> = vec![];
        let mut considered = 0;
        for sub in subs {
            let (t0, dt) = (constant("t0", sub), constant("dt", sub));
            let steps = self.steps_to(t_end, t0, dt)?;
            if self.step_cap.is_some_and(|cap| steps > cap) {
                continue; // a preview: it stops before t_end anyway
            }
            considered += 1;
            let r = (t_end - t0) / dt;
            if (r - steps as f64).abs() > 1e-6f64.max(r * 1e-14) {
                missed.push((t0, dt, steps, t0 + steps as f64 * dt));
            }
        }
        let Some(message) = self.t_end_message(t_end, &missed, considered) else {
            return Ok(vec![]);
        };
        Ok(vec![PlanWarning {
            field: "integrator.t_end".into(),
            message,
        }])
    }

    /// The warning for the plans `missed` (t0, dt, steps, final time) out
    /// of `considered`: the one that ends farthest from `t_end` is shown.
    fn t_end_message(
        &self,
        t_end: f64,
        missed: &[(f64, f64, u64, f64)],
        considered: usize,
    ) -> Option<String> {
        let &(t0, dt, steps, end) = missed
            .iter()
            .max_by(|a, b| (a.3 - t_end).abs().total_cmp(&(b.3 - t_end).abs()))?;
        let from_zero = missed.iter().all(|m| m.0 == 0.0);
        let span = if t0 == 0.0 {
            format!("t_end = {t_end:?}")
        } else {
            format!("t_end − t0 = {} (t0 = {t0:?})", short(t_end - t0, 10))
        };
        let ends = format!("{steps} steps end at t = {}", apart(end, t_end));
        Some(if considered == 1 {
            format!("{span} is not a multiple of dt = {}: {ends}", short(dt, 10))
        } else {
            let names: Vec<&str> = self
                .step_axes()
                .iter()
                .map(|k| self.axes[*k].name.as_str())
                .collect();
            let at = if t0 == 0.0 {
                format!("dt = {}", short(dt, 10))
            } else {
                format!("t0 = {t0:?}, dt = {}", short(dt, 10))
            };
            format!(
                "{} is not a multiple of dt for {} of the {} {}; the farthest: {at}: {ends}",
                if from_zero {
                    format!("t_end = {t_end:?}")
                } else {
                    format!("t_end − t0 (t_end = {t_end:?})")
                },
                missed.len(),
                considered,
                match names[..] {
                    [one] => format!("values of {one}"),
                    _ => format!("pairs of {}", names.join(" and ")),
                }
            )
        })
    }

    /// The plan with the axes in `fixed` held at one value.
    fn plan_for(&self, fixed: &[(usize, usize)]) -> Result<Plan, SceneError> {
        let mut problem = Problem::with_scheme(self.model.clone(), self.scheme.clone());
        problem.order = self.order.clone();
        // Free axes keep their order; fixed ones become constants.
        let mut axis_map = vec![None; self.axes.len()];
        for (k, a) in self.axes.iter().enumerate() {
            if !fixed.iter().any(|(f, _)| *f == k) {
                axis_map[k] = Some(problem.axes.len());
                problem.axes.push(crate::plan::Axis {
                    name: a.name.clone(),
                    len: a.values.len(),
                });
            }
        }
        let source = |input: &Input| self.source(input, &axis_map, fixed);
        for (k, v) in &self.params {
            problem.params.insert(k.clone(), source(v));
        }
        for (k, v) in &self.initial {
            problem.initial.insert(k.clone(), source(v));
        }
        problem.dt = source(&self.dt);
        problem.steps = match self.horizon {
            Horizon::Steps(s) => s,
            Horizon::TEnd(t_end) => match (source(&self.dt), source(&self.t0_input())) {
                (Source::Const(dt), Source::Const(t0)) => self.steps_to(t_end, t0, dt)?,
                _ => unreachable!("dt and t0 are fixed in every sub-run when t_end is given"),
            },
        };
        problem.observers = self.observers.clone();
        if let Some(cap) = self.step_cap.filter(|cap| problem.steps > *cap) {
            let fraction = cap as f64 / problem.steps as f64;
            problem.steps = cap;
            if let Some(p) = &mut problem.observers.poincare {
                p.section = preview_section(&p.section, fraction);
            }
        }
        Plan::new(&problem).map_err(|e| self.error(&e.field, e.message))
    }

    /// The source of an input in a sub-run: a constant, a value of a fixed
    /// axis, or the values of a free one (`axis_map`: scene axis → plan axis).
    fn source(
        &self,
        input: &Input,
        axis_map: &[Option<usize>],
        fixed: &[(usize, usize)],
    ) -> Source {
        match input {
            Input::Const(v) => Source::Const(*v),
            Input::Axis(k) => match axis_map[*k] {
                Some(a) => Source::Axis {
                    axis: a,
                    values: self.axes[*k].values.clone(),
                },
                None => {
                    let idx = fixed
                        .iter()
                        .find(|(f, _)| f == k)
                        .map(|(_, i)| *i)
                        .expect("fixed");
                    Source::Const(self.axes[*k].values[idx])
                }
            },
        }
    }

    /// Steps from t0 to t_end with step dt (a dt ≤ 0 is refused by the plan).
    fn steps_to(&self, t_end: f64, t0: f64, dt: f64) -> Result<u64, SceneError> {
        if dt <= 0.0 {
            return Ok(1);
        }
        if t_end <= t0 {
            return Err(self.error(
                "integrator.t_end",
                format!("{t_end} is not after t0 = {t0}"),
            ));
        }
        let steps = ((t_end - t0) / dt).round();
        if steps > 4e9 {
            return Err(self.error(
                "integrator.t_end",
                format!("{steps:e} steps of dt = {dt}: too many (at most 4·10⁹)"),
            ));
        }
        Ok((steps as u64).max(1))
    }
}

/// A stroboscopic section of a preview that keeps `fraction` of a plan's
/// steps: the whole periods skipped shrink alike (rounded down), so that
/// the section starts where it would in the whole run, relative to its
/// length, instead of after the preview's end. Other skips are fractions
/// of the run already.
fn preview_section(section: &Section, fraction: f64) -> Section {
    let fewer = |periods: f64| (periods * fraction).floor();
    match *section {
        Section::Forced { skip } => Section::Forced { skip: fewer(skip) },
        Section::Stroboscopic { period, phase } if phase >= period => {
            let whole = (phase / period).floor();
            Section::Stroboscopic {
                period,
                phase: phase - whole * period + fewer(whole) * period,
            }
        }
        ref other => other.clone(),
    }
}

/// The inputs of the first trajectory of `plan` at whose start the model's
/// function `f` is not finite (`t` at `t0`). Only the axes `f` reads are
/// walked: its value is the same along the others.
fn first_nonfinite(m: &FormulaModel, f: &Function, plan: &Plan) -> Option<Lane<f64>> {
    let reads = |name: &str| f.inputs.contains(&name) || (name == "t0" && f.inputs.contains(&"t"));
    let mut axes: Vec<usize> = plan
        .bindings
        .iter()
        .filter(|(name, _)| reads(name))
        .filter_map(|(_, src)| match src {
            Source::Axis { axis, .. } => Some(*axis),
            Source::Const(_) => None,
        })
        .collect();
    axes.sort_unstable();
    axes.dedup();
    let count: usize = axes.iter().map(|a| plan.axes[*a].len).product();
    use rayon::prelude::*;
    (0..count).into_par_iter().find_map_first(|mut k| {
        let mut traj = 0;
        for a in &axes {
            traj += (k % plan.axes[*a].len) * plan.strides[*a];
            k /= plan.axes[*a].len;
        }
        let mut x = lane_of(plan, traj);
        x.t = x.t0;
        (!m.value(f, &x).is_finite()).then_some(x)
    })
}

/// What [`distinct`] counts.
struct Distinct {
    /// Distinct values.
    values: usize,
    /// Distinct values once rounded.
    rounded: usize,
    /// The first two (in increasing order) that round to one number.
    pair: Option<[f64; 2]>,
}

/// The values of `axis` that `kept` keeps, counted as [`Distinct`] says,
/// in increasing order ([`ascending`]: an axis from `linspace` or
/// `logspace` is not sorted). Rounding keeps the order, so values that
/// round alike are neighbours.
fn distinct(axis: &[f64], kept: impl Fn(&f64) -> bool, rounded: impl Fn(&f64) -> f64) -> Distinct {
    let mut d = Distinct {
        values: 0,
        rounded: 0,
        pair: None,
    };
    let mut last: Option<f64> = None;
    for &v in ascending(axis).iter().filter(|v| kept(v)) {
        match last {
            Some(p) if p == v => continue,
            Some(p) if rounded(&p) == rounded(&v) => {
                d.pair.get_or_insert([p, v]);
            }
            _ => d.rounded += 1,
        }
        d.values += 1;
        last = Some(v);
    }
    d
}
