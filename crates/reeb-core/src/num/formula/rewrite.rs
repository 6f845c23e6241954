//! Rewriting a DAG's roots: substituting expressions for variables (to
//! compose a step from its ops) and expanding the sine and cosine of a sum
//! whose terms vary differently, so that the part that does not vary with
//! the state (`m t`, a parameter) is computed where it is cheap
//! (`stage.rs`): `cos(2q − m t) = cos 2q cos m t + sin 2q sin m t`.
//!
//! Nodes are rebuilt through the DAG's constructors, so the result is
//! folded and shared like any other formula. Work goes in node order (every
//! operand before its user), without recursion, however deep the DAG.

use std::collections::{HashMap, HashSet};

use super::dag::{operands, Dag, Func, Id, Node};

impl Dag {
    /// Rebuilds every node `roots` reach from its rebuilt operands, passing
    /// each (original node, rebuilt id) through `rule`, which may replace it.
    pub fn rewrite(
        &mut self,
        roots: &[Id],
        mut rule: impl FnMut(&mut Dag, Node, Id) -> Id,
    ) -> Vec<Id> {
        let Some(top) = roots.iter().max() else {
            return vec![];
        };
        let mut reached = vec![false; top.0 as usize + 1];
        for r in roots {
            reached[r.0 as usize] = true;
        }
        for k in (0..reached.len()).rev() {
            if reached[k] {
                for o in operands(self.node(Id(k as u32))) {
                    reached[o.0 as usize] = true;
                }
            }
        }
        // The rebuilt id of each node reached, by node id.
        let mut new: Vec<Id> = vec![Id(u32::MAX); reached.len()];
        for k in (0..reached.len()).filter(|k| reached[*k]) {
            let id = Id(k as u32);
            let m = |x: Id| new[x.0 as usize];
            let node = self.node(id);
            let rebuilt = match node {
                Node::Const(_) | Node::Var(_) => id,
                Node::Neg(a) => self.neg(m(a)),
                Node::Add(a, b) => self.add(m(a), m(b)),
                Node::Mul(a, b) => self.mul(m(a), m(b)),
                Node::Div(a, b) => self.div(m(a), m(b)),
                Node::PowI(a, n) => self.powi(m(a), n),
                Node::Call(f, a) => self.call(f, m(a)),
                Node::Call2(f, a, b) => self.call2(f, m(a), m(b)),
            };
            let r = rule(self, node, rebuilt);
            new[k] = r;
        }
        roots.iter().map(|r| new[r.0 as usize]).collect()
    }

    /// `roots` with variable `k` replaced by `values[k]`.
    pub fn substitute(&mut self, roots: &[Id], values: &[Id]) -> Vec<Id> {
        self.rewrite(roots, |_, node, id| match node {
            Node::Var(k) => values[k as usize],
            _ => id,
        })
    }

    /// `roots` with every `sin`/`cos` of a sum of terms that depend on the
    /// variables `varying` and terms that do not expanded by the addition
    /// theorems.
    pub fn expand_trig(&mut self, roots: &[Id], varying: &[bool]) -> Vec<Id> {
        let mut dep = Depends {
            varying,
            of: vec![],
        };
        self.rewrite(roots, |d, _, id| match d.node(id) {
            Node::Call(f @ (Func::Sin | Func::Cos), x) => {
                let (v, c) = d.split_sum(x, &mut dep);
                if v == d.num(0.0) || c == d.num(0.0) {
                    return id;
                }
                let (sv, cv) = (d.call(Func::Sin, v), d.call(Func::Cos, v));
                let (sc, cc) = d.sin_cos(c);
                if f == Func::Sin {
                    let (a, b) = (d.mul(sv, cc), d.mul(cv, sc));
                    d.add(a, b)
                } else {
                    let (a, b) = (d.mul(cv, cc), d.mul(sv, sc));
                    d.sub(a, b)
                }
            }
            _ => id,
        })
    }

    /// `(sin x, cos x)`; for `x = m·y` with an integer `2 ≤ |m| ≤ 16` by the
    /// recurrences `cos (k+1)y = 2 cos y · cos ky − cos (k−1)y` (and `sin`
    /// alike) from `sin y`, `cos y`, as the built-in models do, so that `cos(m t)` for every `m` of a Fourier sum costs
    /// one sine and cosine of `t` and a few products.
    fn sin_cos(&mut self, x: Id) -> (Id, Id) {
        if let Node::Neg(y) = self.node(x) {
            let (s, c) = self.sin_cos(y);
            return (self.neg(s), c);
        }
        let multiple = match self.node(x) {
            Node::Mul(a, y) => self
                .constant(a)
                .filter(|m| m.fract() == 0.0 && (2.0..=16.0).contains(&m.abs()))
                .map(|m| (m, y)),
            _ => None,
        };
        let Some((m, y)) = multiple else {
            return (self.call(Func::Sin, x), self.call(Func::Cos, x));
        };
        let (s1, c1) = (self.call(Func::Sin, y), self.call(Func::Cos, y));
        let (mut s, mut c) = (s1, c1);
        let two = self.num(2.0);
        let tc = self.mul(two, c1);
        let (mut sp, mut cp) = (self.num(0.0), self.num(1.0));
        for _ in 1..m.abs() as usize {
            let (a, b) = (self.mul(tc, s), self.mul(tc, c));
            let (sn, cn) = (self.sub(a, sp), self.sub(b, cp));
            (sp, cp, s, c) = (s, c, sn, cn);
        }
        if m < 0.0 {
            s = self.neg(s);
        }
        (s, c)
    }

    /// A sum `x` as (its varying terms, its other terms), each summed.
    fn split_sum(&mut self, x: Id, dep: &mut Depends) -> (Id, Id) {
        let mut terms = vec![];
        let mut stack = vec![x];
        while let Some(t) = stack.pop() {
            match self.node(t) {
                Node::Add(a, b) => stack.extend([b, a]),
                _ => terms.push(t),
            }
        }
        let (mut v, mut c) = (self.num(0.0), self.num(0.0));
        for t in terms {
            if dep.varies(self, t) {
                v = self.add(v, t);
            } else {
                c = self.add(c, t);
            }
        }
        (v, c)
    }
}

impl Dag {
    /// `roots` with the factors of each varying product that do not vary
    /// (constants, parameters, signs) gathered into one coefficient:
    /// `c·(2·(−x))` becomes `(−2c)·x` and `x/c` becomes `(1/c)·x`, so that
    /// the coefficient is computed with the values that do not vary (once,
    /// before the steps) and the varying work is one product.
    pub fn fold_coefficients(&mut self, roots: &[Id], varying: &[bool]) -> Vec<Id> {
        let mut dep = Depends {
            varying,
            of: vec![],
        };
        let one = self.num(1.0);
        self.rewrite(roots, |d, _, id| {
            if !dep.varies(d, id) {
                return id;
            }
            let (c, v) = match d.node(id) {
                Node::Neg(_) => d.coefficient(id, &mut dep),
                Node::Mul(a, b) => {
                    let (ca, va) = d.coefficient(a, &mut dep);
                    let (cb, vb) = d.coefficient(b, &mut dep);
                    // With one coefficient, moving it saves nothing and
                    // would unshare `a` (the 2 cos t of a recurrence).
                    if ca == one || cb == one {
                        return id;
                    }
                    let c = d.mul(ca, cb);
                    (c, d.mul(va, vb))
                }
                Node::Div(a, b) if !dep.varies(d, b) => {
                    let (c, v) = d.coefficient(a, &mut dep);
                    (d.div(c, b), v)
                }
                Node::Div(a, b) => {
                    let (c, v) = d.coefficient(a, &mut dep);
                    (c, d.div(v, b))
                }
                _ => return id,
            };
            d.mul(c, v)
        })
    }

    /// `roots` with the terms of each varying sum that differ only in a
    /// coefficient that does not vary merged: `a·cos 5t + b·cos 5t` becomes
    /// `(a + b)·cos 5t` (the terms of `cos(2q + 5t)` and `cos(2q − 5t)` of
    /// a Fourier sum). The order of the first of each kind is kept.
    pub fn merge_like_terms(&mut self, roots: &[Id], varying: &[bool]) -> Vec<Id> {
        let mut dep = Depends {
            varying,
            of: vec![],
        };
        self.rewrite(roots, |d, _, id| {
            if !matches!(d.node(id), Node::Add(..)) || !dep.varies(d, id) {
                return id;
            }
            // Sums are opened while there is room: a sum of n ≤ MAX_TERMS
            // terms is opened whole, and a longer one costs O(MAX_TERMS), not
            // the length of its chain.
            let mut terms = vec![];
            let mut stack = vec![id];
            while let Some(t) = stack.pop() {
                match d.node(t) {
                    Node::Add(a, b) if terms.len() + stack.len() < MAX_TERMS => {
                        stack.extend([b, a])
                    }
                    _ => terms.push(t),
                }
            }
            let n = terms.len();
            let mut groups: Vec<(Id, Id)> = vec![];
            let mut group_of: HashMap<Id, usize> = HashMap::new();
            for t in terms {
                let (c, v) = d.coefficient(t, &mut dep);
                match group_of.get(&v) {
                    Some(&g) => groups[g].1 = d.add(groups[g].1, c),
                    None => {
                        group_of.insert(v, groups.len());
                        groups.push((v, c));
                    }
                }
            }
            if groups.len() == n {
                return id;
            }
            let mut total = d.num(0.0);
            for (v, c) in groups {
                let x = d.mul(c, v);
                total = d.add(total, x);
            }
            total
        })
    }

    /// A varying or fixed `x` as (coefficient that does not vary, varying
    /// rest): `(c, y)` for `c·y` and `−(c·y)`, `(1, x)` for any other
    /// varying `x`, `(x, 1)` for a fixed one.
    fn coefficient(&mut self, x: Id, dep: &mut Depends) -> (Id, Id) {
        let one = self.num(1.0);
        if !dep.varies(self, x) {
            return (x, one);
        }
        match self.node(x) {
            Node::Neg(y) => {
                let (c, v) = self.coefficient(y, dep);
                (self.neg(c), v)
            }
            Node::Mul(a, b) if !dep.varies(self, a) => (a, b),
            Node::Mul(a, b) if !dep.varies(self, b) => (b, a),
            _ => (one, x),
        }
    }
}

/// Terms of a sum, `monomial · coefficient`: the monomial a sorted product
/// of varying factors, the coefficient a node that does not vary.
type Terms = Vec<(Vec<Id>, Id)>;

/// Sums longer than this are left as they are (collecting is quadratic).
const MAX_TERMS: usize = 256;

/// Nodes one walk of [`Dag::terms`] visits at most (a shared node counts
/// each time it is met): 6× the most any example scene's step needs (the
/// spin–orbit Fourier sum composed into a Yoshida 6A step), bounding both a
/// walk down a long chain and one that meets shared nodes exponentially
/// often.
const MAX_VISITS: usize = 64 * MAX_TERMS;

impl Dag {
    /// `roots` with every varying sum whose terms share monomials in the
    /// varying factors rewritten as `Σ monomial · (Σ coefficients)`: the
    /// sums of coefficients do not vary, so they leave the per-lane work.
    /// `Σₘ cₘ (sin 2q cos mt + cos 2q sin mt)` becomes
    /// `sin 2q · Σₘ cₘ cos mt + cos 2q · Σₘ cₘ sin mt`. Sums where nothing
    /// would be shared are kept as written.
    pub fn collect(&mut self, roots: &[Id], varying: &[bool]) -> Vec<Id> {
        let mut dep = Depends {
            varying,
            of: vec![],
        };
        let mut walk = Walk::default();
        self.rewrite(roots, |d, _, id| {
            if !matches!(d.node(id), Node::Add(..)) || !dep.varies(d, id) {
                return id;
            }
            walk.opened.clear();
            let Some(terms) = d.terms(id, &mut dep, &mut walk) else {
                return id;
            };
            let mut groups: Vec<(Vec<Id>, Id)> = vec![];
            for (m, c) in &terms {
                match groups.iter_mut().find(|(g, _)| g == m) {
                    Some((_, sum)) => *sum = d.add(*sum, *c),
                    None => groups.push((m.clone(), *c)),
                }
            }
            // Varying operations after: per group the products and a
            // coefficient (unless 1), and the sums. Before: those opened.
            let one = d.num(1.0);
            let after: usize = groups
                .iter()
                .map(|(m, c)| m.len().saturating_sub(1) + usize::from(*c != one) + 1)
                .sum::<usize>()
                - 1;
            if after >= walk.opened.len() {
                return id;
            }
            // Small terms first, the state variables' own terms (x·(1 + …),
            // the large ones) last: one rounding at the state's magnitude,
            // as in the step written out.
            let bare = |m: &[Id]| m.len() == 1 && matches!(d.node(m[0]), Node::Var(_));
            groups.sort_by_key(|(m, _)| bare(m));
            let mut total = d.num(0.0);
            for (m, c) in groups {
                let mut x = c;
                for f in m {
                    x = d.mul(f, x);
                }
                total = d.add(total, x);
            }
            total
        })
    }

    /// `id` as terms (`None` past [`MAX_TERMS`]): sums, negations, products
    /// and quotients by non-varying coefficients are opened; any other
    /// varying node is a factor.
    /// `opened` gathers the varying nodes opened (the operations the terms
    /// replace). The walk is a list of pending nodes, not a recursion, and
    /// gives up past [`MAX_VISITS`] nodes; a node given up on is in
    /// `gave_up`, and a later walk that meets it gives up at once (without
    /// that, each node of a chain n deep would walk the chain: n²).
    fn terms(&mut self, root: Id, dep: &mut Depends, walk: &mut Walk) -> Option<Terms> {
        let one = self.num(1.0);
        let mut todo = vec![(root, false)];
        let mut done: Vec<Terms> = vec![];
        let mut visits = 0;
        while let Some((id, ready)) = todo.pop() {
            if ready {
                let t = self.close(id, dep, &mut walk.opened, &mut done, one);
                if t.len() > MAX_TERMS {
                    walk.gave_up.extend([id, root]);
                    return None;
                }
                done.push(t);
                continue;
            }
            visits += 1;
            if visits > MAX_VISITS || walk.gave_up.contains(&id) {
                walk.gave_up.insert(root);
                return None;
            }
            match self.opening(id, dep) {
                Opening::Fixed => done.push(vec![(vec![], id)]),
                Opening::Factor => done.push(vec![(vec![id], one)]),
                Opening::Of(a, b) => {
                    walk.opened.insert(id);
                    todo.push((id, true));
                    todo.extend(b.map(|b| (b, false)));
                    todo.push((a, false));
                }
            }
        }
        done.pop()
    }

    /// How [`Dag::terms`] opens `id`.
    fn opening(&mut self, id: Id, dep: &mut Depends) -> Opening {
        if !dep.varies(self, id) {
            return Opening::Fixed;
        }
        match self.node(id) {
            Node::Add(a, b) => Opening::Of(a, Some(b)),
            Node::Neg(a) => Opening::Of(a, None),
            Node::Mul(a, b) if !dep.varies(self, a) => Opening::Of(b, None),
            Node::Mul(a, b) if !dep.varies(self, b) => Opening::Of(a, None),
            Node::Mul(a, b) => Opening::Of(a, Some(b)),
            Node::Div(a, b) if !dep.varies(self, b) => Opening::Of(a, None),
            _ => Opening::Factor,
        }
    }

    /// The terms of the opened node `id` from those of its operands, the
    /// last of `done`.
    fn close(
        &mut self,
        id: Id,
        dep: &mut Depends,
        opened: &mut HashSet<Id>,
        done: &mut Vec<Terms>,
        one: Id,
    ) -> Terms {
        let mut operand = || done.pop().expect("an operand's terms");
        match self.node(id) {
            Node::Add(..) => {
                let (tb, mut ta) = (operand(), operand());
                ta.extend(tb);
                ta
            }
            Node::Neg(_) => {
                let t = operand();
                t.into_iter().map(|(m, c)| (m, self.neg(c))).collect()
            }
            Node::Mul(a, b) if !dep.varies(self, a) || !dep.varies(self, b) => {
                let c = if dep.varies(self, a) { b } else { a };
                let t = operand();
                t.into_iter().map(|(m, x)| (m, self.mul(c, x))).collect()
            }
            Node::Mul(..) => {
                let (tb, ta) = (operand(), operand());
                match (&ta[..], &tb[..]) {
                    // One term each: the product of the monomials.
                    ([(ma, ca)], [(mb, cb)]) => {
                        let mut m: Vec<Id> = ma.iter().chain(mb).copied().collect();
                        m.sort_unstable();
                        vec![(m, self.mul(*ca, *cb))]
                    }
                    _ => {
                        opened.remove(&id);
                        vec![(vec![id], one)]
                    }
                }
            }
            Node::Div(_, b) => {
                let t = operand();
                t.into_iter().map(|(m, x)| (m, self.div(x, b))).collect()
            }
            n => unreachable!("{n:?} is not opened"),
        }
    }
}

/// How [`Dag::terms`] treats a node: a coefficient (it does not vary), a
/// factor, or opened into the terms of one or two operands.
enum Opening {
    Fixed,
    Factor,
    Of(Id, Option<Id>),
}

/// What the walks of one [`Dag::collect`] share: the nodes opened by the
/// current walk, those given up on by any.
#[derive(Default)]
struct Walk {
    opened: HashSet<Id>,
    gave_up: HashSet<Id>,
}

/// Which nodes depend on the varying variables (filled in node order).
struct Depends<'v> {
    varying: &'v [bool],
    of: Vec<bool>,
}

impl Depends<'_> {
    fn varies(&mut self, d: &Dag, id: Id) -> bool {
        for k in self.of.len()..d.nodes().len() {
            let v = match d.node(Id(k as u32)) {
                Node::Var(i) => self.varying.get(i as usize).copied().unwrap_or(false),
                n => operands(n).iter().any(|o| self.of[o.0 as usize]),
            };
            self.of.push(v);
        }
        self.of[id.0 as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::super::compile;
    use super::super::lower::Prim;
    use super::*;

    #[test]
    fn substitution_composes() {
        let mut d = Dag::new();
        let names = ["q", "t"];
        let f = compile(&mut d, "q^2 + sin(t)", &names).unwrap();
        let two = d.num(2.0);
        let q = d.var(0);
        let q2 = d.mul(two, q);
        let t = d.var(1);
        let g = d.substitute(&[f], &[q2, t])[0];
        let want = compile(&mut d, "(2*q)^2 + sin(t)", &names).unwrap();
        assert_eq!(g, want);
    }

    #[test]
    fn sines_of_mixed_sums_expand_and_agree() {
        let mut d = Dag::new();
        let names = ["q", "t", "e"];
        let f = compile(&mut d, "e*cos(2*q - 3*t) + sin(q + t + 1) + cos(q)", &names).unwrap();
        let g = d.expand_trig(&[f], &[true, false, false])[0];
        let calls = |d: &Dag, r: Id| {
            let mut n = 0;
            let _ = d.clone().rewrite(&[r], |_, node, id| {
                if matches!(node, Node::Call(..)) {
                    n += 1;
                }
                id
            });
            n
        };
        assert!(calls(&d, g) > calls(&d, f), "expanded");
        for x in [[0.3, 1.7, 0.2], [-2.0, 40.0, 1.5]] {
            let (a, b) = (d.eval(&[f], &x)[0], d.eval(&[g], &x)[0]);
            assert!((a - b).abs() < 1e-14, "{a} vs {b}");
        }
    }
    #[test]
    fn multiple_angles_by_the_recurrences_agree_up_to_sixteen() {
        let mut d = Dag::new();
        let names = ["q", "t"];
        for m in [2, 9, -7, 16] {
            let f = compile(&mut d, &format!("cos(q - {m}*t) + sin(q + {m}*t)"), &names).unwrap();
            let g = d.expand_trig(&[f], &[true, false])[0];
            for t in [0.01, 0.7, 3.1, -40.0] {
                let x = [0.4, t];
                let (a, b) = (d.eval(&[f], &x)[0], d.eval(&[g], &x)[0]);
                assert!((a - b).abs() < 1e-12, "m = {m}, t = {t}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn constant_factors_gather_into_one_coefficient() {
        let mut d = Dag::new();
        let names = ["q", "e"];
        let f = compile(&mut d, "e*(2*(-(q^2 + q))) + (q*e)/4", &names).unwrap();
        let g = d.fold_coefficients(&[f], &[true, false])[0];
        let want = compile(&mut d, "(-2*e)*(q^2 + q) + (e/4)*q", &names).unwrap();
        assert_eq!(g, want);
        let x = [0.3, 1.7];
        assert!((d.eval(&[f], &x)[0] - d.eval(&[g], &x)[0]).abs() < 1e-15);
    }

    /// The collecting rewrites on a sum of 10⁵ terms and on the derivative
    /// of a tower of 10⁴ powers (chains 10⁵ nodes deep), on a 2 MiB stack:
    /// no recursion, and the values kept.
    #[test]
    fn long_chains_are_collected_without_recursion() {
        let values = std::thread::Builder::new()
            .stack_size(2 << 20)
            .spawn(|| {
                let mut d = Dag::new();
                let names = ["q", "a"];
                let sum = (1..=100_000)
                    .map(|k| format!("a*cos({}*q)", k % 5))
                    .collect::<Vec<_>>()
                    .join(" + ");
                let f = compile(&mut d, &sum, &names).unwrap();
                let tower = compile(&mut d, &vec!["q"; 10_000].join("^"), &names).unwrap();
                let t = d.diff(tower, 0);
                let varying = [true, false];
                let mut roots = vec![f, t];
                roots = d.expand_trig(&roots, &varying);
                roots = d.collect(&roots, &varying);
                roots = d.fold_coefficients(&roots, &varying);
                roots = d.merge_like_terms(&roots, &varying);
                let x = [0.7, 1.3];
                (d.eval(&[f, t], &x), d.eval(&roots, &x))
            })
            .unwrap()
            .join()
            .unwrap();
        let (before, after) = values;
        for (a, b) in before.iter().zip(&after) {
            assert!((a - b).abs() <= 1e-9 * a.abs().max(1.0), "{a} vs {b}");
        }
    }

    #[test]
    fn like_terms_merge_into_one_product() {
        let mut d = Dag::new();
        let names = ["q", "a", "b", "c"];
        let f = compile(&mut d, "a*cos(q) + c*sin(q) + b*cos(q) + a + b", &names).unwrap();
        let g = d.merge_like_terms(&[f], &[true, false, false, false])[0];
        let x = [0.3, 1.5, -0.25, 2.0];
        let (a, b) = (d.eval(&[f], &x)[0], d.eval(&[g], &x)[0]);
        assert!((a - b).abs() < 1e-15, "{a} vs {b}");
        let products = |r: Id| {
            let p = super::super::lower::lower(&d, &[r]);
            p.instrs.iter().filter(|i| i.op == Prim::Mul).count()
        };
        assert_eq!((products(f), products(g)), (3, 2));
    }
}
