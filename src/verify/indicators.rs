//! `reeb verify`'s checks of the chaos indicators (README, "Chaos
//! indicators"): the tangent map of one step against central finite
//! differences of the compiled step for every model × scheme; the sum of
//! the exponents of every model with a 2-dimensional tangent space against
//! the mean log-determinant of the step along the orbit (finite
//! differences again); the linear damped oscillator's exact sum −α; van der
//! Pol's limit cycle (λ₁ → 0); the map's exponents against the flow's from
//! its variational equations (DOP853); and on a GPU, its indicators
//! against the CPU's.

use super::check::{bound, check, failed, Check, Target};
use crate::backend::cpu::kernels;
use crate::backend::cpu::tangent::{CompiledTangent, TangentScratch};
use crate::backend::Engine;
use crate::models::lanes::{Lane, Lanes, LANES, NAMES};
use crate::models::spec::Op;
use crate::models::{scalar_fn, Model, MODEL_NAMES};
use crate::num::formula::tape::Tape;
use crate::num::isa::Isa;
use crate::plan::observations::Observations;
use crate::plan::observers::{LyapunovObs, SampledObs};
use crate::plan::problem::PlanError;
use crate::plan::scheme::SCHEME_NAMES;
use crate::plan::tangent::{TangentInput, TangentStep};
use crate::plan::{Plan, Problem, Source};
use crate::reference::truth::lane_of;
use crate::reference::variational::flow_exponents;
use crate::scene::Scene;

const GROUP: &str = "indicators";
const C: fn(f64) -> Source = Source::Const;

/// Every check of the indicators on `target`.
pub fn checks(target: &Target, f32: bool) -> Vec<Check> {
    let mut rows = vec![finite_differences()];
    rows.push(linear_sum(target, f32));
    rows.extend(sum_rules(target, f32));
    rows.push(limit_cycle(target));
    rows.extend(flow_agreement(target, f32));
    if let Engine::Gpu(_) = target.engine {
        rows.extend(backends_agree(target, f32));
    }
    rows
}

/// A problem of `name` (a built-in model) with every term switched on
/// (forcing, time dependence, damping), at `scheme`, dt = 0.07, from a
/// regular state (Kepler away from its singularity).
pub fn full_problem(name: &str, scheme: &str) -> Option<Problem> {
    let p = Problem::new(Model::from_name(name)?, scheme).ok()?;
    let mut p = match name {
        "damped_oscillator" => p
            .param("alpha", C(0.3))
            .param("forcing_amplitude", C(0.5))
            .param("forcing_frequency", C(1.3)),
        "van_der_pol" => p
            .param("epsilon", C(1.3))
            .param("forcing_amplitude", C(0.4))
            .param("forcing_frequency", C(1.1)),
        "kepler" => p
            .param("alpha", C(0.05))
            .param("theta", C(2.0))
            .initial("q1", C(1.0))
            .initial("p2", C(1.1)),
        "lane_emden" => p.param("index", C(3.0)).initial("t0", C(0.5)),
        "spin_orbit" => p
            .param("eccentricity", C(0.2))
            .param("epsilon", C(0.3))
            .param("lambda", C(0.1))
            .param("omega", C(2.0))
            .param("tidal_k", C(0.05))
            .param("tidal_eta", C(1.2)),
        "quadratic_s" => p.param("gamma", C(0.5)).param("r", C(0.1)),
        _ => p,
    };
    if let Model::Lienard { f, g } = &mut p.model {
        *f = vec![-1.0, 0.0, 1.0];
        *g = vec![0.0, 1.0, 0.0, 0.3];
    }
    p.dt = C(0.07);
    Some(p)
}

/// Formula models (forced Liénard, damped Hénon–Heiles, a damped
/// pendulum) at `scheme`, every term switched on, `steps` of dt = 0.07,
/// with the scene's `output` lines `output`.
pub fn formula_plans(scheme: &str, steps: u64, output: &str) -> Vec<Plan> {
    let texts = [
        "model = \"lienard\"\n[formula]\nf = \"eps*(q^2 - 1)\"\ng = \"q + 0.3*q^3 - A*cos(w*t)\"\nforcing_frequency = \"w\"\n[params]\neps = 1.3\nA = 0.4\nw = 1.1",
        "model = \"mechanical\"\n[formula]\ndof = 2\npotential = \"(q1^2 + q2^2)/2 + q1^2*q2 - q2^3/3\"\ndamping = \"delta\"\n[params]\ndelta = 0.05",
        "model = \"mechanical\"\n[formula]\npotential = \"-cos(q)\"\ndamping = \"gamma*(1 + 0.5*sin(t))\"\n[params]\ngamma = 0.2",
    ];
    texts
        .iter()
        .filter_map(|body| {
            let text = format!(
                "name = \"f\"\n{body}\n[initial]\nq = 0.7\n[integrator]\nscheme = \"{scheme}\"\ndt = 0.07\nsteps = {steps}\n[output]\nfinal = [\"q\"]\n{output}\n"
            );
            let scene = Scene::parse(std::path::Path::new("formula.toml"), &text).ok()?;
            Some(scene.sub_runs().ok()?.swap_remove(0).plan)
        })
        .collect()
}

/// A state to differentiate at, by variable.
pub fn start(var: &str) -> f64 {
    match var {
        "q" => 0.7,
        "p" => -0.4,
        "s" => 0.2,
        "q1" => 0.9,
        "q2" => 0.3,
        "p1" => -0.2,
        "p2" => 1.1,
        _ => 0.1,
    }
}

/// The inputs of the plan's first trajectory in one lane, the state at `x`.
pub fn lane_at(plan: &Plan, x: &[(&str, f64)]) -> Lane<f64> {
    let mut l = lane_of(plan, 0);
    for (v, value) in x {
        *l.get_mut(v).expect("a state variable") = *value;
    }
    l
}

/// Step number `n` of the plan as compiled: the scalar ops (a formula
/// model's from its DAG).
pub fn step(plan: &Plan, l: &mut Lane<f64>, n: u64) {
    let (t0, dt) = (l.t0, l.dt);
    for op in &plan.ops {
        match *op {
            Op::Tau(c) => l.tau = c * dt,
            Op::Time(c) => l.t = t0 + n as f64 * dt + c * dt,
            Op::Call(name) => match (scalar_fn::<f64>(name), plan.model.formula()) {
                (Some(f), _) => f(l),
                (None, Some(m)) => {
                    m.apply_f64(name, l);
                }
                (None, None) => unreachable!("an op of the model"),
            },
        }
    }
}

/// The tangent space and the tangent map of step `n` at `x`: the tangent
/// program applied to the unit vectors (its columns).
pub fn tangent_columns(
    plan: &Plan,
    x: &[(&str, f64)],
    n: u64,
) -> Result<(Vec<&'static str>, Vec<Vec<f64>>), PlanError> {
    let d = TangentStep::new(&plan.step_spec(), 1)?.space.len();
    let t = TangentStep::new(&plan.step_spec(), d)?;
    let untabled = |_: usize, _: usize| unreachable!("an untabled tangent computes its time terms");
    let cols = columns_of(&t, &lane_at(plan, x), n, untabled);
    Ok((t.space, cols))
}

/// The columns of the tangent program `t` (as many vectors as its space
/// has dimensions) at lane `l` and step `n`: its map applied to the unit
/// vectors, in f64 on the tape; `time_term(stage, term)`: the inputs of a
/// tabled tangent (`TangentStep::tabled`).
pub fn columns_of(
    t: &TangentStep,
    l: &Lane<f64>,
    n: u64,
    time_term: impl Fn(usize, usize) -> f64,
) -> Vec<Vec<f64>> {
    let d = t.space.len();
    let inputs: Vec<[f64; 1]> = t
        .inputs
        .iter()
        .map(|i| match *i {
            TangentInput::Lane(name) => [l.get(name).unwrap_or(0.0)],
            TangentInput::Step => [n as f64],
            TangentInput::Deviation { k, j } => [if k == j { 1.0 } else { 0.0 }],
            TangentInput::TimeTerm { stage, term } => [time_term(stage, term)],
        })
        .collect();
    let tape = Tape::<f64>::new(&t.program, |_| false);
    let mut regs = vec![[0.0; 1]; tape.registers];
    tape.run(&mut regs, &inputs[..], Isa::Baseline);
    (0..d)
        .map(|k| (0..d).map(|j| tape.output(&regs, k * d + j)[0]).collect())
        .collect()
}

/// The tangent map of step `n` at `x` on `space` as the CPU's compiled
/// tangent step computes it (its columns, the unit vectors carried at
/// once), where the plan has one (`backend/cpu/tangent.rs`; at the best
/// level this CPU runs).
pub fn compiled_columns(
    plan: &Plan,
    x: &[(&str, f64)],
    space: &[&str],
    n: u64,
) -> Option<Vec<Vec<f64>>> {
    let d = space.len();
    let c = CompiledTangent::<f64>::new(plan, space, d, kernels::isa(), false)?;
    let l = lane_at(plan, x);
    let mut lanes = Lanes::<f64>::boxed();
    for name in NAMES {
        if let (Some(v), Some(a)) = (l.get(name), lanes.field_mut(name)) {
            *a = [v; LANES];
        }
    }
    let mut scratch = TangentScratch::new(&lanes, d);
    for (k, v) in scratch.d.iter_mut().enumerate() {
        for (j, var) in space.iter().enumerate() {
            let unit = if j == k { 1.0 } else { 0.0 };
            *v.field_mut(var).expect("a lane") = [unit; LANES];
        }
    }
    c.run(&mut scratch.x, &mut scratch.d, n);
    let column = |v: &Lanes<f64>| {
        space
            .iter()
            .map(|s| v.field(s).expect("a lane")[0])
            .collect()
    };
    Some(scratch.d.iter().map(|v| column(v)).collect())
}

/// Central finite differences (step `h`) of step `n` of the compiled
/// step at `x` on `space`: the Jacobian's columns.
pub fn difference_columns(
    plan: &Plan,
    x: &[(&str, f64)],
    space: &[&str],
    n: u64,
    h: f64,
) -> Vec<Vec<f64>> {
    let moved = |var: &str, by: f64| {
        let y: Vec<(&str, f64)> = x
            .iter()
            .map(|(v, val)| (*v, if *v == var { val + by } else { *val }))
            .collect();
        let mut l = lane_at(plan, &y);
        step(plan, &mut l, n);
        l
    };
    space
        .iter()
        .map(|var| {
            let (up, down) = (moved(var, h), moved(var, -h));
            let at = |l: &Lane<f64>, v: &str| l.get(v).unwrap_or(f64::NAN);
            space
                .iter()
                .map(|out| (at(&up, out) - at(&down, out)) / (2.0 * h))
                .collect()
        })
        .collect()
}

/// The largest |tangent − finite differences| / max(|finite differences|, 1)
/// over the Jacobian of step 3 at the [`start`] state: the tangent
/// program's and, where the plan has one, the CPU's compiled tangent's.
pub fn tangent_error(plan: &Plan) -> Result<f64, PlanError> {
    let x: Vec<(&str, f64)> = plan.vars.iter().map(|v| (*v, start(v))).collect();
    let (space, mut cols) = tangent_columns(plan, &x, 3)?;
    let mut fd = difference_columns(plan, &x, &space, 3, 1e-6);
    if let Some(compiled) = compiled_columns(plan, &x, &space, 3) {
        cols.extend(compiled);
        fd.extend(fd.clone());
    }
    let mut worst: f64 = 0.0;
    for (a, b) in cols.iter().flatten().zip(fd.iter().flatten()) {
        let e = (a - b).abs() / b.abs().max(1.0);
        worst = if e.is_nan() {
            f64::INFINITY
        } else {
            worst.max(e)
        };
    }
    Ok(worst)
}

/// (1/t) Σ ln|det ∂step| over `steps` steps of the compiled step from
/// the plan's first trajectory, each Jacobian by central differences on
/// the 2-dimensional tangent space `space`: the sum of the two exponents.
pub fn log_det_rate(plan: &Plan, space: &[&str], steps: u64) -> f64 {
    let mut l = lane_of(plan, 0);
    let mut sum = 0.0;
    for n in 0..steps {
        let x: Vec<(&str, f64)> = plan
            .vars
            .iter()
            .map(|v| (*v, l.get(v).unwrap_or(0.0)))
            .collect();
        let j = difference_columns(plan, &x, space, n, 1e-5);
        sum += (j[0][0] * j[1][1] - j[1][0] * j[0][1]).abs().ln();
        step(plan, &mut l, n);
    }
    sum / (steps as f64 * l.dt)
}

/// `p` asking for `k` exponents (every `every` steps, `skip` skipped), the
/// FLI and MEGNO, over `steps` steps of `dt`.
pub fn with_indicators(
    mut p: Problem,
    k: usize,
    every: u64,
    skip: f64,
    steps: u64,
    dt: f64,
) -> Problem {
    p.dt = C(dt);
    p.steps = steps;
    p.observers.lyapunov = Some(LyapunovObs {
        vectors: k,
        every,
        skip,
    });
    p.observers.fli = Some(SampledObs { every });
    p.observers.megno = Some(SampledObs { every });
    p
}

/// The exponents of the first trajectory of `p` on `target`.
fn exponents(target: &Target, p: &Problem) -> Result<Vec<f64>, String> {
    let plan = Plan::new(p).map_err(|e| e.to_string())?;
    exponents_of(target, &plan)
}

fn exponents_of(target: &Target, plan: &Plan) -> Result<Vec<f64>, String> {
    let o = target.run(plan)?;
    Ok(o.lyapunov[..o.exponents].to_vec())
}

/// Every built-in model × scheme with a tangent map, and the formula models.
fn finite_differences() -> Check {
    let mut plans = vec![];
    for scheme in SCHEME_NAMES {
        plans.extend(
            MODEL_NAMES
                .iter()
                .filter_map(|m| Plan::new(&full_problem(m, scheme)?).ok()),
        );
        plans.extend(formula_plans(scheme, 10, ""));
    }
    let (mut worst, mut pairs) = (0.0f64, 0);
    for plan in &plans {
        // Only a comparison method may lack a tangent map (refused by name).
        if let Ok(e) = tangent_error(plan) {
            worst = worst.max(e);
            pairs += 1;
        }
    }
    let name = format!(
        "tangent of a step = central differences of the step ({pairs} model × scheme pairs, f64)"
    );
    bound(GROUP, name, "relative error", worst, 1e-6)
}

/// The linear damped oscillator: λ₁ + λ₂ = −α for any horizon.
fn linear_sum(target: &Target, f32: bool) -> Check {
    let alpha = 3.0;
    let p = Problem::new(Model::DampedOscillator, "s2")
        .expect("s2")
        .param("alpha", C(alpha))
        .initial("q", C(1.0));
    let name = "damped oscillator (α = 3): λ1 + λ2 = −α";
    match exponents(target, &with_indicators(p, 2, 3, 0.0, 4000, 0.05)) {
        Ok(l) => check(
            GROUP,
            name,
            -alpha,
            l[0] + l[1],
            if f32 { 1e-4 } else { 1e-12 * alpha },
        ),
        Err(e) => failed(GROUP, name, e),
    }
}

/// λ₁ + λ₂ of every model with a 2-dimensional tangent space against the
/// mean log-determinant of its compiled step along the orbit.
fn sum_rules(target: &Target, f32: bool) -> Vec<Check> {
    let (steps, every) = (1000, 5);
    let built_in = MODEL_NAMES.iter().filter_map(|m| {
        let p = with_indicators(full_problem(m, "triple_jump4")?, 2, every, 0.0, steps, 0.07);
        Plan::new(&p).ok()
    });
    let output = format!("lyapunov = {{ vectors = 2, every = {every} }}");
    let formula = formula_plans("triple_jump4", steps, &output);
    let mut rows = vec![];
    for plan in built_in.chain(formula) {
        let Ok(t) = TangentStep::new(&plan.step_spec(), 1) else {
            continue;
        };
        if t.space.len() != 2 {
            continue;
        }
        let from = if plan.model.formula().is_some() {
            " from formulas"
        } else {
            ""
        };
        let name = format!(
            "{}{from}: λ1 + λ2 = (1/t) Σ ln|det ∂step| (finite differences)",
            plan.model.name()
        );
        let want = log_det_rate(&plan, &t.space, steps);
        let tol = if f32 { 1e-4 } else { 1e-7 } * want.abs().max(0.1);
        match exponents_of(target, &plan) {
            Ok(l) => rows.push(check(GROUP, name, want, l[0] + l[1], tol)),
            Err(e) => rows.push(failed(GROUP, name, e)),
        }
    }
    rows
}

/// Van der Pol on its limit cycle: the largest exponent (along the flow)
/// vanishes.
fn limit_cycle(target: &Target) -> Check {
    let p = Problem::new(Model::VanDerPol, "s2")
        .expect("s2")
        .param("epsilon", C(1.0))
        .initial("q", C(2.0));
    let name = "van der Pol (ε = 1) on its limit cycle: |λ1| by t = 2000";
    match exponents(target, &with_indicators(p, 1, 10, 0.0, 200_000, 0.01)) {
        Ok(l) => bound(GROUP, name, "|λ1|", l[0].abs(), 5e-3),
        Err(e) => failed(GROUP, name, e),
    }
}

/// The forced van der Pol (A = ε = 5, ω = 2.45): the exponents of the
/// fourth-order map at dt = 0.005 against the flow's, from its variational
/// equations integrated by DOP853.
fn flow_agreement(target: &Target, f32: bool) -> Vec<Check> {
    let (t, skip) = (300.0, 0.2);
    let p = Problem::new(Model::VanDerPol, "triple_jump4")
        .expect("triple_jump4")
        .param("epsilon", C(5.0))
        .param("forcing_amplitude", C(5.0))
        .param("forcing_frequency", C(2.45))
        .initial("q", C(2.0))
        .initial("s", C(2.0));
    let dt = 0.005;
    let p = with_indicators(p, 2, 10, skip, (t / dt) as u64, dt);
    let flow = Plan::new(&p).map_err(|e| e.to_string()).and_then(|plan| {
        flow_exponents(&plan, 0, 2, (t, skip * t, 1.0), 1e-10).map_err(|e| e.to_string())
    });
    let tol = if f32 { 1e-2 } else { 2e-3 };
    let name = |i: usize| {
        format!("forced van der Pol (ω = 2.45): λ{i} of the map (dt = 0.005) = the flow's (DOP853 variational)")
    };
    match (flow, exponents(target, &p)) {
        (Ok(flow), Ok(map)) => (0..2)
            .map(|i| check(GROUP, name(i + 1), flow[i], map[i], tol))
            .collect(),
        (Err(e), _) | (_, Err(e)) => vec![failed(GROUP, name(1), e)],
    }
}

/// Every indicator of five models, GPU against CPU (non-chaotic orbits).
fn backends_agree(target: &Target, f32: bool) -> Vec<Check> {
    let cpu = Target {
        engine: Engine::Cpu,
        precision: target.precision,
    };
    let models = [
        ("damped_oscillator", 2),
        ("van_der_pol", 2),
        ("kepler", 4),
        ("spin_orbit", 2),
        ("quadratic_s", 3),
    ];
    let mut rows = vec![];
    for (m, k) in models {
        let name = format!("{m}: every indicator, GPU = CPU");
        let Some(p) = full_problem(m, "triple_jump4") else {
            continue;
        };
        let p = with_indicators(p, k, 4, 0.0, 2000, 0.01);
        let runs = Plan::new(&p)
            .map_err(|e| e.to_string())
            .and_then(|plan| Ok((target.run(&plan)?, cpu.run(&plan)?)));
        match runs {
            Ok((g, c)) => {
                let worst = largest_difference(&g, &c);
                rows.push(bound(
                    GROUP,
                    name,
                    "relative difference",
                    worst,
                    if f32 { 1e-3 } else { 1e-9 },
                ));
            }
            Err(e) => rows.push(failed(GROUP, name, e)),
        }
    }
    rows
}

/// The largest relative difference between two runs' indicators.
fn largest_difference(a: &Observations<f64>, b: &Observations<f64>) -> f64 {
    let pairs = [
        (&a.lyapunov, &b.lyapunov),
        (&a.fli, &b.fli),
        (&a.megno, &b.megno),
    ];
    let mut worst: f64 = 0.0;
    for (x, y) in pairs {
        for (x, y) in x.iter().zip(y.iter()) {
            let e = (x - y).abs() / x.abs().max(1e-3);
            let both_nan = x.is_nan() && y.is_nan();
            worst = if both_nan {
                worst
            } else if e.is_nan() {
                f64::INFINITY
            } else {
                worst.max(e)
            };
        }
    }
    worst
}
