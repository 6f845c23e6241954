//! What a model declares: variables, parameters, pieces and the shared
//! functions (ops) that implement each piece, time term and method.

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
    /// The parameter whose value ω sets the forcing period 2π/ω, or `None`
    /// without forcing (`Some("")`: a fixed period 2π, mean motion 1).
    pub forcing_frequency: Option<&'static str>,
    /// Lane parameters computed from scene parameters (model-level data such
    /// as Liénard coefficients come from `Model::derived`).
    pub derived: &'static [Derived],
    /// Initial values other than 0 when the scene gives none.
    pub initial_defaults: &'static [(&'static str, f64)],
    /// An initial key that stands for several initial values (Kepler's
    /// `eccentricity`: the orbit's perihelion).
    pub initial_alias: Option<InitialAlias>,
    /// Do the comparison integrators carry the optional variable along
    /// (mechanical models: s) or integrate without it (Liénard: no p)?
    pub methods_carry_optional: bool,
    /// Model rules on parameter and initial values (beyond finiteness);
    /// `values("params.index")` lists every value a field takes.
    pub rules: Rules,
}

/// A broken model rule: the field and what is wrong.
pub type RuleError = (String, String);

/// A model's rules: `values(field)` lists every value a field takes; `time`
/// says whether the plan reads time.
pub type Rules = fn(values: &dyn Fn(&str) -> Vec<f64>, time: bool) -> Result<(), RuleError>;

/// Rules of a model that has none.
pub fn no_rules(_: &dyn Fn(&str) -> Vec<f64>, _: bool) -> Result<(), RuleError> {
    Ok(())
}

/// Every value of `field` lies in `range`, else `message(value)`.
pub fn each_in(
    values: &dyn Fn(&str) -> Vec<f64>,
    field: &str,
    ok: impl Fn(f64) -> bool,
    message: impl Fn(f64) -> String,
) -> Result<(), RuleError> {
    match values(field).into_iter().find(|v| !ok(*v)) {
        Some(v) => Err((field.to_string(), message(v))),
        None => Ok(()),
    }
}

/// Map from a scene parameter's value to a derived lane parameter.
pub type DeriveFn = fn(f64) -> f64;

/// A lane parameter computed from a scene parameter (or a constant).
#[derive(Debug, Clone, Copy)]
pub struct Derived {
    /// Lane field it fills.
    pub name: &'static str,
    /// The scene parameter it depends on, with the map; `None`: a constant.
    pub from: Option<(&'static str, DeriveFn)>,
    /// Value when `from` is `None`.
    pub value: f64,
}

/// An initial key that sets other initial values (unless they are given).
#[derive(Debug, Clone, Copy)]
pub struct InitialAlias {
    pub key: &'static str,
    /// Accepted values, for the message: e.g. "[0, 1)".
    pub range: &'static str,
    pub ok: fn(f64) -> bool,
    /// The initial values it sets, each from the key's value.
    pub sets: &'static [(&'static str, DeriveFn)],
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

/// One instruction of a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Op {
    /// `tau ← c · dt`.
    Tau(f64),
    /// `t ← t0 + (n + c) dt` for step n (computed as `t0 + n dt + c dt`).
    Time(f64),
    /// Apply the shared function of this name (arguments bound by name).
    Call(&'static str),
}
