//! A plan resolved for the CPU: ops as lane loops (or fused S2 stages),
//! names as lane indices.

use crate::models::lanes::{index_of, LaneFn};
use crate::models::{lane_fn, Flows};
use crate::plan::{Op, Plan, Source};

use super::kernels::{Isa, StageBuilder, StageFn};

/// The plan's step, field and inputs for the CPU.
pub struct Program<'p, R> {
    pub plan: &'p Plan,
    pub ops: Vec<CpuOp<R>>,
    /// The step as fused S2 stages `(kernel, w/2, w, time offset)`, when the
    /// plan is a splitting (preferred over `ops`).
    pub stages: Option<Vec<FusedStage<R>>>,
    pub field: Vec<LaneFn<R>>,
    pub needs_field: bool,
    /// Lane index of each integrated variable and of its derivative.
    pub var: Vec<usize>,
    pub dvar: Vec<usize>,
    pub bindings: Vec<(usize, &'p Source)>,
}

/// One instruction of the op interpreter.
pub enum CpuOp<R> {
    Tau(R),
    Time(R),
    Call(LaneFn<R>),
}

/// A fused S2 stage with its `w/2`, `w` and time offset.
pub type FusedStage<R> = (StageFn<R>, R, R, R);

impl<'p, R: Flows> Program<'p, R> {
    /// Resolves `plan`, with fused kernels of instruction-set level `isa`.
    pub fn new(plan: &'p Plan, isa: Isa) -> Self {
        let call = |name: &str| {
            lane_fn::<R>(name).unwrap_or_else(|| panic!("plan names unknown op {name}"))
        };
        let ops = plan
            .ops
            .iter()
            .map(|op| match *op {
                Op::Tau(c) => CpuOp::Tau(R::from_f64(c)),
                Op::Time(c) => CpuOp::Time(R::from_f64(c)),
                Op::Call(name) => CpuOp::Call(call(name)),
            })
            .collect();
        let idx =
            |name: &str| index_of(name).unwrap_or_else(|| panic!("{name} is not a lane field"));
        Program {
            plan,
            ops,
            stages: fused_stages(plan, isa),
            field: plan.field_ops.iter().map(|f| call(f)).collect(),
            needs_field: plan.needs_field(),
            var: plan.vars.iter().map(|v| idx(v)).collect(),
            dvar: plan.vars.iter().map(|v| idx(&format!("d{v}"))).collect(),
            bindings: plan.bindings.iter().map(|(n, s)| (idx(n), s)).collect(),
        }
    }
}

/// The plan's splitting step as fused stages, if the model has a kernel for
/// its piece order.
fn fused_stages<R: Flows>(plan: &Plan, isa: Isa) -> Option<Vec<FusedStage<R>>> {
    let st = plan.stages.as_ref()?;
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
}
