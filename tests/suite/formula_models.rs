//! Formula models against the built-in models they re-express (issue 11,
//! point 5): the damped oscillator, forced van der Pol, Kepler, Lane–Emden
//! and spin–orbit (its Cayley sum written out) as `mechanical`/`lienard`
//! scenes agree with the built-in scene over 1000 steps: to 1e-12 relative
//! in f64 and within the backends' f32 tolerance (tests/gpu.rs), on the CPU
//! and on the GPU.

use std::path::Path;

use reeb::backend::{cpu, gpu};
use reeb::models::spin_orbit::CAYLEY;
use reeb::num::precision::Real;
use reeb::plan::observations::Observations;
use reeb::plan::Plan;
use reeb::scene::Scene;

use crate::common;

/// The single plan of a scene text.
fn plan(text: &str) -> Plan {
    let s = Scene::parse(Path::new("test.toml"), text).unwrap_or_else(|e| panic!("{e}"));
    let mut subs = s.sub_runs().unwrap();
    assert_eq!(subs.len(), 1);
    subs.remove(0).plan
}

/// Largest relative difference (scaled by max(1, |x|)) of the final values.
fn worst<R: Real, S: Real>(a: &Observations<R>, b: &Observations<S>) -> (f64, String) {
    assert_eq!(a.nonfinite_step, b.nonfinite_step, "status");
    let mut w = (0.0f64, String::new());
    for ((name, x), (_, y)) in a.final_values.iter().zip(&b.final_values) {
        for (i, (u, v)) in x.iter().zip(y).enumerate() {
            let (u, v) = (u.to_f64(), v.to_f64());
            let d = (u - v).abs() / v.abs().max(1.0);
            if d > w.0 || d.is_nan() {
                w = (d, format!("{name}[{i}]: {u:e} vs {v:e}"));
            }
        }
    }
    w
}

/// A pair of scenes: the built-in model and its formula twin, sharing the
/// integrator, initial values and outputs.
struct Pair {
    name: &'static str,
    builtin: String,
    formula: String,
}

fn tail(initial: &str, outputs: &str, scheme: &str, dt: f64) -> String {
    format!("[initial]\n{initial}\n[integrator]\nscheme = \"{scheme}\"\ndt = {dt}\nsteps = 1000\n[output]\nfinal = {outputs}\n")
}

fn pairs(scheme: &str) -> Vec<Pair> {
    let mut out = vec![];
    let osc_tail = tail(
        "q = { linspace = [0.5, 1.5, 5] }\np = 0.5",
        "[\"q\", \"p\", \"s\"]",
        scheme,
        0.01,
    );
    out.push(Pair {
        name: "damped_oscillator",
        builtin: format!("model = \"damped_oscillator\"\n[params]\nalpha = 0.3\nforcing_amplitude = 0.5\nforcing_frequency = 1.3\n{osc_tail}"),
        formula: format!("model = \"mechanical\"\n[formula]\npotential = \"q^2/2 - beta*sin(omega*t)*q\"\ndamping = \"alpha\"\n[params]\nalpha = 0.3\nbeta = 0.5\nomega = 1.3\n{osc_tail}"),
    });
    // The comparison integrators carry no p of a Liénard system.
    let method = matches!(scheme, "rk4" | "leapfrog");
    let vdp_tail = tail(
        "q = { linspace = [1.0, 2.0, 5] }\ns = 2.0\np = 0.3",
        if method {
            "[\"q\", \"s\"]"
        } else {
            "[\"q\", \"s\", \"p\"]"
        },
        scheme,
        0.01,
    );
    out.push(Pair {
        name: "van_der_pol",
        builtin: format!("model = \"van_der_pol\"\n[params]\nepsilon = 1.5\nforcing_amplitude = 0.5\nforcing_frequency = 1.1\n{vdp_tail}"),
        formula: format!("model = \"lienard\"\n[formula]\nf = \"-epsilon*(1 - q^2)\"\ng = \"q - A*cos(omega*t)\"\n[params]\nepsilon = 1.5\nA = 0.5\nomega = 1.1\n{vdp_tail}"),
    });
    let kep_tail = tail(
        "q1 = { linspace = [0.6, 1.0, 5] }\nq2 = 0.0\np1 = 0.0\np2 = 1.2",
        "[\"q\", \"p\", \"s\"]",
        scheme,
        0.01,
    );
    out.push(Pair {
        name: "kepler",
        builtin: format!("model = \"kepler\"\n[params]\nalpha = 0.01\ntheta = 6.283185307179586\n{kep_tail}"),
        formula: format!("model = \"mechanical\"\n[formula]\ndof = 2\npotential = \"-1/sqrt(q1^2 + q2^2)\"\ndamping = \"alpha*sin(theta*t)\"\n[params]\nalpha = 0.01\ntheta = 6.283185307179586\n{kep_tail}"),
    });
    let le_tail = tail(
        "q = 1.0\np = { linspace = [0.0, 0.1, 3] }",
        "[\"q\", \"p\", \"s\"]",
        scheme,
        0.005,
    );
    out.push(Pair {
        name: "lane_emden",
        builtin: format!("model = \"lane_emden\"\n[params]\nindex = 3\n{le_tail}"),
        formula: format!("model = \"mechanical\"\n[formula]\npotential = \"q^4/4\"\ndamping = \"2/t\"\n{le_tail}"),
    });
    let so_params = "eccentricity = 0.1\nepsilon = 0.05\nlambda = 0.1\nomega = 1.0\ntidal_k = 0.001\ntidal_eta = 1.0";
    let so_tail = tail(
        "q = { linspace = [0.0, 1.0, 5] }\np = 1.1",
        "[\"q\", \"p\", \"s\"]",
        scheme,
        0.05,
    );
    out.push(Pair {
        name: "spin_orbit",
        builtin: format!("model = \"spin_orbit\"\n[params]\n{so_params}\n{so_tail}"),
        formula: format!("model = \"mechanical\"\n[formula]\npotential = \"{}\"\ndamping = \"tidal_k - lambda*omega*sin(omega*t)/(1 + lambda*cos(omega*t))\"\n[params]\n{so_params}\n{so_tail}", spin_orbit_potential()),
    });
    out
}

/// `V(q, t) = −(ε/2) pref Σ_m W_m(e) cos(2q − m t) − K η q` with the Cayley
/// table written out (SPEC §2.1).
pub fn spin_orbit_potential() -> String {
    let sum: Vec<String> = CAYLEY
        .iter()
        .map(|(m, terms)| {
            let w: Vec<String> = terms
                .iter()
                .map(|(k, c)| format!("{c:?}*eccentricity^{k}"))
                .collect();
            format!("({})*cos(2*q - {m}*t)", w.join(" + "))
        })
        .collect();
    format!(
        "-epsilon/2/(1 + lambda*cos(omega*t))*({}) - tidal_k*tidal_eta*q",
        sum.join(" + ")
    )
}

#[test]
fn formula_models_agree_with_the_built_ins_on_the_cpu() {
    let schemes = [
        "s2",
        "yoshida6a",
        "rk4",
        "leapfrog",
        "variational1",
        "variational2",
    ];
    for scheme in schemes {
        for pair in pairs(scheme) {
            // The contact variational integrators are for mechanical systems.
            if pair.name == "van_der_pol" && scheme.starts_with("variational") {
                continue;
            }
            // RK4 and the leapfrog evaluate f(t) = 2/t at t = 0, where the
            // built-in takes the limit of f·p and a formula cannot.
            if pair.name == "lane_emden" && scheme != "s2" && scheme != "yoshida6a" {
                continue;
            }
            let (b, f) = (plan(&pair.builtin), plan(&pair.formula));
            assert!(f.model.formula().is_some());
            let w = worst(&cpu::run::<f64>(&f, None), &cpu::run::<f64>(&b, None));
            println!("{} {scheme} f64 cpu: {:.2e} ({})", pair.name, w.0, w.1);
            assert!(
                w.0 <= f64_tol(scheme),
                "{} {scheme} f64: {:e} at {}",
                pair.name,
                w.0,
                w.1
            );
            let w = worst(&cpu::run::<f32>(&f, None), &cpu::run::<f64>(&b, None));
            println!("{} {scheme} f32 cpu: {:.2e} ({})", pair.name, w.0, w.1);
            assert!(
                w.0 <= F32_TOL,
                "{} {scheme} f32: {:e} at {}",
                pair.name,
                w.0,
                w.1
            );
        }
    }
}

/// 1e-12 over 1000 S2 steps; Yoshida 6A makes 7 stages a step, and the
/// spin–orbit formulas (`cos(2q − mt)` directly) round differently from the
/// built-in's (Chebyshev recurrences for `cos mt`): 1e-11 there.
fn f64_tol(scheme: &str) -> f64 {
    if scheme == "s2" {
        1e-12
    } else {
        1e-11
    }
}

/// The f32 tolerance over 1000 steps, against the built-in model in f64:
/// a few ULP per step, growing at most linearly (1000 steps × a few 2⁻²⁴),
/// more on trajectories that amplify errors. The reference is the f64 run,
/// not the built-in's f32 run: on the spin–orbit trajectory `p = 1.1` the
/// built-in's own f32 error is 2.3e-3 with Yoshida 6A, so two correct f32
/// programs may differ by more than either errs.
const F32_TOL: f64 = 2e-3;

#[test]
fn formula_models_agree_with_the_built_ins_on_the_gpu() {
    let Some(ctx) = common::gpu() else { return };
    let pairs = pairs("s2")
        .into_iter()
        .chain(pairs("rk4").into_iter().filter(|p| p.name != "lane_emden"));
    for pair in pairs {
        let (b, f) = (plan(&pair.builtin), plan(&pair.formula));
        let run64 = |p: &Plan| gpu::run::<f64>(ctx, p, None).map(|r| r.observations);
        match (run64(&f), run64(&b)) {
            (Ok(fo), Ok(bo)) => {
                let w = worst(&fo, &bo);
                println!("{} f64 gpu: {:.2e} ({})", pair.name, w.0, w.1);
                assert!(w.0 <= 1e-12, "{} f64 gpu: {:e} at {}", pair.name, w.0, w.1);
                // And the formula model on both backends.
                let w = worst(&fo, &cpu::run::<f64>(&f, None));
                assert!(
                    w.0 <= 1e-12,
                    "{} f64 gpu vs cpu: {:e} at {}",
                    pair.name,
                    w.0,
                    w.1
                );
            }
            (Err(e), _) | (_, Err(e)) => println!("{}: no f64 on this adapter: {e}", pair.name),
        }
        let fo = gpu::run::<f32>(ctx, &f, None).unwrap().observations;
        let w = worst(&fo, &cpu::run::<f64>(&b, None));
        println!("{} f32 gpu: {:.2e} ({})", pair.name, w.0, w.1);
        assert!(
            w.0 <= F32_TOL,
            "{} f32 gpu: {:e} at {}",
            pair.name,
            w.0,
            w.1
        );
    }
}

/// Where the ensemble shares `t0` and `dt`, a formula model's shared values
/// at a step (the forcing, spin–orbit's Cayley sums and `pref`, Lane–Emden's
/// `2/t`) come from the host's table per window (`backend/gpu/time_table.rs`)
/// as on the CPU: the kernel's per-trajectory step no longer reads the step
/// number, and windows of any length agree with the CPU. A `dt` along an
/// axis keeps the time per trajectory.
#[test]
fn formula_time_terms_come_from_a_table_on_the_gpu() {
    use reeb::backend::gpu::codegen::generate;
    use reeb::num::precision::Precision;
    let Some(ctx) = common::gpu() else { return };
    let reads_step = |source: &str| {
        let sig = source
            .split("fn formula_step(")
            .nth(1)
            .expect("formula_step");
        sig.split(')').next().unwrap().contains("nf: R")
    };
    for scheme in ["s2", "yoshida6a"] {
        for pair in pairs(scheme) {
            let label = format!("{} {scheme}", pair.name);
            let f = plan(&pair.formula);
            let kernel = generate(&f, Precision::F32).unwrap();
            let tt = kernel.time_table.as_ref();
            assert!(tt.is_some(), "{label}: no time table");
            assert!(!reads_step(&kernel.source), "{label}: time per trajectory");
            for window in [Some(1), Some(7), None] {
                let opts = gpu::GpuOptions {
                    max_chunk: None,
                    max_steps_per_dispatch: window,
                    ..Default::default()
                };
                let g = gpu::run_with::<f32>(ctx, &f, None, &opts).unwrap();
                let w = worst(&g.observations, &cpu::run::<f32>(&f, None));
                println!(
                    "{label} window {window:?} f32 gpu vs cpu: {:.2e} ({})",
                    w.0, w.1
                );
                assert!(
                    w.0 <= 1e-4,
                    "{label} window {window:?} f32: {:e} at {}",
                    w.0,
                    w.1
                );
                if !ctx.shader_f64 {
                    continue;
                }
                let g = gpu::run_with::<f64>(ctx, &f, None, &opts).unwrap();
                let w = worst(&g.observations, &cpu::run::<f64>(&f, None));
                println!(
                    "{label} window {window:?} f64 gpu vs cpu: {:.2e} ({})",
                    w.0, w.1
                );
                assert!(
                    w.0 <= 1e-12,
                    "{label} window {window:?} f64: {:e} at {}",
                    w.0,
                    w.1
                );
            }
        }
    }
    // dt along an axis: the step reads its number, and agrees all the same.
    let forced = &pairs("s2")[1].formula;
    let f = plan(&forced.replace("dt = 0.01", "dt = [0.01, 0.02]"));
    assert!(f.on_axis("dt"));
    let kernel = generate(&f, Precision::F32).unwrap();
    assert!(kernel.time_table.is_none() && reads_step(&kernel.source));
    let g = gpu::run::<f32>(ctx, &f, None).unwrap();
    let w = worst(&g.observations, &cpu::run::<f32>(&f, None));
    assert!(w.0 <= 1e-4, "dt axis f32: {:e} at {}", w.0, w.1);
}

/// A scene's error (or warnings) for a formula model given by its tables.
fn refused(formula: &str, params: &str) -> String {
    let text = format!("model = \"mechanical\"\n[formula]\n{formula}\n[params]\n{params}\n[integrator]\nscheme = \"s2\"\ndt = 0.1\nsteps = 10\n");
    match Scene::parse(Path::new("bad.toml"), &text) {
        Ok(_) => "accepted".into(),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_formulas_are_refused_at_their_line_with_a_caret() {
    let e = refused("potential = \"q^2/2 +* q\"", "");
    assert!(
        e.starts_with("bad.toml:3: formula.potential: column"),
        "{e}"
    );
    assert!(e.contains("\n    q^2/2 +* q\n"), "{e}");
    assert!(e.lines().last().unwrap().trim_start() == "^", "{e}");
    let e = refused("potential = \"epsilom*q^2\"", "epsilon = 1.0");
    assert!(e.contains("did you mean `epsilon`"), "{e}");
    let e = refused("potential = \"q^2 + sn(q)\"", "");
    assert!(e.contains("did you mean `sin`"), "{e}");
    let e = refused("potential = \"q1^2 + q2^2\"", "");
    assert!(e.contains("dof = 1") && e.contains("`q1`"), "{e}");
    let e = refused("dof = 2\npotential = \"q^2\"", "");
    assert!(e.contains("dof = 2"), "{e}");
    let e = refused("potential = \"epsilon*p^2\"", "epsilon = 1.0");
    assert!(e.contains("cannot depend on `p`"), "{e}");
    assert!(
        e.ends_with("\n            ^"),
        "caret under the p of p^2, not of epsilon: {e}"
    );
    let e = refused("kinetic = \"q*p^2\"", "");
    assert!(
        e.contains("formula.kinetic") && e.contains("cannot depend on `q`"),
        "{e}"
    );
    let e = refused("dof = 9", "");
    assert!(e.contains("formula.dof"), "{e}");
    let e = refused("potentail = \"q^2\"", "");
    assert!(e.contains("did you mean `potential`"), "{e}");
    let e = refused("potential = \"q^2\"", "sin = 1.0");
    assert!(e.contains("params.sin"), "{e}");
}

#[test]
fn an_unused_parameter_is_a_warning_and_a_non_finite_value_a_stopped_trajectory() {
    let text = "model = \"mechanical\"\n[formula]\npotential = \"q^2/2 + sqrt(q)\"\n[params]\nunused = 2.0\n[initial]\nq = { linspace = [-1.0, 1.0, 3] }\n[integrator]\nscheme = \"s2\"\ndt = 0.1\nsteps = 10\n";
    let checks = |text: &str| {
        let s = Scene::parse(Path::new("w.toml"), text).unwrap();
        s.checks(reeb::num::precision::Precision::F64)
    };
    let w = checks(&text.replace(" + sqrt(q)", "")).unwrap();
    assert!(
        w.iter()
            .any(|w| w.field == "params.unused" && w.line == Some(5)),
        "{w:?}"
    );
    // √q is not defined where q = −1 starts: the scene is refused…
    let e = checks(text).unwrap_err();
    assert_eq!((e.field.as_str(), e.line), ("formula.potential", Some(3)));
    assert!(
        e.message
            .starts_with("V is NaN where a trajectory starts (q = -1"),
        "{e}"
    );
    // …and a plan run anyway stops there: √q at q = −1 (NaN) and its
    // derivative at 0 (∞) stop, q = 1 runs on.
    let o = cpu::run::<f64>(&plan(text), None);
    assert_eq!(o.nonfinite_step[..2], [1, 1]);
    assert_eq!(o.nonfinite_step[2], 0);
}

/// The step's time terms are shared by the ensemble only when `t0` and
/// `dt` are the same for every trajectory; with either as an axis (and a
/// parameter as another) they are per trajectory, and the composed step
/// must still be the built-in model's.
#[test]
fn time_and_parameters_as_axes_agree_with_the_built_in() {
    let tail = "[initial]\nq = 1.2\ns = 0.0\np = 0.3\nt0 = [0.0, 3.7]\n[integrator]\nscheme = \"s2\"\ndt = [0.01, 0.013, 0.02]\nsteps = 500\n[output]\nfinal = [\"q\", \"s\", \"p\"]\n";
    let builtin = format!("model = \"van_der_pol\"\n[params]\nepsilon = [0.5, 1.5]\nforcing_amplitude = 0.5\nforcing_frequency = 1.1\n{tail}");
    let formula = format!("model = \"lienard\"\n[formula]\nf = \"-epsilon*(1 - q^2)\"\ng = \"q - A*cos(omega*t)\"\n[params]\nepsilon = [0.5, 1.5]\nA = 0.5\nomega = 1.1\n{tail}");
    let (b, f) = (plan(&builtin), plan(&formula));
    assert_eq!(f.n, 12);
    let w = worst(&cpu::run::<f64>(&f, None), &cpu::run::<f64>(&b, None));
    assert!(w.0 <= 1e-12, "{:e} at {}", w.0, w.1);
}

/// The interpreter compiled for each instruction-set level gives the same
/// bits (no contraction into FMA; reeb's functions use exact FMA anyway).
#[test]
fn formula_models_give_the_same_bits_at_every_instruction_set_level() {
    use reeb::backend::cpu::{isa, run_isa, Isa};
    let levels: Vec<Isa> = [Isa::V3, Isa::V4]
        .into_iter()
        .filter(|l| {
            matches!(
                (l, isa()),
                (Isa::V3, Isa::V3 | Isa::V4) | (Isa::V4, Isa::V4)
            )
        })
        .collect();
    for pair in pairs("s2") {
        let f = plan(&pair.formula);
        let base = run_isa::<f64>(&f, None, Isa::Baseline);
        for l in &levels {
            let o = run_isa::<f64>(&f, None, *l);
            assert_eq!(o.final_values, base.final_values, "{} at {l:?}", pair.name);
        }
    }
}

/// `reeb verify SCENE` on the Duffing scene (issue 11, "done when"): the
/// measured orders of S2 and Yoshida 6A against DOP853 within ±0.2 of 2 and
/// 6, and the CPU–GPU agreement, in f64 and in f32.
#[test]
fn verify_measures_the_orders_of_the_duffing_scene() {
    use reeb::backend::Engine;
    use reeb::num::precision::Precision;
    use reeb::verify::Target;
    let text = std::fs::read_to_string("scenes/duffing.toml").unwrap();
    let scene = Scene::parse(Path::new("scenes/duffing.toml"), &text).unwrap();
    let gpu = common::gpu().is_some();
    for precision in [Precision::F64, Precision::F32] {
        let target = Target {
            engine: Engine::Cpu,
            precision,
        };
        let rows = reeb::verify_scene::run_scene(&scene, &target, |_| {});
        for r in &rows {
            println!("{precision:?} {} {} {}", r.name, r.measured, r.tolerance);
            assert!(r.pass, "{precision:?}: {r:?}");
        }
        let order = |s: &str| {
            rows.iter()
                .find(|r| r.name.starts_with(&format!("order of {s} ")))
                .map(|r| r.measured.parse::<f64>().unwrap())
        };
        assert!((order("s2").unwrap() - 2.0).abs() <= 0.2);
        if precision == Precision::F64 {
            assert!((order("yoshida6a").unwrap() - 6.0).abs() <= 0.2);
        }
        let agreement = rows.iter().any(|r| r.name.starts_with("CPU–GPU agreement"));
        assert_eq!(
            agreement, gpu,
            "the agreement row exactly when a GPU is there"
        );
    }
}

/// ln of a negative number is NaN on every backend, so an orbit whose
/// force takes one stops at the same step on the GPU as on the CPU (in
/// lavapipe's programs the NaN was once ∞·0, which its compiler folds to
/// 0: those orbits ran on). V′ = q + 0.01·(log(q + 2) + q/(q + 2)): NaN or
/// ±∞ from q ≤ −2 (the first three orbits), finite above.
#[test]
fn a_logarithm_of_a_negative_number_stops_the_orbit_on_every_backend() {
    let text = "model = \"mechanical\"\n[formula]\npotential = \"q^2/2 + 0.01*q*log(q + 2)\"\n[initial]\nq = { linspace = [-3.0, 1.0, 9] }\n[integrator]\nscheme = \"s2\"\ndt = 0.01\nsteps = 10\n";
    let f = plan(text);
    let cpu64 = cpu::run::<f64>(&f, None).nonfinite_step;
    assert!(cpu64[..3].iter().all(|&s| s == 1), "{cpu64:?}");
    assert!(cpu64[3..].iter().all(|&s| s == 0), "{cpu64:?}");
    assert_eq!(cpu::run::<f32>(&f, None).nonfinite_step, cpu64);
    let Some(ctx) = common::gpu() else { return };
    let g32 = gpu::run::<f32>(ctx, &f, None).unwrap().observations;
    assert_eq!(g32.nonfinite_step, cpu64, "GPU f32");
    match gpu::run::<f64>(ctx, &f, None) {
        Ok(g) => assert_eq!(g.observations.nonfinite_step, cpu64, "GPU f64"),
        Err(e) => println!("no f64 on this adapter: {e}"),
    }
}
