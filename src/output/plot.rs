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
//! The font (DejaVu Sans) is embedded from `assets/DejaVuSans.ttf` at the root
//! of the crate and registered once as plotters' `"sans-serif"` family, so the
//! figures look the same on every machine and need no system fonts.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::coord::Shift;
use plotters::drawing::DrawingAreaErrorKind;
use plotters::prelude::*;
use plotters::style::register_font;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// An 8-bit RGB colour.
pub type Rgb = (u8, u8, u8);

/// A named polyline or point set. `x` and `y` must have the same length.
#[derive(Debug, Clone, Copy)]
pub struct Series<'a> {
    /// Legend entry; an empty name is left out of the legend.
    pub name: &'a str,
    pub x: &'a [f64],
    pub y: &'a [f64],
    /// Colour; `None` picks [`palette`]`(index of the series)`.
    pub color: Option<Rgb>,
}

impl<'a> Series<'a> {
    /// A series with the default colour.
    pub fn new(name: &'a str, x: &'a [f64], y: &'a [f64]) -> Self {
        Self {
            name,
            x,
            y,
            color: None,
        }
    }
}

/// Options shared by the figures. Empty strings are simply not drawn.
#[derive(Debug, Clone, Copy)]
pub struct Figure<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    /// Image size in pixels; fonts and line widths scale with it.
    pub width: u32,
    pub height: u32,
}

impl Default for Figure<'_> {
    fn default() -> Self {
        Self {
            title: "",
            x_label: "",
            y_label: "",
            width: 1000,
            height: 750,
        }
    }
}

/// A dashed reference line `y = anchor.1 · (x / anchor.0)^slope` on a log–log
/// plot, labelled with `label` (e.g. "slope 4"), so an observed order of
/// convergence can be read off by eye.
#[derive(Debug, Clone, PartialEq)]
pub struct Slope {
    pub slope: f64,
    pub anchor: (f64, f64),
    pub label: String,
}

impl Slope {
    /// A reference slope labelled "slope {slope}".
    pub fn new(slope: f64, anchor: (f64, f64)) -> Self {
        Self {
            slope,
            anchor,
            label: format!("slope {}", fmt_general(slope)),
        }
    }
}

/// Errors from drawing a figure.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// plotters (or the PNG encoder underneath it) failed, e.g. the file
    /// could not be written.
    #[error("plotting backend error: {0}")]
    Backend(String),
    /// The input is inconsistent (lengths that do not match, an unusable
    /// image size).
    #[error("invalid plot input: {0}")]
    Input(String),
    /// The embedded font could not be parsed.
    #[error("the embedded font could not be registered with plotters")]
    Font,
    /// plotters panicked; the panic was caught so the caller can carry on.
    #[error("plotting panicked: {0}")]
    Panic(String),
}

impl<E: std::error::Error + Send + Sync> From<DrawingAreaErrorKind<E>> for PlotError {
    fn from(e: DrawingAreaErrorKind<E>) -> Self {
        PlotError::Backend(e.to_string())
    }
}

/// The Tableau 10 colours (matplotlib's `tab10`): distinguishable, and
/// familiar to readers of scientific plots. Cycles after 10.
pub fn palette(i: usize) -> Rgb {
    const TAB10: [Rgb; 10] = [
        (0x1f, 0x77, 0xb4),
        (0xff, 0x7f, 0x0e),
        (0x2c, 0xa0, 0x2c),
        (0xd6, 0x27, 0x28),
        (0x94, 0x67, 0xbd),
        (0x8c, 0x56, 0x4b),
        (0xe3, 0x77, 0xc2),
        (0x7f, 0x7f, 0x7f),
        (0xbc, 0xbd, 0x22),
        (0x17, 0xbe, 0xcf),
    ];
    TAB10[i % TAB10.len()]
}

/// Scalar field over a 2-D grid: `values[ix * y.len() + iy]` sits at
/// `(x[ix], y[iy])`.
///
/// Cells extend to the midpoints between neighbouring grid values (in log
/// space on log axes) so that non-uniform grids look right; the grids need not
/// be sorted. Colours follow viridis; non-finite values are grey (and listed as
/// "NaN" under the colour bar). With `log_color`, the colour scale is log10 of
/// the positive values, and values ≤ 0 get the lowest colour (a zero error is
/// "as good as it gets", not missing). Grid points that are non-finite (or
/// ≤ 0 on a log axis) are left out.
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
    guarded(|| {
        heatmap_impl(
            path,
            fig,
            x,
            y,
            values,
            value_label,
            log_color,
            x_log,
            y_log,
        )
    })
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

/// Point cloud (Poincaré portraits with up to 10⁷–10⁸ points), rasterised as
/// a density image: points are counted per pixel of the plotting area.
///
/// A single series without an explicit colour is coloured by log density
/// (viridis, with a colour bar of points per pixel). Otherwise each pixel
/// takes the count-weighted mean of the series colours, with an opacity that
/// grows with log density, and a legend names the series. Isolated points
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

/// One polyline per series (phase portraits, error against time). A
/// non-finite value (or ≤ 0 on a log axis) breaks the line. Two to eleven
/// series get a legend in the emptiest corner; twelve or more are drawn thin
/// and without a legend, since such a legend would hide the data.
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

// ---------------------------------------------------------------------------
// Shared machinery
// ---------------------------------------------------------------------------

const FONT: &str = "sans-serif";
const FONT_BYTES: &[u8] = include_bytes!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/assets/DejaVuSans.ttf"
));
const NAN_GREY: Rgb = (170, 170, 170);
const BG: Rgb = (255, 255, 255);
const GRID: RGBColor = RGBColor(222, 222, 222);
const GRID_MINOR: RGBColor = RGBColor(240, 240, 240);
const NOTE_GREY: RGBColor = RGBColor(110, 110, 110);
/// Smallest and largest accepted image sides: below the minimum the axis
/// labels would not fit; above the maximum the RGB buffer gets absurd.
const MIN_SIDE: u32 = 160;
const MAX_SIDE: u32 = 16384;
/// Series counts from which `lines` drops the legend and thins the lines.
const MANY_SERIES: usize = 12;

/// Registers the embedded font once per process. plotters' `ab_glyph`
/// backend knows no system fonts, so without this no text can be drawn.
fn ensure_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| register_font(FONT, FontStyle::Normal, FONT_BYTES).is_ok());
    if ok {
        Ok(())
    } else {
        Err(PlotError::Font)
    }
}

/// Runs `f`, turning a panic into `PlotError::Panic`.
fn guarded<F: FnOnce() -> Result<(), PlotError>>(f: F) -> Result<(), PlotError> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => {
            let msg = if let Some(s) = payload.downcast_ref::<&str>() {
                (*s).to_string()
            } else if let Some(s) = payload.downcast_ref::<String>() {
                s.clone()
            } else {
                "unknown panic".to_string()
            };
            Err(PlotError::Panic(msg))
        }
    }
}

type Area<'b> = DrawingArea<BitMapBackend<'b>, Shift>;
type Chart<'c, 'b> = ChartContext<'c, BitMapBackend<'b>, Cartesian2d<TickAxis, TickAxis>>;

/// A linear plotters axis over transformed coordinates whose ticks are
/// chosen by this module. (plotters' `WithKeyPoints` would do, but wrapping
/// `RangedCoordf64` loses the label-formatter support `configure_mesh` needs.)
#[derive(Debug, Clone)]
struct TickAxis {
    lo: f64,
    hi: f64,
    major: Vec<f64>,
    minor: Vec<f64>,
}

impl TickAxis {
    fn new(ax: &Axis, t: &Ticks) -> Self {
        Self {
            lo: ax.lo,
            hi: ax.hi,
            major: t.major.clone(),
            minor: t.minor.clone(),
        }
    }
}

impl Ranged for TickAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    /// Same rounding as plotters' own `RangedCoordf64`, so grid lines and
    /// data land on the pixels plotters would pick.
    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let logic = (v - self.lo) / (self.hi - self.lo);
        let actual = limit.1 - limit.0;
        if actual == 0 {
            return limit.1;
        }
        if logic.is_infinite() {
            return if logic > 0.0 { limit.1 } else { limit.0 };
        }
        if actual > 0 {
            limit.0 + (f64::from(actual) * logic + 1e-3).floor() as i32
        } else {
            limit.0 + (f64::from(actual) * logic - 1e-3).ceil() as i32
        }
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.minor.clone()
        } else {
            self.major.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.lo..self.hi
    }
}

/// Creates the image, draws the title, hands the area below the title to
/// `draw`, and writes the PNG.
fn render<F>(path: &Path, fig: &Figure, draw: F) -> Result<(), PlotError>
where
    F: FnOnce(&Area, &Style) -> Result<(), PlotError>,
{
    let (w, h) = (fig.width, fig.height);
    if !(MIN_SIDE..=MAX_SIDE).contains(&w) || !(MIN_SIDE..=MAX_SIDE).contains(&h) {
        return Err(PlotError::Input(format!(
            "image size {w}x{h} outside {MIN_SIDE}..={MAX_SIDE} pixels per side"
        )));
    }
    ensure_font()?;
    let st = Style::new(w, h);
    let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
    root.fill(&WHITE)?;
    let body = if fig.title.is_empty() {
        root.clone()
    } else {
        // Shrink a title that would not fit rather than clip it.
        let mut font = st.font(23.0);
        let avail = f64::from(w) - 2.0 * f64::from(st.px(10.0));
        let tw = f64::from(text_width(&root, fig.title, &font).max(1));
        if tw > avail {
            let size = (font.font.get_size() * avail / tw).max(9.0);
            font = TextStyle::from((FONT, size).into_font());
        }
        let top = root.margin(st.px(6.0), 0, 0, 0);
        top.titled(fig.title, font)?
    };
    draw(&body, &st)?;
    root.present()?;
    Ok(())
}

/// Sizes that scale with the image, so a 2000×1500 figure looks like a
/// zoomed 1000×750 one.
#[derive(Debug, Clone, Copy)]
struct Style {
    /// Scale of paddings and line widths.
    s: f64,
    /// Scale of fonts: never below 0.75, so small figures stay legible.
    fs: f64,
}

impl Style {
    fn new(w: u32, h: u32) -> Self {
        let s = (f64::from(w) / 1000.0)
            .min(f64::from(h) / 750.0)
            .clamp(0.3, 4.0);
        Self { s, fs: s.max(0.75) }
    }
    fn px(&self, v: f64) -> i32 {
        (v * self.s).round().max(1.0) as i32
    }
    /// Pixels for text-related sizes (line heights, swatches).
    fn fpx(&self, v: f64) -> i32 {
        (v * self.fs).round().max(1.0) as i32
    }
    fn font(&self, pt: f64) -> TextStyle<'static> {
        TextStyle::from((FONT, pt * self.fs).into_font())
    }
    fn tick(&self) -> TextStyle<'static> {
        self.font(15.0)
    }
    fn desc(&self) -> TextStyle<'static> {
        self.font(18.0)
    }
    fn legend(&self) -> TextStyle<'static> {
        self.font(15.0)
    }
}

/// Width of `text` in pixels; falls back to a rough estimate when the font
/// cannot lay it out, since the width only sizes margins.
fn text_width(area: &Area, text: &str, style: &TextStyle) -> i32 {
    area.estimate_text_size(text, style)
        .map(|(w, _)| w as i32)
        .unwrap_or_else(|_| (text.chars().count() as f64 * style.font.get_size() * 0.6) as i32)
}

fn rgb(c: Rgb) -> RGBColor {
    RGBColor(c.0, c.1, c.2)
}

/// Maps a data value to axis coordinates: `log10` on log axes. `None` for
/// values that cannot be shown (non-finite, or ≤ 0 on a log axis).
fn tf(log: bool, v: f64) -> Option<f64> {
    if !v.is_finite() {
        None
    } else if log {
        (v > 0.0).then(|| v.log10())
    } else {
        Some(v)
    }
}

/// Min and max of transformed values.
fn extent<I: IntoIterator<Item = f64>>(log: bool, values: I) -> Option<(f64, f64)> {
    let mut r: Option<(f64, f64)> = None;
    for t in values.into_iter().filter_map(|v| tf(log, v)) {
        r = Some(match r {
            None => (t, t),
            Some((a, b)) => (a.min(t), b.max(t)),
        });
    }
    r
}

fn merge(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    match (a, b) {
        (Some((a0, a1)), Some((b0, b1))) => Some((a0.min(b0), a1.max(b1))),
        (a, None) => a,
        (None, b) => b,
    }
}

/// One axis in transformed coordinates: `lo..hi` are `log10` values when
/// `log`. Always `lo < hi`, both finite.
#[derive(Debug, Clone, Copy)]
struct Axis {
    log: bool,
    lo: f64,
    hi: f64,
}

impl Axis {
    /// The axis for transformed extent `ext`: degenerate ranges widened,
    /// then padded by `pad` of the span on each side. No data gives 0..1
    /// (1..10 on a log axis).
    fn new(log: bool, ext: Option<(f64, f64)>, pad: f64) -> Self {
        let (mut lo, mut hi) = ext.unwrap_or((0.0, 1.0));
        if !(lo.is_finite() && hi.is_finite()) {
            (lo, hi) = (0.0, 1.0);
        }
        if hi < lo {
            std::mem::swap(&mut lo, &mut hi);
        }
        let scale = lo.abs().max(hi.abs());
        if hi - lo <= scale * 1e-12 {
            // Constant data: a decade either side on log axes, ±10% (or ±1
            // around zero) on linear ones.
            let c = 0.5 * lo + 0.5 * hi;
            let d = if log || c == 0.0 { 1.0 } else { 0.1 * c.abs() };
            (lo, hi) = (c - d, c + d);
        }
        let p = pad * (hi - lo);
        if p.is_finite() && (lo - p).is_finite() && (hi + p).is_finite() {
            (lo, hi) = (lo - p, hi + p);
        }
        Self { log, lo, hi }
    }

    fn span(&self) -> f64 {
        self.hi - self.lo
    }

    /// Position of transformed value `t` as a fraction of the axis.
    fn frac(&self, t: f64) -> f64 {
        (t - self.lo) / self.span()
    }
}

/// How tick values are turned into labels.
#[derive(Debug, Clone, Copy)]
enum TickFmt {
    /// Fixed decimals (linear axes).
    Fixed(usize),
    /// Scientific with the given mantissa decimals (linear axes far from 1).
    Sci(usize),
    /// "10ⁿ" (log axes spanning decades).
    Pow10,
    /// Shortest readable form of `10^t` (log axes narrower than a few
    /// decades, where ticks are 1, 2, 5 × 10ⁿ and friends).
    General,
}

/// Tick positions (transformed coordinates) and their label format.
#[derive(Debug, Clone)]
struct Ticks {
    major: Vec<f64>,
    minor: Vec<f64>,
    fmt: TickFmt,
}

impl Ticks {
    fn label(&self, t: f64) -> String {
        match self.fmt {
            TickFmt::Fixed(d) => {
                let s = format!("{t:.d$}");
                // "-0.0" reads as a bug.
                if s.trim_start_matches('-')
                    .chars()
                    .all(|c| c == '0' || c == '.')
                {
                    s.trim_start_matches('-').to_string()
                } else {
                    s
                }
            }
            // Uniform mantissa digits (no trimming): 1.0e5, 1.5e5, 2.0e5.
            TickFmt::Sci(d) => {
                if t == 0.0 {
                    "0".to_string()
                } else {
                    format!("{t:.d$e}")
                }
            }
            TickFmt::Pow10 => format!("10{}", superscript(t.round() as i64)),
            TickFmt::General => fmt_general(10f64.powf(t)),
        }
    }
}

/// "1.50e-7" → "1.5e-7", "2.00e5" → "2e5".
fn trim_sci(s: &str) -> String {
    match s.split_once('e') {
        Some((m, e)) if m.contains('.') => {
            let m = m.trim_end_matches('0').trim_end_matches('.');
            format!("{m}e{e}")
        }
        _ => s.to_string(),
    }
}

fn superscript(k: i64) -> String {
    k.to_string()
        .chars()
        .map(|c| match c {
            '-' => '⁻',
            '0' => '⁰',
            '1' => '¹',
            '2' => '²',
            '3' => '³',
            '4' => '⁴',
            '5' => '⁵',
            '6' => '⁶',
            '7' => '⁷',
            '8' => '⁸',
            _ => '⁹',
        })
        .collect()
}

/// A short, exact-looking rendering of a single number: up to four
/// significant digits, trailing zeros trimmed, scientific notation far from 1
/// (so 0.1 + 0.2 prints as "0.3").
fn fmt_general(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v.is_nan() {
            "NaN".into()
        } else if v == 0.0 {
            "0".into()
        } else {
            format!("{v}")
        };
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return trim_sci(&format!("{v:.3e}"));
    }
    let d = (3 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.d$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// A "nice" step (1, 2 or 5 × 10ⁿ) at least `raw`.
fn nice_step(raw: f64) -> f64 {
    let e = raw.log10().floor();
    let b = 10f64.powf(e);
    let m = raw / b;
    let n = if m <= 1.0 {
        1.0
    } else if m <= 2.0 {
        2.0
    } else if m <= 5.0 {
        5.0
    } else {
        10.0
    };
    n * b
}

/// About `target` evenly spaced nice values in `lo..=hi`, and the step.
fn linear_values(lo: f64, hi: f64, target: usize) -> Option<(Vec<f64>, f64)> {
    let span = hi - lo;
    if !(span.is_finite() && span > 0.0) {
        return None;
    }
    let step = nice_step(span / target.max(1) as f64);
    if !(step.is_finite() && step > 0.0) {
        return None;
    }
    let k0 = (lo / step - 1e-9).ceil();
    let k1 = (hi / step + 1e-9).floor();
    let n = k1 - k0;
    if !(0.0..200.0).contains(&n) {
        return None;
    }
    let v = (0..=n as usize)
        .map(|i| {
            let x = (k0 + i as f64) * step;
            if x.abs() < step * 1e-9 {
                0.0
            } else {
                x
            }
        })
        .collect();
    Some((v, step))
}

/// Decimals needed to show multiples of `step` exactly.
fn decimals_for(step: f64) -> usize {
    (0..=12)
        .find(|&d| {
            let m = step * 10f64.powi(d as i32);
            (m - m.round()).abs() < 1e-6 * m.abs().max(1.0)
        })
        .unwrap_or(12)
}

/// Ticks for an axis, about `target` labelled ones.
fn ticks(ax: &Axis, target: usize) -> Ticks {
    if ax.log {
        log_ticks(ax, target)
    } else {
        linear_ticks(ax, target)
    }
}

fn linear_ticks(ax: &Axis, target: usize) -> Ticks {
    let Some((major, step)) = linear_values(ax.lo, ax.hi, target) else {
        return Ticks {
            major: vec![],
            minor: vec![],
            fmt: TickFmt::General,
        };
    };
    let mag = ax.lo.abs().max(ax.hi.abs());
    let fmt = if !(1e-3..1e6).contains(&mag) {
        let digits = (mag.log10().floor() - step.log10().floor()).clamp(0.0, 8.0);
        TickFmt::Sci(digits as usize)
    } else {
        TickFmt::Fixed(decimals_for(step))
    };
    Ticks {
        major,
        minor: vec![],
        fmt,
    }
}

fn log_ticks(ax: &Axis, target: usize) -> Ticks {
    let (lo, hi) = (ax.lo, ax.hi);
    let inside = |t: f64| t >= lo - 1e-9 && t <= hi + 1e-9;
    let d0 = (lo - 1e-9).ceil();
    let d1 = (hi + 1e-9).floor();
    if !(d0.is_finite() && d1.is_finite()) || d1 - d0 > 2000.0 {
        return Ticks {
            major: vec![],
            minor: vec![],
            fmt: TickFmt::General,
        };
    }
    let ndec = (d1 - d0 + 1.0).max(0.0) as usize;
    // Multiples m × 10ⁿ for m in `set`, inside the axis.
    let multiples = |set: &[f64]| -> Vec<f64> {
        let mut v = vec![];
        let (k0, k1) = (lo.floor() as i64, hi.ceil() as i64);
        for k in k0..=k1 {
            for &m in set {
                let t = k as f64 + m.log10();
                if inside(t) {
                    v.push(t);
                }
            }
        }
        v
    };
    let decades = |stride: usize| -> Ticks {
        let (mut major, mut minor) = (vec![], vec![]);
        for i in 0..ndec {
            let k = d0 + i as f64;
            if (k as i64).rem_euclid(stride as i64) == 0 {
                major.push(k);
            } else {
                minor.push(k);
            }
        }
        if stride == 1 {
            minor = multiples(&[2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
        }
        Ticks {
            major,
            minor,
            fmt: TickFmt::Pow10,
        }
    };
    if ndec >= 3 {
        return decades(ndec.div_ceil(target.max(1) + 1).max(1));
    }
    let a = multiples(&[1.0, 2.0, 5.0]);
    if a.len() >= 3 && a.len() <= target + 2 {
        return Ticks {
            major: a,
            minor: multiples(&[3.0, 4.0, 6.0, 7.0, 8.0, 9.0]),
            fmt: TickFmt::General,
        };
    }
    if ndec == 2 {
        return decades(1);
    }
    let b = multiples(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    if b.len() >= 3 && b.len() <= target + 3 {
        return Ticks {
            major: b,
            minor: vec![],
            fmt: TickFmt::General,
        };
    }
    // Less than about a factor 1.3: linear ticks in value space.
    let major = linear_values(10f64.powf(lo), 10f64.powf(hi), target)
        .map(|(v, _)| v.into_iter().filter_map(|x| tf(true, x)).collect())
        .unwrap_or_default();
    Ticks {
        major,
        minor: vec![],
        fmt: TickFmt::General,
    }
}

/// Pixel rectangle of a plotting area, absolute, ends exclusive.
#[derive(Debug, Clone, Copy)]
struct Frame {
    x0: i32,
    x1: i32,
    y0: i32,
    y1: i32,
}

impl Frame {
    fn of<DB: DrawingBackend, CT: CoordTranslate>(area: &DrawingArea<DB, CT>) -> Self {
        let (xr, yr) = area.get_pixel_range();
        Self {
            x0: xr.start,
            x1: xr.end,
            y0: yr.start,
            y1: yr.end,
        }
    }
    fn w(&self) -> usize {
        (self.x1 - self.x0).max(0) as usize
    }
    fn h(&self) -> usize {
        (self.y1 - self.y0).max(0) as usize
    }
}

/// Ticks for a chart drawn on `area`: about one label per 110 pixels
/// across and 70 pixels up, so labels never crowd.
fn chart_ticks(area: &Area, st: &Style, xa: &Axis, ya: &Axis) -> (Ticks, Ticks) {
    let (aw, ah) = area.dim_in_pixel();
    let nx = (f64::from(aw) - 150.0 * st.s) / (110.0 * st.s);
    let ny = (f64::from(ah) - 110.0 * st.s) / (70.0 * st.s);
    (
        ticks(xa, nx.clamp(2.0, 10.0) as usize),
        ticks(ya, ny.clamp(2.0, 10.0) as usize),
    )
}

/// Builds a chart with axes, ticks, labels and (optionally) grid lines, with
/// label areas sized from the actual tick labels so nothing overlaps.
/// `right_pad` leaves room for half of the last x tick label.
fn build_chart<'c, 'b>(
    area: &Area<'b>,
    st: &Style,
    fig: &Figure,
    xa: &Axis,
    ya: &Axis,
    grid: bool,
    right_pad: i32,
) -> Result<(Chart<'c, 'b>, Frame), PlotError> {
    let (x_label, y_label) = (fig.x_label, fig.y_label);
    let tick_font = st.tick();
    let desc_font = st.desc();
    let (xt, yt) = chart_ticks(area, st, xa, ya);
    let y_tick_w = yt
        .major
        .iter()
        .map(|&t| text_width(area, &yt.label(t), &tick_font))
        .max()
        .unwrap_or(0);
    let desc_h = st.fpx(18.0 * 1.3);
    let tick = st.px(5.0);
    let y_area =
        y_tick_w + 2 * tick + tick + st.px(6.0) + if y_label.is_empty() { 0 } else { desc_h };
    let x_area =
        st.fpx(15.0 * 1.2) + 2 * tick + st.px(8.0) + if x_label.is_empty() { 0 } else { desc_h };

    let mut builder = ChartBuilder::on(area);
    builder
        .margin_top(st.px(14.0))
        .margin_bottom(st.px(8.0))
        .margin_left(st.px(10.0))
        .margin_right(right_pad.max(0))
        .x_label_area_size(x_area)
        .y_label_area_size(y_area);
    let mut chart = builder.build_cartesian_2d(TickAxis::new(xa, &xt), TickAxis::new(ya, &yt))?;
    {
        let fx = |t: &f64| xt.label(*t);
        let fy = |t: &f64| yt.label(*t);
        let mut mesh = chart.configure_mesh();
        mesh.x_label_formatter(&fx)
            .y_label_formatter(&fy)
            .label_style(tick_font.clone())
            .axis_desc_style(desc_font.clone())
            .bold_line_style(GRID)
            .light_line_style(GRID_MINOR)
            .axis_style(BLACK)
            .set_all_tick_mark_size(tick);
        if !x_label.is_empty() {
            mesh.x_desc(x_label);
        }
        if !y_label.is_empty() {
            mesh.y_desc(y_label);
        }
        if !grid {
            mesh.disable_mesh();
        }
        mesh.draw()?;
    }
    let frame = Frame::of(chart.plotting_area());
    Ok((chart, frame))
}

/// Black box around the plotting area, on the pixels of the axis lines.
fn draw_frame(area: &Area, f: &Frame) -> Result<(), PlotError> {
    let (bx, by) = area.get_base_pixel();
    area.draw(&Rectangle::new(
        [(f.x0 - 1 - bx, f.y0 - 1 - by), (f.x1 - bx, f.y1 - by)],
        BLACK.stroke_width(1),
    ))?;
    Ok(())
}

/// Copies an RGB buffer of the frame's size onto the plotting area.
fn blit(area: &Area, f: &Frame, buf: Vec<u8>) -> Result<(), PlotError> {
    let (w, h) = (f.w(), f.h());
    if w == 0 || h == 0 {
        return Ok(());
    }
    let (bx, by) = area.get_base_pixel();
    let elem = BitMapElement::with_owned_buffer((f.x0 - bx, f.y0 - by), (w as u32, h as u32), buf)
        .ok_or_else(|| PlotError::Backend("raster buffer has the wrong size".into()))?;
    area.draw(&elem)?;
    Ok(())
}

fn no_data(area: &Area, f: &Frame, st: &Style) -> Result<(), PlotError> {
    let (bx, by) = area.get_base_pixel();
    let style = st
        .font(26.0)
        .color(&NOTE_GREY)
        .pos(Pos::new(HPos::Center, VPos::Center));
    area.draw_text(
        "no data",
        &style,
        ((f.x0 + f.x1) / 2 - bx, (f.y0 + f.y1) / 2 - by),
    )?;
    Ok(())
}

fn put(buf: &mut [u8], idx: usize, c: Rgb) {
    if let Some(p) = buf.get_mut(3 * idx..3 * idx + 3) {
        p.copy_from_slice(&[c.0, c.1, c.2]);
    }
}

/// Viridis, linearly interpolated between ten control points (matplotlib's
/// `viridis(linspace(0, 1, 10))`): perceptually uniform and readable by
/// colour-blind readers and in greyscale. `t` is clamped to 0..=1.
fn viridis(t: f64) -> Rgb {
    const V: [Rgb; 10] = [
        (0x44, 0x01, 0x54),
        (0x48, 0x28, 0x78),
        (0x3e, 0x4a, 0x89),
        (0x31, 0x68, 0x8e),
        (0x26, 0x82, 0x8e),
        (0x1f, 0x9e, 0x89),
        (0x35, 0xb7, 0x79),
        (0x6d, 0xcd, 0x59),
        (0xb4, 0xde, 0x2c),
        (0xfd, 0xe7, 0x25),
    ];
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let p = t * (V.len() - 1) as f64;
    let i = (p.floor() as usize).min(V.len() - 2);
    let f = p - i as f64;
    let (a, b) = (V[i], V[i + 1]);
    let mix = |x: u8, y: u8| (f64::from(x) + f * (f64::from(y) - f64::from(x))).round() as u8;
    (mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// `over` composited onto `under` with opacity `alpha`.
fn blend(under: Rgb, over: Rgb, alpha: f64) -> Rgb {
    let m = |u: u8, o: u8| (f64::from(u) + alpha * (f64::from(o) - f64::from(u))).round() as u8;
    (m(under.0, over.0), m(under.1, over.1), m(under.2, over.2))
}

/// A colour bar: `axis` in transformed coordinates (log10 when `axis.log`).
struct ColorBar<'l> {
    axis: Axis,
    ticks: Ticks,
    label: &'l str,
    /// Whether to show a grey "NaN" swatch under the bar.
    nan: bool,
}

impl<'l> ColorBar<'l> {
    fn new(axis: Axis, label: &'l str, nan: bool, plot_h: f64, st: &Style) -> Self {
        let target = ((plot_h - 110.0 * st.s) / (60.0 * st.s)).clamp(2.0, 10.0) as usize;
        let ticks = ticks(&axis, target);
        Self {
            axis,
            ticks,
            label,
            nan,
        }
    }

    /// Widest tick label (or the "NaN" note).
    fn label_width(&self, area: &Area, st: &Style) -> i32 {
        let font = st.tick();
        let nan = if self.nan {
            text_width(area, "NaN", &font)
        } else {
            0
        };
        self.ticks
            .major
            .iter()
            .map(|&t| text_width(area, &self.ticks.label(t), &font))
            .fold(nan, i32::max)
    }

    /// Width of the panel: gap, bar, tick marks, labels, title.
    fn width(&self, area: &Area, st: &Style) -> i32 {
        Self::gap(st)
            + st.fpx(Self::BAR)
            + 3 * st.px(5.0)
            + self.label_width(area, st)
            + st.px(12.0)
            + if self.label.is_empty() {
                0
            } else {
                st.fpx(18.0 * 1.3)
            }
            + st.px(10.0)
    }

    const BAR: f64 = 22.0;

    /// Space between the plot and the bar.
    fn gap(st: &Style) -> i32 {
        st.px(24.0).max(12)
    }

    /// Draws the bar on `side`, vertically aligned with the main plot `main`.
    /// The title is drawn here rather than as a plotters axis description,
    /// which would put it at the outer edge of the label area, reading
    /// downwards and partly cut off.
    fn draw(&self, side: &Area, st: &Style, main: &Frame) -> Result<(), PlotError> {
        let (sx, sy) = side.get_base_pixel();
        let (sw, sh) = side.dim_in_pixel();
        let gap = Self::gap(st);
        let bar = st.fpx(Self::BAR);
        let label_area = (sw as i32 - gap - bar).max(0);
        let mut builder = ChartBuilder::on(side);
        builder
            .margin_top((main.y0 - sy).max(0))
            .margin_bottom((sy + sh as i32 - main.y1).max(0))
            .margin_left(gap)
            .margin_right(0)
            .x_label_area_size(0)
            .y_label_area_size(0)
            .right_y_label_area_size(label_area);
        let unit = Axis {
            log: false,
            lo: 0.0,
            hi: 1.0,
        };
        let none = Ticks {
            major: vec![],
            minor: vec![],
            fmt: TickFmt::General,
        };
        let major = Ticks {
            minor: vec![],
            ..self.ticks.clone()
        };
        let mut chart = builder.build_cartesian_2d(
            TickAxis::new(&unit, &none),
            TickAxis::new(&self.axis, &major),
        )?;
        {
            let fy = |t: &f64| self.ticks.label(*t);
            let fx = |_: &f64| String::new();
            let mut mesh = chart.configure_mesh();
            mesh.disable_mesh()
                .disable_x_axis()
                .x_label_formatter(&fx)
                .y_label_formatter(&fy)
                .label_style(st.tick())
                .axis_style(BLACK)
                .set_all_tick_mark_size(st.px(5.0));
            mesh.draw()?;
        }
        let f = Frame::of(chart.plotting_area());
        let (w, h) = (f.w(), f.h());
        let mut buf = vec![0u8; 3 * w * h];
        for j in 0..h {
            let c = viridis(1.0 - (j as f64 + 0.5) / h as f64);
            for i in 0..w {
                put(&mut buf, j * w + i, c);
            }
        }
        blit(side, &f, buf)?;
        draw_frame(side, &f)?;
        if !self.label.is_empty() {
            let x = f.x1 - sx + 3 * st.px(5.0) + self.label_width(side, st) + st.px(12.0);
            let style = st
                .desc()
                .transform(FontTransform::Rotate270)
                .pos(Pos::new(HPos::Center, VPos::Top));
            side.draw_text(self.label, &style, (x, (f.y0 + f.y1) / 2 - sy))?;
        }
        if self.nan {
            let top = f.y1 + st.px(16.0) - sy;
            let left = f.x0 - sx;
            side.draw(&Rectangle::new(
                [(left, top), (left + bar, top + bar)],
                rgb(NAN_GREY).filled(),
            ))?;
            side.draw(&Rectangle::new(
                [(left - 1, top - 1), (left + bar, top + bar)],
                BLACK.stroke_width(1),
            ))?;
            let style = st.tick().pos(Pos::new(HPos::Left, VPos::Center));
            side.draw_text("NaN", &style, (left + bar + st.px(8.0), top + bar / 2))?;
        }
        Ok(())
    }
}

/// Splits `body` into the main plot and a right-hand panel of `side_w`
/// pixels (colour bar or legend).
fn split_side<'b>(body: &Area<'b>, side_w: i32) -> (Area<'b>, Area<'b>) {
    let (w, _) = body.dim_in_pixel();
    body.split_horizontally((w as i32 - side_w).max(0))
}

// ---------------------------------------------------------------------------
// Gridded figures
// ---------------------------------------------------------------------------

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
    let cols: Vec<Option<usize>> = (0..w)
        .map(|i| cx.find(xa.lo + (i as f64 + 0.5) / w as f64 * xa.span()))
        .collect();
    let rows: Vec<Option<usize>> = (0..h)
        .map(|j| cy.find(ya.hi - (j as f64 + 0.5) / h as f64 * ya.span()))
        .collect();
    let mut buf = vec![255u8; 3 * w * h];
    for (j, row) in rows.iter().enumerate() {
        let Some(iy) = *row else { continue };
        for (i, col) in cols.iter().enumerate() {
            if let Some(ix) = *col {
                put(&mut buf, j * w + i, cell(ix, iy));
            }
        }
    }
    buf
}

fn check_grid(nx: usize, ny: usize, n: usize, what: &str) -> Result<(), PlotError> {
    match nx.checked_mul(ny) {
        Some(m) if m == n => Ok(()),
        _ => Err(PlotError::Input(format!(
            "{what} has {n} entries, but the grid is {nx} x {ny}"
        ))),
    }
}

#[allow(clippy::too_many_arguments)]
fn heatmap_impl(
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
    check_grid(x.len(), y.len(), values.len(), "values")?;
    let ny = y.len();
    let cells = Cells::new(x, x_log).zip(Cells::new(y, y_log));
    let crange = extent(log_color, values.iter().copied());
    let has_nan = values.iter().any(|v| !v.is_finite());
    render(path, fig, |body, st| {
        let ca = Axis::new(log_color, crange, 0.0);
        let (_, bh) = body.dim_in_pixel();
        let cb = ColorBar::new(ca, value_label, has_nan, f64::from(bh), st);
        let (main, side) = split_side(body, cb.width(body, st));
        let (xa, ya) = match &cells {
            Some((cx, cy)) => (cx.axis(x_log), cy.axis(y_log)),
            None => (Axis::new(x_log, None, 0.0), Axis::new(y_log, None, 0.0)),
        };
        let (_chart, f) = build_chart(&main, st, fig, &xa, &ya, false, st.px(12.0))?;
        match &cells {
            Some((cx, cy)) if !values.is_empty() => {
                let colour = |v: f64| -> Rgb {
                    if !v.is_finite() {
                        NAN_GREY
                    } else if log_color && v <= 0.0 {
                        viridis(0.0)
                    } else {
                        let t = if log_color { v.log10() } else { v };
                        viridis(ca.frac(t))
                    }
                };
                let buf = grid_raster(&f, &xa, &ya, cx, cy, |ix, iy| {
                    values.get(ix * ny + iy).map_or(NAN_GREY, |&v| colour(v))
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
fn class_map_impl(
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

// ---------------------------------------------------------------------------
// Point clouds
// ---------------------------------------------------------------------------

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

fn point_cloud_impl(
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

fn legend_box<'c, 'b: 'c>(
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

// ---------------------------------------------------------------------------
// Line plots
// ---------------------------------------------------------------------------

/// A series split into runs of drawable points (transformed coordinates).
struct Runs {
    runs: Vec<Vec<(f64, f64)>>,
}

impl Runs {
    fn new(s: &Series, x_log: bool, y_log: bool) -> Self {
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

    fn points(&self) -> impl Iterator<Item = &(f64, f64)> {
        self.runs.iter().flatten()
    }
}

fn check_series(series: &[Series]) -> Result<(), PlotError> {
    for s in series {
        if s.x.len() != s.y.len() {
            return Err(PlotError::Input(format!(
                "series \"{}\": x has {} values, y has {}",
                s.name,
                s.x.len(),
                s.y.len()
            )));
        }
    }
    Ok(())
}

/// Coarse occupancy of the plotting area (row 0 at the top, like pixels),
/// used to put the legend where it hides the least data.
#[derive(Clone)]
struct Occupancy {
    cells: Vec<bool>,
}

impl Occupancy {
    const GX: usize = 100;
    const GY: usize = 75;

    fn new() -> Self {
        Self {
            cells: vec![false; Self::GX * Self::GY],
        }
    }

    /// Occupancy of a `w`×`h` count image.
    fn from_counts(counts: &[u32], w: usize, h: usize) -> Self {
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
    fn add_run(&mut self, run: &[(f64, f64)], xa: &Axis, ya: &Axis) {
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
    fn mark_rect(&mut self, (x0, y0, x1, y1): (i32, i32, i32, i32), w: usize, h: usize) {
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
    fn score(&self, (x0, y0, x1, y1): (i32, i32, i32, i32), w: i32, h: i32) -> usize {
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
fn legend_position(
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

fn lines_impl(
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
) -> (i32, i32, i32, i32) {
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

fn loglog_impl(
    path: &Path,
    fig: &Figure,
    series: &[Series],
    slopes: &[Slope],
) -> Result<(), PlotError> {
    check_series(series)?;
    let prepared: Vec<Runs> = series.iter().map(|s| Runs::new(s, true, true)).collect();
    let has_data = prepared.iter().any(|r| !r.runs.is_empty());
    let good_slopes: Vec<&Slope> = slopes
        .iter()
        .filter(|s| {
            s.slope.is_finite() && tf(true, s.anchor.0).is_some() && tf(true, s.anchor.1).is_some()
        })
        .collect();
    // Anchors count towards the range only alongside data: alone they would
    // make a chart of reference lines with nothing to compare.
    let anchors = || good_slopes.iter().filter(|_| has_data).map(|s| s.anchor);
    let ext_x = merge(
        extent(false, prepared.iter().flat_map(|r| r.points().map(|p| p.0))),
        extent(true, anchors().map(|a| a.0)),
    );
    let ext_y = merge(
        extent(false, prepared.iter().flat_map(|r| r.points().map(|p| p.1))),
        extent(true, anchors().map(|a| a.1)),
    );
    let xa = Axis::new(true, ext_x, 0.03);
    let ya = Axis::new(true, ext_y, 0.03);
    let with_legend = series.iter().any(|s| !s.name.is_empty()) && series.len() < MANY_SERIES;
    render(path, fig, |body, st| {
        let (mut chart, f) = build_chart(body, st, fig, &xa, &ya, true, st.px(28.0))?;
        // Occupancy of the data first: slope labels are placed to avoid it.
        let mut occ = Occupancy::new();
        for run in prepared.iter().flat_map(|r| r.runs.iter()) {
            occ.add_run(run, &xa, &ya);
        }
        // Reference slopes before the data, so the data is drawn over them.
        let lines: Vec<(&Slope, Pt, Pt)> = if has_data {
            good_slopes
                .iter()
                .filter_map(|s| {
                    let (ax, ay) = (s.anchor.0.log10(), s.anchor.1.log10());
                    let line = |tx: f64| (tx, ay + s.slope * (tx - ax));
                    clip(line(xa.lo), line(xa.hi), &xa, &ya).map(|(p0, p1)| (*s, p0, p1))
                })
                .collect()
        } else {
            vec![]
        };
        let grey = RGBColor(80, 80, 80);
        let label_font = st.font(15.0);
        let mut placed: Vec<(i32, i32, i32, i32)> = vec![];
        for (k, (s, p0, p1)) in lines.iter().enumerate() {
            chart.draw_series(DashedLineSeries::new(
                [*p0, *p1],
                st.px(9.0),
                st.px(6.0),
                grey.stroke_width(st.px(1.5) as u32),
            ))?;
            let mut o = occ.clone();
            for (j, (_, q0, q1)) in lines.iter().enumerate() {
                if j != k {
                    o.add_run(&[*q0, *q1], &xa, &ya);
                }
            }
            for r in &placed {
                o.mark_rect(*r, f.w(), f.h());
            }
            let size = body
                .estimate_text_size(&s.label, &label_font)
                .map(|(w, h)| (w as i32, h as i32))
                .unwrap_or((st.fpx(60.0), st.fpx(15.0)));
            let r = slope_label_box(&o, s.slope, *p0, *p1, size, &xa, &ya, &f, st);
            placed.push(r);
            let (bx, by) = body.get_base_pixel();
            let pad = st.px(2.0);
            let (x, y) = (f.x0 + r.0 - bx, f.y0 + r.1 - by);
            body.draw(&Rectangle::new(
                [(x - pad, y - pad), (x + size.0 + pad, y + size.1 + pad)],
                WHITE.mix(0.8).filled(),
            ))?;
            body.draw_text(
                &s.label,
                &label_font.color(&grey).pos(Pos::new(HPos::Left, VPos::Top)),
                (x, y),
            )?;
        }
        for (_, p0, p1) in &lines {
            occ.add_run(&[*p0, *p1], &xa, &ya);
        }
        for r in &placed {
            occ.mark_rect(*r, f.w(), f.h());
        }
        let r = st.px(4.0);
        let width = st.px(2.0) as u32;
        for (i, (s, runs)) in series.iter().zip(&prepared).enumerate() {
            let c = rgb(s.color.unwrap_or_else(|| palette(i)));
            let line = c.stroke_width(width);
            for run in &runs.runs {
                if run.len() > 1 {
                    chart.draw_series(LineSeries::new(run.iter().copied(), line))?;
                }
                draw_markers(&mut chart, run, i, r, c.filled())?;
            }
            if with_legend && !s.name.is_empty() {
                let len = st.px(30.0);
                let m = (len / 2, 0);
                let fill = c.filled();
                let anno = chart
                    .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
                    .label(s.name);
                let path = move || PathElement::new(vec![(0, 0), (len, 0)], line);
                match i % 5 {
                    0 => {
                        anno.legend(move |p| EmptyElement::at(p) + path() + Circle::new(m, r, fill))
                    }
                    1 => anno.legend(move |p| {
                        EmptyElement::at(p)
                            + path()
                            + Rectangle::new([(m.0 - r, -r), (m.0 + r, r)], fill)
                    }),
                    2 => anno.legend(move |p| {
                        EmptyElement::at(p) + path() + TriangleMarker::new(m, r + 1, fill)
                    }),
                    3 => anno.legend(move |p| {
                        let d = diamond(r)
                            .into_iter()
                            .map(|q| (q.0 + m.0, q.1))
                            .collect::<Vec<_>>();
                        EmptyElement::at(p) + path() + Polygon::new(d, fill)
                    }),
                    _ => anno.legend(move |p| {
                        EmptyElement::at(p) + path() + Cross::new(m, r, fill.stroke_width(2))
                    }),
                };
            }
        }
        if !has_data {
            no_data(body, &f, st)?;
        }
        draw_frame(body, &f)?;
        if with_legend && has_data {
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

// ---------------------------------------------------------------------------
// Tests
// ---------------------------------------------------------------------------

#[cfg(test)]
mod tests {
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
