//! The observers of issue 32 — stop conditions, time averages, resonance
//! capture — against a plain reimplementation from the recorded trajectory
//! (every step), on the CPU and the GPU (f64: the same stop steps, values
//! to round-off), and their refusals of bad input.

use std::path::Path;

use reeb::backend::gpu::{self, GpuContext};
use reeb::backend::Engine;
use reeb::plan::observations::Observations;
use reeb::plan::Plan;
use reeb::scene::Scene;

use crate::common;
use common::runs::{reeb, s, tmp};

/// A damped oscillator over 8 initial positions × 3 dampings, every step
/// recorded; `output` adds to `[output]`.
fn damped(output: &str) -> String {
    format!(
        r#"
model = "damped_oscillator"
[params]
alpha = [0.05, 0.2, 0.6]
[initial]
q = {{ linspace = [-2.0, 2.0, 8] }}
p = 0.3
[integrator]
scheme = "yoshida6a"
dt = 0.05
steps = 600
[output]
final = ["q", "p", "t"]
trajectory = {{ every = 1, vars = ["q", "p", "t"] }}
{output}
[run]
precision = "f64"
"#
    )
}

fn plan(text: &str) -> Plan {
    let s = Scene::parse(Path::new("test.toml"), text).unwrap_or_else(|e| panic!("{e}"));
    s.sub_runs().unwrap().remove(0).plan
}

fn cpu(p: &Plan) -> Observations<f64> {
    Engine::Cpu.run::<f64>(p, None).unwrap().observations
}

fn on_gpu(ctx: &GpuContext, p: &Plan) -> Observations<f64> {
    gpu::run_resumable::<f64>(ctx, p, None, &Default::default(), None)
        .unwrap()
        .observations
}

/// Trajectory `i`'s recorded values of `var` (steps 0…).
fn frames<'a>(o: &'a Observations<f64>, var: &str, i: usize) -> &'a [f64] {
    let all = o.trajectory_of(var).unwrap();
    &all[i * o.frames..(i + 1) * o.frames]
}

#[test]
fn a_trajectory_stops_after_the_first_step_at_which_the_condition_holds() {
    // Every trajectory crosses p = 0.5 sooner or later; those from q < 0 first.
    let stop = plan(&damped("stop = \"p - 0.5 > 0.2*alpha\""));
    let free = cpu(&plan(&damped("")));
    let o = cpu(&stop);
    let mut stopped = 0;
    for i in 0..o.n {
        let alpha = [0.05, 0.2, 0.6][i / 8];
        let p = frames(&free, "p", i);
        // The plain check: the first step (≥ 1) whose end satisfies it.
        let first = (1..p.len()).find(|&n| p[n] - 0.5 > 0.2 * alpha);
        assert_eq!(o.nonfinite_step[i], 0);
        match first {
            None => assert_eq!(o.stop_step[i], 0, "trajectory {i}"),
            Some(n) => {
                stopped += 1;
                assert_eq!(o.stop_step[i] as usize, n, "trajectory {i}");
                // Final values: the state where it stopped, bitwise.
                for var in ["q", "p", "t"] {
                    let want = frames(&free, var, i)[n];
                    assert_eq!(o.final_of(var).unwrap()[i], want, "{var} of {i}");
                }
                // Its observers end there: frames up to n, NaN after.
                let q = frames(&o, "q", i);
                assert_eq!(q[n], frames(&free, "q", i)[n]);
                assert!(q[n + 1..].iter().all(|x| x.is_nan()), "trajectory {i}");
            }
        }
    }
    assert!(stopped > 0 && stopped < o.n, "{stopped} of {} stopped", o.n);
    assert_eq!(o.count_stopped(), stopped);
    assert_eq!(o.count_ok(), o.n - stopped);
}

#[test]
fn time_averages_are_plain_means_of_the_steps_after_the_skip() {
    let o = cpu(&plan(&damped(
        "average = { vars = [\"q\", \"p\"], skip = 0.25 }\nstop = \"t > 20 + 10*alpha\"",
    )));
    let start = (0.25 * 600.0_f64).floor() as usize;
    for i in 0..o.n {
        let last = match o.stop_step[i] {
            0 => 600,
            n => n as usize,
        };
        for var in ["q", "p"] {
            let x = &frames(&o, var, i)[start + 1..=last];
            let plain = x.iter().sum::<f64>() / x.len() as f64;
            let mean = o.mean_of(var).unwrap()[i];
            assert!(
                (mean - plain).abs() <= 1e-13 * plain.abs().max(1.0),
                "{var}[{i}]: {mean} vs {plain}"
            );
        }
    }
    // t > 20 + 10α stops the α = 0.6 ones (t_end = 30 < 26 is false for the rest).
    assert!(o.stop_step.iter().any(|s| *s != 0));
}

#[test]
fn a_trajectory_stopped_before_the_averaging_window_has_no_mean() {
    let o = cpu(&plan(&damped(
        "average = { vars = [\"q\"], skip = 0.5 }\nstop = \"t > 5\"",
    )));
    assert!(o.mean_of("q").unwrap().iter().all(|m| m.is_nan()));
    assert!(o.stop_step.iter().all(|s| *s == 101));
}

#[test]
fn the_backends_agree_on_stops_and_averages() {
    let Some(ctx) = common::gpu() else { return };
    let p = plan(&damped(
        "average = [\"q\", \"p\"]\nstop = \"q^2 + p^2 < 0.8 - alpha\"\nresonance = { var = \"p\", ratios = [[1, 8]], tolerance = 0.5 }",
    ));
    let (c, g) = (cpu(&p), on_gpu(ctx, &p));
    assert_eq!(c.stop_step, g.stop_step);
    assert_eq!(c.nonfinite_step, g.nonfinite_step);
    assert!(c.stop_step.iter().any(|s| *s != 0));
    let close = |a: &[f64], b: &[f64], what: &str| {
        for (x, y) in a.iter().zip(b) {
            assert!(
                (x.is_nan() && y.is_nan()) || (x - y).abs() <= 1e-12 * y.abs().max(1.0),
                "{what}: cpu {x} gpu {y}"
            );
        }
    };
    for v in ["q", "p", "t"] {
        close(c.final_of(v).unwrap(), g.final_of(v).unwrap(), v);
        close(c.trajectory_of(v).unwrap(), g.trajectory_of(v).unwrap(), v);
    }
    for v in ["q", "p"] {
        close(c.mean_of(v).unwrap(), g.mean_of(v).unwrap(), v);
    }
}

#[test]
fn resonances_and_their_fractions_reach_the_files_and_the_summary() {
    let dir = tmp("observers", "resonance");
    let scene = dir.join("res.toml");
    // The mean of p over the run is (q_end − q0)/30, within 0.07 of 0:
    // 1:40 (0.025) within 0.03 of it for some q0 < 0, none for others (and a
    // ratio 7:1 that nothing reaches).
    let text = damped(
        "average = { vars = [\"p\"], skip = 0.0 }\nresonance = { var = \"p\", ratios = [[7, 1], [1, 40]], tolerance = 0.03 }",
    )
    .replace("trajectory = { every = 1, vars = [\"q\", \"p\", \"t\"] }", "");
    std::fs::write(&scene, &text).unwrap();
    let out = dir.join("out");
    let run = reeb(&["run", s(&scene), "--out", s(&out), "--backend", "cpu"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let mean = read_f64(&out.join("mean_p.npy"));
    let index = read_i32(&out.join("resonance.npy"));
    let plain = |m: f64| {
        if (m - 7.0).abs() <= 0.03 {
            0
        } else if (m - 0.025).abs() <= 0.03 {
            1
        } else {
            -1
        }
    };
    assert_eq!(index, mean.iter().map(|m| plain(*m)).collect::<Vec<_>>());
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let r = &summary["resonance"];
    let count = |k: i32| index.iter().filter(|i| **i == k).count() as u64;
    assert_eq!(r["counts"]["7:1"], count(0));
    assert_eq!(r["counts"]["1:40"], count(1));
    assert_eq!(r["counts"]["none"], count(-1));
    assert!(count(1) > 0 && count(-1) > 0, "{index:?}");
    let fraction = r["fractions"]["1:40"].as_f64().unwrap();
    assert_eq!(fraction, count(1) as f64 / 24.0);
    let files = summary["files"].as_array().unwrap();
    for picture in ["resonance.png", "capture.png", "mean_p.png"] {
        assert!(files.iter().any(|f| f == picture), "{picture} in {files:?}");
        assert!(out.join(picture).is_file());
    }
    let dims = &summary["dims"];
    assert_eq!(dims["mean_p"], serde_json::json!(["alpha", "q"]));
    assert_eq!(dims["resonance"], serde_json::json!(["alpha", "q"]));
    std::fs::remove_dir_all(&dir).unwrap();
}

fn read_f64(path: &Path) -> Vec<f64> {
    common::npy_f64(path)
}

fn read_i32(path: &Path) -> Vec<i32> {
    common::npy_ints(path)
}

#[test]
fn bad_observers_are_refused_at_their_field() {
    let cases = [
        (
            "stop = \"q + x > 1\"",
            "output.stop: column 5: unknown name `x`",
        ),
        (
            "stop = \"q > 1 > 2\"",
            "output.stop: column 7: one comparison",
        ),
        (
            "stop = \"q + 1\"",
            "output.stop: column 1: needs a comparison",
        ),
        (
            "stop = \"sinn(q) > 1\"",
            "output.stop: column 1: unknown function",
        ),
        ("stop = { if = \"q > 1\" }", "output.stop.if: unknown key"),
        // An indicator switched off is not a name a stop condition reads
        // (it reached the CPU backend once, and panicked there).
        (
            "megno = false\nstop = \"megno > 2\"",
            "output.stop: column 1: unknown name `megno`",
        ),
        (
            "average = [\"x\"]",
            "output.average: model `damped_oscillator` has no variable `x`",
        ),
        ("average = [\"t\"]", "output.average: time has no average"),
        (
            "average = { vars = [\"q\"], skip = 1.0 }",
            "output.average.skip: must be in [0, 1)",
        ),
        (
            "resonance = { var = \"p\", ratios = [[0, 1]], tolerance = 0.1 }",
            "output.resonance.ratios: 0:1 has a term ≤ 0",
        ),
        (
            "resonance = { var = \"p\", ratios = [[1, -2]], tolerance = 0.1 }",
            "output.resonance.ratios: 1:-2 has a term ≤ 0",
        ),
        (
            "resonance = { var = \"p\", ratios = [[1, 1]], tolerance = 0.0 }",
            "output.resonance.tolerance: 0 must be a number > 0",
        ),
        (
            "resonance = { var = \"t\", ratios = [[1, 1]], tolerance = 0.1 }",
            "output.resonance.var: `t` has no average",
        ),
        (
            "resonance = { var = \"p\", ratios = [[1, 1]] }",
            "output.resonance: needs tolerance",
        ),
    ];
    for (line, want) in cases {
        let text = damped(line);
        let e = match Scene::parse(Path::new("bad.toml"), &text) {
            Err(e) => e.to_string(),
            Ok(s) => match s.sub_runs() {
                Err(e) => e.to_string(),
                Ok(_) => "accepted".into(),
            },
        };
        assert!(e.contains(want), "{line}: {e}");
        assert!(e.starts_with("bad.toml:"), "{line}: {e}");
    }
}

#[test]
fn a_bad_stop_shows_the_condition_with_a_caret() {
    let e = Scene::parse(Path::new("bad.toml"), &damped("stop = \"q^2 + pp^2 > 4\""))
        .unwrap_err()
        .to_string();
    assert!(
        e.ends_with("(did you mean `p`?); known here: q, p, s, t, alpha, pi\n    q^2 + pp^2 > 4\n          ^"),
        "{e}"
    );
}
