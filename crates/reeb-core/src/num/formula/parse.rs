//! Formula text → syntax tree (precedence climbing). Every node keeps the
//! column where it starts, so that errors can put a caret under it.
//!
//! Only parentheses and function calls recurse, at most [`MAX_DEPTH`] deep;
//! chains of operators, signs and powers are loops, so a formula of any
//! length parses on a small stack. The tree may still be as deep as the
//! formula is long (a sum of n terms nests n deep on its left), so it is
//! dropped without recursion, and every pass after the parser walks it or
//! its DAG without recursion too.

use std::fmt;

/// How deep parentheses and function calls may nest (a generated formula
/// in Horner form nests as deep as its degree; the parser's recursion on a
/// 2 MiB thread stack takes thousands).
pub const MAX_DEPTH: usize = 256;

/// A formula that cannot be read: the column (0-based, in characters) and why.
#[derive(Debug, Clone, PartialEq)]
pub struct FormulaError {
    pub column: usize,
    pub message: String,
}

impl fmt::Display for FormulaError {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "column {}: {}", self.column + 1, self.message)
    }
}

impl std::error::Error for FormulaError {}

/// A syntax tree; `at` is the column where the node starts.
#[derive(Debug, Clone, PartialEq)]
pub enum Expr {
    Num(f64),
    Name {
        name: String,
        at: usize,
    },
    Neg(Box<Expr>),
    Bin(char, Box<Expr>, Box<Expr>),
    Call {
        name: String,
        at: usize,
        args: Vec<Expr>,
    },
}

/// Drops the subtrees from a list instead of by recursion (a sum of 10⁵
/// terms is a tree 10⁵ deep).
impl Drop for Expr {
    fn drop(&mut self) {
        let mut pending = vec![];
        take_children(self, &mut pending);
        while let Some(mut e) = pending.pop() {
            take_children(&mut e, &mut pending);
        }
    }
}

/// Moves the children of `e` to `out`, leaving leaves in their place.
fn take_children(e: &mut Expr, out: &mut Vec<Expr>) {
    let mut take = |b: &mut Box<Expr>| out.push(std::mem::replace(&mut **b, Expr::Num(0.0)));
    match e {
        Expr::Neg(a) => take(a),
        Expr::Bin(_, a, b) => {
            take(a);
            take(b);
        }
        Expr::Call { args, .. } => out.append(args),
        Expr::Num(_) | Expr::Name { .. } => {}
    }
}

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Num(f64),
    Name(String),
    Sym(char),
    End,
}

/// Splits `text` into (token, column) pairs.
fn tokens(text: &str) -> Result<Vec<(Tok, usize)>, FormulaError> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = vec![];
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let start = i;
        if c.is_whitespace() {
            i += 1;
        } else if c.is_ascii_digit() || c == '.' {
            i = number_end(&chars, i);
            let s: String = chars[start..i].iter().collect();
            let v = s.parse::<f64>().map_err(|_| FormulaError {
                column: start,
                message: format!("`{s}` is not a number"),
            })?;
            if !v.is_finite() {
                return Err(FormulaError {
                    column: start,
                    message: format!(
                        "`{s}` is out of range: expected a finite number (at most {:e} in magnitude)",
                        f64::MAX
                    ),
                });
            }
            out.push((Tok::Num(v), start));
        } else if c.is_alphabetic() || c == '_' {
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            out.push((Tok::Name(chars[start..i].iter().collect()), start));
        } else if "+-*/^(),".contains(c) {
            out.push((Tok::Sym(c), start));
            i += 1;
        } else {
            return Err(FormulaError {
                column: start,
                message: format!("unexpected `{c}`; formulas use numbers, names, + - * / ^, parentheses and functions"),
            });
        }
    }
    out.push((Tok::End, chars.len()));
    Ok(out)
}

/// The end of a number starting at `i`: digits, one point, an exponent.
fn number_end(chars: &[char], mut i: usize) -> usize {
    let digits = |i: &mut usize| {
        while *i < chars.len() && (chars[*i].is_ascii_digit() || chars[*i] == '.') {
            *i += 1;
        }
    };
    digits(&mut i);
    if i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
        let mut j = i + 1;
        if j < chars.len() && (chars[j] == '+' || chars[j] == '-') {
            j += 1;
        }
        if j < chars.len() && chars[j].is_ascii_digit() {
            i = j;
            digits(&mut i);
        }
    }
    i
}

struct Parser {
    toks: Vec<(Tok, usize)>,
    k: usize,
    /// Parentheses and calls open at the current token.
    depth: usize,
}

/// Parses a whole formula.
pub fn parse(text: &str) -> Result<Expr, FormulaError> {
    let mut p = Parser {
        toks: tokens(text)?,
        k: 0,
        depth: 0,
    };
    if p.peek() == &Tok::End {
        return Err(p.error("an empty formula; write 0 for none"));
    }
    let e = p.sum()?;
    match p.peek() {
        Tok::End => Ok(e),
        Tok::Sym(')') => Err(p.error("a `)` without its `(`")),
        _ => Err(p.error("expected an operator (+ - * / ^) here")),
    }
}

impl Parser {
    fn peek(&self) -> &Tok {
        &self.toks[self.k].0
    }
    fn at(&self) -> usize {
        self.toks[self.k].1
    }
    fn error(&self, message: &str) -> FormulaError {
        FormulaError {
            column: self.at(),
            message: message.to_string(),
        }
    }
    fn eat(&mut self, c: char) -> bool {
        let hit = self.peek() == &Tok::Sym(c);
        if hit {
            self.k += 1;
        }
        hit
    }
    /// term (('+' | '-') term)*
    fn sum(&mut self) -> Result<Expr, FormulaError> {
        let mut e = self.product()?;
        loop {
            let op = match self.peek() {
                Tok::Sym(c @ ('+' | '-')) => *c,
                _ => return Ok(e),
            };
            self.k += 1;
            e = Expr::Bin(op, Box::new(e), Box::new(self.product()?));
        }
    }
    /// unary (('*' | '/') unary)*
    fn product(&mut self) -> Result<Expr, FormulaError> {
        let mut e = self.unary()?;
        loop {
            let op = match self.peek() {
                Tok::Sym(c @ ('*' | '/')) => *c,
                _ => return Ok(e),
            };
            self.k += 1;
            e = Expr::Bin(op, Box::new(e), Box::new(self.unary()?));
        }
    }
    /// ('-' | '+')* atom ('^' unary)?: `^` binds to the right and takes
    /// signs in its exponent (`-a^-b^c = -(a^(-(b^c)))`). A loop over the
    /// chain, folded from its right end.
    fn unary(&mut self) -> Result<Expr, FormulaError> {
        let mut bases: Vec<(usize, Expr)> = vec![];
        loop {
            let negations = self.signs();
            let atom = self.atom()?;
            if self.eat('^') {
                bases.push((negations, atom));
                continue;
            }
            let mut e = negated(negations, atom);
            while let Some((negations, base)) = bases.pop() {
                e = negated(negations, Expr::Bin('^', Box::new(base), Box::new(e)));
            }
            return Ok(e);
        }
    }
    /// Eats a run of `+` and `-` signs; how many were `-`.
    fn signs(&mut self) -> usize {
        let mut negations = 0;
        loop {
            if self.eat('-') {
                negations += 1;
            } else if !self.eat('+') {
                return negations;
            }
        }
    }
    /// One level deeper into parentheses or a call opened at `at`.
    fn enter(&mut self, at: usize) -> Result<(), FormulaError> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return Err(FormulaError {
                column: at,
                message: format!("parentheses and function calls nested deeper than {MAX_DEPTH}"),
            });
        }
        Ok(())
    }
    fn atom(&mut self) -> Result<Expr, FormulaError> {
        let at = self.at();
        match self.peek().clone() {
            Tok::Num(v) => {
                self.k += 1;
                Ok(Expr::Num(v))
            }
            Tok::Name(name) => {
                self.k += 1;
                if self.eat('(') {
                    self.enter(at)?;
                    let call = self.call(name, at)?;
                    self.depth -= 1;
                    return Ok(call);
                }
                Ok(Expr::Name { name, at })
            }
            Tok::Sym('(') => {
                self.k += 1;
                self.enter(at)?;
                let e = self.sum()?;
                if !self.eat(')') {
                    return Err(self.error("expected `)` to close the `(`"));
                }
                self.depth -= 1;
                Ok(e)
            }
            Tok::End => Err(self.error("the formula ends where a value is expected")),
            Tok::Sym(c) => Err(self.error(&format!("expected a value, found `{c}`"))),
        }
    }
    /// The arguments of `name(`, up to its `)`.
    fn call(&mut self, name: String, at: usize) -> Result<Expr, FormulaError> {
        let mut args = vec![];
        if !self.eat(')') {
            loop {
                args.push(self.sum()?);
                if self.eat(')') {
                    break;
                }
                if !self.eat(',') {
                    return Err(self.error("expected `,` or `)` in the arguments"));
                }
            }
        }
        Ok(Expr::Call { name, at, args })
    }
}

/// `e` under `n` minus signs.
fn negated(n: usize, mut e: Expr) -> Expr {
    for _ in 0..n {
        e = Expr::Neg(Box::new(e));
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    fn show(e: &Expr) -> String {
        match e {
            Expr::Num(v) => format!("{v}"),
            Expr::Name { name, .. } => name.clone(),
            Expr::Neg(a) => format!("(-{})", show(a)),
            Expr::Bin(op, a, b) => format!("({} {op} {})", show(a), show(b)),
            Expr::Call { name, args, .. } => format!(
                "{name}({})",
                args.iter().map(show).collect::<Vec<_>>().join(", ")
            ),
        }
    }

    #[test]
    fn precedence_and_associativity() {
        for (text, tree) in [
            ("1 + 2*q", "(1 + (2 * q))"),
            ("a - b - c", "((a - b) - c)"),
            ("a / b * c", "((a / b) * c)"),
            ("-q^2", "(-(q ^ 2))"),
            ("q^-2", "(q ^ (-2))"),
            ("2^3^2", "(2 ^ (3 ^ 2))"),
            ("(q1^2 + q2^2)/2", "(((q1 ^ 2) + (q2 ^ 2)) / 2)"),
            ("max(q, 1e-3) * .5", "(max(q, 0.001) * 0.5)"),
            ("epsilon*(q^2 - 1)", "(epsilon * ((q ^ 2) - 1))"),
            ("2.5E+2", "250"),
            ("-a^-b^c", "(-(a ^ (-(b ^ c))))"),
            ("+-+q^2*3", "((-(q ^ 2)) * 3)"),
            ("--q", "(-(-q))"),
            ("(a)^b^(c)", "(a ^ (b ^ c))"),
        ] {
            assert_eq!(show(&parse(text).unwrap()), tree, "{text}");
        }
    }

    #[test]
    fn errors_point_at_the_column() {
        for (text, column, says) in [
            ("q +", 3, "ends where a value"),
            ("q ** 2", 3, "expected a value, found `*`"),
            ("(q + 1", 6, "expected `)`"),
            ("q + 1)", 5, "without its `(`"),
            ("q $ 2", 2, "unexpected `$`"),
            ("2 q", 2, "expected an operator"),
            ("1.2.3", 0, "is not a number"),
            ("", 0, "empty formula"),
            ("sin(q q)", 6, "expected `,` or `)`"),
            ("q^", 2, "ends where a value"),
            ("q^*2", 2, "expected a value, found `*`"),
        ] {
            let e = parse(text).unwrap_err();
            assert_eq!(e.column, column, "{text}: {e}");
            assert!(e.message.contains(says), "{text}: {e}");
        }
    }

    #[test]
    fn nesting_is_limited_and_chains_are_not() {
        let deep = |open: &str, n: usize| format!("{}q{}", open.repeat(n), ")".repeat(n));
        assert!(parse(&deep("(", MAX_DEPTH)).is_ok());
        assert!(parse(&deep("sin(", MAX_DEPTH)).is_ok());
        for (open, column) in [
            ("(", MAX_DEPTH),
            ("sin(", 4 * MAX_DEPTH),
            ("exp((", 5 * MAX_DEPTH / 2),
        ] {
            let e = parse(&deep(open, MAX_DEPTH + 1)).unwrap_err();
            assert_eq!(e.column, column, "{e}");
            assert!(e.message.contains("nested deeper than 256"), "{e}");
        }
        // Chains of operators, signs and powers are loops: a 2 MiB stack
        // (rayon's, the test harness's) parses and drops them.
        let chains = std::thread::Builder::new()
            .stack_size(2 << 20)
            .spawn(|| {
                for text in [
                    vec!["q"; 100_000].join(" + "),
                    vec!["q"; 100_000].join("/"),
                    vec!["q"; 100_000].join("^"),
                    format!("{}q", "-".repeat(100_000)),
                    vec!["q^-"; 100_000].join("") + "q",
                ] {
                    parse(&text).unwrap();
                }
            })
            .unwrap()
            .join();
        assert!(chains.is_ok());
    }
}
