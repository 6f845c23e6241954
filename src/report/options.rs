//! What both reports share: the command line's options, the scene's
//! `[report]` settings, and the directory the report is written to.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use anyhow::{Context, Result};

use crate::backend::BackendChoice;
use crate::num::precision::Precision;
use crate::output::directory::{self, Claim};
use crate::output::run::{provenance, write_json};
use crate::scene::{ReportSettings, Scene};

/// Options of `reeb report`.
#[derive(Debug, Clone, Default)]
pub struct ReportOptions {
    pub out: Option<PathBuf>,
    /// Restrict the scene's backends / precisions.
    pub backend: Option<BackendChoice>,
    pub precision: Option<Precision>,
    /// Replace `out` even when it holds files reeb did not write.
    pub force: bool,
    /// Set from another thread to stop the report (Ctrl-C in Python): its
    /// runs end with an error and its `.partial` directory is removed.
    pub stop: Option<Arc<AtomicBool>>,
}

/// The scene's `[report]` table, or the defaults for its scheme.
pub(super) fn settings(scene: &Scene) -> ReportSettings {
    scene
        .report
        .clone()
        .unwrap_or_else(|| ReportSettings::defaults(&scene.scheme))
}

/// Claims the report's directory (`--out`, or `runs/<scene>-<what>`)
/// before any work, under the rules of `reeb run` (`output/directory.rs`);
/// the report is written into the claim's `.partial`.
pub(super) fn claim_dir(scene: &Scene, opts: &ReportOptions, what: &str) -> Result<Claim> {
    let out = opts
        .out
        .clone()
        .unwrap_or_else(|| Path::new("runs").join(format!("{}-{what}", scene.name)));
    directory::claim(&out, &[&scene.path], opts.force)
}

/// Lists the report's files in its summary.json and swaps its directory
/// into place; returns the path of `main` there.
pub(super) fn finish(claim: Claim, scene: &Scene, what: &str, main: &str) -> Result<PathBuf> {
    let mut files = vec![];
    for e in std::fs::read_dir(claim.dir())
        .with_context(|| format!("reading {}", claim.dir().display()))?
    {
        let name = e?.file_name().to_string_lossy().into_owned();
        if !name.starts_with('.') {
            files.push(name);
        }
    }
    files.sort();
    let mut summary = serde_json::json!({
        "reeb_version": env!("CARGO_PKG_VERSION"),
        "report": what,
        "scene": {"name": scene.name, "path": scene.path.display().to_string(), "text": scene.text},
        "files": files,
    });
    if let serde_json::Value::Object(map) = &mut summary {
        map.extend(provenance(true));
    }
    write_json(&claim.dir().join("summary.json"), &summary)?;
    Ok(claim.commit()?.join(main))
}

/// The precisions to run: the one asked for on the command line, or the
/// scene's; each passes the scene's precision checks (its warnings printed).
pub(super) fn precisions(
    scene: &Scene,
    opts: &ReportOptions,
    set: &ReportSettings,
) -> Result<Vec<Precision>> {
    let precisions = match opts.precision {
        Some(p) => vec![p],
        None => set.precisions.clone(),
    };
    for p in &precisions {
        for w in scene.checks(*p)? {
            eprintln!("warning ({p}): {w}");
        }
    }
    Ok(precisions)
}
