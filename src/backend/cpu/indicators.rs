//! The chaos indicators on the CPU: the tangent step and the samples of
//! `plan/indicators.rs` through the block interpreter, on the observer
//! slots of a block (the GPU runs the same programs as WGSL).

// Lane loops index several arrays by lane; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use super::tangent::{CompiledTangent, TangentScratch};
use crate::models::lanes::{index_of, Lanes, LANES};
use crate::num::formula::tape::{Inputs, Tape};
use crate::num::isa::Isa;
use crate::num::precision::Real;
use crate::plan::indicators::{Indicators, SampleInput, Sampler};
use crate::plan::slots;
use crate::plan::tangent::TangentInput;
use crate::plan::Plan;

/// Where a program input comes from on the CPU.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Src {
    Lane(usize),
    /// State variable `k` of the plan at the step's start.
    Prev(usize),
    Slot(usize),
    /// A value the same in every lane, set per call (step, sample number,
    /// whether the sample counts).
    Step,
    Count,
    Counted,
    /// `n1·dt` per lane.
    Elapsed,
}

/// A program and where its inputs come from and its outputs go.
pub struct Program<R> {
    tape: Tape<R>,
    inputs: Vec<Src>,
    /// The inputs among Step, Count, Counted and Elapsed it reads: the
    /// arrays to fill before each call.
    fills: Vec<Src>,
    /// The real slots the outputs are written to.
    outputs: Vec<usize>,
    every: u64,
}

/// The indicators' programs for a plan.
pub struct IndicatorTapes<R> {
    tangent: Program<R>,
    /// The tangent step compiled (built-in models), run instead of
    /// `tangent`'s tape.
    compiled: Option<CompiledTangent<R>>,
    /// The lane index of each of the plan's state variables.
    var_lanes: Vec<usize>,
    samples: Vec<Program<R>>,
    skip_step: u64,
    /// Lane index of `dt` (the samples' elapsed time).
    dt_lane: usize,
}

impl<R: Real> IndicatorTapes<R> {
    pub fn new(
        plan: &Plan,
        ind: &Indicators,
        compiled: Option<CompiledTangent<R>>,
    ) -> IndicatorTapes<R> {
        // The indicators' slots among the block's real slots.
        let first = slots::indicator_first(plan);
        let lane = |name: &str| match plan.vars.iter().position(|v| *v == name) {
            Some(k) => Src::Prev(k),
            None => Src::Lane(index_of(name).unwrap_or_else(|| panic!("{name} is not a lane"))),
        };
        let inputs: Vec<Src> = ind
            .tangent
            .inputs
            .iter()
            .map(|i| match *i {
                TangentInput::Lane(name) => lane(name),
                TangentInput::Step => Src::Step,
                d => Src::Slot(first + ind.deviation_slot(d).expect("a deviation")),
            })
            .collect();
        let tangent = Program {
            tape: Tape::new(&ind.tangent.program, |_| false),
            fills: fills(&inputs),
            inputs,
            outputs: ind.deviation_slots.iter().map(|k| first + k).collect(),
            every: 1,
        };
        let samples = [&ind.lyapunov, &ind.chaos]
            .into_iter()
            .flatten()
            .map(|s| sampler(s, first))
            .collect();
        IndicatorTapes {
            tangent,
            compiled,
            var_lanes: plan
                .vars
                .iter()
                .map(|v| index_of(v).expect("a lane"))
                .collect(),
            samples,
            skip_step: ind.skip_step,
            dt_lane: index_of("dt").expect("dt is a lane"),
        }
    }

    /// Registers the programs need, and [`FILLS`] more for the inputs
    /// that are one value per call.
    pub fn registers(&self) -> usize {
        let all = std::iter::once(&self.tangent).chain(&self.samples);
        all.map(|p| p.tape.registers).max().unwrap_or(0) + FILLS
    }

    /// The scratch lanes the compiled tangent runs on, for block `l`;
    /// `None` where the tape runs.
    pub fn scratch(&self, l: &Lanes<R>) -> Option<TangentScratch<R>> {
        let c = self.compiled.as_ref()?;
        Some(TangentScratch::new(l, c.vectors()))
    }

    /// Whether [`IndicatorTapes::step`] takes the plan's steps: the
    /// compiled tangent runs the whole step, so the state and the vectors
    /// move in one pass.
    pub fn takes_step(&self) -> bool {
        self.compiled.as_ref().is_some_and(|c| c.takes_step)
    }

    /// Step `n` (0 for the first) of block `l` and of the deviation vectors
    /// of its `running` lanes (bits) at once, on `scratch`, where
    /// [`IndicatorTapes::takes_step`]: the same operations as the fused
    /// stages, so the same state.
    pub fn step(
        &self,
        l: &mut Lanes<R>,
        scratch: &mut TangentScratch<R>,
        real: &mut [[R; LANES]],
        n: u64,
        running: u64,
    ) {
        let c = self.compiled.as_ref().expect("a compiled tangent");
        for &lane in &self.var_lanes {
            *scratch.x.at_mut(lane) = *l.at(lane);
        }
        self.move_vectors(c, scratch, real, n, running);
        for &lane in &self.var_lanes {
            *l.at_mut(lane) = *scratch.x.at(lane);
        }
    }

    /// After step `n1` (1 for the first): the deviation vectors of the
    /// `running` lanes (bits) through the step's tangent map (compiled,
    /// on `scratch`, where there is one), then the samples due. Returns
    /// the running lanes whose vectors became non-finite, as bits.
    #[allow(clippy::too_many_arguments)]
    pub fn after_step(
        &self,
        l: &Lanes<R>,
        prev: &[[R; LANES]],
        real: &mut [[R; LANES]],
        regs: &mut [[R; LANES]],
        scratch: Option<&mut TangentScratch<R>>,
        n1: u64,
        running: u64,
        isa: Isa,
    ) -> u64 {
        let at = Call {
            n1,
            running,
            isa,
            dt_lane: self.dt_lane,
        };
        let scalars = Scalars {
            step: R::from_f64((n1 - 1) as f64),
            count: R::from_f64(0.0),
            counted: R::from_f64(0.0),
        };
        match (&self.compiled, scratch) {
            // The step moved the vectors already.
            (Some(c), _) if c.takes_step => {}
            (Some(c), Some(scratch)) => {
                for (k, &lane) in self.var_lanes.iter().enumerate() {
                    *scratch.x.at_mut(lane) = prev[k];
                }
                self.move_vectors(c, scratch, real, n1 - 1, running);
            }
            _ => run(&self.tangent, l, prev, real, regs, scalars, at),
        }
        for s in self.samples.iter().filter(|s| n1.is_multiple_of(s.every)) {
            let scalars = Scalars {
                count: R::from_f64((n1 / s.every) as f64),
                counted: R::from_f64(f64::from(u8::from(n1 > self.skip_step))),
                ..scalars
            };
            run(s, l, prev, real, regs, scalars, at);
        }
        // One vectorised pass finds whether any lane is non-finite (rare);
        // only then are the lanes told apart.
        let mut any = false;
        for &k in &self.tangent.outputs {
            for i in 0..LANES {
                any |= !real[k][i].finite();
            }
        }
        if !any {
            return 0;
        }
        let mut bad = 0u64;
        for &k in &self.tangent.outputs {
            for i in 0..LANES {
                bad |= u64::from(!real[k][i].finite()) << i;
            }
        }
        bad & running
    }
}

impl<R: Real> IndicatorTapes<R> {
    /// The compiled tangent step `n` from the state in `s.x`: the
    /// deviation vectors into the scratch lanes, the step on both, the
    /// vectors of the `running` lanes back into their slots.
    fn move_vectors(
        &self,
        c: &CompiledTangent<R>,
        s: &mut TangentScratch<R>,
        real: &mut [[R; LANES]],
        n: u64,
        running: u64,
    ) {
        // The tape's outputs are the vectors' slots, vector k's component j
        // at k·d + j.
        let slots = &self.tangent.outputs;
        let d = c.space.len();
        for (k, v) in s.d.iter_mut().enumerate() {
            for (j, &lane) in c.space.iter().enumerate() {
                *v.at_mut(lane) = real[slots[k * d + j]];
            }
        }
        c.run(&mut s.x, &mut s.d, n);
        for (k, v) in s.d.iter().enumerate() {
            for (j, &lane) in c.space.iter().enumerate() {
                put(&mut real[slots[k * d + j]], v.at(lane), running);
            }
        }
    }
}

/// `out` into `slot` where `running` (bits) has the lane.
fn put<R: Real>(slot: &mut [R; LANES], out: &[R; LANES], running: u64) {
    if running == u64::MAX {
        *slot = *out;
        return;
    }
    for i in 0..LANES {
        if running >> i & 1 == 1 {
            slot[i] = out[i];
        }
    }
}

/// A sampler's program, its slots `first` on among the real slots.
fn sampler<R: Real>(s: &Sampler, first: usize) -> Program<R> {
    let inputs: Vec<Src> = s
        .inputs
        .iter()
        .map(|i| match *i {
            SampleInput::Slot(k) => Src::Slot(first + k),
            SampleInput::Elapsed => Src::Elapsed,
            SampleInput::Count => Src::Count,
            SampleInput::Counted => Src::Counted,
        })
        .collect();
    Program {
        tape: Tape::new(&s.program, |_| false),
        fills: fills(&inputs),
        inputs,
        outputs: s.outputs.iter().map(|k| first + k).collect(),
        every: s.every,
    }
}

/// The one-value inputs among `inputs`, each once.
fn fills(inputs: &[Src]) -> Vec<Src> {
    let mut f: Vec<Src> = vec![];
    for src in inputs {
        let one = matches!(src, Src::Step | Src::Count | Src::Counted | Src::Elapsed);
        if one && !f.contains(src) {
            f.push(*src);
        }
    }
    f
}

/// The step a call follows, the lanes still running (as bits: only their
/// slots change) and the instruction-set level.
#[derive(Clone, Copy)]
struct Call {
    n1: u64,
    running: u64,
    isa: Isa,
    dt_lane: usize,
}

/// The values of [`Src::Step`], [`Src::Count`] and [`Src::Counted`].
#[derive(Clone, Copy)]
struct Scalars<R> {
    step: R,
    count: R,
    counted: R,
}

/// Arrays for Step, Count, Counted and Elapsed, after the registers.
const FILLS: usize = 4;

/// A program's inputs on a block, resolved per read (no list built per call).
struct View<'a, R> {
    p: &'a Program<R>,
    l: &'a Lanes<R>,
    prev: &'a [[R; LANES]],
    real: &'a [[R; LANES]],
    /// Step, Count, Counted and Elapsed, as arrays (filled where read).
    fills: &'a [[R; LANES]],
}

impl<R: Real> Inputs<R, LANES> for View<'_, R> {
    #[inline(always)]
    fn array(&self, k: u32) -> &[R; LANES] {
        match self.p.inputs[k as usize] {
            Src::Lane(j) => self.l.at(j),
            Src::Prev(j) => &self.prev[j],
            Src::Slot(j) => &self.real[j],
            Src::Step => &self.fills[0],
            Src::Count => &self.fills[1],
            Src::Counted => &self.fills[2],
            Src::Elapsed => &self.fills[3],
        }
    }
    fn scalar(&self, k: u32) -> R {
        self.array(k)[0]
    }
}

/// Runs `p` on the block and writes its outputs into the slots.
#[allow(clippy::too_many_arguments)]
fn run<R: Real>(
    p: &Program<R>,
    l: &Lanes<R>,
    prev: &[[R; LANES]],
    real: &mut [[R; LANES]],
    regs: &mut [[R; LANES]],
    s: Scalars<R>,
    at: Call,
) {
    let (regs, fills) = regs.split_at_mut(regs.len() - FILLS);
    for src in &p.fills {
        match *src {
            Src::Step => fills[0] = [s.step; LANES],
            Src::Count => fills[1] = [s.count; LANES],
            Src::Counted => fills[2] = [s.counted; LANES],
            Src::Elapsed => {
                let n1r = R::from_f64(at.n1 as f64);
                let dt = l.at(at.dt_lane);
                fills[3] = std::array::from_fn(|i| n1r * dt[i]);
            }
            _ => {}
        }
    }
    let view = View {
        p,
        l,
        prev,
        real,
        fills,
    };
    p.tape.run(regs, &view, at.isa);
    // A lane that stopped or became non-finite keeps its indicators.
    for (k, &slot) in p.outputs.iter().enumerate() {
        put(&mut real[slot], p.tape.output(regs, k), at.running);
    }
}
