//! Chaos indicators as observers: finite-time Lyapunov exponents
//! (Benettin's method), the Fast Lyapunov Indicator and MEGNO. Their
//! deviation vectors follow the exact tangent map of the step
//! (`plan/tangent.rs`); at each sample a program re-normalises them and
//! updates the sums. The tangent step and the samples are formulas lowered
//! to one program each, which both backends run (the CPU's block
//! interpreter, WGSL on the GPU): one source for all of it.
//!
//! Per-trajectory state (real slots, after the time averages'): the
//! deviation vectors `w{k}_{j}` (Lyapunov's k vectors, starting as the
//! identity's columns, then the FLI/MEGNO vector, (1, …, 1)/√d); the sums
//! of ln Rᵢᵢ `lyap_{i}`; `fli_log` = ln‖w‖ so far (the vector is kept
//! normalised, its growth in this running logarithm, so nothing
//! overflows), `fli_max` its maximum over the samples; `megno_sum` =
//! Σ t_k ln(‖w_k‖/‖w_{k−1}‖) and `megno_mean` = ⟨Y⟩.

use crate::num::formula::lower::{lower, Lowered};
use crate::num::formula::{Dag, Func, Func2, Id};

use super::observers::Observers;
use super::problem::{err, PlanError};
use super::tangent::{StepSpec, TangentInput, TangentStep};

/// What a sample program reads besides slots.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleInput {
    /// The indicators' slot at this index (of [`Indicators::slots`]).
    Slot(usize),
    /// The time since the start, `n1·dt`.
    Elapsed,
    /// One over the sample's number (1 for the first): the running mean's
    /// weight, a product where a quotient would cost a division per lane.
    InvCount,
    /// 1 when the sample counts (after the skipped part), else 0.
    Counted,
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
    /// Lyapunov sums start after this step (a multiple of `every`).
    pub skip_step: u64,
    /// The slots: name and value before the first step. Indices here are
    /// into this list; the plan's real slots hold it after the averages'
    /// (`slots::indicator_first`).
    pub slots: Vec<(String, f64)>,
}

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
        if k == 0 && chaos.is_none() {
            return Ok(None);
        }
        let vectors = k + usize::from(chaos.is_some());
        let tangent = TangentStep::new(step, vectors).map_err(|e| {
            let which = if k > 0 { "lyapunov" } else { "fli" };
            err(format!("output.{which}"), e.message)
        })?;
        let d = tangent.space.len();
        if k > d {
            return Err(err(
                "output.lyapunov.vectors",
                format!(
                    "{k} is more than the tangent dimension {d} of this plan ({})",
                    tangent.space.join(", ")
                ),
            ));
        }
        let mut s = Indicators {
            deviation_slots: (0..vectors * d).collect(),
            tangent,
            lyapunov: None,
            chaos: None,
            skip_step: 0,
            slots: vec![],
        };
        s.slots = s.deviation_inits(k, chaos.is_some());
        if let Some(l) = &observers.lyapunov {
            let skip = (l.skip * steps as f64).ceil() as u64;
            s.skip_step = skip.div_ceil(l.every) * l.every;
            s.lyapunov = Some(s.lyapunov_sampler(k, l.every));
        }
        if let Some(every) = chaos {
            s.chaos = Some(s.chaos_sampler(k, every));
        }
        Ok(Some(s))
    }

    fn dimension(&self) -> usize {
        self.tangent.space.len()
    }

    /// The deviation vectors' slots: identity columns, then (1, …, 1)/√d.
    fn deviation_inits(&self, k: usize, chaos: bool) -> Vec<(String, f64)> {
        let d = self.dimension();
        let mut out = vec![];
        for v in 0..k + usize::from(chaos) {
            for j in 0..d {
                let x = match v < k {
                    true => f64::from(u8::from(v == j)),
                    false => 1.0 / (d as f64).sqrt(),
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

    /// Modified Gram–Schmidt on vectors `0..k`, adding ln Rᵢᵢ (when the
    /// sample counts) to the sums ([`lyapunov_program`]).
    fn lyapunov_sampler(&mut self, k: usize, every: u64) -> Sampler {
        let d = self.dimension();
        let sums: Vec<usize> = (0..k)
            .map(|i| self.slot(format!("lyap_{i}"), 0.0))
            .collect();
        let w = &self.deviation_slots[..k * d];
        let mut inputs: Vec<SampleInput> = w.iter().map(|s| SampleInput::Slot(*s)).collect();
        inputs.extend(sums.iter().map(|s| SampleInput::Slot(*s)));
        inputs.push(SampleInput::Counted);
        let mut outputs = w.to_vec();
        outputs.extend(sums);
        let shape = SampleShape::Lyapunov { d, k };
        Sampler {
            every,
            program: shape.program(),
            shape,
            inputs,
            outputs,
        }
    }

    /// The FLI/MEGNO vector (number `k`) normalised, its growth logged
    /// ([`chaos_program`]).
    fn chaos_sampler(&mut self, k: usize, every: u64) -> Sampler {
        let d = self.dimension();
        let u = self.deviation_slots[k * d..(k + 1) * d].to_vec();
        let state = [
            self.slot("fli_log".into(), 0.0),
            self.slot("fli_max".into(), f64::NEG_INFINITY),
            self.slot("megno_sum".into(), 0.0),
            self.slot("megno_mean".into(), 0.0),
        ];
        let mut inputs: Vec<SampleInput> = u.iter().map(|s| SampleInput::Slot(*s)).collect();
        inputs.extend(state.iter().map(|s| SampleInput::Slot(*s)));
        inputs.extend([SampleInput::Elapsed, SampleInput::InvCount]);
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
        self.lyapunov
            .as_ref()
            .map_or(0, |l| l.outputs.len() / (self.dimension() + 1))
    }
}

/// A sample program's shape: which indicator, over a tangent space of
/// dimension `d` (and `k` Lyapunov vectors). The program depends on the
/// shape alone, so the CPU compiles the usual shapes ahead
/// (`backend/cpu/sample_ops.rs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleShape {
    Lyapunov { d: usize, k: usize },
    Chaos { d: usize },
}

impl SampleShape {
    /// How many inputs its program reads.
    pub fn inputs(self) -> usize {
        match self {
            SampleShape::Lyapunov { d, k } => k * d + k + 1,
            SampleShape::Chaos { d } => d + 6,
        }
    }

    pub fn program(self) -> Lowered {
        match self {
            SampleShape::Lyapunov { d, k } => lyapunov_program(d, k),
            SampleShape::Chaos { d } => chaos_program(d),
        }
    }
}

/// Modified Gram–Schmidt on `k` vectors of dimension `d`, adding ln Rᵢᵢ
/// (when the sample counts) to the sums. Inputs: the vectors' components
/// (vector i's component j at i·d + j), the k sums, whether the sample
/// counts; outputs: the orthonormal vectors, then the sums.
pub fn lyapunov_program(d: usize, k: usize) -> Lowered {
    let mut g = Dag::new();
    let var = |g: &mut Dag, k: usize| g.var(k as u32);
    let counted = var(&mut g, k * d + k);
    let mut basis: Vec<Vec<Id>> = vec![];
    let mut roots_sums = vec![];
    for i in 0..k {
        let mut v: Vec<Id> = (0..d).map(|j| var(&mut g, i * d + j)).collect();
        for e in &basis {
            let proj = dot(&mut g, &v, e);
            v = v
                .iter()
                .zip(e)
                .map(|(x, y)| {
                    let p = g.mul(proj, *y);
                    g.sub(*x, p)
                })
                .collect();
        }
        let r = norm(&mut g, &v);
        let inv = reciprocal(&mut g, r);
        basis.push(v.iter().map(|x| g.mul(*x, inv)).collect());
        let ln = g.call(Func::Log, r);
        let add = g.mul(counted, ln);
        let sum = var(&mut g, k * d + i);
        roots_sums.push(g.add(sum, add));
    }
    let mut roots: Vec<Id> = basis.concat();
    roots.extend(roots_sums);
    lower(&g, &roots)
}

/// The FLI/MEGNO vector of dimension `d` normalised, its growth logged.
/// Inputs: its components, `fli_log`, `fli_max`, `megno_sum`,
/// `megno_mean`, the elapsed time, one over the sample's number; outputs: the
/// vector, then the four sums.
pub fn chaos_program(d: usize) -> Lowered {
    let mut g = Dag::new();
    let x: Vec<Id> = (0..d + 6).map(|i| g.var(i as u32)).collect();
    let [log0, max0, sum0, mean0, elapsed, inv_count] = x[d..] else {
        unreachable!("six inputs after the vector")
    };
    let r = norm(&mut g, &x[..d]);
    let inv = reciprocal(&mut g, r);
    let mut roots: Vec<Id> = x[..d].iter().map(|c| g.mul(*c, inv)).collect();
    let ln = g.call(Func::Log, r);
    let log = g.add(log0, ln);
    let max = g.call2(Func2::Max, max0, log);
    let weighted = g.mul(elapsed, ln);
    let sum = g.add(sum0, weighted);
    // Y = 2 Σ / t, and ⟨Y⟩ as a running mean.
    let two = g.num(2.0);
    let twice = g.mul(two, sum);
    let y = g.div(twice, elapsed);
    let dev = g.sub(y, mean0);
    let step = g.mul(dev, inv_count);
    let mean = g.add(mean0, step);
    roots.extend([log, max, sum, mean]);
    lower(&g, &roots)
}

fn dot(g: &mut Dag, a: &[Id], b: &[Id]) -> Id {
    let mut s = g.num(0.0);
    for (x, y) in a.iter().zip(b) {
        let p = g.mul(*x, *y);
        s = g.add(s, p);
    }
    s
}

/// 1/r: one division, then a product per component (a division each
/// would be d of them, the costliest operation of a sample).
fn reciprocal(g: &mut Dag, r: Id) -> Id {
    let one = g.num(1.0);
    g.div(one, r)
}

fn norm(g: &mut Dag, v: &[Id]) -> Id {
    let s = dot(g, v, v);
    g.call(Func::Sqrt, s)
}

/// The Lyapunov exponents from the sums (`sum(i)`), largest first: each
/// sum over the time between the skip step and the last sample at or
/// before `last_step`; NaN when no sample counted or the trajectory did
/// not finish (`ok` false).
pub fn lyapunov_finish(
    ind: &Indicators,
    dt: f64,
    last_step: u64,
    ok: bool,
    sum: impl Fn(usize) -> f64,
) -> Vec<f64> {
    let k = ind.exponents();
    let every = ind.lyapunov.as_ref().map_or(1, |l| l.every);
    let last_sample = last_step / every * every;
    if !ok || last_sample <= ind.skip_step {
        return vec![f64::NAN; k];
    }
    let span = (last_sample - ind.skip_step) as f64 * dt;
    let mut out: Vec<f64> = (0..k).map(|i| sum(i) / span).collect();
    out.sort_by(|a, b| b.total_cmp(a));
    out
}
