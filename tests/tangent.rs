//! Tangent maps: the exact Jacobian of one numerical step, from the ops'
//! one source (`plan/tangent.rs`), against central finite differences of
//! the compiled step, for every model and scheme.

use reeb::models::lanes::Lane;
use reeb::models::spec::Op;
use reeb::models::{scalar_fn, Model, MODEL_NAMES};
use reeb::num::formula::tape::Tape;
use reeb::num::isa::Isa;
use reeb::plan::problem::{Problem, Source};
use reeb::plan::scheme::SCHEME_NAMES;
use reeb::plan::tangent::{TangentInput, TangentStep};
use reeb::plan::Plan;

const C: fn(f64) -> Source = Source::Const;

/// A problem of every model with every term switched on (forcing, time
/// dependence, damping), at `scheme`.
fn problem(name: &str, scheme: &str) -> Problem {
    let p = Problem::new(Model::from_name(name).unwrap(), scheme).unwrap();
    let mut p = match name {
        "damped_oscillator" => p
            .param("alpha", C(0.3))
            .param("forcing_amplitude", C(0.5))
            .param("forcing_frequency", C(1.3)),
        "van_der_pol" => p
            .param("epsilon", C(1.3))
            .param("forcing_amplitude", C(0.4))
            .param("forcing_frequency", C(1.1)),
        "kepler" => p.param("alpha", C(0.05)).param("theta", C(2.0)),
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
    p
}

/// A state to differentiate at, by variable.
fn start(var: &str) -> f64 {
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

/// The plan's inputs in one lane, the state at `x`.
fn lane(plan: &Plan, x: &[(&str, f64)]) -> Lane<f64> {
    let mut l = Lane::<f64>::default();
    for (name, source) in &plan.bindings {
        if let Source::Const(v) = source {
            *l.get_mut(name).unwrap() = *v;
        }
    }
    for (v, value) in x {
        *l.get_mut(v).unwrap() = *value;
    }
    l
}

/// Step number `n` of the plan as compiled (the scalar ops).
fn step(plan: &Plan, l: &mut Lane<f64>, n: u64) {
    let (t0, dt) = (l.get("t0").unwrap(), l.get("dt").unwrap());
    for op in &plan.ops {
        match *op {
            Op::Tau(c) => *l.get_mut("tau").unwrap() = c * dt,
            Op::Time(c) => *l.get_mut("t").unwrap() = t0 + n as f64 * dt + c * dt,
            Op::Call(name) => scalar_fn::<f64>(name).unwrap()(l),
        }
    }
}

/// The tangent program applied to the unit vectors (its columns).
fn jacobian(plan: &Plan, x: &[(&str, f64)], n: u64) -> (Vec<&'static str>, Vec<Vec<f64>>) {
    let space = TangentStep::new(&plan.step_spec(), 1).unwrap().space;
    let d = space.len();
    let t = TangentStep::new(&plan.step_spec(), d).unwrap();
    let l = lane(plan, x);
    let inputs: Vec<[f64; 1]> = t
        .inputs
        .iter()
        .map(|i| match *i {
            TangentInput::Lane(name) => [l.get(name).unwrap()],
            TangentInput::Step => [n as f64],
            TangentInput::Deviation { k, j } => [if k == j { 1.0 } else { 0.0 }],
        })
        .collect();
    let tape = Tape::<f64>::new(&t.program, |_| false);
    let mut regs = vec![[0.0; 1]; tape.registers];
    tape.run(&mut regs, &inputs[..], Isa::Baseline);
    let cols = (0..d)
        .map(|k| (0..d).map(|j| tape.output(&regs, k * d + j)[0]).collect())
        .collect();
    (t.space, cols)
}

#[test]
fn tangents_are_finite_differences_of_the_step() {
    let (mut checked, mut refused) = (0, vec![]);
    for name in MODEL_NAMES {
        for scheme in SCHEME_NAMES {
            let Ok(plan) = Plan::new(&problem(name, scheme)) else {
                continue; // a method this model does not offer
            };
            let what = format!("{name} {scheme}");
            let x: Vec<(&str, f64)> = plan.vars.iter().map(|v| (*v, start(v))).collect();
            let n = 3;
            let (space, cols) = match TangentStep::new(&plan.step_spec(), 1) {
                Ok(_) => jacobian(&plan, &x, n),
                // Only a comparison method may have no tangent (Lane–Emden's
                // RK4 and leapfrog branch on t = 0), refused by name.
                Err(e) if ["rk4", "leapfrog", "variational1", "variational2"].contains(scheme) => {
                    assert!(e.message.contains(&format!("`{scheme}`")), "{what}: {e}");
                    refused.push(what);
                    continue;
                }
                Err(e) => panic!("{what}: {e}"),
            };
            for (k, var) in space.iter().enumerate() {
                let h = 1e-6;
                let moved = |sign: f64| {
                    let y: Vec<(&str, f64)> = x
                        .iter()
                        .map(|(v, val)| (*v, if v == var { val + sign * h } else { *val }))
                        .collect();
                    let mut l = lane(&plan, &y);
                    step(&plan, &mut l, n);
                    l
                };
                let (up, down) = (moved(1.0), moved(-1.0));
                for (j, out) in space.iter().enumerate() {
                    let fd = (up.get(out).unwrap() - down.get(out).unwrap()) / (2.0 * h);
                    let got = cols[k][j];
                    assert!(
                        (got - fd).abs() <= 1e-6 * fd.abs().max(1.0),
                        "{what}: d{out}/d{var} = {got}, finite differences {fd}"
                    );
                }
            }
            checked += 1;
        }
    }
    // 7 models × 12 splitting schemes, and the methods each model offers.
    assert!(checked >= 7 * 12 + 20, "{checked} model × scheme pairs");
    assert!(refused.len() <= 4, "refused: {refused:?}");
    eprintln!("{checked} pairs checked; refused: {refused:?}");
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

mod common;

use reeb::backend::{cpu, gpu};
use reeb::plan::observations::Observations;
use reeb::plan::observers::{LyapunovObs, SampledObs};

/// `problem` asking for `k` exponents (re-orthonormalised every `every`
/// steps), FLI and MEGNO, over `steps` steps of `dt`.
fn indicators(mut p: Problem, k: usize, every: u64, steps: u64, dt: f64) -> Plan {
    p.dt = C(dt);
    p.steps = steps;
    p.observers.lyapunov = Some(LyapunovObs {
        vectors: k,
        every,
        skip: 0.0,
    });
    p.observers.fli = Some(SampledObs { every });
    p.observers.megno = Some(SampledObs { every });
    Plan::new(&p).unwrap()
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
    let (_, cols) = jacobian(&plan, &x, 0);
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
    let mut lane = lane(&plan, &[("q", 0.5), ("s", 0.0)]);
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
        let plan = indicators(
            common::problem(name, "triple_jump4").unwrap(),
            k,
            4,
            2000,
            0.01,
        );
        let c = cpu::run::<f64>(&plan, None);
        let g = gpu::run::<f64>(ctx, &plan, None).unwrap().observations;
        for (what, a, b) in [
            ("lyapunov", &c.lyapunov, &g.lyapunov),
            ("fli", &c.fli, &g.fli),
            ("megno", &c.megno, &g.megno),
        ] {
            for (x, y) in a.iter().zip(b.iter()) {
                assert!(
                    (x - y).abs() <= 1e-9 * x.abs().max(1e-3),
                    "{name} {what}: CPU {x} GPU {y}"
                );
            }
        }
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
