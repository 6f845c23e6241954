//! Formulas as one hash-consed DAG: a node is made once, so equal
//! subexpressions (across every formula and derivative in the DAG) are one
//! node, computed once by the code emitted from it. The constructors fold
//! constants and apply the identities of 0 and 1 (`x + 0 = x`, `x·1 = x`,
//! `x·0 = 0`: a non-finite `x` is flagged by the trajectory's status
//! anyway), and order the operands of `+` and `·` so that `a + b` and
//! `b + a` are one node. Ids grow with creation, so every node's operands
//! come before it: the node order is an evaluation order.

use std::collections::HashMap;

use super::functions::{func, func2};
pub use super::functions::{Func, Func2, FUNCTIONS};
use super::parse::{Expr, FormulaError};
use crate::num::names::suggest;

/// A node of a [`Dag`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Id(pub u32);

/// A node: its operands are earlier nodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Node {
    /// A constant, by its bits (so that nodes hash).
    Const(u64),
    /// The variable at this index of the names the DAG was built over.
    Var(u32),
    Neg(Id),
    Add(Id, Id),
    Mul(Id, Id),
    Div(Id, Id),
    /// An integer power (exact by repeated multiplication).
    PowI(Id, i32),
    Call(Func, Id),
    Call2(Func2, Id, Id),
}

/// Nodes made once each.
#[derive(Debug, Default, Clone)]
pub struct Dag {
    nodes: Vec<Node>,
    index: HashMap<Node, Id>,
}

impl Dag {
    pub fn new() -> Dag {
        Dag::default()
    }
    /// Every node, operands first.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }
    pub fn node(&self, id: Id) -> Node {
        self.nodes[id.0 as usize]
    }
    /// The node, made if new.
    fn make(&mut self, n: Node) -> Id {
        if let Some(id) = self.index.get(&n) {
            return *id;
        }
        let id = Id(self.nodes.len() as u32);
        self.nodes.push(n);
        self.index.insert(n, id);
        id
    }
    /// The value of a constant node.
    pub fn constant(&self, id: Id) -> Option<f64> {
        match self.node(id) {
            Node::Const(bits) => Some(f64::from_bits(bits)),
            _ => None,
        }
    }
    pub fn num(&mut self, v: f64) -> Id {
        // One zero: -0 and 0 are the same constant here.
        let v = if v == 0.0 { 0.0 } else { v };
        self.make(Node::Const(v.to_bits()))
    }
    pub fn var(&mut self, k: u32) -> Id {
        self.make(Node::Var(k))
    }
    pub fn neg(&mut self, a: Id) -> Id {
        match self.node(a) {
            Node::Const(_) => {
                let v = self.constant(a).unwrap_or(0.0);
                self.num(-v)
            }
            Node::Neg(x) => x,
            _ => self.make(Node::Neg(a)),
        }
    }
    pub fn add(&mut self, a: Id, b: Id) -> Id {
        match (self.constant(a), self.constant(b)) {
            (Some(x), Some(y)) => self.num(x + y),
            (Some(0.0), _) => b,
            (_, Some(0.0)) => a,
            _ => self.make(Node::Add(a.min(b), a.max(b))),
        }
    }
    pub fn sub(&mut self, a: Id, b: Id) -> Id {
        if a == b {
            return self.num(0.0);
        }
        let nb = self.neg(b);
        self.add(a, nb)
    }
    pub fn mul(&mut self, a: Id, b: Id) -> Id {
        match (self.constant(a), self.constant(b)) {
            (Some(x), Some(y)) => self.num(x * y),
            (Some(0.0), _) | (_, Some(0.0)) => self.num(0.0),
            (Some(1.0), _) => b,
            (_, Some(1.0)) => a,
            (Some(-1.0), _) => self.neg(b),
            (_, Some(-1.0)) => self.neg(a),
            _ if a == b => self.powi(a, 2),
            // c1·(c2·x) = (c1·c2)·x: the constants of derivatives meet.
            (Some(c), _) => match self.scaled(b) {
                Some((c2, x)) => {
                    let c = self.num(c * c2);
                    self.mul(c, x)
                }
                None => self.make(Node::Mul(a.min(b), a.max(b))),
            },
            (_, Some(_)) => self.mul(b, a),
            _ => self.make(Node::Mul(a.min(b), a.max(b))),
        }
    }
    /// (c, x) for a node c·x with a constant c.
    fn scaled(&self, id: Id) -> Option<(f64, Id)> {
        match self.node(id) {
            Node::Mul(a, b) => match (self.constant(a), self.constant(b)) {
                (Some(c), _) => Some((c, b)),
                (_, Some(c)) => Some((c, a)),
                _ => None,
            },
            _ => None,
        }
    }
    pub fn div(&mut self, a: Id, b: Id) -> Id {
        match (self.constant(a), self.constant(b)) {
            (Some(x), Some(y)) if y != 0.0 => self.num(x / y),
            (Some(0.0), _) => self.num(0.0),
            (_, Some(1.0)) => a,
            // (c·x)/d = (c/d)·x.
            (_, Some(d)) if d != 0.0 && self.scaled(a).is_some() => {
                let (c, x) = self.scaled(a).unwrap_or((1.0, a));
                let c = self.num(c / d);
                self.mul(c, x)
            }
            _ => self.make(Node::Div(a, b)),
        }
    }
    pub fn powi(&mut self, a: Id, n: i32) -> Id {
        if let Some(x) = self.constant(a) {
            return self.num(x.powi(n));
        }
        match n {
            0 => self.num(1.0),
            1 => a,
            _ => match self.node(a) {
                // (x^m)^n = x^(m·n) for integers.
                Node::PowI(x, m) if m.checked_mul(n).is_some() => self.powi(x, m * n),
                _ => self.make(Node::PowI(a, n)),
            },
        }
    }
    pub fn call(&mut self, f: Func, a: Id) -> Id {
        if let Some(x) = self.constant(a) {
            return self.num(func(f, x));
        }
        self.make(Node::Call(f, a))
    }
    pub fn call2(&mut self, f: Func2, a: Id, b: Id) -> Id {
        if let (Some(x), Some(y)) = (self.constant(a), self.constant(b)) {
            return self.num(func2(f, x, y));
        }
        match (f, self.constant(b)) {
            // Integer powers multiply exactly.
            (Func2::Pow, Some(y)) if y.fract() == 0.0 && y.abs() <= 64.0 => self.powi(a, y as i32),
            (Func2::Pow, Some(0.5)) => self.call(Func::Sqrt, a),
            _ => self.make(Node::Call2(f, a, b)),
        }
    }

    /// Adds a syntax tree over the variables `names`; unknown names and
    /// wrong argument counts are refused at their column. The tree is walked
    /// with a list of pending nodes, not by recursion (it may be as deep as
    /// the formula is long), operands in order, each node made once its
    /// operands are.
    pub fn add_expr(&mut self, e: &Expr, names: &[&str]) -> Result<Id, FormulaError> {
        // (node, are its operands made?), and the ids made, operands last.
        let mut todo: Vec<(&Expr, bool)> = vec![(e, false)];
        let mut made: Vec<Id> = vec![];
        while let Some((e, ready)) = todo.pop() {
            if ready {
                let id = self.apply(e, &mut made);
                made.push(id);
                continue;
            }
            match e {
                Expr::Num(v) => made.push(self.num(*v)),
                Expr::Name { name, at } => made.push(self.name(name, *at, names)?),
                Expr::Neg(a) => todo.extend([(e, true), (&**a, false)]),
                Expr::Bin(_, a, b) => todo.extend([(e, true), (&**b, false), (&**a, false)]),
                Expr::Call { name, at, args } => {
                    function(name, *at, args.len())?;
                    todo.push((e, true));
                    todo.extend(args.iter().rev().map(|a| (a, false)));
                }
            }
        }
        Ok(made.pop().expect("the root's id"))
    }

    /// The variable, or `pi`, called `name`.
    fn name(&mut self, name: &str, at: usize, names: &[&str]) -> Result<Id, FormulaError> {
        match names.iter().position(|n| *n == name) {
            Some(k) => Ok(self.var(k as u32)),
            None if name == "pi" => Ok(self.num(std::f64::consts::PI)),
            None => Err(unknown_name(name, at, names)),
        }
    }

    /// The node of operator or call `e`, its operands the last of `made`.
    fn apply(&mut self, e: &Expr, made: &mut Vec<Id>) -> Id {
        let mut operand = || made.pop().expect("an operand made");
        match e {
            Expr::Neg(_) => {
                let a = operand();
                self.neg(a)
            }
            Expr::Bin(op, _, _) => {
                let (b, a) = (operand(), operand());
                match op {
                    '+' => self.add(a, b),
                    '-' => self.sub(a, b),
                    '*' => self.mul(a, b),
                    '/' => self.div(a, b),
                    _ => self.call2(Func2::Pow, a, b),
                }
            }
            Expr::Call { name, at, args } => match function(name, *at, args.len()) {
                Ok((Some(f), _)) => {
                    let a = operand();
                    self.call(f, a)
                }
                Ok((_, Some(f))) => {
                    let (b, a) = (operand(), operand());
                    self.call2(f, a, b)
                }
                _ => unreachable!("calls are checked before their arguments"),
            },
            Expr::Num(_) | Expr::Name { .. } => unreachable!("leaves are made at once"),
        }
    }

    /// The variables `root` depends on.
    pub fn uses(&self, root: Id) -> Vec<u32> {
        let mut seen = vec![false; root.0 as usize + 1];
        seen[root.0 as usize] = true;
        let mut vars = vec![];
        for k in (0..=root.0 as usize).rev() {
            if !seen[k] {
                continue;
            }
            for op in operands(self.nodes[k]) {
                seen[op.0 as usize] = true;
            }
            if let Node::Var(v) = self.nodes[k] {
                vars.push(v);
            }
        }
        vars.sort_unstable();
        vars
    }
}

/// The operands of a node.
pub fn operands(n: Node) -> Vec<Id> {
    match n {
        Node::Const(_) | Node::Var(_) => vec![],
        Node::Neg(a) | Node::PowI(a, _) | Node::Call(_, a) => vec![a],
        Node::Add(a, b) | Node::Mul(a, b) | Node::Div(a, b) | Node::Call2(_, a, b) => vec![a, b],
    }
}

/// The function `name` called with `given` arguments: its one- or
/// two-argument form, or why not.
fn function(
    name: &str,
    at: usize,
    given: usize,
) -> Result<(Option<Func>, Option<Func2>), FormulaError> {
    let Some((_, f1, f2)) = FUNCTIONS.iter().find(|(n, _, _)| *n == name) else {
        let known: Vec<&str> = FUNCTIONS.iter().map(|(n, _, _)| *n).collect();
        return Err(FormulaError {
            column: at,
            message: format!(
                "unknown function `{name}`{}; known: {}",
                suggest(name, &known),
                known.join(", ")
            ),
        });
    };
    let want = if f1.is_some() { 1 } else { 2 };
    if given != want {
        return Err(FormulaError {
            column: at,
            message: format!("`{name}` takes {want} argument(s), given {given}"),
        });
    }
    Ok((*f1, *f2))
}

fn unknown_name(name: &str, at: usize, names: &[&str]) -> FormulaError {
    let mut known: Vec<&str> = names.to_vec();
    known.push("pi");
    let function = FUNCTIONS.iter().any(|(n, _, _)| *n == name);
    FormulaError {
        column: at,
        message: if function {
            format!("`{name}` is a function: write {name}(…)")
        } else {
            format!(
                "unknown name `{name}`{}; known here: {}",
                suggest(name, &known),
                known.join(", ")
            )
        },
    }
}

#[cfg(test)]
mod tests {
    use super::super::compile;
    use super::*;

    #[test]
    fn equal_subexpressions_are_one_node() {
        let mut d = Dag::new();
        let names = ["q1", "q2", "delta"];
        let a = compile(&mut d, "sin(q1 + q2) * delta", &names).unwrap();
        let n = d.nodes().len();
        let b = compile(&mut d, "delta * sin(q2 + q1)", &names).unwrap();
        assert_eq!(a, b);
        assert_eq!(d.nodes().len(), n, "nothing new");
    }

    #[test]
    fn constants_fold_and_identities_apply() {
        let mut d = Dag::new();
        let q = compile(&mut d, "q", &["q"]).unwrap();
        assert_eq!(compile(&mut d, "q + 0", &["q"]).unwrap(), q);
        assert_eq!(compile(&mut d, "1*q/1", &["q"]).unwrap(), q);
        assert_eq!(compile(&mut d, "--q", &["q"]).unwrap(), q);
        assert_eq!(compile(&mut d, "q + 0*sin(q)", &["q"]).unwrap(), q);
        let c = compile(&mut d, "2*pi/4 + 2^3", &["q"]).unwrap();
        assert_eq!(d.constant(c), Some(std::f64::consts::PI / 2.0 + 8.0));
        let sq = compile(&mut d, "q*q", &["q"]).unwrap();
        assert_eq!(d.node(sq), Node::PowI(q, 2));
        assert_eq!(compile(&mut d, "pow(q, 2)", &["q"]).unwrap(), sq);
        assert_eq!(
            compile(&mut d, "q - q", &["q"])
                .ok()
                .and_then(|z| d.constant(z)),
            Some(0.0)
        );
    }

    #[test]
    fn unknown_names_are_refused_with_a_suggestion() {
        let mut d = Dag::new();
        let e = compile(&mut d, "epsilom*(q^2 - 1)", &["q", "epsilon"]).unwrap_err();
        assert_eq!(e.column, 0);
        assert!(e.message.contains("did you mean `epsilon`"), "{e}");
        let e = compile(&mut d, "q + sn(q)", &["q"]).unwrap_err();
        assert_eq!(e.column, 4);
        assert!(e.message.contains("did you mean `sin`"), "{e}");
        let e = compile(&mut d, "max(q)", &["q"]).unwrap_err();
        assert!(e.message.contains("takes 2 argument"), "{e}");
        let e = compile(&mut d, "q*sin", &["q"]).unwrap_err();
        assert!(e.message.contains("is a function"), "{e}");
    }

    #[test]
    fn uses_lists_the_variables() {
        let mut d = Dag::new();
        let names = ["q", "p", "t", "A"];
        let f = compile(&mut d, "q - A*cos(2*t)", &names).unwrap();
        assert_eq!(d.uses(f), vec![0, 2, 3]);
        let g = compile(&mut d, "p^2/2 + 0*t", &names).unwrap();
        assert_eq!(d.uses(g), vec![1]);
    }
}
