//! What a model declares: variables, parameters, pieces and the shared
//! functions (ops) that implement each piece, time term and method.

use super::Method;

/// A scene parameter of a model.
#[derive(Debug, Clone, Copy)]
pub struct ParamDef {
    /// Name in scene files (SPEC §2.4).
    pub name: &'static str,
    /// Value when the scene does not give one; `None`: the scene must give it.
    pub default: Option<f64>,
    /// One line for `--help`-style listings.
    pub doc: &'static str,
}

impl ParamDef {
    /// A parameter whose absence means "switched off" (no forcing, no damping).
    pub const fn zero(name: &'static str, doc: &'static str) -> Self {
        ParamDef {
            name,
            default: Some(0.0),
            doc,
        }
    }
    /// A parameter without a sensible zero.
    pub const fn required(name: &'static str, doc: &'static str) -> Self {
        ParamDef {
            name,
            default: None,
            doc,
        }
    }
}

/// When a model reads time.
#[derive(Debug, Clone, Copy)]
pub enum TimeDependence {
    Never,
    Always,
    /// Only if one of these parameters is nonzero for some trajectory.
    WhenNonzero(&'static [&'static str]),
}

/// The ops that apply one piece's exact flow, in order. An op marked `true`
/// updates the optional variable and is left out when that variable is not
/// integrated.
#[derive(Debug, Clone, Copy)]
pub struct PieceOps {
    pub piece: char,
    pub ops: &'static [(&'static str, bool)],
    /// The piece is the identity when all these parameters are zero for every
    /// trajectory (and is then dropped from the step).
    pub identity_when_zero: &'static [&'static str],
}

/// A model: everything the plan needs to know about it.
#[derive(Debug, Clone, Copy)]
pub struct ModelSpec {
    pub name: &'static str,
    /// The equation of motion, for listings.
    pub summary: &'static str,
    /// State variables in canonical order.
    pub vars: &'static [&'static str],
    /// A variable that does not feed back into the others, integrated only
    /// when asked for (s of mechanical models, p of Liénard systems).
    pub optional_var: Option<&'static str>,
    pub params: &'static [ParamDef],
    /// Piece letters.
    pub pieces: &'static str,
    /// Default S2 inner order.
    pub default_order: &'static str,
    pub time: TimeDependence,
    /// Ops that evaluate the time terms at the stage time `t`.
    pub time_ops: &'static [&'static str],
    pub piece_ops: &'static [PieceOps],
    /// Ops that evaluate the vector field at (state, t) into `d<var>`.
    pub field_ops: &'static [(&'static str, bool)],
    /// Comparison integrators this model offers, as one op per step.
    pub methods: &'static [(Method, &'static str)],
    /// Shared-function texts the GPU kernel needs beyond the common ones.
    pub wgsl: &'static [&'static str],
}

impl ModelSpec {
    pub fn param(&self, name: &str) -> Option<&ParamDef> {
        self.params.iter().find(|p| p.name == name)
    }
    pub fn piece(&self, piece: char) -> Option<&PieceOps> {
        self.piece_ops.iter().find(|p| p.piece == piece)
    }
    pub fn method_op(&self, m: Method) -> Option<&'static str> {
        self.methods.iter().find(|(k, _)| *k == m).map(|(_, n)| *n)
    }
}
