//! Every key a scene file's fixed tables may hold: the parser's list of
//! what it accepts (any other key is refused, naming these), and, with each
//! key's values, default and meaning, the scene reference's tables, which
//! `tests/suite/docs.rs` generates from this list (with the error that each
//! key's `bad` example gets from `reeb check`), so the two cannot drift.
//! `[params]` and `[initial]` hold the model's own names (its table in the
//! reference) and `formula` a model's formulas (its own page).

/// One key of a table.
pub struct Key {
    pub name: &'static str,
    /// The values it takes.
    pub value: &'static str,
    /// What it is when left out ("required" where it must be given).
    pub default: &'static str,
    pub meaning: &'static str,
    /// A wrong setting, as a line of the table's TOML section, that the
    /// reference shows with the error it gets.
    pub bad: &'static str,
}

/// A table of keys: `name` as the error messages spell it, `section` the
/// TOML table its lines are written in (the file's top level: "").
pub struct Table {
    pub name: &'static str,
    pub section: &'static str,
    pub keys: &'static [Key],
}

const fn key(
    name: &'static str,
    value: &'static str,
    default: &'static str,
    meaning: &'static str,
    bad: &'static str,
) -> Key {
    Key {
        name,
        value,
        default,
        meaning,
        bad,
    }
}

/// The names of `keys`, for the parser's check and its messages.
pub fn names(keys: &[Key]) -> Vec<&'static str> {
    keys.iter().map(|k| k.name).collect()
}

pub const TOP: &[Key] = &[
    key("model", "a built-in model's name", "required, unless `formula` is given", "the system integrated: `damped_oscillator`, `van_der_pol`, `lienard`, `kepler`, `lane_emden`, `spin_orbit`, `quadratic_s`", "model = \"van_der_poll\""),
    key("formula", "a table of formulas", "none", "a model of your own, from its Hamiltonian, potential or Liénard functions (see \"Your own model\")", "formula = 3"),
    key("name", "a plain file name", "the scene file's name", "the output directory `runs/<name>` and the pictures' name", "name = \"a/b\""),
    key("title", "a string", "none", "the pictures' title", "title = 3"),
    key("params", "a table of values", "every parameter 0", "the model's parameters: numbers or axes (see \"Values\")", "params = 3"),
    key("initial", "a table of values", "the model's", "the initial state and `t0`: numbers or axes", "initial = 3"),
    key("integrator", "a table", "required", "the scheme, the step and the horizon", "integrator = 3"),
    key("output", "a table", "the final state", "what the run records besides the final state", "output = 3"),
    key("run", "a table", "`auto`, `f32`", "the backend and the precision", "run = 3"),
    key("report", "a table", "none", "what `reeb report` compares", "report = 3"),
    key("plot", "a table", "none", "what the pictures show", "plot = 3"),
];

pub const INTEGRATOR: &[Key] = &[
    key("scheme", "a scheme's name", "`s2`", "the integrator: `s2`; compositions `mclachlan4`, `kahanli6`, `kahanli8`, `sofspa10`, `triple_jump4/6/8`, `yoshida6a`–`c`, `yoshida8a`–`e`; `variational1`, `variational2`; for comparison `rk4`, `leapfrog`", "scheme = \"s3\""),
    key("order", "a string of the model's piece letters", "the model's default", "S2's inner piece order, any palindrome of the model's pieces (e.g. `\"CBABC\"`)", "order = 3"),
    key("dt", "a number or an axis", "required", "the step size τ", "dt = -0.1"),
    key("t_end", "a number", "one of `t_end` and `steps` is required", "the final time: round((t_end − t0)/dt) steps per step size", "t_end = \"long\""),
    key("steps", "a whole number ≥ 1", "one of `t_end` and `steps` is required", "the number of steps", "steps = 0"),
];

pub const OUTPUT: &[Key] = &[
    key(
        "final",
        "a list of variables",
        "the model's state variables",
        "the state at the end of the run, per trajectory",
        "final = [\"x\"]",
    ),
    key(
        "trajectory",
        "{ every, vars }",
        "none",
        "the state every `every` steps, from step 0",
        "trajectory = 3",
    ),
    key(
        "poincare",
        "{ period, … } or { crossing, … }",
        "none",
        "a Poincaré section: stroboscopic, or where a variable crosses a value",
        "poincare = 3",
    ),
    key(
        "cycle",
        "true or { var, level, skip }",
        "off",
        "the limit cycle's amplitude and period over the last part of the run",
        "cycle = 3",
    ),
    key(
        "average",
        "a list of variables or { vars, skip }",
        "none",
        "the mean of each variable over the steps after the skipped fraction",
        "average = 3",
    ),
    key(
        "resonance",
        "{ var, ratios, tolerance }",
        "none",
        "the ratio p:q whose value the mean of `var` is within `tolerance` of",
        "resonance = 3",
    ),
    key(
        "stop",
        "a condition, or { when }",
        "none",
        "a trajectory stops after the first step at whose end the condition holds",
        "stop = \"q >\"",
    ),
    key(
        "lyapunov",
        "true or { vectors, every, skip }",
        "off",
        "finite-time Lyapunov exponents of the numerical map",
        "lyapunov = 3",
    ),
    key(
        "fli",
        "true or { every }",
        "off",
        "the Fast Lyapunov Indicator",
        "fli = 3",
    ),
    key(
        "megno",
        "true or { every }",
        "off",
        "MEGNO ⟨Y⟩",
        "megno = 3",
    ),
    key(
        "sali",
        "true or { every }",
        "off",
        "the smaller alignment index SALI",
        "sali = 3",
    ),
    key(
        "gali",
        "true or { k, every }",
        "off",
        "the generalized alignment index GALI_k",
        "gali = 3",
    ),
    key(
        "attractors",
        "true or { max_period, tolerance, skip, every, angles }",
        "off",
        "which attractor each orbit ends on: a fixed point, a cycle of period ≤ max_period, aperiodic, or escape",
        "attractors = 3",
    ),
    key(
        "format",
        "`\"npy\"` or `\"zarr\"`",
        "`\"npy\"`",
        "`.npy` files, or one Zarr v3 store `run.zarr`",
        "format = \"hdf5\"",
    ),
];

pub const TRAJECTORY: &[Key] = &[
    key(
        "every",
        "a whole number ≥ 1",
        "1",
        "steps between frames",
        "trajectory = { every = \"often\" }",
    ),
    key(
        "vars",
        "a list of variables",
        "the model's state variables",
        "what each frame records",
        "trajectory = { vars = [\"x\"] }",
    ),
];

pub const POINCARE: &[Key] = &[
    key("period", "a number, or `\"forcing\"`", "one of `period` and `crossing` is required", "a stroboscopic section at t0 + phase + k·period; `\"forcing\"`: each trajectory's forcing period 2π/ω", "poincare = { period = -1.0 }"),
    key("phase", "a number", "0", "the stroboscopic section's offset", "poincare = { period = 1.0, phase = \"late\" }"),
    key("crossing", "a state variable", "one of `period` and `crossing` is required", "an event section where this variable crosses `value`", "poincare = { crossing = \"x\" }"),
    key("value", "a number", "0", "the crossing's level", "poincare = { crossing = \"q\", value = \"zero\" }"),
    key("direction", "`\"up\"`, `\"down\"` or `\"both\"`", "`\"up\"`", "which crossings count", "poincare = { crossing = \"q\", direction = \"sideways\" }"),
    key("vars", "a list of variables", "the model's state variables", "what each point records", "poincare = { period = 1.0, vars = [\"x\"] }"),
    key("max_points", "a whole number", "1000", "points kept per trajectory (later ones are counted, not kept)", "poincare = { period = 1.0, max_points = -1 }"),
    key("skip", "a number ≥ 0", "0", "whole periods left out before the first point", "poincare = { period = 1.0, skip = \"some\" }"),
];

pub const CYCLE: &[Key] = &[
    key(
        "var",
        "a state variable",
        "`\"q\"`",
        "the oscillating variable",
        "cycle = { var = \"x\" }",
    ),
    key(
        "level",
        "a number",
        "0",
        "the level whose upward crossings time the period",
        "cycle = { level = \"zero\" }",
    ),
    key(
        "skip",
        "a fraction in [0, 1)",
        "0.5",
        "the part of the run left out as transient",
        "cycle = { skip = \"half\" }",
    ),
];

pub const AVERAGE: &[Key] = &[
    key(
        "vars",
        "a list of state variables",
        "required",
        "the variables averaged",
        "average = { vars = [\"t\"] }",
    ),
    key(
        "skip",
        "a fraction in [0, 1)",
        "0.5",
        "the part of the run left out",
        "average = { vars = [\"p\"], skip = \"half\" }",
    ),
];

pub const RESONANCE: &[Key] = &[
    key(
        "var",
        "a state variable",
        "required",
        "the variable whose mean is classified",
        "resonance = { ratios = [[1, 1]], tolerance = 0.01 }",
    ),
    key(
        "ratios",
        "a list of [p, q] of whole numbers",
        "required",
        "the candidate ratios, in order of preference",
        "resonance = { var = \"p\", ratios = [[1.5, 1]], tolerance = 0.01 }",
    ),
    key(
        "tolerance",
        "a number > 0",
        "required",
        "the half-width of each ratio's window",
        "resonance = { var = \"p\", ratios = [[1, 1]] }",
    ),
];

pub const STOP: &[Key] = &[key(
    "when",
    "a condition: two formulas and <, <=, > or >=",
    "required in the table form",
    "the condition, over the state, `t`, the parameters and the indicators computed",
    "stop = { when = 3 }",
)];

pub const LYAPUNOV: &[Key] = &[
    key(
        "vectors",
        "a whole number ≥ 1",
        "1",
        "deviation vectors, one exponent each, largest first",
        "lyapunov = { vectors = \"two\" }",
    ),
    key(
        "every",
        "a whole number ≥ 1",
        "1",
        "steps between re-orthonormalisations",
        "lyapunov = { every = \"often\" }",
    ),
    key(
        "skip",
        "a fraction in [0, 1)",
        "0",
        "the part of the run before the sums start",
        "lyapunov = { skip = \"half\" }",
    ),
];

pub const SAMPLED: &[Key] = &[key(
    "every",
    "a whole number ≥ 1",
    "1",
    "steps between samples of the deviation vectors",
    "fli = { every = \"often\" }",
)];

pub const GALI: &[Key] = &[
    key(
        "k",
        "a whole number ≥ 2",
        "3",
        "deviation vectors whose volume GALI_k is",
        "gali = { k = \"three\" }",
    ),
    key(
        "every",
        "a whole number ≥ 1",
        "1",
        "steps between samples",
        "gali = { every = \"often\" }",
    ),
];

pub const ATTRACTORS: &[Key] = &[
    key(
        "max_period",
        "a whole number from 1 to 64",
        "8",
        "the longest cycle of samples looked for",
        "attractors = { max_period = 0 }",
    ),
    key(
        "tolerance",
        "a number > 0",
        "1e-3",
        "how close a sample must return to the one a period before (largest difference of a component)",
        "attractors = { tolerance = 0.0 }",
    ),
    key(
        "skip",
        "a fraction in [0, 1)",
        "0.5",
        "the part of the run left out before sampling",
        "attractors = { skip = 1.0 }",
    ),
    key(
        "every",
        "a whole number ≥ 1",
        "64 (fewer in runs under 4096 steps)",
        "steps between samples where the scene has no `poincare` section (with one, its points are the samples)",
        "attractors = { every = 0 }",
    ),
    key(
        "angles",
        "a list of sampled variables",
        "none",
        "variables compared modulo 2π",
        "attractors = { angles = [\"x\"] }",
    ),
];

pub const RUN: &[Key] = &[
    key(
        "backend",
        "`\"auto\"`, `\"cpu\"` or `\"gpu\"`",
        "`\"auto\"`",
        "where the run integrates (`--backend` overrides it)",
        "backend = \"tpu\"",
    ),
    key(
        "precision",
        "`\"f32\"` or `\"f64\"`",
        "`\"f32\"`",
        "the working precision (`--precision` overrides it)",
        "precision = \"f16\"",
    ),
];

pub const PLOT: &[Key] = &[
    key(
        "phase",
        "two recorded variables",
        "the first two recorded",
        "the phase portrait's axes",
        "phase = 3",
    ),
    key(
        "poincare",
        "two section variables",
        "the first two recorded",
        "the Poincaré portrait's axes",
        "poincare = 3",
    ),
    key(
        "wrap_x",
        "`\"2pi\"` or `\"pi\"`",
        "none",
        "wrap the portrait's x into [0, 2π) or [−π, π)",
        "wrap_x = \"tau\"",
    ),
    key(
        "max_trajectories",
        "a whole number",
        "64",
        "trajectories drawn in the phase portrait",
        "max_trajectories = -1",
    ),
    key(
        "lienard_plane",
        "true or false",
        "false",
        "van der Pol: draw (q, q − q³/3 − s/ε)",
        "lienard_plane = \"yes\"",
    ),
    key(
        "bifurcation",
        "{ axis, var }",
        "none",
        "a bifurcation diagram of a section variable along an axis",
        "bifurcation = 3",
    ),
];

pub const BIFURCATION: &[Key] = &[
    key(
        "axis",
        "an axis of the scene",
        "required",
        "the parameter along the diagram",
        "bifurcation = { axis = 3, var = \"q\" }",
    ),
    key(
        "var",
        "a section variable",
        "required",
        "the variable plotted",
        "bifurcation = { axis = \"epsilon\", var = 3 }",
    ),
];

pub const REPORT: &[Key] = &[
    key(
        "schemes",
        "a list of schemes' names",
        "the scene's scheme",
        "the schemes compared",
        "schemes = [\"s3\"]",
    ),
    key(
        "backends",
        "a list of `\"cpu\"`, `\"gpu\"`",
        "`[\"cpu\"]`",
        "the backends compared",
        "backends = [\"tpu\"]",
    ),
    key(
        "precisions",
        "a list of `\"f32\"`, `\"f64\"`",
        "`[\"f64\"]`",
        "the precisions compared",
        "precisions = [\"f16\"]",
    ),
    key(
        "error_vars",
        "a list of state variables",
        "every state variable",
        "the variables the error is measured on",
        "error_vars = 3",
    ),
    key(
        "reference_rtol",
        "a number > 0",
        "10⁻¹²",
        "the relative tolerance of the DOP853 reference",
        "reference_rtol = \"tight\"",
    ),
    key(
        "distorted",
        "a number > 0",
        "0.05",
        "stability: the relative error beyond which a cell is distorted",
        "distorted = \"some\"",
    ),
    key(
        "targets",
        "a list of numbers > 0",
        "10⁻², 10⁻⁴, 10⁻⁶, 10⁻⁸",
        "the errors at which the report compares run times",
        "targets = 3",
    ),
];

/// Every table, in the order of the reference.
pub const TABLES: &[Table] = &[
    Table {
        name: "The file's top level",
        section: "",
        keys: TOP,
    },
    Table {
        name: "integrator",
        section: "integrator",
        keys: INTEGRATOR,
    },
    Table {
        name: "output",
        section: "output",
        keys: OUTPUT,
    },
    Table {
        name: "output.trajectory",
        section: "output",
        keys: TRAJECTORY,
    },
    Table {
        name: "output.poincare",
        section: "output",
        keys: POINCARE,
    },
    Table {
        name: "output.cycle",
        section: "output",
        keys: CYCLE,
    },
    Table {
        name: "output.average",
        section: "output",
        keys: AVERAGE,
    },
    Table {
        name: "output.resonance",
        section: "output",
        keys: RESONANCE,
    },
    Table {
        name: "output.stop",
        section: "output",
        keys: STOP,
    },
    Table {
        name: "output.lyapunov",
        section: "output",
        keys: LYAPUNOV,
    },
    Table {
        name: "output.fli, output.megno, output.sali",
        section: "output",
        keys: SAMPLED,
    },
    Table {
        name: "output.gali",
        section: "output",
        keys: GALI,
    },
    Table {
        name: "output.attractors",
        section: "output",
        keys: ATTRACTORS,
    },
    Table {
        name: "run",
        section: "run",
        keys: RUN,
    },
    Table {
        name: "plot",
        section: "plot",
        keys: PLOT,
    },
    Table {
        name: "plot.bifurcation",
        section: "plot",
        keys: BIFURCATION,
    },
    Table {
        name: "report",
        section: "report",
        keys: REPORT,
    },
];
