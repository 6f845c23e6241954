//! The CPU backend: rayon over blocks of [`LANES`] trajectories in
//! structure-of-arrays form; a step is the plan's fused S2 stages
//! ([`kernels`]) or its ops, each one loop over the lanes, which the compiler
//! vectorises. Every block is independent, so results are bitwise identical
//! for any number of threads.

// Lane loops index several arrays by lane; iterators would hide that.
#![allow(clippy::needless_range_loop)]

pub mod formula;
pub mod kernels;
pub mod observe;
pub mod program;
pub mod sink;

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use crate::models::lanes::{Lanes, LANES};
use crate::models::Flows;
use crate::plan::observations::Observations;
use crate::plan::Plan;
use formula::StepMemory;
pub use kernels::{isa, Isa};
use observe::{BlockObservers, BlockStep};
use program::{CpuOp, Program};
use sink::Sink;

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
    let program = Program::<R>::new(plan, isa);
    let sink = Sink::new(&mut out);
    (0..plan.n.div_ceil(LANES))
        .into_par_iter()
        .for_each_init(Lanes::<R>::boxed, |lanes, b| {
            run_block(&program, b, lanes, &sink, progress);
        });
    drop(sink);
    out
}

fn isa_rank(i: Isa) -> u8 {
    match i {
        Isa::Baseline => 0,
        Isa::V3 => 1,
        Isa::V4 => 2,
    }
}

/// Integrates block `block` (trajectories `block·LANES …`) and stores its rows.
fn run_block<R: Flows>(
    p: &Program<R>,
    block: usize,
    l: &mut Lanes<R>,
    sink: &Sink<R>,
    progress: Option<&AtomicU64>,
) {
    let plan = p.plan;
    let base = block * LANES;
    let count = LANES.min(plan.n - base);
    load_inputs(p, l, base, count);
    let nv = p.var.len();
    let mut status = [0u64; LANES];
    let mut alive = count;
    let mut obs = BlockObservers::new(p, l);
    // Registers of the formula interpreter, one set per block.
    let mut regs = vec![[R::default(); LANES]; p.registers];
    let mut memory = p.formula_step.as_ref().map(|f| {
        let mut m = f.memory();
        f.begin(l, &mut m);
        m
    });
    // State (and slopes) at the start of the current step, for interpolation.
    let mut prev = vec![[R::default(); LANES]; nv];
    let mut dprev = vec![[R::default(); LANES]; nv];
    if p.needs_field {
        eval_field(p, l, &mut regs, 0);
    }
    // The observers' view of the block after step n1.
    macro_rules! after {
        ($n1:expr) => {
            BlockStep {
                p,
                l: &*l,
                sink,
                base,
                count,
                prev: &prev,
                dprev: &dprev,
                status: &status,
                n1: $n1,
            }
        };
    }
    obs.observe(&after!(0));

    let mut reported = 0u64;
    for n in 0..plan.steps {
        if p.needs_field || plan.cycle_var.is_some() {
            for k in 0..nv {
                prev[k] = *l.at(p.var[k]);
                dprev[k] = *l.at(p.dvar[k]);
            }
        }
        let any = step(p, l, &mut regs, memory.as_mut(), n);
        if any {
            alive -= mark_nonfinite(p, l, &mut status, count, n);
        }
        if p.needs_field {
            eval_field(p, l, &mut regs, n + 1);
        }
        let view = after!(n + 1);
        obs.observe(&view);
        obs.cycle(&view);
        if (n + 1) % 1024 == 0 {
            if let Some(pr) = progress {
                pr.fetch_add(count as u64 * (n + 1 - reported), Ordering::Relaxed);
                reported = n + 1;
            }
        }
        if alive == 0 {
            break;
        }
    }
    if let Some(pr) = progress {
        pr.fetch_add(count as u64 * (plan.steps - reported), Ordering::Relaxed);
    }
    obs.finish(p, l, sink, base, count, &status);
}

/// Loads the block's inputs (parameters, initial state, dt, t0, …); padding
/// lanes repeat the block's last trajectory and their results are dropped.
fn load_inputs<R: Flows>(p: &Program<R>, l: &mut Lanes<R>, base: usize, count: usize) {
    for &(k, src) in &p.bindings {
        let a = l.at_mut(k);
        for (i, x) in a.iter_mut().enumerate() {
            *x = R::from_f64(src.value_at(p.plan.first + base + i.min(count - 1), &p.plan.strides));
        }
    }
}

/// Step `n` on every lane; returns whether some state variable may have
/// become non-finite (then [`mark_nonfinite`] looks lane by lane).
fn step<R: Flows>(
    p: &Program<R>,
    l: &mut Lanes<R>,
    regs: &mut [[R; LANES]],
    memory: Option<&mut StepMemory<R>>,
    n: u64,
) -> bool {
    let nf = R::from_f64(n as f64);
    // Fused stages report non-finite lanes themselves (the last stage's
    // answer is the step's); the op interpreter needs a separate pass.
    if let Some(stages) = &p.stages {
        let mut any = false;
        for (f, half, full, tc) in stages {
            // SAFETY: `isa()` chose wide kernels only where the CPU has the features.
            any = unsafe { f(l, *half, *full, *tc, nf) };
        }
        return any;
    }
    if let (Some(f), Some(m)) = (&p.formula_step, memory) {
        // A variable no op assigns keeps its initial value: checked once.
        return f.step(l, m, n) || (n == 0 && any_nonfinite(p, l));
    }
    run_ops(p, l, regs, nf);
    any_nonfinite(p, l)
}

/// Whether some state variable is non-finite in some lane.
fn any_nonfinite<R: Flows>(p: &Program<R>, l: &Lanes<R>) -> bool {
    // One vectorised pass per variable with an OR-reduction.
    let mut any = false;
    for &k in &p.var {
        let x = l.at(k);
        for i in 0..LANES {
            any |= !x[i].finite();
        }
    }
    any
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

/// Marks the lanes whose state went non-finite at step `n` (first time
/// only); returns how many stopped.
fn mark_nonfinite<R: Flows>(
    p: &Program<R>,
    l: &Lanes<R>,
    status: &mut [u64; LANES],
    count: usize,
    n: u64,
) -> usize {
    let mut bad = [false; LANES];
    for &k in &p.var {
        let x = l.at(k);
        for i in 0..LANES {
            bad[i] |= !x[i].finite();
        }
    }
    let mut stopped = 0;
    for i in 0..count {
        if bad[i] && status[i] == 0 {
            status[i] = n + 1;
            stopped += 1;
        }
    }
    stopped
}

/// Vector field at the end of step `n` (time `t0 + n dt`) into the `d<var>` lanes.
fn eval_field<R: Flows>(p: &Program<R>, l: &mut Lanes<R>, regs: &mut [[R; LANES]], n: u64) {
    let nf = R::from_f64(n as f64);
    for i in 0..LANES {
        l.t[i] = l.t0[i] + nf * l.dt[i];
    }
    for f in &p.field {
        f.call(l, regs);
    }
}
