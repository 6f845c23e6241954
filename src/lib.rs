//! reeb — contact Hamiltonian splitting integrators for large ensembles.
//!
//! See `README.md` for the command line and `../shared/SPEC.md` (the
//! mathematics) for what every formula computes.

pub mod backend;
pub mod bench;
pub mod dsl;
pub mod exact;
pub mod math;
pub mod models;
pub mod observations;
pub mod observe;
pub mod pictures;
pub mod plan;
pub mod plot;
pub mod real;
pub mod reference;
pub mod report;
pub mod runner;
pub mod scene;
pub mod scheme;
pub mod truth;
pub mod verify;
