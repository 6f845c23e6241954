//! Gridded figures: heat maps and class maps, rasterised cell by cell.

use std::path::Path;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::axis::{extent, tf, Axis};
use super::canvas::{render, text_width};
use super::chart::{blit, build_chart, draw_frame, no_data, split_side, Frame};
use super::colorbar::ColorBar;
use super::colour::{put, rgb, viridis, NAN_GREY};
use super::figure::{Figure, HeatMap, PlotError, Rgb};

/// Cell boundaries along one grid axis (transformed coordinates): cell `k`
/// in sorted order spans `edges[k]..edges[k + 1]` and shows grid index
/// `index[k]`.
struct Cells {
    edges: Vec<f64>,
    index: Vec<usize>,
}

impl Cells {
    /// Edges at the midpoints between neighbours; the outer cells are as
    /// wide as their inner neighbour's half-distance on the outside. `None`
    /// when no grid value can be shown.
    fn new(v: &[f64], log: bool) -> Option<Self> {
        let mut pts: Vec<(f64, usize)> = v
            .iter()
            .enumerate()
            .filter_map(|(i, &x)| tf(log, x).map(|t| (t, i)))
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let n = pts.len();
        let first = pts.first()?.0;
        let last = pts.last()?.0;
        let mut edges = Vec::with_capacity(n + 1);
        if last - first > 0.0 {
            edges.push(first - 0.5 * (pts[1].0 - first));
            edges.extend(pts.windows(2).map(|p| 0.5 * p[0].0 + 0.5 * p[1].0));
            edges.push(last + 0.5 * (last - pts[n - 2].0));
        } else {
            // A single (possibly repeated) value: a cell of nominal width.
            let half = if log || first == 0.0 {
                0.5
            } else {
                0.05 * first.abs()
            };
            edges.push(first - half);
            edges.extend(std::iter::repeat_n(first, n.saturating_sub(1)));
            edges.push(first + half);
        }
        if !edges.iter().all(|e| e.is_finite()) {
            return None;
        }
        Some(Self {
            edges,
            index: pts.into_iter().map(|p| p.1).collect(),
        })
    }

    fn axis(&self, log: bool) -> Axis {
        let lo = self.edges.first().copied();
        let hi = self.edges.last().copied();
        Axis::new(log, lo.zip(hi), 0.0)
    }

    /// Grid index of the cell containing `t`.
    fn find(&self, t: f64) -> Option<usize> {
        let (lo, hi) = (*self.edges.first()?, *self.edges.last()?);
        if !(t >= lo && t <= hi) {
            return None;
        }
        let k = self.edges.partition_point(|&e| e <= t);
        let k = k.saturating_sub(1).min(self.index.len().saturating_sub(1));
        self.index.get(k).copied()
    }
}

/// Renders a gridded image: `cell(ix, iy)` gives the colour of grid cell
/// `(ix, iy)`; pixels outside every cell stay white.
fn grid_raster(
    f: &Frame,
    xa: &Axis,
    ya: &Axis,
    cx: &Cells,
    cy: &Cells,
    cell: impl Fn(usize, usize) -> Rgb,
) -> Vec<u8> {
    let (w, h) = (f.w(), f.h());
    let (cols, rows) = pixel_cells(f, xa, ya, cx, cy);
    // A cell spans several pixels where the image is finer than the grid:
    // its colour is computed once per run of pixels and a row of the same
    // cells is copied (per pixel, the colour map was 3 % of a 64 × 64
    // MEGNO run).
    let mut buf = vec![255u8; 3 * w * h];
    for (j, row) in rows.iter().enumerate() {
        let Some(iy) = *row else { continue };
        if j > 0 && rows[j - 1] == Some(iy) {
            buf.copy_within(3 * (j - 1) * w..3 * j * w, 3 * j * w);
            continue;
        }
        let mut last: Option<(usize, Rgb)> = None;
        for (i, col) in cols.iter().enumerate() {
            let Some(ix) = *col else { continue };
            let c = match last {
                Some((k, c)) if k == ix => c,
                _ => cell(ix, iy),
            };
            last = Some((ix, c));
            put(&mut buf, j * w + i, c);
        }
    }
    buf
}

/// The grid cell under each pixel's centre: by column (x) and by row (y,
/// top down); `None` outside every cell.
fn pixel_cells(
    f: &Frame,
    xa: &Axis,
    ya: &Axis,
    cx: &Cells,
    cy: &Cells,
) -> (Vec<Option<usize>>, Vec<Option<usize>>) {
    let (w, h) = (f.w(), f.h());
    let cols = (0..w)
        .map(|i| cx.find(xa.lo + (i as f64 + 0.5) / w as f64 * xa.span()))
        .collect();
    let rows = (0..h)
        .map(|j| cy.find(ya.hi - (j as f64 + 0.5) / h as f64 * ya.span()))
        .collect();
    (cols, rows)
}

fn check_grid(nx: usize, ny: usize, n: usize, what: &str) -> Result<(), PlotError> {
    match nx.checked_mul(ny) {
        Some(m) if m == n => Ok(()),
        _ => Err(PlotError::Input(format!(
            "{what} has {n} entries, but the grid is {nx} x {ny}"
        ))),
    }
}

/// What a cell without a value shows: the map's reason for cell `k`, else
/// the grey "NaN".
fn undefined_of<'a>(map: &HeatMap<'a>, k: usize) -> (&'a str, Rgb) {
    map.why
        .get(k)
        .and_then(|&r| map.undefined.get(usize::from(r)))
        .copied()
        .unwrap_or(("NaN", NAN_GREY))
}

/// The reasons that occur, in the order of `map.undefined` ("NaN" last).
fn undefined_present<'a>(map: &HeatMap<'a>) -> Vec<(&'a str, Rgb)> {
    let mut seen = vec![false; map.undefined.len() + 1];
    for (k, v) in map.values.iter().enumerate() {
        if !v.is_finite() {
            let r = map.why.get(k).map_or(usize::MAX, |&r| usize::from(r));
            seen[r.min(map.undefined.len())] = true;
        }
    }
    let mut all = map.undefined.to_vec();
    all.push(("NaN", NAN_GREY));
    all.into_iter()
        .zip(seen)
        .filter(|(_, s)| *s)
        .map(|(e, _)| e)
        .collect()
}

pub(super) fn heatmap_impl(path: &Path, fig: &Figure, map: &HeatMap) -> Result<(), PlotError> {
    let (x, y, values) = (map.x, map.y, map.values);
    let (log_color, x_log, y_log) = (map.log_color, map.x_log, map.y_log);
    check_grid(x.len(), y.len(), values.len(), "values")?;
    let ny = y.len();
    let cells = Cells::new(x, x_log).zip(Cells::new(y, y_log));
    let crange = extent(log_color, values.iter().copied());
    render(path, fig, |body, st| {
        let ca = Axis::new(log_color, crange, 0.0);
        let (_, bh) = body.dim_in_pixel();
        let cb = ColorBar::new(ca, map.label, undefined_present(map), f64::from(bh), st)
            .with_marks(map.marks);
        let (main, side) = split_side(body, cb.width(body, st));
        let (xa, ya) = match &cells {
            Some((cx, cy)) => (cx.axis(x_log), cy.axis(y_log)),
            None => (Axis::new(x_log, None, 0.0), Axis::new(y_log, None, 0.0)),
        };
        let (_chart, f) = build_chart(&main, st, fig, &xa, &ya, false, st.px(12.0))?;
        match &cells {
            Some((cx, cy)) if !values.is_empty() => {
                let colour = |k: usize| -> Rgb {
                    let v = values[k];
                    if !v.is_finite() {
                        undefined_of(map, k).1
                    } else if log_color && v <= 0.0 {
                        viridis(0.0)
                    } else {
                        let t = if log_color { v.log10() } else { v };
                        viridis(ca.frac(t))
                    }
                };
                let buf = grid_raster(&f, &xa, &ya, cx, cy, |ix, iy| {
                    let k = ix * ny + iy;
                    if k < values.len() {
                        colour(k)
                    } else {
                        NAN_GREY
                    }
                });
                blit(&main, &f, buf)?;
            }
            _ => no_data(&main, &f, st)?,
        }
        draw_frame(&main, &f)?;
        cb.draw(&side, st, &f)
    })
}

#[allow(clippy::too_many_arguments)]
pub(super) fn class_map_impl(
    path: &Path,
    fig: &Figure,
    x: &[f64],
    y: &[f64],
    classes: &[u8],
    legend: &[(&str, Rgb)],
    x_log: bool,
    y_log: bool,
) -> Result<(), PlotError> {
    check_grid(x.len(), y.len(), classes.len(), "classes")?;
    let ny = y.len();
    let cells = Cells::new(x, x_log).zip(Cells::new(y, y_log));
    let has_unknown = classes.iter().any(|&c| usize::from(c) >= legend.len());
    render(path, fig, |body, st| {
        let font = st.legend();
        let swatch = st.px(18.0);
        let mut entries: Vec<(&str, Rgb)> = legend.to_vec();
        if has_unknown {
            entries.push(("unknown", NAN_GREY));
        }
        let text_w = entries
            .iter()
            .map(|(name, _)| text_width(body, name, &font))
            .max()
            .unwrap_or(0);
        let side_w = if entries.is_empty() {
            st.px(10.0)
        } else {
            st.px(24.0) + swatch + st.px(8.0) + text_w + st.px(12.0)
        };
        let (main, side) = split_side(body, side_w);
        let (xa, ya) = match &cells {
            Some((cx, cy)) => (cx.axis(x_log), cy.axis(y_log)),
            None => (Axis::new(x_log, None, 0.0), Axis::new(y_log, None, 0.0)),
        };
        let (_chart, f) = build_chart(&main, st, fig, &xa, &ya, false, st.px(12.0))?;
        match &cells {
            Some((cx, cy)) if !classes.is_empty() => {
                let buf = grid_raster(&f, &xa, &ya, cx, cy, |ix, iy| {
                    classes
                        .get(ix * ny + iy)
                        .and_then(|&c| legend.get(usize::from(c)))
                        .map_or(NAN_GREY, |e| e.1)
                });
                blit(&main, &f, buf)?;
            }
            _ => no_data(&main, &f, st)?,
        }
        draw_frame(&main, &f)?;
        // Legend panel: one swatch and name per entry, top-aligned with the map.
        let (_, sy) = side.get_base_pixel();
        let row = st.px(28.0);
        let left = st.px(24.0);
        let style = font.pos(Pos::new(HPos::Left, VPos::Center));
        for (k, (name, c)) in entries.iter().enumerate() {
            let top = f.y0 - sy + k as i32 * row;
            side.draw(&Rectangle::new(
                [(left, top), (left + swatch, top + swatch)],
                rgb(*c).filled(),
            ))?;
            side.draw(&Rectangle::new(
                [(left, top), (left + swatch, top + swatch)],
                RGBColor(80, 80, 80).stroke_width(1),
            ))?;
            side.draw_text(name, &style, (left + swatch + st.px(8.0), top + swatch / 2))?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pixel as the colour of its own cell, called per pixel.
    fn per_pixel(f: &Frame, xa: &Axis, ya: &Axis, cx: &Cells, cy: &Cells) -> Vec<u8> {
        let (w, h) = (f.w(), f.h());
        let (cols, rows) = pixel_cells(f, xa, ya, cx, cy);
        let mut buf = vec![255u8; 3 * w * h];
        for (j, y) in rows.iter().enumerate() {
            for (i, x) in cols.iter().enumerate() {
                if let (Some(ix), Some(iy)) = (*x, *y) {
                    put(&mut buf, j * w + i, colour_of(ix, iy));
                }
            }
        }
        buf
    }

    fn colour_of(ix: usize, iy: usize) -> Rgb {
        (
            (7 * ix + 3 * iy) as u8,
            (ix * iy) as u8,
            (ix + 11 * iy) as u8,
        )
    }

    /// The runs of pixels of one cell and the copied rows are the colours
    /// each pixel would get by itself: grids coarser and finer than the
    /// image, the y axis wider than its cells (rows outside every cell).
    #[test]
    fn grid_raster_is_every_pixel_its_cell() {
        let frame = Frame {
            x0: 0,
            x1: 97,
            y0: 0,
            y1: 61,
        };
        for (nx, ny) in [(5, 3), (40, 17), (300, 200)] {
            let xs: Vec<f64> = (0..nx).map(|i| i as f64 * 0.5).collect();
            let ys: Vec<f64> = (0..ny).map(|i| 1.0 + (i * i) as f64).collect();
            let (cx, cy) = (
                Cells::new(&xs, false).unwrap(),
                Cells::new(&ys, false).unwrap(),
            );
            let cells = cy.axis(false);
            let wider = (cells.lo - 0.3 * cells.span(), cells.hi + 0.1 * cells.span());
            let (xa, ya) = (cx.axis(false), Axis::new(false, Some(wider), 0.0));
            let fast = grid_raster(&frame, &xa, &ya, &cx, &cy, colour_of);
            assert_eq!(fast, per_pixel(&frame, &xa, &ya, &cx, &cy), "{nx} x {ny}");
            assert!(fast.iter().any(|&b| b != 255), "{nx} x {ny}: no cell drawn");
        }
    }
}
