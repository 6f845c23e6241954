//! SALI and GALI_k (`plan/alignment.rs`) against their known laws on the
//! conservative Hénon–Heiles system at energy 1/8 (a formula model with
//! zero damping; the deviation vectors in (q1, q2, p1, p2), starting as
//! the identity's first columns): a chaotic orbit drives them to 0
//! exponentially, SALI at the rate λ₁ − λ₂ = λ₁, GALI_k at
//! (λ₁ − λ₂) + … + (λ₁ − λ_k), i.e. λ₁, 2λ₁ and 4λ₁ for k = 2, 3, 4; on a
//! regular orbit (a 2-torus) SALI and GALI_2 stay of order one, GALI_3
//! falls as t⁻² and GALI_4 as t⁻⁴. Both backends agree; bad settings are
//! refused at their field. (The harmonic map's values against a numpy
//! reimplementation of the definitions are in python/tests.)

use reeb::backend::{cpu, gpu};
use reeb::plan::observations::Observations;

use crate::common;

const ENERGY: f64 = 0.125;

/// A Hénon–Heiles orbit of energy 1/8 from (q1, q2, p2), p1 > 0.
fn p1(q1: f64, q2: f64, p2: f64) -> f64 {
    let v = (q1 * q1 + q2 * q2) / 2.0 + q1 * q1 * q2 - q2.powi(3) / 3.0;
    (2.0 * ENERGY - 2.0 * v - p2 * p2).sqrt()
}

/// One orbit's run: `output` its observers, frames of `every` steps of
/// dt = 0.05 to `t_end`.
fn scene((q1, q2, p2): (f64, f64, f64), t_end: f64, every: u64, output: &str) -> String {
    format!(
        "name = \"hh\"\nmodel = \"mechanical\"\n[formula]\ndof = 2\npotential = \"(q1^2 + q2^2)/2 + q1^2*q2 - q2^3/3\"\ndamping = \"0\"\n[initial]\nq1 = {q1:?}\nq2 = {q2:?}\np1 = {:?}\np2 = {p2:?}\n[integrator]\nscheme = \"s2\"\ndt = 0.05\nt_end = {t_end:?}\n[output]\nfinal = [\"q\"]\ntrajectory = {{ every = {every}, vars = [\"q1\"] }}\n{output}\n[run]\nprecision = \"f64\"\n",
        p1(q1, q2, p2)
    )
}

fn run(text: &str) -> Observations<f64> {
    cpu::run::<f64>(&common::plan(text), None)
}

/// The frames' times and an index's values there, from the first sample on.
fn series(o: &Observations<f64>, column: &[f64], dt_frame: f64) -> (Vec<f64>, Vec<f64>) {
    assert_eq!(o.n, 1);
    (1..o.frames)
        .map(|f| (f as f64 * dt_frame, column[f]))
        .unzip()
}

/// The least-squares slope of y against x.
fn slope(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    sxy / sxx
}

/// The rate at which an index falls exponentially, fitted from t = 5 until
/// it first reaches the round-off floor 10⁻¹⁴.
fn decay_rate(t: &[f64], v: &[f64]) -> f64 {
    let end = v.iter().position(|x| *x < 1e-14).unwrap_or(v.len());
    let from = t.iter().position(|x| *x >= 5.0).unwrap();
    assert!(end > from + 20, "too few frames before the floor: {end}");
    let ln: Vec<f64> = v[from..end].iter().map(|x| x.ln()).collect();
    -slope(&t[from..end], &ln)
}

/// The chaotic orbit of Skokos (2001): (q1, q2, p2) = (0, −0.016, 0).
#[test]
fn a_chaotic_orbit_drives_sali_and_gali_to_zero_at_the_lyapunov_rates() {
    let orbit = (0.0, -0.016, 0.0);
    let mut rates = vec![];
    let mut lambda = f64::NAN;
    for k in [2, 3, 4] {
        let output = format!("sali = {{ every = 10 }}\ngali = {{ k = {k}, every = 10 }}\nlyapunov = {{ every = 10 }}");
        let o = run(&scene(orbit, 500.0, 20, &output));
        lambda = o.lyapunov[0];
        let (t, gali) = series(&o, &o.trajectory_gali, 1.0);
        rates.push(decay_rate(&t, &gali));
        if k == 2 {
            let (_, sali) = series(&o, &o.trajectory_sali, 1.0);
            let rate = decay_rate(&t, &sali);
            assert!(
                (0.8..1.25).contains(&(rate / lambda)),
                "SALI's rate {rate}, λ₁ {lambda}"
            );
            assert!(o.sali[0] < 1e-4, "SALI at the end {}", o.sali[0]);
        }
        assert!(o.gali[0] < 1e-4, "GALI_{k} at the end {}", o.gali[0]);
    }
    assert!(lambda > 0.01, "λ₁ {lambda}: the orbit is chaotic");
    let ratios: Vec<f64> = rates.iter().map(|r| r / lambda).collect();
    let [g2, g3, g4] = ratios[..] else {
        unreachable!()
    };
    assert!(
        (0.8..1.25).contains(&g2),
        "GALI_2's rate over λ₁: {ratios:?}"
    );
    assert!(
        (1.6..2.6).contains(&g3),
        "GALI_3's rate over λ₁: {ratios:?}"
    );
    assert!(
        (2.8..5.0).contains(&g4),
        "GALI_4's rate over λ₁: {ratios:?}"
    );
}

/// A regular orbit off the symmetry line q1 = p2 = 0 (there the identity's
/// columns in q1 and p2 have no component along the actions, stay bounded,
/// and halve the power laws).
#[test]
fn a_regular_orbit_keeps_sali_and_gali_2_and_gali_3_4_fall_as_powers_of_t() {
    let orbit = (0.1, 0.0, 0.05);
    let mut slopes = vec![];
    for k in [2, 3, 4] {
        let output = format!("sali = {{ every = 10 }}\ngali = {{ k = {k}, every = 10 }}");
        let o = run(&scene(orbit, 4000.0, 200, &output));
        let (t, gali) = series(&o, &o.trajectory_gali, 10.0);
        let late: Vec<usize> = (0..t.len()).filter(|i| t[*i] >= 500.0).collect();
        let ln = |v: &[f64], i: &usize| v[*i].ln();
        let lt: Vec<f64> = late.iter().map(|i| t[*i].ln()).collect();
        let lg: Vec<f64> = late.iter().map(|i| ln(&gali, i)).collect();
        slopes.push(slope(&lt, &lg));
        if k == 2 {
            let (_, sali) = series(&o, &o.trajectory_sali, 10.0);
            let least = |v: &[f64]| late.iter().map(|i| v[*i]).fold(f64::INFINITY, f64::min);
            assert!(least(&sali) > 1e-2, "SALI falls to {}", least(&sali));
            assert!(least(&gali) > 1e-2, "GALI_2 falls to {}", least(&gali));
        }
    }
    let [s2, s3, s4] = slopes[..] else {
        unreachable!()
    };
    assert!(s2.abs() < 0.3, "GALI_2 ∝ t^{s2}");
    assert!((-2.3..-1.7).contains(&s3), "GALI_3 ∝ t^{s3}");
    assert!((-4.4..-3.6).contains(&s4), "GALI_4 ∝ t^{s4}");
}

/// SALI and GALI share their vectors: SALI is the same whether GALI runs
/// on two of them or four, and the last frame holds the outputs.
#[test]
fn sali_is_the_same_beside_any_gali() {
    let orbit = (0.1, 0.0, 0.05);
    let alone = run(&scene(orbit, 100.0, 100, "sali = { every = 5 }"));
    let beside = run(&scene(
        orbit,
        100.0,
        100,
        "sali = { every = 5 }\ngali = { k = 4, every = 5 }",
    ));
    assert_eq!(alone.sali[0].to_bits(), beside.sali[0].to_bits());
    assert!(alone.gali.is_empty() && alone.trajectory_gali.is_empty());
    let last = beside.frames - 1;
    assert_eq!(beside.trajectory_sali[last], beside.sali[0]);
    assert_eq!(beside.trajectory_gali[last], beside.gali[0]);
    assert!(beside.trajectory_sali[0].is_nan(), "no sample at step 0");
}

/// Both backends give the same indices (f64; a regular and a chaotic orbit).
#[test]
fn sali_and_gali_agree_between_cpu_and_gpu() {
    let Some(ctx) = common::gpu() else { return };
    for orbit in [(0.1, 0.0, 0.05), (0.0, -0.016, 0.0)] {
        let text = scene(
            orbit,
            100.0,
            50,
            "sali = { every = 3 }\ngali = { k = 3, every = 3 }",
        );
        let plan = common::plan(&text);
        let c = cpu::run::<f64>(&plan, None);
        let g = gpu::run::<f64>(ctx, &plan, None).unwrap().observations;
        for (what, a, b) in [
            ("sali", &c.sali, &g.sali),
            ("gali", &c.gali, &g.gali),
            ("trajectory_sali", &c.trajectory_sali, &g.trajectory_sali),
            ("trajectory_gali", &c.trajectory_gali, &g.trajectory_gali),
        ] {
            assert_eq!(a.len(), b.len(), "{what}");
            assert!(!a.is_empty(), "{what}");
            for (x, y) in a.iter().zip(b) {
                let close = (x - y).abs() <= 1e-9 * x.abs().max(1e-12);
                assert!(
                    close || x.is_nan() && y.is_nan(),
                    "{orbit:?} {what}: CPU {x} GPU {y}"
                );
            }
        }
    }
}

/// `stop = "sali < 1e-8"` ends the chaotic orbit at a sample (SALI changes
/// only there), keeping its indices up to the stop, and not the regular
/// one; the GPU stops it at the same step.
#[test]
fn a_stop_condition_reads_sali() {
    let output = "sali = { every = 10 }\nstop = \"sali < 1e-8\"";
    for (orbit, chaotic) in [((0.0, -0.016, 0.0), true), ((0.1, 0.0, 0.05), false)] {
        let plan = common::plan(&scene(orbit, 1000.0, 100, output));
        let o = cpu::run::<f64>(&plan, None);
        let stop = o.stop_step[0];
        assert_eq!(stop != 0, chaotic, "{orbit:?}: stopped after step {stop}");
        if chaotic {
            assert_eq!(stop % 10, 0, "a stop between samples: {stop}");
            assert!(o.sali[0] < 1e-8 && o.sali[0] >= 0.0, "SALI {}", o.sali[0]);
        }
        if let Some(ctx) = common::gpu() {
            let g = gpu::run::<f64>(ctx, &plan, None).unwrap().observations;
            assert_eq!(g.stop_step[0], stop, "{orbit:?}: the GPU's stop");
        }
    }
}

/// Bad settings are refused before any work, at their line and field.
#[test]
fn bad_alignment_settings_are_refused_at_their_field() {
    let dir = common::runs::tmp("alignment", "refused");
    let base = "name = \"x\"\nmodel = \"van_der_pol\"\n[params]\nepsilon = 1.0\n[integrator]\nscheme = \"s2\"\ndt = 0.01\nsteps = 100\n[output]\n";
    for (line, field) in [
        ("gali = { k = 1 }", "output.gali.k: 1 is below 2"),
        (
            "gali = { k = 3 }",
            "output.gali.k: 3 is more than the tangent dimension 2",
        ),
        (
            "gali = { every = 0 }",
            "output.gali.every: must be at least 1",
        ),
        (
            "sali = { every = 101 }",
            "output.sali.every: 101 is more than the 100 steps",
        ),
        (
            "sali = { every = 2 }\ngali = { k = 2, every = 3 }",
            "output.gali.every: 3 differs from output.sali.every = 2",
        ),
        ("gali = { k = -2 }", "output.gali.k"),
        ("gali = { vectors = 2 }", "vectors"),
        ("sali = 3", "output.sali"),
    ] {
        let path = dir.join("s.toml");
        std::fs::write(&path, format!("{base}{line}\n")).unwrap();
        let e = reeb::scene::Scene::load(&path).unwrap_err().to_string();
        assert!(e.contains(":10: ") || e.contains(":11: "), "{line}: {e}");
        assert!(e.contains(field), "{line}: {e}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
