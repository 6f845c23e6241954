//! `reeb report`: which method, which step, which backend gives an accuracy
//! fastest, and where does each method break.
//!
//! * `work-precision`: for every scheme × backend × precision of the scene's
//!   `[report]` table and every `dt` of its axis, the error against the
//!   reference (closed form, or DOP853 at tight tolerance) and the integration
//!   time; the reference integrator itself as a point.
//! * `stability`: over a 2-D grid (typically ε × τ) every cell classified as
//!   accurate, distorted (cycle amplitude or period off by more than a
//!   threshold from the reference's) or diverged (non-finite).

use std::collections::HashMap;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use crate::backend::BackendChoice;
use crate::backend::Engine;
use crate::num::precision::Precision;
use crate::output::plot::{self, Figure, Series, Slope};
use crate::plan::observers::CycleObs;
use crate::plan::scheme::Scheme;
use crate::plan::Plan;
use crate::reference::truth::{dop853_of, lane_of, truth, Truth};
use crate::scene::{Horizon, OutVar, ReportSettings, Scene};

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

/// Options of `reeb report`.
#[derive(Debug, Clone, Default)]
pub struct ReportOptions {
    pub out: Option<PathBuf>,
    /// Restrict the scene's backends / precisions.
    pub backend: Option<BackendChoice>,
    pub precision: Option<Precision>,
}

fn settings(scene: &Scene) -> ReportSettings {
    scene
        .report
        .clone()
        .unwrap_or_else(|| ReportSettings::defaults(&scene.scheme))
}

fn out_dir(scene: &Scene, opts: &ReportOptions, what: &str) -> Result<PathBuf> {
    let out = opts
        .out
        .clone()
        .unwrap_or_else(|| Path::new("runs").join(format!("{}-{what}", scene.name)));
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    Ok(out)
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

/// Runs the work–precision report of `scene`; returns the path of report.md.
pub fn work_precision(scene: &Scene, opts: &ReportOptions) -> Result<PathBuf> {
    let set = settings(scene);
    let out = out_dir(scene, opts, "work-precision")?;
    // The report's scenes record exactly the variables whose error is measured.
    let error_vars: Vec<String> = if set.error_vars.is_empty() {
        scene
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
    let mut base = scene.clone();
    base.final_vars = error_vars
        .iter()
        .map(|v| OutVar {
            name: v.clone(),
            components: vec![v.clone()],
        })
        .collect();
    base.trajectory = scene
        .trajectory
        .as_ref()
        .map(|(every, _)| (*every, base.final_vars.clone()));
    base.poincare = None;
    base.cycle = None;

    let backends: Vec<BackendChoice> = match opts.backend {
        Some(b) => vec![b],
        None => set.backends.clone(),
    };
    let precisions: Vec<Precision> = match opts.precision {
        Some(p) => vec![p],
        None => set.precisions.clone(),
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

    let tty = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let mut rows: Vec<Row> = vec![];
    let mut references: HashMap<String, Truth> = HashMap::new();
    let mut ref_method = String::new();
    // Error over time at one step size per scheme, for the picture.
    let mut over_time: Vec<(String, Vec<f64>, Vec<f64>)> = vec![];
    for scheme in &set.schemes {
        let mut sc = base.clone();
        sc.scheme = scheme.clone();
        let s = Scheme::by_name(scheme).context("scheme")?;
        let subs = match sc.sub_runs() {
            Ok(s) => s,
            Err(e) => {
                eprintln!("note: skipping {scheme}: {e}");
                continue;
            }
        };
        let mid = subs.len() / 2;
        for (_, engine) in &engines {
            for p in &precisions {
                if let (Engine::Gpu(ctx), Precision::F64) = (engine, p) {
                    if !ctx.shader_f64 {
                        continue;
                    }
                }
                for (k, sub) in subs.iter().enumerate() {
                    let n0 = sub.plan.n;
                    // Enough work to time (≈ 2·10⁷ trajectory-steps, at
                    // least two threads' blocks), no more than needed.
                    let want = (TIMING_WORK / sub.plan.steps.max(1) as f64).ceil() as usize;
                    let copies = want
                        .clamp(MIN_TRAJECTORIES, MAX_TRAJECTORIES)
                        .div_ceil(n0)
                        .max(1);
                    let plan = sub.plan.replicated(copies);
                    let (obs, seconds) = engine.run_f64(&plan, *p)?;
                    let (mut emax, mut erel) = (0.0f64, 0.0f64);
                    let mut per_time: Vec<f64> = vec![];
                    for j in 0..n0 {
                        let times = sub.plan.output_times(j);
                        let key =
                            format!("{:?}|{j}|{}|{:?}", sub.fixed, times.len(), sub.plan.vars);
                        if !references.contains_key(&key) {
                            let t = truth(&sub.plan, j, &times, set.reference_rtol)?;
                            ref_method = t.method.clone();
                            references.insert(key.clone(), t);
                        }
                        let reference = &references[&key];
                        let g = j * copies;
                        for (f, refv) in reference.values.iter().enumerate() {
                            let mut at_t = 0.0f64;
                            for v in &error_vars {
                                let Some(vi) = sub.plan.vars.iter().position(|x| x == v) else {
                                    continue;
                                };
                                let x = match obs.trajectory_of(v) {
                                    Some(tr) => tr[g * obs.frames + f],
                                    None => obs.final_of(v).map_or(f64::NAN, |a| a[g]),
                                };
                                let e = finite_or_inf((x - refv[vi]).abs());
                                at_t = at_t.max(e);
                                emax = emax.max(e);
                                erel = erel.max(finite_or_inf(rel_error(x, refv[vi]).abs()));
                            }
                            if per_time.len() <= f {
                                per_time.push(0.0);
                            }
                            per_time[f] = per_time[f].max(at_t);
                        }
                    }
                    let label = format!("{scheme} {} {p}", engine.name());
                    if k == mid && per_time.len() > 1 {
                        over_time.push((label.clone(), sub.plan.output_times(0), per_time));
                    }
                    let dt = sub.plan.binding("dt").value_at(0, &sub.plan.strides);
                    rows.push(Row {
                        scheme: scheme.clone(),
                        backend: engine.name().into(),
                        precision: p.name().into(),
                        dt,
                        steps: sub.plan.steps,
                        evaluations: sub.plan.steps * s.evaluations() as u64,
                        error_max: emax,
                        error_rel: erel,
                        seconds,
                        traj_steps_per_s: plan.traj_steps() as f64 / seconds.max(1e-12),
                        trajectories: plan.n,
                    });
                    if tty {
                        eprint!("\r{label}: dt {dt:.3e}, error {emax:.3e}          ");
                    }
                }
            }
        }
    }
    if tty {
        eprintln!();
    }

    // The reference integrator as points of the same diagram: DOP853 at
    // several tolerances against the closed form or a 1000× tighter run.
    let first = base.sub_runs()?.into_iter().next().context("no plan")?;
    let times = first.plan.output_times(0);
    let truth0 = truth(&first.plan, 0, &times, set.reference_rtol)?;
    // The reference's own error, estimated from a 100× looser run (DOP853's
    // error is about proportional to its tolerance): slopes are fitted only
    // well above it. Zero for closed forms.
    let reference_error = if truth0.evaluations == 0 {
        0.0
    } else {
        let loose = truth(&first.plan, 0, &times, set.reference_rtol * 100.0)?;
        loose
            .values
            .iter()
            .zip(&truth0.values)
            .flat_map(|(x, y)| x.iter().zip(y).map(|(u, v)| (u - v).abs()))
            .fold(0.0f64, f64::max)
            / 100.0
    };
    for rtol in [1e-4, 1e-6, 1e-8, 1e-10] {
        let d = match dop853_of(&first.plan, 0, &times, rtol) {
            Ok(d) => d,
            Err(e) => {
                eprintln!("note: DOP853 at rtol {rtol:e}: {e:#}");
                continue;
            }
        };
        let (mut emax, mut erel) = (0.0f64, 0.0f64);
        for (a, b) in d.values.iter().zip(&truth0.values) {
            for v in &error_vars {
                if let Some(vi) = first.plan.vars.iter().position(|x| x == v) {
                    emax = emax.max(finite_or_inf((a[vi] - b[vi]).abs()));
                    erel = erel.max(finite_or_inf(rel_error(a[vi], b[vi]).abs()));
                }
            }
        }
        let span = times.last().copied().unwrap_or(0.0)
            - first.plan.binding("t0").value_at(0, &first.plan.strides);
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

    // CSV.
    {
        let mut w = csv::Writer::from_path(out.join("work_precision.csv"))?;
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
        for r in &rows {
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
    }

    // Slopes and pictures.
    let mut groups: Vec<(String, Vec<&Row>)> = vec![];
    for r in &rows {
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
    let title = scene.title.clone().unwrap_or_else(|| scene.name.clone());
    let mut slopes_md = String::new();
    let mut slope_lines: Vec<Slope> = vec![];
    let mut series_t: Vec<(String, Vec<f64>, Vec<f64>)> = vec![];
    let mut series_dt: Vec<(String, Vec<f64>, Vec<f64>)> = vec![];
    for (key, rs) in &groups {
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
        let scheme = Scheme::by_name(&rs[0].scheme).context("scheme")?;
        let u = if rs[0].precision == "f32" {
            f32::EPSILON as f64 / 2.0
        } else {
            f64::EPSILON / 2.0
        };
        match slope(rs, (1e4 * u).max(100.0 * reference_error), 1e-2) {
            Some((m, n)) => {
                let _ = writeln!(slopes_md, "| {key} | {} | {m:.2} | {n} |", scheme.order);
                if let Some(r) = rs
                    .iter()
                    .find(|r| r.error_max.is_finite() && r.error_max > 1e4 * u)
                {
                    slope_lines.push(Slope {
                        slope: scheme.order as f64,
                        anchor: (r.dt, r.error_max),
                        label: format!("slope {}", scheme.order),
                    });
                }
            }
            None => {
                let _ = writeln!(
                    slopes_md,
                    "| {key} | {} | – | too few points between the floor and 10⁻² |",
                    scheme.order
                );
            }
        }
    }
    slope_lines.dedup_by(|a, b| a.slope == b.slope);
    // Pictures, one per precision with every backend in it (so a GPU and a
    // CPU run share a plot), split per backend where that would need more
    // than twelve lines; the first is also `work_precision.png` /
    // `error_vs_dt.png`.
    let mut pictures: Vec<String> = vec![];
    // The distinct values of one column over the schemes' rows, sorted.
    let distinct = |column: fn(&Row) -> &String| -> Vec<String> {
        let mut v: Vec<String> = rows
            .iter()
            .filter(|r| !r.scheme.starts_with("dop853"))
            .map(|r| column(r).clone())
            .collect();
        v.sort();
        v.dedup();
        v
    };
    let precisions_run = distinct(|r| &r.precision);
    let backends_run = distinct(|r| &r.backend);
    let mut panels: Vec<(String, Vec<String>, String)> = vec![];
    for p in &precisions_run {
        let lines = set.schemes.len() * backends_run.len();
        if lines <= 11 {
            panels.push((p.clone(), backends_run.clone(), p.clone()));
        } else {
            for b in &backends_run {
                panels.push((p.clone(), vec![b.clone()], format!("{b}_{p}")));
            }
        }
    }
    for (k, (p, bs, suffix)) in panels.iter().enumerate() {
        let keep = |key: &str| {
            key.starts_with("dop853") || bs.iter().any(|b| key.ends_with(&format!(" {b} {p}")))
        };
        let (st, sd) = (pick(&series_t, &keep), pick(&series_dt, &keep));
        let t = format!("{title} ({})", suffix.replace('_', " "));
        let wp = format!("work_precision_{suffix}.png");
        let ed = format!("error_vs_dt_{suffix}.png");
        plot::loglog(
            &out.join(&wp),
            &Figure {
                title: &t,
                x_label: "integration time per trajectory [s]",
                y_label: "max error",
                ..Figure::default()
            },
            &st,
            &[],
        )?;
        plot::loglog(
            &out.join(&ed),
            &Figure {
                title: &t,
                x_label: "dt",
                y_label: "max error",
                ..Figure::default()
            },
            &sd,
            &slope_lines,
        )?;
        if k == 0 {
            std::fs::copy(out.join(&wp), out.join("work_precision.png"))?;
            std::fs::copy(out.join(&ed), out.join("error_vs_dt.png"))?;
        }
        pictures.push(wp);
        pictures.push(ed);
    }
    if !over_time.is_empty() {
        let first_p = precisions_run.first().cloned().unwrap_or_default();
        let s_o: Vec<Series> = over_time
            .iter()
            .filter(|(n, _, _)| n.ends_with(&first_p))
            .take(11)
            .map(|(n, x, y)| Series::new(n, x, y))
            .collect();
        plot::lines(
            &out.join("error_vs_time.png"),
            &Figure {
                title: &title,
                x_label: "t",
                y_label: "max error at t (middle dt of each scheme)",
                ..Figure::default()
            },
            &s_o,
            false,
            true,
        )?;
        pictures.push("error_vs_time.png".into());
    }

    // report.md
    let mut md = String::new();
    let _ = writeln!(md, "# Work–precision: {title}\n");
    let _ = writeln!(md, "Scene `{}` (model `{}`), reeb {}. Reference: {ref_method}. Errors are the maximum over the output times{}, the trajectories and the variables {} of |x − x_ref|; times are the integration alone, per trajectory, measured on ensembles of {MIN_TRAJECTORIES} to {MAX_TRAJECTORIES} trajectories (the scene's, repeated to about {TIMING_WORK:e} trajectory-steps; the reference DOP853 runs one trajectory at a time).\n", scene.path.display(), scene.model.name(), env!("CARGO_PKG_VERSION"), if base.trajectory.is_some() { "" } else { " (the final time)" }, error_vars.join(", "));
    for pic in &pictures {
        let _ = writeln!(md, "![{pic}]({pic})\n");
    }
    let _ = writeln!(md, "## Measured order\n\nSlope of log error against log dt over the last four points between 10⁻² and the floor (10⁴ unit roundoffs, or 100× the reference's estimated error, {reference_error:.1e}).\n\n| configuration | nominal | measured | points |\n|---|---|---|---|\n{slopes_md}");
    let _ = writeln!(md, "## Fastest configuration for an error target\n\n| target | configuration | dt | error | seconds per trajectory | evaluations per unit time |\n|---|---|---|---|---|---|");
    let span = match scene.horizon {
        Horizon::TEnd(t) => t - first.plan.binding("t0").value_at(0, &first.plan.strides),
        Horizon::Steps(_) => {
            first.plan.steps as f64 * first.plan.binding("dt").value_at(0, &first.plan.strides)
        }
    };
    for target in &set.targets {
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
    let _ = writeln!(md, "\nAll points: `work_precision.csv`.");
    std::fs::write(out.join("report.md"), md)?;
    Ok(out.join("report.md"))
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

/// Class of a stability cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Class {
    Accurate = 0,
    Distorted = 1,
    Diverged = 2,
}

impl Class {
    pub fn name(self) -> &'static str {
        match self {
            Class::Accurate => "accurate",
            Class::Distorted => "distorted",
            Class::Diverged => "diverged",
        }
    }
}

/// Reference cycle statistics of one parameter set: DOP853 sampled densely,
/// with the same definitions as the cycle observer.
fn reference_cycle(
    plan: &Plan,
    traj: usize,
    cycle: &CycleObs,
    var: usize,
    rtol: f64,
) -> Result<(f64, f64)> {
    let x = lane_of(plan, traj);
    let t_end = x.t0 + plan.steps as f64 * x.dt;
    let start = x.t0 + (cycle.skip * plan.steps as f64).floor() * x.dt;
    let samples = 200_000usize;
    let times: Vec<f64> = (0..=samples)
        .map(|k| start + (t_end - start) * k as f64 / samples as f64)
        .collect();
    let mut all = vec![x.t0];
    all.extend(&times);
    let d = dop853_of(plan, traj, &all, rtol)?;
    let v: Vec<f64> = d.values[1..].iter().map(|y| y[var]).collect();
    let (lo, hi) = v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, y| {
        (a.0.min(*y), a.1.max(*y))
    });
    let mut crossings = vec![];
    for k in 1..v.len() {
        let (y0, y1) = (v[k - 1] - cycle.level, v[k] - cycle.level);
        if y0 < 0.0 && y1 >= 0.0 {
            crossings.push(times[k - 1] + (times[k] - times[k - 1]) * y0 / (y0 - y1));
        }
    }
    let period = if crossings.len() >= 2 {
        let n = crossings.len() as f64;
        let kbar = (n - 1.0) / 2.0;
        let tbar = crossings.iter().sum::<f64>() / n;
        let sxy: f64 = crossings
            .iter()
            .enumerate()
            .map(|(k, t)| (k as f64 - kbar) * (t - tbar))
            .sum();
        sxy / (n * (n * n - 1.0) / 12.0)
    } else {
        f64::NAN
    };
    Ok((0.5 * (hi - lo), period))
}

/// Runs the stability report of `scene`; returns the path of stability.csv.
pub fn stability(scene: &Scene, opts: &ReportOptions) -> Result<PathBuf> {
    let set = settings(scene);
    let out = out_dir(scene, opts, "stability")?;
    let shape = scene.shape();
    let varying: Vec<usize> = (0..shape.len()).filter(|k| shape[*k] > 1).collect();
    if varying.len() != 2 {
        bail!("{}: a stability map needs exactly two axes with more than one value (this scene has {})", scene.path.display(), varying.len());
    }
    let (ka, kb) = (varying[0], varying[1]);
    let mut sc = scene.clone();
    let first_var = scene.model.spec().vars[0].to_string();
    let cycle = sc.cycle.clone().unwrap_or(CycleObs {
        var: first_var.clone(),
        ..CycleObs::default()
    });
    sc.cycle = Some(cycle.clone());
    sc.trajectory = None;
    sc.poincare = None;
    sc.final_vars = vec![OutVar {
        name: first_var.clone(),
        components: vec![first_var],
    }];
    let precisions: Vec<Precision> = match opts.precision {
        Some(p) => vec![p],
        None => set.precisions.clone(),
    };
    let backend = opts
        .backend
        .or(set.backends.first().copied())
        .unwrap_or(BackendChoice::Cpu);
    let n = sc.ensemble_size();
    let strides = sc.strides();
    let subs = sc.sub_runs()?;
    // Reference per parameter set: every input but the step.
    let mut references: HashMap<String, (f64, f64)> = HashMap::new();
    let mut reference_of = |plan: &Plan, j: usize| -> Result<(f64, f64)> {
        let x = lane_of(plan, j);
        let key = plan
            .bindings
            .iter()
            .filter(|(b, _)| *b != "dt")
            .map(|(b, _)| format!("{}", x.get(b).unwrap_or(0.0).to_bits()))
            .collect::<Vec<_>>()
            .join(",");
        if let Some(r) = references.get(&key) {
            return Ok(*r);
        }
        let var = plan.cycle_var.context("cycle variable")?;
        let r = reference_cycle(plan, j, &cycle, var, set.reference_rtol.max(1e-10))?;
        references.insert(key, r);
        Ok(r)
    };
    let mut csv = csv::Writer::from_path(out.join("stability.csv"))?;
    csv.write_record([
        scene.axes[ka].name.as_str(),
        scene.axes[kb].name.as_str(),
        "precision",
        "class",
        "error",
        "amplitude",
        "period",
        "reference_amplitude",
        "reference_period",
        "status_step",
    ])?;
    let mut summary = String::new();
    let mut first_map = true;
    for p in &precisions {
        let (engine, notice) = Engine::resolve(backend, *p)?;
        if let Some(n) = notice {
            eprintln!("{n}");
        }
        let mut class = vec![Class::Diverged as u8; n];
        let mut error = vec![f64::NAN; n];
        let mut rowsv: Vec<(usize, f64, f64, f64, f64, u64)> = vec![];
        for sub in &subs {
            let (obs, _) = engine.run_f64(&sub.plan, *p)?;
            for (j, g) in sub.scene_rows(&shape, &strides).enumerate() {
                let (ra, rp) = reference_of(&sub.plan, j)?;
                let (a, per, st) = (
                    obs.cycle_amplitude[j],
                    obs.cycle_period[j],
                    obs.nonfinite_step[j],
                );
                let (c, e) = if st != 0 {
                    (Class::Diverged, f64::INFINITY)
                } else {
                    let ea = (a / ra - 1.0).abs();
                    // A period is compared only where the reference has one;
                    // a missing one where the reference has one is a distortion.
                    let ep = if rp.is_finite() {
                        if per.is_finite() {
                            (per / rp - 1.0).abs()
                        } else {
                            f64::INFINITY
                        }
                    } else {
                        0.0
                    };
                    let e = ea.max(ep);
                    (
                        if e <= set.distorted {
                            Class::Accurate
                        } else {
                            Class::Distorted
                        },
                        e,
                    )
                };
                class[g] = c as u8;
                error[g] = e;
                rowsv.push((g, a, per, ra, rp, st.into()));
            }
        }
        rowsv.sort_by_key(|r| r.0);
        for (g, a, per, ra, rp, st) in &rowsv {
            let (ia, ib) = ((g / strides[ka]) % shape[ka], (g / strides[kb]) % shape[kb]);
            csv.write_record([
                format!("{:e}", scene.axes[ka].values[ia]),
                format!("{:e}", scene.axes[kb].values[ib]),
                p.name().to_string(),
                Class::name(match class[*g] {
                    0 => Class::Accurate,
                    1 => Class::Distorted,
                    _ => Class::Diverged,
                })
                .to_string(),
                format!("{:e}", error[*g]),
                format!("{a:e}"),
                format!("{per:e}"),
                format!("{ra:e}"),
                format!("{rp:e}"),
                st.to_string(),
            ])?;
        }
        let counts = [0u8, 1, 2].map(|c| class.iter().filter(|x| **x == c).count());
        let _ = writeln!(
            summary,
            "{} {}: {} cells: {} accurate, {} distorted, {} diverged",
            scene.name, p, n, counts[0], counts[1], counts[2]
        );
        // Pictures: the class map and the error, over the two axes.
        let (xa, xb) = (&scene.axes[ka], &scene.axes[kb]);
        let mut grid_c = vec![0u8; shape[ka] * shape[kb]];
        let mut grid_e = vec![f64::NAN; shape[ka] * shape[kb]];
        for ia in 0..shape[ka] {
            for ib in 0..shape[kb] {
                let g = ia * strides[ka] + ib * strides[kb];
                grid_c[ia * shape[kb] + ib] = class[g];
                grid_e[ia * shape[kb] + ib] = if error[g].is_finite() {
                    error[g].max(1e-16)
                } else {
                    f64::NAN
                };
            }
        }
        let log_axis = |v: &[f64]| {
            v.len() >= 3
                && v.iter().all(|x| *x > 0.0)
                && ((v[2] / v[1]) / (v[1] / v[0]) - 1.0).abs() < 1e-6
        };
        let title = format!(
            "{}: {} ({}, threshold {}%)",
            scene.title.clone().unwrap_or_else(|| scene.name.clone()),
            p,
            engine.name(),
            set.distorted * 100.0
        );
        let fig = Figure {
            title: &title,
            x_label: &xa.name,
            y_label: &xb.name,
            ..Figure::default()
        };
        let legend = [
            ("accurate", (44u8, 160u8, 44u8)),
            ("distorted", (255, 165, 0)),
            ("diverged", (214, 39, 40)),
        ];
        plot::class_map(
            &out.join(format!("stability_{p}.png")),
            &fig,
            &xa.values,
            &xb.values,
            &grid_c,
            &legend,
            log_axis(&xa.values),
            log_axis(&xb.values),
        )?;
        plot::heatmap(
            &out.join(format!("stability_error_{p}.png")),
            &fig,
            &xa.values,
            &xb.values,
            &grid_e,
            "relative error of cycle amplitude / period (grey: diverged)",
            true,
            log_axis(&xa.values),
            log_axis(&xb.values),
        )?;
        if first_map {
            std::fs::copy(
                out.join(format!("stability_{p}.png")),
                out.join("stability.png"),
            )?;
            first_map = false;
        }
    }
    csv.flush()?;
    let mut f = std::fs::File::create(out.join("summary.txt"))?;
    f.write_all(summary.as_bytes())?;
    print!("{summary}");
    Ok(out.join("stability.csv"))
}

/// The series of `all` whose legend key passes `keep`, borrowed for plotting.
fn pick<'a>(
    all: &'a [(String, Vec<f64>, Vec<f64>)],
    keep: &dyn Fn(&str) -> bool,
) -> Vec<Series<'a>> {
    all.iter()
        .filter(|(n, _, _)| keep(n))
        .map(|(n, x, y)| Series::new(n, x, y))
        .collect()
}
