//! The papers behind a run's scheme and model, as `summary.json`'s
//! `references` lists them (and `CITATION.cff` in full).

/// Contact splitting integrators, and the celestial models they were
/// introduced on (Kepler, Lane–Emden, the dissipative spin–orbit problem).
const CELESTIAL: &str = "A. Bravetti, M. Seri, M. Vermeeren, F. Zadra, Numerical integration in celestial mechanics: a case for contact geometry, Celestial Mechanics and Dynamical Astronomy 132 (2020)";
/// Contact variational integrators, and the damped oscillator.
const VARIATIONAL: &str = "M. Vermeeren, A. Bravetti, M. Seri, Contact variational integrators, Journal of Physics A: Mathematical and Theoretical 52, 445206 (2019)";
/// Contact splitting of Liénard systems (van der Pol among them).
const LIENARD: &str = "F. Zadra, A. Bravetti, M. Seri, Geometric numerical integration of Liénard systems via a contact Hamiltonian approach, Mathematics 9 (2021)";
const YOSHIDA: &str =
    "H. Yoshida, Construction of higher order symplectic integrators, Physics Letters A 150 (1990)";
const MCLACHLAN: &str = "R. I. McLachlan, On the numerical integration of ordinary differential equations by symmetric composition methods, SIAM Journal on Scientific Computing 16 (1995)";
const KAHAN_LI: &str = "W. Kahan, R.-C. Li, Composition constants for raising the orders of unconventional schemes for ordinary differential equations, Mathematics of Computation 66 (1997)";
const SOFSPA: &str = "M. Sofroniou, G. Spaletta, Derivation of symmetric composition constants for symmetric integrators, Optimization Methods and Software 20 (2005)";

/// The citations for scheme `scheme` and model `model` (by their scene
/// names), each once, the scheme's first. A user's formula model cites
/// only its scheme's papers.
pub fn references(scheme: &str, model: &str) -> Vec<&'static str> {
    let of_scheme: &[&str] = match scheme {
        "s2" => &[CELESTIAL],
        s if s.starts_with("triple_jump") || s.starts_with("yoshida") => &[CELESTIAL, YOSHIDA],
        "mclachlan4" => &[CELESTIAL, MCLACHLAN],
        "kahanli6" | "kahanli8" => &[CELESTIAL, KAHAN_LI],
        "sofspa10" => &[CELESTIAL, SOFSPA],
        "variational1" | "variational2" => &[VARIATIONAL],
        // Classical comparison methods (RK4, leapfrog).
        _ => &[],
    };
    let of_model: &[&str] = match model {
        "van_der_pol" | "lienard" => &[LIENARD],
        "kepler" | "lane_emden" | "spin_orbit" => &[CELESTIAL],
        "damped_oscillator" | "quadratic_s" => &[VARIATIONAL],
        _ => &[],
    };
    let mut all: Vec<&'static str> = vec![];
    for r in of_scheme.iter().chain(of_model) {
        if !all.contains(r) {
            all.push(r);
        }
    }
    all
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::scheme::{Scheme, SchemeKind, SCHEME_NAMES};

    #[test]
    fn every_splitting_scheme_cites_the_contact_splitting_paper() {
        for name in SCHEME_NAMES {
            let splitting = matches!(
                Scheme::by_name(name).unwrap().kind,
                SchemeKind::Splitting { .. }
            );
            // A user's model: the scheme's papers alone.
            let cited = references(name, "a_formula_model");
            assert_eq!(cited.first() == Some(&CELESTIAL), splitting, "{name}");
        }
    }

    #[test]
    fn every_built_in_model_cites_its_paper() {
        for name in crate::models::MODEL_NAMES {
            assert!(!references("rk4", name).is_empty(), "{name}");
        }
    }

    #[test]
    fn a_paper_is_cited_once() {
        assert_eq!(references("s2", "spin_orbit"), [CELESTIAL]);
        assert_eq!(
            references("kahanli8", "van_der_pol"),
            [CELESTIAL, KAHAN_LI, LIENARD]
        );
        assert!(references("rk4", "my_formula_model").is_empty());
    }
}
