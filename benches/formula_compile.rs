//! Criterion benchmarks of compiling long formulas (issue 31, point 3):
//! `formula_compile/<shape>/<stage>/<size>`, where a stage is `model` (the
//! text parsed into the DAG, the derivatives, each op lowered) or
//! `model+step` (and the S2 step composed: substitution, the rewrites, the
//! cheapest of four programs lowered), as `reeb run` does once per scene.
//! Shapes: `tower` (`q^q^…^q`, n powers: a chain n deep through every
//! pass), `sum` (`0.5*q^2 + …` to n bytes: the "1 MB formula"), `distinct`
//! (n terms `c_k*sin(q + k)`: nothing merges). Compile time should grow
//! about linearly with n. `REEB_BENCH_QUICK=1` runs the two smallest sizes.

use std::path::Path;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};

use reeb::models::formula::{Cost, FormulaModel, Kind, Source};
use reeb::models::spec::Op;
use reeb::scene::Scene;

fn quick() -> bool {
    std::env::var_os("REEB_BENCH_QUICK").is_some()
}

/// The sizes of a shape, the two smallest when quick.
fn sizes(all: &[usize]) -> &[usize] {
    if quick() {
        &all[..2]
    } else {
        all
    }
}

/// A mechanical model with one degree of freedom and this potential.
fn source(potential: String) -> Source {
    Source {
        kind: Kind::Mechanical { dof: 1 },
        texts: vec![("potential".into(), potential)],
        params: vec![],
        forcing_frequency: None,
    }
}

/// The ops of an S2 step of a mechanical formula model without damping.
fn s2_step() -> Vec<Op> {
    let text = "model = \"mechanical\"\n[formula]\npotential = \"q^2/2\"\n[initial]\nq = 0.5\np = 0.0\n[integrator]\nscheme = \"s2\"\ndt = 0.01\nsteps = 10\n";
    let scene = Scene::parse(Path::new("bench.toml"), text).expect("the scene");
    let mut subs = scene.sub_runs().expect("its plan");
    subs.remove(0).plan.ops.clone()
}

fn shapes() -> Vec<(&'static str, Vec<(usize, String)>)> {
    let tower = sizes(&[1_000, 2_000, 4_000, 8_000])
        .iter()
        .map(|&n| (n, vec!["q"; n].join("^")))
        .collect();
    let sum = sizes(&[125_000, 250_000, 500_000, 1_000_000])
        .iter()
        .map(|&bytes| (bytes, vec!["0.5*q^2"; bytes / 10 + 1].join(" + ")))
        .collect();
    let distinct = sizes(&[6_250, 12_500, 25_000, 50_000])
        .iter()
        .map(|&n| {
            let terms: Vec<String> = (0..n)
                .map(|k| format!("{:e}*sin(q + {k})", 1e-5 / (1.0 + k as f64)))
                .collect();
            (n, terms.join(" + "))
        })
        .collect();
    vec![("tower", tower), ("sum", sum), ("distinct", distinct)]
}

fn compile(c: &mut Criterion) {
    let step = s2_step();
    for (shape, cases) in shapes() {
        let mut g = c.benchmark_group(format!("formula_compile/{shape}"));
        g.sample_size(10)
            .warm_up_time(Duration::from_millis(500))
            .measurement_time(Duration::from_secs(5));
        for (n, text) in cases {
            let src = source(text);
            g.bench_with_input(BenchmarkId::new("model", n), &src, |b, src| {
                b.iter(|| FormulaModel::build(src).expect("compiles"))
            });
            g.bench_with_input(BenchmarkId::new("model+step", n), &src, |b, src| {
                b.iter(|| {
                    let m = FormulaModel::build(src).expect("compiles");
                    m.compose(&step, Cost::PerLane).expect("composes")
                })
            });
        }
        g.finish();
    }
}

criterion_group!(benches, compile);
criterion_main!(benches);
