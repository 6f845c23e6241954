//! The whole `reeb verify` suite (SPEC §4 oracles and every scheme's
//! measured order) on the CPU backend, in both precisions.

use reeb::backend::Engine;
use reeb::num::precision::Precision;
use reeb::verify::{run_all, Target};

fn suite(precision: Precision) {
    let rows = run_all(
        &Target {
            engine: Engine::Cpu,
            precision,
        },
        |_| {},
    );
    let failed: Vec<String> = rows
        .iter()
        .filter(|c| !c.pass)
        .map(|c| {
            format!(
                "{}: expected {} measured {} tolerance {}",
                c.name, c.expected, c.measured, c.tolerance
            )
        })
        .collect();
    assert!(rows.len() >= 40);
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

#[test]
fn verify_cpu_f64() {
    suite(Precision::F64);
}

#[test]
fn verify_cpu_f32() {
    suite(Precision::F32);
}
