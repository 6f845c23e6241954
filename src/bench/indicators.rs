//! What the chaos indicators cost: `reeb bench --indicators`. Each
//! indicator's run of a cost scene against the same scene without it (the
//! plain run), in alternating pairs on one backend and precision, as the
//! median of the pairs' ratios: a machine's drift moves both runs of a
//! pair alike. The goals (issue 33): one exponent, the FLI and MEGNO at
//! most 2 plain runs, the full spectrum of a 2-D system at most 3.

use crate::backend::{BackendError, Engine};
use crate::models::Model;
use crate::num::precision::Precision;
use crate::plan::observers::{LyapunovObs, SampledObs};
use crate::plan::{Plan, Problem, Source};

/// A scene the cost is measured on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CostScene {
    /// Van der Pol, 4096 orbits (64 × 64 over ε ∈ [0.5, 2] and
    /// q₀ ∈ [0.5, 2.5], s₀ = 0) × 100 000 steps of dt = 0.01,
    /// `triple_jump4`.
    VanDerPol,
    /// Spin–orbit (e = 0.1, ε = 0.1), 320 × 320 orbits over
    /// q₀ ∈ [0, π] and p₀ ∈ [0.4, 1.8] × 10 000 S2 steps of dt = π/10.
    SpinOrbit,
}

pub const COST_SCENES: [CostScene; 2] = [CostScene::VanDerPol, CostScene::SpinOrbit];

/// An indicator as a scene asks for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Indicator {
    /// `lyapunov = true`: the largest exponent.
    Lyapunov,
    /// `fli = true`.
    Fli,
    /// `megno = true`.
    Megno,
    /// `lyapunov = { vectors = 2 }`: the full spectrum of a 2-D system.
    Spectrum,
}

pub const INDICATORS: [Indicator; 4] = [
    Indicator::Lyapunov,
    Indicator::Fli,
    Indicator::Megno,
    Indicator::Spectrum,
];

impl CostScene {
    pub fn label(self) -> &'static str {
        match self {
            CostScene::VanDerPol => "van_der_pol/triple_jump4",
            CostScene::SpinOrbit => "spin_orbit/s2",
        }
    }

    /// Its steps per run.
    pub fn steps(self) -> u64 {
        match self {
            CostScene::VanDerPol => 100_000,
            CostScene::SpinOrbit => 10_000,
        }
    }

    /// The plan of `steps` steps with `indicator` sampled every `every`
    /// steps (`None`: the plain run).
    pub fn plan(self, indicator: Option<Indicator>, steps: u64, every: u64) -> Plan {
        let lin = |a: f64, b: f64, n: usize| -> Vec<f64> {
            (0..n)
                .map(|i| a + (b - a) * i as f64 / (n - 1) as f64)
                .collect()
        };
        let mut p = match self {
            CostScene::VanDerPol => {
                let mut p = Problem::new(Model::VanDerPol, "triple_jump4").expect("a scheme");
                let epsilon = p.axis("epsilon", lin(0.5, 2.0, 64));
                let q = p.axis("q", lin(0.5, 2.5, 64));
                p.dt = Source::Const(0.01);
                p.param("epsilon", epsilon).initial("q", q)
            }
            CostScene::SpinOrbit => {
                let mut p = Problem::new(Model::SpinOrbit, "s2").expect("a scheme");
                let q = p.axis("q", lin(0.0, std::f64::consts::PI, 320));
                let pp = p.axis("p", lin(0.4, 1.8, 320));
                p.dt = Source::Const(std::f64::consts::PI / 10.0);
                p.param("eccentricity", Source::Const(0.1))
                    .param("epsilon", Source::Const(0.1))
                    .initial("q", q)
                    .initial("p", pp)
            }
        };
        p.steps = steps;
        let o = &mut p.observers;
        match indicator {
            None => {}
            Some(Indicator::Lyapunov) => {
                o.lyapunov = Some(LyapunovObs {
                    every,
                    ..LyapunovObs::default()
                })
            }
            Some(Indicator::Fli) => o.fli = Some(SampledObs { every }),
            Some(Indicator::Megno) => o.megno = Some(SampledObs { every }),
            Some(Indicator::Spectrum) => {
                o.lyapunov = Some(LyapunovObs {
                    vectors: 2,
                    every,
                    ..LyapunovObs::default()
                })
            }
        }
        Plan::new(&p).expect("the cost scenes are valid")
    }
}

impl Indicator {
    /// As a scene writes it, sampled every `every` steps (the default 1
    /// left out).
    pub fn label(self, every: u64) -> String {
        let (key, mut fields) = match self {
            Indicator::Lyapunov => ("lyapunov", vec![]),
            Indicator::Fli => ("fli", vec![]),
            Indicator::Megno => ("megno", vec![]),
            Indicator::Spectrum => ("lyapunov", vec!["vectors = 2".to_string()]),
        };
        if every != 1 {
            fields.push(format!("every = {every}"));
        }
        match fields.is_empty() {
            true => format!("{key} = true"),
            false => format!("{key} = {{ {} }}", fields.join(", ")),
        }
    }

    /// The most plain runs it should cost.
    pub fn goal(self) -> f64 {
        match self {
            Indicator::Spectrum => 3.0,
            _ => 2.0,
        }
    }
}

/// One indicator's cost on one scene, backend and precision.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CostRow {
    pub backend: String,
    pub scene: &'static str,
    pub precision: Precision,
    pub indicator: String,
    /// Steps between the indicator's samples.
    pub every: u64,
    pub steps: u64,
    pub pairs: usize,
    /// Median seconds of the plain runs and of the indicator's.
    pub plain_s: f64,
    pub indicator_s: f64,
    /// Median of the pairs' ratios (indicator over plain).
    pub ratio: f64,
    pub goal: f64,
}

/// `pairs` alternating runs of `scene` with `indicator` (sampled every
/// `every` steps) and without on `engine`, after one of each that is not
/// timed (it compiles the GPU's kernels and wakes its clocks); `steps`:
/// per run.
#[allow(clippy::too_many_arguments)]
pub fn cost(
    engine: &Engine,
    backend: &str,
    scene: CostScene,
    indicator: Indicator,
    every: u64,
    precision: Precision,
    steps: u64,
    pairs: usize,
) -> Result<CostRow, BackendError> {
    let pairs = pairs.max(1);
    let plain = scene.plan(None, steps, every);
    let with = scene.plan(Some(indicator), steps, every);
    let run = |plan: &Plan| super::seconds(engine, plan, precision);
    run(&plain)?;
    run(&with)?;
    let mut times = (vec![], vec![]);
    for _ in 0..pairs {
        times.0.push(run(&plain)?);
        times.1.push(run(&with)?);
    }
    let ratios = times.0.iter().zip(&times.1).map(|(a, b)| b / a).collect();
    Ok(CostRow {
        backend: backend.to_string(),
        scene: scene.label(),
        precision,
        indicator: indicator.label(every),
        every,
        steps,
        pairs,
        plain_s: super::median(times.0),
        indicator_s: super::median(times.1),
        ratio: super::median(ratios),
        goal: indicator.goal(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cost_scenes_are_the_readmes() {
        let vdp = CostScene::VanDerPol.plan(Some(Indicator::Megno), 10, 1);
        assert_eq!(vdp.n, 4096);
        let so = CostScene::SpinOrbit.plan(Some(Indicator::Spectrum), 10, 1);
        assert_eq!(so.n, 320 * 320);
        assert_eq!(so.observers.lyapunov.as_ref().map(|l| l.vectors), Some(2));
        assert!(so.indicators.is_some());
        assert!(CostScene::SpinOrbit.plan(None, 10, 1).indicators.is_none());
    }

    #[test]
    fn every_reaches_the_observers_and_the_labels() {
        let o = CostScene::SpinOrbit
            .plan(Some(Indicator::Spectrum), 20, 5)
            .observers;
        assert_eq!(o.lyapunov.map(|l| (l.vectors, l.every)), Some((2, 5)));
        let o = CostScene::VanDerPol
            .plan(Some(Indicator::Megno), 20, 5)
            .observers;
        assert_eq!(o.megno.map(|m| m.every), Some(5));
        let labels = INDICATORS.map(|i| i.label(10));
        assert_eq!(
            labels,
            [
                "lyapunov = { every = 10 }",
                "fli = { every = 10 }",
                "megno = { every = 10 }",
                "lyapunov = { vectors = 2, every = 10 }",
            ]
        );
        assert_eq!(Indicator::Fli.label(1), "fli = true");
    }
}
