//! What the working precision cannot hold is refused with its field; what
//! is merely surprising is a warning (issue 10, "say what is surprising"):
//! through the library (`Scene::checks`) and through `reeb check`.

use std::path::{Path, PathBuf};
use std::process::Command;

use reeb::num::precision::Precision;
use reeb::scene::Scene;

/// A van der Pol scene with `params`, `initial` and `integrator` lines.
fn scene(params: &str, initial: &str, integrator: &str) -> String {
    format!(
        "model = \"van_der_pol\"\n[params]\n{params}\n[initial]\n{initial}\n[integrator]\nscheme = \"s2\"\n{integrator}\n[output]\nfinal = [\"q\", \"s\"]\n[run]\nprecision = \"f32\"\n"
    )
}

/// A fresh directory of its own for a test.
fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("reeb-surprises-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `reeb check` (with `args`) on `text` written to `<name>.toml`:
/// (success, stdout, stderr).
fn check(name: &str, text: &str, args: &[&str]) -> (bool, String, String) {
    let dir = tmp(name);
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_reeb"))
        .arg("check")
        .args(args)
        .arg(&path)
        .output()
        .expect("reeb runs");
    std::fs::remove_dir_all(&dir).unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn parse(name: &str, text: &str) -> Scene {
    Scene::parse(Path::new(&format!("{name}.toml")), text).unwrap()
}

/// The scene reads in both precisions, is refused in f32 with `field` at
/// `line` (and `says`), and is accepted in f64, by the library and by
/// `reeb check` (`--precision f64` too).
fn refused_in_f32_only(name: &str, text: &str, line: usize, field: &str, says: &str) {
    let s = parse(name, text);
    let e = s.checks(Precision::F32).unwrap_err();
    assert_eq!((e.line, e.field.as_str()), (Some(line), field), "{e}");
    assert!(e.message.contains(says), "{e}");
    assert!(e.message.contains("use f64"), "{e}");
    assert!(s.checks(Precision::F64).unwrap().is_empty());

    let (ok, _, err) = check(name, text, &[]);
    assert!(!ok, "{name}: accepted in f32");
    let at = format!("{name}.toml:{line}: {field}: {says}");
    assert!(err.contains(&at), "{name}: {err}\nexpected: {at}");
    let (ok, out, err) = check(name, text, &["--precision", "f64"]);
    assert!(ok, "{name}: refused in f64: {err}");
    assert!(
        out.contains("ok: model van_der_pol, scheme s2, f64"),
        "{out}"
    );
    assert!(err.is_empty(), "{name}: {err}");
    let (ok, _, err) = check(name, &text.replace("\"f32\"", "\"f64\""), &[]);
    assert!(ok, "{name}: an f64 scene refused: {err}");
}

#[test]
fn a_dt_that_is_0_in_f32_is_refused() {
    refused_in_f32_only(
        "dt",
        &scene("epsilon = 1.0", "q = 2.0", "dt = 1e-50\nsteps = 10"),
        8,
        "integrator.dt",
        "dt = 1e-50 is 0 in f32 (smallest step f32 can hold: 1.1754944e-38)",
    );
}

#[test]
fn a_subnormal_dt_is_refused() {
    let s = parse(
        "sub",
        &scene("epsilon = 1.0", "q = 2.0", "dt = 1e-40\nsteps = 10"),
    );
    let e = s.checks(Precision::F32).unwrap_err();
    assert_eq!(e.field, "integrator.dt");
    assert!(
        e.message
            .contains("dt = 1e-40 is below the smallest normal f32 number"),
        "{e}"
    );
    assert!(s.checks(Precision::F64).is_ok());
}

#[test]
fn an_initial_value_beyond_f32_is_refused() {
    refused_in_f32_only(
        "initial",
        &scene("epsilon = 1.0", "q = 1e39", "dt = 0.1\nsteps = 10"),
        5,
        "initial.q",
        "1e39 is beyond the range of f32 (largest magnitude 3.4028235e38)",
    );
}

#[test]
fn a_parameter_axis_value_beyond_f32_is_refused() {
    refused_in_f32_only(
        "axis",
        &scene(
            "epsilon = [1.0, 2.0, -5e38]",
            "q = 2.0",
            "dt = 0.1\nsteps = 10",
        ),
        3,
        "params.epsilon",
        "-5e38 (value 3 of 3 along its axis) is beyond the range of f32",
    );
}

#[test]
fn t_end_and_a_section_value_beyond_f32_are_refused() {
    refused_in_f32_only(
        "t_end_range",
        &scene("epsilon = 1.0", "q = 2.0", "dt = 1e35\nt_end = 1e39"),
        9,
        "integrator.t_end",
        "1e39 is beyond the range of f32",
    );
    let text = scene("epsilon = 1.0", "q = 2.0", "dt = 0.1\nsteps = 10").replace(
        "final = [\"q\", \"s\"]",
        "poincare = { crossing = \"q\", value = 1e39, vars = [\"s\"] }",
    );
    refused_in_f32_only(
        "crossing",
        &text,
        11,
        "output.poincare.value",
        "1e39 is beyond the range of f32",
    );
}

#[test]
fn non_finite_inputs_are_refused_when_read() {
    for (name, text, field) in [
        (
            "nan_eps",
            scene("epsilon = nan", "q = 2.0", "dt = 0.1\nsteps = 10"),
            "params.epsilon",
        ),
        (
            "inf_q",
            scene("epsilon = 1.0", "q = inf", "dt = 0.1\nsteps = 10"),
            "initial.q",
        ),
        (
            "nan_dt",
            scene("epsilon = 1.0", "q = 2.0", "dt = nan\nsteps = 10"),
            "integrator.dt",
        ),
        (
            "inf_t_end",
            scene("epsilon = 1.0", "q = 2.0", "dt = 0.1\nt_end = inf"),
            "integrator.t_end",
        ),
    ] {
        let e = Scene::parse(Path::new("x.toml"), &text).unwrap_err();
        assert_eq!(e.field, field, "{name}: {e}");
    }
}

#[test]
fn t_end_not_a_multiple_of_dt_warns_with_the_final_time() {
    let text = scene("epsilon = 1.0", "q = 2.0", "dt = 0.3\nt_end = 10.0");
    let (ok, out, err) = check("t_end", &text, &[]);
    assert!(ok, "{err}");
    assert!(
        err.contains("warning: ")
            && err.contains(
                "t_end.toml:9: integrator.t_end: t_end = 10.0 is not a multiple of dt = 0.3: 33 steps end at t = 9.9"
            ),
        "{err}"
    );
    assert!(out.contains(", 1 warning"), "{out}");
    // The same warning from the library, with its place.
    let w = parse("t_end", &text).checks(Precision::F64).unwrap();
    assert_eq!(w.len(), 1, "{w:?}");
    assert_eq!(
        (w[0].line, w[0].field.as_str()),
        (Some(9), "integrator.t_end")
    );
    assert_eq!(
        w[0].to_string(),
        "t_end.toml:9: integrator.t_end: t_end = 10.0 is not a multiple of dt = 0.3: 33 steps end at t = 9.9"
    );
    // From t0, and along a dt axis: the farthest miss.
    let w = parse(
        "t0",
        &scene(
            "epsilon = 1.0",
            "q = 2.0\nt0 = 0.5",
            "dt = 0.3\nt_end = 10.0",
        ),
    )
    .checks(Precision::F32)
    .unwrap();
    assert!(
        w[0].message.contains(
            "t_end − t0 = 9.5 (t0 = 0.5) is not a multiple of dt = 0.3: 32 steps end at t = 10.1"
        ),
        "{w:?}"
    );
    let w = parse(
        "axis",
        &scene(
            "epsilon = 1.0",
            "q = 2.0",
            "dt = [0.1, 0.3, 0.7, 0.5]\nt_end = 10.0",
        ),
    )
    .checks(Precision::F32)
    .unwrap();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].message.contains(
            "t_end = 10.0 is not a multiple of dt for 2 of the 4 values of dt; the farthest: dt = 0.7: 14 steps end at t = 9.8"
        ),
        "{w:?}"
    );
}

#[test]
fn t_end_a_multiple_of_dt_does_not_warn() {
    // 10/0.1 and 10.1/0.01 are not whole in binary: no warning all the same.
    for (dt, t_end) in [("0.1", "10.0"), ("0.01", "10.1"), ("0.25", "10.0")] {
        let text = scene(
            "epsilon = 1.0",
            "q = 2.0",
            &format!("dt = {dt}\nt_end = {t_end}"),
        );
        let (ok, out, err) = check("whole", &text, &[]);
        assert!(ok && err.is_empty(), "dt = {dt}, t_end = {t_end}: {err}");
        assert!(!out.contains("warning"), "{out}");
    }
}

#[test]
fn a_dt_below_the_resolution_of_time_warns() {
    // Forced: the model reads t; at t ≈ 1000 f32 numbers are 6.1e-5 apart.
    let text = scene(
        "epsilon = 1.0\nforcing_amplitude = 1.0\nforcing_frequency = 1.0",
        "q = 2.0\nt0 = 1000.0",
        "dt = 1e-5\nsteps = 100",
    );
    let (ok, _, err) = check("resolution", &text, &[]);
    assert!(ok, "{err}");
    assert!(
        err.contains(
            "resolution.toml:11: integrator.dt: dt = 1e-5 is less than half the spacing of f32 numbers at t = 1000.0 (6.1035156e-5): t + dt rounds back to t"
        ),
        "{err}"
    );
    let (ok, _, err) = check("resolution", &text, &["--precision", "f64"]);
    assert!(ok && err.is_empty(), "{err}");
    // A few digits left: said so.
    let w = parse("digits", &text.replace("dt = 1e-5", "dt = 1e-4"))
        .checks(Precision::F32)
        .unwrap();
    assert!(
        w[0].message
            .contains("dt = 0.0001 keeps less than one significant digit at t = 1000.01 in f32"),
        "{w:?}"
    );
    // Nothing reads the time of an unforced scene that records no t.
    let w = parse(
        "unforced",
        &scene(
            "epsilon = 1.0",
            "q = 2.0\nt0 = 1000.0",
            "dt = 1e-5\nsteps = 100",
        ),
    )
    .checks(Precision::F32)
    .unwrap();
    assert!(w.is_empty(), "{w:?}");
}

#[test]
fn values_that_underflow_or_merge_in_f32_warn() {
    let w = parse(
        "under",
        &scene(
            "epsilon = { linspace = [1.0, 1.0000000001, 5] }",
            "q = [1e-50, 2.0]",
            "dt = 0.1\nsteps = 10",
        ),
    )
    .checks(Precision::F32)
    .unwrap();
    let said: Vec<String> = w.iter().map(|w| w.to_string()).collect();
    assert_eq!(w.len(), 2, "{said:?}");
    assert!(
        said[0].starts_with(
            "under.toml:3: params.epsilon: its 5 distinct values are only 1 number in f32"
        ),
        "{said:?}"
    );
    assert!(
        said[1].starts_with(
            "under.toml:5: initial.q: 1e-50 (value 1 of 2 along its axis) is 0 in f32"
        ),
        "{said:?}"
    );
}

#[test]
fn a_section_that_starts_after_the_run_warns() {
    let text = scene("epsilon = 1.0", "q = 2.0", "dt = 0.1\nsteps = 100").replace(
        "final = [\"q\", \"s\"]",
        "poincare = { period = 1.0, skip = 20, vars = [\"q\"] }",
    );
    let w = parse("late", &text).checks(Precision::F64).unwrap();
    assert_eq!(w.len(), 1, "{w:?}");
    assert_eq!(w[0].field, "output.poincare");
    assert!(w[0].message.contains("no point will be recorded"), "{w:?}");
}

/// Every shipped scene checks in f32 and f64, and warns only where the
/// warning is true of it: a t_end that its dt does not divide.
#[test]
fn shipped_scenes_check_without_spurious_warnings() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut n = 0;
    for e in std::fs::read_dir(dir).unwrap() {
        let path = e.unwrap().path();
        if path.extension().is_none_or(|x| x != "toml") {
            continue;
        }
        let s = Scene::load(&path).unwrap();
        for p in [Precision::F32, Precision::F64] {
            let w = s
                .checks(p)
                .unwrap_or_else(|e| panic!("{} in {p}: {e}", path.display()));
            for w in w {
                assert_eq!(w.field, "integrator.t_end", "{p}: {w}");
                assert!(w.message.contains("is not a multiple of dt"), "{w}");
            }
        }
        n += 1;
    }
    assert!(n > 10);
}

#[test]
fn a_preview_says_nothing_of_the_t_end_it_stops_before() {
    let s = parse(
        "preview",
        &scene("epsilon = 1.0", "q = 2.0", "dt = 0.3\nt_end = 10000.0"),
    );
    assert_eq!(s.checks(Precision::F32).unwrap().len(), 1);
    let w = s.preview(4, 2000).checks(Precision::F32).unwrap();
    assert!(w.is_empty(), "{w:?}");
}
