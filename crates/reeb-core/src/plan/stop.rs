//! Stop conditions: `[output] stop = "q1^2 + q2^2 > 100"`. A comparison of
//! two formulas (the grammar of formula models) over the model's
//! variables, `t` and the scene's parameters; a trajectory stops after the
//! first step at whose end it holds. Both backends evaluate the one
//! lowered program of `lhs − rhs` (`tape.rs` on the CPU, `wgsl.rs` on the
//! GPU) and compare it with zero, so they stop at the same step unless the
//! difference is within round-off of zero. A NaN never stops.

use crate::num::formula::dag::Dag;
use crate::num::formula::lower::{lower, Lowered};
use crate::num::formula::parse::{parse, FormulaError};

/// How `lhs − rhs` is compared with zero.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Cmp {
    Gt,
    Ge,
    Lt,
    Le,
}

impl Cmp {
    /// Does `g = lhs − rhs` satisfy the comparison? (False for NaN.)
    pub fn holds(self, g: f64) -> bool {
        match self {
            Cmp::Gt => g > 0.0,
            Cmp::Ge => g >= 0.0,
            Cmp::Lt => g < 0.0,
            Cmp::Le => g <= 0.0,
        }
    }

    /// The same test in WGSL, of the value `g`.
    pub fn wgsl(self, g: &str) -> String {
        let op = match self {
            Cmp::Gt => ">",
            Cmp::Ge => ">=",
            Cmp::Lt => "<",
            Cmp::Le => "<=",
        };
        format!("{g} {op} 0.0")
    }
}

/// A compiled stop condition.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StopObs {
    /// The condition as the scene gives it.
    pub text: String,
    pub cmp: Cmp,
    /// `lhs − rhs`, its inputs the DAG variables `names[k]`.
    #[serde(skip)]
    pub program: Lowered,
    /// The names the formula may use (state variables, `t`, parameters).
    #[serde(skip)]
    pub names: Vec<String>,
    /// The names it reads.
    pub reads: Vec<String>,
    /// How many of `names` are state variables (they come first, then
    /// `t`, then the parameters).
    #[serde(skip)]
    pub states: usize,
}

impl StopObs {
    /// Is `name` one of the model's state variables?
    pub fn state(&self, name: &str) -> bool {
        self.names[..self.states].iter().any(|n| n == name)
    }
}

/// The comparison operators, longest first.
const OPERATORS: [(&str, Cmp); 4] = [
    (">=", Cmp::Ge),
    ("<=", Cmp::Le),
    (">", Cmp::Gt),
    ("<", Cmp::Lt),
];

/// Compiles `text` over `names`, of which the first `states` are state
/// variables; errors carry the column (in characters).
pub fn compile(text: &str, names: &[&str], states: usize) -> Result<StopObs, FormulaError> {
    let (at, len, cmp) = comparison(text)?;
    let (lhs, rhs) = (&text[..at], &text[at + len..]);
    let offset = |e: FormulaError, chars: usize| FormulaError {
        column: e.column + chars,
        message: e.message,
    };
    let rhs_at = text[..at + len].chars().count();
    let mut dag = Dag::new();
    let a = parse(lhs).and_then(|e| dag.add_expr(&e, names))?;
    let b = parse(rhs)
        .and_then(|e| dag.add_expr(&e, names))
        .map_err(|e| offset(e, rhs_at))?;
    let g = dag.sub(a, b);
    let program = lower(&dag, &[g]);
    let read = program.inputs_read();
    Ok(StopObs {
        text: text.to_string(),
        cmp,
        program,
        names: names.iter().map(|n| n.to_string()).collect(),
        reads: read
            .iter()
            .map(|k| names[*k as usize].to_string())
            .collect(),
        states,
    })
}

/// The byte offset, length and kind of the one comparison in `text`
/// outside parentheses.
fn comparison(text: &str) -> Result<(usize, usize, Cmp), FormulaError> {
    let column = |byte: usize| text[..byte].chars().count();
    let mut found: Option<(usize, usize, Cmp)> = None;
    let mut depth = 0i64;
    let bytes = text.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'(' => depth += 1,
            b')' => depth -= 1,
            b'=' | b'!' if bytes.get(i + 1) == Some(&b'=') => {
                return Err(FormulaError {
                    column: column(i),
                    message: "a stop condition compares with <, <=, > or >= (equality of floating-point values almost never holds)".into(),
                })
            }
            b'<' | b'>' => {
                let (op, cmp) = OPERATORS
                    .iter()
                    .find(|(op, _)| text[i..].starts_with(op))
                    .expect("< or > starts an operator");
                if found.is_some() || depth != 0 {
                    return Err(FormulaError {
                        column: column(i),
                        message: "one comparison, outside parentheses: `lhs > rhs`".into(),
                    });
                }
                found = Some((i, op.len(), *cmp));
                i += op.len();
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    found.ok_or(FormulaError {
        column: 0,
        message: "needs a comparison, e.g. `q1^2 + q2^2 > 100` (<, <=, > or >=)".into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::num::formula::tape::{Inputs, Tape};
    use crate::num::isa::Isa;

    struct One(Vec<[f64; 1]>);
    impl Inputs<f64, 1> for One {
        fn array(&self, k: u32) -> &[f64; 1] {
            &self.0[k as usize]
        }
        fn scalar(&self, k: u32) -> f64 {
            self.0[k as usize][0]
        }
    }

    fn eval(p: &Lowered, x: &[f64]) -> f64 {
        let tape = Tape::<f64>::new(p, |_| false);
        let mut regs = vec![[0.0; 1]; tape.registers];
        tape.run(
            &mut regs,
            &One(x.iter().map(|v| [*v]).collect()),
            Isa::Baseline,
        );
        tape.output(&regs, 0)[0]
    }

    #[test]
    fn a_comparison_becomes_the_sign_of_a_difference() {
        let s = compile("q1^2 + q2^2 > 4*r", &["q1", "q2", "t", "r"], 2).unwrap();
        assert_eq!(s.cmp, Cmp::Gt);
        assert_eq!(s.reads, ["q1", "q2", "r"]);
        let g = eval(&s.program, &[1.0, 2.0, 0.0, 1.0]);
        assert_eq!(g, 1.0);
        assert!(s.cmp.holds(g) && !s.cmp.holds(f64::NAN));
    }

    #[test]
    fn errors_name_their_column() {
        let e = compile("q > 1 > 2", &["q"], 1).unwrap_err();
        assert_eq!(e.column, 6);
        let e = compile("q + x > 1", &["q", "p"], 2).unwrap_err();
        assert_eq!(e.column, 4, "{}", e.message);
        let e = compile("q > 1 + y", &["q", "p"], 2).unwrap_err();
        assert_eq!(e.column, 8, "{}", e.message);
        assert!(compile("q + 1", &["q"], 1).is_err());
        assert!(compile("q == 1", &["q"], 1).is_err());
        assert!(compile("min(q, 1) >= 0", &["q"], 1).is_ok());
    }
}
