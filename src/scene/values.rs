//! The hand walker of scene files: the value language (a number, a list,
//! `linspace`, `logspace`, `random`), the model-keyed tables `[params]` and
//! `[initial]`, and the keys of every table (unknown keys refused with a
//! did-you-mean; the span of every field recorded for error lines).

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;

use toml::de::{DeTable, DeValue};
use toml::Spanned;

pub use crate::num::names::suggest;

use super::error::SceneError;

/// SplitMix64: the stream of `random = { … seed }` axes (documented, so that
/// others can reproduce the samples).
pub fn splitmix64(seed: u64, n: usize) -> Vec<f64> {
    let mut z = seed;
    (0..n)
        .map(|_| {
            z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut x = z;
            x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            x ^= x >> 31;
            (x >> 11) as f64 / (1u64 << 53) as f64
        })
        .collect()
}

/// The values of an axis as the file gives them, not yet materialised: the
/// size gate of the scene counts them first ([`AxisValues::len`]), so that a
/// `linspace` of 10¹² values is refused before anything of its size exists.
#[derive(Debug, Clone, PartialEq)]
pub enum AxisValues {
    List(Vec<f64>),
    /// `linspace = [start, stop, n]`, or with `log` `logspace` (exponents).
    Linspace {
        start: f64,
        stop: f64,
        n: u64,
        log: bool,
    },
    /// `random = { low, high, n, seed }` (SplitMix64, see [`splitmix64`]).
    Random {
        low: f64,
        high: f64,
        n: u64,
        seed: u64,
    },
}

impl AxisValues {
    /// The number of values.
    pub fn len(&self) -> u64 {
        match self {
            AxisValues::List(v) => v.len() as u64,
            AxisValues::Linspace { n, .. } | AxisValues::Random { n, .. } => *n,
        }
    }

    /// An axis has at least one value (the parser refuses empty ones).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The values. Only after the size gate: panics if the count does not
    /// fit in `usize` (the gate refuses far smaller counts).
    pub fn materialize(self) -> Vec<f64> {
        let count = |n: u64| usize::try_from(n).expect("an axis the size gate let through");
        match self {
            AxisValues::List(v) => v,
            AxisValues::Linspace {
                start,
                stop,
                n,
                log,
            } => {
                let n = count(n);
                let lin = (0..n).map(move |i| {
                    if n == 1 {
                        start
                    } else {
                        start + (stop - start) * i as f64 / (n - 1) as f64
                    }
                });
                if log {
                    lin.map(|e| 10f64.powf(e)).collect()
                } else {
                    lin.collect()
                }
            }
            AxisValues::Random { low, high, n, seed } => splitmix64(seed, count(n))
                .into_iter()
                .map(|u| low + (high - low) * u)
                .collect(),
        }
    }
}

pub struct Parser<'a> {
    path: &'a Path,
    text: &'a str,
    spans: BTreeMap<String, Range<usize>>,
}

pub type Entry<'i> = (
    &'i Spanned<toml::de::DeString<'i>>,
    &'i Spanned<DeValue<'i>>,
);

impl<'a> Parser<'a> {
    pub fn new(path: &'a Path, text: &'a str) -> Self {
        Parser {
            path,
            text,
            spans: BTreeMap::new(),
        }
    }
    /// The spans of every field seen, for [`crate::scene::Scene::line_of`].
    pub fn into_spans(self) -> BTreeMap<String, Range<usize>> {
        self.spans
    }
    /// The span of a field's value, if the file gives it.
    pub fn span_of(&self, field: &str) -> Option<&Range<usize>> {
        self.spans.get(field)
    }
    /// The innermost field whose value contains `span` (where a serde error
    /// of the fixed tables points).
    pub fn field_at(&self, span: &Range<usize>) -> String {
        self.spans
            .iter()
            .filter(|(_, s)| s.start <= span.start && span.end <= s.end)
            .min_by_key(|(_, s)| s.end - s.start)
            .map_or_else(|| "toml".to_string(), |(f, _)| f.clone())
    }
    pub fn line(&self, span: &Range<usize>) -> usize {
        self.text[..span.start.min(self.text.len())]
            .matches('\n')
            .count()
            + 1
    }
    /// "expected `what`, found <type of v>", at `v`.
    pub fn mismatch(&self, field: &str, v: &Spanned<DeValue>, what: &str) -> SceneError {
        let found = v.get_ref().type_str();
        self.err(
            field,
            Some(&v.span()),
            format!("expected {what}, found {found}"),
        )
    }
    pub fn err(
        &self,
        field: &str,
        span: Option<&Range<usize>>,
        message: impl Into<String>,
    ) -> SceneError {
        SceneError {
            path: self.path.to_path_buf(),
            line: span.map(|s| self.line(s)),
            field: field.to_string(),
            message: message.into(),
        }
    }
    /// Entries of a table in file order, rejecting keys outside `known`.
    pub fn entries<'i>(
        &mut self,
        table: &'i DeTable<'i>,
        prefix: &str,
        known: Option<&[&str]>,
    ) -> Result<Vec<Entry<'i>>, SceneError> {
        let mut v: Vec<Entry<'i>> = table.iter().collect();
        v.sort_by_key(|(k, _)| k.span().start);
        for (k, val) in &v {
            let field = if prefix.is_empty() {
                k.get_ref().to_string()
            } else {
                format!("{prefix}.{}", k.get_ref())
            };
            if let Some(known) = known {
                if !known.contains(&k.get_ref().as_ref()) {
                    let hint = suggest(k.get_ref(), known);
                    return Err(self.err(
                        &field,
                        Some(&k.span()),
                        format!("unknown key{hint}; known keys here: {}", known.join(", ")),
                    ));
                }
            }
            self.spans.insert(field, val.span());
        }
        Ok(v)
    }
    pub fn number(&self, field: &str, v: &Spanned<DeValue>) -> Result<f64, SceneError> {
        let x = match v.get_ref() {
            DeValue::Float(f) => f.as_str().parse::<f64>().ok(),
            DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix())
                .ok()
                .map(|i| i as f64),
            _ => return Err(self.mismatch(field, v, "a number")),
        };
        match x {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(self.err(field, Some(&v.span()), out_of_range(v))),
        }
    }
    pub fn integer(&self, field: &str, v: &Spanned<DeValue>) -> Result<u64, SceneError> {
        match v.get_ref() {
            DeValue::Integer(i) => u64::from_str_radix(i.as_str(), i.radix()).map_err(|_| {
                let big = !i.as_str().starts_with('-');
                self.err(field, Some(&v.span()), crate::scene::tables::not_u64(big))
            }),
            _ => Err(self.mismatch(field, v, "an integer")),
        }
    }
    pub fn string(&self, field: &str, v: &Spanned<DeValue>) -> Result<String, SceneError> {
        match v.get_ref() {
            DeValue::String(s) => Ok(s.to_string()),
            _ => Err(self.mismatch(field, v, "a string")),
        }
    }
    pub fn numbers(&self, field: &str, v: &Spanned<DeValue>) -> Result<Vec<f64>, SceneError> {
        match v.get_ref() {
            DeValue::Array(a) => a.iter().map(|x| self.number(field, x)).collect(),
            _ => Err(self.mismatch(field, v, "a list of numbers")),
        }
    }
    /// A value spec: a constant, or the values of a new axis.
    pub fn values(
        &self,
        field: &str,
        v: &Spanned<DeValue>,
    ) -> Result<Result<f64, AxisValues>, SceneError> {
        let sp = Some(v.span());
        match v.get_ref() {
            DeValue::Float(_) | DeValue::Integer(_) => Ok(Ok(self.number(field, v)?)),
            DeValue::Array(a) => {
                if a.is_empty() {
                    return Err(self.err(
                        field,
                        sp.as_ref(),
                        "an empty list is an axis with no values",
                    ));
                }
                Ok(Err(AxisValues::List(self.numbers(field, v)?)))
            }
            DeValue::Table(t) => {
                let mut e: Vec<_> = t.iter().collect();
                e.sort_by_key(|(k, _)| k.span().start);
                if e.len() != 1 {
                    return Err(self.err(
                        field,
                        sp.as_ref(),
                        "expected exactly one of linspace, logspace, random",
                    ));
                }
                let (k, val) = e[0];
                let f = format!("{field}.{}", k.get_ref());
                match k.get_ref().as_ref() {
                    "linspace" | "logspace" => {
                        let xs = self.numbers(&f, val)?;
                        if xs.len() != 3 || xs[2].fract() != 0.0 || xs[2] < 1.0 {
                            return Err(self.err(&f, Some(&val.span()), "expected [start, stop, n] with an integer n ≥ 1"));
                        }
                        // 2^64 as f64 is exact; an integral n below it converts exactly.
                        if xs[2] >= 18_446_744_073_709_551_616.0 {
                            return Err(self.err(&f, Some(&val.span()), format!("n = {:e} values: the ensemble would have more than 2^64 trajectories; use fewer values along an axis", xs[2])));
                        }
                        Ok(Err(AxisValues::Linspace { start: xs[0], stop: xs[1], n: xs[2] as u64, log: k.get_ref() == "logspace" }))
                    }
                    "random" => {
                        let DeValue::Table(rt) = val.get_ref() else {
                            return Err(self.err(&f, Some(&val.span()), "expected { low, high, n, seed }"));
                        };
                        let get = |name: &str| rt.get(name).ok_or_else(|| self.err(&format!("{f}.{name}"), Some(&val.span()), "missing"));
                        for (rk, _) in rt.iter() {
                            if !["low", "high", "n", "seed"].contains(&rk.get_ref().as_ref()) {
                                return Err(self.err(&format!("{f}.{}", rk.get_ref()), Some(&rk.span()), "unknown key; known: low, high, n, seed"));
                            }
                        }
                        let low = self.number(&format!("{f}.low"), get("low")?)?;
                        let high = self.number(&format!("{f}.high"), get("high")?)?;
                        let n = self.integer(&format!("{f}.n"), get("n")?)?;
                        let seed = self.integer(&format!("{f}.seed"), get("seed")?)?;
                        if n == 0 || high <= low {
                            return Err(self.err(&f, Some(&val.span()), "needs n ≥ 1 and high > low"));
                        }
                        Ok(Err(AxisValues::Random { low, high, n, seed }))
                    }
                    other => Err(self.err(&f, Some(&k.span()), format!("unknown value form `{other}`; use a number, a list, linspace, logspace or random"))),
                }
            }
            _ => Err(self.mismatch(
                field,
                v,
                "a number, a list, or { linspace | logspace | random = … }",
            )),
        }
    }
}

/// The span of a table's entries (for "missing" errors at its lines).
pub fn integ_span(entries: &[Entry]) -> Range<usize> {
    entries.first().map(|(k, _)| k.span()).unwrap_or(0..0)
}

/// Why a number of the scene is refused: beyond the range of f64, or not a
/// number at all (`nan`, `inf`).
fn out_of_range(v: &Spanned<DeValue>) -> String {
    match v.get_ref() {
        DeValue::Float(f)
            if f.as_str().parse::<f64>().is_ok_and(f64::is_infinite)
                && f.as_str().chars().any(|c| c.is_ascii_digit()) =>
        {
            format!(
                "{} is out of range: expected a finite number (at most {:e} in magnitude)",
                f.as_str(),
                f64::MAX
            )
        }
        _ => "expected a finite number".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The axis values as the walker built them before the size gate
    /// (copied verbatim): `materialize` must give them bit for bit.
    fn old_linspace(xs: [f64; 3], log: bool) -> Vec<f64> {
        let n = xs[2] as usize;
        let lin: Vec<f64> = (0..n)
            .map(|i| {
                if n == 1 {
                    xs[0]
                } else {
                    xs[0] + (xs[1] - xs[0]) * i as f64 / (n - 1) as f64
                }
            })
            .collect();
        if log {
            lin.into_iter().map(|e| 10f64.powf(e)).collect()
        } else {
            lin
        }
    }

    fn old_random(low: f64, high: f64, n: usize, seed: u64) -> Vec<f64> {
        splitmix64(seed, n)
            .into_iter()
            .map(|u| low + (high - low) * u)
            .collect()
    }

    fn bits(v: &[f64]) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    #[test]
    fn materialize_gives_the_values_of_before_bit_for_bit() {
        let ranges = [
            [0.0, 1.0, 1.0],
            [0.0, 1.0, 2.0],
            [0.0, 100.0, 256.0],
            [-4.0, 0.2, 256.0],
            [-2.0, -1.0, 3.0],
            [1e-3, 0.7, 1000.0],
            [3.5, -2.25, 17.0],
            [0.0, 0.0, 5.0],
            [-1e300, 1e300, 7.0],
        ];
        for xs in ranges {
            for log in [false, true] {
                let a = AxisValues::Linspace {
                    start: xs[0],
                    stop: xs[1],
                    n: xs[2] as u64,
                    log,
                };
                assert_eq!(a.len(), xs[2] as u64);
                assert_eq!(
                    bits(&a.materialize()),
                    bits(&old_linspace(xs, log)),
                    "{xs:?} log {log}"
                );
            }
        }
        for (low, high, n, seed) in [
            (0.0, 1.0, 1, 0),
            (1.0, 2.0, 4, 7),
            (-3.0, 5.5, 1000, u64::MAX),
            (0.2, 0.9, 257, 12345),
        ] {
            let a = AxisValues::Random {
                low,
                high,
                n: n as u64,
                seed,
            };
            assert_eq!(a.len(), n as u64);
            assert_eq!(
                bits(&a.materialize()),
                bits(&old_random(low, high, n, seed))
            );
        }
        let list = AxisValues::List(vec![1.0, -0.0, 3.5]);
        assert_eq!(list.len(), 3);
        assert_eq!(bits(&list.materialize()), bits(&[1.0, -0.0, 3.5]));
    }

    #[test]
    fn huge_counts_are_described_not_allocated() {
        let a = AxisValues::Linspace {
            start: 0.0,
            stop: 1.0,
            n: u64::MAX,
            log: false,
        };
        assert_eq!(a.len(), u64::MAX);
        assert!(!a.is_empty());
    }
}
