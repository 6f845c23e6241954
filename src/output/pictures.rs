//! Quick-look pictures of a run, so a person understands it at a glance:
//! heat maps (or curves) of every statistic over the scene's axes, a phase
//! portrait of the trajectories, a Poincaré portrait of the sections, and a
//! map of where trajectories stopped.

use std::f64::consts::PI;
use std::path::Path;

use anyhow::Result;

use crate::num::precision::Real;
use crate::output::plot::{self, Figure, Series};
use crate::plan::observations::Observations;
use crate::scene::Scene;

/// Is the grid geometric (so a log axis shows it evenly)?
fn is_log_spaced(v: &[f64]) -> bool {
    v.len() >= 3 && v.iter().all(|x| *x > 0.0) && {
        let r = v[1] / v[0];
        r > 1.0 + 1e-9 && v.windows(2).all(|w| ((w[1] / w[0]) / r - 1.0).abs() < 1e-6)
    }
}

fn f64s<R: Real>(v: &[R]) -> Vec<f64> {
    v.iter().map(|x| x.to_f64()).collect()
}

/// A curve of at most ~2·10⁵ points: longer ones are reduced to the minimum
/// and maximum of each bin (their envelope), which is all a picture shows.
fn envelope(x: &[f64], y: impl Fn(usize) -> f64) -> (Vec<f64>, Vec<f64>) {
    const BINS: usize = 100_000;
    let n = x.len();
    if n <= 2 * BINS {
        return (x.to_vec(), (0..n).map(y).collect());
    }
    let (mut xs, mut ys) = (Vec::with_capacity(2 * BINS), Vec::with_capacity(2 * BINS));
    for b in 0..BINS {
        let (lo, hi) = (b * n / BINS, (b + 1) * n / BINS);
        let (mut mn, mut mx) = ((f64::INFINITY, lo), (f64::NEG_INFINITY, lo));
        for i in lo..hi {
            let v = y(i);
            if v < mn.0 {
                mn = (v, i);
            }
            if v > mx.0 {
                mx = (v, i);
            }
        }
        let (a, b) = if mn.1 <= mx.1 { (mn, mx) } else { (mx, mn) };
        for (v, i) in [a, b] {
            xs.push(x[i]);
            ys.push(if v.is_finite() { v } else { f64::NAN });
        }
    }
    (xs, ys)
}

/// Draws the pictures into `dir`; returns the file names written.
pub fn draw<R: Real>(scene: &Scene, dir: &Path, d: &Observations<R>) -> Result<Vec<String>> {
    let mut files = vec![];
    let title = scene
        .title
        .clone()
        .unwrap_or_else(|| format!("{} ({}, {})", scene.name, scene.model.name(), scene.scheme));
    let shape = scene.shape();
    let n: usize = shape.iter().product();
    // The first two axes with more than one value span the maps; the others
    // are held at their first value.
    let varying: Vec<usize> = (0..shape.len()).filter(|k| shape[*k] > 1).collect();
    let strides = scene.strides();
    // Statistics as accessors on the run's arrays: the pictures read only
    // the slice they draw, never a copy of a whole (possibly 10⁷-long) array.
    type Stat<'a> = (String, String, Box<dyn Fn(usize) -> f64 + 'a>);
    let mut stats: Vec<Stat> = vec![];
    for (name, v) in &d.final_values {
        stats.push((
            format!("final_{name}"),
            format!("final {name}"),
            Box::new(move |i| v[i].to_f64()),
        ));
    }
    if !d.cycle_amplitude.is_empty() {
        stats.push((
            "cycle_amplitude".into(),
            "cycle amplitude".into(),
            Box::new(|i| d.cycle_amplitude[i].to_f64()),
        ));
        stats.push((
            "cycle_period".into(),
            "cycle period".into(),
            Box::new(|i| d.cycle_period[i].to_f64()),
        ));
    }
    if d.nonfinite_step.iter().any(|s| *s != 0) {
        stats.push((
            "status_step".into(),
            "step at which it stopped (NaN: ran to the end)".into(),
            Box::new(|i| {
                if d.nonfinite_step[i] == 0 {
                    f64::NAN
                } else {
                    d.nonfinite_step[i] as f64
                }
            }),
        ));
    }
    match varying.len() {
        0 => {}
        1 => {
            let k = varying[0];
            let ax = &scene.axes[k];
            for (file, label, v) in &stats {
                let (x, y) = envelope(&ax.values, |i| v(i * strides[k]));
                let fig = Figure {
                    title: &title,
                    x_label: &ax.name,
                    y_label: label,
                    ..Figure::default()
                };
                let name = format!("{file}.png");
                plot::lines(
                    &dir.join(&name),
                    &fig,
                    &[Series::new(label, &x, &y)],
                    is_log_spaced(&ax.values),
                    false,
                )?;
                files.push(name);
            }
        }
        _ => {
            let (kx, ky) = (varying[0], varying[1]);
            let (ax, ay) = (&scene.axes[kx], &scene.axes[ky]);
            for (file, label, v) in &stats {
                let mut grid = vec![f64::NAN; shape[kx] * shape[ky]];
                for ix in 0..shape[kx] {
                    for iy in 0..shape[ky] {
                        grid[ix * shape[ky] + iy] = v(ix * strides[kx] + iy * strides[ky]);
                    }
                }
                // Values far outside the bulk (a method blowing up, yet still
                // finite) would flatten the colours of everything else: clip
                // the colour range to Tukey's fences, the quartiles ± 3 IQR,
                // and say so.
                let mut label = label.clone();
                let mut sorted: Vec<f64> = grid.iter().copied().filter(|x| x.is_finite()).collect();
                sorted.sort_by(f64::total_cmp);
                if sorted.len() >= 8 {
                    let (q1, q3) = (sorted[sorted.len() / 4], sorted[3 * sorted.len() / 4]);
                    let (lo, hi) = (q1 - 3.0 * (q3 - q1), q3 + 3.0 * (q3 - q1));
                    if q3 > q1 && (sorted[0] < lo || sorted[sorted.len() - 1] > hi) {
                        for x in grid.iter_mut().filter(|x| x.is_finite()) {
                            *x = x.clamp(lo, hi);
                        }
                        label.push_str(" (colours clipped to quartiles ± 3 IQR)");
                    }
                }
                let label = &label;
                let positive = grid.iter().filter(|x| x.is_finite()).all(|x| *x > 0.0);
                let spread = {
                    let f: Vec<f64> = grid
                        .iter()
                        .copied()
                        .filter(|x| x.is_finite() && *x > 0.0)
                        .collect();
                    let (lo, hi) = f
                        .iter()
                        .fold((f64::INFINITY, 0.0f64), |a, x| (a.0.min(*x), a.1.max(*x)));
                    hi / lo
                };
                let fig = Figure {
                    title: &title,
                    x_label: &ax.name,
                    y_label: &ay.name,
                    ..Figure::default()
                };
                let name = format!("{file}.png");
                plot::heatmap(
                    &dir.join(&name),
                    &fig,
                    &ax.values,
                    &ay.values,
                    &grid,
                    label,
                    positive && spread > 1e3,
                    is_log_spaced(&ax.values),
                    is_log_spaced(&ay.values),
                )?;
                files.push(name);
            }
        }
    }

    // Phase portrait of the trajectories.
    if d.frames > 1 && !d.trajectory.is_empty() {
        let names: Vec<&str> = d.trajectory.iter().map(|(v, _)| v.as_str()).collect();
        let pick = |want: &Option<(String, String)>| -> Option<(usize, usize)> {
            match want {
                Some((x, y)) => Some((
                    names.iter().position(|n| n == x)?,
                    names.iter().position(|n| n == y)?,
                )),
                None => {
                    let state: Vec<usize> = (0..names.len()).filter(|k| names[*k] != "t").collect();
                    match state.len() {
                        0 => None,
                        1 => Some((
                            names.iter().position(|n| *n == "t").unwrap_or(state[0]),
                            state[0],
                        )),
                        _ => Some((state[0], state[1])),
                    }
                }
            }
        };
        let lienard = scene.plot.lienard_plane.then(|| {
            (
                names.iter().position(|n| *n == "q"),
                names.iter().position(|n| *n == "s"),
            )
        });
        let pair = match lienard {
            Some((Some(q), Some(s))) => Some((q, s)),
            _ => pick(&scene.plot.phase),
        };
        if let Some((jx, jy)) = pair {
            let count = scene.plot.max_trajectories.max(1).min(n);
            let chosen: Vec<usize> = (0..count).map(|c| c * n / count).collect();
            let xs: Vec<Vec<f64>> = chosen
                .iter()
                .map(|i| f64s(&d.trajectory[jx].1[i * d.frames..(i + 1) * d.frames]))
                .collect();
            let mut ys: Vec<Vec<f64>> = chosen
                .iter()
                .map(|i| f64s(&d.trajectory[jy].1[i * d.frames..(i + 1) * d.frames]))
                .collect();
            let mut y_label = names[jy].to_string();
            if lienard.is_some() {
                // Liénard plane: y = q − q³/3 − s/ε, ε of each trajectory.
                for (c, i) in chosen.iter().enumerate() {
                    let eps = scene.param_value("epsilon", *i, &strides);
                    for (y, q) in ys[c].iter_mut().zip(&xs[c]) {
                        *y = q - q * q * q / 3.0 - *y / eps;
                    }
                }
                y_label = "q − q³/3 − s/ε".into();
            }
            let labels: Vec<String> = chosen
                .iter()
                .map(|i| trajectory_label(scene, *i, &strides))
                .collect();
            let series: Vec<Series> = (0..chosen.len())
                .map(|c| Series::new(&labels[c], &xs[c], &ys[c]))
                .collect();
            let fig = Figure {
                title: &title,
                x_label: names[jx],
                y_label: &y_label,
                ..Figure::default()
            };
            plot::lines(&dir.join("trajectory.png"), &fig, &series, false, false)?;
            files.push("trajectory.png".into());
        }
    }

    // Poincaré portrait.
    if d.max_points > 0 && d.poincare.len() >= 2 {
        let names: Vec<&str> = d.poincare.iter().map(|(v, _)| v.as_str()).collect();
        let (jx, jy) = match &scene.plot.poincare {
            Some((x, y)) => (
                names.iter().position(|n| n == x).unwrap_or(0),
                names.iter().position(|n| n == y).unwrap_or(1),
            ),
            None => {
                let state: Vec<usize> = (0..names.len()).filter(|k| names[*k] != "t").collect();
                if state.len() >= 2 {
                    (state[0], state[1])
                } else {
                    (0, 1)
                }
            }
        };
        let wrap = |x: f64| match scene.plot.wrap_x.as_deref() {
            Some("2pi") => x.rem_euclid(2.0 * PI),
            Some("pi") => (x + PI).rem_euclid(2.0 * PI) - PI,
            _ => x,
        };
        // Few orbits: one colour each. Many: ten colour bands along the last
        // varying axis (the orbits of an area-preserving map fill the plane
        // evenly, so a single density would show no structure).
        let per_orbit = n <= 12;
        let band_axis = varying.last().copied();
        let bands = if per_orbit {
            n
        } else if band_axis.is_some() {
            10
        } else {
            1
        };
        let band_of = |i: usize| match (per_orbit, band_axis) {
            (true, _) => i,
            (false, Some(k)) => (i / strides[k]) % shape[k] * bands / shape[k],
            (false, None) => 0,
        };
        let mut xs: Vec<Vec<f64>> = vec![vec![]; bands];
        let mut ys: Vec<Vec<f64>> = vec![vec![]; bands];
        for i in 0..n {
            let k = (d.poincare_count[i] as usize).min(d.max_points);
            let b = band_of(i);
            let (x, y) = (&mut xs[b], &mut ys[b]);
            for p in 0..k {
                x.push(wrap(d.poincare[jx].1[i * d.max_points + p].to_f64()));
                y.push(d.poincare[jy].1[i * d.max_points + p].to_f64());
            }
        }
        let labels: Vec<String> = (0..xs.len())
            .map(|b| match (per_orbit, band_axis) {
                (true, _) => trajectory_label(scene, b, &strides),
                (false, Some(k)) => {
                    let v = &scene.axes[k].values;
                    let (lo, hi) = (
                        v[b * v.len() / bands],
                        v[((b + 1) * v.len() / bands).max(1) - 1],
                    );
                    format!("{} ∈ [{lo:.3}, {hi:.3}]", scene.axes[k].name)
                }
                (false, None) => format!("{n} orbits"),
            })
            .collect();
        let series: Vec<Series> = (0..xs.len())
            .map(|c| Series::new(&labels[c], &xs[c], &ys[c]))
            .collect();
        let x_range = match scene.plot.wrap_x.as_deref() {
            Some("2pi") => Some((0.0, 2.0 * PI)),
            Some("pi") => Some((-PI, PI)),
            _ => None,
        };
        let fig = Figure {
            title: &title,
            x_label: names[jx],
            y_label: names[jy],
            ..Figure::default()
        };
        plot::point_cloud(&dir.join("poincare.png"), &fig, &series, x_range, None)?;
        files.push("poincare.png".into());
    }
    // Bifurcation diagram: every section value against its trajectory's axis value.
    if let (Some((axis, var)), true) = (&scene.plot.bifurcation, d.max_points > 0) {
        let k = scene.axes.iter().position(|a| &a.name == axis);
        let j = d.poincare.iter().position(|(v, _)| v == var);
        if let (Some(k), Some(j)) = (k, j) {
            let (mut xs, mut ys) = (vec![], vec![]);
            for i in 0..n {
                let a = scene.axes[k].values[(i / strides[k]) % shape[k]];
                for p in 0..(d.poincare_count[i] as usize).min(d.max_points) {
                    xs.push(a);
                    ys.push(d.poincare[j].1[i * d.max_points + p].to_f64());
                }
            }
            let fig = Figure {
                title: &title,
                x_label: axis,
                y_label: var,
                ..Figure::default()
            };
            plot::point_cloud(
                &dir.join("bifurcation.png"),
                &fig,
                &[Series::new(var, &xs, &ys)],
                None,
                None,
            )?;
            files.push("bifurcation.png".into());
        }
    }
    Ok(files)
}

/// "epsilon = 0.5, q = 2" for trajectory `i`.
fn trajectory_label(scene: &Scene, i: usize, strides: &[usize]) -> String {
    scene
        .axes
        .iter()
        .enumerate()
        .filter(|(_, a)| a.values.len() > 1)
        .map(|(k, a)| {
            format!(
                "{} = {:.4}",
                a.name,
                a.values[(i / strides[k]) % a.values.len()]
            )
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
        })
        .collect::<Vec<_>>()
        .join(", ")
}
