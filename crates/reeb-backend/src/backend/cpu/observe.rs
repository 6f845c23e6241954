//! The observers on the CPU: per-lane observer state of a block, and the
//! loops that store what the shared observer functions (`models/events.rs`,
//! the same ones the GPU kernel calls) decide — when a sample is due, where
//! inside the step, what value, how the cycle statistics update. The GPU
//! twin is the observer code of `backend/gpu/codegen.rs`.

// Lane loops index several arrays by lane; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use std::io::{self, Read, Write};

use crate::models::lanes::{LaneArrays, Lanes, LANES};
use crate::models::Flows;
use crate::plan::observations::{Rows, Sink};
use crate::plan::section::{Recorded, SectionKind, SectionStep};
use crate::plan::slots;
use crate::plan::snapshot::{get, put};
use crate::plan::{ObsVar, Plan};

use super::program::Program;
use super::tangent::TangentScratch;

/// A block right after step `n1` (0: the initial state), as the observers
/// see it: the program, the lanes, where its rows go, the state at the
/// step's start (and the vector field there) for interpolation inside the
/// step, and which lanes stopped.
pub struct BlockStep<'a, R> {
    pub p: &'a Program<'a, R>,
    pub l: &'a Lanes<R>,
    pub sink: &'a Sink<R>,
    /// The block's first row, and its trajectories (the rest is padding).
    pub base: usize,
    pub count: usize,
    pub prev: &'a [[R; LANES]],
    pub dprev: &'a [[R; LANES]],
    /// 0: running; k > 0: a variable became non-finite at step k.
    pub status: &'a [u64; LANES],
    pub n1: u64,
}

impl<R> BlockStep<'_, R> {
    /// The lanes still running.
    fn running(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.count).filter(|i| self.status[*i] == 0)
    }
}

/// Per-lane observer state of one block: the slots of `plan/slots.rs`
/// (the GPU kernel keeps the same per trajectory in `aux_r`/`aux_u`).
pub struct BlockObservers<R> {
    /// Stroboscopic section sampled exactly: `(every, first)` steps per lane.
    strobe_exact: Option<([i32; LANES], [i32; LANES])>,
    /// The real slots of [`slots::real`], per lane.
    real: LaneArrays<R>,
    count: [[i32; LANES]; slots::COUNT.len()],
    /// Where the cycle statistics and time averages start, as
    /// `Plan::cycle_start` and `Plan::average_start` say.
    cycle_start: u64,
    average_start: u64,
}

impl<R: Flows> BlockObservers<R> {
    /// Fresh observer state for a block whose inputs are loaded in `l`.
    pub fn new(p: &Program<R>, l: &Lanes<R>) -> Self {
        let plan = p.plan;
        let exact = p
            .section
            .as_ref()
            .is_some_and(|s| s.kind == SectionKind::Exact);
        let strobe_exact = exact.then(|| {
            let (mut every, mut first) = ([1i32; LANES], [0i32; LANES]);
            for i in 0..LANES {
                let (period, phase) = (l.strobe_period[i], l.strobe_phase[i]);
                R::strobe_exact_steps(period, phase, l.dt[i], &mut every[i], &mut first[i]);
            }
            (every, first)
        });
        BlockObservers {
            strobe_exact,
            real: slots::real(plan)
                .iter()
                .map(|(_, init)| [init.value(); LANES])
                .collect(),
            count: [[0; LANES]; slots::COUNT.len()],
            cycle_start: plan.cycle_start(),
            average_start: plan.average_start(),
        }
    }

    /// Writes the slots (the rest follows from the block's inputs, as
    /// [`Self::new`] computes it).
    pub fn write(&self, w: &mut dyn Write) -> io::Result<()> {
        for v in self.real.iter() {
            put(w, v)?;
        }
        for v in &self.count {
            put(w, v)?;
        }
        Ok(())
    }

    /// Reads what [`Self::write`] wrote into observers made by [`Self::new`].
    pub fn read(&mut self, r: &mut dyn Read) -> io::Result<()> {
        for v in self.real.iter_mut() {
            get(r, v)?;
        }
        for v in &mut self.count {
            get(r, v)?;
        }
        Ok(())
    }

    /// With a stroboscopic section sampled exactly, the first step `n1 > n`
    /// after which one of the block's first `count` lanes samples (`u64::MAX`
    /// if none ever does); `None` for any other section, which looks at
    /// every step.
    pub fn next_exact_strobe(&self, n: u64, count: usize) -> Option<u64> {
        let (every, first) = self.strobe_exact.as_ref()?;
        let due = |i: usize| {
            let (every, first) = (every[i] as i64, first[i] as i64);
            if every <= 0 {
                return u64::MAX;
            }
            let lo = (n as i64 + 1).max(first);
            (first + (lo - first + every - 1) / every * every) as u64
        };
        Some((0..count).map(due).min().unwrap_or(u64::MAX))
    }

    /// Trajectory frames and Poincaré points after step `n1` (0: the initial
    /// state), for the first `count` lanes of the block at row `base`.
    pub fn observe(&mut self, s: &BlockStep<R>) {
        record_frame(s);
        self.section(s);
    }

    /// The section's points in the step that ends at `n1`, as the shared
    /// `section_next` finds them.
    fn section(&mut self, s: &BlockStep<R>) {
        let Some(section) = &s.p.section else {
            return;
        };
        let (p, l, n1) = (s.p, s.l, s.n1 as i32);
        let (kind, max_points) = (section.kind.code(), section.kept_limit());
        let (exact_every, exact_first) = self.strobe_exact.unwrap_or(([0; LANES], [0; LANES]));
        let candidates = self.candidates(s, section);
        if candidates == 0 {
            return;
        }
        let zero = R::default();
        let [strobe_k, npoints] = &mut self.count;
        for i in (0..s.count).filter(|i| candidates >> i & 1 == 1) {
            let (mut y0, mut y1, mut d0, mut d1, mut direction) = (zero, zero, zero, zero, 0);
            if let SectionKind::Crossing {
                var,
                level,
                direction: d,
            } = section.kind
            {
                let level = R::from_f64(level);
                y0 = s.prev[var][i] - level;
                y1 = l.at(p.var[var])[i] - level;
                (d0, d1, direction) = (s.dprev[var][i], l.at(p.dvar[var])[i], d.code());
            }
            let (mut done, mut th) = (false, zero);
            while R::section_next(
                kind,
                n1,
                n1 == 0,
                exact_every[i],
                exact_first[i],
                l.strobe_period[i],
                l.strobe_phase[i],
                l.dt[i],
                y0,
                y1,
                d0,
                d1,
                direction,
                &mut strobe_k[i],
                &mut done,
                &mut th,
            ) {
                let k = npoints[i] as usize;
                if R::point_kept(&mut npoints[i], max_points) {
                    record_point(s, section, i, k, th);
                }
            }
        }
    }

    /// The lanes that may find a point in this step, as bits. Exact
    /// sections and crossings are due at few steps of a lane: the per-lane
    /// call is skipped where the predicate `section_next` applies first
    /// says no, which leaves the points found unchanged.
    fn candidates(&self, s: &BlockStep<R>, section: &SectionStep) -> u64 {
        let n1 = s.n1 as i32;
        let bits = |may: &dyn Fn(usize) -> bool| {
            s.running().filter(|&i| may(i)).fold(0, |b, i| b | 1 << i)
        };
        match (section.kind, &self.strobe_exact) {
            (SectionKind::Exact, Some((every, first))) => {
                bits(&|i| R::strobe_exact_due(n1, every[i], first[i]))
            }
            (SectionKind::Crossing { .. }, _) if n1 == 0 => 0,
            (
                SectionKind::Crossing {
                    var,
                    level,
                    direction,
                },
                _,
            ) => {
                let (level, now, d) = (R::from_f64(level), s.l.at(s.p.var[var]), direction.code());
                bits(&|i| R::crossing_due(s.prev[var][i] - level, now[i] - level, d))
            }
            _ => bits(&|_| true),
        }
    }

    /// The real slots, per lane (what a stop condition may read).
    pub fn slots(&self) -> &[[R; LANES]] {
        &self.real
    }

    /// The chaos indicators after the step.
    pub fn indicators(
        &mut self,
        s: &BlockStep<R>,
        regs: &mut [[R; LANES]],
        scratch: Option<&mut TangentScratch<R>>,
    ) {
        let Some(ind) = &s.p.indicators else {
            return;
        };
        let (running, padding) = running_lanes(&s.status[..s.count]);
        let (l, prev, real) = (s.l, s.prev, &mut self.real);
        let lanes = running | padding;
        ind.after_step(l, prev, real, regs, scratch, s.n1, lanes, s.p.isa);
    }

    /// The observers' real slots, mutable (the compiled tangent step moves
    /// the deviation vectors in them).
    pub fn slots_mut(&mut self) -> &mut [[R; LANES]] {
        &mut self.real
    }

    /// Cycle statistics over step `n → n+1`, inside the measuring window.
    pub fn cycle(&mut self, s: &BlockStep<R>) {
        let (p, l) = (s.p, s.l);
        let Some(k) = p.plan.cycle_var else { return };
        if s.n1 < self.cycle_start {
            return;
        }
        let level = R::from_f64(p.plan.observers.cycle.as_ref().map_or(0.0, |cy| cy.level));
        let nf = R::from_f64((s.n1 - 1) as f64);
        let [max, min, count, first, mean, com] = &mut self.real[..slots::MEAN0] else {
            unreachable!("the fixed slots")
        };
        for i in s.running() {
            let x = l.at(p.var[k])[i];
            R::cycle_step(
                x,
                s.prev[k][i] - level,
                x - level,
                s.dprev[k][i],
                l.at(p.dvar[k])[i],
                l.dt[i],
                l.t0[i] + nf * l.dt[i],
                &mut max[i],
                &mut min[i],
                &mut count[i],
                &mut first[i],
                &mut mean[i],
                &mut com[i],
            );
        }
    }

    /// Time averages over step `n → n+1`, after the skipped part of the run.
    pub fn average(&mut self, s: &BlockStep<R>) {
        let (p, l) = (s.p, s.l);
        let start = self.average_start;
        if s.n1 <= start {
            return;
        }
        let k = R::from_f64((s.n1 - start) as f64);
        for (j, v) in p.plan.average_vars.iter().enumerate() {
            let ObsVar::State(v) = *v else {
                unreachable!("time is not averaged")
            };
            let mean = &mut self.real[slots::MEAN0 + j];
            for i in s.running() {
                R::mean_step(l.at(p.var[v])[i], k, &mut mean[i]);
            }
        }
    }

    /// The chaos indicators' outputs of the block's trajectories.
    fn finish_indicators(
        &self,
        p: &Program<R>,
        l: &Lanes<R>,
        sink: &Sink<R>,
        base: usize,
        count: usize,
        status: &[u64; LANES],
    ) {
        let dt = l.at(p.dt_lane);
        for i in 0..count {
            let (nonfinite, stop) = slots::split_status(status[i]);
            let slot = |k: usize| self.real[k][i];
            let values = slots::indicators_finish(p.plan, slot, dt[i], nonfinite == 0, stop);
            let columns = [&sink.lyapunov, &sink.fli, &sink.megno];
            put_indicators(p.plan, columns, base + i, values);
        }
    }

    /// The indicators' running values, if step `n1` is a trajectory frame.
    pub fn indicator_frame(&self, s: &BlockStep<R>) {
        let p = s.p;
        let (Some(_), Some((frame, frames))) = (&p.indicators, frame_at(s)) else {
            return;
        };
        let dt = s.l.at(p.dt_lane);
        let sink = s.sink;
        let columns = [
            &sink.trajectory_lyapunov,
            &sink.trajectory_fli,
            &sink.trajectory_megno,
        ];
        for i in 0..s.count {
            let row = (s.base + i) * frames + frame;
            let slot = |k: usize| self.real[k][i];
            let values = slots::indicators_at(p.plan, slot, dt[i], s.status[i] == 0, s.n1);
            put_indicators(p.plan, columns, row, values);
        }
    }

    /// Final values, cycle statistics, point counts and status of the block.
    pub fn finish(
        &self,
        p: &Program<R>,
        l: &Lanes<R>,
        sink: &Sink<R>,
        base: usize,
        count: usize,
        status: &[u64; LANES],
    ) {
        let plan = p.plan;
        for i in 0..count {
            match slots::split_status(status[i]) {
                (0, 0) => write_finals(p, l, sink, base, i, plan.steps),
                // Written when it stopped.
                (0, _) => {}
                _ => {
                    for column in &sink.final_values {
                        column.set(base + i, R::nan());
                    }
                }
            }
        }
        if plan.cycle_var.is_some() {
            for i in 0..count {
                let ok = slots::split_status(status[i]).0 == 0;
                let (amp, per) = slots::cycle_finish(|k| self.real[k][i], ok);
                sink.cycle_amplitude.set(base + i, amp);
                sink.cycle_period.set(base + i, per);
            }
        }
        for (j, column) in sink.mean.iter().enumerate() {
            for i in 0..count {
                let mean = self.real[slots::MEAN0 + j][i];
                let (nonfinite, stop) = slots::split_status(status[i]);
                column.set(
                    base + i,
                    slots::mean_finish(plan, mean, nonfinite == 0, stop),
                );
            }
        }
        if plan.indicators.is_some() {
            self.finish_indicators(p, l, sink, base, count, status);
        }
        if plan.observers.poincare.is_some() {
            for i in 0..count {
                sink.poincare_count
                    .set(base + i, self.count[slots::NPOINTS][i] as u32);
            }
        }
        for i in 0..count {
            let (nonfinite, stop) = slots::split_status(status[i]);
            sink.nonfinite_step.set(base + i, nonfinite);
            sink.stop_step.set(base + i, stop);
        }
    }
}

/// The final values of lane `i` (row `base + i`), its state after step
/// `last` (the run's last, or where it stopped).
pub fn write_finals<R: Flows>(
    p: &Program<R>,
    l: &Lanes<R>,
    sink: &Sink<R>,
    base: usize,
    i: usize,
    last: u64,
) {
    let steps = R::from_f64(last as f64);
    for (j, v) in p.plan.final_vars.iter().enumerate() {
        let x = match v {
            ObsVar::State(k) => l.at(p.var[*k])[i],
            ObsVar::Time => l.t0[i] + steps * l.dt[i],
        };
        sink.final_values[j].set(base + i, x);
    }
}

/// `(frame, frames per trajectory)` if step `n1` is a trajectory frame.
fn frame_at<R: Flows>(s: &BlockStep<R>) -> Option<(usize, usize)> {
    let plan = s.p.plan;
    let tr = plan.observers.trajectory.as_ref()?;
    R::frame_due(s.n1 as i32, tr.every as i32).then(|| {
        (
            (s.n1 / tr.every) as usize,
            (plan.steps / tr.every) as usize + 1,
        )
    })
}

/// The lanes of a block whose trajectories run (`status` 0), and the
/// padding lanes past them, as bits. The padding lanes run too (nothing
/// reads them), so that a block whose trajectories all run is written
/// whole. This runs after every step: one vectorised pass when every lane
/// runs, lane by lane only when some stopped.
pub fn running_lanes(status: &[u64]) -> (u64, u64) {
    let padding = u64::MAX.checked_shl(status.len() as u32).unwrap_or(0);
    if status.iter().fold(0, |a, &x| a | x) == 0 {
        return (!padding, padding);
    }
    let mut bits = 0u64;
    for (i, &x) in status.iter().enumerate() {
        bits |= u64::from(x == 0) << i;
    }
    (bits, padding)
}

/// The indicators' values `(exponents, FLI, MEGNO)` as row `row` of their
/// columns (outputs or running values), those the plan asks for.
fn put_indicators<R: Copy>(
    plan: &Plan,
    [l, f, m]: [&Rows<R>; 3],
    row: usize,
    (lyap, fli, megno): (Vec<R>, R, R),
) {
    for (j, x) in lyap.iter().enumerate() {
        l.set(row * lyap.len() + j, *x);
    }
    if plan.observers.fli.is_some() {
        f.set(row, fli);
    }
    if plan.observers.megno.is_some() {
        m.set(row, megno);
    }
}

/// A trajectory frame, if step `n1` is one: the state at the step's end.
fn record_frame<R: Flows>(s: &BlockStep<R>) {
    let plan = s.p.plan;
    let Some((frame, frames)) = frame_at(s) else {
        return;
    };
    let one = R::from_f64(1.0);
    for (j, v) in plan.trajectory_vars.iter().enumerate() {
        for i in 0..s.count {
            let x = if s.status[i] != 0 {
                R::nan()
            } else {
                value_at(s, *v, i, one)
            };
            s.sink.trajectory[j].set((s.base + i) * frames + frame, x);
        }
    }
}

/// Poincaré point number `k` of lane `i`, at θ inside the step.
fn record_point<R: Flows>(s: &BlockStep<R>, section: &SectionStep, i: usize, k: usize, th: R) {
    for (j, c) in section.columns.iter().enumerate() {
        let x = match c {
            Recorded::Level(level) => R::from_f64(*level),
            Recorded::Var(v) => value_at(s, *v, i, th),
        };
        s.sink.poincare[j].set((s.base + i) * section.max_points + k, x);
    }
}

/// An observed variable of lane `i` at θ inside step `n1 − 1 → n1`.
fn value_at<R: Flows>(s: &BlockStep<R>, v: ObsVar, i: usize, th: R) -> R {
    let (p, l) = (s.p, s.l);
    match v {
        ObsVar::Time => R::observed_time(l.t0[i], R::from_f64(s.n1 as f64), l.dt[i], th),
        // At the step's end the state itself (no slopes needed).
        ObsVar::State(k) if th == R::from_f64(1.0) => l.at(p.var[k])[i],
        ObsVar::State(k) => R::observed_state(
            s.prev[k][i],
            l.at(p.var[k])[i],
            s.dprev[k][i],
            l.at(p.dvar[k])[i],
            l.dt[i],
            th,
        ),
    }
}
