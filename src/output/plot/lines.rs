//! Line plots: one polyline per series.

use std::path::Path;

use plotters::prelude::*;

use super::axis::{extent, tf, Axis};
use super::canvas::render;
use super::chart::{build_chart, draw_frame, no_data, Chart};
use super::colour::rgb;
use super::figure::{check_series, palette, Figure, PlotError, Series};
use super::legend::{legend_box, legend_position, Occupancy};

/// Series counts from which `lines` drops the legend and thins the lines.
pub(super) const MANY_SERIES: usize = 12;

/// A series split into runs of drawable points (transformed coordinates).
pub(super) struct Runs {
    pub(super) runs: Vec<Vec<(f64, f64)>>,
}

impl Runs {
    pub(super) fn new(s: &Series, x_log: bool, y_log: bool) -> Self {
        let mut runs = vec![];
        let mut cur: Vec<(f64, f64)> = vec![];
        for (&x, &y) in s.x.iter().zip(s.y.iter()) {
            match tf(x_log, x).zip(tf(y_log, y)) {
                Some(p) => cur.push(p),
                None => {
                    if !cur.is_empty() {
                        runs.push(std::mem::take(&mut cur));
                    }
                }
            }
        }
        if !cur.is_empty() {
            runs.push(cur);
        }
        Self { runs }
    }

    pub(super) fn points(&self) -> impl Iterator<Item = &(f64, f64)> {
        self.runs.iter().flatten()
    }
}

/// Draws a run as pixel paths cut where it turns back by more than 120°:
/// plotters mitres the joins of a thick line, and the inner mitre of a
/// hairpin between short segments reaches far past both (a straight spike
/// across the picture, beyond the frame); a cut leaves a square end.
fn draw_run(chart: &Chart, run: &[(f64, f64)], style: ShapeStyle) -> Result<(), PlotError> {
    let area = chart.plotting_area().strip_coord_spec();
    let (bx, by) = area.get_base_pixel();
    let mut path: Vec<(i32, i32)> = vec![];
    for p in run {
        let (x, y) = chart.backend_coord(p);
        let q = (x - bx, y - by);
        match path[..] {
            [.., b] if b == q => continue,
            [.., a, b] if turns_back(a, b, q) => {
                area.draw(&PathElement::new(std::mem::take(&mut path), style))?;
                path.push(b);
            }
            _ => {}
        }
        path.push(q);
    }
    if path.len() > 1 {
        area.draw(&PathElement::new(path, style))?;
    }
    Ok(())
}

/// Whether the path a → b → c turns by more than 120°.
fn turns_back(a: (i32, i32), b: (i32, i32), c: (i32, i32)) -> bool {
    let u = (f64::from(b.0 - a.0), f64::from(b.1 - a.1));
    let v = (f64::from(c.0 - b.0), f64::from(c.1 - b.1));
    let dot = u.0 * v.0 + u.1 * v.1;
    dot < -0.5 * (u.0.hypot(u.1) * v.0.hypot(v.1))
}

pub(super) fn lines_impl(
    path: &Path,
    fig: &Figure,
    series: &[Series],
    x_log: bool,
    y_log: bool,
) -> Result<(), PlotError> {
    check_series(series)?;
    let prepared: Vec<Runs> = series.iter().map(|s| Runs::new(s, x_log, y_log)).collect();
    let ext_x = extent(false, prepared.iter().flat_map(|r| r.points().map(|p| p.0)));
    let ext_y = extent(false, prepared.iter().flat_map(|r| r.points().map(|p| p.1)));
    let xa = Axis::new(x_log, ext_x, 0.03);
    let ya = Axis::new(y_log, ext_y, 0.03);
    let many = series.len() >= MANY_SERIES;
    // One legend entry per name: series that share a name (and, from the
    // caller, a colour) are one group.
    let mut names: Vec<&str> = vec![];
    for s in series.iter().filter(|s| !s.name.is_empty()) {
        if !names.contains(&s.name) {
            names.push(s.name);
        }
    }
    let with_legend = series.len() > 1 && (2..MANY_SERIES).contains(&names.len());
    render(path, fig, |body, st| {
        let (mut chart, f) = build_chart(body, st, fig, &xa, &ya, true, st.px(28.0))?;
        let width = if many { 1 } else { st.px(2.0) as u32 };
        let mut occ = Occupancy::new();
        for (i, (s, r)) in series.iter().zip(&prepared).enumerate() {
            let c = rgb(s.color.unwrap_or_else(|| palette(i)));
            let style = if many {
                c.mix(0.75).stroke_width(width)
            } else {
                c.stroke_width(width)
            };
            for run in &r.runs {
                if run.len() == 1 {
                    // A lone point has no line; show it as a dot.
                    chart
                        .draw_series(run.iter().map(|&p| Circle::new(p, st.px(2.5), c.filled())))?;
                } else {
                    draw_run(&chart, run, style)?;
                }
                if with_legend {
                    occ.add_run(run, &xa, &ya);
                }
            }
            let first = series[..i].iter().all(|o| o.name != s.name);
            if with_legend && !s.name.is_empty() && first {
                // Thin lines of many series still get a legend line wide
                // enough to show their colour.
                let len = st.px(26.0);
                let key = if many {
                    c.stroke_width(st.px(3.0) as u32)
                } else {
                    style
                };
                chart
                    .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
                    .label(s.name)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + len, y)], key));
            }
        }
        if prepared.iter().all(|r| r.runs.is_empty()) {
            no_data(body, &f, st)?;
        }
        draw_frame(body, &f)?;
        if with_legend {
            let pos = legend_position(&occ, &names, body, st, &f);
            legend_box(&mut chart, st, pos)?;
        }
        Ok(())
    })
}
