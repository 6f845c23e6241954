//! Time terms the ensemble shares, tabulated once per window on the host.
//!
//! When every trajectory has the same `t0`, `dt` and time-op inputs
//! ([`Plan::shares_time`]), the time terms of a stage (spin–orbit's `pref`,
//! damping and Cayley sums; a forcing's `A cos ωt`; …) are the same for the
//! whole ensemble. The host evaluates them with the models' own time ops for
//! every stage of a window's steps and uploads them as the uniform `tterms`
//! (binding 8 of `shaders/driver.wgsl`); the kernel reads a row where it would
//! otherwise call the time ops per trajectory. A formula model's shared
//! values are the uniform part of its composed step (`num/formula/stage.rs`),
//! one row set per step, evaluated by the CPU's interpreter. The CPU twins
//! are `kernels::time::SHARED` and `cpu::formula::FormulaStep`.

use crate::models::formula::{names, Composed, STEP_INDEX, UNIFORM_PREFIX};
use crate::models::lanes::{Lane, LANES};
use crate::models::{scalar_fn, Flows};
use crate::num::formula::lower::Lowered;
use crate::num::formula::stage::Staged;
use crate::num::formula::tape::Tape;
use crate::num::isa::Isa;
use crate::plan::tangent::time_terms;
use crate::plan::{Op, Plan};

/// Bytes of the `tterms` uniform: WebGPU's guaranteed uniform binding size.
pub const BYTES: u64 = 65_536;

/// The time terms of a plan whose ensemble shares them.
#[derive(Debug, Clone)]
pub struct TimeTable {
    /// The kernel locals a row set fills, in the table's order.
    pub terms: Vec<String>,
    source: Terms,
}

/// What computes a table's terms.
#[derive(Debug, Clone)]
enum Terms {
    /// A built-in model's time ops (which the table replaces in the
    /// kernel), at each stage's time `t = t0 + n dt + c dt`: one row set
    /// per stage, by its offset `c`, in step order.
    Ops {
        ops: &'static [&'static str],
        offsets: Vec<f64>,
    },
    /// A formula model's values that the ensemble shares at a step: one row
    /// set per step.
    Formula {
        /// The step's values no step changes (those `uniform` reads are
        /// the same in every lane), and the shared ones.
        fixed: Lowered,
        uniform: Lowered,
        /// The lane fields of the composed step's inputs.
        inputs: Vec<&'static str>,
    },
}

impl TimeTable {
    /// The table of a built-in model's `plan`, if its ensemble shares time
    /// terms and its step calls time ops (methods such as RK4 evaluate them
    /// inside).
    pub fn of(plan: &Plan) -> Option<TimeTable> {
        let ops = plan.model.spec().time_ops;
        let calls_time = plan
            .ops
            .iter()
            .any(|o| matches!(o, Op::Call(c) if ops.contains(c)));
        if !calls_time || !plan.shares_time() {
            return None;
        }
        let terms = time_terms(&plan.model)?
            .into_iter()
            .map(String::from)
            .collect();
        let offsets = plan
            .ops
            .iter()
            .filter_map(|o| match o {
                Op::Time(c) => Some(*c),
                _ => None,
            })
            .collect();
        TimeTable {
            terms,
            source: Terms::Ops { ops, offsets },
        }
        .with_room()
    }

    /// The table of a formula model's step `c` split as `s`, if the split
    /// has shared values (`t0` and `dt` not on axes); its terms are the
    /// arguments `tu0…` of `formula_step` (`FormulaModel::step_wgsl`).
    pub fn of_formula(c: &Composed, s: &Staged) -> Option<TimeTable> {
        if s.uniform.outputs.is_empty() {
            return None;
        }
        TimeTable {
            terms: names(UNIFORM_PREFIX, s.uniform.outputs.len()),
            source: Terms::Formula {
                fixed: s.fixed.clone(),
                uniform: s.uniform.clone(),
                inputs: c.inputs.clone(),
            },
        }
        .with_room()
    }

    /// `self` if at least one step fits in either precision (else the kernel
    /// computes the terms per trajectory).
    fn with_room(self) -> Option<TimeTable> {
        (self.row_stride() as u64 <= Self::capacity(8)).then_some(self)
    }

    /// The time ops the table replaces (none for a formula model).
    pub fn ops(&self) -> &'static [&'static str] {
        match &self.source {
            Terms::Ops { ops, .. } => ops,
            Terms::Formula { .. } => &[],
        }
    }

    /// Row sets per step: one per stage of a built-in's step, one for a
    /// formula model's.
    pub fn stages(&self) -> usize {
        match &self.source {
            Terms::Ops { offsets, .. } => offsets.len(),
            Terms::Formula { .. } => 1,
        }
    }

    /// `vec4` rows per stage.
    pub fn vec4s(&self) -> usize {
        self.terms.len().div_ceil(4)
    }

    /// `vec4` rows per step.
    pub fn row_stride(&self) -> usize {
        self.stages() * self.vec4s()
    }

    /// Elements of the `tterms` array for values of `b` bytes.
    pub fn capacity(b: u64) -> u64 {
        BYTES / (4 * b)
    }

    /// Most steps one window's table holds, for values of `b` bytes (≥ 1:
    /// the constructors keep only tables with room for a step).
    pub fn max_steps(&self, b: u64) -> u64 {
        Self::capacity(b) / self.row_stride() as u64
    }

    /// The table of steps `step0 … step0+nsteps−1`: per step and row set,
    /// the terms in order, padded to whole `vec4`s.
    pub fn fill<R: Flows>(&self, plan: &Plan, step0: u64, nsteps: u64) -> Vec<R> {
        let mut lane = Lane::<R>::default();
        for (name, src) in &plan.bindings {
            if let Some(x) = lane.get_mut(name) {
                *x = R::from_f64(src.values()[0]);
            }
        }
        let width = 4 * self.vec4s();
        let mut out = vec![R::from_f64(0.0); nsteps as usize * self.stages() * width];
        let rows = out.chunks_mut(width);
        match &self.source {
            Terms::Ops { ops, offsets } => fill_ops(&self.terms, ops, offsets, lane, rows, step0),
            Terms::Formula {
                fixed,
                uniform,
                inputs,
            } => fill_formula(fixed, uniform, inputs, &lane, rows, step0),
        }
        out
    }
}

/// A built-in's rows: the time ops at each stage's time, as the kernel
/// forms it (`t0 + nf·dt + c·dt` in `R`).
fn fill_ops<'o, R: Flows>(
    terms: &[String],
    ops: &[&str],
    offsets: &[f64],
    mut lane: Lane<R>,
    rows: impl Iterator<Item = &'o mut [R]>,
    step0: u64,
) {
    let ops: Vec<_> = ops.iter().filter_map(|o| scalar_fn::<R>(o)).collect();
    let stages = (step0..).flat_map(|n| offsets.iter().map(move |c| (n, c)));
    for (row, (n, c)) in rows.zip(stages) {
        let nf = R::from_f64(n as f64);
        lane.t = lane.t0 + nf * lane.dt + R::from_f64(*c) * lane.dt;
        for op in &ops {
            op(&mut lane);
        }
        for (slot, term) in row.iter_mut().zip(terms) {
            *slot = lane.get(term).expect("a time term is a lane field");
        }
    }
}

/// A formula model's rows: its fixed part once (the values the uniform
/// part reads are the same in every lane, so lane 0's serve), then the
/// uniform part over [`LANES`] steps at a time (lane `j`: step `n + j`),
/// as the CPU's `FormulaStep` evaluates it.
fn fill_formula<'o, R: Flows>(
    fixed: &Lowered,
    uniform: &Lowered,
    inputs: &[&str],
    lane: &Lane<R>,
    rows: impl Iterator<Item = &'o mut [R]>,
    step0: u64,
) {
    let value = |name: &str| match name {
        STEP_INDEX => R::from_f64(0.0),
        _ => lane.get(name).expect("a formula input is a lane field"),
    };
    let mut args: Vec<[R; LANES]> = inputs.iter().map(|n| [value(n); LANES]).collect();
    let fixed = Tape::<R>::new(fixed, |_| false);
    let mut regs = vec![[R::from_f64(0.0); LANES]; fixed.registers];
    fixed.run(&mut regs, &args[..], Isa::Baseline);
    args.extend((0..fixed.outputs()).map(|k| *fixed.output(&regs, k)));
    let uniform = Tape::<R>::new(uniform, |_| false);
    let mut regs = vec![[R::from_f64(0.0); LANES]; uniform.registers];
    let step = inputs.iter().position(|n| *n == STEP_INDEX);
    let mut rows: Vec<&mut [R]> = rows.collect();
    for (w, window) in rows.chunks_mut(LANES).enumerate() {
        if let Some(k) = step {
            let n0 = step0 + (w * LANES) as u64;
            args[k] = std::array::from_fn(|j| R::from_f64((n0 + j as u64) as f64));
        }
        uniform.run(&mut regs, &args[..], Isa::Baseline);
        for (j, row) in window.iter_mut().enumerate() {
            for (k, slot) in row.iter_mut().take(uniform.outputs()).enumerate() {
                *slot = uniform.output(&regs, k)[j];
            }
        }
    }
}
