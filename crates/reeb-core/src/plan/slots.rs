//! The observers' per-trajectory state, declared once: the CPU keeps it per
//! lane of a block (`backend/cpu/observe.rs`), the GPU per thread in the
//! buffers `aux_r` and `aux_u` (`backend/gpu/codegen.rs` names a WGSL local
//! after each slot; `run.rs` reads them back by these indices); both
//! snapshot it in this order. Each observer's finish, what its outputs are
//! made of from its slots, is here too, so both backends share it.

use crate::models::Flows;
use crate::plan::indicators::{lyapunov_finish, lyapunov_slots, SCALAR_INDICATORS};
use crate::plan::observations::Put;
use crate::plan::observers::Observers;
use crate::plan::recurrence::Layout;
use crate::plan::Plan;

/// A slot's value before the first step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Init {
    Zero,
    Inf,
    NegInf,
    Value(f64),
}

impl Init {
    pub fn value<R: Flows>(self) -> R {
        match self {
            Init::Zero => R::default(),
            Init::Inf => R::inf(),
            Init::NegInf => -R::inf(),
            Init::Value(v) => R::from_f64(v),
        }
    }

    /// The same value in WGSL.
    pub fn wgsl(self) -> String {
        match self {
            Init::Zero => "0.0".into(),
            Init::Inf => "inf()".into(),
            Init::NegInf => "-inf()".into(),
            Init::Value(v) => crate::num::formula::wgsl::lit(v),
        }
    }
}

/// Slots in the working precision: the cycle statistics' running extremes,
/// crossing count, first crossing time, and the running mean and co-moment
/// of the crossing times (`models/events.rs::cycle_step`).
pub const REAL: [(&str, Init); 6] = [
    ("cyc_max", Init::NegInf),
    ("cyc_min", Init::Inf),
    ("cyc_count", Init::Zero),
    ("cyc_first", Init::Zero),
    ("cyc_mean", Init::Zero),
    ("cyc_com", Init::Zero),
];
pub const CYC_MAX: usize = 0;
pub const CYC_MIN: usize = 1;
pub const CYC_COUNT: usize = 2;
pub const CYC_COM: usize = 5;

/// The first slot of the time averages: one per averaged variable after
/// the fixed [`REAL`] slots, each the running mean of its values.
pub const MEAN0: usize = REAL.len();

/// Every real slot of `plan`: [`REAL`], then `mean_<j>` per averaged
/// variable (`plan.average_vars[j]`), starting at 0, then the chaos
/// indicators' (`plan/indicators.rs`), then the attractor detector's
/// (`plan/recurrence.rs`).
pub fn real(plan: &Plan) -> Vec<(String, Init)> {
    let fixed = REAL.iter().map(|(n, init)| (n.to_string(), *init));
    let means = (0..plan.average_vars.len()).map(|j| (format!("mean_{j}"), Init::Zero));
    let indicators = plan.indicators.iter().flat_map(|i| {
        i.slots.iter().map(|(n, v)| {
            let init = match *v {
                0.0 => Init::Zero,
                f64::NEG_INFINITY => Init::NegInf,
                v => Init::Value(v),
            };
            (n.clone(), init)
        })
    });
    let recurrence = (recurrence(plan).into_iter())
        .flat_map(|r| r.slot_names().into_iter().map(|n| (n, Init::Zero)));
    fixed
        .chain(means)
        .chain(indicators)
        .chain(recurrence)
        .collect()
}

/// The attractor detector of `plan`, where it has one, as both backends
/// keep it (`plan/recurrence.rs`): after the chaos indicators' slots.
pub fn recurrence(plan: &Plan) -> Option<Layout> {
    let a = plan.observers.attractors.as_ref()?;
    Some(Layout {
        first: recurrence_first(plan),
        max_period: a.max_period,
        dim: plan.attractor_vars.len(),
        tolerance: a.tolerance,
        wrap: a.wrap(),
        skip_step: a.skip_step(plan.steps),
        every: plan
            .observers
            .poincare
            .is_none()
            .then(|| a.every(plan.steps)),
    })
}

/// The real slot of the attractor detector's first: after the chaos
/// indicators'.
pub fn recurrence_first(plan: &Plan) -> usize {
    indicator_first(plan) + plan.indicators.as_ref().map_or(0, |i| i.slots.len())
}

/// The real slot of the chaos indicators' slot 0: they follow the fixed
/// slots and the averages'.
pub fn indicator_first(plan: &Plan) -> usize {
    MEAN0 + plan.average_vars.len()
}

/// 32-bit counters (start at 0): the next interpolated stroboscopic sample,
/// and the Poincaré points found.
pub const COUNT: [&str; 2] = ["strobe_k", "npoints"];
pub const STROBE_K: usize = 0;
pub const NPOINTS: usize = 1;

/// The cycle statistics' outputs, `(amplitude, period)`, from a
/// trajectory's real slots (`slot(k)`: slot `k`); NaN for a trajectory that
/// stopped (`ok` false), and the period NaN below two crossings.
pub fn cycle_finish<R: Flows>(slot: impl Fn(usize) -> R, ok: bool) -> (R, R) {
    if !ok {
        return (R::nan(), R::nan());
    }
    let amplitude = R::cycle_amplitude(slot(CYC_MAX), slot(CYC_MIN));
    let crossings = slot(CYC_COUNT);
    let period = if crossings >= R::from_f64(2.0) {
        R::cycle_period(slot(CYC_COM), crossings)
    } else {
        R::nan()
    };
    (amplitude, period)
}

/// The flag of a trajectory's status word (both backends: 0 running or
/// finished, k > 0 non-finite at step k, `STOPPED | k` stopped by the stop
/// condition after step k; plans have fewer than 2³¹ steps).
pub const STOPPED: u32 = 1 << 31;

/// The status word of a GPU thread whose step loop the adapter ended before
/// its window's end (`shaders/driver.wgsl`; llvmpipe's limit on loop
/// iterations, `backend/gpu/run.rs`): a stop after step 0, which no stop
/// condition makes (they are tested after a step). Never a result: the run
/// fails.
pub const CUT: u32 = STOPPED;

/// A status word as `(non-finite step, stop step)`, 0 for neither.
pub fn split_status(st: u64) -> (u32, u32) {
    let st = st as u32;
    if st & STOPPED != 0 {
        (0, st & !STOPPED)
    } else {
        (st, 0)
    }
}

/// The step a trajectory's observers ended at: its stop step, or the run's.
pub fn last_step(plan: &Plan, stop_step: u32) -> u64 {
    if stop_step != 0 {
        stop_step.into()
    } else {
        plan.steps
    }
}

/// A time average's output from its slot: NaN for a trajectory that
/// became non-finite (`ok` false) or stopped before its first value.
pub fn mean_finish<R: Flows>(plan: &Plan, mean: R, ok: bool, stop_step: u32) -> R {
    if ok && last_step(plan, stop_step) > plan.average_start() {
        mean
    } else {
        R::nan()
    }
}

/// What the attractor detector says of one trajectory at its end: the
/// period of the cycle its samples end on (0 aperiodic, −1 escaped: stopped
/// or non-finite), the sample from which on they recur (−1: none), and its
/// last `max_period` samples, oldest first, `dim` components each (NaN
/// where fewer were taken, and for a non-finite trajectory).
#[derive(Debug, Clone, PartialEq)]
pub struct AttractorEnd<R> {
    pub period: i32,
    pub transient: i32,
    pub points: Vec<R>,
}

impl<R: Copy> AttractorEnd<R> {
    /// These values as row `row` of the columns `attractor_period`,
    /// `transient` and `attractor_points` (one per component).
    pub fn put<I: Put<i32>, C: Put<R>>(
        &self,
        mut period: I,
        mut transient: I,
        points: Vec<C>,
        row: usize,
    ) {
        period.put(row, self.period);
        transient.put(row, self.transient);
        let dim = points.len().max(1);
        let kept = self.points.len() / dim;
        for (c, mut column) in points.into_iter().enumerate() {
            for m in 0..kept {
                column.put(row * kept + m, self.points[m * dim + c]);
            }
        }
    }
}

/// The attractor detector's end from a trajectory's real slots (`slot(k)`)
/// and its status `(non-finite step, stop step)`.
pub fn attractor_finish<R: Flows>(
    at: &Layout,
    slot: impl Fn(usize) -> R,
    (nonfinite, stop): (u32, u32),
) -> AttractorEnd<R> {
    let n = slot(at.count()).to_f64();
    let mut points = Vec::with_capacity(at.max_period * at.dim);
    for j in (1..=at.max_period).rev() {
        let taken = j as f64 <= n && nonfinite == 0;
        points.extend((0..at.dim).map(|c| match taken {
            true => slot(at.sample(j, c)),
            false => R::nan(),
        }));
    }
    let (period, transient) = match (nonfinite, stop) {
        (0, 0) => at.verdict(|k| slot(k).to_f64()),
        _ => (-1, -1),
    };
    AttractorEnd {
        period,
        transient,
        points,
    }
}

/// The sampling period of scalar indicator `k` of `indicators::SCALAR_INDICATORS`,
/// if the plan asks for it.
pub fn scalar_every(o: &Observers, k: usize) -> Option<u64> {
    (SCALAR_INDICATORS[k].every)(o)
}

/// A trajectory's chaos indicators: its Lyapunov exponents (largest
/// first; none where not asked for) and the `indicators::SCALAR_INDICATORS` (NaN
/// where not asked for).
#[derive(Debug, Clone, PartialEq)]
pub struct IndicatorValues<R> {
    pub lyapunov: Vec<R>,
    pub scalars: [R; 4],
}

impl<R: Copy> IndicatorValues<R> {
    /// These values as row `row` of the indicators' columns (the outputs,
    /// or the running values at a frame): the exponents' row of `lyapunov`,
    /// each scalar in its column where the plan has it.
    pub fn put<C: Put<R>>(&self, mut lyapunov: C, scalars: [C; 4], row: usize) {
        let k = self.lyapunov.len();
        for (j, x) in self.lyapunov.iter().enumerate() {
            lyapunov.put(row * k + j, *x);
        }
        for (mut column, x) in scalars.into_iter().zip(self.scalars) {
            if !column.is_empty() {
                column.put(row, x);
            }
        }
    }
}

/// The chaos indicators' outputs from a trajectory's real slots
/// (`slot(k)`), its step `dt` and status; NaN for a trajectory that
/// became non-finite or ended before a sample counted.
pub fn indicators_finish<R: Flows>(
    plan: &Plan,
    slot: impl Fn(usize) -> R,
    dt: R,
    ok: bool,
    stop_step: u32,
) -> IndicatorValues<R> {
    // A deviation vector that left the finite numbers (its growth between
    // two samples beyond the precision's range) stays out of them: the
    // trajectory keeps its state and loses its indicators. (The frames
    // record the indicators' slots, not the vectors: their running values
    // after such a loss are NaN where they are read from the sums.)
    let first = indicator_first(plan);
    let mut vectors = plan.indicators.iter().flat_map(|i| &i.deviation_slots);
    let ok = ok && vectors.all(|&k| slot(first + k).finite());
    indicators_at(plan, slot, dt, ok, last_step(plan, stop_step))
}

/// The chaos indicators' values after step `last` (their running values,
/// which trajectory frames record; at the run's end, the outputs).
pub fn indicators_at<R: Flows>(
    plan: &Plan,
    slot: impl Fn(usize) -> R,
    dt: R,
    ok: bool,
    last: u64,
) -> IndicatorValues<R> {
    let Some(ind) = &plan.indicators else {
        return IndicatorValues {
            lyapunov: vec![],
            scalars: [R::nan(); 4],
        };
    };
    let first = indicator_first(plan);
    let slot = |k: usize| slot(first + k);
    let exponents = lyapunov_finish(ind, dt.to_f64(), last, ok, |k| slot(k).to_f64());
    let value = |k: usize| {
        let sampled = ok && scalar_every(&plan.observers, k).is_some_and(|e| last >= e);
        match (sampled, ind.scalar_slots[k]) {
            (true, Some(s)) => slot(s),
            _ => R::nan(),
        }
    };
    IndicatorValues {
        lyapunov: exponents.into_iter().map(R::from_f64).collect(),
        scalars: [0, 1, 2, 3].map(value),
    }
}

/// The real slots [`indicators_at`] reads (absolute indices), which the GPU
/// records per trajectory frame; empty without a trajectory observer.
pub fn indicator_frame_slots(plan: &Plan) -> Vec<usize> {
    match (&plan.indicators, &plan.observers.trajectory) {
        (Some(ind), Some(_)) => {
            let first = indicator_first(plan);
            let chaos = ind.scalar_slots;
            lyapunov_slots(ind)
                .into_iter()
                .chain(chaos.into_iter().flatten())
                .map(|k| first + k)
                .collect()
        }
        _ => vec![],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_indices_name_their_slots() {
        let names = [
            (CYC_MAX, "cyc_max"),
            (CYC_MIN, "cyc_min"),
            (CYC_COUNT, "cyc_count"),
            (CYC_COM, "cyc_com"),
        ];
        for (k, name) in names {
            assert_eq!(REAL[k].0, name);
        }
        assert_eq!(COUNT[STROBE_K], "strobe_k");
        assert_eq!(COUNT[NPOINTS], "npoints");
    }
}
