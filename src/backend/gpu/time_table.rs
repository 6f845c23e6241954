//! Time terms the ensemble shares, tabulated once per window on the host.
//!
//! When every trajectory has the same `t0`, `dt` and time-op inputs
//! ([`Plan::shares_time`]), the time terms of a stage (spin–orbit's `pref`,
//! damping and Cayley sums; a forcing's `A cos ωt`; …) are the same for the
//! whole ensemble. The host evaluates them with the models' own time ops for
//! every stage of a window's steps and uploads them as the uniform `tterms`
//! (binding 8 of `shaders/driver.wgsl`); the kernel reads a row where it would
//! otherwise call the time ops per trajectory. The CPU twin is
//! `kernels::time::SHARED`.

use crate::models::lanes::Lane;
use crate::models::{op_args, scalar_fn, Flows};
use crate::plan::{Op, Plan};

/// Bytes of the `tterms` uniform: WebGPU's guaranteed uniform binding size.
pub const BYTES: u64 = 65_536;

/// The time terms of a plan whose ensemble shares them.
#[derive(Debug, Clone)]
pub struct TimeTable {
    /// The time terms (what the time ops write), in the table's order.
    pub terms: Vec<&'static str>,
    /// Each stage's time offset `c` (`t = t0 + n dt + c dt`), in step order.
    pub offsets: Vec<f64>,
    /// The model's time ops, which the table replaces in the kernel.
    pub ops: &'static [&'static str],
}

impl TimeTable {
    /// The table of `plan`, if its ensemble shares time terms and its step
    /// calls time ops (methods such as RK4 evaluate them inside).
    pub fn of(plan: &Plan) -> Option<TimeTable> {
        let ops = plan.model.spec().time_ops;
        let calls_time = plan
            .ops
            .iter()
            .any(|o| matches!(o, Op::Call(c) if ops.contains(c)));
        if !calls_time || !plan.shares_time() {
            return None;
        }
        let mut terms: Vec<&'static str> = vec![];
        for op in ops {
            for &(name, written) in op_args(op)? {
                if written && !terms.contains(&name) {
                    terms.push(name);
                }
            }
        }
        let offsets = plan
            .ops
            .iter()
            .filter_map(|o| match o {
                Op::Time(c) => Some(*c),
                _ => None,
            })
            .collect();
        let table = TimeTable {
            terms,
            offsets,
            ops,
        };
        // At least one step must fit in either precision (else per trajectory).
        (table.row_stride() as u64 <= Self::capacity(8)).then_some(table)
    }

    /// `vec4` rows per stage.
    pub fn vec4s(&self) -> usize {
        self.terms.len().div_ceil(4)
    }

    /// `vec4` rows per step.
    pub fn row_stride(&self) -> usize {
        self.offsets.len() * self.vec4s()
    }

    /// Elements of the `tterms` array for values of `b` bytes.
    pub fn capacity(b: u64) -> u64 {
        BYTES / (4 * b)
    }

    /// Most steps one window's table holds, for values of `b` bytes (≥ 1:
    /// [`Self::of`] keeps only tables with room for a step).
    pub fn max_steps(&self, b: u64) -> u64 {
        Self::capacity(b) / self.row_stride() as u64
    }

    /// The table of steps `step0 … step0+nsteps−1`: per step and stage,
    /// the terms in order, padded to whole `vec4`s; time as the kernel
    /// forms it (`t0 + nf·dt + c·dt` in `R`).
    pub fn fill<R: Flows>(&self, plan: &Plan, step0: u64, nsteps: u64) -> Vec<R> {
        let mut lane = Lane::<R>::default();
        for (name, src) in &plan.bindings {
            if let Some(x) = lane.get_mut(name) {
                *x = R::from_f64(src.values()[0]);
            }
        }
        let ops: Vec<_> = self.ops.iter().filter_map(|o| scalar_fn::<R>(o)).collect();
        let width = 4 * self.vec4s();
        let mut out = vec![R::from_f64(0.0); nsteps as usize * self.offsets.len() * width];
        let rows = out.chunks_mut(width);
        let stages = (step0..step0 + nsteps).flat_map(|n| self.offsets.iter().map(move |c| (n, c)));
        for (row, (n, c)) in rows.zip(stages) {
            let nf = R::from_f64(n as f64);
            lane.t = lane.t0 + nf * lane.dt + R::from_f64(*c) * lane.dt;
            for op in &ops {
                op(&mut lane);
            }
            for (slot, term) in row.iter_mut().zip(&self.terms) {
                *slot = lane.get(term).expect("a time term is a lane field");
            }
        }
        out
    }
}
