//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod runs;

use std::sync::OnceLock;

use reeb::backend::gpu::GpuContext;
use reeb::models::Model;
use reeb::plan::scheme::{Scheme, SchemeKind};
use reeb::plan::{Problem, Source};

/// A problem for `model` with nonzero parameters (so every piece and time term is used).
pub fn problem(model: &str, scheme: &str) -> Option<Problem> {
    let mut m = Model::from_name(model).unwrap();
    if let Model::Lienard { f, g } = &mut m {
        *f = vec![-1.0, 0.0, 1.0];
        *g = vec![0.0, 1.0, 0.0, 0.2];
    }
    let s = Scheme::by_name(scheme).unwrap();
    if let SchemeKind::Method(me) = s.kind {
        m.spec().method_op(me)?;
    }
    let mut p = Problem::new(m.clone(), scheme).unwrap();
    let params: &[(&str, f64)] = match model {
        "damped_oscillator" => &[
            ("alpha", 0.3),
            ("forcing_amplitude", 0.5),
            ("forcing_frequency", 1.3),
        ],
        "van_der_pol" => &[
            ("epsilon", 1.0),
            ("forcing_amplitude", 0.5),
            ("forcing_frequency", 1.1),
        ],
        "kepler" => &[("alpha", 0.01), ("theta", std::f64::consts::TAU)],
        "lane_emden" => &[("index", 3.0)],
        "spin_orbit" => &[
            ("eccentricity", 0.1),
            ("epsilon", 0.05),
            ("lambda", 0.1),
            ("omega", 1.0),
            ("tidal_k", 1e-3),
            ("tidal_eta", 1.0),
        ],
        "quadratic_s" => &[("gamma", 0.2), ("r", 0.1)],
        _ => &[],
    };
    for (k, v) in params {
        p = p.param(k, Source::Const(*v));
    }
    match model {
        "kepler" => {
            p = p
                .initial("q1", Source::Const(0.5))
                .initial("p2", Source::Const(1.5));
        }
        "lane_emden" => {}
        _ => {
            p = p
                .initial("q", Source::Const(1.0))
                .initial("p", Source::Const(0.5));
        }
    }
    p.steps = 10;
    Some(p)
}

pub fn first_var(model: &str) -> &'static str {
    if model == "kepler" {
        "q1"
    } else {
        "q"
    }
}

/// The GPU context shared by a test binary, or `None` (after printing SKIP)
/// when no adapter exists. With `REEB_REQUIRE_GPU=1` (CI, after installing
/// lavapipe) a missing adapter fails the test instead: GPU tests never skip
/// silently there.
pub fn gpu() -> Option<&'static GpuContext> {
    static CTX: OnceLock<Option<GpuContext>> = OnceLock::new();
    CTX.get_or_init(|| match GpuContext::new() {
        Ok(c) => Some(c),
        Err(e) => {
            if std::env::var("REEB_REQUIRE_GPU").is_ok_and(|v| v == "1") {
                panic!("REEB_REQUIRE_GPU=1 but no GPU adapter: {e}");
            }
            eprintln!("SKIP: no GPU adapter ({e})");
            None
        }
    })
    .as_ref()
}
