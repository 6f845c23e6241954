//! What both reports share: the command line's options, the scene's
//! `[report]` settings, and the directory the report is written to.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use crate::backend::BackendChoice;
use crate::num::precision::Precision;
use crate::scene::{ReportSettings, Scene};

/// Options of `reeb report`.
#[derive(Debug, Clone, Default)]
pub struct ReportOptions {
    pub out: Option<PathBuf>,
    /// Restrict the scene's backends / precisions.
    pub backend: Option<BackendChoice>,
    pub precision: Option<Precision>,
}

/// The scene's `[report]` table, or the defaults for its scheme.
pub(super) fn settings(scene: &Scene) -> ReportSettings {
    scene
        .report
        .clone()
        .unwrap_or_else(|| ReportSettings::defaults(&scene.scheme))
}

/// The report's directory (`--out`, or `runs/<scene>-<what>`), created.
pub(super) fn out_dir(scene: &Scene, opts: &ReportOptions, what: &str) -> Result<PathBuf> {
    let out = opts
        .out
        .clone()
        .unwrap_or_else(|| Path::new("runs").join(format!("{}-{what}", scene.name)));
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    Ok(out)
}

/// The precisions to run: the one asked for on the command line, or the scene's.
pub(super) fn precisions(opts: &ReportOptions, set: &ReportSettings) -> Vec<Precision> {
    match opts.precision {
        Some(p) => vec![p],
        None => set.precisions.clone(),
    }
}
