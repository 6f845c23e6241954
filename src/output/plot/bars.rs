//! Bar charts: one bar per named category (capture fractions).

use std::path::Path;

use plotters::prelude::*;

use super::canvas::render;
use super::colour::{rgb, GRID};
use super::figure::{Figure, PlotError, Rgb};

/// One bar per `(label, value, colour)`, from 0 up to the value, its value
/// written above it with `digits` decimals; the y axis from 0 to a little
/// above the largest value.
pub(super) fn bars_impl(
    path: &Path,
    fig: &Figure,
    bars: &[(&str, f64, Rgb)],
    digits: usize,
) -> Result<(), PlotError> {
    if bars.len() < 2 || bars.iter().any(|(_, v, _)| !v.is_finite() || *v < 0.0) {
        return Err(PlotError::Input(
            "a bar chart needs two or more bars of finite values ≥ 0".into(),
        ));
    }
    let top = bars
        .iter()
        .map(|(_, v, _)| *v)
        .fold(0.0, f64::max)
        .max(1e-300)
        * 1.15;
    // A segmented range a..b has b − a + 1 segments.
    let n = bars.len() as u32;
    render(path, fig, |body, st| {
        let mut chart = ChartBuilder::on(body)
            .margin_top(st.px(14.0))
            .margin_bottom(st.px(8.0))
            .margin_left(st.px(10.0))
            .margin_right(st.px(20.0))
            .x_label_area_size(st.px(50.0))
            .y_label_area_size(st.px(80.0))
            .build_cartesian_2d((0..n - 1).into_segmented(), 0.0..top)?;
        let label = |v: &SegmentValue<u32>| match v {
            SegmentValue::CenterOf(k) | SegmentValue::Exact(k) => bars
                .get(*k as usize)
                .map_or(String::new(), |(l, _, _)| l.to_string()),
            SegmentValue::Last => String::new(),
        };
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(bars.len())
            .x_label_formatter(&label)
            .y_desc(fig.y_label)
            .x_desc(fig.x_label)
            .label_style(st.tick())
            .axis_desc_style(st.desc())
            .bold_line_style(GRID)
            .light_line_style(WHITE)
            .axis_style(BLACK)
            .draw()?;
        // Bars in pixels, a sixth of their segment free on either side.
        let (bx, by) = body.get_base_pixel();
        let at = |k: u32, v: f64| {
            let (x, y) = chart.backend_coord(&(SegmentValue::Exact(k), v));
            (x - bx, y - by)
        };
        for (k, (_, v, colour)) in bars.iter().enumerate() {
            let k = k as u32;
            let ((x0, top), (x1, bottom)) = (at(k, *v), at(k + 1, 0.0));
            let m = ((x1 - x0) / 6).max(1);
            body.draw(&Rectangle::new(
                [(x0 + m, top), (x1 - m, bottom)],
                rgb(*colour).filled(),
            ))?;
        }
        for (k, (_, v, _)) in bars.iter().enumerate() {
            chart.draw_series(std::iter::once(Text::new(
                format!("{v:.digits$}"),
                (SegmentValue::CenterOf(k as u32), *v + top * 0.02),
                st.tick(),
            )))?;
        }
        Ok(())
    })
}
