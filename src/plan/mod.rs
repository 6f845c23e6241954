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

pub mod observations;
pub mod observers;
pub mod scheme;

use std::collections::BTreeMap;

use crate::models::spec::{ModelSpec, TimeDependence};
use crate::models::{lanes, Model};
use observers::{Observers, Section};
use scheme::{parse_order, Scheme, SchemeKind};

/// One axis of the ensemble.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    pub name: String,
    pub len: usize,
}

/// Where a per-trajectory input comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    Const(f64),
    /// `values[k]` for the trajectories whose index along `axis` is k. Several
    /// sources on the same axis are zipped.
    Axis {
        axis: usize,
        values: Vec<f64>,
    },
}

impl Source {
    /// Does any trajectory see a nonzero value?
    pub fn any_nonzero(&self) -> bool {
        match self {
            Source::Const(v) => *v != 0.0,
            Source::Axis { values, .. } => values.iter().any(|v| *v != 0.0),
        }
    }
    /// Every value this source takes.
    pub fn values(&self) -> Vec<f64> {
        match self {
            Source::Const(v) => vec![*v],
            Source::Axis { values, .. } => values.clone(),
        }
    }
    /// The value for trajectory `index` given the axis strides.
    #[inline]
    pub fn value_at(&self, index: usize, strides: &[usize]) -> f64 {
        match self {
            Source::Const(v) => *v,
            Source::Axis { axis, values } => values[(index / strides[*axis]) % values.len()],
        }
    }
    /// The same source with every value mapped by `f`.
    pub fn map(&self, f: impl Fn(f64) -> f64) -> Source {
        match self {
            Source::Const(v) => Source::Const(f(*v)),
            Source::Axis { axis, values } => Source::Axis {
                axis: *axis,
                values: values.iter().map(|v| f(*v)).collect(),
            },
        }
    }
}

/// A problem as a user states it.
#[derive(Debug, Clone)]
pub struct Problem {
    pub model: Model,
    pub scheme: Scheme,
    /// S2 inner order (`None`: the model's default, e.g. `CBABC`).
    pub order: Option<String>,
    pub axes: Vec<Axis>,
    /// Model parameters by scene name.
    pub params: BTreeMap<String, Source>,
    /// Initial values by variable name, and `t0`.
    pub initial: BTreeMap<String, Source>,
    pub dt: Source,
    pub steps: u64,
    pub observers: Observers,
}

/// Why a problem cannot be planned; the message names the field.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
#[error("{field}: {message}")]
pub struct PlanError {
    pub field: String,
    pub message: String,
}

fn err(field: impl Into<String>, message: impl Into<String>) -> PlanError {
    PlanError {
        field: field.into(),
        message: message.into(),
    }
}

impl Problem {
    /// A problem with no axes, default parameters, zero initial state, and
    /// final-state output of the model's non-optional variables.
    pub fn new(model: Model, scheme: &str) -> Result<Problem, PlanError> {
        let scheme = Scheme::by_name(scheme).ok_or_else(|| {
            err(
                "integrator.scheme",
                format!(
                    "unknown scheme `{scheme}`; known: {}",
                    crate::plan::scheme::SCHEME_NAMES.join(", ")
                ),
            )
        })?;
        let spec = model.spec();
        let final_vars = spec
            .vars
            .iter()
            .filter(|v| Some(**v) != spec.optional_var)
            .map(|v| v.to_string())
            .collect();
        Ok(Problem {
            model,
            scheme,
            order: None,
            axes: vec![],
            params: BTreeMap::new(),
            initial: BTreeMap::new(),
            dt: Source::Const(0.01),
            steps: 1,
            observers: Observers {
                final_vars,
                ..Observers::default()
            },
        })
    }

    /// Adds an axis and returns the source that runs along it.
    pub fn axis(&mut self, name: &str, values: Vec<f64>) -> Source {
        self.axes.push(Axis {
            name: name.to_string(),
            len: values.len(),
        });
        Source::Axis {
            axis: self.axes.len() - 1,
            values,
        }
    }

    pub fn param(mut self, name: &str, source: Source) -> Self {
        self.params.insert(name.to_string(), source);
        self
    }

    pub fn initial(mut self, name: &str, source: Source) -> Self {
        self.initial.insert(name.to_string(), source);
        self
    }

    /// Number of trajectories: the product of the axis lengths.
    pub fn ensemble_size(&self) -> usize {
        self.axes.iter().map(|a| a.len).product()
    }
}

/// One instruction of a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Op {
    /// `tau ← c · dt`.
    Tau(f64),
    /// `t ← t0 + (n + c) dt` for step n (computed as `t0 + n dt + c dt`).
    Time(f64),
    /// Apply the shared function of this name (arguments bound by name).
    Call(&'static str),
}

/// A splitting step as stages `S2(w_k τ)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Stages {
    /// Piece order outermost first (P1, P2, P3).
    pub order: [char; 3],
    /// Per stage: weight w and time offset c (midpoint, in steps).
    pub stages: Vec<(f64, f64)>,
    /// Is the optional variable integrated?
    pub with_optional: bool,
}

/// A state variable or time, as observers see it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObsVar {
    /// Index into [`Plan::vars`].
    State(usize),
    Time,
}

/// The compiled problem; see the module documentation.
#[derive(Debug, Clone)]
pub struct Plan {
    pub model: Model,
    pub scheme: Scheme,
    pub axes: Vec<Axis>,
    /// Row-major strides of the axes (first axis slowest).
    pub strides: Vec<usize>,
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
}

/// Row-major strides of axes of lengths `lens` (first axis slowest).
pub fn row_major_strides(lens: &[usize]) -> Vec<usize> {
    let mut strides = vec![1usize; lens.len()];
    for k in (0..lens.len().saturating_sub(1)).rev() {
        strides[k] = strides[k + 1] * lens[k + 1];
    }
    strides
}

/// Name of a lane field with a static lifetime.
fn lane_name(name: &str) -> Option<&'static str> {
    lanes::NAMES.iter().copied().find(|n| *n == name)
}

impl Plan {
    pub fn new(problem: &Problem) -> Result<Plan, PlanError> {
        let spec: &'static ModelSpec = problem.model.spec();
        let n = problem.ensemble_size();
        let lens: Vec<usize> = problem.axes.iter().map(|a| a.len).collect();
        let strides = row_major_strides(&lens);
        check_sources(problem)?;

        // Parameters: known names, required ones present, defaults filled in.
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
        let mut params: Vec<(&'static str, Source)> = vec![];
        for p in spec.params {
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
            params.push((p.name, src));
        }
        check_coefficients(&problem.model)?;
        let nonzero = |name: &str| {
            params
                .iter()
                .find(|(p, _)| *p == name)
                .is_some_and(|(_, s)| s.any_nonzero())
        };

        // Variables: the optional one only when observed (or a method needs it).
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
        let method = match &problem.scheme.kind {
            SchemeKind::Method(m) => Some(*m),
            SchemeKind::Splitting { .. } => None,
        };
        let lienard_like = !spec.methods_carry_optional;
        let want_optional = spec
            .optional_var
            .is_some_and(|o| observed.iter().any(|v| v == o));
        let with_optional = match method {
            None => want_optional,
            // Mechanical comparison methods carry s along; Liénard ones only (q, s).
            Some(_) if lienard_like => {
                if want_optional {
                    return Err(err(
                        "output",
                        format!(
                            "`p` of `{}` is integrated by the splitting schemes only, not by `{}`",
                            spec.name, problem.scheme.name
                        ),
                    ));
                }
                false
            }
            Some(_) => spec.optional_var.is_some(),
        };
        let vars: Vec<&'static str> = spec
            .vars
            .iter()
            .copied()
            .filter(|v| with_optional || Some(*v) != spec.optional_var)
            .collect();
        let time = match spec.time {
            TimeDependence::Never => false,
            TimeDependence::Always => true,
            TimeDependence::WhenNonzero(ps) => ps.iter().any(|p| nonzero(p)),
        };

        let initial = resolve_initial(spec, &problem.initial)?;
        let t0 = initial.get("t0").cloned().unwrap_or(Source::Const(0.0));
        let values = |field: &str| -> Vec<f64> {
            let (table, key) = field.split_once('.').unwrap_or(("", field));
            let found = match table {
                "params" => params.iter().find(|(p, _)| *p == key).map(|(_, s)| s),
                "initial" if key == "t0" => Some(&t0),
                "initial" => initial.get(key),
                _ => None,
            };
            found.map(Source::values).unwrap_or_default()
        };
        (spec.rules)(&values, time).map_err(|(f, m)| err(f, m))?;
        if let Some(dt) = problem.dt.values().into_iter().find(|v| !(*v > 0.0)) {
            return Err(err("integrator.dt", format!("must be > 0 (got {dt})")));
        }
        if problem.steps == 0 {
            return Err(err("integrator.steps", "must be at least 1"));
        }
        if problem.steps >= u32::MAX as u64 {
            return Err(err(
                "integrator.steps",
                format!("{} steps: at most {} per run", problem.steps, u32::MAX - 1),
            ));
        }

        let mut bindings: Vec<(&'static str, Source)> = params;
        for d in problem.model.derived() {
            let src = match d.from {
                Some((base, f)) => bindings
                    .iter()
                    .find(|(b, _)| *b == base)
                    .map(|(_, s)| s.map(f))
                    .unwrap_or(Source::Const(f(0.0))),
                None => Source::Const(d.value),
            };
            bindings.push((d.name, src));
        }
        for v in &vars {
            let default = spec
                .initial_defaults
                .iter()
                .find(|(d, _)| d == v)
                .map_or(0.0, |(_, x)| *x);
            bindings.push((
                v,
                initial.get(*v).cloned().unwrap_or(Source::Const(default)),
            ));
        }
        bindings.push(("t0", t0));
        bindings.push(("dt", problem.dt.clone()));
        // Stroboscopic sections: period and phase are lane inputs like any parameter.
        match problem.observers.poincare.as_ref().map(|p| &p.section) {
            Some(Section::Stroboscopic { period, phase }) => {
                bindings.push(("strobe_period", Source::Const(*period)));
                bindings.push(("strobe_phase", Source::Const(*phase)));
            }
            Some(Section::Forced { skip }) => {
                let field = "output.poincare.period";
                let param = problem.model.forcing_frequency_param().ok_or_else(|| {
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
                bindings.push((
                    "strobe_period",
                    omega.map(|w| 2.0 * std::f64::consts::PI / w),
                ));
                bindings.push((
                    "strobe_phase",
                    omega.map(move |w| skip * 2.0 * std::f64::consts::PI / w),
                ));
            }
            _ => {}
        }
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

        let mut stages = None;
        let ops = match &problem.scheme.kind {
            SchemeKind::Splitting { weights } => {
                let order = problem.order.as_deref().unwrap_or(spec.default_order);
                let half =
                    parse_order(order, spec.pieces).map_err(|m| err("integrator.order", m))?;
                if let [a, b, c] = half[..] {
                    let mut cum = 0.0;
                    let list = weights
                        .iter()
                        .map(|w| {
                            let s = (*w, cum + 0.5 * w);
                            cum += w;
                            s
                        })
                        .collect();
                    stages = Some(Stages {
                        order: [a, b, c],
                        stages: list,
                        with_optional,
                    });
                }
                splitting_ops(spec, weights, &half, time, with_optional, &is_zero)
            }
            SchemeKind::Method(m) => {
                let op = spec.method_op(*m).ok_or_else(|| {
                    err(
                        "integrator.scheme",
                        format!(
                            "model `{}` has no `{}` integrator; it has: {}",
                            spec.name,
                            m.name(),
                            spec.methods
                                .iter()
                                .map(|(m, _)| m.name())
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    )
                })?;
                // Methods evaluate time terms themselves, from the step's start.
                let mut ops = if time { vec![Op::Time(0.0)] } else { vec![] };
                ops.extend([Op::Tau(1.0), Op::Call(op)]);
                ops
            }
        };
        let field_ops = spec
            .field_ops
            .iter()
            .filter(|(_, opt)| with_optional || !opt)
            .map(|(o, _)| *o)
            .collect();

        let resolve = |name: &str, field: &str| -> Result<ObsVar, PlanError> {
            if name == "t" {
                return Ok(ObsVar::Time);
            }
            vars.iter()
                .position(|v| *v == name)
                .map(ObsVar::State)
                .ok_or_else(|| err(field, format!("`{name}` is not integrated by this plan")))
        };
        let obs = &problem.observers;
        obs.validate(problem.steps).map_err(|(f, m)| err(f, m))?;
        let final_vars = obs
            .final_vars
            .iter()
            .map(|v| resolve(v, "output.final"))
            .collect::<Result<_, _>>()?;
        let trajectory_vars = match &obs.trajectory {
            Some(t) => t
                .vars
                .iter()
                .map(|v| resolve(v, "output.trajectory.vars"))
                .collect::<Result<_, _>>()?,
            None => vec![],
        };
        let poincare_vars = match &obs.poincare {
            Some(p) => p
                .vars
                .iter()
                .map(|v| resolve(v, "output.poincare.vars"))
                .collect::<Result<_, _>>()?,
            None => vec![],
        };
        let state_only = |o: ObsVar, field: &str| match o {
            ObsVar::State(k) => Ok(k),
            ObsVar::Time => Err(err(field, "time cannot be the crossing variable")),
        };
        let crossing_var = match obs.poincare.as_ref().map(|p| &p.section) {
            Some(Section::Crossing { var, .. }) => Some(state_only(
                resolve(var, "output.poincare.crossing")?,
                "output.poincare.crossing",
            )?),
            _ => None,
        };
        let cycle_var = match &obs.cycle {
            Some(c) => Some(state_only(
                resolve(&c.var, "output.cycle.var")?,
                "output.cycle.var",
            )?),
            None => None,
        };

        Ok(Plan {
            model: problem.model.clone(),
            scheme: problem.scheme.clone(),
            axes: problem.axes.clone(),
            strides,
            n,
            vars,
            time,
            bindings,
            ops,
            stages,
            field_ops,
            steps: problem.steps,
            observers: problem.observers.clone(),
            final_vars,
            trajectory_vars,
            poincare_vars,
            crossing_var,
            cycle_var,
        })
    }

    /// Does any observer need the vector field at the step ends (for
    /// interpolation inside a step)?
    pub fn needs_field(&self) -> bool {
        self.crossing_var.is_some() || self.cycle_var.is_some() || self.strobe_interpolated()
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

    /// Output times of the trajectory observer (or the final time alone) for
    /// trajectory `traj`.
    pub fn output_times(&self, traj: usize) -> Vec<f64> {
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
        self.n as u64 * self.steps
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

/// Initial values by variable name (and `t0`): known keys only, and a
/// model's alias (Kepler's `eccentricity`) replaced by what it stands for.
fn resolve_initial(
    spec: &ModelSpec,
    given: &BTreeMap<String, Source>,
) -> Result<BTreeMap<String, Source>, PlanError> {
    let mut initial = given.clone();
    if let Some(alias) = &spec.initial_alias {
        if let Some(e) = initial.remove(alias.key) {
            let field = format!("initial.{}", alias.key);
            if let Some(v) = e.values().into_iter().find(|v| !(alias.ok)(*v)) {
                return Err(err(field, format!("{v} is not in {}", alias.range)));
            }
            for (var, f) in alias.sets {
                initial.entry(var.to_string()).or_insert_with(|| e.map(f));
            }
        }
    }
    for name in initial.keys() {
        if name != "t0" && !spec.vars.contains(&name.as_str()) {
            return Err(err(
                format!("initial.{name}"),
                format!(
                    "model `{}` has no variable `{name}`; initial conditions are: {}, t0",
                    spec.name,
                    spec.vars.join(", ")
                ),
            ));
        }
    }
    Ok(initial)
}

/// Axis references in range and of the axis's length.
fn check_sources(problem: &Problem) -> Result<(), PlanError> {
    let all = problem
        .params
        .iter()
        .map(|(k, s)| (format!("params.{k}"), s))
        .chain(
            problem
                .initial
                .iter()
                .map(|(k, s)| (format!("initial.{k}"), s)),
        )
        .chain(std::iter::once(("integrator.dt".to_string(), &problem.dt)));
    for (field, s) in all {
        match s {
            Source::Const(v) if !v.is_finite() => {
                return Err(err(field, format!("{v} is not a finite number")))
            }
            Source::Axis { axis, values } => {
                let a = problem
                    .axes
                    .get(*axis)
                    .ok_or_else(|| err(&field, "refers to a missing axis"))?;
                if a.len != values.len() {
                    return Err(err(
                        field,
                        format!(
                            "has {} values but its axis `{}` has {}",
                            values.len(),
                            a.name,
                            a.len
                        ),
                    ));
                }
                if values.iter().any(|v| !v.is_finite()) {
                    return Err(err(field, "contains a value that is not a finite number"));
                }
            }
            _ => {}
        }
    }
    if problem.axes.iter().any(|a| a.len == 0) {
        return Err(err("axes", "an axis has no values"));
    }
    Ok(())
}

/// The Liénard model's coefficient lists (model-level data, not parameters).
fn check_coefficients(model: &Model) -> Result<(), PlanError> {
    if let Model::Lienard { f, g } = model {
        for (name, c) in [("f", f), ("g", g)] {
            if c.len() > crate::models::lienard::MAX_COEFFICIENTS {
                return Err(err(
                    format!("params.{name}"),
                    format!(
                        "{} coefficients; at most {} (degree 9)",
                        c.len(),
                        crate::models::lienard::MAX_COEFFICIENTS
                    ),
                ));
            }
            if c.iter().any(|v| !v.is_finite()) {
                return Err(err(
                    format!("params.{name}"),
                    "contains a value that is not a finite number",
                ));
            }
        }
    }
    Ok(())
}

/// Ops of one step of the composition `S2(w_1 τ) … S2(w_k τ)`:
/// per stage, the time terms at the stage midpoint (D is outermost, SPEC §1.1)
/// and the pieces `P1(w/2) … Pm(w) … P1(w/2)`. Pieces that are the identity
/// for this problem are dropped, and for autonomous problems equal neighbours
/// across stages are merged (`P1(a) P1(b) = P1(a + b)`, exact flows).
fn splitting_ops(
    spec: &ModelSpec,
    weights: &[f64],
    half: &[char],
    time: bool,
    with_optional: bool,
    is_zero: &dyn Fn(&str) -> bool,
) -> Vec<Op> {
    enum Item {
        Time(f64),
        Piece(char, f64),
    }
    let identity = |piece: char| {
        spec.piece(piece).is_some_and(|p| {
            !p.identity_when_zero.is_empty() && p.identity_when_zero.iter().all(|n| is_zero(n))
        })
    };
    let mut items: Vec<Item> = vec![];
    let mut cum = 0.0;
    for &w in weights {
        if time {
            items.push(Item::Time(cum + 0.5 * w));
        }
        let m = half.len();
        let seq = half
            .iter()
            .enumerate()
            .map(|(k, &c)| (c, if k + 1 == m { w } else { 0.5 * w }));
        let back = half[..m - 1].iter().rev().map(|&c| (c, 0.5 * w));
        for (c, coef) in seq.chain(back) {
            if identity(c) {
                continue;
            }
            match items.last_mut() {
                Some(Item::Piece(prev, a)) if *prev == c => *a += coef,
                _ => items.push(Item::Piece(c, coef)),
            }
        }
        cum += w;
    }
    let mut ops = vec![];
    for item in items {
        match item {
            Item::Time(c) => {
                ops.push(Op::Time(c));
                ops.extend(spec.time_ops.iter().map(|o| Op::Call(o)));
            }
            Item::Piece(c, coef) => {
                ops.push(Op::Tau(coef));
                let piece = spec.piece(c).expect("parse_order checked the letters");
                ops.extend(
                    piece
                        .ops
                        .iter()
                        .filter(|(_, opt)| with_optional || !opt)
                        .map(|(o, _)| Op::Call(o)),
                );
            }
        }
    }
    ops
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
