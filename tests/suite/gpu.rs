//! GPU backend against the CPU backend: every model × scheme × precision,
//! every observer, chunk and window boundaries, and scale.
//!
//! Tolerance (documented in the README): on short horizons in non-chaotic
//! regimes the two backends evaluate the same formulas in the same order, so
//! they differ only where the GPU compiler contracts `a*b + c` into an FMA or
//! rounds `sqrt` differently: a few ULPs per step, growing at most linearly
//! over the horizon. We allow `|gpu − cpu| ≤ tol · max(1, |cpu|)` with
//! tol = 2·10⁻⁴ in f32 and 10⁻¹⁰ in f64 (60 steps), and identical status,
//! Poincaré counts and crossings.

use reeb::backend::gpu::accuracy;
use reeb::backend::gpu::codegen::{generate, ExpForm};
use reeb::backend::gpu::time_table::TimeTable;
use reeb::backend::gpu::tuning::Launch;
use reeb::backend::{cpu, gpu};
use reeb::models::{Model, MODEL_NAMES};
use reeb::num::math::{exp_f32, log_f32_bits, log_f64_bits, sample_log_f32};
use reeb::num::precision::Precision;
use reeb::num::precision::Real;
use reeb::plan::observations::Observations;
use reeb::plan::observers::{CycleObs, Direction, PoincareObs, Section, TrajectoryObs};
use reeb::plan::scheme::{Scheme, SCHEME_NAMES};
use reeb::plan::tangent::{TangentInput, TangentStep};
use reeb::plan::{Plan, Problem, Source};
use reeb::verify::indicators::{columns_of, lane_at, with_indicators};

use crate::common;
use common::{first_var, gpu, problem};

/// Largest disagreement between two observation sets, with where it is.
fn compare<R: Real>(label: &str, g: &Observations<R>, c: &Observations<R>, tol: f64) -> f64 {
    assert_eq!(g.nonfinite_step, c.nonfinite_step, "{label}: status");
    assert_eq!(
        g.poincare_count, c.poincare_count,
        "{label}: Poincaré counts"
    );
    let groups = [
        ("final", &g.final_values, &c.final_values),
        ("trajectory", &g.trajectory, &c.trajectory),
        ("poincare", &g.poincare, &c.poincare),
    ];
    let mut worst = (0.0f64, String::new());
    let mut consider = |name: &str, i: usize, a: R, b: R| {
        let (a, b) = (a.to_f64(), b.to_f64());
        if a.is_nan() && b.is_nan() {
            return;
        }
        // One NaN and one number: as bad as it gets.
        let d = (a - b).abs() / b.abs().max(1.0);
        let d = if d.is_nan() { f64::INFINITY } else { d };
        if d > worst.0 {
            worst = (d, format!("{name}[{i}]: gpu {a:e}, cpu {b:e}"));
        }
    };
    for (group, gs, cs) in groups {
        for ((name, gv), (_, cv)) in gs.iter().zip(cs.iter()) {
            for (i, (a, b)) in gv.iter().zip(cv).enumerate() {
                consider(&format!("{group}_{name}"), i, *a, *b);
            }
        }
    }
    for (i, (a, b)) in g.cycle_amplitude.iter().zip(&c.cycle_amplitude).enumerate() {
        consider("cycle_amplitude", i, *a, *b);
    }
    for (i, (a, b)) in g.cycle_period.iter().zip(&c.cycle_period).enumerate() {
        consider("cycle_period", i, *a, *b);
    }
    assert!(
        worst.0 <= tol,
        "{label}: worst relative difference {:e} at {} (tolerance {tol:e})",
        worst.0,
        worst.1
    );
    worst.0
}

/// Runs `plan` on the GPU with `opts` in f32, and in f64 where the adapter
/// has it, and compares each with the CPU (tolerances `tol32` and `tol64`);
/// returns the f32 run's number of dispatches.
fn agrees_with_cpu(
    ctx: &gpu::GpuContext,
    label: &str,
    plan: &Plan,
    opts: &gpu::GpuOptions,
    (tol32, tol64): (f64, f64),
) -> u64 {
    let g = gpu::run_with::<f32>(ctx, plan, None, opts).unwrap_or_else(|e| panic!("{label}: {e}"));
    compare(
        &format!("{label} f32"),
        &g.observations,
        &cpu::run::<f32>(plan, None),
        tol32,
    );
    if ctx.shader_f64 {
        let g64 =
            gpu::run_with::<f64>(ctx, plan, None, opts).unwrap_or_else(|e| panic!("{label}: {e}"));
        compare(
            &format!("{label} f64"),
            &g64.observations,
            &cpu::run::<f64>(plan, None),
            tol64,
        );
    }
    g.dispatches
}

/// An ensemble over the first variable's initial value and one parameter,
/// with every observer.
fn ensemble(model: &str, scheme: &str) -> Option<Problem> {
    let mut p = problem(model, scheme)?;
    let x = first_var(model);
    let x0 = match &p.initial.get(x) {
        Some(Source::Const(v)) => *v,
        _ => 1.0,
    };
    let ax = p.axis("x0", vec![x0, 0.95 * x0, 1.05 * x0]);
    p = p.initial(x, ax);
    if let Some(first) = p.model.spec().params.first() {
        if let Some(Source::Const(v)) = p.params.get(first.name).cloned() {
            if first.name != "index" {
                let ax = p.axis(first.name, vec![v, 1.1 * v, 0.9 * v, 1.2 * v]);
                p = p.param(first.name, ax);
            }
        }
    }
    p.dt = Source::Const(0.05);
    p.steps = 60;
    if Scheme::by_name(scheme).unwrap().is_splitting() {
        p.observers.final_vars = p
            .model
            .spec()
            .vars
            .iter()
            .map(|v| (*v).into())
            .chain(["t".into()])
            .collect();
    }
    p.observers.trajectory = Some(TrajectoryObs {
        every: 7,
        vars: vec![x.into(), "t".into()],
    });
    p.observers.poincare = Some(PoincareObs {
        section: Section::Crossing {
            var: x.into(),
            value: 0.9 * x0,
            direction: Direction::Both,
        },
        vars: vec!["t".into(), x.into()],
        max_points: 3,
    });
    p.observers.cycle = Some(CycleObs {
        var: x.into(),
        level: 0.9 * x0,
        skip: 0.2,
    });
    Some(p)
}

#[test]
fn gpu_agrees_with_cpu_for_every_model_scheme_and_precision() {
    let Some(ctx) = gpu() else { return };
    let mut checked = 0;
    for model in MODEL_NAMES {
        let (mut w32, mut w64) = (0.0f64, 0.0f64);
        for scheme in SCHEME_NAMES {
            let Some(p) = ensemble(model, scheme) else {
                continue;
            };
            let plan = Plan::new(&p).unwrap_or_else(|e| panic!("{model} {scheme}: {e}"));
            let label = format!("{model} {scheme} f32");
            let g = gpu::run::<f32>(ctx, &plan, None).unwrap_or_else(|e| panic!("{label}: {e}"));
            w32 = w32.max(compare(
                &label,
                &g.observations,
                &cpu::run::<f32>(&plan, None),
                2e-4,
            ));
            if ctx.shader_f64 {
                let label = format!("{model} {scheme} f64");
                let g =
                    gpu::run::<f64>(ctx, &plan, None).unwrap_or_else(|e| panic!("{label}: {e}"));
                w64 = w64.max(compare(
                    &label,
                    &g.observations,
                    &cpu::run::<f64>(&plan, None),
                    1e-10,
                ));
            }
            checked += 1;
        }
        eprintln!("max |gpu − cpu| / max(1, |cpu|), {model}: f32 {w32:.2e}, f64 {w64:.2e}");
    }
    assert!(checked >= 80, "{checked}");
}

#[test]
fn stroboscopic_sections_agree() {
    let Some(ctx) = gpu() else { return };
    for (period, phase, dt) in [
        (std::f64::consts::PI, 0.0, std::f64::consts::PI / 20.0),
        (1.0, 0.25, 0.03),
    ] {
        let mut p = Problem::new(Model::SpinOrbit, "s2")
            .unwrap()
            .param("eccentricity", Source::Const(0.06))
            .param("epsilon", Source::Const(0.045))
            .param("lambda", Source::Const(0.01))
            .param("omega", Source::Const(std::f64::consts::SQRT_2));
        let q0 = p.axis("q0", vec![0.0, 1.0, 2.0, 3.0]);
        let p0 = p.axis("p0", (0..40).map(|k| 0.4 + 0.035 * k as f64).collect());
        p = p.initial("q", q0).initial("p", p0);
        p.dt = Source::Const(dt);
        p.steps = 200;
        p.observers.poincare = Some(PoincareObs {
            section: Section::Stroboscopic { period, phase },
            vars: vec!["q".into(), "p".into(), "t".into()],
            max_points: 100,
        });
        let plan = Plan::new(&p).unwrap();
        agrees_with_cpu(
            ctx,
            "spin-orbit strobe",
            &plan,
            &Default::default(),
            (2e-4, 1e-10),
        );
    }
}

#[test]
fn chunk_and_window_boundaries() {
    let Some(ctx) = gpu() else { return };
    for n in [1usize, 63, 64, 65, 1000] {
        let mut p = Problem::new(Model::VanDerPol, "yoshida6a")
            .unwrap()
            .initial("q", Source::Const(2.0));
        let eps = p.axis(
            "epsilon",
            (0..n).map(|k| 0.1 + 3.0 * k as f64 / n as f64).collect(),
        );
        p = p.param("epsilon", eps);
        p.dt = Source::Const(0.02);
        p.steps = 101;
        p.observers.trajectory = Some(TrajectoryObs {
            every: 3,
            vars: vec!["q".into(), "s".into()],
        });
        p.observers.poincare = Some(PoincareObs {
            section: Section::Crossing {
                var: "q".into(),
                value: 1.0,
                direction: Direction::Down,
            },
            vars: vec!["s".into()],
            max_points: 2,
        });
        p.observers.cycle = Some(CycleObs {
            var: "q".into(),
            level: 0.0,
            skip: 0.0,
        });
        let plan = Plan::new(&p).unwrap();
        let c = cpu::run::<f32>(&plan, None);
        for (chunk, window) in [
            (None, None),
            (Some(64), Some(7)),
            (Some(100), Some(1)),
            (Some(1), Some(50)),
        ] {
            let opts = gpu::GpuOptions {
                max_chunk: chunk,
                max_steps_per_dispatch: window,
                ..Default::default()
            };
            let g = gpu::run_with::<f32>(ctx, &plan, None, &opts).unwrap();
            compare(
                &format!("n = {n}, chunk {chunk:?}, window {window:?}"),
                &g.observations,
                &c,
                2e-4,
            );
        }
    }
}

#[test]
fn diverging_trajectories_stop_on_the_gpu_too() {
    let Some(ctx) = gpu() else { return };
    let mut p = Problem::new(Model::VanDerPol, "s2")
        .unwrap()
        .initial("q", Source::Const(0.05));
    let eps = p.axis("epsilon", vec![1.0, 1000.0, 2.0]);
    p = p.param("epsilon", eps);
    p.dt = Source::Const(0.1);
    p.steps = 200;
    p.observers.trajectory = Some(TrajectoryObs {
        every: 1,
        vars: vec!["q".into()],
    });
    let plan = Plan::new(&p).unwrap();
    let g = gpu::run_with::<f32>(
        ctx,
        &plan,
        None,
        &gpu::GpuOptions {
            max_chunk: None,
            max_steps_per_dispatch: Some(13),
            ..Default::default()
        },
    )
    .unwrap();
    let c = cpu::run::<f32>(&plan, None);
    assert!(g.observations.nonfinite_step[1] > 0);
    compare("divergence", &g.observations, &c, 2e-4);
}

#[test]
fn ten_million_trajectories_on_the_gpu() {
    let Some(ctx) = gpu() else { return };
    let mut p = Problem::new(Model::VanDerPol, "s2").unwrap();
    let eps = p.axis(
        "epsilon",
        (0..3163).map(|k| 0.1 + 10.0 * k as f64 / 3163.0).collect(),
    );
    let q0 = p.axis(
        "q0",
        (0..3163).map(|k| 2.0 + 0.5 * k as f64 / 3163.0).collect(),
    );
    p = p.param("epsilon", eps).initial("q", q0);
    p.dt = Source::Const(0.01);
    p.steps = 20;
    let plan = Plan::new(&p).unwrap();
    assert!(plan.n >= 10_000_000);
    let g = gpu::run::<f32>(ctx, &plan, None).unwrap();
    assert_eq!(g.observations.count_ok(), plan.n);
    let c = cpu::run::<f32>(&plan, None);
    compare("10⁷ trajectories", &g.observations, &c, 1e-4);
    eprintln!(
        "10⁷ trajectories: {} chunks, {} dispatches, {:.3} s ({})",
        g.chunks, g.dispatches, g.phases.integration, g.timing
    );
}

/// [`ensemble`] with every parameter one value (it may vary a time input),
/// so that the ensemble shares its time terms.
fn shared_ensemble(model: &str, scheme: &str) -> Option<Problem> {
    let mut p = ensemble(model, scheme)?;
    for (name, v) in problem(model, scheme)?.params {
        p = p.param(&name, v);
    }
    Some(p)
}

/// Time terms the ensemble shares are tabulated on the host once per window
/// (the uniform `tterms`, `backend/gpu/time_table.rs`): the kernel reads them
/// instead of calling the time ops, over windows of any length and every
/// stage of a composition, and agrees with the CPU; a `t0` along an axis
/// keeps the per-trajectory time ops.
#[test]
fn shared_time_terms_come_from_a_table_per_window() {
    use reeb::backend::gpu::codegen::generate;
    use reeb::num::precision::Precision;
    let Some(ctx) = gpu() else { return };
    let mut tabled = vec![];
    for model in MODEL_NAMES {
        for scheme in ["s2", "yoshida6a", "yoshida8e", "rk4"] {
            let Some(p) = shared_ensemble(model, scheme) else {
                continue;
            };
            let plan = Plan::new(&p).unwrap();
            let kernel = generate(&plan, Precision::F32).unwrap();
            let Some(tt) = &kernel.time_table else {
                continue;
            };
            // The declared uniform array holds the longest window's rows.
            for precision in [Precision::F32, Precision::F64] {
                let source = generate(&plan, precision).unwrap().source;
                let decl = source
                    .split("var<uniform> tterms: array<vec4<R>, ")
                    .nth(1)
                    .and_then(|r| r.split('>').next())
                    .and_then(|n| n.parse::<u64>().ok())
                    .expect("tterms declared");
                let rows = tt.max_steps(precision.bytes() as u64) * tt.row_stride() as u64;
                assert!(decl >= rows, "{model} {scheme}: {decl} < {rows}");
            }
            for op in tt.ops() {
                assert!(
                    !kernel.source.contains(&format!("        {op}(")),
                    "{model} {scheme}: {op} still called per trajectory"
                );
            }
            tabled.push(format!("{model} {scheme}"));
            for window in [Some(1), Some(7), None] {
                let opts = gpu::GpuOptions {
                    max_chunk: None,
                    max_steps_per_dispatch: window,
                    ..Default::default()
                };
                let label = format!("{model} {scheme} window {window:?}");
                agrees_with_cpu(ctx, &label, &plan, &opts, (2e-4, 1e-10));
            }
        }
    }
    eprintln!("tabled: {tabled:?}");
    for must in [
        "spin_orbit s2",
        "spin_orbit yoshida8e",
        "lane_emden yoshida6a",
    ] {
        assert!(
            tabled.iter().any(|t| t == must),
            "{must} not tabled: {tabled:?}"
        );
    }
    assert!(!tabled.iter().any(|t| t.ends_with("rk4")), "{tabled:?}");
    // Windows as long as the table allows (4096 f32 / 2048 f64 steps of
    // spin–orbit S2: the whole uniform array is read).
    let mut p = shared_ensemble("spin_orbit", "s2").unwrap();
    p.steps = 9000;
    let plan = Plan::new(&p).unwrap();
    // 9000 f32 steps: round-off (FMAs contract differently on the two
    // sides) grows to ~2e-4; a wrong row would be O(1).
    let windows = agrees_with_cpu(
        ctx,
        "long windows",
        &plan,
        &Default::default(),
        (1e-3, 1e-9),
    );
    assert!(windows >= 3, "{windows} windows");
    // A t0 along an axis: every trajectory its own time terms.
    let mut p = ensemble("spin_orbit", "s2").unwrap();
    let t0 = p.axis("t0", vec![0.0, 0.5]);
    p = p.initial("t0", t0);
    let plan = Plan::new(&p).unwrap();
    assert!(generate(&plan, Precision::F32)
        .unwrap()
        .time_table
        .is_none());
    let g = gpu::run::<f32>(ctx, &plan, None).unwrap();
    compare(
        "t0 axis",
        &g.observations,
        &cpu::run::<f32>(&plan, None),
        2e-4,
    );
}

/// llvmpipe ends a shader's loops once they have run 65 535 iterations in
/// all (`codegen::LOOP_ITERATIONS`): windows that long, with observers whose
/// per-step code may loop (crossings located by Newton, a section that may
/// find two samples in a step), must lose no step and no sample, whatever
/// the window.
#[test]
fn long_windows_lose_no_step() {
    let Some(ctx) = gpu() else { return };
    let (dt, steps) = (0.02, 70_000u64);
    // A period of several steps, and one within rounding of a step (so a
    // step might hold two samples, and the section loops).
    for period in [0.0731, 0.020015] {
        let mut p = Problem::new(Model::VanDerPol, "s2")
            .unwrap()
            .initial("q", Source::Const(2.0));
        let eps = p.axis("epsilon", (0..64).map(|k| 0.5 + 0.02 * k as f64).collect());
        p = p.param("epsilon", eps);
        p.dt = Source::Const(dt);
        p.steps = steps;
        p.observers.poincare = Some(PoincareObs {
            section: Section::Stroboscopic { period, phase: 0.0 },
            vars: vec!["t".into(), "q".into()],
            max_points: 500,
        });
        p.observers.cycle = Some(CycleObs {
            var: "q".into(),
            level: 0.0,
            skip: 0.0,
        });
        let plan = Plan::new(&p).unwrap();
        // Samples at k·period for k = 0, 1, … up to the horizon.
        let expected = ((steps as f64 * dt) / period).floor() as u32 + 1;
        let c = cpu::run::<f32>(&plan, None);
        assert!(c.poincare_count.iter().all(|n| *n == expected), "cpu");
        let runs: Vec<_> = [None, Some(997)]
            .into_iter()
            .map(|window| {
                let opts = gpu::GpuOptions {
                    max_chunk: None,
                    max_steps_per_dispatch: window,
                    ..Default::default()
                };
                gpu::run_with::<f32>(ctx, &plan, None, &opts)
                    .unwrap_or_else(|e| panic!("period {period}, window {window:?}: {e}"))
                    .observations
            })
            .collect();
        for g in &runs {
            assert_eq!(g.poincare_count, c.poincare_count, "period {period}");
            assert!(g.nonfinite_step.iter().all(|s| *s == 0));
        }
        let bits = |o: &Observations<f32>| -> Vec<u32> {
            let columns = o
                .final_values
                .iter()
                .chain(&o.poincare)
                .flat_map(|(_, v)| v);
            let cycle = o.cycle_amplitude.iter().chain(&o.cycle_period);
            columns.chain(cycle).map(|x| x.to_bits()).collect()
        };
        assert!(
            bits(&runs[0]) == bits(&runs[1]),
            "period {period}: the window changed the results"
        );
    }
}

/// The launch changes the speed, never the bits (issue 35, point 2): every
/// workgroup size, trajectories per invocation and window tried against
/// the default launch, with a finite test every step or every 4, for a plan
/// with every observer, one whose time terms come from a table
/// (spin–orbit), and a formula model; and a launch beyond the adapter's
/// limits is refused before it is tried.
#[test]
fn every_launch_gives_the_same_bits() {
    let Some(ctx) = gpu() else { return };
    let plans = [
        (
            "van_der_pol s2",
            Plan::new(&ensemble("van_der_pol", "s2").unwrap()).unwrap(),
        ),
        (
            "spin_orbit yoshida6a",
            Plan::new(&shared_ensemble("spin_orbit", "yoshida6a").unwrap()).unwrap(),
        ),
        ("spin_orbit yoshida6a, final values only", {
            let mut p = shared_ensemble("spin_orbit", "yoshida6a").unwrap();
            let final_vars = p.observers.final_vars.clone();
            p.observers = Default::default();
            p.observers.final_vars = final_vars;
            Plan::new(&p).unwrap()
        }),
        (
            "lienard formula",
            reeb::bench::Scenario::LienardFormulaS2.plan(300, 40),
        ),
    ];
    let blocked: Vec<&str> = plans
        .iter()
        .filter(|(_, p)| {
            let k = gpu::codegen::generate(p, reeb::num::precision::Precision::F32).unwrap();
            k.has_blocks()
        })
        .map(|(label, _)| *label)
        .collect();
    assert_eq!(
        blocked,
        ["spin_orbit yoshida6a, final values only", "lienard formula"]
    );
    let bits = |o: &dyn std::fmt::Debug| format!("{o:?}");
    let mut tried = 0;
    for (label, plan) in &plans {
        let base32 = bits(&gpu::run::<f32>(ctx, plan, None).unwrap().observations);
        let base64 = ctx
            .shader_f64
            .then(|| bits(&gpu::run::<f64>(ctx, plan, None).unwrap().observations));
        for workgroup in [32, 64, 128, 256] {
            for per_thread in [1, 2, 3, 4] {
                for window in [None, Some(5)] {
                    let opts = gpu::GpuOptions {
                        launch: Some(Launch {
                            workgroup,
                            per_thread,
                            dispatch_seconds: 0.01,
                            window,
                            finite_block: [1, 4][(workgroup / 32 + per_thread) as usize % 2],
                        }),
                        max_chunk: Some(256),
                        ..Default::default()
                    };
                    let what = format!("{label}, workgroup {workgroup}, {per_thread} per invocation, window {window:?}");
                    let g = gpu::run_with::<f32>(ctx, plan, None, &opts)
                        .unwrap_or_else(|e| panic!("{what}: {e}"));
                    assert!(bits(&g.observations) == base32, "{what}: f32 bits differ");
                    if let (Some(b), true) = (&base64, per_thread % 2 == 1) {
                        let g = gpu::run_with::<f64>(ctx, plan, None, &opts)
                            .unwrap_or_else(|e| panic!("{what}: {e}"));
                        assert!(bits(&g.observations) == *b, "{what}: f64 bits differ");
                    }
                    tried += 1;
                }
            }
        }
    }
    assert_eq!(tried, 4 * 32);
    let too_wide = gpu::GpuOptions {
        launch: Some(Launch {
            workgroup: ctx.limits.max_compute_invocations_per_workgroup * 2,
            ..Launch::default()
        }),
        ..Default::default()
    };
    let e = gpu::run_with::<f32>(ctx, &plans[0].1, None, &too_wide)
        .err()
        .unwrap();
    assert!(e.to_string().contains("this adapter allows"), "{e}");
}

/// Both f32 logarithms (formulas' `log_r`, the indicators' `sample_log_r`)
/// give the CPU's values in their cases: NaN below 0 and for NaN (a
/// constant: lavapipe folded the ∞·0 it once was to 0), −∞ at 0, ∞ at ∞,
/// and the CPU's bits at the ends of the normal range.
#[test]
fn f32_log_cases_are_the_cpus() {
    let Some(ctx) = gpu() else { return };
    let xs = [
        -1.0,
        -f32::MIN_POSITIVE,
        -f32::MAX,
        f32::NEG_INFINITY,
        f32::NAN,
        0.0,
        -0.0,
        f32::INFINITY,
        f32::MIN_POSITIVE,
        f32::MAX,
        1.0,
        0.75,
    ];
    let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
    type Log = fn(f32) -> f32;
    let cpu: [(&str, Log); 2] = [("log_r", log_f32_bits), ("sample_log_r", sample_log_f32)];
    for (name, f) in cpu {
        let ys = accuracy::log_f32_on(ctx, name, &xs).unwrap();
        for (&x, &y) in xs.iter().zip(&ys) {
            assert!(same(y, f(x)), "{name} {x:e}: {y:e}, the CPU's {:e}", f(x));
        }
    }
}

/// The f64 `log_r` (every formula's logarithm) and `sample_log_r` (the
/// indicators', whose x = 2^k·m from the bits has m in [√½, √2)), each
/// with its split from the bits (SHADER_INT64) and by the ladder of
/// scalings, give the same bits, the CPU's (`log_f64_bits`) wherever x is
/// not subnormal (an adapter may flush those): around every power of two,
/// where the split changes, at the ends of the range and the cases, NaN
/// below 0 (a constant: lavapipe folded the ∞·0 it once was to 0).
#[test]
fn f64_log_forms_are_the_cpus_bits() {
    let Some(ctx) = gpu() else { return };
    if !ctx.shader_f64 {
        return;
    }
    let mut xs = vec![
        0.0,
        -0.0,
        1.0,
        f64::INFINITY,
        f64::NAN,
        f64::MAX,
        f64::MIN_POSITIVE,
        -1.0,
        -f64::MIN_POSITIVE,
        -f64::MAX,
        f64::NEG_INFINITY,
    ];
    for k in -1022..=1023 {
        let x = 2f64.powi(k);
        xs.extend([
            x,
            x.next_down(),
            x.next_up(),
            1.7 * x,
            std::f64::consts::SQRT_2 * x,
        ]);
    }
    // A spread of mantissas: 4·10⁴ bit patterns of positive normal numbers.
    let mut h: u64 = 0x9e37_79b9_7f4a_7c15;
    for _ in 0..40_000 {
        h = h
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let x = f64::from_bits(h >> 1);
        if x.is_normal() {
            xs.push(x);
        }
    }
    let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
    for name in ["log_r", "sample_log_r"] {
        let bits = accuracy::log_f64_on(ctx, name, true, &xs).unwrap();
        let ladder = accuracy::log_f64_on(ctx, name, false, &xs).unwrap();
        for ((&x, &a), &b) in xs.iter().zip(&bits).zip(&ladder) {
            assert!(
                same(a, b),
                "{name} {x:e}: {a:e} from the bits, {b:e} by the ladder"
            );
            assert!(
                same(a, log_f64_bits(x)),
                "{name} {x:e}: {a:e}, the CPU's {:e}",
                log_f64_bits(x)
            );
        }
    }
}

/// The f64 kernels' `pow2` and the logarithm's split x = 2^e·m from
/// 64-bit integers (adapters with SHADER_INT64) and without them (f32
/// powers of two, a ladder of scalings) give the same bits: the same
/// plans on a second device told it has no 64-bit integers (the FLI and
/// MEGNO take a logarithm at every sample).
#[test]
fn f64_forms_with_and_without_int64_give_the_same_bits() {
    let Some(ctx) = gpu() else { return };
    if !ctx.shader_f64 {
        return;
    }
    assert!(ctx.shader_int64, "lavapipe and NVIDIA have SHADER_INT64");
    let mut portable = gpu::GpuContext::on(Some(ctx.index)).unwrap();
    portable.shader_int64 = false;
    let plans = [
        Plan::new(&ensemble("van_der_pol", "s2").unwrap()).unwrap(),
        Plan::new(&shared_ensemble("spin_orbit", "yoshida6a").unwrap()).unwrap(),
        Plan::new(&ensemble("damped_oscillator", "triple_jump4").unwrap()).unwrap(),
        indicators(shared_ensemble("spin_orbit", "s2").unwrap()),
        indicators(ensemble("van_der_pol", "triple_jump4").unwrap()),
    ];
    /// `p` with one exponent, the FLI and MEGNO at every step.
    fn indicators(p: Problem) -> Plan {
        Plan::new(&with_indicators(p, 1, 1, 0.0, 400, 0.05)).unwrap()
    }
    for plan in &plans {
        let a = gpu::run::<f64>(ctx, plan, None).unwrap().observations;
        let b = gpu::run::<f64>(&portable, plan, None).unwrap().observations;
        assert!(format!("{a:?}") == format!("{b:?}"), "{:?}", plan.model);
    }
}

/// Without observers the GPU may test finiteness once per block of steps
/// and replay a block that ends non-finite step by step (`codegen::blocks`,
/// `Launch::finite_block`): the status is still the first non-finite step,
/// as on the CPU, whatever the block and the window (blocks cut short at a
/// window's end, windows shorter than a block), and the bits are the same
/// for every block and window.
#[test]
fn divergence_without_observers_stops_at_the_same_step() {
    let Some(ctx) = gpu() else { return };
    // Negative damping: growing as e^{|α|t/2}, overflowing at steps 10 to
    // 77 in f32 (so blocks end non-finite at every offset) and 80 to 370
    // in f64; positive α stays finite.
    let mut p = Problem::new(Model::DampedOscillator, "s2")
        .unwrap()
        .initial("q", Source::Const(1.0));
    let alpha = p.axis(
        "alpha",
        vec![
            -100.0, -90.0, -80.0, -60.0, -45.0, -30.0, -20.0, -12.0, 0.5, 1.0,
        ],
    );
    p = p.param("alpha", alpha);
    p.dt = Source::Const(0.1);
    p.steps = 400;
    let plan = Plan::new(&p).unwrap();
    /// Every block × window on the GPU: the CPU's status, one set of bits.
    fn against<R: reeb::models::Flows>(
        ctx: &gpu::GpuContext,
        plan: &Plan,
        c: &Observations<R>,
        tol: f64,
    ) {
        use reeb::backend::gpu::tuning::Launch;
        let mut first: Option<String> = None;
        for finite_block in [1, 3, 4] {
            for window in [None, Some(1), Some(3), Some(6), Some(13)] {
                let opts = gpu::GpuOptions {
                    max_chunk: None,
                    max_steps_per_dispatch: window,
                    launch: Some(Launch {
                        finite_block,
                        ..Launch::default()
                    }),
                };
                let g = gpu::run_with::<R>(ctx, plan, None, &opts)
                    .unwrap_or_else(|e| panic!("block {finite_block}, window {window:?}: {e}"))
                    .observations;
                assert_eq!(g.nonfinite_step, c.nonfinite_step);
                let bits = format!("{g:?}");
                match &first {
                    None => {
                        compare("divergence", &g, c, tol);
                        first = Some(bits);
                    }
                    Some(b) => assert!(bits == *b, "a window changed the bits"),
                }
            }
        }
    }
    let c = cpu::run::<f32>(&plan, None);
    let offsets: std::collections::BTreeSet<u32> = c
        .nonfinite_step
        .iter()
        .filter(|s| **s > 0)
        .map(|s| s % 4)
        .collect();
    assert_eq!(offsets.len(), 4, "diverging at {:?}", c.nonfinite_step);
    against::<f32>(ctx, &plan, &c, 2e-4);
    if ctx.shader_f64 {
        against::<f64>(ctx, &plan, &cpu::run::<f64>(&plan, None), 1e-10);
    }
}

/// The f32 exp's two forms evaluated on the adapter (`gpu::accuracy`):
/// reeb's polynomial is the CPU's function (within 2 ULP of its bits,
/// a third of them 1 or 2 apart: lavapipe contracts a·b + c into fma) and
/// within 2 ULP of exp; the adapter's exp2 form is
/// measured, and a device that took it by default keeps it only where it
/// is within `HARDWARE_EXP_ULP`. Lavapipe's exp2 is not: its error grows
/// with the argument, 3.6 ULP on [−1, 1] and 63 near ±85, as WGSL allows
/// (3 + 2|x| ULP), so there the device falls back to the polynomial.
#[test]
fn f32_exp_forms_on_the_adapter() {
    let Some(ctx) = gpu() else { return };
    let xs = accuracy::arguments(1 << 16);
    let exact = accuracy::exp_f32_on(ctx, ExpForm::Exact, &xs).unwrap();
    // Where the CPU's result is normal: the adapter may flush subnormals.
    for (&x, y) in xs
        .iter()
        .zip(&exact)
        .filter(|(&x, _)| exp_f32(x).is_normal())
    {
        let bits = |v: f32| v.to_bits() as i64;
        assert!((bits(*y) - bits(exp_f32(x))).abs() <= 2, "exp({x}): {y}");
    }
    let exact = accuracy::exp_f32_accuracy(ctx, ExpForm::Exact, 1 << 16).unwrap();
    assert!(exact.max_ulp <= 2.0, "{exact:?}");
    // The edges, in both forms: overflow to +∞ past 88.73 (at every
    // argument: ∞·(1 + e·ln 2) would be NaN for half of them), 0 far
    // below, NaN through.
    let mut edges: Vec<f32> = (0..2000).map(|i| 88.73 + 0.3 * i as f32 / 2000.0).collect();
    edges.extend([
        100.0,
        f32::INFINITY,
        -110.0,
        -1e30,
        f32::NEG_INFINITY,
        f32::NAN,
    ]);
    for form in [ExpForm::Exact, ExpForm::Hardware] {
        let ys = accuracy::exp_f32_on(ctx, form, &edges).unwrap();
        for (x, y) in edges.iter().zip(&ys) {
            let right = match *x {
                x if x.is_nan() => y.is_nan(),
                x if x > 0.0 => *y == f32::INFINITY,
                _ => y.to_bits() == 0,
            };
            assert!(right, "{form:?} exp({x}) = {y}");
        }
    }
    let hw = accuracy::exp_f32_accuracy(ctx, ExpForm::Hardware, 1 << 16).unwrap();
    eprintln!("hardware exp on {}: {hw:?}", ctx.describe());
    assert!(hw.max_ulp < 1e3, "{hw:?}");
    let mut device = gpu::GpuContext::on(Some(ctx.index)).unwrap();
    device.exp_f32 = ExpForm::Hardware;
    accuracy::settle_exp(&mut device);
    let kept = hw.max_ulp <= accuracy::HARDWARE_EXP_ULP;
    assert_eq!(device.exp_f32 == ExpForm::Hardware, kept, "{hw:?}");
}

/// Kernels with the adapter's exp2 form agree with the CPU, every model ×
/// s2 and kahanli8, and give the same bits for every launch (blocks of
/// steps included). Within 10⁻³, not the f32 tolerance 2·10⁻⁴: lavapipe's
/// exp2 is tens of ULP off for large arguments (see above); Kepler's
/// kahanli8 differs by 3.7·10⁻⁴ with it.
#[test]
fn hardware_exp_agrees_with_the_cpu() {
    let Some(ctx) = gpu() else { return };
    let mut device = gpu::GpuContext::on(Some(ctx.index)).unwrap();
    device.exp_f32 = ExpForm::Hardware;
    let blocks = gpu::GpuOptions {
        launch: Some(Launch {
            finite_block: 4,
            per_thread: 2,
            ..Launch::default()
        }),
        ..Default::default()
    };
    let mut checked = 0;
    for model in MODEL_NAMES {
        for scheme in ["s2", "kahanli8"] {
            let Some(p) = ensemble(model, scheme) else {
                continue;
            };
            let plan = Plan::new(&p).unwrap();
            let label = format!("{model} {scheme} hardware exp");
            let g = gpu::run::<f32>(&device, &plan, None).unwrap();
            let c = cpu::run::<f32>(&plan, None);
            compare(&label, &g.observations, &c, 1e-3);
            let mut q = p.clone();
            let final_vars = q.observers.final_vars.clone();
            q.observers = Default::default();
            q.observers.final_vars = final_vars;
            let final_only = Plan::new(&q).unwrap();
            assert!(generate(&final_only, Precision::F32).unwrap().has_blocks());
            let a = gpu::run::<f32>(&device, &final_only, None).unwrap();
            let b = gpu::run_with::<f32>(&device, &final_only, None, &blocks).unwrap();
            assert!(
                format!("{:?}", a.observations) == format!("{:?}", b.observations),
                "{label}: launches"
            );
            checked += 1;
        }
    }
    assert!(checked >= 10, "{checked}");
}

/// The tangent the GPU builds where the ensemble shares its time terms
/// reads them from its time table (`TangentStep::tabled`): the same map,
/// bit for bit, as the tangent that computes them, at every stage of a
/// composition and for every model with time ops.
#[test]
fn a_tangent_reading_the_table_is_the_tangent_computing_it() {
    let mut tabled = vec![];
    for model in [
        "damped_oscillator",
        "kepler",
        "lane_emden",
        "van_der_pol",
        "spin_orbit",
    ] {
        for scheme in ["s2", "triple_jump4"] {
            let plan = Plan::new(&problem(model, scheme).expect("a problem")).unwrap();
            let Some(tt) = TimeTable::of(&plan) else {
                continue;
            };
            let spec = plan.step_spec();
            let d = TangentStep::new(&spec, 1).unwrap().space.len();
            let computed = TangentStep::new(&spec, d).unwrap();
            let read = TangentStep::tabled(&spec, d).unwrap();
            let n = 7;
            let rows: Vec<f64> = tt.fill::<f64>(&plan, n, 1);
            let l = lane_at(&plan, &[]);
            let row = |stage: usize, term: usize| rows[stage * 4 * tt.vec4s() + term];
            let columns = |t: &TangentStep| -> Vec<u64> {
                let cols = columns_of(t, &l, n, row).concat();
                cols.iter().map(|x| x.to_bits()).collect()
            };
            let terms = read.inputs.iter();
            let stages = terms.filter_map(|i| match i {
                TangentInput::TimeTerm { stage, .. } => Some(*stage),
                _ => None,
            });
            assert_eq!(
                stages.max().map(|s| s + 1),
                Some(tt.stages()),
                "{model} {scheme}"
            );
            assert_eq!(columns(&computed), columns(&read), "{model} {scheme}");
            tabled.push(format!("{model} {scheme}"));
        }
    }
    assert!(tabled.len() >= 4, "tables for {tabled:?}");
}
