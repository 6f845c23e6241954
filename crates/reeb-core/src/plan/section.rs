//! The Poincaré section as both backends run it, decided once from the plan:
//! how its points are found in a step (the `kind` of the shared
//! `models/events.rs::section_next`) and what each of its columns records.
//! The CPU (`backend/cpu/observe.rs`) and the GPU kernel
//! (`backend/gpu/codegen.rs`) only feed that function and store what it
//! finds.

use super::observers::{Direction, Section};
use super::{ObsVar, Plan};

/// How the section finds its points inside a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SectionKind {
    /// Stroboscopic, period and phase whole numbers of steps: the state at
    /// a step's end.
    Exact,
    /// Stroboscopic, sampled inside the step by interpolation.
    Interpolated,
    /// Crossings of a state variable (index into `plan.vars`) through a
    /// level, in a direction.
    Crossing {
        var: usize,
        level: f64,
        direction: Direction,
    },
}

impl SectionKind {
    /// The `kind` argument of `section_next`.
    pub fn code(self) -> i32 {
        match self {
            SectionKind::Exact => 0,
            SectionKind::Interpolated => 1,
            SectionKind::Crossing { .. } => 2,
        }
    }

    /// Does a point lie inside a step (so its values are interpolated and
    /// the step's start and slopes are needed)?
    pub fn interpolates(self) -> bool {
        self != SectionKind::Exact
    }
}

impl Direction {
    /// The `direction` argument of `crossing_due` and `section_next`.
    pub fn code(self) -> i32 {
        match self {
            Direction::Up => 0,
            Direction::Down => 1,
            Direction::Both => 2,
        }
    }
}

/// What one column of the section's points holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Recorded {
    /// The variable (time, or a state variable interpolated at θ).
    Var(ObsVar),
    /// The crossing variable: on the section exactly, its level.
    Level(f64),
}

/// The section of a plan, as its per-step code needs it.
#[derive(Debug, Clone)]
pub struct SectionStep {
    pub kind: SectionKind,
    /// Points kept per trajectory (later ones are counted only), the row
    /// length of `poincare_*`.
    pub max_points: usize,
    /// One per column of `poincare_*` (`plan.poincare_vars`).
    pub columns: Vec<Recorded>,
    /// The most points one step may hold, over the ensemble (an
    /// interpolated stroboscopic section with a period shorter than the
    /// step has several; every other section at most one).
    pub max_per_step: u64,
}

impl SectionStep {
    /// The `max_points` argument of `point_kept` (32-bit; no plan finds
    /// more points than that: it has fewer than 2³¹ steps).
    pub fn kept_limit(&self) -> i32 {
        self.max_points.min(i32::MAX as usize) as i32
    }
}

impl Plan {
    /// The plan's Poincaré section, if it has one.
    pub fn section(&self) -> Option<SectionStep> {
        let pc = self.observers.poincare.as_ref()?;
        let kind = match &pc.section {
            Section::Stroboscopic { .. } | Section::Forced { .. } if self.strobe_interpolated() => {
                SectionKind::Interpolated
            }
            Section::Stroboscopic { .. } | Section::Forced { .. } => SectionKind::Exact,
            Section::Crossing {
                value, direction, ..
            } => SectionKind::Crossing {
                var: self.crossing_var.expect("resolved with the section"),
                level: *value,
                direction: *direction,
            },
        };
        let columns = self
            .poincare_vars
            .iter()
            .map(|v| match (kind, v) {
                (SectionKind::Crossing { var, level, .. }, ObsVar::State(k)) if *k == var => {
                    Recorded::Level(level)
                }
                _ => Recorded::Var(*v),
            })
            .collect();
        Some(SectionStep {
            kind,
            max_points: pc.max_points,
            columns,
            max_per_step: match kind {
                SectionKind::Interpolated => self.strobe_samples_per_step(),
                _ => 1,
            },
        })
    }

    /// The most stroboscopic samples one step holds: consecutive samples
    /// are period/dt steps apart, so a period of at least a step (with room
    /// for rounding) gives one, and a shorter one up to ⌈dt/period⌉ + 1.
    fn strobe_samples_per_step(&self) -> u64 {
        let dt = self.binding("dt").values().into_iter().fold(0.0, f64::max);
        let period = self
            .binding("strobe_period")
            .values()
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        if period > 1.001 * dt {
            1
        } else {
            (dt / period).ceil() as u64 + 1
        }
    }
}
