//! Quick-look PNG figures (heatmaps, class maps, point clouds, line plots and
//! log–log convergence plots) drawn with `plotters`.
//!
//! The figures sit next to numeric outputs, so they favour robustness and
//! speed over configurability. Design decisions, and why:
//!
//! * **Transformed coordinates.** Every chart is a linear plotters chart over
//!   *transformed* values: an axis flagged as logarithmic is drawn over
//!   `log10(value)` and its tick labels are written as powers of ten. This
//!   gives one concrete chart type for all four lin/log combinations, and it
//!   lets this module place the ticks itself: plotters' own `LogCoord` puts its
//!   first key point at the first power of ten inside the range, so a range
//!   narrower than a decade (say 2..9) gets no tick label at all.
//! * **Rasterised dense data.** Heatmaps, class maps and point clouds are
//!   rendered by this module into an RGB buffer the size of the plotting area
//!   and blitted once. Drawing one plotters element per cell or per point would
//!   be orders of magnitude slower (a point cloud may hold 10⁸ points).
//! * **Ranges that cannot be empty.** Ranges come from finite data only
//!   (positive finite data on log axes); a degenerate range (constant data, a
//!   single point) is widened and every range is padded by 3%, so no input
//!   yields an empty or inverted axis. No data at all gives an image with a
//!   "no data" note rather than an error, so a batch job always leaves a
//!   picture behind.
//! * **No panics.** Inputs are validated up front; in addition each public
//!   function runs inside `catch_unwind`, because plotters has internal
//!   `unwrap`s and `panic!`s, and a quick-look picture must never take down a
//!   long ensemble run. (This guard is ineffective under `panic = "abort"`.)
//!
//! The font (DejaVu Sans: Latin, Greek, Cyrillic, math) is embedded from
//! `assets/DejaVuSans.ttf` at the root of the crate and registered once as
//! plotters' `"sans-serif"` family, so the figures look the same on every
//! machine and need no system fonts. A title with characters it lacks (CJK)
//! draws those in a system font that has them (`REEB_FONT=FILE`, else the
//! usual places of Noto Sans CJK, WenQuanYi, Droid Sans Fallback), else as
//! "�" with one warning naming them: never as silent boxes.
//!
//! The files, bottom up: `figure` (the public vocabulary), `axis` (axes and
//! ticks), `fonts` (coverage and fallback), `canvas` (image, title, sizes),
//! `colour`, `chart` (a chart with its axes on an area), `colorbar`,
//! `legend`, and one file per kind of figure: `grid` (heat and class maps),
//! `cloud`, `lines`, `loglog`. This file holds only the public entry
//! points, so no file below imports it.

mod axis;
mod bars;
mod canvas;
mod chart;
mod cloud;
mod colorbar;
mod colour;
mod figure;
mod fonts;
mod grid;
mod legend;
mod lines;
mod loglog;

use std::path::Path;

use bars::bars_impl;
use canvas::guarded;
use cloud::{point_cloud_impl, valued_cloud_impl};
use grid::{class_map_impl, heatmap_impl};
use lines::lines_impl;
use loglog::loglog_impl;

pub use axis::{fmt_general, fmt_significant, log_scale};
pub use cloud::ByValue;
pub use figure::{palette, Figure, HeatMap, PlotError, Rgb, Series, Slope};

/// Scalar field over a 2-D grid: `values[ix * y.len() + iy]` sits at
/// `(x[ix], y[iy])`; every non-finite value is "NaN" (grey). See
/// [`heat_map`], which also says why a cell has no value.
#[allow(clippy::too_many_arguments)] // The signature is the host crate's API.
pub fn heatmap(
    path: &Path,
    fig: &Figure,
    x: &[f64],
    y: &[f64],
    values: &[f64],
    value_label: &str,
    log_color: bool,
    x_log: bool,
    y_log: bool,
) -> Result<(), PlotError> {
    let map = HeatMap {
        x,
        y,
        values,
        label: value_label,
        log_color,
        x_log,
        y_log,
        why: &[],
        undefined: &[],
        marks: &[],
    };
    heat_map(path, fig, &map)
}

/// A heat map ([`HeatMap`]).
///
/// Cells extend to the midpoints between neighbouring grid values (in log
/// space on log axes) so that non-uniform grids look right; the grids need not
/// be sorted. Colours follow viridis; a cell without a finite value takes the
/// grey of its reason (`map.why`, `map.undefined`; "NaN" otherwise), listed
/// with what it means under the colour bar. With `log_color`, the colour
/// scale is log10 of the positive values, and values ≤ 0 get the lowest
/// colour (a zero error is "as good as it gets", not missing). Grid points
/// that are non-finite (or ≤ 0 on a log axis) are left out.
pub fn heat_map(path: &Path, fig: &Figure, map: &HeatMap) -> Result<(), PlotError> {
    guarded(|| heatmap_impl(path, fig, map))
}

/// Categorical map over a 2-D grid: `classes[ix * y.len() + iy]` indexes
/// `legend`, whose colour fills the cell; indices outside `legend` are grey.
/// The legend is drawn beside the map (the map fills the plotting area, so
/// there is no free corner), listing every entry even if it does not occur,
/// so that figures of a sweep can be compared.
#[allow(clippy::too_many_arguments)] // The signature is the host crate's API.
pub fn class_map(
    path: &Path,
    fig: &Figure,
    x: &[f64],
    y: &[f64],
    classes: &[u8],
    legend: &[(&str, Rgb)],
    x_log: bool,
    y_log: bool,
) -> Result<(), PlotError> {
    guarded(|| class_map_impl(path, fig, x, y, classes, legend, x_log, y_log))
}

/// A bar chart: one bar per `(label, value, colour)`, its value written
/// above it with `digits` decimals (capture fractions).
pub fn bars(
    path: &Path,
    fig: &Figure,
    bars: &[(&str, f64, Rgb)],
    digits: usize,
) -> Result<(), PlotError> {
    guarded(|| bars_impl(path, fig, bars, digits))
}

/// Point cloud (Poincaré portraits with up to 10⁷–10⁸ points), rasterised as
/// a density image: points are counted per pixel of the plotting area.
///
/// A single series without an explicit colour is coloured by log density
/// (viridis, with a colour bar of points per pixel). Otherwise each pixel
/// takes the colour of the series with the most points in it (never a mix,
/// so every colour seen is one of the legend's), with an opacity that grows
/// with log density, and a legend names the series. Isolated points
/// are drawn 3×3 pixels when the image is sparse, so that a few thousand
/// points remain visible. `x_range`/`y_range` fix the axes (points outside are
/// dropped); otherwise the range of the finite data, padded by 3%, is used.
pub fn point_cloud(
    path: &Path,
    fig: &Figure,
    series: &[Series],
    x_range: Option<(f64, f64)>,
    y_range: Option<(f64, f64)>,
) -> Result<(), PlotError> {
    guarded(|| point_cloud_impl(path, fig, series, x_range, y_range))
}

/// A point cloud coloured by a value per point (a Poincaré portrait by
/// each orbit's FLI): a pixel takes viridis of the largest value among its
/// points on `by_value.range` (values beyond it clipped, grey where no
/// point has a value), with a colour bar labelled `by_value.label`.
pub fn valued_cloud(
    path: &Path,
    fig: &Figure,
    series: &Series,
    by_value: &ByValue,
    x_range: Option<(f64, f64)>,
    y_range: Option<(f64, f64)>,
) -> Result<(), PlotError> {
    guarded(|| valued_cloud_impl(path, fig, series, by_value, x_range, y_range))
}

/// One polyline per series (phase portraits, error against time). A
/// non-finite value (or ≤ 0 on a log axis) breaks the line. Two to eleven
/// distinct series names get a legend in the emptiest corner, one entry per
/// name (series of one name are one group); twelve or more series are drawn
/// thin, and more names than eleven get no legend, since it would hide the
/// data.
pub fn lines(
    path: &Path,
    fig: &Figure,
    series: &[Series],
    x_log: bool,
    y_log: bool,
) -> Result<(), PlotError> {
    guarded(|| lines_impl(path, fig, series, x_log, y_log))
}

/// Log–log lines with markers (work–precision diagrams, error against step)
/// plus dashed reference `slopes`. The axis ranges cover the data and the
/// slope anchors; the reference lines are clipped to the plotting area.
pub fn loglog(
    path: &Path,
    fig: &Figure,
    series: &[Series],
    slopes: &[Slope],
) -> Result<(), PlotError> {
    guarded(|| loglog_impl(path, fig, series, slopes))
}

#[cfg(test)]
mod tests {
    use super::axis::{fmt_general, ticks, Axis};
    use super::colour::viridis;
    use super::*;
    use std::path::PathBuf;
    use std::time::Instant;

    fn out(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("reeb_plot_test_{}_{name}.png", std::process::id()))
    }

    /// Asserts that `path` is a PNG of `w`×`h` pixels that is not blank
    /// (a white 1000×750 PNG compresses to about 3 KB; axes and labels alone
    /// push it well above that).
    fn check_png(path: &Path, w: u32, h: u32, min_bytes: usize) {
        let bytes = std::fs::read(path).expect("PNG was not written");
        assert!(bytes.len() > 24, "file too short");
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "not a PNG");
        assert_eq!(&bytes[12..16], b"IHDR");
        let pw = u32::from_be_bytes([bytes[16], bytes[17], bytes[18], bytes[19]]);
        let ph = u32::from_be_bytes([bytes[20], bytes[21], bytes[22], bytes[23]]);
        assert_eq!((pw, ph), (w, h));
        assert!(
            bytes.len() > min_bytes,
            "{} is only {} bytes: blank image?",
            path.display(),
            bytes.len()
        );
        let _ = std::fs::remove_file(path);
    }

    fn fig<'a>(title: &'a str) -> Figure<'a> {
        Figure {
            title,
            x_label: "x",
            y_label: "y",
            ..Figure::default()
        }
    }

    #[test]
    fn heatmap_with_nan_and_log_colour() {
        let x: Vec<f64> = (0..40)
            .map(|i| 10f64.powf(-3.0 + 0.1 * f64::from(i)))
            .collect();
        let y: Vec<f64> = (0..30).map(|j| f64::from(j) * 0.5).collect();
        let mut v = vec![0.0; x.len() * y.len()];
        for (ix, &xv) in x.iter().enumerate() {
            for (iy, &yv) in y.iter().enumerate() {
                v[ix * y.len() + iy] = xv.powi(2) * (1.0 + yv);
            }
        }
        v[5 * y.len() + 7] = f64::NAN;
        v[6 * y.len() + 7] = f64::INFINITY;
        let p = out("heatmap");
        heatmap(&p, &fig("heatmap"), &x, &y, &v, "error", true, true, false).expect("heatmap");
        check_png(&p, 1000, 750, 20_000);
    }

    #[test]
    fn class_map_three_classes() {
        let x: Vec<f64> = (0..50).map(f64::from).collect();
        let y: Vec<f64> = (0..40).map(|j| 1e-4 * 1.2f64.powi(j)).collect();
        let classes: Vec<u8> = (0..x.len() * y.len())
            .map(|k| ((k / y.len() + k % y.len()) / 25).min(2) as u8)
            .collect();
        let legend = [
            ("accurate", (44, 160, 44)),
            ("distorted", (255, 127, 14)),
            ("diverged", (214, 39, 40)),
        ];
        let p = out("classmap");
        class_map(&p, &fig("classes"), &x, &y, &classes, &legend, false, true).expect("class_map");
        check_png(&p, 1000, 750, 15_000);
    }

    #[test]
    fn bars_of_capture_fractions() {
        let bars = [
            ("1:1", 40.8, palette(0)),
            ("3:2", 29.9, palette(1)),
            ("none", 0.0, (200, 200, 200)),
        ];
        let p = out("bars");
        super::bars(&p, &fig("capture"), &bars, 1).expect("bars");
        check_png(&p, 1000, 750, 8_000);
        assert!(super::bars(&p, &fig("capture"), &bars[..1], 1).is_err());
        let nan = [("a", f64::NAN, palette(0)), ("b", 1.0, palette(1))];
        assert!(super::bars(&p, &fig("capture"), &nan, 1).is_err());
    }

    #[test]
    fn point_cloud_five_million_points() {
        let n = 5_000_000;
        // Standard map orbits: a cheap chaotic point set, computed outside
        // the timed section.
        let (mut xs, mut ys) = (Vec::with_capacity(n), Vec::with_capacity(n));
        let k = 0.97;
        let tau = std::f64::consts::TAU;
        let per = 5000;
        for orbit in 0..n / per {
            let mut p = 0.1 + orbit as f64 * tau / (n / per) as f64;
            let mut q = 0.5 + 0.37 * orbit as f64;
            for _ in 0..per {
                p = (p + k * q.sin()).rem_euclid(tau);
                q = (q + p).rem_euclid(tau);
                xs.push(q);
                ys.push(p);
            }
        }
        let s = [Series::new("standard map", &xs, &ys)];
        let p = out("cloud");
        let t = Instant::now();
        point_cloud(&p, &fig("cloud"), &s, None, None).expect("point_cloud");
        let dt = t.elapsed().as_secs_f64();
        eprintln!("point_cloud, {n} points: {dt:.3} s");
        if !cfg!(debug_assertions) {
            assert!(dt < 3.0, "point_cloud took {dt:.2} s");
        }
        check_png(&p, 1000, 750, 30_000);
    }

    #[test]
    fn point_cloud_several_series_and_fixed_range() {
        let xs: Vec<f64> = (0..20_000).map(|i| (f64::from(i) * 0.001).sin()).collect();
        let ys: Vec<f64> = (0..20_000).map(|i| (f64::from(i) * 0.0013).cos()).collect();
        let ys2: Vec<f64> = ys.iter().map(|v| 0.5 * v).collect();
        let s = [Series::new("a", &xs, &ys), Series::new("b", &xs, &ys2)];
        let p = out("cloud2");
        point_cloud(&p, &fig("two"), &s, Some((-1.5, 1.5)), Some((-1.2, 1.2))).expect("cloud");
        check_png(&p, 1000, 750, 15_000);
    }

    #[test]
    fn lines_with_nan_gap() {
        let t: Vec<f64> = (0..500).map(|i| f64::from(i) * 0.02).collect();
        let mut a: Vec<f64> = t.iter().map(|v| v.sin()).collect();
        for v in &mut a[200..230] {
            *v = f64::NAN;
        }
        let b: Vec<f64> = t.iter().map(|v| 0.5 * v.cos()).collect();
        let s = [Series::new("sin", &t, &a), Series::new("cos/2", &t, &b)];
        let p = out("lines");
        lines(&p, &fig("lines"), &s, false, false).expect("lines");
        check_png(&p, 1000, 750, 15_000);
    }

    #[test]
    fn loglog_two_series_two_slopes() {
        let h: Vec<f64> = (0..12).map(|i| 0.5f64.powi(i)).collect();
        let e2: Vec<f64> = h.iter().map(|v| 0.3 * v * v).collect();
        let e4: Vec<f64> = h.iter().map(|v| 0.05 * v.powi(4)).collect();
        let s = [Series::new("RK2", &h, &e2), Series::new("RK4", &h, &e4)];
        let slopes = [Slope::new(2.0, (0.1, 1e-2)), Slope::new(4.0, (0.1, 1e-6))];
        let p = out("loglog");
        loglog(&p, &fig("loglog"), &s, &slopes).expect("loglog");
        check_png(&p, 1000, 750, 15_000);
    }

    #[test]
    fn empty_and_degenerate_inputs_do_not_panic() {
        let f = fig("empty");
        let e: [f64; 0] = [];
        let p = out("empty_heat");
        heatmap(&p, &f, &e, &e, &e, "v", true, true, true).expect("empty heatmap");
        check_png(&p, 1000, 750, 5_000);
        let p = out("empty_class");
        class_map(&p, &f, &e, &e, &[], &[], false, false).expect("empty class_map");
        check_png(&p, 1000, 750, 5_000);
        let p = out("empty_cloud");
        point_cloud(&p, &f, &[], None, None).expect("empty cloud");
        check_png(&p, 1000, 750, 5_000);
        let p = out("empty_cloud_series");
        point_cloud(&p, &f, &[Series::new("", &e, &e)], None, None).expect("empty cloud");
        check_png(&p, 1000, 750, 5_000);
        let p = out("empty_lines");
        lines(&p, &f, &[], true, false).expect("empty lines");
        check_png(&p, 1000, 750, 5_000);
        let p = out("empty_loglog");
        loglog(&p, &f, &[], &[Slope::new(2.0, (1.0, 1.0))]).expect("empty loglog");
        check_png(&p, 1000, 750, 5_000);

        // Degenerate: constant data, single points, all-NaN, non-positive
        // values on log axes.
        let one = [3.0];
        let nan = [f64::NAN, f64::INFINITY];
        let p = out("single_heat");
        heatmap(&p, &f, &one, &one, &[7.0], "v", false, false, false).expect("1x1 heatmap");
        check_png(&p, 1000, 750, 5_000);
        let p = out("nan_heat");
        heatmap(&p, &f, &[1.0, 2.0], &one, &nan, "v", true, false, false).expect("NaN heatmap");
        check_png(&p, 1000, 750, 5_000);
        let p = out("single_cloud");
        point_cloud(&p, &f, &[Series::new("p", &one, &one)], None, None).expect("1 point");
        check_png(&p, 1000, 750, 5_000);
        let p = out("const_lines");
        let c = [2.0, 2.0, 2.0];
        lines(&p, &f, &[Series::new("c", &c, &c)], false, false).expect("constant");
        check_png(&p, 1000, 750, 5_000);
        let p = out("neg_loglog");
        let neg = [-1.0, 0.0, f64::NAN];
        loglog(&p, &f, &[Series::new("n", &neg, &neg)], &[]).expect("non-positive");
        check_png(&p, 1000, 750, 5_000);
        let p = out("nan_lines");
        lines(&p, &f, &[Series::new("n", &nan, &nan)], true, true).expect("all NaN");
        check_png(&p, 1000, 750, 5_000);
        let p = out("huge_lines");
        let huge = [-f64::MAX, f64::MAX, 0.0];
        lines(&p, &f, &[Series::new("h", &huge, &huge)], false, false).expect("huge");
        check_png(&p, 1000, 750, 5_000);
    }

    /// Small inputs drawn from special values, in every lin/log
    /// combination: every call must succeed (and, above all, not panic).
    #[test]
    fn special_values_never_panic() {
        let specials = [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
            -1.0,
            1e-300,
            1e300,
            f64::MAX,
            -f64::MAX,
            f64::MIN_POSITIVE,
            1.0,
            1.0,
            2.5,
        ];
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut pick = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            specials[(state % specials.len() as u64) as usize]
        };
        let f = Figure {
            title: "special",
            width: 320,
            height: 240,
            ..Figure::default()
        };
        let p = out("special");
        let ranges = [
            None,
            Some((f64::NAN, 1.0)),
            Some((1.0, 1.0)),
            Some((5.0, -5.0)),
            Some((-f64::MAX, f64::MAX)),
        ];
        for round in 0..40usize {
            let n = round % 5;
            let xs: Vec<f64> = (0..n).map(|_| pick()).collect();
            let ys: Vec<f64> = (0..n).map(|_| pick()).collect();
            let vals: Vec<f64> = (0..n * n).map(|_| pick()).collect();
            let classes: Vec<u8> = (0..n * n).map(|k| (k % 5) as u8).collect();
            let (a, b, c) = (round % 2 == 0, round % 3 == 0, round % 4 < 2);
            heatmap(&p, &f, &xs, &ys, &vals, "v", a, b, c).expect("heatmap");
            class_map(&p, &f, &xs, &ys, &classes, &[("a", (1, 2, 3))], b, c).expect("class_map");
            let s = [Series::new("s", &xs, &ys), Series::new("t", &ys, &xs)];
            let k = round % s.len() + 1;
            point_cloud(&p, &f, &s[..k], ranges[round % 5], ranges[(round + 2) % 5])
                .expect("point_cloud");
            lines(&p, &f, &s[..k], a, c).expect("lines");
            let slopes = [
                Slope::new(pick(), (pick(), pick())),
                Slope::new(2.0, (1.0, 1.0)),
            ];
            loglog(&p, &f, &s[..k], &slopes).expect("loglog");
        }
        let _ = std::fs::remove_file(&p);
    }

    #[test]
    fn extreme_figure_sizes() {
        let x = [1.0, 2.0, 3.0];
        let y = [1e-3, 1e-2, 1e-1];
        let v: Vec<f64> = (0..9).map(f64::from).collect();
        for (w, h) in [(160, 160), (3000, 160), (160, 1200)] {
            let f = Figure {
                title: "a rather long title for such a small figure",
                x_label: "a long x axis description",
                y_label: "a long y axis description",
                width: w,
                height: h,
            };
            let p = out(&format!("size_{w}x{h}"));
            heatmap(&p, &f, &x, &y, &v, "value", false, false, true).expect("heatmap");
            check_png(&p, w, h, 1_000);
            let p = out(&format!("size_lines_{w}x{h}"));
            let s = [Series::new("a", &x, &y), Series::new("b", &y, &x)];
            lines(&p, &f, &s, false, true).expect("lines");
            check_png(&p, w, h, 1_000);
        }
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let f = Figure::default();
        let p = out("bad");
        let r = heatmap(&p, &f, &[1.0, 2.0], &[1.0], &[1.0], "", false, false, false);
        assert!(matches!(r, Err(PlotError::Input(_))));
        let r = lines(&p, &f, &[Series::new("", &[1.0], &[])], false, false);
        assert!(matches!(r, Err(PlotError::Input(_))));
        let tiny = Figure {
            width: 10,
            height: 0,
            ..Figure::default()
        };
        assert!(matches!(
            lines(&p, &tiny, &[], false, false),
            Err(PlotError::Input(_))
        ));
    }

    #[test]
    fn log_axes_for_logspaces_and_lists_over_decades() {
        let logspace = |a: f64, b: f64, n: usize| -> Vec<f64> {
            (0..n)
                .map(|i| 10f64.powf(a + (b - a) * i as f64 / (n - 1) as f64))
                .collect()
        };
        let linspace = |a: f64, b: f64, n: usize| -> Vec<f64> {
            (0..n)
                .map(|i| a + (b - a) * i as f64 / (n - 1) as f64)
                .collect()
        };
        let mut down = logspace(-4.0, 0.196, 256);
        assert!(log_scale(&down));
        down.reverse();
        assert!(log_scale(&down), "a descending logspace");
        assert!(
            log_scale(&logspace(0.0, 0.5, 3)),
            "geometric, under a decade"
        );
        assert!(log_scale(&[1e-2, 5e-3, 1e-3, 5e-4, 1e-4]));
        assert!(log_scale(&[1e-4, 1e-2]));
        assert!(
            !log_scale(&linspace(0.01, 1.0, 100)),
            "a linspace stays linear"
        );
        assert!(!log_scale(&linspace(2.45, 2.47, 201)), "nearly geometric");
        assert!(!log_scale(&[0.0, 1e-3, 1.0]));
        assert!(!log_scale(&[0.01, 2.0, 5.0]));
        assert!(!log_scale(&[1e-3]));
    }

    #[test]
    fn tick_labels_tell_close_values_apart() {
        let ax = Axis::new(false, Some((1.6715893, 1.6715915)), 0.03);
        let t = ticks(&ax, 8);
        let labels: Vec<String> = t.major.iter().map(|&v| t.label(v)).collect();
        let mut distinct = labels.clone();
        distinct.dedup();
        assert!(labels.len() >= 3 && distinct == labels, "{labels:?}");
    }

    #[test]
    fn tick_labels_are_clean() {
        let ax = Axis::new(false, Some((0.0, 1.0)), 0.0);
        let t = ticks(&ax, 10);
        let labels: Vec<String> = t.major.iter().map(|&v| t.label(v)).collect();
        assert!(labels.contains(&"0.3".to_string()), "{labels:?}");
        assert!(labels.iter().all(|l| l.len() <= 4), "{labels:?}");
        let ax = Axis::new(false, Some((1e-7, 5e-7)), 0.0);
        let t = ticks(&ax, 5);
        let labels: Vec<String> = t.major.iter().map(|&v| t.label(v)).collect();
        assert!(labels.iter().all(|l| l.contains('e')), "{labels:?}");
        // A log axis narrower than a decade still gets labels.
        let ax = Axis::new(true, Some((2f64.log10(), 9f64.log10())), 0.0);
        assert!(ticks(&ax, 6).major.len() >= 3);
        let ax = Axis::new(true, Some((-12.0, 0.0)), 0.0);
        let t = ticks(&ax, 8);
        assert_eq!(t.label(-3.0), "10⁻³");
        assert_eq!(fmt_general(0.1 + 0.2), "0.3");
        assert_eq!(palette(10), palette(0));
        assert_eq!(viridis(0.0), (0x44, 0x01, 0x54));
        assert_eq!(viridis(1.0), (0xfd, 0xe7, 0x25));
    }
}
