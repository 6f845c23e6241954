//! The tangent step of a built-in model, compiled: the step's S2 stages
//! run again from the state at the step's start over a block, each op's
//! generated tangent (`models/tangent_ops.rs`) carrying the deviation
//! vectors along, one lane loop per stage as in the fused stages, over a
//! chunk of the block at a time (see [`chunk`]). The
//! stages' weights are values, so a model has one kernel per precision,
//! level (AVX2, AVX-512) and number of vectors per pass (1, 2), whatever
//! its scheme; only the piece order every model takes by default (`CBABC`)
//! is compiled (each order more would be as many kernels again, and the
//! build is bounded). Formula models, other orders and CPUs without AVX2
//! keep the tape (`indicators.rs`).

// Lane loops index several arrays by lane; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use super::kernels::{time, time_mode, weights, Weights};
use crate::models::lanes::{index_of, Lane, Lanes, LANES};
use crate::models::pieces::{Pieces, PiecesVisitor};
use crate::models::{tangent_ops, Model};
use crate::num::isa::Isa;
use crate::num::precision::{in_precision, Real};
use crate::plan::Plan;

/// The most deviation vectors one pass of a kernel carries; more run in
/// passes of at most this many, each from the step's start.
pub const MAX_VECTORS: usize = 2;

/// One step's tangent over a block: `(x, d, stages, n, time, time_terms)`.
/// `x` holds the state at the step's start and the lanes' inputs, `d[k]`
/// vector k's components at the tangent space's lanes; the step `n` runs
/// on both (`x` ends at the step's end, a scratch copy). Unsafe to call:
/// the AVX2/FMA and AVX-512 variants need those features.
pub type TangentFn<R> =
    unsafe fn(&mut Lanes<R>, &mut [Box<Lanes<R>>], &[Weights<R>], u64, u8, bool);

/// The step on `x` and `d` (see [`TangentFn`]), its stages in the piece
/// order every model takes by default, `CBABC`.
#[inline(always)]
fn tangent_step<R: Real, P: Pieces<R>, const K: usize, const AVX512: bool>(
    x: &mut Lanes<R>,
    d: &mut [Box<Lanes<R>>],
    stages: &[Weights<R>],
    n: u64,
    time_mode: u8,
    time_terms: bool,
) {
    let d: &mut [Box<Lanes<R>>; K] = d.try_into().expect("K deviation vectors");
    let nf = R::from_f64(n as f64);
    let chunk = const { chunk::<R>(K, AVX512) };
    for first in (0..LANES).step_by(chunk) {
        let lanes = first..first + chunk;
        for &(half, full, c) in stages {
            let shared = time_pass::<R, P>(x, c, nf, time_mode, time_terms, lanes.clone());
            // Whether the lanes take shared time terms, decided once per
            // stage, not per lane: a test in the lane loop splits it into
            // a block per vector, which the compiler cannot overlap
            // (van der Pol one exponent, Zen 3 AVX2: f64 1.68× → 1.37× the
            // plain run, f32 2.16× → 1.74×).
            let lanes = lanes.clone();
            match &shared {
                Some(s) => stage_pass::<R, P, 'C', 'B', 'A', K, true>(x, d, half, full, s, lanes),
                None => {
                    let unused = Lane::default();
                    stage_pass::<R, P, 'C', 'B', 'A', K, false>(x, d, half, full, &unused, lanes)
                }
            }
        }
    }
}

/// Lanes taken through every stage of the step at once, for `k` vectors
/// in precision `R` (`avx512`: at that level, else AVX2): the compiler
/// keeps a chunk's state and deviations in registers from stage to stage.
/// With one vector in f32 at AVX-512, half the block:
/// van der Pol, `triple_jump4`, one exponent, against the plain run
/// (medians of 5, Zen 4): AVX-512 2.38× (the whole block 2.71×, 16 lanes
/// 2.98×), AVX2 2.48× (2.54×, 16 lanes 2.81×). Otherwise the whole block:
/// f64 one exponent 1.98× (half the block 2.13×), f32 two vectors 3.2×
/// (32 lanes 3.4×, 16 lanes 4.4×). Measured again on Zen 3 (AVX2) once
/// the lane loop had no test in it (see [`tangent_step`]), pairs of runs
/// against this choice: f32 one vector, the whole block 1.03× its time;
/// half the block for the rest, f32 two vectors 1.07×, f64 one vector
/// 1.06×, two 1.05×. At AVX2 the whole block for one vector in f32 too
/// (Zen 3 after b21a020, pairs of whole runs against half the block):
/// spin–orbit (S2, 320 × 320 orbits) one exponent 0.86× the time (5
/// pairs), MEGNO 0.85× (5); van der Pol one exponent 1.03× (9), the FLI
/// 1.01× (7), MEGNO 1.01× (7). Time terms the ensemble shares are
/// evaluated for each chunk, as values: kept in a buffer for the chunks to
/// read, they cost the registers (the one-exponent run 2× slower).
const fn chunk<R>(k: usize, avx512: bool) -> usize {
    if avx512 && k == 1 && std::mem::size_of::<R>() == 4 {
        LANES / 2
    } else {
        LANES
    }
}

/// A stage's time terms at `t0 + (n + c) dt`, as the fused stage evaluates
/// them: once for the block's `lanes` (returned, for every lane to take),
/// or per lane into `x`.
#[inline(always)]
fn time_pass<R: Real, P: Pieces<R>>(
    x: &mut Lanes<R>,
    c: R,
    nf: R,
    time_mode: u8,
    time_terms: bool,
    lanes: std::ops::Range<usize>,
) -> Option<Lane<R>> {
    if time_mode == time::SHARED {
        let mut shared = Lane::gather(x, 0);
        shared.t = shared.t0 + nf * shared.dt + c * shared.dt;
        if time_terms {
            P::time(&mut shared);
        }
        return Some(shared);
    }
    if time_mode == time::PER_LANE {
        for i in lanes {
            let mut xi = Lane::gather(x, i);
            xi.t = xi.t0 + nf * xi.dt + c * xi.dt;
            P::time(&mut xi);
            xi.scatter_time(x, i);
        }
    }
    None
}

/// One stage `P1½ P2½ P3 P2½ P1½` (weights `half`, `full` times dt) on
/// every lane, with its tangent, as the fused stage applies it; `SHARED`:
/// every lane takes the time terms of `shared` (else `shared` is unused).
#[inline(always)]
fn stage_pass<
    R: Real,
    P: Pieces<R>,
    const P1: char,
    const P2: char,
    const P3: char,
    const K: usize,
    const SHARED: bool,
>(
    x: &mut Lanes<R>,
    d: &mut [Box<Lanes<R>>; K],
    half: R,
    full: R,
    shared: &Lane<R>,
    lanes: std::ops::Range<usize>,
) {
    if const { ways::<R>(K) } == 2 {
        return stage_pass_two::<R, P, P1, P2, P3, K, SHARED>(x, d, half, full, shared, lanes);
    }
    for i in lanes {
        let mut xi = Lane::gather(x, i);
        if SHARED {
            P::share_time(&mut xi, shared);
        }
        let mut di = [Lane::gather(&d[0], i); K];
        for k in 1..K {
            di[k] = Lane::gather(&d[k], i);
        }
        xi.tau = half * xi.dt;
        P::piece_tangent::<K>(P1, &mut xi, &mut di);
        P::piece_tangent::<K>(P2, &mut xi, &mut di);
        xi.tau = full * xi.dt;
        P::piece_tangent::<K>(P3, &mut xi, &mut di);
        xi.tau = half * xi.dt;
        P::piece_tangent::<K>(P2, &mut xi, &mut di);
        P::piece_tangent::<K>(P1, &mut xi, &mut di);
        P::scatter(&xi, x, i);
        for k in 0..K {
            P::scatter(&di[k], &mut d[k], i);
        }
    }
}

/// [`stage_pass`] two lanes half the chunk apart per iteration: once
/// vectorised, two independent chains in program order, as in the fused
/// stages (`kernels::fused_stage_body`). The same operations on each lane,
/// so the same bits.
#[inline(always)]
fn stage_pass_two<
    R: Real,
    P: Pieces<R>,
    const P1: char,
    const P2: char,
    const P3: char,
    const K: usize,
    const SHARED: bool,
>(
    x: &mut Lanes<R>,
    d: &mut [Box<Lanes<R>>; K],
    half: R,
    full: R,
    shared: &Lane<R>,
    lanes: std::ops::Range<usize>,
) {
    let len = lanes.len() / 2;
    for i in lanes.start..lanes.start + len {
        let at = [i, i + len];
        let mut xs = [Lane::gather(x, at[0]), Lane::gather(x, at[1])];
        let mut ds = [
            [Lane::gather(&d[0], at[0]); K],
            [Lane::gather(&d[0], at[1]); K],
        ];
        for w in 0..2 {
            for k in 1..K {
                ds[w][k] = Lane::gather(&d[k], at[w]);
            }
            if SHARED {
                P::share_time(&mut xs[w], shared);
            }
        }
        for w in 0..2 {
            xs[w].tau = half * xs[w].dt;
        }
        for w in 0..2 {
            P::piece_tangent::<K>(P1, &mut xs[w], &mut ds[w]);
        }
        for w in 0..2 {
            P::piece_tangent::<K>(P2, &mut xs[w], &mut ds[w]);
        }
        for w in 0..2 {
            xs[w].tau = full * xs[w].dt;
        }
        for w in 0..2 {
            P::piece_tangent::<K>(P3, &mut xs[w], &mut ds[w]);
        }
        for w in 0..2 {
            xs[w].tau = half * xs[w].dt;
        }
        for w in 0..2 {
            P::piece_tangent::<K>(P2, &mut xs[w], &mut ds[w]);
        }
        for w in 0..2 {
            P::piece_tangent::<K>(P1, &mut xs[w], &mut ds[w]);
        }
        for w in 0..2 {
            P::scatter(&xs[w], x, at[w]);
            for k in 0..K {
                P::scatter(&ds[w][k], &mut d[k], at[w]);
            }
        }
    }
}

/// Lanes per iteration of [`stage_pass`] for `k` vectors in precision `R`:
/// two for one vector in f32, else one. Zen 3 AVX2, pairs of whole runs
/// against one (same bits): spin–orbit MEGNO f32 0.94× the time (7 pairs),
/// van der Pol MEGNO f32 0.97× (7), one exponent 0.96× (5); with this
/// code, spin–orbit MEGNO f32 0.95× (11 pairs), one exponent 0.97× (9).
/// Not kept: the one-way loop written as the two-way one with a slot
/// unused (the two-vector kernel, spin–orbit full spectrum f32, 1.14×);
/// generic code for four (arrays indexed by the way in a loop) was not
/// vectorised, 100× slower; the number of ways chosen at run time, 1.1×.
const fn ways<R>(k: usize) -> usize {
    if k == 1 && std::mem::size_of::<R>() == 4 {
        2
    } else {
        1
    }
}

/// Declares a [`TangentFn`] variant of [`tangent_step`] for one level.
macro_rules! tangent_variant {
    ($(#[$m:meta])* $name:ident, $avx512:literal) => {
        $(#[$m])*
        unsafe fn $name<R: Real, P: Pieces<R>, const K: usize>(
            x: &mut Lanes<R>,
            d: &mut [Box<Lanes<R>>],
            stages: &[Weights<R>],
            n: u64,
            time_mode: u8,
            time_terms: bool,
        ) {
            tangent_step::<R, P, K, $avx512>(x, d, stages, n, time_mode, time_terms)
        }
    };
}

tangent_variant! {
    /// [`tangent_step`] compiled for AVX2 and FMA.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    tangent_v3, false
}

tangent_variant! {
    /// [`tangent_step`] compiled for AVX-512.
    ///
    /// # Safety
    /// The CPU must support AVX-512 F, VL, DQ and BW, AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw,avx2,fma")]
    tangent_v4, true
}

/// Picks the variant of whichever model's pieces it visits: the level and
/// the number of vectors. `None` below AVX2 (the tape runs there).
#[derive(Clone, Copy)]
struct Builder {
    isa: Isa,
    vectors: usize,
}

impl<R: Real> PiecesVisitor<R> for Builder {
    type Out = Option<TangentFn<R>>;
    #[allow(unreachable_code)]
    fn visit<P: Pieces<R>>(self) -> Option<TangentFn<R>> {
        #[cfg(target_arch = "x86_64")]
        {
            return match (self.isa, self.vectors) {
                (Isa::V4, 1) => Some(tangent_v4::<R, P, 1> as TangentFn<R>),
                (Isa::V4, 2) => Some(tangent_v4::<R, P, 2> as TangentFn<R>),
                (Isa::V3, 1) => Some(tangent_v3::<R, P, 1> as TangentFn<R>),
                (Isa::V3, 2) => Some(tangent_v3::<R, P, 2> as TangentFn<R>),
                _ => None,
            };
        }
        let _ = self;
        None
    }
}

/// The lanes the compiled tangent step runs on for one block: a copy of
/// the block's lanes (its parameters; the state is set before each step)
/// and each deviation vector's lanes.
pub struct TangentScratch<R> {
    pub x: Box<Lanes<R>>,
    pub d: Vec<Box<Lanes<R>>>,
}

impl<R: Real> TangentScratch<R> {
    pub fn new(l: &Lanes<R>, vectors: usize) -> TangentScratch<R> {
        let mut x = Lanes::boxed();
        x.as_mut_slice().copy_from_slice(l.as_slice());
        TangentScratch {
            x,
            d: (0..vectors).map(|_| Lanes::boxed()).collect(),
        }
    }
}

/// A plan's compiled tangent step: the kernels and what they read.
pub struct CompiledTangent<R> {
    /// The kernels for one and for two vectors.
    kernels: [TangentFn<R>; MAX_VECTORS],
    /// The lane index of each of the model's state variables.
    vars: Vec<usize>,
    stages: Vec<Weights<R>>,
    time_mode: u8,
    time_terms: bool,
    /// The lane index of each tangent-space variable, in order.
    pub space: Vec<usize>,
    vectors: usize,
    /// Whether its stages are the whole step: the plan integrates no
    /// optional variable (which the tangent leaves out).
    pub takes_step: bool,
}

impl<R: Real> CompiledTangent<R> {
    /// The compiled tangent of `plan`'s step for `vectors` deviation
    /// vectors over `space` (its tangent space), or `None` where the tape
    /// must do: a plan that is no splitting or has another piece order
    /// than `CBABC`, a formula model, no vector,
    /// an op without a generated tangent, a tangent space other than the
    /// model's variables less the optional one, a CPU without AVX2, a
    /// precision other than f32 and f64. `shared`: the ensemble shares the
    /// time terms (as for the fused stages).
    pub fn new(
        plan: &Plan,
        space: &[&str],
        vectors: usize,
        isa: Isa,
        shared: bool,
    ) -> Option<CompiledTangent<R>> {
        let model = &plan.model;
        let spec = model.spec();
        let ops = spec.piece_ops.iter().flat_map(|p| p.ops.iter());
        let generated = ops
            .filter(|(_, optional)| !optional)
            .all(|(op, _)| !tangent_ops::UNSUPPORTED.contains(op));
        let expected: Vec<&str> = spec
            .vars
            .iter()
            .copied()
            .filter(|v| Some(*v) != spec.optional_var)
            .collect();
        let default_order = plan.stages.as_ref()?.order == ['C', 'B', 'A'];
        if model.formula().is_some()
            || !default_order
            || vectors == 0
            || !generated
            || expected != space
        {
            return None;
        }
        Some(CompiledTangent {
            kernels: [kernel::<R>(model, isa, 1)?, kernel::<R>(model, isa, 2)?],
            vars: spec
                .vars
                .iter()
                .map(|v| index_of(v).expect("a lane"))
                .collect(),
            stages: weights(plan)?,
            time_mode: time_mode(plan, shared),
            time_terms: plan.time,
            space: space.iter().map(|v| index_of(v).expect("a lane")).collect(),
            vectors,
            takes_step: !plan.stages.as_ref()?.with_optional,
        })
    }

    /// How many deviation vectors it carries.
    pub fn vectors(&self) -> usize {
        self.vectors
    }

    /// Step `n` on the scratch lanes `x` and the vectors `d` (see
    /// [`TangentFn`]), in passes of at most [`MAX_VECTORS`] vectors, each
    /// from the step's start.
    pub fn run(&self, x: &mut Lanes<R>, d: &mut [Box<Lanes<R>>], n: u64) {
        let start: Vec<[R; LANES]> = if d.len() > MAX_VECTORS {
            self.vars.iter().map(|&v| *x.at(v)).collect()
        } else {
            vec![]
        };
        for (k, pass) in d.chunks_mut(MAX_VECTORS).enumerate() {
            if k > 0 {
                for (&v, a) in self.vars.iter().zip(&start) {
                    *x.at_mut(v) = *a;
                }
            }
            let kernel = self.kernels[pass.len() - 1];
            // SAFETY: the kernels were picked for `isa`, which
            // `kernels::isa` only names where the CPU has its features.
            unsafe { kernel(x, pass, &self.stages, n, self.time_mode, self.time_terms) }
        }
    }
}

/// The kernel of `model` in precision `R` at level `isa`, compiled in this
/// crate alone (see [`in_precision`]).
fn kernel<R: Real>(model: &Model, isa: Isa, vectors: usize) -> Option<TangentFn<R>> {
    let b = Builder { isa, vectors };
    in_precision::<R, Option<TangentFn<R>>, _, _>(|| kernel_f32(model, b), || kernel_f64(model, b))
}

#[inline(never)]
fn kernel_f32(model: &Model, b: Builder) -> Option<TangentFn<f32>> {
    model.with_pieces::<f32, _>(b).flatten()
}

#[inline(never)]
fn kernel_f64(model: &Model, b: Builder) -> Option<TangentFn<f64>> {
    model.with_pieces::<f64, _>(b).flatten()
}
