//! Point clouds, rasterised as a density image.

use std::path::Path;

use plotters::prelude::*;

use super::axis::{merge, Axis};
use super::canvas::render;
use super::chart::{blit, build_chart, chart_ticks, draw_frame, no_data, split_side};
use super::colorbar::ColorBar;
use super::colour::{blend, put, rgb, viridis, BG, GRID};
use super::figure::{check_series, palette, Figure, PlotError, Rgb, Series};
use super::legend::{legend_box, legend_position, Occupancy};

/// Fixed range from the caller if usable, otherwise the padded data extent.
fn cloud_axis(fixed: Option<(f64, f64)>, data: Option<(f64, f64)>) -> Axis {
    match fixed {
        Some((a, b)) if a.is_finite() && b.is_finite() && a != b => {
            Axis::new(false, Some((a, b)), 0.0)
        }
        _ => Axis::new(false, data, 0.03),
    }
}

/// Calls `hit(pixel index)` for every point of `s` inside the frame. The
/// loop is the hot path of `point_cloud` (10⁸ points): no allocation, one
/// multiply-add per coordinate, NaN and ±∞ rejected by the range tests.
fn bin_points(s: &Series, xa: &Axis, ya: &Axis, w: usize, h: usize, mut hit: impl FnMut(usize)) {
    let (wf, hf) = (w as f64, h as f64);
    let sx = wf / xa.span();
    let sy = hf / ya.span();
    let (x0, y1) = (xa.lo, ya.hi);
    for (&x, &y) in s.x.iter().zip(s.y.iter()) {
        let fx = (x - x0) * sx;
        let fy = (y1 - y) * sy;
        if fx >= 0.0 && fx <= wf && fy >= 0.0 && fy <= hf {
            let i = (fx as usize).min(w - 1);
            let j = (fy as usize).min(h - 1);
            hit(j * w + i);
        }
    }
}

pub(super) fn point_cloud_impl(
    path: &Path,
    fig: &Figure,
    series: &[Series],
    x_range: Option<(f64, f64)>,
    y_range: Option<(f64, f64)>,
) -> Result<(), PlotError> {
    check_series(series)?;
    let need_x = !matches!(x_range, Some((a, b)) if a.is_finite() && b.is_finite() && a != b);
    let need_y = !matches!(y_range, Some((a, b)) if a.is_finite() && b.is_finite() && a != b);
    // Extents only over points with both coordinates finite, so that a
    // diverged trajectory (x finite, y = NaN) does not stretch the axes.
    let mut ext_x = None;
    let mut ext_y = None;
    if need_x || need_y {
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
    }
    let xa = cloud_axis(x_range, ext_x);
    let ya = cloud_axis(y_range, ext_y);
    let density = series.len() == 1 && series.iter().all(|s| s.color.is_none());
    let colours: Vec<Rgb> = series
        .iter()
        .enumerate()
        .map(|(i, s)| s.color.unwrap_or_else(|| palette(i)))
        .collect();

    render(path, fig, |body, st| {
        // The count range is only known after binning, which needs the
        // layout; size the colour bar for labels up to "10⁹".
        let (main, side) = if density {
            let probe = ColorBar::new(
                Axis::new(true, Some((0.0, 9.0)), 0.0),
                "points per pixel",
                false,
                750.0,
                st,
            );
            let w = probe.width(body, st);
            let (m, s) = split_side(body, w);
            (m, Some(s))
        } else {
            (body.clone(), None)
        };
        let (mut chart, f) = build_chart(&main, st, fig, &xa, &ya, true, st.px(28.0))?;
        let (w, h) = (f.w(), f.h());
        if w == 0 || h == 0 {
            return Ok(());
        }
        let mut counts = vec![0u32; w * h];
        // Count-weighted colour sums, only needed when colouring by series.
        let mut sums: Vec<[f64; 3]> = if density {
            vec![]
        } else {
            vec![[0.0; 3]; w * h]
        };
        for (s, c) in series.iter().zip(&colours) {
            if density {
                bin_points(s, &xa, &ya, w, h, |k| {
                    counts[k] = counts[k].saturating_add(1);
                });
            } else {
                let cf = [f64::from(c.0), f64::from(c.1), f64::from(c.2)];
                bin_points(s, &xa, &ya, w, h, |k| {
                    counts[k] = counts[k].saturating_add(1);
                    let acc = &mut sums[k];
                    acc[0] += cf[0];
                    acc[1] += cf[1];
                    acc[2] += cf[2];
                });
            }
        }
        let max = counts.iter().copied().max().unwrap_or(0);
        let occupied = counts.iter().filter(|&&c| c > 0).count();

        // Background with the grid lines, since the blit covers the mesh.
        let mut bg = vec![BG; w * h];
        let (xt, yt) = chart_ticks(&main, st, &xa, &ya);
        let grid = (GRID.0, GRID.1, GRID.2);
        for &t in &xt.major {
            let i = (xa.frac(t) * (w - 1) as f64 + 1e-3).floor();
            if (0.0..w as f64).contains(&i) {
                for j in 0..h {
                    bg[j * w + i as usize] = grid;
                }
            }
        }
        for &t in &yt.major {
            let j = ((1.0 - ya.frac(t)) * (h - 1) as f64 + 1e-3).floor();
            if (0.0..h as f64).contains(&j) {
                let j = j as usize;
                bg[j * w..(j + 1) * w].fill(grid);
            }
        }

        let lmax = f64::from(max.max(2)).ln();
        let colour_of = |k: usize| -> Option<Rgb> {
            let n = counts[k];
            if n == 0 {
                return None;
            }
            let t = f64::from(n).ln() / lmax;
            if density {
                Some(viridis(t))
            } else {
                let a = sums[k];
                let nf = f64::from(n);
                let mean = (
                    (a[0] / nf).round() as u8,
                    (a[1] / nf).round() as u8,
                    (a[2] / nf).round() as u8,
                );
                Some(blend(bg[k], mean, 0.45 + 0.55 * t))
            }
        };
        // Sparse clouds: paint empty neighbours of occupied pixels too.
        let splat = occupied > 0 && (occupied as f64) < 0.01 * (w * h) as f64;
        let mut buf = vec![0u8; 3 * w * h];
        for j in 0..h {
            for i in 0..w {
                let k = j * w + i;
                let c = colour_of(k).or_else(|| {
                    if !splat {
                        return None;
                    }
                    let mut best: Option<(u32, usize)> = None;
                    for dj in [-1i64, 0, 1] {
                        for di in [-1i64, 0, 1] {
                            let (ni, nj) = (i as i64 + di, j as i64 + dj);
                            if ni < 0 || nj < 0 || ni >= w as i64 || nj >= h as i64 {
                                continue;
                            }
                            let nk = nj as usize * w + ni as usize;
                            if counts[nk] > best.map_or(0, |b| b.0) {
                                best = Some((counts[nk], nk));
                            }
                        }
                    }
                    best.and_then(|(_, nk)| colour_of(nk))
                });
                put(&mut buf, k, c.unwrap_or(bg[k]));
            }
        }
        blit(&main, &f, buf)?;
        if occupied == 0 {
            no_data(&main, &f, st)?;
        }
        draw_frame(&main, &f)?;

        let named = series.iter().any(|s| !s.name.is_empty());
        if !density && series.len() > 1 && named && occupied > 0 {
            let r = st.px(6.0);
            for (s, c) in series.iter().zip(&colours) {
                if s.name.is_empty() {
                    continue;
                }
                let c = rgb(*c);
                chart
                    .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
                    .label(s.name)
                    .legend(move |(x, y)| {
                        Rectangle::new([(x, y - r), (x + 2 * r, y + r)], c.filled())
                    });
            }
            let names: Vec<&str> = series
                .iter()
                .map(|s| s.name)
                .filter(|n| !n.is_empty())
                .collect();
            let pos = legend_position(
                &Occupancy::from_counts(&counts, w, h),
                &names,
                &main,
                st,
                &f,
            );
            legend_box(&mut chart, st, pos)?;
        }
        if let Some(side) = side {
            let ca = Axis {
                log: true,
                lo: 0.0,
                hi: f64::from(max.max(2)).log10(),
            };
            let cb = ColorBar::new(
                ca,
                "points per pixel",
                false,
                f.h() as f64 + 110.0 * st.s,
                st,
            );
            cb.draw(&side, st, &f)?;
        }
        Ok(())
    })
}
