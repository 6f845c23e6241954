//! A stop condition on a recorded run (`cpu::Walk::recorded_runs`): the
//! condition evaluated once for all the run's steps, on lanes as wide as
//! the run, so the interpreter's dispatch is paid once per run instead of
//! once per step, and its part that no step changes (what it computes from
//! the parameters) once per block; then each lane's first step at whose
//! end it holds. The same operations on the same values as one evaluation
//! per step, so the same verdicts.

// Lane loops index several arrays by lane; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use crate::models::lanes::{index_of, Lanes, LANES};
use crate::num::formula::stage::{split, Vary};
use crate::num::formula::tape::{Inputs, Tape};
use crate::num::precision::Real;

use super::formula::{holds_at, Condition};
use super::kernels::{Isa, Recorded, RECORDED};

/// The lanes of a whole recorded run: step j's lane i is `j·LANES + i`.
pub const WIDE: usize = LANES * RECORDED;

/// What one input of the condition reads on a recorded run.
#[derive(Clone, Copy)]
enum Source {
    /// State variable k of the plan, as the run recorded it.
    Var(usize),
    /// Time at the end of each step.
    Time,
    /// A lane the steps do not change (a parameter), the same at every step.
    Fixed(usize),
    /// An input the program does not read.
    Unread,
}

/// The condition's inputs and registers on the lanes of a recorded run.
pub struct RunStops<R> {
    /// What each input of `per_step` reads: the condition's inputs, then
    /// the outputs of its fixed part.
    sources: Vec<Source>,
    fixed: Vec<Box<[R; WIDE]>>,
    time: Option<Box<[R; WIDE]>>,
    /// The condition's part that varies from step to step.
    per_step: Tape<R>,
    regs: Vec<[R; WIDE]>,
}

/// A lane array repeated for every step of a run.
fn repeated<R: Real>(x: &[R; LANES]) -> Box<[R; WIDE]> {
    let mut out = Box::new([R::default(); WIDE]);
    for j in 0..RECORDED {
        out[j * LANES..][..LANES].copy_from_slice(x);
    }
    out
}

/// The inputs of one run: its recorded states, the time of its steps and
/// the fixed lanes.
struct RunInputs<'a, R> {
    sources: &'a [Source],
    after: &'a [Recorded<R>],
    time: Option<&'a [R; WIDE]>,
    fixed: &'a [Box<[R; WIDE]>],
}

impl<R: Real> Inputs<R, WIDE> for RunInputs<'_, R> {
    #[inline(always)]
    fn array(&self, k: u32) -> &[R; WIDE] {
        match self.sources[k as usize] {
            Source::Var(v) => wide(&self.after[v]),
            Source::Time => self.time.expect("the time of the run's steps"),
            Source::Fixed(f) => &self.fixed[f],
            Source::Unread => wide(&self.after[0]),
        }
    }
    #[inline(always)]
    fn scalar(&self, k: u32) -> R {
        self.array(k)[0]
    }
}

/// A variable's recorded run as one array of [`WIDE`] lanes.
fn wide<R>(x: &Recorded<R>) -> &[R; WIDE] {
    x.as_flattened()
        .try_into()
        .expect("RECORDED steps of LANES lanes")
}

impl<R: Real> RunStops<R> {
    /// For `stop` on a block whose lanes are `l` (what the steps do not
    /// change is read from them once, and what the condition computes from
    /// that alone, the parameters' part, computed once, at level `isa`);
    /// `vars`: the lane of each state variable.
    pub fn new(stop: &Condition<R>, vars: &[usize], l: &Lanes<R>, isa: Isa) -> Self {
        let t = index_of("t");
        let mut fixed = vec![];
        let lanes = stop.lanes_read();
        let mut sources = (lanes.iter())
            .map(|&lane| match lane {
                None => Source::Unread,
                Some(lane) if Some(lane) == t => Source::Time,
                Some(lane) => match vars.iter().position(|&v| v == lane) {
                    Some(k) => Source::Var(k),
                    None => {
                        fixed.push(repeated(l.at(lane)));
                        Source::Fixed(fixed.len() - 1)
                    }
                },
            })
            .collect::<Vec<_>>();
        // The program split by what varies from step to step: its fixed
        // part's outputs follow the inputs (`num/formula/stage.rs`).
        let vary: Vec<Vary> = (sources.iter())
            .map(|s| Vary {
                lane: true,
                step: matches!(s, Source::Var(_) | Source::Time),
            })
            .collect();
        let staged = split(stop.program(), &vary);
        let once = Tape::<R>::new(&staged.fixed, |_| false);
        let inputs: Vec<&[R; LANES]> = lanes.iter().map(|k| l.at(k.unwrap_or(0))).collect();
        let mut regs = vec![[R::default(); LANES]; once.registers];
        once.run(&mut regs, &inputs[..], isa);
        for k in 0..once.outputs() {
            fixed.push(repeated(once.output(&regs, k)));
            sources.push(Source::Fixed(fixed.len() - 1));
        }
        let per_step = Tape::new(&staged.lane, |_| false);
        let reads_time = sources.iter().any(|s| matches!(s, Source::Time));
        RunStops {
            sources,
            fixed,
            time: reads_time.then(|| Box::new([R::default(); WIDE])),
            regs: vec![[R::default(); WIDE]; per_step.registers],
            per_step,
        }
    }

    /// Each lane's first step of the run from step `n` (`after`: the
    /// states it recorded, `done` steps) at whose end `stop` holds, for
    /// the block's first `count` lanes that still run (`status` 0);
    /// [`RECORDED`] where it holds at none. The lane loops at the kernels'
    /// level `isa` (they only compare; time's arithmetic stays baseline).
    #[allow(clippy::too_many_arguments)]
    pub fn first(
        &mut self,
        stop: &Condition<R>,
        l: &Lanes<R>,
        after: &[Recorded<R>],
        n: u64,
        done: usize,
        status: &[u64; LANES],
        count: usize,
        isa: Isa,
    ) -> [u8; LANES] {
        if let Some(t) = self.time.as_deref_mut() {
            run_time(t, l, n, done);
        }
        let input = RunInputs {
            sources: &self.sources,
            after,
            time: self.time.as_deref(),
            fixed: &self.fixed,
        };
        self.per_step.run(&mut self.regs, &input, isa);
        let g = self.per_step.output(&self.regs, 0);
        let sign = stop.sign();
        let mut first = {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the kernels' level is one `isa()` found on this CPU.
            match isa {
                Isa::V4 => unsafe { first_v4(g, done, sign) },
                Isa::V3 => unsafe { first_v3(g, done, sign) },
                Isa::Baseline => first_holding(g, done, sign),
            }
            #[cfg(not(target_arch = "x86_64"))]
            first_holding(g, done, sign)
        };
        for i in 0..LANES {
            if i >= count || status[i] != 0 {
                first[i] = RECORDED as u8;
            }
        }
        first
    }
}

/// Each lane's first of `done` steps where a condition of comparison
/// `sign` ([`Condition::sign`]) holds on `g`, [`RECORDED`] where none: from
/// the last step back, so that the first is kept, one select per lane and
/// step.
#[inline(always)]
fn first_holding<R: Real>(g: &[R; WIDE], done: usize, sign: (R, bool)) -> [u8; LANES] {
    let mut first = [RECORDED as u8; LANES];
    for j in (0..done).rev() {
        let g = &g[j * LANES..][..LANES];
        for i in 0..LANES {
            first[i] = if holds_at(sign, g[i]) {
                j as u8
            } else {
                first[i]
            };
        }
    }
    first
}

/// [`first_holding`] for AVX-512.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx2,fma")]
unsafe fn first_v4<R: Real>(g: &[R; WIDE], done: usize, sign: (R, bool)) -> [u8; LANES] {
    first_holding(g, done, sign)
}

/// [`first_holding`] for AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn first_v3<R: Real>(g: &[R; WIDE], done: usize, sign: (R, bool)) -> [u8; LANES] {
    first_holding(g, done, sign)
}

/// Time at the end of each of the `done` steps of a run from step `n`, on
/// the lanes of `l`, as `cpu::stop_lanes` computes it. Never inlined: its
/// arithmetic stays that of the baseline build (no contraction into FMA).
#[inline(never)]
fn run_time<R: Real>(t: &mut [R; WIDE], l: &Lanes<R>, n: u64, done: usize) {
    for j in 0..done {
        let nf = R::from_f64((n + j as u64 + 1) as f64);
        for i in 0..LANES {
            t[j * LANES + i] = l.t0[i] + nf * l.dt[i];
        }
    }
}
