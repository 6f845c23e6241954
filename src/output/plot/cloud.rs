//! Point clouds, rasterised as a density image.

use std::path::Path;

use plotters::prelude::*;

use super::axis::{merge, Axis};
use super::canvas::{render, Area, Style};
use super::chart::{blit, build_chart, chart_ticks, draw_frame, no_data, split_side, Chart, Frame};
use super::colorbar::ColorBar;
use super::colour::{blend, put, rgb, viridis, BG, GRID};
use super::figure::{check_series, palette, Figure, PlotError, Rgb, Series};
use super::legend::{legend_box, legend_position, Occupancy};

/// Fixed range from the caller if usable, otherwise the padded data extent.
fn cloud_axis(fixed: Option<(f64, f64)>, data: Option<(f64, f64)>) -> Axis {
    match fixed_range(fixed) {
        Some(range) => Axis::new(false, Some(range), 0.0),
        None => Axis::new(false, data, 0.03),
    }
}

/// Calls `hit(pixel index, point index)` for every point of `s` inside the
/// frame. The loop is the hot path of `point_cloud` (10⁸ points): no
/// allocation, one multiply-add per coordinate, NaN and ±∞ rejected by the
/// range tests.
fn bin_points(
    s: &Series,
    xa: &Axis,
    ya: &Axis,
    w: usize,
    h: usize,
    mut hit: impl FnMut(usize, usize),
) {
    let (wf, hf) = (w as f64, h as f64);
    let sx = wf / xa.span();
    let sy = hf / ya.span();
    let (x0, y1) = (xa.lo, ya.hi);
    for (p, (&x, &y)) in s.x.iter().zip(s.y.iter()).enumerate() {
        let fx = (x - x0) * sx;
        let fy = (y1 - y) * sy;
        if fx >= 0.0 && fx <= wf && fy >= 0.0 && fy <= hf {
            let i = (fx as usize).min(w - 1);
            let j = (fy as usize).min(h - 1);
            hit(j * w + i, p);
        }
    }
}

/// A data range `(lo, hi)`, `None` when there is no data.
type Extent = Option<(f64, f64)>;

/// `range` if it can be used as an axis range as given: finite, not empty.
fn fixed_range(range: Option<(f64, f64)>) -> Option<(f64, f64)> {
    range.filter(|&(a, b)| a.is_finite() && b.is_finite() && a != b)
}

/// Extents over the points with both coordinates finite, so that a diverged
/// trajectory (x finite, y = NaN) does not stretch the axes.
fn finite_extents(series: &[Series]) -> (Extent, Extent) {
    let mut ext_x = None;
    let mut ext_y = None;
    for s in series {
        let (mut xl, mut xh, mut yl, mut yh) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for (&x, &y) in s.x.iter().zip(s.y.iter()) {
            if x.is_finite() && y.is_finite() {
                xl = xl.min(x);
                xh = xh.max(x);
                yl = yl.min(y);
                yh = yh.max(y);
            }
        }
        if xl <= xh {
            ext_x = merge(ext_x, Some((xl, xh)));
            ext_y = merge(ext_y, Some((yl, yh)));
        }
    }
    (ext_x, ext_y)
}

/// Hits per pixel of the plotting area (row-major, `w`×`h`) and, when
/// colouring by series, the series with the most hits in each pixel.
struct Bins {
    w: usize,
    h: usize,
    counts: Vec<u32>,
    top: Vec<u32>,
    /// Colouring by value: the largest value of each pixel's points.
    value: Vec<f64>,
}

impl Bins {
    fn max(&self) -> u32 {
        self.counts.iter().copied().max().unwrap_or(0)
    }

    fn occupied(&self) -> usize {
        self.counts.iter().filter(|&&c| c > 0).count()
    }

    /// Index of the fullest pixel among `(i, j)` and its eight neighbours,
    /// if any of them is hit; the first one in row order wins ties.
    fn fullest_around(&self, i: usize, j: usize) -> Option<usize> {
        let (w, h) = (self.w, self.h);
        let mut best: Option<(u32, usize)> = None;
        for dj in [-1i64, 0, 1] {
            for di in [-1i64, 0, 1] {
                let (ni, nj) = (i as i64 + di, j as i64 + dj);
                if ni < 0 || nj < 0 || ni >= w as i64 || nj >= h as i64 {
                    continue;
                }
                let nk = nj as usize * w + ni as usize;
                if self.counts[nk] > best.map_or(0, |b| b.0) {
                    best = Some((self.counts[nk], nk));
                }
            }
        }
        best.map(|(_, nk)| nk)
    }
}

/// Axis of the colour bar of values on `range`.
fn value_axis(range: (f64, f64)) -> Axis {
    Axis::new(false, Some(range), 0.0)
}

/// Axis of the colour bar: log10 of the points per pixel, up to `max`.
fn count_axis(max: u32) -> Axis {
    Axis {
        log: true,
        lo: 0.0,
        hi: f64::from(max.max(2)).log10(),
    }
}

/// Points coloured by a value each (a Poincaré portrait by the orbit's
/// FLI): the values, the colour range and the colour bar's label.
pub struct ByValue<'a> {
    pub values: &'a [f64],
    pub range: (f64, f64),
    pub label: &'a str,
}

/// A point cloud ready to draw: axes fixed before the layout, one colour
/// per series.
struct Cloud<'s, 'a> {
    series: &'s [Series<'a>],
    by_value: Option<&'s ByValue<'a>>,
    colours: Vec<Rgb>,
    xa: Axis,
    ya: Axis,
    /// A single uncoloured series is shaded by density (with a colour bar);
    /// otherwise each pixel takes the colour of the series with the most
    /// points there. (A mean of the colours would turn every pixel that
    /// several series share into one grey-brown that no legend entry shows.)
    density: bool,
}

impl<'s, 'a> Cloud<'s, 'a> {
    fn new(
        series: &'s [Series<'a>],
        by_value: Option<&'s ByValue<'a>>,
        x_range: Option<(f64, f64)>,
        y_range: Option<(f64, f64)>,
    ) -> Self {
        // The data extents are only scanned when some axis needs them.
        let (ext_x, ext_y) = if fixed_range(x_range).is_none() || fixed_range(y_range).is_none() {
            finite_extents(series)
        } else {
            (None, None)
        };
        Self {
            series,
            by_value,
            colours: series
                .iter()
                .enumerate()
                .map(|(i, s)| s.color.unwrap_or_else(|| palette(i)))
                .collect(),
            xa: cloud_axis(x_range, ext_x),
            ya: cloud_axis(y_range, ext_y),
            density: by_value.is_none()
                && series.len() == 1
                && series.iter().all(|s| s.color.is_none()),
        }
    }

    /// Lays out, rasterises and decorates the cloud on `body`.
    fn draw(&self, body: &Area, st: &Style, fig: &Figure) -> Result<(), PlotError> {
        let (main, side) = self.split_off_colour_bar(body, st);
        let (mut chart, f) = build_chart(&main, st, fig, &self.xa, &self.ya, true, st.px(28.0))?;
        let (w, h) = (f.w(), f.h());
        if w == 0 || h == 0 {
            return Ok(());
        }
        let bins = self.bin(w, h);
        let max = bins.max();
        let occupied = bins.occupied();
        let bg = self.grid_background(&main, st, w, h);
        blit(&main, &f, self.paint(&bins, &bg, max, occupied))?;
        if occupied == 0 {
            no_data(&main, &f, st)?;
        }
        draw_frame(&main, &f)?;

        let named = self.series.iter().any(|s| !s.name.is_empty());
        if !self.density && self.series.len() > 1 && named && occupied > 0 {
            self.draw_legend(&mut chart, &main, st, &f, &bins)?;
        }
        if let Some(side) = side {
            let height = f.h() as f64 + 110.0 * st.s;
            let cb = match self.by_value {
                Some(v) => ColorBar::new(value_axis(v.range), v.label, vec![], height, st),
                None => ColorBar::new(count_axis(max), "points per pixel", vec![], height, st),
            };
            cb.draw(&side, st, &f)?;
        }
        Ok(())
    }

    /// The chart area and, for a density image, the colour bar's side panel.
    /// The count range is only known after binning, which needs the layout;
    /// the bar is sized for labels up to "10⁹".
    fn split_off_colour_bar<'b>(
        &self,
        body: &Area<'b>,
        st: &Style,
    ) -> (Area<'b>, Option<Area<'b>>) {
        if !self.density && self.by_value.is_none() {
            return (body.clone(), None);
        }
        let probe = ColorBar::new(
            Axis::new(true, Some((0.0, 9.0)), 0.0),
            "points per pixel",
            vec![],
            750.0,
            st,
        );
        let w = probe.width(body, st);
        let (m, s) = split_side(body, w);
        (m, Some(s))
    }

    /// Counts the points per pixel of a `w`×`h` plotting area and, when
    /// colouring by series, finds each pixel's most frequent series.
    fn bin(&self, w: usize, h: usize) -> Bins {
        let (xa, ya) = (&self.xa, &self.ya);
        let mut counts = vec![0u32; w * h];
        if let Some(v) = self.by_value {
            let mut value = vec![f64::NEG_INFINITY; w * h];
            for s in self.series {
                bin_points(s, xa, ya, w, h, |k, p| {
                    counts[k] = counts[k].saturating_add(1);
                    // NaN (an orbit without a value) never wins.
                    value[k] = value[k].max(v.values[p]);
                });
            }
            return Bins {
                w,
                h,
                counts,
                top: vec![],
                value,
            };
        }
        if self.density {
            for s in self.series {
                bin_points(s, xa, ya, w, h, |k, _| {
                    counts[k] = counts[k].saturating_add(1);
                });
            }
            return Bins {
                w,
                h,
                counts,
                top: vec![],
                value: vec![],
            };
        }
        // Per series: its hits per pixel (and the pixels it touched, so
        // that only those are compared and reset), then the running winner.
        let (mut best, mut top) = (vec![0u32; w * h], vec![0u32; w * h]);
        let mut mine = vec![0u32; w * h];
        let mut touched: Vec<usize> = vec![];
        for (i, s) in self.series.iter().enumerate() {
            bin_points(s, xa, ya, w, h, |k, _| {
                if mine[k] == 0 {
                    touched.push(k);
                }
                mine[k] = mine[k].saturating_add(1);
            });
            for &k in &touched {
                counts[k] = counts[k].saturating_add(mine[k]);
                if mine[k] > best[k] || (mine[k] == best[k] && coin(k, i)) {
                    (best[k], top[k]) = (mine[k], i as u32);
                }
                mine[k] = 0;
            }
            touched.clear();
        }
        Bins {
            w,
            h,
            counts,
            top,
            value: vec![],
        }
    }

    /// Background with the major grid lines, since the blit covers the
    /// chart's own mesh.
    fn grid_background(&self, main: &Area, st: &Style, w: usize, h: usize) -> Vec<Rgb> {
        let mut bg = vec![BG; w * h];
        let (xt, yt) = chart_ticks(main, st, &self.xa, &self.ya);
        let grid = (GRID.0, GRID.1, GRID.2);
        for &t in &xt.major {
            let i = (self.xa.frac(t) * (w - 1) as f64 + 1e-3).floor();
            if (0.0..w as f64).contains(&i) {
                for j in 0..h {
                    bg[j * w + i as usize] = grid;
                }
            }
        }
        for &t in &yt.major {
            let j = ((1.0 - self.ya.frac(t)) * (h - 1) as f64 + 1e-3).floor();
            if (0.0..h as f64).contains(&j) {
                let j = j as usize;
                bg[j * w..(j + 1) * w].fill(grid);
            }
        }
        bg
    }

    /// Colour of pixel `k`, `None` when empty: viridis of the log count for
    /// a density image, otherwise the colour of its most frequent series
    /// laid over the background, more opaque where the count is higher
    /// (but at least 75 %, so a lone point keeps its hue).
    fn pixel_colour(&self, bins: &Bins, bg: &[Rgb], lmax: f64, k: usize) -> Option<Rgb> {
        let n = bins.counts[k];
        if n == 0 {
            return None;
        }
        let t = f64::from(n).ln() / lmax;
        if let Some(v) = self.by_value {
            let (lo, hi) = v.range;
            let x = bins.value[k];
            // A pixel whose points all lack a value is grey.
            let grey = (160, 160, 160);
            return Some(if x.is_finite() {
                viridis(((x - lo) / (hi - lo)).clamp(0.0, 1.0))
            } else {
                grey
            });
        }
        if self.density {
            Some(viridis(t))
        } else {
            let c = self.colours[bins.top[k] as usize];
            Some(blend(bg[k], c, 0.75 + 0.25 * t))
        }
    }

    /// The RGB raster of the plotting area.
    fn paint(&self, bins: &Bins, bg: &[Rgb], max: u32, occupied: usize) -> Vec<u8> {
        let (w, h) = (bins.w, bins.h);
        let lmax = f64::from(max.max(2)).ln();
        let colour_of = |k: usize| self.pixel_colour(bins, bg, lmax, k);
        // Sparse clouds: paint empty neighbours of occupied pixels too, so
        // that isolated points stay visible.
        let splat = occupied > 0 && (occupied as f64) < 0.01 * (w * h) as f64;
        let mut buf = vec![0u8; 3 * w * h];
        for j in 0..h {
            for i in 0..w {
                let k = j * w + i;
                let c = colour_of(k).or_else(|| {
                    if !splat {
                        return None;
                    }
                    bins.fullest_around(i, j).and_then(colour_of)
                });
                put(&mut buf, k, c.unwrap_or(bg[k]));
            }
        }
        buf
    }

    /// Legend of the named series (colour squares), placed where it hides
    /// the fewest hit pixels.
    fn draw_legend<'c, 'b: 'c>(
        &self,
        chart: &mut Chart<'c, 'b>,
        main: &Area,
        st: &Style,
        f: &Frame,
        bins: &Bins,
    ) -> Result<(), PlotError> {
        let r = st.px(6.0);
        for (s, c) in self.series.iter().zip(&self.colours) {
            if s.name.is_empty() {
                continue;
            }
            let c = rgb(*c);
            chart
                .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
                .label(s.name)
                .legend(move |(x, y)| Rectangle::new([(x, y - r), (x + 2 * r, y + r)], c.filled()));
        }
        let names: Vec<&str> = self
            .series
            .iter()
            .map(|s| s.name)
            .filter(|n| !n.is_empty())
            .collect();
        let occ = Occupancy::from_counts(&bins.counts, bins.w, bins.h);
        let pos = legend_position(&occ, &names, main, st, f);
        legend_box(chart, st, pos)
    }
}

/// A fair-looking, repeatable coin for series `i` tying with an earlier one
/// in pixel `k`: where series share a pixel evenly (orbits on one
/// attractor), no series wins all the ties, so every colour stays in view.
fn coin(k: usize, i: usize) -> bool {
    let h = (((k as u64) << 16) ^ i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    h >> 63 == 1
}

pub(super) fn point_cloud_impl(
    path: &Path,
    fig: &Figure,
    series: &[Series],
    x_range: Option<(f64, f64)>,
    y_range: Option<(f64, f64)>,
) -> Result<(), PlotError> {
    check_series(series)?;
    let cloud = Cloud::new(series, None, x_range, y_range);
    render(path, fig, |body, st| cloud.draw(body, st, fig))
}

pub(super) fn valued_cloud_impl(
    path: &Path,
    fig: &Figure,
    series: &Series,
    by_value: &ByValue,
    x_range: Option<(f64, f64)>,
    y_range: Option<(f64, f64)>,
) -> Result<(), PlotError> {
    let series = std::slice::from_ref(series);
    check_series(series)?;
    let (lo, hi) = by_value.range;
    if by_value.values.len() != series[0].x.len() || !(lo.is_finite() && hi.is_finite() && lo < hi)
    {
        return Err(PlotError::Input(format!(
            "{} values for {} points, colour range [{lo}, {hi}]",
            by_value.values.len(),
            series[0].x.len()
        )));
    }
    let cloud = Cloud::new(series, Some(by_value), x_range, y_range);
    render(path, fig, |body, st| cloud.draw(body, st, fig))
}
