//! The GPU backend: wgpu compute shaders generated from the plan (see
//! [`codegen`]), run by [`run`]. One [`GpuContext`] (instance, adapter, device,
//! queue, pipeline cache) is created once and reused.

pub mod accuracy;
pub mod codegen;
pub mod context;
pub mod run;
pub mod time_table;
pub mod tuning;

pub use context::{
    every_gpu, is_software, list_adapters, validate, AdapterSummary, GpuContext, GpuError,
};
pub use run::{fingerprint, run, run_resumable, run_with, GpuOptions, GpuRun};
