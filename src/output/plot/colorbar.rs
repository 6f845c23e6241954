//! The colour bar beside heat maps and density clouds.

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::axis::{ticks, Axis, TickAxis, TickFmt, Ticks};
use super::canvas::{text_width, Area, Style};
use super::chart::{blit, draw_frame, Frame};
use super::colour::{put, rgb, viridis};
use super::figure::{PlotError, Rgb};

/// A colour bar: `axis` in transformed coordinates (log10 when `axis.log`).
pub(super) struct ColorBar<'l> {
    axis: Axis,
    ticks: Ticks,
    label: &'l str,
    /// Swatches under the bar for the colours of cells without a value,
    /// and what each means ("NaN", "no cycle found").
    missing: Vec<(&'l str, Rgb)>,
    /// Values marked across the bar (transformed coordinates) and their
    /// labels, written left of it.
    marks: Vec<(f64, &'l str)>,
}

impl<'l> ColorBar<'l> {
    pub(super) fn new(
        axis: Axis,
        label: &'l str,
        missing: Vec<(&'l str, Rgb)>,
        plot_h: f64,
        st: &Style,
    ) -> Self {
        let target = ((plot_h - 110.0 * st.s) / (60.0 * st.s)).clamp(2.0, 10.0) as usize;
        let ticks = ticks(&axis, target);
        Self {
            axis,
            ticks,
            label,
            missing,
            marks: vec![],
        }
    }

    /// The same bar with `marks` across it (values in data coordinates;
    /// those outside the bar's range are left out).
    pub(super) fn with_marks(mut self, marks: &[(f64, &'l str)]) -> Self {
        self.marks = marks
            .iter()
            .filter_map(|(v, l)| {
                let t = if self.axis.log {
                    (*v > 0.0).then(|| v.log10())?
                } else {
                    *v
                };
                (self.axis.lo..=self.axis.hi)
                    .contains(&t)
                    .then_some((t, *l))
            })
            .collect();
        self
    }

    /// Widest mark label, and the space it takes left of the bar.
    fn marks_width(&self, area: &Area, st: &Style) -> i32 {
        self.marks
            .iter()
            .map(|(_, l)| text_width(area, l, &st.tick()) + st.px(4.0))
            .fold(0, i32::max)
    }

    /// Widest tick label.
    fn label_width(&self, area: &Area, st: &Style) -> i32 {
        let font = st.tick();
        self.ticks
            .major
            .iter()
            .map(|&t| text_width(area, &self.ticks.label(t), &font))
            .fold(0, i32::max)
    }

    /// Width of the panel: gap, bar, tick marks, labels, title; or gap,
    /// swatch and the widest note on a missing value, if wider.
    pub(super) fn width(&self, area: &Area, st: &Style) -> i32 {
        let bar = Self::gap(st)
            + self.marks_width(area, st)
            + st.fpx(Self::BAR)
            + 3 * st.px(5.0)
            + self.label_width(area, st)
            + st.px(12.0)
            + if self.label.is_empty() {
                0
            } else {
                st.fpx(18.0 * 1.3)
            }
            + st.px(10.0);
        let notes = self
            .missing
            .iter()
            .map(|(note, _)| text_width(area, note, &st.tick()))
            .max()
            .map_or(0, |w| {
                Self::gap(st) + st.fpx(Self::BAR) + st.px(8.0) + w + st.px(6.0)
            });
        bar.max(notes)
    }

    /// Height of the swatches under the bar, gap above included.
    fn notes_height(&self, st: &Style) -> i32 {
        match self.missing.len() {
            0 => 0,
            k => st.px(16.0) + k as i32 * Self::row(st),
        }
    }

    /// One swatch and its note.
    fn row(st: &Style) -> i32 {
        st.fpx(Self::BAR) + st.px(6.0)
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
    pub(super) fn draw(&self, side: &Area, st: &Style, main: &Frame) -> Result<(), PlotError> {
        let (sx, sy) = side.get_base_pixel();
        let (sw, sh) = side.dim_in_pixel();
        let gap = Self::gap(st) + self.marks_width(side, st);
        let bar = st.fpx(Self::BAR);
        let label_area = (sw as i32 - gap - bar).max(0);
        // The bar ends with the plot, unless the swatches under it would
        // then run off the image.
        let below = sy + sh as i32 - main.y1;
        let mut builder = ChartBuilder::on(side);
        builder
            .margin_top((main.y0 - sy).max(0))
            .margin_bottom(below.max(self.notes_height(st)).max(0))
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
        let mark_style = st.tick().pos(Pos::new(HPos::Right, VPos::Center));
        for (t, label) in &self.marks {
            chart.draw_series(std::iter::once(PathElement::new(
                vec![(0.0, *t), (1.0, *t)],
                BLACK.stroke_width(st.px(2.0).max(1) as u32),
            )))?;
            chart.draw_series(std::iter::once(Text::new(
                label.to_string(),
                (0.0, *t),
                mark_style.clone(),
            )))?;
        }
        if !self.label.is_empty() {
            let x = f.x1 - sx + 3 * st.px(5.0) + self.label_width(side, st) + st.px(12.0);
            let style = st
                .desc()
                .transform(FontTransform::Rotate270)
                .pos(Pos::new(HPos::Center, VPos::Top));
            side.draw_text(self.label, &style, (x, (f.y0 + f.y1) / 2 - sy))?;
        }
        let left = f.x0 - sx;
        let style = st.tick().pos(Pos::new(HPos::Left, VPos::Center));
        for (k, (note, colour)) in self.missing.iter().enumerate() {
            let top = f.y1 + st.px(16.0) + k as i32 * Self::row(st) - sy;
            side.draw(&Rectangle::new(
                [(left, top), (left + bar, top + bar)],
                rgb(*colour).filled(),
            ))?;
            side.draw(&Rectangle::new(
                [(left - 1, top - 1), (left + bar, top + bar)],
                BLACK.stroke_width(1),
            ))?;
            side.draw_text(note, &style, (left + bar + st.px(8.0), top + bar / 2))?;
        }
        Ok(())
    }
}
