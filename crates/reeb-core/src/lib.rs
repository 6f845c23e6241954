//! reeb's core: numbers, models and plans, the layers every backend and
//! every output stands on (`num` → `models` → `plan`, each using only the
//! ones before it; ARCHITECTURE.md). No backend, file or picture is here, so
//! that an edit above these layers never recompiles them.

pub mod num;

pub mod models;

pub mod plan;
