//! Chaos indicators as observers: finite-time Lyapunov exponents
//! (Benettin's method), the Fast Lyapunov Indicator and MEGNO. Their
//! deviation vectors follow the exact tangent map of the step
//! (`plan/tangent.rs`); at each sample a program orthogonalises them
//! (Gram–Schmidt without normalising), keeps what their growth is read
//! from, and brings them back in range by an exact power of two. The
//! tangent step and the samples are formulas lowered to one program each,
//! which both backends run (the CPU's block interpreter, WGSL on the GPU):
//! one source for all of it.
//!
//! Why no normalisation: the vector a sample keeps, u, is the true
//! (Gram–Schmidt) vector times 2^−E with E an integer in a slot, so
//! ln‖w‖ = E ln 2 + ½ ln‖u‖², and the Rᵢᵢ of the normalised method
//! telescope into differences of it, read with one rounding whatever the
//! horizon. A square root and a division per lane go; the Lyapunov
//! samples take no logarithm at all (the exponents are read from E and
//! ‖u‖² when asked for, [`lyapunov_finish`]), the FLI/MEGNO sample one.
//!
//! Per-trajectory state (real slots, after the time averages'): the
//! deviation vectors `w{k}_{j}` (Lyapunov's k vectors, starting as the
//! identity's columns, then the FLI/MEGNO vector, (1, …, 1)/√d); per
//! Lyapunov vector i its octaves `lyap_oct_{i}` (E) and ‖u‖² at the last
//! sample `lyap_n2_{i}`, and both at the skip step, `lyap_start_oct_{i}`
//! and `lyap_start_n2_{i}`; for the FLI/MEGNO vector `fli_oct` (E),
//! `fli_log` = ln‖w‖ at the last sample, `fli_max` its maximum over the
//! samples, `megno_sum` = Σ k ln(‖w_k‖/‖w_{k−1}‖) over the samples
//! k = 1, 2, … and `megno_mean` = ⟨Y⟩ (Y_n = 2·megno_sum/n: the
//! definition's t_k = k·m·dt cancel). Then SALI's and GALI's vectors
//! (`plan/alignment.rs`, the identity's first columns again), and `sali`,
//! `gali` at the last sample.

use crate::num::formula::lower::{lower, Lowered};
use crate::num::formula::{Dag, Func, Func2, Id};

use super::alignment::alignment_program;
use super::observers::Observers;
use super::problem::{err, PlanError};
use super::tangent::{StepSpec, TangentInput, TangentStep};
use super::vectors::{dot, minus_projections, reciprocal};

/// What a sample program reads besides slots.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleInput {
    /// The indicators' slot at this index (of [`Indicators::slots`]).
    Slot(usize),
    /// The sample's number (1 for the first).
    Count,
    /// One over it: the running mean's weight, a product where a quotient
    /// would cost a division per lane.
    InvCount,
    /// 1 at the sample of the skip step (where the Lyapunov sums start),
    /// else 0.
    AtSkip,
}

/// A program run every `every` steps: it reads `inputs` and writes its
/// outputs into the indicators' slots `outputs`.
#[derive(Debug, Clone)]
pub struct Sampler {
    pub every: u64,
    pub shape: SampleShape,
    pub program: Lowered,
    pub inputs: Vec<SampleInput>,
    pub outputs: Vec<usize>,
}

/// A plan's chaos indicators; see the module documentation.
#[derive(Debug, Clone)]
pub struct Indicators {
    pub tangent: TangentStep,
    /// The tangent step's deviation inputs and outputs, as slots.
    pub deviation_slots: Vec<usize>,
    pub lyapunov: Option<Sampler>,
    /// The FLI/MEGNO vector's samples.
    pub chaos: Option<Sampler>,
    /// SALI's and GALI's vectors' samples.
    pub alignment: Option<Sampler>,
    /// Lyapunov sums start after this step (a multiple of `every`).
    pub skip_step: u64,
    /// The slots: name and value before the first step. Indices here are
    /// into this list; the plan's real slots hold it after the averages'
    /// (`slots::indicator_first`).
    pub slots: Vec<(String, f64)>,
    /// The slot of each of [`SCALAR_INDICATORS`] the plan has, found once
    /// (its finish runs per trajectory and frame).
    pub scalar_slots: [Option<usize>; 4],
}

/// An indicator read from one slot.
pub struct ScalarIndicator {
    /// Its scene key (`output.KEY`), and the name a stop condition reads
    /// it by.
    pub key: &'static str,
    /// The slot it is read from.
    pub slot: &'static str,
    /// Its sampling period, if `observers` ask for it.
    pub every: fn(&Observers) -> Option<u64>,
}

/// The indicators read from one slot each, in the order of
/// `slots::IndicatorValues::scalars` and of
/// `Observations::scalar_indicators`: the FLI so far, MEGNO's ⟨Y⟩, SALI
/// and GALI at the last sample.
pub const SCALAR_INDICATORS: [ScalarIndicator; 4] = [
    ScalarIndicator {
        key: "fli",
        slot: "fli_max",
        every: |o| o.fli.as_ref().map(|f| f.every),
    },
    ScalarIndicator {
        key: "megno",
        slot: "megno_mean",
        every: |o| o.megno.as_ref().map(|m| m.every),
    },
    ScalarIndicator {
        key: "sali",
        slot: "sali",
        every: |o| o.sali.as_ref().map(|s| s.every),
    },
    ScalarIndicator {
        key: "gali",
        slot: "gali",
        every: |o| o.gali.as_ref().map(|g| g.every),
    },
];

impl Indicators {
    /// The indicators `observers` ask for, on the step `step` of a run of
    /// `steps` steps; `None` if it asks for none.
    pub fn new(
        step: &StepSpec,
        steps: u64,
        observers: &Observers,
    ) -> Result<Option<Indicators>, PlanError> {
        let k = observers.lyapunov.as_ref().map_or(0, |l| l.vectors);
        let chaos = observers.chaos_every();
        let alignment = observers.alignment();
        let m = alignment.map_or(0, |(m, _)| m);
        if k == 0 && chaos.is_none() && m == 0 {
            return Ok(None);
        }
        let vectors = k + usize::from(chaos.is_some()) + m;
        let which = match (k, chaos, &observers.sali) {
            (1.., _, _) => "lyapunov",
            (0, Some(_), _) => "fli",
            (0, None, Some(_)) => "sali",
            (0, None, None) => "gali",
        };
        let tangent = TangentStep::new(step, vectors)
            .map_err(|e| err(format!("output.{which}"), e.message))?;
        let d = tangent.space.len();
        let too_many = |field: &str, what: String| {
            let space = tangent.space.join(", ");
            let message =
                format!("{what} is more than the tangent dimension {d} of this plan ({space})");
            Err(err(field, message))
        };
        if k > d {
            return too_many("output.lyapunov.vectors", format!("{k}"));
        }
        if let Some(g) = observers.gali.as_ref().filter(|g| g.k > d) {
            return too_many("output.gali.k", format!("{}", g.k));
        }
        if observers.sali.is_some() && d < 2 {
            let message =
                format!("needs two deviation vectors; this plan's tangent dimension is {d}");
            return Err(err("output.sali", message));
        }
        let mut s = Indicators {
            deviation_slots: (0..vectors * d).collect(),
            tangent,
            lyapunov: None,
            chaos: None,
            alignment: None,
            skip_step: 0,
            slots: vec![],
            scalar_slots: [None; 4],
        };
        s.slots = s.deviation_inits(k, chaos.is_some(), m);
        if let Some(l) = &observers.lyapunov {
            s.skip_step = l.skip_step(steps);
            s.lyapunov = Some(s.lyapunov_sampler(k, l.every));
        }
        if let Some(every) = chaos {
            s.chaos = Some(s.chaos_sampler(k, every));
        }
        if let Some((m, every)) = alignment {
            let first = k + usize::from(chaos.is_some());
            s.alignment = Some(s.alignment_sampler(first, m, every));
        }
        s.scalar_slots = SCALAR_INDICATORS.map(|i| s.slot_of(i.slot));
        Ok(Some(s))
    }

    /// The sample programs, each with the name of its function on the GPU.
    pub fn samplers(&self) -> impl Iterator<Item = (&'static str, &Sampler)> {
        [
            ("lyapunov_sample", &self.lyapunov),
            ("chaos_sample", &self.chaos),
            ("alignment_sample", &self.alignment),
        ]
        .into_iter()
        .filter_map(|(name, s)| Some((name, s.as_ref()?)))
    }

    fn dimension(&self) -> usize {
        self.tangent.space.len()
    }

    /// The deviation vectors' slots: `k` identity columns, then
    /// (1, …, 1)/√d where `chaos`, then `m` identity columns again.
    fn deviation_inits(&self, k: usize, chaos: bool, m: usize) -> Vec<(String, f64)> {
        let d = self.dimension();
        let c = usize::from(chaos);
        let mut out = vec![];
        for v in 0..k + c + m {
            // Which identity column: Lyapunov's vectors, then the alignment's.
            let column = match v {
                _ if v < k => Some(v),
                _ if v >= k + c => Some(v - k - c),
                _ => None,
            };
            for j in 0..d {
                let x = match column {
                    Some(i) => f64::from(u8::from(i == j)),
                    None => 1.0 / (d as f64).sqrt(),
                };
                out.push((format!("w{v}_{j}"), x));
            }
        }
        out
    }

    /// A new slot, its index.
    fn slot(&mut self, name: String, init: f64) -> usize {
        self.slots.push((name, init));
        self.slots.len() - 1
    }

    /// Gram–Schmidt on vectors `0..k`, their growth kept
    /// ([`lyapunov_program`]).
    fn lyapunov_sampler(&mut self, k: usize, every: u64) -> Sampler {
        let d = self.dimension();
        let mut state = vec![];
        for (name, init) in LYAPUNOV_STATE {
            state.extend((0..k).map(|i| self.slot(format!("{name}_{i}"), init)));
        }
        let w = &self.deviation_slots[..k * d];
        let mut inputs: Vec<SampleInput> = w.iter().map(|s| SampleInput::Slot(*s)).collect();
        inputs.extend(state.iter().map(|s| SampleInput::Slot(*s)));
        inputs.push(SampleInput::AtSkip);
        let mut outputs = w.to_vec();
        outputs.extend(state);
        let shape = SampleShape::Lyapunov { d, k };
        Sampler {
            every,
            program: shape.program(),
            shape,
            inputs,
            outputs,
        }
    }

    /// The FLI/MEGNO vector (number `k`): its growth read, the sums
    /// updated ([`chaos_program`]).
    fn chaos_sampler(&mut self, k: usize, every: u64) -> Sampler {
        let d = self.dimension();
        let u = self.deviation_slots[k * d..(k + 1) * d].to_vec();
        let state = [
            self.slot("fli_oct".into(), 0.0),
            self.slot("fli_log".into(), 0.0),
            self.slot("fli_max".into(), f64::NEG_INFINITY),
            self.slot("megno_sum".into(), 0.0),
            self.slot("megno_mean".into(), 0.0),
        ];
        let mut inputs: Vec<SampleInput> = u.iter().map(|s| SampleInput::Slot(*s)).collect();
        inputs.extend(state.iter().map(|s| SampleInput::Slot(*s)));
        inputs.extend([SampleInput::Count, SampleInput::InvCount]);
        let mut outputs = u;
        outputs.extend(state);
        let shape = SampleShape::Chaos { d };
        Sampler {
            every,
            program: shape.program(),
            shape,
            inputs,
            outputs,
        }
    }

    /// SALI and GALI over the `m` vectors from number `first` on
    /// ([`alignment_program`]).
    fn alignment_sampler(&mut self, first: usize, m: usize, every: u64) -> Sampler {
        let d = self.dimension();
        let w = self.deviation_slots[first * d..(first + m) * d].to_vec();
        let indices = [
            self.slot("sali".into(), std::f64::consts::SQRT_2),
            self.slot("gali".into(), 1.0),
        ];
        let mut outputs = w;
        outputs.extend(indices);
        let shape = SampleShape::Alignment { d, m };
        Sampler {
            every,
            program: shape.program(),
            shape,
            inputs: outputs.iter().map(|s| SampleInput::Slot(*s)).collect(),
            outputs,
        }
    }

    /// The slot of the running value `name` (`fli_max`, `megno_mean`, `lyap_0`, …).
    pub fn slot_of(&self, name: &str) -> Option<usize> {
        self.slots.iter().position(|(n, _)| n == name)
    }

    /// The tangent step's input `k` when it is a deviation: its slot.
    pub fn deviation_slot(&self, input: TangentInput) -> Option<usize> {
        match input {
            TangentInput::Deviation { k, j } => {
                Some(self.deviation_slots[k * self.dimension() + j])
            }
            _ => None,
        }
    }

    /// How many Lyapunov exponents each trajectory has.
    pub fn exponents(&self) -> usize {
        match self.lyapunov.as_ref().map(|l| l.shape) {
            Some(SampleShape::Lyapunov { k, .. }) => k,
            _ => 0,
        }
    }
}

/// Each Lyapunov vector's slots besides its components, in the program's
/// order, and their values before the first step (ln‖w‖ = 0 at both).
const LYAPUNOV_STATE: [(&str, f64); 4] = [
    ("lyap_oct", 0.0),
    ("lyap_n2", 1.0),
    ("lyap_start_oct", 0.0),
    ("lyap_start_n2", 1.0),
];

/// A sample program's shape: which indicator, over a tangent space of
/// dimension `d` (and `k` Lyapunov vectors). The program depends on the
/// shape alone, so the CPU compiles the usual shapes ahead
/// (`backend/cpu/sample_ops.rs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleShape {
    Lyapunov {
        d: usize,
        k: usize,
    },
    Chaos {
        d: usize,
    },
    /// SALI and GALI over `m` vectors.
    Alignment {
        d: usize,
        m: usize,
    },
}

impl SampleShape {
    /// How many inputs its program reads.
    pub fn inputs(self) -> usize {
        match self {
            SampleShape::Lyapunov { d, k } => k * d + 4 * k + 1,
            SampleShape::Chaos { d } => d + 7,
            SampleShape::Alignment { d, m } => m * d + 2,
        }
    }

    pub fn program(self) -> Lowered {
        match self {
            SampleShape::Lyapunov { d, k } => lyapunov_program(d, k),
            SampleShape::Chaos { d } => chaos_program(d),
            SampleShape::Alignment { d, m } => alignment_program(d, m),
        }
    }
}

/// Gram–Schmidt on `k` vectors of dimension `d` without normalising
/// (each vector minus its projections on the ones before), each brought
/// near norm 1 by a power of two. Inputs: the vectors' components (vector
/// i's component j at i·d + j), then for each vector in turn its octaves
/// E, its ‖u‖², both at the skip step, and whether this sample is the
/// skip step's; outputs: the vectors, then the rest in the inputs' order.
/// No logarithm: [`lyapunov_finish`] reads the growth from them.
pub fn lyapunov_program(d: usize, k: usize) -> Lowered {
    lyapunov_lowered(d, k, true)
}

/// [`lyapunov_program`] for a sample that is not the skip step's: the
/// same operations but for the starts, which it leaves as they are
/// (outputs: the vectors, their octaves and ‖u‖²; the starts and the
/// skip flag are inputs it does not read). The whole program writes
/// 1·x + 0·y there, which is x wherever y (E or ‖u‖²) is finite and x is
/// not −0 (no start is: they begin at +0 and 1, and take a finite E, a
/// sum of octaves from +0, or a ‖u‖² > 0); where y is not finite the
/// vectors are not either, and the trajectory's exponents are NaN.
/// The CPU's compiled samples take it between skip steps: a fifth of the
/// full spectrum's sample is the starts' blends.
pub fn lyapunov_program_between(d: usize, k: usize) -> Lowered {
    lyapunov_lowered(d, k, false)
}

/// [`lyapunov_program`]; `starts`: with the starts' outputs.
fn lyapunov_lowered(d: usize, k: usize, starts: bool) -> Lowered {
    let mut g = Dag::new();
    let var = |g: &mut Dag, k: usize| g.var(k as u32);
    let at_skip = var(&mut g, k * d + 4 * k);
    let one = g.num(1.0);
    let before = g.sub(one, at_skip);
    // The vectors orthogonalised, each with 1/‖v‖² (to project on it).
    let mut basis: Vec<(Vec<Id>, Id)> = vec![];
    let mut vectors = vec![];
    let mut state: Vec<Vec<Id>> = vec![vec![]; 4];
    for i in 0..k {
        let w: Vec<Id> = (0..d).map(|j| var(&mut g, i * d + j)).collect();
        let v = minus_projections(&mut g, w, &basis);
        let n2 = dot(&mut g, &v, &v);
        let octave = var(&mut g, k * d + i);
        let (scaled, e, s) = rescale(&mut g, &v, octave, n2);
        let s2 = g.mul(s, s);
        let n2_scaled = g.mul(n2, s2);
        // At the skip step the start takes E and ‖u‖²; 0·x + 1·y and
        // 1·x + 0·y are exact.
        for (j, now) in [(2, e), (3, n2_scaled)] {
            let start = var(&mut g, k * d + j * k + i);
            let keep = g.mul(before, start);
            let take = g.mul(at_skip, now);
            state[j].push(g.add(keep, take));
        }
        if i + 1 < k {
            basis.push((v, reciprocal(&mut g, n2)));
        }
        vectors.extend(scaled);
        state[0].push(e);
        state[1].push(n2_scaled);
    }
    let mut roots = vectors;
    let outputs = if starts { 4 } else { 2 };
    roots.extend(state[..outputs].concat());
    lower(&g, &roots)
}

/// The FLI/MEGNO vector of dimension `d`: its growth read, the sums
/// updated. Inputs: its components, `fli_oct`, `fli_log`, `fli_max`,
/// `megno_sum`, `megno_mean`, the sample's number, one over it; outputs:
/// the vector brought near norm 1, then the five in the inputs' order.
/// Where the vector's ‖u‖² is in the band of `in_band_r` its octave is
/// 0 (the vector scales by 1, `fli_oct` gains 0), and the CPU runs it in
/// two parts with the same operations ([`chaos_n2_program`],
/// [`chaos_ln_sums_program`]).
pub fn chaos_program(d: usize) -> Lowered {
    chaos_lowered(d, true)
}

/// [`chaos_program`] where MEGNO is not asked for: the same vector,
/// octaves, `fli_log` and `fli_max`, MEGNO's sums passed through as they
/// are (nothing reads them). The GPU runs it for the FLI alone: there
/// every sample runs whole, so the sums' eight operations per trajectory
/// and sample were paid for nothing.
pub fn chaos_fli_program(d: usize) -> Lowered {
    chaos_lowered(d, false)
}

fn chaos_lowered(d: usize, megno: bool) -> Lowered {
    let mut g = Dag::new();
    let x: Vec<Id> = (0..d + 7).map(|i| g.var(i as u32)).collect();
    let [octave, log0, max0, sum0, mean0, count, inv_count] = x[d..] else {
        unreachable!("seven inputs after the vector")
    };
    let u = &x[..d];
    let n2 = dot(&mut g, u, u);
    let ln = ln_norm(&mut g, octave, n2);
    let sums = match megno {
        true => megno_sums(&mut g, ln, [log0, max0, sum0, mean0], count, inv_count),
        false => [ln, g.call2(Func2::Max, max0, ln), sum0, mean0],
    };
    let (mut roots, e, _) = rescale(&mut g, u, octave, n2);
    roots.push(e);
    roots.extend(sums);
    lower(&g, &roots)
}

/// The first part of [`chaos_program`] for a vector in the band: its
/// ‖u‖². Inputs: the result's array (not read), the vector's `d`
/// components; output ‖u‖², over input 0. The samples of a run of steps
/// take it step by step (its band check decides whether they wait), and
/// the rest when they are brought up to date ([`chaos_ln_sums_program`]).
pub fn chaos_n2_program(d: usize) -> Lowered {
    let mut g = Dag::new();
    let x: Vec<Id> = (0..d + 1).map(|i| g.var(i as u32)).collect();
    let n2 = dot(&mut g, &x[1..], &x[1..]);
    lower(&g, &[n2])
}

/// The second part of [`chaos_program`] for a vector in the band: ln‖w‖
/// and the sums. Inputs `fli_log`, `fli_max`, `megno_sum`, `megno_mean`,
/// ‖u‖² (from [`chaos_n2_program`]), `fli_oct`, the sample's number and
/// one over it; outputs the first four, over them. Its logarithm reads a
/// positive normal number (the CPU's `sample_log_normal_r`). The
/// logarithms of consecutive samples are independent: taken here, they
/// overlap the sums' chain from one sample to the next.
pub fn chaos_ln_sums_program() -> Lowered {
    let mut g = Dag::new();
    let x: Vec<Id> = (0..8).map(|i| g.var(i)).collect();
    let ln = ln_norm(&mut g, x[5], x[4]);
    let sums = megno_sums(&mut g, ln, [x[0], x[1], x[2], x[3]], x[6], x[7]);
    lower(&g, &sums)
}

/// `fli_log`, `fli_max`, `megno_sum` and `megno_mean` after a sample
/// whose ln‖w‖ is `ln` (the sample's number `count`).
fn megno_sums(g: &mut Dag, ln: Id, state: [Id; 4], count: Id, inv_count: Id) -> [Id; 4] {
    let [log0, max0, sum0, mean0] = state;
    let max = g.call2(Func2::Max, max0, ln);
    let delta = g.sub(ln, log0);
    let weighted = g.mul(count, delta);
    let sum = g.add(sum0, weighted);
    // Y = 2 Σ / n, and ⟨Y⟩ as a running mean.
    let two = g.num(2.0);
    let twice = g.mul(two, sum);
    let y = g.mul(twice, inv_count);
    let dev = g.sub(y, mean0);
    let step = g.mul(dev, inv_count);
    let mean = g.add(mean0, step);
    [ln, max, sum, mean]
}

/// ln‖w‖ = E ln 2 + ½ ln‖u‖² of a vector kept as u = w·2^−E.
fn ln_norm(g: &mut Dag, octave: Id, n2: Id) -> Id {
    let ln2 = g.num(std::f64::consts::LN_2);
    let whole = g.mul(octave, ln2);
    let log = g.call(Func::SampleLog, n2);
    let half = g.num(0.5);
    let part = g.mul(half, log);
    g.add(whole, part)
}
/// The FLI vector's ‖u‖² as [`chaos_program`] computes it, into a running
/// maximum (a run of steps keeps it while the FLI's samples wait, where a
/// sample would change nothing but `fli_max`): inputs the result's array
/// (not read), that maximum, then the vector's `d` components; output the
/// new maximum, over input 0 (the old one stays, for a vector that turns
/// out to be outside the band, where the sample must run).
pub fn chaos_peak_program(d: usize) -> Lowered {
    let mut g = Dag::new();
    let x: Vec<Id> = (0..d + 2).map(|i| g.var(i as u32)).collect();
    let n2 = dot(&mut g, &x[2..], &x[2..]);
    let max = g.call2(Func2::Max, x[1], n2);
    lower(&g, &[max])
}

/// `fli_max` after samples that waited, from the largest ‖u‖² among them
/// ([`chaos_peak_program`]), as [`chaos_program`] would have made it at
/// that step (ln is non-decreasing, and E does not change while the
/// samples wait): inputs `fli_max`, `fli_oct` and that ‖u‖², in the band
/// of `in_band_r`; output `fli_max`, over input 0.
pub fn chaos_fold_program() -> Lowered {
    let mut g = Dag::new();
    let [max0, octave, n2] = [0, 1, 2].map(|i| g.var(i));
    let ln = ln_norm(&mut g, octave, n2);
    let max = g.call2(Func2::Max, max0, ln);
    lower(&g, &[max])
}

/// Where [`chaos_program`] of dimension `d` reads and writes `fli_max`
/// among its inputs and outputs (the vector, `fli_oct`, `fli_log`, then it).
pub fn chaos_fli_max(d: usize) -> usize {
    d + 2
}

/// `v` times the power of two s = 2^a that keeps it in range (`n2` its
/// squared norm), exactly, its octaves E − a, and s: NaN where `n2` is
/// not positive, so that a collapsed vector is flagged like a diverged
/// one.
fn rescale(g: &mut Dag, v: &[Id], octave: Id, n2: Id) -> (Vec<Id>, Id, Id) {
    let a = g.call(Func::Octave, n2);
    let s = g.call(Func::Rescale, a);
    let scaled = v.iter().map(|x| g.mul(*x, s)).collect();
    (scaled, g.sub(octave, a), s)
}

/// The Lyapunov exponents from the indicators' slots (`slot(k)` the value
/// of slot k), largest first: each Σ ln Rᵢᵢ = ln‖wᵢ‖ at the last sample at
/// or before `last_step` minus ln‖wᵢ‖ at the skip step, in f64, over the
/// time between them; NaN when no sample counted or the trajectory did
/// not finish (`ok` false).
pub fn lyapunov_finish(
    ind: &Indicators,
    dt: f64,
    last_step: u64,
    ok: bool,
    slot: impl Fn(usize) -> f64,
) -> Vec<f64> {
    let k = ind.exponents();
    let every = ind.lyapunov.as_ref().map_or(1, |l| l.every);
    let last_sample = last_step / every * every;
    if !ok || last_sample <= ind.skip_step {
        return vec![f64::NAN; k];
    }
    let span = (last_sample - ind.skip_step) as f64 * dt;
    let value = |name: &str, i: usize| ind.slot_of(&format!("{name}_{i}")).map_or(f64::NAN, &slot);
    let ln = |oct: f64, n2: f64| oct * std::f64::consts::LN_2 + 0.5 * n2.ln();
    let mut out: Vec<f64> = (0..k)
        .map(|i| {
            let now = ln(value("lyap_oct", i), value("lyap_n2", i));
            let start = ln(value("lyap_start_oct", i), value("lyap_start_n2", i));
            (now - start) / span
        })
        .collect();
    out.sort_by(|a, b| b.total_cmp(a));
    out
}

/// The Lyapunov slots [`lyapunov_finish`] reads.
pub fn lyapunov_slots(ind: &Indicators) -> Vec<usize> {
    (0..ind.exponents())
        .flat_map(|i| {
            LYAPUNOV_STATE
                .iter()
                .map(move |(name, _)| format!("{name}_{i}"))
        })
        .filter_map(|name| ind.slot_of(&name))
        .collect()
}
