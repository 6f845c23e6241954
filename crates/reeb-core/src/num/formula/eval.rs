//! Evaluating a DAG in f64: the reference the backends' code is tested
//! against, and the vector field of the DOP853 reference.

use super::dag::{Dag, Id, Node};
use super::functions::{func, func2};

impl Dag {
    /// The values of `roots` at `vars` (indexed as the names the DAG was
    /// built over). Every node up to the last root is evaluated once.
    pub fn eval(&self, roots: &[Id], vars: &[f64]) -> Vec<f64> {
        let last = roots.iter().map(|r| r.0 as usize + 1).max().unwrap_or(0);
        let mut v: Vec<f64> = Vec::with_capacity(last);
        for n in &self.nodes()[..last] {
            let x = |id: Id| v[id.0 as usize];
            let value = match *n {
                Node::Const(bits) => f64::from_bits(bits),
                Node::Var(k) => vars[k as usize],
                Node::Neg(a) => -x(a),
                Node::Add(a, b) => x(a) + x(b),
                Node::Mul(a, b) => x(a) * x(b),
                Node::Div(a, b) => x(a) / x(b),
                Node::PowI(a, k) => x(a).powi(k),
                Node::Call(f, a) => func(f, x(a)),
                Node::Call2(f, a, b) => func2(f, x(a), x(b)),
            };
            v.push(value);
        }
        roots.iter().map(|r| v[r.0 as usize]).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::super::{compile, Dag};

    #[test]
    fn evaluates_as_written() {
        let mut d = Dag::new();
        let names = ["q", "p", "epsilon"];
        let cases = [
            ("epsilon*(q^2 - 1)", 2.0 * (0.25 - 1.0)),
            ("(q^2 + p^2)/2 - q^4/4", (0.25 + 9.0) / 2.0 - 0.0625 / 4.0),
            ("-q^2", -0.25),
            (
                "sqrt(abs(p)) + exp(q)*log(epsilon)",
                3f64.sqrt() + 0.5f64.exp() * 2f64.ln(),
            ),
            (
                "atan(p) - tanh(q) + min(q, p) * max(q, p)",
                (-3f64).atan() - 0.5f64.tanh() - 1.5,
            ),
            ("pow(epsilon, 0.5) + q^-2", 2f64.sqrt() + 4.0),
        ];
        let roots: Vec<_> = cases
            .iter()
            .map(|(t, _)| compile(&mut d, t, &names).unwrap())
            .collect();
        let got = d.eval(&roots, &[0.5, -3.0, 2.0]);
        for ((text, want), got) in cases.iter().zip(got) {
            assert!(
                (got - want).abs() <= 1e-15 * want.abs().max(1.0),
                "{text}: {got} vs {want}"
            );
        }
    }
}
