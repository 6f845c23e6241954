//! The Zarr store (issue 12, point 2) read by Python's `zarr` and `xarray`
//! as users read it: `xarray.open_zarr(DIR/"run.zarr")` is a Dataset whose
//! every variable equals the `.npy` of the same run, with the scene's axes
//! as dimensions and coordinates and the summary as attributes. Written in
//! chunks (edge chunks included), in shards, and for a vector variable.
//!
//! Needs a Python with `zarr` and `xarray` (`REEB_PYTHON`, else `python3`);
//! without one the tests print SKIP, unless `REEB_REQUIRE_ZARR=1` (CI,
//! which installs them in a venv).

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common;

use common::runs::{grid_scene, ok, s, REEB};

/// A Python that imports zarr and xarray, or `None` (SKIP).
fn python() -> Option<String> {
    let py = std::env::var("REEB_PYTHON").unwrap_or_else(|_| "python3".into());
    let ok = Command::new(&py)
        .args(["-c", "import zarr, xarray, numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    if ok {
        return Some(py);
    }
    assert!(
        std::env::var_os("REEB_REQUIRE_ZARR").is_none(),
        "REEB_REQUIRE_ZARR is set but {py} cannot import zarr and xarray"
    );
    eprintln!("SKIP: {py} cannot import zarr and xarray (set REEB_PYTHON)");
    None
}

fn tmp(name: &str) -> PathBuf {
    common::runs::tmp("zarr", name)
}

/// Opens `zarr_dir/run.zarr` with xarray and compares it with the `.npy`
/// run in `npy_dir`; `dims` are the expected dimensions of each variable.
const COMPARE: &str = r#"
import json, sys, warnings
import numpy as np, xarray as xr, zarr
npy, store, want = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
warnings.simplefilter("ignore", RuntimeWarning)  # no consolidated metadata
ds = xr.open_zarr(store)
assert zarr.open_group(store, mode="r").metadata.zarr_format == 3
names = sorted(ds.data_vars)
assert names == sorted(want), (names, sorted(want))
for v, dims in want.items():
    a, b = np.load(f"{npy}/{v}.npy"), ds[v].values
    assert a.dtype == b.dtype and a.shape == b.shape, (v, a.dtype, b.dtype, a.shape, b.shape)
    assert a.tobytes() == b.tobytes(), v
    assert list(ds[v].dims) == dims, (v, ds[v].dims, dims)
summary = json.load(open(f"{npy}/summary.json"))
for ax in summary["scene"]["axes"]:
    name = ax["name"]
    assert np.array_equal(ds[name].values, np.load(f"{npy}/axis_{name}.npy")), name
assert ds.attrs["scene"]["text"] == summary["scene"]["text"]
assert ds.attrs["ensemble_size"] == summary["ensemble_size"]
print("ok", len(names), "arrays")
"#;

fn compare(py: &str, npy: &Path, zarr_dir: &Path, want: &str) {
    let o = Command::new(py)
        .args([
            "-c",
            COMPARE,
            npy.to_str().unwrap(),
            zarr_dir.join("run.zarr").to_str().unwrap(),
            want,
        ])
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn xarray_reads_the_store_as_the_npy_run_in_chunks_and_shards() {
    let Some(py) = python() else { return };
    let d = tmp("grid");
    let scene = grid_scene(&d, 20.0, 100, "cpu");
    let npy = d.join("npy");
    ok(&["run", s(&scene), "--out", s(&npy)]);
    let with = |extra: &str| -> String {
        let mut v = vec!["epsilon", "q", "dt"];
        v.extend((!extra.is_empty()).then_some(extra));
        serde_json::to_string(&v).unwrap()
    };
    let want = format!(
        r#"{{"final_q": {a}, "final_s": {a}, "trajectory_q": {f}, "poincare_q": {p}, "poincare_p": {p}, "poincare_count": {a}, "cycle_amplitude": {a}, "cycle_period": {a}, "status": {a}, "status_step": {a}}}"#,
        a = with(""),
        f = with("frame"),
        p = with("point"),
    );
    // Chunks of 5 trajectories: runs of 2 values of q, an edge chunk at 7.
    let chunked = d.join("chunked");
    ok(&[
        "run",
        s(&scene),
        "--out",
        s(&chunked),
        "--format",
        "zarr",
        "--chunk-trajectories",
        "5",
    ]);
    compare(&py, &npy, &chunked, &want);
    // Three shards at once, then merged.
    let sharded = d.join("sharded");
    let children: Vec<_> = (0..3)
        .map(|k| {
            Command::new(REEB)
                .args(["run", s(&scene), "--out", s(&sharded), "--format", "zarr"])
                .args(["--chunk-trajectories", "4", "--shard", &format!("{k}/3")])
                .spawn()
                .unwrap()
        })
        .collect();
    for mut c in children {
        assert!(c.wait().unwrap().success());
    }
    ok(&["merge", s(&sharded)]);
    compare(&py, &npy, &sharded, &want);
}

#[test]
fn a_vector_variable_has_a_component_dimension() {
    let Some(py) = python() else { return };
    let d = tmp("kepler");
    let scene = d.join("kepler.toml");
    std::fs::write(
        &scene,
        r#"model = "kepler"
[params]
alpha = { linspace = [0.0, 0.1, 3] }
[initial]
q1 = { linspace = [0.8, 1.2, 5] }
q2 = 0.0
p1 = 0.0
p2 = 1.0
[integrator]
scheme = "s2"
dt = 0.01
steps = 300
[output]
final = ["q", "p"]
trajectory = { every = 50, vars = ["q"] }
[run]
backend = "cpu"
precision = "f64"
"#,
    )
    .unwrap();
    let npy = d.join("npy");
    ok(&["run", s(&scene), "--out", s(&npy)]);
    let z = d.join("z");
    ok(&[
        "run",
        s(&scene),
        "--out",
        s(&z),
        "--format",
        "zarr",
        "--chunk-trajectories",
        "2",
    ]);
    let a = r#"["alpha", "q1""#;
    let want = format!(
        r#"{{"final_q": {a}, "component"], "final_p": {a}, "component"], "trajectory_q": {a}, "frame", "component"], "status": {a}], "status_step": {a}]}}"#
    );
    compare(&py, &npy, &z, &want);
}

#[test]
fn averages_resonances_and_stops_reach_the_store() {
    let Some(py) = python() else { return };
    let d = tmp("observers");
    let scene = d.join("observers.toml");
    std::fs::write(
        &scene,
        r#"model = "damped_oscillator"
[params]
alpha = [0.05, 0.2, 0.6]
[initial]
q = { linspace = [-2.0, 2.0, 7] }
p = 0.3
[integrator]
scheme = "s2"
dt = 0.05
steps = 600
[output]
final = ["q"]
average = { vars = ["p"], skip = 0.0 }
resonance = { var = "p", ratios = [[1, 40]], tolerance = 0.03 }
stop = "t > 20.52 + 20*alpha"
[run]
precision = "f64"
"#,
    )
    .unwrap();
    let npy = d.join("npy");
    ok(&["run", s(&scene), "--out", s(&npy), "--backend", "cpu"]);
    let zarr = d.join("zarr");
    ok(&[
        "run",
        s(&scene),
        "--out",
        s(&zarr),
        "--backend",
        "cpu",
        "--format",
        "zarr",
        "--chunk-trajectories",
        "5",
    ]);
    let a = r#"["alpha", "q"]"#;
    let want = format!(
        r#"{{"final_q": {a}, "mean_p": {a}, "resonance": {a}, "status": {a}, "status_step": {a}}}"#
    );
    compare(&py, &npy, &zarr, &want);
}
