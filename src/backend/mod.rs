//! Backends: the CPU (rayon) and the GPU (wgpu). Both execute a [`Plan`] and
//! return the same [`Observations`].

pub mod cpu;
pub mod gpu;

use std::sync::atomic::AtomicU64;

use crate::models::Flows;
use crate::plan::observations::Observations;
use crate::plan::Plan;
use crate::num::precision::Precision;

/// Observations in the precision they were computed in.
#[derive(Debug, Clone)]
pub enum AnyObservations {
    F32(Observations<f32>),
    F64(Observations<f64>),
}

impl AnyObservations {
    /// Widened to f64 for analysis.
    pub fn to_f64(&self) -> Observations<f64> {
        match self {
            AnyObservations::F32(o) => o.convert(),
            AnyObservations::F64(o) => o.clone(),
        }
    }
    pub fn precision(&self) -> Precision {
        match self {
            AnyObservations::F32(_) => Precision::F32,
            AnyObservations::F64(_) => Precision::F64,
        }
    }
}

/// Runs `plan` on the CPU in `precision`.
pub fn run_cpu(plan: &Plan, precision: Precision, progress: Option<&AtomicU64>) -> AnyObservations {
    match precision {
        Precision::F32 => AnyObservations::F32(cpu::run::<f32>(plan, progress)),
        Precision::F64 => AnyObservations::F64(cpu::run::<f64>(plan, progress)),
    }
}

impl<R: Flows> Observations<R> {
    /// The same observations in another precision.
    pub fn convert<S: Flows>(&self) -> Observations<S> {
        let c = |v: &Vec<R>| {
            v.iter()
                .map(|x| S::from_f64(x.to_f64()))
                .collect::<Vec<S>>()
        };
        let cn = |v: &Vec<(String, Vec<R>)>| v.iter().map(|(n, x)| (n.clone(), c(x))).collect();
        Observations {
            n: self.n,
            final_values: cn(&self.final_values),
            frames: self.frames,
            trajectory: cn(&self.trajectory),
            max_points: self.max_points,
            poincare: cn(&self.poincare),
            poincare_count: self.poincare_count.clone(),
            cycle_amplitude: c(&self.cycle_amplitude),
            cycle_period: c(&self.cycle_period),
            nonfinite_step: self.nonfinite_step.clone(),
        }
    }
}
