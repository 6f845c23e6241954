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

/// What is merely surprising about a scene (it runs, perhaps not as meant):
/// located like a [`SceneError`]; printed as `warning: file:line: field: message`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct SceneWarning {
    pub path: PathBuf,
    pub line: Option<usize>,
    pub field: String,
    pub message: String,
}

impl std::fmt::Display for SceneWarning {
    // `file:line: field: message`, as a `SceneError` (without `warning: `).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        write!(f, ": {}: {}", self.field, self.message)
    }
}
