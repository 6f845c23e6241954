//! Reading a scene file: the TOML parsed once with spans; the model-keyed
//! tables and `dt` through the value-language walker (`values.rs`); the
//! fixed tables through their serde types (`tables.rs`); then the scene's
//! plans are built, so that every check of the plan (parameters, variables,
//! observers, model rules) is reported at the line of its field.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;

use serde::de::DeserializeOwned;
use toml::de::{DeTable, DeValue, ValueDeserializer};
use toml::Spanned;

use crate::models::spec::ModelSpec;
use crate::models::{Model, MODEL_NAMES};
use crate::num::precision::Precision;
use crate::plan::indicators::SCALAR_INDICATORS;
use crate::plan::observers::{
    check_skip, check_strobe, AttractorObs, AverageObs, CycleObs, Direction, GaliObs, LyapunovObs,
    Observers, PoincareObs, ResonanceObs, SampledObs, Section, TrajectoryObs,
};
use crate::plan::scheme::{Scheme, SCHEME_NAMES};
use crate::plan::size;
use crate::plan::stop::StopObs;

use super::keys::{self, Key};
use super::tables::{self, Cycle, Lyapunov, Period, Sampled, Str, Strs, Table};
use super::values::{integ_span, suggest, AxisValues, Entry, Parser};
use super::{
    BackendChoice, Format, Horizon, Input, OutVar, PlotSettings, ReportSettings, Scene, SceneAxis,
    SceneError,
};

/// The top-level entries of a scene file.
struct Doc<'i> {
    top: Vec<Entry<'i>>,
}

impl<'i> Doc<'i> {
    fn get(&self, name: &str) -> Option<&'i Spanned<DeValue<'i>>> {
        self.top
            .iter()
            .find(|(k, _)| k.get_ref() == name)
            .map(|(_, v)| *v)
    }
    /// The table `name`, if given; anything else there is an error.
    fn table(&self, p: &Parser, name: &str) -> Result<Option<&'i DeTable<'i>>, SceneError> {
        match self.get(name) {
            None => Ok(None),
            Some(v) => match v.get_ref() {
                DeValue::Table(t) => Ok(Some(t)),
                _ => Err(p.mismatch(name, v, "a table")),
            },
        }
    }
}

/// An axis as the file gives it, before the size gate lets it be materialised.
struct PendingAxis {
    span: Range<usize>,
    name: String,
    field: String,
    values: AxisValues,
}

/// Inputs given so far, and the axes they open (keyed by where their value
/// starts in the file, which fixes the axes' order).
#[derive(Default)]
struct Inputs {
    axes: Vec<PendingAxis>,
}

impl Inputs {
    /// A constant, or a new axis named `name` (its index is resolved once
    /// every axis is known).
    fn add(
        &mut self,
        p: &Parser,
        field: &str,
        name: &str,
        v: &Spanned<DeValue>,
    ) -> Result<(usize, Input), SceneError> {
        Ok(match p.values(field, v)? {
            Ok(c) => (v.span().start, Input::Const(c)),
            Err(values) => {
                self.axes.push(PendingAxis {
                    span: v.span(),
                    name: name.to_string(),
                    field: field.to_string(),
                    values,
                });
                (v.span().start, Input::Axis(usize::MAX))
            }
        })
    }

    /// The size gate, before any axis is materialised: the ensemble (the
    /// product of the axis counts) fits in 64 bits, and the memory it takes
    /// before anything is recorded (the axis values, the plans' copies of
    /// them, the status of each trajectory: 8 bytes) fits in the memory a run
    /// may use ([`size::default_limit`]), the limit `reeb run` uses by
    /// default. Refused at the largest axis.
    /// `step_fields`: the axes that make one plan per value (`dt` and `t0`
    /// with `t_end`).
    fn gate(&mut self, p: &Parser, step_fields: &[&str]) -> Result<(), SceneError> {
        // File order, for the message (and the first of equal largest axes).
        self.axes.sort_by_key(|a| a.span.start);
        let Some(largest) = self.axes.iter().rev().max_by_key(|a| a.values.len()) else {
            return Ok(());
        };
        let counts = self
            .axes
            .iter()
            .map(|a| format!("{} {}", a.field, a.values.len()))
            .collect::<Vec<_>>()
            .join(" × ");
        let refuse = |message: String| p.err(&largest.field, Some(&largest.span), message);
        let fewer = "use fewer values along an axis (a shorter list, a smaller n in linspace, logspace or random)";
        let Some(trajectories) = self
            .axes
            .iter()
            .try_fold(1u64, |n, a| n.checked_mul(a.values.len()))
        else {
            return Err(refuse(format!(
                "the ensemble has more than 2^64 trajectories ({counts} values); {fewer}"
            )));
        };
        // Bytes, saturating: they are only compared with the limit.
        let is_step = |a: &PendingAxis| step_fields.contains(&a.field.as_str());
        let values_of = |step: bool| {
            self.axes
                .iter()
                .filter(|a| is_step(a) == step)
                .fold(0u64, |b, a| {
                    b.saturating_add(a.values.len().saturating_mul(8))
                })
        };
        let plans = self
            .axes
            .iter()
            .filter(|a| is_step(a))
            .fold(1u64, |n, a| n.saturating_mul(a.values.len()));
        let need = values_of(true)
            .saturating_add(values_of(false).saturating_mul(plans.saturating_add(1)))
            .saturating_add(trajectories.saturating_mul(8));
        let limit = size::default_limit();
        if need > limit {
            let per_plan = if plans > 1 {
                let fields: Vec<&str> = self
                    .axes
                    .iter()
                    .filter(|a| is_step(a))
                    .map(|a| a.field.as_str())
                    .collect();
                format!(
                    ", or fewer values of {} (one plan per value, each with a copy of the other axes)",
                    fields.join(" and ")
                )
            } else {
                String::new()
            };
            return Err(refuse(format!(
                "{trajectories} trajectories ({counts} values) need at least {} before anything is recorded (the axis values, the plans' copies of them, each trajectory's status) and {} is available; {fewer}{per_plan}",
                size::bytes(need),
                size::bytes(limit),
            )));
        }
        Ok(())
    }

    /// The axes in file order, materialised (repeated names made unique),
    /// and a map from an input's start to its axis index. After [`Self::gate`].
    fn number(mut self) -> (Vec<SceneAxis>, impl Fn((usize, Input)) -> Input) {
        self.axes.sort_by_key(|a| a.span.start);
        let starts: Vec<usize> = self.axes.iter().map(|a| a.span.start).collect();
        let mut axes: Vec<SceneAxis> = self
            .axes
            .into_iter()
            .map(|a| SceneAxis {
                name: a.name,
                field: a.field,
                values: a.values.materialize(),
            })
            .collect();
        // Axis names are file names: make repeats unique.
        for k in 0..axes.len() {
            if axes[..k].iter().any(|a| a.name == axes[k].name) {
                axes[k].name = axes[k].field.replace('.', "_");
            }
        }
        let resolve = move |(start, input): (usize, Input)| match input {
            Input::Axis(usize::MAX) => {
                Input::Axis(starts.iter().position(|s| *s == start).expect("registered"))
            }
            other => other,
        };
        (axes, resolve)
    }
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
        let root = parse_toml(path, text)?;
        let mut p = Parser::new(path, text);
        let doc = Doc {
            top: p.entries(root.get_ref(), "", Some(&keys::names(keys::TOP)))?,
        };
        let mut model = model(&mut p, &doc)?;
        let spec = model.spec();
        let name = scene_name(&p, &doc, path)?;
        let title = doc.get("title").map(|v| p.string("title", v)).transpose()?;
        let mut inputs = Inputs::default();
        let params = params(&mut p, &doc, &mut model, &mut inputs)?;
        let initial = initial(&mut p, &doc, spec, &mut inputs)?;
        let integ = integrator(&mut p, &doc, &mut inputs)?;
        let step_fields: &[&str] = match integ.horizon {
            Horizon::TEnd(_) => &["integrator.dt", "initial.t0"],
            Horizon::Steps(_) => &[],
        };
        inputs.gate(&p, step_fields)?;
        let (axes, resolve) = inputs.number();
        let resolve_all = |m: BTreeMap<String, (usize, Input)>| -> BTreeMap<String, Input> {
            m.into_iter().map(|(k, i)| (k, resolve(i))).collect()
        };
        let params = resolve_all(params);
        let initial = resolve_all(initial);
        let dt = resolve(integ.dt);
        let names: Vec<&str> = params.keys().map(|k| k.as_str()).collect();
        let out = output(&mut p, &doc, &model, &names)?;
        let (backend, precision) = run(&mut p, &doc)?;
        let plot = plot(&mut p, &doc, &model)?;
        let report = report(&mut p, &doc, &integ.scheme)?;
        check_bifurcation(&p, &plot, &axes, out.observers.poincare.is_some())?;
        check_plot_vars(&p, &plot, &out)?;
        let scene = Scene {
            path: path.to_path_buf(),
            name,
            title,
            model,
            axes,
            params,
            initial,
            dt,
            horizon: integ.horizon,
            scheme: integ.scheme,
            order: integ.order,
            observers: out.observers,
            format: out.format,
            backend,
            precision,
            plot,
            report,
            text: text.to_string(),
            step_cap: None,
            preview: None,
            spans: p.into_spans(),
        };
        // Everything the plan checks (parameters, values, scheme for the
        // model, variables, observers), reported at the line of the field.
        scene.sub_runs()?;
        Ok(scene)
    }
}

fn parse_toml<'i>(path: &Path, text: &'i str) -> Result<Spanned<DeTable<'i>>, SceneError> {
    DeTable::parse(text).map_err(|e| SceneError {
        path: path.to_path_buf(),
        line: e
            .span()
            .map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1),
        field: "toml".into(),
        message: e.message().to_string(),
    })
}

/// `model = "…"`: by name from the registry, or a formula model
/// (`mechanical`, or `lienard` with a `[formula]` table).
fn model(p: &mut Parser, doc: &Doc) -> Result<Model, SceneError> {
    let names: Vec<&str> = MODEL_NAMES.iter().copied().chain(["mechanical"]).collect();
    let v = doc.get("model").ok_or_else(|| {
        p.err(
            "model",
            None,
            format!("missing; one of: {}", names.join(", ")),
        )
    })?;
    let name = p.string("model", v)?;
    let formula = doc.get("formula");
    if name == "mechanical" || (name == "lienard" && formula.is_some()) {
        let table = match formula {
            Some(f) => Some((doc.table(p, "formula")?.expect("given"), f.span())),
            None => None,
        };
        let params = match doc.table(p, "params")? {
            Some(t) => p
                .entries(t, "params", None)?
                .iter()
                .map(|(k, _)| k.get_ref().to_string())
                .collect(),
            None => vec![],
        };
        return super::formula::formula_model(p, &name, table, params);
    }
    if let Some(f) = formula {
        return Err(p.err(
            "formula",
            Some(&f.span()),
            format!(
                "model `{name}` takes no formulas; [formula] is for `mechanical` and `lienard`"
            ),
        ));
    }
    Model::from_name(&name).ok_or_else(|| {
        p.err(
            "model",
            Some(&v.span()),
            format!(
                "unknown model `{name}`{}; one of: {}",
                suggest(&name, &names),
                names.join(", ")
            ),
        )
    })
}

/// `name = "…"` (default: the file's stem), a plain file name.
fn scene_name(p: &Parser, doc: &Doc, path: &Path) -> Result<String, SceneError> {
    let name = match doc.get("name") {
        Some(v) => p.string("name", v)?,
        None => path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scene".into()),
    };
    // The name becomes a folder name and reaches shell scripts (`reeb
    // slurm`): a control character there would end a line of the script.
    if name.is_empty()
        || name.contains(['/', '\\'])
        || name.chars().any(char::is_control)
        || name == "."
        || name == ".."
    {
        return Err(p.err(
            "name",
            doc.get("name").map(|v| v.span()).as_ref(),
            format!(
                "{name:?} must be a plain file name: not empty, not . or .., without /, \\ or control characters (newlines, tabs, NUL)"
            ),
        ));
    }
    Ok(name)
}

/// `[params]`: the model's parameters in the value language; for the
/// Liénard model also its coefficient lists `f` and `g` (model data, not axes).
fn params(
    p: &mut Parser,
    doc: &Doc,
    model: &mut Model,
    inputs: &mut Inputs,
) -> Result<BTreeMap<String, (usize, Input)>, SceneError> {
    let mut params = BTreeMap::new();
    let mut known: Vec<&str> = model.spec().params.iter().map(|d| d.name).collect();
    if matches!(model, Model::Lienard { .. }) {
        known.extend(["f", "g"]);
    }
    let table = doc.table(p, "params")?;
    if let Some(t) = table {
        for (k, v) in p.entries(t, "params", Some(&known))? {
            let field = format!("params.{}", k.get_ref());
            if let Model::Lienard { f, g } = &mut *model {
                let coef = match k.get_ref().as_ref() {
                    "f" => Some(f),
                    "g" => Some(g),
                    _ => None,
                };
                if let Some(c) = coef {
                    *c = p.numbers(&field, v)?;
                    continue;
                }
            }
            params.insert(
                k.get_ref().to_string(),
                inputs.add(p, &field, k.get_ref(), v)?,
            );
        }
    }
    if let Model::Lienard { g, .. } = model {
        if g.is_empty() {
            return Err(p.err(
                "params.g",
                None,
                "the Liénard model needs g (ascending coefficients of g(q), e.g. g = [0.0, 1.0])",
            ));
        }
    }
    Ok(params)
}

/// `[initial]`: the model's variables, `t0`, and the model's alias key.
fn initial(
    p: &mut Parser,
    doc: &Doc,
    spec: &ModelSpec,
    inputs: &mut Inputs,
) -> Result<BTreeMap<String, (usize, Input)>, SceneError> {
    let mut initial = BTreeMap::new();
    let mut known: Vec<&str> = spec.vars.to_vec();
    known.push("t0");
    if let Some(alias) = &spec.initial_alias {
        // e.g. Kepler's eccentricity: an orbit at perihelion (SPEC §2.1).
        known.push(alias.key);
    }
    if let Some(t) = doc.table(p, "initial")? {
        for (k, v) in p.entries(t, "initial", Some(&known))? {
            let field = format!("initial.{}", k.get_ref());
            initial.insert(
                k.get_ref().to_string(),
                inputs.add(p, &field, k.get_ref(), v)?,
            );
        }
    }
    Ok(initial)
}

/// What `[integrator]` gives.
struct Integ {
    scheme: Scheme,
    order: Option<String>,
    dt: (usize, Input),
    horizon: Horizon,
}

fn integrator(p: &mut Parser, doc: &Doc, inputs: &mut Inputs) -> Result<Integ, SceneError> {
    let t = doc.table(p, "integrator")?.ok_or_else(|| {
        p.err(
            "integrator",
            None,
            "missing; it needs scheme, dt and t_end or steps",
        )
    })?;
    let entries = p.entries(t, "integrator", Some(&keys::names(keys::INTEGRATOR)))?;
    let entries: Vec<Entry> = entries.into_iter().collect();
    let table: tables::Integrator = deserialize(p, doc.get("integrator"))?;
    let scheme = table
        .scheme
        .as_ref()
        .map_or("s2".into(), |s| s.get_ref().0.clone());
    let Some(parsed) = Scheme::by_name(&scheme) else {
        return Err(p.err(
            "integrator.scheme",
            table.scheme.as_ref().map(|s| s.span()).as_ref(),
            format!(
                "unknown scheme `{scheme}`{}; one of: {}",
                suggest(&scheme, SCHEME_NAMES),
                SCHEME_NAMES.join(", ")
            ),
        ));
    };
    let scheme = parsed;
    let dt_v = entries
        .iter()
        .find(|(k, _)| k.get_ref() == "dt")
        .map(|(_, v)| *v)
        .ok_or_else(|| {
            p.err(
                "integrator.dt",
                Some(&integ_span(&entries)),
                "missing: the step size",
            )
        })?;
    let dt = inputs.add(p, "integrator.dt", "dt", dt_v)?;
    let horizon = match (table.t_end, table.steps) {
        (Some(t), None) => Horizon::TEnd(t.get_ref().0),
        (None, Some(s)) if s.get_ref().0 == 0 => {
            return Err(p.err("integrator.steps", Some(&s.span()), "must be at least 1"))
        }
        (None, Some(s)) => Horizon::Steps(s.get_ref().0),
        (Some(t), Some(_)) => {
            return Err(p.err(
                "integrator.t_end",
                Some(&t.span()),
                "give t_end or steps, not both",
            ))
        }
        (None, None) => {
            return Err(p.err(
                "integrator",
                Some(&integ_span(&entries)),
                "needs t_end or steps",
            ))
        }
    };
    Ok(Integ {
        scheme,
        order: table.order.map(|o| o.into_inner().0),
        dt,
        horizon,
    })
}

/// A fixed table (`value`, the whole table's value) through its serde
/// type; a type error is reported at its span's field and line.
fn deserialize<T: DeserializeOwned + Default>(
    p: &Parser,
    value: Option<&Spanned<DeValue>>,
) -> Result<T, SceneError> {
    let Some(v) = value else {
        return Ok(T::default());
    };
    T::deserialize(ValueDeserializer::from(v.clone())).map_err(|e| {
        let span = e.span().unwrap_or_else(|| v.span());
        p.err(&p.field_at(&span), Some(&span), e.message().to_string())
    })
}

/// What `[output]` gives.
struct Out {
    observers: Observers,
    format: Format,
}

/// Resolves output variable names against the model: a variable, `t`, or a
/// vector (`q` of Kepler is `[q1, q2]`).
struct OutVars<'a> {
    spec: &'a ModelSpec,
}

impl OutVars<'_> {
    fn one(
        &self,
        p: &Parser,
        field: &str,
        name: &str,
        span: &Range<usize>,
    ) -> Result<OutVar, SceneError> {
        let vars = self.spec.vars;
        if name == "t" || vars.contains(&name) {
            return Ok(OutVar {
                name: name.into(),
                components: vec![name.into()],
            });
        }
        let comps: Vec<String> = vars
            .iter()
            .filter(|v| {
                v.len() == name.len() + 1
                    && v.starts_with(name)
                    && v.ends_with(|c: char| c.is_ascii_digit())
            })
            .map(|v| v.to_string())
            .collect();
        if comps.is_empty() {
            return Err(p.err(
                field,
                Some(span),
                format!(
                    "model `{}` has no variable `{name}`; its variables are: {}, t",
                    self.spec.name,
                    vars.join(", ")
                ),
            ));
        }
        Ok(OutVar {
            name: name.into(),
            components: comps,
        })
    }
    fn list(&self, p: &Parser, field: &str, v: &Spanned<Strs>) -> Result<Vec<OutVar>, SceneError> {
        v.get_ref()
            .0
            .iter()
            .map(|n| self.one(p, field, n, &v.span()))
            .collect()
    }
    /// The model's variables other than the optional one.
    fn defaults(&self) -> Vec<OutVar> {
        self.spec
            .vars
            .iter()
            .filter(|v| Some(**v) != self.spec.optional_var)
            .map(|v| OutVar {
                name: v.to_string(),
                components: vec![v.to_string()],
            })
            .collect()
    }
}

fn output(p: &mut Parser, doc: &Doc, model: &Model, params: &[&str]) -> Result<Out, SceneError> {
    let ov = OutVars { spec: model.spec() };
    let table = doc.table(p, "output")?;
    if let Some(t) = table {
        check_keys(
            p,
            t,
            "output",
            keys::OUTPUT,
            &[
                ("trajectory", keys::TRAJECTORY),
                ("poincare", keys::POINCARE),
                ("cycle", keys::CYCLE),
                ("average", keys::AVERAGE),
                ("resonance", keys::RESONANCE),
                ("stop", keys::STOP),
                ("lyapunov", keys::LYAPUNOV),
                ("fli", keys::SAMPLED),
                ("megno", keys::SAMPLED),
                ("sali", keys::SAMPLED),
                ("gali", keys::GALI),
                ("attractors", keys::ATTRACTORS),
            ],
        )?;
    }
    let o: tables::Output = deserialize(p, doc.get("output"))?;
    let (average, resonance) = averages(p, &ov, &o)?;
    let chaos = indicators(o.lyapunov, o.fli, o.megno, o.sali, o.gali);
    // The indicators a stop condition may read, by name.
    let readable = SCALAR_INDICATORS
        .iter()
        .filter(|i| (i.every)(&chaos).is_some())
        .map(|i| i.key);
    let params: Vec<&str> = params.iter().copied().chain(readable).collect();
    let stop = o
        .stop
        .as_ref()
        .map(|s| stop(p, model, &params, s))
        .transpose()?;
    let final_vars = match &o.final_vars {
        Some(v) => ov.list(p, "output.final", v)?,
        None => ov.defaults(),
    };
    let trajectory = match o.trajectory {
        None => None,
        Some(tr) => {
            let Table(tr) = tr.into_inner();
            let every = tr.every.map_or(1, |e| e.into_inner().0);
            let vars = match &tr.vars {
                Some(v) => ov.list(p, "output.trajectory.vars", v)?,
                None => ov.defaults(),
            };
            Some(TrajectoryObs { every, vars })
        }
    };
    let poincare = match o.poincare {
        None => None,
        Some(pc) => Some(poincare(p, &ov, model, pc)?),
    };
    let first_var = model.spec().vars[0].to_string();
    let cycle = match o.cycle.map(Spanned::into_inner) {
        None | Some(Cycle::On(false)) => None,
        Some(Cycle::On(true)) => Some(CycleObs {
            var: first_var,
            ..CycleObs::default()
        }),
        Some(Cycle::Table(c)) => {
            let var = match &c.var {
                Some(v) => {
                    ov.one(p, "output.cycle.var", &v.get_ref().0, &v.span())?;
                    v.get_ref().0.clone()
                }
                None => first_var,
            };
            let d = CycleObs::default();
            Some(CycleObs {
                var,
                level: c.level.map_or(d.level, |x| x.into_inner().0),
                skip: c.skip.map_or(d.skip, |x| x.into_inner().0),
            })
        }
    };
    let attractors = attractors(p, &ov, o.attractors, poincare.as_ref())?;
    let format = parsed(p, "output.format", &o.format)?.unwrap_or(Format::Npy);
    let observers = Observers {
        final_vars,
        trajectory,
        poincare,
        cycle,
        average: average.map(|(vars, skip)| AverageObs { vars, skip }),
        resonance,
        stop,
        attractors,
        ..chaos
    };
    Ok(Out { observers, format })
}

/// `output.attractors`: its samples are the section's state variables
/// (`poincare`), else the model's state; `angles` must be among them. The
/// numbers are checked with the other observers'.
fn attractors(
    p: &Parser,
    ov: &OutVars,
    a: Option<Spanned<tables::Attractors>>,
    poincare: Option<&PoincareObs>,
) -> Result<Option<AttractorObs>, SceneError> {
    let span = a.as_ref().map(|a| a.span());
    let t = match a.map(Spanned::into_inner) {
        None | Some(tables::Attractors::On(false)) => return Ok(None),
        Some(tables::Attractors::On(true)) => tables::AttractorsTable::default(),
        Some(tables::Attractors::Table(t)) => t,
    };
    let vars: Vec<OutVar> = match poincare {
        Some(pc) => pc.vars.iter().filter(|v| v.name != "t").cloned().collect(),
        None => ov.defaults(),
    };
    if vars.is_empty() {
        return Err(p.err(
            "output.attractors",
            span.as_ref(),
            "the section records no state variable to sample: add one to output.poincare.vars",
        ));
    }
    let angles = t.angles.as_ref().map_or(vec![], |a| a.get_ref().0.clone());
    let sampled: Vec<&String> = crate::plan::observers::components(&vars).collect();
    if let Some(bad) = angles.iter().find(|a| !sampled.contains(a)) {
        let names: Vec<&str> = sampled.iter().map(|s| s.as_str()).collect();
        return Err(p.err(
            "output.attractors.angles",
            t.angles.as_ref().map(|a| a.span()).as_ref(),
            format!(
                "`{bad}` is not sampled; the samples' variables are: {}",
                names.join(", ")
            ),
        ));
    }
    let d = AttractorObs::default();
    Ok(Some(AttractorObs {
        max_period: t
            .max_period
            .map_or(d.max_period, |x| x.into_inner().0 as usize),
        tolerance: t.tolerance.map_or(d.tolerance, |x| x.into_inner().0),
        skip: t.skip.map_or(d.skip, |x| x.into_inner().0),
        every: t.every.map(|x| x.into_inner().0),
        vars,
        angles,
    }))
}

/// `output.lyapunov`, `output.fli`, `output.megno`, `output.sali`,
/// `output.gali` (`true`: the defaults; the values are checked with the
/// other observers').
fn indicators(
    lyapunov: Option<Spanned<Lyapunov>>,
    fli: Option<Spanned<Sampled>>,
    megno: Option<Spanned<Sampled>>,
    sali: Option<Spanned<Sampled>>,
    gali: Option<Spanned<tables::Gali>>,
) -> Observers {
    let whole =
        |x: Option<Spanned<tables::Int>>, default: u64| x.map_or(default, |v| v.into_inner().0);
    let lyapunov = match lyapunov.map(Spanned::into_inner) {
        None | Some(Lyapunov::On(false)) => None,
        Some(Lyapunov::On(true)) => Some(LyapunovObs::default()),
        Some(Lyapunov::Table(t)) => Some(LyapunovObs {
            vectors: whole(t.vectors, 1) as usize,
            every: whole(t.every, 1),
            skip: t.skip.map_or(0.0, |x| x.into_inner().0),
        }),
    };
    let sampled = |s: Option<Spanned<Sampled>>| match s.map(Spanned::into_inner) {
        None | Some(Sampled::On(false)) => None,
        Some(Sampled::On(true)) => Some(SampledObs::default()),
        Some(Sampled::Table(t)) => Some(SampledObs {
            every: whole(t.every, 1),
        }),
    };
    let gali = match gali.map(Spanned::into_inner) {
        None | Some(tables::Gali::On(false)) => None,
        Some(tables::Gali::On(true)) => Some(GaliObs::default()),
        Some(tables::Gali::Table(t)) => Some(GaliObs {
            k: whole(t.k, GaliObs::default().k as u64) as usize,
            every: whole(t.every, 1),
        }),
    };
    Observers {
        lyapunov,
        fli: sampled(fli),
        megno: sampled(megno),
        sali: sampled(sali),
        gali,
        ..Observers::default()
    }
}

/// `output.stop`: the condition compiled over the model's variables, `t`
/// and the scene's parameters; errors at its column, with a caret.
fn stop(
    p: &Parser,
    model: &Model,
    params: &[&str],
    s: &Spanned<tables::Stop>,
) -> Result<StopObs, SceneError> {
    let text = &s.get_ref().0;
    let vars = model.spec().vars;
    let names: Vec<&str> = vars
        .iter()
        .copied()
        .chain(["t"])
        .chain(params.iter().copied())
        .collect();
    crate::plan::stop::compile(text, &names, vars.len()).map_err(|e| {
        p.err(
            "output.stop",
            Some(&s.span()),
            super::formula::with_caret(text, e.column, &e.message),
        )
    })
}

/// `output.average` and `output.resonance` (which averages its variable
/// too, skipping the average's fraction, or half the run).
#[allow(clippy::type_complexity)]
fn averages(
    p: &Parser,
    ov: &OutVars,
    o: &tables::Output,
) -> Result<(Option<(Vec<OutVar>, f64)>, Option<ResonanceObs>), SceneError> {
    let field = "output.average";
    let mut average = match o.average.as_ref() {
        None => None,
        Some(a) => {
            let span = a.span();
            let (vars, skip) = match a.get_ref() {
                tables::Average::Vars(v) => (v.0.clone(), None),
                tables::Average::Table(t) => (
                    t.vars
                        .as_ref()
                        .map(|v| v.get_ref().0.clone())
                        .unwrap_or_default(),
                    t.skip.as_ref().map(|x| x.get_ref().0),
                ),
            };
            if vars.is_empty() {
                return Err(p.err(field, Some(&span), "names no variable".to_string()));
            }
            let mut out = vec![];
            for v in &vars {
                if v == "t" {
                    return Err(p.err(
                        field,
                        Some(&span),
                        "time has no average to take".to_string(),
                    ));
                }
                out.push(ov.one(p, field, v, &span)?);
            }
            Some((out, skip.unwrap_or(0.5)))
        }
    };
    let Some(r) = o.resonance.as_ref() else {
        return Ok((average, None));
    };
    let span = r.span();
    let r = &r.get_ref().0;
    let field = "output.resonance";
    let Some(var) = r.var.as_ref() else {
        return Err(p.err(
            field,
            Some(&span),
            "needs var, the variable whose mean is classified (e.g. var = \"p\")".to_string(),
        ));
    };
    let var_span = var.span();
    let var = ov.one(p, "output.resonance.var", &var.get_ref().0, &var_span)?;
    if var.name == "t" || var.components.len() != 1 {
        return Err(p.err(
            "output.resonance.var",
            Some(&var_span),
            format!(
                "`{}` has no average to classify: name one state variable",
                var.name
            ),
        ));
    }
    let Some(ratios) = r.ratios.as_ref() else {
        return Err(p.err(
            field,
            Some(&span),
            "needs ratios, e.g. ratios = [[1, 1], [3, 2]]".to_string(),
        ));
    };
    let Some(tolerance) = r.tolerance.as_ref() else {
        return Err(p.err(
            field,
            Some(&span),
            "needs tolerance, e.g. tolerance = 0.01".to_string(),
        ));
    };
    let (vars, _) = average.get_or_insert_with(|| (vec![], 0.5));
    if !vars.iter().any(|v| v.name == var.name) {
        vars.push(var.clone());
    }
    Ok((
        average,
        Some(ResonanceObs {
            var: var.name,
            ratios: ratios.get_ref().0.clone(),
            tolerance: tolerance.get_ref().0,
        }),
    ))
}

/// `output.poincare`: the section, its variables and the points kept.
fn poincare(
    p: &Parser,
    ov: &OutVars,
    model: &Model,
    pc: Spanned<Table<tables::Poincare>>,
) -> Result<PoincareObs, SceneError> {
    let span = pc.span();
    let Table(pc) = pc.into_inner();
    other_sections_keys(p, &pc)?;
    let section = match (&pc.period, &pc.crossing) {
        (Some(per), None) => stroboscopic(p, model, &pc, per)?,
        (None, Some(c)) => crossing(p, ov, &pc, c)?,
        _ => {
            return Err(p.err(
                "output.poincare",
                Some(&span),
                "give either period (stroboscopic) or crossing (event section)",
            ))
        }
    };
    let vars = match &pc.vars {
        Some(v) => ov.list(p, "output.poincare.vars", v)?,
        None => ov.defaults(),
    };
    let max_points = pc.max_points.map_or(1000, |m| m.into_inner().0 as usize);
    Ok(PoincareObs {
        section,
        vars,
        max_points,
    })
}

/// Refuses a key of the other kind of section, which would be ignored: a
/// crossing section has no period to phase or skip whole periods of, a
/// stroboscopic one no crossing value or direction.
fn other_sections_keys(p: &Parser, pc: &tables::Poincare) -> Result<(), SceneError> {
    fn span<T>(f: &Option<Spanned<T>>) -> Option<Range<usize>> {
        f.as_ref().map(|s| s.span())
    }
    let (keys, why) = match (&pc.period, &pc.crossing) {
        (None, Some(_)) => (
            [("phase", span(&pc.phase)), ("skip", span(&pc.skip))],
            "belongs to a stroboscopic section (period = T): a crossing section records every crossing from the start of the run; to leave out a transient, drop the first points of poincare_*.npy (poincare_count.npy counts them per trajectory)",
        ),
        (Some(_), None) => (
            [("value", span(&pc.value)), ("direction", span(&pc.direction))],
            "belongs to a crossing section (crossing = \"q\"); a stroboscopic section samples at t0 + phase + k·period",
        ),
        _ => return Ok(()),
    };
    match keys.into_iter().find_map(|(k, s)| s.map(|s| (k, s))) {
        Some((key, s)) => Err(p.err(&format!("output.poincare.{key}"), Some(&s), why)),
        None => Ok(()),
    }
}

/// A stroboscopic section: a period (or each trajectory's forcing period),
/// a phase, and whole periods skipped before it starts.
fn stroboscopic(
    p: &Parser,
    model: &Model,
    pc: &tables::Poincare,
    per: &Spanned<Period>,
) -> Result<Section, SceneError> {
    let skip = pc.skip.as_ref().map_or(0.0, |s| s.get_ref().0);
    check_skip(skip).map_err(|m| {
        p.err(
            "output.poincare.skip",
            pc.skip.as_ref().map(|s| s.span()).as_ref(),
            m,
        )
    })?;
    let period = match per.get_ref() {
        Period::Named(s) if s != "forcing" => {
            return Err(p.err(
                "output.poincare.period",
                Some(&per.span()),
                "expected a number or \"forcing\" (the forcing period 2π/ω of each trajectory)",
            ))
        }
        Period::Named(_) if model.forcing_frequency_param().is_none() => {
            return Err(p.err(
                "output.poincare.period",
                Some(&per.span()),
                format!("model `{}` has no forcing period", model.name()),
            ))
        }
        Period::Named(_) => None,
        Period::Number(x) => Some(*x),
    };
    let phase = pc.phase.as_ref().map_or(0.0, |x| x.get_ref().0) + skip * period.unwrap_or(1.0);
    check_strobe(period.unwrap_or(1.0), phase).map_err(|(f, m)| p.err(&f, Some(&per.span()), m))?;
    Ok(match period {
        None => Section::Forced { skip },
        Some(period) => Section::Stroboscopic { period, phase },
    })
}

/// An event section: where a variable crosses a value, in a direction.
fn crossing(
    p: &Parser,
    ov: &OutVars,
    pc: &tables::Poincare,
    c: &Spanned<Str>,
) -> Result<Section, SceneError> {
    let var = c.get_ref().0.clone();
    ov.one(p, "output.poincare.crossing", &var, &c.span())?;
    let direction = match &pc.direction {
        None => Direction::Up,
        Some(d) => match d.get_ref().0.as_str() {
            "up" => Direction::Up,
            "down" => Direction::Down,
            "both" => Direction::Both,
            o => {
                return Err(p.err(
                    "output.poincare.direction",
                    Some(&d.span()),
                    format!("`{o}` is not up, down or both"),
                ))
            }
        },
    };
    Ok(Section::Crossing {
        var,
        value: pc.value.as_ref().map_or(0.0, |x| x.get_ref().0),
        direction,
    })
}

/// Checks the keys of `table` (and of its inline tables in `nested`),
/// recording every field's span.
fn check_keys(
    p: &mut Parser,
    table: &DeTable,
    name: &str,
    known: &[Key],
    nested: &[(&str, &[Key])],
) -> Result<(), SceneError> {
    for (k, v) in p.entries(table, name, Some(&keys::names(known)))? {
        let inner = nested.iter().find(|(n, _)| *n == k.get_ref().as_ref());
        if let (Some((n, known)), DeValue::Table(t)) = (inner, v.get_ref()) {
            p.entries(t, &format!("{name}.{n}"), Some(&keys::names(known)))?;
        }
    }
    Ok(())
}

/// `[run]`: backend and precision.
fn run(p: &mut Parser, doc: &Doc) -> Result<(BackendChoice, Precision), SceneError> {
    if let Some(t) = doc.table(p, "run")? {
        check_keys(p, t, "run", keys::RUN, &[])?;
    }
    let r: tables::Run = deserialize(p, doc.get("run"))?;
    let backend = parsed(p, "run.backend", &r.backend)?.unwrap_or(BackendChoice::Auto);
    let precision = parsed(p, "run.precision", &r.precision)?.unwrap_or(Precision::F32);
    Ok((backend, precision))
}

/// A string field parsed by `FromStr` (whose message is the error's).
fn parsed<T: std::str::FromStr<Err = String>>(
    p: &Parser,
    field: &str,
    v: &Option<Spanned<Str>>,
) -> Result<Option<T>, SceneError> {
    v.as_ref()
        .map(|s| {
            s.get_ref()
                .0
                .parse()
                .map_err(|m: String| p.err(field, Some(&s.span()), m))
        })
        .transpose()
}

/// `[plot]`: the quick-look pictures' settings.
fn plot(p: &mut Parser, doc: &Doc, model: &Model) -> Result<PlotSettings, SceneError> {
    if let Some(t) = doc.table(p, "plot")? {
        check_keys(
            p,
            t,
            "plot",
            keys::PLOT,
            &[("bifurcation", keys::BIFURCATION)],
        )?;
    }
    let t: tables::Plot = deserialize(p, doc.get("plot"))?;
    let pair =
        |field: &str, v: &Option<Spanned<Strs>>| -> Result<Option<(String, String)>, SceneError> {
            match v {
                None => Ok(None),
                Some(xs) if xs.get_ref().0.len() != 2 => Err(p.err(
                    field,
                    Some(&xs.span()),
                    "expected two variable names [x, y]",
                )),
                Some(xs) => Ok(Some((xs.get_ref().0[0].clone(), xs.get_ref().0[1].clone()))),
            }
        };
    let mut plot = PlotSettings {
        max_trajectories: t.max_trajectories.map_or(64, |m| m.into_inner().0 as usize),
        phase: pair("plot.phase", &t.phase)?,
        poincare: pair("plot.poincare", &t.poincare)?,
        ..PlotSettings::default()
    };
    if let Some(w) = &t.wrap_x {
        if w.get_ref().0 != "2pi" && w.get_ref().0 != "pi" {
            return Err(p.err(
                "plot.wrap_x",
                Some(&w.span()),
                "expected \"2pi\" (wrap into [0, 2π)) or \"pi\" (into [−π, π))",
            ));
        }
        plot.wrap_x = Some(w.get_ref().0.clone());
    }
    if let Some(l) = &t.lienard_plane {
        plot.lienard_plane = l.get_ref().0;
        if plot.lienard_plane && !matches!(model, Model::VanDerPol) {
            return Err(p.err(
                "plot.lienard_plane",
                Some(&l.span()),
                "the Liénard plane is drawn for van_der_pol only",
            ));
        }
    }
    if let Some(b) = t.bifurcation {
        let span = b.span();
        let Table(b) = b.into_inner();
        let need = |n: &str, v: Option<Spanned<Str>>| {
            v.map(|s| s.into_inner().0)
                .ok_or_else(|| p.err(&format!("plot.bifurcation.{n}"), Some(&span), "missing"))
        };
        let axis = need("axis", b.axis)?;
        let var = need("var", b.var)?;
        plot.bifurcation = Some((axis, var));
    }
    Ok(plot)
}

/// `[report]`, if given: what `reeb report` runs.
fn report(
    p: &mut Parser,
    doc: &Doc,
    scheme: &Scheme,
) -> Result<Option<ReportSettings>, SceneError> {
    let Some(t) = doc.table(p, "report")? else {
        return Ok(None);
    };
    check_keys(p, t, "report", keys::REPORT, &[])?;
    let t: tables::Report = deserialize(p, doc.get("report"))?;
    let mut r = ReportSettings::defaults(scheme);
    if let Some(s) = &t.schemes {
        r.schemes = s
            .get_ref()
            .0
            .iter()
            .map(|name| {
                Scheme::by_name(name).ok_or_else(|| {
                    p.err(
                        "report.schemes",
                        Some(&s.span()),
                        format!("unknown scheme `{name}`{}", suggest(name, SCHEME_NAMES)),
                    )
                })
            })
            .collect::<Result<_, _>>()?;
    }
    if let Some(b) = &t.backends {
        r.backends = each(p, "report.backends", b)?;
    }
    if let Some(pr) = &t.precisions {
        r.precisions = each(p, "report.precisions", pr)?;
    }
    if let Some(e) = t.error_vars {
        r.error_vars = e.into_inner().0;
    }
    if let Some(x) = t.reference_rtol {
        r.reference_rtol = x.into_inner().0;
    }
    if let Some(x) = t.distorted {
        r.distorted = x.into_inner().0;
    }
    if let Some(x) = t.targets {
        r.targets = x.into_inner().0;
    }
    Ok(Some(r))
}

/// Every string of a list field parsed by `FromStr` (whose message is the error's).
fn each<T: std::str::FromStr<Err = String>>(
    p: &Parser,
    field: &str,
    v: &Spanned<Strs>,
) -> Result<Vec<T>, SceneError> {
    v.get_ref()
        .0
        .iter()
        .map(|s| {
            s.parse()
                .map_err(|m: String| p.err(field, Some(&v.span()), m))
        })
        .collect()
}

/// The portraits' variables are recorded: `plot.phase` by the trajectory
/// observer, `plot.poincare` by the section (else the picture could not be drawn).
fn check_plot_vars(p: &Parser, plot: &PlotSettings, out: &Out) -> Result<(), SceneError> {
    let components = |vars: &[OutVar]| -> Vec<String> {
        vars.iter().flat_map(|v| v.components.clone()).collect()
    };
    let checks = [
        (
            "plot.phase",
            &plot.phase,
            "output.trajectory",
            out.observers
                .trajectory
                .as_ref()
                .map(|t| components(&t.vars)),
        ),
        (
            "plot.poincare",
            &plot.poincare,
            "output.poincare",
            out.observers.poincare.as_ref().map(|p| components(&p.vars)),
        ),
    ];
    for (field, pair, observer, recorded) in checks {
        let Some((x, y)) = pair else { continue };
        let Some(recorded) = recorded else {
            return Err(p.err(
                field,
                p.span_of(field),
                format!("draws {observer}, which this scene does not record"),
            ));
        };
        // An observer that records nothing is refused by the plan, by name.
        if recorded.is_empty() {
            continue;
        }
        if let Some(missing) = [x, y].into_iter().find(|v| !recorded.contains(v)) {
            return Err(p.err(
                field,
                p.span_of(field),
                format!(
                    "`{missing}` is not recorded by {observer}; it records: {}",
                    recorded.join(", ")
                ),
            ));
        }
    }
    Ok(())
}

/// The bifurcation diagram's axis is an axis of the scene, and there is a
/// Poincaré section to draw it from.
fn check_bifurcation(
    p: &Parser,
    plot: &PlotSettings,
    axes: &[SceneAxis],
    has_section: bool,
) -> Result<(), SceneError> {
    let Some((axis, _)) = &plot.bifurcation else {
        return Ok(());
    };
    if !axes.iter().any(|a| &a.name == axis) {
        return Err(p.err(
            "plot.bifurcation.axis",
            p.span_of("plot.bifurcation"),
            format!(
                "`{axis}` is not an axis of this scene; its axes are: {}",
                axes.iter()
                    .map(|a| a.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ));
    }
    if !has_section {
        return Err(p.err(
            "plot.bifurcation",
            p.span_of("plot.bifurcation"),
            "needs an output.poincare section",
        ));
    }
    Ok(())
}
