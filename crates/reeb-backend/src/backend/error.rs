//! What a backend run can fail with: the GPU's own errors, and what any
//! backend may say (too large, a checkpoint, stopped as asked).

use super::gpu::context::GpuError;

#[derive(Debug, thiserror::Error)]
pub enum BackendError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// The plan's arrays or buffers do not fit (in memory, in 64 bits, in
    /// the adapter's limits).
    #[error("{0}")]
    TooLarge(String),
    #[error("checkpoint: {0}")]
    Checkpoint(String),
    /// A kernel the adapter ended early (a driver's loop limit).
    #[error("{0}")]
    Cut(String),
    /// A launch the environment asks for and the adapter cannot take.
    #[error("GPU tuning: {0}")]
    Tuning(String),
    #[error("stopped before the end, as asked")]
    Stopped,
}

impl BackendError {
    /// A checkpoint that could not be written or read back.
    pub fn checkpoint(e: std::io::Error) -> BackendError {
        BackendError::Checkpoint(e.to_string())
    }
}

impl From<super::gpu::codegen::CodegenError> for BackendError {
    fn from(e: super::gpu::codegen::CodegenError) -> BackendError {
        BackendError::Gpu(e.into())
    }
}
