//! Legends inside the plotting area, put where they hide the least data.

use plotters::prelude::*;

use super::axis::Axis;
use super::canvas::{text_width, Area, Style};
use super::chart::{Chart, Frame};
use super::figure::PlotError;

/// Coarse occupancy of the plotting area (row 0 at the top, like pixels),
/// used to put the legend where it hides the least data.
#[derive(Clone)]
pub(super) struct Occupancy {
    cells: Vec<bool>,
}

impl Occupancy {
    const GX: usize = 100;
    const GY: usize = 75;

    pub(super) fn new() -> Self {
        Self {
            cells: vec![false; Self::GX * Self::GY],
        }
    }

    /// Occupancy of a `w`×`h` count image.
    pub(super) fn from_counts(counts: &[u32], w: usize, h: usize) -> Self {
        let mut o = Self::new();
        for (k, &c) in counts.iter().enumerate() {
            if c > 0 && w > 0 && h > 0 {
                let (i, j) = (k % w, k / w);
                o.cells[(j * Self::GY / h).min(Self::GY - 1) * Self::GX
                    + (i * Self::GX / w).min(Self::GX - 1)] = true;
            }
        }
        o
    }

    /// Marks the point at axis fractions `fx` (rightwards), `fy` (upwards).
    fn mark(&mut self, fx: f64, fy: f64) {
        if (0.0..=1.0).contains(&fx) && (0.0..=1.0).contains(&fy) {
            let i = ((fx * Self::GX as f64) as usize).min(Self::GX - 1);
            let j = (((1.0 - fy) * Self::GY as f64) as usize).min(Self::GY - 1);
            self.cells[j * Self::GX + i] = true;
        }
    }

    /// Marks a polyline, sampled densely enough to hit every cell it crosses.
    pub(super) fn add_run(&mut self, run: &[(f64, f64)], xa: &Axis, ya: &Axis) {
        let mut prev: Option<(f64, f64)> = None;
        for &(x, y) in run {
            let p = (xa.frac(x), ya.frac(y));
            if let Some(q) = prev {
                let cells =
                    ((p.0 - q.0).abs() * Self::GX as f64).max((p.1 - q.1).abs() * Self::GY as f64);
                let n = (2.0 * cells).ceil().clamp(1.0, 512.0) as usize;
                for k in 1..=n {
                    let t = k as f64 / n as f64;
                    self.mark(q.0 + t * (p.0 - q.0), q.1 + t * (p.1 - q.1));
                }
            } else {
                self.mark(p.0, p.1);
            }
            prev = Some(p);
        }
    }

    /// Marks pixel rectangle `x0..x1, y0..y1` of a `w`×`h` plotting area.
    pub(super) fn mark_rect(&mut self, (x0, y0, x1, y1): (i32, i32, i32, i32), w: usize, h: usize) {
        if w == 0 || h == 0 {
            return;
        }
        let cell = |v: i32, n: usize, g: usize| (v.clamp(0, n as i32) as usize * g / n).min(g);
        let (i0, i1) = (cell(x0, w, Self::GX), cell(x1, w, Self::GX));
        let (j0, j1) = (cell(y0, h, Self::GY), cell(y1, h, Self::GY));
        for j in j0..=j1.min(Self::GY - 1) {
            for i in i0..=i1.min(Self::GX - 1) {
                self.cells[j * Self::GX + i] = true;
            }
        }
    }

    /// Occupied cells under pixel rectangle `x0..x1, y0..y1` of a `w`×`h`
    /// plotting area.
    pub(super) fn score(&self, (x0, y0, x1, y1): (i32, i32, i32, i32), w: i32, h: i32) -> usize {
        if w <= 0 || h <= 0 {
            return 0;
        }
        let cx = |x: i32| (x.clamp(0, w) as usize * Self::GX).div_ceil(w as usize);
        let cy = |y: i32| (y.clamp(0, h) as usize * Self::GY).div_ceil(h as usize);
        let (i0, i1) = ((x0.clamp(0, w) as usize * Self::GX) / w as usize, cx(x1));
        let (j0, j1) = ((y0.clamp(0, h) as usize * Self::GY) / h as usize, cy(y1));
        (j0..j1.min(Self::GY))
            .map(|j| {
                self.cells[j * Self::GX + i0.min(Self::GX)..j * Self::GX + i1.min(Self::GX)]
                    .iter()
                    .filter(|&&c| c)
                    .count()
            })
            .sum()
    }
}

/// The legend position (of plotters' named ones, corners first) whose box
/// covers the fewest occupied cells; the box size is estimated the way
/// plotters lays the legend out in `legend_box`.
pub(super) fn legend_position(
    occ: &Occupancy,
    names: &[&str],
    area: &Area,
    st: &Style,
    f: &Frame,
) -> SeriesLabelPosition {
    use SeriesLabelPosition::*;
    let font = st.legend();
    let tw = names
        .iter()
        .map(|n| text_width(area, n, &font))
        .max()
        .unwrap_or(0);
    let margin = st.px(10.0);
    let lw = tw + st.px(38.0) + 2 * margin;
    let lh = names.len() as i32 * st.fpx(15.0 * 1.3) + 2 * margin;
    let (w, h) = (f.w() as i32, f.h() as i32);
    let xs = [5, (w - lw) / 2, w - lw - 5];
    let ys = [5, (h - lh) / 2, h - lh - 5];
    let candidates = [
        (UpperRight, 2, 0),
        (UpperLeft, 0, 0),
        (LowerRight, 2, 2),
        (LowerLeft, 0, 2),
        (MiddleRight, 2, 1),
        (MiddleLeft, 0, 1),
        (UpperMiddle, 1, 0),
        (LowerMiddle, 1, 2),
    ];
    let mut best = (UpperRight, usize::MAX);
    for (pos, i, j) in candidates {
        let (x, y) = (xs[i], ys[j]);
        let score = occ.score((x, y, x + lw, y + lh), w, h);
        if score < best.1 {
            best = (pos, score);
        }
    }
    best.0
}

pub(super) fn legend_box<'c, 'b: 'c>(
    chart: &mut Chart<'c, 'b>,
    st: &Style,
    pos: SeriesLabelPosition,
) -> Result<(), PlotError> {
    chart
        .configure_series_labels()
        .position(pos)
        .margin(st.px(10.0))
        .legend_area_size(st.px(38.0))
        .label_font(st.legend())
        .background_style(WHITE.mix(0.9))
        .border_style(RGBColor(150, 150, 150))
        .draw()?;
    Ok(())
}
