//! What a run produces, per trajectory, in the run's precision.

use crate::num::precision::{Precision, Real};
use crate::plan::{ObsVar, Plan};

/// Status of a trajectory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    Ok,
    /// A state variable became non-finite (overflow, a singular map such as
    /// Kepler at q = 0) at this step (1-based); the trajectory stopped there.
    NonFinite {
        step: u64,
    },
}

/// Observations of a whole ensemble. Arrays are indexed by trajectory (the
/// row-major index over the plan's axes), then frame or point.
#[derive(Debug, Clone)]
pub struct Observations<R> {
    pub n: usize,
    /// `(variable, values[n])`; NaN for trajectories that did not finish.
    pub final_values: Vec<(String, Vec<R>)>,
    /// Frames per trajectory (`steps / every + 1`, from step 0).
    pub frames: usize,
    /// `(variable, values[n × frames])`, NaN after a trajectory stopped.
    pub trajectory: Vec<(String, Vec<R>)>,
    /// Points kept per trajectory.
    pub max_points: usize,
    /// `(variable, values[n × max_points])`, NaN-padded.
    pub poincare: Vec<(String, Vec<R>)>,
    /// Points found per trajectory (may exceed `max_points`; only that many kept).
    pub poincare_count: Vec<u32>,
    /// Half the peak-to-peak range of the cycle variable over the measuring window.
    pub cycle_amplitude: Vec<R>,
    /// Mean time between upward crossings of the cycle level in the window (NaN if fewer than two).
    pub cycle_period: Vec<R>,
    /// 0: ok; k > 0: non-finite at step k.
    pub nonfinite_step: Vec<u32>,
}

fn var_name(plan: &Plan, v: ObsVar) -> String {
    match v {
        ObsVar::State(k) => plan.vars[k].to_string(),
        ObsVar::Time => "t".to_string(),
    }
}

impl<R: Real> Observations<R> {
    /// Arrays for `plan`, filled with NaN (counts and status with 0).
    ///
    /// Panics if an array's length overflows `usize`; [`Self::try_for_plan`]
    /// says so instead. The backends are reached through
    /// [`crate::plan::size::output_gate`] or [`Self::lengths`], which refuse
    /// such plans first.
    pub fn for_plan(plan: &Plan) -> Self {
        Self::try_for_plan(plan).unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`Self::for_plan`], or why its arrays cannot be sized.
    pub fn try_for_plan(plan: &Plan) -> Result<Self, String> {
        let Lengths {
            n,
            frames,
            max_points,
            trajectory,
            poincare,
        } = Self::lengths(plan)?;
        let nan = |len: usize| vec![R::nan(); len];
        let has_cycle = plan.cycle_var.is_some();
        Ok(Observations {
            n,
            final_values: plan
                .final_vars
                .iter()
                .map(|v| (var_name(plan, *v), nan(n)))
                .collect(),
            frames,
            trajectory: plan
                .trajectory_vars
                .iter()
                .map(|v| (var_name(plan, *v), nan(trajectory)))
                .collect(),
            max_points,
            poincare: plan
                .poincare_vars
                .iter()
                .map(|v| (var_name(plan, *v), nan(poincare)))
                .collect(),
            poincare_count: if max_points > 0 { vec![0; n] } else { vec![] },
            cycle_amplitude: if has_cycle { nan(n) } else { vec![] },
            cycle_period: if has_cycle { nan(n) } else { vec![] },
            nonfinite_step: vec![0; n],
        })
    }

    /// The lengths of the arrays of `plan`, counted with checked arithmetic
    /// (nothing is allocated).
    pub fn lengths(plan: &Plan) -> Result<Lengths, String> {
        let n = plan.n;
        let frames = frames_per_trajectory(plan)
            .and_then(|f| usize::try_from(f).ok())
            .ok_or("the trajectory frames per trajectory do not fit in 64 bits")?;
        let max_points = plan.observers.poincare.as_ref().map_or(0, |p| p.max_points);
        let too_many = |what: &str, per: usize| {
            format!("{n} trajectories × {per} {what} do not fit in 64 bits: record less (a larger output.trajectory.every, a smaller output.poincare.max_points) or use fewer values along an axis")
        };
        Ok(Lengths {
            n,
            frames,
            max_points,
            trajectory: n
                .checked_mul(frames)
                .ok_or_else(|| too_many("trajectory frames", frames))?,
            poincare: n
                .checked_mul(max_points)
                .ok_or_else(|| too_many("Poincaré points", max_points))?,
        })
    }

    /// Copies the rows of `src` (a sub-run's) to rows `rows` of `self` (the
    /// whole scene's); a sub-run of fewer steps fills the leading frames.
    pub fn place_rows(&mut self, src: &Observations<R>, rows: impl Iterator<Item = usize>) {
        let (fs, mp) = (src.frames, src.max_points);
        for (j, g) in rows.enumerate() {
            for ((_, dst), (_, s)) in self.final_values.iter_mut().zip(&src.final_values) {
                dst[g] = s[j];
            }
            for ((_, dst), (_, s)) in self.trajectory.iter_mut().zip(&src.trajectory) {
                dst[g * self.frames..g * self.frames + fs]
                    .copy_from_slice(&s[j * fs..(j + 1) * fs]);
            }
            for ((_, dst), (_, s)) in self.poincare.iter_mut().zip(&src.poincare) {
                dst[g * mp..(g + 1) * mp].copy_from_slice(&s[j * mp..(j + 1) * mp]);
            }
            if mp > 0 {
                self.poincare_count[g] = src.poincare_count[j];
            }
            if !src.cycle_amplitude.is_empty() {
                self.cycle_amplitude[g] = src.cycle_amplitude[j];
                self.cycle_period[g] = src.cycle_period[j];
            }
            self.nonfinite_step[g] = src.nonfinite_step[j];
        }
    }

    pub fn status(&self, i: usize) -> Status {
        match self.nonfinite_step[i] {
            0 => Status::Ok,
            step => Status::NonFinite { step: step.into() },
        }
    }

    /// Number of trajectories that finished with a finite state.
    pub fn count_ok(&self) -> usize {
        self.nonfinite_step.iter().filter(|s| **s == 0).count()
    }

    pub fn final_of(&self, var: &str) -> Option<&[R]> {
        self.final_values
            .iter()
            .find(|(v, _)| v == var)
            .map(|(_, x)| x.as_slice())
    }

    pub fn trajectory_of(&self, var: &str) -> Option<&[R]> {
        self.trajectory
            .iter()
            .find(|(v, _)| v == var)
            .map(|(_, x)| x.as_slice())
    }

    pub fn poincare_of(&self, var: &str) -> Option<&[R]> {
        self.poincare
            .iter()
            .find(|(v, _)| v == var)
            .map(|(_, x)| x.as_slice())
    }
}

/// The lengths of the arrays of a plan's [`Observations`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Lengths {
    /// Trajectories (the length of the per-trajectory arrays).
    pub n: usize,
    /// Frames per trajectory, and the length of each trajectory array.
    pub frames: usize,
    pub trajectory: usize,
    /// Points kept per trajectory, and the length of each Poincaré array.
    pub max_points: usize,
    pub poincare: usize,
}

/// Trajectory frames per trajectory (every `every` steps from step 0);
/// `None` if the count overflows.
fn frames_per_trajectory(plan: &Plan) -> Option<u64> {
    match &plan.observers.trajectory {
        Some(t) => (plan.steps / t.every).checked_add(1),
        None => Some(0),
    }
}

/// Bytes the observations of `plan` take in `precision`, before running;
/// `None` if they do not fit in 64 bits (every count is checked).
pub fn estimate_bytes(plan: &Plan, precision: Precision) -> Option<u64> {
    (plan.n as u64).checked_mul(bytes_per_trajectory(plan, precision)?)
}

/// Bytes of one trajectory's observations of `plan` in `precision`; `None`
/// if they do not fit in 64 bits.
pub fn bytes_per_trajectory(plan: &Plan, precision: Precision) -> Option<u64> {
    let b = precision.bytes() as u64;
    let frames = frames_per_trajectory(plan)?;
    let points = plan
        .observers
        .poincare
        .as_ref()
        .map_or(0, |p| p.max_points as u64);
    let vars = |k: usize, per: u64| (k as u64).checked_mul(per)?.checked_mul(b);
    [
        vars(plan.final_vars.len(), 1)?,
        vars(plan.trajectory_vars.len(), frames)?,
        vars(plan.poincare_vars.len(), points)?,
        if points > 0 { 4 } else { 0 },
        if plan.cycle_var.is_some() { 2 * b } else { 0 },
        8,
    ]
    .into_iter()
    .try_fold(0u64, u64::checked_add)
}

impl<R: Real> Observations<R> {
    /// The same observations in another precision.
    pub fn convert<S: Real>(&self) -> Observations<S> {
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
