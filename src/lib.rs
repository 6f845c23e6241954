//! reeb — contact Hamiltonian splitting integrators for large ensembles.
//!
//! See `README.md` for the command line and `../shared/SPEC.md` (the
//! mathematics) for what every formula computes.

pub mod dsl;
pub mod math;
pub mod models;
pub mod real;
