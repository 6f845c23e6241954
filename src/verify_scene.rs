//! `reeb verify SCENE`: trust for the user's own scene (formula models
//! above all). On the scene's first trajectory over a short horizon, the
//! measured convergence order of its scheme (and of S2 and Yoshida 6A)
//! against an adaptive DOP853 reference built from the same vector field
//! (the formulas' DAG for formula models); then the CPU–GPU agreement on the
//! scene's ensemble over its first steps.

use crate::backend::Engine;
use crate::num::precision::Precision;
use crate::plan::observations::Observations;
use crate::plan::{Plan, Problem, Source};
use crate::reference::truth::dop853_of;
use crate::scene::{Input, Scene};
use crate::verify::{
    bound, failed, fmt, largest_difference, order_check, Check, OrderProblem, Target,
};

/// Horizon of the order measurement: long enough to see the scheme's
/// global error, short enough to stay out of chaos.
pub const ORDER_HORIZON: f64 = 4.0;
/// The measured order may differ from the nominal one by this much.
const ORDER_TOLERANCE: f64 = 0.2;
/// Steps of the CPU–GPU comparison.
const AGREEMENT_STEPS: u64 = 200;

/// Every check for `scene` on `target`, calling `each` as rows complete.
pub fn run_scene(scene: &Scene, target: &Target, mut each: impl FnMut(&Check)) -> Vec<Check> {
    let mut rows = vec![];
    let mut push = |c: Check| {
        each(&c);
        rows.push(c);
    };
    let f32 = target.precision == Precision::F32;
    match order_problem(scene) {
        Ok(op) => {
            for scheme in schemes(scene) {
                if let Some(c) = order_check(target, &op, &scheme, f32, ORDER_TOLERANCE) {
                    push(c);
                }
            }
        }
        Err(e) => push(failed("order", "reference DOP853", e)),
    }
    if let Some(c) = agreement(scene, target.precision) {
        push(c);
    }
    rows
}

/// The scene's scheme, then S2 and Yoshida 6A (without repeats).
fn schemes(scene: &Scene) -> Vec<String> {
    let mut out = vec![scene.scheme.name.clone()];
    for s in ["s2", "yoshida6a"] {
        if !out.iter().any(|o| o == s) {
            out.push(s.to_string());
        }
    }
    out
}

/// A scene input's first value (trajectory 0).
fn first(scene: &Scene, i: &Input) -> f64 {
    match i {
        Input::Const(v) => *v,
        Input::Axis(k) => scene.axes[*k].values[0],
    }
}

/// The scene's first trajectory over [`ORDER_HORIZON`] (or its own shorter
/// horizon), with a DOP853 reference at rtol 10⁻¹⁴.
fn order_problem(scene: &Scene) -> Result<OrderProblem, String> {
    let spec = scene.model.spec();
    let params: Vec<(&'static str, f64)> = spec
        .params
        .iter()
        .filter_map(|p| scene.params.get(p.name).map(|i| (p.name, first(scene, i))))
        .collect();
    let mut initial: Vec<(&'static str, f64)> = spec
        .vars
        .iter()
        .filter_map(|v| scene.initial.get(*v).map(|i| (*v, first(scene, i))))
        .collect();
    let t0 = scene.initial.get("t0").map_or(0.0, |i| first(scene, i));
    if t0 != 0.0 {
        initial.push(("t0", t0));
    }
    let dt = first(scene, &scene.dt);
    let horizon = match scene.horizon {
        crate::scene::Horizon::TEnd(t) => t - t0,
        crate::scene::Horizon::Steps(n) => n as f64 * dt,
    };
    let t_end = ORDER_HORIZON.min(horizon);
    let vars: Vec<&'static str> = spec
        .vars
        .iter()
        .copied()
        .filter(|v| Some(*v) != spec.optional_var)
        .collect();
    let mut p = Problem::new(scene.model.clone(), "s2").map_err(|e| e.to_string())?;
    for (k, v) in params.iter() {
        p = p.param(k, Source::Const(*v));
    }
    for (k, v) in initial.iter() {
        p = p.initial(k, Source::Const(*v));
    }
    p.dt = Source::Const(t_end);
    p.steps = 1;
    p.observers.final_vars = vars.iter().map(|v| (*v).into()).collect();
    let plan = Plan::new(&p).map_err(|e| e.to_string())?;
    let truth = dop853_of(&plan, 0, &[t0 + t_end], 1e-14).map_err(|e| e.to_string())?;
    let reference = vars
        .iter()
        .map(|v| {
            plan.vars
                .iter()
                .position(|x| x == v)
                .map(|k| truth.values[0][k])
        })
        .collect::<Option<Vec<f64>>>()
        .ok_or("the reference lacks a variable")?;
    Ok(OrderProblem {
        label: format!(
            "{} (trajectory 0, t ≤ {}, DOP853 reference)",
            scene.name,
            fmt(t_end)
        ),
        model: scene.model.clone(),
        params,
        initial,
        t_end,
        vars,
        reference,
        // A DOP853 reference at tolerance 1e-14 hides order 10.
        max_order: 8,
        f32_hides_small_constants: true,
    })
}

/// The scene's ensemble over its first steps on the CPU and the GPU: the
/// largest difference relative to max(1, |value|), `None` without a GPU.
fn agreement(scene: &Scene, precision: Precision) -> Option<Check> {
    let gpu = Engine::gpu(None).ok()?;
    let mut capped = scene.clone();
    capped.step_cap = Some(AGREEMENT_STEPS);
    let name = format!(
        "CPU–GPU agreement on {} (first {AGREEMENT_STEPS} steps)",
        scene.name
    );
    let subs = match capped.sub_runs() {
        Ok(s) => s,
        Err(e) => return Some(failed("agreement", name, e.to_string())),
    };
    let plan = &subs[0].plan;
    let run = |e: &Engine| e.run_f64(plan, precision).map(|(o, _)| o);
    let (c, g) = match (run(&Engine::Cpu), run(&gpu)) {
        (Ok(c), Ok(g)) => (c, g),
        (Err(e), _) | (_, Err(e)) => return Some(failed("agreement", name, e.to_string())),
    };
    if precision == Precision::F64 {
        return Some(bound(
            "agreement",
            name,
            "round-off",
            largest_difference(&c, &g, false),
            1e-9,
        ));
    }
    Some(f32_agreement(name, plan, &c, &g))
}

/// The f32 agreement row: a chaotic scene amplifies round-off past any
/// fixed bound in 200 steps (Duffing: 7e-2), on either backend, so the
/// GPU's f32 error against the CPU in f64 is held to twice the CPU's own
/// f32 error, and both must stop the same trajectories.
fn f32_agreement(name: String, plan: &Plan, c: &Observations<f64>, g: &Observations<f64>) -> Check {
    let truth = match Engine::Cpu.run_f64(plan, Precision::F64) {
        Ok((t, _)) => t,
        Err(e) => return failed("agreement", name, e.to_string()),
    };
    let (cpu_err, gpu_err) = (
        largest_difference(&truth, c, true),
        largest_difference(&truth, g, true),
    );
    let stopped = |o: &Observations<f64>| o.nonfinite_step.iter().filter(|s| **s > 0).count();
    let differ = c
        .nonfinite_step
        .iter()
        .zip(&g.nonfinite_step)
        .filter(|(a, b)| (**a > 0) != (**b > 0))
        .count();
    if differ > 0 {
        let what = format!(
            "the same trajectories stop (CPU {}, GPU {})",
            stopped(c),
            stopped(g)
        );
        return bound("agreement", name, &what, differ as f64, 0.0);
    }
    let what = format!(
        "GPU f32 error against f64 (CPU's f32 error {})",
        fmt(cpu_err)
    );
    bound("agreement", name, &what, gpu_err, (2.0 * cpu_err).max(1e-3))
}
