//! `reeb run`: a scene through a backend into a directory of arrays, a
//! summary and pictures; `reeb merge`: the shards of one run made whole.
//!
//! The directory is claimed before any work and written as `<dir>.partial`
//! (`directory.rs`), then swapped into place: a run that fails or is killed
//! never leaves a directory that looks complete, and nothing the user did
//! not ask reeb to replace is touched; `summary.json` is the last file
//! written. The ensemble is integrated chunk by chunk (`stream.rs`), each
//! written to disk and marked finished (`journal.rs`), so memory is bounded
//! by a chunk, a killed run resumes, and shards share one directory.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};

use crate::backend::phases::{lap, Phases};
use crate::backend::{Adapters, Engine};
use crate::models::Flows;
use crate::num::precision::Precision;
use crate::output::arrays::write_axes;
pub use crate::output::arrays::write_npy;
use crate::output::basins;
use crate::output::chunks::{self, Chunks};
use crate::output::directory::{self, Claim, Mode};
use crate::output::doubts;
use crate::output::journal::{self, Record};
use crate::output::references::references;
use crate::output::stream::{self, Target, Watch};
use crate::output::zarr;
use crate::plan::observations::bytes_per_trajectory;
use crate::plan::observers::ResonanceObs;
use crate::plan::size::{available_memory, Estimate};
use crate::scene::{BackendChoice, Format, Scene, SceneWarning, SubRun};

/// What a finished run reports.
pub struct RunReport {
    pub out: PathBuf,
    pub summary: serde_json::Value,
    pub line: String,
}

/// Options of `reeb run`: the one definition of its flags (flattened into
/// `reeb run`'s command line), of the Python `reeb.run` keywords (parsed by
/// the same definition) and, through [`TaskOptions::to_args`], of what each
/// Slurm task runs with.
#[derive(clap::Args, Default, Debug, Clone)]
pub struct RunOptions {
    /// Output directory (default: runs/<scene name>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the output directory even when it holds files reeb did not write (they are deleted).
    #[arg(long)]
    pub force: bool,
    /// Continue the run a kill interrupted in DIR.partial (the same scene):
    /// finished chunks are kept, the others integrated.
    #[arg(long)]
    pub resume: bool,
    /// Integrate only the K-th of N contiguous parts of the ensemble into the
    /// shared DIR.partial (0 <= K < N); `reeb merge DIR` finishes the run.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<Shard>,
    #[command(flatten)]
    pub task: TaskOptions,
    /// Show a progress bar (on stderr, when it is a terminal).
    #[arg(skip)]
    pub progress: bool,
    /// Largest output size accepted before running (default: the free disk
    /// where the outputs go).
    #[arg(skip)]
    pub max_output_bytes: Option<u64>,
    /// Followed from another thread (progress, a request to stop).
    #[arg(skip)]
    pub watch: Option<Arc<Watch>>,
    /// When the command began, reading the scene (`timing`'s wall clock;
    /// default: when the run is called).
    #[arg(skip)]
    pub started: Option<Instant>,
}

/// The options every part of one run takes alike: a `reeb run`, and each
/// task of `reeb slurm` (which passes them on with [`TaskOptions::to_args`]).
#[derive(clap::Args, Default, Debug, Clone, PartialEq)]
pub struct TaskOptions {
    /// Override the scene's backend: auto, cpu or gpu.
    #[arg(long)]
    pub backend: Option<BackendChoice>,
    /// Override the scene's precision: f32 or f64.
    #[arg(long)]
    pub precision: Option<Precision>,
    /// Override the scene's output.format: npy (one file per array) or zarr
    /// (one Zarr v3 store, DIR/run.zarr, for xarray and dask).
    #[arg(long)]
    pub format: Option<Format>,
    /// Trajectories per chunk, the unit of memory, checkpoint and shard
    /// (default: outputs of at most 1 GiB per chunk).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    pub chunk_trajectories: Option<u64>,
    /// Save the integrator's state inside a chunk every SECONDS (long
    /// horizons: a kill then loses at most that much; every finished chunk
    /// is kept too); 0: only finished chunks [default: 300].
    #[arg(long, value_name = "SECONDS", value_parser = seconds)]
    pub checkpoint_every: Option<Duration>,
    /// Run on GPU adapter INDEX (as `reeb info` numbers them from 0): one
    /// shard per GPU of a node.
    #[arg(long, value_name = "INDEX")]
    pub adapter: Option<usize>,
    /// Spread the chunks over several GPU adapters, one device and queue
    /// each: `all` (every GPU of the machine) or indices as `reeb info`
    /// numbers them (e.g. 0,1; an index twice opens two devices on it).
    /// The arrays are bitwise those of a one-adapter run.
    #[arg(long, value_name = "all|I,J", conflicts_with = "adapter")]
    pub adapters: Option<Adapters>,
}

impl TaskOptions {
    /// `--chunk-trajectories` as a count of rows.
    fn chunk_rows(&self) -> Option<usize> {
        self.chunk_trajectories
            .map(|n| usize::try_from(n).unwrap_or(usize::MAX))
    }

    /// These options as `reeb run` arguments (what a Slurm task is given):
    /// parsed back by [`RunOptions`], they are these options again.
    pub fn to_args(&self) -> Vec<String> {
        let TaskOptions {
            backend,
            precision,
            format,
            chunk_trajectories,
            checkpoint_every,
            adapter,
            adapters,
        } = self;
        let pairs = [
            ("--backend", backend.map(|b| b.name().to_string())),
            ("--precision", precision.map(|p| p.name().to_string())),
            ("--format", format.map(|f| f.name().to_string())),
            (
                "--chunk-trajectories",
                chunk_trajectories.map(|n| n.to_string()),
            ),
            (
                "--checkpoint-every",
                checkpoint_every.map(|d| d.as_secs_f64().to_string()),
            ),
            ("--adapter", adapter.map(|k| k.to_string())),
            ("--adapters", adapters.as_ref().map(Adapters::to_string)),
        ];
        pairs
            .into_iter()
            .filter_map(|(flag, v)| v.map(|v| [flag.to_string(), v]))
            .flatten()
            .collect()
    }
}

impl RunOptions {
    /// The long names of `reeb run`'s options (`chunk_trajectories`, …):
    /// the keywords the Python `run` takes besides the scene.
    pub fn names() -> Vec<String> {
        use clap::Args;
        RunOptions::augment_args(clap::Command::new("run"))
            .get_arguments()
            .filter_map(|a| a.get_long())
            .map(|l| l.replace('-', "_"))
            .collect()
    }

    /// Options from `(name, value)` pairs as [`RunOptions::names`] spells
    /// them, each parsed as its flag is (`None`: a flag given bare). An
    /// error names the keyword.
    pub fn from_pairs(pairs: &[(String, Option<String>)]) -> Result<RunOptions, String> {
        let names = RunOptions::names();
        let mut args = vec![];
        for (name, value) in pairs {
            if !names.contains(name) {
                return Err(format!(
                    "{name}: not an option of run (options: {})",
                    names.join(", ")
                ));
            }
            let flag = format!("--{}", name.replace('_', "-"));
            let arg = match value {
                Some(v) => format!("{flag}={v}"),
                None => flag,
            };
            RunOptions::parse_args(std::slice::from_ref(&arg))
                .map_err(|e| format!("{name}: {e}"))?;
            args.push(arg);
        }
        RunOptions::parse_args(&args)
    }

    /// Options from `reeb run`'s arguments (without the scene).
    pub fn parse_args(args: &[String]) -> Result<RunOptions, String> {
        use clap::{Args, FromArgMatches};
        let cmd = RunOptions::augment_args(clap::Command::new("run").no_binary_name(true));
        let clean = |e: clap::Error| {
            let text = e.render().to_string();
            let first = text.lines().next().unwrap_or_default();
            first.trim_start_matches("error: ").to_string()
        };
        let m = cmd.try_get_matches_from(args).map_err(clean)?;
        RunOptions::from_arg_matches(&m).map_err(clean)
    }
}

/// A number of seconds, 0 or more (fractions allowed).
pub fn seconds(s: &str) -> Result<Duration, String> {
    let x: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number of seconds"))?;
    Duration::try_from_secs_f64(x)
        .map_err(|_| format!("`{s}`: seconds must be 0 or more, and finite"))
}

/// The default time between checkpoints inside a chunk.
pub const CHECKPOINT_EVERY: Duration = Duration::from_secs(300);

fn checkpoint_every(opts: &RunOptions) -> Option<Duration> {
    match opts.task.checkpoint_every {
        None => Some(CHECKPOINT_EVERY),
        Some(d) if d.is_zero() => None,
        d => d,
    }
}

/// Part `index` of `count` contiguous parts of a run's chunks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl std::str::FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Shard, String> {
        let bad = || format!("`{s}` is not K/N with 0 <= K < N (e.g. 0/4)");
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            k.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

/// Runs `scene` and writes its directory (or, with a shard, its part of it).
pub fn run_scene(scene: &Scene, opts: &RunOptions) -> Result<RunReport> {
    let started = opts.started.unwrap_or_else(Instant::now);
    let precision = opts.task.precision.unwrap_or(scene.precision);
    let choice = opts.task.backend.unwrap_or(scene.backend);
    let Gated {
        warnings,
        subs,
        estimate,
        out,
    } = gates_crediting(
        scene,
        precision,
        opts.out.as_deref(),
        opts.max_output_bytes,
        opts.resume || opts.shard.is_some(),
    )?;
    let mode = match (opts.shard, opts.resume) {
        (Some(_), _) => Mode::Shared,
        (None, true) => Mode::Resume,
        (None, false) => Mode::Fresh,
    };
    if opts.task.adapter.is_some() && choice == BackendChoice::Cpu {
        bail!("--adapter pins a GPU adapter, and this run's backend is cpu; leave out one or the other");
    }
    if opts.task.adapters.is_some() && choice == BackendChoice::Cpu {
        bail!("--adapters spreads the run over GPU adapters, and this run's backend is cpu; leave out one or the other");
    }
    let claim = directory::claim_as(&out, &[&scene.path], opts.force, mode)?;
    // A run continued needs room only for what it has not written yet.
    let written = match mode {
        Mode::Fresh => 0,
        _ => directory::disk_usage(claim.dir()),
    };
    claim.check_space(estimate.bytes.saturating_sub(written))?;
    let (engines, notice) = engines(choice, precision, &opts.task, &subs)?;
    if let Some(n) = &notice {
        eprintln!("{n}");
    }
    let made = Made {
        engines: &engines,
        precision,
        warnings: &warnings,
        notice,
        started,
    };
    match precision {
        Precision::F32 => run_typed::<f32>(scene, &subs, claim, opts, &made),
        Precision::F64 => run_typed::<f64>(scene, &subs, claim, opts, &made),
    }
}

/// The engines of a run: one (`--backend`, `--adapter`; `auto` weighing
/// the GPU against the CPU on the first plan), or one per adapter of
/// `--adapters`; and the notice saying what was chosen.
fn engines(
    choice: BackendChoice,
    precision: Precision,
    task: &TaskOptions,
    subs: &[SubRun],
) -> Result<(Vec<Engine>, Option<String>)> {
    if let Some(list) = &task.adapters {
        let (engines, notice) = Engine::resolve_many(precision, list)?;
        return Ok((engines, Some(notice)));
    }
    let first = subs.first().map(|s| &s.plan);
    let (engine, notice) = Engine::resolve_for(choice, precision, task.adapter, first)?;
    Ok((vec![engine], notice))
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
/// default the free disk where they go). The output directory's own gate
/// follows: [`directory::claim`] for a run, [`directory::check`] for check.
pub fn gates(
    scene: &Scene,
    precision: Precision,
    out: Option<&Path>,
    max_output_bytes: Option<u64>,
) -> Result<Gated> {
    gates_crediting(scene, precision, out, max_output_bytes, false)
}

/// [`gates`]; with `continued` (`--resume`, a shard), the free disk is
/// counted with what `DIR.partial` already holds, which the run keeps.
fn gates_crediting(
    scene: &Scene,
    precision: Precision,
    out: Option<&Path>,
    max_output_bytes: Option<u64>,
    continued: bool,
) -> Result<Gated> {
    let subs = scene.sub_runs()?;
    let warnings = scene.checks_of(&subs, precision)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    let out = out.map_or_else(|| Path::new("runs").join(&scene.name), Path::to_path_buf);
    let written = match continued {
        true => directory::partial_of(&out).map_or(0, |p| directory::disk_usage(&p)),
        false => 0,
    };
    let limit = max_output_bytes
        .or_else(|| directory::free_space_for(&out).map(|free| free.saturating_add(written)));
    let estimate = scene.size_gate(&subs, precision, Some(limit.unwrap_or(u64::MAX)))?;
    Ok(Gated {
        warnings,
        subs,
        estimate,
        out,
    })
}

/// How a run is made: engines (none for `reeb merge`), precision, the
/// warnings it was given, why its backend (`auto`'s notice), and when the
/// command began (the wall clock of `timing`).
struct Made<'a> {
    engines: &'a [Engine],
    precision: Precision,
    warnings: &'a [SceneWarning],
    notice: Option<String>,
    started: Instant,
}

fn run_typed<R: Flows>(
    scene: &Scene,
    subs: &[SubRun],
    mut claim: Claim,
    opts: &RunOptions,
    made: &Made,
) -> Result<RunReport> {
    let dir = claim.dir().to_path_buf();
    let record = record_of(scene, subs, opts, made, &dir)?;
    if opts.resume && opts.shard.is_none() {
        claim.own()?;
    }
    // From here on a failure keeps the finished chunks for --resume.
    claim.keep();
    let all = 0..record.chunks.count();
    let mine = opts
        .shard
        .map_or(all, |s| record.chunks.shard(s.index, s.count));
    let target = Target {
        scene,
        subs,
        engines: made.engines,
        device: None,
        chunks: &record.chunks,
        dir: &dir,
        format: format_of(&record)?,
        checkpoint_every: checkpoint_every(opts),
        watch: opts.watch.as_deref(),
    };
    let setup = made.started.elapsed().as_secs_f64();
    let streamed = stream::integrate::<R>(&target, mine.clone(), opts.progress).map_err(|e| {
        anyhow::anyhow!(
            "{e:#}\n(the chunks that finished are kept in {}: run it again with --resume to continue)",
            dir.display()
        )
    })?;
    let Some(s) = opts.shard else {
        return finish::<R>(
            scene,
            subs,
            claim,
            &record,
            made,
            Integrated { setup, streamed },
        );
    };
    let line = format!(
        "{}: shard {}/{} (chunks {}..{} of {}) done → {}; when every shard has finished: reeb merge {}",
        scene.name,
        s.index,
        s.count,
        mine.start,
        mine.end,
        record.chunks.count(),
        dir.display(),
        claim.out().display()
    );
    let summary =
        serde_json::json!({"shard": [s.index, s.count], "chunks": [mine.start, mine.end]});
    Ok(RunReport {
        out: dir,
        summary,
        line,
    })
}

/// The record of this run in `dir`: this run's, or the one a killed run or
/// an earlier shard left there if it is the same run (refused otherwise).
fn record_of(
    scene: &Scene,
    subs: &[SubRun],
    opts: &RunOptions,
    made: &Made,
    dir: &Path,
) -> Result<Record> {
    let engine = made.engines.first().context("an engine")?;
    let adapters: Vec<String> = made.engines.iter().map(Engine::describe).collect();
    let mut record = Record {
        reeb_version: env!("CARGO_PKG_VERSION").into(),
        scene_path: scene.path.display().to_string(),
        scene_text: scene.text.clone(),
        preview: scene.preview,
        precision: made.precision.name().into(),
        backend: engine.name().into(),
        adapter: adapters.join("; "),
        choice: made.notice.clone(),
        format: opts.task.format.unwrap_or(scene.format).name().into(),
        chunks: chunks_of(scene, subs, opts.task.chunk_rows(), made.precision),
    };
    // A run continued keeps its chunks unless asked for others (shards on
    // machines of different memory agree on the first shard's).
    let (old, created) = record.establish(dir)?;
    if created && opts.resume {
        eprintln!(
            "note: {} holds no earlier run to resume; starting from the beginning",
            dir.display()
        );
    }
    if opts.task.chunk_trajectories.is_none() && old.chunks.shape == record.chunks.shape {
        record.chunks = old.chunks.clone();
    }
    let advice = match opts.shard {
        Some(_) => "the shards of one run must run the same scene with the same options: run this shard with those, or give this run another --out",
        None => "run it again without --resume to start over, or choose another --out",
    };
    record.check_same(&old, dir, advice)?;
    Ok(record)
}

/// The format a record names.
fn format_of(record: &Record) -> Result<Format> {
    record.format.parse().map_err(anyhow::Error::msg)
}

/// `reeb merge DIR`: checks that every chunk of the streamed run in
/// `DIR.partial` finished (every shard), then writes the pictures and
/// `summary.json` and puts the directory in place.
pub fn merge(out: &Path, force: bool) -> Result<RunReport> {
    let started = Instant::now();
    // Looked at before claiming, which would leave a partial behind.
    let partial = directory::partial_of(out)?;
    if Record::read(&partial)?.is_none() {
        bail!(
            "reeb merge {}: there is no sharded run to merge ({} holds no {}); run the shards first with reeb run SCENE --out {} --shard K/N",
            out.display(),
            partial.display(),
            journal::RECORD_FILE,
            out.display()
        );
    }
    let claim = directory::claim_as(out, &[], force, Mode::Resume)?;
    let dir = claim.dir().to_path_buf();
    let record = Record::read(&dir)?.context("the run's record vanished")?;
    claim.own()?;
    let mut scene = Scene::parse(Path::new(&record.scene_path), &record.scene_text)
        .with_context(|| format!("the scene recorded in {}", dir.display()))?;
    if let Some((values, steps)) = record.preview {
        scene = scene.preview(values, steps);
    }
    let precision: Precision = record
        .precision
        .parse()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let subs = scene.sub_runs()?;
    let warnings = scene.checks_of(&subs, precision)?;
    let made = Made {
        engines: &[],
        precision,
        warnings: &warnings,
        notice: None,
        started,
    };
    match precision {
        Precision::F32 => merge_typed::<f32>(&scene, &subs, claim, &record, &made),
        Precision::F64 => merge_typed::<f64>(&scene, &subs, claim, &record, &made),
    }
}

/// [`merge`] in precision `R`: every chunk finished, each checked against
/// its marker; one whose data is not what it wrote is integrated again, on
/// the run's backend, before the run is finished.
fn merge_typed<R: Flows>(
    scene: &Scene,
    subs: &[SubRun],
    claim: Claim,
    record: &Record,
    made: &Made,
) -> Result<RunReport> {
    let dir = claim.dir().to_path_buf();
    stream::finished(&dir, &record.chunks)?;
    let mut target = Target {
        scene,
        subs,
        engines: &[],
        device: None,
        chunks: &record.chunks,
        dir: &dir,
        format: format_of(record)?,
        checkpoint_every: Some(CHECKPOINT_EVERY),
        watch: None,
    };
    let bad = stream::damaged::<R>(&target, 0..record.chunks.count())?;
    let done = Integrated {
        setup: made.started.elapsed().as_secs_f64(),
        streamed: stream::Streamed {
            kept: None,
            overlap: 0.0,
        },
    };
    if bad.is_empty() {
        return finish::<R>(scene, subs, claim, record, made, done);
    }
    let choice: BackendChoice = record.backend.parse().map_err(anyhow::Error::msg)?;
    let (engine, _) = Engine::resolve_for(choice, made.precision, None, None).with_context(|| {
        format!(
            "{} chunk(s) must be integrated again on the run's backend ({}), which this machine lacks; run the shards that hold them again with --resume where it is",
            bad.len(),
            record.backend
        )
    })?;
    eprintln!(
        "integrating {} chunk(s) again on {}",
        bad.len(),
        engine.describe()
    );
    let engines = [engine];
    target.engines = &engines;
    for k in bad {
        stream::integrate::<R>(&target, k..k + 1, false)?;
    }
    let made = Made {
        engines: &engines,
        precision: made.precision,
        warnings: made.warnings,
        notice: None,
        started: made.started,
    };
    finish::<R>(scene, subs, claim, record, &made, done)
}

/// The chunks of a new run of `scene`: `rows` trajectories each, or outputs
/// of at most [`chunks::DEFAULT_BUDGET`] bytes (less on a small machine).
fn chunks_of(scene: &Scene, subs: &[SubRun], rows: Option<usize>, precision: Precision) -> Chunks {
    let shape = scene.shape();
    if let Some(rows) = rows {
        return Chunks::with_rows(&shape, rows);
    }
    let per_row = subs
        .iter()
        .filter_map(|s| bytes_per_trajectory(&s.plan, precision))
        .max()
        .unwrap_or(8);
    let budget = available_memory().map_or(chunks::DEFAULT_BUDGET, |m| {
        (m / 8).min(chunks::DEFAULT_BUDGET)
    });
    Chunks::with_budget(&shape, per_row, budget)
}

/// What the integration of a run leaves for [`finish`]: the seconds before
/// its first chunk, and what streaming the chunks left.
struct Integrated<R> {
    setup: f64,
    streamed: stream::Streamed<R>,
}

/// Pictures, summary and commit of a run whose chunks have all finished.
fn finish<R: Flows>(
    scene: &Scene,
    subs: &[SubRun],
    claim: Claim,
    record: &Record,
    made: &Made,
    integrated: Integrated<R>,
) -> Result<RunReport> {
    let mut since = Instant::now();
    let dir = claim.dir().to_path_buf();
    let done = stream::finished(&dir, &record.chunks)?;
    let format = format_of(record)?;
    let mut files = match format {
        Format::Npy => write_axes(scene, &dir)?,
        Format::Zarr => vec![],
    };
    let mut phases = Phases {
        setup: integrated.setup,
        writing: lap(&mut since),
        ..Phases::default()
    };
    match format {
        Format::Npy => {
            let list = stream::array_list::<R>(scene, subs)?;
            files.extend(list.into_iter().map(|a| a.file));
        }
        Format::Zarr => files.push(zarr::STORE.into()),
    }
    // The arrays reach the disk while the pictures are drawn.
    let (observations, doubts, pictures, basins) = std::thread::scope(|s| -> Result<_> {
        let synced = s.spawn(|| directory::sync_tree(&dir));
        let observations =
            stream::for_pictures(scene, subs, &dir, format, integrated.streamed.kept)?;
        let doubts = doubts::of(scene, subs, &observations);
        let basins = basins::of(scene, &observations);
        let pictures = crate::output::pictures::draw(scene, &dir, &observations, &doubts);
        let pictures = match &basins {
            Some(b) => pictures.and_then(|mut p| {
                p.extend(crate::output::basin_pictures::draw(scene, &dir, b)?);
                Ok(p)
            }),
            None => pictures,
        };
        synced.join().expect("syncing does not panic")?;
        Ok((observations, doubts, pictures, basins))
    })?;
    if let Some(b) = &basins {
        files.extend(basins::write(scene, &dir, format, b)?);
    }
    match pictures {
        Ok(p) => files.extend(p),
        Err(e) => eprintln!("warning: pictures not drawn: {e:#}"),
    }
    phases.pictures = lap(&mut since);
    let max_steps = subs.iter().map(|s| s.plan.steps).max().unwrap_or(0);
    let levels = cpu_levels(&done);
    let mut warnings: Vec<String> = made.warnings.iter().map(|w| w.to_string()).collect();
    for w in &doubts.warnings {
        eprintln!("warning: {w}");
        warnings.push(w.clone());
    }
    if levels.len() > 1 {
        let w = format!(
            "the chunks were integrated at different CPU instruction-set levels ({}): they agree to round-off, not bit for bit (set REEB_CPU_ISA to one level on every node for bitwise results)",
            levels.join(", ")
        );
        eprintln!("warning: {w}");
        warnings.push(w);
    }
    let ran = Ran {
        seconds: done.iter().map(|d| d.seconds).sum(),
        traj_steps: done.iter().map(|d| d.traj_steps).sum(),
        ok: done.iter().map(|d| d.ok).sum(),
        stopped: observations.count_stopped() as u64,
        timing: done.first().map_or("none".into(), |d| d.timing.clone()),
        phases: done.iter().fold(phases, |p, d| {
            p.plus(Phases {
                integration: d.seconds,
                ..d.phases
            })
        }),
        max_steps,
        chunks: done.len(),
        cpu_isa: (!levels.is_empty()).then(|| levels.join(" + ")),
        devices: devices(&done),
        warnings,
    };
    let mut summary = summary(scene, subs, made, record, &ran, &files);
    summary["dims"] = dims_of::<R>(scene, subs)?;
    for (key, value) in doubts.summary {
        summary[key] = value;
    }
    if let Some(r) = &scene.observers.resonance {
        summary["resonance"] = capture(r, &crate::output::arrays::resonance(r, &observations)?);
    }
    if let Some(b) = &basins {
        summary["attractors"] = b.summary.clone();
        let axes: Vec<&str> = scene.axes.iter().map(|a| a.name.as_str()).collect();
        summary["dims"]["attractor"] = axes.into();
    }
    let wall = made.started.elapsed().as_secs_f64();
    summary["timing"] = timing(&ran.phases, integrated.streamed.overlap, wall);
    if format == Format::Zarr {
        zarr::finish(&dir, scene, summary.clone())?;
    }
    write_json(&dir.join("summary.json"), &summary)?;
    journal::remove(&dir)?;
    let out = claim.commit()?;
    let n = scene.ensemble_size() as u64;
    let line = format!(
        "{}: {} trajectories × {} steps on {} ({}): {:.3} s wall, {:.3} s integrating ({} trajectory-steps/s); {} ok, {} non-finite{} → {}",
        scene.name,
        n,
        ran.max_steps,
        record.backend,
        made.precision,
        wall,
        ran.seconds,
        crate::output::progress::sig3(ran.rate()),
        ran.ok,
        n - ran.ok - ran.stopped,
        if ran.stopped > 0 {
            format!(", {} stopped", ran.stopped)
        } else {
            String::new()
        },
        out.display()
    ) + &shares(&ran);
    Ok(RunReport { out, summary, line })
}

/// `summary.json`'s `timing`: the seconds of each phase, added up over the
/// chunks (a resumed run's too, from their markers); `overlap`, the seconds
/// this command read back or wrote one chunk while a GPU integrated
/// another; and the
/// wall clock of this command, from its start to the summary.
fn timing(phases: &Phases, overlap: f64, wall: f64) -> serde_json::Value {
    let mut map: serde_json::Map<String, serde_json::Value> = phases
        .named()
        .into_iter()
        .map(|(name, s)| (name.to_string(), s.into()))
        .collect();
    map.insert("overlap".into(), overlap.into());
    map.insert("wall".into(), wall.into());
    map.into()
}

/// `; chunks by device: #0 adapter 0: NAME 5, #1 adapter 1: NAME 4` for a
/// run spread over several devices.
fn shares(ran: &Ran) -> String {
    let Some(serde_json::Value::Array(list)) = &ran.devices else {
        return String::new();
    };
    let each: Vec<String> = list
        .iter()
        .map(|d| format!("{} {}", d["device"].as_str().unwrap_or("?"), d["chunks"]))
        .collect();
    format!("; chunks by device: {}", each.join(", "))
}

/// Each array's dimension names (the scene's axes, then `frame`, `point`,
/// `component`): what xarray and `reeb.open` label them with.
fn dims_of<R: Flows>(scene: &Scene, subs: &[SubRun]) -> Result<serde_json::Value> {
    let axes: Vec<&str> = scene.axes.iter().map(|a| a.name.as_str()).collect();
    let dims: serde_json::Map<String, serde_json::Value> = stream::array_list::<R>(scene, subs)?
        .into_iter()
        .map(|a| {
            let names: Vec<&str> = axes.iter().copied().chain(a.inner_names).collect();
            (a.file.trim_end_matches(".npy").to_string(), names.into())
        })
        .collect();
    Ok(dims.into())
}

/// What each GPU device did, when the chunks name more than one: its
/// chunks, trajectory-steps and integration seconds.
fn devices(done: &[journal::Done]) -> Option<serde_json::Value> {
    let mut by: std::collections::BTreeMap<&str, (u64, u64, f64)> = Default::default();
    for d in done {
        if let Some(name) = &d.device {
            let e = by.entry(name).or_default();
            *e = (e.0 + 1, e.1 + d.traj_steps, e.2 + d.seconds);
        }
    }
    (by.len() > 1).then(|| {
        by.iter()
            .map(|(name, (chunks, steps, secs))| serde_json::json!({"device": name, "chunks": chunks, "traj_steps": steps, "seconds": secs}))
            .collect()
    })
}

/// The CPU levels the chunks were integrated at, each once, with the
/// number of chunks (`x86-64-v3 (12 chunks)`) when there are several.
fn cpu_levels(done: &[journal::Done]) -> Vec<String> {
    let mut count: std::collections::BTreeMap<&str, usize> = Default::default();
    for d in done {
        if let Some(level) = &d.cpu_isa {
            *count.entry(level).or_default() += 1;
        }
    }
    match count.len() {
        0 | 1 => count.keys().map(|l| l.to_string()).collect(),
        _ => count
            .iter()
            .map(|(l, n)| format!("{l} ({n} chunk{})", if *n == 1 { "" } else { "s" }))
            .collect(),
    }
}

/// The integration of a run, added up over its chunks.
struct Ran {
    seconds: f64,
    traj_steps: u64,
    ok: u64,
    /// Trajectories the stop condition stopped.
    stopped: u64,
    /// How `seconds` was measured.
    timing: String,
    /// Every phase's seconds (`integration` added up as `seconds` is).
    phases: Phases,
    max_steps: u64,
    chunks: usize,
    /// The level(s) the CPU kernels ran at (`None`: not the CPU).
    cpu_isa: Option<String>,
    /// What each GPU device integrated, when a run spread over several.
    devices: Option<serde_json::Value>,
    /// The scene's warnings, and the run's own.
    warnings: Vec<String>,
}

impl Ran {
    /// Trajectory-steps per second of the integration.
    fn rate(&self) -> f64 {
        if self.seconds > 0.0 {
            self.traj_steps as f64 / self.seconds
        } else {
            f64::NAN
        }
    }
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

/// `summary.json`'s `resonance`: the ratios, and how many trajectories
/// (and what fraction of the ensemble) each captured, and none.
fn capture(r: &ResonanceObs, index: &[i32]) -> serde_json::Value {
    let n = index.len().max(1) as f64;
    let labels: Vec<String> = (0..=r.ratios.len()).map(|k| r.label(k)).collect();
    let counts = r.counts(index);
    let by_label =
        |f: &dyn Fn(u64) -> serde_json::Value| -> serde_json::Map<String, serde_json::Value> {
            labels
                .iter()
                .zip(&counts)
                .map(|(l, c)| (l.clone(), f(*c)))
                .collect()
        };
    serde_json::json!({
        "var": r.var,
        "ratios": labels[..r.ratios.len()],
        "tolerance": r.tolerance,
        "counts": by_label(&|c| c.into()),
        "fractions": by_label(&|c| (c as f64 / n).into()),
    })
}

/// The contents of summary.json.
fn summary(
    scene: &Scene,
    subs: &[SubRun],
    made: &Made,
    record: &Record,
    ran: &Ran,
    files: &[String],
) -> serde_json::Value {
    let n = scene.ensemble_size() as u64;
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
        "backend": record.backend,
        "adapter": record.adapter,
        "backend_choice": record.choice,
        "precision": made.precision.name(),
        "ensemble_size": n,
        "shape": scene.shape(),
        "steps": ran.max_steps,
        "steps_per_run": subs.iter().map(|s| s.plan.steps).collect::<Vec<_>>(),
        "traj_steps": ran.traj_steps,
        "integration_seconds": ran.seconds,
        "integration_clock": ran.timing,
        "traj_steps_per_s": ran.rate(),
        "evaluations_per_step": Some(scene.scheme.evaluations()),
        "status": {"ok": ran.ok, "non_finite": n - ran.ok - ran.stopped, "stopped": ran.stopped},
        "chunks": {"count": ran.chunks, "trajectories": record.chunks.largest(), "format": record.format},
        "warnings": ran.warnings,
        "files": files,
        "references": references(&scene.scheme.name, scene.model.name()),
    });
    if let serde_json::Value::Object(map) = &mut value {
        map.extend(provenance(record.backend == "cpu"));
        // The chunks' own levels: a merge may run on another node.
        if ran.cpu_isa.is_some() {
            map.insert("cpu_isa".into(), ran.cpu_isa.clone().into());
        }
        if let Some(d) = &ran.devices {
            map.insert("devices".into(), d.clone());
        }
    }
    value
}
