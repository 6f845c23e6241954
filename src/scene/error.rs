//! The error of a scene file: where (file, line, field) and what is wrong.

use std::path::PathBuf;

/// A scene error: file, line, field and what is wrong.
#[derive(Debug, Clone, thiserror::Error)]
#[error("{}{}: {field}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
pub struct SceneError {
    pub path: PathBuf,
    pub line: Option<usize>,
    pub field: String,
    pub message: String,
}
