//! The CPU backend: rayon over blocks of [`LANES`] trajectories in
//! structure-of-arrays form; a step is the plan's fused S2 stages
//! ([`kernels`]) or its ops, each one loop over the lanes, which the compiler
//! vectorises. Every block is independent, so results are bitwise identical
//! for any number of threads.

// Lane loops index several arrays by lane; iterators would hide that.
#![allow(clippy::needless_range_loop)]

pub mod formula;
pub mod indicators;
pub mod kernels;
pub mod observe;
pub mod program;
#[cfg(test)]
mod sample_gen;
// Generated (`sample_gen.rs`), checked against its generator by a test.
#[rustfmt::skip]
mod sample_ops;
pub mod samples;
pub mod stops;
pub mod tangent;

use std::io::{self, Read, Write};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use super::checkpoint::Checkpoints;
use super::error::BackendError;
use super::phases::{lap, Phases};

use crate::models::lanes::{LaneArrays, Lanes, LANES};
use crate::models::Flows;
use crate::num::precision::{handed_back, is_f32};
use crate::plan::observations::{Observations, Sink};
use crate::plan::snapshot::{get, get_array, get_one, get_vec, invalid, put, put_slice, Header};
use crate::plan::{slots, Plan};
use formula::Condition;
use formula::StepMemory;
pub use kernels::{isa, Isa};
use kernels::{Record, Recorded, RECORDED};
use observe::{BlockObservers, BlockStep, Slopes};
use program::{CpuOp, Program};
use stops::RunStops;

/// Integrates `plan` on the CPU in precision `R`. `progress`, if given, is
/// advanced by trajectory-steps as blocks go.
pub fn run<R: Flows>(plan: &Plan, progress: Option<&AtomicU64>) -> Observations<R> {
    run_isa(plan, progress, isa())
}

/// [`run`] with the fused kernels of a given instruction-set level (which
/// must not exceed the CPU's, see [`isa`]).
pub fn run_isa<R: Flows>(plan: &Plan, progress: Option<&AtomicU64>, isa: Isa) -> Observations<R> {
    uninterrupted(integrate(plan, progress, isa, USUAL, None))
}

/// The threads the CPU backend integrates on (rayon's pool: every core,
/// or `RAYON_NUM_THREADS`).
pub fn threads() -> usize {
    rayon::current_num_threads()
}

/// What a snapshot of a CPU run names its engine: the kernels' level
/// decides the bits.
pub fn fingerprint(isa: Isa) -> String {
    format!("cpu {isa:?}")
}

/// [`run_isa`] with checkpoints: continues from `cp`'s snapshot if it has
/// one, and pauses every block between two steps when a snapshot is due.
/// Also returns the integration's seconds (those before the snapshot it
/// continues included).
pub fn resumable<R: Flows>(
    plan: &Plan,
    progress: Option<&AtomicU64>,
    isa: Isa,
    cp: Option<&mut Checkpoints>,
) -> Result<(Observations<R>, Phases), BackendError> {
    integrate(plan, progress, isa, USUAL, cp)
}

/// [`run_isa`] evaluating the time terms on every trajectory even where the
/// ensemble shares them (`Plan::shares_time`): the reference the shared
/// evaluation is tested and timed against.
pub fn run_time_per_trajectory<R: Flows>(plan: &Plan, isa: Isa) -> Observations<R> {
    let how = How {
        share_time: false,
        record: true,
    };
    uninterrupted(integrate(plan, None, isa, how, None))
}

/// [`run_isa`] with one step per call of the fused kernels wherever an
/// observer looks at every step, instead of recorded runs
/// ([`Walk::recorded_runs`]): the reference those are tested against.
pub fn run_step_by_step<R: Flows>(plan: &Plan, isa: Isa) -> Observations<R> {
    let how = How {
        share_time: true,
        record: false,
    };
    uninterrupted(integrate(plan, None, isa, how, None))
}

/// How a run goes where it may choose: `share_time`, the time terms once
/// per block where the ensemble shares them; `record`, recorded runs where
/// observers look at every step.
#[derive(Clone, Copy)]
struct How {
    share_time: bool,
    record: bool,
}

/// The usual [`How`]: both.
const USUAL: How = How {
    share_time: true,
    record: true,
};

/// The observations of a run without checkpoints, which cannot fail.
fn uninterrupted<R>(run: Integrated<R>) -> Observations<R> {
    match run {
        Ok((out, _)) => out,
        Err(e) => unreachable!("a run without checkpoints failed: {e}"),
    }
}

/// The run of every entry above, through [`integrate_f32`] or
/// [`integrate_f64`] (see [`crate::num::precision::in_precision`]).
fn integrate<R: Flows>(
    plan: &Plan,
    progress: Option<&AtomicU64>,
    isa: Isa,
    how: How,
    cp: Option<&mut Checkpoints>,
) -> Integrated<R> {
    if is_f32::<R>() {
        handed_back(integrate_f32(plan, progress, isa, how, cp))
    } else {
        handed_back(integrate_f64(plan, progress, isa, how, cp))
    }
}

/// A run's observations and its phases (set-up and integration).
type Integrated<R> = Result<(Observations<R>, Phases), BackendError>;

/// [`integrate_in`] in f32, compiled in this crate only.
#[inline(never)]
fn integrate_f32(
    plan: &Plan,
    progress: Option<&AtomicU64>,
    isa: Isa,
    how: How,
    cp: Option<&mut Checkpoints>,
) -> Integrated<f32> {
    integrate_in(plan, progress, isa, how, cp)
}

/// [`integrate_in`] in f64, compiled in this crate only.
#[inline(never)]
fn integrate_f64(
    plan: &Plan,
    progress: Option<&AtomicU64>,
    isa: Isa,
    how: How,
    cp: Option<&mut Checkpoints>,
) -> Integrated<f64> {
    integrate_in(plan, progress, isa, how, cp)
}

fn integrate_in<R: Flows>(
    plan: &Plan,
    progress: Option<&AtomicU64>,
    isa: Isa,
    how: How,
    mut cp: Option<&mut Checkpoints>,
) -> Integrated<R> {
    assert!(
        isa_rank(isa) <= isa_rank(self::isa()),
        "the CPU lacks {isa:?}"
    );
    let mut since = Instant::now();
    let mut out = Observations::<R>::for_plan(plan);
    let mut program = Program::<R>::new(plan, isa, how.share_time);
    program.record &= how.record;
    let mut blocks: Vec<Block<R>> = (0..plan.n.div_ceil(LANES))
        .map(|_| Block::Unstarted)
        .collect();
    let mut header = Header::of::<R>(plan, fingerprint(isa));
    if let Some(c) = cp.as_deref_mut() {
        if let Some((h, r)) = c.restore(&mut out).map_err(BackendError::checkpoint)? {
            read_blocks(&program, r, &mut blocks).map_err(BackendError::checkpoint)?;
            header.seconds = h.seconds;
            if let Some(pr) = progress {
                pr.fetch_add(h.traj_steps, Ordering::Relaxed);
            }
        }
    }
    let setup = lap(&mut since);
    loop {
        let c = cp.as_deref();
        let pause = Pause::new(c.and_then(|c| c.deadline()), c.and_then(|c| c.stop));
        let started = Instant::now();
        let sink = out.sink();
        blocks
            .par_iter_mut()
            .enumerate()
            .for_each_init(Lanes::<R>::boxed, |lanes, (b, slot)| {
                run_block(&program, b, slot, lanes, &sink, progress, &pause);
            });
        drop(sink);
        header.seconds += started.elapsed().as_secs_f64();
        if blocks.iter().all(|b| matches!(b, Block::Done)) {
            let phases = Phases {
                setup,
                integration: header.seconds,
                ..Phases::default()
            };
            return Ok((out, phases));
        }
        let c = cp
            .as_deref_mut()
            .expect("blocks pause only for a checkpoint");
        // Stopped (Ctrl-C, SIGTERM): the work so far is kept too, unless
        // the run takes no checkpoints.
        let stopped = c.stopped();
        if !stopped || c.every.is_some() {
            header.traj_steps = traj_steps_done(plan, &blocks);
            c.take(&header, &out, &|w| write_blocks(w, &blocks))
                .map_err(BackendError::checkpoint)?;
        }
        if stopped {
            return Err(BackendError::Stopped);
        }
    }
}

fn isa_rank(i: Isa) -> u8 {
    match i {
        Isa::Baseline => 0,
        Isa::V3 => 1,
        Isa::V4 => 2,
    }
}

/// Where a block of trajectories stands.
enum Block<R> {
    Unstarted,
    /// Paused between two steps for a checkpoint.
    Suspended(Box<BlockState<R>>),
    Done,
}

/// A block paused before step `n`: what continuing it needs. The formula
/// interpreter's memory is not kept: its fixed values follow from the
/// lanes, and a block pauses only at a multiple of [`LANES`] steps, where
/// the window of its shared values starts anyway.
struct BlockState<R> {
    n: u64,
    lanes: Box<Lanes<R>>,
    status: [u64; LANES],
    obs: BlockObservers<R>,
}

/// Asks the blocks to pause for a checkpoint once its deadline passes, or
/// for good when `stop` is set.
struct Pause<'s> {
    deadline: Option<Instant>,
    stop: Option<&'s AtomicBool>,
    requested: AtomicBool,
    /// Some block finished or paused since the run (re)started: only then
    /// may a block that has not started wait, so every round gets on.
    progressed: AtomicBool,
}

impl Pause<'_> {
    fn new(deadline: Option<Instant>, stop: Option<&AtomicBool>) -> Pause<'_> {
        Pause {
            deadline,
            stop,
            requested: AtomicBool::new(false),
            progressed: AtomicBool::new(false),
        }
    }

    /// Whether a running block pauses now; `clock`: also read the clock
    /// (not at every check: reading it costs more than a step of a block).
    fn due(&self, clock: bool) -> bool {
        if self.requested.load(Ordering::Relaxed) {
            return true;
        }
        if self.stop_asked() {
            self.requested.store(true, Ordering::Relaxed);
            return true;
        }
        let late = clock && self.deadline.is_some_and(|d| Instant::now() >= d);
        if late {
            self.requested.store(true, Ordering::Relaxed);
        }
        late
    }

    /// Whether a block that has not started waits for the checkpoint.
    fn holds_back(&self) -> bool {
        self.stop_asked() || self.progressed.load(Ordering::Relaxed) && self.due(true)
    }

    fn stop_asked(&self) -> bool {
        self.stop.is_some_and(|s| s.load(Ordering::Relaxed))
    }

    fn progressed(&self) {
        self.progressed.store(true, Ordering::Relaxed);
    }
}

/// Trajectory-steps of the blocks done or paused (as the progress counts them).
fn traj_steps_done<R>(plan: &Plan, blocks: &[Block<R>]) -> u64 {
    let count = |b: usize| LANES.min(plan.n - b * LANES) as u64;
    blocks
        .iter()
        .enumerate()
        .map(|(b, s)| match s {
            Block::Unstarted => 0,
            Block::Suspended(st) => count(b) * st.n,
            Block::Done => count(b) * plan.steps,
        })
        .sum()
}

/// The blocks of a snapshot: where each stands, then each paused block's state.
fn write_blocks<R: Flows>(w: &mut dyn Write, blocks: &[Block<R>]) -> io::Result<()> {
    let tags: Vec<u8> = blocks
        .iter()
        .map(|b| match b {
            Block::Unstarted => 0,
            Block::Suspended(_) => 1,
            Block::Done => 2,
        })
        .collect();
    put_slice(w, &tags)?;
    for b in blocks {
        if let Block::Suspended(st) = b {
            put(w, &[st.n])?;
            put(w, st.lanes.as_slice())?;
            put(w, &st.status)?;
            st.obs.write(w)?;
        }
    }
    Ok(())
}

/// Reads what [`write_blocks`] wrote.
fn read_blocks<R: Flows>(
    p: &Program<R>,
    r: &mut dyn Read,
    blocks: &mut [Block<R>],
) -> io::Result<()> {
    let tags: Vec<u8> = get_vec(r, blocks.len())?;
    if tags.len() != blocks.len() {
        return Err(invalid("a snapshot of another number of blocks"));
    }
    for (b, tag) in blocks.iter_mut().zip(tags) {
        *b = match tag {
            0 => Block::Unstarted,
            2 => Block::Done,
            1 => {
                let n: u64 = get_one(r)?;
                if n == 0 || n >= p.plan.steps {
                    return Err(invalid(&format!("a block paused at step {n}")));
                }
                let mut lanes = Lanes::<R>::boxed();
                get(r, lanes.as_mut_slice())?;
                let status = get_array(r)?;
                let mut obs = BlockObservers::new(p, &lanes);
                obs.read(r)?;
                Block::Suspended(Box::new(BlockState {
                    n,
                    lanes,
                    status,
                    obs,
                }))
            }
            _ => return Err(invalid("a block of no known kind")),
        };
    }
    Ok(())
}

/// Where block `block` starts or continues: `(step, status, observers)`
/// with its lanes in `l`; `None` if it is done or waits for a checkpoint.
fn enter<R: Flows>(
    p: &Program<R>,
    block: usize,
    slot: &mut Block<R>,
    l: &mut Box<Lanes<R>>,
    pause: &Pause,
) -> Option<(u64, [u64; LANES], BlockObservers<R>)> {
    match std::mem::replace(slot, Block::Done) {
        Block::Done => None,
        Block::Unstarted if pause.holds_back() => {
            *slot = Block::Unstarted;
            None
        }
        Block::Unstarted => {
            let base = block * LANES;
            load_inputs(p, l, base, LANES.min(p.plan.n - base));
            Some((0, [0; LANES], BlockObservers::new(p, l)))
        }
        Block::Suspended(st) => {
            let BlockState {
                n,
                lanes,
                status,
                obs,
            } = *st;
            *l = lanes;
            Some((n, status, obs))
        }
    }
}

/// Integrates block `block` (trajectories `block·LANES …`) from where it
/// stands and stores its rows, or pauses it when `pause` asks.
fn run_block<R: Flows>(
    p: &Program<R>,
    block: usize,
    slot: &mut Block<R>,
    l: &mut Box<Lanes<R>>,
    sink: &Sink<R>,
    progress: Option<&AtomicU64>,
    pause: &Pause,
) {
    let Some((n0, status, obs)) = enter(p, block, slot, l, pause) else {
        return;
    };
    let plan = p.plan;
    let base = block * LANES;
    let count = LANES.min(plan.n - base);
    let mut b = Walk {
        here: Here {
            p,
            sink,
            base,
            count,
            status,
            run: observe::running_flags(&status, count),
            prev: LaneArrays::filled(p.var.len(), R::default()),
            slopes: p.needs_field.then(|| Slopes::new(p)),
        },
        alive: count - status[..count].iter().filter(|s| **s != 0).count(),
        obs,
        regs: LaneArrays::filled(p.registers, R::default()),
        reported: n0,
        progress,
    };
    if n0 == 0 {
        // The initial state: frames and sections (cycles and averages start
        // with the first step).
        let view = b.here.view(l, 0);
        b.obs.observe(&view);
        b.obs.indicator_frame(&view);
    }
    let finished = match p.records() {
        true => b.recorded_runs(l, n0, pause),
        false => b.steps(l, n0, pause),
    };
    match finished {
        Ok(()) => {
            b.report(plan.steps);
            b.obs.finish(p, l, sink, base, count, &b.here.status);
        }
        Err(n) => {
            let lanes = std::mem::replace(l, Lanes::boxed());
            *slot = Block::Suspended(Box::new(BlockState {
                n,
                lanes,
                status: b.here.status,
                obs: b.obs,
            }));
        }
    }
    pause.progressed();
}

/// A block on its way through the run, with its observers.
struct Walk<'a, R> {
    here: Here<'a, R>,
    /// Trajectories of the block still running.
    alive: usize,
    obs: BlockObservers<R>,
    /// Registers of the formula interpreter.
    regs: LaneArrays<R>,
    /// Steps the progress counts for the block.
    reported: u64,
    progress: Option<&'a AtomicU64>,
}

/// What the observers see of a block besides its lanes and their own state.
struct Here<'a, R> {
    p: &'a Program<'a, R>,
    sink: &'a Sink<R>,
    base: usize,
    count: usize,
    status: [u64; LANES],
    /// Which lanes run, as `status` says.
    run: [bool; LANES],
    /// The state at the start of the step the observers look at.
    prev: LaneArrays<R>,
    slopes: Option<Slopes<R>>,
}

impl<R: Flows> Here<'_, R> {
    /// The observers' view of the block after step `n1`, its state in `l`.
    fn view<'s>(&'s self, l: &'s Lanes<R>, n1: u64) -> BlockStep<'s, R> {
        BlockStep {
            p: self.p,
            l,
            sink: self.sink,
            base: self.base,
            count: self.count,
            prev: &self.prev,
            slopes: self.slopes.as_ref(),
            status: &self.status,
            run: &self.run,
            n1,
        }
    }
}

impl<'a, R: Flows> Walk<'a, R> {
    /// Advances the progress to step `n` of the block.
    fn report(&mut self, n: u64) {
        if let Some(pr) = self.progress {
            pr.fetch_add(
                self.here.count as u64 * (n - self.reported),
                Ordering::Relaxed,
            );
            self.reported = n;
        }
    }

    /// Whether the block pauses before step `n` (`n0`: where it entered).
    fn pauses(&mut self, n: u64, n0: u64, pause: &Pause) -> bool {
        let due = n > n0 && n.is_multiple_of(LANES as u64) && pause.due(n.is_multiple_of(1024));
        if due {
            self.report(n);
        }
        due
    }

    /// Copies the state of `l` as the start of the next step.
    #[inline(always)]
    fn keep_start(&mut self, l: &Lanes<R>) {
        let h = &mut self.here;
        for (k, &v) in h.p.var.iter().enumerate() {
            h.prev[k] = *l.at(v);
        }
    }

    /// Marks the lanes that left the finite numbers in step `n` (its
    /// state in `l`), and makes them twins of running lanes.
    fn nonfinite(&mut self, l: &mut Lanes<R>, n: u64) {
        let h = &mut self.here;
        let bad = nonfinite_lanes(h.p, l);
        self.alive -= mark_nonfinite(&bad, &mut h.status, h.count, n);
        h.run = observe::running_flags(&h.status, h.count);
        if h.p.stages.is_some() {
            retire(&bad, l, &h.status, h.count);
        }
    }

    /// Frames, sections, cycle statistics and averages after step `n1`, its
    /// state in `l`.
    #[inline(always)]
    fn observe(&mut self, l: &Lanes<R>, n1: u64) {
        let view = self.here.view(l, n1);
        self.obs.observe(&view);
        self.obs.cycle(&view);
        self.obs.average(&view);
    }

    /// Stops the lanes where the stop condition holds after step `n1`.
    #[inline(always)]
    fn stop(&mut self, l: &mut Lanes<R>, n1: u64) {
        let h = &mut self.here;
        let Some(stop) = &h.p.stop else { return };
        let stopped = stop_lanes(
            h.p,
            stop,
            l,
            self.obs.slots(),
            &mut self.regs,
            &mut h.status,
            n1,
            h.sink,
            h.base,
            h.count,
        );
        self.stopped(stopped);
    }

    /// The block from step `n0` to the end, observed after each call of
    /// the step (one step where an observer looks at every step); `Err(n)`
    /// if it pauses before step `n`.
    fn steps(&mut self, l: &mut Box<Lanes<R>>, n0: u64, pause: &Pause) -> Result<(), u64> {
        let p = self.here.p;
        let plan = p.plan;
        let mut memory = p.formula_step.as_ref().map(|f| {
            let mut m = f.memory();
            f.begin(l, &mut m);
            m
        });
        // The compiled tangent step's lanes, where it runs; whether it takes
        // the steps (else the tape or the compiled tangent reads `prev`).
        let mut tangent = p.indicators.as_ref().and_then(|i| i.scratch(l));
        let tangent_steps = p.indicators.as_ref().is_some_and(|i| i.takes_step());
        let reads_prev = p.indicators.is_some() && !tangent_steps;
        // Whether the indicators take runs of steps: compiled throughout, and
        // no other observer looks at every step.
        let indicator_runs = p.indicators.as_ref().is_some_and(|i| i.takes_runs())
            && !plan.others_observe_every_step();
        let mut n = n0;
        while n < plan.steps {
            if self.pauses(n, n0, pause) {
                return Err(n);
            }
            if p.needs_field || plan.cycle_var.is_some() || reads_prev {
                self.keep_start(l);
            }
            // Whether a run of steps took the samples of its last step.
            let mut sampled = false;
            let count = self.here.count;
            let (done, any) = match (&p.indicators, tangent.as_mut()) {
                // Runs of steps no other observer looks at, in one call.
                (Some(ind), Some(scratch)) if indicator_runs => {
                    let (running, padding) = observe::running_lanes(&self.here.status[..count]);
                    let k = quiet_run(p, &self.obs, n, count, true);
                    let (real, mask) = (self.obs.slots_mut(), running | padding);
                    let out = ind.steps(l, scratch, real, &mut self.regs, n, k, mask, p.isa);
                    sampled = out.sampled;
                    (out.done, !out.sampled)
                }
                // The compiled tangent step moves state and vectors at once.
                (Some(ind), Some(scratch)) if tangent_steps => {
                    let (running, padding) = observe::running_lanes(&self.here.status[..count]);
                    ind.step(l, scratch, self.obs.slots_mut(), n, running | padding);
                    (1, l.any_nonfinite(&p.var))
                }
                _ => {
                    let k = quiet_run(p, &self.obs, n, count, false);
                    advance(p, l, &mut self.regs, memory.as_mut(), n, k)
                }
            };
            if any {
                self.nonfinite(l, n + done - 1);
            }
            n += done;
            self.observe(l, n);
            if !sampled {
                let view = self.here.view(l, n);
                self.obs.indicators(&view, &mut self.regs, tangent.as_mut());
            }
            self.obs.indicator_frame(&self.here.view(l, n));
            self.stop(l, n);
            if n.is_multiple_of(1024) {
                self.report(n);
            }
            if self.alive == 0 {
                break;
            }
        }
        Ok(())
    }

    /// [`Self::steps`] for observers that look at every step of fused
    /// stages without chaos indicators: each call of the kernel takes a run
    /// of steps and records the state after each, and the observers then
    /// look at the recorded steps one by one, on `view`: the block's lanes
    /// with each step's state. A lane stops at the first step at whose end
    /// its condition holds ([`RunStops`]: evaluated on the whole run at
    /// once); the steps its lane took past it are never read. Where the
    /// stop condition is all that looks at every step, a run in which no
    /// lane stops is not looked at step by step: it ends where a frame or
    /// an exact stroboscopic sample is due, and only its end is observed.
    fn recorded_runs(&mut self, l: &mut Box<Lanes<R>>, n0: u64, pause: &Pause) -> Result<(), u64> {
        let p = self.here.p;
        let plan = p.plan;
        let f = p.stages.as_ref().expect("recorded runs of fused stages");
        let mut view = Lanes::<R>::boxed();
        view.as_mut_slice().copy_from_slice(l.as_slice());
        let mut after: Vec<Recorded<R>> = vec![[[R::default(); LANES]; RECORDED]; p.var.len()];
        let mut stops = (p.stop.as_ref()).map(|c| (c, RunStops::new(c, &p.var, l, p.isa)));
        let stop_only = stops.is_some() && !plan.more_than_stop_observes_every_step();
        let mut n = n0;
        while n < plan.steps {
            if self.pauses(n, n0, pause) {
                return Err(n);
            }
            let end = match stop_only {
                true => next_look(p, &self.obs, n, self.here.count).unwrap_or(n + 1),
                false => (n / LANES as u64 + 1) * LANES as u64,
            };
            let k = (RECORDED as u64).min(end.min(plan.steps) - n);
            self.keep_start(l);
            let mut record = Record {
                vars: &p.var,
                after: &mut after,
            };
            // SAFETY: `isa()` chose wide kernels only where the CPU has the features.
            let (done, any) =
                unsafe { (f.kernel)(l, &f.weights, n, k, f.time_terms, Some(&mut record)) };
            let steps = done as usize;
            let h = &self.here;
            let first = (stops.as_mut())
                .map(|(c, s)| s.first(c, l, &after, n, steps, &h.status, h.count, p.isa));
            let quiet =
                stop_only && !any && first.is_some_and(|f| f.iter().all(|&j| j as usize >= steps));
            if quiet {
                for (&v, x) in p.var.iter().zip(&after) {
                    *view.at_mut(v) = x[steps - 1];
                }
                self.observe(&view, n + done);
            } else {
                let run = Run {
                    after: &after,
                    n,
                    steps,
                    any,
                    first: first.as_ref(),
                };
                if self.look_at_run(l, &mut view, &run) {
                    return Ok(());
                }
            }
            n += done;
            if n.is_multiple_of(1024) {
                self.report(n);
            }
        }
        Ok(())
    }

    /// The observers after each step of recorded run `run`; whether every
    /// lane of the block has stopped. Compiled for each instruction-set
    /// level, as the kernels are, so the observers' lane loops are as wide.
    /// Only loops without a product feeding a sum are inlined here: the wide
    /// builds contract a·b + c into an FMA (`.cargo/config.toml`), which
    /// would change the observers' bits (and differ from the GPU's); the
    /// rest (crossings, samples, frames, stops, slopes) is `inline(never)`.
    fn look_at_run(&mut self, l: &mut Lanes<R>, view: &mut Lanes<R>, run: &Run<R>) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            // SAFETY: the program's level is one `isa()` found on this CPU.
            match self.here.p.isa {
                Isa::V4 => unsafe { self.look_v4(l, view, run) },
                Isa::V3 => unsafe { self.look_v3(l, view, run) },
                Isa::Baseline => self.look(l, view, run),
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        self.look(l, view, run)
    }

    /// [`Self::look`] for AVX-512.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx2,fma")]
    unsafe fn look_v4(&mut self, l: &mut Lanes<R>, view: &mut Lanes<R>, run: &Run<R>) -> bool {
        self.look(l, view, run)
    }

    /// [`Self::look`] for AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn look_v3(&mut self, l: &mut Lanes<R>, view: &mut Lanes<R>, run: &Run<R>) -> bool {
        self.look(l, view, run)
    }

    /// [`Self::look_at_run`] at the level it is inlined into.
    #[inline(always)]
    fn look(&mut self, l: &mut Lanes<R>, view: &mut Lanes<R>, run: &Run<R>) -> bool {
        let p = self.here.p;
        for j in 0..run.steps {
            let n1 = run.n + j as u64 + 1;
            if run.any && j + 1 == run.steps {
                self.nonfinite(l, n1 - 1);
            }
            for (&v, x) in p.var.iter().zip(run.after) {
                *view.at_mut(v) = x[j];
            }
            self.observe(view, n1);
            if let Some(first) = run.first {
                self.stop_recorded(view, n1, j, first);
            }
            if self.alive == 0 {
                return true;
            }
            self.keep_start(view);
        }
        false
    }

    /// Stops the running lanes whose stop condition first holds at step `j`
    /// of a recorded run (`first`, from [`RunStops::first`]), which ends at
    /// step `n1` with the state in `l`.
    #[inline(always)]
    fn stop_recorded(&mut self, l: &Lanes<R>, n1: u64, j: usize, first: &[u8; LANES]) {
        let h = &mut self.here;
        let mut stopped = 0;
        for i in 0..h.count {
            if first[i] as usize == j && h.status[i] == 0 {
                stop_lane(h.p, l, &mut h.status, n1, h.sink, h.base, i);
                stopped += 1;
            }
        }
        self.stopped(stopped);
    }

    /// Counts `k` more lanes stopped (their status already set).
    fn stopped(&mut self, k: usize) {
        if k > 0 {
            self.alive -= k;
            self.here.run = observe::running_flags(&self.here.status, self.here.count);
        }
    }
}

/// A recorded run from step `n`: `steps` states in `after`; `any`: its
/// last step left some lane non-finite; `first`: each lane's first step at
/// whose end the stop condition holds, where there is one.
struct Run<'r, R> {
    after: &'r [Recorded<R>],
    n: u64,
    steps: usize,
    any: bool,
    first: Option<&'r [u8; LANES]>,
}

/// Loads the block's inputs (parameters, initial state, dt, t0, …); padding
/// lanes repeat the block's last trajectory and their results are dropped.
fn load_inputs<R: Flows>(p: &Program<R>, l: &mut Lanes<R>, base: usize, count: usize) {
    for &(k, src) in &p.bindings {
        let mut values = src.values_from(p.plan.first + base, &p.plan.strides);
        let mut v = 0.0;
        for (i, x) in l.at_mut(k).iter_mut().enumerate() {
            if i < count {
                v = values.next().unwrap_or_default();
            }
            *x = R::from_f64(v);
        }
    }
}

/// How many steps from step `n` the block takes in one call: 1 where
/// something looks at every step (the vector field, cycle statistics, an
/// event or interpolated Poincaré section, the chaos indicators unless they
/// take the run themselves: `indicator_run`) or the step is not fused
/// stages; else up to the next trajectory frame, exact stroboscopic sample
/// of one of the block's `count` lanes or multiple of [`LANES`] steps (where
/// a pause may come), at most to the end.
fn quiet_run<R: Flows>(
    p: &Program<R>,
    obs: &BlockObservers<R>,
    n: u64,
    count: usize,
    indicator_run: bool,
) -> u64 {
    let plan = p.plan;
    let every_step = match indicator_run {
        true => plan.others_observe_every_step(),
        false => p.stages.is_none() || p.observes_every_step,
    };
    match every_step {
        true => 1,
        false => next_look(p, obs, n, count).map_or(1, |end| end - n),
    }
}

/// The first step after `n` at whose end frames, samples or sections want
/// the state (the next trajectory frame, attractor sample, exact
/// stroboscopic sample of one of the block's `count` lanes), or a pause
/// may come (a multiple of [`LANES`]), at most the end; `None` where the
/// section looks at every step.
fn next_look<R: Flows>(
    p: &Program<R>,
    obs: &BlockObservers<R>,
    n: u64,
    count: usize,
) -> Option<u64> {
    let plan = p.plan;
    let strobe = plan
        .observers
        .poincare
        .as_ref()
        .map(|_| obs.next_exact_strobe(n, count));
    if strobe == Some(None) {
        return None;
    }
    let lanes = LANES as u64;
    let mut end = (n / lanes + 1) * lanes;
    if let Some(tr) = &plan.observers.trajectory {
        end = end.min((n / tr.every + 1) * tr.every);
    }
    if let (Some(a), None) = (&plan.observers.attractors, &plan.observers.poincare) {
        // The samples after the skipped part only: the runs before it are
        // as long as without them.
        let (every, first) = (a.every(plan.steps), a.first_sample(plan.steps));
        end = end.min(((n / every + 1) * every).max(first));
    }
    if let Some(Some(due)) = strobe {
        end = end.min(due);
    }
    Some(end.min(plan.steps))
}

/// Steps `n … n+k−1` on every lane (`k` > 1 only for fused stages); returns
/// how many it took (it stops after a step that may have left some state
/// variable non-finite) and whether the last one did (then
/// [`nonfinite_lanes`] looks lane by lane).
fn advance<R: Flows>(
    p: &Program<R>,
    l: &mut Lanes<R>,
    regs: &mut [[R; LANES]],
    memory: Option<&mut StepMemory<R>>,
    n: u64,
    k: u64,
) -> (u64, bool) {
    if let Some(f) = &p.stages {
        // SAFETY: `isa()` chose wide kernels only where the CPU has the features.
        return unsafe { (f.kernel)(l, &f.weights, n, k, f.time_terms, None) };
    }
    if let (Some(f), Some(m)) = (&p.formula_step, memory) {
        // A variable no op assigns keeps its initial value: checked once.
        return (1, f.step(l, m, n) || (n == 0 && l.any_nonfinite(&p.var)));
    }
    run_ops(p, l, regs, R::from_f64(n as f64));
    (1, l.any_nonfinite(&p.var))
}

/// Makes every lane whose state is non-finite (`bad`: marked, or padding)
/// a twin of a running one: what it computes from now on is never read (its
/// results are NaN), and as a twin it no longer ends every run of steps
/// after one step. Does nothing when no lane runs (the block stops).
fn retire<R: Flows>(bad: &[bool; LANES], l: &mut Lanes<R>, status: &[u64; LANES], count: usize) {
    let Some(live) = (0..count).find(|&i| status[i] == 0) else {
        return;
    };
    for i in (0..LANES).filter(|&i| bad[i]) {
        l.copy_lane(live, i);
    }
}

/// The plan's ops in order (the step of models without a fused kernel).
fn run_ops<R: Flows>(p: &Program<R>, l: &mut Lanes<R>, regs: &mut [[R; LANES]], nf: R) {
    for op in &p.ops {
        match op {
            CpuOp::Tau(coef) => {
                for i in 0..LANES {
                    l.tau[i] = *coef * l.dt[i];
                }
            }
            CpuOp::Time(coef) => {
                for i in 0..LANES {
                    l.t[i] = l.t0[i] + nf * l.dt[i] + *coef * l.dt[i];
                }
            }
            op => op.call(l, regs),
        }
    }
}

/// Which lanes have some state variable non-finite.
fn nonfinite_lanes<R: Flows>(p: &Program<R>, l: &Lanes<R>) -> [bool; LANES] {
    let mut bad = [false; LANES];
    for &k in &p.var {
        let x = l.at(k);
        for i in 0..LANES {
            bad[i] |= !x[i].finite();
        }
    }
    bad
}

/// Stops the running lanes where the stop condition holds after step `n`
/// and writes their final values; returns how many stopped. Their lanes
/// go on computing what is never read. Never inlined: time's arithmetic
/// stays that of the baseline build (see [`Walk::look_at_run`]).
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn stop_lanes<R: Flows>(
    p: &Program<R>,
    stop: &Condition<R>,
    l: &mut Lanes<R>,
    real: &[[R; LANES]],
    regs: &mut [[R; LANES]],
    status: &mut [u64; LANES],
    n: u64,
    sink: &Sink<R>,
    base: usize,
    count: usize,
) -> usize {
    if stop.reads_time {
        let nf = R::from_f64(n as f64);
        for i in 0..LANES {
            l.t[i] = l.t0[i] + nf * l.dt[i];
        }
    }
    let holds = stop.holds(l, real, regs);
    let mut stopped = 0;
    for i in 0..count {
        if holds[i] && status[i] == 0 {
            stop_lane(p, l, status, n, sink, base, i);
            stopped += 1;
        }
    }
    stopped
}

/// Stops lane `i` after step `n`, its state in `l`: its status and final values.
fn stop_lane<R: Flows>(
    p: &Program<R>,
    l: &Lanes<R>,
    status: &mut [u64; LANES],
    n: u64,
    sink: &Sink<R>,
    base: usize,
    i: usize,
) {
    status[i] = u64::from(slots::STOPPED) | n;
    observe::write_finals(p, l, sink, base, i, n);
}

/// Marks the lanes `bad` at step `n` as stopped there (first time only);
/// returns how many stopped.
fn mark_nonfinite(bad: &[bool; LANES], status: &mut [u64; LANES], count: usize, n: u64) -> usize {
    let mut stopped = 0;
    for i in 0..count {
        if bad[i] && status[i] == 0 {
            status[i] = n + 1;
            stopped += 1;
        }
    }
    stopped
}
