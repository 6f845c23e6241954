//! Dissipative spin–orbit problem with a time-varying moment of inertia,
//! SPEC §2.1: `θ'' + ε pref Σ W_m(e) sin(2θ − m t) = −K(θ' − η) + λΩ sin(Ωt) pref θ'`
//! with `pref(t) = 1/(1 + λ cos Ωt)`.
//!
//! The sum over the Cayley table is evaluated as
//! `Σ W_m sin(2q − mt) = sin 2q · C(t) − cos 2q · S(t)` with
//! `C = Σ_{m≥1} a_m cos mt`, `S = Σ_{m≥1} b_m sin mt`, `a_m = W_m + W_{−m}`,
//! `b_m = W_m − W_{−m}`: the t-dependent sums are time terms (once per stage),
//! cos mt and sin mt come from one sincos by the Chebyshev recurrence, and a
//! B piece costs one sincos of 2q instead of fourteen.

#[allow(unused_imports)]
use super::mechanical::{Mechanical1dOps, MechanicalFlows};
#[allow(unused_imports)]
use crate::num::{math::Math, prims::Prims};

use super::spec::Method;
use super::spec::{each_in, Derived, ModelSpec, ParamDef, RuleError, TimeDependence};

/// Cayley coefficients of `(a/r)³ cos(2θ − 2f)` to e⁷ (SPEC §2.1):
/// `(m, [(k, c)])` with `W_m(e) = Σ c e^k`.
pub const CAYLEY: &[(i32, &[(i32, f64)])] = &[
    (-5, &[(7, 15625.0 / 129024.0)]),
    (-4, &[(6, 4.0 / 45.0)]),
    (-3, &[(5, 81.0 / 1280.0), (7, 81.0 / 2048.0)]),
    (-2, &[(4, 1.0 / 24.0), (6, 7.0 / 240.0)]),
    (
        -1,
        &[(3, 1.0 / 48.0), (5, 11.0 / 768.0), (7, 313.0 / 30720.0)],
    ),
    (
        1,
        &[
            (1, -1.0 / 2.0),
            (3, 1.0 / 16.0),
            (5, -5.0 / 384.0),
            (7, -143.0 / 18432.0),
        ],
    ),
    (
        2,
        &[
            (0, 1.0),
            (2, -5.0 / 2.0),
            (4, 13.0 / 16.0),
            (6, -35.0 / 288.0),
        ],
    ),
    (
        3,
        &[
            (1, 7.0 / 2.0),
            (3, -123.0 / 16.0),
            (5, 489.0 / 128.0),
            (7, -1763.0 / 2048.0),
        ],
    ),
    (4, &[(2, 17.0 / 2.0), (4, -115.0 / 6.0), (6, 601.0 / 48.0)]),
    (
        5,
        &[
            (3, 845.0 / 48.0),
            (5, -32525.0 / 768.0),
            (7, 208225.0 / 6144.0),
        ],
    ),
    (6, &[(4, 533.0 / 16.0), (6, -13827.0 / 160.0)]),
    (7, &[(5, 228347.0 / 3840.0), (7, -3071075.0 / 18432.0)]),
    (8, &[(6, 73369.0 / 720.0)]),
    (9, &[(7, 12144273.0 / 71680.0)]),
];

/// `W_m(e)` from the Cayley table (0 for m outside it).
pub fn cayley_w(m: i32, e: f64) -> f64 {
    CAYLEY
        .iter()
        .find(|(mm, _)| *mm == m)
        .map(|(_, terms)| terms.iter().map(|(k, c)| c * e.powi(*k)).sum())
        .unwrap_or(0.0)
}

/// `a_m = W_m + W_{−m}` (cosine weights of the time sums), m = 1..9.
pub fn weight_a(m: i32, e: f64) -> f64 {
    cayley_w(m, e) + cayley_w(-m, e)
}

/// `b_m = W_m − W_{−m}` (sine weights of the time sums), m = 1..9.
pub fn weight_b(m: i32, e: f64) -> f64 {
    cayley_w(m, e) - cayley_w(-m, e)
}

crate::shared_fns! {
    /// Model functions used by the ops (not ops themselves).
    trait SpinOrbitFlows, wgsl SPIN_ORBIT_FLOWS_WGSL;

    /// `V'(q,t)`, `V(q,t)` and `f(t)` for the comparison integrators.
    fn spin_orbit_mech(q: R, t: R, a1: R, a2: R, a3: R, a4: R, a5: R, a6: R, a7: R, a8: R, a9: R,
                       b1: R, b2: R, b3: R, b4: R, b5: R, b6: R, b7: R, b8: R, b9: R,
                       epsilon: R, lambda: R, omega: R, tidal_k: R, tidal_eta: R,
                       dv: &mut R, v: &mut R, f: &mut R) {
        let mut pref: R = 0.0;
        let mut cw: R = 0.0;
        let mut sw: R = 0.0;
        R::spin_orbit_time(t, a1, a2, a3, a4, a5, a6, a7, a8, a9, b1, b2, b3, b4, b5, b6, b7, b8, b9,
                           lambda, omega, tidal_k, &mut pref, f, &mut cw, &mut sw);
        let mut s2q: R = 0.0;
        let mut c2q: R = 0.0;
        R::sincos_r(2.0 * q, &mut s2q, &mut c2q);
        *dv = epsilon * pref * (s2q * cw - c2q * sw) - tidal_k * tidal_eta;
        *v = -0.5 * epsilon * pref * (c2q * cw + s2q * sw) - tidal_k * tidal_eta * q;
    }
}

crate::model_ops! {
    /// Pieces and time terms of the spin–orbit model.
    trait SpinOrbitOps, wgsl SPIN_ORBIT_WGSL, lanes spin_orbit_lanes;

    /// Time terms at t: `pref`, the damping `f(t) = K − λΩ sin(Ωt) pref`, and
    /// the sums `cw = Σ a_m cos mt`, `sw = Σ b_m sin mt`.
    fn spin_orbit_time(t: R, a1: R, a2: R, a3: R, a4: R, a5: R, a6: R, a7: R, a8: R, a9: R,
                       b1: R, b2: R, b3: R, b4: R, b5: R, b6: R, b7: R, b8: R, b9: R,
                       lambda: R, omega: R, tidal_k: R,
                       pref: &mut R, damping: &mut R, cw: &mut R, sw: &mut R) {
        let mut s1: R = 0.0;
        let mut c1: R = 0.0;
        R::sincos_r(t, &mut s1, &mut c1);
        let tc: R = 2.0 * c1;
        let c2: R = tc * c1 - 1.0;
        let s2: R = tc * s1;
        let c3: R = tc * c2 - c1;
        let s3: R = tc * s2 - s1;
        let c4: R = tc * c3 - c2;
        let s4: R = tc * s3 - s2;
        let c5: R = tc * c4 - c3;
        let s5: R = tc * s4 - s3;
        let c6: R = tc * c5 - c4;
        let s6: R = tc * s5 - s4;
        let c7: R = tc * c6 - c5;
        let s7: R = tc * s6 - s5;
        let c8: R = tc * c7 - c6;
        let s8: R = tc * s7 - s6;
        let c9: R = tc * c8 - c7;
        let s9: R = tc * s8 - s7;
        *cw = a1 * c1 + a2 * c2 + a3 * c3 + a4 * c4 + a5 * c5 + a6 * c6 + a7 * c7 + a8 * c8 + a9 * c9;
        *sw = b1 * s1 + b2 * s2 + b3 * s3 + b4 * s4 + b5 * s5 + b6 * s6 + b7 * s7 + b8 * s8 + b9 * s9;
        let mut so: R = 0.0;
        let mut co: R = 0.0;
        R::sincos_r(omega * t, &mut so, &mut co);
        *pref = 1.0 / (1.0 + lambda * co);
        *damping = tidal_k - lambda * omega * so * *pref;
    }
    /// Piece B on p: `p ← p − τ V'`, `V' = ε pref (sin 2q · cw − cos 2q · sw) − K η`.
    fn spin_orbit_b_p(q: R, p: &mut R, tau: R, epsilon: R, tidal_k: R, tidal_eta: R,
                      pref: R, cw: R, sw: R) {
        let mut s2q: R = 0.0;
        let mut c2q: R = 0.0;
        R::sincos_r(2.0 * q, &mut s2q, &mut c2q);
        *p = R::mech_kick(*p, tau, epsilon * pref * (s2q * cw - c2q * sw) - tidal_k * tidal_eta);
    }
    /// Piece B on s: `s ← s − τ V`, `V = −(ε/2) pref (cos 2q · cw + sin 2q · sw) − K η q`.
    fn spin_orbit_b_s(q: R, s: &mut R, tau: R, epsilon: R, tidal_k: R, tidal_eta: R,
                      pref: R, cw: R, sw: R) {
        let mut s2q: R = 0.0;
        let mut c2q: R = 0.0;
        R::sincos_r(2.0 * q, &mut s2q, &mut c2q);
        *s = R::mech_kick(*s, tau, -0.5 * epsilon * pref * (c2q * cw + s2q * sw) - tidal_k * tidal_eta * q);
    }
}

crate::mechanical_1d_methods! {
    ops trait SpinOrbitMethods, wgsl SPIN_ORBIT_METHODS_WGSL, lanes spin_orbit_method_lanes;
    mech spin_orbit_mech, field spin_orbit_field, rk4 spin_orbit_rk4,
    leapfrog spin_orbit_leapfrog, variational1 spin_orbit_variational1,
    variational2 spin_orbit_variational2;
    params [a1, a2, a3, a4, a5, a6, a7, a8, a9, b1, b2, b3, b4, b5, b6, b7, b8, b9,
            epsilon, lambda, omega, tidal_k, tidal_eta]
}

crate::model_lanes! {
    traits [SpinOrbitFlows, SpinOrbitOps, SpinOrbitMethods, MechanicalFlows, Mechanical1dOps];
    lanes [spin_orbit_lanes, spin_orbit_method_lanes, super::mechanical::mechanical_1d_lanes];
}

crate::pieces! {
    SPIN_ORBIT_PIECES, SPIN_ORBIT_TIME, SpinOrbitPieces;
    ops [SpinOrbitOps in spin_orbit_lanes, Mechanical1dOps in super::mechanical::mechanical_1d_lanes];
    vars [q, p, s];
    time [spin_orbit_time];
    'A' [mech1_a_p, mech1_a_s(opt)] identity_when_zero [lambda, tidal_k];
    'B' [spin_orbit_b_p, spin_orbit_b_s(opt)] identity_when_zero [];
    'C' [mech1_c_q, mech1_c_s(opt)] identity_when_zero [];
}

/// The Fourier weights of the Cayley sums, from the eccentricity.
#[rustfmt::skip]
const WEIGHTS: &[Derived] = &[
    Derived { name: "a1", from: Some(("eccentricity", |e| weight_a(1, e))), value: 0.0 },
    Derived { name: "b1", from: Some(("eccentricity", |e| weight_b(1, e))), value: 0.0 },
    Derived { name: "a2", from: Some(("eccentricity", |e| weight_a(2, e))), value: 0.0 },
    Derived { name: "b2", from: Some(("eccentricity", |e| weight_b(2, e))), value: 0.0 },
    Derived { name: "a3", from: Some(("eccentricity", |e| weight_a(3, e))), value: 0.0 },
    Derived { name: "b3", from: Some(("eccentricity", |e| weight_b(3, e))), value: 0.0 },
    Derived { name: "a4", from: Some(("eccentricity", |e| weight_a(4, e))), value: 0.0 },
    Derived { name: "b4", from: Some(("eccentricity", |e| weight_b(4, e))), value: 0.0 },
    Derived { name: "a5", from: Some(("eccentricity", |e| weight_a(5, e))), value: 0.0 },
    Derived { name: "b5", from: Some(("eccentricity", |e| weight_b(5, e))), value: 0.0 },
    Derived { name: "a6", from: Some(("eccentricity", |e| weight_a(6, e))), value: 0.0 },
    Derived { name: "b6", from: Some(("eccentricity", |e| weight_b(6, e))), value: 0.0 },
    Derived { name: "a7", from: Some(("eccentricity", |e| weight_a(7, e))), value: 0.0 },
    Derived { name: "b7", from: Some(("eccentricity", |e| weight_b(7, e))), value: 0.0 },
    Derived { name: "a8", from: Some(("eccentricity", |e| weight_a(8, e))), value: 0.0 },
    Derived { name: "b8", from: Some(("eccentricity", |e| weight_b(8, e))), value: 0.0 },
    Derived { name: "a9", from: Some(("eccentricity", |e| weight_a(9, e))), value: 0.0 },
    Derived { name: "b9", from: Some(("eccentricity", |e| weight_b(9, e))), value: 0.0 },
];

/// The eccentricity lies in [0, 1).
fn rules(values: &dyn Fn(&str) -> Vec<f64>, _time: bool) -> Result<(), RuleError> {
    each_in(
        values,
        "params.eccentricity",
        |e| (0.0..1.0).contains(&e),
        |e| format!("{e} is not in [0, 1)"),
    )
}

pub const SPEC: ModelSpec = ModelSpec {
    name: "spin_orbit",
    summary: "theta'' + epsilon pref sum W_m(e) sin(2 theta - m t) = -tidal_k (theta' - tidal_eta) + lambda omega sin(omega t) pref theta'",
    vars: &["q", "p", "s"],
    optional_var: Some("s"),
    params: &[
        ParamDef::zero("eccentricity", "orbital eccentricity e (Cayley series to e^7)"),
        ParamDef::zero("epsilon", "asphericity ε = 3(B−A)/(2C)"),
        ParamDef::zero("lambda", "amplitude λ of the inertia modulation"),
        ParamDef::zero("omega", "frequency Ω of the inertia modulation"),
        ParamDef::zero("tidal_k", "tidal dissipation coefficient K"),
        ParamDef::zero("tidal_eta", "tidal equilibrium spin rate η"),
    ],
    pieces: "ABC",
    default_order: "CBABC",
    time: TimeDependence::Always,
    time_ops: SPIN_ORBIT_TIME,
    piece_ops: SPIN_ORBIT_PIECES,
    field_ops: &[("spin_orbit_field", false)],
    methods: &[
        (Method::Rk4, "spin_orbit_rk4"),
        (Method::Leapfrog, "spin_orbit_leapfrog"),
        (Method::Variational1, "spin_orbit_variational1"),
        (Method::Variational2, "spin_orbit_variational2"),
    ],
    wgsl: &[SPIN_ORBIT_FLOWS_WGSL, SPIN_ORBIT_WGSL, SPIN_ORBIT_METHODS_WGSL],
    forcing_frequency: Some(""),
    derived: WEIGHTS,
    initial_defaults: &[],
    initial_alias: None,
    methods_carry_optional: true,
    rules,
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn circular_orbit_keeps_only_m2() {
        assert_eq!(weight_a(2, 0.0), 1.0);
        assert_eq!(weight_b(2, 0.0), 1.0);
        for m in [1, 3, 4, 5, 6, 7, 8, 9] {
            assert_eq!(weight_a(m, 0.0), 0.0);
        }
    }
}
