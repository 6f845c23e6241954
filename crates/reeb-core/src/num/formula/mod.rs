//! Formulas a user writes in a scene (`potential = "q^2/2 - q^4/4"`), from
//! text to the code both backends run.
//!
//! - `parse.rs`: text → syntax tree, errors at a column.
//! - `dag.rs`: the tree as a hash-consed DAG over named variables: equal
//!   subexpressions are one node (common subexpressions shared), constants
//!   folded and the identities of 0 and 1 applied as nodes are made.
//! - `diff.rs`: symbolic derivatives, built in the same DAG.
//! - `functions.rs`: the functions a formula may call, in f64.
//! - `eval.rs`: evaluation in f64 (the reference for both backends).
//! - `rewrite.rs`: substitution (composing ops into a step) and the
//!   addition theorems for `sin`/`cos` of mixed sums.
//! - `stage.rs`: a program split into per-block, per-step shared and
//!   per-lane parts.
//! - `symbolic.rs`: shared functions (`num/dsl.rs`) run into the DAG.
//! - `lower.rs`: roots → one straight-line program of primitive operations,
//!   which both backends run: `tape.rs` (the CPU's block interpreter) and
//!   `wgsl.rs` (a WGSL function for the GPU).
//!
//! Grammar: numbers, `pi`, names, `+ - * / ^` (`^` binds tightest and to
//! the right, `-x^2 = -(x^2)`), parentheses, and the functions of [`Func`]
//! and [`Func2`].

pub mod dag;
pub mod diff;
pub mod eval;
pub mod functions;
pub mod lower;
pub mod parse;
pub mod rewrite;
pub mod stage;
pub mod symbolic;
pub mod tape;
pub mod wgsl;

pub use dag::{Dag, Func, Func2, Id, Node};
pub use parse::{parse, Expr, FormulaError};

/// Parses `text` into `dag` over the variables `names` (a variable's index
/// is its position there); unknown names are refused with a did-you-mean.
pub fn compile(dag: &mut Dag, text: &str, names: &[&str]) -> Result<Id, FormulaError> {
    let expr = parse(text)?;
    dag.add_expr(&expr, names)
}
