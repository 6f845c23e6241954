//! Perturbed Kepler problem in the plane, SPEC §2.1:
//! `H = |p|²/2 − 1/|q| + α sin(θt) s`, so `q'' = −q/|q|³ − α sin(θt) q'`.
//! Singular at q = 0 (the trajectory is then flagged non-finite).

#[allow(unused_imports)]
use super::mechanical::{Mechanical1dOps, MechanicalFlows};
#[allow(unused_imports)]
use crate::num::{math::Math, prims::Prims};

use super::spec::Method;
use super::spec::{InitialAlias, ModelSpec, ParamDef, TimeDependence};

crate::shared_fns! {
    /// Model functions used by the ops (not ops themselves).
    trait KeplerFlows, wgsl KEPLER_FLOWS_WGSL;

    /// `∇V(q)`, `V(q)` and `f(t)` for the comparison integrators.
    fn kepler_mech(q1: R, q2: R, t: R, alpha: R, theta: R,
                   dv1: &mut R, dv2: &mut R, v: &mut R, f: &mut R) {
        let r2: R = q1 * q1 + q2 * q2;
        let r: R = R::sqrt(r2);
        let inv3: R = 1.0 / (r2 * r);
        *dv1 = q1 * inv3;
        *dv2 = q2 * inv3;
        *v = -1.0 / r;
        R::kepler_time(t, alpha, theta, f);
    }
}

crate::model_ops! {
    /// Pieces, vector field and comparison integrators of the Kepler problem.
    trait KeplerOps, wgsl KEPLER_WGSL, lanes kepler_lanes;

    /// Time term: the damping `f(t) = α sin θt`.
    fn kepler_time(t: R, alpha: R, theta: R, damping: &mut R) {
        *damping = alpha * R::sin_r(theta * t);
    }
    /// Piece A on p.
    fn kepler_a_p(p1: &mut R, p2: &mut R, tau: R, damping: R) {
        *p1 = R::mech_scale(*p1, tau, damping);
        *p2 = R::mech_scale(*p2, tau, damping);
    }
    /// Piece B (V = −1/|q|) on p: `p ← p − τ q/|q|³`.
    fn kepler_b_p(q1: R, q2: R, p1: &mut R, p2: &mut R, tau: R) {
        let r2: R = q1 * q1 + q2 * q2;
        let inv3: R = 1.0 / (r2 * R::sqrt(r2));
        *p1 = R::mech_kick(*p1, tau, q1 * inv3);
        *p2 = R::mech_kick(*p2, tau, q2 * inv3);
    }
    /// Piece B (V = −1/|q|) on s.
    fn kepler_b_s(q1: R, q2: R, s: &mut R, tau: R) {
        *s = R::mech_kick(*s, tau, -1.0 / R::sqrt(q1 * q1 + q2 * q2));
    }
    /// Piece C on q.
    fn kepler_c_q(q1: &mut R, q2: &mut R, p1: R, p2: R, tau: R) {
        *q1 = R::mech_drift(*q1, tau, p1);
        *q2 = R::mech_drift(*q2, tau, p2);
    }
    /// Piece C on s.
    fn kepler_c_s(s: &mut R, p1: R, p2: R, tau: R) {
        *s = R::mech_drift_s(*s, tau, p1 * p1 + p2 * p2);
    }
    /// The contact vector field.
    fn kepler_field(q1: R, q2: R, p1: R, p2: R, s: R, t: R, alpha: R, theta: R,
                    dq1: &mut R, dq2: &mut R, dp1: &mut R, dp2: &mut R, ds: &mut R) {
        let mut g1: R = 0.0;
        let mut g2: R = 0.0;
        let mut v: R = 0.0;
        let mut f: R = 0.0;
        R::kepler_mech(q1, q2, t, alpha, theta, &mut g1, &mut g2, &mut v, &mut f);
        *dq1 = p1;
        *dq2 = p2;
        *dp1 = -g1 - f * p1;
        *dp2 = -g2 - f * p2;
        *ds = 0.5 * (p1 * p1 + p2 * p2) - v - f * s;
    }
    /// Classical fourth-order Runge–Kutta step from t over τ.
    fn kepler_rk4(q1: &mut R, q2: &mut R, p1: &mut R, p2: &mut R, s: &mut R, t: R, tau: R,
                  alpha: R, theta: R) {
        let hh: R = 0.5 * tau;
        let mut a1: R = 0.0;
        let mut a2: R = 0.0;
        let mut a3: R = 0.0;
        let mut a4: R = 0.0;
        let mut a5: R = 0.0;
        R::kepler_field(*q1, *q2, *p1, *p2, *s, t, alpha, theta, &mut a1, &mut a2, &mut a3, &mut a4, &mut a5);
        let mut b1: R = 0.0;
        let mut b2: R = 0.0;
        let mut b3: R = 0.0;
        let mut b4: R = 0.0;
        let mut b5: R = 0.0;
        R::kepler_field(*q1 + hh * a1, *q2 + hh * a2, *p1 + hh * a3, *p2 + hh * a4, *s + hh * a5, t + hh,
                        alpha, theta, &mut b1, &mut b2, &mut b3, &mut b4, &mut b5);
        let mut c1: R = 0.0;
        let mut c2: R = 0.0;
        let mut c3: R = 0.0;
        let mut c4: R = 0.0;
        let mut c5: R = 0.0;
        R::kepler_field(*q1 + hh * b1, *q2 + hh * b2, *p1 + hh * b3, *p2 + hh * b4, *s + hh * b5, t + hh,
                        alpha, theta, &mut c1, &mut c2, &mut c3, &mut c4, &mut c5);
        let mut d1: R = 0.0;
        let mut d2: R = 0.0;
        let mut d3: R = 0.0;
        let mut d4: R = 0.0;
        let mut d5: R = 0.0;
        R::kepler_field(*q1 + tau * c1, *q2 + tau * c2, *p1 + tau * c3, *p2 + tau * c4, *s + tau * c5, t + tau,
                        alpha, theta, &mut d1, &mut d2, &mut d3, &mut d4, &mut d5);
        *q1 = R::rk4_combine(*q1, tau, a1, b1, c1, d1);
        *q2 = R::rk4_combine(*q2, tau, a2, b2, c2, d2);
        *p1 = R::rk4_combine(*p1, tau, a3, b3, c3, d3);
        *p2 = R::rk4_combine(*p2, tau, a4, b4, c4, d4);
        *s = R::rk4_combine(*s, tau, a5, b5, c5, d5);
    }
    /// Leapfrog with the damping in the acceleration (see the 1-D template in
    /// `mechanical.rs`), componentwise.
    fn kepler_leapfrog(q1: &mut R, q2: &mut R, p1: &mut R, p2: &mut R, s: &mut R, t: R, tau: R,
                       alpha: R, theta: R) {
        let mut g1: R = 0.0;
        let mut g2: R = 0.0;
        let mut v0: R = 0.0;
        let mut fa: R = 0.0;
        R::kepler_mech(*q1, *q2, t, alpha, theta, &mut g1, &mut g2, &mut v0, &mut fa);
        let mut fm: R = 0.0;
        R::kepler_time(t + 0.5 * tau, alpha, theta, &mut fm);
        let d: R = 1.0 + 0.5 * tau * fm;
        let h1: R = (*p1 - 0.5 * tau * g1) / d;
        let h2: R = (*p2 - 0.5 * tau * g2) / d;
        let n1: R = *q1 + tau * h1;
        let n2: R = *q2 + tau * h2;
        let mut e1: R = 0.0;
        let mut e2: R = 0.0;
        let mut v1: R = 0.0;
        let mut fb: R = 0.0;
        R::kepler_mech(n1, n2, t + tau, alpha, theta, &mut e1, &mut e2, &mut v1, &mut fb);
        *s = (*s * (1.0 - 0.5 * tau * fm) + tau * (0.5 * (h1 * h1 + h2 * h2) - 0.5 * (v0 + v1))) / d;
        *p1 = h1 - 0.5 * tau * (e1 + fm * h1);
        *p2 = h2 - 0.5 * tau * (e2 + fm * h2);
        *q1 = n1;
        *q2 = n2;
    }
    /// Contact variational integrator of first order, componentwise.
    fn kepler_variational1(q1: &mut R, q2: &mut R, p1: &mut R, p2: &mut R, s: &mut R, t: R, tau: R,
                           alpha: R, theta: R) {
        let mut g1: R = 0.0;
        let mut g2: R = 0.0;
        let mut v0: R = 0.0;
        let mut fa: R = 0.0;
        R::kepler_mech(*q1, *q2, t, alpha, theta, &mut g1, &mut g2, &mut v0, &mut fa);
        let mut fm: R = 0.0;
        R::kepler_time(t + 0.5 * tau, alpha, theta, &mut fm);
        let c: R = 1.0 - tau * fm;
        let n1: R = *q1 + tau * c * *p1 - 0.5 * tau * tau * g1;
        let n2: R = *q2 + tau * c * *p2 - 0.5 * tau * tau * g2;
        let mut e1: R = 0.0;
        let mut e2: R = 0.0;
        let mut v1: R = 0.0;
        let mut fb: R = 0.0;
        R::kepler_mech(n1, n2, t + tau, alpha, theta, &mut e1, &mut e2, &mut v1, &mut fb);
        let w1: R = (n1 - *q1) / tau;
        let w2: R = (n2 - *q2) / tau;
        *s = *s * c + tau * (0.5 * (w1 * w1 + w2 * w2) - 0.5 * (v0 + v1));
        *p1 = c * *p1 - 0.5 * tau * (g1 + e1);
        *p2 = c * *p2 - 0.5 * tau * (g2 + e2);
        *q1 = n1;
        *q2 = n2;
    }
    /// Contact variational integrator of second order, componentwise.
    fn kepler_variational2(q1: &mut R, q2: &mut R, p1: &mut R, p2: &mut R, s: &mut R, t: R, tau: R,
                           alpha: R, theta: R) {
        let mut g1: R = 0.0;
        let mut g2: R = 0.0;
        let mut v0: R = 0.0;
        let mut fa: R = 0.0;
        R::kepler_mech(*q1, *q2, t, alpha, theta, &mut g1, &mut g2, &mut v0, &mut fa);
        let mut fm: R = 0.0;
        R::kepler_time(t + 0.5 * tau, alpha, theta, &mut fm);
        let c: R = 1.0 - 0.5 * tau * fm;
        let d: R = 1.0 + 0.5 * tau * fm;
        let n1: R = *q1 + tau * c * *p1 - 0.5 * tau * tau * g1;
        let n2: R = *q2 + tau * c * *p2 - 0.5 * tau * tau * g2;
        let mut e1: R = 0.0;
        let mut e2: R = 0.0;
        let mut v1: R = 0.0;
        let mut fb: R = 0.0;
        R::kepler_mech(n1, n2, t + tau, alpha, theta, &mut e1, &mut e2, &mut v1, &mut fb);
        let w1: R = (n1 - *q1) / tau;
        let w2: R = (n2 - *q2) / tau;
        *s = (*s * c + tau * (0.5 * (w1 * w1 + w2 * w2) - 0.5 * (v0 + v1))) / d;
        *p1 = (c * *p1 - 0.5 * tau * (g1 + e1)) / d;
        *p2 = (c * *p2 - 0.5 * tau * (g2 + e2)) / d;
        *q1 = n1;
        *q2 = n2;
    }
}

/// Initial state of a Kepler orbit of semi-major axis 1 and eccentricity e at
/// perihelion: `q = (1 − e, 0)`, `p = (0, sqrt((1 + e)/(1 − e)))` (SPEC §2.1).
pub fn perihelion(e: f64) -> ([f64; 2], [f64; 2]) {
    ([1.0 - e, 0.0], [0.0, ((1.0 + e) / (1.0 - e)).sqrt()])
}

crate::model_lanes! {
    traits [KeplerFlows, KeplerOps, MechanicalFlows, Mechanical1dOps];
    lanes [kepler_lanes, super::mechanical::mechanical_1d_lanes];
}

crate::pieces! {
    KEPLER_PIECES, KEPLER_TIME, KeplerPieces;
    ops [KeplerOps in kepler_lanes, Mechanical1dOps in super::mechanical::mechanical_1d_lanes];
    vars [q1, q2, p1, p2, s];
    time [kepler_time];
    'A' [kepler_a_p, mech1_a_s(opt)] identity_when_zero [alpha];
    'B' [kepler_b_p, kepler_b_s(opt)] identity_when_zero [];
    'C' [kepler_c_q, kepler_c_s(opt)] identity_when_zero [];
}

/// `initial.eccentricity = e`: the orbit of semi-major axis 1 at perihelion
/// (sets q1 and p2 unless they are given).
const PERIHELION: InitialAlias = InitialAlias {
    key: "eccentricity",
    range: "[0, 1)",
    ok: |e| (0.0..1.0).contains(&e),
    sets: &[
        ("q1", |e| perihelion(e).0[0]),
        ("p2", |e| perihelion(e).1[1]),
    ],
};

pub const SPEC: ModelSpec = ModelSpec {
    name: "kepler",
    summary: "q'' = -q/|q|^3 - alpha sin(theta t) q' in the plane",
    vars: &["q1", "q2", "p1", "p2", "s"],
    optional_var: Some("s"),
    params: &[
        ParamDef::zero("alpha", "amplitude α of the damping α sin θt"),
        ParamDef::zero("theta", "frequency θ of the damping"),
    ],
    pieces: "ABC",
    default_order: "CBABC",
    time: TimeDependence::WhenNonzero(&["alpha"]),
    time_ops: KEPLER_TIME,
    piece_ops: KEPLER_PIECES,
    field_ops: &[("kepler_field", false)],
    methods: &[
        (Method::Rk4, "kepler_rk4"),
        (Method::Leapfrog, "kepler_leapfrog"),
        (Method::Variational1, "kepler_variational1"),
        (Method::Variational2, "kepler_variational2"),
    ],
    wgsl: &[KEPLER_FLOWS_WGSL, KEPLER_WGSL],
    forcing_frequency: Some("theta"),
    derived: &[],
    initial_defaults: &[],
    initial_alias: Some(PERIHELION),
    methods_carry_optional: true,
    rules: super::spec::no_rules,
};
