//! A scene's plans: one, or one per value of the axes that change the step
//! count (`dt` or `t0` with `t_end`), each a [`Plan`] of the scene's
//! problem with those axes held fixed.

use crate::plan::observers::{Observers, PoincareObs, TrajectoryObs};
use crate::plan::{Plan, Problem, Source};

use super::{Horizon, Input, OutVar, Scene, SceneError, SubRun};

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
        if let Some(cap) = self.step_cap {
            problem.steps = problem.steps.min(cap);
        }
        problem.observers = self.observers();
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

    /// The scene's observers, vectors expanded into their components.
    fn observers(&self) -> Observers {
        let comps = |vars: &[OutVar]| -> Vec<String> {
            vars.iter().flat_map(|v| v.components.clone()).collect()
        };
        Observers {
            final_vars: comps(&self.final_vars),
            trajectory: self.trajectory.as_ref().map(|(every, vars)| TrajectoryObs {
                every: *every,
                vars: comps(vars),
            }),
            poincare: self
                .poincare
                .as_ref()
                .map(|(section, vars, max_points)| PoincareObs {
                    section: section.clone(),
                    vars: comps(vars),
                    max_points: *max_points,
                }),
            cycle: self.cycle.clone(),
        }
    }
}
