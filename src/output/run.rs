//! `reeb run`: a scene through a backend into a directory of arrays, a
//! summary and pictures.
//!
//! The directory is claimed before any work and written as `<dir>.partial`
//! (`directory.rs`), then swapped into place: a run that fails or is killed
//! never leaves a directory that looks complete, and nothing the user did
//! not ask reeb to replace is touched; `summary.json` is the last file
//! written.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use anyhow::{Context, Result};

use crate::backend::Engine;
use crate::models::Flows;
use crate::num::precision::Precision;
use crate::output::arrays::write_arrays;
pub use crate::output::arrays::write_npy;
use crate::output::directory::{self, Claim};
use crate::plan::observations::Observations;
use crate::plan::size::Estimate;
use crate::scene::{BackendChoice, Scene, SceneWarning, SubRun};

/// What a finished run reports.
pub struct RunReport {
    pub out: PathBuf,
    pub summary: serde_json::Value,
    pub line: String,
}

/// Options of `reeb run` that override the scene.
#[derive(Default)]
pub struct RunOptions {
    pub out: Option<PathBuf>,
    pub backend: Option<BackendChoice>,
    pub precision: Option<Precision>,
    /// Show a progress bar (on stderr, when it is a terminal).
    pub progress: bool,
    /// Largest output size accepted before running (default: 70 % of available memory).
    pub max_output_bytes: Option<u64>,
    /// Replace `out` even when it holds files reeb did not write.
    pub force: bool,
}

/// Runs `scene` and writes its directory.
pub fn run_scene(scene: &Scene, opts: &RunOptions) -> Result<RunReport> {
    let precision = opts.precision.unwrap_or(scene.precision);
    let choice = opts.backend.unwrap_or(scene.backend);
    let Gated {
        warnings,
        subs,
        estimate,
        out,
    } = gates(scene, precision, opts.out.as_deref(), opts.max_output_bytes)?;
    let claim = directory::claim(&out, &[&scene.path], opts.force)?;
    // On disk the scene's arrays once: half the memory estimate.
    claim.check_space(estimate.bytes / 2)?;
    let (engine, notice) = Engine::resolve(choice, precision)?;
    if let Some(n) = notice {
        eprintln!("{n}");
    }
    let made = Made {
        engine: &engine,
        precision,
        warnings: &warnings,
    };
    match precision {
        Precision::F32 => run_typed::<f32>(scene, subs, claim, opts, &made),
        Precision::F64 => run_typed::<f64>(scene, subs, claim, opts, &made),
    }
}

/// What passed the gates of a run.
pub struct Gated {
    pub warnings: Vec<SceneWarning>,
    pub subs: Vec<SubRun>,
    pub estimate: Estimate,
    /// The output directory: `--out`, or `runs/<scene name>`.
    pub out: PathBuf,
}

/// The gates `reeb run` applies before any work, and `reeb check` as they
/// are: the checks of the working precision (refusals; warnings printed),
/// the plans, and the size of the outputs against `max_output_bytes` (by
/// default 70 % of the available memory). The output directory's own gate
/// follows: [`directory::claim`] for a run, [`directory::check`] for check.
pub fn gates(
    scene: &Scene,
    precision: Precision,
    out: Option<&Path>,
    max_output_bytes: Option<u64>,
) -> Result<Gated> {
    let warnings = scene.checks(precision)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    let subs = scene.sub_runs()?;
    let estimate = scene.size_gate(&subs, precision, max_output_bytes)?;
    let out = out.map_or_else(|| Path::new("runs").join(&scene.name), Path::to_path_buf);
    Ok(Gated {
        warnings,
        subs,
        estimate,
        out,
    })
}

/// How a run is made: engine, precision, and the warnings it was given.
struct Made<'a> {
    engine: &'a Engine,
    precision: Precision,
    warnings: &'a [SceneWarning],
}

fn run_typed<R: Flows>(
    scene: &Scene,
    subs: Vec<SubRun>,
    claim: Claim,
    opts: &RunOptions,
    made: &Made,
) -> Result<RunReport> {
    let (engine, precision) = (made.engine, made.precision);
    let run = integrate_scene::<R>(scene, &subs, engine, opts.progress)?;
    let partial = claim.dir();
    let mut files = write_arrays(scene, partial, &run.observations)?;
    match crate::output::pictures::draw(scene, partial, &run.observations) {
        Ok(p) => files.extend(p),
        Err(e) => eprintln!("warning: pictures not drawn: {e:#}"),
    }
    let summary = summary(scene, &subs, made, &run, &files);
    write_json(&partial.join("summary.json"), &summary)?;
    let out = claim.commit()?;
    let n = scene.ensemble_size();
    let ok = run.observations.count_ok();
    let line = format!(
        "{}: {} trajectories × {} steps on {} ({}) in {:.3} s: {:.3e} trajectory-steps/s; {} ok, {} non-finite → {}",
        scene.name,
        n,
        run.max_steps,
        engine.name(),
        precision,
        run.seconds,
        run.rate(),
        ok,
        n - ok,
        out.display()
    );
    Ok(RunReport { out, summary, line })
}

/// A scene integrated: its arrays (rows in the scene's axis order) and timing.
struct SceneRun<R> {
    observations: Observations<R>,
    seconds: f64,
    timing: &'static str,
    max_steps: u64,
    traj_steps: u64,
}

impl<R> SceneRun<R> {
    /// Trajectory-steps per second of the integration.
    fn rate(&self) -> f64 {
        if self.seconds > 0.0 {
            self.traj_steps as f64 / self.seconds
        } else {
            f64::NAN
        }
    }
}

/// Integrates every sub-run of `scene` and places its rows in the scene's
/// arrays, with a progress bar on stderr if asked for.
fn integrate_scene<R: Flows>(
    scene: &Scene,
    subs: &[SubRun],
    engine: &Engine,
    progress: bool,
) -> Result<SceneRun<R>> {
    // Saturating: a count for the progress bar and the rate, never a size.
    let total: u64 = subs
        .iter()
        .map(|s| s.plan.traj_steps())
        .fold(0, u64::saturating_add);
    let done = AtomicU64::new(0);
    let bar = (progress && total > 0)
        .then(|| progress_bar(total, format!("{} on {}", scene.name, engine.name())));
    let finished = std::sync::atomic::AtomicBool::new(false);
    let (shape, strides) = (scene.shape(), scene.strides());
    let mut whole: Option<Observations<R>> = None;
    let (mut seconds, mut timing, mut max_steps) = (0.0, "wall clock", 0);
    std::thread::scope(|scope| -> Result<()> {
        if let Some(b) = &bar {
            let (b, done, finished) = (b.clone(), &done, &finished);
            scope.spawn(move || {
                while !finished.load(Ordering::Relaxed) {
                    b.set_position(done.load(Ordering::Relaxed));
                    std::thread::sleep(Duration::from_millis(100));
                }
            });
        }
        let result = (|| -> Result<()> {
            for sub in subs {
                let run = engine.run::<R>(&sub.plan, Some(&done))?;
                seconds += run.seconds;
                timing = run.timing;
                max_steps = max_steps.max(sub.plan.steps);
                if subs.len() == 1 {
                    whole = Some(run.observations);
                    continue;
                }
                whole
                    .get_or_insert_with(|| scene_arrays(scene, subs))
                    .place_rows(&run.observations, sub.scene_rows(&shape, &strides));
            }
            Ok(())
        })();
        finished.store(true, Ordering::Relaxed);
        result
    })?;
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    Ok(SceneRun {
        observations: whole.context("the scene produced no run")?,
        seconds,
        timing,
        max_steps,
        traj_steps: total,
    })
}

/// Arrays for the whole scene, shaped by its longest sub-run, NaN-filled.
fn scene_arrays<R: Flows>(scene: &Scene, subs: &[SubRun]) -> Observations<R> {
    let longest = subs.iter().max_by_key(|s| s.plan.steps).expect("a sub-run");
    let mut whole = longest.plan.clone();
    whole.n = scene.ensemble_size();
    Observations::for_plan(&whole)
}

fn progress_bar(total: u64, message: String) -> indicatif::ProgressBar {
    let b = indicatif::ProgressBar::with_draw_target(
        Some(total),
        indicatif::ProgressDrawTarget::stderr(),
    );
    b.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} {msg} [{bar:30}] {percent:>3}% {elapsed} (eta {eta}) {per_sec}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    b.set_message(message);
    b
}

/// Writes `value` as pretty JSON to `path`.
pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<()> {
    let write = || -> std::io::Result<()> {
        let mut f = BufWriter::new(std::fs::File::create(path)?);
        serde_json::to_writer_pretty(&mut f, value)?;
        f.write_all(b"\n")?;
        f.flush()
    };
    write().with_context(|| format!("writing {}", path.display()))
}

/// Where and how a run was made: the command line, the host, the UTC time
/// and the CPU kernels' instruction set.
/// `cpu_isa` is null when the CPU kernels did not run.
pub fn provenance(cpu_ran: bool) -> serde_json::Map<String, serde_json::Value> {
    let args: Vec<String> = std::env::args_os()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    let isa = cpu_ran.then(|| crate::backend::cpu::kernels::isa().name());
    let utc = humantime::format_rfc3339_seconds(std::time::SystemTime::now());
    let mut map = serde_json::Map::new();
    map.insert("command_line".into(), args.into());
    map.insert("host".into(), directory::hostname().into());
    map.insert("utc".into(), utc.to_string().into());
    map.insert("cpu_isa".into(), isa.into());
    map
}

/// The contents of summary.json.
fn summary<R>(
    scene: &Scene,
    subs: &[SubRun],
    made: &Made,
    run: &SceneRun<R>,
    files: &[String],
) -> serde_json::Value {
    let (engine, precision) = (made.engine, made.precision);
    let n = scene.ensemble_size();
    let ok = run
        .observations
        .nonfinite_step
        .iter()
        .filter(|s| **s == 0)
        .count();
    let mut value = serde_json::json!({
        "reeb_version": env!("CARGO_PKG_VERSION"),
        "scene": {
            "name": scene.name,
            "title": scene.title,
            "path": scene.path.display().to_string(),
            "model": scene.model.name(),
            "scheme": scene.scheme,
            "order": scene.order.clone().unwrap_or_else(|| scene.model.spec().default_order.to_string()),
            "horizon": scene.horizon,
            "axes": scene.axes.iter().map(|a| serde_json::json!({"name": a.name, "field": a.field, "len": a.values.len(), "first": a.values.first(), "last": a.values.last()})).collect::<Vec<_>>(),
            "text": scene.text,
        },
        "backend": engine.name(),
        "adapter": engine.describe(),
        "precision": precision.name(),
        "ensemble_size": n,
        "shape": scene.shape(),
        "steps": run.max_steps,
        "steps_per_run": subs.iter().map(|s| s.plan.steps).collect::<Vec<_>>(),
        "traj_steps": run.traj_steps,
        "integration_seconds": run.seconds,
        "timing": run.timing,
        "traj_steps_per_s": run.rate(),
        "evaluations_per_step": Some(scene.scheme.evaluations()),
        "status": {"ok": ok, "non_finite": n - ok},
        "warnings": made.warnings.iter().map(|w| w.to_string()).collect::<Vec<_>>(),
        "files": files,
    });
    if let serde_json::Value::Object(map) = &mut value {
        map.extend(provenance(matches!(engine, Engine::Cpu)));
    }
    value
}
