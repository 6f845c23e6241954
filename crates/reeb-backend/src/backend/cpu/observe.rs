//! The observers on the CPU: per-lane observer state of a block, and the
//! loops that store what the shared observer functions (`models/events.rs`,
//! the same ones the GPU kernel calls) decide — when a sample is due, where
//! inside the step, what value, how the cycle statistics update. The GPU
//! twin is the observer code of `backend/gpu/codegen.rs`.

// Lane loops index several arrays by lane; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use std::cell::{Ref, RefCell};
use std::io::{self, Read, Write};

use crate::models::lanes::{Lane, LaneArrays, Lanes, LANES};
use crate::models::pieces::MAX_VARS;
use crate::models::Flows;
use crate::plan::observations::Sink;
use crate::plan::recurrence::{Layout, OrbitSlots};
use crate::plan::section::{Recorded, SectionKind, SectionStep};
use crate::plan::slots;
use crate::plan::snapshot::{get, put};
use crate::plan::ObsVar;

use super::program::Program;
use super::tangent::TangentScratch;

/// A block right after step `n1` (0: the initial state), as the observers
/// see it: the program, the lanes (their state the state after the step),
/// where its rows go, the state at the step's start and the vector field at
/// both ends for interpolation inside the step, and which lanes stopped.
pub struct BlockStep<'a, R> {
    pub p: &'a Program<'a, R>,
    pub l: &'a Lanes<R>,
    pub sink: &'a Sink<R>,
    /// The block's first row, and its trajectories (the rest is padding).
    pub base: usize,
    pub count: usize,
    pub prev: &'a [[R; LANES]],
    /// Where the plan needs the field ([`Program::needs_field`]).
    pub slopes: Option<&'a Slopes<R>>,
    /// 0: running; k > 0: a variable became non-finite at step k.
    pub status: &'a [u64; LANES],
    /// Which lanes run: status 0, and not padding ([`running_flags`]).
    pub run: &'a [bool; LANES],
    pub n1: u64,
}

impl<R: Flows> BlockStep<'_, R> {
    /// The vector field at the step's start and end on lane `i` (see
    /// [`Slopes`]).
    fn slopes(&self, i: usize) -> LaneSlopes<R> {
        let slopes = self.slopes.expect("slopes where the plan needs the field");
        slopes.of_lane(self, i)
    }
}

/// The vector field at both ends of the step the observers look at,
/// evaluated only where one of them interpolates inside it (a crossing, a
/// sample between two steps): on most steps no lane does, and the field of a
/// whole block costs as much as a step. Evaluated on one trajectory where
/// the model's field has scalar ops (the same shared functions as its lane
/// loops), else on lanes of its own, once per step; either from the
/// block's inputs and the observed state: the values the step's ends have.
pub struct Slopes<R> {
    at: RefCell<SlopesAt<R>>,
}

/// The field of [`Slopes`] at the step that ends at `n1`.
pub struct SlopesAt<R> {
    /// The block's inputs, where the field is evaluated on the whole block
    /// (copied from the observed lanes when first needed).
    lanes: Option<Box<Lanes<R>>>,
    regs: LaneArrays<R>,
    n1: Option<u64>,
    /// Each state variable's derivative at the step's start and end.
    pub d0: LaneArrays<R>,
    pub d1: LaneArrays<R>,
}

impl<R: Flows> Slopes<R> {
    /// Slopes for a block of `p`.
    pub fn new(p: &Program<R>) -> Self {
        let nv = p.var.len();
        Slopes {
            at: RefCell::new(SlopesAt {
                lanes: None,
                regs: LaneArrays::filled(p.registers, R::default()),
                n1: None,
                d0: LaneArrays::filled(nv, R::default()),
                d1: LaneArrays::filled(nv, R::default()),
            }),
        }
    }

    /// The field at both ends of the step `s` looks at, on lane `i`.
    /// Never inlined: its arithmetic stays that of the baseline build (see
    /// `cpu::Walk::look_at_run`).
    #[inline(never)]
    fn of_lane(&self, s: &BlockStep<R>, i: usize) -> LaneSlopes<R> {
        let p = s.p;
        let Some(ops) = &p.field_lane else {
            let at = self.at(s);
            let pick = |d: &LaneArrays<R>| {
                std::array::from_fn(|k| d.get(k).map_or(R::default(), |a| a[i]))
            };
            return LaneSlopes {
                d0: pick(&at.d0),
                d1: pick(&at.d1),
            };
        };
        // The lane's inputs from the observed lanes, its state from the step.
        let mut x = Lane::gather(s.l, i);
        let mut field = |state: &dyn Fn(usize) -> R, n: u64| {
            for (k, &v) in p.var.iter().enumerate() {
                *x.at_mut(v) = state(k);
            }
            x.t = x.t0 + R::from_f64(n as f64) * x.dt;
            for f in ops {
                f(&mut x);
            }
            std::array::from_fn(|k| p.dvar.get(k).map_or(R::default(), |&v| x.at(v)))
        };
        LaneSlopes {
            d0: field(&|k| s.prev[k][i], s.n1.saturating_sub(1)),
            d1: field(&|k| s.l.at(p.var[k])[i], s.n1),
        }
    }

    /// The field at both ends of the step `s` looks at, on every lane,
    /// evaluated once per step.
    #[inline(never)]
    fn at(&self, s: &BlockStep<R>) -> Ref<'_, SlopesAt<R>> {
        if self.at.borrow().n1 != Some(s.n1) {
            let mut at = self.at.borrow_mut();
            let SlopesAt {
                lanes,
                regs,
                n1,
                d0,
                d1,
            } = &mut *at;
            let p = s.p;
            let lanes = lanes.get_or_insert_with(|| {
                let mut lanes = Lanes::boxed();
                lanes.as_mut_slice().copy_from_slice(s.l.as_slice());
                lanes
            });
            let start = s.n1.saturating_sub(1);
            field_at(p, lanes, regs, s.prev, start, d0);
            let end = p.var.iter().map(|&v| s.l.at(v));
            field_at(p, lanes, regs, end, s.n1, d1);
            *n1 = Some(s.n1);
        }
        self.at.borrow()
    }
}

/// Each state variable's derivative at the start and the end of a step,
/// on one lane.
pub struct LaneSlopes<R> {
    pub d0: [R; MAX_VARS],
    pub d1: [R; MAX_VARS],
}

/// The vector field at state `x` (each variable's lanes, in the plan's
/// order) at the end of step `n` (time `t0 + n dt`) into `d`.
fn field_at<'x, R: Flows + 'x>(
    p: &Program<R>,
    l: &mut Lanes<R>,
    regs: &mut [[R; LANES]],
    x: impl IntoIterator<Item = &'x [R; LANES]>,
    n: u64,
    d: &mut [[R; LANES]],
) {
    for (&v, x) in p.var.iter().zip(x) {
        *l.at_mut(v) = *x;
    }
    p.eval_field(l, regs, n);
    for (d, &v) in d.iter_mut().zip(&p.dvar) {
        *d = *l.at(v);
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
    /// Interpolated stroboscopic section: each lane's next sample, as
    /// `strobe_position` of sample `strobe_for` (−1: not yet computed).
    strobe_at: [R; LANES],
    strobe_for: [i32; LANES],
    /// Where the cycle statistics and time averages start, as
    /// `Plan::cycle_start` and `Plan::average_start` say.
    cycle_start: u64,
    average_start: u64,
    detector: Option<Detector<R>>,
}

/// The attractor detector (`plan/recurrence.rs`) in the run's precision.
struct Detector<R> {
    at: Layout,
    tolerance: R,
    wrap: Vec<R>,
    vars: Vec<ObsVar>,
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
            strobe_at: [R::default(); LANES],
            strobe_for: [-1; LANES],
            cycle_start: plan.cycle_start(),
            average_start: plan.average_start(),
            detector: slots::recurrence(plan).map(|at| Detector {
                tolerance: R::from_f64(at.tolerance),
                wrap: at.wrap.iter().map(|&w| R::from_f64(w)).collect(),
                vars: plan.attractor_vars.clone(),
                at,
            }),
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
    #[inline(always)]
    pub fn observe(&mut self, s: &BlockStep<R>) {
        record_frame(s);
        self.section(s);
        self.attractor_sample(s);
    }

    /// The attractor detector's sample after step `n1`, where one is due
    /// (without a section: every `every` steps after the skipped part).
    #[inline(always)]
    fn attractor_sample(&mut self, s: &BlockStep<R>) {
        let Some(d) = &self.detector else { return };
        if !d.at.due(s.n1) {
            return;
        }
        for i in (0..s.count).filter(|&i| s.run[i]) {
            take_sample(d, &mut self.real, s, i, R::from_f64(1.0));
        }
    }

    /// The section's points in the step that ends at `n1`, as the shared
    /// `section_next` finds them.
    #[inline(always)]
    fn section(&mut self, s: &BlockStep<R>) {
        let Some(section) = &s.p.section else {
            return;
        };
        let candidates = self.candidates(s, section);
        if candidates != 0 {
            self.section_points(s, section, candidates);
        }
    }

    /// The points of [`Self::section`] on the lanes `candidates`. Never
    /// inlined: its arithmetic stays that of the baseline build (see
    /// `cpu::Walk::look_at_run`).
    #[inline(never)]
    fn section_points(&mut self, s: &BlockStep<R>, section: &SectionStep, candidates: u64) {
        let (p, l, n1) = (s.p, s.l, s.n1 as i32);
        let (kind, max_points) = (section.kind.code(), section.kept_limit());
        let (exact_every, exact_first) = self.strobe_exact.unwrap_or(([0; LANES], [0; LANES]));
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
                let f = s.slopes(i);
                y0 = s.prev[var][i] - level;
                y1 = l.at(p.var[var])[i] - level;
                (d0, d1, direction) = (f.d0[var], f.d1[var], d.code());
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
                if let Some(d) = self.detector.as_ref().filter(|d| s.n1 >= d.at.skip_step) {
                    take_sample(d, &mut self.real, s, i, th);
                }
            }
        }
    }

    /// The lanes that may find a point in this step, as bits. Exact
    /// sections and crossings are due at few steps of a lane: the per-lane
    /// call is skipped where the predicate `section_next` applies first
    /// says no, which leaves the points found unchanged.
    #[inline(always)]
    fn candidates(&mut self, s: &BlockStep<R>, section: &SectionStep) -> u64 {
        let n1 = s.n1 as i32;
        let run = *s.run;
        let mut may = [false; LANES];
        match (section.kind, &self.strobe_exact) {
            (SectionKind::Exact, Some((every, first))) => {
                for i in 0..LANES {
                    may[i] = R::strobe_exact_due(n1, every[i], first[i]);
                }
            }
            (SectionKind::Crossing { .. }, _) if n1 == 0 => return 0,
            (
                SectionKind::Crossing {
                    var,
                    level,
                    direction,
                },
                _,
            ) => {
                let (level, now, d) = (R::from_f64(level), s.l.at(s.p.var[var]), direction.code());
                for i in 0..LANES {
                    may[i] = R::crossing_due(s.prev[var][i] - level, now[i] - level, d);
                }
            }
            (SectionKind::Exact, None) => unreachable!("an exact section has its steps"),
            (SectionKind::Interpolated, _) => {
                let k = &self.count[slots::STROBE_K];
                let mut stale = false;
                for i in 0..LANES {
                    stale |= self.strobe_for[i] != k[i];
                }
                if stale {
                    strobe_positions(s, k, &mut self.strobe_at, &mut self.strobe_for);
                }
                let n1 = R::from_i32(n1);
                for i in 0..LANES {
                    may[i] = R::strobe_reached(self.strobe_at[i], n1);
                }
            }
        }
        flags_to_bits(&may, &run)
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

    /// Cycle statistics over step `n → n+1`, inside the measuring window:
    /// `cycle_step`'s extremes and crossing test on every lane at once, its
    /// crossing on the lanes that cross.
    #[inline(always)]
    pub fn cycle(&mut self, s: &BlockStep<R>) {
        let (p, l) = (s.p, s.l);
        let Some(k) = p.plan.cycle_var else { return };
        if s.n1 < self.cycle_start {
            return;
        }
        let level = R::from_f64(p.plan.observers.cycle.as_ref().map_or(0.0, |cy| cy.level));
        let [max, min, count, first, mean, com] = &mut self.real[..slots::MEAN0] else {
            unreachable!("the fixed slots")
        };
        let (x, x0, run) = (l.at(p.var[k]), &s.prev[k], *s.run);
        let mut up = [false; LANES];
        for i in 0..LANES {
            let (mut hi, mut lo) = (max[i], min[i]);
            R::cycle_extremes(x[i], &mut hi, &mut lo);
            max[i] = R::select(max[i], hi, run[i]);
            min[i] = R::select(min[i], lo, run[i]);
            up[i] = R::cycle_up(x0[i] - level, x[i] - level);
        }
        let up = flags_to_bits(&up, &run);
        if up == 0 {
            return;
        }
        let slots = [count, first, mean, com];
        cycle_upcrossings(s, k, level, up, slots);
    }
    /// Time averages over step `n → n+1`, after the skipped part of the run.
    #[inline(always)]
    pub fn average(&mut self, s: &BlockStep<R>) {
        let (p, l) = (s.p, s.l);
        let start = self.average_start;
        if s.n1 <= start {
            return;
        }
        let k = R::from_f64((s.n1 - start) as f64);
        let run = *s.run;
        for (j, v) in p.plan.average_vars.iter().enumerate() {
            let ObsVar::State(v) = *v else {
                unreachable!("time is not averaged")
            };
            let (mean, x) = (&mut self.real[slots::MEAN0 + j], l.at(p.var[v]));
            for i in 0..LANES {
                let mut m = mean[i];
                R::mean_step(x[i], k, &mut m);
                mean[i] = R::select(mean[i], m, run[i]);
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
            let (lyapunov, scalars) = sink.indicators(false);
            values.put(lyapunov, scalars, base + i);
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
        let (lyapunov, scalars) = sink.indicators(true);
        for i in 0..s.count {
            let row = (s.base + i) * frames + frame;
            let slot = |k: usize| self.real[k][i];
            let values = slots::indicators_at(p.plan, slot, dt[i], s.status[i] == 0, s.n1);
            values.put(lyapunov, scalars, row);
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
        if let Some(d) = &self.detector {
            for i in 0..count {
                let slot = |k: usize| self.real[k][i];
                let status = slots::split_status(status[i]);
                let end = slots::attractor_finish(&d.at, slot, status);
                let points = sink.attractor_points.iter().collect();
                end.put(&sink.attractor_period, &sink.transient, points, base + i);
            }
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

/// The position of each lane's next interpolated stroboscopic sample
/// (number `k`) where it is not that of sample `at_k`: what `strobe_due`
/// compares with the step, which changes only when a sample is taken.
/// Never inlined: `strobe_position`, contracted into an FMA in wider code,
/// would differ from `strobe_due`'s (see `cpu::Walk::look_at_run`).
#[inline(never)]
fn strobe_positions<R: Flows>(
    s: &BlockStep<R>,
    k: &[i32; LANES],
    at: &mut [R; LANES],
    at_k: &mut [i32; LANES],
) {
    let l = s.l;
    for i in 0..LANES {
        if at_k[i] == k[i] {
            continue;
        }
        let (period, phase) = (l.strobe_period[i], l.strobe_phase[i]);
        at[i] = R::strobe_position(R::from_i32(k[i]), period, phase, l.dt[i]);
        at_k[i] = k[i];
    }
}

/// `cycle_step`'s crossings on the lanes `up`, into their cycle slots
/// `[count, first, mean, comoment]`. Never inlined: its arithmetic stays
/// that of the baseline build (see `cpu::Walk::look_at_run`; inlined into
/// AVX-512 code it gave other last bits).
#[inline(never)]
fn cycle_upcrossings<R: Flows>(
    s: &BlockStep<R>,
    k: usize,
    level: R,
    up: u64,
    [count, first, mean, com]: [&mut [R; LANES]; 4],
) {
    let (p, l) = (s.p, s.l);
    let (x, x0) = (l.at(p.var[k]), &s.prev[k]);
    let nf = R::from_f64((s.n1 - 1) as f64);
    for i in (0..LANES).filter(|i| up >> i & 1 == 1) {
        let f = s.slopes(i);
        R::cycle_upcrossing(
            x0[i] - level,
            x[i] - level,
            f.d0[k],
            f.d1[k],
            l.dt[i],
            l.t0[i] + nf * l.dt[i],
            &mut count[i],
            &mut first[i],
            &mut mean[i],
            &mut com[i],
        );
    }
}

/// The final values of lane `i` (row `base + i`), its state after step
/// `last` (the run's last, or where it stopped). Never inlined: time's
/// arithmetic stays that of the baseline build.
#[inline(never)]
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
#[inline(always)]
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

/// A trajectory frame, if step `n1` is one: the state at the step's end.
/// Never inlined: time's arithmetic stays that of the baseline build.
#[inline(never)]
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

/// Lane `i`'s sample at θ inside the step `s` ends, into its attractor
/// detector (`Layout::take`). Never inlined: its arithmetic stays that of
/// the baseline build (see `cpu::Walk::look_at_run`).
#[inline(never)]
fn take_sample<R: Flows>(
    d: &Detector<R>,
    real: &mut LaneArrays<R>,
    s: &BlockStep<R>,
    i: usize,
    th: R,
) {
    let mut x = [R::default(); MAX_VARS];
    for (c, v) in d.vars.iter().enumerate() {
        x[c] = value_at(s, *v, i, th);
    }
    let mut lane = LaneSlots { real, i };
    d.at.take(&x[..d.vars.len()], d.tolerance, &d.wrap, &mut lane);
}

/// Lane `i` of a block's real slots.
struct LaneSlots<'a, R> {
    real: &'a mut LaneArrays<R>,
    i: usize,
}

impl<R: Copy> OrbitSlots<R> for LaneSlots<'_, R> {
    fn read(&self, k: usize) -> R {
        self.real[k][self.i]
    }
    fn write(&mut self, k: usize, v: R) {
        self.real[k][self.i] = v;
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
        ObsVar::State(k) => {
            let f = s.slopes(i);
            R::observed_state(
                s.prev[k][i],
                l.at(p.var[k])[i],
                f.d0[k],
                f.d1[k],
                l.dt[i],
                th,
            )
        }
    }
}

/// The lanes of a block whose trajectories run (`status` 0 among the
/// first `count`), one flag per lane.
pub fn running_flags(status: &[u64; LANES], count: usize) -> [bool; LANES] {
    let mut run = [false; LANES];
    for i in 0..count {
        run[i] = status[i] == 0;
    }
    run
}

/// The lanes where `may` holds and `run` too, as bits.
#[inline(always)]
fn flags_to_bits(may: &[bool; LANES], run: &[bool; LANES]) -> u64 {
    // Mostly none: one vectorised pass says so.
    let mut any = false;
    for i in 0..LANES {
        any |= may[i] & run[i];
    }
    if !any {
        return 0;
    }
    let mut bits = 0u64;
    for i in 0..LANES {
        bits |= u64::from(may[i] & run[i]) << i;
    }
    bits
}
