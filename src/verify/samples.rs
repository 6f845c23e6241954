//! Sample problems of every model, with every parameter nonzero (so every
//! piece and time term is used), and the small ensembles over them on which
//! `reeb doctor` and the tests compare the backends.

use crate::models::Model;
use crate::plan::scheme::{Scheme, SchemeKind};
use crate::plan::{Problem, Source};

/// A problem for `model` (a name of `MODEL_NAMES`) and `scheme`, 10 steps;
/// `None` where the model lacks the comparison method `scheme`.
pub fn problem(model: &str, scheme: &str) -> Option<Problem> {
    let mut m = Model::from_name(model)?;
    if let Model::Lienard { f, g } = &mut m {
        *f = vec![-1.0, 0.0, 1.0];
        *g = vec![0.0, 1.0, 0.0, 0.2];
    }
    let s = Scheme::by_name(scheme)?;
    if let SchemeKind::Method(me) = s.kind {
        m.spec().method_op(me)?;
    }
    let mut p = Problem::new(m, scheme).ok()?;
    for (k, v) in params(model) {
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

fn params(model: &str) -> &'static [(&'static str, f64)] {
    match model {
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
    }
}

/// The model's first variable (the one its sample ensembles sweep).
pub fn first_var(model: &str) -> &'static str {
    if model == "kepler" {
        "q1"
    } else {
        "q"
    }
}
