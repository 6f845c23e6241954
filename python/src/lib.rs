//! `reeb._reeb`: the Rust engine as a Python extension module. The package
//! around it (`python/reeb/`) turns scenes into TOML text and run
//! directories into xarray Datasets; this module runs, checks and verifies
//! exactly as the `reeb` command does, with the GIL released while the
//! engine works, progress and Ctrl-C polled every 0.1 s, and every error a
//! Python exception (`reeb.SceneError`, `reeb.ReebError`, a Rust panic
//! `reeb.InternalError`).

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict};

use reeb::backend::gpu::list_adapters;
use reeb::backend::Engine;
use reeb::num::precision::Precision;
use reeb::output::run::{gates, run_scene, RunOptions};
use reeb::output::stream::Watch;
use reeb::scene::{BackendChoice, Scene, SceneError};
use reeb::verify::Target;

/// How often the waiting thread looks at the run (progress, Ctrl-C).
const POLL: Duration = Duration::from_millis(100);

/// A Python exception of `reeb.errors` named `class`, made with `args`.
fn raise<'py, A: pyo3::call::PyCallArgs<'py>>(py: Python<'py>, class: &str, args: A) -> PyErr {
    let made = py
        .import("reeb.errors")
        .and_then(|m| m.getattr(class))
        .and_then(|c| c.call1(args));
    match made {
        Ok(e) => PyErr::from_value(e),
        Err(e) => e,
    }
}

fn scene_error(py: Python, e: &SceneError) -> PyErr {
    let path = e.path.display().to_string();
    raise(
        py,
        "SceneError",
        (e.message.clone(), e.field.clone(), e.line, path),
    )
}

/// An error of the library as the Python exception it is.
fn error(py: Python, e: anyhow::Error) -> PyErr {
    match e.downcast_ref::<SceneError>() {
        Some(s) => scene_error(py, s),
        None => raise(py, "ReebError", (format!("{e:#}"),)),
    }
}

/// What a panic said, as `reeb.InternalError`.
fn panicked(py: Python, payload: Box<dyn std::any::Any + Send>) -> PyErr {
    let what = payload
        .downcast_ref::<String>()
        .cloned()
        .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "a panic".into());
    raise(
        py,
        "InternalError",
        (format!(
            "reeb panicked: {what} (please report it with the scene)"
        ),),
    )
}

fn parse<T: std::str::FromStr>(what: &str, v: Option<&str>) -> PyResult<Option<T>>
where
    T::Err: std::fmt::Display,
{
    v.map(|s| {
        s.parse::<T>()
            .map_err(|e| PyValueError::new_err(format!("{what}: {e}")))
    })
    .transpose()
}

/// Runs `work` on a thread of its own while this one, without the GIL,
/// waits; every [`POLL`] it takes the GIL to report progress and to look
/// for Ctrl-C (which asks the run to stop, waits for it, and is raised).
fn watched<T: Send>(
    py: Python,
    watch: &Watch,
    progress: Option<&Bound<PyAny>>,
    work: impl FnOnce() -> T + Send,
) -> PyResult<T> {
    std::thread::scope(|s| {
        let worker = s.spawn(work);
        loop {
            let finished = py.detach(|| {
                let start = std::time::Instant::now();
                while !worker.is_finished() && start.elapsed() < POLL {
                    std::thread::sleep(Duration::from_millis(5));
                }
                worker.is_finished()
            });
            let report = || -> PyResult<()> {
                if let Some(cb) = progress {
                    let total = watch.total.load(Ordering::Relaxed);
                    cb.call1((watch.done.load(Ordering::Relaxed), total))?;
                }
                py.check_signals()
            };
            if let Err(e) = report() {
                watch.stop.store(true, Ordering::Relaxed);
                let _ = py.detach(|| worker.join());
                return Err(e);
            }
            if finished {
                return worker.join().map_err(|p| panicked(py, p));
            }
        }
    })
}

/// Runs the scene `text` (read from `path`) into the directory `out`, as
/// `reeb run` does; returns `summary.json`'s text. `progress(done, total)`
/// is called with trajectory-steps as the run goes. The other keywords are
/// `reeb run`'s options (`run_option_names()`: `backend`, `shard="K/N"`,
/// `checkpoint_every`, …), read by the same definition as its flags: a
/// value is the flag's text, `True` a flag given, `None` and `False` none.
#[pyfunction]
#[pyo3(signature = (text, path, out, preview=false, progress=None, **options))]
fn run(
    py: Python,
    text: &str,
    path: &str,
    out: PathBuf,
    preview: bool,
    progress: Option<Bound<PyAny>>,
    options: Option<&Bound<PyDict>>,
) -> PyResult<String> {
    let mut opts = run_options(options)?;
    let mut scene = Scene::parse(Path::new(path), text).map_err(|e| scene_error(py, &e))?;
    if preview {
        scene = scene.preview(4, 2000);
    }
    let watch = Arc::new(Watch::default());
    opts.out = Some(out);
    opts.watch = Some(watch.clone());
    let report = watched(py, &watch, progress.as_ref(), || run_scene(&scene, &opts))?;
    let report = report.map_err(|e| error(py, e))?;
    Ok(serde_json::to_string_pretty(&report.summary).unwrap_or_default())
}

/// Keyword arguments as [`RunOptions`]; `out` is the positional argument.
fn run_options(options: Option<&Bound<PyDict>>) -> PyResult<RunOptions> {
    let (names, mut pairs) = (RunOptions::names(), vec![]);
    for (k, v) in options.into_iter().flatten() {
        let name: String = k.extract()?;
        if name == "out" || !names.contains(&name) {
            return Err(PyTypeError::new_err(format!(
                "run() got an unexpected keyword argument '{name}' (run options: {})",
                names.join(", ")
            )));
        }
        if v.is_none() || (v.is_instance_of::<PyBool>() && !v.is_truthy()?) {
            continue;
        }
        let value = match v.is_instance_of::<PyBool>() {
            true => None,
            false => Some(v.str()?.to_string()),
        };
        pairs.push((name, value));
    }
    RunOptions::from_pairs(&pairs).map_err(PyValueError::new_err)
}

/// The keywords of `run` that are `reeb run`'s options.
#[pyfunction]
fn run_option_names() -> Vec<String> {
    RunOptions::names()
}

/// `reeb merge DIR`: checks that every shard of the run in `DIR.partial`
/// finished, then writes `summary.json` and the pictures; returns the
/// summary's text.
#[pyfunction]
#[pyo3(signature = (out, force=false))]
fn merge(py: Python, out: PathBuf, force: bool) -> PyResult<String> {
    let watch = Watch::default();
    let report = watched(py, &watch, None, || reeb::output::run::merge(&out, force))?;
    let report = report.map_err(|e| error(py, e))?;
    Ok(serde_json::to_string_pretty(&report.summary).unwrap_or_default())
}

/// Every gate of `run` without running: the scene, its sizes, the output
/// directory's refusals. Returns JSON: warnings, plans, trajectories,
/// estimated output bytes.
#[pyfunction]
#[pyo3(signature = (text, path, precision=None, out=None))]
fn check(
    py: Python,
    text: &str,
    path: &str,
    precision: Option<&str>,
    out: Option<PathBuf>,
) -> PyResult<String> {
    let scene = Scene::parse(Path::new(path), text).map_err(|e| scene_error(py, &e))?;
    let precision = parse::<Precision>("precision", precision)?.unwrap_or(scene.precision);
    let g = gates(&scene, precision, out.as_deref(), None).map_err(|e| error(py, e))?;
    let warnings: Vec<serde_json::Value> = g
        .warnings
        .iter()
        .map(|w| serde_json::json!({"line": w.line, "field": w.field, "message": w.message}))
        .collect();
    let v = serde_json::json!({
        "model": scene.model.name(),
        "scheme": scene.scheme,
        "precision": precision.name(),
        "trajectories": scene.ensemble_size(),
        "axes": scene.axes.iter().map(|a| a.name.clone()).collect::<Vec<_>>(),
        "plans": g.subs.len(),
        "output_bytes": g.estimate.bytes,
        "out": g.out,
        "warnings": warnings,
    });
    Ok(v.to_string())
}

/// `reeb verify`: the oracles and convergence orders on `backend` in
/// `precision`; returns the rows as JSON.
#[pyfunction]
#[pyo3(signature = (backend="cpu", precision="f64"))]
fn verify(py: Python, backend: &str, precision: &str) -> PyResult<String> {
    let backend = parse::<BackendChoice>("backend", Some(backend))?.unwrap_or(BackendChoice::Cpu);
    let precision = parse::<Precision>("precision", Some(precision))?.unwrap_or(Precision::F64);
    let (engine, _) = Engine::resolve(backend, precision).map_err(|e| error(py, e.into()))?;
    let target = Target { engine, precision };
    let watch = Watch::default();
    let rows = watched(py, &watch, None, || reeb::verify::run_all(&target, |_| {}))?;
    let rows: Vec<serde_json::Value> = rows
        .iter()
        .map(|c| {
            serde_json::json!({
                "check": c.name, "pass": c.pass, "expected": c.expected,
                "measured": c.measured, "tolerance": c.tolerance,
            })
        })
        .collect();
    Ok(serde_json::Value::from(rows).to_string())
}

/// What `reeb info` says, as JSON: version, CPU kernels, GPU adapters.
#[pyfunction]
fn info() -> String {
    let isa = format!("{:?}", reeb::backend::cpu::isa());
    let adapters = list_adapters();
    let gpu = match Engine::gpu(None) {
        Ok(Engine::Gpu(ctx)) => Ok(ctx.describe()),
        Ok(Engine::Cpu) => Err("no GPU engine".to_string()),
        Err(e) => Err(e.to_string()),
    };
    serde_json::json!({
        "version": env!("CARGO_PKG_VERSION"),
        "cpu": {"threads": reeb::backend::cpu::threads(), "kernels": isa},
        "adapters": adapters,
        "gpu": gpu.as_ref().ok(),
        "gpu_unavailable": gpu.err(),
    })
    .to_string()
}

/// `reeb report KIND`: the work–precision (`"work-precision"`) or
/// stability (`"stability"`) report of the scene, into `out` (default as
/// the command's); returns the path of its main file (`report.md` or
/// `stability.csv`) in the report's directory.
#[pyfunction]
#[pyo3(signature = (kind, text, path, out=None, backend=None, precision=None, force=false))]
#[allow(clippy::too_many_arguments)]
fn report(
    py: Python,
    kind: &str,
    text: &str,
    path: &str,
    out: Option<PathBuf>,
    backend: Option<&str>,
    precision: Option<&str>,
    force: bool,
) -> PyResult<String> {
    use reeb::report::{stability, work_precision, ReportOptions};
    let make: fn(&Scene, &ReportOptions) -> anyhow::Result<PathBuf> = match kind {
        "work-precision" => work_precision,
        "stability" => stability,
        _ => {
            return Err(PyValueError::new_err(format!(
                "report: `{kind}` is not a report (work-precision, stability)"
            )))
        }
    };
    let scene = Scene::parse(Path::new(path), text).map_err(|e| scene_error(py, &e))?;
    let watch = Watch::default();
    let opts = ReportOptions {
        out,
        backend: parse::<BackendChoice>("backend", backend)?,
        precision: parse::<Precision>("precision", precision)?,
        force,
        stop: Some(watch.stop.clone()),
    };
    let written = watched(py, &watch, None, || make(&scene, &opts))?;
    let written = written.map_err(|e| error(py, e))?;
    Ok(written.display().to_string())
}

/// Panics on the engine's thread, as a bug in reeb would: the tests' way
/// to see that a panic reaches Python as `reeb.InternalError`.
#[pyfunction]
fn _panic(py: Python, message: String) -> PyResult<()> {
    watched(py, &Watch::default(), None, || -> () {
        panic!("{message}")
    })
}

#[pymodule]
fn _reeb(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(run_option_names, m)?)?;
    m.add_function(wrap_pyfunction!(check, m)?)?;
    m.add_function(wrap_pyfunction!(merge, m)?)?;
    m.add_function(wrap_pyfunction!(verify, m)?)?;
    m.add_function(wrap_pyfunction!(info, m)?)?;
    m.add_function(wrap_pyfunction!(report, m)?)?;
    m.add_function(wrap_pyfunction!(_panic, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
