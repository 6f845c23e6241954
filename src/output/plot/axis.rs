//! Axes in transformed coordinates (`log10` on log axes) and their ticks,
//! chosen by this module, with labels; and the plotters axis type over them.

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::prelude::*;

use crate::num::order::ascending;

/// A linear plotters axis over transformed coordinates whose ticks are
/// chosen by this module. (plotters' `WithKeyPoints` would do, but wrapping
/// `RangedCoordf64` loses the label-formatter support `configure_mesh` needs.)
#[derive(Debug, Clone)]
pub(super) struct TickAxis {
    lo: f64,
    hi: f64,
    major: Vec<f64>,
    minor: Vec<f64>,
}

impl TickAxis {
    pub(super) fn new(ax: &Axis, t: &Ticks) -> Self {
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

/// Whether an axis over grid `values` should be logarithmic: every value
/// positive and finite, and either geometric (a `logspace`, in either
/// order) or spanning two decades or more with steps at least as even in
/// `log10` as in value (the list 10⁻², 5·10⁻³, …, 10⁻⁴). An evenly spaced
/// grid (a `linspace`) stays linear whatever its span: a log axis would
/// crowd its cells at one end.
pub fn log_scale(values: &[f64]) -> bool {
    use rayon::prelude::*;
    if values.is_empty() || !values.par_iter().all(|x| x.is_finite() && *x > 0.0) {
        return false;
    }
    let mut v = ascending(values).into_owned();
    v.dedup();
    let logs: Vec<f64> = v.par_iter().map(|x| x.log10()).collect();
    let (lin, log) = (unevenness(&v), unevenness(&logs));
    let decades = logs[logs.len() - 1] - logs[0];
    (v.len() >= 3 && log < 1.0 + 1e-6) || (decades >= 2.0 - 1e-9 && log <= lin)
}

/// The largest step of sorted distinct `v` over its smallest (1: even).
fn unevenness(v: &[f64]) -> f64 {
    let steps = v.windows(2).map(|w| w[1] - w[0]);
    let (lo, hi) = steps.fold((f64::INFINITY, 0.0f64), |(a, b), d| (a.min(d), b.max(d)));
    if lo > 0.0 {
        hi / lo
    } else {
        1.0
    }
}

/// Maps a data value to axis coordinates: `log10` on log axes. `None` for
/// values that cannot be shown (non-finite, or ≤ 0 on a log axis).
pub(super) fn tf(log: bool, v: f64) -> Option<f64> {
    if !v.is_finite() {
        None
    } else if log {
        (v > 0.0).then(|| v.log10())
    } else {
        Some(v)
    }
}

/// Min and max of transformed values.
pub(super) fn extent<I: IntoIterator<Item = f64>>(log: bool, values: I) -> Option<(f64, f64)> {
    let mut r: Option<(f64, f64)> = None;
    for t in values.into_iter().filter_map(|v| tf(log, v)) {
        r = Some(match r {
            None => (t, t),
            Some((a, b)) => (a.min(t), b.max(t)),
        });
    }
    r
}

pub(super) fn merge(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    match (a, b) {
        (Some((a0, a1)), Some((b0, b1))) => Some((a0.min(b0), a1.max(b1))),
        (a, None) => a,
        (None, b) => b,
    }
}

/// One axis in transformed coordinates: `lo..hi` are `log10` values when
/// `log`. Always `lo < hi`, both finite.
#[derive(Debug, Clone, Copy)]
pub(super) struct Axis {
    pub(super) log: bool,
    pub(super) lo: f64,
    pub(super) hi: f64,
}

impl Axis {
    /// The axis for transformed extent `ext`: degenerate ranges widened,
    /// then padded by `pad` of the span on each side. No data gives 0..1
    /// (1..10 on a log axis).
    pub(super) fn new(log: bool, ext: Option<(f64, f64)>, pad: f64) -> Self {
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

    pub(super) fn span(&self) -> f64 {
        self.hi - self.lo
    }

    /// Position of transformed value `t` as a fraction of the axis.
    pub(super) fn frac(&self, t: f64) -> f64 {
        (t - self.lo) / self.span()
    }
}

/// How tick values are turned into labels.
#[derive(Debug, Clone, Copy)]
pub(super) enum TickFmt {
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
pub(super) struct Ticks {
    pub(super) major: Vec<f64>,
    pub(super) minor: Vec<f64>,
    pub(super) fmt: TickFmt,
}

impl Ticks {
    pub(super) fn label(&self, t: f64) -> String {
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
pub fn fmt_general(v: f64) -> String {
    fmt_significant(v, 4)
}

/// [`fmt_general`] with up to `digits` significant digits (at least 1).
pub fn fmt_significant(v: f64, digits: usize) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v.is_nan() {
            "NaN".into()
        } else if v == 0.0 {
            "0".into()
        } else {
            format!("{v}")
        };
    }
    let last = digits.max(1) - 1;
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return trim_sci(&format!("{v:.last$e}"));
    }
    let d = (last as i32 - a.log10().floor() as i32).max(0) as usize;
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

/// Decimals needed to show multiples of `step` exactly: the first count at
/// which the step is a whole number (not merely close to zero, so ticks
/// 2e-7 apart around 1.67 get seven decimals, not none).
fn decimals_for(step: f64) -> usize {
    (0..=12)
        .find(|&d| {
            let m = step * 10f64.powi(d as i32);
            m.round() >= 1.0 && (m - m.round()).abs() < 1e-6 * m
        })
        .unwrap_or(12)
}

/// Ticks for an axis, about `target` labelled ones.
pub(super) fn ticks(ax: &Axis, target: usize) -> Ticks {
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
