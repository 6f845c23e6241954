//! Colours: the fixed greys, viridis, blending, and writing a colour into
//! an RGB buffer.

use plotters::prelude::*;

use super::figure::Rgb;

pub(super) const NAN_GREY: Rgb = (170, 170, 170);
pub(super) const BG: Rgb = (255, 255, 255);
pub(super) const GRID: RGBColor = RGBColor(222, 222, 222);
pub(super) const GRID_MINOR: RGBColor = RGBColor(240, 240, 240);
pub(super) const NOTE_GREY: RGBColor = RGBColor(110, 110, 110);

pub(super) fn rgb(c: Rgb) -> RGBColor {
    RGBColor(c.0, c.1, c.2)
}

pub(super) fn put(buf: &mut [u8], idx: usize, c: Rgb) {
    if let Some(p) = buf.get_mut(3 * idx..3 * idx + 3) {
        p.copy_from_slice(&[c.0, c.1, c.2]);
    }
}

/// Viridis, linearly interpolated between ten control points (matplotlib's
/// `viridis(linspace(0, 1, 10))`): perceptually uniform and readable by
/// colour-blind readers and in greyscale. `t` is clamped to 0..=1.
pub(super) fn viridis(t: f64) -> Rgb {
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
pub(super) fn blend(under: Rgb, over: Rgb, alpha: f64) -> Rgb {
    let m = |u: u8, o: u8| (f64::from(u) + alpha * (f64::from(o) - f64::from(u))).round() as u8;
    (m(under.0, over.0), m(under.1, over.1), m(under.2, over.2))
}
