//! One step of a plan: the ops that make it (time terms, sub-steps, calls of
//! the model's shared functions) from the scheme, and for splitting schemes
//! the same step as S2 stages for the CPU's fused kernels.

use crate::models::spec::ModelSpec;
pub use crate::models::spec::Op;

use super::problem::{err, PlanError};
use super::scheme::{parse_order, SchemeKind};

/// A splitting step as stages `S2(w_k τ)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Stages {
    /// Piece order outermost first (P1, P2, P3).
    pub order: [char; 3],
    /// Per stage: weight w and time offset c (midpoint, in steps).
    pub stages: Vec<(f64, f64)>,
    /// Is the optional variable integrated?
    pub with_optional: bool,
}

/// The ops of one step of `scheme` (and its stages, for a splitting), given
/// the piece order, whether time and the optional variable are integrated,
/// and which parameters are zero for every trajectory.
pub fn step_ops(
    spec: &ModelSpec,
    scheme: &SchemeKind,
    order: Option<&str>,
    time: bool,
    with_optional: bool,
    is_zero: &dyn Fn(&str) -> bool,
) -> Result<(Vec<Op>, Option<Stages>), PlanError> {
    match scheme {
        SchemeKind::Splitting { weights } => {
            let order = order.unwrap_or(spec.default_order);
            let half = parse_order(order, spec.pieces).map_err(|m| err("integrator.order", m))?;
            let stages = match half[..] {
                [a, b, c] => Some(Stages {
                    order: [a, b, c],
                    stages: stage_offsets(weights),
                    with_optional,
                }),
                _ => None,
            };
            let ops = splitting_ops(spec, weights, &half, time, with_optional, is_zero);
            Ok((ops, stages))
        }
        SchemeKind::Method(m) if order.is_some() => Err(err(
            "integrator.order",
            format!(
                "`{}` has no piece order; only the splitting schemes (s2 and its compositions) take one",
                m.name()
            ),
        )),
        SchemeKind::Method(m) => {
            let op = spec.method_op(*m).ok_or_else(|| {
                err(
                    "integrator.scheme",
                    format!(
                        "model `{}` has no `{}` integrator; it has: {}",
                        spec.name,
                        m.name(),
                        spec.methods
                            .iter()
                            .map(|(m, _)| m.name())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                )
            })?;
            // Methods evaluate time terms themselves, from the step's start.
            let mut ops = if time { vec![Op::Time(0.0)] } else { vec![] };
            ops.extend([Op::Tau(1.0), Op::Call(op)]);
            Ok((ops, None))
        }
    }
}

/// Per stage of weight w: (w, time offset of its midpoint in steps).
fn stage_offsets(weights: &[f64]) -> Vec<(f64, f64)> {
    let mut cum = 0.0;
    weights
        .iter()
        .map(|w| {
            let s = (*w, cum + 0.5 * w);
            cum += w;
            s
        })
        .collect()
}

/// Ops of one step of the composition `S2(w_1 τ) … S2(w_k τ)`:
/// per stage, the time terms at the stage midpoint (D is outermost, SPEC §1.1)
/// and the pieces `P1(w/2) … Pm(w) … P1(w/2)`. Pieces that are the identity
/// for this problem are dropped, and for autonomous problems equal neighbours
/// across stages are merged (`P1(a) P1(b) = P1(a + b)`, exact flows).
fn splitting_ops(
    spec: &ModelSpec,
    weights: &[f64],
    half: &[char],
    time: bool,
    with_optional: bool,
    is_zero: &dyn Fn(&str) -> bool,
) -> Vec<Op> {
    enum Item {
        Time(f64),
        Piece(char, f64),
    }
    // A piece is dropped when its parameters are all zero, or when it has
    // no op on the variables integrated (a formula model without damping).
    let identity = |piece: char| {
        spec.piece(piece).is_some_and(|p| {
            let switched_off =
                !p.identity_when_zero.is_empty() && p.identity_when_zero.iter().all(|n| is_zero(n));
            let nothing = !p.ops.iter().any(|(_, opt)| with_optional || !opt);
            switched_off || nothing
        })
    };
    let mut items: Vec<Item> = vec![];
    let mut cum = 0.0;
    for &w in weights {
        if time {
            items.push(Item::Time(cum + 0.5 * w));
        }
        let m = half.len();
        let seq = half
            .iter()
            .enumerate()
            .map(|(k, &c)| (c, if k + 1 == m { w } else { 0.5 * w }));
        let back = half[..m - 1].iter().rev().map(|&c| (c, 0.5 * w));
        for (c, coef) in seq.chain(back) {
            if identity(c) {
                continue;
            }
            match items.last_mut() {
                Some(Item::Piece(prev, a)) if *prev == c => *a += coef,
                _ => items.push(Item::Piece(c, coef)),
            }
        }
        cum += w;
    }
    let mut ops = vec![];
    for item in items {
        match item {
            Item::Time(c) => {
                ops.push(Op::Time(c));
                ops.extend(spec.time_ops.iter().map(|o| Op::Call(o)));
            }
            Item::Piece(c, coef) => {
                ops.push(Op::Tau(coef));
                let piece = spec.piece(c).expect("parse_order checked the letters");
                ops.extend(
                    piece
                        .ops
                        .iter()
                        .filter(|(_, opt)| with_optional || !opt)
                        .map(|(o, _)| Op::Call(o)),
                );
            }
        }
    }
    ops
}
