//! Formula models on the CPU: an op (the vector field) through the block
//! interpreter, and the whole step as one composed program
//! (`FormulaModel::compose`) split by what its values vary with
//! (`num/formula/stage.rs`): the block's fixed values once, the values the
//! ensemble shares once per step for all lanes, the rest per lane.

// Lane loops index several arrays by lane; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use crate::models::formula::{Cost, FormulaModel, STEP_INDEX};
use crate::models::lanes::{index_of, LaneArrays, Lanes, LANES};
use crate::num::formula::lower::Lowered;
use crate::num::formula::stage::split;
use crate::num::formula::tape::{Inputs, Tape};
use crate::num::precision::Real;
use crate::plan::stop::Cmp;
use crate::plan::{Plan, StopPlan};

use super::kernels::Isa;

fn lane(name: &str) -> usize {
    index_of(name).unwrap_or_else(|| panic!("{name} is not a lane field"))
}

/// A formula op resolved to lane indices: its program's inputs (by DAG
/// variable) and the lanes its outputs assign.
pub struct FormulaCall<R> {
    pub tape: Tape<R>,
    pub inputs: Vec<usize>,
    pub outputs: Vec<usize>,
    pub isa: Isa,
}

/// A block's lanes as the inputs of a program, by lane index.
struct LaneView<'a, R> {
    l: &'a Lanes<R>,
    lanes: &'a [usize],
}

impl<R: Real> Inputs<R, LANES> for LaneView<'_, R> {
    #[inline(always)]
    fn array(&self, k: u32) -> &[R; LANES] {
        self.l.at(self.lanes[k as usize])
    }
    #[inline(always)]
    fn scalar(&self, k: u32) -> R {
        self.array(k)[0]
    }
}

impl<R: Real> FormulaCall<R> {
    pub fn new(m: &FormulaModel, name: &str, isa: Isa) -> Option<Self> {
        let op = m.op(name)?;
        Some(FormulaCall {
            tape: Tape::new(&op.program, |_| false),
            inputs: m.inputs.iter().map(|n| lane(n)).collect(),
            outputs: op.outputs.iter().map(|n| lane(n)).collect(),
            isa,
        })
    }

    /// Evaluates every output, then assigns them (simultaneous update).
    pub fn run(&self, l: &mut Lanes<R>, regs: &mut [[R; LANES]]) {
        let view = LaneView {
            l,
            lanes: &self.inputs,
        };
        self.tape.run(regs, &view, self.isa);
        for (k, &lane) in self.outputs.iter().enumerate() {
            *l.at_mut(lane) = *self.tape.output(regs, k);
        }
    }
}

/// A stop condition on a block: `lhs − rhs` through the interpreter,
/// compared with zero per lane. Its inputs are lanes, or observer slots
/// (an indicator's running value).
pub struct Condition<R> {
    tape: Tape<R>,
    program: Lowered,
    inputs: Vec<usize>,
    /// The slot of each input that reads one (by input).
    slots: Vec<Option<usize>>,
    cmp: Cmp,
    isa: Isa,
    /// Does it read `t` (set to the step's end before it runs)?
    pub reads_time: bool,
}

impl<R: Real> Condition<R> {
    /// `slot(name)`: the observer slot of an input that is not a lane.
    pub fn new(s: &StopPlan, isa: Isa, slot: impl Fn(&str) -> Option<usize>) -> Self {
        let slots: Vec<Option<usize>> = s.inputs.iter().map(|n| slot(n)).collect();
        Condition {
            tape: Tape::new(&s.program, |_| false),
            program: s.program.clone(),
            inputs: s
                .inputs
                .iter()
                .zip(&slots)
                .map(|(n, k)| if k.is_some() { 0 } else { lane(n) })
                .collect(),
            slots,
            cmp: s.cmp,
            isa,
            reads_time: s.inputs.contains(&"t"),
        }
    }

    pub fn registers(&self) -> usize {
        self.tape.registers
    }

    /// The lane of each input (where it is no observer slot), `None` where
    /// the program does not read it.
    pub fn lanes_read(&self) -> Vec<Option<usize>> {
        let read = self.program.inputs_read();
        (self.inputs.iter().enumerate())
            .map(|(k, &lane)| read.contains(&(k as u32)).then_some(lane))
            .collect()
    }

    /// Whether some input reads an observer slot.
    pub fn reads_slots(&self) -> bool {
        self.slots.iter().any(Option::is_some)
    }

    /// The lanes where the condition holds (never where it is NaN); `real`:
    /// the block's observer slots.
    pub fn holds(
        &self,
        l: &Lanes<R>,
        real: &[[R; LANES]],
        regs: &mut [[R; LANES]],
    ) -> [bool; LANES] {
        let mut holds = [false; LANES];
        if !self.reads_slots() {
            let view = LaneView {
                l,
                lanes: &self.inputs,
            };
            self.holds_on(&view, regs, &mut holds);
        } else {
            let arrays: Vec<&[R; LANES]> = (self.inputs.iter().zip(&self.slots))
                .map(|(lane, slot)| match slot {
                    Some(k) => &real[*k],
                    None => l.at(*lane),
                })
                .collect();
            self.holds_on(&arrays[..], regs, &mut holds);
        }
        holds
    }

    /// The program of `lhs − rhs`, by input.
    pub fn program(&self) -> &Lowered {
        &self.program
    }

    /// The comparison as `(sign, strict)`: the condition holds where
    /// `sign·(lhs − rhs)` is above zero, or at zero where it is not strict
    /// (a negation is exact, and NaN holds nowhere).
    pub fn sign(&self) -> (R, bool) {
        let one = R::from_f64(1.0);
        match self.cmp {
            Cmp::Gt => (one, true),
            Cmp::Ge => (one, false),
            Cmp::Lt => (-one, true),
            Cmp::Le => (-one, false),
        }
    }

    /// Where the condition holds on `N` lanes of inputs (by input index).
    pub fn holds_on<const N: usize>(
        &self,
        input: &(impl Inputs<R, N> + ?Sized),
        regs: &mut [[R; N]],
        holds: &mut [bool; N],
    ) {
        self.tape.run(regs, input, self.isa);
        let g = self.tape.output(regs, 0);
        let sign = self.sign();
        for i in 0..N {
            holds[i] = holds_at(sign, g[i]);
        }
    }
}

/// Whether a condition whose comparison is `(sign, strict)`
/// ([`Condition::sign`]) holds where `lhs − rhs` is `g`: `Cmp::holds` in
/// the working precision (its comparison with zero is the f64 one of its
/// value), the same test for every lane so that lane loops vectorise.
#[inline(always)]
pub fn holds_at<R: Real>((sign, strict): (R, bool), g: R) -> bool {
    let x = sign * g;
    x > R::default() || (!strict && x == R::default())
}

/// Where an input of the composed step comes from.
#[derive(Debug, Clone, Copy)]
enum In {
    Lane(usize),
    /// The step number.
    Step,
}

/// A plan's whole step, composed and staged; see the module documentation.
pub struct FormulaStep<R> {
    fixed: Tape<R>,
    uniform: Tape<R>,
    lane: Tape<R>,
    inputs: Vec<In>,
    /// Outputs of `fixed` (they follow the inputs in the index space).
    fixed_outputs: usize,
    outputs: Vec<usize>,
    isa: Isa,
}

/// A block's working memory for a [`FormulaStep`]: each part's registers.
/// Those of `fixed` keep the block's fixed values across the steps; those
/// of `uniform` the shared values of a window of [`LANES`] steps (lane `j`:
/// step `window + j`), computed in one pass of the interpreter.
pub struct StepMemory<R> {
    fixed: LaneArrays<R>,
    uniform: LaneArrays<R>,
    window: Option<u64>,
    lane: LaneArrays<R>,
}

impl<R: Real> FormulaStep<R> {
    /// The plan's step for formula model `m`, if every op is the model's.
    pub fn new(plan: &Plan, m: &FormulaModel, isa: Isa) -> Option<Self> {
        let c = m.compose(&plan.ops, Cost::PerLane)?;
        let vary = c.vary(|name| plan.on_axis(name));
        let s = split(&c.program, &vary);
        let n = vary.len() as u32;
        Some(FormulaStep {
            fixed: Tape::new(&s.fixed, |_| false),
            uniform: Tape::new(&s.uniform, |_| false),
            lane: Tape::new(&s.lane, |k| s.scalar_in_lane(k, &vary)),
            inputs: c
                .inputs
                .iter()
                .map(|name| match *name {
                    STEP_INDEX => In::Step,
                    _ => In::Lane(lane(name)),
                })
                .collect(),
            fixed_outputs: s.fixed.outputs.len(),
            outputs: c.outputs.iter().map(|name| lane(name)).collect(),
            isa,
        })
        .filter(|_| n as usize == c.inputs.len())
    }

    pub fn memory(&self) -> StepMemory<R> {
        StepMemory {
            fixed: LaneArrays::filled(self.fixed.registers, R::default()),
            uniform: LaneArrays::filled(self.uniform.registers, R::default()),
            window: None,
            lane: LaneArrays::filled(self.lane.registers, R::default()),
        }
    }

    /// Computes the block's fixed values (after its inputs are loaded).
    pub fn begin(&self, l: &Lanes<R>, m: &mut StepMemory<R>) {
        // The same view as the uniform part's: the fixed part reads neither
        // `n` nor fixed values, so neither is there yet.
        let view = Uniform {
            s: self,
            l,
            fixed: &[],
            steps: &[R::default(); LANES],
        };
        self.fixed.run(&mut m.fixed, &view, self.isa);
    }

    /// Step `n` on every lane of the block; returns whether a value it
    /// assigned is non-finite in some lane.
    pub fn step(&self, l: &mut Lanes<R>, m: &mut StepMemory<R>, n: u64) -> bool {
        let window = match m.window {
            Some(w) if (w..w + LANES as u64).contains(&n) => w,
            _ => {
                let steps: [R; LANES] = std::array::from_fn(|j| R::from_f64((n + j as u64) as f64));
                let shared = Uniform {
                    s: self,
                    l,
                    fixed: &m.fixed,
                    steps: &steps,
                };
                self.uniform.run(&mut m.uniform, &shared, self.isa);
                m.window = Some(n);
                n
            }
        };
        let view = PerLane {
            s: self,
            l,
            fixed: &m.fixed,
            uniform: &m.uniform,
            j: (n - window) as usize,
            n: R::from_f64(n as f64),
        };
        self.lane.run(&mut m.lane, &view, self.isa);
        #[cfg(target_arch = "x86_64")]
        if self.isa != Isa::Baseline && std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked).
            return unsafe { commit_v3(&self.outputs, &self.lane, &m.lane, l) };
        }
        commit(&self.outputs, &self.lane, &m.lane, l)
    }
}

/// Copies the step's outputs into their lanes; returns whether any is
/// non-finite (one pass, vectorised like the step).
#[inline(always)]
fn commit<R: Real>(
    outputs: &[usize],
    tape: &Tape<R>,
    regs: &[[R; LANES]],
    l: &mut Lanes<R>,
) -> bool {
    let mut bad = false;
    for (k, &lane) in outputs.iter().enumerate() {
        let (src, dst) = (tape.output(regs, k), l.at_mut(lane));
        for i in 0..LANES {
            dst[i] = src[i];
            bad |= !src[i].finite();
        }
    }
    bad
}

/// [`commit`] compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn commit_v3<R: Real>(
    outputs: &[usize],
    tape: &Tape<R>,
    regs: &[[R; LANES]],
    l: &mut Lanes<R>,
) -> bool {
    commit(outputs, tape, regs, l)
}

/// The inputs of the uniform part over a window of steps: lane `j` is
/// step `steps[j]`; every other input it reads (and every fixed value) is
/// the same in all lanes of the block.
struct Uniform<'a, R> {
    s: &'a FormulaStep<R>,
    l: &'a Lanes<R>,
    fixed: &'a [[R; LANES]],
    steps: &'a [R; LANES],
}

impl<R: Real> Inputs<R, LANES> for Uniform<'_, R> {
    #[inline(always)]
    fn array(&self, k: u32) -> &[R; LANES] {
        let k = k as usize;
        match self.s.inputs.get(k) {
            Some(In::Lane(i)) => self.l.at(*i),
            Some(In::Step) => self.steps,
            None => self.s.fixed.output(self.fixed, k - self.s.inputs.len()),
        }
    }
    #[inline(always)]
    fn scalar(&self, k: u32) -> R {
        self.array(k)[0]
    }
}

/// The inputs of the per-lane part: the lanes, the fixed values, and the
/// uniform values and inputs as scalars.
struct PerLane<'a, R> {
    s: &'a FormulaStep<R>,
    l: &'a Lanes<R>,
    fixed: &'a [[R; LANES]],
    uniform: &'a [[R; LANES]],
    /// The step's lane in the uniform window.
    j: usize,
    n: R,
}

impl<R: Real> Inputs<R, LANES> for PerLane<'_, R> {
    #[inline(always)]
    fn array(&self, k: u32) -> &[R; LANES] {
        let k = k as usize;
        match self.s.inputs.get(k) {
            Some(In::Lane(i)) => self.l.at(*i),
            _ => self.s.fixed.output(self.fixed, k - self.s.inputs.len()),
        }
    }
    #[inline(always)]
    fn scalar(&self, k: u32) -> R {
        let k = k as usize;
        let n = self.s.inputs.len();
        match self.s.inputs.get(k) {
            Some(In::Lane(i)) => self.l.at(*i)[0],
            Some(In::Step) => self.n,
            None => self
                .s
                .uniform
                .output(self.uniform, k - n - self.s.fixed_outputs)[self.j],
        }
    }
}
