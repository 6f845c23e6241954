//! Mid-run checkpoints (issue 12, point 3, `--checkpoint-every`): an
//! integration paused for a snapshot at every moment it can, and one
//! continued from a snapshot in a fresh engine (as after a kill), end with
//! observations bitwise identical to an uninterrupted run, on the CPU (f32
//! and f64, fused kernels, the op interpreter, formula models) and on the
//! GPU (across chunks and windows), with every observer (every column of
//! the observations, checked).

use std::time::{Duration, Instant};

use reeb::backend::checkpoint::{Checkpoints, Contents};
use reeb::backend::gpu;
use reeb::backend::BackendError;
use reeb::backend::Engine;
use reeb::models::Flows;
use reeb::plan::observations::{Col, Observations};
use reeb::plan::snapshot::Header;
use reeb::plan::Plan;

use crate::common;
use common::plan;

/// Van der Pol with every observer, trajectories that diverge and
/// trajectories the stop condition stops (t > 60 + 10ε: ε < 1.2 of them).
const VAN_DER_POL: &str = r#"
model = "van_der_pol"
[params]
epsilon = { linspace = [0.5, 3.0, 149] }
forcing_amplitude = 0.3
forcing_frequency = 1.1
[initial]
q = 2.0
[integrator]
scheme = "yoshida6a"
dt = 0.02
steps = 3600
[output]
final = ["q", "p", "s", "t"]
trajectory = { every = 7, vars = ["q", "s"] }
poincare = { crossing = "q", value = 1.0, direction = "down", vars = ["s", "p"], max_points = 5 }
cycle = { var = "q", skip = 0.3 }
average = { vars = ["q", "s"], skip = 0.4 }
stop = "t > 60 + 10*epsilon"
attractors = { max_period = 3, skip = 0.2 }
"#;

/// Spin–orbit with an interpolated stroboscopic section (fused S2 kernels).
const SPIN_ORBIT: &str = r#"
model = "spin_orbit"
[params]
eccentricity = 0.1
epsilon = 0.05
[initial]
q = { linspace = [0.0, 6.0, 9] }
p = { linspace = [0.5, 1.5, 11] }
[integrator]
scheme = "s2"
dt = 0.1
steps = 5000
[output]
final = ["q", "p"]
poincare = { period = 6.283185307179586, vars = ["q", "p"], max_points = 90 }
attractors = { angles = ["q"], max_period = 4, tolerance = 1e-2 }
"#;

/// Chaos indicators (two exponents, FLI, MEGNO, their running values per
/// frame): on the CPU the compiled tangent and samples take runs of steps,
/// the vectors in scratch lanes between the pause points.
const CHAOS: &str = r#"
model = "spin_orbit"
[params]
eccentricity = 0.1
epsilon = 0.05
[initial]
q = { linspace = [0.0, 6.0, 9] }
p = { linspace = [0.5, 1.5, 11] }
[integrator]
scheme = "triple_jump4"
dt = 0.05
steps = 3500
[output]
final = ["q", "p"]
trajectory = { every = 50, vars = ["q"] }
lyapunov = { vectors = 2, every = 5 }
fli = true
megno = true
attractors = { every = 50, skip = 0.3 }
"#;

/// SALI and GALI_4 on conservative Hénon–Heiles (a formula model: the
/// tangent and the samples through the interpreter), with their frames.
const ALIGNMENT: &str = r#"
model = "mechanical"
[formula]
dof = 2
potential = "(q1^2 + q2^2)/2 + q1^2*q2 - q2^3/3"
damping = "0"
[initial]
q1 = { linspace = [-0.1, 0.1, 5] }
q2 = { linspace = [-0.2, 0.3, 13] }
p1 = 0.3
p2 = 0.1
[integrator]
scheme = "s2"
dt = 0.05
steps = 3500
[output]
final = ["q", "p"]
trajectory = { every = 70, vars = ["q1"] }
sali = { every = 5 }
gali = { k = 4, every = 5 }
"#;

/// A formula model (the interpreter) with an exactly sampled section.
const DUFFING: &str = r#"
model = "mechanical"
[formula]
potential = "alpha*q^2/2 + beta*q^4/4 - gamma*q*cos(omega*t)"
damping = "delta"
forcing_frequency = "omega"
[params]
alpha = -1.0
beta = 1.0
gamma = 0.5
delta = 0.3
omega = 1.2
[initial]
q = { linspace = [-2.0, 2.0, 13] }
p = { linspace = [-2.0, 2.0, 7] }
[integrator]
scheme = "s2"
dt = 0.08181230868723419
steps = 3600
[output]
final = ["q", "p"]
trajectory = { every = 10, vars = ["q"] }
poincare = { period = "forcing", vars = ["q", "p"], max_points = 30 }
"#;

/// Every array of two observations, bit for bit.
fn same<R: Flows>(label: &str, a: &Observations<R>, b: &Observations<R>) {
    let bits = |c: &Col<R>| match c {
        Col::Real(v) => bytemuck::cast_slice::<R, u8>(v).to_vec(),
        Col::Count(v) => bytemuck::cast_slice::<u32, u8>(v).to_vec(),
        Col::Int(v) => bytemuck::cast_slice::<i32, u8>(v).to_vec(),
    };
    let (ca, cb) = (a.columns(), b.columns());
    assert_eq!(ca.len(), cb.len(), "{label}: columns");
    for (k, ((_, x), (_, y))) in ca.iter().zip(&cb).enumerate() {
        assert!(bits(x) == bits(y), "{label}: column {k} differs");
    }
}

type Run<'r, R> = &'r dyn Fn(Option<&mut Checkpoints>) -> Result<Observations<R>, BackendError>;

/// Runs `run` uninterrupted, paused for a snapshot at every chance, and
/// continued from its first, middle and last snapshots: all bitwise equal.
/// (A CPU block reads the clock every 1024 steps, so a horizon of more than
/// 3 × 1024 steps pauses at least three times whatever the threads do.)
fn resumes<R: Flows>(label: &str, run: Run<R>, header: &Header) {
    let plain = run(None).unwrap();
    let mut saved: Vec<Vec<u8>> = vec![];
    let mut keep = |contents: Contents| {
        let mut bytes = vec![];
        contents(&mut bytes)?;
        saved.push(bytes);
        Ok(())
    };
    let mut cp = Checkpoints {
        every: Some(Duration::ZERO),
        since: Instant::now(),
        resume: None,
        save: &mut keep,
        taken: 0,
        stop: None,
    };
    let paused = run(Some(&mut cp)).unwrap();
    let taken = cp.taken;
    assert!(taken >= 3, "{label}: only {taken} snapshots");
    assert_eq!(saved.len(), taken);
    same(&format!("{label}, paused {taken} times"), &paused, &plain);
    let total = header.n * header.steps;
    for k in [0, taken / 2, taken - 1] {
        let mut r = saved[k].as_slice();
        let h = Header::read(&mut r).unwrap();
        h.continues(header).unwrap();
        assert!(
            h.traj_steps > 0 && h.traj_steps < total,
            "{label}: snapshot {k} after {} of {total} trajectory-steps",
            h.traj_steps
        );
        let mut ignore = |_: Contents| Ok(());
        let mut cp = Checkpoints {
            every: None,
            since: Instant::now(),
            resume: Some((h, &mut r)),
            save: &mut ignore,
            taken: 0,
            stop: None,
        };
        let resumed = run(Some(&mut cp)).unwrap();
        same(&format!("{label}, from snapshot {k}"), &resumed, &plain);
    }
}

fn on_cpu<R: Flows>(label: &str, plan: &Plan) {
    let engine = Engine::Cpu;
    let run = |cp: Option<&mut Checkpoints>| {
        engine
            .run_resumable::<R>(plan, None, cp)
            .map(|r| r.observations)
    };
    let header = engine.snapshot_header::<R>(plan).unwrap();
    resumes::<R>(&format!("{label} cpu {}", R::NAME), &run, &header);
}

const SCENES: [(&str, &str); 5] = [
    ("van der Pol", VAN_DER_POL),
    ("spin–orbit", SPIN_ORBIT),
    ("chaos indicators", CHAOS),
    ("alignment indices", ALIGNMENT),
    ("formula Duffing", DUFFING),
];

#[test]
fn cpu_runs_continue_bitwise_from_any_snapshot() {
    for (label, text) in SCENES {
        let plan = plan(text);
        on_cpu::<f64>(label, &plan);
        on_cpu::<f32>(label, &plan);
    }
}

/// The scenes above hold every column observations may have, so that the
/// snapshots' round trip covers each observer's state and outputs: a new
/// column fails here until a scene asks for it.
#[test]
fn the_snapshot_scenes_cover_every_column() {
    let mut covered = std::collections::BTreeSet::new();
    for (_, text) in SCENES {
        let o = Engine::Cpu
            .run::<f32>(&plan(text), None)
            .unwrap()
            .observations;
        for (name, (_, column)) in o.column_names().into_iter().zip(o.columns()) {
            let filled = match column {
                Col::Real(v) => !v.is_empty(),
                Col::Count(v) => !v.is_empty(),
                Col::Int(v) => !v.is_empty(),
            };
            if filled {
                covered.insert(name);
            }
        }
    }
    let all: std::collections::BTreeSet<&str> =
        Observations::<f32>::COLUMN_NAMES.iter().copied().collect();
    let missing: Vec<_> = all.difference(&covered).collect();
    assert!(missing.is_empty(), "no snapshot scene has {missing:?}");
}

#[test]
fn gpu_runs_continue_bitwise_from_any_snapshot() {
    let Some(ctx) = common::gpu() else { return };
    // Small chunks and windows: snapshots fall in every chunk, at many steps.
    let opts = gpu::GpuOptions {
        max_chunk: Some(64),
        max_steps_per_dispatch: Some(97),
        ..Default::default()
    };
    for (label, text) in [
        ("van der Pol", VAN_DER_POL),
        ("spin–orbit", SPIN_ORBIT),
        ("chaos indicators", CHAOS),
        ("alignment indices", ALIGNMENT),
    ] {
        let plan = plan(text);
        let run = |cp: Option<&mut Checkpoints>| {
            gpu::run_resumable::<f32>(ctx, &plan, None, &opts, cp).map(|r| r.observations)
        };
        let engine = gpu::fingerprint::<f32>(ctx, &plan, &opts).unwrap();
        let header = Header::of::<f32>(&plan, engine);
        resumes::<f32>(&format!("{label} gpu"), &run, &header);
    }
}

#[test]
fn a_snapshot_of_another_engine_or_plan_is_not_continued() {
    let (a, b) = (plan(VAN_DER_POL), plan(SPIN_ORBIT));
    let cpu = Engine::Cpu.snapshot_header::<f64>(&a).unwrap();
    let why = cpu
        .continues(&Engine::Cpu.snapshot_header::<f32>(&a).unwrap())
        .unwrap_err();
    assert!(why.contains("in f64, this run is in f32"), "{why}");
    let why = cpu
        .continues(&Engine::Cpu.snapshot_header::<f64>(&b).unwrap())
        .unwrap_err();
    assert!(
        why.contains("149") && why.contains("over 3600 steps"),
        "{why}"
    );
    let gpu = Header {
        engine: "gpu llvmpipe".into(),
        ..cpu.clone()
    };
    let why = gpu.continues(&cpu).unwrap_err();
    assert!(
        why.contains("taken on gpu llvmpipe, this run is on cpu"),
        "{why}"
    );
}
