//! `reeb run`: a scene through a backend into a directory of arrays, a
//! summary and pictures.
//!
//! The directory is written as `<dir>.partial` and renamed into place at the
//! end, so a run that fails or is killed never leaves a directory that looks
//! complete; `summary.json` is the last file written.

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
use crate::plan::observations::Observations;
pub use crate::plan::size::{available_memory, bytes};
use crate::scene::{BackendChoice, Scene, SubRun};

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
}

/// Runs `scene` and writes its directory.
pub fn run_scene(scene: &Scene, opts: &RunOptions) -> Result<RunReport> {
    let precision = opts.precision.unwrap_or(scene.precision);
    let choice = opts.backend.unwrap_or(scene.backend);
    let subs = scene.sub_runs()?;
    // Memory before any work: the observations of every sub-run, twice over
    // while they are assembled into the scene's arrays (the gate `reeb
    // check` applies too).
    scene.size_gate(&subs, precision, opts.max_output_bytes)?;
    let (engine, notice) = Engine::resolve(choice, precision)?;
    if let Some(n) = notice {
        eprintln!("{n}");
    }
    match precision {
        Precision::F32 => run_typed::<f32>(scene, subs, opts, &engine, precision),
        Precision::F64 => run_typed::<f64>(scene, subs, opts, &engine, precision),
    }
}

fn run_typed<R: Flows>(
    scene: &Scene,
    subs: Vec<SubRun>,
    opts: &RunOptions,
    engine: &Engine,
    precision: Precision,
) -> Result<RunReport> {
    let run = integrate_scene::<R>(scene, &subs, engine, opts.progress)?;
    // Write into <out>.partial, then move into place.
    let out = opts
        .out
        .clone()
        .unwrap_or_else(|| Path::new("runs").join(&scene.name));
    let partial = fresh_partial(&out)?;
    let mut files = write_arrays(scene, &partial, &run.observations)?;
    match crate::output::pictures::draw(scene, &partial, &run.observations) {
        Ok(p) => files.extend(p),
        Err(e) => eprintln!("warning: pictures not drawn: {e:#}"),
    }
    let summary = summary(scene, &subs, engine, precision, &run, &files);
    {
        let mut f = BufWriter::new(std::fs::File::create(partial.join("summary.json"))?);
        serde_json::to_writer_pretty(&mut f, &summary)?;
        f.write_all(b"\n")?;
        f.flush()?;
    }
    if out.exists() {
        std::fs::remove_dir_all(&out).with_context(|| format!("replacing {}", out.display()))?;
    }
    std::fs::rename(&partial, &out)
        .with_context(|| format!("moving {} to {}", partial.display(), out.display()))?;
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
        .map(|s| (s.plan.n as u64).saturating_mul(s.plan.steps))
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

/// `<out>.partial`, empty and ready to write.
fn fresh_partial(out: &Path) -> Result<PathBuf> {
    let partial = partial_dir(out);
    if partial.exists() {
        std::fs::remove_dir_all(&partial)
            .with_context(|| format!("removing {}", partial.display()))?;
    }
    std::fs::create_dir_all(&partial).with_context(|| format!("creating {}", partial.display()))?;
    Ok(partial)
}

/// The contents of summary.json.
fn summary<R>(
    scene: &Scene,
    subs: &[SubRun],
    engine: &Engine,
    precision: Precision,
    run: &SceneRun<R>,
    files: &[String],
) -> serde_json::Value {
    let n = scene.ensemble_size();
    let ok = run
        .observations
        .nonfinite_step
        .iter()
        .filter(|s| **s == 0)
        .count();
    serde_json::json!({
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
        "files": files,
    })
}

fn partial_dir(out: &Path) -> PathBuf {
    let mut name = out
        .file_name()
        .map(|s| s.to_os_string())
        .unwrap_or_else(|| "run".into());
    name.push(".partial");
    out.with_file_name(name)
}
