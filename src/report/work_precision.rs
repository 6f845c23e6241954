//! The work–precision report: for every scheme × backend × precision of the
//! scene's `[report]` table and every `dt` of its axis, the error against the
//! reference (closed form, or DOP853 at tight tolerance) and the integration
//! time; the reference integrator itself as a point. Written as
//! `work_precision.csv`, diagrams, and report.md with the measured orders
//! and the fastest configuration per error target.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use anyhow::{bail, Context, Result};

use crate::backend::BackendChoice;
use crate::backend::Engine;
use crate::num::precision::Precision;
use crate::output::plot::{self, Figure, Series, Slope};
use crate::plan::observations::Observations;
use crate::plan::observers::TrajectoryObs;
use crate::plan::scheme::Scheme;
use crate::plan::Plan;
use crate::reference::truth::{dop853_of, truth, Truth};
use crate::scene::{Horizon, ReportSettings, Scene, SubRun};

use super::options::{claim_dir, finish, precisions, settings, ReportOptions};

/// One measured point of a work–precision diagram.
#[derive(Debug, Clone)]
pub struct Row {
    pub scheme: String,
    pub backend: String,
    pub precision: String,
    pub dt: f64,
    pub steps: u64,
    /// Flow (or right-hand-side) evaluations per trajectory over the run.
    pub evaluations: u64,
    pub error_max: f64,
    pub error_rel: f64,
    /// Integration time of the whole run (`trajectories` of them).
    pub seconds: f64,
    pub traj_steps_per_s: f64,
    pub trajectories: usize,
}

impl Row {
    /// Time per trajectory: comparable between ensembles and the reference.
    pub fn seconds_per_trajectory(&self) -> f64 {
        self.seconds / self.trajectories.max(1) as f64
    }
}

/// Timed runs repeat the scene's ensemble to about this many
/// trajectory-steps, with between `MIN_TRAJECTORIES` and `MAX_TRAJECTORIES`
/// trajectories, so that timings measure throughput, not overheads.
const TIMING_WORK: f64 = 2e7;
const MIN_TRAJECTORIES: usize = 128;
const MAX_TRAJECTORIES: usize = 4096;

/// The regularised relative error of seed 000: `(10 + x*)/(10 + x) − 1`.
fn rel_error(approx: f64, exact: f64) -> f64 {
    (10.0 + approx) / (10.0 + exact) - 1.0
}

fn finite_or_inf(x: f64) -> f64 {
    if x.is_finite() {
        x
    } else {
        f64::INFINITY
    }
}

/// A named curve of a picture: legend key, x, y.
type Curve = (String, Vec<f64>, Vec<f64>);

/// Runs the work–precision report of `scene`; returns the path of report.md.
pub fn work_precision(scene: &Scene, opts: &ReportOptions) -> Result<PathBuf> {
    let set = settings(scene);
    let claim = claim_dir(scene, opts, "work-precision")?;
    let out = claim.dir().to_path_buf();
    let error_vars = error_vars(scene, &set)?;
    let base = measured_scene(scene, &error_vars);
    let engines = engines(opts, &set);
    let precisions = precisions(scene, opts, &set)?;
    let stop = opts.stop.as_deref();
    let measured = measure_schemes(&base, &set, &engines, &precisions, &error_vars, stop)?;
    let mut rows = measured.rows;

    // The reference integrator as points of the same diagram, on the first plan.
    let first = base.sub_runs()?.into_iter().next().context("no plan")?;
    let times = first.plan.output_times(0);
    let truth0 = truth(&first.plan, 0, &times, set.reference_rtol)?;
    let reference_error = reference_error(&first.plan, &times, &truth0, set.reference_rtol)?;
    rows.extend(dop853_rows(&first.plan, &times, &truth0, &error_vars));

    write_csv(&out.join("work_precision.csv"), &rows)?;

    let title = scene.title.clone().unwrap_or_else(|| scene.name.clone());
    let groups = by_configuration(&rows);
    let (orders_md, slope_lines) = fit_orders(&groups, &set.schemes, reference_error)?;
    let (series_t, series_dt) = diagram_series(&groups);
    let panels = panels(&rows, set.schemes.len());
    let mut pictures = draw_diagrams(&out, &title, &panels, &series_t, &series_dt, &slope_lines)?;
    if !measured.over_time.is_empty() {
        let first_p = distinct(&rows, |r| &r.precision)
            .first()
            .cloned()
            .unwrap_or_default();
        draw_error_over_time(&out, &title, &measured.over_time, &first_p)?;
        pictures.push("error_vs_time.png".into());
    }

    let mut md = String::new();
    let over = if base.observers.trajectory.is_some() {
        ""
    } else {
        " (the final time)"
    };
    describe(
        &mut md,
        scene,
        &title,
        &measured.ref_method,
        over,
        &error_vars,
    );
    for pic in &pictures {
        let _ = writeln!(md, "![{pic}]({pic})\n");
    }
    let _ = writeln!(md, "## Measured order\n\nSlope of log error against log dt over the last four points between 10⁻² and the floor (10⁴ unit roundoffs, or 100× the reference's estimated error, {reference_error:.1e}).\n\n| configuration | nominal | measured | points |\n|---|---|---|---|\n{orders_md}");
    fastest_per_target(&mut md, &rows, &set.targets, time_span(scene, &first.plan));
    let _ = writeln!(md, "\nAll points: `work_precision.csv`.");
    let md_path = out.join("report.md");
    std::fs::write(&md_path, md).with_context(|| format!("writing {}", md_path.display()))?;
    finish(claim, scene, "work-precision", "report.md")
}

// ---------------------------------------------------------------------------
// What is measured, and on what
// ---------------------------------------------------------------------------

/// The variables whose error is measured: the report's `error_vars` (a
/// recorded vector variable stands for its components), or else every
/// recorded final variable but time.
fn error_vars(scene: &Scene, set: &ReportSettings) -> Result<Vec<String>> {
    let error_vars: Vec<String> = if set.error_vars.is_empty() {
        scene
            .observers
            .final_vars
            .iter()
            .flat_map(|v| v.components.clone())
            .filter(|v| v != "t")
            .collect()
    } else {
        set.error_vars
            .iter()
            .flat_map(|n| {
                scene
                    .observers
                    .final_vars
                    .iter()
                    .find(|v| &v.name == n)
                    .map(|v| v.components.clone())
                    .unwrap_or_else(|| vec![n.clone()])
            })
            .collect()
    };
    if error_vars.is_empty() {
        bail!(
            "{}: no variable to measure the error of (set report.error_vars)",
            scene.path.display()
        );
    }
    Ok(error_vars)
}

/// The scene as the report runs it: it records exactly the variables whose
/// error is measured (at the scene's output times, if it records a
/// trajectory), and nothing else.
fn measured_scene(scene: &Scene, error_vars: &[String]) -> Scene {
    let mut base = scene.clone();
    base.observers.final_vars = error_vars.iter().map(|v| v.as_str().into()).collect();
    base.observers.trajectory = scene.observers.trajectory.as_ref().map(|t| TrajectoryObs {
        every: t.every,
        vars: base.observers.final_vars.clone(),
    });
    base.observers.poincare = None;
    base.observers.cycle = None;
    base
}

/// The engines of the backends to run (the one asked for on the command
/// line, or the scene's); a backend that is not available here is skipped
/// with a note, so a report on a machine without a GPU still comes out.
fn engines(opts: &ReportOptions, set: &ReportSettings) -> Vec<(BackendChoice, Engine)> {
    let backends: Vec<BackendChoice> = match opts.backend {
        Some(b) => vec![b],
        None => set.backends.clone(),
    };
    let mut engines: Vec<(BackendChoice, Engine)> = vec![];
    for b in &backends {
        match Engine::resolve(*b, Precision::F32) {
            Ok((e, notice)) => {
                if let Some(n) = notice {
                    eprintln!("{n}");
                }
                engines.push((*b, e));
            }
            Err(e) => eprintln!("note: skipping backend {b:?}: {e:#}"),
        }
    }
    engines
}

/// Every (engine, precision) pair that can run: a GPU without f64 shaders
/// runs f32 only.
fn configurations<'a>(
    engines: &'a [(BackendChoice, Engine)],
    precisions: &[Precision],
) -> Vec<(&'a Engine, Precision)> {
    let mut out = vec![];
    for (_, engine) in engines {
        for p in precisions {
            if engine.runs(*p) {
                out.push((engine, *p));
            }
        }
    }
    out
}

/// The scheme and the scene's runs with it, one per step of the `dt` axis;
/// `None`, with a note, where the scheme cannot run the scene.
fn scheme_runs(base: &Scene, scheme: &Scheme) -> Result<Option<(Scheme, Vec<SubRun>)>> {
    let mut sc = base.clone();
    sc.scheme = scheme.clone();
    // The scene's piece order is for its splitting schemes.
    if !scheme.is_splitting() {
        sc.order = None;
    }
    match sc.sub_runs() {
        Ok(subs) => Ok(Some((scheme.clone(), subs))),
        Err(e) => {
            eprintln!("note: skipping {scheme}: {e}");
            Ok(None)
        }
    }
}

// ---------------------------------------------------------------------------
// The measurements
// ---------------------------------------------------------------------------

/// The measured points of the schemes, and what the pictures and report.md
/// need besides.
#[derive(Default)]
struct Measured {
    rows: Vec<Row>,
    /// How the references were obtained (the last one computed).
    ref_method: String,
    /// Error over time at the middle step of each configuration.
    over_time: Vec<Curve>,
}

/// One row per (scheme, backend, precision, dt), in that order of loops.
fn measure_schemes(
    base: &Scene,
    set: &ReportSettings,
    engines: &[(BackendChoice, Engine)],
    precisions: &[Precision],
    error_vars: &[String],
    stop: Option<&AtomicBool>,
) -> Result<Measured> {
    let tty = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let mut m = Measured::default();
    let mut references = References::new(set.reference_rtol);
    for scheme in &set.schemes {
        let Some((s, subs)) = scheme_runs(base, scheme)? else {
            continue;
        };
        let mid = subs.len() / 2;
        for (engine, p) in configurations(engines, precisions) {
            for (k, sub) in subs.iter().enumerate() {
                let (row, per_time) =
                    measure(&s, engine, p, sub, &mut references, error_vars, stop)?;
                let label = format!("{scheme} {} {p}", engine.name());
                if k == mid && per_time.len() > 1 {
                    m.over_time
                        .push((label.clone(), sub.plan.output_times(0), per_time));
                }
                let (dt, emax) = (row.dt, row.error_max);
                m.rows.push(row);
                if tty {
                    eprint!("\r{label}: dt {dt:.3e}, error {emax:.3e}          ");
                }
            }
        }
    }
    if tty {
        eprintln!();
    }
    m.ref_method = references.method;
    Ok(m)
}

/// Copies of a step's ensemble to time: enough work to time (≈ 2·10⁷
/// trajectory-steps, at least two threads' blocks), no more than needed.
fn timing_copies(plan: &Plan) -> usize {
    let want = (TIMING_WORK / plan.steps.max(1) as f64).ceil() as usize;
    want.clamp(MIN_TRAJECTORIES, MAX_TRAJECTORIES)
        .div_ceil(plan.n)
        .max(1)
}

/// One point of the diagram: the step's ensemble, replicated to a timeable
/// size, run and timed, and its error against the reference; with the error
/// at each output time, for the picture of error over time.
fn measure(
    s: &Scheme,
    engine: &Engine,
    p: Precision,
    sub: &SubRun,
    references: &mut References,
    error_vars: &[String],
    stop: Option<&AtomicBool>,
) -> Result<(Row, Vec<f64>)> {
    let copies = timing_copies(&sub.plan);
    let plan = sub.plan.replicated(copies);
    let (obs, seconds) = engine.run_f64_until(&plan, p, stop)?;
    let mut err = Errors::default();
    for j in 0..sub.plan.n {
        let times = sub.plan.output_times(j);
        let reference = references.of(sub, j, &times)?;
        // The first copy of trajectory j in the replicated run.
        let g = j * copies;
        for (f, refv) in reference.values.iter().enumerate() {
            err.add_frame(&sub.plan, &obs, g, f, refv, error_vars);
        }
    }
    let dt = sub.plan.binding("dt").value_at(0, &sub.plan.strides);
    let row = Row {
        scheme: s.name.clone(),
        backend: engine.name().into(),
        precision: p.name().into(),
        dt,
        steps: sub.plan.steps,
        evaluations: sub.plan.steps * s.evaluations() as u64,
        error_max: err.max,
        error_rel: err.rel,
        seconds,
        traj_steps_per_s: plan.traj_steps() as f64 / seconds.max(1e-12),
        trajectories: plan.n,
    };
    Ok((row, err.per_time))
}

/// The reference solutions, computed once per (fixed axes, trajectory,
/// output times, variables): the schemes, engines and precisions share them.
struct References {
    rtol: f64,
    known: HashMap<String, Truth>,
    /// How the last one computed was obtained.
    method: String,
}

impl References {
    fn new(rtol: f64) -> Self {
        Self {
            rtol,
            known: HashMap::new(),
            method: String::new(),
        }
    }

    /// The reference of trajectory `j` of the step's plan at `times`.
    fn of(&mut self, sub: &SubRun, j: usize, times: &[f64]) -> Result<&Truth> {
        let key = format!("{:?}|{j}|{}|{:?}", sub.fixed, times.len(), sub.plan.vars);
        if !self.known.contains_key(&key) {
            let t = truth(&sub.plan, j, times, self.rtol)?;
            self.method = t.method.clone();
            self.known.insert(key.clone(), t);
        }
        Ok(&self.known[&key])
    }
}

/// The largest errors of a run against the reference, over the output
/// times, the trajectories and the variables.
#[derive(Default)]
struct Errors {
    /// max |x − x_ref|.
    max: f64,
    /// The largest regularised relative error.
    rel: f64,
    /// max |x − x_ref| at each output time.
    per_time: Vec<f64>,
}

impl Errors {
    /// Folds in output time `f` of trajectory `g` of the run, whose reference
    /// values (every variable of the plan) are `refv`.
    fn add_frame(
        &mut self,
        plan: &Plan,
        obs: &Observations<f64>,
        g: usize,
        f: usize,
        refv: &[f64],
        error_vars: &[String],
    ) {
        let mut at_t = 0.0f64;
        for v in error_vars {
            let Some(vi) = plan.vars.iter().position(|x| x == v) else {
                continue;
            };
            // Scenes that record no trajectory have one output time: the final.
            let x = match obs.trajectory_of(v) {
                Some(tr) => tr[g * obs.frames + f],
                None => obs.final_of(v).map_or(f64::NAN, |a| a[g]),
            };
            let e = finite_or_inf((x - refv[vi]).abs());
            at_t = at_t.max(e);
            self.max = self.max.max(e);
            self.rel = self.rel.max(finite_or_inf(rel_error(x, refv[vi]).abs()));
        }
        if self.per_time.len() <= f {
            self.per_time.push(0.0);
        }
        self.per_time[f] = self.per_time[f].max(at_t);
    }
}

// ---------------------------------------------------------------------------
// The reference integrator
// ---------------------------------------------------------------------------

/// The reference's own error, estimated from a 100× looser run (DOP853's
/// error is about proportional to its tolerance): slopes are fitted only
/// well above it. Zero for closed forms.
fn reference_error(plan: &Plan, times: &[f64], truth0: &Truth, rtol: f64) -> Result<f64> {
    if truth0.evaluations == 0 {
        return Ok(0.0);
    }
    let loose = truth(plan, 0, times, rtol * 100.0)?;
    Ok(loose
        .values
        .iter()
        .zip(&truth0.values)
        .flat_map(|(x, y)| x.iter().zip(y).map(|(u, v)| (u - v).abs()))
        .fold(0.0f64, f64::max)
        / 100.0)
}

/// The reference integrator as points of the same diagram: DOP853 at
/// several tolerances against the closed form or a 1000× tighter run.
fn dop853_rows(plan: &Plan, times: &[f64], truth0: &Truth, error_vars: &[String]) -> Vec<Row> {
    let mut rows = vec![];
    for rtol in [1e-4, 1e-6, 1e-8, 1e-10] {
        let d = match dop853_of(plan, 0, times, rtol) {
            Ok(d) => d,
            Err(e) => {
                eprintln!("note: DOP853 at rtol {rtol:e}: {e:#}");
                continue;
            }
        };
        let (mut emax, mut erel) = (0.0f64, 0.0f64);
        for (a, b) in d.values.iter().zip(&truth0.values) {
            for v in error_vars {
                if let Some(vi) = plan.vars.iter().position(|x| x == v) {
                    emax = emax.max(finite_or_inf((a[vi] - b[vi]).abs()));
                    erel = erel.max(finite_or_inf(rel_error(a[vi], b[vi]).abs()));
                }
            }
        }
        let span =
            times.last().copied().unwrap_or(0.0) - plan.binding("t0").value_at(0, &plan.strides);
        // DOP853 takes 12 evaluations per accepted step.
        let steps = (d.evaluations / 12).max(1);
        rows.push(Row {
            scheme: format!("dop853 rtol {rtol:e}"),
            backend: "cpu".into(),
            precision: "f64".into(),
            dt: span / steps as f64,
            steps,
            evaluations: d.evaluations,
            error_max: emax,
            error_rel: erel,
            seconds: d.seconds,
            traj_steps_per_s: steps as f64 / d.seconds.max(1e-12),
            trajectories: 1,
        });
    }
    rows
}

// ---------------------------------------------------------------------------
// The CSV
// ---------------------------------------------------------------------------

/// Every point, one line each.
fn write_csv(path: &Path, rows: &[Row]) -> Result<()> {
    let mut w = csv::Writer::from_path(path)?;
    w.write_record([
        "scheme",
        "backend",
        "precision",
        "dt",
        "steps",
        "evaluations",
        "error_max",
        "error_rel",
        "seconds",
        "traj_steps_per_s",
        "trajectories",
    ])?;
    for r in rows {
        w.write_record([
            r.scheme.clone(),
            r.backend.clone(),
            r.precision.clone(),
            format!("{:e}", r.dt),
            r.steps.to_string(),
            r.evaluations.to_string(),
            format!("{:e}", r.error_max),
            format!("{:e}", r.error_rel),
            format!("{:e}", r.seconds),
            format!("{:e}", r.traj_steps_per_s),
            r.trajectories.to_string(),
        ])?;
    }
    w.flush()?;
    Ok(())
}

// ---------------------------------------------------------------------------
// Orders and pictures
// ---------------------------------------------------------------------------

/// The rows of one configuration ("scheme backend precision"), under its key.
type Group<'a> = (String, Vec<&'a Row>);

/// The rows per configuration, in the order they were measured; the
/// reference's tolerances form one group.
fn by_configuration(rows: &[Row]) -> Vec<Group<'_>> {
    let mut groups: Vec<Group> = vec![];
    for r in rows {
        let key = if r.scheme.starts_with("dop853") {
            "dop853 (reference, adaptive)".to_string()
        } else {
            format!("{} {} {}", r.scheme, r.backend, r.precision)
        };
        match groups.iter_mut().find(|(k, _)| *k == key) {
            Some((_, v)) => v.push(r),
            None => groups.push((key, vec![r])),
        }
    }
    groups
}

/// The measured order of each scheme configuration, as rows of report.md's
/// table; and a reference slope of the nominal order (one per distinct
/// order) for the picture of error against dt.
fn fit_orders(
    groups: &[Group],
    schemes: &[Scheme],
    reference_error: f64,
) -> Result<(String, Vec<Slope>)> {
    let mut table = String::new();
    let mut lines: Vec<Slope> = vec![];
    for (key, rs) in groups {
        if key.starts_with("dop853") {
            continue;
        }
        let scheme = schemes
            .iter()
            .find(|s| s.name == rs[0].scheme)
            .context("a measured scheme of the settings")?;
        // Unit roundoff of the precision: the error floor is 10⁴ of it.
        let u = if rs[0].precision == "f32" {
            f32::EPSILON as f64 / 2.0
        } else {
            f64::EPSILON / 2.0
        };
        match slope(rs, (1e4 * u).max(100.0 * reference_error), 1e-2) {
            Some((m, n)) => {
                let _ = writeln!(table, "| {key} | {} | {m:.2} | {n} |", scheme.order);
                if let Some(r) = rs
                    .iter()
                    .find(|r| r.error_max.is_finite() && r.error_max > 1e4 * u)
                {
                    lines.push(Slope {
                        slope: scheme.order as f64,
                        anchor: (r.dt, r.error_max),
                        label: format!("slope {}", scheme.order),
                    });
                }
            }
            None => {
                let _ = writeln!(
                    table,
                    "| {key} | {} | – | too few points between the floor and 10⁻² |",
                    scheme.order
                );
            }
        }
    }
    lines.dedup_by(|a, b| a.slope == b.slope);
    Ok((table, lines))
}

/// Least-squares slope of log error against log dt over the last four points
/// (smallest steps) with error in [floor, ceiling], stopping at roundoff.
fn slope(rows: &[&Row], floor: f64, ceiling: f64) -> Option<(f64, usize)> {
    let mut pts: Vec<(f64, f64)> = rows.iter().map(|r| (r.dt, r.error_max)).collect();
    pts.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut kept = vec![];
    let mut last = f64::INFINITY;
    for (dt, e) in pts {
        if !e.is_finite() || e > ceiling {
            continue;
        }
        if e < floor || e > last {
            break;
        }
        kept.push((dt.ln(), e.ln()));
        last = e;
    }
    let kept = &kept[kept.len().saturating_sub(4)..];
    if kept.len() < 3 {
        return None;
    }
    let n = kept.len() as f64;
    let (mx, my) = (
        kept.iter().map(|p| p.0).sum::<f64>() / n,
        kept.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = kept.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = kept.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    Some((sxy / sxx, kept.len()))
}

/// The curves of the diagrams: error against time per trajectory (every
/// configuration, the reference included) and error against dt (the schemes).
fn diagram_series(groups: &[Group]) -> (Vec<Curve>, Vec<Curve>) {
    let mut series_t: Vec<Curve> = vec![];
    let mut series_dt: Vec<Curve> = vec![];
    for (key, rs) in groups {
        series_t.push((
            key.clone(),
            rs.iter().map(|r| r.seconds_per_trajectory()).collect(),
            rs.iter().map(|r| r.error_max).collect(),
        ));
        if key.starts_with("dop853") {
            continue;
        }
        series_dt.push((
            key.clone(),
            rs.iter().map(|r| r.dt).collect(),
            rs.iter().map(|r| r.error_max).collect(),
        ));
    }
    (series_t, series_dt)
}

/// The distinct values of one column over the schemes' rows, sorted.
fn distinct(rows: &[Row], column: fn(&Row) -> &String) -> Vec<String> {
    let mut v: Vec<String> = rows
        .iter()
        .filter(|r| !r.scheme.starts_with("dop853"))
        .map(|r| column(r).clone())
        .collect();
    v.sort();
    v.dedup();
    v
}

/// One pair of diagrams: the precision, the backends in it, the file suffix.
type Panel = (String, Vec<String>, String);

/// The panels: one per precision with every backend in it (so a GPU and a
/// CPU run share a plot), split per backend where that would need more than
/// twelve lines.
fn panels(rows: &[Row], schemes: usize) -> Vec<Panel> {
    let backends_run = distinct(rows, |r| &r.backend);
    let mut panels: Vec<Panel> = vec![];
    for p in &distinct(rows, |r| &r.precision) {
        let lines = schemes * backends_run.len();
        if lines <= 11 {
            panels.push((p.clone(), backends_run.clone(), p.clone()));
        } else {
            for b in &backends_run {
                panels.push((p.clone(), vec![b.clone()], format!("{b}_{p}")));
            }
        }
    }
    panels
}

/// The series of `all` whose legend key passes `keep`, borrowed for plotting.
fn pick<'a>(all: &'a [Curve], keep: &dyn Fn(&str) -> bool) -> Vec<Series<'a>> {
    all.iter()
        .filter(|(n, _, _)| keep(n))
        .map(|(n, x, y)| Series::new(n, x, y))
        .collect()
}

/// Error against time and against dt for each panel (the reference in
/// each); the first panel's are also `work_precision.png` /
/// `error_vs_dt.png`. Returns the file names.
fn draw_diagrams(
    out: &Path,
    title: &str,
    panels: &[Panel],
    series_t: &[Curve],
    series_dt: &[Curve],
    slope_lines: &[Slope],
) -> Result<Vec<String>> {
    let mut pictures: Vec<String> = vec![];
    for (k, (p, bs, suffix)) in panels.iter().enumerate() {
        let keep = |key: &str| {
            key.starts_with("dop853") || bs.iter().any(|b| key.ends_with(&format!(" {b} {p}")))
        };
        let (st, sd) = (pick(series_t, &keep), pick(series_dt, &keep));
        let t = format!("{title} ({})", suffix.replace('_', " "));
        let wp = format!("work_precision_{suffix}.png");
        let ed = format!("error_vs_dt_{suffix}.png");
        let x_t = "integration time per trajectory [s]";
        draw_error_against(&out.join(&wp), &t, x_t, &st, &[])?;
        draw_error_against(&out.join(&ed), &t, "dt", &sd, slope_lines)?;
        if k == 0 {
            std::fs::copy(out.join(&wp), out.join("work_precision.png"))?;
            std::fs::copy(out.join(&ed), out.join("error_vs_dt.png"))?;
        }
        pictures.push(wp);
        pictures.push(ed);
    }
    Ok(pictures)
}

/// A log–log diagram of max error against `x_label`.
fn draw_error_against(
    path: &Path,
    title: &str,
    x_label: &str,
    series: &[Series],
    slopes: &[Slope],
) -> Result<()> {
    let fig = Figure {
        title,
        x_label,
        y_label: "max error",
        ..Figure::default()
    };
    plot::loglog(path, &fig, series, slopes)?;
    Ok(())
}

/// `error_vs_time.png`: the error over time at the middle dt of each scheme,
/// in the first precision run; at most eleven lines, so they keep a legend.
fn draw_error_over_time(out: &Path, title: &str, over_time: &[Curve], first_p: &str) -> Result<()> {
    let s_o: Vec<Series> = over_time
        .iter()
        .filter(|(n, _, _)| n.ends_with(first_p))
        .take(11)
        .map(|(n, x, y)| Series::new(n, x, y))
        .collect();
    plot::lines(
        &out.join("error_vs_time.png"),
        &Figure {
            title,
            x_label: "t",
            y_label: "max error at t (middle dt of each scheme)",
            ..Figure::default()
        },
        &s_o,
        false,
        true,
    )?;
    Ok(())
}

// ---------------------------------------------------------------------------
// report.md
// ---------------------------------------------------------------------------

/// The title and what was measured, how: report.md's opening paragraph.
fn describe(
    md: &mut String,
    scene: &Scene,
    title: &str,
    ref_method: &str,
    over: &str,
    error_vars: &[String],
) {
    let _ = writeln!(md, "# Work–precision: {title}\n");
    let _ = writeln!(md, "Scene `{}` (model `{}`), reeb {}. Reference: {ref_method}. Errors are the maximum over the output times{}, the trajectories and the variables {} of |x − x_ref|; times are the integration alone, per trajectory, measured on ensembles of {MIN_TRAJECTORIES} to {MAX_TRAJECTORIES} trajectories (the scene's, repeated to about {TIMING_WORK:e} trajectory-steps; the reference DOP853 runs one trajectory at a time).\n", scene.path.display(), scene.model.name(), env!("CARGO_PKG_VERSION"), over, error_vars.join(", "));
}

/// The time the scene integrates over, per unit of which report.md counts
/// evaluations.
fn time_span(scene: &Scene, plan: &Plan) -> f64 {
    match scene.horizon {
        Horizon::TEnd(t) => t - plan.binding("t0").value_at(0, &plan.strides),
        Horizon::Steps(_) => plan.steps as f64 * plan.binding("dt").value_at(0, &plan.strides),
    }
}

/// The table of the fastest configuration per error target: the row (of
/// any configuration, the reference's included) that reaches the target in
/// the least time per trajectory.
fn fastest_per_target(md: &mut String, rows: &[Row], targets: &[f64], span: f64) {
    let _ = writeln!(md, "## Fastest configuration for an error target\n\n| target | configuration | dt | error | seconds per trajectory | evaluations per unit time |\n|---|---|---|---|---|---|");
    for target in targets {
        let best = rows
            .iter()
            .filter(|r| r.error_max <= *target)
            .min_by(|a, b| {
                a.seconds_per_trajectory()
                    .total_cmp(&b.seconds_per_trajectory())
            });
        match best {
            Some(r) => {
                let _ = writeln!(
                    md,
                    "| {target:e} | {} {} {} | {:.3e} | {:.2e} | {:.3e} | {:.3e} |",
                    r.scheme,
                    r.backend,
                    r.precision,
                    r.dt,
                    r.error_max,
                    r.seconds_per_trajectory(),
                    r.evaluations as f64 / span.max(1e-300)
                );
            }
            None => {
                let _ = writeln!(md, "| {target:e} | none reached it | | | | |");
            }
        }
    }
}
