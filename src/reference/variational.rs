//! The flow's Lyapunov exponents from its variational equations, an
//! implementation independent of the splitting schemes and their tangent
//! maps: the model's vector field (its field ops, run symbolically into
//! formulas by `models/symbolic.rs`), its Jacobian on the tangent space by
//! symbolic differentiation, and the state with k deviation vectors
//! integrated together by the DOP853 reference, re-orthonormalised by
//! modified Gram–Schmidt at every sample (Benettin's method on the flow).
//! The exponents of reeb's numerical maps converge to these as dt → 0.

use anyhow::{anyhow, Context, Result};

use crate::models::lanes::{self, Lane};
use crate::models::symbolic::LaneFormulas;
use crate::num::formula::Id;
use crate::plan::tangent::TangentStep;
use crate::plan::Plan;
use crate::reference::dop853::{dop853, Dop853Options};
use crate::reference::truth::lane_of;

/// The variational equations of a plan's model: the field of every
/// integrated variable, then the Jacobian on the tangent space.
struct Variational {
    formulas: LaneFormulas,
    /// `d<var>` per plan variable, then `J[i][j]` row by row.
    roots: Vec<Id>,
    vars: Vec<&'static str>,
    /// Positions of the tangent space's variables in `vars`.
    space: Vec<usize>,
}

impl Variational {
    fn new(plan: &Plan) -> Result<Variational> {
        let model = &plan.model;
        let mut f = LaneFormulas::new(model);
        for op in &plan.field_ops {
            f.apply(model, op).map_err(|e| anyhow!("{e}"))?;
        }
        let space_names = TangentStep::new(&plan.step_spec(), 1)
            .map_err(|e| anyhow!("{e}"))?
            .space;
        let mut roots = vec![];
        for v in &plan.vars {
            let d = format!("d{v}");
            let lane = lanes::NAMES
                .iter()
                .copied()
                .find(|n| *n == d)
                .with_context(|| format!("no lane {d}"))?;
            roots.push(f.read(lane));
        }
        let space: Vec<usize> = space_names
            .iter()
            .map(|v| {
                plan.vars
                    .iter()
                    .position(|w| w == v)
                    .expect("a state variable")
            })
            .collect();
        for &i in &space {
            for v in &space_names {
                let entry = match f.variable(v) {
                    Some(k) => f.dag.diff(roots[i], k),
                    None => f.dag.num(0.0),
                };
                roots.push(entry);
            }
        }
        Ok(Variational {
            formulas: f,
            roots,
            vars: plan.vars.clone(),
            space,
        })
    }

    /// `dy` of y = (state, then k deviation vectors of the tangent space).
    fn rhs(&self, base: &Lane<f64>, t: f64, y: &[f64], dy: &mut [f64]) {
        let (n, d) = (self.vars.len(), self.space.len());
        let mut lane = *base;
        for (v, x) in self.vars.iter().zip(y) {
            *lane.get_mut(v).expect("a lane") = *x;
        }
        lane.t = t;
        let f = &self.formulas;
        let inputs: Vec<f64> = f
            .variables
            .iter()
            .map(|l| lane.get(l).unwrap_or(0.0))
            .collect();
        let values = f.dag.eval(&self.roots, &inputs);
        dy[..n].copy_from_slice(&values[..n]);
        let jac = &values[n..];
        for (w, dw) in y[n..].chunks(d).zip(dy[n..].chunks_mut(d)) {
            for i in 0..d {
                dw[i] = (0..d).map(|j| jac[i * d + j] * w[j]).sum();
            }
        }
    }
}

/// The flow's `k` largest Lyapunov exponents along trajectory `traj` of
/// `plan` from its t0 over `duration`, re-orthonormalised every `sample`
/// (and at `t0 + skip`), summed after `skip` as reeb's Benettin sums are;
/// DOP853 at relative tolerance `rtol`. Largest first.
pub fn flow_exponents(
    plan: &Plan,
    traj: usize,
    k: usize,
    (duration, skip, sample): (f64, f64, f64),
    rtol: f64,
) -> Result<Vec<f64>> {
    let var = Variational::new(plan)?;
    let (n, d) = (var.vars.len(), var.space.len());
    anyhow::ensure!(
        k >= 1 && k <= d,
        "{k} vectors in a {d}-dimensional tangent space"
    );
    let base = lane_of(plan, traj);
    let mut y: Vec<f64> = var
        .vars
        .iter()
        .map(|v| base.get(v).unwrap_or(0.0))
        .collect();
    for j in 0..k {
        y.extend((0..d).map(|i| if i == j { 1.0 } else { 0.0 }));
    }
    let t0 = base.t0;
    let mut times: Vec<f64> = (1..)
        .map(|m| m as f64 * sample)
        .take_while(|s| *s < duration)
        .chain([skip, duration])
        .collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    let opts = Dop853Options {
        rtol,
        atol: rtol * 1e-2,
        ..Dop853Options::default()
    };
    let mut sums = vec![0.0; k];
    let mut from = 0.0;
    for to in times.into_iter().filter(|t| *t > 0.0) {
        let rhs = |t: f64, y: &[f64], dy: &mut [f64]| var.rhs(&base, t, y, dy);
        let (out, _) = dop853(rhs, t0 + from, &y, &[t0 + to], &opts)?;
        y.clone_from(&out[0]);
        let logs = orthonormalise(&mut y[n..], d);
        if from >= skip {
            for (s, l) in sums.iter_mut().zip(logs) {
                *s += l;
            }
        }
        from = to;
    }
    let mut out: Vec<f64> = sums.iter().map(|s| s / (duration - skip)).collect();
    out.sort_by(|a, b| b.total_cmp(a));
    Ok(out)
}

/// Modified Gram–Schmidt on the vectors (`d` values each) in `w`, in place;
/// returns ln Rᵢᵢ of each.
fn orthonormalise(w: &mut [f64], d: usize) -> Vec<f64> {
    let k = w.len() / d;
    let mut logs = Vec::with_capacity(k);
    for i in 0..k {
        for j in 0..i {
            let (done, rest) = w.split_at_mut(i * d);
            let q = &done[j * d..(j + 1) * d];
            let v = &mut rest[..d];
            let r: f64 = q.iter().zip(v.iter()).map(|(a, b)| a * b).sum();
            for (x, a) in v.iter_mut().zip(q) {
                *x -= r * a;
            }
        }
        let v = &mut w[i * d..(i + 1) * d];
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        for x in v.iter_mut() {
            *x /= norm;
        }
        logs.push(norm.ln());
    }
    logs
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::Model;
    use crate::plan::{Problem, Source};

    /// The linear damped oscillator's flow: λ₁ + λ₂ = −α exactly, and for
    /// an overdamped one the exponents are the roots of λ² + αλ + 1 = 0.
    #[test]
    fn overdamped_oscillator_exponents_are_the_eigenvalues() {
        let alpha = 3.0;
        let p = Problem::new(Model::DampedOscillator, "s2")
            .unwrap()
            .param("alpha", Source::Const(alpha))
            .initial("q", Source::Const(1.0));
        let plan = Plan::new(&p).unwrap();
        let l = flow_exponents(&plan, 0, 2, (200.0, 0.0, 1.0), 1e-11).unwrap();
        let disc = (alpha * alpha / 4.0 - 1.0f64).sqrt();
        let eig = [-alpha / 2.0 + disc, -alpha / 2.0 - disc];
        assert!((l[0] + l[1] + alpha).abs() < 1e-8, "{l:?}");
        // Finite time: the second exponent converges like 1/t.
        for (got, want) in l.iter().zip(eig) {
            assert!((got - want).abs() < 1e-2, "{l:?} against {eig:?}");
        }
    }
}
