//! CPU backend: determinism across thread counts, divergence isolation,
//! exact solutions, and the observers.

use reeb::backend::cpu;
use reeb::models::exact;
use reeb::models::{lane_emden, Model, MODEL_NAMES};
use reeb::plan::observations::Status;
use reeb::plan::observers::{CycleObs, Direction, PoincareObs, Section, TrajectoryObs};
use reeb::plan::{Plan, Problem, Source};

use crate::common;

fn vdp(eps: Source, dt: f64, steps: u64) -> Problem {
    let mut p = Problem::new(Model::VanDerPol, "s2")
        .unwrap()
        .param("epsilon", eps)
        .initial("q", Source::Const(2.0));
    p.dt = Source::Const(dt);
    p.steps = steps;
    p
}

#[test]
fn bitwise_identical_for_1_and_2_threads() {
    for scheme in ["s2", "yoshida6a", "rk4"] {
        let mut p = vdp(Source::Const(0.0), 0.01, 300);
        let eps = p.axis(
            "epsilon",
            (0..777).map(|i| 0.1 + 0.013 * i as f64).collect(),
        );
        let q0 = p.axis("q0", vec![0.5, 1.0, 2.5]);
        p = p.param("epsilon", eps).initial("q", q0);
        p.scheme = reeb::plan::scheme::Scheme::by_name(scheme).unwrap();
        p.observers.trajectory = Some(TrajectoryObs {
            every: 50,
            vars: vec!["q".into()],
        });
        let plan = Plan::new(&p).unwrap();
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| cpu::run::<f32>(&plan, None))
        };
        let (a, b) = (run(1), run(2));
        for ((_, x), (_, y)) in a.final_values.iter().zip(&b.final_values) {
            assert!(
                x.iter().zip(y).all(|(u, v)| u.to_bits() == v.to_bits()),
                "{scheme}"
            );
        }
        assert!(a.trajectory[0]
            .1
            .iter()
            .zip(&b.trajectory[0].1)
            .all(|(u, v)| u.to_bits() == v.to_bits()));
    }
}

#[test]
fn a_diverging_trajectory_is_flagged_and_isolated() {
    // ετ = 100 in f32: near q = 0 the A flow multiplies s by e^{ετ(1−q²)} ≈
    // e^{99.75}, beyond the f32 exponent range (finite in f64).
    let mut with = vdp(Source::Const(0.0), 0.1, 200).initial("q", Source::Const(0.05));
    let eps = with.axis("epsilon", vec![1.0, 1000.0, 2.0]);
    with = with.param("epsilon", eps);
    let mut without = vdp(Source::Const(0.0), 0.1, 200).initial("q", Source::Const(0.05));
    let eps = without.axis("epsilon", vec![1.0, 2.0]);
    without = without.param("epsilon", eps);
    let a = cpu::run::<f32>(&Plan::new(&with).unwrap(), None);
    let b = cpu::run::<f32>(&Plan::new(&without).unwrap(), None);
    assert!(
        matches!(a.status(1), Status::NonFinite { step } if step <= 3),
        "{:?}",
        a.status(1)
    );
    assert_eq!(a.status(0), Status::Ok);
    assert_eq!(a.status(2), Status::Ok);
    assert!(a.final_of("q").unwrap()[1].is_nan());
    let (qa, qb) = (a.final_of("q").unwrap(), b.final_of("q").unwrap());
    assert_eq!(qa[0].to_bits(), qb[0].to_bits());
    assert_eq!(qa[2].to_bits(), qb[1].to_bits());
    assert_eq!(a.count_ok(), 2);
}

#[test]
fn damped_oscillator_matches_its_closed_form_for_every_scheme() {
    for scheme in [
        "s2",
        "triple_jump4",
        "yoshida6a",
        "yoshida8a",
        "variational2",
        "rk4",
        "leapfrog",
    ] {
        for alpha in [0.1, 2.0, 4.0] {
            let mut p = Problem::new(Model::DampedOscillator, scheme)
                .unwrap()
                .param("alpha", Source::Const(alpha))
                .initial("q", Source::Const(1.0))
                .initial("p", Source::Const(1.0));
            p.dt = Source::Const(0.001);
            p.steps = 5000;
            let o = cpu::run::<f64>(&Plan::new(&p).unwrap(), None);
            let (q, pp) = exact::damped_oscillator(alpha, 0.0, 0.0, 1.0, 1.0, 5.0);
            let e = (o.final_of("q").unwrap()[0] - q)
                .abs()
                .max((o.final_of("p").unwrap()[0] - pp).abs());
            assert!(e < 2e-6, "{scheme} α = {alpha}: {e}");
        }
    }
}

#[test]
fn lane_emden_matches_exact_solutions() {
    for k in [0u32, 1, 5] {
        let mut p = Problem::new(Model::LaneEmden, "yoshida6a")
            .unwrap()
            .param("index", Source::Const(k as f64));
        p.dt = Source::Const(0.001);
        p.steps = 3000;
        p.observers.final_vars = vec!["q".into(), "p".into()];
        let o = cpu::run::<f64>(&Plan::new(&p).unwrap(), None);
        let (q, dq) = lane_emden::exact(k, 3.0).unwrap();
        assert!((o.final_of("q").unwrap()[0] - q).abs() < 1e-5, "k = {k}");
        assert!((o.final_of("p").unwrap()[0] - dq).abs() < 1e-5, "k = {k}");
    }
}

#[test]
fn harmonic_oscillator_observers() {
    // ε = 0: q = 2 cos t. Trajectory frames, event section and cycle agree with it.
    let mut p = vdp(Source::Const(0.0), 0.001, 20_000);
    p.observers.trajectory = Some(TrajectoryObs {
        every: 1000,
        vars: vec!["q".into(), "t".into()],
    });
    p.observers.poincare = Some(PoincareObs {
        section: Section::Crossing {
            var: "q".into(),
            value: 0.0,
            direction: Direction::Up,
        },
        vars: vec!["t".into(), "s".into(), "q".into()],
        max_points: 2,
    });
    p.observers.cycle = Some(CycleObs {
        var: "q".into(),
        level: 0.0,
        skip: 0.0,
    });
    let o = cpu::run::<f64>(&Plan::new(&p).unwrap(), None);
    assert_eq!(o.frames, 21);
    let (q, t) = (o.trajectory_of("q").unwrap(), o.trajectory_of("t").unwrap());
    for k in 0..o.frames {
        assert!((t[k] - k as f64).abs() < 1e-12);
        assert!((q[k] - exact::harmonic(2.0, 0.0, t[k]).0).abs() < 1e-5);
    }
    // Upward zero crossings at t = 3π/2 + 2πk: 3 in [0, 20], 2 kept.
    assert_eq!(o.poincare_count[0], 3);
    let pt = o.poincare_of("t").unwrap();
    let ps = o.poincare_of("s").unwrap();
    assert!(
        (pt[0] - 1.5 * std::f64::consts::PI).abs() < 1e-6,
        "{}",
        pt[0]
    );
    assert!((pt[1] - 3.5 * std::f64::consts::PI).abs() < 1e-6);
    assert!((ps[0] - 2.0).abs() < 1e-5);
    assert_eq!(o.poincare_of("q").unwrap()[0], 0.0);
    assert!((o.cycle_amplitude[0] - 2.0).abs() < 1e-5);
    assert!((o.cycle_period[0] - 2.0 * std::f64::consts::PI).abs() < 1e-5);
}

#[test]
fn stroboscopic_sections_exact_and_interpolated_agree() {
    // Period 2π with τ = 2π/20 samples exactly; with τ = 0.01 it interpolates.
    let period = 2.0 * std::f64::consts::PI;
    let run = |dt: f64, steps: u64| {
        let mut p = Problem::new(Model::DampedOscillator, "yoshida8a")
            .unwrap()
            .param("alpha", Source::Const(0.05))
            .param("forcing_amplitude", Source::Const(0.3))
            .param("forcing_frequency", Source::Const(1.0))
            .initial("q", Source::Const(1.0));
        p.dt = Source::Const(dt);
        p.steps = steps;
        p.observers.poincare = Some(PoincareObs {
            section: Section::Stroboscopic { period, phase: 0.0 },
            vars: vec!["q".into(), "p".into(), "t".into()],
            max_points: 10,
        });
        cpu::run::<f64>(&Plan::new(&p).unwrap(), None)
    };
    let exact = run(period / 200.0, 2000);
    let interp = run(0.01, 6284);
    assert_eq!(exact.poincare_count[0], 11);
    assert_eq!(interp.poincare_count[0], 11);
    for k in 0..10 {
        let (a, b) = (
            exact.poincare_of("t").unwrap()[k],
            interp.poincare_of("t").unwrap()[k],
        );
        assert!((a - k as f64 * period).abs() < 1e-9 && (b - k as f64 * period).abs() < 1e-9);
        let (qa, qb) = (
            exact.poincare_of("q").unwrap()[k],
            interp.poincare_of("q").unwrap()[k],
        );
        let (q, _) = exact::damped_oscillator(0.05, 0.3, 1.0, 1.0, 0.0, a);
        assert!(
            (qa - q).abs() < 1e-6 && (qb - q).abs() < 1e-6,
            "k = {k}: {qa} {qb} {q}"
        );
    }
}

#[test]
fn kepler_orbit_closes() {
    // Unperturbed Kepler, e = 0.5: after one period (2π) the orbit returns to perihelion.
    let ([q1, q2], [p1, p2]) = reeb::models::kepler::perihelion(0.5);
    let mut p = Problem::new(Model::Kepler, "yoshida8a")
        .unwrap()
        .initial("q1", Source::Const(q1))
        .initial("q2", Source::Const(q2))
        .initial("p1", Source::Const(p1))
        .initial("p2", Source::Const(p2));
    p.dt = Source::Const(2.0 * std::f64::consts::PI / 2000.0);
    p.steps = 2000;
    let o = cpu::run::<f64>(&Plan::new(&p).unwrap(), None);
    assert!((o.final_of("q1").unwrap()[0] - q1).abs() < 1e-9);
    assert!(o.final_of("q2").unwrap()[0].abs() < 1e-9);
}

#[test]
fn every_instruction_set_level_agrees() {
    use reeb::backend::cpu::{isa, run_isa, Isa};
    let levels: Vec<Isa> = [Isa::Baseline, Isa::V3, Isa::V4]
        .into_iter()
        .filter(|l| {
            matches!(
                (l, isa()),
                (Isa::Baseline, _) | (Isa::V3, Isa::V3 | Isa::V4) | (Isa::V4, Isa::V4)
            )
        })
        .collect();
    eprintln!("levels on this CPU: {levels:?}");
    for plan in [
        reeb::bench::Scenario::VdpS2.plan(1000, 300),
        reeb::bench::Scenario::SpinOrbitS2.plan(1000, 300),
        reeb::bench::Scenario::KeplerS2.plan(1000, 300),
    ] {
        let base = run_isa::<f64>(&plan, None, Isa::Baseline);
        for l in &levels[1..] {
            let o = run_isa::<f64>(&plan, None, *l);
            for ((_, a), (_, b)) in o.final_values.iter().zip(&base.final_values) {
                for (x, y) in a.iter().zip(b) {
                    assert!(
                        (x - y).abs() <= 1e-10 * y.abs().max(1.0),
                        "{l:?}: {x} vs {y}"
                    );
                }
            }
        }
    }
}

/// Time terms shared by the ensemble (`t0`, `dt` and the time ops' inputs
/// one value) are evaluated once per block and stage: bitwise the
/// per-trajectory evaluation (to round-off where FMAs contract), for every time-dependent model, in both
/// precisions, on every stage of a composition, with the observers that
/// read time; an ensemble that varies a time input is not shared.
#[test]
fn shared_time_terms_are_bitwise_the_per_trajectory_ones() {
    use reeb::backend::cpu::program::Program;
    use reeb::backend::cpu::Isa;
    use reeb::bench::Scenario;
    let forced = |model: Model, scheme: &str| {
        let mut p = Problem::new(model, scheme)
            .unwrap()
            .param("forcing_amplitude", Source::Const(0.7))
            .param("forcing_frequency", Source::Const(1.3));
        let q0 = p.axis("q0", (0..100).map(|i| 0.5 + 0.02 * i as f64).collect());
        p = p.initial("q", q0).initial("t0", Source::Const(0.25));
        p.dt = Source::Const(0.01);
        p.steps = 400;
        p.observers.trajectory = Some(TrajectoryObs {
            every: 50,
            vars: vec!["q".into(), "t".into()],
        });
        p
    };
    let lane_emden = {
        let mut p = Problem::new(Model::LaneEmden, "s2")
            .unwrap()
            .param("index", Source::Const(3.0));
        let q0 = p.axis("q0", (0..70).map(|i| 1.0 - 0.001 * i as f64).collect());
        p = p.initial("q", q0).initial("t0", Source::Const(0.01));
        p.dt = Source::Const(0.001);
        p.steps = 500;
        p
    };
    let plans = [
        Scenario::SpinOrbitS2.plan(300, 500),
        Scenario::KeplerS2.plan(130, 500),
        Plan::new(&forced(Model::VanDerPol, "s2")).unwrap(),
        Plan::new(&forced(Model::VanDerPol, "yoshida6a")).unwrap(),
        Plan::new(&forced(Model::DampedOscillator, "s2")).unwrap(),
        Plan::new(&lane_emden).unwrap(),
    ];
    // Bitwise where nothing contracts a·b + c (the baseline kernels); the
    // FMA levels may fuse the shared and the per-trajectory forms differently
    // (build flag `-fp-contract=fast`), so there they agree to round-off.
    let isa = cpu::isa();
    let mut levels = vec![(Isa::Baseline, 0.0, 0.0)];
    if isa != Isa::Baseline {
        levels.push((isa, 1e-12, 1e-4));
    }
    fn agree<R: reeb::num::precision::Real>(x: &[R], y: &[R], tol: f64) -> bool {
        x.iter().zip(y).all(|(x, y)| {
            let (x, y) = (x.to_f64(), y.to_f64());
            x.to_bits() == y.to_bits() || (x - y).abs() <= tol * y.abs().max(1.0)
        })
    }
    for plan in &plans {
        let name = plan.model.name();
        assert!(Program::<f64>::new(plan, isa, true).shared_time, "{name}");
        for &(isa, tol64, tol32) in &levels {
            let a = cpu::run_isa::<f64>(plan, None, isa);
            let b = cpu::run_time_per_trajectory::<f64>(plan, isa);
            for ((n, x), (_, y)) in a.final_values.iter().zip(&b.final_values) {
                assert!(agree(x, y, tol64), "{isa:?} {name} {n}");
            }
            for ((n, x), (_, y)) in a.trajectory.iter().zip(&b.trajectory) {
                assert!(agree(x, y, tol64), "{isa:?} {name} {n}");
            }
            assert_eq!(a.nonfinite_step, b.nonfinite_step, "{name}");
            let a = cpu::run_isa::<f32>(plan, None, isa);
            let b = cpu::run_time_per_trajectory::<f32>(plan, isa);
            for ((n, x), (_, y)) in a.final_values.iter().zip(&b.final_values) {
                assert!(agree(x, y, tol32), "{isa:?} {name} f32 {n}");
            }
        }
    }
    // A time input along an axis: evaluated per trajectory.
    let mut p = forced(Model::VanDerPol, "s2");
    let w = p.axis("w", vec![1.0, 1.3]);
    p = p.param("forcing_frequency", w);
    let plan = Plan::new(&p).unwrap();
    assert!(!Program::<f64>::new(&plan, isa, true).shared_time);
    // So is a `t0` along one.
    let mut p = forced(Model::VanDerPol, "s2");
    let t0 = p.axis("t0", vec![0.0, 0.5]);
    p = p.initial("t0", t0);
    let plan = Plan::new(&p).unwrap();
    assert!(!Program::<f64>::new(&plan, isa, true).shared_time);
}

/// The fused kernels take runs of steps no observer looks at in one call
/// (up to the next trajectory frame or multiple of 64 steps), stop a run at
/// the first step that leaves a lane non-finite, and make such a lane a twin
/// of a running one. All of it is bitwise one step per call (a frame after
/// every step forces that), with divergences at many different steps inside
/// runs, and the trajectories that do not diverge are bitwise those of an
/// ensemble without the diverging ones. A model without time shares its one
/// `dt`; a `dt` along an axis is per trajectory.
#[test]
fn runs_of_steps_are_bitwise_single_steps() {
    use reeb::backend::cpu::program::Program;
    // S2 (ετ = 100), and a composition whose stages but the last skip the
    // check (ετ = 2: its negative weights overflow where |q| > 1; no
    // trajectory survives there).
    runs_match_single_steps("s2", 500.0, 0.2, true);
    runs_match_single_steps("yoshida6a", 40.0, 0.05, false);
    // No time, one dt: shared; bitwise the per-trajectory dt.
    let isa = cpu::isa();
    let mut p = vdp(Source::Const(3.0), 0.05, 300);
    let q0 = p.axis("q0", (0..100).map(|i| 0.5 + 0.03 * i as f64).collect());
    p = p.initial("q", q0);
    let plan = Plan::new(&p).unwrap();
    assert!(Program::<f32>::new(&plan, isa, true).shared_time);
    let (shared, per_lane) = (
        cpu::run::<f32>(&plan, None),
        cpu::run_time_per_trajectory::<f32>(&plan, isa),
    );
    for ((n, x), (_, y)) in shared.final_values.iter().zip(&per_lane.final_values) {
        assert!(
            x.iter().zip(y).all(|(a, b)| a.to_bits() == b.to_bits()),
            "dt per trajectory: {n}"
        );
    }
    let mut p = vdp(Source::Const(1.0), 0.05, 10);
    let dt = p.axis("dt", vec![0.05, 0.01]);
    p.dt = dt;
    assert!(!Program::<f32>::new(&Plan::new(&p).unwrap(), isa, true).shared_time);
}

/// [`runs_of_steps_are_bitwise_single_steps`] for one scheme, ε and dt;
/// `survivors`: whether some trajectories survive 700 steps.
fn runs_match_single_steps(scheme: &str, eps: f64, dt: f64, survivors: bool) {
    // The A flow overflows f32 at a step that depends on q0 (or never).
    let ensemble = |q0: Vec<f64>, every: Option<u64>| {
        let mut p = vdp(Source::Const(eps), dt, 700);
        p.scheme = reeb::plan::scheme::Scheme::by_name(scheme).unwrap();
        let q = p.axis("q0", q0);
        p = p.initial("q", q);
        p.observers.trajectory = every.map(|every| TrajectoryObs {
            every,
            vars: vec!["q".into(), "s".into()],
        });
        Plan::new(&p).unwrap()
    };
    let q0: Vec<f64> = (0..300).map(|i| 1.0 + 0.01 * i as f64).collect();
    let runs = cpu::run::<f32>(&ensemble(q0.clone(), None), None);
    let single = cpu::run::<f32>(&ensemble(q0.clone(), Some(1)), None);
    let sevens = cpu::run::<f32>(&ensemble(q0.clone(), Some(7)), None);
    let bits = |x: &[f32]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    for (o, name) in [(&single, "every step"), (&sevens, "every 7")] {
        for ((n, x), (_, y)) in runs.final_values.iter().zip(&o.final_values) {
            assert_eq!(bits(x), bits(y), "{scheme} {name}: {n}");
        }
        assert_eq!(runs.nonfinite_step, o.nonfinite_step, "{scheme} {name}");
    }
    // Frame f of every 7 is frame 7f of every step.
    let frames = |every: u64| (700 / every + 1) as usize;
    for ((_, a), (_, b)) in sevens.trajectory.iter().zip(&single.trajectory) {
        for i in 0..q0.len() {
            for f in 0..frames(7) {
                let (x, y) = (a[i * frames(7) + f], b[i * frames(1) + 7 * f]);
                assert_eq!(x.to_bits(), y.to_bits(), "trajectory {i} frame {f}");
            }
        }
    }
    let steps: std::collections::BTreeSet<u32> = runs
        .nonfinite_step
        .iter()
        .copied()
        .filter(|s| *s > 0)
        .collect();
    let inside = steps.iter().filter(|&&s| s > 64 && s % 64 != 0).count();
    assert!(
        steps.len() >= 10 && inside >= 5,
        "{scheme}: divergence steps {steps:?}"
    );
    if !survivors {
        return;
    }
    // The survivors are bitwise an ensemble of survivors alone.
    let alive: Vec<usize> = (0..q0.len())
        .filter(|&i| runs.nonfinite_step[i] == 0)
        .collect();
    assert!(
        alive.len() >= 20 && alive.len() < q0.len() - 20,
        "{scheme}: {} survive",
        alive.len()
    );
    let survivors = cpu::run::<f32>(
        &ensemble(alive.iter().map(|&i| q0[i]).collect(), None),
        None,
    );
    for ((n, x), (_, y)) in runs.final_values.iter().zip(&survivors.final_values) {
        let kept: Vec<f32> = alive.iter().map(|&i| x[i]).collect();
        assert_eq!(bits(&kept), bits(y), "{scheme} survivors: {n}");
    }
}

/// An exact stroboscopic section lets the fused kernels take runs of steps
/// up to the block's next sample (not one step per call): its points are
/// bitwise the states a trajectory observer records at those steps, with a
/// different sampling interval per lane (forcing periods of 7, 11 and 13
/// steps along an axis) and a composition.
#[test]
fn exact_stroboscopic_samples_are_the_states_at_those_steps() {
    let dt = 0.05;
    let periods = [7u64, 11, 13];
    let mut p = Problem::new(Model::DampedOscillator, "yoshida6a")
        .unwrap()
        .param("alpha", Source::Const(0.05))
        .param("forcing_amplitude", Source::Const(0.3));
    let w = p.axis(
        "w",
        periods
            .iter()
            .map(|m| 2.0 * std::f64::consts::PI / (*m as f64 * dt))
            .collect(),
    );
    let q0 = p.axis("q0", (0..30).map(|i| 0.5 + 0.05 * i as f64).collect());
    p = p.param("forcing_frequency", w).initial("q", q0);
    p.dt = Source::Const(dt);
    p.steps = 300;
    // The states at every step (a frame per step: runs of one step) …
    let mut every_step = p.clone();
    every_step.observers.trajectory = Some(TrajectoryObs {
        every: 1,
        vars: vec!["q".into()],
    });
    let t = cpu::run::<f64>(&Plan::new(&every_step).unwrap(), None);
    // … and the section alone (runs up to the next sample).
    p.observers.poincare = Some(PoincareObs {
        section: Section::Forced { skip: 1.0 },
        vars: vec!["q".into()],
        max_points: 50,
    });
    let plan = Plan::new(&p).unwrap();
    assert!(!plan.strobe_interpolated());
    let o = cpu::run::<f64>(&plan, None);
    let (frames, points) = (t.trajectory_of("q").unwrap(), o.poincare_of("q").unwrap());
    for i in 0..o.n {
        let every = periods[i / 30] as usize;
        assert_eq!(
            o.poincare_count[i] as usize,
            (300 - every) / every + 1,
            "lane {i}"
        );
        for k in 0..o.poincare_count[i] as usize {
            let step = every * (k + 1);
            assert_eq!(
                points[i * o.max_points + k].to_bits(),
                frames[i * t.frames + step].to_bits(),
                "lane {i}, point {k} (step {step})"
            );
        }
    }
}

/// The fused kernels check a run of steps for non-finite values only at its
/// end (`backend/cpu/kernels.rs`), which finds every lane that left the
/// finite numbers only if ±∞ and NaN, once in a state variable, never leave
/// the state: every piece of every model with fused kernels, applied to a
/// trajectory with one variable ±∞ or NaN and the others random (time and τ
/// too), leaves some variable non-finite, over random sequences of pieces.
#[test]
fn non_finite_states_stay_non_finite() {
    use reeb::models::lanes::Lane;
    use reeb::models::pieces::{Pieces, PiecesVisitor};
    use reeb::models::Flows;

    struct Absorbing<'a> {
        plan: &'a Plan,
    }
    impl<R: Flows> PiecesVisitor<R> for Absorbing<'_> {
        type Out = usize;
        fn visit<P: Pieces<R>>(self) -> usize {
            let spec = self.plan.model.spec();
            let mut base = Lane::<R>::default();
            for (name, src) in &self.plan.bindings {
                if let Some(x) = base.get_mut(name) {
                    *x = R::from_f64(src.values()[0]);
                }
            }
            // xorshift64*: reproducible without a dependency.
            let mut seed = 0x9e37_79b9_7f4a_7c15u64;
            let mut uniform = move |lo: f64, hi: f64| {
                seed ^= seed >> 12;
                seed ^= seed << 25;
                seed ^= seed >> 27;
                let u =
                    (seed.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64;
                lo + (hi - lo) * u
            };
            let pieces: Vec<char> = spec.pieces.chars().collect();
            let mut checked = 0;
            for bad_var in spec.vars {
                for bad in [f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
                    for trial in 0..200 {
                        let mut x = base;
                        for v in spec.vars {
                            // Every tenth trial, the others exactly 0.
                            let value = if trial % 10 == 0 {
                                0.0
                            } else {
                                uniform(-4.0, 4.0)
                            };
                            *x.get_mut(v).unwrap() = R::from_f64(value);
                        }
                        *x.get_mut(bad_var).unwrap() = R::from_f64(bad);
                        x.t = R::from_f64(uniform(0.01, 20.0));
                        P::time(&mut x);
                        for _ in 0..7 {
                            let piece = pieces[uniform(0.0, pieces.len() as f64) as usize];
                            x.tau = R::from_f64(uniform(0.0, 0.5));
                            match trial % 2 {
                                0 => P::piece::<true>(piece, &mut x),
                                _ => P::piece::<false>(piece, &mut x),
                            }
                            assert!(
                                !P::finite(&x),
                                "{}: {bad_var} = {bad} became finite after piece {piece} (trial {trial})",
                                spec.name
                            );
                            checked += 1;
                        }
                    }
                }
            }
            checked
        }
    }
    let mut models = 0;
    for model in MODEL_NAMES {
        let Some(p) = common::problem(model, "s2") else {
            continue;
        };
        let plan = Plan::new(&p).unwrap();
        let f64s = plan.model.with_pieces::<f64, _>(Absorbing { plan: &plan });
        let f32s = plan.model.with_pieces::<f32, _>(Absorbing { plan: &plan });
        if let (Some(a), Some(b)) = (f64s, f32s) {
            assert!(a > 0 && b > 0, "{model}");
            models += 1;
        }
    }
    assert!(models >= 6, "{models} models with fused kernels");
}

/// Every built-in model has its fused kernels in both precisions for its
/// default piece order, every optional variable and time mode, at every
/// level: they are compiled in the library and handed back through `Any`,
/// and a failed hand-back would silently fall back to the (slower) op
/// interpreter. The other orders have AVX2/FMA kernels for ensembles that
/// share their time only (the rest run through the ops), and what is no
/// permutation has none.
#[test]
fn every_model_has_fused_kernels_in_both_precisions() {
    use reeb::backend::cpu::kernels::{time, Isa, StageBuilder, FUSED_ORDER};
    let others = [
        ['A', 'B', 'C'],
        ['A', 'C', 'B'],
        ['B', 'A', 'C'],
        ['B', 'C', 'A'],
        ['C', 'A', 'B'],
    ];
    for name in MODEL_NAMES {
        let model = Model::from_name(name).unwrap();
        let default: Vec<char> = model.spec().default_order.chars().take(3).collect();
        assert_eq!(
            default, FUSED_ORDER,
            "{name}: its default order has no kernels"
        );
        for opt in [false, true] {
            for time in [time::NONE, time::PER_LANE, time::SHARED] {
                for isa in [Isa::Baseline, Isa::V3, Isa::V4] {
                    let b = |order| StageBuilder {
                        order,
                        opt,
                        time,
                        isa,
                    };
                    let what = format!("{name} opt {opt} time {time} {isa:?}");
                    assert!(b(FUSED_ORDER).build::<f32>(&model).is_some(), "{what} f32");
                    assert!(b(FUSED_ORDER).build::<f64>(&model).is_some(), "{what} f64");
                    for order in others {
                        let has = b(order).build::<f64>(&model).is_some();
                        let shared = time == time::SHARED;
                        assert_eq!(has, isa != Isa::Baseline && shared, "{what} {order:?}");
                    }
                    let bad = b(['A', 'A', 'C']).build::<f64>(&model);
                    assert!(bad.is_none(), "{what}: not a permutation");
                }
            }
        }
    }
}
