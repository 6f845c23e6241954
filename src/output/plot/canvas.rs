//! The image a figure is drawn on: the embedded font, the guard against
//! plotters' panics, the title, and sizes that scale with the image.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::register_font;

use super::figure::{Figure, PlotError};

const FONT: &str = "sans-serif";
const FONT_BYTES: &[u8] = include_bytes!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/assets/DejaVuSans.ttf"
));
/// Smallest and largest accepted image sides: below the minimum the axis
/// labels would not fit; above the maximum the RGB buffer gets absurd.
const MIN_SIDE: u32 = 160;
const MAX_SIDE: u32 = 16384;

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
