//! A plan resolved for the CPU: ops as lane loops (or fused S2 stages),
//! names as lane indices.

use crate::models::lanes::{index_of, LaneFn, Lanes, ScalarFn, LANES};
use crate::models::{lane_fn, scalar_fn, Flows};
use crate::num::precision::Real;
use crate::plan::section::SectionStep;
use crate::plan::{Op, Plan, Source};

use super::formula::{Condition, FormulaCall, FormulaStep};
use super::indicators::IndicatorTapes;
use super::kernels::{time_mode, weights, Isa, StageBuilder, StepsFn, Weights};
use super::tangent::CompiledTangent;

/// The plan's step, field and inputs for the CPU.
pub struct Program<'p, R> {
    pub plan: &'p Plan,
    pub ops: Vec<CpuOp<R>>,
    /// The step as fused S2 stages, when the plan is a splitting (preferred
    /// over `ops`).
    pub stages: Option<FusedSteps<R>>,
    /// Whether `stages` evaluate time terms the ensemble shares (or, for a
    /// plan without time, its one `dt`) once per block ([`Plan::shares_time`]).
    pub shared_time: bool,
    /// A formula model's step composed into one program (preferred over
    /// `ops`).
    pub formula_step: Option<FormulaStep<R>>,
    pub field: Vec<CpuOp<R>>,
    /// The field's ops on one trajectory, where the model has them (not a
    /// formula model's): the observers' slopes at a lane that crosses.
    pub field_lane: Option<Vec<ScalarFn<R>>>,
    /// The stop condition.
    pub stop: Option<Condition<R>>,
    /// The chaos indicators' tangent step and samples.
    pub indicators: Option<IndicatorTapes<R>>,
    pub isa: Isa,
    /// Lane index of `dt`.
    pub dt_lane: usize,
    /// Registers (lane arrays) the block interpreter of formula ops needs.
    pub registers: usize,
    pub needs_field: bool,
    /// Does an observer look at every step (`Plan::observes_every_step`)?
    pub observes_every_step: bool,
    /// Whether recorded runs are allowed ([`Program::records`]; off only
    /// for the reference they are tested against).
    pub record: bool,
    /// The plan's Poincaré section (`Plan::section`).
    pub section: Option<SectionStep>,
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
    /// An op of a formula model, run by the block interpreter.
    Formula(FormulaCall<R>),
}

impl<R: Real> CpuOp<R> {
    /// Applies the op to a block (`Tau` and `Time` are the step's business).
    pub fn call(&self, l: &mut Lanes<R>, regs: &mut [[R; LANES]]) {
        match self {
            CpuOp::Call(f) => f(l),
            CpuOp::Formula(f) => f.run(l, regs),
            CpuOp::Tau(_) | CpuOp::Time(_) => {}
        }
    }
}

fn lane(name: &str) -> usize {
    index_of(name).unwrap_or_else(|| panic!("{name} is not a lane field"))
}

/// The plan's step as fused S2 stages: the kernel that takes runs of steps,
/// and each stage's weights.
pub struct FusedSteps<R> {
    pub kernel: StepsFn<R>,
    pub weights: Vec<Weights<R>>,
    /// Whether the kernel evaluates the model's time ops (the plan has time).
    pub time_terms: bool,
}

impl<'p, R: Flows> Program<'p, R> {
    /// Resolves `plan`, with fused kernels of instruction-set level `isa`;
    /// `share_time`: time terms once per block where the ensemble shares them.
    pub fn new(plan: &'p Plan, isa: Isa, share_time: bool) -> Self {
        // Formula models' ops first: their names are the same for every
        // formula model, their programs are the model's.
        let call = |name: &str| match plan.model.formula() {
            Some(m) => CpuOp::Formula(
                FormulaCall::new(m, name, isa)
                    .unwrap_or_else(|| panic!("plan names unknown formula op {name}")),
            ),
            None => CpuOp::Call(
                lane_fn::<R>(name).unwrap_or_else(|| panic!("plan names unknown op {name}")),
            ),
        };
        let field: Vec<CpuOp<R>> = plan.field_ops.iter().map(|f| call(f)).collect();
        let ops: Vec<CpuOp<R>> = plan
            .ops
            .iter()
            .map(|op| match *op {
                Op::Tau(c) => CpuOp::Tau(R::from_f64(c)),
                Op::Time(c) => CpuOp::Time(R::from_f64(c)),
                Op::Call(name) => call(name),
            })
            .collect();
        let registers = ops
            .iter()
            .chain(&field)
            .map(|o| match o {
                CpuOp::Formula(f) => f.tape.registers,
                _ => 0,
            })
            .max()
            .unwrap_or(0);
        let first = crate::plan::slots::indicator_first(plan);
        let slot = |name: &str| {
            let ind = plan.indicators.as_ref()?;
            ind.slot_of(name).map(|k| first + k)
        };
        let stop = plan.stop.as_ref().map(|s| Condition::new(s, isa, slot));
        let shared_time = share_time && plan.stages.is_some() && plan.shares_time();
        let indicators = plan
            .indicators
            .as_ref()
            .map(|i| IndicatorTapes::new(plan, i, compiled_tangent(plan, isa, shared_time), isa));
        let registers = registers
            .max(stop.as_ref().map_or(0, |s| s.registers()))
            .max(indicators.as_ref().map_or(0, |i| i.registers()));
        let idx = lane;
        Program {
            plan,
            ops,
            stages: fused_stages(plan, isa, shared_time),
            shared_time,
            formula_step: plan
                .model
                .formula()
                .and_then(|m| FormulaStep::new(plan, m, isa)),
            field,
            field_lane: match plan.model.formula() {
                Some(_) => None,
                None => plan.field_ops.iter().map(|f| scalar_fn::<R>(f)).collect(),
            },
            stop,
            indicators,
            isa,
            dt_lane: lane("dt"),
            registers,
            needs_field: plan.needs_field(),
            observes_every_step: plan.observes_every_step(),
            record: true,
            section: plan.section(),
            var: plan.vars.iter().map(|v| idx(v)).collect(),
            dvar: plan.vars.iter().map(|v| idx(&format!("d{v}"))).collect(),
            bindings: plan.bindings.iter().map(|(n, s)| (idx(n), s)).collect(),
        }
    }
}

impl<R: Flows> Program<'_, R> {
    /// The vector field at the end of step `n` (time `t0 + n dt`) into the
    /// `d<var>` lanes of `l`.
    pub fn eval_field(&self, l: &mut Lanes<R>, regs: &mut [[R; LANES]], n: u64) {
        let nf = R::from_f64(n as f64);
        for i in 0..LANES {
            l.t[i] = l.t0[i] + nf * l.dt[i];
        }
        for f in &self.field {
            f.call(l, regs);
        }
    }
}

impl<R> Program<'_, R> {
    /// Whether the block's observers read recorded runs of fused steps
    /// (`cpu::Walk::recorded_runs`): some observer looks at every step, and
    /// no chaos indicator, whose tangent steps with the state.
    pub fn records(&self) -> bool {
        self.record
            && self.stages.is_some()
            && self.indicators.is_none()
            && self.observes_every_step
    }
}

/// The plan's splitting step as fused stages, if the model has a kernel for
/// its piece order.
/// `shared`: whether the ensemble shares the time terms.
fn fused_stages<R: Flows>(plan: &Plan, isa: Isa, shared: bool) -> Option<FusedSteps<R>> {
    let st = plan.stages.as_ref()?;
    let kernel = StageBuilder {
        order: st.order,
        opt: st.with_optional,
        time: time_mode(plan, shared),
        isa,
    }
    .build::<R>(&plan.model)?;
    Some(FusedSteps {
        kernel,
        weights: weights(plan)?,
        time_terms: plan.time,
    })
}

/// The plan's tangent step compiled, where its model and indicators have
/// one (else the indicators run the tape).
fn compiled_tangent<R: Flows>(plan: &Plan, isa: Isa, shared: bool) -> Option<CompiledTangent<R>> {
    let ind = plan.indicators.as_ref()?;
    CompiledTangent::new(plan, &ind.tangent.space, ind.tangent.vectors, isa, shared)
}
