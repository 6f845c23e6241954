//! `reeb report`: the work–precision report measures every scheme's order,
//! and the stability report classifies every cell, stiff and extreme corners
//! included, in f32 and f64.

use std::path::Path;

use reeb::plan::scheme::Scheme;
use reeb::report::{stability, work_precision, ReportOptions};
use reeb::scene::{BackendChoice, Scene};

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("reeb-report-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// The work–precision report of `scene` on the CPU into `out`: its text.
fn work_precision_on_cpu(scene: &Scene, out: &Path) -> String {
    let md = work_precision(
        scene,
        &ReportOptions {
            out: Some(out.to_path_buf()),
            backend: Some(BackendChoice::Cpu),
            precision: None,
            force: false,
            stop: None,
        },
    )
    .unwrap();
    std::fs::read_to_string(&md).unwrap()
}

/// Each scheme's measured order (the report's f64 CPU row) within 0.2 of
/// its nominal order.
fn assert_orders(text: &str, orders: &[(&str, f64)]) {
    for (scheme, order) in orders {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("| {scheme} cpu f64 |")))
            .unwrap_or_else(|| panic!("{scheme} missing:\n{text}"));
        let measured: f64 = line
            .split('|')
            .nth(3)
            .unwrap()
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("{line}"));
        assert!((measured - order).abs() <= 0.2, "{scheme}: {measured}");
    }
}

#[test]
fn work_precision_measures_the_orders() {
    // The damped-oscillator scene of scenes/, on the four schemes the issue names.
    let mut scene = Scene::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/damped_oscillator_work_precision.toml"),
    )
    .unwrap();
    let r = scene.report.as_mut().unwrap();
    r.schemes = ["s2", "triple_jump4", "yoshida6a", "yoshida8a"]
        .map(|s| Scheme::by_name(s).unwrap())
        .to_vec();
    r.precisions = vec![reeb::num::precision::Precision::F64];
    let out = tmp("wp");
    let text = work_precision_on_cpu(&scene, &out);
    assert_orders(
        &text,
        &[
            ("s2", 2.0),
            ("triple_jump4", 4.0),
            ("yoshida6a", 6.0),
            ("yoshida8a", 8.0),
        ],
    );
    let csv = std::fs::read_to_string(out.join("work_precision.csv")).unwrap();
    assert!(csv.starts_with("scheme,backend,precision,dt,steps,evaluations,error_max,error_rel,seconds,traj_steps_per_s"));
    assert_eq!(
        csv.lines().filter(|l| l.starts_with("yoshida6a,")).count(),
        16
    );
    assert!(
        csv.lines().any(|l| l.starts_with("dop853")),
        "the reference is a point too"
    );
    for f in ["work_precision.png", "error_vs_dt.png", "report.md"] {
        assert!(out.join(f).exists(), "{f}");
    }
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn stability_classifies_every_cell_in_both_precisions() {
    let scene = Scene::parse(
        Path::new("st.toml"),
        r#"
model = "van_der_pol"
[params]
epsilon = { logspace = [-1.0, 3.0, 6] }
[initial]
q = 2.0
[integrator]
dt = { logspace = [-3.0, 0.30102999566398120, 6] }
t_end = 20.0
[output]
cycle = true
[report]
precisions = ["f32", "f64"]
"#,
    )
    .unwrap();
    let out = tmp("st");
    let opts = ReportOptions {
        out: Some(out.clone()),
        backend: Some(BackendChoice::Cpu),
        precision: None,
        force: false,
        stop: None,
    };
    let csv = stability(&scene, &opts).unwrap();
    // A report replaces its own earlier output (its summary.json lists every file).
    let listed = std::fs::read_to_string(out.join("summary.json")).unwrap();
    assert!(listed.contains("stability.csv") && listed.contains("stability.png"));
    let csv = stability(&scene, &opts).map(|again| {
        assert_eq!(again, csv);
        again
    });
    let csv = csv.unwrap();
    let text = std::fs::read_to_string(csv).unwrap();
    let rows: Vec<Vec<&str>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 2 * 36);
    for r in &rows {
        assert!(
            ["accurate", "distorted", "diverged"].contains(&r[3]),
            "{r:?}"
        );
        let e: f64 = r[4].parse().unwrap();
        assert!(!e.is_nan(), "NaN error leaked: {r:?}");
    }
    // The corners: ε = 1000 with τ = 2 (ετ = 2000: e^{ετ} far beyond f32) and the smallest cell.
    let num = |s: &str| s.parse::<f64>().unwrap();
    let corner = rows
        .iter()
        .find(|r| num(r[0]) == 1e3 && (num(r[1]) - 2.0).abs() < 1e-9 && r[2] == "f32")
        .expect("corner row");
    assert_ne!(corner[3], "accurate");
    let easy = rows
        .iter()
        .find(|r| num(r[0]) == 0.1 && num(r[1]) == 1e-3 && r[2] == "f64")
        .expect("small cell");
    assert_eq!(easy[3], "accurate", "{easy:?}");
    assert!(out.join("stability.png").exists());
    std::fs::remove_dir_all(&out).unwrap();
}

/// The work–precision report takes a formula model: its schemes and its
/// comparison integrators (built from the same formulas) at their orders.
#[test]
fn work_precision_takes_a_formula_model() {
    let mut scene = Scene::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/duffing_work_precision.toml"),
    )
    .unwrap();
    assert!(scene.model.formula().is_some());
    scene.report.as_mut().unwrap().precisions = vec![reeb::num::precision::Precision::F64];
    let out = tmp("wp-formula");
    let text = work_precision_on_cpu(&scene, &out);
    assert_orders(
        &text,
        &[
            ("s2", 2.0),
            ("yoshida6a", 6.0),
            ("rk4", 4.0),
            ("leapfrog", 2.0),
        ],
    );
}

/// The stability report takes a formula model: van der Pol written as
/// `lienard` formulas gets the built-in model's map, cell by cell.
#[test]
fn stability_takes_a_formula_model() {
    let grid = r#"
[params]
epsilon = { logspace = [-1.0, 2.0, 5] }
[initial]
q = 2.0
s = 0.0
[integrator]
dt = { logspace = [-3.0, 0.0, 5] }
t_end = 20.0
[output]
cycle = true
[report]
precisions = ["f64"]
"#;
    let opts = |name: &str| ReportOptions {
        out: Some(tmp(name)),
        backend: Some(BackendChoice::Cpu),
        precision: None,
        force: false,
        stop: None,
    };
    let map = |text: String, name: &str| {
        let scene = Scene::parse(Path::new("st.toml"), &text).unwrap();
        let csv = stability(&scene, &opts(name)).unwrap();
        let rows: Vec<String> = std::fs::read_to_string(csv)
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').take(4).collect::<Vec<_>>().join(","))
            .collect();
        rows
    };
    let builtin = map(format!("model = \"van_der_pol\"\n{grid}"), "st-builtin");
    let formula = map(
        format!("model = \"lienard\"\n[formula]\nf = \"epsilon*(q^2 - 1)\"\ng = \"q\"\n{grid}"),
        "st-formula",
    );
    assert_eq!(builtin.len(), 25);
    assert_eq!(formula, builtin, "epsilon, dt, precision, class per cell");
}

/// A report asked to stop (Ctrl-C in Python) ends with an error inside its
/// first run, and leaves nothing (its `.partial` is removed).
#[test]
fn a_stopped_report_ends_and_looks_unfinished() {
    let scene = Scene::parse(
        Path::new("st.toml"),
        r#"
model = "van_der_pol"
[params]
epsilon = { logspace = [-1.0, 1.0, 2] }
[initial]
q = 2.0
[integrator]
dt = { logspace = [-4.0, -3.0, 2] }
t_end = 1e5
[output]
cycle = true
[report]
precisions = ["f64"]
"#,
    )
    .unwrap();
    let out = tmp("st-stopped");
    let opts = ReportOptions {
        out: Some(out.clone()),
        backend: Some(BackendChoice::Cpu),
        precision: None,
        force: false,
        stop: Some(std::sync::Arc::new(true.into())),
    };
    let started = std::time::Instant::now();
    let e = stability(&scene, &opts).unwrap_err();
    assert!(format!("{e:#}").contains("stopped"), "{e:#}");
    assert!(started.elapsed().as_secs() < 10, "{:?}", started.elapsed());
    assert!(!out.exists());
    assert!(!out.with_extension("partial").exists());
}
