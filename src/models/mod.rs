//! The models of SPEC §2: each a contact Hamiltonian split into pieces with
//! exact flows, written once as shared functions (see [`crate::dsl`]).

pub mod damped_oscillator;
pub mod kepler;
pub mod lane_emden;
pub mod lanes;
pub mod lienard;
pub mod mechanical;
pub mod pieces;
pub mod quadratic_s;
pub mod spec;
pub mod spin_orbit;

use lanes::LaneFn;
use prelude::*;
use spec::ModelSpec;

use crate::real::Real;

/// Every shared-function trait, so that `R: Real` can call them all.
pub trait Flows:
    Sized
    + MechanicalFlows
    + Mechanical1dOps
    + DampedOscillatorFlows
    + DampedOscillatorOps
    + DampedOscillatorMethods
    + KeplerFlows
    + KeplerOps
    + LaneEmdenFlows
    + LaneEmdenMechFlows
    + LaneEmdenOps
    + LaneEmdenMethods
    + SpinOrbitFlows
    + SpinOrbitOps
    + SpinOrbitMethods
    + QuadraticSOps
    + LienardFlows
    + LienardModelFlows
    + LienardOps
    + VanDerPolMethods
    + LienardMethods
    + ObserveFlows
{
}

impl<T> Flows for T where
    T: MechanicalFlows
        + Mechanical1dOps
        + DampedOscillatorFlows
        + DampedOscillatorOps
        + DampedOscillatorMethods
        + KeplerFlows
        + KeplerOps
        + LaneEmdenFlows
        + LaneEmdenMechFlows
        + LaneEmdenOps
        + LaneEmdenMethods
        + SpinOrbitFlows
        + SpinOrbitOps
        + SpinOrbitMethods
        + QuadraticSOps
        + LienardFlows
        + LienardModelFlows
        + LienardOps
        + VanDerPolMethods
        + LienardMethods
        + ObserveFlows
{
}

/// Every scalar op (one trajectory) by name, for [`pieces!`](crate::pieces).
#[allow(ambiguous_glob_reexports)]
pub mod scalar_ops {
    pub use super::damped_oscillator::damped_oscillator_lanes::scalar::*;
    pub use super::kepler::kepler_lanes::scalar::*;
    pub use super::lane_emden::lane_emden_lanes::scalar::*;
    pub use super::lienard::lienard_lanes::scalar::*;
    pub use super::mechanical::mechanical_1d_lanes::scalar::*;
    pub use super::quadratic_s::quadratic_s_lanes::scalar::*;
    pub use super::spin_orbit::spin_orbit_lanes::scalar::*;
}

/// Every trait a shared function may call through `R::name(..)`.
pub mod prelude {
    pub use super::damped_oscillator::{
        DampedOscillatorFlows, DampedOscillatorMethods, DampedOscillatorOps,
    };
    pub use super::kepler::{KeplerFlows, KeplerOps};
    pub use super::lane_emden::{
        LaneEmdenFlows, LaneEmdenMechFlows, LaneEmdenMethods, LaneEmdenOps,
    };
    pub use super::lienard::{
        LienardFlows, LienardMethods, LienardModelFlows, LienardOps, VanDerPolMethods,
    };
    pub use super::mechanical::{Mechanical1dOps, MechanicalFlows};
    pub use super::quadratic_s::QuadraticSOps;
    pub use super::spin_orbit::{SpinOrbitFlows, SpinOrbitMethods, SpinOrbitOps};
    pub use crate::observe::ObserveFlows;
    pub use crate::real::{Math, Prims};
}

/// Shared-function texts every GPU kernel includes (models add their own).
pub const COMMON_WGSL: &[&str] = &[
    mechanical::MECHANICAL_FLOWS_WGSL,
    mechanical::MECHANICAL_1D_WGSL,
    lienard::LIENARD_FLOWS_WGSL,
    crate::observe::OBSERVE_WGSL,
];

macro_rules! op_modules {
    ($($m:ident :: $lanes:ident),* $(,)?) => {
        /// The lane loop of the op called `name`, from whichever model defines it.
        pub fn lane_fn<R: Real>(name: &str) -> Option<LaneFn<R>> {
            None$(.or_else(|| $m::$lanes::lookup(name)))*
        }
        /// The scalar op called `name` (one trajectory).
        pub fn scalar_fn<R: Real>(name: &str) -> Option<lanes::ScalarFn<R>> {
            None$(.or_else(|| $m::$lanes::scalar::lookup(name)))*
        }
    };
}

op_modules! {
    mechanical::mechanical_1d_lanes,
    damped_oscillator::damped_oscillator_lanes,
    damped_oscillator::damped_oscillator_method_lanes,
    kepler::kepler_lanes,
    lane_emden::lane_emden_lanes,
    lane_emden::lane_emden_method_lanes,
    spin_orbit::spin_orbit_lanes,
    spin_orbit::spin_orbit_method_lanes,
    quadratic_s::quadratic_s_lanes,
    lienard::lienard_lanes,
    lienard::van_der_pol_method_lanes,
    lienard::lienard_method_lanes,
}

/// A comparison integrator (SPEC §3), as opposed to a splitting scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    Rk4,
    Leapfrog,
    Variational1,
    Variational2,
}

impl Method {
    pub fn name(self) -> &'static str {
        match self {
            Method::Rk4 => "rk4",
            Method::Leapfrog => "leapfrog",
            Method::Variational1 => "variational1",
            Method::Variational2 => "variational2",
        }
    }
    /// Nominal order of accuracy.
    pub fn order(self) -> u32 {
        match self {
            Method::Rk4 => 4,
            Method::Leapfrog | Method::Variational2 => 2,
            Method::Variational1 => 1,
        }
    }
    /// Right-hand-side (force) evaluations per step, for cost comparisons.
    pub fn evaluations(self) -> u32 {
        match self {
            Method::Rk4 => 4,
            Method::Leapfrog | Method::Variational1 | Method::Variational2 => 1,
        }
    }
}

/// A model with its model-level data (the Liénard polynomials).
#[derive(Debug, Clone, PartialEq)]
pub enum Model {
    DampedOscillator,
    VanDerPol,
    /// General Liénard system: ascending coefficients of f(q) and g(q).
    Lienard {
        f: Vec<f64>,
        g: Vec<f64>,
    },
    Kepler,
    LaneEmden,
    SpinOrbit,
    QuadraticS,
}

/// Names accepted by [`Model::from_name`].
pub const MODEL_NAMES: &[&str] = &[
    "damped_oscillator",
    "van_der_pol",
    "lienard",
    "kepler",
    "lane_emden",
    "spin_orbit",
    "quadratic_s",
];

/// Map from a scene parameter's value to a derived lane parameter.
pub type DeriveFn = fn(f64) -> f64;

/// A lane parameter computed from a scene parameter (or from model data).
pub struct Derived {
    /// Lane field it fills.
    pub name: &'static str,
    /// The scene parameter it depends on, with the map; `None`: a constant.
    pub from: Option<(&'static str, DeriveFn)>,
    /// Value when `from` is `None`.
    pub value: f64,
}

macro_rules! spin_orbit_weights {
    ($($m:literal => $a:ident, $b:ident);* $(;)?) => {
        vec![$(
            Derived { name: stringify!($a), from: Some(("eccentricity", |e| spin_orbit::weight_a($m, e))), value: 0.0 },
            Derived { name: stringify!($b), from: Some(("eccentricity", |e| spin_orbit::weight_b($m, e))), value: 0.0 },
        )*]
    };
}

impl Model {
    /// The model of a scene's `model = "…"` (the Liénard polynomials are
    /// filled in separately, from the scene's coefficient lists).
    pub fn from_name(name: &str) -> Option<Model> {
        Some(match name {
            "damped_oscillator" => Model::DampedOscillator,
            "van_der_pol" => Model::VanDerPol,
            "lienard" => Model::Lienard {
                f: vec![],
                g: vec![],
            },
            "kepler" => Model::Kepler,
            "lane_emden" => Model::LaneEmden,
            "spin_orbit" => Model::SpinOrbit,
            "quadratic_s" => Model::QuadraticS,
            _ => return None,
        })
    }

    pub fn spec(&self) -> &'static ModelSpec {
        match self {
            Model::DampedOscillator => &damped_oscillator::SPEC,
            Model::VanDerPol => &lienard::VAN_DER_POL,
            Model::Lienard { .. } => &lienard::LIENARD,
            Model::Kepler => &kepler::SPEC,
            Model::LaneEmden => &lane_emden::SPEC,
            Model::SpinOrbit => &spin_orbit::SPEC,
            Model::QuadraticS => &quadratic_s::SPEC,
        }
    }

    pub fn name(&self) -> &'static str {
        self.spec().name
    }

    /// The parameter whose value ω sets the forcing period 2π/ω, or `None`
    /// without forcing; the spin–orbit problem's orbit has period 2π
    /// (`Some("")`: mean motion 1).
    pub fn forcing_frequency_param(&self) -> Option<&'static str> {
        match self {
            Model::DampedOscillator | Model::VanDerPol => Some("forcing_frequency"),
            Model::Kepler => Some("theta"),
            Model::SpinOrbit => Some(""),
            _ => None,
        }
    }

    /// The CPU's fused S2 stage for this model, piece order (outermost
    /// first), optional variable and time, built for the instruction set `isa`.
    pub fn stage_fn<R: Real>(
        &self,
        order: [char; 3],
        opt: bool,
        time: bool,
        isa: pieces::Isa,
    ) -> Option<pieces::StageFn<R>> {
        use pieces::stage_fn;
        match self {
            Model::DampedOscillator => {
                stage_fn::<R, damped_oscillator::DampedOscillatorPieces>(order, opt, time, isa)
            }
            Model::VanDerPol => stage_fn::<R, lienard::VanDerPolPieces>(order, opt, time, isa),
            Model::Lienard { .. } => stage_fn::<R, lienard::LienardPieces>(order, opt, time, isa),
            Model::Kepler => stage_fn::<R, kepler::KeplerPieces>(order, opt, time, isa),
            Model::LaneEmden => stage_fn::<R, lane_emden::LaneEmdenPieces>(order, opt, time, isa),
            Model::SpinOrbit => stage_fn::<R, spin_orbit::SpinOrbitPieces>(order, opt, time, isa),
            Model::QuadraticS => {
                stage_fn::<R, quadratic_s::QuadraticSPieces>(order, opt, time, isa)
            }
        }
    }

    /// Lane parameters derived from scene parameters or model data.
    pub fn derived(&self) -> Vec<Derived> {
        match self {
            Model::SpinOrbit => spin_orbit_weights! {
                1 => a1, b1; 2 => a2, b2; 3 => a3, b3; 4 => a4, b4; 5 => a5, b5;
                6 => a6, b6; 7 => a7, b7; 8 => a8, b8; 9 => a9, b9;
            },
            Model::Lienard { f, g } => {
                const F: [&str; 10] = ["f0", "f1", "f2", "f3", "f4", "f5", "f6", "f7", "f8", "f9"];
                const G: [&str; 10] = ["g0", "g1", "g2", "g3", "g4", "g5", "g6", "g7", "g8", "g9"];
                let coef = |c: &[f64], k: usize| c.get(k).copied().unwrap_or(0.0);
                (0..lienard::MAX_COEFFICIENTS)
                    .flat_map(|k| {
                        [
                            Derived {
                                name: F[k],
                                from: None,
                                value: coef(f, k),
                            },
                            Derived {
                                name: G[k],
                                from: None,
                                value: coef(g, k),
                            },
                        ]
                    })
                    .collect()
            }
            _ => vec![],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dsl::to_wgsl;

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
