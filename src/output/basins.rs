//! A run's attractors and their basins (`output.attractors`): every orbit's
//! end as the backends found it (`attractor_period`, `attractor_points`)
//! labelled across the whole ensemble (`output::attractors`), continued
//! along a parameter axis where the ensemble has one, with each basin's
//! fraction and standard error and, on a grid of initial conditions, the
//! basin entropy. Written as `attractor.npy`, `attractors.json` and
//! `summary.json`'s `attractors`, after every chunk (a merge's too).

use std::path::Path;

use anyhow::Result;
use serde_json::{json, Value};

use crate::num::precision::Real;
use crate::output::attractors::{self, End, Kind, Labelling};
use crate::plan::observations::Observations;
use crate::plan::observers::{components, AttractorObs};
use crate::plan::recurrence::Recurrence;
use crate::scene::{Format, Scene};

/// Cells per side of the boxes of the basin entropy (Daza et al. use 5).
const ENTROPY_BOX: usize = 5;

/// A finite-time maximal Lyapunov exponent above which an aperiodic
/// attractor is called chaotic (a quasi-periodic orbit's decays as ln t / t).
const CHAOTIC: f64 = 1e-2;

/// The run's attractors: each orbit's label, the table and the summary.
pub struct Basins {
    pub labels: Vec<i32>,
    pub table: Value,
    pub summary: Value,
    pub along: Option<Along>,
}

/// The parameter axis the attractors were continued along, and each
/// label's orbits at each of its values (escapes last).
pub struct Along {
    pub axis: usize,
    pub counts: Vec<(i32, Vec<usize>)>,
}

/// The detector's settings on the host, as the backends had them.
pub fn detector(a: &AttractorObs) -> Recurrence {
    Recurrence::new(a.max_period, a.tolerance, &a.wrap())
}

/// Every orbit's end: its kind and period, and its samples on the
/// attractor (a cycle's last `period`, an aperiodic orbit's every finite
/// one), angles taken into [0, 2π).
fn ends<R: Real>(obs: &Observations<R>, r: &Recurrence) -> Vec<End> {
    let (kept, columns) = (obs.cycle_points, &obs.attractor_points);
    (0..obs.n)
        .map(|i| {
            let period = obs.attractor_period[i];
            let kind = match period {
                p if p < 0 => Kind::Escape,
                0 => Kind::Aperiodic,
                1 => Kind::FixedPoint,
                _ => Kind::Periodic,
            };
            let from = match kind {
                Kind::FixedPoint | Kind::Periodic => kept - (period as usize).min(kept),
                _ => 0,
            };
            let mut points = vec![];
            for m in from..kept {
                let raw: Vec<f64> = columns
                    .iter()
                    .map(|(_, v)| v[i * kept + m].to_f64())
                    .collect();
                // Angles in [0, 2π): where the points are drawn and listed.
                let x: Vec<f64> = (0..raw.len()).map(|c| r.coordinate(&raw, c)).collect();
                if x.iter().all(|v| v.is_finite()) {
                    points.extend(x);
                }
            }
            End {
                kind,
                period: period.max(0) as usize,
                points,
            }
        })
        .collect()
}

/// The run's attractors, where the scene asks for them.
pub fn of<R: Real>(scene: &Scene, obs: &Observations<R>) -> Option<Basins> {
    let a = scene.observers.attractors.as_ref()?;
    let r = detector(a);
    let ends = ends(obs, &r);
    let (shape, strides) = (scene.shape(), scene.strides());
    let axis = parameter_axis(scene);
    let (labelling, along) = match axis {
        Some(k) => {
            let slices: Vec<Vec<usize>> = (0..shape[k])
                .map(|v| {
                    (0..obs.n)
                        .filter(|i| (i / strides[k]) % shape[k] == v)
                        .collect()
                })
                .collect();
            let c = attractors::continue_along(&ends, &slices, &r);
            let counts = per_slice(&c.labelling, &slices);
            (c.labelling, Some(Along { axis: k, counts }))
        }
        None => (attractors::label(&ends, &r), None),
    };
    let table = table(scene, a, &labelling, obs, along.as_ref());
    let mut summary = json!({
        "count": labelling.attractors.iter().filter(|x| x.label >= 0).count(),
        "fractions": fractions(&labelling),
    });
    if let Some((s_b, s_bb)) = entropy(scene, &labelling.labels) {
        summary["basin_entropy"] = s_b.into();
        summary["boundary_basin_entropy"] = s_bb.into();
    }
    if let Some(a) = &along {
        summary["continuation"] = continuation(scene, a.axis, &a.counts);
    }
    Some(Basins {
        labels: labelling.labels,
        table,
        summary,
        along,
    })
}

/// The first axis of a parameter with more than one value.
fn parameter_axis(scene: &Scene) -> Option<usize> {
    (scene.axes.iter()).position(|a| a.field.starts_with("params.") && a.values.len() > 1)
}

/// Each label's orbits in each slice (escapes as −1, last).
fn per_slice(l: &Labelling, slices: &[Vec<usize>]) -> Vec<(i32, Vec<usize>)> {
    l.attractors
        .iter()
        .map(|a| {
            let counts = slices
                .iter()
                .map(|s| s.iter().filter(|&&i| l.labels[i] == a.label).count())
                .collect();
            (a.label, counts)
        })
        .collect()
}

/// `summary.json`'s fractions: label, kind, period, fraction and error.
fn fractions(l: &Labelling) -> Value {
    let n = l.labels.len();
    l.attractors
        .iter()
        .map(|a| {
            let (f, e) = attractors::fraction(a.count, n);
            json!({"label": a.label, "kind": a.kind, "period": a.period,
                   "fraction": f, "fraction_error": e})
        })
        .collect()
}

/// `attractors.json`: per attractor its label, kind, period, points by
/// variable, the mean maximal Lyapunov exponent of its orbits where the run
/// has one (and, aperiodic, whether that says chaotic), count, fraction
/// and error; along a parameter axis, the values where it is found.
fn table<R: Real>(
    scene: &Scene,
    a: &AttractorObs,
    l: &Labelling,
    obs: &Observations<R>,
    along: Option<&Along>,
) -> Value {
    let names: Vec<&String> = components(&a.vars).collect();
    let n = l.labels.len();
    let entries = l.attractors.iter().map(|at| {
        let mut points = serde_json::Map::new();
        let d = names.len().max(1);
        for (c, name) in names.iter().enumerate() {
            let v: Vec<f64> = at.points.chunks(d).map(|x| x[c]).collect();
            points.insert(name.to_string(), v.into());
        }
        let (f, e) = attractors::fraction(at.count, n);
        let mut entry = json!({"label": at.label, "kind": at.kind, "period": at.period,
            "points": points, "count": at.count, "fraction": f, "fraction_error": e});
        if let Some(lyapunov) = mean_exponent(obs, &l.labels, at.label) {
            entry["lyapunov"] = lyapunov.into();
            if at.kind == Kind::Aperiodic {
                entry["chaotic"] = (lyapunov > CHAOTIC).into();
            }
        }
        if let Some(along) = along {
            let found = found_at(&scene.axes[along.axis].values, along, at.label);
            entry["found_from"] = found.first().copied().into();
            entry["found_to"] = found.last().copied().into();
        }
        entry
    });
    Value::Array(entries.collect())
}

/// The values of the parameter at which attractor `label` has orbits.
fn found_at(values: &[f64], along: &Along, label: i32) -> Vec<f64> {
    let Some((_, counts)) = along.counts.iter().find(|(l, _)| *l == label) else {
        return vec![];
    };
    (counts.iter().zip(values))
        .filter(|(&c, _)| c > 0)
        .map(|(_, &v)| v)
        .collect()
}

/// The mean maximal Lyapunov exponent of the orbits labelled `label`, over
/// those that have a finite one; `None` without exponents.
fn mean_exponent<R: Real>(obs: &Observations<R>, labels: &[i32], label: i32) -> Option<f64> {
    let k = obs.exponents;
    if k == 0 || obs.lyapunov.is_empty() {
        return None;
    }
    let values: Vec<f64> = (0..obs.n)
        .filter(|&i| labels[i] == label)
        .map(|i| obs.lyapunov[i * k].to_f64())
        .filter(|v| v.is_finite())
        .collect();
    (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
}

/// S_b and S_bb over the grid of the first two varying axes, where those
/// are the only ones and both are initial conditions.
fn entropy(scene: &Scene, labels: &[i32]) -> Option<(f64, f64)> {
    let varying: Vec<usize> = (0..scene.axes.len())
        .filter(|&k| scene.axes[k].values.len() > 1)
        .collect();
    let [kx, ky] = varying[..] else { return None };
    let initial = |k: usize| scene.axes[k].field.starts_with("initial.");
    let (nx, ny) = (scene.axes[kx].values.len(), scene.axes[ky].values.len());
    if !(initial(kx) && initial(ky)) || nx < ENTROPY_BOX || ny < ENTROPY_BOX {
        return None;
    }
    // Rows are row-major over the axes: with the others of length one the
    // labels are the nx × ny grid itself.
    Some(attractors::basin_entropy(labels, nx, ny, ENTROPY_BOX))
}

/// `summary.json`'s `attractors.continuation`: the axis, its values, and
/// each label's fraction at each value.
fn continuation(scene: &Scene, k: usize, per: &[(i32, Vec<usize>)]) -> Value {
    let axis = &scene.axes[k];
    let totals: Vec<usize> = (0..axis.values.len())
        .map(|v| per.iter().map(|(_, c)| c[v]).sum())
        .collect();
    let fractions: serde_json::Map<String, Value> = per
        .iter()
        .map(|(label, counts)| {
            let f: Vec<f64> = (counts.iter().zip(&totals))
                .map(|(&c, &t)| if t == 0 { 0.0 } else { c as f64 / t as f64 })
                .collect();
            (label.to_string(), f.into())
        })
        .collect();
    json!({"axis": axis.name, "values": axis.values, "fractions": fractions})
}

/// Writes `attractor.npy` (or the store's `attractor` array) and
/// `attractors.json` into `dir`; returns the files written.
pub fn write(scene: &Scene, dir: &Path, format: Format, b: &Basins) -> Result<Vec<String>> {
    let shape: Vec<u64> = scene.shape().iter().map(|&s| s as u64).collect();
    let mut files = vec![];
    match format {
        Format::Npy => {
            crate::output::arrays::write_npy(
                &dir.join("attractor.npy"),
                &shape,
                b.labels.iter().copied(),
            )?;
            files.push("attractor.npy".to_string());
        }
        Format::Zarr => {
            let dims: Vec<String> = scene.axes.iter().map(|a| a.name.clone()).collect();
            let bytes: Vec<u8> = b.labels.iter().flat_map(|l| l.to_le_bytes()).collect();
            crate::output::zarr::write_whole(dir, "attractor", &shape, &dims, "<i4", &bytes)?;
        }
    }
    let text = serde_json::to_string_pretty(&b.table)?;
    std::fs::write(dir.join("attractors.json"), text + "\n")?;
    files.push("attractors.json".to_string());
    Ok(files)
}
