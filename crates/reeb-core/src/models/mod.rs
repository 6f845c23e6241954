//! The models of SPEC §2: each a contact Hamiltonian split into pieces with
//! exact flows, written once as shared functions (see [`crate::num::dsl`]),
//! one file per model. This file is the registry: the one list of models,
//! from which the [`Model`] enum, the lookups by name and [`Flows`] follow.
//!
//! Adding a model: write `models/<name>.rs` after the pattern of
//! `damped_oscillator.rs` (shared functions, `model_lanes!`, `pieces!`, a
//! `ModelSpec` with its rules), add `pub mod <name>;` and its line in
//! `registry!` below; new parameter names also become lane fields
//! (`lanes.rs`). See ARCHITECTURE.md.

pub mod damped_oscillator;
pub mod events;
pub mod exact;
pub mod formula;
pub mod kepler;
pub mod lane_emden;
pub mod lanes;
pub mod lienard;
pub mod mechanical;
pub mod pieces;
pub mod quadratic_s;
pub mod spec;
pub mod spin_orbit;
pub mod symbolic;
/// The generator of `tangent_ops.rs` (and the Rust it writes, which the
/// CPU backend's generator of its sample loops shares).
pub mod tangent_gen;
// Generated (`tangent_gen.rs`), checked against its generator by a test.
#[rustfmt::skip]
pub mod tangent_ops;

use lanes::{LaneFn, ScalarFn};
use pieces::PiecesVisitor;
use spec::{Derived, ModelSpec};

/// Shared-function texts every GPU kernel includes (models add their own).
pub const COMMON_WGSL: &[&str] = &[
    mechanical::MECHANICAL_FLOWS_WGSL,
    mechanical::MECHANICAL_1D_WGSL,
    lienard::LIENARD_FLOWS_WGSL,
    events::OBSERVE_WGSL,
];

/// The registry: `Variant = file: SPEC_CONST, PiecesType;`, one line a model.
macro_rules! registry {
    ($( $variant:ident $({ $($field:ident : $fty:ty),* })? = $file:ident : $spec:ident, $pieces:ident; )*) => {
        /// A model with its model-level data (the Liénard polynomials).
        #[derive(Debug, Clone, PartialEq)]
        pub enum Model {
            $( $variant $({ $($field: $fty),* })?, )*
            /// A model from the scene's formulas (`models/formula.rs`).
            Formula(&'static formula::FormulaModel),
        }

        /// Names accepted by [`Model::from_name`], in registry order.
        pub const MODEL_NAMES: &[&str] = &[$( $file::$spec.name ),*];

        /// A working precision with every model's shared functions (and the
        /// observers'), so that generic code calls `R::flow_name(..)`.
        pub trait Flows: crate::num::precision::Real + events::ObserveFlows $(+ $file::Ops)* {}
        impl<T: crate::num::precision::Real + events::ObserveFlows $(+ $file::Ops)*> Flows for T {}

        impl Model {
            /// The model of a scene's `model = "…"` (model-level data empty).
            pub fn from_name(name: &str) -> Option<Model> {
                $( if name == $file::$spec.name {
                    return Some(Model::$variant $({ $($field: Default::default()),* })?);
                } )*
                None
            }

            pub fn spec(&self) -> &'static ModelSpec {
                match self {
                    $( Model::$variant { .. } => &$file::$spec, )*
                    Model::Formula(m) => &m.spec,
                }
            }

            /// Runs `v` with this model's [`pieces::Pieces`] type (how the CPU
            /// backend builds its fused kernels without the models knowing it);
            /// `None` for formula models, which have no compiled pieces.
            pub fn with_pieces<R: Flows, V: PiecesVisitor<R>>(&self, v: V) -> Option<V::Out> {
                match self {
                    $( Model::$variant { .. } => Some(v.visit::<$file::$pieces>()), )*
                    Model::Formula(_) => None,
                }
            }
        }

        /// The lane loop of the op called `name`, from whichever model defines it.
        pub fn lane_fn<R: Flows>(name: &str) -> Option<LaneFn<R>> {
            None$(.or_else(|| $file::lane_fn::<R>(name)))*
        }
        /// The arguments of the op called `name`: lane names, and whether
        /// the op writes them.
        pub fn op_args(name: &str) -> Option<&'static [(&'static str, bool)]> {
            None$(.or_else(|| $file::op_args(name)))*
        }
        /// The scalar op called `name` (one trajectory).
        pub fn scalar_fn<R: Flows>(name: &str) -> Option<ScalarFn<R>> {
            None$(.or_else(|| $file::scalar_fn::<R>(name)))*
        }
    };
}

registry! {
    DampedOscillator = damped_oscillator: SPEC, DampedOscillatorPieces;
    VanDerPol = lienard: VAN_DER_POL, VanDerPolPieces;
    Lienard { f: Vec<f64>, g: Vec<f64> } = lienard: LIENARD, LienardPieces;
    Kepler = kepler: SPEC, KeplerPieces;
    LaneEmden = lane_emden: SPEC, LaneEmdenPieces;
    SpinOrbit = spin_orbit: SPEC, SpinOrbitPieces;
    QuadraticS = quadratic_s: SPEC, QuadraticSPieces;
}

impl Model {
    pub fn name(&self) -> &'static str {
        self.spec().name
    }

    /// The compiled formulas of a formula model.
    pub fn formula(&self) -> Option<&'static formula::FormulaModel> {
        match self {
            Model::Formula(m) => Some(m),
            _ => None,
        }
    }

    /// The lane field a scene parameter binds (formula parameters live in
    /// slots; a built-in model's parameters are lane fields by name).
    pub fn param_lane(&self, name: &'static str) -> &'static str {
        self.formula()
            .and_then(|m| m.param_lane(name))
            .unwrap_or(name)
    }

    /// The parameter whose value ω sets the forcing period 2π/ω (see
    /// [`ModelSpec::forcing_frequency`]).
    pub fn forcing_frequency_param(&self) -> Option<&'static str> {
        self.spec().forcing_frequency
    }

    /// Lane parameters derived from scene parameters or model data.
    pub fn derived(&self) -> Vec<Derived> {
        const F: [&str; 10] = ["f0", "f1", "f2", "f3", "f4", "f5", "f6", "f7", "f8", "f9"];
        const G: [&str; 10] = ["g0", "g1", "g2", "g3", "g4", "g5", "g6", "g7", "g8", "g9"];
        let mut out = self.spec().derived.to_vec();
        if let Model::Lienard { f, g } = self {
            let coef = |c: &[f64], k: usize| c.get(k).copied().unwrap_or(0.0);
            for k in 0..lienard::MAX_COEFFICIENTS {
                for (name, c) in [(F[k], f), (G[k], g)] {
                    out.push(Derived {
                        name,
                        from: None,
                        value: coef(c, k),
                    });
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::num::dsl::to_wgsl;

    /// Every op a model names has a lane loop, and every shared text translates.
    #[test]
    fn every_named_op_exists() {
        for name in MODEL_NAMES {
            let spec = Model::from_name(name).unwrap().spec();
            let mut ops: Vec<&str> = spec.time_ops.to_vec();
            ops.extend(
                spec.piece_ops
                    .iter()
                    .flat_map(|p| p.ops.iter().map(|(o, _)| *o)),
            );
            ops.extend(spec.field_ops.iter().map(|(o, _)| *o));
            ops.extend(spec.methods.iter().map(|(_, o)| *o));
            for op in ops {
                assert!(lane_fn::<f64>(op).is_some(), "{name}: no op {op}");
                assert!(scalar_fn::<f32>(op).is_some(), "{name}: no scalar op {op}");
            }
            for text in spec.wgsl.iter().chain(COMMON_WGSL) {
                to_wgsl(text).unwrap();
            }
        }
    }
}
