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
    let space = TangentStep::new(plan, 1).unwrap().space;
    let d = space.len();
    let t = TangentStep::new(plan, d).unwrap();
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
            let (space, cols) = match TangentStep::new(&plan, 1) {
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
    assert!(checked >= 7 * 16, "{checked} model × scheme pairs");
    assert!(refused.len() <= 4, "refused: {refused:?}");
}

/// The tangent spaces of the README: (q, p) for mechanical models, (q, s)
/// for Liénard systems, everything for quadratic_s.
#[test]
fn tangent_spaces_are_the_dynamical_phase_spaces() {
    let space = |name: &str| {
        let plan = Plan::new(&problem(name, "s2")).unwrap();
        TangentStep::new(&plan, 1).unwrap().space
    };
    assert_eq!(space("damped_oscillator"), ["q", "p"]);
    assert_eq!(space("van_der_pol"), ["q", "s"]);
    assert_eq!(space("lienard"), ["q", "s"]);
    assert_eq!(space("kepler"), ["q1", "q2", "p1", "p2"]);
    assert_eq!(space("lane_emden"), ["q", "p"]);
    assert_eq!(space("spin_orbit"), ["q", "p"]);
    assert_eq!(space("quadratic_s"), ["q", "p", "s"]);
}
