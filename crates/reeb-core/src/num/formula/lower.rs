//! A DAG's roots lowered to one straight-line program of primitive
//! instructions: what both backends run (`tape.rs` on the CPU, `wgsl.rs` on
//! the GPU), so that they evaluate the same operations in the same order.
//!
//! Lowering expands integer powers into one fixed chain of products, writes
//! `a + (−b)` as `a − b`, and keeps only the nodes the roots need. Every
//! function becomes a call of reeb's own shared function (`num/math.rs`).

use std::collections::HashMap;

use super::dag::{Dag, Func, Func2, Id, Node};

/// Where an instruction's operand comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Operand {
    /// The result of instruction `k`.
    Val(u32),
    /// Input variable `k` (as the DAG's `Var(k)`).
    Input(u32),
    Const(f64),
}

/// A primitive operation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Prim {
    Neg,
    Add,
    Sub,
    Mul,
    Div,
    Call(Func),
    Call2(Func2),
}

/// One instruction: `op(a, b)` (`b` unused by unary operations).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Instr {
    pub op: Prim,
    pub a: Operand,
    pub b: Operand,
}

/// A straight-line program: instructions in evaluation order (operands
/// before their users) and the operands that are the roots' values.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Lowered {
    pub instrs: Vec<Instr>,
    pub outputs: Vec<Operand>,
}

impl Prim {
    pub fn unary(self) -> bool {
        matches!(self, Prim::Neg | Prim::Call(_))
    }

    /// The instruction as an expression of its operands' text `a`, `b`,
    /// the same in WGSL and Rust: operators infix, calls with `call`
    /// before the function's name (`""` in WGSL, `"R::"` in Rust).
    pub fn expression(self, a: &str, b: &str, call: &str) -> String {
        match self {
            Prim::Neg => format!("-{a}"),
            Prim::Add => format!("{a} + {b}"),
            Prim::Sub => format!("{a} - {b}"),
            Prim::Mul => format!("{a} * {b}"),
            Prim::Div => format!("{a} / {b}"),
            Prim::Call(_) => format!("{call}{}({a})", self.function()),
            Prim::Call2(_) => format!("{call}{}({a}, {b})", self.function()),
        }
    }

    /// The name of a call's function: reeb's own (`num/math.rs` and the
    /// preludes), except the exactly rounded `sqrt` and `abs`; the same in
    /// WGSL (`wgsl.rs`) and as `R::name` in Rust (`models/tangent_gen.rs`).
    pub fn function(self) -> &'static str {
        match self {
            Prim::Call(f) => match f {
                Func::Sqrt => "sqrt",
                Func::Exp => "exp_r",
                Func::Log => "log_r",
                Func::Sin => "sin_r",
                Func::Cos => "cos_r",
                Func::Tan => "tan_r",
                Func::Atan => "atan_r",
                Func::Sinh => "sinh_r",
                Func::Cosh => "cosh_r",
                Func::Tanh => "tanh_r",
                Func::Abs => "abs",
                Func::Sign => "sign_r",
                Func::Octave => "octave_r",
                Func::Rescale => "rescale_r",
                Func::SampleLog => "sample_log_r",
            },
            Prim::Call2(f) => match f {
                Func2::Pow => "pow_r",
                Func2::Min => "min_r",
                Func2::Max => "max_r",
            },
            _ => unreachable!("{self:?} is an operator"),
        }
    }
}

impl Lowered {
    /// The inputs the program reads, each once, in increasing order.
    pub fn inputs_read(&self) -> Vec<u32> {
        let mut read: Vec<u32> = (self.instrs.iter())
            .flat_map(|i| [i.a, i.b])
            .chain(self.outputs.iter().copied())
            .filter_map(|o| match o {
                Operand::Input(k) => Some(k),
                _ => None,
            })
            .collect();
        read.sort_unstable();
        read.dedup();
        read
    }

    /// The same values with negations carried outward through products and
    /// quotients into the sums that take them, where `a + (−b)` and
    /// `a − (−b)` become `a − b` and `a + b`: fewer instructions (LLVM, given
    /// `x·(−sin y)`, pushes the negation into the clamps of `sin_r`'s selects
    /// and keeps two copies of them). Every rewrite is exact, signed zeros
    /// included (−x·y = −(x·y), and IEEE's a − b is a + (−b)); a negated
    /// value that only a call, a sum of two negated values or an output
    /// takes is negated as before.
    pub fn signs_outward(&self) -> Lowered {
        let mut s = Signs {
            out: Lowered::default(),
            rep: vec![],
            negs: HashMap::new(),
        };
        for i in &self.instrs {
            let (a, b) = (s.get(i.a), s.get(i.b));
            let r = s.rewrite(i.op, a, b);
            s.rep.push(r);
        }
        let outputs = self.outputs.iter().map(|o| s.get(*o)).collect::<Vec<_>>();
        s.out.outputs = outputs.into_iter().map(|r| s.plain(r)).collect();
        s.out
    }
}

/// [`Lowered::signs_outward`]'s work: each old instruction's value as
/// (operand, negated) in the new program.
struct Signs {
    out: Lowered,
    rep: Vec<(Operand, bool)>,
    /// The negation emitted of each operand, so that it is made once.
    negs: HashMap<u64, Operand>,
}

impl Signs {
    fn get(&self, o: Operand) -> (Operand, bool) {
        match o {
            Operand::Val(k) => self.rep[k as usize],
            _ => (o, false),
        }
    }
    fn emit(&mut self, op: Prim, a: Operand, b: Operand) -> Operand {
        self.out.instrs.push(Instr { op, a, b });
        Operand::Val(self.out.instrs.len() as u32 - 1)
    }
    /// The value of `r` as one operand: its negation emitted where needed.
    fn plain(&mut self, (o, neg): (Operand, bool)) -> Operand {
        if !neg {
            return o;
        }
        if let Some(n) = self.negs.get(&key(o)) {
            return *n;
        }
        let n = self.emit(Prim::Neg, o, Operand::Const(0.0));
        self.negs.insert(key(o), n);
        n
    }
    fn rewrite(&mut self, op: Prim, a: (Operand, bool), b: (Operand, bool)) -> (Operand, bool) {
        let (x, y) = (a.0, b.0);
        match (op, a.1, b.1) {
            (Prim::Neg, n, _) => (x, !n),
            (Prim::Mul | Prim::Div, na, nb) => (self.emit(op, x, y), na != nb),
            (Prim::Add, false, true) | (Prim::Sub, false, false) => {
                (self.emit(Prim::Sub, x, y), false)
            }
            (Prim::Add, true, false) | (Prim::Sub, true, true) => {
                (self.emit(Prim::Sub, y, x), false)
            }
            (Prim::Add, false, false) | (Prim::Sub, false, true) => {
                (self.emit(Prim::Add, x, y), false)
            }
            _ => {
                let (pa, pb) = (self.plain(a), self.plain(b));
                (self.emit(op, pa, pb), false)
            }
        }
    }
}

/// Lowers `roots` of `dag` into one program (shared nodes computed once).
pub fn lower(dag: &Dag, roots: &[Id]) -> Lowered {
    let mut l = Lowering {
        dag,
        done: vec![None; dag.nodes().len()],
        made: HashMap::new(),
        out: Lowered::default(),
    };
    let outputs = roots.iter().map(|r| l.node(*r)).collect();
    l.out.outputs = outputs;
    l.out
}

struct Lowering<'d> {
    dag: &'d Dag,
    /// The operand of each node lowered, by node id.
    done: Vec<Option<Operand>>,
    /// Instructions made, so that equal ones (the squares of a power chain
    /// shared with an explicit product) are made once.
    made: HashMap<(Prim, u64, u64), Operand>,
    out: Lowered,
}

/// A hashable key of an operand.
pub(super) fn key(o: Operand) -> u64 {
    match o {
        Operand::Val(k) => k as u64,
        Operand::Input(k) => (1 << 40) | k as u64,
        Operand::Const(c) => c.to_bits() ^ (3 << 62),
    }
}

impl Lowering<'_> {
    fn emit(&mut self, op: Prim, a: Operand, b: Operand) -> Operand {
        let k = (op, key(a), key(b));
        if let Some(o) = self.made.get(&k) {
            return *o;
        }
        let o = Operand::Val(self.out.instrs.len() as u32);
        self.out.instrs.push(Instr { op, a, b });
        self.made.insert(k, o);
        o
    }

    /// The operand of node `id`, its instructions emitted first (iteratively:
    /// deep formulas must not overflow the stack).
    fn node(&mut self, id: Id) -> Operand {
        let mut stack = vec![(id, false)];
        while let Some((n, ready)) = stack.pop() {
            if self.done[n.0 as usize].is_some() {
                continue;
            }
            let deps = self.deps(n);
            if !ready {
                stack.push((n, true));
                stack.extend(deps.into_iter().rev().map(|d| (d, false)));
                continue;
            }
            let o = self.lower_node(n);
            self.done[n.0 as usize] = Some(o);
        }
        self.operand(id)
    }

    /// The operand of a node already lowered.
    fn operand(&self, id: Id) -> Operand {
        self.done[id.0 as usize].expect("a node lowered before its users")
    }

    /// The nodes that lowering `n` reads (a negated addend is read through).
    fn deps(&self, n: Id) -> Vec<Id> {
        match self.dag.node(n) {
            Node::Const(_) | Node::Var(_) => vec![],
            Node::Add(a, b) => [a, b]
                .into_iter()
                .map(|x| match self.dag.node(x) {
                    Node::Neg(y) => y,
                    _ => x,
                })
                .collect(),
            Node::Neg(a) | Node::PowI(a, _) | Node::Call(_, a) => vec![a],
            Node::Mul(a, b) | Node::Div(a, b) | Node::Call2(_, a, b) => vec![a, b],
        }
    }

    fn lower_node(&mut self, n: Id) -> Operand {
        let v = |s: &Self, x: Id| s.operand(x);
        let none = Operand::Const(0.0);
        match self.dag.node(n) {
            Node::Const(bits) => Operand::Const(f64::from_bits(bits)),
            Node::Var(k) => Operand::Input(k),
            Node::Neg(a) => self.emit(Prim::Neg, v(self, a), none),
            Node::Add(a, b) => {
                let negated = |s: &Self, x: Id| match s.dag.node(x) {
                    Node::Neg(y) => Some(s.operand(y)),
                    _ => None,
                };
                match (negated(self, a), negated(self, b)) {
                    (None, Some(nb)) => self.emit(Prim::Sub, v(self, a), nb),
                    (Some(na), None) => self.emit(Prim::Sub, v(self, b), na),
                    (Some(na), Some(nb)) => {
                        let s = self.emit(Prim::Add, na, nb);
                        self.emit(Prim::Neg, s, none)
                    }
                    (None, None) => self.emit(Prim::Add, v(self, a), v(self, b)),
                }
            }
            Node::Mul(a, b) => self.emit(Prim::Mul, v(self, a), v(self, b)),
            Node::Div(a, b) => self.emit(Prim::Div, v(self, a), v(self, b)),
            Node::PowI(a, k) => self.power(v(self, a), k),
            Node::Call(f, a) => self.emit(Prim::Call(f), v(self, a), none),
            Node::Call2(f, a, b) => self.emit(Prim::Call2(f), v(self, a), v(self, b)),
        }
    }

    /// `x^k` by binary powering (the squares low to high, multiplied in as
    /// their bits come), `1/x^|k|` for negative `k`.
    fn power(&mut self, x: Operand, k: i32) -> Operand {
        let mut m = k.unsigned_abs();
        let mut square = x;
        let mut acc: Option<Operand> = None;
        while m > 0 {
            if m & 1 == 1 {
                acc = Some(match acc {
                    None => square,
                    Some(a) => self.emit(Prim::Mul, a, square),
                });
            }
            m >>= 1;
            if m > 0 {
                square = self.emit(Prim::Mul, square, square);
            }
        }
        let pos = acc.unwrap_or(Operand::Const(1.0));
        if k < 0 {
            self.emit(Prim::Div, Operand::Const(1.0), pos)
        } else {
            pos
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::compile;
    use super::*;

    /// The lowered program evaluated in f64, as the backends do.
    fn run(l: &Lowered, vars: &[f64]) -> Vec<f64> {
        use crate::num::math::Math;
        let mut vals: Vec<f64> = vec![];
        let get = |vals: &[f64], o: Operand| match o {
            Operand::Val(k) => vals[k as usize],
            Operand::Input(k) => vars[k as usize],
            Operand::Const(c) => c,
        };
        for i in &l.instrs {
            let (a, b) = (get(&vals, i.a), get(&vals, i.b));
            vals.push(match i.op {
                Prim::Neg => -a,
                Prim::Add => a + b,
                Prim::Sub => a - b,
                Prim::Mul => a * b,
                Prim::Div => a / b,
                Prim::Call(Func::Exp) => f64::exp_r(a),
                Prim::Call(Func::Sin) => f64::sin_r(a),
                Prim::Call(_) | Prim::Call2(_) => f64::NAN,
            });
        }
        l.outputs.iter().map(|o| get(&vals, *o)).collect()
    }

    /// Negations go outward into the sums, the values the same bits, signed
    /// zeros included.
    #[test]
    fn signs_outward_is_exact_and_shorter() {
        let mut d = Dag::new();
        let names = ["q", "p", "u"];
        let roots = [
            compile(&mut d, "u - p*(q*(-sin(q)))", &names).unwrap(),
            compile(&mut d, "(-q)*(-p) - (-u)/p", &names).unwrap(),
            compile(&mut d, "exp(-(q*p)) + (-q)*p", &names).unwrap(),
            compile(&mut d, "-(q*u)", &names).unwrap(),
        ];
        let l = lower(&d, &roots);
        let o = l.signs_outward();
        let negs = |l: &Lowered| l.instrs.iter().filter(|i| i.op == Prim::Neg).count();
        assert!(negs(&o) < negs(&l), "{:#?}", o.instrs);
        let zero = [0.0, -0.0];
        for x in [
            [1.3, -0.4, 0.7],
            [-2.0, 0.5, -0.0],
            [zero[0], zero[1], 0.0],
            [0.0, 2.0, 0.0],
        ] {
            let (a, b) = (run(&l, &x), run(&o, &x));
            for (a, b) in a.iter().zip(&b) {
                assert!(
                    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
                    "{a} vs {b} at {x:?}"
                );
            }
        }
    }

    #[test]
    fn powers_chain_and_negated_addends_subtract() {
        let mut d = Dag::new();
        let names = ["q", "p"];
        let roots = [
            compile(&mut d, "q^5 - p", &names).unwrap(),
            compile(&mut d, "q^-3 + exp(p)*sin(q)", &names).unwrap(),
            compile(&mut d, "q^4", &names).unwrap(),
        ];
        let l = lower(&d, &roots);
        // q², q⁴, q⁵, q⁵ − p, q³ = q·q², 1/q³, exp p, sin q, product, sum.
        assert_eq!(l.instrs.len(), 10, "{:#?}", l.instrs);
        assert!(l.instrs.iter().any(|i| i.op == Prim::Sub));
        assert!(!l.instrs.iter().any(|i| i.op == Prim::Neg));
        let x = [1.3, -0.4];
        let got = run(&l, &x);
        let want = d.eval(&roots, &x);
        for (g, w) in got.iter().zip(&want) {
            assert!((g - w).abs() <= 4e-16 * w.abs(), "{g} vs {w}");
        }
    }
}
