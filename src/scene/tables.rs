//! The scene's fixed tables — `[integrator]`, `[output]`, `[run]`, `[plot]`,
//! `[report]` — as serde types, deserialized with their spans from the
//! parsed TOML. Leaf types say what they expected in the scene's own words
//! ("expected a number, found string"); `parse.rs` turns the error's span
//! back into the field and line. Unknown keys are refused before (with a
//! did-you-mean) by the walker in `values.rs`; `dt` is read there too (it
//! speaks the value language: scalar, list, linspace, …).

use std::fmt;

use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};
use serde::Deserialize;
use toml::Spanned;

/// A finite number.
#[derive(Debug, Clone, Copy)]
pub struct Num(pub f64);

/// A non-negative integer.
#[derive(Debug, Clone, Copy)]
pub struct Int(pub u64);

/// A string.
#[derive(Debug, Clone)]
pub struct Str(pub String);

/// A list of strings (a single string is a list of one).
#[derive(Debug, Clone)]
pub struct Strs(pub Vec<String>);

/// A list of finite numbers.
#[derive(Debug, Clone)]
pub struct Nums(pub Vec<f64>);

/// A boolean.
#[derive(Debug, Clone, Copy)]
pub struct Bool(pub bool);

/// A value read by kind: each method accepts one kind of TOML value; the
/// defaults refuse with "expected WHAT, found <kind>".
pub trait Leaf: Sized {
    /// What the value should be, e.g. "a number".
    const WHAT: &'static str;
    fn found(kind: &str) -> String {
        format!("expected {}, found {kind}", Self::WHAT)
    }
    fn from_bool(_: bool) -> Result<Self, String> {
        Err(Self::found("boolean"))
    }
    fn from_int(_: i128) -> Result<Self, String> {
        Err(Self::found("integer"))
    }
    fn from_float(_: f64) -> Result<Self, String> {
        Err(Self::found("float"))
    }
    fn from_str(_: &str) -> Result<Self, String> {
        Err(Self::found("string"))
    }
    fn from_seq<'de, A: SeqAccess<'de>>(_: A) -> Result<Self, A::Error> {
        Err(de::Error::custom(Self::found("array")))
    }
    fn from_map<'de, A: MapAccess<'de>>(_: A) -> Result<Self, A::Error> {
        Err(de::Error::custom(Self::found("table")))
    }
}

/// The serde visitor of a [`Leaf`].
struct LeafVisitor<T>(std::marker::PhantomData<T>);

impl<'de, T: Leaf> Visitor<'de> for LeafVisitor<T> {
    type Value = T;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(T::WHAT)
    }
    fn visit_bool<E: de::Error>(self, v: bool) -> Result<T, E> {
        T::from_bool(v).map_err(E::custom)
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<T, E> {
        T::from_int(v.into()).map_err(E::custom)
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<T, E> {
        T::from_int(v.into()).map_err(E::custom)
    }
    fn visit_i128<E: de::Error>(self, v: i128) -> Result<T, E> {
        T::from_int(v).map_err(E::custom)
    }
    fn visit_u128<E: de::Error>(self, v: u128) -> Result<T, E> {
        T::from_int(i128::try_from(v).unwrap_or(i128::MAX)).map_err(E::custom)
    }
    fn visit_f64<E: de::Error>(self, v: f64) -> Result<T, E> {
        T::from_float(v).map_err(E::custom)
    }
    fn visit_str<E: de::Error>(self, v: &str) -> Result<T, E> {
        T::from_str(v).map_err(E::custom)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<T, A::Error> {
        T::from_seq(seq)
    }
    fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<T, A::Error> {
        T::from_map(map)
    }
}

/// `Deserialize` for [`Leaf`] types.
macro_rules! leaf_deserialize {
    ($($ty:ty),* $(,)?) => {
        $(impl<'de> Deserialize<'de> for $ty {
            fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                d.deserialize_any(LeafVisitor::<$ty>(std::marker::PhantomData))
            }
        })*
    };
}

impl Leaf for Num {
    const WHAT: &'static str = "a number";
    fn from_int(v: i128) -> Result<Num, String> {
        match i64::try_from(v) {
            Ok(i) => Ok(Num(i as f64)),
            Err(_) => Err("expected a finite number".into()),
        }
    }
    fn from_float(v: f64) -> Result<Num, String> {
        if v.is_finite() {
            Ok(Num(v))
        } else {
            Err("expected a finite number".into())
        }
    }
}

impl Leaf for Int {
    const WHAT: &'static str = "an integer";
    fn from_int(v: i128) -> Result<Int, String> {
        u64::try_from(v).map(Int).map_err(|_| not_u64(v > 0))
    }
}

/// Why an integer of the scene is refused: negative, or too large (`big`).
pub fn not_u64(big: bool) -> String {
    match big {
        true => format!("is too large: at most {}", u64::MAX),
        false => "expected a non-negative integer".into(),
    }
}

impl Leaf for Str {
    const WHAT: &'static str = "a string";
    fn from_str(v: &str) -> Result<Str, String> {
        Ok(Str(v.to_string()))
    }
}

impl Leaf for Bool {
    const WHAT: &'static str = "true or false";
    fn from_bool(v: bool) -> Result<Bool, String> {
        Ok(Bool(v))
    }
}

impl Leaf for Strs {
    const WHAT: &'static str = "a list of strings";
    fn from_str(v: &str) -> Result<Strs, String> {
        Ok(Strs(vec![v.to_string()]))
    }
    fn from_seq<'de, A: SeqAccess<'de>>(mut seq: A) -> Result<Strs, A::Error> {
        let mut out = vec![];
        while let Some(Str(s)) = seq.next_element()? {
            out.push(s);
        }
        Ok(Strs(out))
    }
}

impl Leaf for Nums {
    const WHAT: &'static str = "a list of numbers";
    fn from_seq<'de, A: SeqAccess<'de>>(mut seq: A) -> Result<Nums, A::Error> {
        let mut out = vec![];
        while let Some(Num(x)) = seq.next_element()? {
            out.push(x);
        }
        Ok(Nums(out))
    }
}

leaf_deserialize!(
    Num, Int, Str, Bool, Strs, Nums, Period, Cycle, Average, Ratios, Stop, Lyapunov, Sampled, Gali,
    Attractors
);

/// An inline table of known fields; any other value is refused with
/// `T::EXPECTED`, the form the scene should have used.
#[derive(Debug, Clone)]
pub struct Table<T>(pub T);

/// The form of an inline table, for the message when something else is given.
pub trait Expected {
    const EXPECTED: &'static str;
}

impl<T: for<'a> Deserialize<'a> + Expected> Leaf for Table<T> {
    const WHAT: &'static str = T::EXPECTED;
    fn found(_: &str) -> String {
        format!("expected {}", T::EXPECTED)
    }
    fn from_map<'de, A: MapAccess<'de>>(map: A) -> Result<Table<T>, A::Error> {
        T::deserialize(de::value::MapAccessDeserializer::new(map)).map(Table)
    }
}

impl<'de, T: for<'a> Deserialize<'a> + Expected> Deserialize<'de> for Table<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(LeafVisitor::<Table<T>>(std::marker::PhantomData))
    }
}

type Field<T> = Option<Spanned<T>>;

/// `[integrator]` (its `dt` is read in the value language).
#[derive(Debug, Default, Deserialize)]
pub struct Integrator {
    pub scheme: Field<Str>,
    pub order: Field<Str>,
    pub t_end: Field<Num>,
    pub steps: Field<Int>,
}

/// `[output]`.
#[derive(Debug, Default, Deserialize)]
pub struct Output {
    #[serde(rename = "final")]
    pub final_vars: Field<Strs>,
    pub trajectory: Field<Table<Trajectory>>,
    pub poincare: Field<Table<Poincare>>,
    pub cycle: Field<Cycle>,
    pub average: Field<Average>,
    pub resonance: Field<Table<Resonance>>,
    pub stop: Field<Stop>,
    pub lyapunov: Field<Lyapunov>,
    pub fli: Field<Sampled>,
    pub megno: Field<Sampled>,
    pub sali: Field<Sampled>,
    pub gali: Field<Gali>,
    pub attractors: Field<Attractors>,
    pub format: Field<Str>,
}

/// `output.stop = "q1^2 + q2^2 > 100"` or `{ when = "…" }`.
#[derive(Debug)]
pub struct Stop(pub String);

#[derive(Debug, Default, Deserialize)]
struct StopTable {
    when: Option<Str>,
}

impl Leaf for Stop {
    const WHAT: &'static str = "a condition (\"q1^2 + q2^2 > 100\") or { when = \"…\" }";
    fn from_str(v: &str) -> Result<Stop, String> {
        Ok(Stop(v.to_string()))
    }
    fn from_map<'de, A: MapAccess<'de>>(map: A) -> Result<Stop, A::Error> {
        let t = StopTable::deserialize(de::value::MapAccessDeserializer::new(map))?;
        t.when
            .map(|Str(w)| Stop(w))
            .ok_or_else(|| de::Error::custom("needs when = \"<condition>\""))
    }
}

/// `output.average = ["p"]` or `{ vars = ["p"], skip = 0.5 }`.
#[derive(Debug)]
pub enum Average {
    Vars(Strs),
    Table(AverageTable),
}

#[derive(Debug, Default, Deserialize)]
pub struct AverageTable {
    pub vars: Field<Strs>,
    pub skip: Field<Num>,
}

impl Leaf for Average {
    const WHAT: &'static str = "a list of variables or { vars = [...], skip = 0.5 }";
    fn from_str(v: &str) -> Result<Average, String> {
        Strs::from_str(v).map(Average::Vars)
    }
    fn from_seq<'de, A: SeqAccess<'de>>(seq: A) -> Result<Average, A::Error> {
        Strs::from_seq(seq).map(Average::Vars)
    }
    fn from_map<'de, A: MapAccess<'de>>(map: A) -> Result<Average, A::Error> {
        AverageTable::deserialize(de::value::MapAccessDeserializer::new(map)).map(Average::Table)
    }
}

/// `output.resonance = { var = "p", ratios = [[1, 1], [3, 2]], tolerance = 0.01 }`.
#[derive(Debug, Default, Deserialize)]
pub struct Resonance {
    pub var: Field<Str>,
    pub ratios: Field<Ratios>,
    pub tolerance: Field<Num>,
}

impl Expected for Resonance {
    const EXPECTED: &'static str = "{ var = \"p\", ratios = [[1, 1], [3, 2]], tolerance = 0.01 }";
}

/// A list of ratios `[p, q]` of whole numbers.
#[derive(Debug, Clone)]
pub struct Ratios(pub Vec<[i64; 2]>);

impl Leaf for Ratios {
    const WHAT: &'static str = "a list of ratios [p, q] of whole numbers";
    fn from_seq<'de, A: SeqAccess<'de>>(mut seq: A) -> Result<Ratios, A::Error> {
        let mut out = vec![];
        while let Some(Nums(pq)) = seq.next_element()? {
            let whole = |x: f64| (x.fract() == 0.0 && x.abs() < 1e15).then_some(x as i64);
            match pq.as_slice() {
                [p, q] => match (whole(*p), whole(*q)) {
                    (Some(p), Some(q)) => out.push([p, q]),
                    _ => {
                        return Err(de::Error::custom(format!(
                            "[{p}, {q}] is not a ratio of whole numbers"
                        )))
                    }
                },
                _ => {
                    return Err(de::Error::custom(format!(
                        "a ratio is two whole numbers [p, q], found {} numbers",
                        pq.len()
                    )))
                }
            }
        }
        Ok(Ratios(out))
    }
}

/// `output.trajectory = { every = k, vars = [...] }`.
#[derive(Debug, Default, Deserialize)]
pub struct Trajectory {
    pub every: Field<Int>,
    pub vars: Field<Strs>,
}

impl Expected for Trajectory {
    const EXPECTED: &'static str = "{ every = k, vars = [...] }";
}

/// `output.poincare`: a stroboscopic (`period`) or an event (`crossing`) section.
#[derive(Debug, Default, Deserialize)]
pub struct Poincare {
    pub period: Field<Period>,
    pub phase: Field<Num>,
    pub skip: Field<Num>,
    pub crossing: Field<Str>,
    pub value: Field<Num>,
    pub direction: Field<Str>,
    pub vars: Field<Strs>,
    pub max_points: Field<Int>,
}

impl Expected for Poincare {
    const EXPECTED: &'static str =
        "{ period = T } or { crossing = \"q\", value = 0.0, direction = \"up\" }";
}

/// A section period: a number, or `"forcing"` (each trajectory's forcing period).
#[derive(Debug, Clone)]
pub enum Period {
    Number(f64),
    Named(String),
}

impl Leaf for Period {
    const WHAT: &'static str = "a number";
    fn from_int(v: i128) -> Result<Period, String> {
        Num::from_int(v).map(|Num(x)| Period::Number(x))
    }
    fn from_float(v: f64) -> Result<Period, String> {
        Num::from_float(v).map(|Num(x)| Period::Number(x))
    }
    fn from_str(v: &str) -> Result<Period, String> {
        Ok(Period::Named(v.to_string()))
    }
}

/// `output.cycle = true` or `{ var, level, skip }`.
#[derive(Debug)]
pub enum Cycle {
    On(bool),
    Table(CycleTable),
}

#[derive(Debug, Default, Deserialize)]
pub struct CycleTable {
    pub var: Field<Str>,
    pub level: Field<Num>,
    pub skip: Field<Num>,
}

impl Leaf for Cycle {
    const WHAT: &'static str = "true or { var, level, skip }";
    fn from_bool(v: bool) -> Result<Cycle, String> {
        Ok(Cycle::On(v))
    }
    fn from_map<'de, A: MapAccess<'de>>(map: A) -> Result<Cycle, A::Error> {
        CycleTable::deserialize(de::value::MapAccessDeserializer::new(map)).map(Cycle::Table)
    }
}

/// `output.attractors = true` or `{ max_period, tolerance, skip, every, angles }`.
#[derive(Debug)]
pub enum Attractors {
    On(bool),
    Table(AttractorsTable),
}

#[derive(Debug, Default, Deserialize)]
pub struct AttractorsTable {
    pub max_period: Field<Int>,
    pub tolerance: Field<Num>,
    pub skip: Field<Num>,
    pub every: Field<Int>,
    pub angles: Field<Strs>,
}

impl Leaf for Attractors {
    const WHAT: &'static str = "true or { max_period, tolerance, skip, every, angles }";
    fn from_bool(v: bool) -> Result<Attractors, String> {
        Ok(Attractors::On(v))
    }
    fn from_map<'de, A: MapAccess<'de>>(map: A) -> Result<Attractors, A::Error> {
        AttractorsTable::deserialize(de::value::MapAccessDeserializer::new(map))
            .map(Attractors::Table)
    }
}

/// `output.lyapunov = true` or `{ vectors = k, every = m, skip = 0.0 }`.
#[derive(Debug)]
pub enum Lyapunov {
    On(bool),
    Table(LyapunovTable),
}

#[derive(Debug, Default, Deserialize)]
pub struct LyapunovTable {
    pub vectors: Field<Int>,
    pub every: Field<Int>,
    pub skip: Field<Num>,
}

impl Leaf for Lyapunov {
    const WHAT: &'static str = "true or { vectors = 1, every = 1, skip = 0.0 }";
    fn from_bool(v: bool) -> Result<Lyapunov, String> {
        Ok(Lyapunov::On(v))
    }
    fn from_map<'de, A: MapAccess<'de>>(map: A) -> Result<Lyapunov, A::Error> {
        LyapunovTable::deserialize(de::value::MapAccessDeserializer::new(map)).map(Lyapunov::Table)
    }
}

/// `output.fli` or `output.megno`: `true` or `{ every = m }`.
#[derive(Debug)]
pub enum Sampled {
    On(bool),
    Table(SampledTable),
}

#[derive(Debug, Default, Deserialize)]
pub struct SampledTable {
    pub every: Field<Int>,
}

impl Leaf for Sampled {
    const WHAT: &'static str = "true or { every = 1 }";
    fn from_bool(v: bool) -> Result<Sampled, String> {
        Ok(Sampled::On(v))
    }
    fn from_map<'de, A: MapAccess<'de>>(map: A) -> Result<Sampled, A::Error> {
        SampledTable::deserialize(de::value::MapAccessDeserializer::new(map)).map(Sampled::Table)
    }
}

/// `output.gali`: `true` or `{ k = 3, every = m }`.
#[derive(Debug)]
pub enum Gali {
    On(bool),
    Table(GaliTable),
}

#[derive(Debug, Default, Deserialize)]
pub struct GaliTable {
    pub k: Field<Int>,
    pub every: Field<Int>,
}

impl Leaf for Gali {
    const WHAT: &'static str = "true or { k = 3, every = 1 }";
    fn from_bool(v: bool) -> Result<Gali, String> {
        Ok(Gali::On(v))
    }
    fn from_map<'de, A: MapAccess<'de>>(map: A) -> Result<Gali, A::Error> {
        GaliTable::deserialize(de::value::MapAccessDeserializer::new(map)).map(Gali::Table)
    }
}

/// `[run]`.
#[derive(Debug, Default, Deserialize)]
pub struct Run {
    pub backend: Field<Str>,
    pub precision: Field<Str>,
}

/// `[plot]`.
#[derive(Debug, Default, Deserialize)]
pub struct Plot {
    pub phase: Field<Strs>,
    pub poincare: Field<Strs>,
    pub wrap_x: Field<Str>,
    pub max_trajectories: Field<Int>,
    pub lienard_plane: Field<Bool>,
    pub bifurcation: Field<Table<Bifurcation>>,
}

/// `plot.bifurcation = { axis = "…", var = "…" }`.
#[derive(Debug, Default, Deserialize)]
pub struct Bifurcation {
    pub axis: Field<Str>,
    pub var: Field<Str>,
}

impl Expected for Bifurcation {
    const EXPECTED: &'static str = "{ axis = \"…\", var = \"…\" }";
}

/// `[report]`.
#[derive(Debug, Default, Deserialize)]
pub struct Report {
    pub schemes: Field<Strs>,
    pub backends: Field<Strs>,
    pub precisions: Field<Strs>,
    pub error_vars: Field<Strs>,
    pub reference_rtol: Field<Num>,
    pub distorted: Field<Num>,
    pub targets: Field<Nums>,
}
