//! The observers on the CPU: per-lane observer state of a block, and the
//! loops that store what the shared observer functions (`models/events.rs`,
//! the same ones the GPU kernel calls) decide — when a sample is due, where
//! inside the step, what value, how the cycle statistics update. The GPU
//! twin is the observer code of `backend/gpu/codegen.rs`.

// Lane loops index several arrays by lane; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use crate::models::lanes::{Lanes, LANES};
use crate::models::Flows;
use crate::plan::observers::{Direction, Section};
use crate::plan::ObsVar;

use super::program::Program;
use super::sink::Sink;

/// The block's state at the start of the current step (and the vector field
/// there), for interpolation inside the step; and which lanes stopped.
pub struct StepStart<'a, R> {
    pub prev: &'a [[R; LANES]],
    pub dprev: &'a [[R; LANES]],
    /// 0: running; k > 0: a variable became non-finite at step k.
    pub status: &'a [u64; LANES],
}

/// Per-lane observer state of one block (the GPU kernel keeps the same
/// state per trajectory in `aux_r`/`aux_u`).
pub struct BlockObservers<R> {
    /// Stroboscopic section sampled exactly: `(every, first)` steps per lane.
    strobe_exact: Option<([i32; LANES], [i32; LANES])>,
    /// Interpolated stroboscopic section: the next sample's number.
    strobe_next: [u64; LANES],
    points: [u32; LANES],
    cycle_max: [R; LANES],
    cycle_min: [R; LANES],
    cycle_count: [R; LANES],
    /// Time of the first crossing, and the running mean and co-moment of
    /// (crossing index, crossing time − first) for the least-squares period.
    cycle_first: [R; LANES],
    cycle_mean_t: [R; LANES],
    cycle_comoment: [R; LANES],
    /// First step (0-based) of the cycle statistics' measuring window.
    cycle_start: u64,
}

impl<R: Flows> BlockObservers<R> {
    /// Fresh observer state for a block whose inputs are loaded in `l`.
    pub fn new(p: &Program<R>, l: &Lanes<R>) -> Self {
        let plan = p.plan;
        let strobe_exact =
            (plan.observers.stroboscopic() && !plan.strobe_interpolated()).then(|| {
                let (mut every, mut first) = ([1i32; LANES], [0i32; LANES]);
                for i in 0..LANES {
                    let (period, phase) = (l.strobe_period[i], l.strobe_phase[i]);
                    R::strobe_exact_steps(period, phase, l.dt[i], &mut every[i], &mut first[i]);
                }
                (every, first)
            });
        BlockObservers {
            strobe_exact,
            strobe_next: [0; LANES],
            points: [0; LANES],
            cycle_max: [-R::inf(); LANES],
            cycle_min: [R::inf(); LANES],
            cycle_count: [R::default(); LANES],
            cycle_first: [R::nan(); LANES],
            cycle_mean_t: [R::default(); LANES],
            cycle_comoment: [R::default(); LANES],
            cycle_start: plan
                .observers
                .cycle
                .as_ref()
                .map_or(u64::MAX, |cy| (cy.skip * plan.steps as f64).floor() as u64),
        }
    }

    /// Trajectory frames and Poincaré points after step `n1` (0: the initial
    /// state), for the first `count` lanes of the block at row `base`.
    #[allow(clippy::too_many_arguments)]
    pub fn observe(
        &mut self,
        p: &Program<R>,
        l: &Lanes<R>,
        sink: &Sink<R>,
        base: usize,
        count: usize,
        at: &StepStart<R>,
        n1: u64,
    ) {
        record_frame(p, l, sink, base, count, at, n1);
        let Some(pc) = &p.plan.observers.poincare else {
            return;
        };
        match &pc.section {
            Section::Stroboscopic { .. } | Section::Forced { .. } => {
                self.strobe(p, l, sink, base, count, at, n1)
            }
            Section::Crossing {
                value, direction, ..
            } => self.crossing(p, l, sink, base, count, at, n1, *value, *direction),
        }
    }

    /// Stroboscopic samples due in the step that ends at `n1`.
    #[allow(clippy::too_many_arguments)]
    fn strobe(
        &mut self,
        p: &Program<R>,
        l: &Lanes<R>,
        sink: &Sink<R>,
        base: usize,
        count: usize,
        at: &StepStart<R>,
        n1: u64,
    ) {
        let (n1r, one) = (R::from_f64(n1 as f64), R::from_f64(1.0));
        for i in (0..count).filter(|i| at.status[*i] == 0) {
            if let Some((every, first)) = &self.strobe_exact {
                if R::strobe_exact_due(n1 as i32, every[i], first[i]) {
                    self.record(p, l, sink, base, i, at, n1, one, None);
                }
                continue;
            }
            let mut th = one;
            while R::strobe_due(
                R::from_f64(self.strobe_next[i] as f64),
                l.strobe_period[i],
                l.strobe_phase[i],
                l.dt[i],
                n1r,
                n1 == 0,
                &mut th,
            ) {
                self.record(p, l, sink, base, i, at, n1, th, None);
                self.strobe_next[i] += 1;
            }
        }
    }

    /// Event-section crossings inside the step that ends at `n1`.
    #[allow(clippy::too_many_arguments)]
    fn crossing(
        &mut self,
        p: &Program<R>,
        l: &Lanes<R>,
        sink: &Sink<R>,
        base: usize,
        count: usize,
        at: &StepStart<R>,
        n1: u64,
        value: f64,
        direction: Direction,
    ) {
        if n1 == 0 {
            return;
        }
        let cv = p.plan.crossing_var.expect("planned");
        let level = R::from_f64(value);
        let dir = direction_code(direction);
        for i in (0..count).filter(|i| at.status[*i] == 0) {
            let y0 = at.prev[cv][i] - level;
            let y1 = l.at(p.var[cv])[i] - level;
            if R::crossing_due(y0, y1, dir) {
                let dy1 = l.at(p.dvar[cv])[i];
                let th = R::crossing_theta(y0, y1, at.dprev[cv][i], dy1, l.dt[i]);
                self.record(p, l, sink, base, i, at, n1, th, Some((cv, level)));
            }
        }
    }

    /// Stores Poincaré point number `points[i]` of lane `i` (if kept) at θ
    /// inside the step; the crossing variable sits on the section exactly.
    #[allow(clippy::too_many_arguments)]
    fn record(
        &mut self,
        p: &Program<R>,
        l: &Lanes<R>,
        sink: &Sink<R>,
        base: usize,
        i: usize,
        at: &StepStart<R>,
        n1: u64,
        th: R,
        crossing: Option<(usize, R)>,
    ) {
        let max_points = p
            .plan
            .observers
            .poincare
            .as_ref()
            .map_or(0, |pc| pc.max_points);
        let k = self.points[i] as usize;
        if k < max_points {
            for (j, v) in p.plan.poincare_vars.iter().enumerate() {
                let x = match (crossing, v) {
                    (Some((cv, level)), ObsVar::State(s)) if *s == cv => level,
                    _ => value_at(p, l, *v, i, n1, th, at),
                };
                sink.poincare[j].set((base + i) * max_points + k, x);
            }
        }
        self.points[i] = self.points[i].saturating_add(1);
    }

    /// Cycle statistics over step `n → n+1`, inside the measuring window.
    pub fn cycle(&mut self, p: &Program<R>, l: &Lanes<R>, count: usize, at: &StepStart<R>, n: u64) {
        let Some(k) = p.plan.cycle_var else { return };
        if n + 1 < self.cycle_start {
            return;
        }
        let level = R::from_f64(p.plan.observers.cycle.as_ref().map_or(0.0, |cy| cy.level));
        let nf = R::from_f64(n as f64);
        for i in (0..count).filter(|i| at.status[*i] == 0) {
            let x = l.at(p.var[k])[i];
            R::cycle_step(
                x,
                at.prev[k][i] - level,
                x - level,
                at.dprev[k][i],
                l.at(p.dvar[k])[i],
                l.dt[i],
                l.t0[i] + nf * l.dt[i],
                &mut self.cycle_max[i],
                &mut self.cycle_min[i],
                &mut self.cycle_count[i],
                &mut self.cycle_first[i],
                &mut self.cycle_mean_t[i],
                &mut self.cycle_comoment[i],
            );
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
        let steps = R::from_f64(plan.steps as f64);
        for (j, v) in plan.final_vars.iter().enumerate() {
            for i in 0..count {
                let x = match (status[i], v) {
                    (0, ObsVar::State(k)) => l.at(p.var[*k])[i],
                    (0, ObsVar::Time) => l.t0[i] + steps * l.dt[i],
                    _ => R::nan(),
                };
                sink.final_values[j].set(base + i, x);
            }
        }
        if plan.cycle_var.is_some() {
            for i in 0..count {
                let ok = status[i] == 0;
                let two = R::from_f64(2.0);
                let amp = if ok {
                    R::cycle_amplitude(self.cycle_max[i], self.cycle_min[i])
                } else {
                    R::nan()
                };
                let per = if ok && self.cycle_count[i] >= two {
                    R::cycle_period(self.cycle_comoment[i], self.cycle_count[i])
                } else {
                    R::nan()
                };
                sink.cycle_amplitude.set(base + i, amp);
                sink.cycle_period.set(base + i, per);
            }
        }
        if plan.observers.poincare.is_some() {
            for i in 0..count {
                sink.poincare_count.set(base + i, self.points[i]);
            }
        }
        for i in 0..count {
            // Plans have fewer than 2³¹ steps.
            sink.nonfinite_step.set(base + i, status[i] as u32);
        }
    }
}

/// A trajectory frame, if step `n1` is one: the state at the step's end.
fn record_frame<R: Flows>(
    p: &Program<R>,
    l: &Lanes<R>,
    sink: &Sink<R>,
    base: usize,
    count: usize,
    at: &StepStart<R>,
    n1: u64,
) {
    let plan = p.plan;
    let Some(tr) = &plan.observers.trajectory else {
        return;
    };
    if !R::frame_due(n1 as i32, tr.every as i32) {
        return;
    }
    let frame = (n1 / tr.every) as usize;
    let frames = (plan.steps / tr.every) as usize + 1;
    let one = R::from_f64(1.0);
    for (j, v) in plan.trajectory_vars.iter().enumerate() {
        for i in 0..count {
            let x = if at.status[i] != 0 {
                R::nan()
            } else {
                value_at(p, l, *v, i, n1, one, at)
            };
            sink.trajectory[j].set((base + i) * frames + frame, x);
        }
    }
}

/// An observed variable of lane `i` at θ inside step `n1 − 1 → n1`.
fn value_at<R: Flows>(
    p: &Program<R>,
    l: &Lanes<R>,
    v: ObsVar,
    i: usize,
    n1: u64,
    th: R,
    at: &StepStart<R>,
) -> R {
    match v {
        ObsVar::Time => R::observed_time(l.t0[i], R::from_f64(n1 as f64), l.dt[i], th),
        // At the step's end the state itself (no slopes needed).
        ObsVar::State(k) if th == R::from_f64(1.0) => l.at(p.var[k])[i],
        ObsVar::State(k) => R::observed_state(
            at.prev[k][i],
            l.at(p.var[k])[i],
            at.dprev[k][i],
            l.at(p.dvar[k])[i],
            l.dt[i],
            th,
        ),
    }
}

/// The direction argument of the shared `crossing_due`.
pub fn direction_code(d: Direction) -> i32 {
    match d {
        Direction::Up => 0,
        Direction::Down => 1,
        Direction::Both => 2,
    }
}
