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

use anyhow::{bail, Context, Result};
use npyz::WriterBuilder;

use crate::backend::Engine;
use crate::models::Flows;
use crate::num::precision::Precision;
use crate::plan::observations::{estimate_bytes, Observations};
use crate::scene::{BackendChoice, OutVar, Scene};

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

/// Available memory in bytes (Linux `/proc/meminfo`), if known.
fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    line.split_whitespace()
        .nth(1)?
        .parse::<u64>()
        .ok()
        .map(|kb| kb * 1024)
}

/// Human-readable bytes.
pub fn bytes(b: u64) -> String {
    let units = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut x = b as f64;
    let mut u = 0;
    while x >= 1024.0 && u + 1 < units.len() {
        x /= 1024.0;
        u += 1;
    }
    format!("{x:.1} {}", units[u])
}

/// Runs `scene` and writes its directory.
pub fn run_scene(scene: &Scene, opts: &RunOptions) -> Result<RunReport> {
    let precision = opts.precision.unwrap_or(scene.precision);
    let choice = opts.backend.unwrap_or(scene.backend);
    let subs = scene.sub_runs()?;
    // Memory before any work: the observations of every sub-run, twice over
    // while they are assembled into the scene's arrays.
    let need: u64 = 2 * subs
        .iter()
        .map(|s| estimate_bytes(&s.plan, precision))
        .sum::<u64>();
    let limit = opts
        .max_output_bytes
        .or_else(|| available_memory().map(|m| m / 10 * 7))
        .unwrap_or(u64::MAX);
    if need > limit {
        bail!(
            "{}: the outputs need about {} and {} is available; record less: a larger output.trajectory.every, fewer output.trajectory.vars or output.poincare.vars, a smaller output.poincare.max_points, or fewer values along an axis",
            scene.path.display(),
            bytes(need),
            bytes(limit)
        );
    }
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
    subs: Vec<crate::scene::SubRun>,
    opts: &RunOptions,
    engine: &Engine,
    precision: Precision,
) -> Result<RunReport> {
    let n = scene.ensemble_size();
    let total: u64 = subs.iter().map(|s| s.plan.traj_steps()).sum();
    let done = AtomicU64::new(0);
    let bar = (opts.progress && total > 0).then(|| {
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
        b.set_message(format!("{} on {}", scene.name, engine.name()));
        b
    });
    // The scene's arrays, rows in the scene's axis order; sub-runs of fewer
    // steps fill the leading frames of their rows.
    let mut asm: Option<Observations<R>> = None;
    let mut seconds = 0.0;
    let mut timing = "wall clock";
    let mut max_steps = 0;
    let (shape, strides) = (scene.shape(), scene.strides());
    let finished = std::sync::atomic::AtomicBool::new(false);
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
            for sub in &subs {
                let run = engine.run::<R>(&sub.plan, Some(&done))?;
                let (obs, secs, how) = (run.observations, run.seconds, run.timing);
                seconds += secs;
                timing = how;
                max_steps = max_steps.max(sub.plan.steps);
                if subs.len() == 1 {
                    asm = Some(obs);
                    continue;
                }
                let a = asm.get_or_insert_with(|| {
                    let longest = subs.iter().max_by_key(|s| s.plan.steps).unwrap_or(sub);
                    let mut whole = longest.plan.clone();
                    whole.n = n;
                    Observations::for_plan(&whole)
                });
                // Local row j (over the free axes) → global row g.
                for (j, g) in sub.scene_rows(&shape, &strides).enumerate() {
                    for ((_, dst), (_, src)) in a.final_values.iter_mut().zip(&obs.final_values) {
                        dst[g] = src[j];
                    }
                    for ((_, dst), (_, src)) in a.trajectory.iter_mut().zip(&obs.trajectory) {
                        dst[g * a.frames..g * a.frames + obs.frames]
                            .copy_from_slice(&src[j * obs.frames..(j + 1) * obs.frames]);
                    }
                    let mp = obs.max_points;
                    for ((_, dst), (_, src)) in a.poincare.iter_mut().zip(&obs.poincare) {
                        dst[g * mp..(g + 1) * mp].copy_from_slice(&src[j * mp..(j + 1) * mp]);
                    }
                    if mp > 0 {
                        a.poincare_count[g] = obs.poincare_count[j];
                    }
                    if !obs.cycle_amplitude.is_empty() {
                        a.cycle_amplitude[g] = obs.cycle_amplitude[j];
                        a.cycle_period[g] = obs.cycle_period[j];
                    }
                    a.nonfinite_step[g] = obs.nonfinite_step[j];
                }
            }
            Ok(())
        })();
        finished.store(true, Ordering::Relaxed);
        result
    })?;
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    let a = asm.context("the scene produced no run")?;

    // Write into <out>.partial, then move into place.
    let out = opts
        .out
        .clone()
        .unwrap_or_else(|| Path::new("runs").join(&scene.name));
    let partial = partial_dir(&out);
    if partial.exists() {
        std::fs::remove_dir_all(&partial)
            .with_context(|| format!("removing {}", partial.display()))?;
    }
    std::fs::create_dir_all(&partial).with_context(|| format!("creating {}", partial.display()))?;
    let mut files: Vec<String> = vec![];
    let shape: Vec<u64> = scene.shape().iter().map(|s| *s as u64).collect();
    let with = |extra: &[u64]| -> Vec<u64> { shape.iter().chain(extra).copied().collect() };

    for ax in &scene.axes {
        write_npy(
            &partial.join(format!("axis_{}.npy", ax.name)),
            &[ax.values.len() as u64],
            ax.values.iter().copied(),
        )?;
        files.push(format!("axis_{}.npy", ax.name));
    }
    let vec_out = |vars: &[OutVar],
                   arrays: &[(String, Vec<R>)],
                   inner: usize,
                   prefix: &str,
                   files: &mut Vec<String>|
     -> Result<()> {
        for v in vars {
            let comps: Vec<&Vec<R>> = v
                .components
                .iter()
                .map(|c| {
                    arrays
                        .iter()
                        .find(|(n, _)| n == c)
                        .map(|(_, x)| x)
                        .context("recorded component")
                })
                .collect::<Result<_>>()?;
            let mut dims = if inner > 0 {
                with(&[inner as u64])
            } else {
                with(&[])
            };
            let name = format!("{prefix}_{}.npy", v.name);
            if comps.len() == 1 {
                write_npy(&partial.join(&name), &dims, comps[0].iter().copied())?;
            } else {
                dims.push(comps.len() as u64);
                let len = comps[0].len();
                write_npy(
                    &partial.join(&name),
                    &dims,
                    (0..len).flat_map(|i| comps.iter().map(move |c| c[i])),
                )?;
            }
            files.push(name);
        }
        Ok(())
    };
    vec_out(&scene.final_vars, &a.final_values, 0, "final", &mut files)?;
    if let Some((_, vars)) = &scene.trajectory {
        vec_out(vars, &a.trajectory, a.frames, "trajectory", &mut files)?;
    }
    if let Some((_, vars, _)) = &scene.poincare {
        vec_out(vars, &a.poincare, a.max_points, "poincare", &mut files)?;
        write_npy(
            &partial.join("poincare_count.npy"),
            &with(&[]),
            a.poincare_count.iter().copied(),
        )?;
        files.push("poincare_count.npy".into());
    }
    if scene.cycle.is_some() {
        write_npy(
            &partial.join("cycle_amplitude.npy"),
            &with(&[]),
            a.cycle_amplitude.iter().copied(),
        )?;
        write_npy(
            &partial.join("cycle_period.npy"),
            &with(&[]),
            a.cycle_period.iter().copied(),
        )?;
        files.extend([
            "cycle_amplitude.npy".to_string(),
            "cycle_period.npy".to_string(),
        ]);
    }
    // status: 0 ok, 1 non-finite; status_step: the step it became non-finite (−1: never).
    write_npy(
        &partial.join("status.npy"),
        &with(&[]),
        a.nonfinite_step.iter().map(|s| u8::from(*s != 0)),
    )?;
    write_npy(
        &partial.join("status_step.npy"),
        &with(&[]),
        a.nonfinite_step
            .iter()
            .map(|s| if *s == 0 { -1i64 } else { *s as i64 }),
    )?;
    files.extend(["status.npy".to_string(), "status_step.npy".to_string()]);

    let pictures = crate::output::pictures::draw(scene, &partial, &a);
    let pictures = match pictures {
        Ok(p) => p,
        Err(e) => {
            eprintln!("warning: pictures not drawn: {e:#}");
            vec![]
        }
    };
    files.extend(pictures);

    let ok = a.count_ok();
    let rate = if seconds > 0.0 {
        total as f64 / seconds
    } else {
        f64::NAN
    };
    let summary = serde_json::json!({
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
        "steps": max_steps,
        "steps_per_run": subs.iter().map(|s| s.plan.steps).collect::<Vec<_>>(),
        "traj_steps": total,
        "integration_seconds": seconds,
        "timing": timing,
        "traj_steps_per_s": rate,
        "evaluations_per_step": crate::plan::scheme::Scheme::by_name(&scene.scheme).map(|s| s.evaluations()),
        "status": {"ok": ok, "non_finite": n - ok},
        "files": files,
    });
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
    let line = format!(
        "{}: {} trajectories × {} steps on {} ({}) in {:.3} s: {:.3e} trajectory-steps/s; {} ok, {} non-finite → {}",
        scene.name,
        n,
        max_steps,
        engine.name(),
        precision,
        seconds,
        rate,
        ok,
        n - ok,
        out.display()
    );
    Ok(RunReport { out, summary, line })
}

fn partial_dir(out: &Path) -> PathBuf {
    let mut name = out
        .file_name()
        .map(|s| s.to_os_string())
        .unwrap_or_else(|| "run".into());
    name.push(".partial");
    out.with_file_name(name)
}

/// Writes a C-order .npy array.
pub fn write_npy<T: npyz::AutoSerialize + npyz::Serialize>(
    path: &Path,
    shape: &[u64],
    data: impl IntoIterator<Item = T>,
) -> Result<()> {
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(shape)
        .writer(BufWriter::new(file))
        .begin_nd()?;
    w.extend(data)?;
    w.finish()?;
    Ok(())
}
