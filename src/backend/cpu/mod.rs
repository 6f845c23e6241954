//! The CPU backend: rayon over blocks of [`LANES`] trajectories in
//! structure-of-arrays form; each op of the plan is one loop over the lanes,
//! which the compiler vectorises. Every block is independent, so results are
//! bitwise identical for any number of threads.

// Lane loops index several arrays by lane; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

pub mod kernels;

use crate::models::lanes::{index_of, LaneFn, Lanes, LANES};
use crate::models::{lane_fn, Flows};
use crate::plan::observations::Observations;
use crate::plan::observers::{Direction, Section};
use crate::plan::{ObsVar, Op, Plan, Source};
pub use kernels::{isa, Isa};
use kernels::{StageBuilder, StageFn};

/// A plan resolved for the CPU: ops as lane loops, names as lane indices.
struct Compiled<'p, R> {
    plan: &'p Plan,
    ops: Vec<CpuOp<R>>,
    /// The step as fused S2 stages `(kernel, w/2, w, time offset)`, when the
    /// plan is a splitting (preferred over `ops`).
    stages: Option<Vec<FusedStage<R>>>,
    field: Vec<LaneFn<R>>,
    needs_field: bool,
    /// Lane index of each integrated variable and of its derivative.
    var: Vec<usize>,
    dvar: Vec<usize>,
    bindings: Vec<(usize, &'p Source)>,
}

enum CpuOp<R> {
    Tau(R),
    Time(R),
    Call(LaneFn<R>),
}

/// A fused S2 stage with its `w/2`, `w` and time offset.
type FusedStage<R> = (StageFn<R>, R, R, R);

/// Raw view of an output array that blocks fill in disjoint rows.
struct Rows<T> {
    ptr: *mut T,
    len: usize,
}
unsafe impl<T: Send> Sync for Rows<T> {}
unsafe impl<T: Send> Send for Rows<T> {}

impl<T> Rows<T> {
    fn new(v: &mut [T]) -> Self {
        Rows {
            ptr: v.as_mut_ptr(),
            len: v.len(),
        }
    }
    /// SAFETY: callers write each index from one block only (rows of distinct
    /// trajectories), and the vector outlives the run.
    #[inline]
    fn set(&self, i: usize, v: T) {
        assert!(i < self.len);
        unsafe { *self.ptr.add(i) = v }
    }
}

/// Every output array as disjoint-row views.
struct Sink<R> {
    final_values: Vec<Rows<R>>,
    trajectory: Vec<Rows<R>>,
    poincare: Vec<Rows<R>>,
    poincare_count: Rows<u32>,
    cycle_amplitude: Rows<R>,
    cycle_period: Rows<R>,
    nonfinite_step: Rows<u32>,
}

/// Integrates `plan` on the CPU in precision `R`. `progress`, if given, is
/// advanced by trajectory-steps as blocks go.
pub fn run<R: Flows>(plan: &Plan, progress: Option<&AtomicU64>) -> Observations<R> {
    run_isa(plan, progress, isa())
}

/// [`run`] with the fused kernels of a given instruction-set level (which
/// must not exceed the CPU's, see [`isa`]).
pub fn run_isa<R: Flows>(plan: &Plan, progress: Option<&AtomicU64>, isa: Isa) -> Observations<R> {
    assert!(
        isa_rank(isa) <= isa_rank(self::isa()),
        "the CPU lacks {isa:?}"
    );
    let mut out = Observations::<R>::for_plan(plan);
    let c = compile::<R>(plan, isa);
    {
        let sink = Sink {
            final_values: out
                .final_values
                .iter_mut()
                .map(|(_, v)| Rows::new(v))
                .collect(),
            trajectory: out
                .trajectory
                .iter_mut()
                .map(|(_, v)| Rows::new(v))
                .collect(),
            poincare: out.poincare.iter_mut().map(|(_, v)| Rows::new(v)).collect(),
            poincare_count: Rows::new(&mut out.poincare_count),
            cycle_amplitude: Rows::new(&mut out.cycle_amplitude),
            cycle_period: Rows::new(&mut out.cycle_period),
            nonfinite_step: Rows::new(&mut out.nonfinite_step),
        };
        let blocks = plan.n.div_ceil(LANES);
        (0..blocks)
            .into_par_iter()
            .for_each_init(Lanes::<R>::boxed, |lanes, b| {
                run_block(&c, b, lanes, &sink, progress);
            });
    }
    out
}

fn isa_rank(i: Isa) -> u8 {
    match i {
        Isa::Baseline => 0,
        Isa::V3 => 1,
        Isa::V4 => 2,
    }
}

fn compile<R: Flows>(plan: &Plan, isa: Isa) -> Compiled<'_, R> {
    let call =
        |name: &str| lane_fn::<R>(name).unwrap_or_else(|| panic!("plan names unknown op {name}"));
    let ops = plan
        .ops
        .iter()
        .map(|op| match *op {
            Op::Tau(c) => CpuOp::Tau(R::from_f64(c)),
            Op::Time(c) => CpuOp::Time(R::from_f64(c)),
            Op::Call(name) => CpuOp::Call(call(name)),
        })
        .collect();
    let idx = |name: &str| index_of(name).unwrap_or_else(|| panic!("{name} is not a lane field"));
    let stages = plan.stages.as_ref().and_then(|st| {
        let f = plan.model.with_pieces::<R, _>(StageBuilder {
            order: st.order,
            opt: st.with_optional,
            time: plan.time,
            isa,
        })?;
        Some(
            st.stages
                .iter()
                .map(|(w, c)| (f, R::from_f64(0.5 * w), R::from_f64(*w), R::from_f64(*c)))
                .collect(),
        )
    });
    Compiled {
        plan,
        ops,
        stages,
        field: plan.field_ops.iter().map(|f| call(f)).collect(),
        needs_field: plan.needs_field(),
        var: plan.vars.iter().map(|v| idx(v)).collect(),
        dvar: plan.vars.iter().map(|v| idx(&format!("d{v}"))).collect(),
        bindings: plan.bindings.iter().map(|(n, s)| (idx(n), s)).collect(),
    }
}

/// Per-lane observer state of one block (the GPU kernel keeps the same state
/// per trajectory, see `backend/gpu/codegen.rs`).
struct BlockObservers<R> {
    /// Stroboscopic section sampled exactly: `(every, first)` steps per lane.
    strobe_exact: Option<([u64; LANES], [u64; LANES])>,
    strobe_next: [u64; LANES],
    points: [u32; LANES],
    cycle_max: [R; LANES],
    cycle_min: [R; LANES],
    cycle_count: [u32; LANES],
    /// Time of the first crossing, and the running mean and co-moment of
    /// (crossing index, crossing time − first) for the least-squares period.
    cycle_first: [R; LANES],
    cycle_mean_t: [R; LANES],
    cycle_comoment: [R; LANES],
}

fn run_block<R: Flows>(
    c: &Compiled<R>,
    block: usize,
    l: &mut Lanes<R>,
    sink: &Sink<R>,
    progress: Option<&AtomicU64>,
) {
    let plan = c.plan;
    let base = block * LANES;
    let count = LANES.min(plan.n - base);
    // Padding lanes repeat the block's last trajectory; their results are dropped.
    for &(k, src) in &c.bindings {
        let a = l.at_mut(k);
        for (i, x) in a.iter_mut().enumerate() {
            *x = R::from_f64(src.value_at(base + i.min(count - 1), &plan.strides));
        }
    }
    let nv = c.var.len();
    let mut status = [0u64; LANES];
    let mut alive = count;
    let mut obs = BlockObservers::<R> {
        strobe_exact: None,
        strobe_next: [0; LANES],
        points: [0; LANES],
        cycle_max: [-R::inf(); LANES],
        cycle_min: [R::inf(); LANES],
        cycle_count: [0; LANES],
        cycle_first: [R::nan(); LANES],
        cycle_mean_t: [R::default(); LANES],
        cycle_comoment: [R::default(); LANES],
    };
    if plan.observers.stroboscopic() && !plan.strobe_interpolated() {
        // Every step divides the period: sample by step count, in R as the GPU does.
        let (mut every, mut first) = ([1u64; LANES], [0u64; LANES]);
        let half = R::from_f64(0.5);
        for i in 0..LANES {
            every[i] = (l.strobe_period[i] / l.dt[i] + half).floor().to_f64() as u64;
            first[i] = (l.strobe_phase[i] / l.dt[i] + half).floor().to_f64() as u64;
        }
        obs.strobe_exact = Some((every, first));
    }
    // State (and slopes) at the start of the current step, for interpolation.
    let mut prev = vec![[R::default(); LANES]; nv];
    let mut dprev = vec![[R::default(); LANES]; nv];
    if c.needs_field {
        eval_field(c, l, 0);
    }
    observe(c, l, &mut obs, sink, base, count, &status, 0, &prev, &dprev);

    let mut reported = 0u64;
    let cycle_start = plan
        .observers
        .cycle
        .as_ref()
        .map_or(u64::MAX, |cy| (cy.skip * plan.steps as f64).floor() as u64);
    for n in 0..plan.steps {
        if c.needs_field || plan.cycle_var.is_some() {
            for k in 0..nv {
                prev[k] = *l.at(c.var[k]);
                dprev[k] = *l.at(c.dvar[k]);
            }
        }
        let nf = R::from_f64(n as f64);
        // Fused stages report non-finite lanes themselves (the last stage's
        // answer is the step's); the op interpreter needs a separate pass.
        let mut any = false;
        if let Some(stages) = &c.stages {
            for (f, half, full, tc) in stages {
                // SAFETY: `isa()` chose wide kernels only where the CPU has the features.
                any = unsafe { f(l, *half, *full, *tc, nf) };
            }
        }
        for op in c.ops.iter().filter(|_| c.stages.is_none()) {
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
                CpuOp::Call(f) => f(l),
            }
        }
        // Status: the first step at which any variable is non-finite.
        // One vectorised pass per variable with an OR-reduction; lanes are
        // examined one by one only in the rare step where one went bad.
        let mut bad = [false; LANES];
        if c.stages.is_none() {
            for &k in &c.var {
                let x = l.at(k);
                for i in 0..LANES {
                    let b = !x[i].finite();
                    bad[i] |= b;
                    any |= b;
                }
            }
        } else if any {
            for &k in &c.var {
                let x = l.at(k);
                for i in 0..LANES {
                    bad[i] |= !x[i].finite();
                }
            }
        }
        if any {
            for i in 0..count {
                if bad[i] && status[i] == 0 {
                    status[i] = n + 1;
                    alive -= 1;
                }
            }
        }
        if c.needs_field {
            eval_field(c, l, n + 1);
        }
        observe(
            c,
            l,
            &mut obs,
            sink,
            base,
            count,
            &status,
            n + 1,
            &prev,
            &dprev,
        );
        if n + 1 >= cycle_start {
            cycle_update(c, l, &mut obs, count, &status, n, &prev, &dprev);
        }
        if (n + 1) % 1024 == 0 {
            if let Some(p) = progress {
                p.fetch_add(count as u64 * (n + 1 - reported), Ordering::Relaxed);
                reported = n + 1;
            }
        }
        if alive == 0 {
            break;
        }
    }
    if let Some(p) = progress {
        p.fetch_add(count as u64 * (plan.steps - reported), Ordering::Relaxed);
    }

    // Final values, cycle statistics and status.
    let t_end = |i: usize| l.t0[i] + R::from_f64(plan.steps as f64) * l.dt[i];
    for (j, v) in plan.final_vars.iter().enumerate() {
        for i in 0..count {
            let x = if status[i] != 0 {
                R::nan()
            } else {
                match v {
                    ObsVar::State(k) => l.at(c.var[*k])[i],
                    ObsVar::Time => t_end(i),
                }
            };
            sink.final_values[j].set(base + i, x);
        }
    }
    if plan.cycle_var.is_some() {
        for i in 0..count {
            let ok = status[i] == 0;
            let amp = if ok {
                R::from_f64(0.5) * (obs.cycle_max[i] - obs.cycle_min[i])
            } else {
                R::nan()
            };
            let per = if ok && obs.cycle_count[i] >= 2 {
                R::cycle_period(
                    obs.cycle_comoment[i],
                    R::from_f64(obs.cycle_count[i] as f64),
                )
            } else {
                R::nan()
            };
            sink.cycle_amplitude.set(base + i, amp);
            sink.cycle_period.set(base + i, per);
        }
    }
    if plan.observers.poincare.is_some() {
        for i in 0..count {
            sink.poincare_count.set(base + i, obs.points[i]);
        }
    }
    for (i, s) in status.iter().enumerate().take(count) {
        // Plans have fewer than 2³² steps.
        sink.nonfinite_step.set(base + i, *s as u32);
    }
}

/// Vector field at the end of step `n` (time `t0 + n dt`) into the `d<var>` lanes.
fn eval_field<R: Flows>(c: &Compiled<R>, l: &mut Lanes<R>, n: u64) {
    let nf = R::from_f64(n as f64);
    for i in 0..LANES {
        l.t[i] = l.t0[i] + nf * l.dt[i];
    }
    for f in &c.field {
        f(l);
    }
}

/// Value of an observed variable at θ inside step `n → n+1` (θ = 1: the end).
#[inline]
#[allow(clippy::too_many_arguments)]
fn value_at<R: Flows>(
    c: &Compiled<R>,
    l: &Lanes<R>,
    v: ObsVar,
    i: usize,
    n1: u64,
    th: R,
    prev: &[[R; LANES]],
    dprev: &[[R; LANES]],
) -> R {
    let one = R::from_f64(1.0);
    let t1 = l.t0[i] + R::from_f64(n1 as f64) * l.dt[i];
    match v {
        ObsVar::Time => t1 - (one - th) * l.dt[i],
        ObsVar::State(k) => {
            if th == one {
                l.at(c.var[k])[i]
            } else {
                R::hermite(
                    prev[k][i],
                    l.at(c.var[k])[i],
                    dprev[k][i],
                    l.at(c.dvar[k])[i],
                    l.dt[i],
                    th,
                )
            }
        }
    }
}

/// Trajectory frames and Poincaré points after step `n1` (0: the initial state).
#[allow(clippy::too_many_arguments)]
fn observe<R: Flows>(
    c: &Compiled<R>,
    l: &Lanes<R>,
    obs: &mut BlockObservers<R>,
    sink: &Sink<R>,
    base: usize,
    count: usize,
    status: &[u64; LANES],
    n1: u64,
    prev: &[[R; LANES]],
    dprev: &[[R; LANES]],
) {
    let plan = c.plan;
    let one = R::from_f64(1.0);
    if let Some(tr) = &plan.observers.trajectory {
        if n1.is_multiple_of(tr.every) {
            let frame = (n1 / tr.every) as usize;
            let frames = (plan.steps / tr.every) as usize + 1;
            for (j, v) in plan.trajectory_vars.iter().enumerate() {
                for i in 0..count {
                    let x = if status[i] != 0 {
                        R::nan()
                    } else {
                        value_at(c, l, *v, i, n1, one, prev, dprev)
                    };
                    sink.trajectory[j].set((base + i) * frames + frame, x);
                }
            }
        }
    }
    let Some(pc) = &plan.observers.poincare else {
        return;
    };
    let record = |obs: &mut BlockObservers<R>, i: usize, th: R, crossing: Option<(usize, R)>| {
        let k = obs.points[i] as usize;
        if k < pc.max_points {
            for (j, v) in plan.poincare_vars.iter().enumerate() {
                let x = match (crossing, v) {
                    // The crossing variable sits on the section by definition.
                    (Some((cv, level)), ObsVar::State(s)) if *s == cv => level,
                    _ => value_at(c, l, *v, i, n1, th, prev, dprev),
                };
                sink.poincare[j].set((base + i) * pc.max_points + k, x);
            }
        }
        obs.points[i] = obs.points[i].saturating_add(1);
    };
    match &pc.section {
        Section::Stroboscopic { .. } | Section::Forced { .. } => {
            let (n1r, tol) = (R::from_f64(n1 as f64), R::from_f64(1e-4));
            for i in 0..count {
                if status[i] != 0 {
                    continue;
                }
                if let Some((every, first)) = &obs.strobe_exact {
                    if n1 >= first[i] && (n1 - first[i]).is_multiple_of(every[i]) {
                        record(obs, i, one, None);
                    }
                    continue;
                }
                // Every sample time in (t_{n1−1}, t_{n1}] (t_0 itself at step 0).
                loop {
                    let x = R::strobe_position(
                        R::from_f64(obs.strobe_next[i] as f64),
                        l.strobe_period[i],
                        l.strobe_phase[i],
                        l.dt[i],
                    );
                    if x > n1r + tol {
                        break;
                    }
                    let th = if n1 == 0 { one } else { clamp01(x - n1r + one) };
                    record(obs, i, th, None);
                    obs.strobe_next[i] += 1;
                }
            }
        }
        Section::Crossing {
            value, direction, ..
        } => {
            if n1 == 0 {
                return;
            }
            let cv = plan.crossing_var.expect("planned");
            let level = R::from_f64(*value);
            for i in 0..count {
                if status[i] != 0 {
                    continue;
                }
                let y0 = prev[cv][i] - level;
                let y1 = l.at(c.var[cv])[i] - level;
                let zero = R::default();
                let up = y0 < zero && y1 >= zero;
                let down = y0 > zero && y1 <= zero;
                let hit = match direction {
                    Direction::Up => up,
                    Direction::Down => down,
                    Direction::Both => up || down,
                };
                if hit {
                    let th = R::crossing_theta(y0, y1, dprev[cv][i], l.at(c.dvar[cv])[i], l.dt[i]);
                    record(obs, i, th, Some((cv, level)));
                }
            }
        }
    }
}

/// `x` clamped to [0, 1] (WGSL's `clamp(x, 0.0, 1.0)`).
#[inline]
fn clamp01<R: Flows>(x: R) -> R {
    let (zero, one) = (R::default(), R::from_f64(1.0));
    if x < zero {
        zero
    } else if x > one {
        one
    } else {
        x
    }
}

/// Cycle statistics over step `n → n+1` (inside the measuring window).
#[allow(clippy::too_many_arguments)]
fn cycle_update<R: Flows>(
    c: &Compiled<R>,
    l: &Lanes<R>,
    obs: &mut BlockObservers<R>,
    count: usize,
    status: &[u64; LANES],
    n: u64,
    prev: &[[R; LANES]],
    dprev: &[[R; LANES]],
) {
    let Some(k) = c.plan.cycle_var else { return };
    let level = R::from_f64(c.plan.observers.cycle.as_ref().map_or(0.0, |cy| cy.level));
    let zero = R::default();
    for i in 0..count {
        if status[i] != 0 {
            continue;
        }
        let x = l.at(c.var[k])[i];
        if x > obs.cycle_max[i] {
            obs.cycle_max[i] = x;
        }
        if x < obs.cycle_min[i] {
            obs.cycle_min[i] = x;
        }
        let y0 = prev[k][i] - level;
        let y1 = x - level;
        if y0 < zero && y1 >= zero {
            let th = R::crossing_theta(y0, y1, dprev[k][i], l.at(c.dvar[k])[i], l.dt[i]);
            let tc = l.t0[i] + R::from_f64(n as f64) * l.dt[i] + th * l.dt[i];
            if obs.cycle_count[i] == 0 {
                obs.cycle_first[i] = tc;
            }
            R::cycle_crossing(
                R::from_f64(obs.cycle_count[i] as f64),
                tc - obs.cycle_first[i],
                &mut obs.cycle_mean_t[i],
                &mut obs.cycle_comoment[i],
            );
            obs.cycle_count[i] += 1;
        }
    }
}
