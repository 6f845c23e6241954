//! The figures' vocabulary: series, figure options, reference slopes,
//! errors, and the default colours of series.

use plotters::drawing::DrawingAreaErrorKind;

use super::axis::fmt_general;

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

/// A scalar field over a 2-D grid, for [`heat_map`](super::heat_map).
#[derive(Debug, Clone, Copy)]
pub struct HeatMap<'a> {
    pub x: &'a [f64],
    pub y: &'a [f64],
    /// `values[ix * y.len() + iy]` sits at `(x[ix], y[iy])`.
    pub values: &'a [f64],
    /// The colour bar's title.
    pub label: &'a str,
    /// Colours on a log scale of the positive values.
    pub log_color: bool,
    pub x_log: bool,
    pub y_log: bool,
    /// Why each cell whose value is not finite has none: an index into
    /// `undefined`, one per cell. Empty, or an index past `undefined`: "NaN".
    pub why: &'a [u8],
    /// What a cell without a value means and its colour (a grey, not a
    /// colour of the scale), listed under the colour bar where it occurs.
    pub undefined: &'a [(&'a str, Rgb)],
    /// Values marked across the colour bar, with their labels (the
    /// resonances p/q on a map of a mean).
    pub marks: &'a [(f64, &'a str)],
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

pub(super) fn check_series(series: &[Series]) -> Result<(), PlotError> {
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
