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

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};

use toml::de::{DeTable, DeValue};
use toml::Spanned;

pub use crate::backend::BackendChoice;
use crate::models::{lienard, Model, MODEL_NAMES};
use crate::num::precision::Precision;
use crate::plan::observers::{CycleObs, Direction, PoincareObs, Section, TrajectoryObs};
use crate::plan::scheme::{Scheme, SCHEME_NAMES};
use crate::plan::{Plan, Problem, Source};

/// A scene error: file, line, field and what is wrong.
#[derive(Debug, Clone, thiserror::Error)]
#[error("{}{}: {field}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct SceneError {
    pub path: PathBuf,
    pub line: Option<usize>,
    pub field: String,
    pub message: String,
}

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

/// A variable of the output files: a state variable, `t`, or a vector
/// (`q` of Kepler is `[q1, q2]`: its arrays carry a trailing component axis).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct OutVar {
    pub name: String,
    pub components: Vec<String>,
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
    pub schemes: Vec<String>,
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
    pub fn defaults(scheme: &str) -> ReportSettings {
        ReportSettings {
            schemes: vec![scheme.to_string()],
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
    pub scheme: String,
    pub order: Option<String>,
    pub final_vars: Vec<OutVar>,
    pub trajectory: Option<(u64, Vec<OutVar>)>,
    pub poincare: Option<(Section, Vec<OutVar>, usize)>,
    pub cycle: Option<CycleObs>,
    pub backend: BackendChoice,
    pub precision: Precision,
    pub plot: PlotSettings,
    pub report: Option<ReportSettings>,
    /// The file's text (copied into summary.json).
    pub text: String,
    /// Preview: at most this many steps per plan.
    pub step_cap: Option<u64>,
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
        let free: Vec<usize> = (0..shape.len())
            .filter(|k| !self.fixed.iter().any(|(f, _)| f == k))
            .collect();
        let fixed_offset: usize = self.fixed.iter().map(|(k, i)| i * strides[*k]).sum();
        (0..self.plan.n).map(move |j| {
            let free_offset: usize = free
                .iter()
                .enumerate()
                .map(|(fk, k)| (j / self.plan.strides[fk]) % shape[*k] * strides[*k])
                .sum();
            fixed_offset + free_offset
        })
    }
}

const TOP_KEYS: &[&str] = &[
    "model",
    "name",
    "title",
    "params",
    "initial",
    "integrator",
    "output",
    "run",
    "report",
    "plot",
];
const INTEGRATOR_KEYS: &[&str] = &["scheme", "order", "dt", "t_end", "steps"];
const OUTPUT_KEYS: &[&str] = &["final", "trajectory", "poincare", "cycle"];
const RUN_KEYS: &[&str] = &["backend", "precision"];
const PLOT_KEYS: &[&str] = &[
    "phase",
    "poincare",
    "wrap_x",
    "max_trajectories",
    "lienard_plane",
    "bifurcation",
];
const REPORT_KEYS: &[&str] = &[
    "schemes",
    "backends",
    "precisions",
    "error_vars",
    "reference_rtol",
    "distorted",
    "targets",
];

/// SplitMix64: the stream of `random = { … seed }` axes (documented, so that
/// others can reproduce the samples).
pub fn splitmix64(seed: u64, n: usize) -> Vec<f64> {
    let mut z = seed;
    (0..n)
        .map(|_| {
            z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut x = z;
            x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            x ^= x >> 31;
            (x >> 11) as f64 / (1u64 << 53) as f64
        })
        .collect()
}

struct Parser<'a> {
    path: &'a Path,
    text: &'a str,
    spans: BTreeMap<String, Range<usize>>,
}

type Entry<'i> = (
    &'i Spanned<toml::de::DeString<'i>>,
    &'i Spanned<DeValue<'i>>,
);

impl<'a> Parser<'a> {
    fn line(&self, span: &Range<usize>) -> usize {
        self.text[..span.start.min(self.text.len())]
            .matches('\n')
            .count()
            + 1
    }
    /// "expected `what`, found <type of v>", at `v`.
    fn mismatch(&self, field: &str, v: &Spanned<DeValue>, what: &str) -> SceneError {
        let found = v.get_ref().type_str();
        self.err(
            field,
            Some(&v.span()),
            format!("expected {what}, found {found}"),
        )
    }
    fn err(
        &self,
        field: &str,
        span: Option<&Range<usize>>,
        message: impl Into<String>,
    ) -> SceneError {
        SceneError {
            path: self.path.to_path_buf(),
            line: span.map(|s| self.line(s)),
            field: field.to_string(),
            message: message.into(),
        }
    }
    /// Entries of a table in file order, rejecting keys outside `known`.
    fn entries<'i>(
        &mut self,
        table: &'i DeTable<'i>,
        prefix: &str,
        known: Option<&[&str]>,
    ) -> Result<Vec<Entry<'i>>, SceneError> {
        let mut v: Vec<Entry<'i>> = table.iter().collect();
        v.sort_by_key(|(k, _)| k.span().start);
        for (k, val) in &v {
            let field = if prefix.is_empty() {
                k.get_ref().to_string()
            } else {
                format!("{prefix}.{}", k.get_ref())
            };
            if let Some(known) = known {
                if !known.contains(&k.get_ref().as_ref()) {
                    let hint = suggest(k.get_ref(), known);
                    return Err(self.err(
                        &field,
                        Some(&k.span()),
                        format!("unknown key{hint}; known keys here: {}", known.join(", ")),
                    ));
                }
            }
            self.spans.insert(field, val.span());
        }
        Ok(v)
    }
    fn number(&self, field: &str, v: &Spanned<DeValue>) -> Result<f64, SceneError> {
        let x = match v.get_ref() {
            DeValue::Float(f) => f.as_str().parse::<f64>().ok(),
            DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
                .ok()
                .map(|i| i as f64),
            _ => return Err(self.mismatch(field, v, "a number")),
        };
        match x {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(self.err(field, Some(&v.span()), "expected a finite number")),
        }
    }
    fn integer(&self, field: &str, v: &Spanned<DeValue>) -> Result<u64, SceneError> {
        match v.get_ref() {
            DeValue::Integer(i) => u64::from_str_radix(i.as_str(), i.radix())
                .map_err(|_| self.err(field, Some(&v.span()), "expected a non-negative integer")),
            _ => Err(self.mismatch(field, v, "an integer")),
        }
    }
    fn string(&self, field: &str, v: &Spanned<DeValue>) -> Result<String, SceneError> {
        match v.get_ref() {
            DeValue::String(s) => Ok(s.to_string()),
            _ => Err(self.mismatch(field, v, "a string")),
        }
    }
    fn strings(&self, field: &str, v: &Spanned<DeValue>) -> Result<Vec<String>, SceneError> {
        match v.get_ref() {
            DeValue::Array(a) => a.iter().map(|x| self.string(field, x)).collect(),
            DeValue::String(s) => Ok(vec![s.to_string()]),
            _ => Err(self.mismatch(field, v, "a list of strings")),
        }
    }
    fn numbers(&self, field: &str, v: &Spanned<DeValue>) -> Result<Vec<f64>, SceneError> {
        match v.get_ref() {
            DeValue::Array(a) => a.iter().map(|x| self.number(field, x)).collect(),
            _ => Err(self.mismatch(field, v, "a list of numbers")),
        }
    }
    /// A value spec: a constant, or the values of a new axis.
    fn values(
        &self,
        field: &str,
        v: &Spanned<DeValue>,
    ) -> Result<Result<f64, Vec<f64>>, SceneError> {
        let sp = Some(v.span());
        match v.get_ref() {
            DeValue::Float(_) | DeValue::Integer(_) => Ok(Ok(self.number(field, v)?)),
            DeValue::Array(a) => {
                if a.is_empty() {
                    return Err(self.err(
                        field,
                        sp.as_ref(),
                        "an empty list is an axis with no values",
                    ));
                }
                Ok(Err(self.numbers(field, v)?))
            }
            DeValue::Table(t) => {
                let mut e: Vec<_> = t.iter().collect();
                e.sort_by_key(|(k, _)| k.span().start);
                if e.len() != 1 {
                    return Err(self.err(
                        field,
                        sp.as_ref(),
                        "expected exactly one of linspace, logspace, random",
                    ));
                }
                let (k, val) = e[0];
                let f = format!("{field}.{}", k.get_ref());
                match k.get_ref().as_ref() {
                    "linspace" | "logspace" => {
                        let xs = self.numbers(&f, val)?;
                        if xs.len() != 3 || xs[2].fract() != 0.0 || xs[2] < 1.0 {
                            return Err(self.err(&f, Some(&val.span()), "expected [start, stop, n] with an integer n ≥ 1"));
                        }
                        let n = xs[2] as usize;
                        let lin: Vec<f64> = (0..n).map(|i| if n == 1 { xs[0] } else { xs[0] + (xs[1] - xs[0]) * i as f64 / (n - 1) as f64 }).collect();
                        Ok(Err(if k.get_ref() == "logspace" { lin.into_iter().map(|e| 10f64.powf(e)).collect() } else { lin }))
                    }
                    "random" => {
                        let DeValue::Table(rt) = val.get_ref() else {
                            return Err(self.err(&f, Some(&val.span()), "expected { low, high, n, seed }"));
                        };
                        let get = |name: &str| rt.get(name).ok_or_else(|| self.err(&format!("{f}.{name}"), Some(&val.span()), "missing"));
                        for (rk, _) in rt.iter() {
                            if !["low", "high", "n", "seed"].contains(&rk.get_ref().as_ref()) {
                                return Err(self.err(&format!("{f}.{}", rk.get_ref()), Some(&rk.span()), "unknown key; known: low, high, n, seed"));
                            }
                        }
                        let low = self.number(&format!("{f}.low"), get("low")?)?;
                        let high = self.number(&format!("{f}.high"), get("high")?)?;
                        let n = self.integer(&format!("{f}.n"), get("n")?)? as usize;
                        let seed = self.integer(&format!("{f}.seed"), get("seed")?)?;
                        if n == 0 || high <= low {
                            return Err(self.err(&f, Some(&val.span()), "needs n ≥ 1 and high > low"));
                        }
                        Ok(Err(splitmix64(seed, n).into_iter().map(|u| low + (high - low) * u).collect()))
                    }
                    other => Err(self.err(&f, Some(&k.span()), format!("unknown value form `{other}`; use a number, a list, linspace, logspace or random"))),
                }
            }
            _ => Err(self.mismatch(
                field,
                v,
                "a number, a list, or { linspace | logspace | random = … }",
            )),
        }
    }
}

fn suggest(key: &str, known: &[&str]) -> String {
    let dist = |a: &str, b: &str| {
        let (a, b): (Vec<char>, Vec<char>) = (a.chars().collect(), b.chars().collect());
        let mut d: Vec<usize> = (0..=b.len()).collect();
        for i in 1..=a.len() {
            let mut prev = d[0];
            d[0] = i;
            for j in 1..=b.len() {
                let cur = d[j];
                d[j] = (d[j] + 1)
                    .min(d[j - 1] + 1)
                    .min(prev + usize::from(a[i - 1] != b[j - 1]));
                prev = cur;
            }
        }
        d[b.len()]
    };
    known
        .iter()
        .map(|k| (dist(key, k), k))
        .filter(|(d, _)| *d <= 2)
        .min()
        .map(|(_, k)| format!(" (did you mean `{k}`?)"))
        .unwrap_or_default()
}

impl Scene {
    /// Reads and validates a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError {
            path: path.to_path_buf(),
            line: None,
            field: "file".into(),
            message: e.to_string(),
        })?;
        Scene::parse(path, &text)
    }

    /// Parses and validates scene text (`path` names it in errors).
    pub fn parse(path: &Path, text: &str) -> Result<Scene, SceneError> {
        let root = DeTable::parse(text).map_err(|e| {
            let line = e
                .span()
                .map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
            SceneError {
                path: path.to_path_buf(),
                line,
                field: "toml".into(),
                message: e.message().to_string(),
            }
        })?;
        let mut p = Parser {
            path,
            text,
            spans: BTreeMap::new(),
        };
        let top = p.entries(root.get_ref(), "", Some(TOP_KEYS))?;
        let get = |name: &str| {
            top.iter()
                .find(|(k, _)| k.get_ref() == name)
                .map(|(_, v)| *v)
        };
        let table = |p: &Parser, name: &str| -> Result<Option<&DeTable>, SceneError> {
            match get(name) {
                None => Ok(None),
                Some(v) => match v.get_ref() {
                    DeValue::Table(t) => Ok(Some(t)),
                    _ => Err(p.mismatch(name, v, "a table")),
                },
            }
        };

        let model_v = get("model").ok_or_else(|| {
            p.err(
                "model",
                None,
                format!("missing; one of: {}", MODEL_NAMES.join(", ")),
            )
        })?;
        let model_name = p.string("model", model_v)?;
        let mut model = Model::from_name(&model_name).ok_or_else(|| {
            p.err(
                "model",
                Some(&model_v.span()),
                format!(
                    "unknown model `{model_name}`{}; one of: {}",
                    suggest(&model_name, MODEL_NAMES),
                    MODEL_NAMES.join(", ")
                ),
            )
        })?;
        let spec = model.spec();
        let name = match get("name") {
            Some(v) => p.string("name", v)?,
            None => path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scene".into()),
        };
        if name.is_empty() || name.contains(['/', '\\']) || name == "." || name == ".." {
            return Err(p.err(
                "name",
                get("name").map(|v| v.span()).as_ref(),
                "must be a plain file name",
            ));
        }
        let title = get("title").map(|v| p.string("title", v)).transpose()?;

        let mut axes: Vec<(usize, SceneAxis)> = vec![];
        let add_input = |p: &Parser,
                         field: &str,
                         name: &str,
                         v: &Spanned<DeValue>,
                         axes: &mut Vec<(usize, SceneAxis)>|
         -> Result<Input, SceneError> {
            Ok(match p.values(field, v)? {
                Ok(c) => Input::Const(c),
                Err(values) => {
                    axes.push((
                        v.span().start,
                        SceneAxis {
                            name: name.to_string(),
                            field: field.to_string(),
                            values,
                        },
                    ));
                    Input::Axis(usize::MAX)
                }
            })
        };

        // [params]
        let mut params = BTreeMap::new();
        let mut known_params: Vec<&str> = spec.params.iter().map(|d| d.name).collect();
        if matches!(model, Model::Lienard { .. }) {
            known_params.extend(["f", "g"]);
        }
        if let Some(t) = table(&p, "params")? {
            for (k, v) in p.entries(t, "params", Some(&known_params))? {
                let field = format!("params.{}", k.get_ref());
                if let Model::Lienard { f, g } = &mut model {
                    // Coefficient lists are the one exception: not axes.
                    let coef = match k.get_ref().as_ref() {
                        "f" => Some(&mut *f),
                        "g" => Some(&mut *g),
                        _ => None,
                    };
                    if let Some(c) = coef {
                        *c = p.numbers(&field, v)?;
                        if c.len() > lienard::MAX_COEFFICIENTS {
                            return Err(p.err(
                                &field,
                                Some(&v.span()),
                                format!(
                                    "{} coefficients; at most {} (degree 9)",
                                    c.len(),
                                    lienard::MAX_COEFFICIENTS
                                ),
                            ));
                        }
                        continue;
                    }
                }
                let input = add_input(&p, &field, k.get_ref(), v, &mut axes)?;
                params.insert(k.get_ref().to_string(), (v.span().start, input));
            }
        }
        if let Model::Lienard { f, g } = &model {
            if g.is_empty() {
                return Err(p.err("params.g", table(&p, "params")?.and(None), "the Liénard model needs g (ascending coefficients of g(q), e.g. g = [0.0, 1.0])"));
            }
            let _ = f;
        }

        // [initial]
        let mut initial = BTreeMap::new();
        let mut known_initial: Vec<&str> = spec.vars.to_vec();
        known_initial.push("t0");
        if let Some(alias) = &spec.initial_alias {
            // e.g. Kepler's eccentricity: an orbit at perihelion (SPEC §2.1).
            known_initial.push(alias.key);
        }
        if let Some(t) = table(&p, "initial")? {
            for (k, v) in p.entries(t, "initial", Some(&known_initial))? {
                let field = format!("initial.{}", k.get_ref());
                let input = add_input(&p, &field, k.get_ref(), v, &mut axes)?;
                initial.insert(k.get_ref().to_string(), (v.span().start, input));
            }
        }

        // [integrator]
        let integ = table(&p, "integrator")?.ok_or_else(|| {
            p.err(
                "integrator",
                None,
                "missing; it needs scheme, dt and t_end or steps",
            )
        })?;
        let ie = p.entries(integ, "integrator", Some(INTEGRATOR_KEYS))?;
        let iget = |name: &str| {
            ie.iter()
                .find(|(k, _)| k.get_ref() == name)
                .map(|(_, v)| *v)
        };
        let scheme = match iget("scheme") {
            Some(v) => p.string("integrator.scheme", v)?,
            None => "s2".into(),
        };
        if Scheme::by_name(&scheme).is_none() {
            return Err(p.err(
                "integrator.scheme",
                iget("scheme").map(|v| v.span()).as_ref(),
                format!(
                    "unknown scheme `{scheme}`{}; one of: {}",
                    suggest(&scheme, SCHEME_NAMES),
                    SCHEME_NAMES.join(", ")
                ),
            ));
        }
        let order = iget("order")
            .map(|v| p.string("integrator.order", v))
            .transpose()?;
        let dt_v = iget("dt").ok_or_else(|| {
            p.err(
                "integrator.dt",
                Some(&integ_span(&ie)),
                "missing: the step size",
            )
        })?;
        let dt = add_input(&p, "integrator.dt", "dt", dt_v, &mut axes)?;
        let horizon = match (iget("t_end"), iget("steps")) {
            (Some(v), None) => Horizon::TEnd(p.number("integrator.t_end", v)?),
            (None, Some(v)) => {
                let s = p.integer("integrator.steps", v)?;
                if s == 0 {
                    return Err(p.err("integrator.steps", Some(&v.span()), "must be at least 1"));
                }
                Horizon::Steps(s)
            }
            (Some(v), Some(_)) => {
                return Err(p.err(
                    "integrator.t_end",
                    Some(&v.span()),
                    "give t_end or steps, not both",
                ))
            }
            (None, None) => {
                return Err(p.err("integrator", Some(&integ_span(&ie)), "needs t_end or steps"))
            }
        };

        // Axis numbering in file order.
        axes.sort_by_key(|(start, _)| *start);
        let index_of = |start: usize| {
            axes.iter()
                .position(|(s, _)| *s == start)
                .expect("registered")
        };
        let resolve = |m: BTreeMap<String, (usize, Input)>| -> BTreeMap<String, Input> {
            m.into_iter()
                .map(|(k, (start, i))| {
                    (
                        k,
                        if i == Input::Axis(usize::MAX) {
                            Input::Axis(index_of(start))
                        } else {
                            i
                        },
                    )
                })
                .collect()
        };
        let params = resolve(params);
        let initial = resolve(initial);
        let dt = if dt == Input::Axis(usize::MAX) {
            Input::Axis(index_of(dt_v.span().start))
        } else {
            dt
        };
        let mut axes: Vec<SceneAxis> = axes.into_iter().map(|(_, a)| a).collect();
        // Axis names are file names: make repeats unique.
        for k in 0..axes.len() {
            if axes[..k].iter().any(|a| a.name == axes[k].name) {
                axes[k].name = axes[k].field.replace('.', "_");
            }
        }

        // [output]
        let var_names: Vec<String> = spec.vars.iter().map(|v| v.to_string()).collect();
        let out_var = |p: &Parser,
                       field: &str,
                       name: &str,
                       span: &Range<usize>|
         -> Result<OutVar, SceneError> {
            if name == "t" || var_names.iter().any(|v| v == name) {
                return Ok(OutVar {
                    name: name.into(),
                    components: vec![name.into()],
                });
            }
            let comps: Vec<String> = var_names
                .iter()
                .filter(|v| {
                    v.len() == name.len() + 1
                        && v.starts_with(name)
                        && v.ends_with(|c: char| c.is_ascii_digit())
                })
                .cloned()
                .collect();
            if comps.is_empty() {
                return Err(p.err(
                    field,
                    Some(span),
                    format!(
                        "model `{}` has no variable `{name}`; its variables are: {}, t",
                        spec.name,
                        var_names.join(", ")
                    ),
                ));
            }
            Ok(OutVar {
                name: name.into(),
                components: comps,
            })
        };
        let out_vars =
            |p: &Parser, field: &str, v: &Spanned<DeValue>| -> Result<Vec<OutVar>, SceneError> {
                p.strings(field, v)?
                    .iter()
                    .map(|n| out_var(p, field, n, &v.span()))
                    .collect()
            };
        let default_vars: Vec<OutVar> = spec
            .vars
            .iter()
            .filter(|v| Some(**v) != spec.optional_var)
            .map(|v| OutVar {
                name: v.to_string(),
                components: vec![v.to_string()],
            })
            .collect();
        let mut final_vars = default_vars.clone();
        let mut trajectory = None;
        let mut poincare = None;
        let mut cycle = None;
        let first_var = spec.vars[0].to_string();
        if let Some(t) = table(&p, "output")? {
            for (k, v) in p.entries(t, "output", Some(OUTPUT_KEYS))? {
                let field = format!("output.{}", k.get_ref());
                match k.get_ref().as_ref() {
                    "final" => final_vars = out_vars(&p, &field, v)?,
                    "trajectory" => {
                        let DeValue::Table(tt) = v.get_ref() else {
                            return Err(p.err(
                                &field,
                                Some(&v.span()),
                                "expected { every = k, vars = [...] }",
                            ));
                        };
                        let te = p.entries(tt, &field, Some(&["every", "vars"]))?;
                        let every = match te.iter().find(|(k, _)| k.get_ref() == "every") {
                            Some((_, e)) => p.integer(&format!("{field}.every"), e)?,
                            None => 1,
                        };
                        if every == 0 {
                            return Err(p.err(
                                &format!("{field}.every"),
                                Some(&v.span()),
                                "must be at least 1",
                            ));
                        }
                        let vars = match te.iter().find(|(k, _)| k.get_ref() == "vars") {
                            Some((_, vv)) => out_vars(&p, &format!("{field}.vars"), vv)?,
                            None => default_vars.clone(),
                        };
                        trajectory = Some((every, vars));
                    }
                    "poincare" => {
                        let DeValue::Table(pt) = v.get_ref() else {
                            return Err(p.err(&field, Some(&v.span()), "expected { period = T } or { crossing = \"q\", value = 0.0, direction = \"up\" }"));
                        };
                        let pe = p.entries(
                            pt,
                            &field,
                            Some(&[
                                "period",
                                "phase",
                                "crossing",
                                "value",
                                "direction",
                                "vars",
                                "max_points",
                                "skip",
                            ]),
                        )?;
                        let pget =
                            |n: &str| pe.iter().find(|(k, _)| k.get_ref() == n).map(|(_, v)| *v);
                        let section = match (pget("period"), pget("crossing")) {
                            (Some(per), None) => {
                                let mut forced = false;
                                let skip = pget("skip")
                                    .map(|x| p.number(&format!("{field}.skip"), x))
                                    .transpose()?
                                    .unwrap_or(0.0);
                                if skip < 0.0 || skip.fract() != 0.0 {
                                    return Err(p.err(
                                        &format!("{field}.skip"),
                                        pget("skip").map(|x| x.span()).as_ref(),
                                        "must be a whole number of periods ≥ 0",
                                    ));
                                }
                                let period = if matches!(per.get_ref(), DeValue::String(_)) {
                                    let s = p.string(&format!("{field}.period"), per)?;
                                    if s != "forcing" {
                                        return Err(p.err(&format!("{field}.period"), Some(&per.span()), "expected a number or \"forcing\" (the forcing period 2π/ω of each trajectory)"));
                                    }
                                    if model.forcing_frequency_param().is_none() {
                                        return Err(p.err(
                                            &format!("{field}.period"),
                                            Some(&per.span()),
                                            format!("model `{}` has no forcing period", spec.name),
                                        ));
                                    }
                                    forced = true;
                                    1.0
                                } else {
                                    p.number(&format!("{field}.period"), per)?
                                };
                                let phase = pget("phase")
                                    .map(|x| p.number(&format!("{field}.phase"), x))
                                    .transpose()?
                                    .unwrap_or(0.0)
                                    + skip * period;
                                if period <= 0.0 || phase < 0.0 {
                                    return Err(p.err(
                                        &format!("{field}.period"),
                                        Some(&per.span()),
                                        "needs period > 0 and phase ≥ 0",
                                    ));
                                }
                                if forced {
                                    Section::Forced { skip }
                                } else {
                                    Section::Stroboscopic { period, phase }
                                }
                            }
                            (None, Some(c)) => {
                                let var = p.string(&format!("{field}.crossing"), c)?;
                                out_var(&p, &format!("{field}.crossing"), &var, &c.span())?;
                                let value = pget("value")
                                    .map(|x| p.number(&format!("{field}.value"), x))
                                    .transpose()?
                                    .unwrap_or(0.0);
                                let direction = match pget("direction") {
                                    None => Direction::Up,
                                    Some(d) => {
                                        match p.string(&format!("{field}.direction"), d)?.as_str() {
                                            "up" => Direction::Up,
                                            "down" => Direction::Down,
                                            "both" => Direction::Both,
                                            o => {
                                                return Err(p.err(
                                                    &format!("{field}.direction"),
                                                    Some(&d.span()),
                                                    format!("`{o}` is not up, down or both"),
                                                ))
                                            }
                                        }
                                    }
                                };
                                Section::Crossing {
                                    var,
                                    value,
                                    direction,
                                }
                            }
                            _ => {
                                return Err(p.err(
                                    &field,
                                    Some(&v.span()),
                                    "give either period (stroboscopic) or crossing (event section)",
                                ))
                            }
                        };
                        let vars = match pget("vars") {
                            Some(vv) => out_vars(&p, &format!("{field}.vars"), vv)?,
                            None => default_vars.clone(),
                        };
                        let max_points = match pget("max_points") {
                            Some(m) => p.integer(&format!("{field}.max_points"), m)? as usize,
                            None => 1000,
                        };
                        if max_points == 0 {
                            return Err(p.err(
                                &format!("{field}.max_points"),
                                pget("max_points").map(|m| m.span()).as_ref(),
                                "must be at least 1",
                            ));
                        }
                        poincare = Some((section, vars, max_points));
                    }
                    "cycle" => {
                        cycle = match v.get_ref() {
                            DeValue::Boolean(true) => Some(CycleObs {
                                var: first_var.clone(),
                                ..CycleObs::default()
                            }),
                            DeValue::Boolean(false) => None,
                            DeValue::Table(ct) => {
                                let ce = p.entries(ct, &field, Some(&["var", "level", "skip"]))?;
                                let mut c = CycleObs {
                                    var: first_var.clone(),
                                    ..CycleObs::default()
                                };
                                for (ck, cv) in ce {
                                    let f = format!("{field}.{}", ck.get_ref());
                                    match ck.get_ref().as_ref() {
                                        "var" => {
                                            c.var = p.string(&f, cv)?;
                                            out_var(&p, &f, &c.var, &cv.span())?;
                                        }
                                        "level" => c.level = p.number(&f, cv)?,
                                        _ => {
                                            c.skip = p.number(&f, cv)?;
                                            if !(0.0..1.0).contains(&c.skip) {
                                                return Err(p.err(&f, Some(&cv.span()), "must be in [0, 1): the fraction of the run skipped as transient"));
                                            }
                                        }
                                    }
                                }
                                Some(c)
                            }
                            _ => return Err(p.mismatch(&field, v, "true or { var, level, skip }")),
                        };
                    }
                    _ => unreachable!("checked by entries"),
                }
            }
        }

        // [run]
        let mut backend = BackendChoice::Auto;
        let mut precision = Precision::F32;
        if let Some(t) = table(&p, "run")? {
            for (k, v) in p.entries(t, "run", Some(RUN_KEYS))? {
                let field = format!("run.{}", k.get_ref());
                let s = p.string(&field, v)?;
                match k.get_ref().as_ref() {
                    "backend" => {
                        backend = s
                            .parse()
                            .map_err(|m: String| p.err(&field, Some(&v.span()), m))?
                    }
                    _ => {
                        precision = s
                            .parse()
                            .map_err(|m: String| p.err(&field, Some(&v.span()), m))?
                    }
                }
            }
        }

        // [plot]
        let mut plot = PlotSettings {
            max_trajectories: 64,
            ..PlotSettings::default()
        };
        if let Some(t) = table(&p, "plot")? {
            for (k, v) in p.entries(t, "plot", Some(PLOT_KEYS))? {
                let field = format!("plot.{}", k.get_ref());
                match k.get_ref().as_ref() {
                    "phase" | "poincare" => {
                        let xs = p.strings(&field, v)?;
                        if xs.len() != 2 {
                            return Err(p.err(
                                &field,
                                Some(&v.span()),
                                "expected two variable names [x, y]",
                            ));
                        }
                        let pair = Some((xs[0].clone(), xs[1].clone()));
                        if k.get_ref() == "phase" {
                            plot.phase = pair;
                        } else {
                            plot.poincare = pair;
                        }
                    }
                    "wrap_x" => {
                        let w = p.string(&field, v)?;
                        if w != "2pi" && w != "pi" {
                            return Err(p.err(
                                &field,
                                Some(&v.span()),
                                "expected \"2pi\" (wrap into [0, 2π)) or \"pi\" (into [−π, π))",
                            ));
                        }
                        plot.wrap_x = Some(w);
                    }
                    "lienard_plane" => {
                        plot.lienard_plane = match v.get_ref() {
                            DeValue::Boolean(b) => *b,
                            _ => return Err(p.mismatch(&field, v, "true or false")),
                        };
                        if plot.lienard_plane && !matches!(model, Model::VanDerPol) {
                            return Err(p.err(
                                &field,
                                Some(&v.span()),
                                "the Liénard plane is drawn for van_der_pol only",
                            ));
                        }
                    }
                    "bifurcation" => {
                        let DeValue::Table(bt) = v.get_ref() else {
                            return Err(p.err(
                                &field,
                                Some(&v.span()),
                                "expected { axis = \"…\", var = \"…\" }",
                            ));
                        };
                        let be = p.entries(bt, &field, Some(&["axis", "var"]))?;
                        let bget = |n: &str| {
                            be.iter()
                                .find(|(k, _)| k.get_ref() == n)
                                .map(|(_, v)| *v)
                                .ok_or_else(|| {
                                    p.err(&format!("{field}.{n}"), Some(&v.span()), "missing")
                                })
                        };
                        let axis = p.string(&format!("{field}.axis"), bget("axis")?)?;
                        let var = p.string(&format!("{field}.var"), bget("var")?)?;
                        plot.bifurcation = Some((axis, var));
                    }
                    _ => plot.max_trajectories = p.integer(&field, v)? as usize,
                }
            }
        }

        // [report]
        let report = match table(&p, "report")? {
            None => None,
            Some(t) => {
                let mut r = ReportSettings::defaults(&scheme);
                for (k, v) in p.entries(t, "report", Some(REPORT_KEYS))? {
                    let field = format!("report.{}", k.get_ref());
                    match k.get_ref().as_ref() {
                        "schemes" => {
                            r.schemes = p.strings(&field, v)?;
                            for s in &r.schemes {
                                if Scheme::by_name(s).is_none() {
                                    return Err(p.err(
                                        &field,
                                        Some(&v.span()),
                                        format!("unknown scheme `{s}`{}", suggest(s, SCHEME_NAMES)),
                                    ));
                                }
                            }
                        }
                        "backends" => {
                            r.backends = p
                                .strings(&field, v)?
                                .iter()
                                .map(|s| {
                                    s.parse()
                                        .map_err(|m: String| p.err(&field, Some(&v.span()), m))
                                })
                                .collect::<Result<_, _>>()?
                        }
                        "precisions" => {
                            r.precisions = p
                                .strings(&field, v)?
                                .iter()
                                .map(|s| {
                                    s.parse()
                                        .map_err(|m: String| p.err(&field, Some(&v.span()), m))
                                })
                                .collect::<Result<_, _>>()?
                        }
                        "error_vars" => r.error_vars = p.strings(&field, v)?,
                        "reference_rtol" => r.reference_rtol = p.number(&field, v)?,
                        "distorted" => r.distorted = p.number(&field, v)?,
                        _ => r.targets = p.numbers(&field, v)?,
                    }
                }
                Some(r)
            }
        };

        if let Some((axis, _)) = &plot.bifurcation {
            if !axes.iter().any(|a| &a.name == axis) {
                return Err(p.err(
                    "plot.bifurcation.axis",
                    p.spans.get("plot.bifurcation"),
                    format!(
                        "`{axis}` is not an axis of this scene; its axes are: {}",
                        axes.iter()
                            .map(|a| a.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                ));
            }
            if poincare.is_none() {
                return Err(p.err(
                    "plot.bifurcation",
                    p.spans.get("plot.bifurcation"),
                    "needs an output.poincare section",
                ));
            }
        }
        let spans = p.spans;
        let scene = Scene {
            path: path.to_path_buf(),
            name,
            title,
            model,
            axes,
            params,
            initial,
            dt,
            horizon,
            scheme,
            order,
            final_vars,
            trajectory,
            poincare,
            cycle,
            backend,
            precision,
            plot,
            report,
            text: text.to_string(),
            step_cap: None,
            spans,
        };
        // Everything the plan checks (parameters, values, scheme for the
        // model, variables), reported at the line of the field.
        scene.sub_runs()?;
        Ok(scene)
    }

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
        if let Some((every, _)) = &mut s.trajectory {
            *every = (*every).min((steps / 10).max(1));
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

    /// Number of trajectories.
    pub fn ensemble_size(&self) -> usize {
        self.axes.iter().map(|a| a.values.len()).product()
    }

    /// Shape of the output arrays' leading dimensions (the axes, in order).
    pub fn shape(&self) -> Vec<usize> {
        self.axes.iter().map(|a| a.values.len()).collect()
    }

    /// Row-major strides of the axes: trajectory i has index
    /// (i / strides[k]) % shape[k] on axis k.
    pub fn strides(&self) -> Vec<usize> {
        crate::plan::row_major_strides(&self.shape())
    }

    fn t0_input(&self) -> Input {
        self.initial.get("t0").cloned().unwrap_or(Input::Const(0.0))
    }

    /// The axes that change the step count (dt and t0 with t_end): each plan
    /// holds them at one value.
    fn step_axes(&self) -> Vec<usize> {
        let mut v = vec![];
        if let Horizon::TEnd(_) = self.horizon {
            for input in [&self.dt, &self.t0_input()] {
                if let Input::Axis(k) = input {
                    if !v.contains(k) {
                        v.push(*k);
                    }
                }
            }
        }
        v
    }

    /// The plans that make up the scene: one, or one per value combination of
    /// the axes that change the step count.
    pub fn sub_runs(&self) -> Result<Vec<SubRun>, SceneError> {
        let step_axes = self.step_axes();
        let combos: usize = step_axes
            .iter()
            .map(|k| self.axes[*k].values.len())
            .product();
        let mut out = vec![];
        for c in 0..combos {
            let mut fixed = vec![];
            let mut rem = c;
            for k in step_axes.iter().rev() {
                let len = self.axes[*k].values.len();
                fixed.push((*k, rem % len));
                rem /= len;
            }
            fixed.reverse();
            out.push(SubRun {
                plan: self.plan_for(&fixed)?,
                fixed,
            });
        }
        Ok(out)
    }

    /// The plan with the axes in `fixed` held at one value.
    fn plan_for(&self, fixed: &[(usize, usize)]) -> Result<Plan, SceneError> {
        let mut problem = Problem::new(self.model.clone(), &self.scheme)
            .map_err(|e| self.error(&e.field, e.message))?;
        problem.order = self.order.clone();
        // Free axes keep their order; fixed ones become constants.
        let mut axis_map = vec![None; self.axes.len()];
        for (k, a) in self.axes.iter().enumerate() {
            if !fixed.iter().any(|(f, _)| *f == k) {
                axis_map[k] = Some(problem.axes.len());
                problem.axes.push(crate::plan::Axis {
                    name: a.name.clone(),
                    len: a.values.len(),
                });
            }
        }
        let source = |input: &Input| -> Source {
            match input {
                Input::Const(v) => Source::Const(*v),
                Input::Axis(k) => match axis_map[*k] {
                    Some(a) => Source::Axis {
                        axis: a,
                        values: self.axes[*k].values.clone(),
                    },
                    None => {
                        let idx = fixed
                            .iter()
                            .find(|(f, _)| f == k)
                            .map(|(_, i)| *i)
                            .expect("fixed");
                        Source::Const(self.axes[*k].values[idx])
                    }
                },
            }
        };
        for (k, v) in &self.params {
            problem.params.insert(k.clone(), source(v));
        }
        for (k, v) in &self.initial {
            problem.initial.insert(k.clone(), source(v));
        }
        problem.dt = source(&self.dt);
        problem.steps = match self.horizon {
            Horizon::Steps(s) => s,
            Horizon::TEnd(t_end) => {
                let (Source::Const(dt), Source::Const(t0)) =
                    (source(&self.dt), source(&self.t0_input()))
                else {
                    unreachable!("dt and t0 are fixed in every sub-run when t_end is given")
                };
                if dt <= 0.0 {
                    return Err(self.error("integrator.dt", format!("must be > 0 (got {dt})")));
                }
                if t_end <= t0 {
                    return Err(self.error(
                        "integrator.t_end",
                        format!("{t_end} is not after t0 = {t0}"),
                    ));
                }
                let steps = ((t_end - t0) / dt).round();
                if steps > 4e9 {
                    return Err(self.error(
                        "integrator.t_end",
                        format!("{steps:e} steps of dt = {dt}: too many (at most 4·10⁹)"),
                    ));
                }
                (steps as u64).max(1)
            }
        };
        if let Some(cap) = self.step_cap {
            problem.steps = problem.steps.min(cap);
        }
        let comps = |vars: &[OutVar]| -> Vec<String> {
            vars.iter().flat_map(|v| v.components.clone()).collect()
        };
        problem.observers.final_vars = comps(&self.final_vars);
        problem.observers.trajectory =
            self.trajectory.as_ref().map(|(every, vars)| TrajectoryObs {
                every: *every,
                vars: comps(vars),
            });
        problem.observers.poincare =
            self.poincare
                .as_ref()
                .map(|(section, vars, max_points)| PoincareObs {
                    section: section.clone(),
                    vars: comps(vars),
                    max_points: *max_points,
                });
        problem.observers.cycle = self.cycle.clone();
        if let Some(tr) = &problem.observers.trajectory {
            if tr.every > problem.steps {
                return Err(self.error(
                    "output.trajectory.every",
                    format!(
                        "{} is more than the {} steps of the run",
                        tr.every, problem.steps
                    ),
                ));
            }
        }
        Plan::new(&problem).map_err(|e| self.error(&e.field, e.message))
    }
}

fn integ_span(entries: &[Entry]) -> Range<usize> {
    entries.first().map(|(k, _)| k.span()).unwrap_or(0..0)
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert_eq!(s.final_vars[0].components, ["q1", "q2"]);
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
