//! The CPU's fused S2 stages: one stage `D½ P1½ P2½ P3 P2½ P1½ D½` applied to
//! a whole block in one loop (which the compiler vectorises), built from a
//! model's [`Pieces`]; a run of steps of such stages in one call, compiled for
//! three instruction-set levels and chosen at run time.

use crate::models::lanes::{Lane, Lanes, LANES};
use crate::models::pieces::{Pieces, PiecesVisitor, Saved, MAX_VARS};
pub use crate::num::isa::Isa;
use crate::num::precision::Real;

/// A stage's weights: `(w/2, w, time offset c)`.
pub type Weights<R> = (R, R, R);

/// A run of steps over a block: `(lanes, stages, n, k, time_terms)` takes
/// steps `n … n+k−1`, each the stages in order; `time_terms`: whether the
/// [`time::SHARED`] mode evaluates the model's time ops (a plan without time
/// shares only `dt`). Returns how many steps it took — fewer than `k` when
/// one left some lane non-finite (the last stage's verdict is the step's) —
/// and whether the last one did. Unsafe to call: the variants compiled for
/// AVX2/FMA and AVX-512 need those features.
pub type StepsFn<R> = unsafe fn(&mut Lanes<R>, &[Weights<R>], u64, u64, bool) -> (u64, bool);

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
/// (`tests/cpu.rs::non_finite_states_stay_non_finite`). Only then is the run
/// repeated from a copy of its start, checking each step, to find the step:
/// the same operations, so the same bits and the same verdict as checking
/// every step.
#[inline(always)]
fn fused_steps_body<
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
) -> (u64, bool) {
    if k > 1 {
        let mut start: Saved<R> = [[R::default(); LANES]; MAX_VARS];
        P::save(l, &mut start);
        for j in 0..k {
            let nf = R::from_f64((n + j) as f64);
            for &(h, f, c) in stages {
                fused_stage_body::<R, P, P1, P2, P3, OPT, TIME, false>(l, h, f, c, nf, time_terms);
            }
        }
        if all_finite::<R, P>(l) {
            return (k, false);
        }
        P::restore(l, &start);
    }
    checked_steps::<R, P, P1, P2, P3, OPT, TIME>(l, stages, n, k, time_terms)
}

/// [`fused_steps_body`] checking after every step.
#[inline(always)]
fn checked_steps<
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
) -> (u64, bool) {
    // Only the last stage's verdict counts: the others skip the check.
    let Some((&(half, full, c), rest)) = stages.split_last() else {
        return (k, false);
    };
    for j in 0..k {
        let nf = R::from_f64((n + j) as f64);
        for &(h, f, c) in rest {
            fused_stage_body::<R, P, P1, P2, P3, OPT, TIME, false>(l, h, f, c, nf, time_terms);
        }
        if fused_stage_body::<R, P, P1, P2, P3, OPT, TIME, true>(l, half, full, c, nf, time_terms) {
            return (j + 1, true);
        }
    }
    (k, false)
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
/// `half = w/2`, `full = w` (times dt), time terms at `t0 + (n + c) dt`;
/// with `CHECK`, whether some lane's state is non-finite after it (else
/// false).
#[inline(always)]
fn fused_stage_body<
    R: Real,
    P: Pieces<R>,
    const P1: char,
    const P2: char,
    const P3: char,
    const OPT: bool,
    const TIME: u8,
    const CHECK: bool,
>(
    l: &mut Lanes<R>,
    half: R,
    full: R,
    c: R,
    nf: R,
    time_terms: bool,
) -> bool {
    let mut shared = Lane::default();
    if TIME == time::SHARED {
        shared = Lane::gather(l, 0);
        shared.t = shared.t0 + nf * shared.dt + c * shared.dt;
        if time_terms {
            P::time(&mut shared);
        }
    }
    let mut bad = R::Flag::default();
    // Several lanes, a fraction of a block apart, per iteration: once
    // vectorised, independent chains that the core overlaps (one stage is a
    // long dependent chain, exp's polynomial most of it). Four where the
    // state is small (van der Pol at AVX2: +5 %), two where four would
    // spill (Kepler's five variables: −9 % with four).
    macro_rules! interleaved {
        ($($x:ident $k:literal),*) => {{
            const WAYS: usize = [$($k),*].len();
            for i in 0..LANES / WAYS {
                $( let mut $x = Lane::gather(l, i + $k * LANES / WAYS); )*
                if TIME == time::SHARED {
                    $( P::share_time(&mut $x, &shared); )*
                }
                $(
                    let b = stage::<R, P, P1, P2, P3, OPT, TIME>(&mut $x, half, full, c, nf);
                    if CHECK {
                        bad |= b.into();
                    }
                )*
                $( $x.scatter_state(l, i + $k * LANES / WAYS); )*
            }
        }};
    }
    if P::VARS <= 3 {
        interleaved!(x 0, y 1, z 2, w 3);
    } else {
        interleaved!(x 0, y 1);
    }
    CHECK && bad != R::Flag::default()
}

/// The stage on one trajectory; whether its state is non-finite after it.
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
) -> bool {
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
    !P::finite(x)
}

/// Declares a [`StepsFn`] variant of [`fused_steps_body`], compiled with
/// the given attributes (its instruction-set level).
macro_rules! steps_variant {
    ($(#[$m:meta])* $name:ident) => {
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
        ) -> (u64, bool) {
            fused_steps_body::<R, P, P1, P2, P3, OPT, TIME>(l, stages, n, k, time_terms)
        }
    };
}

steps_variant! {
    /// [`fused_steps_body`] for any x86-64 (or other) CPU.
    ///
    /// # Safety
    /// None required; `unsafe` only to share [`StepsFn`] with the wide variants.
    fused_steps
}

steps_variant! {
    /// [`fused_steps_body`] compiled for AVX2 and FMA (x86-64-v3).
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fused_steps_v3
}

steps_variant! {
    /// [`fused_steps_body`] compiled for AVX-512 (x86-64-v4): twice the lanes
    /// per instruction and 32 vector registers, so constants stay in registers.
    ///
    /// # Safety
    /// The CPU must support AVX-512 F, VL, DQ and BW, AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx2,fma")]
    fused_steps_v4
}

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

/// The fused steps for a piece order, optional variable and time, or `None`
/// for an order that is not a permutation of A, B, C.
pub fn steps_fn<R: Real, P: Pieces<R>>(
    order: [char; 3],
    opt: bool,
    time: u8,
    isa: Isa,
) -> Option<StepsFn<R>> {
    macro_rules! pick {
        ($($a:literal $b:literal $c:literal),*) => {
            match (order, opt, time) {
                $(
                    ([$a, $b, $c], false, 0) => Some(variant!($a, $b, $c, false, 0)),
                    ([$a, $b, $c], true, 0) => Some(variant!($a, $b, $c, true, 0)),
                    ([$a, $b, $c], false, 1) => Some(variant!($a, $b, $c, false, 1)),
                    ([$a, $b, $c], true, 1) => Some(variant!($a, $b, $c, true, 1)),
                    ([$a, $b, $c], false, 2) => Some(variant!($a, $b, $c, false, 2)),
                    ([$a, $b, $c], true, 2) => Some(variant!($a, $b, $c, true, 2)),
                )*
                _ => None,
            }
        };
    }
    macro_rules! variant {
        ($a:literal, $b:literal, $c:literal, $o:literal, $t:literal) => {{
            #[cfg(target_arch = "x86_64")]
            {
                match isa {
                    Isa::V4 => fused_steps_v4::<R, P, $a, $b, $c, $o, $t> as StepsFn<R>,
                    Isa::V3 => fused_steps_v3::<R, P, $a, $b, $c, $o, $t> as StepsFn<R>,
                    Isa::Baseline => fused_steps::<R, P, $a, $b, $c, $o, $t> as StepsFn<R>,
                }
            }
            #[cfg(not(target_arch = "x86_64"))]
            {
                let _ = isa;
                fused_steps::<R, P, $a, $b, $c, $o, $t> as StepsFn<R>
            }
        }};
    }
    pick!('A' 'B' 'C', 'A' 'C' 'B', 'B' 'A' 'C', 'B' 'C' 'A', 'C' 'A' 'B', 'C' 'B' 'A')
}

/// Builds the fused steps of whichever model's pieces it visits.
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
