//! Liénard systems `q'' + f(q) q' + g(q, t) = 0` as the `(q, s)` projection of
//! `H = p s + f(q) s + g(q, t)` (SPEC §2.2): van der Pol and the general system
//! with polynomial f and g. The slope variable `p` does not feed back and is
//! integrated only when a scene asks for it.

#[allow(unused_imports)]
use super::mechanical::{Mechanical1dOps, MechanicalFlows};
#[allow(unused_imports)]
use crate::num::{math::Math, prims::Prims};

use super::spec::Method;
use super::spec::{ModelSpec, ParamDef, TimeDependence};

/// Coefficients a polynomial f or g of the general Liénard model may have
/// (degree ≤ 9).
pub const MAX_COEFFICIENTS: usize = 10;

crate::shared_fns! {
    /// Model functions used by the ops (not ops themselves).
    trait LienardModelFlows, wgsl LIENARD_MODEL_FLOWS_WGSL;

    /// f, f', g, g' of the general model at q.
    fn lienard_lien(q: R, t: R, f0: R, f1: R, f2: R, f3: R, f4: R, f5: R, f6: R, f7: R, f8: R, f9: R,
                    g0: R, g1: R, g2: R, g3: R, g4: R, g5: R, g6: R, g7: R, g8: R, g9: R,
                    f: &mut R, df: &mut R, g: &mut R, dg: &mut R) {
        R::poly10(q, f0, f1, f2, f3, f4, f5, f6, f7, f8, f9, f, df);
        R::poly10(q, g0, g1, g2, g3, g4, g5, g6, g7, g8, g9, g, dg);
    }
    /// f, f', g, g' of van der Pol at (q, t).
    fn van_der_pol_lien(q: R, t: R, epsilon: R, forcing_amplitude: R, forcing_frequency: R,
                        f: &mut R, df: &mut R, g: &mut R, dg: &mut R) {
        let mut forcing: R = 0.0;
        R::van_der_pol_time(t, forcing_amplitude, forcing_frequency, &mut forcing);
        *f = -epsilon * (1.0 - q * q);
        *df = 2.0 * epsilon * q;
        *g = q - forcing;
        *dg = 1.0;
    }
}

crate::shared_fns! {
    /// Exact flows of the Liénard pieces, given f, f', g, g' at q.
    trait LienardFlows, wgsl LIENARD_FLOWS_WGSL;

    /// Piece A (f(q) s) on s: `s ← s e^{−τ f(q)}` (SPEC §5: the sign printed
    /// in the paper's eq. (40) is wrong).
    fn lienard_flow_a_s(s: R, tau: R, f: R) -> R {
        return s * R::exp_r(-(tau * f));
    }
    /// Piece A on p, with the old s: `p ← (p − τ f'(q) s) e^{−τ f(q)}` (SPEC §5:
    /// the authors' code has the wrong sign).
    fn lienard_flow_a_p(p: R, s: R, tau: R, f: R, df: R) -> R {
        return (p - tau * df * s) * R::exp_r(-(tau * f));
    }
    /// `c0 + c1 x + … + c9 x⁹` and its derivative, by Horner's scheme.
    fn poly10(x: R, c0: R, c1: R, c2: R, c3: R, c4: R, c5: R, c6: R, c7: R, c8: R, c9: R,
              v: &mut R, d: &mut R) {
        let mut pv: R = c9;
        let mut pd: R = 0.0;
        pd = pd * x + pv; pv = pv * x + c8;
        pd = pd * x + pv; pv = pv * x + c7;
        pd = pd * x + pv; pv = pv * x + c6;
        pd = pd * x + pv; pv = pv * x + c5;
        pd = pd * x + pv; pv = pv * x + c4;
        pd = pd * x + pv; pv = pv * x + c3;
        pd = pd * x + pv; pv = pv * x + c2;
        pd = pd * x + pv; pv = pv * x + c1;
        pd = pd * x + pv; pv = pv * x + c0;
        *v = pv;
        *d = pd;
    }
}

crate::model_ops! {
    /// Pieces of Liénard systems common to van der Pol and the general model.
    trait LienardOps, wgsl LIENARD_WGSL, lanes lienard_lanes;

    /// Piece C (p s) on q: `q ← q + τ s`.
    fn lienard_c_q(q: &mut R, s: R, tau: R) {
        *q = *q + tau * s;
    }
    /// Piece C (p s) on p: `p ← p/(1 + τ p)` (p = ds/dq passes through ±∞ when s = 0).
    fn lienard_c_p(p: &mut R, tau: R) {
        *p = *p / (1.0 + tau * *p);
    }
    /// Piece B (g) on s for the general model (autonomous g).
    fn lienard_b_s(q: R, s: &mut R, tau: R, g0: R, g1: R, g2: R, g3: R, g4: R, g5: R, g6: R, g7: R, g8: R, g9: R) {
        let mut g: R = 0.0;
        let mut dg: R = 0.0;
        R::poly10(q, g0, g1, g2, g3, g4, g5, g6, g7, g8, g9, &mut g, &mut dg);
        *s = *s - tau * g;
    }
    /// Piece B (g) on p for the general model.
    fn lienard_b_p(q: R, p: &mut R, tau: R, g0: R, g1: R, g2: R, g3: R, g4: R, g5: R, g6: R, g7: R, g8: R, g9: R) {
        let mut g: R = 0.0;
        let mut dg: R = 0.0;
        R::poly10(q, g0, g1, g2, g3, g4, g5, g6, g7, g8, g9, &mut g, &mut dg);
        *p = *p - tau * dg;
    }
    /// Piece A (f(q) s) on s for the general model.
    fn lienard_a_s(q: R, s: &mut R, tau: R, f0: R, f1: R, f2: R, f3: R, f4: R, f5: R, f6: R, f7: R, f8: R, f9: R) {
        let mut f: R = 0.0;
        let mut df: R = 0.0;
        R::poly10(q, f0, f1, f2, f3, f4, f5, f6, f7, f8, f9, &mut f, &mut df);
        *s = R::lienard_flow_a_s(*s, tau, f);
    }
    /// Piece A on p for the general model (runs before `lienard_a_s`: it reads the old s).
    fn lienard_a_p(q: R, s: R, p: &mut R, tau: R, f0: R, f1: R, f2: R, f3: R, f4: R, f5: R, f6: R, f7: R, f8: R, f9: R) {
        let mut f: R = 0.0;
        let mut df: R = 0.0;
        R::poly10(q, f0, f1, f2, f3, f4, f5, f6, f7, f8, f9, &mut f, &mut df);
        *p = R::lienard_flow_a_p(*p, s, tau, f, df);
    }
    /// Time term of van der Pol: the forcing `A cos ωt`.
    fn van_der_pol_time(t: R, forcing_amplitude: R, forcing_frequency: R, forcing: &mut R) {
        *forcing = forcing_amplitude * R::cos_r(forcing_frequency * t);
    }
    /// Piece B (g = q − A cos ωt) on s: `s ← (s + τ A cos ωt) − τ q`, the
    /// forcing added to the old s, so that only `− τ q` waits for the new q
    /// (a shorter dependent chain; unforced, it is `s − τ q` exactly).
    fn van_der_pol_b_s(q: R, s: &mut R, tau: R, forcing: R) {
        *s = (*s + tau * forcing) - tau * q;
    }
    /// Piece B on p (g' = 1).
    fn van_der_pol_b_p(p: &mut R, tau: R) {
        *p = *p - tau;
    }
    /// Piece A (f(q) s, f = −ε(1 − q²)) on s: `s ← s e^{τε(1 − q²)}`, with τε
    /// formed before q is known (it shortens the step's dependent chain).
    fn van_der_pol_a_s(q: R, s: &mut R, tau: R, epsilon: R) {
        *s = *s * R::exp_r((tau * epsilon) * (1.0 - q * q));
    }
    /// Piece A on p (f' = 2εq): `p ← (p − 2τεq s) e^{τε(1 − q²)}`; runs
    /// before `van_der_pol_a_s`.
    fn van_der_pol_a_p(q: R, s: R, p: &mut R, tau: R, epsilon: R) {
        *p = (*p - tau * (2.0 * epsilon * q) * s) * R::exp_r((tau * epsilon) * (1.0 - q * q));
    }
}

/// Generates, from a Liénard model's `lien` function (f, f', g, g' at (q, t)),
/// its vector field and the comparison integrators on `(q, s)`: RK4, and the
/// leapfrog with the damping f(q) q' in the acceleration (seed 000 §2).
#[macro_export]
macro_rules! lienard_methods {
    (
        ops trait $tr:ident, wgsl $wg:ident, lanes $lm:ident;
        lien $lien:ident, field $field:ident, field_p $field_p:ident, rk4 $rk4:ident,
        leapfrog $lf:ident;
        params [$($par:ident),* $(,)?]
    ) => {
        $crate::model_ops! {
            /// Vector field and comparison integrators.
            trait $tr, wgsl $wg, lanes $lm;

            /// `q' = s`, `s' = −f(q) s − g(q, t)`.
            fn $field(q: R, s: R, t: R, $($par: R,)* dq: &mut R, ds: &mut R) {
                let mut f: R = 0.0;
                let mut df: R = 0.0;
                let mut g: R = 0.0;
                let mut dg: R = 0.0;
                R::$lien(q, t, $($par,)* &mut f, &mut df, &mut g, &mut dg);
                *dq = s;
                *ds = -f * s - g;
            }
            /// `p' = −p² − f p − f' s − g'`.
            fn $field_p(q: R, s: R, p: R, t: R, $($par: R,)* dp: &mut R) {
                let mut f: R = 0.0;
                let mut df: R = 0.0;
                let mut g: R = 0.0;
                let mut dg: R = 0.0;
                R::$lien(q, t, $($par,)* &mut f, &mut df, &mut g, &mut dg);
                *dp = -p * p - f * p - df * s - dg;
            }
            /// Classical fourth-order Runge–Kutta step on (q, s) from t over τ.
            fn $rk4(q: &mut R, s: &mut R, t: R, tau: R, $($par: R),*) {
                let hh: R = 0.5 * tau;
                let mut k1q: R = 0.0;
                let mut k1s: R = 0.0;
                R::$field(*q, *s, t, $($par,)* &mut k1q, &mut k1s);
                let mut k2q: R = 0.0;
                let mut k2s: R = 0.0;
                R::$field(*q + hh * k1q, *s + hh * k1s, t + hh, $($par,)* &mut k2q, &mut k2s);
                let mut k3q: R = 0.0;
                let mut k3s: R = 0.0;
                R::$field(*q + hh * k2q, *s + hh * k2s, t + hh, $($par,)* &mut k3q, &mut k3s);
                let mut k4q: R = 0.0;
                let mut k4s: R = 0.0;
                R::$field(*q + tau * k3q, *s + tau * k3s, t + tau, $($par,)* &mut k4q, &mut k4s);
                *q = R::rk4_combine(*q, tau, k1q, k2q, k3q, k4q);
                *s = R::rk4_combine(*s, tau, k1s, k2s, k3s, k4s);
            }
            /// Leapfrog with the damping in the acceleration, velocity s:
            /// `s½ = s − τ/2 (g(q) + f(q) s½)`, `q ← q + τ s½`,
            /// `s ← s½ − τ/2 (g(q') + f(q') s½)`.
            fn $lf(q: &mut R, s: &mut R, t: R, tau: R, $($par: R),*) {
                let mut fa: R = 0.0;
                let mut dfa: R = 0.0;
                let mut ga: R = 0.0;
                let mut dga: R = 0.0;
                R::$lien(*q, t, $($par,)* &mut fa, &mut dfa, &mut ga, &mut dga);
                let sh: R = (*s - 0.5 * tau * ga) / (1.0 + 0.5 * tau * fa);
                let qn: R = *q + tau * sh;
                let mut fb: R = 0.0;
                let mut dfb: R = 0.0;
                let mut gb: R = 0.0;
                let mut dgb: R = 0.0;
                R::$lien(qn, t + tau, $($par,)* &mut fb, &mut dfb, &mut gb, &mut dgb);
                *s = sh - 0.5 * tau * (gb + fb * sh);
                *q = qn;
            }
        }
    };
}

crate::lienard_methods! {
    ops trait VanDerPolMethods, wgsl VAN_DER_POL_METHODS_WGSL, lanes van_der_pol_method_lanes;
    lien van_der_pol_lien, field van_der_pol_field, field_p van_der_pol_field_p,
    rk4 van_der_pol_rk4, leapfrog van_der_pol_leapfrog;
    params [epsilon, forcing_amplitude, forcing_frequency]
}

crate::lienard_methods! {
    ops trait LienardMethods, wgsl LIENARD_METHODS_WGSL, lanes lienard_method_lanes;
    lien lienard_lien, field lienard_field, field_p lienard_field_p,
    rk4 lienard_rk4, leapfrog lienard_leapfrog;
    params [f0, f1, f2, f3, f4, f5, f6, f7, f8, f9, g0, g1, g2, g3, g4, g5, g6, g7, g8, g9]
}

crate::model_lanes! {
    traits [LienardFlows, LienardModelFlows, LienardOps, VanDerPolMethods, LienardMethods];
    lanes [lienard_lanes, van_der_pol_method_lanes, lienard_method_lanes];
}

crate::pieces! {
    VAN_DER_POL_PIECES, VAN_DER_POL_TIME, VanDerPolPieces;
    ops [LienardOps in lienard_lanes];
    vars [q, s, p];
    time [van_der_pol_time];
    'A' [van_der_pol_a_p(opt), van_der_pol_a_s] identity_when_zero [epsilon];
    'B' [van_der_pol_b_s, van_der_pol_b_p(opt)] identity_when_zero [];
    'C' [lienard_c_q, lienard_c_p(opt)] identity_when_zero [];
}

pub const VAN_DER_POL: ModelSpec = ModelSpec {
    name: "van_der_pol",
    summary: "q'' - epsilon (1 - q^2) q' + q = forcing_amplitude cos(forcing_frequency t)",
    vars: &["q", "s", "p"],
    optional_var: Some("p"),
    params: &[
        ParamDef::zero("epsilon", "nonlinearity ε"),
        ParamDef::zero(
            "forcing_amplitude",
            "forcing amplitude A (forcing A cos ωt)",
        ),
        ParamDef::zero("forcing_frequency", "forcing frequency ω"),
    ],
    pieces: "ABC",
    default_order: "CBABC",
    time: TimeDependence::WhenNonzero(&["forcing_amplitude"]),
    time_ops: VAN_DER_POL_TIME,
    piece_ops: VAN_DER_POL_PIECES,
    field_ops: &[("van_der_pol_field", false), ("van_der_pol_field_p", true)],
    methods: &[
        (Method::Rk4, "van_der_pol_rk4"),
        (Method::Leapfrog, "van_der_pol_leapfrog"),
    ],
    wgsl: &[
        LIENARD_MODEL_FLOWS_WGSL,
        LIENARD_WGSL,
        VAN_DER_POL_METHODS_WGSL,
    ],
    forcing_frequency: Some("forcing_frequency"),
    derived: &[],
    initial_defaults: &[],
    initial_alias: None,
    methods_carry_optional: false,
    rules: super::spec::no_rules,
};

crate::pieces! {
    LIENARD_PIECES, LIENARD_TIME, LienardPieces;
    ops [LienardOps in lienard_lanes];
    vars [q, s, p];
    time [];
    'A' [lienard_a_p(opt), lienard_a_s] identity_when_zero [f0, f1, f2, f3, f4, f5, f6, f7, f8, f9];
    'B' [lienard_b_s, lienard_b_p(opt)] identity_when_zero [];
    'C' [lienard_c_q, lienard_c_p(opt)] identity_when_zero [];
}

pub const LIENARD: ModelSpec = ModelSpec {
    name: "lienard",
    summary: "q'' + f(q) q' + g(q) = 0, f and g polynomials given by ascending coefficients",
    vars: &["q", "s", "p"],
    optional_var: Some("p"),
    params: &[],
    pieces: "ABC",
    default_order: "CBABC",
    time: TimeDependence::Never,
    time_ops: LIENARD_TIME,
    piece_ops: LIENARD_PIECES,
    field_ops: &[("lienard_field", false), ("lienard_field_p", true)],
    methods: &[
        (Method::Rk4, "lienard_rk4"),
        (Method::Leapfrog, "lienard_leapfrog"),
    ],
    wgsl: &[LIENARD_MODEL_FLOWS_WGSL, LIENARD_WGSL, LIENARD_METHODS_WGSL],
    forcing_frequency: None,
    derived: &[],
    initial_defaults: &[],
    initial_alias: None,
    methods_carry_optional: false,
    rules: super::spec::no_rules,
};
