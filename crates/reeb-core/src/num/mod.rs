//! Numbers: the working precision, the primitives both backends implement by
//! hand, reeb's own elementary functions, and the shared-function DSL that
//! writes every formula once for Rust and WGSL. Knows nothing of models.

pub mod dsl;
pub mod formula;
pub mod isa;
pub mod math;
pub mod names;
pub mod order;
pub mod precision;
pub mod prims;
