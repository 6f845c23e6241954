//! Line plots: one polyline per series.

use std::path::Path;

use plotters::prelude::*;

use super::axis::{extent, tf, Axis};
use super::canvas::render;
use super::chart::{build_chart, draw_frame, no_data};
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
    let with_legend = series.len() > 1 && !many && series.iter().any(|s| !s.name.is_empty());
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
                    chart.draw_series(LineSeries::new(run.iter().copied(), style))?;
                }
                if with_legend {
                    occ.add_run(run, &xa, &ya);
                }
            }
            if with_legend && !s.name.is_empty() {
                let len = st.px(26.0);
                chart
                    .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
                    .label(s.name)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + len, y)], style));
            }
        }
        if prepared.iter().all(|r| r.runs.is_empty()) {
            no_data(body, &f, st)?;
        }
        draw_frame(body, &f)?;
        if with_legend {
            let names: Vec<&str> = series
                .iter()
                .map(|s| s.name)
                .filter(|n| !n.is_empty())
                .collect();
            let pos = legend_position(&occ, &names, body, st, &f);
            legend_box(&mut chart, st, pos)?;
        }
        Ok(())
    })
}
