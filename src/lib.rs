//! reeb — contact Hamiltonian splitting integrators for large ensembles.
//!
//! Layers, each using only the ones above it in this list (ARCHITECTURE.md;
//! `tests/suite/layers.rs` keeps it so): `num` (precision, primitives, own math,
//! the shared-function DSL) → `models` → `plan` (problem, scheme, observers,
//! plan, results) → `backend` (cpu, gpu, the one dispatch path) and
//! `reference` (DOP853, exact solutions as references) → `scene` → `output`
//! (arrays, pictures, `reeb run`) → `report`, `verify`, `bench` → the CLI.
//!
//! See `README.md` for the command line and `../shared/SPEC.md` (the
//! mathematics) for what every formula computes.

// The lower layers are crates of their own (`crates/`), so that an edit in
// the layers here never recompiles their kernels; re-exported, they keep
// their paths (`crate::plan::Plan`, `reeb::backend::cpu`).
pub use reeb_backend::backend;
pub use reeb_core::{models, num, plan};
// The macros the core exports (at its root), at reeb's.
pub use reeb_core::{
    lienard_methods, mechanical_1d_methods, model_lanes, model_ops, pieces, shared_fns, with_fma,
};

pub mod reference;

pub mod scene;

pub mod output;

pub mod bench;
pub mod doctor;
pub mod report;
pub mod verify;
pub mod verify_scene;

pub use num::precision::{Precision, Real};
