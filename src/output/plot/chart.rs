//! A chart on a drawing area: axes, ticks, labels and grid lines sized so
//! nothing overlaps; the frame of its plotting area, blitting a raster onto
//! it, the "no data" note, and splitting off a side panel.

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::axis::{ticks, Axis, TickAxis, Ticks};
use super::canvas::{text_width, Area, Style};
use super::colour::{GRID, GRID_MINOR, NOTE_GREY};
use super::figure::{Figure, PlotError};

pub(super) type Chart<'c, 'b> =
    ChartContext<'c, BitMapBackend<'b>, Cartesian2d<TickAxis, TickAxis>>;

/// Pixel rectangle of a plotting area, absolute, ends exclusive.
#[derive(Debug, Clone, Copy)]
pub(super) struct Frame {
    pub(super) x0: i32,
    pub(super) x1: i32,
    pub(super) y0: i32,
    pub(super) y1: i32,
}

impl Frame {
    pub(super) fn of<DB: DrawingBackend, CT: CoordTranslate>(area: &DrawingArea<DB, CT>) -> Self {
        let (xr, yr) = area.get_pixel_range();
        Self {
            x0: xr.start,
            x1: xr.end,
            y0: yr.start,
            y1: yr.end,
        }
    }
    pub(super) fn w(&self) -> usize {
        (self.x1 - self.x0).max(0) as usize
    }
    pub(super) fn h(&self) -> usize {
        (self.y1 - self.y0).max(0) as usize
    }
}

/// Ticks for a chart drawn on `area`: about one label per 110 pixels
/// across and 70 pixels up, so labels never crowd.
pub(super) fn chart_ticks(area: &Area, st: &Style, xa: &Axis, ya: &Axis) -> (Ticks, Ticks) {
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
pub(super) fn build_chart<'c, 'b>(
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
pub(super) fn draw_frame(area: &Area, f: &Frame) -> Result<(), PlotError> {
    let (bx, by) = area.get_base_pixel();
    area.draw(&Rectangle::new(
        [(f.x0 - 1 - bx, f.y0 - 1 - by), (f.x1 - bx, f.y1 - by)],
        BLACK.stroke_width(1),
    ))?;
    Ok(())
}

/// Copies an RGB buffer of the frame's size onto the plotting area.
pub(super) fn blit(area: &Area, f: &Frame, buf: Vec<u8>) -> Result<(), PlotError> {
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

pub(super) fn no_data(area: &Area, f: &Frame, st: &Style) -> Result<(), PlotError> {
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

/// Splits `body` into the main plot and a right-hand panel of `side_w`
/// pixels (colour bar or legend).
pub(super) fn split_side<'b>(body: &Area<'b>, side_w: i32) -> (Area<'b>, Area<'b>) {
    let (w, _) = body.dim_in_pixel();
    body.split_horizontally((w as i32 - side_w).max(0))
}
