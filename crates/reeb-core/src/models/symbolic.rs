//! A model's ops as formulas in one DAG, from each op's one source: a
//! built-in model's ops run symbolically from their shared-function text
//! (`num/formula/symbolic.rs`), a formula model's as compiled. Applying a
//! step's ops in order gives the numerical one-step map as formulas of the
//! state at the step's start, whose derivatives are the tangent map
//! (`plan/tangent.rs`).

use std::collections::HashMap;
use std::sync::OnceLock;

use crate::num::formula::symbolic::{Library, SymbolicError, Val};
use crate::num::formula::{Dag, Id};

use super::{op_args, Model, COMMON_WGSL, MODEL_NAMES};

/// Lane values as formulas: what each lane holds now, over variables that
/// are the lanes' values before the first op (a lane becomes a variable
/// when it is first read).
#[derive(Debug, Clone)]
pub struct LaneFormulas {
    pub dag: Dag,
    /// The lane of each variable of the DAG, by index.
    pub variables: Vec<&'static str>,
    now: HashMap<&'static str, Id>,
}

impl LaneFormulas {
    /// Lanes of `model` before any op: a formula model's DAG (its inputs
    /// are the first variables), an empty one for a built-in model.
    pub fn new(model: &Model) -> LaneFormulas {
        let (dag, variables) = match model.formula() {
            Some(m) => (
                m.op_roots("formula_field").map(|r| r.0.clone()),
                m.inputs.clone(),
            ),
            None => (None, Vec::new()),
        };
        let mut f = LaneFormulas {
            dag: dag.unwrap_or_default(),
            variables: Vec::new(),
            now: HashMap::new(),
        };
        for lane in variables {
            f.read(lane);
        }
        f
    }

    /// What lane `lane` holds now.
    pub fn read(&mut self, lane: &'static str) -> Id {
        if let Some(id) = self.now.get(lane) {
            return *id;
        }
        let id = self.dag.var(self.variables.len() as u32);
        self.variables.push(lane);
        self.now.insert(lane, id);
        id
    }

    /// Lane `lane` holds a new variable from here on, whatever it held: a
    /// value the step reads from elsewhere (a table of time terms).
    pub fn fresh(&mut self, lane: &'static str) -> Id {
        let id = self.dag.var(self.variables.len() as u32);
        self.variables.push(lane);
        self.now.insert(lane, id);
        id
    }

    /// Lane `lane` holds the known value `v` (not a variable): a parameter
    /// of one value, so that what depends on it only (Lane–Emden's integer
    /// index) folds while the formulas are built.
    pub fn know(&mut self, lane: &'static str, v: f64) {
        let id = self.dag.num(v);
        self.now.insert(lane, id);
    }

    pub fn write(&mut self, lane: &'static str, id: Id) {
        self.read(lane);
        self.now.insert(lane, id);
    }

    /// The variable index of lane `lane`, if it was read.
    pub fn variable(&self, lane: &str) -> Option<u32> {
        self.variables
            .iter()
            .position(|v| *v == lane)
            .map(|k| k as u32)
    }

    /// Applies op `name` of `model`: every lane it writes gets its formula.
    pub fn apply(&mut self, model: &Model, name: &str) -> Result<(), SymbolicError> {
        match model.formula() {
            Some(m) => {
                let missing = || SymbolicError {
                    function: name.to_string(),
                    message: "not an op of this formula model".into(),
                };
                let (_, roots) = m.op_roots(name).ok_or_else(missing)?;
                let op = m.op(name).ok_or_else(missing)?;
                let values: Vec<Id> = m.inputs.iter().map(|l| self.read(l)).collect();
                let new = self.dag.substitute(roots, &values);
                for (lane, id) in op.outputs.iter().zip(new) {
                    self.write(lane, id);
                }
                Ok(())
            }
            None => self.apply_shared(name),
        }
    }

    /// A built-in op, run symbolically from its text.
    fn apply_shared(&mut self, name: &str) -> Result<(), SymbolicError> {
        let args = op_args(name).ok_or_else(|| SymbolicError {
            function: name.to_string(),
            message: "no such op".into(),
        })?;
        let values: Vec<Val> = args.iter().map(|(l, _)| Val::Real(self.read(l))).collect();
        let (_, outs) = library()?.call(&mut self.dag, name, &values)?;
        let written = args.iter().filter(|a| a.1).map(|a| a.0);
        for (lane, v) in written.zip(outs) {
            match v {
                Val::Real(id) => self.write(lane, id),
                _ => {
                    return Err(SymbolicError {
                        function: name.to_string(),
                        message: format!("writes a non-real value to `{lane}`"),
                    })
                }
            }
        }
        Ok(())
    }
}

/// Every built-in model's shared functions (their names are unique: one
/// trait holds them all), parsed once.
fn library() -> Result<&'static Library, SymbolicError> {
    static LIBRARY: OnceLock<Result<Library, SymbolicError>> = OnceLock::new();
    LIBRARY
        .get_or_init(|| {
            let mut texts: Vec<&str> = COMMON_WGSL.to_vec();
            for name in MODEL_NAMES {
                if let Some(m) = Model::from_name(name) {
                    texts.extend(m.spec().wgsl);
                }
            }
            Library::new(&texts)
        })
        .as_ref()
        .map_err(Clone::clone)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::lanes::Lane;
    use crate::models::scalar_fn;

    /// Every op of every built-in model, run symbolically and evaluated,
    /// gives what its compiled function gives (f64).
    #[test]
    fn built_in_ops_run_symbolically_as_compiled() {
        let mut checked = 0;
        for name in MODEL_NAMES {
            let model = Model::from_name(name).unwrap();
            let spec = model.spec();
            let mut ops: Vec<&str> = spec.time_ops.to_vec();
            ops.extend(
                spec.piece_ops
                    .iter()
                    .flat_map(|p| p.ops.iter().map(|o| o.0)),
            );
            ops.extend(spec.methods.iter().map(|m| m.1));
            for op in ops {
                let mut f = LaneFormulas::new(&model);
                if let Err(e) = f.apply(&model, op) {
                    // Only Lane–Emden's Horner power needs a known index.
                    assert!(e.message.contains("not known"), "{name}.{op}: {e}");
                    continue;
                }
                let mut lane = Lane::<f64>::default();
                for (k, v) in f.variables.iter().enumerate() {
                    *lane.get_mut(v).unwrap() = 0.3 + 0.17 * k as f64;
                }
                let inputs: Vec<f64> = f.variables.iter().map(|v| lane.get(v).unwrap()).collect();
                scalar_fn::<f64>(op).unwrap()(&mut lane);
                for (l, _) in op_args(op).unwrap().iter().filter(|a| a.1) {
                    let got = f.dag.eval(&[f.now[l]], &inputs)[0];
                    let want = lane.get(l).unwrap();
                    assert!(
                        (got - want).abs() <= 1e-13 * want.abs().max(1.0),
                        "{name}.{op}.{l}: {got} vs {want}"
                    );
                }
                checked += 1;
            }
        }
        assert!(checked > 40, "{checked} ops");
    }
}
