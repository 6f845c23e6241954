//! Formula text → syntax tree (precedence climbing). Every node keeps the
//! column where it starts, so that errors can put a caret under it.

use std::fmt;

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
}

/// Parses a whole formula.
pub fn parse(text: &str) -> Result<Expr, FormulaError> {
    let mut p = Parser {
        toks: tokens(text)?,
        k: 0,
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
    /// '-' unary | '+' unary | power
    fn unary(&mut self) -> Result<Expr, FormulaError> {
        if self.eat('-') {
            return Ok(Expr::Neg(Box::new(self.unary()?)));
        }
        if self.eat('+') {
            return self.unary();
        }
        self.power()
    }
    /// atom ('^' unary)?, right-associative
    fn power(&mut self) -> Result<Expr, FormulaError> {
        let base = self.atom()?;
        if self.eat('^') {
            return Ok(Expr::Bin('^', Box::new(base), Box::new(self.unary()?)));
        }
        Ok(base)
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
                    return self.call(name, at);
                }
                Ok(Expr::Name { name, at })
            }
            Tok::Sym('(') => {
                self.k += 1;
                let e = self.sum()?;
                if !self.eat(')') {
                    return Err(self.error("expected `)` to close the `(`"));
                }
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
        ] {
            let e = parse(text).unwrap_err();
            assert_eq!(e.column, column, "{text}: {e}");
            assert!(e.message.contains(says), "{text}: {e}");
        }
    }
}
