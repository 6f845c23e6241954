//! The image a figure is drawn on: the embedded font, the guard against
//! plotters' panics, the title, and sizes that scale with the image.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

use super::figure::{Figure, PlotError};
use super::fonts::{ensure_font, runs, FONT};

/// Smallest and largest accepted image sides: below the minimum the axis
/// labels would not fit; above the maximum the RGB buffer gets absurd.
const MIN_SIDE: u32 = 160;
const MAX_SIDE: u32 = 16384;

/// Runs `f`, turning a panic into `PlotError::Panic`.
pub(super) fn guarded<F: FnOnce() -> Result<(), PlotError>>(f: F) -> Result<(), PlotError> {
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

pub(super) type Area<'b> = DrawingArea<BitMapBackend<'b>, Shift>;

/// Creates the image, draws the title, hands the area below the title to
/// `draw`, and writes the PNG.
pub(super) fn render<F>(path: &Path, fig: &Figure, draw: F) -> Result<(), PlotError>
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
        draw_title(&root.margin(st.px(6.0), 0, 0, 0), fig.title, &st)?
    };
    draw(&body, &st)?;
    root.present()?;
    Ok(())
}

/// Draws `title` centred at the top of `area`, in runs of the fonts that
/// have its characters, shrunk to fit the width rather than clipped;
/// returns the area below it (as plotters' `titled` would).
fn draw_title<'b>(area: &Area<'b>, title: &str, st: &Style) -> Result<Area<'b>, PlotError> {
    let runs = runs(title);
    let width = |size: f64| -> f64 {
        runs.iter()
            .map(|(family, text)| {
                let style = TextStyle::from((*family, size).into_font());
                f64::from(text_width(area, text, &style))
            })
            .sum()
    };
    let (w, _) = area.dim_in_pixel();
    let mut size = 23.0 * st.fs;
    let avail = f64::from(w) - 2.0 * f64::from(st.px(10.0));
    let tw = width(size).max(1.0);
    if tw > avail {
        size = (size * avail / tw).max(9.0);
    }
    // plotters' line height and padding for a title of this size.
    let text_h = (size / 1.24) as i32;
    let pad = (text_h / 2).min(5);
    let mut x = ((f64::from(w) - width(size)) / 2.0).max(0.0);
    for (family, text) in &runs {
        let style =
            TextStyle::from((*family, size).into_font()).pos(Pos::new(HPos::Left, VPos::Top));
        area.draw_text(text, &style, (x.round() as i32, pad))?;
        x += f64::from(text_width(area, text, &style));
    }
    Ok(area.split_vertically(2 * pad + text_h).1)
}

/// Sizes that scale with the image, so a 2000×1500 figure looks like a
/// zoomed 1000×750 one.
#[derive(Debug, Clone, Copy)]
pub(super) struct Style {
    /// Scale of paddings and line widths.
    pub(super) s: f64,
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
    pub(super) fn px(&self, v: f64) -> i32 {
        (v * self.s).round().max(1.0) as i32
    }
    /// Pixels for text-related sizes (line heights, swatches).
    pub(super) fn fpx(&self, v: f64) -> i32 {
        (v * self.fs).round().max(1.0) as i32
    }
    pub(super) fn font(&self, pt: f64) -> TextStyle<'static> {
        TextStyle::from((FONT, pt * self.fs).into_font())
    }
    pub(super) fn tick(&self) -> TextStyle<'static> {
        self.font(15.0)
    }
    pub(super) fn desc(&self) -> TextStyle<'static> {
        self.font(18.0)
    }
    pub(super) fn legend(&self) -> TextStyle<'static> {
        self.font(15.0)
    }
}

/// Width of `text` in pixels; falls back to a rough estimate when the font
/// cannot lay it out, since the width only sizes margins.
pub(super) fn text_width(area: &Area, text: &str, style: &TextStyle) -> i32 {
    area.estimate_text_size(text, style)
        .map(|(w, _)| w as i32)
        .unwrap_or_else(|_| (text.chars().count() as f64 * style.font.get_size() * 0.6) as i32)
}
