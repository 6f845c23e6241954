//! A problem as a user states it: model, parameters and initial values as
//! [`Source`]s over the ensemble's axes, step, horizon, scheme, observers;
//! and the checks that need nothing but the problem itself.

use std::collections::BTreeMap;

use crate::models::spec::ModelSpec;
use crate::models::Model;

use super::observers::Observers;
use super::scheme::Scheme;

/// One axis of the ensemble.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    pub name: String,
    pub len: usize,
}

/// Where a per-trajectory input comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    Const(f64),
    /// `values[k]` for the trajectories whose index along `axis` is k. Several
    /// sources on the same axis are zipped.
    Axis {
        axis: usize,
        values: Vec<f64>,
    },
}

impl Source {
    /// Does any trajectory see a nonzero value?
    pub fn any_nonzero(&self) -> bool {
        match self {
            Source::Const(v) => *v != 0.0,
            Source::Axis { values, .. } => values.iter().any(|v| *v != 0.0),
        }
    }
    /// Every value this source takes.
    pub fn values(&self) -> Vec<f64> {
        match self {
            Source::Const(v) => vec![*v],
            Source::Axis { values, .. } => values.clone(),
        }
    }
    /// [`Source::values`] without a copy.
    pub fn as_slice(&self) -> &[f64] {
        match self {
            Source::Const(v) => std::slice::from_ref(v),
            Source::Axis { values, .. } => values,
        }
    }
    /// The value for trajectory `index` given the axis strides.
    #[inline]
    pub fn value_at(&self, index: usize, strides: &[usize]) -> f64 {
        match self {
            Source::Const(v) => *v,
            Source::Axis { axis, values } => values[(index / strides[*axis]) % values.len()],
        }
    }
    /// [`Source::value_at`] for trajectories `first`, `first + 1`, … in
    /// turn: one division for the first, then counting (a division per
    /// trajectory and input was 2 % of a van der Pol run on the CPU).
    pub fn values_from<'a>(
        &'a self,
        first: usize,
        strides: &[usize],
    ) -> impl Iterator<Item = f64> + 'a {
        let (values, stride) = match self {
            Source::Const(v) => (std::slice::from_ref(v), usize::MAX),
            Source::Axis { axis, values } => (&values[..], strides[*axis]),
        };
        let (mut k, mut within) = (first / stride % values.len(), first % stride);
        std::iter::repeat_with(move || {
            let v = values[k];
            within += 1;
            if within == stride {
                within = 0;
                k += 1;
                if k == values.len() {
                    k = 0;
                }
            }
            v
        })
    }
    /// The same source with every value mapped by `f`.
    pub fn map(&self, f: impl Fn(f64) -> f64) -> Source {
        match self {
            Source::Const(v) => Source::Const(f(*v)),
            Source::Axis { axis, values } => Source::Axis {
                axis: *axis,
                values: values.iter().map(|v| f(*v)).collect(),
            },
        }
    }
}

/// A problem as a user states it.
#[derive(Debug, Clone)]
pub struct Problem {
    pub model: Model,
    pub scheme: Scheme,
    /// S2 inner order (`None`: the model's default, e.g. `CBABC`).
    pub order: Option<String>,
    pub axes: Vec<Axis>,
    /// Model parameters by scene name.
    pub params: BTreeMap<String, Source>,
    /// Initial values by variable name, and `t0`.
    pub initial: BTreeMap<String, Source>,
    pub dt: Source,
    pub steps: u64,
    pub observers: Observers,
}

/// Why a problem cannot be planned; the message names the field.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
#[error("{field}: {message}")]
pub struct PlanError {
    pub field: String,
    pub message: String,
}

/// What is merely surprising about a problem (it runs, but perhaps not as
/// meant); the message names the field, like [`PlanError`].
#[derive(Debug, Clone, PartialEq)]
pub struct PlanWarning {
    pub field: String,
    pub message: String,
}

impl std::fmt::Display for PlanWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.field, self.message)
    }
}

pub fn warn(field: impl Into<String>, message: impl Into<String>) -> PlanWarning {
    PlanWarning {
        field: field.into(),
        message: message.into(),
    }
}

pub fn err(field: impl Into<String>, message: impl Into<String>) -> PlanError {
    PlanError {
        field: field.into(),
        message: message.into(),
    }
}

impl Problem {
    /// A problem with no axes, default parameters, zero initial state, and
    /// final-state output of the model's non-optional variables.
    pub fn new(model: Model, scheme: &str) -> Result<Problem, PlanError> {
        let scheme = Scheme::by_name(scheme).ok_or_else(|| {
            err(
                "integrator.scheme",
                format!(
                    "unknown scheme `{scheme}`; known: {}",
                    super::scheme::SCHEME_NAMES.join(", ")
                ),
            )
        })?;
        Ok(Problem::with_scheme(model, scheme))
    }

    /// [`Problem::new`] with the scheme already chosen.
    pub fn with_scheme(model: Model, scheme: Scheme) -> Problem {
        let spec = model.spec();
        let final_vars = spec
            .vars
            .iter()
            .filter(|v| Some(**v) != spec.optional_var)
            .map(|v| (*v).into())
            .collect();
        Problem {
            model,
            scheme,
            order: None,
            axes: vec![],
            params: BTreeMap::new(),
            initial: BTreeMap::new(),
            dt: Source::Const(0.01),
            steps: 1,
            observers: Observers {
                final_vars,
                ..Observers::default()
            },
        }
    }

    /// Adds an axis and returns the source that runs along it.
    pub fn axis(&mut self, name: &str, values: Vec<f64>) -> Source {
        self.axes.push(Axis {
            name: name.to_string(),
            len: values.len(),
        });
        Source::Axis {
            axis: self.axes.len() - 1,
            values,
        }
    }

    pub fn param(mut self, name: &str, source: Source) -> Self {
        self.params.insert(name.to_string(), source);
        self
    }

    pub fn initial(mut self, name: &str, source: Source) -> Self {
        self.initial.insert(name.to_string(), source);
        self
    }

    /// Number of trajectories: the product of the axis lengths, if it fits.
    pub fn checked_ensemble_size(&self) -> Option<usize> {
        self.axes
            .iter()
            .try_fold(1usize, |n, a| n.checked_mul(a.len))
    }

    /// Number of trajectories: the product of the axis lengths
    /// ([`check_sources`], which `Plan::new` runs first, refuses a product
    /// that overflows; here it fails loudly instead of wrapping).
    pub fn ensemble_size(&self) -> usize {
        self.checked_ensemble_size()
            .expect("check_sources refuses an ensemble beyond usize")
    }
}

/// Row-major strides of axes of lengths `lens` (first axis slowest). Each
/// stride is a product of lengths no larger than the ensemble's, which the
/// callers have checked; an overflow fails loudly instead of wrapping.
pub fn row_major_strides(lens: &[usize]) -> Vec<usize> {
    let mut strides = vec![1usize; lens.len()];
    for k in (0..lens.len().saturating_sub(1)).rev() {
        strides[k] = strides[k + 1]
            .checked_mul(lens[k + 1])
            .expect("the ensemble's size was checked");
    }
    strides
}

/// Initial values by variable name (and `t0`): known keys only, and a
/// model's alias (Kepler's `eccentricity`) replaced by what it stands for.
pub fn resolve_initial(
    spec: &ModelSpec,
    given: &BTreeMap<String, Source>,
) -> Result<BTreeMap<String, Source>, PlanError> {
    let mut initial = given.clone();
    if let Some(alias) = &spec.initial_alias {
        if let Some(e) = initial.remove(alias.key) {
            let field = format!("initial.{}", alias.key);
            if let Some(v) = e.values().into_iter().find(|v| !(alias.ok)(*v)) {
                return Err(err(field, format!("{v} is not in {}", alias.range)));
            }
            for (var, f) in alias.sets {
                if initial.contains_key(*var) {
                    let sets: Vec<&str> = alias.sets.iter().map(|(v, _)| *v).collect();
                    return Err(err(
                        format!("initial.{var}"),
                        format!(
                            "conflicts with initial.{}, which sets {}: give one or the other",
                            alias.key,
                            sets.join(" and ")
                        ),
                    ));
                }
                initial.insert(var.to_string(), e.map(f));
            }
        }
    }
    for name in initial.keys() {
        if name != "t0" && !spec.vars.contains(&name.as_str()) {
            return Err(err(
                format!("initial.{name}"),
                format!(
                    "model `{}` has no variable `{name}`; initial conditions are: {}, t0",
                    spec.name,
                    spec.vars.join(", ")
                ),
            ));
        }
    }
    Ok(initial)
}

/// Axis references in range and of the axis's length.
pub fn check_sources(problem: &Problem) -> Result<(), PlanError> {
    let all = problem
        .params
        .iter()
        .map(|(k, s)| (format!("params.{k}"), s))
        .chain(
            problem
                .initial
                .iter()
                .map(|(k, s)| (format!("initial.{k}"), s)),
        )
        .chain(std::iter::once(("integrator.dt".to_string(), &problem.dt)));
    for (field, s) in all {
        match s {
            Source::Const(v) if !v.is_finite() => {
                return Err(err(field, format!("{v} is not a finite number")))
            }
            Source::Axis { axis, values } => {
                let a = problem
                    .axes
                    .get(*axis)
                    .ok_or_else(|| err(&field, "refers to a missing axis"))?;
                if a.len != values.len() {
                    return Err(err(
                        field,
                        format!(
                            "has {} values but its axis `{}` has {}",
                            values.len(),
                            a.name,
                            a.len
                        ),
                    ));
                }
                if values.iter().any(|v| !v.is_finite()) {
                    return Err(err(field, "contains a value that is not a finite number"));
                }
            }
            _ => {}
        }
    }
    if problem.axes.iter().any(|a| a.len == 0) {
        return Err(err("axes", "an axis has no values"));
    }
    if problem.checked_ensemble_size().is_none() {
        let counts: Vec<String> = problem
            .axes
            .iter()
            .map(|a| format!("{} {}", a.name, a.len))
            .collect();
        return Err(err(
            "axes",
            format!(
                "the ensemble has more than 2^64 trajectories ({} values); use fewer values along an axis",
                counts.join(" × ")
            ),
        ));
    }
    Ok(())
}

/// The Liénard model's coefficient lists (model-level data, not parameters).
pub fn check_coefficients(model: &Model) -> Result<(), PlanError> {
    if let Model::Lienard { f, g } = model {
        for (name, c) in [("f", f), ("g", g)] {
            if c.len() > crate::models::lienard::MAX_COEFFICIENTS {
                return Err(err(
                    format!("params.{name}"),
                    format!(
                        "{} coefficients; at most {} (degree 9)",
                        c.len(),
                        crate::models::lienard::MAX_COEFFICIENTS
                    ),
                ));
            }
            if c.iter().any(|v| !v.is_finite()) {
                return Err(err(
                    format!("params.{name}"),
                    "contains a value that is not a finite number",
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::Source;

    #[test]
    fn values_from_counts_as_value_at_divides() {
        let strides = [1, 3, 12];
        let sources = [
            Source::Const(2.5),
            Source::Axis {
                axis: 0,
                values: vec![1.0, 2.0, 3.0],
            },
            Source::Axis {
                axis: 1,
                values: vec![4.0, 5.0, 6.0, 7.0],
            },
            Source::Axis {
                axis: 2,
                values: vec![8.0, 9.0],
            },
        ];
        for src in &sources {
            for first in [0, 1, 2, 3, 11, 12, 13, 23, 24, 100] {
                let got: Vec<f64> = src.values_from(first, &strides).take(30).collect();
                let want: Vec<f64> = (first..first + 30)
                    .map(|i| src.value_at(i, &strides))
                    .collect();
                assert_eq!(got, want, "{src:?} from {first}");
            }
        }
    }
}
