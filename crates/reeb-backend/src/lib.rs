//! reeb's backends: the CPU's fused kernels, tangent and sample programs
//! (rayon, SIMD), the GPU's generated WGSL (wgpu), the one dispatch path and
//! the tuning probe. Built on `reeb-core` alone, whose layers it re-exports
//! so that paths read `crate::plan::…` here as in every layer above.

pub use reeb_core::{models, num, plan};

pub mod backend;
