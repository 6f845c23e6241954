//! Quadratic-s oscillator (seed 000, example 3; the "cosmological" toy model of
//! seed 001), SPEC §2.3: `H = p²/2 + q²/2 + γ s²/2 − R`, so that
//! `q'' = −q − γ s q'`: the damping depends on the action itself.

#[allow(unused_imports)]
use super::mechanical::{Mechanical1dOps, MechanicalFlows};
#[allow(unused_imports)]
use crate::num::{math::Math, prims::Prims};

use super::spec::Method;
use super::spec::{ModelSpec, ParamDef, TimeDependence};

crate::model_ops! {
    /// Pieces, vector field and RK4 of the quadratic-s oscillator.
    trait QuadraticSOps, wgsl QUADRATIC_S_WGSL, lanes quadratic_s_lanes;

    /// Piece A (γ s²/2) over τ: with `u = 1 + γ s τ/2`, `s ← s/u`, `p ← p/u²`
    /// (singular when u = 0: the trajectory is then flagged non-finite).
    fn quadratic_s_a(p: &mut R, s: &mut R, tau: R, gamma: R) {
        let u: R = 1.0 + 0.5 * gamma * *s * tau;
        *s = *s / u;
        *p = *p / (u * u);
    }
    /// Piece B (V = q²/2, with the constant −R folded in) on p and s.
    fn quadratic_s_b(q: R, p: &mut R, s: &mut R, tau: R, r: R) {
        *p = R::mech_kick(*p, tau, q);
        *s = R::mech_kick(*s, tau, 0.5 * q * q - r);
    }
    /// The contact vector field.
    fn quadratic_s_field(q: R, p: R, s: R, gamma: R, r: R, dq: &mut R, dp: &mut R, ds: &mut R) {
        *dq = p;
        *dp = -q - gamma * s * p;
        *ds = 0.5 * p * p - (0.5 * q * q - r) - 0.5 * gamma * s * s;
    }
    /// Classical fourth-order Runge–Kutta step over τ.
    fn quadratic_s_rk4(q: &mut R, p: &mut R, s: &mut R, tau: R, gamma: R, r: R) {
        let hh: R = 0.5 * tau;
        let mut k1q: R = 0.0;
        let mut k1p: R = 0.0;
        let mut k1s: R = 0.0;
        R::quadratic_s_field(*q, *p, *s, gamma, r, &mut k1q, &mut k1p, &mut k1s);
        let mut k2q: R = 0.0;
        let mut k2p: R = 0.0;
        let mut k2s: R = 0.0;
        R::quadratic_s_field(*q + hh * k1q, *p + hh * k1p, *s + hh * k1s, gamma, r, &mut k2q, &mut k2p, &mut k2s);
        let mut k3q: R = 0.0;
        let mut k3p: R = 0.0;
        let mut k3s: R = 0.0;
        R::quadratic_s_field(*q + hh * k2q, *p + hh * k2p, *s + hh * k2s, gamma, r, &mut k3q, &mut k3p, &mut k3s);
        let mut k4q: R = 0.0;
        let mut k4p: R = 0.0;
        let mut k4s: R = 0.0;
        R::quadratic_s_field(*q + tau * k3q, *p + tau * k3p, *s + tau * k3s, gamma, r, &mut k4q, &mut k4p, &mut k4s);
        *q = R::rk4_combine(*q, tau, k1q, k2q, k3q, k4q);
        *p = R::rk4_combine(*p, tau, k1p, k2p, k3p, k4p);
        *s = R::rk4_combine(*s, tau, k1s, k2s, k3s, k4s);
    }
}

crate::model_lanes! {
    traits [QuadraticSOps, MechanicalFlows, Mechanical1dOps];
    lanes [quadratic_s_lanes, super::mechanical::mechanical_1d_lanes];
}

crate::pieces! {
    QUADRATIC_S_PIECES, QUADRATIC_S_TIME, QuadraticSPieces;
    ops [QuadraticSOps in quadratic_s_lanes, Mechanical1dOps in super::mechanical::mechanical_1d_lanes];
    vars [q, p, s];
    time [];
    'A' [quadratic_s_a] identity_when_zero [gamma];
    'B' [quadratic_s_b] identity_when_zero [];
    'C' [mech1_c_q, mech1_c_s] identity_when_zero [];
}

pub const SPEC: ModelSpec = ModelSpec {
    name: "quadratic_s",
    summary: "q'' = -q - gamma s q', H = p^2/2 + q^2/2 + gamma s^2/2 - r",
    vars: &["q", "p", "s"],
    optional_var: None,
    params: &[
        ParamDef::zero("gamma", "coefficient γ of the s²/2 term"),
        ParamDef::zero("r", "constant R (H contains −R)"),
    ],
    pieces: "ABC",
    default_order: "CBABC",
    time: TimeDependence::Never,
    time_ops: QUADRATIC_S_TIME,
    piece_ops: QUADRATIC_S_PIECES,
    field_ops: &[("quadratic_s_field", false)],
    methods: &[(Method::Rk4, "quadratic_s_rk4")],
    wgsl: &[QUADRATIC_S_WGSL],
    forcing_frequency: None,
    derived: &[],
    initial_defaults: &[],
    initial_alias: None,
    methods_carry_optional: true,
    rules: super::spec::no_rules,
};
