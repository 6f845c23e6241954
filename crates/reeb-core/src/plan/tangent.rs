//! The tangent map of a plan's step: the exact Jacobian of the numerical
//! one-step map, applied to deviation vectors. The step's ops become
//! formulas of the state at the step's start (`models/symbolic.rs`: each
//! op from its one source), and their derivatives along each vector
//! (`Dag::directional`) are the vectors after the step — the tangent-map
//! method (Skokos & Gerlach 2010), never a Jacobian written per model.
//!
//! The tangent space is the state variables that feed back into the
//! positions: starting from the `q`s, every variable the new values of the
//! space read joins it. So it is `(q, p)` for mechanical models (`s` does
//! not feed back), `(q, s)` for Liénard systems (`p` does not), and every
//! variable for `quadratic_s`, whose damping is s itself; in the plan's
//! variable order. Time is a parameter, not a direction.

use crate::models::formula::STEP_INDEX;
use crate::models::spec::Op;
use crate::models::symbolic::LaneFormulas;
use crate::num::formula::lower::{lower, Lowered};
use crate::num::formula::{Dag, Id};

use crate::models::{op_args, Model};

use super::problem::{err, PlanError, Source};

/// What the tangent map is made of: a plan's model, scheme, integrated
/// variables, lane inputs and step (`Plan::step_spec`).
#[derive(Debug, Clone, Copy)]
pub struct StepSpec<'a> {
    pub model: &'a Model,
    pub scheme: &'a str,
    pub vars: &'a [&'static str],
    pub bindings: &'a [(&'static str, Source)],
    pub ops: &'a [Op],
}

/// Where an input of the tangent program comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TangentInput {
    /// A lane field (the state at the step's start, parameters, `t0`, `dt`).
    Lane(&'static str),
    /// The number of the step (0 for the first).
    Step,
    /// Component `j` (of the tangent space) of deviation vector `k`.
    Deviation { k: usize, j: usize },
    /// Time term `term` (of [`time_terms`]) at the step's stage `stage`,
    /// from the table of the terms the ensemble shares
    /// ([`TangentStep::tabled`]).
    TimeTerm { stage: usize, term: usize },
}

/// The lanes `model`'s time ops write, in the order of its ops and their
/// arguments: a row of the table of time terms an ensemble shares
/// (`backend/gpu/time_table.rs`). `None` if an op is unknown.
pub fn time_terms(model: &Model) -> Option<Vec<&'static str>> {
    let mut terms: Vec<&'static str> = vec![];
    for op in model.spec().time_ops {
        for &(name, written) in op_args(op)? {
            if written && !terms.contains(&name) {
                terms.push(name);
            }
        }
    }
    Some(terms)
}

/// One step of the tangent map for `vectors` deviation vectors.
#[derive(Debug, Clone)]
pub struct TangentStep {
    /// The tangent space: state variables, in the plan's order.
    pub space: Vec<&'static str>,
    pub vectors: usize,
    /// Inputs by variable index; outputs: vector k's component j at
    /// `k·space.len() + j`.
    pub program: Lowered,
    pub inputs: Vec<TangentInput>,
}

/// A step's map as formulas: the lanes' values after the step over their
/// values before it (`t` from `t0`, `dt` and the step number, as the ops
/// compute it).
pub fn step_formulas(plan: &StepSpec) -> Result<LaneFormulas, PlanError> {
    Ok(formulas(plan, false)?.0)
}

/// [`step_formulas`]; `tabled`: the time ops' terms are read, not
/// computed, each stage's a variable of its own, returned with the
/// input it is (by variable index).
fn formulas(
    plan: &StepSpec,
    tabled: bool,
) -> Result<(LaneFormulas, Vec<(u32, TangentInput)>), PlanError> {
    let field = "integrator.scheme";
    let mut f = LaneFormulas::new(plan.model);
    let time_ops = plan.model.spec().time_ops;
    let terms = match tabled {
        true => time_terms(plan.model).ok_or_else(|| err(field, "a time op without arguments"))?,
        false => vec![],
    };
    let mut read = vec![];
    let mut stages = 0;
    for (lane, source) in plan.bindings {
        if let (Source::Const(v), false) = (source, plan.vars.contains(lane)) {
            f.know(lane, *v);
        }
    }
    for op in plan.ops {
        match *op {
            Op::Tau(c) => {
                let dt = f.read("dt");
                let c = f.dag.num(c);
                let tau = f.dag.mul(c, dt);
                f.write("tau", tau);
            }
            Op::Time(c) => {
                // t0 + n dt + c dt, as the op interpreter computes it.
                let (t0, dt, n) = (f.read("t0"), f.read("dt"), f.read(STEP_INDEX));
                let ndt = f.dag.mul(n, dt);
                let start = f.dag.add(t0, ndt);
                let c = f.dag.num(c);
                let cdt = f.dag.mul(c, dt);
                let t = f.dag.add(start, cdt);
                f.write("t", t);
                stages += 1;
            }
            Op::Call(name) if tabled && time_ops.contains(&name) => {
                let written = op_args(name).into_iter().flatten().filter(|a| a.1);
                for &(lane, _) in written {
                    let term = terms.iter().position(|t| *t == lane).expect("a time term");
                    let k = f.variables.len() as u32;
                    f.fresh(lane);
                    let stage = stages.max(1) - 1;
                    read.push((k, TangentInput::TimeTerm { stage, term }));
                }
            }
            Op::Call(name) => f.apply(plan.model, name).map_err(|e| {
                err(
                    field,
                    format!(
                        "`{}` has no tangent map for model `{}` ({e}); every splitting scheme (s2, triple_jump4, …) has one",
                        plan.scheme,
                        plan.model.name()
                    ),
                )
            })?,
        }
    }
    Ok((f, read))
}

/// The tangent space of `plan` (see the module documentation).
pub fn tangent_space(plan: &StepSpec, f: &mut LaneFormulas) -> Vec<&'static str> {
    let mut space: Vec<&'static str> = plan
        .vars
        .iter()
        .copied()
        .filter(|v| v.starts_with('q'))
        .collect();
    loop {
        let mut grown = space.clone();
        for v in &space {
            let after = f.read(v);
            for k in f.dag.uses(after) {
                let lane = f.variables[k as usize];
                if plan.vars.contains(&lane) && !grown.contains(&lane) {
                    grown.push(lane);
                }
            }
        }
        if grown.len() == space.len() {
            break;
        }
        space = grown;
    }
    plan.vars
        .iter()
        .copied()
        .filter(|v| space.contains(v))
        .collect()
}

impl TangentStep {
    /// The tangent map of `plan`'s step for `vectors` deviation vectors
    /// (at most the tangent dimension).
    pub fn new(plan: &StepSpec, vectors: usize) -> Result<TangentStep, PlanError> {
        TangentStep::build(plan, vectors, false, false)
    }

    /// As [`TangentStep::new`], with the state after the step as more
    /// outputs (after the vectors', in the plan's variable order): one
    /// program that moves the state and the vectors (the GPU's, where the
    /// step and the tangent would otherwise compute the step twice).
    pub fn with_state(plan: &StepSpec, vectors: usize) -> Result<TangentStep, PlanError> {
        TangentStep::build(plan, vectors, true, false)
    }

    /// [`TangentStep::with_state`] with the time ops' terms read from the
    /// table ([`TangentStep::tabled`]): one program that moves the state
    /// and the vectors, each stage's sin and cos computed once for both.
    pub fn with_state_tabled(plan: &StepSpec, vectors: usize) -> Result<TangentStep, PlanError> {
        TangentStep::build(plan, vectors, true, true)
    }

    /// As [`TangentStep::new`], the time ops' terms read from the table of
    /// the terms the ensemble shares ([`TangentInput::TimeTerm`]) rather
    /// than computed for each trajectory, as the GPU's step reads them: the
    /// same values (the table holds what the ops compute), at no cost.
    pub fn tabled(plan: &StepSpec, vectors: usize) -> Result<TangentStep, PlanError> {
        TangentStep::build(plan, vectors, false, true)
    }

    fn build(
        plan: &StepSpec,
        vectors: usize,
        state: bool,
        tabled: bool,
    ) -> Result<TangentStep, PlanError> {
        let (mut f, read) = formulas(plan, tabled)?;
        // Read before the deviations' variables are numbered: a lane no op
        // touches becomes a variable here.
        let state_after: Vec<Id> = match state {
            true => plan.vars.iter().map(|v| f.read(v)).collect(),
            false => Vec::new(),
        };
        let space = tangent_space(plan, &mut f);
        let after: Vec<Id> = space.iter().map(|v| f.read(v)).collect();
        let before: Vec<Option<u32>> = space.iter().map(|v| f.variable(v)).collect();
        let base = f.variables.len() as u32;
        let d = space.len() as u32;
        let mut roots = Vec::with_capacity(vectors * space.len());
        for k in 0..vectors as u32 {
            let mut seed = |dag: &mut Dag, v: u32| match before.iter().position(|b| *b == Some(v)) {
                Some(j) => dag.var(base + k * d + j as u32),
                None => dag.num(0.0),
            };
            roots.extend(f.dag.directional(&after, &mut seed));
        }
        roots.extend(state_after);
        let mut inputs: Vec<TangentInput> = f
            .variables
            .iter()
            .map(|v| match *v {
                STEP_INDEX => TangentInput::Step,
                lane => TangentInput::Lane(lane),
            })
            .collect();
        for (k, term) in read {
            inputs[k as usize] = term;
        }
        for k in 0..vectors {
            inputs.extend((0..space.len()).map(|j| TangentInput::Deviation { k, j }));
        }
        Ok(TangentStep {
            program: lower(&f.dag, &roots),
            space,
            vectors,
            inputs,
        })
    }
}
