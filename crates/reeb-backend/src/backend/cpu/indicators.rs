//! The chaos indicators on the CPU: the tangent step and the samples of
//! `plan/indicators.rs` on the observer slots of a block — compiled where
//! they can be (`tangent.rs`, `samples.rs`), else through the block
//! interpreter (the GPU runs the same programs as WGSL). Where both are
//! compiled and nothing else observes the steps, a run of steps goes in one
//! call ([`IndicatorTapes::steps`]), the deviation vectors in the compiled
//! tangent's scratch lanes throughout.

// Lane loops index several arrays by lane; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use super::sample_ops;
use super::samples::{array_ptrs, on_arrays, sample_fn, SampleFn};
use super::tangent::{CompiledTangent, TangentScratch};
use crate::models::lanes::{index_of, Lanes, LANES};
use crate::num::formula::tape::{Inputs, Tape};
use crate::num::isa::Isa;
use crate::num::precision::Real;
use crate::plan::indicators::{chaos_fli_max, Indicators, SampleInput, SampleShape, Sampler};
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
    /// A value the same in every lane, set per call (step, the sample's
    /// number and one over it, whether the sample counts).
    Step,
    Count,
    InvCount,
    AtSkip,
}

/// A program and where its inputs come from and its outputs go.
pub struct Program<R> {
    tape: Tape<R>,
    inputs: Vec<Src>,
    /// The inputs among Step, Count, InvCount and AtSkip it reads: the
    /// arrays to fill before each call.
    fills: Vec<Src>,
    /// The real slots the outputs are written to.
    outputs: Vec<usize>,
    every: u64,
    /// A sample program compiled (`samples.rs`), run instead of the tape.
    compiled: Option<(SampleShape, SampleFn<R>)>,
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
    /// Where each sample's inputs and outputs are in a run of steps
    /// ([`IndicatorTapes::steps`]), where it can take one.
    runs: Option<Vec<RunLocs>>,
    skip_step: u64,
}

/// Where a compiled sample's array is in a run of steps: the deviation
/// vectors live in the compiled tangent's scratch lanes then.
#[derive(Debug, Clone, Copy)]
enum Loc {
    /// Vector `k`'s lane `lane` in the scratch.
    Vector(usize, usize),
    /// A real slot.
    Real(usize),
    /// The sample's number, one over it, whether it counts.
    Count,
    InvCount,
    AtSkip,
}

/// Where a sample's arrays (its inputs, in order; output k replaces input
/// k) are in a run of steps, and the same sorted for each step's copies
/// (no match per array and step).
struct RunLocs {
    arrays: Vec<Loc>,
    /// `(array, vector, lane)` of each vector component.
    vectors: Vec<(usize, usize, usize)>,
    /// `(array, which)` of each one-value input (a [`Loc::Count`],
    /// [`Loc::InvCount`] or [`Loc::AtSkip`]).
    scalars: Vec<(usize, Loc)>,
    /// Whether and how the sample may wait.
    waits: Waits,
    /// Whether it is an FLI/MEGNO sample ([`Pending`] takes it in the band).
    chaos: bool,
}

/// How a sample due every step may wait inside a run of steps, while its
/// vector stays in the band of `in_band_r` (see [`in_band`]).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Waits {
    Never,
    /// One Lyapunov vector: the sample would change nothing but ‖u‖².
    Lyapunov,
    /// The FLI without MEGNO: the sample would change nothing but
    /// `fli_max` (its array `max`; and `fli_log` and the sums, which only
    /// MEGNO reads); the largest ‖u‖² of the steps it waited gives their
    /// largest ln‖w‖ ([`Peak`]).
    Fli {
        max: usize,
    },
}

impl RunLocs {
    fn new(arrays: Vec<Loc>, waits: Waits, chaos: bool) -> RunLocs {
        let mut vectors = vec![];
        let mut scalars = vec![];
        for (a, &at) in arrays.iter().enumerate() {
            match at {
                Loc::Vector(k, lane) => vectors.push((a, k, lane)),
                Loc::Real(_) => {}
                one => scalars.push((a, one)),
            }
        }
        RunLocs {
            arrays,
            vectors,
            scalars,
            waits,
            chaos,
        }
    }
}

/// The steps of a run and the lanes still running (bits).
#[derive(Clone, Copy)]
struct Run {
    n: u64,
    k: u64,
    running: u64,
}

/// What a run of steps ([`IndicatorTapes::steps`]) did.
#[derive(Debug, Clone, Copy)]
pub struct RunOutcome {
    /// How many steps it took.
    pub done: u64,
    /// Whether the last step's samples were taken: not when that step left
    /// some state variable non-finite (the caller marks those lanes first,
    /// then samples, as after any step).
    pub sampled: bool,
}

impl<R: Real> IndicatorTapes<R> {
    pub fn new(
        plan: &Plan,
        ind: &Indicators,
        compiled: Option<CompiledTangent<R>>,
        isa: Isa,
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
            compiled: None,
        };
        let samples: Vec<Program<R>> = ind
            .samplers()
            .map(|(_, s)| sampler(s, first, isa))
            .collect();
        let megno = plan.observers.megno.is_some();
        let runs = run_locs(&tangent.outputs, compiled.as_ref(), &samples, megno);
        IndicatorTapes {
            tangent,
            runs,
            compiled,
            var_lanes: plan
                .vars
                .iter()
                .map(|v| index_of(v).expect("a lane"))
                .collect(),
            samples,
            skip_step: ind.skip_step,
        }
    }

    /// Registers the programs need (compiled samples: their arrays, all
    /// at once in a run of steps), and [`FILLS`] more for the inputs that
    /// are one value per call.
    pub fn registers(&self) -> usize {
        let all = std::iter::once(&self.tangent).chain(&self.samples);
        let tapes = all.map(|p| p.tape.registers).max().unwrap_or(0);
        let runs: usize = self.samples.iter().map(|p| p.inputs.len()).sum();
        // And a run's waiting ‖u‖² and octaves of an FLI/MEGNO sample
        // ([`Pending`]; a run is at most `LANES` steps).
        let chaos = self.runs.iter().flatten().any(|loc| loc.chaos);
        tapes.max(runs + usize::from(chaos) * 2 * LANES) + FILLS
    }

    /// The scratch lanes the compiled tangent runs on, for block `l`;
    /// `None` where the tape runs.
    pub fn scratch(&self, l: &Lanes<R>) -> Option<TangentScratch<R>> {
        let c = self.compiled.as_ref()?;
        Some(TangentScratch::new(l, c.vectors()))
    }

    /// Whether [`IndicatorTapes::steps`] can take runs of steps: the
    /// tangent and every sample compiled, the tangent the whole step.
    pub fn takes_runs(&self) -> bool {
        self.runs.is_some()
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

    /// Steps `n … n+k−1` of block `l` where [`IndicatorTapes::takes_runs`],
    /// with the deviation vectors of its `running` lanes (bits) and their
    /// samples: the same operations as [`IndicatorTapes::step`] and
    /// [`IndicatorTapes::after_step`] step by step, so the same bits, with
    /// the vectors in `scratch` and the samples' sums in `regs` until the
    /// run ends. It ends early after a step that leaves a state variable
    /// non-finite (a vector that leaves the finite numbers only loses its
    /// trajectory's indicators: `slots::indicators_finish`).
    #[allow(clippy::too_many_arguments)]
    pub fn steps(
        &self,
        l: &mut Lanes<R>,
        scratch: &mut TangentScratch<R>,
        real: &mut [[R; LANES]],
        regs: &mut [[R; LANES]],
        n: u64,
        k: u64,
        running: u64,
        isa: Isa,
    ) -> RunOutcome {
        let run = Run { n, k, running };
        #[cfg(target_arch = "x86_64")]
        match isa {
            // SAFETY: `kernels::isa` names a level only where the CPU has
            // its features.
            Isa::V4 => return unsafe { steps_v4(self, l, scratch, real, regs, run) },
            Isa::V3 => return unsafe { steps_v3(self, l, scratch, real, regs, run) },
            Isa::Baseline => {}
        }
        let _ = isa;
        steps_body(self, l, scratch, real, regs, run)
    }

    /// After step `n1` (1 for the first): the deviation vectors of the
    /// `running` lanes (bits) through the step's tangent map (compiled,
    /// on `scratch`, where there is one), then the samples due.
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
    ) {
        let at = Call { running, isa };
        let scalars = Scalars {
            step: R::from_f64((n1 - 1) as f64),
            count: R::from_f64(0.0),
            inv_count: R::from_f64(0.0),
            at_skip: R::from_f64(0.0),
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
        for s in self.samples.iter().filter(|s| sampled_after(s.every, n1)) {
            run(s, l, prev, real, regs, self.sample_scalars(s.every, n1), at);
        }
    }
}

impl<R: Real> IndicatorTapes<R> {
    /// The one-value inputs of a sample taken every `every` steps, after
    /// step `n1`: its number, one over it, whether it is the skip step's.
    fn sample_scalars(&self, every: u64, n1: u64) -> Scalars<R> {
        let count = sample_number(every, n1);
        Scalars {
            step: R::from_f64((n1 - 1) as f64),
            count: R::from_f64(count as f64),
            inv_count: inv_count::<R>(count),
            at_skip: R::from_f64(f64::from(u8::from(n1 == self.skip_step))),
        }
    }

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
        self.load_vectors(c, s, real, running);
        c.run(&mut s.x, &mut s.d, n);
        self.store_vectors(c, s, real, running);
    }

    /// The deviation vectors from their slots into the scratch lanes; a
    /// lane not `running` (bits) takes a running lane's, so that what it
    /// computes stays finite (it is never stored).
    #[inline(always)]
    fn load_vectors(
        &self,
        c: &CompiledTangent<R>,
        s: &mut TangentScratch<R>,
        real: &[[R; LANES]],
        running: u64,
    ) {
        // The tape's outputs are the vectors' slots, vector k's component j
        // at k·d + j.
        let slots = &self.tangent.outputs;
        let d = c.space.len();
        // The first running lane, where some lane does not run.
        let some_stopped = running != 0 && running != u64::MAX;
        let twin = some_stopped.then(|| running.trailing_zeros() as usize);
        for (k, v) in s.d.iter_mut().enumerate() {
            for (j, &lane) in c.space.iter().enumerate() {
                let a = v.at_mut(lane);
                *a = real[slots[k * d + j]];
                if let Some(t) = twin {
                    for i in (0..LANES).filter(|i| running >> i & 1 == 0) {
                        a[i] = a[t];
                    }
                }
            }
        }
    }

    /// Sample `p` after step `n1` inside a run of steps, on its arrays
    /// `buf` (at `loc`): the vectors from the scratch lanes and back, the
    /// one-value inputs filled.
    #[inline(always)]
    fn sample_in_run(
        &self,
        p: &Program<R>,
        loc: &RunLocs,
        s: &mut TangentScratch<R>,
        buf: &mut [[R; LANES]],
        n1: u64,
    ) {
        let (shape, f) = p.compiled.expect("a compiled sample");
        let v = self.sample_scalars(p.every, n1);
        for &(a, one) in &loc.scalars {
            buf[a] = [match one {
                Loc::Count => v.count,
                Loc::InvCount => v.inv_count,
                _ => v.at_skip,
            }; LANES];
        }
        // The arrays of `buf`, but the vectors' where they lie in the
        // scratch: each pointer from one base pointer per struct, taken
        // once, so none invalidates another.
        let n = buf.len();
        let mut at = array_ptrs(buf);
        for (k, d) in s.d.iter_mut().enumerate() {
            let vector = d.as_mut_slice().as_mut_ptr() as *mut [R; LANES];
            for &(a, _, lane) in loc.vectors.iter().filter(|v| v.1 == k) {
                // SAFETY: `Lanes` is `repr(C)`, `COUNT` arrays of `LANES`
                // values (see `Lanes::at`), and `lane` is one of them.
                at[a] = unsafe { vector.add(lane) };
            }
        }
        // SAFETY: `sample_fn` compiled it for the block's level, which
        // `kernels::isa` names only where the CPU has its features; the
        // arrays are distinct (the vectors' lanes, `buf`'s other arrays),
        // and borrowed here.
        unsafe { f(shape, &at[..n], v.is_skip_step()) };
    }

    /// The vectors of the `running` lanes (bits) back into their slots.
    #[inline(always)]
    fn store_vectors(
        &self,
        c: &CompiledTangent<R>,
        s: &TangentScratch<R>,
        real: &mut [[R; LANES]],
        running: u64,
    ) {
        let slots = &self.tangent.outputs;
        let d = c.space.len();
        for (k, v) in s.d.iter().enumerate() {
            for (j, &lane) in c.space.iter().enumerate() {
                put(&mut real[slots[k * d + j]], v.at(lane), running);
            }
        }
    }
}

macro_rules! steps_variant {
    ($(#[$m:meta])* $name:ident) => {
        $(#[$m])*
        unsafe fn $name<R: Real>(
            ind: &IndicatorTapes<R>,
            l: &mut Lanes<R>,
            s: &mut TangentScratch<R>,
            real: &mut [[R; LANES]],
            regs: &mut [[R; LANES]],
            run: Run,
        ) -> RunOutcome {
            steps_body(ind, l, s, real, regs, run)
        }
    };
}

steps_variant! {
    /// [`steps_body`] compiled for AVX2 and FMA.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    steps_v3
}

steps_variant! {
    /// [`steps_body`] compiled for AVX-512.
    ///
    /// # Safety
    /// The CPU must support AVX-512 F, VL, DQ and BW, AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx2,fma")]
    steps_v4
}

/// [`IndicatorTapes::steps`]: each sample's arrays in `regs` for the run
/// (its sums loaded once), the vectors copied in and out of them around
/// each sample.
///
/// As the fused stages do (`kernels::fused_steps_body`), a run of several
/// steps first goes unchecked and is looked at once, at its end: a state
/// variable that leaves the finite numbers stays out (the pieces add to or
/// scale a variable). Only when one is non-finite then is the run taken
/// again from its start, which is still in `l` and `real`, checking after
/// each step: the same operations, so the same bits and verdict as
/// checking every step.
#[inline(always)]
fn steps_body<R: Real>(
    ind: &IndicatorTapes<R>,
    l: &mut Lanes<R>,
    s: &mut TangentScratch<R>,
    real: &mut [[R; LANES]],
    regs: &mut [[R; LANES]],
    run: Run,
) -> RunOutcome {
    let c = ind.compiled.as_ref().expect("a compiled tangent");
    let locs = ind.runs.as_ref().expect("compiled samples");
    // Each sample's arrays, one after the other in `regs`.
    let mut bufs: Vec<&mut [[R; LANES]]> = vec![];
    let mut rest = regs;
    for loc in locs {
        let (buf, r) = rest.split_at_mut(loc.arrays.len());
        bufs.push(buf);
        rest = r;
    }
    let mut check = run.k == 1;
    let out = loop {
        // The run's start: the state, the vectors, the samples' sums.
        for &lane in &ind.var_lanes {
            *s.x.at_mut(lane) = *l.at(lane);
        }
        ind.load_vectors(c, s, real, run.running);
        for (loc, buf) in locs.iter().zip(bufs.iter_mut()) {
            for (a, at) in buf.iter_mut().zip(&loc.arrays) {
                if let Loc::Real(j) = *at {
                    *a = real[j];
                }
            }
        }
        let out = run_steps(ind, c, s, &mut bufs, rest, run, check);
        let bad = !check && s.x.any_nonfinite(&ind.var_lanes);
        if !bad {
            break out;
        }
        check = true;
    };
    for &lane in &ind.var_lanes {
        *l.at_mut(lane) = *s.x.at(lane);
    }
    ind.store_vectors(c, s, real, run.running);
    for (loc, buf) in locs.iter().zip(bufs) {
        for (a, at) in buf.iter().zip(&loc.arrays) {
            if let Loc::Real(j) = *at {
                put(&mut real[j], a, run.running);
            }
        }
    }
    out
}

/// The steps of `run` on the scratch and the samples' arrays `bufs`
/// (`spare`: arrays for [`Pending`]); `check`: look at the state and the
/// vectors after every step, and stop after the first that left some
/// non-finite.
#[inline(always)]
fn run_steps<R: Real>(
    ind: &IndicatorTapes<R>,
    c: &CompiledTangent<R>,
    s: &mut TangentScratch<R>,
    bufs: &mut [&mut [[R; LANES]]],
    spare: &mut [[R; LANES]],
    run: Run,
    check: bool,
) -> RunOutcome {
    let locs = ind.runs.as_ref().expect("compiled samples");
    let mut pending = Pending::new(locs, spare);
    let out = run_steps_pending(ind, c, s, bufs, run, check, &mut pending);
    if let Some((i, _)) = pending.sample {
        pending.flush(i, bufs[i]);
    }
    out
}

/// [`run_steps`], the sums of the FLI/MEGNO sample in the band left
/// `pending`.
#[inline(always)]
fn run_steps_pending<R: Real>(
    ind: &IndicatorTapes<R>,
    c: &CompiledTangent<R>,
    s: &mut TangentScratch<R>,
    bufs: &mut [&mut [[R; LANES]]],
    run: Run,
    check: bool,
    pending: &mut Pending<R>,
) -> RunOutcome {
    let locs = ind.runs.as_ref().expect("compiled samples");
    // At most one FLI sample; its peak only where it waits.
    let fli = |loc: &RunLocs| matches!(loc.waits, Waits::Fli { .. });
    let mut peak = locs.iter().any(fli).then(Peak::new);
    for j in 0..run.k {
        c.run(&mut s.x, &mut s.d, run.n + j);
        if check && s.x.any_nonfinite(&ind.var_lanes) {
            return RunOutcome {
                done: j + 1,
                sampled: false,
            };
        }
        let n1 = run.n + j + 1;
        let may_wait = !check && j + 1 < run.k && n1 != ind.skip_step;
        let all = ind.samples.iter().zip(locs).zip(bufs.iter_mut());
        for (i, ((p, loc), buf)) in all.enumerate() {
            if !sampled_after(p.every, n1) {
                continue;
            }
            let waits = match loc.waits {
                Waits::Never => false,
                _ if !may_wait => false,
                Waits::Lyapunov => in_band(s, &loc.vectors),
                Waits::Fli { max } => {
                    let peak = peak.as_mut().expect("a peak");
                    peak.keep(s, &loc.vectors) || {
                        pending.flush(i, buf);
                        peak.rescale(s, &loc.vectors, buf, max)
                    }
                }
            };
            if waits {
                continue;
            }
            if let Waits::Fli { max } = loc.waits {
                pending.flush(i, buf);
                let octave = loc.vectors.len();
                peak.as_mut().expect("a peak").fold(buf, max, octave)
            }
            if pending.takes(i) && pending.take(s, loc, ind.sample_scalars(p.every, n1), buf) {
                continue;
            }
            pending.flush(i, buf);
            ind.sample_in_run(p, loc, s, buf, n1);
        }
    }
    RunOutcome {
        done: run.k,
        sampled: true,
    }
}

/// An FLI/MEGNO sample of a run of steps in two parts while its vector's
/// ‖u‖² is a positive normal number: only ‖u‖² is taken at each step
/// (`chaos_n2`) and the rest waits, with the octaves `fli_oct` of that
/// step, to be brought up to date (`chaos_ln_sums`, step after step)
/// before anything else reads the sums. Where ‖u‖² leaves the band of
/// `in_band_r` the vector and `fli_oct` are rescaled at once, as the
/// program rescales them ([`rescale`]). The same
/// operations as the whole program, so the same bits; but the vector is
/// read where it is (no copy), the sample's number is a value, not an
/// array, and each waiting sample's logarithm, independent of the sums,
/// overlaps their chain from one sample to the next. MEGNO, Zen 3 AVX2,
/// medians of the ratios of 7 alternating pairs against the plain run:
/// f64 2.19 → 1.86, f32 2.77 → 2.66 (the in-band whole program before;
/// same bits). Taking the logarithms with the sums rather than at each
/// step: MEGNO f32 0.98× the time (11 pairs), f64 0.98× (5 pairs).
/// Rescaling outside the band rather than running the whole program: on
/// the spin–orbit cost scene (S2, 320 × 320 orbits), where some lane of a
/// block leaves the band at most steps, MEGNO f32 0.90× the time (7
/// pairs); van der Pol's MEGNO f32 1.00×, f64 1.03× (7 pairs: the octaves
/// copied at each step).
struct Pending<'a, R> {
    /// The FLI/MEGNO sample's index among the run's and its vector's
    /// dimension (`fli_oct` is its array `d`, the sums after it).
    sample: Option<(usize, usize)>,
    /// The waiting samples' ‖u‖², in order: `len` of them.
    n2s: &'a mut [[R; LANES]],
    /// The octaves `fli_oct` each was taken with.
    octaves: &'a mut [[R; LANES]],
    /// Their numbers and one over each.
    counts: [(R, R); LANES],
    len: usize,
}

impl<'a, R: Real> Pending<'a, R> {
    /// For the samples at `locs`, at most one of them FLI/MEGNO, in a run
    /// of at most `LANES` steps, its vectors' ‖u‖² and octaves in `spare`.
    fn new(locs: &[RunLocs], spare: &'a mut [[R; LANES]]) -> Pending<'a, R> {
        let sample = locs
            .iter()
            .position(|loc| loc.chaos)
            .map(|i| (i, locs[i].vectors.len()));
        let (n2s, octaves) = match sample {
            Some(_) => spare[..2 * LANES].split_at_mut(LANES),
            None => (&mut [][..], &mut [][..]),
        };
        Pending {
            sample,
            n2s,
            octaves,
            counts: [(R::from_f64(0.0), R::from_f64(0.0)); LANES],
            len: 0,
        }
    }

    /// Whether sample `i` is the FLI/MEGNO one.
    #[inline(always)]
    fn takes(&self, i: usize) -> bool {
        self.sample.is_some_and(|(at, _)| at == i)
    }

    /// ‖u‖² of the sample after a step, the vector in the scratch `s`
    /// (at `loc`), `fli_oct` in its arrays `buf`; `v` its number. Whether
    /// it waits: only if ‖u‖² is positive and normal in every lane (else
    /// the whole program must run, its logarithm reading 0, ∞ or NaN).
    #[inline(always)]
    fn take(
        &mut self,
        s: &mut TangentScratch<R>,
        loc: &RunLocs,
        v: Scalars<R>,
        buf: &mut [[R; LANES]],
    ) -> bool {
        let n2 = &mut self.n2s[self.len];
        let d = loc.vectors.len();
        let in_band = sample_ops::chaos_n2(n2, &components(s, &loc.vectors)[..d]);
        if !in_band && !all_positive_normal(n2) {
            return false;
        }
        let octave = &mut buf[d];
        copy_lanes(&mut self.octaves[self.len], octave);
        if !in_band {
            rescale(s, &loc.vectors, octave, n2);
        }
        self.counts[self.len] = (v.count, v.inv_count);
        self.len += 1;
        true
    }

    /// Where sample `i` (arrays `buf`) is the FLI/MEGNO one, its waiting
    /// logarithms and sums brought up to date.
    #[inline(always)]
    fn flush(&mut self, i: usize, buf: &mut [[R; LANES]]) {
        let Some((at, d)) = self.sample else { return };
        if at != i || self.len == 0 {
            return;
        }
        let sums = &mut buf[d + 1..d + 5];
        // Two registers of lanes per chunk in either precision on AVX2.
        match std::mem::size_of::<R>() {
            4 => self.flush_chunks::<16>(sums),
            _ => self.flush_chunks::<8>(sums),
        }
        self.len = 0;
    }

    /// [`Pending::flush`]'s logarithms and sums into `sums`, `W` lanes at
    /// a time.
    #[inline(always)]
    fn flush_chunks<const W: usize>(&self, sums: &mut [[R; LANES]]) {
        // A chunk of lanes at a time, its sums in registers through every
        // waiting sample (one array pass per sample kept them in memory),
        // each sample's logarithm beside them.
        for c in (0..LANES).step_by(W) {
            let mut r: [[R; W]; 4] = [[R::from_f64(0.0); W]; 4];
            for (to, from) in r.iter_mut().zip(sums.iter()) {
                to.copy_from_slice(&from[c..c + W]);
            }
            let [log, max, sum, mean] = &mut r;
            let waiting = self.n2s.iter().zip(self.octaves.iter());
            for ((n2, octave), &(count, inv)) in waiting.zip(&self.counts[..self.len]) {
                // Each sample's own octaves: E ln 2 then stays in the loop,
                // where the compiler fuses it into ln‖w‖ as in the whole
                // program. Taken out of the loop (one octave for every
                // sample), it could not be, and ½ ln‖u‖² would be instead:
                // another rounding (`pending_samples_are_the_program`).
                let octave = &octave[c..c + W];
                for j in 0..W {
                    let (l, m) = (&mut log[j], &mut max[j]);
                    let (s, y) = (&mut sum[j], &mut mean[j]);
                    let (n2, e) = (n2[c + j], octave[j]);
                    sample_ops::chaos_ln_sums(l, m, s, y, n2, e, count, inv);
                }
            }
            for (from, to) in r.iter().zip(sums.iter_mut()) {
                to[c..c + W].copy_from_slice(from);
            }
        }
    }
}

/// `to = from`, a chunk of lanes at a time, in line: as one assignment,
/// f64's 512 bytes were a call to `memmove` at every step (2 % of the
/// spin–orbit MEGNO run).
#[inline(always)]
fn copy_lanes<R: Real>(to: &mut [R; LANES], from: &[R; LANES]) {
    const W: usize = 8;
    for (to, from) in to.chunks_exact_mut(W).zip(from.chunks_exact(W)) {
        let chunk: [R; W] = from.try_into().expect("a chunk");
        to.copy_from_slice(&chunk);
    }
}

/// The components of the vector at `vectors` (`(array, vector, lane)`,
/// at most 4) in `s`, then filler.
#[inline(always)]
fn components<'s, R: Real>(
    s: &'s TangentScratch<R>,
    vectors: &[(usize, usize, usize)],
) -> [&'s [R; LANES]; 4] {
    let mut u: [&[R; LANES]; 4] = [s.x.at(0); 4];
    for (j, &(_, k, lane)) in vectors.iter().enumerate() {
        u[j] = s.d[k].at(lane);
    }
    u
}

/// Whether every lane of `n2` is positive and normal, where the
/// logarithm of a waiting sample may read it (`sample_log_normal_r`).
#[inline(always)]
fn all_positive_normal<R: Real>(n2: &[R; LANES]) -> bool {
    let mut out = false;
    for x in n2 {
        out |= !x.positive_normal();
    }
    !out
}

/// The FLI/MEGNO vector at `vectors` in `s` and its octaves `octave`
/// rescaled as [`chaos_program`] rescales them after a sample of ‖u‖²
/// `n2`: u·2^a and E − a, a from `octave_r` (0 in the band, where u and E
/// stay as they are). Exact, and the same operations, so the same bits.
#[inline(always)]
fn rescale<R: Real>(
    s: &mut TangentScratch<R>,
    vectors: &[(usize, usize, usize)],
    octave: &mut [R; LANES],
    n2: &[R; LANES],
) {
    let mut scale = [R::from_f64(0.0); LANES];
    for i in 0..LANES {
        let a = R::octave_r(n2[i]);
        scale[i] = R::rescale_r(a);
        octave[i] -= a;
    }
    for &(_, k, lane) in vectors {
        let x = s.d[k].at_mut(lane);
        for i in 0..LANES {
            x[i] *= scale[i];
        }
    }
}

/// Whether ‖u‖² of the vector at `vectors` (`(array, vector, lane)`) is
/// in the band of `in_band_r` in every lane (the compiler may fuse its sum
/// otherwise than a sample program's: the band's margin covers that);
/// there a sample of one Lyapunov vector would leave everything as it is
/// but ‖u‖² (its octave is 0: it scales by 1, adds 0 octaves and keeps the
/// start slots; the next sample computes ‖u‖² from the same u), and so
/// would the FLI's but `fli_max` (whose band check is in its peak's pass,
/// [`Peak::keep`]). A run of steps takes those samples only where the vector leaves the
/// band, at the skip step and at the run's end, with the same bits as
/// every step: the one-exponent run 2.39× → 1.99× the plain run, the FLI
/// 2.91× → 2.34× (AVX-512 f32). The GPU kernel samples every step: the
/// FLI's wait made lavapipe slower (`gpu/codegen.rs`, where the FLI alone
/// takes a sample without MEGNO's sums instead).
#[inline(always)]
fn in_band<R: Real>(s: &TangentScratch<R>, vectors: &[(usize, usize, usize)]) -> bool {
    let mut n2 = [R::from_f64(0.0); LANES];
    for &(_, k, lane) in vectors {
        let x = s.d[k].at(lane);
        for i in 0..LANES {
            n2[i] += x[i] * x[i];
        }
    }
    let mut out = false;
    for i in 0..LANES {
        out |= !R::in_band_r(n2[i]);
    }
    !out
}

/// The FLI vector's largest ‖u‖² over the steps its sample waited, per
/// lane (0: none yet), computed as the sample program computes it
/// (`chaos_peak_program`), so that the fold gives `fli_max` the bits of
/// sampling each of those steps. (It kept the vector at that step and ran
/// the sample on it: 0.23 plain steps per step, the FLI run 2.04× the
/// plain run against 1.9×, Xeon AVX-512 f32.) On the heap, as the run's
/// other state: the stack of a run of steps holds the compiled tangent's
/// spills.
struct Peak<R> {
    n2: Box<[R; LANES]>,
    /// The maximum with the step's ‖u‖² before it is known whether the
    /// step's sample may wait.
    next: Box<[R; LANES]>,
    /// The step's ‖u‖², where the vector left the band.
    now: Box<[R; LANES]>,
}

impl<R: Real> Peak<R> {
    fn new() -> Peak<R> {
        Peak {
            n2: Box::new([R::from_f64(0.0); LANES]),
            next: Box::new([R::from_f64(0.0); LANES]),
            now: Box::new([R::from_f64(0.0); LANES]),
        }
    }

    /// The vector at `vectors` in `s` into the largest ‖u‖² if it is in
    /// the band in every lane (whether it is: then the sample waits), in
    /// one pass (a band check of its own cost the FLI 4 % of its run).
    #[inline(always)]
    fn keep(&mut self, s: &TangentScratch<R>, vectors: &[(usize, usize, usize)]) -> bool {
        let u = |j: usize| {
            let (_, k, lane) = vectors[j];
            s.d[k].at(lane)
        };
        let (next, n2) = (&mut *self.next, &*self.n2);
        let in_band = match vectors.len() {
            2 => sample_ops::chaos_peak_2(next, n2, u(0), u(1)),
            3 => sample_ops::chaos_peak_3(next, n2, u(0), u(1), u(2)),
            4 => sample_ops::chaos_peak_4(next, n2, u(0), u(1), u(2), u(3)),
            d => unreachable!("no compiled FLI sample of dimension {d}"),
        };
        if in_band {
            std::mem::swap(&mut self.n2, &mut self.next);
        }
        in_band
    }

    /// After a step whose FLI sample could not wait ([`Peak::keep`]: its
    /// vector at `vectors` in `s` left the band in some lane), where its
    /// ‖u‖² is positive and normal in every lane: that step joins the
    /// ones that waited, `fli_max` (array `max` of `buf`) is brought up to
    /// date from them all ([`Peak::fold`]), and the vector and `fli_oct`
    /// are rescaled as the sample would rescale them. The sample then
    /// changes nothing else that FLI reads, and is taken (true): ln‖w‖ is
    /// one logarithm per lane where the whole program after the fold took
    /// two. Spin–orbit cost scene, with [`Pending::take`]'s rescaling: the
    /// FLI f32 0.94× the time (7 pairs). (Folding only the chunks of 8
    /// lanes whose octaves move: 1.01× f32, 0.97× f64, not kept.)
    #[inline(always)]
    fn rescale(
        &mut self,
        s: &mut TangentScratch<R>,
        vectors: &[(usize, usize, usize)],
        buf: &mut [[R; LANES]],
        max: usize,
    ) -> bool {
        let d = vectors.len();
        sample_ops::chaos_n2(&mut self.now, &components(s, vectors)[..d]);
        if !all_positive_normal(&self.now) {
            return false;
        }
        std::mem::swap(&mut self.n2, &mut self.next);
        self.fold(buf, max, d);
        rescale(s, vectors, &mut buf[d], &self.now);
        true
    }

    /// Before the FLI sample (arrays `buf`, `fli_max` at `max`, `fli_oct`
    /// before it) after steps it waited: `fli_max` from the largest ‖u‖²
    /// (`chaos_fold_program`), as the samples at those steps would have
    /// made it. All lanes or none waited (a run waits only where every
    /// lane is in the band). Inlined into the run's instruction-set level:
    /// its logarithm's FMAs are libm calls below AVX2 (the FLI run 13 %
    /// slower, Zen 3 f32).
    #[inline(always)]
    fn fold(&mut self, buf: &mut [[R; LANES]], max: usize, octave: usize) {
        let zero = R::from_f64(0.0);
        if self.n2[0] == zero {
            return;
        }
        debug_assert!(octave < max);
        let (low, high) = buf.split_at_mut(max);
        sample_ops::chaos_fold(&mut high[0], &low[octave], &self.n2);
        *self.n2 = [zero; LANES];
    }
}

/// Where each sample's inputs and outputs are in a run of steps: `None`
/// unless the tangent takes the whole step compiled and every sample is
/// compiled. `slots`: the vectors' slots (vector k's component j at
/// k·d + j).
fn run_locs<R: Real>(
    slots: &[usize],
    c: Option<&CompiledTangent<R>>,
    samples: &[Program<R>],
    megno: bool,
) -> Option<Vec<RunLocs>> {
    let c = c.filter(|c| c.takes_step)?;
    let d = c.space.len();
    let at = |j: usize| match slots.iter().position(|&s| s == j) {
        Some(pos) => Loc::Vector(pos / d, c.space[pos % d]),
        None => Loc::Real(j),
    };
    samples
        .iter()
        .map(|p| {
            p.compiled?;
            // Output k is written over input k: the same slot.
            let over = |(k, &j): (usize, &usize)| p.inputs.get(k) == Some(&Src::Slot(j));
            if !p.outputs.iter().enumerate().all(over) {
                return None;
            }
            let inputs = p.inputs.iter().map(|src| match *src {
                Src::Slot(j) => Some(at(j)),
                Src::Count => Some(Loc::Count),
                Src::InvCount => Some(Loc::InvCount),
                Src::AtSkip => Some(Loc::AtSkip),
                _ => None,
            });
            let waits = match p.compiled.map(|(shape, _)| shape) {
                _ if p.every != 1 => Waits::Never,
                Some(SampleShape::Lyapunov { k: 1, .. }) => Waits::Lyapunov,
                Some(SampleShape::Chaos { d }) if !megno => Waits::Fli {
                    max: chaos_fli_max(d),
                },
                _ => Waits::Never,
            };
            let chaos = matches!(p.compiled, Some((SampleShape::Chaos { .. }, _)));
            Some(RunLocs::new(inputs.collect::<Option<_>>()?, waits, chaos))
        })
        .collect()
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

/// A sampler's program, its slots `first` on among the real slots,
/// compiled for `isa` where its shape is.
fn sampler<R: Real>(s: &Sampler, first: usize, isa: Isa) -> Program<R> {
    let inputs: Vec<Src> = s
        .inputs
        .iter()
        .map(|i| match *i {
            SampleInput::Slot(k) => Src::Slot(first + k),
            SampleInput::Count => Src::Count,
            SampleInput::InvCount => Src::InvCount,
            SampleInput::AtSkip => Src::AtSkip,
        })
        .collect();
    Program {
        tape: Tape::new(&s.program, |_| false),
        fills: fills(&inputs),
        inputs,
        outputs: s.outputs.iter().map(|k| first + k).collect(),
        every: s.every,
        compiled: sample_fn::<R>(s.shape, isa).map(|f| (s.shape, f)),
    }
}

/// The one-value inputs among `inputs`, each once.
fn fills(inputs: &[Src]) -> Vec<Src> {
    let mut f: Vec<Src> = vec![];
    for src in inputs {
        let one = matches!(src, Src::Step | Src::Count | Src::InvCount | Src::AtSkip);
        if one && !f.contains(src) {
            f.push(*src);
        }
    }
    f
}

/// The lanes still running (as bits: only their slots change) and the
/// instruction-set level.
#[derive(Clone, Copy)]
struct Call {
    running: u64,
    isa: Isa,
}

/// The values of [`Src::Step`], [`Src::Count`], [`Src::InvCount`] and
/// [`Src::AtSkip`].
#[derive(Clone, Copy)]
struct Scalars<R> {
    step: R,
    count: R,
    inv_count: R,
    at_skip: R,
}

impl<R: Real> Scalars<R> {
    /// Whether the sample is the skip step's (a compiled sample's flag).
    #[inline(always)]
    fn is_skip_step(&self) -> bool {
        self.at_skip != R::from_f64(0.0)
    }
}

/// Whether a sample taken every `every` steps is due after step `n1`:
/// every step without a division for `every = 1` (the default), which a
/// run of steps asks after each step.
#[inline(always)]
fn sampled_after(every: u64, n1: u64) -> bool {
    every == 1 || n1.is_multiple_of(every)
}

/// The number of the sample taken every `every` steps after step `n1`.
#[inline(always)]
fn sample_number(every: u64, n1: u64) -> u64 {
    match every {
        1 => n1,
        _ => n1 / every,
    }
}

/// 1/n in precision `R`, as the GPU computes it.
fn inv_count<R: Real>(n: u64) -> R {
    R::from_f64(1.0) / R::from_f64(n as f64)
}

/// Arrays for Step, Count, InvCount and AtSkip, after the registers.
const FILLS: usize = 4;

/// A program's inputs on a block, resolved per read (no list built per call).
struct View<'a, R> {
    p: &'a Program<R>,
    l: &'a Lanes<R>,
    prev: &'a [[R; LANES]],
    real: &'a [[R; LANES]],
    /// Step, Count, InvCount and AtSkip, as arrays (filled where read).
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
            Src::InvCount => &self.fills[2],
            Src::AtSkip => &self.fills[3],
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
            Src::InvCount => fills[2] = [s.inv_count; LANES],
            Src::AtSkip => fills[3] = [s.at_skip; LANES],
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
    if let Some((shape, f)) = p.compiled {
        let x = &mut regs[..p.inputs.len()];
        for (k, a) in x.iter_mut().enumerate() {
            *a = *view.array(k as u32);
        }
        // SAFETY: `sample_fn` compiled it for `at.isa`, which
        // `kernels::isa` names only where the CPU has its features.
        unsafe { on_arrays(f, shape, x, s.is_skip_step()) };
        for (&slot, out) in p.outputs.iter().zip(x.iter()) {
            put(&mut real[slot], out, at.running);
        }
        return;
    }
    p.tape.run(regs, &view, at.isa);
    // A lane that stopped or became non-finite keeps its indicators.
    for (k, &slot) in p.outputs.iter().enumerate() {
        put(&mut real[slot], p.tape.output(regs, k), at.running);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::cpu::sample_ops;

    /// Where [`in_band`] lets the sample of one Lyapunov vector wait, that
    /// sample changes nothing but ‖u‖² (which the next one recomputes from
    /// the same u), so waiting keeps the bits; and the band is that of the
    /// octaves less a margin, not empty.
    fn samples_wait_only_where_they_change_nothing<R: Real>() {
        let shape = SampleShape::Lyapunov { d: 2, k: 1 };
        let mut s = TangentScratch::new(&Lanes::<R>::boxed(), 1);
        let lanes = [index_of("q").unwrap(), index_of("s").unwrap()];
        let vectors = [(0, 0, lanes[0]), (1, 0, lanes[1])];
        for e in -45..=55 {
            for m in [1.0, 1.5, 1.99] {
                let norm = 2f64.powi(e) * m;
                let u = [0.6 * norm, 0.8 * norm].map(|x| [R::from_f64(x); LANES]);
                for (j, &lane) in lanes.iter().enumerate() {
                    *s.d[0].at_mut(lane) = u[j];
                }
                // u, E, ‖u‖², both at the skip step, not the skip step.
                let rest = [3.0, 0.5, -2.0, 0.25, 0.0].map(|x| [R::from_f64(x); LANES]);
                let before: Vec<[R; LANES]> = u.iter().chain(&rest).copied().collect();
                let mut x = before.clone();
                // SAFETY: the generated loop at the baseline level.
                unsafe { on_arrays(sample_ops::run::<R>, shape, &mut x, true) };
                let unchanged = (0..x.len()).filter(|&k| k != 3).all(|k| x[k] == before[k]);
                let waits = in_band(&s, &vectors);
                assert!(!waits || unchanged, "‖u‖ = {norm:e}");
                // ‖u‖² in [2⁻³⁹, 2⁵⁹]: ‖u‖ from 2^−19.5 to 2^29.5.
                let inside = (-18..=28).contains(&e);
                if inside || e <= -21 || e >= 30 {
                    assert_eq!(waits, inside, "‖u‖ = {norm:e}");
                }
            }
        }
    }

    #[test]
    fn samples_wait_only_where_they_change_nothing_f32() {
        samples_wait_only_where_they_change_nothing::<f32>();
    }

    #[test]
    fn samples_wait_only_where_they_change_nothing_f64() {
        samples_wait_only_where_they_change_nothing::<f64>();
    }

    /// A sample's ‖u‖² taken as a run of steps compiles it, with AVX2 and
    /// FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn take_v3<R: Real>(
        pending: &mut Pending<R>,
        s: &mut TangentScratch<R>,
        loc: &RunLocs,
        v: Scalars<R>,
        buf: &mut [[R; LANES]],
    ) -> bool {
        pending.take(s, loc, v, buf)
    }

    /// Samples' logarithms and sums brought up to date as a run of steps
    /// compiles them: where the octaves stay the same from one sample to
    /// the next, the compiler could take them out of the loop.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn flush_v3<R: Real>(pending: &mut Pending<R>, buf: &mut [[R; LANES]]) {
        pending.flush(0, buf)
    }

    /// FLI/MEGNO samples taken in two parts ([`Pending`]: ‖u‖² after each
    /// step, the vector rescaled where it left the band, ln‖w‖ and the sums
    /// when brought up to date) give the bits of the whole program taken
    /// after each step, with octaves other than 0, in and out of the band
    /// (AVX2/FMA, where contraction could tell them apart).
    #[cfg(target_arch = "x86_64")]
    fn pending_is_the_program<R: Real>() {
        if (crate::backend::cpu::kernels::isa() as u8) < (Isa::V3 as u8) {
            return;
        }
        let d = 2;
        let shape = SampleShape::Chaos { d };
        let whole = sample_fn::<R>(shape, Isa::V3).expect("a compiled sample");
        let lanes = [index_of("q").unwrap(), index_of("s").unwrap()];
        let loc = RunLocs {
            arrays: vec![],
            vectors: vec![(0, 0, lanes[0]), (1, 0, lanes[1])],
            scalars: vec![],
            waits: Waits::Never,
            chaos: true,
        };
        // u, fli_oct, fli_log, fli_max, megno_sum, megno_mean, n, 1/n.
        let mut want = vec![[R::from_f64(0.0); LANES]; d + 7];
        for i in 0..LANES {
            want[d][i] = R::from_f64(i as f64 - 20.0);
            want[d + 1][i] = R::from_f64(0.3 * i as f64 - 5.0);
            want[d + 2][i] = R::from_f64(-3.0);
            want[d + 3][i] = R::from_f64(0.01 * i as f64);
            want[d + 4][i] = R::from_f64(1.5);
        }
        let mut got = want.clone();
        let mut s = TangentScratch::new(&Lanes::<R>::boxed(), 1);
        let mut spare = vec![[R::from_f64(0.0); LANES]; 2 * LANES];
        let mut pending = Pending::new(std::slice::from_ref(&loc), &mut spare);
        let mut rescaled = 0;
        for n in 1..=9 {
            let count = R::from_f64(n as f64);
            let inv_count = R::from_f64(1.0) / count;
            for i in 0..LANES {
                let a = 0.37 * (n * 5 + i) as f64;
                // ‖u‖ from 2⁻³⁰ to 2³⁰: out of the band in some lanes.
                let norm = 2f64.powf(((n * 13 + i * 7) % 121) as f64 / 2.0 - 30.0);
                want[0][i] = R::from_f64(a.cos() * norm);
                want[1][i] = R::from_f64(a.sin() * norm);
            }
            for (j, &lane) in lanes.iter().enumerate() {
                *s.d[0].at_mut(lane) = want[j];
            }
            want[d + 5] = [count; LANES];
            want[d + 6] = [inv_count; LANES];
            let octaves = want[d];
            // SAFETY: AVX2 and FMA were checked above.
            unsafe { on_arrays(whole, shape, &mut want, false) };
            let v = Scalars {
                step: count,
                count,
                inv_count,
                at_skip: R::from_f64(0.0),
            };
            // SAFETY: as above.
            let waits = unsafe { take_v3(&mut pending, &mut s, &loc, v, &mut got) };
            assert!(waits, "sample {n}: ‖u‖² positive and normal");
            rescaled += rescaled_as_the_program(&s, &lanes, &want, &got, &octaves, n);
        }
        assert!(rescaled > 50, "{rescaled} lanes rescaled");
        // SAFETY: as above.
        unsafe { flush_v3(&mut pending, &mut got) };
        for k in d..d + 5 {
            for i in 0..LANES {
                let bits = |a: &[[R; LANES]]| a[k][i].to_f64().to_bits();
                assert_eq!(bits(&got), bits(&want), "array {k} lane {i}");
            }
        }
    }

    /// After sample `n`: the vector in `s` (at `lanes`) and the octaves in
    /// `got` are the whole program's (`want`, whose octaves were
    /// `octaves` before it), bit for bit; how many lanes it rescaled.
    fn rescaled_as_the_program<R: Real>(
        s: &TangentScratch<R>,
        lanes: &[usize],
        want: &[[R; LANES]],
        got: &[[R; LANES]],
        octaves: &[R; LANES],
        n: usize,
    ) -> usize {
        let d = lanes.len();
        let bits = |a: &[R; LANES]| a.map(|x| x.to_f64().to_bits());
        for (j, &lane) in lanes.iter().enumerate() {
            assert_eq!(bits(s.d[0].at(lane)), bits(&want[j]), "sample {n} u{j}");
        }
        assert_eq!(bits(&got[d]), bits(&want[d]), "sample {n} fli_oct");
        (0..LANES).filter(|&i| want[d][i] != octaves[i]).count()
    }

    /// The FLI's waiting samples as a run of steps compiles them.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn peak_v3<R: Real>(
        peak: &mut Peak<R>,
        s: &mut TangentScratch<R>,
        vectors: &[(usize, usize, usize)],
        buf: &mut [[R; LANES]],
        max: usize,
    ) -> bool {
        peak.keep(s, vectors) || peak.rescale(s, vectors, buf, max)
    }

    /// [`Peak::fold`] as a run of steps compiles it.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn fold_v3<R: Real>(peak: &mut Peak<R>, buf: &mut [[R; LANES]], max: usize, d: usize) {
        peak.fold(buf, max, d)
    }

    /// The FLI's samples that wait ([`Peak`]: the largest ‖u‖² kept, folded
    /// into `fli_max` where the vector is rescaled and at the end) give the
    /// whole program's `fli_max`, `fli_oct` and vectors, bit for bit, with
    /// lanes that stay in the band and lanes that leave it (AVX2/FMA).
    #[cfg(target_arch = "x86_64")]
    fn peak_is_the_program<R: Real>() {
        if (crate::backend::cpu::kernels::isa() as u8) < (Isa::V3 as u8) {
            return;
        }
        let d = 2;
        let shape = SampleShape::Chaos { d };
        let whole = sample_fn::<R>(shape, Isa::V3).expect("a compiled sample");
        let lanes = [index_of("q").unwrap(), index_of("s").unwrap()];
        let vectors = [(0, 0, lanes[0]), (1, 0, lanes[1])];
        let max = crate::plan::indicators::chaos_fli_max(d);
        let mut want = vec![[R::from_f64(0.0); LANES]; d + 7];
        for i in 0..LANES {
            want[d][i] = R::from_f64(i as f64 - 20.0);
            want[d + 2][i] = R::from_f64(-30.0);
        }
        let mut got = want.clone();
        let mut s = TangentScratch::new(&Lanes::<R>::boxed(), 1);
        let mut peak = Peak::new();
        let mut rescaled = 0;
        for n in 1..=40 {
            let count = R::from_f64(n as f64);
            for i in 0..LANES {
                let a = 0.37 * (n * 5 + i) as f64;
                // The first half of the lanes in the band, the rest
                // from 2⁻³⁰ to 2³⁰.
                let (range, low) = if i < LANES / 2 {
                    (61, 15.0)
                } else {
                    (121, 30.0)
                };
                let norm = 2f64.powf(((n * 13 + i * 7) % range) as f64 / 2.0 - low);
                want[0][i] = R::from_f64(a.cos() * norm);
                want[1][i] = R::from_f64(a.sin() * norm);
            }
            for (j, &lane) in lanes.iter().enumerate() {
                *s.d[0].at_mut(lane) = want[j];
            }
            want[d + 5] = [count; LANES];
            want[d + 6] = [R::from_f64(1.0) / count; LANES];
            let octaves = want[d];
            // SAFETY: AVX2 and FMA were checked above.
            unsafe { on_arrays(whole, shape, &mut want, false) };
            // SAFETY: as above.
            let waits = unsafe { peak_v3(&mut peak, &mut s, &vectors, &mut got, max) };
            assert!(waits, "sample {n}: ‖u‖² positive and normal");
            rescaled += rescaled_as_the_program(&s, &lanes, &want, &got, &octaves, n);
        }
        assert!(rescaled > 50, "{rescaled} lanes rescaled");
        // SAFETY: as above.
        unsafe { fold_v3(&mut peak, &mut got, max, d) };
        for i in 0..LANES {
            let bits = |a: &[[R; LANES]]| a[max][i].to_f64().to_bits();
            assert_eq!(bits(&got), bits(&want), "fli_max lane {i}");
        }
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn peak_samples_are_the_program() {
        peak_is_the_program::<f32>();
        peak_is_the_program::<f64>();
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn pending_samples_are_the_program() {
        pending_is_the_program::<f32>();
        pending_is_the_program::<f64>();
    }
}
