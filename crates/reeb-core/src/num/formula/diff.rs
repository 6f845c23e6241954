//! Symbolic derivatives in the DAG, memoised per (node, variable): the
//! gradient ∇V, ∇K, f′ and ∂g/∂q of formula models share their nodes with
//! the formulas themselves.

use super::dag::{operands, Dag, Func, Func2, Id, Node};

impl Dag {
    /// ∂root/∂(variable `k`).
    pub fn diff(&mut self, root: Id, k: u32) -> Id {
        self.directional(&[root], &mut |d, v| d.num(if v == k { 1.0 } else { 0.0 }))[0]
    }

    /// The gradient of `root` over the variables `ks`.
    pub fn gradient(&mut self, root: Id, ks: &[u32]) -> Vec<Id> {
        ks.iter().map(|k| self.diff(root, *k)).collect()
    }

    /// The derivatives of `roots` along a direction in which variable `v`
    /// changes at the rate `seed(v)` (forward mode: a tangent map applied
    /// to a deviation vector, when the seeds are the vector's components).
    /// The DAG is walked with a list of pending nodes, not by recursion (a
    /// sum of n terms is n nodes deep), operands first, each node once.
    pub fn directional(
        &mut self,
        roots: &[Id],
        seed: &mut dyn FnMut(&mut Dag, u32) -> Id,
    ) -> Vec<Id> {
        let last = roots.iter().map(|r| r.0 as usize + 1).max().unwrap_or(0);
        let mut memo: Vec<Option<Id>> = vec![None; last];
        for root in roots {
            let mut todo = vec![(*root, false)];
            while let Some((id, ready)) = todo.pop() {
                if memo[id.0 as usize].is_some() {
                    continue;
                }
                if ready {
                    let d = self.derivative(id, &memo, seed);
                    memo[id.0 as usize] = Some(d);
                } else {
                    todo.push((id, true));
                    todo.extend(
                        operands(self.node(id))
                            .into_iter()
                            .rev()
                            .map(|o| (o, false)),
                    );
                }
            }
        }
        roots
            .iter()
            .map(|r| memo[r.0 as usize].expect("the root differentiated"))
            .collect()
    }

    /// The derivative of `id`, given those of its operands in `memo`.
    fn derivative(
        &mut self,
        id: Id,
        memo: &[Option<Id>],
        seed: &mut dyn FnMut(&mut Dag, u32) -> Id,
    ) -> Id {
        let d = |x: Id| memo[x.0 as usize].expect("operands first");
        match self.node(id) {
            Node::Const(_) => self.num(0.0),
            Node::Var(v) => seed(self, v),
            Node::Neg(a) => self.neg(d(a)),
            Node::Add(a, b) => self.add(d(a), d(b)),
            Node::Mul(a, b) => {
                let (x, y) = (self.mul(d(a), b), self.mul(a, d(b)));
                self.add(x, y)
            }
            // (a/b)′ = a′/b − (a/b)·b′/b
            Node::Div(a, b) => {
                let first = self.div(d(a), b);
                let ratio = self.mul(id, d(b));
                let second = self.div(ratio, b);
                self.sub(first, second)
            }
            Node::PowI(a, n) => {
                let lower = self.powi(a, n - 1);
                let c = self.num(n as f64);
                let scaled = self.mul(c, lower);
                self.mul(scaled, d(a))
            }
            Node::Call(f, a) => {
                let outer = self.outer_derivative(f, a, id);
                self.mul(outer, d(a))
            }
            Node::Call2(f, a, b) => self.diff_call2(f, id, (a, d(a)), (b, d(b))),
        }
    }

    /// f′(a) for `id` = f(a).
    fn outer_derivative(&mut self, f: Func, a: Id, id: Id) -> Id {
        let one = self.num(1.0);
        match f {
            Func::Sqrt => {
                let two = self.num(2.0);
                let twice = self.mul(two, id);
                self.div(one, twice)
            }
            Func::Exp => id,
            Func::Log | Func::SampleLog => self.div(one, a),
            Func::Sin => self.call(Func::Cos, a),
            Func::Cos => {
                let s = self.call(Func::Sin, a);
                self.neg(s)
            }
            Func::Tan => {
                let t2 = self.powi(id, 2);
                self.add(one, t2)
            }
            Func::Atan => {
                let a2 = self.powi(a, 2);
                let den = self.add(one, a2);
                self.div(one, den)
            }
            Func::Sinh => self.call(Func::Cosh, a),
            Func::Cosh => self.call(Func::Sinh, a),
            Func::Tanh => {
                let t2 = self.powi(id, 2);
                self.sub(one, t2)
            }
            Func::Abs => self.call(Func::Sign, a),
            // Step functions.
            Func::Sign | Func::Octave | Func::Rescale => self.num(0.0),
        }
    }

    /// The derivative of `id` = f(a, b), given a′ and b′.
    fn diff_call2(&mut self, f: Func2, id: Id, (a, da): (Id, Id), (b, db): (Id, Id)) -> Id {
        match f {
            // (a^b)′ = a^b · (b′·log a + b·a′/a)
            Func2::Pow => {
                let log_a = self.call(Func::Log, a);
                let x = self.mul(db, log_a);
                let ba = self.mul(b, da);
                let y = self.div(ba, a);
                let sum = self.add(x, y);
                self.mul(id, sum)
            }
            // min(a, b) = (a + b − |a − b|)/2, max with +|a − b|.
            Func2::Min | Func2::Max => {
                let diff = self.sub(a, b);
                let sign = self.call(Func::Sign, diff);
                let dd = self.sub(da, db);
                let mut jump = self.mul(sign, dd);
                if f == Func2::Min {
                    jump = self.neg(jump);
                }
                let both = self.add(da, db);
                let sum = self.add(both, jump);
                let half = self.num(0.5);
                self.mul(half, sum)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{compile, Dag};

    /// Every derivative agrees with a central difference.
    #[test]
    fn derivatives_match_finite_differences() {
        let names = ["q1", "q2", "a"];
        let at = [0.7, -0.4, 1.3];
        for text in [
            "(q1^2 + q2^2)/2 + q1^2*q2 - q2^3/3",
            "a*(1 - cos(q1)) + q2/(1 + q1^2)",
            "exp(-a*q1)*sin(q2)^3 + log(q1 + 2)",
            "sqrt(q1^2 + q2^2 + a) - 1/sqrt(q1^2 + q2^2)",
            "tan(q1) + atan(q2) + sinh(q1*q2) + cosh(a*q2) + tanh(q1)",
            "abs(q2) + min(q1, q2) * max(q1, a) + pow(q1 + 2, q2)",
            "q1^-3 + (q2^2)^3",
        ] {
            let mut d = Dag::new();
            let f = compile(&mut d, text, &names).unwrap();
            for k in 0..3u32 {
                let df = d.diff(f, k);
                let got = d.eval(&[df], &at)[0];
                let h = 1e-6;
                let (mut up, mut down) = (at, at);
                up[k as usize] += h;
                down[k as usize] -= h;
                let want = (d.eval(&[f], &up)[0] - d.eval(&[f], &down)[0]) / (2.0 * h);
                assert!(
                    (got - want).abs() <= 1e-7 * want.abs().max(1.0),
                    "d({text})/d{}: {got} vs {want}",
                    names[k as usize]
                );
            }
        }
    }

    /// Long chains (a sum of 10⁵ terms, a tower of 10⁴ powers) are
    /// differentiated on a 2 MiB stack (rayon's, the test harness's).
    #[test]
    fn chains_differentiate_without_recursion() {
        let chains = std::thread::Builder::new()
            .stack_size(2 << 20)
            .spawn(|| {
                let mut d = Dag::new();
                let sum = (1..=100_000)
                    .map(|k| format!("q^{}/{k}", k % 7))
                    .collect::<Vec<_>>()
                    .join(" + ");
                let f = compile(&mut d, &sum, &["q"]).unwrap();
                let df = d.diff(f, 0);
                let tower = compile(&mut d, &vec!["q"; 10_000].join("^"), &["q"]).unwrap();
                let dt = d.diff(tower, 0);
                d.eval(&[df, dt], &[0.5])
            })
            .unwrap()
            .join()
            .unwrap();
        // Σ_k (k mod 7) q^(k mod 7 − 1)/k at q = 1/2, summed as compiled.
        let want: f64 = (1..=100_000)
            .map(|k| (k % 7) as f64 * 0.5f64.powi(k % 7 - 1) / k as f64)
            .sum();
        assert!(
            (chains[0] - want).abs() < 1e-12 * want,
            "{chains:?} vs {want}"
        );
        assert!(chains[1].is_finite(), "{chains:?}");
    }

    #[test]
    fn derivatives_share_nodes_and_simplify() {
        let mut d = Dag::new();
        let names = ["q", "p"];
        let v = compile(&mut d, "q^2/2", &names).unwrap();
        let dv = d.diff(v, 0);
        let q = compile(&mut d, "q", &names).unwrap();
        assert_eq!(dv, q, "d(q²/2)/dq is q itself");
        let dp = d.diff(v, 1);
        assert_eq!(d.constant(dp), Some(0.0));
        let s = compile(&mut d, "sin(q)", &names).unwrap();
        let c = compile(&mut d, "cos(q)", &names).unwrap();
        assert_eq!(d.diff(s, 0), c);
    }
}
