//! The stability report: over a 2-D grid of the scene's axes (typically
//! ε × τ) every cell classified as accurate, distorted (cycle amplitude or
//! period off by more than a threshold from the reference's) or diverged
//! (non-finite). Written as `stability.csv`, a class map and an error map
//! per precision, and `summary.txt`.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use crate::backend::BackendChoice;
use crate::backend::BackendError;
use crate::backend::Engine;
use crate::num::precision::Precision;
use crate::output::plot::{self, Figure};
use crate::plan::observations::Observations;
use crate::plan::observers::CycleObs;
use crate::plan::Plan;
use crate::reference::truth::{dop853_of, lane_of};
use crate::scene::{ReportSettings, Scene, SubRun};

use super::options::{claim_dir, finish, precisions, settings, ReportOptions};

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

/// Runs the stability report of `scene`; returns the path of stability.csv.
pub fn stability(scene: &Scene, opts: &ReportOptions) -> Result<PathBuf> {
    let set = settings(scene);
    let claim = claim_dir(scene, opts, "stability")?;
    let out = claim.dir().to_path_buf();
    let map = Map::of(scene)?;
    let (sc, cycle) = cycle_scene(scene);
    let precisions = precisions(scene, opts, &set)?;
    let backend = opts
        .backend
        .or(set.backends.first().copied())
        .unwrap_or(BackendChoice::Cpu);
    let subs = sc.sub_runs()?;
    let mut references = CycleReferences::new(cycle, set.reference_rtol.max(1e-10));
    let csv_path = out.join("stability.csv");
    let mut csv = csv::Writer::from_path(&csv_path)
        .with_context(|| format!("creating {}", csv_path.display()))?;
    csv.write_record([
        scene.axes[map.ka].name.as_str(),
        scene.axes[map.kb].name.as_str(),
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
    for (i, p) in precisions.iter().enumerate() {
        let (engine, notice) = Engine::resolve(backend, *p)?;
        if let Some(n) = notice {
            eprintln!("{n}");
        }
        let run = |plan: &Plan| engine.run_f64_until(plan, *p, opts.stop.as_deref());
        let cells = classify_cells(run, &subs, &map, &mut references, set.distorted)?;
        write_rows(&mut csv, scene, &map, *p, &cells)?;
        let counts = [0u8, 1, 2].map(|c| cells.class.iter().filter(|x| **x == c).count());
        let _ = writeln!(
            summary,
            "{} {}: {} cells: {} accurate, {} distorted, {} diverged",
            scene.name, p, map.n, counts[0], counts[1], counts[2]
        );
        draw_maps(&out, scene, &set, &map, *p, engine.name(), &cells)?;
        // The first precision's class map is also `stability.png`.
        if i == 0 {
            std::fs::copy(
                out.join(format!("stability_{p}.png")),
                out.join("stability.png"),
            )?;
        }
    }
    csv.flush()
        .with_context(|| format!("writing {}", csv_path.display()))?;
    let txt = out.join("summary.txt");
    std::fs::write(&txt, summary.as_bytes())
        .with_context(|| format!("writing {}", txt.display()))?;
    print!("{summary}");
    finish(claim, scene, "stability", "stability.csv")
}

/// The two axes a stability map spans, and where a scene row sits on them.
struct Map {
    /// The axes with more than one value: the map's x (`ka`) and y (`kb`).
    ka: usize,
    kb: usize,
    shape: Vec<usize>,
    strides: Vec<usize>,
    /// Cells (scene rows).
    n: usize,
}

impl Map {
    /// The map of a scene with exactly two axes of more than one value.
    fn of(scene: &Scene) -> Result<Map> {
        let shape = scene.shape();
        let varying: Vec<usize> = (0..shape.len()).filter(|k| shape[*k] > 1).collect();
        if varying.len() != 2 {
            bail!("{}: a stability map needs exactly two axes with more than one value (this scene has {})", scene.path.display(), varying.len());
        }
        Ok(Map {
            ka: varying[0],
            kb: varying[1],
            shape,
            strides: scene.strides(),
            n: scene.ensemble_size(),
        })
    }

    /// The positions of scene row `g` on the two axes.
    fn position(&self, g: usize) -> (usize, usize) {
        let (ka, kb) = (self.ka, self.kb);
        (
            (g / self.strides[ka]) % self.shape[ka],
            (g / self.strides[kb]) % self.shape[kb],
        )
    }
}

/// The scene as the report runs it: it observes the limit cycle of its
/// `cycle` variable (default: the model's first) and records nothing else.
fn cycle_scene(scene: &Scene) -> (Scene, CycleObs) {
    let mut sc = scene.clone();
    let first_var = scene.model.spec().vars[0].to_string();
    let cycle = sc.observers.cycle.clone().unwrap_or(CycleObs {
        var: first_var.clone(),
        ..CycleObs::default()
    });
    sc.observers.cycle = Some(cycle.clone());
    sc.observers.trajectory = None;
    sc.observers.poincare = None;
    sc.observers.final_vars = vec![first_var.as_str().into()];
    (sc, cycle)
}

// ---------------------------------------------------------------------------
// The reference cycles
// ---------------------------------------------------------------------------

/// The reference cycles, one per parameter set: every input but the step,
/// so the cells that differ only in `dt` share one.
struct CycleReferences {
    cycle: CycleObs,
    rtol: f64,
    known: HashMap<String, (f64, f64)>,
}

impl CycleReferences {
    fn new(cycle: CycleObs, rtol: f64) -> Self {
        Self {
            cycle,
            rtol,
            known: HashMap::new(),
        }
    }

    /// Amplitude and period of the reference cycle of trajectory `j`.
    fn of(&mut self, plan: &Plan, j: usize) -> Result<(f64, f64)> {
        let x = lane_of(plan, j);
        let key = plan
            .bindings
            .iter()
            .filter(|(b, _)| *b != "dt")
            .map(|(b, _)| format!("{}", x.get(b).unwrap_or(0.0).to_bits()))
            .collect::<Vec<_>>()
            .join(",");
        if let Some(r) = self.known.get(&key) {
            return Ok(*r);
        }
        let var = plan.cycle_var.context("cycle variable")?;
        let r = reference_cycle(plan, j, &self.cycle, var, self.rtol)?;
        self.known.insert(key, r);
        Ok(r)
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
    Ok((0.5 * (hi - lo), mean_period(&v, &times, cycle.level)))
}

/// Period of the upward crossings of `level` by the samples `v` at `times`:
/// the least-squares slope of crossing time against crossing number. NaN
/// with fewer than two crossings.
fn mean_period(v: &[f64], times: &[f64], level: f64) -> f64 {
    let mut crossings = vec![];
    for k in 1..v.len() {
        let (y0, y1) = (v[k - 1] - level, v[k] - level);
        if y0 < 0.0 && y1 >= 0.0 {
            crossings.push(times[k - 1] + (times[k] - times[k - 1]) * y0 / (y0 - y1));
        }
    }
    if crossings.len() >= 2 {
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
    }
}

// ---------------------------------------------------------------------------
// The cells
// ---------------------------------------------------------------------------

/// What was measured in one cell, and its reference.
struct Measurement {
    /// Scene row.
    g: usize,
    amplitude: f64,
    period: f64,
    ref_amplitude: f64,
    ref_period: f64,
    /// Step at which the run turned non-finite (0: ran to the end).
    status_step: u64,
}

/// The cells of one precision: class and error by scene row, and the
/// measurements in scene-row order.
struct Cells {
    class: Vec<u8>,
    error: Vec<f64>,
    measured: Vec<Measurement>,
}

/// Runs every plan (with `run`, in one precision) and classifies each of its cells.
fn classify_cells(
    run: impl Fn(&Plan) -> Result<(Observations<f64>, f64), BackendError>,
    subs: &[SubRun],
    map: &Map,
    references: &mut CycleReferences,
    distorted: f64,
) -> Result<Cells> {
    let mut cells = Cells {
        class: vec![Class::Diverged as u8; map.n],
        error: vec![f64::NAN; map.n],
        measured: vec![],
    };
    for sub in subs {
        let (obs, _) = run(&sub.plan)?;
        for (j, g) in sub.scene_rows(&map.shape, &map.strides).enumerate() {
            let (ra, rp) = references.of(&sub.plan, j)?;
            let (a, per, st) = (
                obs.cycle_amplitude[j],
                obs.cycle_period[j],
                obs.nonfinite_step[j],
            );
            let (c, e) = classify(a, per, st != 0, ra, rp, distorted);
            cells.class[g] = c as u8;
            cells.error[g] = e;
            cells.measured.push(Measurement {
                g,
                amplitude: a,
                period: per,
                ref_amplitude: ra,
                ref_period: rp,
                status_step: st.into(),
            });
        }
    }
    cells.measured.sort_by_key(|m| m.g);
    Ok(cells)
}

/// Class and error of a cell: diverged where the run stopped, otherwise the
/// larger relative error of amplitude and period against the reference's,
/// accurate up to the `distorted` threshold.
fn classify(a: f64, per: f64, stopped: bool, ra: f64, rp: f64, distorted: f64) -> (Class, f64) {
    if stopped {
        return (Class::Diverged, f64::INFINITY);
    }
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
        if e <= distorted {
            Class::Accurate
        } else {
            Class::Distorted
        },
        e,
    )
}

/// One CSV line per cell of precision `p`, in scene-row order.
fn write_rows(
    csv: &mut csv::Writer<std::fs::File>,
    scene: &Scene,
    map: &Map,
    p: Precision,
    cells: &Cells,
) -> Result<()> {
    for m in &cells.measured {
        let (ia, ib) = map.position(m.g);
        csv.write_record([
            format!("{:e}", scene.axes[map.ka].values[ia]),
            format!("{:e}", scene.axes[map.kb].values[ib]),
            p.name().to_string(),
            Class::name(match cells.class[m.g] {
                0 => Class::Accurate,
                1 => Class::Distorted,
                _ => Class::Diverged,
            })
            .to_string(),
            format!("{:e}", cells.error[m.g]),
            format!("{:e}", m.amplitude),
            format!("{:e}", m.period),
            format!("{:e}", m.ref_amplitude),
            format!("{:e}", m.ref_period),
            m.status_step.to_string(),
        ])?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------
// The pictures
// ---------------------------------------------------------------------------

/// The class and the error of the cells on the map's grid
/// (`[ia * shape[kb] + ib]`); errors floored at 10⁻¹⁶ for the log colour
/// scale, diverged cells NaN (grey).
fn grids(map: &Map, cells: &Cells) -> (Vec<u8>, Vec<f64>) {
    let (ka, kb) = (map.ka, map.kb);
    let (na, nb) = (map.shape[ka], map.shape[kb]);
    let mut grid_c = vec![0u8; na * nb];
    let mut grid_e = vec![f64::NAN; na * nb];
    for ia in 0..na {
        for ib in 0..nb {
            let g = ia * map.strides[ka] + ib * map.strides[kb];
            grid_c[ia * nb + ib] = cells.class[g];
            grid_e[ia * nb + ib] = if cells.error[g].is_finite() {
                cells.error[g].max(1e-16)
            } else {
                f64::NAN
            };
        }
    }
    (grid_c, grid_e)
}

/// `stability_{p}.png` (the class map) and `stability_error_{p}.png` (the
/// error), over the two axes.
fn draw_maps(
    out: &Path,
    scene: &Scene,
    set: &ReportSettings,
    map: &Map,
    p: Precision,
    backend: &str,
    cells: &Cells,
) -> Result<()> {
    let (xa, xb) = (&scene.axes[map.ka], &scene.axes[map.kb]);
    let (grid_c, grid_e) = grids(map, cells);
    let title = format!(
        "{}: {} ({}, threshold {}%)",
        scene.title.clone().unwrap_or_else(|| scene.name.clone()),
        p,
        backend,
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
    let (log_a, log_b) = (plot::log_scale(&xa.values), plot::log_scale(&xb.values));
    plot::class_map(
        &out.join(format!("stability_{p}.png")),
        &fig,
        &xa.values,
        &xb.values,
        &grid_c,
        &legend,
        log_a,
        log_b,
    )?;
    plot::heatmap(
        &out.join(format!("stability_error_{p}.png")),
        &fig,
        &xa.values,
        &xb.values,
        &grid_e,
        "relative error of cycle amplitude / period (grey: diverged)",
        true,
        log_a,
        log_b,
    )?;
    Ok(())
}
