//! Scene files: one TOML file describes a whole sweep or portrait.
//!
//! ```toml
//! model = "van_der_pol"
//! [params]
//! epsilon = { linspace = [0.0, 100.0, 256] }
//! [initial]
//! q = 2.0
//! [integrator]
//! scheme = "s2"
//! dt = { logspace = [-4.0, 0.2, 256] }
//! t_end = 1000.0
//! [output]
//! final = ["q", "s"]
//! [run]
//! backend = "auto"
//! precision = "f32"
//! ```
//!
//! Every parameter, initial value and `dt` is a scalar, a list, `linspace`,
//! `logspace` (base-10 exponents) or `random = { low, high, n, seed }`; a list
//! is always an axis; the ensemble is the cartesian product of the axes in the
//! order they appear in the file. Every error names the file, line and field.

mod error;
mod formula;
pub mod keys;
mod parse;
mod plans;
pub mod tables;
pub mod values;

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::PathBuf;

pub use crate::backend::BackendChoice;
use crate::models::Model;
use crate::num::precision::Precision;
use crate::plan::observers::Observers;
pub use crate::plan::observers::OutVar;
use crate::plan::scheme::Scheme;
use crate::plan::size::{self, Estimate, SizeError};
use crate::plan::Plan;
pub use error::SceneError;
pub use error::SceneWarning;
pub use values::{splitmix64, AxisValues};

/// An axis of the ensemble, as the scene names it.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SceneAxis {
    /// Output name (`axis_<name>.npy`): the parameter or variable name, `dt`, `t0`.
    pub name: String,
    /// Where it was given, e.g. `params.epsilon`.
    pub field: String,
    pub values: Vec<f64>,
}

/// How long to integrate.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Horizon {
    /// Steps = round((t_end − t0)/dt) for each trajectory.
    TEnd(f64),
    Steps(u64),
}

/// The format of a run's arrays: `.npy` files, or one Zarr v3 store.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    Npy,
    Zarr,
}

impl std::str::FromStr for Format {
    type Err = String;
    fn from_str(s: &str) -> Result<Format, String> {
        match s {
            "npy" => Ok(Format::Npy),
            "zarr" => Ok(Format::Zarr),
            _ => Err(format!("`{s}` is not an output format (npy, zarr)")),
        }
    }
}

impl Format {
    pub fn name(self) -> &'static str {
        match self {
            Format::Npy => "npy",
            Format::Zarr => "zarr",
        }
    }
}

/// Settings of the quick-look pictures.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct PlotSettings {
    /// Variables of the phase portrait (default: the first two recorded).
    pub phase: Option<(String, String)>,
    /// Variables of the Poincaré portrait (default: the first two recorded).
    pub poincare: Option<(String, String)>,
    /// Wrap the portrait's x into [0, 2π) (`"2pi"`) or [−π, π) (`"pi"`).
    pub wrap_x: Option<String>,
    /// Trajectories drawn in the phase portrait (default 64).
    pub max_trajectories: usize,
    /// Draw van der Pol's phase portrait in the Liénard plane (q, q − q³/3 − s/ε).
    pub lienard_plane: bool,
    /// Bifurcation diagram: Poincaré values of `var` against the axis `axis`.
    pub bifurcation: Option<(String, String)>,
}

/// What `reeb report` reads from `[report]` (see `reeb report --help`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct ReportSettings {
    pub schemes: Vec<Scheme>,
    pub backends: Vec<BackendChoice>,
    pub precisions: Vec<Precision>,
    /// Variables whose error is measured (default: the recorded final variables).
    pub error_vars: Vec<String>,
    /// Relative tolerance of the DOP853 reference.
    pub reference_rtol: f64,
    /// Stability map: class thresholds on the relative amplitude/period error.
    pub distorted: f64,
    /// Error targets of report.md's table of best configurations.
    pub targets: Vec<f64>,
}

impl ReportSettings {
    /// The settings of a scene without a `[report]` table (or before it is read):
    /// the scene's scheme on the CPU in f64.
    pub fn defaults(scheme: &Scheme) -> ReportSettings {
        ReportSettings {
            schemes: vec![scheme.clone()],
            backends: vec![BackendChoice::Cpu],
            precisions: vec![Precision::F64],
            error_vars: vec![],
            reference_rtol: 1e-12,
            distorted: 0.05,
            targets: vec![1e-2, 1e-4, 1e-6, 1e-8],
        }
    }
}

/// A validated scene.
#[derive(Debug, Clone)]
pub struct Scene {
    pub path: PathBuf,
    pub name: String,
    pub title: Option<String>,
    pub model: Model,
    pub axes: Vec<SceneAxis>,
    /// Per parameter / initial value / dt: a constant or the index of its axis.
    pub params: BTreeMap<String, Input>,
    pub initial: BTreeMap<String, Input>,
    pub dt: Input,
    pub horizon: Horizon,
    /// Parsed once, here; everything downstream takes the `Scheme`.
    pub scheme: Scheme,
    pub order: Option<String>,
    /// What the run records and when it stops, as its plans take it.
    pub observers: Observers,
    /// How the arrays are written (`output.format`).
    pub format: Format,
    pub backend: BackendChoice,
    pub precision: Precision,
    pub plot: PlotSettings,
    pub report: Option<ReportSettings>,
    /// The file's text (copied into summary.json).
    pub text: String,
    /// Preview: at most this many steps per plan.
    pub step_cap: Option<u64>,
    /// `(values, steps)` of [`Scene::preview`] if this is a preview.
    pub preview: Option<(usize, u64)>,
    spans: BTreeMap<String, Range<usize>>,
}

/// A per-trajectory input of a scene.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum Input {
    Const(f64),
    Axis(usize),
}

/// One plan of a scene: scenes whose step count differs between trajectories
/// (an axis of `dt` or `t0` with `t_end`) run one plan per value of those axes.
pub struct SubRun {
    /// Axes held at one value in this plan: (axis, value index).
    pub fixed: Vec<(usize, usize)>,
    pub plan: Plan,
}

impl SubRun {
    /// The scene row (index over all axes, row-major `strides` of the scene's
    /// `shape`) of each trajectory of this plan, whose rows range over the
    /// free axes only.
    pub fn scene_rows<'a>(
        &'a self,
        shape: &'a [usize],
        strides: &'a [usize],
    ) -> impl Iterator<Item = usize> + 'a {
        (0..self.plan.n).map(move |j| self.scene_row(j, shape, strides))
    }

    /// The scene row of this plan's trajectory `j` (increasing with `j`).
    pub fn scene_row(&self, j: usize, shape: &[usize], strides: &[usize]) -> usize {
        let fixed = |k: usize| self.fixed.iter().find(|(f, _)| *f == k).map(|(_, i)| *i);
        let mut free = 0;
        let mut row = 0;
        for k in 0..shape.len() {
            let index = fixed(k).unwrap_or_else(|| {
                free += 1;
                (j / self.plan.strides[free - 1]) % shape[k]
            });
            row += index * strides[k];
        }
        row
    }

    /// This plan's trajectories whose scene rows lie in `rows` (contiguous,
    /// as the map to scene rows increases).
    pub fn rows_within(
        &self,
        rows: &std::ops::Range<usize>,
        shape: &[usize],
        strides: &[usize],
    ) -> std::ops::Range<usize> {
        let below = |x: usize| {
            let (mut lo, mut hi) = (0, self.plan.n);
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if self.scene_row(mid, shape, strides) < x {
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            lo
        };
        below(rows.start)..below(rows.end)
    }
}

impl Scene {
    /// A small version of the scene for a quick look or a smoke test: every
    /// axis thinned to at most `values` evenly spaced values (first and last
    /// kept), at most `steps` steps per plan, trajectory frames thinned to
    /// match; written under `<name>-preview`.
    pub fn preview(&self, values: usize, steps: u64) -> Scene {
        let mut s = self.clone();
        s.name = format!("{}-preview", self.name);
        for a in &mut s.axes {
            let n = a.values.len();
            if n > values {
                a.values = (0..values)
                    .map(|k| a.values[k * (n - 1) / (values - 1).max(1)])
                    .collect();
            }
        }
        s.step_cap = Some(steps);
        s.preview = Some((values, steps));
        if let Some(t) = &mut s.observers.trajectory {
            t.every = t.every.min((steps / 10).max(1));
        }
        // Enough attractor samples in the shorter run to find a cycle.
        if let Some(a) = &mut s.observers.attractors {
            a.every = a.every.map(|e| e.min((steps / 64).max(1)));
        }
        s
    }

    /// The line of a field (e.g. `params.epsilon`), if the file gives it.
    pub fn line_of(&self, field: &str) -> Option<usize> {
        let mut f = field.to_string();
        loop {
            if let Some(s) = self.spans.get(&f) {
                return Some(
                    self.text[..s.start.min(self.text.len())]
                        .matches('\n')
                        .count()
                        + 1,
                );
            }
            match f.rfind('.') {
                Some(k) => f.truncate(k),
                None => return None,
            }
        }
    }

    fn error(&self, field: &str, message: impl Into<String>) -> SceneError {
        SceneError {
            path: self.path.clone(),
            line: self.line_of(field),
            field: field.to_string(),
            message: message.into(),
        }
    }

    /// Value of parameter `name` for trajectory `i` (row-major `strides`).
    pub fn param_value(&self, name: &str, i: usize, strides: &[usize]) -> f64 {
        match self.params.get(name) {
            Some(Input::Const(v)) => *v,
            Some(Input::Axis(k)) => {
                self.axes[*k].values[(i / strides[*k]) % self.axes[*k].values.len()]
            }
            None => 0.0,
        }
    }

    /// The longest integration time of the ensemble: `steps × dt` (the
    /// largest dt), or `t_end − t0` (the smallest t0); within a preview's
    /// step cap.
    pub fn duration(&self) -> f64 {
        let extreme = |input: Option<&Input>, max: bool| match input {
            Some(Input::Const(v)) => *v,
            Some(Input::Axis(k)) => {
                let v = self.axes[*k].values.iter().copied();
                if max {
                    v.fold(f64::NEG_INFINITY, f64::max)
                } else {
                    v.fold(f64::INFINITY, f64::min)
                }
            }
            None => 0.0,
        };
        let dt = extreme(Some(&self.dt), true);
        let capped = |t: f64| self.step_cap.map_or(t, |cap| t.min(cap as f64 * dt));
        match self.horizon {
            Horizon::Steps(n) => capped(n as f64 * dt),
            Horizon::TEnd(t_end) => capped(t_end - extreme(self.initial.get("t0"), false)),
        }
    }

    /// Number of trajectories. The size gate of [`Scene::parse`] refuses an
    /// ensemble whose count overflows (or whose status alone exceeds the
    /// memory), and [`Scene::preview`] only thins axes, so the product is
    /// checked here only to fail loudly instead of wrapping.
    pub fn ensemble_size(&self) -> usize {
        self.axes
            .iter()
            .try_fold(1usize, |n, a| n.checked_mul(a.values.len()))
            .expect("the size gate of Scene::parse bounds the ensemble")
    }

    /// Shape of the output arrays' leading dimensions (the axes, in order).
    pub fn shape(&self) -> Vec<usize> {
        self.axes.iter().map(|a| a.values.len()).collect()
    }

    /// Row-major strides of the axes: trajectory i has index
    /// (i / strides[k]) % shape[k] on axis k. Each stride is a product of
    /// axis counts no larger than [`Scene::ensemble_size`], which fits.
    pub fn strides(&self) -> Vec<usize> {
        crate::plan::row_major_strides(&self.shape())
    }

    /// The second stage of the size gate, which `reeb run` and `reeb check`
    /// both apply: the outputs of the plans `subs` (this scene's
    /// [`Scene::sub_runs`]) in `precision` against `max_output_bytes`, or
    /// by default 70 % of the available memory. Refused with the estimate
    /// and the knobs to change.
    pub fn size_gate(
        &self,
        subs: &[SubRun],
        precision: Precision,
        max_output_bytes: Option<u64>,
    ) -> Result<Estimate, SizeError> {
        let limit = max_output_bytes.unwrap_or_else(size::default_limit);
        let plans: Vec<&Plan> = subs.iter().map(|s| &s.plan).collect();
        size::output_gate(&self.path, &plans, precision, limit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn parse(text: &str) -> Result<Scene, SceneError> {
        Scene::parse(Path::new("test.toml"), text)
    }

    const VDP: &str = r#"
model = "van_der_pol"
[params]
epsilon = { linspace = [0.0, 10.0, 5] }
[initial]
q = [1.0, 2.0]
[integrator]
scheme = "s2"
dt = { logspace = [-2.0, -1.0, 3] }
t_end = 10.0
[output]
final = ["q", "s"]
trajectory = { every = 10, vars = ["q", "s"] }
cycle = true
"#;

    #[test]
    fn axes_in_file_order_and_sub_runs_per_dt() {
        let s = parse(VDP).unwrap();
        let names: Vec<&str> = s.axes.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(names, ["epsilon", "q", "dt"]);
        assert_eq!(s.shape(), [5, 2, 3]);
        let runs = s.sub_runs().unwrap();
        assert_eq!(runs.len(), 3);
        assert_eq!(runs[0].plan.steps, 1000);
        assert_eq!(runs[2].plan.steps, 100);
        assert_eq!(runs[1].plan.n, 10);
        assert!((s.axes[2].values[1] - 10f64.powf(-1.5)).abs() < 1e-15);
    }

    #[test]
    fn sub_run_rows_cover_the_scene_once() {
        // dt between two free axes: each plan's rows must land, in order, on
        // exactly the scene rows that hold dt at the plan's value.
        let text = VDP.replace("[initial]\nq = [1.0, 2.0]\n", "") + "[initial]\nq = [1.0, 2.0]\n";
        let s = parse(&text).unwrap();
        let names: Vec<&str> = s.axes.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(names, ["epsilon", "dt", "q"]);
        let (shape, strides) = (s.shape(), s.strides());
        assert_eq!(strides, [6, 2, 1]);
        let mut seen = vec![0; s.ensemble_size()];
        for run in s.sub_runs().unwrap() {
            let rows: Vec<usize> = run.scene_rows(&shape, &strides).collect();
            assert_eq!(rows.len(), run.plan.n);
            assert!(rows.windows(2).all(|w| w[0] < w[1]), "{rows:?}");
            for g in rows {
                for (k, i) in &run.fixed {
                    assert_eq!((g / strides[*k]) % shape[*k], *i);
                }
                seen[g] += 1;
            }
        }
        assert!(seen.iter().all(|c| *c == 1), "{seen:?}");
    }

    #[test]
    fn errors_name_line_and_field() {
        let e = parse(&VDP.replace("epsilon = {", "epsilonn = {")).unwrap_err();
        assert_eq!((e.line, e.field.as_str()), (Some(4), "params.epsilonn"));
        assert!(
            e.message.contains("did you mean `epsilon`"),
            "{}",
            e.message
        );
        let e =
            parse(&VDP.replace("dt = { logspace = [-2.0, -1.0, 3] }", "dt = -0.1")).unwrap_err();
        assert_eq!(
            (e.line, e.field.as_str()),
            (Some(9), "integrator.dt"),
            "{e}"
        );
        let e = parse(&VDP.replace("t_end = 10.0", "t_end = -1.0")).unwrap_err();
        assert_eq!(e.field, "integrator.t_end");
        let e = parse(&VDP.replace("scheme = \"s2\"", "scheme = \"variational2\"")).unwrap_err();
        assert_eq!(
            (e.line, e.field.as_str()),
            (Some(8), "integrator.scheme"),
            "{e}"
        );
        let e =
            parse(&VDP.replace("final = [\"q\", \"s\"]", "final = [\"q\", \"x\"]")).unwrap_err();
        assert_eq!(
            (e.line, e.field.as_str()),
            (Some(12), "output.final"),
            "{e}"
        );
        let e = parse(&VDP.replace("q = [1.0, 2.0]", "q = \"two\"")).unwrap_err();
        assert_eq!((e.line, e.field.as_str()), (Some(6), "initial.q"), "{e}");
        let e = parse("model = \"van_der_poll\"\n").unwrap_err();
        assert!(e.message.contains("did you mean `van_der_pol`"), "{e}");
        let e = parse("model = \"lane_emden\"\n[integrator]\ndt = 0.1\nsteps = 10\n").unwrap_err();
        assert_eq!(e.field, "params.index");
        let e = parse("model = \"van_der_pol\"\n[integrator]\ndt = 0.1\nsteps = 10\n[output]\nfinal = [\"q\"]\ncolor = 1\n").unwrap_err();
        assert_eq!((e.line, e.field.as_str()), (Some(7), "output.color"));
        let e = parse("model = \"van_der_pol\"\n[integrator]\ndt = 0.1\nsteps = 10\n[run]\nprecision = \"f16\"\n").unwrap_err();
        assert_eq!((e.line, e.field.as_str()), (Some(6), "run.precision"));
        let e = parse("model = \"van_der_pol\"\n[integrator]\ndt = 0.1\n").unwrap_err();
        assert!(e.message.contains("t_end or steps"));
        let e = parse("model = \"van_der_pol\"\n[integrator\n").unwrap_err();
        assert_eq!((e.line, e.field.as_str()), (Some(2), "toml"));
    }

    #[test]
    fn kepler_vectors_and_lienard_coefficients() {
        let s = parse("model = \"kepler\"\n[initial]\nq1 = 0.5\np2 = 1.7\n[integrator]\ndt = 0.01\nsteps = 10\n[output]\nfinal = [\"q\", \"p2\"]\n").unwrap();
        assert_eq!(s.observers.final_vars[0].components, ["q1", "q2"]);
        let s = parse("model = \"lienard\"\n[params]\nf = [-1.0, 0.0, 1.0]\ng = [0.0, 1.0]\n[integrator]\ndt = 0.01\nsteps = 10\n").unwrap();
        assert_eq!(
            s.model,
            Model::Lienard {
                f: vec![-1.0, 0.0, 1.0],
                g: vec![0.0, 1.0]
            }
        );
        assert!(s.axes.is_empty());
    }

    #[test]
    fn random_axes_are_reproducible() {
        let a = parse("model = \"van_der_pol\"\n[params]\nepsilon = { random = { low = 1.0, high = 2.0, n = 4, seed = 7 } }\n[integrator]\ndt = 0.1\nsteps = 1\n").unwrap();
        let v = &a.axes[0].values;
        assert_eq!(v.len(), 4);
        assert!(v.iter().all(|x| (1.0..2.0).contains(x)));
        assert_eq!(v[0], 1.0 + splitmix64(7, 1)[0]);
    }
}
