//! Tangent maps: the exact Jacobian of one numerical step, from the ops'
//! one source (`plan/tangent.rs`), against central finite differences of
//! the compiled step, for every model and scheme.

use reeb::models::spec::Op;
use reeb::models::{scalar_fn, Model, MODEL_NAMES};
use reeb::plan::problem::{Problem, Source};
use reeb::plan::scheme::SCHEME_NAMES;
use reeb::plan::tangent::TangentStep;
use reeb::plan::Plan;
use reeb::verify::indicators::{
    compiled_columns, difference_columns, formula_plans, full_problem, lane_at, start,
    tangent_columns, with_indicators,
};

const C: fn(f64) -> Source = Source::Const;

fn problem(name: &str, scheme: &str) -> Problem {
    full_problem(name, scheme).unwrap()
}

#[test]
fn tangents_are_finite_differences_of_the_step() {
    let (mut checked, mut refused) = (0, vec![]);
    for scheme in SCHEME_NAMES {
        let built_in = MODEL_NAMES
            .iter()
            .filter_map(|m| Plan::new(&problem(m, scheme)).ok());
        for plan in built_in.chain(formula_plans(scheme, 10, "")) {
            let what = format!("{} {scheme}", plan.model.name());
            let x: Vec<(&str, f64)> = plan.vars.iter().map(|v| (*v, start(v))).collect();
            let n = 3;
            let (space, cols) = match tangent_columns(&plan, &x, n) {
                Ok(j) => j,
                // Only a comparison method may have no tangent (Lane–Emden's
                // RK4 and leapfrog branch on t = 0), refused by name.
                Err(e) if ["rk4", "leapfrog", "variational1", "variational2"].contains(scheme) => {
                    assert!(e.message.contains(&format!("`{scheme}`")), "{what}: {e}");
                    refused.push(what);
                    continue;
                }
                Err(e) => panic!("{what}: {e}"),
            };
            let fd = difference_columns(&plan, &x, &space, n, 1e-6);
            for (k, var) in space.iter().enumerate() {
                for (j, out) in space.iter().enumerate() {
                    let (got, fd) = (cols[k][j], fd[k][j]);
                    assert!(
                        (got - fd).abs() <= 1e-6 * fd.abs().max(1.0),
                        "{what}: d{out}/d{var} = {got}, finite differences {fd}"
                    );
                }
            }
            checked += 1;
        }
    }
    // 7 built-in and 3 formula models × 12 splitting schemes, less the
    // comparison methods a model does not offer or refuses.
    assert!(checked >= 130, "{checked} model × scheme pairs");
    assert!(refused.len() <= 4, "refused: {refused:?}");
    eprintln!("{checked} pairs checked; refused: {refused:?}");
}

/// The CPU's compiled tangent step (`backend/cpu/tangent.rs`, the ops'
/// generated tangents) is the tangent program's map to round-off, for
/// every built-in model whose ops all have one × every splitting scheme
/// (in the default piece order), at the best level this CPU runs;
/// Lane–Emden (a power by a per-trajectory index) keeps the tape.
#[test]
fn compiled_tangents_are_the_tangent_programs() {
    let mut checked = 0;
    for scheme in SCHEME_NAMES {
        for m in MODEL_NAMES {
            let Ok(plan) = Plan::new(&problem(m, scheme)) else {
                continue;
            };
            let x: Vec<(&str, f64)> = plan.vars.iter().map(|v| (*v, start(v))).collect();
            let Ok((space, cols)) = tangent_columns(&plan, &x, 3) else {
                continue;
            };
            let Some(compiled) = compiled_columns(&plan, &x, &space, 3) else {
                let splitting = plan.stages.is_some();
                let avx2 = reeb::backend::cpu::kernels::isa() != reeb::num::isa::Isa::Baseline;
                assert!(
                    *m == "lane_emden" || !splitting || !avx2,
                    "{m} {scheme}: no compiled tangent"
                );
                continue;
            };
            for (a, b) in cols.iter().flatten().zip(compiled.iter().flatten()) {
                assert!(
                    (a - b).abs() <= 1e-12 * a.abs().max(1.0),
                    "{m} {scheme}: tape {a}, compiled {b}"
                );
            }
            checked += 1;
        }
    }
    assert!(checked >= 60, "{checked} model × scheme pairs");
    eprintln!("{checked} pairs: compiled = tape");
}

/// The tangent spaces of the README: (q, p) for mechanical models, (q, s)
/// for Liénard systems, everything for quadratic_s.
#[test]
fn tangent_spaces_are_the_dynamical_phase_spaces() {
    let space = |name: &str| {
        let plan = Plan::new(&problem(name, "s2")).unwrap();
        TangentStep::new(&plan.step_spec(), 1).unwrap().space
    };
    assert_eq!(space("damped_oscillator"), ["q", "p"]);
    assert_eq!(space("van_der_pol"), ["q", "s"]);
    assert_eq!(space("lienard"), ["q", "s"]);
    assert_eq!(space("kepler"), ["q1", "q2", "p1", "p2"]);
    assert_eq!(space("lane_emden"), ["q", "p"]);
    assert_eq!(space("spin_orbit"), ["q", "p"]);
    assert_eq!(space("quadratic_s"), ["q", "p", "s"]);
}

// ---- indicators: oracles ----

use crate::common;

use reeb::backend::{cpu, gpu};
use reeb::plan::observations::Observations;
use reeb::plan::observers::{AverageObs, TrajectoryObs};
use reeb::reference::variational::flow_exponents;

/// `problem` asking for `k` exponents (re-orthonormalised every `every`
/// steps), FLI and MEGNO, over `steps` steps of `dt`.
fn indicators(p: Problem, k: usize, every: u64, steps: u64, dt: f64) -> Plan {
    Plan::new(&with_indicators(p, k, every, 0.0, steps, dt)).unwrap()
}

fn exponents(o: &Observations<f64>, i: usize) -> Vec<f64> {
    o.lyapunov[i * o.exponents..(i + 1) * o.exponents].to_vec()
}

/// The linear damped oscillator's step is a constant matrix M: the
/// exponents are ln|eig M|/dt, and λ₁ + λ₂ = ln det M/dt = −α for any
/// horizon (the A piece scales p by e^{−τα}, the others preserve area).
#[test]
fn linear_damped_oscillator_exponents_are_the_step_eigenvalues() {
    let alpha = 3.0; // overdamped: two real eigenvalues
    let p = Problem::new(Model::from_name("damped_oscillator").unwrap(), "s2")
        .unwrap()
        .param("alpha", C(alpha))
        .initial("q", C(1.0));
    let dt = 0.05;
    let plan = indicators(p, 2, 3, 4000, dt);
    let o = cpu::run::<f64>(&plan, None);
    let l = exponents(&o, 0);
    // M from the compiled step (finite differences are exact for a linear map).
    let x = [("q", 0.3), ("p", -0.2), ("s", 0.0)];
    let (space, _) = tangent_columns(&plan, &x, 0).unwrap();
    let cols = difference_columns(&plan, &x, &space, 0, 1e-6);
    let (a, b, c, d) = (cols[0][0], cols[1][0], cols[0][1], cols[1][1]);
    let (tr, det) = (a + d, a * d - b * c);
    let disc = (tr * tr / 4.0 - det).sqrt();
    let eig = [tr / 2.0 + disc, tr / 2.0 - disc].map(|e: f64| e.abs().ln() / dt);
    assert!(
        (l[0] + l[1] + alpha).abs() < 1e-12 * alpha,
        "λ₁ + λ₂ = {} (−α = {})",
        l[0] + l[1],
        -alpha
    );
    for (got, want) in l.iter().zip(eig) {
        // Finite time: the second exponent converges like 1/t.
        assert!((got - want).abs() < 2e-3, "λ = {l:?}, ln|eig|/dt = {eig:?}");
    }
}

/// Van der Pol: the (q, s) step's determinant is the A pieces' e^{τε(1−q²)},
/// so λ₁ + λ₂ = (1/t) Σ τ ε(1 − q²) over the A pieces of the run, summed
/// here by the compiled step itself.
#[test]
fn van_der_pol_exponents_obey_the_sum_rule() {
    let eps = 1.5;
    let p = Problem::new(Model::from_name("van_der_pol").unwrap(), "triple_jump4")
        .unwrap()
        .param("epsilon", C(eps))
        .param("forcing_amplitude", C(0.3))
        .param("forcing_frequency", C(1.1))
        .initial("q", C(0.5));
    let (dt, steps) = (0.02, 5000);
    let plan = indicators(p, 2, 5, steps, dt);
    let o = cpu::run::<f64>(&plan, None);
    let l = exponents(&o, 0);
    let mut lane = lane_at(&plan, &[("q", 0.5), ("s", 0.0)]);
    let mut contraction = 0.0;
    for n in 0..steps {
        let (t0, h) = (lane.get("t0").unwrap(), lane.get("dt").unwrap());
        for op in &plan.ops {
            match *op {
                Op::Tau(c) => *lane.get_mut("tau").unwrap() = c * h,
                Op::Time(c) => *lane.get_mut("t").unwrap() = t0 + n as f64 * h + c * h,
                Op::Call(name) => {
                    if name == "van_der_pol_a_s" {
                        let (q, tau) = (lane.q, lane.tau);
                        contraction += tau * eps * (1.0 - q * q);
                    }
                    scalar_fn::<f64>(name).unwrap()(&mut lane);
                }
            }
        }
    }
    let want = contraction / (steps as f64 * dt);
    let got = l[0] + l[1];
    assert!(
        (got - want).abs() <= 1e-9 * want.abs(),
        "λ₁ + λ₂ = {got}, sum rule {want}"
    );
}

/// The exponents of the numerical maps converge to the flow's (variational
/// equations integrated by DOP853) as dt → 0: the forced van der Pol on its
/// regular attractor (A = ε = 5, ω = 2.45).
#[test]
fn map_exponents_converge_to_the_flows() {
    let (t, skip) = (300.0, 0.2);
    let p = |scheme: &str| {
        Problem::new(Model::VanDerPol, scheme)
            .unwrap()
            .param("epsilon", C(5.0))
            .param("forcing_amplitude", C(5.0))
            .param("forcing_frequency", C(2.45))
            .initial("q", C(2.0))
            .initial("s", C(2.0))
    };
    let map = |scheme: &str, dt: f64| {
        let plan = Plan::new(&with_indicators(
            p(scheme),
            2,
            10,
            skip,
            (t / dt) as u64,
            dt,
        ))
        .unwrap();
        cpu::run::<f64>(&plan, None).lyapunov
    };
    let plan = Plan::new(&with_indicators(p("s2"), 2, 10, skip, 100, 0.01)).unwrap();
    let flow = flow_exponents(&plan, 0, 2, (t, skip * t, 1.0), 1e-10).unwrap();
    let error = |l: &[f64]| (l[0] - flow[0]).abs().max((l[1] - flow[1]).abs());
    let coarse = error(&map("s2", 0.02));
    let fine = error(&map("triple_jump4", 0.005));
    eprintln!("flow {flow:?}: s2 at 0.02 off by {coarse:.2e}, triple_jump4 at 0.005 by {fine:.2e}");
    assert!(flow[0] < 0.0 && flow[0] + flow[1] < 0.0, "{flow:?}");
    assert!(
        fine < 2e-3 && fine < coarse / 10.0,
        "{fine} against {coarse}"
    );
}

/// On the limit cycle the largest exponent vanishes (the flow's direction).
#[test]
fn van_der_pol_limit_cycle_has_a_zero_exponent() {
    let p = Problem::new(Model::from_name("van_der_pol").unwrap(), "s2")
        .unwrap()
        .param("epsilon", C(1.0))
        .initial("q", C(2.0));
    let plan = indicators(p, 1, 10, 200_000, 0.01);
    let o = cpu::run::<f64>(&plan, None);
    assert!(
        o.lyapunov[0].abs() < 5e-3,
        "λ₁ = {} by t = 2000",
        o.lyapunov[0]
    );
}

/// Both backends give the same indicators (f64, non-chaotic orbits).
#[test]
fn indicators_agree_between_cpu_and_gpu() {
    let Some(ctx) = common::gpu() else { return };
    for (name, k) in [
        ("damped_oscillator", 2),
        ("van_der_pol", 2),
        ("kepler", 4),
        ("spin_orbit", 2),
        ("quadratic_s", 3),
    ] {
        let mut p = common::problem(name, "triple_jump4").unwrap();
        p.observers.trajectory = Some(TrajectoryObs {
            every: 100,
            vars: vec!["t".into()],
        });
        let plan = indicators(p.clone(), k, 4, 2000, 0.01);
        let c = cpu::run::<f64>(&plan, None);
        let g = gpu::run::<f64>(ctx, &plan, None).unwrap().observations;
        assert_eq!(c.frames, 21);
        // The FLI alone, whose GPU sample leaves MEGNO's sums out: the
        // same FLI, to the bit.
        let mut alone = with_indicators(p, k, 4, 0.0, 2000, 0.01);
        alone.observers.megno = None;
        let a = gpu::run::<f64>(ctx, &Plan::new(&alone).unwrap(), None)
            .unwrap()
            .observations;
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert!(a.megno.is_empty(), "{name}");
        assert_eq!(bits(&a.fli), bits(&g.fli), "{name} FLI alone");
        assert_eq!(
            bits(&a.trajectory_fli),
            bits(&g.trajectory_fli),
            "{name} FLI alone"
        );
        for (what, a, b) in [
            ("lyapunov", &c.lyapunov, &g.lyapunov),
            ("fli", &c.fli, &g.fli),
            ("megno", &c.megno, &g.megno),
            (
                "trajectory_lyapunov",
                &c.trajectory_lyapunov,
                &g.trajectory_lyapunov,
            ),
            ("trajectory_fli", &c.trajectory_fli, &g.trajectory_fli),
            ("trajectory_megno", &c.trajectory_megno, &g.trajectory_megno),
        ] {
            assert_eq!(a.len(), b.len(), "{name} {what}");
            assert!(!a.is_empty(), "{name} {what}");
            for (x, y) in a.iter().zip(b.iter()) {
                assert!(
                    (x - y).abs() <= 1e-9 * x.abs().max(1e-3) || x.is_nan() && y.is_nan(),
                    "{name} {what}: CPU {x} GPU {y}"
                );
            }
        }
        running_values_end_at_the_outputs(name, &c);
    }
}

/// The last trajectory frame (the run's last step) holds each indicator's
/// output; the first (step 0) holds none yet.
fn running_values_end_at_the_outputs(name: &str, o: &Observations<f64>) {
    let (f, k) = (o.frames, o.exponents);
    for i in 0..o.n {
        let last = (i * f + f - 1) * k;
        assert_eq!(
            o.trajectory_lyapunov[last..last + k],
            o.lyapunov[i * k..(i + 1) * k],
            "{name}"
        );
        assert_eq!(o.trajectory_fli[i * f + f - 1], o.fli[i], "{name}");
        assert_eq!(o.trajectory_megno[i * f + f - 1], o.megno[i], "{name}");
        assert!(o.trajectory_fli[i * f].is_nan() && o.trajectory_lyapunov[i * f * k].is_nan());
    }
}

/// Bad indicator settings are refused before any work, at their line.
#[test]
fn bad_indicator_settings_are_refused_at_their_field() {
    let dir = std::env::temp_dir().join(format!("reeb-tangent-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let base = "name = \"x\"\nmodel = \"van_der_pol\"\n[params]\nepsilon = 1.0\n[integrator]\nscheme = \"s2\"\ndt = 0.01\nsteps = 100\n[output]\n";
    for (line, field) in [
        (
            "lyapunov = { vectors = 3 }",
            "output.lyapunov.vectors: 3 is more than the tangent dimension 2",
        ),
        (
            "lyapunov = { vectors = 0 }",
            "output.lyapunov.vectors: must be at least 1",
        ),
        (
            "lyapunov = { every = 0 }",
            "output.lyapunov.every: must be at least 1",
        ),
        (
            "lyapunov = { skip = 1.0 }",
            "output.lyapunov.skip: must be in [0, 1)",
        ),
        (
            "fli = { every = 101 }",
            "output.fli.every: 101 is more than the 100 steps",
        ),
        (
            "megno = { every = 0 }",
            "output.megno.every: must be at least 1",
        ),
        (
            "fli = { every = 2 }\nmegno = { every = 3 }",
            "output.megno.every: 3 differs",
        ),
    ] {
        let path = dir.join("s.toml");
        std::fs::write(&path, format!("{base}{line}\n")).unwrap();
        let e = reeb::scene::Scene::load(&path).unwrap_err().to_string();
        assert!(e.contains(":10: ") || e.contains(":11: "), "{line}: {e}");
        assert!(e.contains(field), "{line}: {e}");
    }
    let path = dir.join("le.toml");
    let text = "name = \"x\"\nmodel = \"lane_emden\"\n[params]\nindex = 3\n[integrator]\nscheme = \"rk4\"\ndt = 0.01\nsteps = 100\n[output]\nlyapunov = true\n";
    std::fs::write(&path, text).unwrap();
    let e = reeb::scene::Scene::load(&path).unwrap_err().to_string();
    assert!(
        e.contains("le.toml:10: output.lyapunov: `rk4` has no tangent map"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `stop = "fli > 20"` ends the orbits known to be chaotic, at the same
/// step on both backends.
#[test]
fn a_stop_condition_reads_the_fli() {
    let dir = std::env::temp_dir().join(format!("reeb-tangent-stop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string("scenes/spin_orbit_fli.toml")
        .unwrap()
        .replace(
            "fli = { every = 20 }",
            "fli = { every = 20 }\nstop = \"fli > 20\"",
        )
        .replace("320]", "6]");
    let path = dir.join("s.toml");
    std::fs::write(&path, text).unwrap();
    let scene = reeb::scene::Scene::load(&path).unwrap();
    let plans = scene.sub_runs().unwrap();
    let plan = &plans[0].plan;
    let c = cpu::run::<f64>(plan, None);
    let stopped: Vec<usize> = (0..c.n).filter(|i| c.stop_step[*i] != 0).collect();
    assert!(
        !stopped.is_empty() && stopped.len() < c.n,
        "{:?}",
        c.stop_step
    );
    for i in 0..c.n {
        let chaotic = c.fli[i] > 20.0;
        assert_eq!(chaotic, c.stop_step[i] != 0, "orbit {i}: FLI {}", c.fli[i]);
    }
    if let Some(ctx) = common::gpu() {
        let g = gpu::run::<f64>(ctx, plan, None).unwrap().observations;
        assert_eq!(g.stop_step, c.stop_step);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Where the plan integrates no optional variable, the compiled tangent
/// step takes the step itself (`backend/cpu/tangent.rs`): the state is
/// bitwise the plain run's. With the optional variable (van der Pol's p),
/// the fused stages take it, and in another piece order the tape carries
/// the vectors: the state is the plain run's there too. On the GPU, to
/// round-off.
#[test]
fn indicators_leave_the_state_bitwise_unchanged() {
    let cases = [
        ("damped_oscillator", false, None),
        ("van_der_pol", false, None),
        ("van_der_pol", true, None),
        ("van_der_pol", false, Some("ABCBA")),
        ("kepler", false, None),
        ("spin_orbit", false, None),
        ("quadratic_s", false, None),
    ];
    for (name, optional, order) in cases {
        let mut p = common::problem(name, "triple_jump4").unwrap();
        p.order = order.map(String::from);
        let spec = p.model.spec();
        let vars: Vec<String> = spec
            .vars
            .iter()
            .filter(|v| optional || Some(**v) != spec.optional_var)
            .map(|v| v.to_string())
            .collect();
        p.observers.final_vars = vars.iter().map(|v| v.as_str().into()).collect();
        let mut plain = p.clone();
        (plain.dt, plain.steps) = (C(0.01), 300);
        let (plain, with) = (Plan::new(&plain).unwrap(), indicators(p, 1, 1, 300, 0.01));
        let a = cpu::run::<f64>(&plain, None);
        let b = cpu::run::<f64>(&with, None);
        for v in &vars {
            let bits = |o: &Observations<f64>| -> Vec<u64> {
                o.final_of(v).unwrap().iter().map(|x| x.to_bits()).collect()
            };
            assert_eq!(bits(&a), bits(&b), "{name} {order:?} {v}");
        }
        assert!(b.fli.iter().all(|x| x.is_finite()), "{name} {order:?}");
        // On the GPU the tangent program may move the state
        // (`TangentStep::with_state`): the plain run's to round-off.
        if let Some(ctx) = common::gpu() {
            let a = gpu::run::<f64>(ctx, &plain, None).unwrap().observations;
            let b = gpu::run::<f64>(ctx, &with, None).unwrap().observations;
            for v in &vars {
                let (x, y) = (a.final_of(v).unwrap(), b.final_of(v).unwrap());
                for (x, y) in x.iter().zip(y) {
                    let tol = 1e-12 * x.abs().max(1.0);
                    assert!((x - y).abs() <= tol, "{name} {order:?} {v}: {x} {y}");
                }
            }
        }
    }
}

fn bits<R: Copy + Into<f64>>(v: &[R]) -> Vec<u64> {
    v.iter().map(|x| (*x).into().to_bits()).collect()
}

/// Asserts that `runs` and `steps` give the same indicators, bit for bit;
/// returns how many trajectories diverged.
fn same<R: reeb::models::Flows + Into<f64>>(name: &str, runs: &Plan, steps: &Plan) -> usize {
    let name = &format!("{name} {}", std::any::type_name::<R>());
    let a = cpu::run::<R>(runs, None);
    let b = cpu::run::<R>(steps, None);
    assert_eq!(a.nonfinite_step, b.nonfinite_step, "{name}");
    assert_eq!(bits(&a.lyapunov), bits(&b.lyapunov), "{name}: exponents");
    assert_eq!(bits(&a.fli), bits(&b.fli), "{name}: FLI");
    assert_eq!(bits(&a.megno), bits(&b.megno), "{name}: MEGNO");
    assert_eq!(bits(&a.trajectory_fli), bits(&b.trajectory_fli), "{name}");
    assert_eq!(
        bits(&a.trajectory_megno),
        bits(&b.trajectory_megno),
        "{name}"
    );
    assert_eq!(
        bits(&a.trajectory_lyapunov),
        bits(&b.trajectory_lyapunov),
        "{name}"
    );
    assert!(
        a.fli.iter().any(|x| Into::<f64>::into(*x).is_finite()),
        "{name}"
    );
    a.nonfinite_step.iter().filter(|s| **s != 0).count()
}

/// `p` with indicators (`k` exponents, none for 0; the FLI; MEGNO if
/// `megno`) taken by runs of steps, and the same forced step by step by a
/// time average (an observer of every step).
fn runs_and_steps(p: Problem, k: usize, megno: bool, steps: u64, dt: f64) -> (Plan, Plan) {
    let var = p.model.spec().vars[0];
    let mut runs = with_indicators(p, k.max(1), 1, 0.1, steps, dt);
    if !megno {
        runs.observers.megno = None;
    }
    if k == 0 {
        runs.observers.lyapunov = None;
    }
    let mut by_step = runs.clone();
    by_step.observers.average = Some(AverageObs {
        vars: vec![var.into()],
        skip: 0.0,
    });
    (Plan::new(&runs).unwrap(), Plan::new(&by_step).unwrap())
}

fn takes_runs(plan: &Plan) -> bool {
    let p = cpu::program::Program::<f64>::new(plan, cpu::isa(), true);
    p.indicators.as_ref().is_some_and(|i| i.takes_runs()) && !plan.others_observe_every_step()
}

/// Where the tangent and the samples are compiled and no other observer
/// looks at every step, the CPU takes runs of steps in one call
/// (`IndicatorTapes::steps`, the vectors in scratch lanes throughout). It
/// computes the bits of the step-by-step path, which a time average (an
/// observer of every step) forces here: two exponents, FLI and MEGNO
/// (three vectors, so two passes), trajectory frames, 100 trajectories
/// (a padded second block), some of them diverging mid-run; f32 and f64.
#[test]
fn runs_of_steps_are_the_steps_one_by_one() {
    let mut diverged = 0;
    for name in [
        "damped_oscillator",
        "van_der_pol",
        "kepler",
        "spin_orbit",
        "quadratic_s",
    ] {
        let mut p = problem(name, "triple_jump4");
        let var = p.model.spec().vars[0];
        // Every 37th trajectory starts far out, where the nonlinear models'
        // steps overflow.
        let values = (0..100)
            .map(|i| match i % 37 == 5 {
                true => 1e200,
                false => 0.3 + 0.01 * f64::from(i),
            })
            .collect();
        let q0 = p.axis(var, values);
        p = p.initial(var, q0);
        p.observers.trajectory = Some(TrajectoryObs {
            every: 60,
            vars: vec![var.into()],
        });
        // One exponent, and the FLI without MEGNO: their samples wait while
        // the vectors stay in the band. Without exponents, the FLI alone
        // and with MEGNO: one vector, the chaos sample's.
        for (k, megno) in [(1, false), (2, true), (0, true), (0, false)] {
            let (runs, steps) = runs_and_steps(p.clone(), k, megno, 400, 0.01);
            let avx2 = cpu::isa() != cpu::Isa::Baseline;
            assert_eq!(takes_runs(&runs), avx2, "{name} takes runs of steps");
            assert!(!takes_runs(&steps), "{name}");
            diverged += same::<f64>(name, &runs, &steps);
            diverged += same::<f32>(name, &runs, &steps);
        }
    }
    assert!(diverged > 0, "some trajectory diverges");
}

/// A damped oscillator's vectors shrink like e^{−αt/2}: over t = 300 the
/// Lyapunov and FLI vectors leave the band where their samples may wait
/// (‖u‖² in [2⁻³⁹, 2⁵⁹]) a few times and are brought back; the bits are
/// still those of sampling every step. So with MEGNO, whose samples in
/// the band take their logarithms step by step and their sums later.
#[test]
fn deferred_samples_are_taken_where_the_vector_leaves_the_band() {
    let p = Problem::new(
        Model::from_name("damped_oscillator").unwrap(),
        "triple_jump4",
    )
    .unwrap()
    .param("alpha", C(1.0))
    .initial("q", C(1.0));
    // One exponent with MEGNO, the FLI and MEGNO alone (one vector), one
    // exponent without MEGNO.
    for (k, megno) in [(1, true), (0, true), (1, false)] {
        let (runs, steps) = runs_and_steps(p.clone(), k, megno, 3000, 0.1);
        same::<f64>("damped_oscillator", &runs, &steps);
        same::<f32>("damped_oscillator", &runs, &steps);
    }
    let (runs, _) = runs_and_steps(p, 1, false, 3000, 0.1);
    let o = cpu::run::<f64>(&runs, None);
    assert!((o.lyapunov[0] + 0.5).abs() < 1e-2, "λ₁ = {}", o.lyapunov[0]);
}
