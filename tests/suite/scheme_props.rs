//! Property tests of the splitting schemes: whatever palindromic inner order
//! S2 is given (`CBABC`, `BCACB`, `ACBCA`, …), it is a second-order method,
//! and the triple jump built on it is fourth order. Measured on the damped
//! (optionally forced) oscillator against its closed form and on van der Pol
//! (optionally forced) against a fine RK4 reference, as the error at N and 2N
//! steps: the maximum over components and over eleven output times, so that
//! a chance zero of one component at one time cannot fake an order.

use proptest::prelude::*;
use proptest::test_runner::RngSeed;

use reeb::backend::cpu;
use reeb::models::{exact, Model};
use reeb::plan::observers::TrajectoryObs;
use reeb::plan::scheme::Scheme;
use reeb::plan::{Plan, Problem, Source};

/// Deterministic runs (fixed seed, no regression files): CI reproduces them.
fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: RngSeed::Fixed(0x7265_6562),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// A smooth test problem.
#[derive(Debug, Clone)]
enum Case {
    /// `q'' + α q' + q = β sin ωt` from (q0, p0).
    Damped {
        alpha: f64,
        forcing: Option<(f64, f64)>,
        q0: f64,
        p0: f64,
    },
    /// van der Pol (optionally forced) from (q0, s0).
    VanDerPol {
        eps: f64,
        forcing: Option<(f64, f64)>,
        q0: f64,
        s0: f64,
    },
}

const T_END: f64 = 4.0;
/// Output frames per run (every N/10 steps).
const FRAMES: u64 = 10;

impl Case {
    fn model(&self) -> Model {
        match self {
            Case::Damped { .. } => Model::DampedOscillator,
            Case::VanDerPol { .. } => Model::VanDerPol,
        }
    }
    fn vars(&self) -> [&'static str; 2] {
        match self {
            Case::Damped { .. } => ["q", "p"],
            Case::VanDerPol { .. } => ["q", "s"],
        }
    }
    /// The problem with `scheme`, inner `order`, `steps` steps to T_END and
    /// the variables recorded FRAMES + 1 times.
    fn problem(&self, scheme: &str, order: Option<&str>, steps: u64) -> Problem {
        let mut p = Problem::new(self.model(), scheme).unwrap();
        let (params, initial) = match *self {
            Case::Damped {
                alpha,
                forcing,
                q0,
                p0,
            } => {
                let (b, w) = forcing.unwrap_or((0.0, 0.0));
                (
                    [
                        ("alpha", alpha),
                        ("forcing_amplitude", b),
                        ("forcing_frequency", w),
                    ],
                    [("q", q0), ("p", p0)],
                )
            }
            Case::VanDerPol {
                eps,
                forcing,
                q0,
                s0,
            } => {
                let (b, w) = forcing.unwrap_or((0.0, 0.0));
                (
                    [
                        ("epsilon", eps),
                        ("forcing_amplitude", b),
                        ("forcing_frequency", w),
                    ],
                    [("q", q0), ("s", s0)],
                )
            }
        };
        for (k, v) in params {
            p = p.param(k, Source::Const(v));
        }
        for (k, v) in initial {
            p = p.initial(k, Source::Const(v));
        }
        p.order = order.map(str::to_string);
        p.dt = Source::Const(T_END / steps as f64);
        p.steps = steps;
        p.observers.final_vars = vec![];
        p.observers.trajectory = Some(TrajectoryObs {
            every: steps / FRAMES,
            vars: self.vars().iter().map(|v| (*v).into()).collect(),
        });
        p
    }
    /// The variables at the FRAMES + 1 output times, component-major.
    fn run(&self, scheme: &str, order: Option<&str>, steps: u64) -> Vec<Vec<f64>> {
        let plan = Plan::new(&self.problem(scheme, order, steps)).unwrap();
        let o = cpu::run::<f64>(&plan, None);
        assert_eq!(o.frames as u64, FRAMES + 1);
        self.vars()
            .iter()
            .map(|v| o.trajectory_of(v).unwrap().to_vec())
            .collect()
    }
    /// The exact values (damped oscillator) or RK4 with 10 000 steps, whose
    /// error (~10⁻¹³) is far below the errors measured here.
    fn reference(&self) -> Vec<Vec<f64>> {
        match *self {
            Case::Damped {
                alpha,
                forcing,
                q0,
                p0,
            } => {
                let (b, w) = forcing.unwrap_or((0.0, 0.0));
                let at: Vec<(f64, f64)> = (0..=FRAMES)
                    .map(|k| {
                        let t = T_END * k as f64 / FRAMES as f64;
                        exact::damped_oscillator(alpha, b, w, q0, p0, t)
                    })
                    .collect();
                vec![
                    at.iter().map(|x| x.0).collect(),
                    at.iter().map(|x| x.1).collect(),
                ]
            }
            Case::VanDerPol { .. } => self.run("rk4", None, 10_000),
        }
    }
}

fn max_error(x: &[Vec<f64>], reference: &[Vec<f64>]) -> f64 {
    x.iter()
        .flatten()
        .zip(reference.iter().flatten())
        .map(|(a, b)| (a - b).abs())
        .fold(
            0.0,
            |m, e| if e.is_nan() { f64::INFINITY } else { m.max(e) },
        )
}

/// log2(e(N) / e(2N)) of `scheme` with inner `order`.
fn observed_order(case: &Case, scheme: &str, order: &str, n: u64) -> (f64, f64, f64) {
    let reference = case.reference();
    let e1 = max_error(&case.run(scheme, Some(order), n), &reference);
    let e2 = max_error(&case.run(scheme, Some(order), 2 * n), &reference);
    ((e1 / e2).log2(), e1, e2)
}

fn forcing() -> impl Strategy<Value = Option<(f64, f64)>> {
    prop::option::of((0.1..1.0f64, 0.5..2.0f64))
}

fn case() -> impl Strategy<Value = Case> {
    prop_oneof![
        (0.05..3.0f64, forcing(), -1.5..1.5f64, -1.5..1.5f64)
            .prop_filter("a nonzero start or forcing", |(_, f, q, p)| {
                f.is_some() || q.abs() + p.abs() > 0.3
            })
            .prop_map(|(alpha, forcing, q0, p0)| Case::Damped {
                alpha,
                forcing,
                q0,
                p0
            }),
        (0.1..2.0f64, forcing(), 0.5..2.5f64, -1.0..1.0f64).prop_map(|(eps, forcing, q0, s0)| {
            Case::VanDerPol {
                eps,
                forcing,
                q0,
                s0,
            }
        }),
    ]
}

/// A palindromic S2 order of the model's pieces: a permutation P1 … Pm of
/// the letters, then back (`CBA` → `CBABC`).
fn s2_order(pieces: &'static str) -> impl Strategy<Value = String> {
    Just(pieces.chars().collect::<Vec<char>>())
        .prop_shuffle()
        .prop_map(|half| {
            let back = half[..half.len() - 1].iter().rev();
            half.iter().chain(back).collect()
        })
}

fn case_and_order() -> impl Strategy<Value = (Case, String)> {
    // Both models have the pieces A, B, C (checked in the tests).
    (case(), s2_order("ABC"))
}

proptest! {
    #![proptest_config(config(24))]

    /// Every palindromic inner order makes S2 second order.
    #[test]
    fn every_palindromic_s2_order_is_second_order((case, order) in case_and_order()) {
        prop_assert_eq!(case.model().spec().pieces, "ABC");
        let (p, e1, e2) = observed_order(&case, "s2", &order, 200);
        prop_assert!(
            (p - 2.0).abs() <= 0.2,
            "S2({order}) on {case:?}: observed order {p:.3} (errors {e1:.3e} → {e2:.3e})"
        );
    }
}

proptest! {
    #![proptest_config(config(8))]

    /// The triple jump S2(γ1τ) S2(γ0τ) S2(γ1τ) is fourth order whatever the
    /// inner order of S2.
    #[test]
    fn triple_jump_of_every_s2_order_is_fourth_order((case, order) in case_and_order()) {
        let (p, e1, e2) = observed_order(&case, "triple_jump4", &order, 100);
        prop_assert!(
            (p - 4.0).abs() <= 0.3,
            "triple_jump4({order}) on {case:?}: observed order {p:.3} (errors {e1:.3e} → {e2:.3e})"
        );
    }
}

proptest! {
    #![proptest_config(config(256))]

    /// The plan accepts exactly the palindromes of odd length that name each
    /// piece once up to the middle; everything else is an `integrator.order`
    /// error (never a panic).
    #[test]
    fn plans_accept_exactly_the_s2_orders(order in "[ABCD]{0,7}") {
        let chars: Vec<char> = order.chars().collect();
        let valid = chars.len() == 5
            && chars.iter().eq(chars.iter().rev())
            && {
                let mut half = chars[..3].to_vec();
                half.sort_unstable();
                half == ['A', 'B', 'C']
            };
        for model in [Model::DampedOscillator, Model::VanDerPol] {
            let mut p = Problem::new(model, "s2").unwrap();
            if matches!(p.model, Model::VanDerPol) {
                p = p.param("epsilon", Source::Const(1.0));
            } else {
                p = p.param("alpha", Source::Const(0.5));
            }
            p.order = Some(order.clone());
            match Plan::new(&p) {
                Ok(plan) => {
                    prop_assert!(valid, "`{order}` accepted");
                    let stages = plan.stages.expect("a splitting has stages");
                    prop_assert_eq!(&stages.order[..], &chars[..3]);
                }
                Err(e) => {
                    prop_assert!(!valid, "`{order}` refused: {e}");
                    prop_assert_eq!(e.field, "integrator.order");
                }
            }
        }
    }
}

/// All six orders of S2 agree to O(τ²) with one another (they are different
/// methods with the same limit), and the default is `CBABC`.
#[test]
fn all_six_orders_are_different_second_order_methods() {
    assert!(Scheme::by_name("s2").is_some());
    let case = Case::VanDerPol {
        eps: 1.0,
        forcing: None,
        q0: 2.0,
        s0: 0.0,
    };
    let orders = ["CBABC", "BCACB", "ACBCA", "ABCBA", "BACAB", "CABAC"];
    let runs: Vec<Vec<Vec<f64>>> = orders
        .iter()
        .map(|o| case.run("s2", Some(o), 400))
        .collect();
    assert_eq!(case.run("s2", None, 400), runs[0]);
    for (i, a) in runs.iter().enumerate() {
        for b in &runs[i + 1..] {
            let d = max_error(a, b);
            assert!(d > 0.0 && d < 1e-2, "{} vs other: {d:e}", orders[i]);
        }
    }
}
