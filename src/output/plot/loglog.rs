//! Log–log lines with markers and dashed reference slopes.

use std::path::Path;

use plotters::chart::SeriesAnno;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::axis::{extent, merge, tf, Axis};
use super::canvas::{render, Area, Style};
use super::chart::{build_chart, draw_frame, no_data, Chart, Frame};
use super::colour::rgb;
use super::figure::{check_series, palette, Figure, PlotError, Series, Slope};
use super::legend::{legend_box, legend_position, Occupancy};
use super::lines::{Runs, MANY_SERIES};

/// Draws marker `kind` (circle, square, triangle, diamond, cross, cycling)
/// at each point; shapes as well as colours tell series apart, which
/// survives greyscale printing. One concrete element type per arm, because
/// plotters' `DynElement` cannot be drawn as a series on a backend that
/// borrows its output path.
fn draw_markers(
    chart: &mut Chart,
    run: &[(f64, f64)],
    kind: usize,
    r: i32,
    style: ShapeStyle,
) -> Result<(), PlotError> {
    let pts = run.iter().copied();
    match kind % 5 {
        0 => {
            chart.draw_series(pts.map(|p| Circle::new(p, r, style)))?;
        }
        1 => {
            chart.draw_series(
                pts.map(|p| EmptyElement::at(p) + Rectangle::new([(-r, -r), (r, r)], style)),
            )?;
        }
        2 => {
            chart.draw_series(pts.map(|p| TriangleMarker::new(p, r + 1, style)))?;
        }
        3 => {
            chart
                .draw_series(pts.map(|p| EmptyElement::at(p) + Polygon::new(diamond(r), style)))?;
        }
        _ => {
            chart.draw_series(pts.map(|p| Cross::new(p, r, style.stroke_width(2))))?;
        }
    }
    Ok(())
}

fn diamond(r: i32) -> Vec<(i32, i32)> {
    vec![(0, -r - 1), (r + 1, 0), (0, r + 1), (-r - 1, 0)]
}

/// Clips the segment `p0..p1` to the axes' box (Liang–Barsky).
fn clip(p0: (f64, f64), p1: (f64, f64), xa: &Axis, ya: &Axis) -> Option<((f64, f64), (f64, f64))> {
    let (dx, dy) = (p1.0 - p0.0, p1.1 - p0.1);
    let mut t0: f64 = 0.0;
    let mut t1: f64 = 1.0;
    for (p, q) in [
        (-dx, p0.0 - xa.lo),
        (dx, xa.hi - p0.0),
        (-dy, p0.1 - ya.lo),
        (dy, ya.hi - p0.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    if t0.is_nan() || t1.is_nan() || t0 >= t1 {
        return None;
    }
    Some((
        (p0.0 + t0 * dx, p0.1 + t0 * dy),
        (p0.0 + t1 * dx, p0.1 + t1 * dy),
    ))
}

/// A point in transformed (axis) coordinates.
type Pt = (f64, f64);

/// A rectangle in pixels relative to the plotting area: left, top, right,
/// bottom.
type PxRect = (i32, i32, i32, i32);

/// Pixel box (relative to the plotting area) for a slope label of `size`:
/// beside a point of the line `p0..p1`, on the side away from the line
/// (upper left or lower right of a rising line, upper right or lower left
/// of a falling one), at the position that covers the fewest occupied cells
/// and stays inside the plot.
#[allow(clippy::too_many_arguments)]
fn slope_label_box(
    occ: &Occupancy,
    slope: f64,
    p0: (f64, f64),
    p1: (f64, f64),
    (tw, th): (i32, i32),
    xa: &Axis,
    ya: &Axis,
    f: &Frame,
    st: &Style,
) -> PxRect {
    let (w, h) = (f.w() as i32, f.h() as i32);
    let d = st.px(6.0);
    let mut best = ((0, 0, tw, th), usize::MAX);
    for t in [0.8, 0.2, 0.65, 0.35, 0.5, 0.9, 0.1] {
        let (x, y) = (p0.0 + t * (p1.0 - p0.0), p0.1 + t * (p1.1 - p0.1));
        let px = (xa.frac(x) * f64::from(w)) as i32;
        let py = ((1.0 - ya.frac(y)) * f64::from(h)) as i32;
        let boxes = if slope >= 0.0 {
            [(px - d - tw, py - d - th), (px + d, py + d)]
        } else {
            [(px + d, py - d - th), (px - d - tw, py + d)]
        };
        for (x0, y0) in boxes {
            let r = (x0, y0, x0 + tw, y0 + th);
            let inside = r.0 >= 0 && r.1 >= 0 && r.2 <= w && r.3 <= h;
            let score = occ.score(r, w, h) + if inside { 0 } else { 1_000_000 };
            if score < best.1 {
                best = (r, score);
            }
        }
    }
    best.0
}

/// A reference slope with its line clipped to the axes' box.
type SlopeLine<'s> = (&'s Slope, Pt, Pt);

/// Colour of the reference slopes and their labels.
const SLOPE_GREY: RGBColor = RGBColor(80, 80, 80);

/// Legend entry of series `kind`: a line with the series' marker on it.
fn marker_legend<'c, 'b: 'c>(
    anno: &mut SeriesAnno<'c, BitMapBackend<'b>>,
    kind: usize,
    line: ShapeStyle,
    fill: ShapeStyle,
    r: i32,
    len: i32,
) {
    let m = (len / 2, 0);
    let path = move || PathElement::new(vec![(0, 0), (len, 0)], line);
    match kind % 5 {
        0 => anno.legend(move |p| EmptyElement::at(p) + path() + Circle::new(m, r, fill)),
        1 => anno.legend(move |p| {
            EmptyElement::at(p) + path() + Rectangle::new([(m.0 - r, -r), (m.0 + r, r)], fill)
        }),
        2 => {
            anno.legend(move |p| EmptyElement::at(p) + path() + TriangleMarker::new(m, r + 1, fill))
        }
        3 => anno.legend(move |p| {
            let d = diamond(r)
                .into_iter()
                .map(|q| (q.0 + m.0, q.1))
                .collect::<Vec<_>>();
            EmptyElement::at(p) + path() + Polygon::new(d, fill)
        }),
        _ => anno
            .legend(move |p| EmptyElement::at(p) + path() + Cross::new(m, r, fill.stroke_width(2))),
    };
}

/// A log–log chart ready to draw: the series split into drawable runs, the
/// usable reference slopes, and axes fixed before the layout.
struct LogLog<'s, 'a> {
    series: &'s [Series<'a>],
    prepared: Vec<Runs>,
    /// Slopes with a finite slope and an anchor that has a logarithm.
    slopes: Vec<&'s Slope>,
    has_data: bool,
    with_legend: bool,
    xa: Axis,
    ya: Axis,
}

impl<'s, 'a> LogLog<'s, 'a> {
    fn new(series: &'s [Series<'a>], slopes: &'s [Slope]) -> Self {
        let prepared: Vec<Runs> = series.iter().map(|s| Runs::new(s, true, true)).collect();
        let has_data = prepared.iter().any(|r| !r.runs.is_empty());
        let slopes: Vec<&Slope> = slopes
            .iter()
            .filter(|s| {
                s.slope.is_finite()
                    && tf(true, s.anchor.0).is_some()
                    && tf(true, s.anchor.1).is_some()
            })
            .collect();
        // Anchors count towards the range only alongside data: alone they would
        // make a chart of reference lines with nothing to compare.
        let anchors = || slopes.iter().filter(|_| has_data).map(|s| s.anchor);
        let ext_x = merge(
            extent(false, prepared.iter().flat_map(|r| r.points().map(|p| p.0))),
            extent(true, anchors().map(|a| a.0)),
        );
        let ext_y = merge(
            extent(false, prepared.iter().flat_map(|r| r.points().map(|p| p.1))),
            extent(true, anchors().map(|a| a.1)),
        );
        let with_legend = series.iter().any(|s| !s.name.is_empty()) && series.len() < MANY_SERIES;
        Self {
            series,
            prepared,
            slopes,
            has_data,
            with_legend,
            xa: Axis::new(true, ext_x, 0.03),
            ya: Axis::new(true, ext_y, 0.03),
        }
    }

    /// Lays out the chart on `body` and draws slopes, data and legend.
    fn draw(&self, body: &Area, st: &Style, fig: &Figure) -> Result<(), PlotError> {
        let (xa, ya) = (&self.xa, &self.ya);
        let (mut chart, f) = build_chart(body, st, fig, xa, ya, true, st.px(28.0))?;
        // Occupancy of the data first: slope labels are placed to avoid it.
        let mut occ = Occupancy::new();
        for run in self.prepared.iter().flat_map(|r| r.runs.iter()) {
            occ.add_run(run, xa, ya);
        }
        // Reference slopes before the data, so the data is drawn over them.
        let lines = self.slope_lines();
        let placed = self.draw_slopes(&mut chart, body, st, &f, &lines, &occ)?;
        // The legend then avoids the slopes and their labels as well.
        for (_, p0, p1) in &lines {
            occ.add_run(&[*p0, *p1], xa, ya);
        }
        for r in &placed {
            occ.mark_rect(*r, f.w(), f.h());
        }
        self.draw_data(&mut chart, st)?;
        if !self.has_data {
            no_data(body, &f, st)?;
        }
        draw_frame(body, &f)?;
        if self.with_legend && self.has_data {
            let names: Vec<&str> = self
                .series
                .iter()
                .map(|s| s.name)
                .filter(|n| !n.is_empty())
                .collect();
            let pos = legend_position(&occ, &names, body, st, &f);
            legend_box(&mut chart, st, pos)?;
        }
        Ok(())
    }

    /// The slopes' lines through their anchors, clipped to the axes' box;
    /// none without data.
    fn slope_lines(&self) -> Vec<SlopeLine<'s>> {
        if !self.has_data {
            return vec![];
        }
        let (xa, ya) = (&self.xa, &self.ya);
        self.slopes
            .iter()
            .filter_map(|s| {
                let (ax, ay) = (s.anchor.0.log10(), s.anchor.1.log10());
                let line = |tx: f64| (tx, ay + s.slope * (tx - ax));
                clip(line(xa.lo), line(xa.hi), xa, ya).map(|(p0, p1)| (*s, p0, p1))
            })
            .collect()
    }

    /// Draws each slope dashed with its label beside it, the label placed
    /// away from the data, the other slopes and the labels already placed.
    /// Returns the labels' boxes.
    fn draw_slopes(
        &self,
        chart: &mut Chart,
        body: &Area,
        st: &Style,
        f: &Frame,
        lines: &[SlopeLine],
        occ: &Occupancy,
    ) -> Result<Vec<PxRect>, PlotError> {
        let label_font = st.font(15.0);
        let mut placed: Vec<PxRect> = vec![];
        for (k, (s, p0, p1)) in lines.iter().enumerate() {
            chart.draw_series(DashedLineSeries::new(
                [*p0, *p1],
                st.px(9.0),
                st.px(6.0),
                SLOPE_GREY.stroke_width(st.px(1.5) as u32),
            ))?;
            let mut o = occ.clone();
            for (j, (_, q0, q1)) in lines.iter().enumerate() {
                if j != k {
                    o.add_run(&[*q0, *q1], &self.xa, &self.ya);
                }
            }
            for r in &placed {
                o.mark_rect(*r, f.w(), f.h());
            }
            let size = body
                .estimate_text_size(&s.label, &label_font)
                .map(|(w, h)| (w as i32, h as i32))
                .unwrap_or((st.fpx(60.0), st.fpx(15.0)));
            let r = slope_label_box(&o, s.slope, *p0, *p1, size, &self.xa, &self.ya, f, st);
            placed.push(r);
            draw_slope_label(body, st, f, &s.label, &label_font, r, size)?;
        }
        Ok(placed)
    }

    /// Each series as a line with markers, and its legend entry.
    fn draw_data<'c, 'b: 'c>(
        &self,
        chart: &mut Chart<'c, 'b>,
        st: &Style,
    ) -> Result<(), PlotError> {
        let r = st.px(4.0);
        let width = st.px(2.0) as u32;
        for (i, (s, runs)) in self.series.iter().zip(&self.prepared).enumerate() {
            let c = rgb(s.color.unwrap_or_else(|| palette(i)));
            let line = c.stroke_width(width);
            for run in &runs.runs {
                if run.len() > 1 {
                    chart.draw_series(LineSeries::new(run.iter().copied(), line))?;
                }
                draw_markers(chart, run, i, r, c.filled())?;
            }
            if self.with_legend && !s.name.is_empty() {
                let anno = chart
                    .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
                    .label(s.name);
                marker_legend(anno, i, line, c.filled(), r, st.px(30.0));
            }
        }
        Ok(())
    }
}

/// Writes a slope's label at box `r` (relative to the plotting area) on a
/// translucent white patch, so it stays legible over grid lines.
fn draw_slope_label(
    body: &Area,
    st: &Style,
    f: &Frame,
    label: &str,
    font: &TextStyle,
    r: PxRect,
    size: (i32, i32),
) -> Result<(), PlotError> {
    let (bx, by) = body.get_base_pixel();
    let pad = st.px(2.0);
    let (x, y) = (f.x0 + r.0 - bx, f.y0 + r.1 - by);
    body.draw(&Rectangle::new(
        [(x - pad, y - pad), (x + size.0 + pad, y + size.1 + pad)],
        WHITE.mix(0.8).filled(),
    ))?;
    body.draw_text(
        label,
        &font.color(&SLOPE_GREY).pos(Pos::new(HPos::Left, VPos::Top)),
        (x, y),
    )?;
    Ok(())
}

pub(super) fn loglog_impl(
    path: &Path,
    fig: &Figure,
    series: &[Series],
    slopes: &[Slope],
) -> Result<(), PlotError> {
    check_series(series)?;
    let chart = LogLog::new(series, slopes);
    render(path, fig, |body, st| chart.draw(body, st, fig))
}
