//! What the finished arrays of a run say is doubtful: Poincaré points
//! dropped beyond `max_points`, chaos indicators of trajectories the stop
//! condition ended early, indicators lost to deviation vectors that left
//! the precision's range, and Lyapunov exponents that the spacing of the
//! re-orthonormalisations cannot resolve. Each is a warning (stderr and
//! `summary.json`'s `warnings`) and a count in `summary.json`; the
//! pictures mark the trajectories concerned. Read from the arrays alone,
//! so a resumed run and `reeb merge` say the same.

use serde_json::{json, Map, Value};

use crate::num::precision::Real;
use crate::plan::observations::Observations;
use crate::scene::{Scene, SubRun};

/// How many digits an exponent's sample may lose and still count as
/// resolved: between two re-orthonormalisations the part of vector k
/// orthogonal to the ones before it shrinks, relative to them, by about
/// e^{−(λ₁ − λ_k)·every·dt}; once that ratio is below 2¹⁰ units of
/// round-off, that part (whose growth is λ_k's sample) keeps fewer than
/// about three significant digits, and soon none.
const DIGITS_LOST: f64 = 1024.0;

/// The doubts of a run (see the module documentation).
#[derive(Debug, Default)]
pub struct Doubts {
    pub warnings: Vec<String>,
    /// `summary.json`'s entries: `poincare`, `indicators`.
    pub summary: Map<String, Value>,
    /// Per trajectory and exponent (`n × exponents`): whether it is
    /// resolved (always for the first).
    pub resolved: Vec<bool>,
}

impl Doubts {
    /// Whether exponent `j` (0 the largest) of trajectory `i` is resolved.
    pub fn resolved(&self, i: usize, j: usize, exponents: usize) -> bool {
        self.resolved
            .get(i * exponents + j)
            .copied()
            .unwrap_or(true)
    }
}

/// The doubts of the run of `scene` (its plans `subs`) whose arrays `d` holds.
pub fn of<R: Real>(scene: &Scene, subs: &[SubRun], d: &Observations<R>) -> Doubts {
    let mut out = Doubts::default();
    dropped_points(scene, d, &mut out);
    let mut indicators = Map::new();
    if scene.observers.has_indicators() {
        stopped_indicators(d, &mut indicators, &mut out);
        lost_indicators(d, &mut indicators, &mut out);
    }
    unresolved_exponents::<R>(scene, subs, d, &mut indicators, &mut out);
    if !indicators.is_empty() {
        out.summary.insert("indicators".into(), indicators.into());
    }
    out
}

/// Points a Poincaré section found beyond `max_points` (counted, not kept).
fn dropped_points<R: Real>(scene: &Scene, d: &Observations<R>, out: &mut Doubts) {
    if scene.observers.poincare.is_none() {
        return;
    }
    let max = d.max_points as u64;
    let found: u64 = d.poincare_count.iter().map(|c| u64::from(*c)).sum();
    let over: Vec<u64> = d
        .poincare_count
        .iter()
        .map(|c| u64::from(*c).saturating_sub(max))
        .filter(|x| *x > 0)
        .collect();
    let dropped: u64 = over.iter().sum();
    out.summary.insert(
        "poincare".into(),
        json!({"max_points": max, "found": found, "kept": found - dropped, "dropped": dropped, "trajectories_over": over.len()}),
    );
    if dropped > 0 {
        out.warnings.push(format!(
            "output.poincare.max_points = {max}: {} of {} trajectories crossed the section more often, and their {dropped} further points were dropped (poincare_count.npy holds every trajectory's count); raise max_points to keep them",
            over.len(),
            d.n
        ));
    }
}

/// Trajectories the stop condition ended: their indicators cover less time.
fn stopped_indicators<R: Real>(
    d: &Observations<R>,
    indicators: &mut Map<String, Value>,
    out: &mut Doubts,
) {
    let stopped = d.stop_step.iter().filter(|s| **s != 0).count();
    indicators.insert("stopped".into(), stopped.into());
    if stopped > 0 {
        out.warnings.push(format!(
            "{stopped} of {} trajectories stopped (output.stop) before the run's end: their chaos indicators measure only the time before they stopped, not the whole run; the maps show them as \"stopped\"",
            d.n
        ));
    }
}

/// Whether trajectory `i` has every indicator the run asks for finite.
fn indicators_finite<R: Real>(d: &Observations<R>, i: usize) -> bool {
    let k = d.exponents;
    let finite = |v: &[R], i: usize| v.get(i).is_none_or(|x| x.finite());
    (0..k).all(|j| finite(&d.lyapunov, i * k + j))
        && d.scalar_indicators(false).iter().all(|v| finite(v, i))
}

/// Trajectories that ran to the end with indicators that are not finite:
/// their deviation vectors left the precision's range between samples.
fn lost_indicators<R: Real>(
    d: &Observations<R>,
    indicators: &mut Map<String, Value>,
    out: &mut Doubts,
) {
    let ran = |i: usize| d.nonfinite_step[i] == 0 && d.stop_step[i] == 0;
    let lost = (0..d.n)
        .filter(|&i| ran(i) && !indicators_finite(d, i))
        .count();
    indicators.insert("lost".into(), lost.into());
    if lost > 0 {
        out.warnings.push(format!(
            "the deviation vectors of {lost} of {} trajectories left the range of {} between two samples, or collapsed onto each other: their chaos indicators are NaN (their states ran to the end and are kept); sample more often (a smaller every){}",
            d.n,
            R::NAME,
            if R::NAME == "f32" { ", or run in f64" } else { "" }
        ));
    }
}

/// Lyapunov exponents beyond the first whose samples the spacing of the
/// re-orthonormalisations leaves at round-off ([`DIGITS_LOST`]), judged
/// from the exponents found: a collapsed vector's exponent comes out
/// about ln(1/round-off) / (every·dt) below λ₁, so it is caught too.
fn unresolved_exponents<R: Real>(
    scene: &Scene,
    subs: &[SubRun],
    d: &Observations<R>,
    indicators: &mut Map<String, Value>,
    out: &mut Doubts,
) {
    let k = d.exponents;
    out.resolved = vec![true; d.n * k];
    if k < 2 {
        return;
    }
    let limit = (1.0 / (DIGITS_LOST * R::UNIT_ROUNDOFF)).ln();
    let (shape, strides) = (scene.shape(), scene.strides());
    let mut count = vec![0u64; k];
    // The largest (λ₁ − λ_k)·dt over the unresolved, per plan's `every`.
    let mut worst: Option<(f64, u64)> = None;
    for sub in subs {
        let Some(every) = sub.plan.observers.lyapunov.as_ref().map(|l| l.every) else {
            continue;
        };
        let dt = sub.plan.binding("dt");
        for j in 0..sub.plan.n {
            let i = sub.scene_row(j, &shape, &strides);
            let dt = dt.value_at(sub.plan.first + j, &sub.plan.strides);
            let exponents = &d.lyapunov[i * k..(i + 1) * k];
            let lambda1 = exponents[0].to_f64();
            for (m, lambda) in exponents.iter().enumerate().skip(1) {
                let gap = (lambda1 - lambda.to_f64()) * dt;
                if gap * every as f64 > limit {
                    out.resolved[i * k + m] = false;
                    count[m] += 1;
                    if worst.is_none_or(|(g, _)| gap > g) {
                        worst = Some((gap, every));
                    }
                }
            }
        }
    }
    indicators.insert("unresolved".into(), json!(count));
    let Some((gap, every)) = worst else {
        return;
    };
    let named: Vec<String> = (1..k)
        .filter(|m| count[*m] > 0)
        .map(|m| format!("λ{} in {} of {} trajectories", m + 1, count[m], d.n))
        .collect();
    // The gap found is a lower bound once a vector has collapsed.
    let bound = (limit / gap).floor().max(1.0);
    out.warnings.push(format!(
        "{} not resolved: between two re-orthonormalisations (output.lyapunov.every = {every} steps) a deviation vector's part orthogonal to the faster ones shrinks by e^-{:.0} or more relative to them, beyond what {} resolves, so its exponent is round-off and the exponents' sum no longer holds; re-orthonormalise more often (every well below {bound}, until this warning goes); the maps show these as \"not resolved\"",
        named.join(", "),
        gap * every as f64,
        R::NAME
    ));
}
