//! Models from formulas (SPEC §2.1, §2.2 for any V, K, f, g): a mechanical
//! system `H = K(p) + V(q, t) + f(t)·s` with n degrees of freedom, or a
//! Liénard system `q'' + f(q) q' + g(q, t) = 0`, compiled at run time.
//!
//! The pieces' exact flows are built symbolically from the formulas and
//! their derivatives in one DAG (shared subexpressions once), each op lowered
//! to one straight-line program (`num/formula/lower.rs`) that the CPU
//! interprets over blocks and the GPU gets as WGSL. The op names are fixed
//! (`formula_a`, …), parameters live in the lane slots `k0…`, so the plan,
//! both backends and the observers treat a formula model like any other.

use std::collections::HashMap;
use std::sync::Mutex;

use super::lanes::Lane;
use super::spec::{Method, ModelSpec, Op, ParamDef, PieceOps, TimeDependence};
use crate::num::formula::lower::{lower, Lowered};
use crate::num::formula::stage::{Staged, Vary};
use crate::num::formula::{compile, Dag, FormulaError, Func, Id};

/// Most degrees of freedom of a mechanical formula model (lane fields).
pub const MAX_DOF: usize = 4;
/// Lane slots of formula parameters, in the order the scene names them.
pub const SLOTS: [&str; 16] = [
    "k0", "k1", "k2", "k3", "k4", "k5", "k6", "k7", "k8", "k9", "k10", "k11", "k12", "k13", "k14",
    "k15",
];
const Q: [&str; MAX_DOF] = ["q1", "q2", "q3", "q4"];
const P: [&str; MAX_DOF] = ["p1", "p2", "p3", "p4"];

/// Which family of systems.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kind {
    Mechanical { dof: usize },
    Lienard,
}

/// What a scene's `[formula]` gives: the family and its formula texts by key.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Source {
    pub kind: Kind,
    /// `(key, text)`: potential, kinetic, damping (mechanical); f, g (Liénard).
    pub texts: Vec<(String, String)>,
    /// The scene's parameter names, in slot order.
    pub params: Vec<String>,
    /// The parameter whose value ω sets the forcing period 2π/ω, if any.
    pub forcing_frequency: Option<String>,
}

/// A refused formula: the scene field (`formula.potential`), the column in
/// its text when there is one (a byte offset), and what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelError {
    pub field: String,
    pub column: Option<usize>,
    pub message: String,
}

/// The input of a composed step that is the step number `n`.
pub const STEP_INDEX: &str = "n";

/// What a composed step should make cheap.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cost {
    /// The work that depends on the state (the rest is shared by the lanes
    /// of a block or by the ensemble: the CPU).
    PerLane,
    /// The work that changes from step to step (each GPU thread does all
    /// of it; what no step changes is computed before the step loop).
    PerStep,
}

/// A whole step as one program; see [`FormulaModel::compose`].
#[derive(Debug, Clone)]
pub struct Composed {
    pub program: Lowered,
    /// The lane field of each input ([`STEP_INDEX`] for the step number).
    pub inputs: Vec<&'static str>,
    /// The lane fields the step assigns, in the order of the outputs.
    pub outputs: Vec<&'static str>,
}

impl Composed {
    /// Does input `name` change from step to step?
    pub fn changes_each_step(&self, name: &str) -> bool {
        changes_each_step(name, self.outputs.contains(&name))
    }

    /// How each input varies when the inputs bound to an axis are those for
    /// which `on_axis` holds: the step number is the same in every lane, an
    /// input a step changes is per lane, any other per lane exactly when it
    /// is on an axis. What the ensemble shares (`t0`, `dt`, parameters of
    /// one value) then lands in the split's fixed and uniform parts.
    pub fn vary(&self, on_axis: impl Fn(&str) -> bool) -> Vec<Vary> {
        self.inputs
            .iter()
            .map(|name| match self.changes_each_step(name) {
                true => Vary {
                    lane: *name != STEP_INDEX,
                    step: true,
                },
                false => Vary {
                    lane: on_axis(name),
                    step: false,
                },
            })
            .collect()
    }
}

/// Does an input of a composed step change from step to step: the state
/// it assigns, the step number, and the time and sub-step derived from it?
fn changes_each_step(name: &str, assigned: bool) -> bool {
    assigned || [STEP_INDEX, "t", "tau"].contains(&name)
}

/// One op: a program and the lane fields its outputs assign.
#[derive(Debug)]
pub struct FormulaOp {
    pub name: &'static str,
    pub program: Lowered,
    pub outputs: Vec<&'static str>,
}

/// A compiled formula model; see the module documentation.
#[derive(Debug)]
pub struct FormulaModel {
    pub source: Source,
    pub spec: ModelSpec,
    /// The lane field of each DAG variable (state, `t`, parameter slots, `tau`).
    pub inputs: Vec<&'static str>,
    pub ops: Vec<FormulaOp>,
    /// Parameters no formula reads (a scene warning).
    pub unused: Vec<String>,
    dag: Dag,
    roots: HashMap<&'static str, Vec<Id>>,
    /// The scene's functions and the derivatives the pieces use, each
    /// with its field: what must be finite where a trajectory starts.
    functions: Vec<Function>,
}

/// One of a model's functions: its field, its name (`V`, `∂V/∂q1`) and
/// the lane fields it reads ([`FormulaModel::functions`]).
#[derive(Debug)]
pub struct Function {
    pub field: String,
    pub name: String,
    pub inputs: Vec<&'static str>,
    root: Id,
}

impl PartialEq for FormulaModel {
    fn eq(&self, other: &Self) -> bool {
        self.source == other.source
    }
}

/// Compiled models by source: a scene compiled again (each sub-run, each
/// test) reuses its model, so the `'static` data is made once per source.
static MODELS: Mutex<Option<HashMap<Source, &'static FormulaModel>>> = Mutex::new(None);

impl FormulaModel {
    /// Compiles `source` (once per distinct source in a process).
    pub fn get(source: &Source) -> Result<&'static FormulaModel, ModelError> {
        let mut cache = MODELS.lock().unwrap_or_else(|e| e.into_inner());
        let cache = cache.get_or_insert_with(HashMap::new);
        if let Some(m) = cache.get(source) {
            return Ok(m);
        }
        let m: &'static FormulaModel = Box::leak(Box::new(build(source)?));
        cache.insert(source.clone(), m);
        Ok(m)
    }

    /// Compiles `source` anew, without the cache (the compile-time
    /// benchmark: `benches/formula_compile.rs`).
    pub fn build(source: &Source) -> Result<FormulaModel, ModelError> {
        build(source)
    }

    /// The op called `name`.
    pub fn op(&self, name: &str) -> Option<&FormulaOp> {
        self.ops.iter().find(|o| o.name == name)
    }

    /// Applies op `name` to one trajectory in f64 (the reference evaluation
    /// of the DAG, used by the DOP853 reference).
    pub fn apply_f64(&self, name: &str, x: &mut Lane<f64>) -> bool {
        let (Some(op), Some(roots)) = (self.op(name), self.roots.get(name)) else {
            return false;
        };
        let vars: Vec<f64> = self
            .inputs
            .iter()
            .map(|n| x.get(n).unwrap_or(0.0))
            .collect();
        for (v, lane) in self.dag.eval(roots, &vars).into_iter().zip(&op.outputs) {
            if let Some(slot) = x.get_mut(lane) {
                *slot = v;
            }
        }
        true
    }

    /// The scene's functions and the derivatives the pieces take: what
    /// must be finite where a trajectory starts.
    pub fn functions(&self) -> &[Function] {
        &self.functions
    }

    /// The value of `f` (one of [`Self::functions`]) at the inputs `x`.
    pub fn value(&self, f: &Function, x: &Lane<f64>) -> f64 {
        let vars: Vec<f64> = self
            .inputs
            .iter()
            .map(|n| x.get(n).unwrap_or(0.0))
            .collect();
        self.dag.eval(&[f.root], &vars)[0]
    }

    /// The WGSL functions of every op.
    pub fn wgsl(&self) -> String {
        self.ops
            .iter()
            .map(|o| {
                crate::num::formula::wgsl::function_text(
                    o.name,
                    &o.program,
                    &self.inputs,
                    &o.outputs,
                )
            })
            .collect()
    }

    /// A whole step (the plan's ops in order) composed into one program over
    /// the state at the step's start, the parameters, `t0`, `dt` and the step
    /// number [`STEP_INDEX`]: the ops' programs substituted into each other
    /// (subexpressions shared across pieces and stages), the sine and cosine
    /// of state-and-time sums expanded so that the time part can be shared
    /// by the ensemble (`num/formula/stage.rs`). `None` for an unknown op.
    pub fn compose(&self, step: &[Op], cost: Cost) -> Option<Composed> {
        let mut dag = self.dag.clone();
        let mut inputs = self.inputs.clone();
        let at = |inputs: &[&str], n: &str| inputs.iter().position(|x| *x == n);
        let (t, tau) = (at(&inputs, "t")?, at(&inputs, "tau")?);
        inputs.extend(["t0", "dt", STEP_INDEX]);
        let k = self.inputs.len() as u32;
        let (t0, dt, n) = (dag.var(k), dag.var(k + 1), dag.var(k + 2));
        let mut env: Vec<Id> = (0..inputs.len() as u32).map(|v| dag.var(v)).collect();
        let mut written = vec![false; inputs.len()];
        for op in step {
            match *op {
                Op::Tau(c) => {
                    let c = dag.num(c);
                    env[tau] = dag.mul(c, dt);
                }
                Op::Time(c) => {
                    // t0 + n dt + c dt, as the op interpreter computes it.
                    let ndt = dag.mul(n, dt);
                    let start = dag.add(t0, ndt);
                    let c = dag.num(c);
                    let cdt = dag.mul(c, dt);
                    env[t] = dag.add(start, cdt);
                }
                Op::Call(name) => {
                    let (op, roots) = (self.op(name)?, self.roots.get(name)?);
                    let new = dag.substitute(roots, &env);
                    for (v, lane) in new.into_iter().zip(&op.outputs) {
                        let k = at(&inputs, lane)?;
                        env[k] = v;
                        written[k] = true;
                    }
                }
            }
        }
        let outputs: Vec<&'static str> = (0..inputs.len())
            .filter(|k| written[*k])
            .map(|k| inputs[k])
            .collect();
        let roots: Vec<Id> = (0..inputs.len())
            .filter(|k| written[*k])
            .map(|k| env[k])
            .collect();
        // The rewrites pay off for some formulas only (sin(q + t) alone
        // costs more expanded): the cheapest program is kept. Each candidate
        // gathers its constant factors; the last also merges the Fourier
        // terms of ±m (one coefficient per cos mt, as the built-ins have).
        let per_step: Vec<bool> = (0..inputs.len())
            .map(|k| changes_each_step(inputs[k], written[k]))
            .collect();
        let expanded = dag.expand_trig(&roots, &written);
        let collected = dag.collect(&expanded, &written);
        let [roots, expanded, collected] =
            [roots, expanded, collected].map(|r| dag.fold_coefficients(&r, &per_step));
        let merged = dag.merge_like_terms(&collected, &per_step);
        let program = [roots, expanded, collected, merged]
            .iter()
            .map(|r| lower(&dag, r))
            .min_by_key(|p| {
                let varying = match cost {
                    Cost::PerLane => work(p, &written),
                    Cost::PerStep => work(p, &per_step),
                };
                (varying, p.instrs.len())
            })?;
        Some(Composed {
            program,
            inputs,
            outputs,
        })
    }

    /// The WGSL of a composed step split as `s` (`num/formula/stage.rs`):
    /// `formula_fixed`, which the kernel calls once before its step loop,
    /// computes what no step changes (functions of the parameters, `t0` and
    /// `dt`: a Fourier sum's coefficients) into the kernel's locals `fx0…`;
    /// `formula_step` is the step reading them and the values the ensemble
    /// shares at the step, `tu0…` (the host tabulates them per window:
    /// `backend/gpu/time_table.rs`). Other arguments are the kernel's locals
    /// of the same names (`nf` for [`STEP_INDEX`]).
    pub fn step_wgsl(c: &Composed, s: &Staged) -> String {
        use crate::num::formula::wgsl::function_text;
        let mut inputs: Vec<&str> = c
            .inputs
            .iter()
            .map(|n| if *n == STEP_INDEX { "nf" } else { n })
            .collect();
        let fixed = names("fx", s.fixed.outputs.len());
        let fixed: Vec<&str> = fixed.iter().map(|f| f.as_str()).collect();
        let mut text = String::new();
        if !fixed.is_empty() {
            text.push_str(&function_text("formula_fixed", &s.fixed, &inputs, &fixed));
        }
        inputs.extend(&fixed);
        let shared = names(UNIFORM_PREFIX, s.uniform.outputs.len());
        inputs.extend(shared.iter().map(|u| u.as_str()));
        text.push_str(&function_text("formula_step", &s.lane, &inputs, &c.outputs));
        text
    }

    /// The DAG of every op and the roots of op `name` in it (its outputs,
    /// in the order of `FormulaOp::outputs`), over the variables `inputs`.
    pub fn op_roots(&self, name: &str) -> Option<(&Dag, &[Id])> {
        Some((&self.dag, self.roots.get(name)?))
    }

    /// The lane slot of parameter `name`.
    pub fn param_lane(&self, name: &str) -> Option<&'static str> {
        let k = self.source.params.iter().position(|p| p == name)?;
        Some(SLOTS[k])
    }
}

/// The cost of the instructions of `p` that depend on the inputs `state`,
/// in rough multiples of an add.
fn work(p: &Lowered, state: &[bool]) -> usize {
    use crate::num::formula::lower::{Operand, Prim};
    let mut varies: Vec<bool> = Vec::with_capacity(p.instrs.len());
    let mut cost = 0;
    for i in &p.instrs {
        let v = [i.a, i.b].iter().any(|o| match *o {
            Operand::Val(k) => varies[k as usize],
            Operand::Input(k) => state[k as usize],
            Operand::Const(_) => false,
        });
        varies.push(v);
        if v {
            cost += match i.op {
                Prim::Call(_) | Prim::Call2(_) => 16,
                Prim::Div => 4,
                _ => 1,
            };
        }
    }
    cost
}

/// The kernel locals holding the shared values of a step: `tu0…`.
pub const UNIFORM_PREFIX: &str = "tu";

/// `prefix0 … prefix{count−1}`.
pub fn names(prefix: &str, count: usize) -> Vec<String> {
    (0..count).map(|k| format!("{prefix}{k}")).collect()
}

fn leak(s: String) -> &'static str {
    Box::leak(s.into_boxed_str())
}

fn text<'s>(source: &'s Source, key: &str) -> Option<&'s str> {
    source
        .texts
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, t)| t.as_str())
}

/// The names a formula may use: state variables, `t`, parameters.
struct Names {
    all: Vec<String>,
    state: Vec<&'static str>,
}

impl Names {
    fn new(kind: Kind, params: &[String]) -> Names {
        let state: Vec<&'static str> = match kind {
            Kind::Mechanical { dof: 1 } => vec!["q", "p", "s"],
            Kind::Mechanical { dof } => Q[..dof]
                .iter()
                .chain(&P[..dof])
                .copied()
                .chain(["s"])
                .collect(),
            Kind::Lienard => vec!["q", "s", "p"],
        };
        let mut all: Vec<String> = state.iter().map(|s| s.to_string()).collect();
        all.push("t".into());
        all.extend(params.iter().cloned());
        Names { all, state }
    }
    fn index(&self, name: &str) -> u32 {
        self.all
            .iter()
            .position(|n| n == name)
            .expect("a known name") as u32
    }
    /// The index of the internal sub-step `tau` (not a name formulas see).
    fn tau(&self) -> u32 {
        self.all.len() as u32
    }
}

fn build(source: &Source) -> Result<FormulaModel, ModelError> {
    check_source(source)?;
    let names = Names::new(source.kind, &source.params);
    let mut dag = Dag::new();
    let mut b = Builder {
        dag: &mut dag,
        names: &names,
        source,
        ops: vec![],
        functions: vec![],
    };
    match source.kind {
        Kind::Mechanical { dof } => b.mechanical(dof)?,
        Kind::Lienard => b.lienard()?,
    }
    let ops = std::mem::take(&mut b.ops);
    let functions = std::mem::take(&mut b.functions);
    let used: Vec<u32> = {
        let mut u: Vec<u32> = ops
            .iter()
            .flat_map(|(_, roots, _)| roots.iter().flat_map(|r| dag.uses(*r)))
            .collect();
        u.sort_unstable();
        u.dedup();
        u
    };
    let unused = source
        .params
        .iter()
        .filter(|p| !used.contains(&names.index(p)))
        .cloned()
        .collect();
    let time = used.contains(&names.index("t"));
    let mut inputs: Vec<&'static str> = names.state.clone();
    inputs.push("t");
    inputs.extend(&SLOTS[..source.params.len()]);
    inputs.push("tau");
    let mut roots = HashMap::new();
    let mut formula_ops = vec![];
    for (name, r, outputs) in ops {
        formula_ops.push(FormulaOp {
            name,
            program: lower(&dag, &r),
            outputs,
        });
        roots.insert(name, r);
    }
    let mut functions = functions;
    for f in &mut functions {
        f.inputs = dag
            .uses(f.root)
            .into_iter()
            .map(|v| inputs[v as usize])
            .collect();
    }
    let spec = spec(source, &names, time, &formula_ops);
    Ok(FormulaModel {
        source: source.clone(),
        spec,
        inputs,
        ops: formula_ops,
        unused,
        dag,
        roots,
        functions,
    })
}

/// Counts and names the scene controls: dof, parameter count, reserved names.
fn check_source(source: &Source) -> Result<(), ModelError> {
    let err = |field: &str, message: String| ModelError {
        field: field.into(),
        column: None,
        message,
    };
    if let Kind::Mechanical { dof } = source.kind {
        if !(1..=MAX_DOF).contains(&dof) {
            return Err(err(
                "formula.dof",
                format!("must be 1 to {MAX_DOF} (got {dof})"),
            ));
        }
    }
    if source.params.len() > SLOTS.len() {
        return Err(err(
            "params",
            format!(
                "a formula model takes at most {} parameters (got {})",
                SLOTS.len(),
                source.params.len()
            ),
        ));
    }
    let names = Names::new(source.kind, &[]);
    for p in &source.params {
        let reserved = names.all.contains(p) || p == "pi" || p == "tau";
        let function = crate::num::formula::dag::FUNCTIONS
            .iter()
            .any(|(n, _, _)| n == p);
        if reserved || function {
            return Err(err(
                &format!("params.{p}"),
                format!("`{p}` is a variable or function name in formulas; name the parameter otherwise"),
            ));
        }
    }
    Ok(())
}

/// A mechanical system's formulas in the DAG: positions and momenta, V, K,
/// f and the gradients of V and K.
struct MechanicalParts {
    qs: Vec<&'static str>,
    ps: Vec<&'static str>,
    v: Id,
    k: Id,
    f: Id,
    grad_v: Vec<Id>,
    grad_k: Vec<Id>,
}

/// Builds the ops of a model in one DAG.
struct Builder<'a> {
    dag: &'a mut Dag,
    names: &'a Names,
    source: &'a Source,
    /// `(op name, roots, output lanes)`, optional-variable ops first in a piece.
    ops: Vec<(&'static str, Vec<Id>, Vec<&'static str>)>,
    functions: Vec<Function>,
}

impl Builder<'_> {
    /// Records `root` as function `name` of formula `key`.
    fn function(&mut self, key: &str, name: String, root: Id) {
        self.functions.push(Function {
            field: format!("formula.{key}"),
            name,
            inputs: vec![],
            root,
        });
    }

    /// Formula `key` (or `default`) over the names, using only `allowed`
    /// variables beyond the parameters.
    fn formula(&mut self, key: &str, default: &str, allowed: &[&str]) -> Result<Id, ModelError> {
        let field = format!("formula.{key}");
        let text = text(self.source, key).unwrap_or(default);
        let all: Vec<&str> = self.names.all.iter().map(|s| s.as_str()).collect();
        let root = compile(self.dag, text, &all).map_err(|e| self.explain(&field, text, e))?;
        for v in self.dag.uses(root) {
            let name = &self.names.all[v as usize];
            let is_var = (v as usize) <= self.names.state.len();
            if is_var && !allowed.contains(&name.as_str()) {
                return Err(ModelError {
                    field,
                    column: word_at(text, name),
                    message: format!(
                        "{} cannot depend on `{name}` (it may use {}, and the parameters): the piece's flow is exact only then",
                        signature(key),
                        allowed.join(", ")
                    ),
                });
            }
        }
        Ok(root)
    }

    /// A formula error, with the degrees of freedom explained when the
    /// unknown name is a variable of another dof.
    fn explain(&self, field: &str, text: &str, e: FormulaError) -> ModelError {
        // The parser counts characters, the model error bytes.
        let at = text
            .char_indices()
            .nth(e.column)
            .map_or(text.len(), |(i, _)| i);
        let word: String = text[at..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let looks_like_var = !word.is_empty()
            && (word.starts_with('q') || word.starts_with('p'))
            && word[1..].chars().all(|c| c.is_ascii_digit());
        let message = match self.source.kind {
            Kind::Mechanical { dof } if looks_like_var && e.message.contains("unknown name") => {
                format!(
                    "`{word}` is not a variable of a system with dof = {dof} (its variables: {}); set `dof` in [formula] to match the variables used",
                    self.names.state.join(", ")
                )
            }
            _ => e.message,
        };
        ModelError {
            field: field.into(),
            column: Some(at),
            message,
        }
    }

    fn var(&mut self, name: &str) -> Id {
        let k = self.names.index(name);
        self.dag.var(k)
    }
    fn tau(&mut self) -> Id {
        let k = self.names.tau();
        self.dag.var(k)
    }
    /// `x + c·tau·y`.
    fn step(&mut self, x: Id, c: f64, y: Id) -> Id {
        let tau = self.tau();
        let c = self.dag.num(c);
        let ty = self.dag.mul(tau, y);
        let cty = self.dag.mul(c, ty);
        self.dag.add(x, cty)
    }
    /// `e^{−tau·f}`.
    fn decay(&mut self, f: Id) -> Id {
        let tau = self.tau();
        let tf = self.dag.mul(tau, f);
        let m = self.dag.neg(tf);
        self.dag.call(Func::Exp, m)
    }
    fn op(&mut self, name: &'static str, roots: Vec<Id>, outputs: Vec<&'static str>) {
        self.ops.push((name, roots, outputs));
    }

    /// SPEC §2.1 with a general K(p): pieces A (f s), B (V), C (K).
    fn mechanical(&mut self, dof: usize) -> Result<(), ModelError> {
        let (qs, ps): (Vec<&'static str>, Vec<&'static str>) = if dof == 1 {
            (vec!["q"], vec!["p"])
        } else {
            (Q[..dof].to_vec(), P[..dof].to_vec())
        };
        let mut qt = qs.clone();
        qt.push("t");
        let default_k = ps
            .iter()
            .map(|p| format!("{p}^2"))
            .collect::<Vec<_>>()
            .join(" + ");
        let v = self.formula("potential", "0", &qt)?;
        let k = self.formula("kinetic", &format!("({default_k})/2"), &ps)?;
        let f = self.formula("damping", "0", &["t"])?;
        let qi: Vec<u32> = qs.iter().map(|n| self.names.index(n)).collect();
        let pi: Vec<u32> = ps.iter().map(|n| self.names.index(n)).collect();
        let grad_v = self.dag.gradient(v, &qi);
        let grad_k = self.dag.gradient(k, &pi);
        self.function("potential", "V".into(), v);
        for (q, d) in qs.iter().zip(&grad_v) {
            self.function("potential", format!("∂V/∂{q}"), *d);
        }
        self.function("kinetic", "K".into(), k);
        for (p, d) in ps.iter().zip(&grad_k) {
            self.function("kinetic", format!("∂K/∂{p}"), *d);
        }
        self.function("damping", "f".into(), f);
        let (pv, qv, s) = (
            ps.iter().map(|n| self.var(n)).collect::<Vec<_>>(),
            qs.iter().map(|n| self.var(n)).collect::<Vec<_>>(),
            self.var("s"),
        );
        // p·∇K − K: the s-rate of piece C.
        let mut pdk = self.dag.num(0.0);
        for (p, dk) in pv.iter().zip(&grad_k) {
            let t = self.dag.mul(*p, *dk);
            pdk = self.dag.add(pdk, t);
        }
        let c_rate = self.dag.sub(pdk, k);
        if self.dag.constant(f) != Some(0.0) {
            let e = self.decay(f);
            let se = self.dag.mul(s, e);
            self.op("formula_a_opt", vec![se], vec!["s"]);
            let pe = pv.iter().map(|p| self.dag.mul(*p, e)).collect();
            self.op("formula_a", pe, ps.clone());
        }
        let sb = self.step(s, -1.0, v);
        self.op("formula_b_opt", vec![sb], vec!["s"]);
        let pb = pv
            .iter()
            .zip(&grad_v)
            .map(|(p, d)| self.step(*p, -1.0, *d))
            .collect();
        self.op("formula_b", pb, ps.clone());
        let sc = self.step(s, 1.0, c_rate);
        self.op("formula_c_opt", vec![sc], vec!["s"]);
        let qc = qv
            .iter()
            .zip(&grad_k)
            .map(|(q, d)| self.step(*q, 1.0, *d))
            .collect();
        self.op("formula_c", qc, qs.clone());
        // The vector field: q' = ∇K, p' = −∇V − f p, s' = p·∇K − K − V − f s.
        let mut field = grad_k.clone();
        let mut outs: Vec<&'static str> = qs.iter().map(|q| leak(format!("d{q}"))).collect();
        for ((p, dv), name) in pv.iter().zip(&grad_v).zip(&ps) {
            let fp = self.dag.mul(f, *p);
            let sum = self.dag.add(*dv, fp);
            field.push(self.dag.neg(sum));
            outs.push(leak(format!("d{name}")));
        }
        self.op("formula_field", field.clone(), outs);
        let cv = self.dag.sub(c_rate, v);
        let fs = self.dag.mul(f, s);
        let ds = self.dag.sub(cv, fs);
        self.op("formula_field_opt", vec![ds], vec!["ds"]);
        field.push(ds);
        let m = MechanicalParts {
            qs,
            ps,
            v,
            k,
            f,
            grad_v,
            grad_k,
        };
        self.mechanical_methods(&m, &field, &default_k);
        Ok(())
    }

    /// The contact variational integrators for `K = |p|²/2` (seed 000,
    /// examples 1, 2 and 6; the built-in mechanical models' methods):
    /// `q' = q + τ c p − τ²/2 ∇V(q, t)`, `p' = (c p − τ/2 (∇V + ∇V')) / d`,
    /// `s' = (c s + τ (|q' − q|²/(2τ²) − (V + V')/2)) / d` with `c = 1 − τ f`,
    /// `d = 1` (first order) or `c = 1 − τ/2 f`, `d = 1 + τ/2 f` (second),
    /// `f` at the step's midpoint.
    fn variational(&mut self, m: &MechanicalParts, second: bool) -> Vec<Id> {
        let (qs, ps, grad_v) = (&m.qs[..], &m.ps[..], &m.grad_v[..]);
        let (v, f) = (m.v, m.f);
        let (t, tau, s) = (self.var("t"), self.tau(), self.var("s"));
        let q: Vec<Id> = qs.iter().map(|n| self.var(n)).collect();
        let p: Vec<Id> = ps.iter().map(|n| self.var(n)).collect();
        let (half, one) = (self.dag.num(0.5), self.dag.num(1.0));
        let hh = self.dag.mul(half, tau);
        let (tm, t1) = (self.dag.add(t, hh), self.dag.add(t, tau));
        let fm = self.at(&[f], &[], &[], tm)[0];
        let w = if second { hh } else { tau };
        let wf = self.dag.mul(w, fm);
        let c = self.dag.sub(one, wf);
        let d = if second { self.dag.add(one, wf) } else { one };
        let tc = self.dag.mul(tau, c);
        let htt = self.dag.mul(hh, tau);
        let mhtt = self.dag.neg(htt);
        let drift = self.axpy(&q, tc, &p);
        let qn = self.axpy(&drift, mhtt, grad_v);
        let (v1, dv1) = {
            let mut r = self.at(&[v], qs, &qn, t1);
            r.extend(self.at(grad_v, qs, &qn, t1));
            (r[0], r[1..].to_vec())
        };
        let mut vel2 = self.dag.num(0.0);
        for (a, b) in qn.iter().zip(&q) {
            let dq = self.dag.sub(*a, *b);
            let vel = self.dag.div(dq, tau);
            let sq = self.dag.mul(vel, vel);
            vel2 = self.dag.add(vel2, sq);
        }
        let kin = self.dag.mul(half, vel2);
        let s1 = self.action(s, c, tau, kin, (v, v1), d);
        let mut out = qn;
        for ((pk, d0), d1) in p.iter().zip(grad_v).zip(&dv1) {
            let cp = self.dag.mul(c, *pk);
            let sum = self.dag.add(*d0, *d1);
            let hs = self.dag.mul(hh, sum);
            let num = self.dag.sub(cp, hs);
            let pn = self.dag.div(num, d);
            out.push(pn);
        }
        out.push(s1);
        out
    }

    /// The action step of the variational and leapfrog methods:
    /// `s' = (c s + τ (kinetic − (V + V')/2)) / d`, the Lagrangian by the
    /// trapezoidal rule in V.
    fn action(&mut self, s: Id, c: Id, tau: Id, kinetic: Id, (v, v1): (Id, Id), d: Id) -> Id {
        let half = self.dag.num(0.5);
        let vv = self.dag.add(v, v1);
        let vmean = self.dag.mul(half, vv);
        let l = self.dag.sub(kinetic, vmean);
        let tl = self.dag.mul(tau, l);
        let sc = self.dag.mul(s, c);
        let top = self.dag.add(sc, tl);
        self.dag.div(top, d)
    }

    /// The comparison integrators on (q, p, s), `field` their vector field;
    /// the contact variational ones only for `K = |p|²/2`.
    fn mechanical_methods(&mut self, m: &MechanicalParts, field: &[Id], default_k: &str) {
        let vars: Vec<&'static str> = m.qs.iter().chain(&m.ps).copied().chain(["s"]).collect();
        let rk4 = self.rk4(&vars, field);
        self.op("formula_rk4", rk4, vars.clone());
        let lf = self.mechanical_leapfrog(m);
        self.op("formula_leapfrog", lf, vars.clone());
        let all: Vec<&str> = self.names.all.iter().map(|n| n.as_str()).collect();
        let half_p2 = compile(self.dag, &format!("({default_k})/2"), &all).ok();
        if half_p2 == Some(m.k) {
            for (name, second) in [
                ("formula_variational1", false),
                ("formula_variational2", true),
            ] {
                let x = self.variational(m, second);
                self.op(name, x, vars.clone());
            }
        }
    }

    /// `roots` with the variables `vars` replaced by `values` and `t` by `t`.
    fn at(&mut self, roots: &[Id], vars: &[&str], values: &[Id], t: Id) -> Vec<Id> {
        let n = self.names.all.len() as u32 + 1;
        let mut env: Vec<Id> = (0..n).map(|k| self.dag.var(k)).collect();
        for (v, x) in vars.iter().zip(values) {
            env[self.names.index(v) as usize] = *x;
        }
        env[self.names.index("t") as usize] = t;
        self.dag.substitute(roots, &env)
    }

    /// `x + c·y` componentwise.
    fn axpy(&mut self, x: &[Id], c: Id, y: &[Id]) -> Vec<Id> {
        x.iter()
            .zip(y)
            .map(|(x, y)| {
                let cy = self.dag.mul(c, *y);
                self.dag.add(*x, cy)
            })
            .collect()
    }

    /// The classical RK4 step from `t` over `tau` of `vars` with the
    /// vector field `field` (as the built-in models' `rk4_combine`).
    fn rk4(&mut self, vars: &[&'static str], field: &[Id]) -> Vec<Id> {
        let x: Vec<Id> = vars.iter().map(|v| self.var(v)).collect();
        let (t, tau) = (self.var("t"), self.tau());
        let half = self.dag.num(0.5);
        let hh = self.dag.mul(half, tau);
        let (t2, t4) = (self.dag.add(t, hh), self.dag.add(t, tau));
        let k1 = self.at(field, vars, &x, t);
        let x2 = self.axpy(&x, hh, &k1);
        let k2 = self.at(field, vars, &x2, t2);
        let x3 = self.axpy(&x, hh, &k2);
        let k3 = self.at(field, vars, &x3, t2);
        let x4 = self.axpy(&x, tau, &k3);
        let k4 = self.at(field, vars, &x4, t4);
        let six = self.dag.num(6.0);
        let w = self.dag.div(tau, six);
        let two = self.dag.num(2.0);
        (0..x.len())
            .map(|i| {
                let k23 = self.dag.add(k2[i], k3[i]);
                let mid = self.dag.mul(two, k23);
                let sum = self.dag.add(k1[i], mid);
                let sum = self.dag.add(sum, k4[i]);
                let inc = self.dag.mul(w, sum);
                self.dag.add(x[i], inc)
            })
            .collect()
    }

    /// Leapfrog with the damping in the acceleration (the built-in
    /// mechanical models' method for any K): `p½ = (p − τ/2 ∇V(q, t)) /
    /// (1 + τ/2 f(t + τ/2))`, `q' = q + τ ∇K(p½)`, the action by the
    /// trapezoidal Lagrangian `p½·∇K(p½) − K(p½) − (V + V')/2`, then
    /// `p' = p½ − τ/2 (∇V(q', t + τ) + f p½)`.
    fn mechanical_leapfrog(&mut self, m: &MechanicalParts) -> Vec<Id> {
        let (qs, ps, grad_v, grad_k) = (&m.qs[..], &m.ps[..], &m.grad_v[..], &m.grad_k[..]);
        let (v, k, f) = (m.v, m.k, m.f);
        let (t, tau, s) = (self.var("t"), self.tau(), self.var("s"));
        let q: Vec<Id> = qs.iter().map(|n| self.var(n)).collect();
        let p: Vec<Id> = ps.iter().map(|n| self.var(n)).collect();
        let half = self.dag.num(0.5);
        let hh = self.dag.mul(half, tau);
        let (tm, t1) = (self.dag.add(t, hh), self.dag.add(t, tau));
        let fm = self.at(&[f], &[], &[], tm)[0];
        let hf = self.dag.mul(hh, fm);
        let one = self.dag.num(1.0);
        let (den, num) = (self.dag.add(one, hf), self.dag.sub(one, hf));
        let mhh = self.dag.neg(hh);
        let kick = self.axpy(&p, mhh, grad_v);
        let ph: Vec<Id> = kick.iter().map(|x| self.dag.div(*x, den)).collect();
        let dk = self.at(grad_k, ps, &ph, t);
        let qn = self.axpy(&q, tau, &dk);
        let kh = self.at(&[k], ps, &ph, t)[0];
        let mut lag = self.dag.neg(kh);
        for (a, b) in ph.iter().zip(&dk) {
            let ab = self.dag.mul(*a, *b);
            lag = self.dag.add(lag, ab);
        }
        let v1 = self.at(&[v], qs, &qn, t1)[0];
        let s1 = self.action(s, num, tau, lag, (v, v1), den);
        let dv1 = self.at(grad_v, qs, &qn, t1);
        let mut out = qn;
        for (d, x) in dv1.iter().zip(&ph) {
            let fx = self.dag.mul(fm, *x);
            let sum = self.dag.add(*d, fx);
            let hs = self.dag.mul(hh, sum);
            let pn = self.dag.sub(*x, hs);
            out.push(pn);
        }
        out.push(s1);
        out
    }

    /// SPEC §2.2 with general f(q), g(q, t): pieces A (f s), B (g), C (p s).
    fn lienard(&mut self) -> Result<(), ModelError> {
        let f = self.formula("f", "0", &["q", "t"])?;
        let g = self.formula("g", "0", &["q", "t"])?;
        let qk = self.names.index("q");
        let df = self.dag.diff(f, qk);
        let dg = self.dag.diff(g, qk);
        for (key, name, root) in [
            ("f", "f", f),
            ("f", "∂f/∂q", df),
            ("g", "g", g),
            ("g", "∂g/∂q", dg),
        ] {
            self.function(key, name.into(), root);
        }
        let (q, s, p) = (self.var("q"), self.var("s"), self.var("p"));
        let tau = self.tau();
        // C: q ← q + τ s, p ← p/(1 + τ p).
        let tp = self.dag.mul(tau, p);
        let one = self.dag.num(1.0);
        let den = self.dag.add(one, tp);
        let pc = self.dag.div(p, den);
        self.op("formula_c_opt", vec![pc], vec!["p"]);
        let qc = self.step(q, 1.0, s);
        self.op("formula_c", vec![qc], vec!["q"]);
        // B: s ← s − τ g, p ← p − τ ∂g/∂q.
        let pb = self.step(p, -1.0, dg);
        self.op("formula_b_opt", vec![pb], vec!["p"]);
        let sb = self.step(s, -1.0, g);
        self.op("formula_b", vec![sb], vec!["s"]);
        // A: s ← s e^{−τf}, p ← (p − τ f′ s) e^{−τf} (s before its update).
        let e = self.decay(f);
        let dfs = self.dag.mul(df, s);
        let inner = self.step(p, -1.0, dfs);
        let pa = self.dag.mul(inner, e);
        self.op("formula_a_opt", vec![pa], vec!["p"]);
        let sa = self.dag.mul(s, e);
        self.op("formula_a", vec![sa], vec!["s"]);
        // Field: q' = s, s' = −f s − g, p' = −p² − f p − f′ s − ∂g/∂q.
        let fs = self.dag.mul(f, s);
        let fsg = self.dag.add(fs, g);
        let ds = self.dag.neg(fsg);
        self.op("formula_field", vec![s, ds], vec!["dq", "ds"]);
        let p2 = self.dag.powi(p, 2);
        let fp = self.dag.mul(f, p);
        let mut sum = self.dag.add(p2, fp);
        sum = self.dag.add(sum, dfs);
        sum = self.dag.add(sum, dg);
        let dp = self.dag.neg(sum);
        self.op("formula_field_opt", vec![dp], vec!["dp"]);
        // The comparison integrators on (q, s).
        let rk4 = self.rk4(&["q", "s"], &[s, ds]);
        self.op("formula_rk4", rk4, vec!["q", "s"]);
        let lf = self.lienard_leapfrog(f, g);
        self.op("formula_leapfrog", lf, vec!["q", "s"]);
        Ok(())
    }

    /// Leapfrog with the damping in the acceleration, velocity s (the
    /// built-in Liénard models' method): `s½ = (s − τ/2 g(q, t)) / (1 + τ/2
    /// f(q, t))`, `q' = q + τ s½`, `s' = s½ − τ/2 (g(q', t + τ) + f(q', t + τ) s½)`.
    fn lienard_leapfrog(&mut self, f: Id, g: Id) -> Vec<Id> {
        let (q, s, t, tau) = (self.var("q"), self.var("s"), self.var("t"), self.tau());
        let half = self.dag.num(0.5);
        let hh = self.dag.mul(half, tau);
        let one = self.dag.num(1.0);
        let hf = self.dag.mul(hh, f);
        let den = self.dag.add(one, hf);
        let hg = self.dag.mul(hh, g);
        let top = self.dag.sub(s, hg);
        let sh = self.dag.div(top, den);
        let qn = self.step(q, 1.0, sh);
        let t1 = self.dag.add(t, tau);
        let fg = self.at(&[f, g], &["q"], &[qn], t1);
        let fs = self.dag.mul(fg[0], sh);
        let sum = self.dag.add(fg[1], fs);
        let hs = self.dag.mul(hh, sum);
        let sn = self.dag.sub(sh, hs);
        vec![qn, sn]
    }
}

/// The column of the first whole-word `name` in `text` (not the `p` inside
/// `epsilon`).
fn word_at(text: &str, name: &str) -> Option<usize> {
    let ident = |c: char| c.is_alphanumeric() || c == '_';
    text.match_indices(name).map(|(i, _)| i).find(|&i| {
        let before = text[..i].chars().next_back();
        let after = text[i + name.len()..].chars().next();
        !before.is_some_and(ident) && !after.is_some_and(ident)
    })
}

/// How a formula key reads in messages.
fn signature(key: &str) -> &'static str {
    match key {
        "potential" => "the potential V(q, t)",
        "kinetic" => "the kinetic energy K(p)",
        "damping" => "the damping f(t)",
        "f" => "f(q, t)",
        _ => "g(q, t)",
    }
}

/// The model's spec: its variables, parameters and pieces (op lists).
fn spec(source: &Source, names: &Names, time: bool, ops: &[FormulaOp]) -> ModelSpec {
    let has = |n: &str| ops.iter().any(|o| o.name == n);
    let piece = |c: char, main: &'static str, opt: &'static str| {
        let mut list: Vec<(&'static str, bool)> = vec![];
        if has(opt) {
            list.push((opt, true));
        }
        if has(main) {
            list.push((main, false));
        }
        PieceOps {
            piece: c,
            ops: Box::leak(list.into_boxed_slice()),
            identity_when_zero: &[],
        }
    };
    let piece_ops = vec![
        piece('A', "formula_a", "formula_a_opt"),
        piece('B', "formula_b", "formula_b_opt"),
        piece('C', "formula_c", "formula_c_opt"),
    ];
    let methods: Vec<(Method, &'static str)> = [
        (Method::Rk4, "formula_rk4"),
        (Method::Leapfrog, "formula_leapfrog"),
        (Method::Variational1, "formula_variational1"),
        (Method::Variational2, "formula_variational2"),
    ]
    .into_iter()
    .filter(|(_, op)| has(op))
    .collect();
    let params: Vec<ParamDef> = source
        .params
        .iter()
        .map(|p| ParamDef::required(leak(p.clone()), "a parameter of the formulas"))
        .collect();
    let (name, optional) = match source.kind {
        Kind::Mechanical { .. } => ("mechanical", "s"),
        Kind::Lienard => ("lienard", "p"),
    };
    let summary = source
        .texts
        .iter()
        .map(|(k, t)| format!("{k} = {t}"))
        .collect::<Vec<_>>()
        .join("; ");
    ModelSpec {
        name,
        summary: leak(summary),
        vars: Box::leak(names.state.clone().into_boxed_slice()),
        optional_var: Some(optional),
        params: Box::leak(params.into_boxed_slice()),
        pieces: "ABC",
        default_order: "CBABC",
        time: if time {
            TimeDependence::Always
        } else {
            TimeDependence::Never
        },
        time_ops: &[],
        piece_ops: Box::leak(piece_ops.into_boxed_slice()),
        field_ops: &[("formula_field", false), ("formula_field_opt", true)],
        methods: Box::leak(methods.into_boxed_slice()),
        wgsl: &[],
        forcing_frequency: source
            .forcing_frequency
            .as_ref()
            .and_then(|w| source.params.iter().position(|p| p == w))
            .map(|k| SLOTS[k]),
        derived: &[],
        initial_defaults: &[],
        initial_alias: None,
        methods_carry_optional: matches!(source.kind, Kind::Mechanical { .. }),
        rules: super::spec::no_rules,
    }
}
