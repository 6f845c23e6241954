//! A run streamed to disk: its chunks (`chunks.rs`) integrated one after
//! the other, each written into its slab of every array (`npy.rs`) and
//! marked finished (`journal.rs`), so that memory holds one chunk whatever
//! the size of the run; and the finished arrays read back for the pictures.

use std::io::Read;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};

use crate::backend::checkpoint::{Checkpoints, Contents};
use crate::backend::{Engine, Integration};
use crate::models::Flows;
use crate::num::precision::Real;
use crate::output::arrays::{arrays, out_vars, Array};
use crate::output::chunks::Chunks;
use crate::output::journal::{self, Done, Written};
use crate::output::npy::{read_rows, Slabs};
use crate::output::progress::{self, Followed};
use crate::output::zarr;
use crate::plan::observations::{ColMut, ColumnMut, Observations};
use crate::plan::size::bytes;
use crate::plan::snapshot::{get_one, put, read_observations, write_observations, Header};
use crate::plan::Plan;
use crate::scene::{Format, Scene, SubRun};

/// Frames and section points are read back for the pictures up to this
/// many bytes; beyond, only the per-trajectory values are.
const PICTURE_BUDGET: u64 = 1 << 30;

/// What a streamed run integrates, and where.
#[derive(Clone, Copy)]
pub struct Target<'a> {
    pub scene: &'a Scene,
    pub subs: &'a [SubRun],
    /// The engines that integrate, each taking the next chunk left (none:
    /// the chunks are only checked).
    pub engines: &'a [Engine],
    /// Which of several engines this is (`#k` in the chunks' markers).
    pub device: Option<usize>,
    pub chunks: &'a Chunks,
    /// `DIR.partial`.
    pub dir: &'a Path,
    pub format: Format,
    /// Time between checkpoints inside a chunk (`None`: only finished chunks).
    pub checkpoint_every: Option<Duration>,
    /// Followed from another thread, if given.
    pub watch: Option<&'a Watch>,
}

/// A run followed from another thread (the Python package polls it every
/// 0.1 s): the trajectory-steps done and in all, and a request to stop,
/// which the backends honour within a window or 64 steps of a block.
#[derive(Debug, Default)]
pub struct Watch {
    pub done: AtomicU64,
    pub total: AtomicU64,
    pub stop: Arc<AtomicBool>,
}

/// Where a run's chunks go: `.npy` files written in slabs, or a Zarr store.
enum Sink {
    Npy(Vec<(PathBuf, Slabs)>),
    Zarr(zarr::Store),
}

impl Sink {
    /// Opens (or creates) every array of the run.
    fn open<R: Flows>(t: &Target) -> Result<Sink> {
        let list = array_list::<R>(t.scene, t.subs)?;
        let shape = t.scene.shape();
        Ok(match t.format {
            Format::Npy => Sink::Npy(
                list.iter()
                    .map(|a| {
                        let path = t.dir.join(&a.file);
                        let rows = t.chunks.rows() as u64;
                        Slabs::open(&path, a.descr, &a.shape(&shape), rows).map(|s| (path, s))
                    })
                    .collect::<Result<_>>()?,
            ),
            Format::Zarr => Sink::Zarr(zarr::Store::open(t.dir, t.scene, &list, t.chunks)?),
        })
    }

    /// The bytes chunk `k` holds in every array of `list` (read back).
    fn read(&self, t: &Target, k: usize, list: &[Array]) -> Result<Vec<Vec<u8>>> {
        match self {
            Sink::Npy(slabs) => {
                let rows = t.chunks.range(k);
                slabs
                    .iter()
                    .map(|(path, slab)| slab.read_rows(rows.start as u64, rows.len() as u64, path))
                    .collect()
            }
            Sink::Zarr(store) => store.read_chunk(t.chunks, k, list),
        }
    }

    /// Writes chunk `k` (`list` holds its rows) and makes it durable.
    fn write(&self, t: &Target, k: usize, list: &[Array]) -> Result<()> {
        match self {
            Sink::Npy(slabs) => {
                let first = t.chunks.range(k).start as u64;
                for ((path, slab), array) in slabs.iter().zip(list) {
                    slab.write_rows(first, &array.bytes, path)?;
                }
                slabs.iter().try_for_each(|(path, slab)| slab.sync(path))
            }
            Sink::Zarr(store) => store.write_chunk(t.chunks, k, list),
        }
    }
}

/// Integrates the chunks `mine` that have not finished, each into its slabs
/// and then marked finished; a progress bar counts the finished ones too.
pub fn integrate<R: Flows>(t: &Target, mine: Range<usize>, progress: bool) -> Result<()> {
    let sink = Sink::open::<R>(t)?;
    let total: u64 = mine.clone().map(|k| traj_steps(t, k)).sum();
    let list = array_list::<R>(t.scene, t.subs)?;
    let mut todo = vec![];
    for k in mine.clone() {
        if !trusted(t, &sink, &list, k)? {
            todo.push(k);
        }
    }
    if todo.len() < mine.len() {
        eprintln!(
            "resuming: {} of the {} chunks {}..{} already finished in {}",
            mine.len() - todo.len(),
            mine.len(),
            mine.start,
            mine.end,
            t.dir.display()
        );
    }
    // The bar counts the chunks already finished as done.
    let left: u64 = todo.iter().map(|k| traj_steps(t, *k)).sum();
    let own = Watch::default();
    let watch = t.watch.unwrap_or(&own);
    watch.total.store(total, Ordering::Relaxed);
    watch.done.store(total - left, Ordering::Relaxed);
    let done = &watch.done;
    let finished = AtomicBool::new(false);
    let followed = Followed {
        label: format!("{} on {}", t.scene.name, engine_name(t)),
        total,
        start: total - left,
        done,
        finished: &finished,
    };
    std::thread::scope(|scope| -> Result<()> {
        if progress && left > 0 {
            scope.spawn(|| progress::follow(&followed));
        }
        // Set on the way out, a panic's too: the scope waits for the bar,
        // which would otherwise wait for ever.
        let _finish = Finish(&finished);
        match t.engines.len() {
            0 | 1 => todo.iter().try_for_each(|k| chunk::<R>(t, *k, &sink, done)),
            _ => share::<R>(t, &todo, &sink, done),
        }
    })
}

/// Tells the progress bar the run is over when dropped.
struct Finish<'a>(&'a AtomicBool);

impl Drop for Finish<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

/// The chunks `todo` shared among the engines: each, on a thread of its
/// own, takes the next chunk left until none is (or one of them failed).
fn share<R: Flows>(t: &Target, todo: &[usize], sink: &Sink, done: &AtomicU64) -> Result<()> {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let workers: Vec<_> = t
            .engines
            .iter()
            .enumerate()
            .map(|(j, e)| {
                let mine = Target {
                    engines: std::slice::from_ref(e),
                    device: Some(j),
                    ..*t
                };
                let (next, failed) = (&next, &failed);
                scope.spawn(move || -> Result<()> {
                    while !failed.load(Ordering::Relaxed) {
                        let Some(k) = todo.get(next.fetch_add(1, Ordering::Relaxed)) else {
                            return Ok(());
                        };
                        chunk::<R>(&mine, *k, sink, done)
                            .inspect_err(|_| failed.store(true, Ordering::Relaxed))?;
                    }
                    Ok(())
                })
            })
            .collect();
        workers
            .into_iter()
            .map(|w| {
                w.join()
                    .unwrap_or_else(|_| Err(anyhow::anyhow!("a GPU worker panicked")))
            })
            .collect::<Result<Vec<()>>>()
            .map(drop)
    })
}

/// The chunks of `range` that are marked finished but whose data is not
/// what their markers say was written: their markers are taken back
/// (`reeb merge` checks every chunk before it trusts one).
pub fn damaged<R: Flows>(t: &Target, range: Range<usize>) -> Result<Vec<usize>> {
    let sink = Sink::open::<R>(t)?;
    let list = array_list::<R>(t.scene, t.subs)?;
    let mut bad = vec![];
    for k in range {
        if journal::done(t.dir, k).is_some() && !trusted(t, &sink, &list, k)? {
            bad.push(k);
        }
    }
    Ok(bad)
}

fn engine<'a>(t: &Target<'a>) -> Result<&'a Engine> {
    t.engines
        .first()
        .context("chunks to integrate and no engine")
}

/// `cpu`, `gpu`, or `gpu ×2` for a run spread over two devices.
fn engine_name(t: &Target) -> String {
    match t.engines {
        [] => "none".into(),
        [e] => e.name().into(),
        [e, ..] => format!("{} ×{}", e.name(), t.engines.len()),
    }
}

/// Whether chunk `k` finished and its data is what its marker says was
/// written; a marker that does not hold is taken back, saying why, and the
/// chunk is integrated again.
fn trusted(t: &Target, sink: &Sink, list: &[Array], k: usize) -> Result<bool> {
    let Some(done) = journal::done(t.dir, k) else {
        return Ok(false);
    };
    let found = sink.read(t, k, list);
    let Some(why) = damage(&done, list, found) else {
        return Ok(true);
    };
    eprintln!(
        "warning: chunk {k} (trajectories {:?}) was marked finished, but {why}; integrating it again",
        t.chunks.range(k)
    );
    journal::unmark(t.dir, k)?;
    Ok(false)
}

/// Why the arrays of a finished chunk (`found`, read back) are not what its
/// marker `done` says was written into `list`, if they are not.
fn damage(done: &Done, list: &[Array], found: Result<Vec<Vec<u8>>>) -> Option<String> {
    if done.arrays.len() != list.len() {
        return Some("its marker does not list what it wrote (an older reeb's?)".into());
    }
    let found = match found {
        Ok(f) => f,
        Err(e) => return Some(format!("its data cannot be read back ({e:#})")),
    };
    done.arrays
        .iter()
        .zip(list)
        .zip(&found)
        .find_map(|((w, a), bytes)| {
            if w.file != a.file {
                return Some(format!("its marker lists {} where {} is", w.file, a.file));
            }
            w.differs(bytes)
        })
}

/// Integrates chunk `k`, writes its rows, makes them durable, marks it
/// with what it wrote.
fn chunk<R: Flows>(t: &Target, k: usize, sink: &Sink, done: &AtomicU64) -> Result<()> {
    let (obs, seconds, timing) = integrate_rows::<R>(t, k, done)?;
    let list = arrays(t.scene, &obs)?;
    sink.write(t, k, &list)?;
    let mark = Done {
        ok: obs.count_ok() as u64,
        traj_steps: traj_steps(t, k),
        seconds,
        timing: timing.into(),
        arrays: list
            .iter()
            .map(|a| Written::of(&a.file, &a.bytes))
            .collect(),
        cpu_isa: t.engines.first().and_then(Engine::cpu_isa),
        device: t
            .engines
            .first()
            .and_then(Engine::adapter)
            .map(|a| match t.device {
                Some(j) => format!("#{j} {a}"),
                None => a,
            }),
    };
    journal::mark_done(t.dir, k, &mark)?;
    journal::remove_state(t.dir, k)
}

/// A sub-run with rows in a chunk, and those rows (of the sub-run's grid).
type Part<'a> = (&'a SubRun, Range<usize>);

/// The parts of chunk `k`: the sub-runs with rows in it, in order.
fn parts<'a>(t: &Target<'a>, k: usize) -> Vec<Part<'a>> {
    let (shape, strides) = (t.scene.shape(), t.scene.strides());
    let rows = t.chunks.range(k);
    t.subs
        .iter()
        .map(|sub| (sub, sub.rows_within(&rows, &shape, &strides)))
        .filter(|(_, own)| !own.is_empty())
        .collect()
}

/// Trajectory-steps of a part.
fn part_steps((sub, own): &Part) -> u64 {
    own.len() as u64 * sub.plan.steps
}

/// The observations of chunk `k`'s rows, from every sub-run that has some
/// of them, continued from the chunk's checkpoint if it has one (and
/// checkpointed every `t.checkpoint_every`); and the seconds the
/// integration took.
fn integrate_rows<R: Flows>(
    t: &Target,
    k: usize,
    progress: &AtomicU64,
) -> Result<(Observations<R>, f64, &'static str)> {
    let rows = t.chunks.range(k);
    let (shape, strides) = (t.scene.shape(), t.scene.strides());
    let parts = parts(t, k);
    // Sub-runs fill one set of arrays shaped by the longest; a scene of one
    // sub-run takes its arrays as they come.
    let mut whole =
        (t.subs.len() > 1).then(|| Observations::<R>::for_plan(&longest(t.subs, rows.len())));
    let mut saved = journal::open_state(t.dir, k)?;
    let mut from = None;
    if let Some(r) = saved.as_mut() {
        from = continued(t, k, &parts, r, whole.as_mut());
        if from.is_none() && whole.is_some() {
            whole = Some(Observations::for_plan(&longest(t.subs, rows.len())));
        }
    }
    let (first, mut seconds, mut header) = match from {
        Some((i, s, h)) => (i, s, Some(h)),
        None => (0, 0.0, None),
    };
    let (mut since, mut timing, mut single) = (Instant::now(), "wall clock", None);
    for (i, part) in parts.iter().enumerate() {
        if i < first {
            progress.fetch_add(part_steps(part), Ordering::Relaxed);
            continue;
        }
        let (sub, own) = part;
        let resume = header
            .take()
            .zip(saved.as_mut().map(|r| r as &mut dyn Read));
        let done = (whole.as_ref(), seconds);
        let run = integrate_part(t, k, (i, sub, own), done, &mut since, resume, progress)?;
        seconds += run.seconds;
        timing = run.timing;
        match whole.as_mut() {
            Some(w) => {
                let at = own
                    .clone()
                    .map(|j| sub.scene_row(j, &shape, &strides) - rows.start);
                w.place_rows(&run.observations, at);
            }
            None => single = Some(run.observations),
        }
    }
    Ok((
        whole.or(single).context("a chunk has rows")?,
        seconds,
        timing,
    ))
}

/// Integrates sub-run `i` of chunk `k` (its rows `own`), continued from
/// `resume` if given, with checkpoints that also hold what is `done`: the
/// sub-runs before it (their rows in the chunk's arrays, their seconds).
/// `since` is when the last checkpoint was taken, and moves on.
fn integrate_part<R: Flows>(
    t: &Target,
    k: usize,
    (i, sub, own): (usize, &SubRun, &Range<usize>),
    done: (Option<&Observations<R>>, f64),
    since: &mut Instant,
    resume: Option<(Header, &mut dyn Read)>,
    progress: &AtomicU64,
) -> Result<Integration<R>> {
    // A checkpoint that cannot be written (a full disk) is skipped: the
    // run goes on, and the one before stays. Said once per chunk.
    let mut warned = false;
    let mut save = |contents: Contents| {
        let saved = journal::save_state(t.dir, k, &|w| {
            put(w, &[i as u64])?;
            put(w, &[done.1])?;
            if let Some(o) = done.0 {
                write_observations(w, o)?;
            }
            contents(w)
        });
        match saved {
            Err(e) if !warned => {
                warned = true;
                eprintln!(
                    "warning: chunk {k}'s checkpoint was not written ({e}); the run goes on, and a kill now would lose the work since the last one (later checkpoints of this chunk that fail are not reported)"
                );
            }
            _ => {}
        }
        Ok(())
    };
    let mut cp = Checkpoints {
        every: t.checkpoint_every,
        since: *since,
        // (A shorter-lived reader: coercions do not reach inside the Option.)
        resume: resume.map(|(h, r)| (h, r as &mut dyn Read)),
        save: &mut save,
        taken: 0,
        stop: t.watch.map(|w| &*w.stop),
    };
    let plan = sub.plan.rows(own.clone());
    let run = engine(t)?.run_resumable::<R>(&plan, Some(progress), Some(&mut cp))?;
    *since = cp.since;
    Ok(run)
}

/// Reads chunk `k`'s checkpoint up to its engine's body: `(sub-run, seconds
/// before it, the engine snapshot's header)`, the finished sub-runs'
/// observations into `whole`. `None` (and a note) when it does not continue
/// this run: the chunk then starts over.
fn continued<R: Flows>(
    t: &Target,
    k: usize,
    parts: &[Part],
    r: &mut dyn Read,
    whole: Option<&mut Observations<R>>,
) -> Option<(usize, f64, Header)> {
    let read = || -> Result<(usize, f64, Header)> {
        let i = get_one::<u64>(r)? as usize;
        let seconds: f64 = get_one(r)?;
        if let Some(w) = whole {
            read_observations(r, w)?;
        }
        let (sub, own) = parts
            .get(i)
            .with_context(|| format!("a sub-run {i} of {}", parts.len()))?;
        let h = Header::read(r)?;
        let expected = engine(t)?.snapshot_header::<R>(&sub.plan.rows(own.clone()))?;
        h.continues(&expected).map_err(anyhow::Error::msg)?;
        Ok((i, seconds, h))
    };
    match read() {
        Ok((i, seconds, h)) => {
            let before: u64 = parts[..i].iter().map(part_steps).sum();
            let share = (before + h.traj_steps) as f64 / traj_steps(t, k).max(1) as f64;
            eprintln!(
                "chunk {k}: continuing from its checkpoint ({:.0} % of its trajectory-steps done)",
                100.0 * share
            );
            Some((i, seconds, h))
        }
        Err(e) => {
            eprintln!(
                "note: chunk {k}'s checkpoint is not continued ({e:#}); the chunk starts over"
            );
            None
        }
    }
}

/// Trajectory-steps of chunk `k`.
fn traj_steps(t: &Target, k: usize) -> u64 {
    parts(t, k).iter().map(part_steps).sum()
}

/// The longest sub-run's plan for `n` trajectories: it shapes the arrays.
fn longest(subs: &[SubRun], n: usize) -> Plan {
    let mut p = subs
        .iter()
        .max_by_key(|s| s.plan.steps)
        .map(|s| s.plan.clone())
        .expect("a scene has a sub-run");
    p.first = 0;
    p.n = n;
    p
}

/// The per-trajectory arrays of the scene's run (bytes empty).
pub fn array_list<R: Flows>(scene: &Scene, subs: &[SubRun]) -> Result<Vec<Array<'static>>> {
    let empty = Observations::<R>::for_plan(&longest(subs, 1));
    Ok(arrays(scene, &empty)?
        .into_iter()
        .map(|a| Array {
            bytes: Vec::new().into(),
            ..a
        })
        .collect())
}

/// What every chunk's marker says; refuses while any has not finished.
pub fn finished(dir: &Path, chunks: &Chunks) -> Result<Vec<Done>> {
    let all: Vec<Option<Done>> = (0..chunks.count()).map(|k| journal::done(dir, k)).collect();
    let missing: Vec<usize> = (0..all.len()).filter(|k| all[*k].is_none()).collect();
    if let Some(first) = missing.first() {
        bail!(
            "{}: {} of {} chunks have not finished (the first: chunk {first}, trajectories {:?}); run the shards that hold them again with --resume",
            dir.display(),
            missing.len(),
            all.len(),
            chunks.range(*first)
        );
    }
    Ok(all.into_iter().flatten().collect())
}

/// The run's arrays read back from `dir`, for the pictures: every
/// per-trajectory value, and the frames and section points if they take at
/// most [`PICTURE_BUDGET`] bytes.
pub fn read_back<R: Flows>(
    scene: &Scene,
    subs: &[SubRun],
    dir: &Path,
    format: Format,
) -> Result<Observations<R>> {
    let mut plan = longest(subs, scene.ensemble_size());
    let lengths = Observations::<R>::lengths(&plan).map_err(anyhow::Error::msg)?;
    let values = lengths.trajectory * plan.trajectory_vars.len()
        + lengths.poincare * plan.poincare_vars.len();
    let big = values as u64 * std::mem::size_of::<R>() as u64;
    if big > PICTURE_BUDGET {
        eprintln!(
            "note: the frames and section points ({}) are larger than the pictures read back ({}): trajectory and Poincaré pictures are not drawn; the arrays are complete",
            bytes(big),
            bytes(PICTURE_BUDGET)
        );
        plan.observers.trajectory = None;
        plan.trajectory_vars.clear();
        plan.observers.poincare = None;
        plan.poincare_vars.clear();
    }
    let mut obs = Observations::<R>::for_plan(&plan);
    load(scene, &Source { dir, format }, &mut obs)?;
    Ok(obs)
}

/// The finished arrays of a run.
struct Source<'a> {
    dir: &'a Path,
    format: Format,
}

impl Source<'_> {
    /// The data of array `file` (`n` rows of `row_bytes`) as values.
    fn values<T: bytemuck::Pod>(&self, file: &str, n: u64, row_bytes: u64) -> Result<Vec<T>> {
        let raw = match self.format {
            Format::Npy => read_rows(&self.dir.join(file), 0, n, row_bytes)?,
            Format::Zarr => zarr::read(self.dir, file.trim_end_matches(".npy"))?,
        };
        Ok(bytemuck::pod_collect_to_vec(&raw))
    }

    /// Fills `dst` (`n` rows) from array `file`.
    fn fill<T: bytemuck::Pod>(&self, file: &str, n: u64, dst: &mut [T]) -> Result<()> {
        let row_bytes = (dst.len() as u64 / n.max(1)) * std::mem::size_of::<T>() as u64;
        let values: Vec<T> = self.values(file, n, row_bytes)?;
        if values.len() != dst.len() {
            bail!(
                "{}: {file} holds {} values where {} were expected",
                self.dir.display(),
                values.len(),
                dst.len()
            );
        }
        dst.copy_from_slice(&values);
        Ok(())
    }

    /// Spreads the interleaved components of `file` into the arrays `dst`
    /// of their names.
    fn components<R: Real>(
        &self,
        file: &str,
        n: u64,
        names: &[String],
        dst: &mut [(String, Vec<R>)],
    ) -> Result<()> {
        let Some(len) = dst.first().map(|(_, d)| d.len() as u64) else {
            return Ok(());
        };
        let per_row = len / n.max(1) * names.len() as u64 * std::mem::size_of::<R>() as u64;
        let all: Vec<R> = self.values(file, n, per_row)?;
        for (c, name) in names.iter().enumerate() {
            let (_, d) = dst
                .iter_mut()
                .find(|(v, _)| v == name)
                .with_context(|| format!("{file}: component {name}"))?;
            for (i, x) in d.iter_mut().enumerate() {
                *x = all[i * names.len() + c];
            }
        }
        Ok(())
    }
}

/// Fills `obs` from the finished arrays (the inverse of [`arrays`]): every
/// column it has room for.
fn load<R: Real>(scene: &Scene, src: &Source, obs: &mut Observations<R>) -> Result<()> {
    let n = obs.n as u64;
    for (file, column) in obs.files_mut() {
        match column {
            ColumnMut::Named(dst) => {
                for v in out_vars(scene, file.field) {
                    src.components(&file.npy(Some(&v.name)), n, &v.components, dst)?;
                }
            }
            ColumnMut::Plain(dst) if !dst.is_empty() => {
                let name = file.npy(None);
                match dst {
                    ColMut::Real(d) => src.fill(&name, n, d)?,
                    ColMut::Count(d) => src.fill(&name, n, d)?,
                }
            }
            ColumnMut::Plain(_) => {}
        }
    }
    let steps: Vec<i64> = src.values("status_step.npy", n, 8)?;
    let status: Vec<u8> = src.values("status.npy", n, 1)?;
    for (i, (s, step)) in status.iter().zip(&steps).enumerate() {
        let step = (*step).max(0) as u32;
        (obs.nonfinite_step[i], obs.stop_step[i]) = match s {
            2 => (0, step),
            _ => (step, 0),
        };
    }
    Ok(())
}
