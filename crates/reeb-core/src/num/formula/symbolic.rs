//! Shared functions (`num/dsl.rs`) run symbolically: a function's text,
//! executed with DAG nodes for its real arguments, gives its results as
//! formulas of those arguments. This is how the built-in models' exact
//! flows reach the DAG — their one source, not a copy — so that `diff.rs`
//! can differentiate them (tangent flows, `models/tangent.rs`).
//!
//! Reals become nodes; integers and truth values must be known while the
//! function runs (a branch, `select` or loop on a state-dependent condition
//! is refused: the DAG has no branches). The elementary functions map to
//! the DAG's functions, which both backends evaluate with reeb's own
//! polynomials, as the shared functions do.

use std::collections::HashMap;

use super::dag::{Dag, Id};
use super::functions::{Func, Func2};
use crate::num::dsl::{tokenize, Tok};

/// Why a shared function could not run symbolically.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("shared function `{function}`: {message}")]
pub struct SymbolicError {
    pub function: String,
    pub message: String,
}

/// A value while a function runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Val {
    Real(Id),
    Int(i64),
    Bool(bool),
}

/// A parsed function: its parameters (name, passed as `&mut`) and the
/// tokens of its body, braces included.
#[derive(Debug)]
struct Function {
    params: Vec<(String, bool)>,
    body: Vec<Tok>,
}

/// The shared functions of some texts, by name.
#[derive(Debug, Default)]
pub struct Library {
    fns: HashMap<String, Function>,
}

/// Most nested calls, and most loop iterations of one function: the
/// shared functions neither recurse nor loop long.
const MAX_DEPTH: usize = 64;
const MAX_ITERATIONS: usize = 4096;

impl Library {
    /// The functions of `texts` (each the Rust text a `shared_fns!` or
    /// `model_ops!` keeps).
    pub fn new(texts: &[&str]) -> Result<Library, SymbolicError> {
        let mut fns = HashMap::new();
        for text in texts {
            let toks = tokenize(text).map_err(|e| err("(text)", e.to_string()))?;
            let mut i = 0;
            while i < toks.len() {
                let (name, f, next) = function_at(&toks, i)?;
                fns.insert(name, f);
                i = next;
            }
        }
        Ok(Library { fns })
    }

    pub fn contains(&self, name: &str) -> bool {
        self.fns.contains_key(name)
    }

    /// Runs function `name` with `args` (one per parameter; a `&mut`
    /// parameter's value going in): its return value, if any, and the
    /// final values of its `&mut` parameters, in order.
    pub fn call(
        &self,
        dag: &mut Dag,
        name: &str,
        args: &[Val],
    ) -> Result<(Option<Val>, Vec<Val>), SymbolicError> {
        self.call_at(dag, name, args, 0)
    }

    fn call_at(
        &self,
        dag: &mut Dag,
        name: &str,
        args: &[Val],
        depth: usize,
    ) -> Result<(Option<Val>, Vec<Val>), SymbolicError> {
        let f = self
            .fns
            .get(name)
            .ok_or_else(|| err(name, "no such shared function".into()))?;
        if args.len() != f.params.len() {
            return Err(err(
                name,
                format!("{} arguments for {}", args.len(), f.params.len()),
            ));
        }
        if depth > MAX_DEPTH {
            return Err(err(name, "calls nested too deep".into()));
        }
        let mut run = Run {
            lib: self,
            dag,
            name,
            toks: &f.body,
            pos: 0,
            vars: f
                .params
                .iter()
                .map(|p| p.0.clone())
                .zip(args.iter().copied())
                .collect(),
            depth,
            returned: None,
        };
        run.block()?;
        let outs = f
            .params
            .iter()
            .filter(|p| p.1)
            .map(|p| run.vars[&p.0])
            .collect();
        Ok((run.returned.flatten(), outs))
    }
}

fn err(function: &str, message: String) -> SymbolicError {
    SymbolicError {
        function: function.to_string(),
        message,
    }
}

fn is(t: Option<&Tok>, s: &str) -> bool {
    matches!(t, Some(Tok::Ident(x)) | Some(Tok::Punct(x)) if x == s)
}

/// The function starting at token `i` (`fn name(params) [-> T] { … }`),
/// and where the next one starts.
fn function_at(toks: &[Tok], mut i: usize) -> Result<(String, Function, usize), SymbolicError> {
    let name = match (toks.get(i), toks.get(i + 1)) {
        (Some(Tok::Ident(f)), Some(Tok::Ident(n))) if f == "fn" => n.clone(),
        other => {
            return Err(err(
                "(text)",
                format!("expected `fn name`, found {other:?}"),
            ))
        }
    };
    i += 3; // fn name (
    let mut params = Vec::new();
    while !is(toks.get(i), ")") {
        let Some(Tok::Ident(p)) = toks.get(i) else {
            return Err(err(&name, "a parameter without a name".into()));
        };
        let by_ref = is(toks.get(i + 2), "&");
        params.push((p.clone(), by_ref));
        while !is(toks.get(i), ",") && !is(toks.get(i), ")") {
            i += 1;
        }
        if is(toks.get(i), ",") {
            i += 1;
        }
    }
    while !is(toks.get(i), "{") {
        i += 1;
        if i >= toks.len() {
            return Err(err(&name, "no body".into()));
        }
    }
    let end = matching(toks, i).ok_or_else(|| err(&name, "unbalanced braces".into()))?;
    let body = toks[i..=end].to_vec();
    Ok((name, Function { params, body }, end + 1))
}

/// The index of the brace closing the one at `open`.
fn matching(toks: &[Tok], open: usize) -> Option<usize> {
    let mut level = 0usize;
    for (k, t) in toks.iter().enumerate().skip(open) {
        if is(Some(t), "{") {
            level += 1;
        } else if is(Some(t), "}") {
            level -= 1;
            if level == 0 {
                return Some(k);
            }
        }
    }
    None
}

/// One function running: its tokens, a cursor, its variables.
struct Run<'a> {
    lib: &'a Library,
    dag: &'a mut Dag,
    name: &'a str,
    toks: &'a [Tok],
    pos: usize,
    vars: HashMap<String, Val>,
    depth: usize,
    /// Set by `return` (with its value, if any): the rest is skipped.
    returned: Option<Option<Val>>,
}

impl Run<'_> {
    fn fail<T>(&self, message: impl Into<String>) -> Result<T, SymbolicError> {
        Err(err(self.name, message.into()))
    }

    fn peek(&self) -> Option<&Tok> {
        self.toks.get(self.pos)
    }

    fn at(&self, s: &str) -> bool {
        is(self.peek(), s)
    }

    fn eat(&mut self, s: &str) -> Result<(), SymbolicError> {
        if !self.at(s) {
            return self.fail(format!("expected `{s}`, found {:?}", self.peek()));
        }
        self.pos += 1;
        Ok(())
    }

    fn ident(&mut self) -> Result<String, SymbolicError> {
        match self.peek().cloned() {
            Some(Tok::Ident(x)) => {
                self.pos += 1;
                Ok(x)
            }
            other => self.fail(format!("expected a name, found {other:?}")),
        }
    }

    /// `{ statements }`, from its opening brace.
    fn block(&mut self) -> Result<(), SymbolicError> {
        self.eat("{")?;
        while !self.at("}") {
            if self.returned.is_some() {
                self.pos = matching(self.toks, self.open_of_current()).unwrap_or(self.toks.len());
                break;
            }
            self.statement()?;
        }
        self.eat("}")
    }

    /// The opening brace of the block the cursor is in.
    fn open_of_current(&self) -> usize {
        let mut level = 0usize;
        for k in (0..self.pos).rev() {
            if is(self.toks.get(k), "}") {
                level += 1;
            } else if is(self.toks.get(k), "{") {
                if level == 0 {
                    return k;
                }
                level -= 1;
            }
        }
        0
    }

    /// Skips the block at the cursor.
    fn skip_block(&mut self) -> Result<(), SymbolicError> {
        match matching(self.toks, self.pos) {
            Some(end) if self.at("{") => {
                self.pos = end + 1;
                Ok(())
            }
            _ => self.fail("expected a block"),
        }
    }

    fn statement(&mut self) -> Result<(), SymbolicError> {
        match self.peek().cloned() {
            Some(Tok::Ident(k)) if k == "let" => self.let_statement(),
            Some(Tok::Ident(k)) if k == "return" => {
                self.pos += 1;
                let v = if self.at(";") {
                    None
                } else {
                    Some(self.expr(0)?)
                };
                self.eat(";")?;
                self.returned = Some(v);
                Ok(())
            }
            Some(Tok::Ident(k)) if k == "if" => self.if_statement(),
            Some(Tok::Ident(k)) if k == "while" => self.while_statement(),
            Some(Tok::Punct(p)) if p == "*" => {
                self.pos += 1;
                self.assignment()
            }
            Some(Tok::Ident(_)) if !is(self.toks.get(self.pos + 1), "::") => self.assignment(),
            _ => {
                self.expr(0)?;
                self.eat(";")
            }
        }
    }

    fn let_statement(&mut self) -> Result<(), SymbolicError> {
        self.eat("let")?;
        if self.at("mut") {
            self.pos += 1;
        }
        let name = self.ident()?;
        if self.at(":") {
            self.pos += 2; // the type: R, i32 or bool
        }
        self.eat("=")?;
        let v = self.expr(0)?;
        self.eat(";")?;
        self.vars.insert(name, v);
        Ok(())
    }

    /// `x = e;`, `x += e;` and the like (`*x` for a `&mut` parameter).
    fn assignment(&mut self) -> Result<(), SymbolicError> {
        let name = self.ident()?;
        let op = match self.peek() {
            Some(Tok::Punct(p)) => p.clone(),
            other => return self.fail(format!("expected an assignment, found {other:?}")),
        };
        self.pos += 1;
        let rhs = self.expr(0)?;
        self.eat(";")?;
        let v = match op.as_str() {
            "=" => rhs,
            "+=" | "-=" | "*=" | "/=" => {
                let old = self.var(&name)?;
                self.binary(&op[..1], old, rhs)?
            }
            _ => return self.fail(format!("`{op}` is not an assignment")),
        };
        self.vars.insert(name, v);
        Ok(())
    }

    fn if_statement(&mut self) -> Result<(), SymbolicError> {
        self.eat("if")?;
        let c = self.known_bool("an `if`")?;
        if c {
            self.block()?;
        } else {
            self.skip_block()?;
        }
        if !self.at("else") {
            return Ok(());
        }
        self.pos += 1;
        match (c, self.at("if")) {
            (true, _) => self.skip_else_chain(),
            (false, true) => self.if_statement(),
            (false, false) => self.block(),
        }
    }

    /// Skips `if … { } else …` or `{ }` after a taken branch's `else`.
    fn skip_else_chain(&mut self) -> Result<(), SymbolicError> {
        while !self.at("{") {
            self.pos += 1;
            if self.pos >= self.toks.len() {
                return self.fail("an `else` without a block");
            }
        }
        self.skip_block()?;
        if self.at("else") {
            self.pos += 1;
            return self.skip_else_chain();
        }
        Ok(())
    }

    fn while_statement(&mut self) -> Result<(), SymbolicError> {
        let start = self.pos;
        for _ in 0..MAX_ITERATIONS {
            self.pos = start;
            self.eat("while")?;
            if !self.known_bool("a `while`")? {
                return self.skip_block();
            }
            self.block()?;
            if self.returned.is_some() {
                return Ok(());
            }
        }
        self.fail(format!("a loop ran more than {MAX_ITERATIONS} times"))
    }

    fn known_bool(&mut self, what: &str) -> Result<bool, SymbolicError> {
        match self.expr(0)? {
            Val::Bool(b) => Ok(b),
            _ => self.fail(format!(
                "the condition of {what} is not a known truth value"
            )),
        }
    }

    fn var(&self, name: &str) -> Result<Val, SymbolicError> {
        match self.vars.get(name) {
            Some(v) => Ok(*v),
            None => self.fail(format!("unknown name `{name}`")),
        }
    }
}

/// Binding powers of the binary operators (Rust's precedence).
fn precedence(op: &str) -> Option<u8> {
    Some(match op {
        "||" => 1,
        "&&" => 2,
        "==" | "!=" | "<" | ">" | "<=" | ">=" => 3,
        "|" => 4,
        "^" => 5,
        "&" => 6,
        "<<" | ">>" => 7,
        "+" | "-" => 8,
        "*" | "/" | "%" => 9,
        _ => return None,
    })
}

impl Run<'_> {
    /// An expression whose operators bind tighter than `min`.
    fn expr(&mut self, min: u8) -> Result<Val, SymbolicError> {
        let mut lhs = self.unary()?;
        while let Some(Tok::Punct(op)) = self.peek().cloned() {
            let Some(prec) = precedence(&op) else { break };
            if prec <= min {
                break;
            }
            self.pos += 1;
            let rhs = self.expr(prec)?;
            lhs = self.binary(&op, lhs, rhs)?;
        }
        Ok(lhs)
    }

    fn unary(&mut self) -> Result<Val, SymbolicError> {
        if self.at("-") {
            self.pos += 1;
            return match self.unary()? {
                Val::Real(a) => Ok(Val::Real(self.dag.neg(a))),
                Val::Int(a) => Ok(Val::Int(-a)),
                Val::Bool(_) => self.fail("`-` of a truth value"),
            };
        }
        if self.at("!") {
            self.pos += 1;
            return match self.unary()? {
                Val::Bool(b) => Ok(Val::Bool(!b)),
                _ => self.fail("`!` of a number"),
            };
        }
        if self.at("*") {
            self.pos += 1;
            let name = self.ident()?;
            return self.var(&name);
        }
        self.primary()
    }

    fn primary(&mut self) -> Result<Val, SymbolicError> {
        match self.peek().cloned() {
            Some(Tok::Num(n)) => {
                self.pos += 1;
                self.number(&n)
            }
            Some(Tok::Punct(p)) if p == "(" => {
                self.pos += 1;
                let v = self.expr(0)?;
                self.eat(")")?;
                Ok(v)
            }
            Some(Tok::Ident(x)) if x == "true" || x == "false" => {
                self.pos += 1;
                Ok(Val::Bool(x == "true"))
            }
            Some(Tok::Ident(x)) if is(self.toks.get(self.pos + 1), "::") => {
                self.pos += 2;
                let _ = x; // R::, f32::, f64::
                let f = self.ident()?;
                self.call(&f)
            }
            Some(Tok::Ident(x)) => {
                self.pos += 1;
                self.var(&x)
            }
            other => self.fail(format!("unexpected {other:?}")),
        }
    }

    fn number(&mut self, n: &str) -> Result<Val, SymbolicError> {
        if n.contains(['.', 'e', 'E']) {
            match n.parse::<f64>() {
                Ok(v) => Ok(Val::Real(self.dag.num(v))),
                Err(_) => self.fail(format!("bad number {n}")),
            }
        } else {
            match n.parse::<i64>() {
                Ok(v) => Ok(Val::Int(v)),
                Err(_) => self.fail(format!("bad integer {n}")),
            }
        }
    }

    fn binary(&mut self, op: &str, a: Val, b: Val) -> Result<Val, SymbolicError> {
        match (a, b) {
            (Val::Real(x), Val::Real(y)) => self.real_binary(op, x, y),
            (Val::Int(x), Val::Int(y)) => {
                int_binary(op, x, y).ok_or_else(|| err(self.name, format!("`{op}` on integers")))
            }
            (Val::Bool(x), Val::Bool(y)) => match op {
                "&&" => Ok(Val::Bool(x && y)),
                "||" => Ok(Val::Bool(x || y)),
                "==" => Ok(Val::Bool(x == y)),
                "!=" => Ok(Val::Bool(x != y)),
                _ => self.fail(format!("`{op}` on truth values")),
            },
            _ => self.fail(format!("`{op}` on operands of different types")),
        }
    }

    fn real_binary(&mut self, op: &str, x: Id, y: Id) -> Result<Val, SymbolicError> {
        let d = &mut *self.dag;
        Ok(Val::Real(match op {
            "+" => d.add(x, y),
            "-" => d.sub(x, y),
            "*" => d.mul(x, y),
            "/" => d.div(x, y),
            _ => {
                let (Some(a), Some(b)) = (d.constant(x), d.constant(y)) else {
                    return self.fail(format!(
                        "`{op}` compares values that are not known while the formula is built"
                    ));
                };
                return match compare(op, a, b) {
                    Some(c) => Ok(Val::Bool(c)),
                    None => self.fail(format!("`{op}` on reals")),
                };
            }
        }))
    }
}

fn compare(op: &str, a: f64, b: f64) -> Option<bool> {
    Some(match op {
        "==" => a == b,
        "!=" => a != b,
        "<" => a < b,
        ">" => a > b,
        "<=" => a <= b,
        ">=" => a >= b,
        _ => return None,
    })
}

fn int_binary(op: &str, x: i64, y: i64) -> Option<Val> {
    Some(match op {
        "+" => Val::Int(x + y),
        "-" => Val::Int(x - y),
        "*" => Val::Int(x * y),
        "/" if y != 0 => Val::Int(x / y),
        "%" if y != 0 => Val::Int(x % y),
        "&" => Val::Int(x & y),
        "|" => Val::Int(x | y),
        "^" => Val::Int(x ^ y),
        "<<" => Val::Int(x << (y & 63)),
        ">>" => Val::Int(x >> (y & 63)),
        _ => return compare(op, x as f64, y as f64).map(Val::Bool),
    })
}

impl Run<'_> {
    /// The arguments of a call, from its `(`: values, and for each `&mut x`
    /// the name it writes back to.
    /// A `&mut` parameter passed on is written back too (`by_ref`: the
    /// callee's parameters, if it is a shared function).
    fn arguments(&mut self, by_ref: &[bool]) -> Result<Vec<(Val, Option<String>)>, SymbolicError> {
        self.eat("(")?;
        let mut args = Vec::new();
        while !self.at(")") {
            let passed_on = by_ref.get(args.len()).copied().unwrap_or(false)
                && matches!(self.peek(), Some(Tok::Ident(_)))
                && (is(self.toks.get(self.pos + 1), ",") || is(self.toks.get(self.pos + 1), ")"));
            if self.at("&") || passed_on {
                for skip in ["&", "mut", "*"] {
                    if self.at(skip) {
                        self.pos += 1;
                    }
                }
                let name = self.ident()?;
                args.push((self.var(&name)?, Some(name)));
            } else {
                args.push((self.expr(0)?, None));
            }
            if self.at(",") {
                self.pos += 1;
            }
        }
        self.eat(")")?;
        Ok(args)
    }

    fn call(&mut self, f: &str) -> Result<Val, SymbolicError> {
        let by_ref: Vec<bool> = match self.lib.fns.get(f) {
            Some(callee) => callee.params.iter().map(|p| p.1).collect(),
            None => Vec::new(),
        };
        let args = self.arguments(&by_ref)?;
        if let Some(v) = self.primitive(f, &args)? {
            return Ok(v);
        }
        let values: Vec<Val> = args.iter().map(|a| a.0).collect();
        let (ret, outs) = self.lib.call_at(self.dag, f, &values, self.depth + 1)?;
        let targets = args.iter().filter_map(|a| a.1.clone());
        for (name, v) in targets.zip(outs) {
            self.vars.insert(name, v);
        }
        Ok(ret.unwrap_or(Val::Bool(false)))
    }

    fn real(&self, v: Val) -> Result<Id, SymbolicError> {
        match v {
            Val::Real(x) => Ok(x),
            _ => self.fail("a real argument expected"),
        }
    }

    /// A primitive or elementary function (`None` for a shared function).
    fn primitive(
        &mut self,
        f: &str,
        args: &[(Val, Option<String>)],
    ) -> Result<Option<Val>, SymbolicError> {
        let func = match f {
            "exp_r" => Some(Func::Exp),
            "log_r" => Some(Func::Log),
            "sin_r" => Some(Func::Sin),
            "cos_r" => Some(Func::Cos),
            "tan_r" => Some(Func::Tan),
            "atan_r" => Some(Func::Atan),
            "sinh_r" => Some(Func::Sinh),
            "cosh_r" => Some(Func::Cosh),
            "tanh_r" => Some(Func::Tanh),
            "sqrt" => Some(Func::Sqrt),
            "abs" => Some(Func::Abs),
            _ => None,
        };
        if let (Some(func), [(a, None)]) = (func, args) {
            let a = self.real(*a)?;
            return Ok(Some(Val::Real(self.dag.call(func, a))));
        }
        let real = |k: usize| match args.get(k) {
            Some((Val::Real(x), _)) => Ok(*x),
            _ => Err(err(f, "a real argument expected".into())),
        };
        let v = match f {
            "min" | "max" => {
                let g = if f == "min" { Func2::Min } else { Func2::Max };
                Val::Real(self.dag.call2(g, real(0)?, real(1)?))
            }
            "fma" => {
                let ab = self.dag.mul(real(0)?, real(1)?);
                Val::Real(self.dag.add(ab, real(2)?))
            }
            "sincos_r" => {
                let x = real(0)?;
                let (s, c) = (self.dag.call(Func::Sin, x), self.dag.call(Func::Cos, x));
                for (k, v) in [(1, s), (2, c)] {
                    match &args.get(k).and_then(|a| a.1.clone()) {
                        Some(name) => self.vars.insert(name.clone(), Val::Real(v)),
                        None => return self.fail("sincos_r writes through `&mut`"),
                    };
                }
                Val::Bool(false)
            }
            "select" => match args {
                [(a, _), (b, _), (Val::Bool(c), _)] => {
                    if *c {
                        *b
                    } else {
                        *a
                    }
                }
                _ => {
                    return self
                        .fail("`select` on a condition not known while the formula is built")
                }
            },
            "from_i32" => match args {
                [(Val::Int(n), _)] => Val::Real(self.dag.num(*n as f64)),
                _ => return self.fail("`from_i32` of an unknown integer"),
            },
            "to_i32" | "floor" | "rint" | "pow2" => self.known_real(f, real(0)?)?,
            "inf" => Val::Real(self.dag.num(f64::INFINITY)),
            "quiet_nan" => Val::Real(self.dag.num(<f64 as crate::num::prims::Prims>::quiet_nan())),
            _ => return Ok(None),
        };
        Ok(Some(v))
    }

    /// A primitive that only known values may take.
    fn known_real(&mut self, f: &str, x: Id) -> Result<Val, SymbolicError> {
        let Some(v) = self.dag.constant(x) else {
            return self.fail(format!(
                "`{f}` of a value not known while the formula is built"
            ));
        };
        Ok(match f {
            "to_i32" => Val::Int(if v.is_nan() {
                0
            } else {
                v.clamp(-2e9, 2e9) as i64
            }),
            "floor" => Val::Real(self.dag.num(v.floor())),
            "rint" => Val::Real(self.dag.num(v.round_ties_even())),
            _ => Val::Real(self.dag.num(v.exp2())),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(text: &str, name: &str, args: &[f64]) -> (Option<f64>, Vec<f64>) {
        let lib = Library::new(&[text]).unwrap();
        let mut dag = Dag::new();
        let vals: Vec<Val> = (0..args.len() as u32)
            .map(|k| Val::Real(dag.var(k)))
            .collect();
        let (ret, outs) = lib.call(&mut dag, name, &vals).unwrap();
        let id = |v: Val| match v {
            Val::Real(x) => x,
            other => panic!("{other:?}"),
        };
        let outs: Vec<Id> = outs.into_iter().map(id).collect();
        let evaluated = dag.eval(&outs, args);
        (ret.map(|r| dag.eval(&[id(r)], args)[0]), evaluated)
    }

    #[test]
    fn statements_calls_and_outputs() {
        let text = "fn g(x: R, y: &mut R) { *y = *y + x * 2.0; }
            fn f(a: R, b: &mut R, c: &mut R) -> R {
                let mut u: R = a * a;
                u = u - 1.0;
                R::g(u, &mut *b);
                let k: i32 = 3;
                if (k & 1) == 1 { *c = R::select(a, u, k > 2); } else { *c = a; }
                return R::exp_r(-u) + R::fma(a, a, 1.0);
            }";
        let (ret, outs) = run(text, "f", &[1.5, 0.25, 9.0]);
        let u: f64 = 1.5 * 1.5 - 1.0;
        assert_eq!(outs, vec![0.25 + u * 2.0, u]);
        assert!((ret.unwrap() - ((-u).exp() + 1.5 * 1.5 + 1.0)).abs() < 1e-15);
    }

    #[test]
    fn unknown_conditions_are_refused() {
        let text = "fn f(a: R) -> R { return R::select(a, -a, a < 0.0); }";
        let lib = Library::new(&[text]).unwrap();
        let mut dag = Dag::new();
        let a = Val::Real(dag.var(0));
        let e = lib.call(&mut dag, "f", &[a]).unwrap_err();
        assert!(e.message.contains("not known"), "{e}");
    }
}
