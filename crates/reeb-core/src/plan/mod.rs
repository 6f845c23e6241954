//! The plan: a problem compiled into the cheapest program that answers it,
//! which both backends execute.
//!
//! A [`Problem`] says what to integrate (model, parameters, initial conditions,
//! step, horizon, scheme, observers); every per-trajectory input is a
//! [`Source`]: a constant or the values along one axis of the ensemble, which
//! is the cartesian product of the axes (first axis slowest). A [`Plan`] knows
//! which variables must be integrated (no `p` for a van der Pol scene that asks
//! for `(q, s)`, no `t` for an autonomous one), which ops make one step, and
//! where every lane input comes from. The ensemble is never materialised.

pub mod alignment;
pub mod indicators;
pub mod observations;
pub mod observed;
pub mod observers;
pub mod precision;
pub mod problem;
pub mod recurrence;
pub mod scheme;
pub mod section;
pub mod size;
pub mod slots;
pub mod snapshot;
pub mod step;
pub mod stop;
pub mod tangent;
pub mod vectors;

use crate::models::spec::{ModelSpec, TimeDependence};
use crate::models::{lanes, Model};
pub use observed::ObsVar;
use observed::Observed;
use observers::{Observers, Section};
use problem::{check_coefficients, check_sources, err, resolve_initial};
pub use problem::{row_major_strides, Axis, PlanError, PlanWarning, Problem, Source};
use scheme::{Scheme, SchemeKind};
pub use step::{Op, Stages};

/// The compiled problem; see the module documentation.
#[derive(Debug, Clone)]
pub struct Plan {
    pub model: Model,
    pub scheme: Scheme,
    pub axes: Vec<Axis>,
    /// Row-major strides of the axes (first axis slowest).
    pub strides: Vec<usize>,
    /// The plan integrates the trajectories `first..first + n` of its grid
    /// (a chunk of a streamed run, or a shard); 0 and the whole grid unless
    /// [`Plan::rows`] narrowed it.
    pub first: usize,
    pub n: usize,
    /// Integrated state variables (lane field names), canonical order.
    pub vars: Vec<&'static str>,
    /// Does the step read time?
    pub time: bool,
    /// Lane inputs: field name ← source (parameters, derived parameters,
    /// initial state, `t0`, `dt`).
    pub bindings: Vec<(&'static str, Source)>,
    /// One step.
    pub ops: Vec<Op>,
    /// The same step as S2 stages for the CPU's fused kernels: the piece
    /// order and, per stage, its weight and time offset (splitting schemes).
    pub stages: Option<Stages>,
    /// Ops that put the vector field at (state, t) into `d<var>`.
    pub field_ops: Vec<&'static str>,
    pub steps: u64,
    pub observers: Observers,
    /// Observed variables resolved: final, trajectory, Poincaré.
    pub final_vars: Vec<ObsVar>,
    pub trajectory_vars: Vec<ObsVar>,
    pub poincare_vars: Vec<ObsVar>,
    /// The crossing variable of an event section, or of the cycle statistics.
    pub crossing_var: Option<usize>,
    pub cycle_var: Option<usize>,
    /// The averaged variables (state variables only).
    pub average_vars: Vec<ObsVar>,
    /// The components of the attractor detector's samples.
    pub attractor_vars: Vec<ObsVar>,
    /// The stop condition, its inputs resolved to lane fields.
    pub stop: Option<StopPlan>,
    /// The chaos indicators: tangent step, samples, slots.
    pub indicators: Option<indicators::Indicators>,
}

/// A stop condition's program of `lhs − rhs` over lane fields.
#[derive(Debug, Clone)]
pub struct StopPlan {
    pub program: crate::num::formula::lower::Lowered,
    pub cmp: stop::Cmp,
    /// The lane field of each input of the program (`t`: the time at the
    /// step's end), or an indicator's slot ([`indicator_slot`]).
    pub inputs: Vec<&'static str>,
}

/// Resolves the names `s` reads to lane fields: state variables the plan
/// integrates, `t`, and parameters bound to a lane (a built-in model's by
/// name, a formula model's by slot).
fn stop_plan(
    model: &Model,
    s: &stop::StopObs,
    vars: &[&'static str],
    bindings: &[(&'static str, Source)],
) -> Result<StopPlan, PlanError> {
    let field = "output.stop";
    let bound = |lane: &str| bindings.iter().find(|(b, _)| *b == lane).map(|(b, _)| *b);
    let mut inputs = vec![];
    for name in &s.names {
        let lane = if !s.reads.contains(name) || name == "t" {
            "t"
        } else if let Some(slot) = indicator_slot(name) {
            slot
        } else if s.state(name) {
            vars.iter()
                .copied()
                .find(|v| v == name)
                .ok_or_else(|| err(field, format!("`{name}` is not integrated by this plan")))?
        } else {
            let lane = match model.formula() {
                Some(m) => m.param_lane(name).and_then(bound),
                None => bound(name),
            };
            lane.ok_or_else(|| {
                err(
                    field,
                    format!(
                        "parameter `{name}` is not an input of model `{}`",
                        model.name()
                    ),
                )
            })?
        };
        inputs.push(lane);
    }
    Ok(StopPlan {
        program: s.program.clone(),
        cmp: s.cmp,
        inputs,
    })
}

/// The observer slot a stop condition reads for an indicator's name: the
/// FLI so far, MEGNO's running ⟨Y⟩, SALI and GALI at the last sample
/// (`plan/indicators.rs`).
pub fn indicator_slot(name: &str) -> Option<&'static str> {
    let mut scalars = indicators::SCALAR_INDICATORS.iter();
    scalars.find(|i| i.key == name).map(|i| i.slot)
}

/// Name of a lane field with a static lifetime.
fn lane_name(name: &str) -> Option<&'static str> {
    lanes::NAMES.iter().copied().find(|n| *n == name)
}

impl Plan {
    /// Compiles `problem`: every check of the problem, then the cheapest
    /// program that answers it.
    pub fn new(problem: &Problem) -> Result<Plan, PlanError> {
        let spec: &'static ModelSpec = problem.model.spec();
        check_sources(problem)?;
        let params = model_params(spec, problem)?;
        check_coefficients(&problem.model)?;
        let with_optional = integrates_optional(spec, problem)?;
        let vars: Vec<&'static str> = spec
            .vars
            .iter()
            .copied()
            .filter(|v| with_optional || Some(*v) != spec.optional_var)
            .collect();
        let time = reads_time(spec, &params);
        let initial = resolve_initial(spec, &problem.initial)?;
        let t0 = initial.get("t0").cloned().unwrap_or(Source::Const(0.0));
        check_rules(spec, &params, &initial, &t0, time)?;
        check_steps(problem)?;
        let mut bindings = params;
        bindings.extend(derived_params(problem, &bindings));
        bindings.extend(initial_state(spec, &vars, &initial));
        bindings.push(("t0", t0));
        bindings.push(("dt", problem.dt.clone()));
        bindings.extend(section_inputs(problem, &bindings)?);
        check_section_period(&bindings)?;
        for (name, _) in &bindings {
            debug_assert!(
                lane_name(name).is_some(),
                "binding {name} is not a lane field"
            );
        }
        let is_zero = |name: &str| {
            !bindings
                .iter()
                .find(|(b, _)| *b == name)
                .is_some_and(|(_, s)| s.any_nonzero())
        };
        let (ops, stages) = step::step_ops(
            spec,
            &problem.scheme.kind,
            problem.order.as_deref(),
            time,
            with_optional,
            &is_zero,
        )?;
        let field_ops = spec
            .field_ops
            .iter()
            .filter(|(_, opt)| with_optional || !opt)
            .map(|(o, _)| *o)
            .collect();
        let obs = &problem.observers;
        obs.validate(problem.steps).map_err(|(f, m)| err(f, m))?;
        let observed = Observed::resolve(obs, &vars)?;
        let stop = match &obs.stop {
            Some(s) => Some(stop_plan(&problem.model, s, &vars, &bindings)?),
            None => None,
        };
        let lens: Vec<usize> = problem.axes.iter().map(|a| a.len).collect();
        let mut plan = Plan {
            model: problem.model.clone(),
            scheme: problem.scheme.clone(),
            axes: problem.axes.clone(),
            strides: row_major_strides(&lens),
            first: 0,
            n: problem.ensemble_size(),
            vars,
            time,
            bindings,
            ops,
            stages,
            field_ops,
            steps: problem.steps,
            observers: problem.observers.clone(),
            final_vars: observed.final_vars,
            trajectory_vars: observed.trajectory_vars,
            poincare_vars: observed.poincare_vars,
            crossing_var: observed.crossing_var,
            cycle_var: observed.cycle_var,
            average_vars: observed.average_vars,
            attractor_vars: observed.attractor_vars,
            stop,
            indicators: None,
        };
        plan.indicators =
            indicators::Indicators::new(&plan.step_spec(), plan.steps, &plan.observers)?;
        Ok(plan)
    }

    /// What the tangent map of the step is made of.
    pub fn step_spec(&self) -> tangent::StepSpec<'_> {
        tangent::StepSpec {
            model: &self.model,
            scheme: &self.scheme.name,
            vars: &self.vars,
            bindings: &self.bindings,
            ops: &self.ops,
        }
    }

    /// The step after which time averages start: the first `skip` fraction
    /// of the run is left out, and the states at the ends of the steps
    /// `average_start + 1 …` are averaged.
    pub fn average_start(&self) -> u64 {
        self.observers
            .average
            .as_ref()
            .map_or(u64::MAX, |a| (a.skip * self.steps as f64).floor() as u64)
    }

    /// The first step after which cycle statistics measure (the steps that
    /// end at it and later, the first `skip` fraction of the run left out).
    pub fn cycle_start(&self) -> u64 {
        self.observers
            .cycle
            .as_ref()
            .map_or(u64::MAX, |cy| (cy.skip * self.steps as f64).floor() as u64)
    }

    /// Does an observer keep state across steps (`plan/slots.rs`)?
    pub fn has_slots(&self) -> bool {
        self.observers.poincare.is_some()
            || self.cycle_var.is_some()
            || !self.average_vars.is_empty()
            || self.indicators.is_some()
            || self.observers.attractors.is_some()
    }

    /// Does an observer look at the state after every step?
    pub fn observes_every_step(&self) -> bool {
        self.others_observe_every_step() || self.indicators.is_some()
    }

    /// Does an observer other than the chaos indicators look at every step?
    pub fn others_observe_every_step(&self) -> bool {
        self.more_than_stop_observes_every_step() || self.stop.is_some()
    }

    /// Does an observer other than the chaos indicators and the stop
    /// condition look at every step?
    pub fn more_than_stop_observes_every_step(&self) -> bool {
        self.needs_field() || self.cycle_var.is_some() || !self.average_vars.is_empty()
    }

    /// Does any observer need the vector field at the step ends (for
    /// interpolation inside a step)?
    pub fn needs_field(&self) -> bool {
        self.crossing_var.is_some() || self.cycle_var.is_some() || self.strobe_interpolated()
    }

    /// Whether the ensemble shares the step's time terms: `t0`, `dt` and
    /// every input of the model's time ops one value for the whole plan (for
    /// a plan without time, `dt` alone). Then the CPU's fused stages
    /// evaluate them once per block and stage, not per trajectory (the
    /// peers' trick: sin, cos and exp of t once per step), and take `dt`,
    /// hence every τ, as a loop invariant; the GPU reads them from a table
    /// per window. Formula models share theirs in their staged programs
    /// instead (`num/formula/stage.rs`), on both backends.
    pub fn shares_time(&self) -> bool {
        if self.model.formula().is_some() {
            return false;
        }
        let mut reads = vec!["dt"];
        if self.time {
            reads.push("t0");
        }
        for op in self.model.spec().time_ops {
            match crate::models::op_args(op) {
                Some(args) => reads.extend(
                    args.iter()
                        .filter(|(n, w)| !w && *n != "t")
                        .map(|(n, _)| *n),
                ),
                None => return false,
            }
        }
        let one_value = |name: &str| match self.bindings.iter().find(|(n, _)| *n == name) {
            Some((_, src)) => src.values().windows(2).all(|w| w[0] == w[1]),
            None => true,
        };
        reads.into_iter().all(one_value)
    }

    /// Does some trajectory's stroboscopic sample fall inside a step (period
    /// or phase not a whole number of steps), so that it is interpolated?
    pub fn strobe_interpolated(&self) -> bool {
        if !self.observers.stroboscopic() {
            return false;
        }
        let dts = self.binding("dt").values();
        // Period and phase run along the same axis (or are both constant).
        let pairs: Vec<(f64, f64)> = self
            .binding("strobe_period")
            .values()
            .into_iter()
            .zip(self.binding("strobe_phase").values())
            .collect();
        !dts.iter().all(|dt| {
            pairs
                .iter()
                .all(|(pe, ph)| observers::strobe_steps(*pe, *ph, *dt).is_some())
        })
    }

    /// Is `name` bound to an axis (one value per trajectory along it)?
    pub fn on_axis(&self, name: &str) -> bool {
        self.bindings
            .iter()
            .any(|(n, s)| *n == name && matches!(s, Source::Axis { .. }))
    }

    /// The source of a lane input (`dt`, `t0`, a parameter or an initial value).
    pub fn binding(&self, name: &str) -> &Source {
        &self
            .bindings
            .iter()
            .find(|(b, _)| *b == name)
            .unwrap_or_else(|| panic!("plan binds no `{name}`"))
            .1
    }

    /// The same plan with every trajectory repeated `copies` times (a last
    /// axis `copy`), so that timings of small ensembles measure throughput.
    pub fn replicated(&self, copies: usize) -> Plan {
        let mut p = self.clone();
        if copies > 1 {
            for s in &mut p.strides {
                *s *= copies;
            }
            p.strides.push(1);
            p.axes.push(Axis {
                name: "copy".into(),
                len: copies,
            });
            p.n *= copies;
        }
        p
    }

    /// The same plan for its trajectories `rows` only (indices into the
    /// plan's own rows): trajectory `i` of the result is `rows.start + i`.
    pub fn rows(&self, rows: std::ops::Range<usize>) -> Plan {
        debug_assert!(rows.end <= self.n);
        let mut p = self.clone();
        p.first += rows.start;
        p.n = rows.len();
        p
    }

    /// Output times of the trajectory observer (or the final time alone) for
    /// trajectory `traj`.
    pub fn output_times(&self, traj: usize) -> Vec<f64> {
        let traj = self.first + traj;
        let t0 = self.binding("t0").value_at(traj, &self.strides);
        let dt = self.binding("dt").value_at(traj, &self.strides);
        match &self.observers.trajectory {
            Some(tr) => (0..=self.steps / tr.every)
                .map(|f| t0 + (f * tr.every) as f64 * dt)
                .collect(),
            None => vec![t0 + self.steps as f64 * dt],
        }
    }

    /// Trajectory-steps of the run.
    pub fn traj_steps(&self) -> u64 {
        // A count for rates and progress: saturates instead of wrapping.
        (self.n as u64).saturating_mul(self.steps)
    }

    /// Every op name the plan calls (step and field), without repeats.
    pub fn called_ops(&self) -> Vec<&'static str> {
        let mut out: Vec<&'static str> = vec![];
        for op in &self.ops {
            if let Op::Call(name) = op {
                if !out.contains(name) {
                    out.push(name);
                }
            }
        }
        if self.needs_field() {
            for f in &self.field_ops {
                if !out.contains(f) {
                    out.push(f);
                }
            }
        }
        out
    }
}

/// Lane inputs, by lane name.
type Bindings = Vec<(&'static str, Source)>;

/// The model's parameters: known names only, required ones present,
/// defaults filled in (in the model's order).
fn model_params(spec: &ModelSpec, problem: &Problem) -> Result<Bindings, PlanError> {
    for name in problem.params.keys() {
        if spec.param(name).is_none() {
            let known: Vec<&str> = spec.params.iter().map(|p| p.name).collect();
            return Err(err(
                format!("params.{name}"),
                format!(
                    "model `{}` has no parameter `{name}`; its parameters are: {}",
                    spec.name,
                    if known.is_empty() {
                        "(none)".into()
                    } else {
                        known.join(", ")
                    }
                ),
            ));
        }
    }
    spec.params
        .iter()
        .map(|p| {
            let src = match (problem.params.get(p.name), p.default) {
                (Some(s), _) => s.clone(),
                (None, Some(d)) => Source::Const(d),
                (None, None) => {
                    return Err(err(
                        format!("params.{}", p.name),
                        format!("model `{}` needs `{}` ({})", spec.name, p.name, p.doc),
                    ))
                }
            };
            Ok((problem.model.param_lane(p.name), src))
        })
        .collect()
}

/// Is the optional variable integrated? Only when observed; the comparison
/// integrators of mechanical models carry s along, Liénard ones only (q, s).
fn integrates_optional(spec: &ModelSpec, problem: &Problem) -> Result<bool, PlanError> {
    let observed = problem.observers.variables();
    for v in &observed {
        if *v != "t" && !spec.vars.contains(&v.as_str()) {
            return Err(err(
                "output",
                format!(
                    "model `{}` has no variable `{v}`; its variables are: {}, t",
                    spec.name,
                    spec.vars.join(", ")
                ),
            ));
        }
    }
    let want = spec
        .optional_var
        .is_some_and(|o| observed.iter().any(|v| v == o));
    Ok(match &problem.scheme.kind {
        SchemeKind::Splitting { .. } => want,
        SchemeKind::Method(_) if spec.methods_carry_optional => spec.optional_var.is_some(),
        SchemeKind::Method(_) if want => {
            return Err(err(
                "output",
                format!(
                    "`p` of `{}` is integrated by the splitting schemes only, not by `{}`",
                    spec.name, problem.scheme.name
                ),
            ))
        }
        SchemeKind::Method(_) => false,
    })
}

/// Does the step read time (for some trajectory)?
fn reads_time(spec: &ModelSpec, params: &Bindings) -> bool {
    let nonzero = |name: &str| {
        params
            .iter()
            .find(|(p, _)| *p == name)
            .is_some_and(|(_, s)| s.any_nonzero())
    };
    match spec.time {
        TimeDependence::Never => false,
        TimeDependence::Always => true,
        TimeDependence::WhenNonzero(ps) => ps.iter().any(|p| nonzero(p)),
    }
}

/// The model's own rules on its parameter and initial values.
fn check_rules(
    spec: &ModelSpec,
    params: &Bindings,
    initial: &std::collections::BTreeMap<String, Source>,
    t0: &Source,
    time: bool,
) -> Result<(), PlanError> {
    let values = |field: &str| -> Vec<f64> {
        let (table, key) = field.split_once('.').unwrap_or(("", field));
        let found = match table {
            "params" => params.iter().find(|(p, _)| *p == key).map(|(_, s)| s),
            "initial" if key == "t0" => Some(t0),
            "initial" => initial.get(key),
            _ => None,
        };
        found.map(Source::values).unwrap_or_default()
    };
    (spec.rules)(&values, time).map_err(|(f, m)| err(f, m))
}

/// Every step size > 0; a step count the backends can count.
fn check_steps(problem: &Problem) -> Result<(), PlanError> {
    if let Some(dt) = problem.dt.values().into_iter().find(|v| *v <= 0.0) {
        return Err(err("integrator.dt", format!("must be > 0 (got {dt})")));
    }
    if problem.steps == 0 {
        return Err(err("integrator.steps", "must be at least 1"));
    }
    if problem.steps >= MAX_STEPS {
        return Err(err(
            "integrator.steps",
            format!("{} steps: at most {} per run", problem.steps, MAX_STEPS - 1),
        ));
    }
    Ok(())
}

/// Steps a plan may have: step numbers are `i32` in the shared observer
/// functions (both backends) and `u32` on the GPU.
pub const MAX_STEPS: u64 = i32::MAX as u64;

/// A stroboscopic section samples at most once per step: a shorter period
/// would make the observers' work per step unbounded (a period of 1e-300
/// would never finish a step).
fn check_section_period(bindings: &Bindings) -> Result<(), PlanError> {
    let values = |name: &str| {
        bindings
            .iter()
            .find(|(b, _)| *b == name)
            .map(|(_, s)| s.values())
            .unwrap_or_default()
    };
    let shortest = values("strobe_period")
        .into_iter()
        .fold(f64::INFINITY, f64::min);
    let longest_step = values("dt").into_iter().fold(0.0, f64::max);
    if shortest < longest_step {
        return Err(err(
            "output.poincare.period",
            format!(
                "a period of {shortest:?} is shorter than the step dt = {longest_step:?}; a section samples at most once per step: lengthen the period or lower dt"
            ),
        ));
    }
    Ok(())
}

/// Lane parameters derived from the scene's (spin–orbit weights) or from
/// model data (Liénard coefficients).
fn derived_params(problem: &Problem, params: &Bindings) -> Bindings {
    problem
        .model
        .derived()
        .into_iter()
        .map(|d| {
            let src = match d.from {
                Some((base, f)) => params
                    .iter()
                    .find(|(b, _)| *b == base)
                    .map(|(_, s)| s.map(f))
                    .unwrap_or(Source::Const(f(0.0))),
                None => Source::Const(d.value),
            };
            (d.name, src)
        })
        .collect()
}

/// The initial state of the integrated variables (the model's default where
/// the problem gives none).
fn initial_state(
    spec: &ModelSpec,
    vars: &[&'static str],
    initial: &std::collections::BTreeMap<String, Source>,
) -> Bindings {
    vars.iter()
        .map(|v| {
            let default = spec
                .initial_defaults
                .iter()
                .find(|(d, _)| d == v)
                .map_or(0.0, |(_, x)| *x);
            (
                *v,
                initial.get(*v).cloned().unwrap_or(Source::Const(default)),
            )
        })
        .collect()
}

/// A stroboscopic section's period and phase, lane inputs like any
/// parameter (at the forcing period 2π/ω: per trajectory).
fn section_inputs(problem: &Problem, bindings: &Bindings) -> Result<Bindings, PlanError> {
    Ok(
        match problem.observers.poincare.as_ref().map(|p| &p.section) {
            Some(Section::Stroboscopic { period, phase }) => vec![
                ("strobe_period", Source::Const(*period)),
                ("strobe_phase", Source::Const(*phase)),
            ],
            Some(Section::Forced { skip }) => {
                let field = "output.poincare.period";
                let spec = problem.model.spec();
                let param = spec.forcing_frequency.ok_or_else(|| {
                    err(
                        field,
                        format!("model `{}` has no forcing period", spec.name),
                    )
                })?;
                let omega = if param.is_empty() {
                    Source::Const(1.0)
                } else {
                    bindings
                        .iter()
                        .find(|(b, _)| *b == param)
                        .map(|(_, s)| s.clone())
                        .unwrap_or(Source::Const(0.0))
                };
                if omega.values().iter().any(|w| !(w.is_finite() && *w > 0.0)) {
                    return Err(err(
                        field,
                        format!(
                            "the forcing period 2π/{param} needs {param} > 0 for every trajectory"
                        ),
                    ));
                }
                let skip = *skip;
                vec![
                    (
                        "strobe_period",
                        omega.map(|w| 2.0 * std::f64::consts::PI / w),
                    ),
                    (
                        "strobe_phase",
                        omega.map(move |w| skip * 2.0 * std::f64::consts::PI / w),
                    ),
                ]
            }
            _ => vec![],
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vdp() -> Problem {
        Problem::new(Model::VanDerPol, "s2")
            .unwrap()
            .param("epsilon", Source::Const(1.0))
    }

    #[test]
    fn van_der_pol_qs_integrates_no_p_and_no_t() {
        let plan = Plan::new(&vdp()).unwrap();
        assert_eq!(plan.vars, vec!["q", "s"]);
        assert!(!plan.time);
        let calls: Vec<_> = plan
            .ops
            .iter()
            .filter_map(|o| if let Op::Call(c) = o { Some(*c) } else { None })
            .collect();
        assert_eq!(
            calls,
            vec![
                "lienard_c_q",
                "van_der_pol_b_s",
                "van_der_pol_a_s",
                "van_der_pol_b_s",
                "lienard_c_q"
            ]
        );
    }

    #[test]
    fn asking_for_p_adds_it() {
        let mut p = vdp();
        p.observers.final_vars = vec!["q".into(), "s".into(), "p".into()];
        let plan = Plan::new(&p).unwrap();
        assert_eq!(plan.vars, vec!["q", "s", "p"]);
        assert!(plan.called_ops().contains(&"van_der_pol_a_p"));
    }

    #[test]
    fn forcing_brings_time() {
        let p = vdp()
            .param("forcing_amplitude", Source::Const(5.0))
            .param("forcing_frequency", Source::Const(2.463));
        let plan = Plan::new(&p).unwrap();
        assert!(plan.time);
        assert_eq!(plan.ops[0], Op::Time(0.5));
    }

    #[test]
    fn autonomous_compositions_merge_neighbours() {
        let mut p = vdp();
        p.scheme = Scheme::by_name("triple_jump4").unwrap();
        let plan = Plan::new(&p).unwrap();
        // 3 stages × 5 pieces, minus 2 merges at the stage boundaries.
        assert_eq!(
            plan.ops.iter().filter(|o| matches!(o, Op::Tau(_))).count(),
            13
        );
        let total: f64 = plan
            .ops
            .iter()
            .filter_map(|o| if let Op::Tau(c) = o { Some(*c) } else { None })
            .sum();
        // Each stage moves C by w (two halves), B by w and A by w: total 3.
        assert!((total - 3.0).abs() < 1e-12);
    }

    #[test]
    fn a_section_period_below_the_step_is_refused() {
        let mut p = vdp();
        p.dt = Source::Const(0.01);
        p.steps = 10;
        p.observers.poincare = Some(observers::PoincareObs {
            section: Section::Stroboscopic {
                period: 1e-300,
                phase: 0.0,
            },
            vars: vec!["q".into()],
            max_points: 10,
        });
        let e = Plan::new(&p).unwrap_err();
        assert_eq!(e.field, "output.poincare.period");
        assert!(e.message.contains("shorter than the step"), "{e}");
        if let Some(pc) = p.observers.poincare.as_mut() {
            pc.section = Section::Stroboscopic {
                period: 0.01,
                phase: 0.0,
            };
        }
        assert!(Plan::new(&p).is_ok());
    }

    #[test]
    fn errors_name_the_field() {
        let e = Plan::new(&vdp().param("mu", Source::Const(1.0))).unwrap_err();
        assert_eq!(e.field, "params.mu");
        let e = Plan::new(&Problem::new(Model::LaneEmden, "s2").unwrap()).unwrap_err();
        assert_eq!(e.field, "params.index");
        let mut p = vdp();
        p.order = Some("CABAC".into());
        assert!(Plan::new(&p).is_ok());
        p.order = Some("CBAB".into());
        assert_eq!(Plan::new(&p).unwrap_err().field, "integrator.order");
        let mut p = Problem::new(Model::QuadraticS, "leapfrog").unwrap();
        p.steps = 10;
        assert_eq!(Plan::new(&p).unwrap_err().field, "integrator.scheme");
    }
}
