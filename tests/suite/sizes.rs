//! Checked sizes (issue 10): every count is checked, one size gate runs
//! before anything is allocated, and `reeb check` applies exactly the gates
//! of `reeb run`. Each case here was a bug: an ensemble count that wrapped
//! modulo 2⁶⁴, an axis allocated before any check (an abort), a check that
//! passed what the run refused, a scene name with a NUL byte.

use std::path::{Path, PathBuf};
use std::process::Command;

/// A scene file in a temporary directory of its own (removed on drop).
struct TempScene {
    dir: PathBuf,
    file: PathBuf,
}

impl TempScene {
    fn new(name: &str, text: &str) -> TempScene {
        let dir = std::env::temp_dir().join(format!("reeb-sizes-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join(format!("{name}.toml"));
        std::fs::write(&file, text).unwrap();
        TempScene { dir, file }
    }
}

impl Drop for TempScene {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// What `reeb <verb> scene` did: exit code (None: killed by a signal),
/// stdout, stderr.
struct Outcome {
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

fn reeb(verb: &str, scene: &Path, out: &Path) -> Outcome {
    let mut c = Command::new(env!("CARGO_BIN_EXE_reeb"));
    c.arg(verb).arg(scene);
    if verb == "run" {
        c.args(["--backend", "cpu", "--out"]).arg(out);
    }
    let o = c.env("RUST_BACKTRACE", "0").output().expect("reeb runs");
    Outcome {
        code: o.status.code(),
        stdout: String::from_utf8_lossy(&o.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
    }
}

/// `reeb check` and `reeb run` both refuse `text` with exit code 1 (not a
/// signal, not a panic), the same message, containing every one of `says`;
/// the run writes nothing.
fn refused_alike(name: &str, text: &str, says: &[&str]) -> String {
    let scene = TempScene::new(name, text);
    let out = scene.dir.join("out");
    let check = reeb("check", &scene.file, &out);
    let run = reeb("run", &scene.file, &out);
    for (verb, o) in [("check", &check), ("run", &run)] {
        assert_eq!(
            o.code,
            Some(1),
            "{name}: {verb} exited with {:?}: {}",
            o.code,
            o.stderr
        );
        assert!(
            o.stderr.starts_with("error: "),
            "{name}: {verb}: {}",
            o.stderr
        );
        assert!(
            !o.stderr.contains("panicked"),
            "{name}: {verb}: {}",
            o.stderr
        );
        assert!(
            !o.stderr.contains("memory allocation"),
            "{name}: {verb}: {}",
            o.stderr
        );
        assert!(o.stdout.is_empty(), "{name}: {verb} printed {}", o.stdout);
        for s in says {
            assert!(
                o.stderr.contains(s),
                "{name}: {verb}: `{s}` not in {}",
                o.stderr
            );
        }
    }
    assert_eq!(check.stderr, run.stderr, "{name}: check and run differ");
    assert!(!out.exists(), "{name}: the run wrote {}", out.display());
    check.stderr
}

/// A van der Pol scene with `params` and `initial` lines.
fn vdp(params: &str, initial: &str, integrator: &str) -> String {
    format!(
        "model = \"van_der_pol\"\n[params]\n{params}\n[initial]\n{initial}\n[integrator]\n{integrator}\n"
    )
}

#[test]
fn four_axes_of_65536_values_are_refused_not_zero_trajectories() {
    // 65536⁴ = 2⁶⁴ wrapped to 0 trajectories, which `check` printed as ok.
    let text = vdp(
        "epsilon = { linspace = [0.0, 1.0, 65536] }",
        "q = { linspace = [0.0, 1.0, 65536] }\ns = { logspace = [0.0, 1.0, 65536] }",
        "dt = { linspace = [0.01, 0.02, 65536] }\nsteps = 10",
    );
    let e = refused_alike(
        "four",
        &text,
        &[
            "four.toml:3: params.epsilon: the ensemble has more than 2^64 trajectories",
            "params.epsilon 65536 × initial.q 65536 × initial.s 65536 × integrator.dt 65536 values",
            "use fewer values along an axis",
        ],
    );
    assert!(!e.contains("0 trajectories"), "{e}");
}

#[test]
fn a_product_of_2_64_plus_418_is_refused_not_418() {
    // 2⁶⁴ + 418 = 2·7·31·673 × 853·1669 × 5821·7621: it wrapped to 418.
    let text = vdp(
        "epsilon = { linspace = [0.0, 1.0, 292082] }",
        "q = { random = { low = 0.0, high = 1.0, n = 1423657, seed = 3 } }\ns = { linspace = [0.0, 1.0, 44361841] }",
        "dt = 0.01\nsteps = 10",
    );
    // The largest axis carries the error.
    refused_alike(
        "wrap",
        &text,
        &[
            "wrap.toml:6: initial.s: the ensemble has more than 2^64 trajectories",
            "params.epsilon 292082 × initial.q 1423657 × initial.s 44361841 values",
        ],
    );
}

#[test]
fn a_linspace_of_10_12_values_is_refused_before_it_is_allocated() {
    // It aborted with "memory allocation of 8000000000000 bytes failed".
    for (name, value) in [
        ("lin12", "{ linspace = [0, 1, 1e12] }"),
        ("log12", "{ logspace = [0, 1, 1e12] }"),
        (
            "rand12",
            "{ random = { low = 0.0, high = 1.0, n = 1000000000000, seed = 1 } }",
        ),
    ] {
        let text = vdp(
            &format!("epsilon = {value}"),
            "q = 1.0",
            "dt = 0.01\nsteps = 10",
        );
        refused_alike(
            name,
            &text,
            &[
                &format!("{name}.toml:3: params.epsilon: 1000000000000 trajectories (params.epsilon 1000000000000 values) need at least"),
                "is available; use fewer values along an axis",
            ],
        );
    }
    // A dt axis with t_end: one plan per value.
    let text = vdp(
        "epsilon = 1.0",
        "q = 1.0",
        "dt = { linspace = [0.1, 0.2, 1e12] }\nt_end = 10.0",
    );
    refused_alike(
        "dt12",
        &text,
        &["dt12.toml:7: integrator.dt: 1000000000000 trajectories"],
    );
}

#[test]
fn n_beyond_2_64_is_refused_not_saturated() {
    for (name, n) in [("e308", "1e308"), ("e20", "1e20"), ("p64", "2e19")] {
        let text = vdp(
            &format!("epsilon = {{ linspace = [0, 1, {n}] }}"),
            "q = 1.0",
            "dt = 0.01\nsteps = 10",
        );
        refused_alike(
            name,
            &text,
            &[
                &format!("{name}.toml:3: params.epsilon.linspace: n = "),
                "more than 2^64 trajectories",
            ],
        );
    }
    // 2⁶³ (saturated to 2⁶³ − 1 before): counted, then refused for memory.
    let text = vdp(
        "epsilon = { linspace = [0, 1, 9223372036854775807] }",
        "q = 1.0",
        "dt = 0.01\nsteps = 10",
    );
    refused_alike(
        "p63",
        &text,
        &[
            "p63.toml:3: params.epsilon: 9223372036854775808 trajectories",
            "need at least",
        ],
    );
}

#[test]
fn ensembles_of_10_12_and_10_18_that_run_refuses_check_refuses_too() {
    let text = vdp(
        "epsilon = { linspace = [0, 1, 1e6] }",
        "q = { linspace = [0, 1, 1e6] }",
        "dt = 0.01\nsteps = 10",
    );
    refused_alike(
        "e12",
        &text,
        &["e12.toml:3: params.epsilon: 1000000000000 trajectories (params.epsilon 1000000 × initial.q 1000000 values) need at least"],
    );
    let text = vdp(
        "epsilon = { linspace = [0, 1, 1e6] }",
        "q = { linspace = [0, 1, 1e6] }\ns = { linspace = [0, 1, 1e6] }",
        "dt = 0.01\nsteps = 10",
    );
    refused_alike(
        "e18",
        &text,
        &[
            "e18.toml:3: params.epsilon: 1000000000000000000 trajectories",
            "EiB",
        ],
    );
}

#[test]
fn outputs_beyond_memory_are_refused_by_check_as_by_run() {
    // Few trajectories, but 10⁶ × 10⁶ trajectory frames: the second stage.
    let text = vdp(
        "epsilon = { linspace = [0, 1, 1e6] }",
        "q = 1.0",
        "dt = 0.001\nsteps = 1000000\n[output]\ntrajectory = { every = 1 }",
    );
    refused_alike(
        "frames",
        &text,
        &[
            "frames.toml: the outputs of 1000000 trajectories need about",
            "TiB and",
            "record less: a larger output.trajectory.every",
        ],
    );
    // Poincaré points whose bytes do not fit in 64 bits.
    let text = vdp(
        "epsilon = 1.0",
        "q = 1.0",
        "dt = 0.1\nsteps = 10\n[output]\npoincare = { period = 1.0, max_points = 9223372036854775807 }",
    );
    refused_alike(
        "points",
        &text,
        &["points.toml: the outputs of 1 trajectory need more than 16 EiB and"],
    );
}

#[test]
fn names_that_cannot_be_file_names_are_refused() {
    for (case, name) in [
        ("nul", "a\\u0000b"),
        ("slash", "a/b"),
        ("empty", ""),
        ("dot", "."),
        ("dots", ".."),
    ] {
        let text = format!(
            "model = \"van_der_pol\"\nname = \"{name}\"\n[integrator]\ndt = 0.1\nsteps = 10\n"
        );
        refused_alike(
            case,
            &text,
            &[
                &format!("{case}.toml:2: name: "),
                "must be a plain file name",
            ],
        );
    }
}

#[test]
fn check_prints_the_estimate_of_a_scene_it_accepts() {
    let text = vdp(
        "epsilon = { linspace = [0, 1, 5] }",
        "q = [1.0, 2.0]",
        "dt = { logspace = [-2.0, -1.0, 3] }\nt_end = 10.0\n[run]\nprecision = \"f64\"",
    );
    let scene = TempScene::new("ok", &text);
    let o = reeb("check", &scene.file, &scene.dir.join("out"));
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    assert!(
        o.stdout
            .contains("f64, 30 trajectories over 3 axes, 3 plan(s), outputs about "),
        "{}",
        o.stdout
    );
}
