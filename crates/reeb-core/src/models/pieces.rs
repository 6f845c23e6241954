//! A model's pieces, declared once by [`pieces!`]: the data the plan and the
//! GPU code generator read (which ops apply each piece, in order), and a
//! [`Pieces`] implementation that applies them to one trajectory, from which
//! the CPU backend builds its fused S2 stages (`backend/cpu/kernels.rs`).

use super::lanes::{Lane, Lanes, LANES};
use crate::num::precision::Real;

/// Most state variables a model with pieces has (Kepler's q₁, q₂, p₁, p₂, s).
pub const MAX_VARS: usize = 5;

/// A block's state variables, in the model's order (the start of a run of
/// steps, to which a run that left the finite numbers returns).
pub type Saved<R> = [[R; LANES]; MAX_VARS];

/// Applies a model's pieces and time terms to one trajectory in precision `R`.
pub trait Pieces<R: Real> {
    /// How many state variables the model has.
    const VARS: usize;
    /// The time terms at `x.t`.
    fn time(x: &mut Lane<R>);
    /// Takes the time terms, their inputs, `t`, `t0` and `dt` from `from`
    /// (time terms the ensemble shares, evaluated once).
    fn share_time(x: &mut Lane<R>, from: &Lane<R>);
    /// Piece `piece` over `x.tau`; `OPT`: also on the optional variable.
    fn piece<const OPT: bool>(piece: char, x: &mut Lane<R>);
    /// Piece `piece` over `x.tau` carrying the deviations `d` along: each
    /// op's tangent (`tangent_ops.rs`, generated from the op's text) moves
    /// `d` at the lanes before the op, then the op moves `x`. The optional
    /// variable is left out: it never feeds back.
    fn piece_tangent<const K: usize>(piece: char, x: &mut Lane<R>, d: &mut [Lane<R>; K]);
    /// Writes the model's state variables of `x` into lane `i` of `l`.
    fn scatter(x: &Lane<R>, l: &mut Lanes<R>, i: usize);
    /// Are the model's state variables finite?
    fn finite(x: &Lane<R>) -> bool;
    /// Copies the block's state variables into `to`.
    fn save(l: &Lanes<R>, to: &mut Saved<R>);
    /// Puts back the state variables [`Pieces::save`] copied.
    fn restore(l: &mut Lanes<R>, from: &Saved<R>);
}

/// Something done with a model's [`Pieces`] type, e.g. building its CPU
/// kernels; see `Model::with_pieces`.
pub trait PiecesVisitor<R: Real> {
    type Out;
    fn visit<P: Pieces<R>>(self) -> Self::Out;
}

/// Declares a model's pieces: `pieces! { PIECES_CONST, TIME_CONST, Type;
/// ops [OpsTrait in lane_module, …]; vars [..]; time [ops];
/// 'A' [op, op(opt)] identity_when_zero [params]; … }` defines the
/// `PieceOps` table, the time-op list and `Type: Pieces<R>` for every `R`
/// with the ops traits.
#[macro_export]
macro_rules! pieces {
    (
        $pieces:ident, $time:ident, $ty:ident;
        ops [$($optr:ident in $($opmod:ident)::+),* $(,)?];
        vars [$($var:ident),* $(,)?];
        time [$($top:ident),* $(,)?];
        $( $letter:literal [$($op:ident $(($opt:ident))?),* $(,)?] identity_when_zero [$($zero:ident),* $(,)?]; )*
    ) => {
        /// Ops that evaluate the time terms.
        pub const $time: &[&str] = &[$(stringify!($top)),*];
        /// Ops of each piece, in order (`true`: on the optional variable).
        pub const $pieces: &[$crate::models::spec::PieceOps] = &[
            $( $crate::models::spec::PieceOps {
                piece: $letter,
                ops: &[$( (stringify!($op), false $(|| { let _ = stringify!($opt); true })?) ),*],
                identity_when_zero: &[$(stringify!($zero)),*],
            }, )*
        ];
        /// The pieces applied to one trajectory (for the fused CPU kernels).
        pub struct $ty;
        impl<R: $crate::num::precision::Real $(+ $optr)*> $crate::models::pieces::Pieces<R> for $ty {
            const VARS: usize = [$(stringify!($var)),*].len();
            #[inline(always)]
            fn time(x: &mut $crate::models::lanes::Lane<R>) {
                $( #[allow(unused_imports)] use $($opmod)::+::scalar::*; )*
                $( $top(x); )*
                let _ = x;
            }
            #[inline(always)]
            fn share_time(x: &mut $crate::models::lanes::Lane<R>, from: &$crate::models::lanes::Lane<R>) {
                $( #[allow(unused_imports)] use $($opmod)::+::share::*; )*
                $( $top(x, from); )*
                x.t = from.t;
                x.t0 = from.t0;
                x.dt = from.dt;
            }
            #[inline(always)]
            fn piece<const OPT: bool>(piece: char, x: &mut $crate::models::lanes::Lane<R>) {
                $( #[allow(unused_imports)] use $($opmod)::+::scalar::*; )*
                match piece {
                    $( $letter => {
                        $(
                            let optional = false $(|| { let _ = stringify!($opt); true })?;
                            if !optional || OPT {
                                $op(x);
                            }
                        )*
                    } )*
                    _ => {}
                }
            }
            #[inline(always)]
            fn piece_tangent<const K: usize>(
                piece: char,
                x: &mut $crate::models::lanes::Lane<R>,
                d: &mut [$crate::models::lanes::Lane<R>; K],
            ) {
                $( #[allow(unused_imports)] use $($opmod)::+::scalar::*; )*
                match piece {
                    $( $letter => {
                        $(
                            let optional = false $(|| { let _ = stringify!($opt); true })?;
                            if !optional {
                                for dk in d.iter_mut() {
                                    $crate::models::tangent_ops::$op(x, dk);
                                }
                                $op(x);
                            }
                        )*
                    } )*
                    _ => {}
                }
            }
            #[inline(always)]
            fn scatter(x: &$crate::models::lanes::Lane<R>, l: &mut $crate::models::lanes::Lanes<R>, i: usize) {
                $( l.$var[i] = x.$var; )*
            }
            #[inline(always)]
            fn finite(x: &$crate::models::lanes::Lane<R>) -> bool {
                // v·0 is ±0 for finite v and NaN for ±∞ and NaN: one sum and
                // one compare for all variables, where a test per variable
                // costs a mask each (and `&&` a conditional load).
                let zero = R::from_f64(0.0);
                zero $(+ x.$var * zero)* == zero
            }
            #[inline(always)]
            fn save(l: &$crate::models::lanes::Lanes<R>, to: &mut $crate::models::pieces::Saved<R>) {
                const { assert!(<Self as $crate::models::pieces::Pieces<R>>::VARS <= $crate::models::pieces::MAX_VARS) };
                let mut k = 0;
                $( to[k] = l.$var; k += 1; )*
                let _ = k;
            }
            #[inline(always)]
            fn restore(l: &mut $crate::models::lanes::Lanes<R>, from: &$crate::models::pieces::Saved<R>) {
                let mut k = 0;
                $( l.$var = from[k]; k += 1; )*
                let _ = k;
            }
        }
    };
}
