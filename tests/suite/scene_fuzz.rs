//! Fuzzing the scene parser: `Scene::parse` never panics, and every error it
//! returns names a field or a line. Two sources of input: scenes generated
//! from the model registry (plausible keys and value forms, sometimes wrong),
//! and the real scenes of `scenes/` mutated (lines deleted, duplicated,
//! swapped or replaced, numbers set to extremes, types flipped, text
//! truncated, random bytes and unicode inserted). Parsing only: nothing runs.
//!
//! Axis counts stay small here (≤ 1000 values; ≤ 16 for `dt` and `t0`, whose
//! axes multiply the plans a scene is checked as), so that parsing never
//! allocates much; huge counts have their own tests at the end.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use proptest::prelude::*;
use proptest::sample::{select, Index};
use proptest::test_runner::RngSeed;
use reeb::models::{Model, MODEL_NAMES};
use reeb::num::precision::Precision;
use reeb::plan::scheme::SCHEME_NAMES;
use reeb::scene::Scene;
use toml::de::{DeTable, DeValue};
use toml::Spanned;

use crate::common;

use common::runs::toml_string as quoted;

/// Deterministic runs (fixed seed, no regression files): CI reproduces them.
/// `REEB_FUZZ_CASES` and `REEB_FUZZ_SEED` run more, or others (long runs).
fn config(cases: u32) -> ProptestConfig {
    let env = |k: &str| std::env::var(k).ok().and_then(|s| s.parse::<u64>().ok());
    ProptestConfig {
        cases: env("REEB_FUZZ_CASES").map_or(cases, |c| c as u32),
        rng_seed: RngSeed::Fixed(env("REEB_FUZZ_SEED").unwrap_or(0x0073_6365_6e65)),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// Parses `text` and applies every gate of `reeb check` (the precision
/// checks in f32 and f64, the plans, the size gate): `Err` if anything
/// panicked, or returned an error that names neither a field nor a line.
fn check(text: &str) -> Result<Option<Scene>, String> {
    let parsed = catch_unwind(AssertUnwindSafe(|| {
        let scene = Scene::parse(Path::new("fuzz.toml"), text)?;
        for p in [Precision::F32, Precision::F64] {
            scene.checks(p)?;
        }
        let subs = scene.sub_runs()?;
        if let Err(e) = scene.size_gate(&subs, scene.precision, None) {
            assert!(!e.to_string().is_empty(), "an empty size refusal");
        }
        Ok::<_, reeb::scene::SceneError>(scene)
    }));
    match parsed {
        Err(panic) => {
            let why = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            Err(format!(
                "Scene::parse or a gate panicked ({why}) on:\n{text}"
            ))
        }
        Ok(Err(e)) if e.field.is_empty() && e.line.is_none() => Err(format!(
            "error names neither field nor line: {e:?}\non:\n{text}"
        )),
        Ok(Err(_)) => Ok(None),
        Ok(Ok(scene)) => Ok(Some(scene)),
    }
}

// ---------------------------------------------------------------------------
// Generated scenes

/// The entries with the first of each key only (a repeated key is a TOML
/// error, which the mutation test covers).
fn dedupe(entries: Vec<String>) -> Vec<String> {
    let mut seen = vec![];
    entries
        .into_iter()
        .filter(|e| {
            let key = e.split('=').next().unwrap_or("").trim().to_string();
            let new = !seen.contains(&key);
            seen.push(key);
            new
        })
        .collect()
}

fn list(items: &[String]) -> String {
    format!("[{}]", items.join(", "))
}

/// Extreme numbers and number-like text, valid TOML or not. No value here
/// is used as an axis count by the generated scenes.
const EXTREME: &[&str] = &[
    "0",
    "-1",
    "0.0",
    "-0.0",
    "1e308",
    "-1e308",
    "1e-308",
    "5e-324",
    "1.7976931348623157e308",
    "nan",
    "+nan",
    "-nan",
    "inf",
    "-inf",
    "\"NaN\"",
    "\"inf\"",
    "NaN",
    "Infinity",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551615",
    "99999999999999999999999",
    "0x7fffffffffffffff",
    "0o777",
    "0b101",
    "1_000",
    "4294967295",
    "4294967296",
    "1e12",
    "1e19",
    "0.5",
    "true",
    "\"\"",
    "[]",
    "{}",
    "[1, 2]",
    "1979-05-27T07:32:00Z",
];

type Gen<T> = BoxedStrategy<T>;

/// `good`, or in a noisy scene now and then (1 in `odds + 1`) `bad`.
fn or_bad<T: std::fmt::Debug + 'static>(
    clean: bool,
    odds: u32,
    good: impl Strategy<Value = T> + 'static,
    bad: impl Strategy<Value = T> + 'static,
) -> Gen<T> {
    if clean {
        good.boxed()
    } else {
        prop_oneof![odds => good, 1 => bad].boxed()
    }
}

fn texts(v: &'static [&'static str]) -> Gen<String> {
    select(v).prop_map(str::to_string).boxed()
}

/// A finite float as TOML text.
fn finite(lo: f64, hi: f64) -> Gen<String> {
    (lo..hi).prop_map(|x| format!("{x:?}")).boxed()
}

/// A number as TOML text: moderate floats and integers, in a noisy scene
/// sometimes an extreme.
fn scalar(clean: bool) -> Gen<String> {
    let good = prop_oneof![
        8 => finite(-10.0, 10.0),
        6 => finite(0.001, 2.0),
        5 => (-3i64..20).prop_map(|i| i.to_string()),
    ];
    or_bad(clean, 10, good, texts(EXTREME))
}

/// An axis count n ≤ `max` as the third element of linspace/logspace: an
/// integer or an integral float; in a noisy scene sometimes a fraction, zero,
/// a negative number or not a number.
fn count_text(clean: bool, max: u64) -> Gen<String> {
    let good = prop_oneof![
        4 => (1..=8u64).prop_map(|n| n.to_string()),
        2 => (1..=max).prop_map(|n| n.to_string()),
        2 => (1..=max).prop_map(|n| format!("{n}.0")),
    ];
    let bad = prop_oneof![
        (0..max).prop_map(|n| format!("{n}.5")),
        texts(&["-1", "0", "-0.0", "1e-3", "\"3\"", "nan", "inf"]),
    ];
    or_bad(clean, 8, good, bad)
}

/// A per-trajectory value as a scene writes it: a scalar, a list, linspace,
/// logspace, random; in a noisy scene sometimes a wrong form. Axis counts
/// are at most `max_n`; values lie in `lo..hi`.
fn value(clean: bool, lo: f64, hi: f64, max_n: u64) -> Gen<String> {
    let x = move || or_bad(clean, 20, finite(lo, hi), scalar(clean));
    let random = (x(), x(), 1..=max_n, any::<u64>()).prop_map(|(lo, hi, n, seed)| {
        format!("{{ random = {{ low = {lo}, high = {hi}, n = {n}, seed = {seed} }} }}")
    });
    let good = prop_oneof![
        10 => x(),
        4 => prop::collection::vec(x(), 1..6).prop_map(|v| list(&v)),
        4 => (x(), x(), count_text(clean, max_n))
            .prop_map(|(a, b, n)| format!("{{ linspace = [{a}, {b}, {n}] }}")),
        2 => (finite(-4.0, 3.0), finite(-4.0, 3.0), count_text(clean, max_n))
            .prop_map(|(a, b, n)| format!("{{ logspace = [{a}, {b}, {n}] }}")),
        2 => random,
    ];
    let bad = prop_oneof![
        (finite(-5.0, 5.0), finite(-5.0, 5.0), 1..=max_n, any::<u64>(), 0..5u8).prop_map(
            |(lo, hi, n, seed, variant)| match variant {
                0 => format!("{{ random = {{ low = {lo}, high = {hi}, n = {n} }} }}"),
                1 => format!("{{ random = {{ low = {lo}, high = {hi}, n = {n}.0, seed = {seed} }} }}"),
                2 => format!("{{ random = {{ low = {lo}, high = {hi}, n = {n}, seed = {seed}, mean = 1 }} }}"),
                3 => format!("{{ random = [{lo}, {hi}, {n}] }}"),
                _ => format!("{{ random = {{ low = {lo}, high = {hi}, n = 0, seed = {seed} }} }}"),
            }
        ),
        texts(&[
            "[]",
            "\"two\"",
            "true",
            "{ linspace = [0, 1] }",
            "{ linspace = [0, 1, 2, 3] }",
            "{ linspace = \"0..1\" }",
            "{ logspace = [400, 500, 3] }",
            "{ geomspace = [1, 2, 3] }",
            "{ linspace = [0, 1, 3], logspace = [0, 1, 3] }",
            "{}",
            "[[1.0], [2.0]]",
            "[1.0, \"x\"]",
        ]),
    ];
    or_bad(clean, 15, good, bad)
}

/// A name: one of `good`, in a noisy scene sometimes one of `bad`.
fn name_from(clean: bool, good: Vec<String>, bad: &'static [&'static str]) -> Gen<String> {
    or_bad(clean, 15, select(good), texts(bad))
}

fn model_names() -> Vec<String> {
    MODEL_NAMES.iter().map(|s| s.to_string()).collect()
}

fn spec_of(model: &str) -> &'static reeb::models::spec::ModelSpec {
    Model::from_name(model).unwrap_or(Model::VanDerPol).spec()
}

/// The output variables of a model: its variables, `t`, and vector names
/// (Kepler's `q` for `q1, q2`).
fn out_vars(model: &str) -> Vec<String> {
    let spec = spec_of(model);
    let mut v: Vec<String> = spec.vars.iter().map(|s| s.to_string()).collect();
    v.push("t".into());
    for x in spec.vars {
        if x.ends_with(|c: char| c.is_ascii_digit()) {
            v.push(x[..x.len() - 1].to_string());
        }
    }
    v.dedup();
    v
}

fn var(clean: bool, model: &str) -> Gen<String> {
    name_from(clean, out_vars(model), &["x", "", "q3", "T"])
        .prop_map(|s| quoted(&s))
        .boxed()
}

fn var_list(clean: bool, model: &str) -> Gen<String> {
    prop::collection::vec(var(clean, model), 1..4)
        .prop_map(|v| list(&v))
        .boxed()
}

/// `[params]` entries: the model's parameters (Liénard: its coefficients f
/// and g) with values in 0..2 (a good range for every model).
fn params(clean: bool, model: &str) -> Gen<Vec<String>> {
    let names: Vec<String> = spec_of(model)
        .params
        .iter()
        .map(|p| p.name.to_string())
        .collect();
    let coefficients = || {
        prop::collection::vec(finite(-3.0, 3.0), 0..12)
            .prop_map(|v| list(&v))
            .boxed()
    };
    if names.is_empty() {
        let g = or_bad(clean, 8, coefficients().prop_map(Some), Just(None));
        let bad = or_bad(
            clean,
            8,
            Just(None),
            value(clean, 0.0, 2.0, 1000).prop_map(|v| Some(format!("mu = {v}"))),
        );
        return (prop::option::of(coefficients()), g, bad)
            .prop_map(|(f, g, bad)| {
                let mut lines = vec![];
                if let Some(f) = f {
                    lines.push(format!("f = {f}"));
                }
                if let Some(g) = g {
                    lines.push(format!("g = {g}"));
                }
                lines.extend(bad);
                lines
            })
            .boxed();
    }
    let entry = (
        name_from(clean, names, &["mu", "Epsilon", "alpha ", "ε"]),
        value(clean, 0.0, 2.0, 1000),
    )
        .prop_map(|(k, v)| format!("{} = {v}", quoted(&k)));
    prop::collection::vec(entry, 0..4).boxed()
}

/// `[initial]` entries (t0 with at most 16 values).
fn initial(clean: bool, model: &str) -> Gen<Vec<String>> {
    let spec = spec_of(model);
    let mut names: Vec<String> = spec.vars.iter().map(|s| s.to_string()).collect();
    if let Some(alias) = &spec.initial_alias {
        names.push(alias.key.to_string());
    }
    let var = (
        name_from(clean, names, &["x", "q0", "Q"]),
        value(clean, 0.0, 0.9, 1000),
    )
        .prop_map(|(k, v)| format!("{} = {v}", quoted(&k)));
    let t0 = value(clean, 0.0, 1.0, 16).prop_map(|v| format!("t0 = {v}"));
    prop::collection::vec(prop_oneof![4 => var, 1 => t0], 0..4).boxed()
}

/// `[integrator]` entries (dt with at most 16 values).
fn integrator(clean: bool, model: &str) -> Gen<Vec<String>> {
    let pieces: Vec<char> = spec_of(model).pieces.chars().collect();
    let schemes: Vec<String> = SCHEME_NAMES.iter().map(|s| s.to_string()).collect();
    let order = or_bad(
        clean,
        3,
        Just(pieces).prop_shuffle().prop_map(|half| {
            let back = half[..half.len() - 1].iter().rev();
            half.iter().chain(back).collect::<String>()
        }),
        "[ABCDa]{0,7}",
    );
    let dt = or_bad(
        clean,
        5,
        prop_oneof![
            4 => finite(1e-4, 0.5),
            1 => (finite(-4.0, -0.5), finite(-4.0, -0.5), 1..=16u64)
                .prop_map(|(a, b, n)| format!("{{ logspace = [{a}, {b}, {n}] }}")),
            1 => prop::collection::vec(finite(1e-4, 0.5), 1..5).prop_map(|v| list(&v)),
        ],
        value(clean, -0.1, 0.5, 16),
    );
    let horizon = or_bad(
        clean,
        6,
        prop_oneof![
            finite(0.5, 50.0).prop_map(|t| format!("t_end = {t}")),
            (1..100_000u64).prop_map(|s| format!("steps = {s}")),
        ],
        prop_oneof![
            scalar(clean).prop_map(|s| format!("steps = {s}")),
            scalar(clean).prop_map(|s| format!("t_end = {s}")),
            Just("t_end = 10.0\nsteps = 100".to_string()),
            Just(String::new()),
        ],
    );
    (
        prop::option::of(name_from(
            clean,
            schemes,
            &["s3", "rk45", "S2", "yoshida6d"],
        )),
        prop::option::of(order),
        or_bad(clean, 20, dt.prop_map(Some), Just(None)),
        horizon,
        or_bad(clean, 30, Just(None), Just(Some("tolerance = 1e-6"))),
    )
        .prop_map(|(scheme, order, dt, horizon, extra)| {
            let mut v = vec![];
            if let Some(s) = scheme {
                v.push(format!("scheme = {}", quoted(&s)));
            }
            if let Some(o) = order {
                v.push(format!("order = {}", quoted(&o)));
            }
            if let Some(dt) = dt {
                v.push(format!("dt = {dt}"));
            }
            if !horizon.is_empty() {
                v.push(horizon);
            }
            v.extend(extra.map(str::to_string));
            v
        })
        .boxed()
}

/// `[output]` entries.
fn output(clean: bool, model: &str) -> Gen<Vec<String>> {
    let final_ = or_bad(
        clean,
        8,
        var_list(clean, model),
        prop_oneof![
            var(clean, model),
            Just("1".to_string()),
            Just("[]".to_string())
        ],
    )
    .prop_map(|v| format!("final = {v}"));
    let every = or_bad(
        clean,
        8,
        (1..20u64).prop_map(|e| e.to_string()),
        scalar(clean),
    );
    let trajectory =
        (every, var_list(clean, model), 0..3u8).prop_map(|(every, vars, variant)| match variant {
            0 => format!("trajectory = {{ vars = {vars} }}"),
            1 => format!("trajectory = {{ every = {every} }}"),
            _ => format!("trajectory = {{ every = {every}, vars = {vars} }}"),
        });
    let trajectory = or_bad(
        clean,
        10,
        trajectory,
        var_list(clean, model).prop_map(|v| format!("trajectory = {v}")),
    );
    let period = or_bad(
        clean,
        6,
        prop_oneof![3 => finite(0.1, 10.0), 1 => Just("\"forcing\"".to_string())],
        prop_oneof![scalar(clean), Just("\"daily\"".to_string())],
    );
    let poincare = (
        period,
        finite(0.0, 5.0),
        var(clean, model),
        or_bad(clean, 10, texts(&["up", "down", "both"]), texts(&["sideways"])),
        var_list(clean, model),
        or_bad(clean, 10, (1..5000u64).prop_map(|m| m.to_string()), scalar(clean)),
        or_bad(clean, 10, (0..200u64).prop_map(|m| m.to_string()), scalar(clean)),
        0..4u8,
    )
        .prop_map(|(period, value, crossing, dir, vars, max_points, skip, variant)| {
            let body = match variant {
                0 => format!("period = {period}, phase = {value}, vars = {vars}, max_points = {max_points}"),
                1 => format!("period = {period}, skip = {skip}, vars = {vars}"),
                2 => format!("crossing = {crossing}, value = {value}, direction = \"{dir}\", vars = {vars}"),
                _ => format!("crossing = {crossing}, max_points = {max_points}"),
            };
            format!("poincare = {{ {body} }}")
        });
    let poincare = or_bad(
        clean,
        10,
        poincare,
        prop_oneof![
            (var(clean, model), finite(0.1, 2.0))
                .prop_map(|(c, p)| format!("poincare = {{ crossing = {c}, period = {p} }}")),
            var_list(clean, model).prop_map(|v| format!("poincare = {{ vars = {v} }}")),
        ],
    );
    let cycle = or_bad(
        clean,
        8,
        prop_oneof![
            1 => Just("cycle = true".to_string()),
            1 => Just("cycle = false".to_string()),
            3 => (var(clean, model), finite(-1.0, 1.0), finite(0.0, 1.0))
                .prop_map(|(v, level, skip)| format!("cycle = {{ var = {v}, level = {level}, skip = {skip} }}")),
        ],
        prop_oneof![
            Just("cycle = 1".to_string()),
            scalar(clean).prop_map(|s| format!("cycle = {{ skip = {s} }}")),
            var(clean, model).prop_map(|v| format!("cycle = {{ var = {v}, period = 1 }}")),
        ],
    );
    (
        prop::option::of(final_),
        prop::option::of(trajectory),
        prop::option::of(poincare),
        prop::option::of(cycle),
    )
        .prop_map(|(a, b, c, d)| [a, b, c, d].into_iter().flatten().collect())
        .boxed()
}

/// `[run]` entries.
fn run(clean: bool) -> Gen<Vec<String>> {
    (
        prop::option::of(or_bad(
            clean,
            10,
            texts(&["auto", "cpu", "gpu"]),
            texts(&["tpu", ""]),
        )),
        prop::option::of(or_bad(
            clean,
            10,
            texts(&["f32", "f64"]),
            texts(&["f16", "F64"]),
        )),
    )
        .prop_map(|(b, p)| {
            let mut v = vec![];
            if let Some(b) = b {
                v.push(format!("backend = \"{b}\""));
            }
            if let Some(p) = p {
                v.push(format!("precision = \"{p}\""));
            }
            v
        })
        .boxed()
}

/// `[plot]` entries.
fn plot(clean: bool, model: &str) -> Gen<Vec<String>> {
    let axis_names: Vec<String> = spec_of(model)
        .params
        .iter()
        .map(|p| p.name.to_string())
        .chain(["dt".to_string(), "q".to_string()])
        .collect();
    let good = prop_oneof![
        (var(clean, model), var(clean, model)).prop_map(|(a, b)| format!("phase = [{a}, {b}]")),
        (var(clean, model), var(clean, model)).prop_map(|(a, b)| format!("poincare = [{a}, {b}]")),
        texts(&["\"2pi\"", "\"pi\""]).prop_map(|w| format!("wrap_x = {w}")),
        (0..1000u64).prop_map(|m| format!("max_trajectories = {m}")),
        texts(&["true", "false"]).prop_map(|b| format!("lienard_plane = {b}")),
        (name_from(clean, axis_names, &["nope"]), var(clean, model))
            .prop_map(|(a, v)| format!("bifurcation = {{ axis = {}, var = {v} }}", quoted(&a))),
    ];
    let bad = prop_oneof![
        var_list(clean, model).prop_map(|v| format!("phase = {v}")),
        texts(&["\"tau\"", "6.28"]).prop_map(|w| format!("wrap_x = {w}")),
        scalar(clean).prop_map(|m| format!("max_trajectories = {m}")),
        Just("lienard_plane = 1".to_string()),
        Just("bifurcation = { axis = \"dt\" }".to_string()),
        Just("colour = \"red\"".to_string()),
    ];
    prop::collection::vec(or_bad(clean, 10, good, bad), 0..4).boxed()
}

/// `[report]` entries.
fn report(clean: bool, model: &str) -> Gen<Vec<String>> {
    let schemes: Vec<String> = SCHEME_NAMES.iter().map(|s| s.to_string()).collect();
    let names = |v: Vec<String>| list(&v.iter().map(|s| quoted(s)).collect::<Vec<_>>());
    let backends = or_bad(clean, 10, texts(&["cpu", "gpu", "auto"]), texts(&["fpga"]));
    let precisions = or_bad(clean, 10, texts(&["f32", "f64"]), texts(&["f128"]));
    let entry = prop_oneof![
        prop::collection::vec(name_from(clean, schemes, &["s3"]), 1..4)
            .prop_map(move |v| format!("schemes = {}", names(v))),
        prop::collection::vec(backends, 1..3).prop_map(move |v| format!("backends = {}", names(v))),
        prop::collection::vec(precisions, 1..3)
            .prop_map(move |v| format!("precisions = {}", names(v))),
        var_list(clean, model).prop_map(|v| format!("error_vars = {v}")),
        finite(1e-14, 1e-6).prop_map(|x| format!("reference_rtol = {x}")),
        scalar(clean).prop_map(|x| format!("distorted = {x}")),
        prop::collection::vec(scalar(clean), 0..5).prop_map(|v| format!("targets = {}", list(&v))),
    ];
    let entry = or_bad(clean, 20, entry, Just("targets = 1e-3".to_string()));
    prop::collection::vec(entry, 0..4).boxed()
}

/// A whole scene: the top-level keys, then the tables in a random order
/// (each maybe missing, or in a noisy scene a non-table value). Clean scenes
/// use right names and value forms only (their values may still break a
/// model's rules); noisy ones now and then a wrong one anywhere.
fn scene() -> impl Strategy<Value = String> {
    (any::<bool>(), select(model_names())).prop_flat_map(|(clean, model)| {
        let model_line = or_bad(
            clean,
            30,
            Just(Some(model.clone())),
            prop_oneof![
                Just(None),
                texts(&["van_der_poll", "", "Kepler"]).prop_map(Some),
            ],
        );
        let name = or_bad(
            clean,
            10,
            prop::option::of(Just("vdp".to_string())),
            texts(&["", "a/b", "..", ".", "ünï cödé", "x\\y"]).prop_map(Some),
        );
        let header = (
            model_line,
            name,
            prop::option::of(any::<String>()),
            or_bad(clean, 30, Just(None), Just(Some("seed = 1"))),
        )
            .prop_map(|(model, name, title, extra)| {
                let mut v = vec![];
                if let Some(m) = model {
                    v.push(format!("model = {}", quoted(&m)));
                }
                if let Some(n) = name {
                    v.push(format!("name = {}", quoted(&n)));
                }
                if let Some(t) = title {
                    v.push(format!("title = {}", quoted(&t)));
                }
                v.extend(extra.map(str::to_string));
                v.join("\n") + "\n"
            });
        let section = |name: &'static str, entries: Gen<Vec<String>>, present: u32| {
            or_bad(
                clean,
                20,
                prop_oneof![
                    1 => Just(None),
                    present => entries.prop_map(move |e| Some(format!("[{name}]\n{}\n", dedupe(e).join("\n")))),
                ],
                Just(Some(format!("{name} = 1\n"))),
            )
        };
        let sections = (
            section("params", params(clean, &model), 4),
            section("initial", initial(clean, &model), 4),
            section("integrator", integrator(clean, &model), 30),
            section("output", output(clean, &model), 4),
            section("run", run(clean), 4),
            section("plot", plot(clean, &model), 2),
            section("report", report(clean, &model), 2),
        )
            .prop_map(|(a, b, c, d, e, f, g)| {
                [a, b, c, d, e, f, g].into_iter().flatten().collect::<Vec<_>>()
            })
            .prop_shuffle();
        (header, sections).prop_map(|(h, s)| h + &s.concat())
    })
}

// ---------------------------------------------------------------------------
// Mutated real scenes

fn scene_files() -> Vec<(PathBuf, String)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut v: Vec<(PathBuf, String)> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .map(|p| {
            let text = std::fs::read_to_string(&p).unwrap();
            (p, text)
        })
        .collect();
    v.sort();
    assert!(!v.is_empty(), "no scenes in {}", dir.display());
    v
}

#[derive(Debug, Clone)]
enum Mutation {
    DeleteLine(Index),
    DuplicateLine(Index),
    SwapLines(Index, Index),
    ReplaceLine(Index, String),
    InsertLine(Index, String),
    /// Replace a number with an extreme value.
    ReplaceNumber(Index, &'static str),
    /// Change the type of a value: number ↔ string, list → first element, table → list.
    FlipType(Index),
    Truncate(Index),
    InsertText(Index, String),
    DeleteRange(Index, usize),
}

/// Lines a scene might (wrongly) contain.
const LINES: &[&str] = &[
    "[params]",
    "[initial]",
    "[integrator]",
    "[output]",
    "[run]",
    "[plot]",
    "[report]",
    "[[params]]",
    "[integrator.dt]",
    "model = \"kepler\"",
    "model = 3",
    "scheme = \"yoshida8e\"",
    "scheme = \"leapfrog\"",
    "order = \"ABCBA\"",
    "order = \"CBA\"",
    "dt = 0",
    "dt = -0.1",
    "dt = [0.1, 0.0]",
    "dt = { logspace = [-3, 2, 4] }",
    "t_end = 0",
    "t_end = 1e300",
    "steps = 0",
    "steps = 4294967295",
    "t0 = [0.0, 1.0]",
    "t0 = -5",
    "final = []",
    "final = [\"t\"]",
    "trajectory = { every = 0 }",
    "trajectory = { every = 1000000000 }",
    "poincare = { period = 0.0 }",
    "poincare = { period = \"forcing\", skip = 1.5 }",
    "poincare = { crossing = \"t\" }",
    "poincare = { crossing = \"q\", max_points = 0 }",
    "cycle = { skip = 1.0 }",
    "cycle = { var = \"t\" }",
    "eccentricity = 1.0",
    "eccentricity = [0.5, 2.0]",
    "index = 16",
    "index = 2.5",
    "epsilon = { random = { low = 0, high = 1, n = 5, seed = -1 } }",
    "q = { linspace = [0, 1, 1] }",
    "lienard_plane = true",
    "bifurcation = { axis = \"dt\", var = \"q\" }",
    "wrap_x = \"pi\"",
    "max_trajectories = -1",
    "precision = \"f64\"",
    "backends = [\"gpu\"]",
    "targets = [1e-3, nan]",
    "= 1",
    "\"\" = 1",
    "a.b.c = 1",
    "x = \"unterminated",
    "'''",
    "\u{feff}model = \"van_der_pol\"",
    "",
];

fn mutation() -> impl Strategy<Value = Mutation> {
    let text = prop_oneof![
        prop::collection::vec(any::<u8>(), 1..8)
            .prop_map(|b| String::from_utf8_lossy(&b).into_owned()),
        prop::collection::vec(any::<char>(), 1..6).prop_map(|c| c.into_iter().collect()),
        select(
            &[
                "\"", "'", "[", "]", "{", "}", "=", "\n", "\r", "\t", "#", ",", ".", "\\", "\0",
                "é", "🦀", "\u{202e}", "\u{feff}"
            ][..]
        )
        .prop_map(str::to_string),
    ];
    let line = prop_oneof![
        3 => select(LINES).prop_map(str::to_string),
        1 => "[a-z_]{1,12} = [-0-9.e]{1,8}",
        1 => any::<String>(),
    ];
    prop_oneof![
        2 => any::<Index>().prop_map(Mutation::DeleteLine),
        1 => any::<Index>().prop_map(Mutation::DuplicateLine),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(a, b)| Mutation::SwapLines(a, b)),
        2 => (any::<Index>(), line.clone()).prop_map(|(i, l)| Mutation::ReplaceLine(i, l)),
        2 => (any::<Index>(), line).prop_map(|(i, l)| Mutation::InsertLine(i, l)),
        8 => (any::<Index>(), select(EXTREME)).prop_map(|(i, x)| Mutation::ReplaceNumber(i, x)),
        2 => any::<Index>().prop_map(Mutation::FlipType),
        1 => any::<Index>().prop_map(Mutation::Truncate),
        1 => (any::<Index>(), text).prop_map(|(i, t)| Mutation::InsertText(i, t)),
        1 => (any::<Index>(), 1..40usize).prop_map(|(i, n)| Mutation::DeleteRange(i, n)),
    ]
}

/// Byte ranges of the number tokens of `text` (not inside names such as `q1`).
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = vec![];
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit()
            || (matches!(b[i], b'-' | b'+') && b.get(i + 1).is_some_and(u8::is_ascii_digit));
        let after_name =
            i > 0 && (b[i - 1].is_ascii_alphanumeric() || matches!(b[i - 1], b'_' | b'.'));
        if starts && !after_name {
            let mut j = i + 1;
            while j < b.len()
                && (b[j].is_ascii_alphanumeric() || matches!(b[j], b'.' | b'_' | b'+' | b'-'))
            {
                j += 1;
            }
            out.push((i, j));
            i = j;
        } else {
            i += 1;
        }
    }
    out
}

/// Character boundaries of `text`, end included.
fn boundaries(text: &str) -> Vec<usize> {
    text.char_indices()
        .map(|(k, _)| k)
        .chain([text.len()])
        .collect()
}

fn apply(text: &str, m: &Mutation) -> String {
    let mut lines: Vec<String> = text.split_inclusive('\n').map(String::from).collect();
    if lines.is_empty() {
        lines.push(String::new());
    }
    let n = lines.len();
    let with_newline = |s: &str| format!("{s}\n");
    match m {
        Mutation::DeleteLine(i) => {
            lines.remove(i.index(n));
        }
        Mutation::DuplicateLine(i) => {
            let k = i.index(n);
            lines.insert(k, lines[k].clone());
        }
        Mutation::SwapLines(a, b) => lines.swap(a.index(n), b.index(n)),
        Mutation::ReplaceLine(i, l) => lines[i.index(n)] = with_newline(l),
        Mutation::InsertLine(i, l) => lines.insert(i.index(n + 1), with_newline(l)),
        Mutation::ReplaceNumber(i, x) => {
            let nums = numbers(text);
            if nums.is_empty() {
                return text.to_string();
            }
            let (a, b) = nums[i.index(nums.len())];
            return format!("{}{x}{}", &text[..a], &text[b..]);
        }
        Mutation::FlipType(i) => {
            let k = i.index(n);
            let line = lines[k].trim_end_matches('\n').to_string();
            if let Some((key, value)) = line.split_once('=') {
                let v = value.trim();
                let flipped = if let Some(s) = v.strip_prefix('"') {
                    s.trim_end_matches('"').to_string()
                } else if let Some(inner) = v.strip_prefix('[') {
                    inner
                        .split(',')
                        .next()
                        .unwrap_or("")
                        .trim()
                        .trim_end_matches(']')
                        .to_string()
                } else if v.starts_with('{') {
                    format!("[{}]", v.trim_matches(|c| c == '{' || c == '}'))
                } else if v == "true" || v == "false" {
                    "1".to_string()
                } else if v.parse::<f64>().is_ok() {
                    format!("\"{v}\"")
                } else {
                    "true".to_string()
                };
                lines[k] = format!("{key}= {flipped}\n");
            }
        }
        Mutation::Truncate(i) => {
            let b = boundaries(text);
            return text[..b[i.index(b.len())]].to_string();
        }
        Mutation::InsertText(i, t) => {
            let b = boundaries(text);
            let k = b[i.index(b.len())];
            return format!("{}{t}{}", &text[..k], &text[k..]);
        }
        Mutation::DeleteRange(i, len) => {
            let b = boundaries(text);
            let k = i.index(b.len());
            let end = b[(k + len).min(b.len() - 1)];
            return format!("{}{}", &text[..b[k]], &text[end..]);
        }
    }
    lines.concat()
}

/// The largest axis count the text asks for (linspace/logspace `n`,
/// random `n`), read the way the scene parser reads it: the mutation test
/// leaves counts over [`MAX_COUNT`] to the huge-count tests below.
fn largest_count(text: &str) -> f64 {
    fn number(v: &Spanned<DeValue>) -> f64 {
        match v.get_ref() {
            // Non-finite counts are refused as such.
            DeValue::Float(f) => f
                .as_str()
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .unwrap_or(0.0),
            DeValue::Integer(i) => u64::from_str_radix(i.as_str(), i.radix())
                .map(|u| u as f64)
                .or_else(|_| i64::from_str_radix(i.as_str(), i.radix()).map(|i| i as f64))
                .unwrap_or(0.0),
            _ => 0.0,
        }
    }
    fn walk(v: &Spanned<DeValue>, max: &mut f64) {
        match v.get_ref() {
            DeValue::Table(t) => walk_table(t, max),
            DeValue::Array(a) => a.iter().for_each(|x| walk(x, max)),
            _ => {}
        }
    }
    fn walk_table(t: &DeTable, max: &mut f64) {
        for (k, v) in t.iter() {
            match (k.get_ref().as_ref(), v.get_ref()) {
                ("linspace" | "logspace", DeValue::Array(a)) if a.len() >= 3 => {
                    *max = max.max(number(&a[2]));
                }
                ("random", DeValue::Table(r)) => {
                    if let Some((_, n)) = r.iter().find(|(k, _)| k.get_ref() == "n") {
                        *max = max.max(number(n));
                    }
                }
                _ => {}
            }
            walk(v, max);
        }
    }
    let mut max = 0.0f64;
    if let Ok(root) = DeTable::parse(text) {
        walk_table(root.get_ref(), &mut max);
    }
    max
}

/// Axis counts above this are the huge-count tests' business.
const MAX_COUNT: f64 = 1000.0;

fn mutated_scene() -> impl Strategy<Value = (usize, Vec<Mutation>)> {
    (
        0..scene_files().len(),
        prop::collection::vec(mutation(), 1..4),
    )
}

// ---------------------------------------------------------------------------
// Properties

proptest! {
    #![proptest_config(config(256))]

    /// Generated scenes: no panic; every error names a field or a line.
    #[test]
    fn generated_scenes_parse_or_name_the_problem(text in scene()) {
        prop_assert!(largest_count(&text) <= MAX_COUNT);
        check(&text).map_err(TestCaseError::fail)?;
    }

    /// Mutated real scenes: no panic; every error names a field or a line.
    #[test]
    fn mutated_scenes_parse_or_name_the_problem((k, mutations) in mutated_scene()) {
        let files = scene_files();
        let mut text = files[k].1.clone();
        for m in &mutations {
            text = apply(&text, m);
        }
        prop_assume!(largest_count(&text) <= MAX_COUNT, "a huge axis count");
        check(&text).map_err(|e| TestCaseError::fail(format!("{} {mutations:?}: {e}", files[k].0.display())))?;
    }
}

/// The baseline of the mutation test: every real scene parses.
#[test]
fn every_real_scene_parses() {
    for (path, text) in scene_files() {
        match check(&text) {
            Ok(Some(_)) => {}
            Ok(None) => panic!("{}: {:?}", path.display(), Scene::parse(&path, &text).err()),
            Err(e) => panic!("{}: {e}", path.display()),
        }
    }
}

/// A van der Pol scene with `line` in `[params]` and `extra` after it.
fn vdp(line: &str, extra: &str) -> String {
    format!(
        "model = \"van_der_pol\"\n[params]\n{line}\n[integrator]\ndt = 0.1\nsteps = 10\n{extra}"
    )
}

/// Huge counts and sizes that the parser refuses before allocating anything
/// of their size (or accepts without allocating it: Poincaré points and
/// trajectories drawn are sized at run time).
#[test]
fn huge_counts_refused_before_allocating() {
    let refused = [
        vdp("epsilon = { linspace = [0.0, 1.0, 1000000000000.5] }", ""),
        vdp("epsilon = { linspace = [0.0, 1.0, -1e12] }", ""),
        vdp("epsilon = { linspace = [0.0, 1.0, inf] }", ""),
        vdp("epsilon = { logspace = [0.0, 1.0, nan] }", ""),
        vdp(
            "epsilon = { random = { low = 0.0, high = 1.0, n = 1e12, seed = 1 } }",
            "",
        ),
        vdp(
            "epsilon = { random = { low = 0.0, high = 1.0, n = 18446744073709551616, seed = 1 } }",
            "",
        ),
        vdp(
            "epsilon = { random = { low = 1.0, high = 0.0, n = 1000000000000, seed = 1 } }",
            "",
        ),
        vdp(
            "epsilon = { random = { low = 0.0, high = 1.0, n = -1000000000000, seed = 1 } }",
            "",
        ),
        vdp("epsilon = 1.0", "").replace("steps = 10", "steps = 1000000000000000"),
        vdp("epsilon = 1.0", "").replace("steps = 10", "steps = 1e15"),
        vdp("epsilon = 1.0", "").replace("dt = 0.1\nsteps = 10", "dt = 1e-300\nt_end = 1e300"),
        vdp(
            "epsilon = 1.0",
            "[output]\ntrajectory = { every = 18446744073709551615 }\n",
        ),
    ];
    for text in &refused {
        match check(text) {
            Ok(None) => {}
            Ok(Some(_)) => panic!("accepted:\n{text}"),
            Err(e) => panic!("{e}"),
        }
    }
    let accepted = [
        vdp(
            "epsilon = 1.0",
            "[output]\npoincare = { period = 1.0, max_points = 9223372036854775807 }\n",
        ),
        vdp(
            "epsilon = 1.0",
            "[plot]\nmax_trajectories = 9223372036854775807\n",
        ),
    ];
    for text in &accepted {
        match check(text) {
            Ok(Some(_)) => {}
            Ok(None) => panic!("refused:\n{text}"),
            Err(e) => panic!("{e}"),
        }
    }
}

/// Huge axis counts: each is parsed in a child process under a 4 GiB
/// address-space limit (`ulimit -v`), which must exit cleanly (no panic, no
/// abort). The parser counted them only after building the values: n = 10¹²
/// aborted (allocating 8 TB failed), n ≥ 2⁶³ (1e308 saturated) panicked
/// with "capacity overflow", n = 10⁹ allocated 8 GB, and each plan of a
/// scene with a `dt` axis and `t_end` copied the other axes (10⁴ dt values ×
/// 10⁵ ε values: 8 GB). The size gate of the parser now counts them first,
/// against a limit that includes what the address-space limit leaves.
#[cfg(unix)]
#[test]
fn huge_axis_counts_neither_panic_nor_abort() {
    use std::os::unix::process::ExitStatusExt;
    let cases = huge_cases();
    let mut failures = vec![];
    for (k, (label, _)) in cases.iter().enumerate() {
        let out = std::process::Command::new("sh")
            .arg("-c")
            .arg("ulimit -v 4194304 && exec \"$0\" --exact \"$1\" --nocapture --test-threads=1")
            .arg(std::env::current_exe().unwrap())
            .arg(child_test())
            .env(CHILD_CASE, k.to_string())
            .env("RUST_BACKTRACE", "0")
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let stdout = String::from_utf8_lossy(&out.stdout);
        let what = match (out.status.code(), out.status.signal()) {
            // The child really parsed (a filter that matched nothing would pass too).
            (Some(0), _) if stdout.contains("1 passed") => continue,
            (Some(0), _) => format!("the child ran no test: {stdout}"),
            (Some(c), _) => format!("exit code {c}"),
            (_, Some(s)) => format!("signal {s}"),
            _ => "unknown status".into(),
        };
        let why = stderr
            .lines()
            .find(|l| l.contains("memory allocation") || l.contains("panicked"))
            .unwrap_or("");
        failures.push(format!("{label}: {what}: {why}"));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

const CHILD_CASE: &str = "REEB_SCENE_FUZZ_CASE";

/// The test the child runs, by its name in the test binary (the module
/// path without the crate's name).
fn child_test() -> String {
    let module = module_path!().split_once("::").map_or("", |(_, m)| m);
    format!("{module}::parse_one_in_a_child")
}

/// Huge axis counts, by label.
fn huge_cases() -> Vec<(&'static str, String)> {
    vec![
        (
            "linspace n = 1e12",
            vdp("epsilon = { linspace = [0.0, 1.0, 1e12] }", ""),
        ),
        (
            "logspace n = 1e12",
            vdp("epsilon = { logspace = [0.0, 1.0, 1e12] }", ""),
        ),
        (
            "random n = 10^12",
            vdp(
                "epsilon = { random = { low = 0.0, high = 1.0, n = 1000000000000, seed = 1 } }",
                "",
            ),
        ),
        (
            "linspace n = 1e308",
            vdp("epsilon = { linspace = [0.0, 1.0, 1e308] }", ""),
        ),
        (
            "linspace n = 2^63 - 1",
            vdp(
                "epsilon = { linspace = [0.0, 1.0, 9223372036854775807] }",
                "",
            ),
        ),
        (
            "dt linspace n = 1e12",
            vdp("epsilon = 1.0", "").replace("dt = 0.1", "dt = { linspace = [0.1, 0.2, 1e12] }"),
        ),
        // 8 GB: allocated (and filled) unless the address space is limited.
        (
            "linspace n = 1e9",
            vdp("epsilon = { linspace = [0.0, 1.0, 1e9] }", ""),
        ),
        // One plan per dt value, each with its own copy of the 10⁵ ε values: 8 GB.
        (
            "dt 10^4 values with t_end × epsilon 10^5 values",
            vdp("epsilon = { linspace = [0.0, 1.0, 100000] }", "").replace(
                "dt = 0.1\nsteps = 10",
                "dt = { logspace = [-3.0, -1.0, 10000] }\nt_end = 1.0",
            ),
        ),
    ]
}

/// The child of [`huge_axis_counts_neither_panic_nor_abort`]: parses one case
/// (and nothing when run on its own).
#[test]
fn parse_one_in_a_child() {
    let Ok(k) = std::env::var(CHILD_CASE) else {
        return;
    };
    let (_, text) = &huge_cases()[k.parse::<usize>().unwrap()];
    if let Err(e) = check(text) {
        panic!("{e}");
    }
}
