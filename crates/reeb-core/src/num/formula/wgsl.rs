//! A [`Lowered`] program as a WGSL function: the GPU's half of "one
//! source" (the CPU runs the same program through `tape.rs`).

use std::fmt::Write;

use super::dag::Func;
use super::lower::{key, Lowered, Operand, Prim};

/// A WGSL literal for `v` (abstract float: full f64 precision, converted by
/// the compiler to the working precision exactly as `as f32` does).
pub fn lit(v: f64) -> String {
    let s = format!("{v:?}");
    let s = if s.contains('.') || s.contains('e') || !v.is_finite() {
        s
    } else {
        format!("{s}.0")
    };
    if v < 0.0 {
        format!("({s})")
    } else {
        s
    }
}

/// `fn name(...)` evaluating `l` over inputs named `inputs` (by the DAG's
/// variable index) and assigning output `k` to `*outputs[k]`. A name both
/// read and written is one pointer argument; every read comes before any
/// write, so the outputs are updated simultaneously.
pub fn function_text(name: &str, l: &Lowered, inputs: &[&str], outputs: &[&str]) -> String {
    let mut read: Vec<u32> = vec![];
    for i in &l.instrs {
        for o in [i.a, i.b] {
            if let Operand::Input(k) = o {
                read.push(k);
            }
        }
    }
    for o in &l.outputs {
        if let Operand::Input(k) = o {
            read.push(*k);
        }
    }
    read.sort_unstable();
    read.dedup();
    let by_ptr = |n: &str| outputs.contains(&n);
    let mut args: Vec<String> = read
        .iter()
        .map(|k| inputs[*k as usize])
        .filter(|n| !by_ptr(n))
        .map(|n| format!("{n}: R"))
        .collect();
    args.extend(outputs.iter().map(|n| format!("{n}: ptr<function, R>")));
    let operand = |o: Operand| match o {
        Operand::Val(k) => format!("v{k}"),
        Operand::Input(k) if by_ptr(inputs[k as usize]) => format!("(*{})", inputs[k as usize]),
        Operand::Input(k) => inputs[k as usize].to_string(),
        Operand::Const(c) => lit(c),
    };
    // The sine and cosine of one operand: one `sincos_r` at the first (each
    // of `sin_r`, `cos_r` evaluates both).
    let pairs = sin_cos_pairs(l);
    let mut body = String::new();
    for (k, i) in l.instrs.iter().enumerate() {
        let (a, b) = (operand(i.a), operand(i.b));
        if let Some(&(first, is_sin)) = pairs.get(&k) {
            if first == k {
                writeln!(
                    body,
                    "    var s{k}: R;\n    var c{k}: R;\n    sincos_r({a}, &s{k}, &c{k});"
                )
                .unwrap();
            }
            let v = if is_sin { 's' } else { 'c' };
            writeln!(body, "    let v{k}: R = {v}{first};").unwrap();
            continue;
        }
        let e = i.op.expression(&a, &b, "");
        writeln!(body, "    let v{k}: R = {e};").unwrap();
    }
    // Outputs read as values first, then written.
    for (k, o) in l.outputs.iter().enumerate() {
        writeln!(body, "    let out{k}: R = {};", operand(*o)).unwrap();
    }
    for (k, n) in outputs.iter().enumerate() {
        writeln!(body, "    *{n} = out{k};").unwrap();
    }
    format!("fn {name}({}) {{\n{body}}}\n", args.join(", "))
}

/// For each `sin`/`cos` instruction whose operand also has the other one:
/// (the first of the two, whether it is the sine).
fn sin_cos_pairs(l: &Lowered) -> std::collections::HashMap<usize, (usize, bool)> {
    use std::collections::HashMap;
    let mut sin: HashMap<u64, usize> = HashMap::new();
    let mut cos: HashMap<u64, usize> = HashMap::new();
    for (k, i) in l.instrs.iter().enumerate() {
        match i.op {
            Prim::Call(Func::Sin) => sin.entry(key(i.a)).or_insert(k),
            Prim::Call(Func::Cos) => cos.entry(key(i.a)).or_insert(k),
            _ => continue,
        };
    }
    let mut out = HashMap::new();
    for (x, &ks) in &sin {
        if let Some(&kc) = cos.get(x) {
            let first = ks.min(kc);
            out.insert(ks, (first, true));
            out.insert(kc, (first, false));
        }
    }
    out
}
