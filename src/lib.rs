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

pub mod num;

pub mod models;

pub mod plan;

pub mod backend;
pub mod reference;

pub mod scene;

pub mod output;

pub mod bench;
pub mod doctor;
pub mod report;
pub mod verify;
pub mod verify_scene;

pub use num::precision::{Precision, Real};
