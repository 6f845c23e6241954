//! The observed variables of a plan resolved to what it integrates: state
//! variables by index, or time.

use super::observers::{components, Observers, OutVar, Section};
use super::problem::{err, PlanError};

/// A state variable or time, as observers see it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObsVar {
    /// Index into [`Plan::vars`].
    State(usize),
    Time,
}

/// Every observer's variables, resolved.
pub struct Observed {
    pub final_vars: Vec<ObsVar>,
    pub trajectory_vars: Vec<ObsVar>,
    pub poincare_vars: Vec<ObsVar>,
    /// The crossing variable of an event section, and of the cycle statistics.
    pub crossing_var: Option<usize>,
    pub cycle_var: Option<usize>,
    /// The averaged variables (state variables only).
    pub average_vars: Vec<ObsVar>,
    /// The components of the attractor detector's samples.
    pub attractor_vars: Vec<ObsVar>,
}

impl Observed {
    /// Resolves the observers' names against the integrated `vars`.
    pub fn resolve(obs: &Observers, vars: &[&str]) -> Result<Observed, PlanError> {
        let resolve = |name: &str, field: &str| -> Result<ObsVar, PlanError> {
            if name == "t" {
                return Ok(ObsVar::Time);
            }
            vars.iter()
                .position(|v| *v == name)
                .map(ObsVar::State)
                .ok_or_else(|| err(field, format!("`{name}` is not integrated by this plan")))
        };
        let list = |vars: Option<&Vec<OutVar>>, field: &str| -> Result<Vec<ObsVar>, PlanError> {
            components(vars.map_or(&[], |v| v.as_slice()))
                .map(|v| resolve(v, field))
                .collect()
        };
        let state_only = |name: &str, field: &str| match resolve(name, field)? {
            ObsVar::State(k) => Ok(k),
            ObsVar::Time => Err(err(field, "time cannot be the crossing variable")),
        };
        Ok(Observed {
            final_vars: list(Some(&obs.final_vars), "output.final")?,
            trajectory_vars: list(
                obs.trajectory.as_ref().map(|t| &t.vars),
                "output.trajectory.vars",
            )?,
            poincare_vars: list(
                obs.poincare.as_ref().map(|p| &p.vars),
                "output.poincare.vars",
            )?,
            crossing_var: match obs.poincare.as_ref().map(|p| &p.section) {
                Some(Section::Crossing { var, .. }) => {
                    Some(state_only(var, "output.poincare.crossing")?)
                }
                _ => None,
            },
            cycle_var: obs
                .cycle
                .as_ref()
                .map(|c| state_only(&c.var, "output.cycle.var"))
                .transpose()?,
            average_vars: obs
                .average
                .iter()
                .flat_map(|a| components(&a.vars))
                .map(|v| match resolve(v, "output.average")? {
                    ObsVar::Time => Err(err("output.average", "time has no average to take")),
                    state => Ok(state),
                })
                .collect::<Result<_, _>>()?,
            attractor_vars: list(
                obs.attractors.as_ref().map(|a| &a.vars),
                "output.attractors.vars",
            )?,
        })
    }
}
