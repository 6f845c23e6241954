//! Damped (and forced) oscillator, SPEC §2.1: `H = p²/2 + q²/2 − F(t) q + α s`,
//! `q'' = −q − α q' + β sin ωt`.

#[allow(unused_imports)]
use super::mechanical::{Mechanical1dOps, MechanicalFlows};
#[allow(unused_imports)]
use crate::num::{math::Math, prims::Prims};

use super::spec::Method;
use super::spec::{ModelSpec, ParamDef, TimeDependence};

crate::shared_fns! {
    /// Model functions used by the ops (not ops themselves).
    trait DampedOscillatorFlows, wgsl DAMPED_OSCILLATOR_FLOWS_WGSL;

    /// `V'(q,t)`, `V(q,t)` and `f(t)` for the comparison integrators.
    fn damped_oscillator_mech(q: R, t: R, alpha: R, forcing_amplitude: R, forcing_frequency: R,
                              dv: &mut R, v: &mut R, f: &mut R) {
        let mut forcing: R = 0.0;
        R::damped_oscillator_time(t, forcing_amplitude, forcing_frequency, &mut forcing);
        *dv = q - forcing;
        *v = 0.5 * q * q - forcing * q;
        *f = alpha;
    }
}

crate::model_ops! {
    /// Pieces and time terms of the damped oscillator.
    trait DampedOscillatorOps, wgsl DAMPED_OSCILLATOR_WGSL, lanes damped_oscillator_lanes;

    /// Time term: the forcing `F(t) = β sin ωt`.
    fn damped_oscillator_time(t: R, forcing_amplitude: R, forcing_frequency: R, forcing: &mut R) {
        *forcing = forcing_amplitude * R::sin_r(forcing_frequency * t);
    }
    /// Piece A (α s) on p.
    fn damped_oscillator_a_p(p: &mut R, tau: R, alpha: R) {
        *p = R::mech_scale(*p, tau, alpha);
    }
    /// Piece A (α s) on s.
    fn damped_oscillator_a_s(s: &mut R, tau: R, alpha: R) {
        *s = R::mech_scale(*s, tau, alpha);
    }
    /// Piece B (V = q²/2 − F q) on p.
    fn damped_oscillator_b_p(q: R, p: &mut R, tau: R, forcing: R) {
        *p = R::mech_kick(*p, tau, q - forcing);
    }
    /// Piece B (V = q²/2 − F q) on s.
    fn damped_oscillator_b_s(q: R, s: &mut R, tau: R, forcing: R) {
        *s = R::mech_kick(*s, tau, 0.5 * q * q - forcing * q);
    }
}

crate::mechanical_1d_methods! {
    ops trait DampedOscillatorMethods, wgsl DAMPED_OSCILLATOR_METHODS_WGSL, lanes damped_oscillator_method_lanes;
    mech damped_oscillator_mech, field damped_oscillator_field, rk4 damped_oscillator_rk4,
    leapfrog damped_oscillator_leapfrog, variational1 damped_oscillator_variational1,
    variational2 damped_oscillator_variational2;
    params [alpha, forcing_amplitude, forcing_frequency]
}

crate::model_lanes! {
    traits [DampedOscillatorFlows, DampedOscillatorOps, DampedOscillatorMethods, MechanicalFlows, Mechanical1dOps];
    lanes [damped_oscillator_lanes, damped_oscillator_method_lanes, super::mechanical::mechanical_1d_lanes];
}

crate::pieces! {
    DAMPED_OSCILLATOR_PIECES, DAMPED_OSCILLATOR_TIME, DampedOscillatorPieces;
    ops [DampedOscillatorOps in damped_oscillator_lanes, Mechanical1dOps in super::mechanical::mechanical_1d_lanes];
    vars [q, p, s];
    time [damped_oscillator_time];
    'A' [damped_oscillator_a_p, damped_oscillator_a_s(opt)] identity_when_zero [alpha];
    'B' [damped_oscillator_b_p, damped_oscillator_b_s(opt)] identity_when_zero [];
    'C' [mech1_c_q, mech1_c_s(opt)] identity_when_zero [];
}

pub const SPEC: ModelSpec = ModelSpec {
    name: "damped_oscillator",
    summary: "q'' = -q - alpha q' + forcing_amplitude sin(forcing_frequency t)",
    vars: &["q", "p", "s"],
    optional_var: Some("s"),
    params: &[
        ParamDef::zero("alpha", "damping coefficient α"),
        ParamDef::zero(
            "forcing_amplitude",
            "forcing amplitude β (forcing β sin ωt)",
        ),
        ParamDef::zero("forcing_frequency", "forcing frequency ω"),
    ],
    pieces: "ABC",
    default_order: "CBABC",
    time: TimeDependence::WhenNonzero(&["forcing_amplitude"]),
    time_ops: DAMPED_OSCILLATOR_TIME,
    piece_ops: DAMPED_OSCILLATOR_PIECES,
    field_ops: &[("damped_oscillator_field", false)],
    methods: &[
        (Method::Rk4, "damped_oscillator_rk4"),
        (Method::Leapfrog, "damped_oscillator_leapfrog"),
        (Method::Variational1, "damped_oscillator_variational1"),
        (Method::Variational2, "damped_oscillator_variational2"),
    ],
    wgsl: &[
        DAMPED_OSCILLATOR_FLOWS_WGSL,
        DAMPED_OSCILLATOR_WGSL,
        DAMPED_OSCILLATOR_METHODS_WGSL,
    ],
    forcing_frequency: Some("forcing_frequency"),
    derived: &[],
    initial_defaults: &[],
    initial_alias: None,
    methods_carry_optional: true,
    rules: super::spec::no_rules,
};
