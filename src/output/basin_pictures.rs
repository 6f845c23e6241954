//! The attractors' pictures: the basin map over the first two varying
//! axes (`basins.png`, a colour per attractor with its kind, period and
//! fraction in the legend), the fractions against a parameter as stacked
//! bands (`basin_fractions.png`), and each attractor's samples
//! (`attractors.png`).

use std::path::Path;

use anyhow::Result;

use crate::output::basins::Basins;
use crate::output::pictures::classes_over_first_two;
use crate::output::plot::{self, Figure, Rgb, Series};
use crate::scene::Scene;

/// Attractors with a colour of their own; the smaller ones share "other".
const SHOWN: usize = 10;

/// Rows of the stacked bands' picture (its resolution in fraction).
const BAND_ROWS: usize = 400;

/// Draws the pictures into `dir`; returns the file names written.
pub fn draw(scene: &Scene, dir: &Path, b: &Basins) -> Result<Vec<String>> {
    let title = scene.title.clone().unwrap_or_else(|| scene.name.clone());
    let legend = legend(b);
    let mut files = vec![];
    files.extend(basin_map(scene, dir, &title, b, &legend)?);
    files.extend(fraction_bands(scene, dir, &title, b, &legend)?);
    files.extend(samples(scene, dir, &title, b)?);
    Ok(files)
}

/// A legend entry per shown class: the largest attractors, then "other"
/// where there are more, then escapes; `class(label)` gives each label's.
struct Legend {
    entries: Vec<(String, Rgb)>,
    shown: Vec<i32>,
}

impl Legend {
    /// The entries as the class map takes them.
    fn entries(&self) -> Vec<(&str, Rgb)> {
        (self.entries.iter())
            .map(|(s, c)| (s.as_str(), *c))
            .collect()
    }

    fn class(&self, label: i32) -> u8 {
        match self.shown.iter().position(|&l| l == label) {
            Some(k) => k as u8,
            None if label < 0 => (self.entries.len() - 1) as u8,
            None => self.shown.len() as u8,
        }
    }
}

fn legend(b: &Basins) -> Legend {
    let rows: Vec<&serde_json::Value> = b.table.as_array().map_or(vec![], |t| t.iter().collect());
    let label = |r: &serde_json::Value| r["label"].as_i64().unwrap_or(-1) as i32;
    let shown: Vec<i32> = (rows.iter().map(|r| label(r)))
        .filter(|&l| l >= 0)
        .take(SHOWN)
        .collect();
    let describe = |r: &serde_json::Value| {
        let percent = 100.0 * r["fraction"].as_f64().unwrap_or(0.0);
        let what = match (
            r["kind"].as_str().unwrap_or(""),
            r["period"].as_u64().unwrap_or(0),
        ) {
            ("fixed_point", _) => "fixed point".to_string(),
            ("periodic", k) => format!("period {k}"),
            ("aperiodic", _) => "aperiodic".to_string(),
            _ => "escape".to_string(),
        };
        format!("{}: {what} ({percent:.1} %)", label(r))
    };
    let mut entries: Vec<(String, Rgb)> = rows
        .iter()
        .filter(|r| shown.contains(&label(r)))
        .enumerate()
        .map(|(k, r)| (describe(r), plot::palette(k)))
        .collect();
    let others = rows.iter().filter(|r| label(r) >= 0).count() > shown.len();
    if others {
        entries.push(("other attractors".into(), (120, 120, 120)));
    }
    let escape = rows.iter().find(|r| label(r) < 0);
    entries.push(match escape {
        Some(r) => (describe(r).replacen("-1: ", "", 1), (215, 215, 215)),
        None => ("escape (none)".into(), (215, 215, 215)),
    });
    Legend { entries, shown }
}

fn figure<'f>(title: &'f str, x: &'f str, y: &'f str) -> Figure<'f> {
    Figure {
        title,
        x_label: x,
        y_label: y,
        ..Figure::default()
    }
}

/// The label of every cell of the first two varying axes (the others at
/// their first value), as legend classes.
fn basin_map(
    scene: &Scene,
    dir: &Path,
    title: &str,
    b: &Basins,
    legend: &Legend,
) -> Result<Option<String>> {
    let class = |row: usize| legend.class(b.labels[row]);
    let Some((kx, ky, classes)) = classes_over_first_two(scene, class) else {
        return Ok(None);
    };
    let entries = legend.entries();
    let (ax, ay) = (&scene.axes[kx], &scene.axes[ky]);
    let name = "basins.png".to_string();
    plot::class_map(
        &dir.join(&name),
        &figure(title, &ax.name, &ay.name),
        &ax.values,
        &ay.values,
        &classes,
        &entries,
        plot::log_scale(&ax.values),
        false,
    )?;
    Ok(Some(name))
}

/// Each attractor's share of the orbits at each value of the parameter
/// axis, stacked from the largest basin up (escapes on top).
fn fraction_bands(
    scene: &Scene,
    dir: &Path,
    title: &str,
    b: &Basins,
    legend: &Legend,
) -> Result<Option<String>> {
    let Some(along) = &b.along else {
        return Ok(None);
    };
    let (axis, per) = (&scene.axes[along.axis], &along.counts);
    let values = axis.values.len();
    let rows: Vec<f64> = (0..BAND_ROWS)
        .map(|r| (r as f64 + 0.5) / BAND_ROWS as f64)
        .collect();
    let mut classes = vec![0u8; values * BAND_ROWS];
    for v in 0..values {
        let total: usize = per.iter().map(|(_, c)| c[v]).sum();
        let mut top = 0.0;
        let mut bands = vec![];
        for (label, counts) in per {
            top += counts[v] as f64 / total.max(1) as f64;
            bands.push((top, legend.class(*label)));
        }
        for (r, y) in rows.iter().enumerate() {
            let class = bands.iter().find(|(t, _)| y <= t).map_or(0, |(_, c)| *c);
            classes[v * BAND_ROWS + r] = class;
        }
    }
    let entries = legend.entries();
    let name = "basin_fractions.png".to_string();
    plot::class_map(
        &dir.join(&name),
        &figure(title, &axis.name, "fraction of the orbits"),
        &axis.values,
        &rows,
        &classes,
        &entries,
        plot::log_scale(&axis.values),
        false,
    )?;
    Ok(Some(name))
}

/// Each shown attractor's samples in the plane of the first two sampled
/// components.
fn samples(scene: &Scene, dir: &Path, title: &str, b: &Basins) -> Result<Option<String>> {
    let Some(a) = &scene.observers.attractors else {
        return Ok(None);
    };
    let names: Vec<&String> = crate::plan::observers::components(&a.vars).collect();
    let [x, y, ..] = names[..] else {
        return Ok(None);
    };
    let rows = b.table.as_array().cloned().unwrap_or_default();
    let coords = |r: &serde_json::Value, c: &str| -> Vec<f64> {
        (r["points"][c].as_array().into_iter().flatten())
            .filter_map(|v| v.as_f64())
            .collect()
    };
    let shown: Vec<(String, Vec<f64>, Vec<f64>)> = rows
        .iter()
        .filter(|r| r["label"].as_i64().unwrap_or(-1) >= 0)
        .take(SHOWN)
        .map(|r| (r["label"].to_string(), coords(r, x), coords(r, y)))
        .collect();
    if shown.iter().all(|(_, xs, _)| xs.is_empty()) {
        return Ok(None);
    }
    let series: Vec<Series> = shown
        .iter()
        .enumerate()
        .map(|(k, (label, xs, ys))| Series {
            name: label,
            x: xs,
            y: ys,
            color: Some(plot::palette(k)),
        })
        .collect();
    let name = "attractors.png".to_string();
    plot::point_cloud(&dir.join(&name), &figure(title, x, y), &series, None, None)?;
    Ok(Some(name))
}
