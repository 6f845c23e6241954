//! The command line refuses what it cannot do, with a message naming the
//! argument or field, instead of panicking, aborting or hanging.

use std::process::Command;

use crate::common;

fn reeb(args: &[&str], env: &[(&str, &str)]) -> (bool, String) {
    let mut c = Command::new(env!("CARGO_BIN_EXE_reeb"));
    c.args(args);
    for (k, v) in env {
        c.env(k, v);
    }
    let out = c.output().expect("reeb runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn bench_refuses_arguments_it_cannot_run() {
    for (arg, value, says) in [
        ("--n", "0", "--n: an ensemble needs at least 1"),
        (
            "--n",
            "1000000000000000",
            "--n: 1000000000000000 trajectories need about",
        ),
        ("--steps", "0", "--steps: 0 is not between 1"),
        ("--threads", "0", "--threads:"),
        ("--threads", "100000", "--threads: 100000 threads on"),
        ("--repeats", "0", "--repeats:"),
        ("--every", "2", "--every: only with --indicators"),
    ] {
        let (ok, err) = reeb(
            &[
                "bench",
                "--backend",
                "cpu",
                "--scenario",
                "van_der_pol/s2",
                arg,
                value,
            ],
            &[],
        );
        assert!(!ok, "{arg} {value} was accepted");
        assert!(err.contains(says), "{arg} {value}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}

#[test]
fn bench_indicators_refuses_what_it_does_not_use() {
    for (args, says) in [
        (&["--n", "100"][..], "--n: not used with --indicators"),
        (
            &["--scenario", "van_der_pol/s2"],
            "--scenario: not used with --indicators",
        ),
        (&["--threads", "1"], "--threads: not used with --indicators"),
        (&["--steps", "0"], "--steps: 0 is not between 1"),
        (&["--repeats", "0"], "--repeats:"),
        (&["--backend", "fpga"], "--backend: unknown backend `fpga`"),
        (&["--every", "0"], "--every: 0 is not between 1 and the"),
        (
            &["--steps", "3", "--every", "5"],
            "--every: 5 is not between 1 and the 3 steps",
        ),
    ] {
        let mut a = vec!["bench", "--indicators"];
        a.extend(args);
        let (ok, err) = reeb(&a, &[]);
        assert!(!ok, "{args:?} was accepted");
        assert!(err.contains(says), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// Every indicator on both cost scenes, a row each, on the CPU and (where
/// an adapter exists) the GPU: a few steps, so only that it runs and what
/// it reports, not the cost, which is a benchmark's.
#[test]
fn bench_indicators_reports_every_indicator_on_both_scenes() {
    let dir = common::runs::tmp("cli", "bench-indicators");
    let mut backends = vec!["cpu"];
    if common::gpu().is_some() {
        backends.push("gpu");
    }
    for backend in backends {
        let json = dir.join(format!("{backend}.jsonl"));
        let rows = bench_indicator_rows(backend, &json, &["--steps", "3"]);
        for (r, scene) in rows.iter().zip(
            ["van_der_pol/triple_jump4"; 4]
                .iter()
                .chain(&["spin_orbit/s2"; 4]),
        ) {
            assert_eq!(r["scene"], *scene);
            assert_eq!(r["steps"], 3);
            let ratio = r["ratio"].as_f64().unwrap();
            assert!(ratio.is_finite() && ratio > 0.0, "{r}");
        }
        let indicators: Vec<&str> = rows[..4]
            .iter()
            .map(|r| r["indicator"].as_str().unwrap())
            .collect();
        assert_eq!(
            indicators,
            [
                "lyapunov = true",
                "fli = true",
                "megno = true",
                "lyapunov = { vectors = 2 }"
            ]
        );
    }
}

#[test]
fn an_unknown_cpu_isa_is_refused() {
    let (ok, err) = reeb(&["info"], &[("REEB_CPU_ISA", "bogus")]);
    assert!(!ok);
    assert!(
        err.contains("REEB_CPU_ISA=\"bogus\" is not one of baseline, v3, v4"),
        "{err}"
    );
}

#[test]
fn a_section_period_below_the_step_is_refused_not_run_forever() {
    let dir = std::env::temp_dir().join(format!("reeb-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("hang.toml");
    std::fs::write(
        &scene,
        "model = \"van_der_pol\"\n[params]\nepsilon = 1.0\n[initial]\nq = 2.0\n\
         [integrator]\ndt = 0.05\nsteps = 100\n[output]\n\
         poincare = { period = 1e-300, vars = [\"q\"] }\n",
    )
    .unwrap();
    for verb in ["check", "run"] {
        let (ok, err) = reeb(&[verb, scene.to_str().unwrap()], &[]);
        assert!(!ok);
        assert!(
            err.contains(
                "hang.toml:10: output.poincare.period: a period of 1e-300 is shorter than the step"
            ),
            "{verb}: {err}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `reeb check` on a scene written to a temporary file.
fn check(name: &str, text: &str) -> (bool, String) {
    let dir = std::env::temp_dir().join(format!("reeb-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join(format!("{name}.toml"));
    std::fs::write(&scene, text).unwrap();
    let r = reeb(&["check", scene.to_str().unwrap()], &[]);
    std::fs::remove_dir_all(&dir).unwrap();
    r
}

#[test]
fn surprising_scenes_are_refused_with_the_field() {
    let cases = [
        (
            "kepler",
            "model = \"kepler\"\n[initial]\neccentricity = 0.5\nq1 = 0.3\n[integrator]\ndt = 0.01\nsteps = 10\n",
            "kepler.toml:4: initial.q1: conflicts with initial.eccentricity, which sets q1 and p2",
        ),
        (
            "order",
            "model = \"van_der_pol\"\n[integrator]\nscheme = \"rk4\"\norder = \"BCACB\"\ndt = 0.01\nsteps = 10\n",
            "order.toml:4: integrator.order: `rk4` has no piece order",
        ),
        (
            "phase",
            "model = \"van_der_pol\"\n[integrator]\ndt = 0.01\nsteps = 10\n[output]\ntrajectory = { every = 1, vars = [\"q\"] }\n[plot]\nphase = [\"q\", \"s\"]\n",
            "phase.toml:8: plot.phase: `s` is not recorded by output.trajectory; it records: q",
        ),
        (
            "section",
            "model = \"van_der_pol\"\n[integrator]\ndt = 0.01\nsteps = 10\n[plot]\npoincare = [\"q\", \"s\"]\n",
            "section.toml:6: plot.poincare: draws output.poincare, which this scene does not record",
        ),
    ];
    for (name, text, says) in cases {
        let (ok, err) = check(name, text);
        assert!(!ok, "{name} was accepted");
        assert!(err.contains(says), "{name}: {err}");
    }
}

/// `--every M` samples every indicator every M steps, and says so in its
/// rows (on the CPU: the sampling is the same code on either backend).
#[test]
fn bench_indicators_samples_every_m_steps() {
    let dir = common::runs::tmp("cli", "bench-indicators-every");
    let json = dir.join("cpu.jsonl");
    let rows = bench_indicator_rows("cpu", &json, &["--steps", "4", "--every", "2"]);
    let indicators: Vec<&str> = rows[4..]
        .iter()
        .map(|r| r["indicator"].as_str().unwrap())
        .collect();
    assert_eq!(
        indicators,
        [
            "lyapunov = { every = 2 }",
            "fli = { every = 2 }",
            "megno = { every = 2 }",
            "lyapunov = { vectors = 2, every = 2 }"
        ]
    );
    for r in &rows {
        assert_eq!(r["every"], 2, "{r}");
        assert!(r["ratio"].as_f64().is_some_and(|x| x > 0.0), "{r}");
    }
}

/// The 8 JSON rows of `reeb bench --indicators` in f32 on `backend`, one
/// pair each, with `args`, written through `json`.
fn bench_indicator_rows(
    backend: &str,
    json: &std::path::Path,
    args: &[&str],
) -> Vec<serde_json::Value> {
    let mut a = vec!["bench", "--indicators", "--backend", backend];
    a.extend(["--precision", "f32", "--repeats", "1"]);
    a.extend(["--json", common::runs::s(json)]);
    a.extend(args);
    let (ok, err) = reeb(&a, &[]);
    assert!(ok, "{backend}: {err}");
    let rows: Vec<serde_json::Value> = std::fs::read_to_string(json)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(rows.len(), 8, "{backend}: {rows:?}");
    rows
}
