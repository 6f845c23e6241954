//! A run streamed to disk: its chunks (`chunks.rs`) integrated one after
//! the other, each written into its slab of every array (`npy.rs`) and
//! marked finished (`journal.rs`), so that memory holds one chunk whatever
//! the size of the run (two per GPU, which integrates the next while the
//! last is read back and written); and the finished arrays read back for
//! the pictures.

use std::io::Read;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};

use crate::backend::checkpoint::{Checkpoints, Contents};
use crate::backend::phases::Phases;
use crate::backend::{Engine, Integration};
use crate::models::Flows;
use crate::num::precision::Real;
use crate::output::arrays::{arrays, out_vars, Array};
use crate::output::chunks::Chunks;
use crate::output::journal::{self, Done, Written};
use crate::output::npy::{read_rows, read_rows_into, Slabs};
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
                // Not synced here: a chunk's marker holds the CRC-32 of what
                // it wrote, which a resumed run checks, and the finished run
                // is synced before it is put in place.
                for ((path, slab), array) in slabs.iter().zip(list) {
                    slab.write_rows(first, &array.bytes, path)?;
                }
                Ok(())
            }
            Sink::Zarr(store) => store.write_chunk(t.chunks, k, list),
        }
    }
}

/// Integrates the chunks `mine` that have not finished, each into its slabs
/// and then marked finished; a progress bar counts the finished ones too.
/// A run of one chunk, integrated here, hands back its observations: the
/// pictures take them as they are instead of reading the arrays back.
pub fn integrate<R: Flows>(t: &Target, mine: Range<usize>, progress: bool) -> Result<Streamed<R>> {
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
    // One GPU integrates a chunk while it reads the last back: two
    // workers take turns at it (several GPUs, two each).
    let gpu = matches!(t.engines, [Engine::Gpu(_)]);
    std::thread::scope(|scope| -> Result<Streamed<R>> {
        let bar = (progress && left > 0).then(|| scope.spawn(|| progress::follow(&followed)));
        // Set on the way out, a panic's too: the scope waits for the bar,
        // which would otherwise wait for ever (and is woken, not left to
        // notice at its next tick).
        let _finish = Finish(&finished, bar.as_ref().map(|b| b.thread().clone()));
        let (kept, overlap) = match (t.engines.len(), &todo[..]) {
            (1, [0]) if t.chunks.count() == 1 => (Some(chunk::<R>(t, 0, &sink, done)?), 0.0),
            (1, [_, _, ..]) if gpu => (None, share::<R>(t, &todo, &sink, done)?),
            (0 | 1, _) => {
                let each = |k: &usize| chunk::<R>(t, *k, &sink, done).map(drop);
                todo.iter().try_for_each(each)?;
                (None, 0.0)
            }
            _ => (None, share::<R>(t, &todo, &sink, done)?),
        };
        Ok(Streamed { kept, overlap })
    })
}

/// What [`integrate`] leaves: the observations of a run of one chunk
/// integrated here, and the seconds during which one chunk was read back
/// or written while a GPU integrated another.
pub struct Streamed<R> {
    pub kept: Option<Observations<R>>,
    pub overlap: f64,
}

/// A chunk integrated and not yet written: its observations, their
/// phases, the integration's clock, and when it had a GPU's queue.
struct Rows<R> {
    obs: Observations<R>,
    phases: Phases,
    timing: &'static str,
    busy: Vec<Span>,
}

/// From when to when something ran.
type Span = (Instant, Instant);

/// Seconds during which a span of `a` and a span of `b` both ran (the
/// spans of each list do not overlap one another).
fn overlap(a: &[Span], b: &[Span]) -> f64 {
    a.iter()
        .flat_map(|x| b.iter().map(move |y| (x.0.max(y.0), x.1.min(y.1))))
        .filter(|(from, to)| to > from)
        .map(|(from, to)| (to - from).as_secs_f64())
        .sum()
}

/// Tells the progress bar the run is over when dropped.
struct Finish<'a>(&'a AtomicBool, Option<std::thread::Thread>);

impl Drop for Finish<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
        if let Some(bar) = &self.1 {
            bar.unpark();
        }
    }
}

/// The chunks `todo` shared among workers, each on a thread of its own
/// taking the next chunk left until none is (or one of them failed): two
/// per GPU, which take turns at its queue, so that while one integrates
/// chunk k+1 the other reads chunk k back and writes it (at most two
/// chunks' outputs in memory per GPU). Returns the seconds during which
/// one chunk's host work ran while a GPU integrated another.
fn share<R: Flows>(t: &Target, todo: &[usize], sink: &Sink, done: &AtomicU64) -> Result<f64> {
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let timelines = Mutex::new(vec![]);
    let many = t.engines.len() > 1;
    let workers = t.engines.iter().enumerate().flat_map(|(j, e)| {
        let mine = Target {
            engines: std::slice::from_ref(e),
            device: if many { Some(j) } else { t.device },
            ..*t
        };
        let each = if matches!(e, Engine::Gpu(_)) { 2 } else { 1 };
        std::iter::repeat_n(mine, each)
    });
    std::thread::scope(|scope| {
        let (next, failed, timelines) = (&next, &failed, &timelines);
        let running: Vec<_> = workers
            .map(|mine| {
                scope.spawn(move || -> Result<()> {
                    while !failed.load(Ordering::Relaxed) {
                        let Some(k) = todo.get(next.fetch_add(1, Ordering::Relaxed)) else {
                            return Ok(());
                        };
                        let timeline = timed_chunk::<R>(&mine, *k, sink, done)
                            .inspect_err(|_| failed.store(true, Ordering::Relaxed))?;
                        let mut all = timelines.lock().unwrap_or_else(PoisonError::into_inner);
                        all.push(timeline);
                    }
                    Ok(())
                })
            })
            .collect();
        running
            .into_iter()
            .map(|w| {
                w.join()
                    .unwrap_or_else(|_| Err(anyhow::anyhow!("a GPU worker panicked")))
            })
            .collect::<Result<Vec<()>>>()
    })?;
    let timelines = timelines
        .into_inner()
        .unwrap_or_else(PoisonError::into_inner);
    Ok(host_under_gpu(&timelines))
}

/// When a chunk had a GPU's queue, and when its host work (read-back,
/// conversion, writing) ran.
type Timeline = (Vec<Span>, Span);

/// [`chunk`], and when it ran what.
fn timed_chunk<R: Flows>(t: &Target, k: usize, sink: &Sink, done: &AtomicU64) -> Result<Timeline> {
    let mut rows = integrate_rows::<R>(t, k, done)?;
    let busy = std::mem::take(&mut rows.busy);
    let host = busy.last().map_or_else(Instant::now, |b| b.1);
    write_chunk(t, k, sink, rows)?;
    Ok((busy, (host, Instant::now())))
}

/// Seconds during which one chunk's host work ran while another chunk had
/// a GPU's queue.
fn host_under_gpu(timelines: &[Timeline]) -> f64 {
    let mut seconds = 0.0;
    for (a, (_, host)) in timelines.iter().enumerate() {
        for (b, (busy, _)) in timelines.iter().enumerate() {
            if a != b {
                seconds += overlap(std::slice::from_ref(host), busy);
            }
        }
    }
    seconds
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

/// Integrates chunk `k` and writes it ([`write_chunk`]).
fn chunk<R: Flows>(t: &Target, k: usize, sink: &Sink, done: &AtomicU64) -> Result<Observations<R>> {
    write_chunk(t, k, sink, integrate_rows::<R>(t, k, done)?)
}

/// Writes chunk `k`'s rows, marks it with what it wrote; returns its
/// observations.
fn write_chunk<R: Flows>(
    t: &Target,
    k: usize,
    sink: &Sink,
    rows: Rows<R>,
) -> Result<Observations<R>> {
    let Rows {
        obs,
        mut phases,
        timing,
        ..
    } = rows;
    let writing = Instant::now();
    let list = arrays(t.scene, &obs)?;
    sink.write(t, k, &list)?;
    let written = {
        use rayon::prelude::*;
        list.par_iter()
            .map(|a| Written::of(&a.file, &a.bytes))
            .collect()
    };
    drop(list);
    phases.writing = writing.elapsed().as_secs_f64();
    let mark = Done {
        ok: obs.count_ok() as u64,
        traj_steps: traj_steps(t, k),
        seconds: phases.integration,
        phases,
        timing: timing.into(),
        arrays: written,
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
    journal::remove_state(t.dir, k)?;
    Ok(obs)
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
/// checkpointed every `t.checkpoint_every`); and the seconds its phases
/// took (the integration's from the chunk's start, the others this time).
fn integrate_rows<R: Flows>(t: &Target, k: usize, progress: &AtomicU64) -> Result<Rows<R>> {
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
    let (first, seconds, mut header) = match from {
        Some((i, s, h)) => (i, s, Some(h)),
        None => (0, 0.0, None),
    };
    let mut phases = Phases {
        integration: seconds,
        ..Phases::default()
    };
    let (mut since, mut timing, mut single) = (Instant::now(), "wall clock", None);
    let mut busy = vec![];
    for (i, part) in parts.iter().enumerate() {
        if i < first {
            progress.fetch_add(part_steps(part), Ordering::Relaxed);
            continue;
        }
        let (sub, own) = part;
        let resume = header
            .take()
            .zip(saved.as_mut().map(|r| r as &mut dyn Read));
        let done = (whole.as_ref(), phases.integration);
        let run = integrate_part(t, k, (i, sub, own), done, &mut since, resume, progress)?;
        phases = phases.plus(run.phases);
        timing = run.timing;
        busy.extend(run.busy);
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
    Ok(Rows {
        obs: whole.or(single).context("a chunk has rows")?,
        phases,
        timing,
        busy,
    })
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

/// The observations the pictures are drawn from: `kept`, those of a run of
/// one chunk as it was integrated, where the arrays would read back the
/// same; else the arrays read back ([`read_back`]).
pub fn for_pictures<R: Flows>(
    scene: &Scene,
    subs: &[SubRun],
    dir: &Path,
    format: Format,
    kept: Option<Observations<R>>,
) -> Result<Observations<R>> {
    let plan = longest(subs, scene.ensemble_size());
    match kept {
        Some(mut obs) if picture_bytes::<R>(&plan)? <= PICTURE_BUDGET => {
            // The status as the arrays hold it: a trajectory that became
            // non-finite is not also stopped.
            for (nonfinite, stop) in obs.nonfinite_step.iter().zip(&mut obs.stop_step) {
                if *nonfinite != 0 {
                    *stop = 0;
                }
            }
            Ok(obs)
        }
        _ => read_back(scene, subs, dir, format),
    }
}

/// The bytes of `plan`'s frames and section points.
fn picture_bytes<R: Real>(plan: &Plan) -> Result<u64> {
    let lengths = Observations::<R>::lengths(plan).map_err(anyhow::Error::msg)?;
    let values = lengths.trajectory * plan.trajectory_vars.len()
        + lengths.poincare * plan.poincare_vars.len();
    Ok(values as u64 * std::mem::size_of::<R>() as u64)
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
    let big = picture_bytes::<R>(&plan)?;
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

    /// Fills `dst` (`n` rows) from array `file`: a `.npy` file read
    /// straight into it.
    fn fill<T: bytemuck::Pod>(&self, file: &str, n: u64, dst: &mut [T]) -> Result<()> {
        let bytes: &mut [u8] = bytemuck::cast_slice_mut(dst);
        let found = match self.format {
            Format::Npy => return read_rows_into(&self.dir.join(file), 0, bytes),
            Format::Zarr => zarr::read(self.dir, file.trim_end_matches(".npy"))?,
        };
        if found.len() != bytes.len() {
            bail!(
                "{}: {file} holds {} bytes where {} were expected ({n} rows)",
                self.dir.display(),
                found.len(),
                bytes.len()
            );
        }
        bytes.copy_from_slice(&found);
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
    use rayon::prelude::*;
    let n = obs.n as u64;
    // Each column from its own files, the columns at once.
    obs.files_mut()
        .into_par_iter()
        .try_for_each(|(file, column)| -> Result<()> {
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
                        ColMut::Int(d) => src.fill(&name, n, d)?,
                    }
                }
                ColumnMut::Plain(_) => {}
            }
            Ok(())
        })?;
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
