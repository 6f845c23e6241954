//! Recorded runs: where observers look at every step of fused stages, the
//! CPU kernel takes runs of steps and the observers read the states it
//! recorded. Every column must be bitwise that of one step per call, with
//! every such observer at once, lanes that stop inside a run, lanes that
//! leave the finite numbers, in both precisions and both kernel paths
//! (a single stage's, a composition's).

use reeb::backend::cpu;
use reeb::models::Flows;
use reeb::plan::observations::{Col, Observations};

use crate::common::plan;

/// Van der Pol over ε (some of whose steps overflow: ετ up to 120) and q0,
/// with `scheme`, frames every 5 steps and the `[output]` lines `observers`.
fn van_der_pol(scheme: &str, observers: &str) -> String {
    format!(
        r#"
model = "van_der_pol"
[params]
epsilon = {{ linspace = [0.3, 600.0, 37] }}
[initial]
q = {{ linspace = [0.5, 2.5, 5] }}
[integrator]
scheme = "{scheme}"
dt = 0.2
steps = 700
[output]
final = ["q", "s", "t"]
trajectory = {{ every = 5, vars = ["q", "s"] }}
{observers}
"#
    )
}

/// [`van_der_pol`] with every observer that looks at every step: cycle
/// statistics from the first step, a Poincaré `section`, averages and a
/// stop that holds for some trajectories inside a run (t > 2 + 3ε, not a
/// multiple of 16 steps).
fn every_observer(scheme: &str, section: &str) -> String {
    let observers = format!(
        r#"poincare = {section}
cycle = {{ var = "q", skip = 0.0 }}
average = {{ vars = ["q", "s"], skip = 0.1 }}
stop = "t > 2 + 3*epsilon""#
    );
    van_der_pol(scheme, &observers)
}

/// [`van_der_pol`] with a stop condition as the only observer that looks
/// at every step, and an exact stroboscopic section (every 6 steps).
fn stop_only(scheme: &str) -> String {
    let observers = r#"poincare = { period = 1.2, vars = ["q", "s"], max_points = 200 }
stop = "t + 0.1*q > 2 + 3*epsilon""#;
    van_der_pol(scheme, observers)
}

/// Every column of `a` and `b`, bitwise.
fn same<R: Flows>(what: &str, a: &Observations<R>, b: &Observations<R>) {
    let (ca, cb) = (a.columns(), b.columns());
    assert_eq!(ca.len(), cb.len(), "{what}");
    for (k, ((_, x), (_, y))) in ca.iter().zip(&cb).enumerate() {
        let same = match (x, y) {
            (Col::Real(x), Col::Real(y)) => {
                x.len() == y.len()
                    && x.iter()
                        .zip(*y)
                        .all(|(u, v)| u.to_f64().to_bits() == v.to_f64().to_bits())
            }
            (Col::Count(x), Col::Count(y)) => x == y,
            (Col::Int(x), Col::Int(y)) => x == y,
            _ => false,
        };
        assert!(same, "{what}: column {k} differs");
    }
}

fn check<R: Flows>(what: &str, text: &str) -> Observations<R> {
    let p = plan(text);
    let recorded = cpu::run::<R>(&p, None);
    let stepwise = cpu::run_step_by_step::<R>(&p, cpu::isa());
    same(what, &recorded, &stepwise);
    recorded
}

#[test]
fn recorded_runs_are_bitwise_one_step_per_call() {
    let crossing =
        r#"{ crossing = "q", value = 1.0, direction = "both", vars = ["s"], max_points = 30 }"#;
    let strobe = r#"{ period = 2.9, vars = ["q", "s"], max_points = 300 }"#;
    for scheme in ["s2", "yoshida6a"] {
        // Then a stop condition alone (of the state, a parameter and
        // time), with frames and an exact stroboscopic section: runs in
        // which no lane stops are observed only at their end.
        let scenes = [
            ("crossing", every_observer(scheme, crossing)),
            ("strobe", every_observer(scheme, strobe)),
            ("stop", stop_only(scheme)),
            // Of the parameters alone: the whole condition computed once.
            (
                "parameter stop",
                van_der_pol(scheme, r#"stop = "epsilon > 1""#),
            ),
        ];
        for (name, text) in scenes {
            let o = check::<f32>(&format!("{scheme} {name} f32"), &text);
            check::<f64>(&format!("{scheme} {name} f64"), &text);
            // The cases are there: stopped and non-finite trajectories.
            let (stopped, ok) = (o.count_stopped(), o.count_ok());
            assert!(
                stopped > 0 && ok + stopped < o.n,
                "{scheme} {name}: {stopped} stopped, {ok} ok"
            );
        }
    }
    // Spin–orbit (time terms per trajectory): an interpolated section
    // with a phase, averages, no stop.
    let spin_orbit = r#"
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
steps = 3000
[output]
final = ["q", "p"]
poincare = { period = 6.283185307179586, phase = 1.0, vars = ["q", "p"], max_points = 60 }
average = ["p"]
"#;
    check::<f32>("spin–orbit f32", spin_orbit);
    check::<f64>("spin–orbit f64", spin_orbit);
}
