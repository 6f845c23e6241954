//! Lane–Emden equation of index k, SPEC §2.1: `q'' + (2/t) q' + q^k = 0` as
//! `H = p²/2 + q^{k+1}/(k+1) + (2/t) s`, from t0 = 0 with q = 1, p = 0.
//! The outermost `D½` of S2 means `f = 2/t` is first read at t = τ/2.

#[allow(unused_imports)]
use super::mechanical::{Mechanical1dOps, MechanicalFlows};
#[allow(unused_imports)]
use crate::num::{math::Math, prims::Prims};

use super::spec::Method;
use super::spec::{each_in, ModelSpec, ParamDef, RuleError, TimeDependence};

/// Largest index `powi_small` handles.
pub const MAX_INDEX: f64 = 15.0;

crate::shared_fns! {
    /// Model functions used by the ops (not ops themselves).
    trait LaneEmdenMechFlows, wgsl LANE_EMDEN_MECH_WGSL;

    /// `V'(q)`, `V(q)` and `f(t)` for the comparison integrators.
    fn lane_emden_mech(q: R, t: R, index: R, dv: &mut R, v: &mut R, f: &mut R) {
        let qk: R = R::powi_small(q, index);
        *dv = qk;
        *v = qk * q / (index + 1.0);
        R::lane_emden_time(t, f);
    }
}

crate::shared_fns! {
    /// Helpers of the Lane–Emden model.
    trait LaneEmdenFlows, wgsl LANE_EMDEN_FLOWS_WGSL;

    /// x^n for an integer 0 ≤ n ≤ 15 given as a float, branch-free (binary powering).
    fn powi_small(x: R, n: R) -> R {
        let k: i32 = R::to_i32(n + 0.5);
        let mut acc: R = 1.0;
        let mut b: R = x;
        acc = R::select(acc, acc * b, (k & 1) == 1);
        b = b * b;
        acc = R::select(acc, acc * b, (k & 2) == 2);
        b = b * b;
        acc = R::select(acc, acc * b, (k & 4) == 4);
        b = b * b;
        acc = R::select(acc, acc * b, (k & 8) == 8);
        return acc;
    }
    /// A damping term f·x = (2/t)·x at t = 0 by its limit on the regular
    /// solution: x/t → x'(0) = −g/3 where x' = −g − (2/t)x (g = V' for x = p,
    /// g = V for x = s), so the vector field is finite at t = 0.
    fn lane_emden_regular(fp: R, dv: R, t: R) -> R {
        return R::select(fp, -0.6666666666666666 * dv, t == 0.0);
    }
}

crate::model_ops! {
    /// Pieces and time terms of the Lane–Emden model.
    trait LaneEmdenOps, wgsl LANE_EMDEN_WGSL, lanes lane_emden_lanes;

    /// Time term: the damping `f(t) = 2/t`.
    fn lane_emden_time(t: R, damping: &mut R) {
        *damping = 2.0 / t;
    }
    /// Piece B (V = q^{k+1}/(k+1)) on p.
    fn lane_emden_b_p(q: R, p: &mut R, tau: R, index: R) {
        *p = R::mech_kick(*p, tau, R::powi_small(q, index));
    }
    /// Piece B (V = q^{k+1}/(k+1)) on s.
    fn lane_emden_b_s(q: R, s: &mut R, tau: R, index: R) {
        *s = R::mech_kick(*s, tau, R::powi_small(q, index) * q / (index + 1.0));
    }
}

crate::mechanical_1d_methods! {
    ops trait LaneEmdenMethods, wgsl LANE_EMDEN_METHODS_WGSL, lanes lane_emden_method_lanes;
    mech lane_emden_mech, field lane_emden_field, rk4 lane_emden_rk4,
    leapfrog lane_emden_leapfrog, variational1 lane_emden_variational1,
    variational2 lane_emden_variational2, regular_at_zero lane_emden_regular;
    params [index]
}

/// Exact solutions (SPEC §2.1) for k = 0, 1, 5 from q(0) = 1, q'(0) = 0:
/// returns (q, q') at t, or `None` for other indices.
pub fn exact(index: u32, t: f64) -> Option<(f64, f64)> {
    match index {
        0 => Some((1.0 - t * t / 6.0, -t / 3.0)),
        1 => {
            if t.abs() < 1e-4 {
                Some((
                    1.0 - t * t / 6.0 + t.powi(4) / 120.0,
                    -t / 3.0 + t.powi(3) / 30.0,
                ))
            } else {
                Some((t.sin() / t, (t * t.cos() - t.sin()) / (t * t)))
            }
        }
        5 => {
            let u = 1.0 + t * t / 3.0;
            Some((u.powf(-0.5), -(t / 3.0) * u.powf(-1.5)))
        }
        _ => None,
    }
}

crate::model_lanes! {
    traits [LaneEmdenFlows, LaneEmdenMechFlows, LaneEmdenOps, LaneEmdenMethods, MechanicalFlows, Mechanical1dOps];
    lanes [lane_emden_lanes, lane_emden_method_lanes, super::mechanical::mechanical_1d_lanes];
}

crate::pieces! {
    LANE_EMDEN_PIECES, LANE_EMDEN_TIME, LaneEmdenPieces;
    ops [LaneEmdenOps in lane_emden_lanes, Mechanical1dOps in super::mechanical::mechanical_1d_lanes];
    vars [q, p, s];
    time [lane_emden_time];
    'A' [mech1_a_p, mech1_a_s(opt)] identity_when_zero [];
    'B' [lane_emden_b_p, lane_emden_b_s(opt)] identity_when_zero [];
    'C' [mech1_c_q, mech1_c_s(opt)] identity_when_zero [];
}

/// The index is an integer in 0..=15; with time (f = 2/t), t0 ≥ 0.
fn rules(values: &dyn Fn(&str) -> Vec<f64>, time: bool) -> Result<(), RuleError> {
    each_in(
        values,
        "params.index",
        |k| k.fract() == 0.0 && (0.0..=MAX_INDEX).contains(&k),
        |k| format!("{k} is not an integer in 0..=15"),
    )?;
    if time {
        each_in(
            values,
            "initial.t0",
            |t| t >= 0.0,
            |_| "Lane–Emden starts at t0 ≥ 0 (f = 2/t)".into(),
        )?;
    }
    Ok(())
}

pub const SPEC: ModelSpec = ModelSpec {
    name: "lane_emden",
    summary: "q'' + (2/t) q' + q^index = 0, from t0 = 0, q = 1, p = 0",
    vars: &["q", "p", "s"],
    optional_var: Some("s"),
    params: &[ParamDef::required(
        "index",
        "polytropic index k, an integer 0..15",
    )],
    pieces: "ABC",
    default_order: "CBABC",
    time: TimeDependence::Always,
    time_ops: LANE_EMDEN_TIME,
    piece_ops: LANE_EMDEN_PIECES,
    field_ops: &[("lane_emden_field", false)],
    methods: &[
        (Method::Rk4, "lane_emden_rk4"),
        (Method::Leapfrog, "lane_emden_leapfrog"),
        (Method::Variational1, "lane_emden_variational1"),
        (Method::Variational2, "lane_emden_variational2"),
    ],
    wgsl: &[
        LANE_EMDEN_FLOWS_WGSL,
        LANE_EMDEN_MECH_WGSL,
        LANE_EMDEN_WGSL,
        LANE_EMDEN_METHODS_WGSL,
    ],
    forcing_frequency: None,
    derived: &[],
    initial_defaults: &[("q", 1.0)],
    initial_alias: None,
    methods_carry_optional: true,
    rules,
};
