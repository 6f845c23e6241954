//! Formulas of deviation vectors that the indicators' sample programs
//! share: dot products, Gram–Schmidt's projections, reciprocals.

use crate::num::formula::{Dag, Id};

/// `v` minus its projections on the vectors of `basis`, each with
/// 1/‖b‖², one after the other (modified Gram–Schmidt: each projection of
/// the vector updated so far).
pub fn minus_projections(g: &mut Dag, mut v: Vec<Id>, basis: &[(Vec<Id>, Id)]) -> Vec<Id> {
    for (b, inv) in basis {
        let c = dot(g, &v, b);
        let proj = g.mul(c, *inv);
        v = v
            .iter()
            .zip(b)
            .map(|(x, y)| {
                let p = g.mul(proj, *y);
                g.sub(*x, p)
            })
            .collect();
    }
    v
}

pub fn dot(g: &mut Dag, a: &[Id], b: &[Id]) -> Id {
    let mut s = g.num(0.0);
    for (x, y) in a.iter().zip(b) {
        let p = g.mul(*x, *y);
        s = g.add(s, p);
    }
    s
}

/// 1/x: one division, then a product per component (a division each
/// would be d of them, the costliest operation of a sample).
pub fn reciprocal(g: &mut Dag, x: Id) -> Id {
    let one = g.num(1.0);
    g.div(one, x)
}
