//! The CPU's fused S2 stages: one stage `D½ P1½ P2½ P3 P2½ P1½ D½` applied to
//! a whole block in one loop (which the compiler vectorises), built from a
//! model's [`Pieces`]; a run of steps of such stages in one call, compiled for
//! three instruction-set levels and chosen at run time.

use crate::models::lanes::{Lane, Lanes, LANES};
use crate::models::pieces::{Pieces, PiecesVisitor, Saved, MAX_VARS};
use crate::models::Model;
pub use crate::num::isa::Isa;
use crate::num::precision::{in_precision, Real};
use crate::plan::Plan;

/// A stage's weights: `(w/2, w, time offset c)`.
pub type Weights<R> = (R, R, R);

/// A run of steps over a block: `(lanes, stages, n, k, time_terms)` takes
/// steps `n … n+k−1`, each the stages in order; `time_terms`: whether the
/// [`time::SHARED`] mode evaluates the model's time ops (a plan without time
/// shares only `dt`). Returns how many steps it took — fewer than `k` when
/// one left some lane non-finite (the last stage's verdict is the step's) —
/// and whether the last one did; `record`, if given, receives the state
/// after each step. Unsafe to call: the variants compiled for AVX2/FMA and
/// AVX-512 need those features.
pub type StepsFn<R> =
    unsafe fn(&mut Lanes<R>, &[Weights<R>], u64, u64, bool, Option<&mut Record<R>>) -> (u64, bool);

/// Where a run of steps leaves the block's state after each of its steps,
/// for observers that look at every step: they then read the run's states
/// after it, and the step runs as many steps per call as when nobody looks.
/// A recorded run takes at most [`RECORDED`] steps.
pub struct Record<'a, R> {
    /// Lane index of each state variable recorded, in the plan's order.
    pub vars: &'a [usize],
    /// `after[k][j]`: variable `vars[k]` after the run's step j.
    pub after: &'a mut [Recorded<R>],
}

/// The most steps a recorded run takes: a quarter of a pause's distance,
/// so that their states stay in the core's first-level cache (16 × 5 × 64
/// f64: 40 KB).
pub const RECORDED: usize = 16;

/// One variable over a recorded run: its lanes after each step, one step
/// after another (so a run's values of a variable are one array).
pub type Recorded<R> = [[R; LANES]; RECORDED];

impl<R: Real> Record<'_, R> {
    /// Copies the state after the run's step `j`.
    #[inline(always)]
    fn take(&mut self, l: &Lanes<R>, j: u64) {
        for (to, &v) in self.after.iter_mut().zip(self.vars) {
            to[j as usize] = *l.at(v);
        }
    }
}

/// How a stage gets its time terms.
pub mod time {
    /// The model reads no time.
    pub const NONE: u8 = 0;
    /// Every trajectory evaluates its own.
    pub const PER_LANE: u8 = 1;
    /// The ensemble shares them (`t0`, `dt` and the time ops' inputs one
    /// value): evaluated once on the first lane, and every lane takes them
    /// (with `dt`) as values the loop does not vary, so the compiler also
    /// hoists what the pieces compute from time terms alone (the damping's
    /// `exp` of the spin–orbit A piece). A plan without time shares `dt`
    /// alone this way (every τ then a loop invariant).
    pub const SHARED: u8 = 2;
}

/// Steps `n … n+k−1` on every lane (see [`StepsFn`]): one call for a run of
/// steps no observer looks at, so the core overlaps the end of one step's
/// lanes with the start of the next's, and no call, return or observer
/// check comes between them.
///
/// A run of several steps is checked for non-finite values once, at its end
/// (the check on every step cost a quarter of van der Pol's step at AVX2).
/// That finds every lane that left the finite numbers inside the run: every
/// piece moves a variable by adding to it or scaling it (`v + x`, `v·x`,
/// `(v ⊕ x)/d`), so ±∞ and NaN stay non-finite
/// (`tests/suite/cpu.rs::non_finite_states_stay_non_finite`). Only then is the run
/// repeated from a copy of its start, checking after each step, to find the
/// step: the same operations, so the same bits and the same verdict as
/// checking every step.
///
/// A run that records its states goes through [`steps`] alone, which takes
/// them; a rerun records them again, the same.
///
/// A scheme of one stage (S2, the sweeps' workhorse) runs its unchecked
/// steps in a loop of its own: the stage's weights are then loop
/// invariants, so what the pieces compute from them and the lanes' fixed
/// inputs (τ, τε, τ·forcing) is computed once per run instead of once per
/// step (van der Pol S2 +4.5 % at AVX2 f32 on Zen 5). Every other run — a
/// scheme of several stages, the checked pass — goes through one loop,
/// [`steps`], which checks after each step only when asked. So each kernel
/// holds the stage's code twice, not three times (three copies and every
/// lane count compiled made the library's build take 15 GB and 7 minutes;
/// a third copy for the single-stage loop alone, a minute more).
#[inline(always)]
fn fused_steps_body<
    R: Real,
    P: Pieces<R>,
    const P1: char,
    const P2: char,
    const P3: char,
    const OPT: bool,
    const TIME: u8,
    const VEC: usize,
>(
    l: &mut Lanes<R>,
    stages: &[Weights<R>],
    n: u64,
    k: u64,
    time_terms: bool,
    mut record: Option<&mut Record<R>>,
) -> (u64, bool) {
    // A single step's run is checked as it goes; a longer one first runs
    // unchecked, and again from its start, checked, only if it ended with
    // some lane non-finite. Only a longer run copies its start (a copy on
    // every single step would cost the runs that observers stop at each step).
    let mut frame = FrameAlign([0; 64]);
    std::hint::black_box(&mut frame);
    let mut check = k == 1;
    let mut start: Option<Saved<R>> = None;
    if !check {
        P::save(l, start.insert([[R::default(); LANES]; MAX_VARS]));
        if let ([(h, f, c)], None) = (stages, &record) {
            let (h, f, c) = (*h, *f, *c);
            for j in 0..k {
                let nf = R::from_f64((n + j) as f64);
                fused_stage_body::<R, P, P1, P2, P3, OPT, TIME, VEC>(l, h, f, c, nf, time_terms);
            }
            if all_finite::<R, P>(l) {
                return (k, false);
            }
            restore::<R, P>(l, &start);
            check = true;
        }
    }
    // One call site, `check` known only at run time: the loop is compiled
    // once (a call with `false` and one with `true` would be two copies).
    loop {
        let rec = record.as_deref_mut();
        let done =
            steps::<R, P, P1, P2, P3, OPT, TIME, VEC>(l, stages, n, k, time_terms, check, rec);
        if check || all_finite::<R, P>(l) {
            return done;
        }
        restore::<R, P>(l, &start);
        check = true;
    }
}

/// Puts back the block's state at the start of the run, if it was copied.
#[inline(always)]
fn restore<R: Real, P: Pieces<R>>(l: &mut Lanes<R>, start: &Option<Saved<R>>) {
    if let Some(s) = start {
        P::restore(l, s);
    }
}

/// A 64-byte-aligned local that the kernel must keep in memory: it makes
/// the kernel realign its stack frame, so the vector spill slots of the
/// stage loops are aligned too. Without it their alignment followed the
/// caller's stack pointer, and 32-byte spills straddling cache lines made
/// the same loop 2–4 % slower or faster from one build to the next (AVX2
/// f32 on Zen 5).
#[repr(C, align(64))]
struct FrameAlign([u8; 64]);

/// Steps `n … n+k−1`, each the stages in order; `check`: look for
/// non-finite lanes after every step and stop after the first step that
/// left some (a single step's run, and the search for that step);
/// `record`: take the state after each step.
#[inline(always)]
fn steps<
    R: Real,
    P: Pieces<R>,
    const P1: char,
    const P2: char,
    const P3: char,
    const OPT: bool,
    const TIME: u8,
    const VEC: usize,
>(
    l: &mut Lanes<R>,
    stages: &[Weights<R>],
    n: u64,
    k: u64,
    time_terms: bool,
    check: bool,
    mut record: Option<&mut Record<R>>,
) -> (u64, bool) {
    for j in 0..k {
        step::<R, P, P1, P2, P3, OPT, TIME, VEC>(l, stages, n + j, time_terms);
        if let Some(r) = record.as_deref_mut() {
            r.take(l, j);
        }
        if check && !all_finite::<R, P>(l) {
            return (j + 1, true);
        }
    }
    (k, false)
}

/// Step `n` on every lane: each stage in order.
#[inline(always)]
fn step<
    R: Real,
    P: Pieces<R>,
    const P1: char,
    const P2: char,
    const P3: char,
    const OPT: bool,
    const TIME: u8,
    const VEC: usize,
>(
    l: &mut Lanes<R>,
    stages: &[Weights<R>],
    n: u64,
    time_terms: bool,
) {
    let nf = R::from_f64(n as f64);
    for &(h, f, c) in stages {
        fused_stage_body::<R, P, P1, P2, P3, OPT, TIME, VEC>(l, h, f, c, nf, time_terms);
    }
}

/// Are the model's state variables finite in every lane of the block?
#[inline(always)]
fn all_finite<R: Real, P: Pieces<R>>(l: &Lanes<R>) -> bool {
    let mut bad = R::Flag::default();
    for i in 0..LANES {
        bad |= (!P::finite(&Lane::gather(l, i))).into();
    }
    bad == R::Flag::default()
}

/// One stage `D½ P1½ P2½ P3 P2½ P1½ D½` of weight w on every lane:
/// `half = w/2`, `full = w` (times dt), time terms at `t0 + (n + c) dt`.
#[inline(always)]
fn fused_stage_body<
    R: Real,
    P: Pieces<R>,
    const P1: char,
    const P2: char,
    const P3: char,
    const OPT: bool,
    const TIME: u8,
    const VEC: usize,
>(
    l: &mut Lanes<R>,
    half: R,
    full: R,
    c: R,
    nf: R,
    time_terms: bool,
) {
    let mut shared = Lane::default();
    if TIME == time::SHARED {
        shared = Lane::gather(l, 0);
        shared.t = shared.t0 + nf * shared.dt + c * shared.dt;
        if time_terms {
            P::time(&mut shared);
        }
    }
    // Several lanes, a fraction of a block apart, per iteration: once
    // vectorised, independent chains that the core overlaps (one stage is a
    // long dependent chain, exp's polynomial most of it). How many: see
    // [`interleave`].
    macro_rules! interleaved {
        ($($x:ident $k:literal),*) => {{
            const WAYS: usize = [$($k),*].len();
            for i in 0..LANES / WAYS {
                $( let mut $x = Lane::gather(l, i + $k * LANES / WAYS); )*
                if TIME == time::SHARED {
                    $( P::share_time(&mut $x, &shared); )*
                }
                $( stage::<R, P, P1, P2, P3, OPT, TIME>(&mut $x, half, full, c, nf); )*
                $( $x.scatter_state(l, i + $k * LANES / WAYS); )*
            }
        }};
    }
    // A constant block: only the arm taken is compiled.
    match const { interleave::<R>(P::VARS, VEC, OPT || TIME == time::PER_LANE) } {
        8 => interleaved!(x 0, y 1, z 2, w 3, a 4, b 5, d 6, e 7),
        4 => interleaved!(x 0, y 1, z 2, w 3),
        _ => interleaved!(x 0, y 1),
    }
}

/// Lanes per iteration of a fused stage (see [`fused_stage_body`]) for a
/// model of `vars` state variables in vectors of `vec` bytes; `heavy`: the
/// stage also carries the optional variable or evaluates the time terms
/// per trajectory. One whole vector per lane's chain, up to eight chains,
/// where the state is small. Measured on Zen 4, eight against four, medians
/// of 5 pairs: AVX2 f32 van der Pol S2 +5 %, with `p` +13 %, Yoshida 6A
/// +19 %, spin–orbit +12 % (its time terms per trajectory: −1 %); AVX-512
/// f64 van der Pol S2 +9 to +13 %, spin–orbit +15 %, with `p` +1 % (so its
/// heavy stages keep four: a smaller build). AVX2 f64 keeps four (16 registers, twice exp's
/// constants: eight spill, 2 % slower), AVX-512 f32 four (eight would split
/// its vectors: −25 %). Two where more would spill (Kepler's five
/// variables: −9 % with four); four in the baseline build (two: van der Pol
/// f32 −5 %).
const fn interleave<R>(vars: usize, vec: usize, heavy: bool) -> usize {
    let per_vector = vec / std::mem::size_of::<R>();
    let chains = LANES / per_vector;
    let avx2_f64 = vec == 32 && std::mem::size_of::<R>() == 8;
    if vars > 3 {
        2
    } else if vec <= 16 {
        4
    } else if chains >= 8 && !avx2_f64 && (!heavy || vec == 32) {
        8
    } else if chains >= 4 {
        4
    } else {
        2
    }
}

/// The stage on one trajectory.
#[inline(always)]
fn stage<
    R: Real,
    P: Pieces<R>,
    const P1: char,
    const P2: char,
    const P3: char,
    const OPT: bool,
    const TIME: u8,
>(
    x: &mut Lane<R>,
    half: R,
    full: R,
    c: R,
    nf: R,
) {
    if TIME == time::PER_LANE {
        x.t = x.t0 + nf * x.dt + c * x.dt;
        P::time(x);
    }
    x.tau = half * x.dt;
    P::piece::<OPT>(P1, x);
    P::piece::<OPT>(P2, x);
    x.tau = full * x.dt;
    P::piece::<OPT>(P3, x);
    x.tau = half * x.dt;
    P::piece::<OPT>(P2, x);
    P::piece::<OPT>(P1, x);
}

/// Declares a [`StepsFn`] variant of [`fused_steps_body`], compiled with
/// the given attributes (its instruction-set level).
macro_rules! steps_variant {
    ($(#[$m:meta])* $name:ident, $vec:literal) => {
        $(#[$m])*
        pub unsafe fn $name<
            R: Real,
            P: Pieces<R>,
            const P1: char,
            const P2: char,
            const P3: char,
            const OPT: bool,
            const TIME: u8,
        >(
            l: &mut Lanes<R>,
            stages: &[Weights<R>],
            n: u64,
            k: u64,
            time_terms: bool,
            record: Option<&mut Record<R>>,
        ) -> (u64, bool) {
            fused_steps_body::<R, P, P1, P2, P3, OPT, TIME, $vec>(l, stages, n, k, time_terms, record)
        }
    };
}

// Each level in a module of its own, so that each gets a codegen unit of
// its own: rustc places a generic function's instances by the module that
// defines it, and the three levels in one unit were the largest module
// LLVM held (a third of the crate's optimised IR) while it worked on it.
mod baseline {
    use super::*;
    steps_variant! {
        /// [`fused_steps_body`] for any x86-64 (or other) CPU.
        ///
        /// # Safety
        /// None required; `unsafe` only to share [`StepsFn`] with the wide variants.
        fused_steps, 16
    }
}
pub use baseline::fused_steps;

#[cfg(target_arch = "x86_64")]
mod v3 {
    use super::*;
    steps_variant! {
        /// [`fused_steps_body`] compiled for AVX2 and FMA (x86-64-v3).
        ///
        /// # Safety
        /// The CPU must support AVX2 and FMA.
        #[target_feature(enable = "avx2,fma")]
        fused_steps_v3, 32
    }
}
#[cfg(target_arch = "x86_64")]
pub use v3::fused_steps_v3;

#[cfg(target_arch = "x86_64")]
mod v4 {
    use super::*;
    steps_variant! {
        /// [`fused_steps_body`] compiled for AVX-512 (x86-64-v4): twice the lanes
        /// per instruction and 32 vector registers, so constants stay in registers.
        ///
        /// # Safety
        /// The CPU must support AVX-512 F, VL, DQ and BW, AVX2 and FMA.
        #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx2,fma")]
        fused_steps_v4, 64
    }
}
#[cfg(target_arch = "x86_64")]
pub use v4::fused_steps_v4;

/// The values `REEB_CPU_ISA` may take.
pub const ISA_CAPS: &[&str] = &["baseline", "v3", "v4"];

/// Why `REEB_CPU_ISA` is unusable, if it is set to something unknown.
pub fn isa_cap_error() -> Option<String> {
    let cap = std::env::var("REEB_CPU_ISA").ok()?;
    (!cap.is_empty() && !ISA_CAPS.contains(&cap.as_str())).then(|| {
        format!(
            "REEB_CPU_ISA={cap:?} is not one of {} (unset it to use the best level this CPU runs)",
            ISA_CAPS.join(", ")
        )
    })
}

/// The best kernel level this CPU runs; `REEB_CPU_ISA=baseline|v3|v4` caps it.
pub fn isa() -> Isa {
    let cap = std::env::var("REEB_CPU_ISA").unwrap_or_default();
    if cap == "baseline" {
        return Isa::Baseline;
    }
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        let v3 = has!("avx2") && has!("fma");
        let v4 = v3 && has!("avx512f") && has!("avx512vl") && has!("avx512dq") && has!("avx512bw");
        if v4 && cap != "v3" {
            Isa::V4
        } else if v3 {
            Isa::V3
        } else {
            Isa::Baseline
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Isa::Baseline
    }
}

/// The piece order the fused kernels are compiled for in every shape:
/// every model's default, `CBABC` (`D = C`, then B, then A in the middle).
/// The other five orders of S2, which no shipped scene uses, have kernels
/// for AVX2/FMA alone, for ensembles that share their time ([`other_order`]), and run
/// through the plan's ops elsewhere (`cpu::run_ops`): every order in every
/// shape at every level was 1512 kernels and three quarters of the
/// library's machine code (now 252 + 140).
pub const FUSED_ORDER: [char; 3] = ['C', 'B', 'A'];

/// The fused steps for a piece order, optional variable and time, or `None`
/// where none is compiled: an order that is not a permutation of A, B, C,
/// or one other than [`FUSED_ORDER`] in a shape [`other_order`] does not
/// take.
pub fn steps_fn<R: Real, P: Pieces<R>>(
    order: [char; 3],
    opt: bool,
    time: u8,
    isa: Isa,
) -> Option<StepsFn<R>> {
    match order == FUSED_ORDER {
        true => default_order::<R, P>(opt, time, isa),
        false => other_order::<R, P>(order, opt, time, isa),
    }
}

/// The kernels of another piece order than [`FUSED_ORDER`] for the plans
/// sweeps make, whose ensemble shares `t0` and `dt` ([`time::SHARED`]: the
/// time terms once per block), in AVX2/FMA. Any other plan, and any below
/// AVX2, runs the ops (their lane loops compiled for the baseline, without
/// FMA: spin–orbit 3 · 10⁷ trajectory-steps/s against 3 · 10⁸ with its time
/// terms per trajectory in this kernel).
fn other_order<R: Real, P: Pieces<R>>(
    order: [char; 3],
    opt: bool,
    time: u8,
    isa: Isa,
) -> Option<StepsFn<R>> {
    #[cfg(target_arch = "x86_64")]
    {
        if isa == Isa::Baseline || time != time::SHARED {
            return None;
        }
        macro_rules! pick {
            ($($a:literal $b:literal $c:literal),*) => {
                match (order, opt) {
                    $(
                        ([$a, $b, $c], false) => Some(fused_steps_v3::<R, P, $a, $b, $c, false, { time::SHARED }> as StepsFn<R>),
                        ([$a, $b, $c], true) => Some(fused_steps_v3::<R, P, $a, $b, $c, true, { time::SHARED }> as StepsFn<R>),
                    )*
                    _ => None,
                }
            };
        }
        pick!('A' 'B' 'C', 'A' 'C' 'B', 'B' 'A' 'C', 'B' 'C' 'A', 'C' 'A' 'B')
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (order, opt, time, isa);
        None
    }
}

/// The kernels of [`FUSED_ORDER`], in every shape and at every level.
fn default_order<R: Real, P: Pieces<R>>(opt: bool, time: u8, isa: Isa) -> Option<StepsFn<R>> {
    macro_rules! variant {
        ($o:literal, $t:literal) => {{
            #[cfg(target_arch = "x86_64")]
            {
                match isa {
                    Isa::V4 => fused_steps_v4::<R, P, 'C', 'B', 'A', $o, $t> as StepsFn<R>,
                    Isa::V3 => fused_steps_v3::<R, P, 'C', 'B', 'A', $o, $t> as StepsFn<R>,
                    Isa::Baseline => fused_steps::<R, P, 'C', 'B', 'A', $o, $t> as StepsFn<R>,
                }
            }
            #[cfg(not(target_arch = "x86_64"))]
            {
                let _ = isa;
                fused_steps::<R, P, 'C', 'B', 'A', $o, $t> as StepsFn<R>
            }
        }};
    }
    // The order's letters are literals, as the const generics need.
    debug_assert_eq!(FUSED_ORDER, ['C', 'B', 'A']);
    match (opt, time) {
        (false, 0) => Some(variant!(false, 0)),
        (true, 0) => Some(variant!(true, 0)),
        (false, 1) => Some(variant!(false, 1)),
        (true, 1) => Some(variant!(true, 1)),
        (false, 2) => Some(variant!(false, 2)),
        (true, 2) => Some(variant!(true, 2)),
        _ => None,
    }
}

/// How a plan's fused stages get their time terms ([`time`]); `shared`:
/// the ensemble shares them.
pub fn time_mode(plan: &Plan, shared: bool) -> u8 {
    match (plan.time, shared) {
        (_, true) => time::SHARED,
        (false, false) => time::NONE,
        (true, false) => time::PER_LANE,
    }
}

/// Each S2 stage's weights `(w/2, w, c)`, for a splitting plan.
pub fn weights<R: Real>(plan: &Plan) -> Option<Vec<Weights<R>>> {
    let st = plan.stages.as_ref()?;
    let w = |(w, c): &(f64, f64)| (R::from_f64(0.5 * w), R::from_f64(*w), R::from_f64(*c));
    Some(st.stages.iter().map(w).collect())
}

/// Builds the fused steps of whichever model's pieces it visits.
#[derive(Clone, Copy)]
pub struct StageBuilder {
    pub order: [char; 3],
    pub opt: bool,
    /// One of [`time`]'s modes.
    pub time: u8,
    pub isa: Isa,
}

impl<R: Real> PiecesVisitor<R> for StageBuilder {
    type Out = Option<StepsFn<R>>;
    fn visit<P: Pieces<R>>(self) -> Option<StepsFn<R>> {
        steps_fn::<R, P>(self.order, self.opt, self.time, self.isa)
    }
}

impl StageBuilder {
    /// The fused steps of `model` in precision `R`; `None` for a formula
    /// model or an order other than [`FUSED_ORDER`].
    ///
    /// Compiled through the non-generic [`kernels_f32`] and
    /// [`kernels_f64`] (see [`in_precision`]).
    pub fn build<R: Real>(self, model: &Model) -> Option<StepsFn<R>> {
        in_precision::<R, Option<StepsFn<R>>, _, _>(
            || kernels_f32(self, model),
            || kernels_f64(self, model),
        )
    }
}

/// [`StageBuilder::build`] in f32, compiled here only.
#[inline(never)]
fn kernels_f32(b: StageBuilder, model: &Model) -> Option<StepsFn<f32>> {
    model.with_pieces::<f32, _>(b).flatten()
}

/// [`StageBuilder::build`] in f64, compiled here only.
#[inline(never)]
fn kernels_f64(b: StageBuilder, model: &Model) -> Option<StepsFn<f64>> {
    model.with_pieces::<f64, _>(b).flatten()
}
