//! Writes `tangent_ops.rs`: each built-in piece op's tangent as Rust, from
//! the op's one source. The op runs symbolically from its shared-function
//! text (`symbolic.rs`), the lanes it writes are differentiated along a
//! deviation (`Dag::directional`) and the result is lowered and printed —
//! the same derivatives the tape and WGSL paths evaluate, compiled. The
//! test below fails when the checked-in file differs from what this writes;
//! `REEB_BLESS=1 cargo test --lib tangent_ops_are_generated` rewrites it.

use std::fmt::Write;

use crate::num::formula::dag::Func;
use crate::num::formula::lower::{lower, Lowered, Operand, Prim};
use crate::num::formula::Id;

use super::symbolic::LaneFormulas;
use super::{op_args, Model, MODEL_NAMES};

/// The lanes whose deviations a tangent op carries: every model's state
/// variables (parameters, τ, time and time terms are not directions).
fn active(lane: &str) -> bool {
    MODEL_NAMES
        .iter()
        .filter_map(|m| Model::from_name(m))
        .any(|m| m.spec().vars.contains(&lane))
}

/// Every op of the built-in models' pieces, each once, with its model.
fn piece_ops() -> Vec<(Model, &'static str)> {
    let mut ops: Vec<(Model, &'static str)> = vec![];
    for name in MODEL_NAMES {
        let model = Model::from_name(name).expect("a built-in model");
        for piece in model.spec().piece_ops {
            for (op, _) in piece.ops {
                if !ops.iter().any(|(_, o)| o == op) {
                    ops.push((model.clone(), op));
                }
            }
        }
    }
    ops
}

/// The tangent of `op` as a function `op(x, d)`: `d`'s written lanes
/// become their derivatives along `d` at `x`, the lanes before the op.
/// `None` where the op does not run symbolically (Lane–Emden's power of a
/// per-trajectory index).
fn tangent_fn(model: &Model, op: &str) -> Option<String> {
    let mut f = LaneFormulas::new(model);
    f.apply(model, op).ok()?;
    let written: Vec<&'static str> = op_args(op)?.iter().filter(|a| a.1).map(|a| a.0).collect();
    let after: Vec<Id> = written.iter().map(|l| f.read(l)).collect();
    let lanes = f.variables.clone();
    let base = lanes.len() as u32;
    let mut seed = |dag: &mut crate::num::formula::Dag, v: u32| {
        if active(lanes[v as usize]) {
            dag.var(base + v)
        } else {
            dag.num(0.0)
        }
    };
    let roots = f.dag.directional(&after, &mut seed);
    let program = lower(&f.dag, &roots).signs_outward();
    let input = |k: u32| match k.checked_sub(base) {
        Some(j) => format!("d.{}", lanes[j as usize]),
        None => format!("x.{}", lanes[k as usize]),
    };
    Some(body(op, &program, &input, &written))
}

/// The Rust text of `program` as the function `name`.
fn body(name: &str, l: &Lowered, input: &dyn Fn(u32) -> String, written: &[&str]) -> String {
    let mut s = String::new();
    writeln!(s, "#[inline(always)]").unwrap();
    writeln!(s, "pub fn {name}<R: Real>(x: &Lane<R>, d: &mut Lane<R>) {{").unwrap();
    writeln!(s, "    let _ = x;").unwrap();
    s.push_str(&rust_lets(l, input, "    "));
    // Every read before any write: the outputs change together.
    for (k, o) in l.outputs.iter().enumerate() {
        writeln!(s, "    let o{k}: R = {};", rust_operand(*o, input)).unwrap();
    }
    for (k, w) in written.iter().enumerate() {
        writeln!(s, "    d.{w} = o{k};").unwrap();
    }
    s.push_str("}\n");
    s
}

/// An operand of a lowered program as Rust: `input(k)` names input k.
pub fn rust_operand(o: Operand, input: &dyn Fn(u32) -> String) -> String {
    match o {
        Operand::Val(k) => format!("v{k}"),
        Operand::Input(k) => input(k),
        Operand::Const(c) => format!("R::from_f64({c:?})"),
    }
}

/// A lowered program's instructions as Rust, one `let vK: R = …;` each,
/// in the precision `R` and with the same functions the tape calls. The
/// sine and cosine of one operand are one `sincos_r` (what `sin_r` and
/// `cos_r` each call: the same bits), where the first of them stood: two
/// calls left LLVM two copies of its selects (spin–orbit tangent stage,
/// AVX2 f32: 126 → 120 instructions per 8 lanes).
pub fn rust_lets(l: &Lowered, input: &dyn Fn(u32) -> String, indent: &str) -> String {
    // The instruction calling `f` on operand `a`, if any.
    let call_of = |f: Func, a: Operand| {
        l.instrs
            .iter()
            .position(|j| j.op == Prim::Call(f) && j.a == a)
    };
    let mut s = String::new();
    for (k, i) in l.instrs.iter().enumerate() {
        let (a, b) = (rust_operand(i.a, input), rust_operand(i.b, input));
        let pair = match i.op {
            Prim::Call(Func::Sin) => call_of(Func::Cos, i.a).map(|c| (k, c)),
            Prim::Call(Func::Cos) => call_of(Func::Sin, i.a).map(|sn| (sn, k)),
            _ => None,
        };
        match pair {
            Some((sn, c)) if sn.min(c) == k => writeln!(
                s,
                "{indent}let (mut v{sn}, mut v{c}): (R, R) = (R::from_f64(0.0), R::from_f64(0.0));\n\
                 {indent}R::sincos_r({a}, &mut v{sn}, &mut v{c});"
            )
            .unwrap(),
            Some(_) => {}
            None => writeln!(s, "{indent}let v{k}: R = {};", i.op.expression(&a, &b, "R::")).unwrap(),
        }
    }
    s
}

/// The text of `tangent_ops.rs`.
pub fn generate() -> String {
    let mut s = String::from(
        "//! GENERATED by `models/tangent_gen.rs` (`REEB_BLESS=1 cargo test --lib\n\
         //! tangent_ops_are_generated`); do not edit. Each built-in piece op's\n\
         //! tangent: `op(x, d)` sets the deviations `d` of the lanes the op\n\
         //! writes from those of the lanes it reads, at `x` before the op\n\
         //! (see `Pieces::piece_tangent`).\n\n\
         #![allow(clippy::all, unused_variables, unused_parens)]\n\n\
         use super::lanes::Lane;\n\
         use crate::num::precision::Real;\n\n",
    );
    let mut missing = vec![];
    for (model, op) in piece_ops() {
        match tangent_fn(&model, op) {
            Some(text) => s.push_str(&text),
            None => {
                missing.push(op);
                writeln!(s, "#[inline(always)]\npub fn {op}<R: Real>(_: &Lane<R>, _: &mut Lane<R>) {{\n    unreachable!(\"`{op}` has no compiled tangent (see UNSUPPORTED)\")\n}}").unwrap();
            }
        }
        s.push('\n');
    }
    writeln!(
        s,
        "/// Ops without a compiled tangent: plans with them keep the tape.\npub const UNSUPPORTED: &[&str] = &{missing:?};"
    )
    .unwrap();
    s
}

#[cfg(test)]
mod tests {
    #[test]
    fn tangent_ops_are_generated() {
        let text = super::generate();
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/src/models/tangent_ops.rs");
        if std::env::var("REEB_BLESS").is_ok_and(|v| v == "1") {
            std::fs::write(path, &text).unwrap();
        }
        let have = std::fs::read_to_string(path).unwrap_or_default();
        assert!(
            have == text,
            "src/models/tangent_ops.rs is not what models/tangent_gen.rs writes: \
             run `REEB_BLESS=1 cargo test --lib tangent_ops_are_generated`"
        );
    }
}
