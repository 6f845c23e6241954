//! The alignment indices SALI (Skokos 2001) and GALI_k (Skokos, Bountis
//! and Antonopoulos 2007) as a sample program. Their deviation vectors
//! follow the tangent map freely, never orthogonalised, and are brought
//! back to unit length at each sample (which changes no direction, so
//! nothing the indices read). Of the unit vectors ŵ₁ … ŵ_m:
//!
//! - SALI = min(‖ŵ₁ + ŵ₂‖, ‖ŵ₁ − ŵ₂‖), from the sum and the difference
//!   themselves, not from 2 ± 2 ŵ₁·ŵ₂, whose cancellation would stop it
//!   at √ε instead of ε;
//! - GALI_m = ‖ŵ₁ ∧ … ∧ ŵ_m‖, the product of the norms of the vectors
//!   Gram–Schmidt leaves (modified: each projection on the vector
//!   updated so far), which is the product of the singular values of the
//!   matrix of the ŵᵢ; 0, never NaN, once round-off aligns two of them.
//!
//! On a chaotic orbit every vector turns towards the most unstable
//! direction and both go to 0 exponentially; on a regular orbit of N
//! degrees of freedom the vectors fall into the torus' tangent space,
//! SALI and GALI_k for k ≤ N stay of order one and GALI_k decays as a
//! power of t beyond.

use crate::num::formula::lower::{lower, Lowered};
use crate::num::formula::{Dag, Func, Func2, Id};

use super::vectors::{dot, minus_projections, reciprocal};

/// The program over `m ≥ 2` vectors of dimension `d`. Inputs: the
/// vectors' components (vector i's component j at i·d + j), then SALI and
/// GALI (not read: so that each output is written over its input, as the
/// CPU's compiled samples keep their state); outputs: the unit vectors in
/// the same order, then SALI (of the first two) and GALI_m.
pub fn alignment_program(d: usize, m: usize) -> Lowered {
    assert!(m >= 2, "SALI and GALI need two vectors");
    let mut g = Dag::new();
    let unit: Vec<Vec<Id>> = (0..m)
        .map(|i| {
            let w: Vec<Id> = (0..d).map(|j| g.var((i * d + j) as u32)).collect();
            normalised(&mut g, &w)
        })
        .collect();
    let sali = sali(&mut g, &unit[0], &unit[1]);
    let gali = gali(&mut g, &unit);
    let mut roots = unit.concat();
    roots.extend([sali, gali]);
    lower(&g, &roots)
}

/// `w / ‖w‖`: NaN where ‖w‖ is 0 or not finite, as for a diverged vector.
fn normalised(g: &mut Dag, w: &[Id]) -> Vec<Id> {
    let n2 = dot(g, w, w);
    let norm = g.call(Func::Sqrt, n2);
    let inv = reciprocal(g, norm);
    w.iter().map(|x| g.mul(*x, inv)).collect()
}

fn sali(g: &mut Dag, a: &[Id], b: &[Id]) -> Id {
    let sum: Vec<Id> = a.iter().zip(b).map(|(x, y)| g.add(*x, *y)).collect();
    let diff: Vec<Id> = a.iter().zip(b).map(|(x, y)| g.sub(*x, *y)).collect();
    let plus = dot(g, &sum, &sum);
    let minus = dot(g, &diff, &diff);
    let least = g.call2(Func2::Min, plus, minus);
    g.call(Func::Sqrt, least)
}

/// The volume spanned by unit vectors: modified Gram–Schmidt, the
/// squared norms of what it leaves multiplied, one square root.
fn gali(g: &mut Dag, unit: &[Vec<Id>]) -> Id {
    let mut basis: Vec<(Vec<Id>, Id)> = vec![];
    let mut volume2 = g.num(1.0);
    for w in unit {
        let v = minus_projections(g, w.clone(), &basis);
        let n2 = dot(g, &v, &v);
        volume2 = g.mul(volume2, n2);
        // A part that round-off left at 0 projects as 0, not NaN (its
        // volume is 0 already); f32's least normal number is one in f64.
        let least = g.num(f64::from(f32::MIN_POSITIVE));
        let floored = g.call2(Func2::Max, n2, least);
        basis.push((v, reciprocal(g, floored)));
    }
    g.call(Func::Sqrt, volume2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::num::formula::tape::Tape;
    use crate::num::isa::Isa;

    /// The program on one set of vectors, by the tape in f64.
    fn run(d: usize, vectors: &[Vec<f64>]) -> Vec<f64> {
        let tape = Tape::<f64>::new(&alignment_program(d, vectors.len()), |_| false);
        let mut inputs: Vec<[f64; 1]> = vectors.concat().into_iter().map(|x| [x]).collect();
        inputs.extend([[f64::NAN], [f64::NAN]]);
        let mut regs = vec![[0.0; 1]; tape.registers];
        tape.run(&mut regs, inputs.as_slice(), Isa::Baseline);
        (0..tape.outputs())
            .map(|k| tape.output(&regs, k)[0])
            .collect()
    }

    #[test]
    fn orthonormal_vectors_have_sali_root_two_and_unit_volume() {
        let out = run(
            3,
            &[
                vec![2.0, 0.0, 0.0],
                vec![0.0, 0.5, 0.0],
                vec![0.0, 0.0, 3.0],
            ],
        );
        assert_eq!(&out[..3], &[1.0, 0.0, 0.0]);
        assert!((out[9] - 2f64.sqrt()).abs() < 1e-15, "sali {}", out[9]);
        assert!((out[10] - 1.0).abs() < 1e-15, "gali {}", out[10]);
    }

    #[test]
    fn the_indices_match_their_definitions() {
        // Two vectors at angle θ: SALI = 2 sin(θ/2) for θ ≤ π/2, GALI_2 = sin θ.
        for theta in [1e-9, 1e-4, 0.3, 1.2, 2.5] {
            let (s, c) = f64::sin_cos(theta);
            let out = run(2, &[vec![3.0, 0.0], vec![5.0 * c, 5.0 * s]]);
            let sali = 2.0 * (theta.min(std::f64::consts::PI - theta) / 2.0).sin();
            assert!(
                (out[4] / sali - 1.0).abs() < 1e-6,
                "θ {theta}: sali {} vs {sali}",
                out[4]
            );
            assert!(
                (out[5] / s - 1.0).abs() < 1e-6,
                "θ {theta}: gali {} vs {s}",
                out[5]
            );
        }
        // Aligned to the last bit: both indices 0, and a vector after
        // them leaves the volume 0, not NaN.
        let out = run(
            3,
            &[
                vec![2.0, 0.0, 0.0],
                vec![1.0, 0.0, 0.0],
                vec![0.0, 1.0, 0.0],
            ],
        );
        assert_eq!((out[9], out[10]), (0.0, 0.0));
        // GALI_3 of three vectors in 3-D: |det| over the norms' product.
        let v = [
            vec![1.0, 2.0, 0.5],
            vec![-0.3, 1.0, 2.0],
            vec![0.7, -1.1, 0.4],
        ];
        let det = v[0][0] * (v[1][1] * v[2][2] - v[1][2] * v[2][1])
            - v[0][1] * (v[1][0] * v[2][2] - v[1][2] * v[2][0])
            + v[0][2] * (v[1][0] * v[2][1] - v[1][1] * v[2][0]);
        let norms: f64 = v
            .iter()
            .map(|x| x.iter().map(|y| y * y).sum::<f64>().sqrt())
            .product();
        let out = run(3, &v);
        assert!(
            (out[10] - det.abs() / norms).abs() < 1e-14,
            "gali {}",
            out[10]
        );
    }
}
