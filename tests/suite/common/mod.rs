//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod runs;

use std::sync::OnceLock;

use reeb::backend::gpu::GpuContext;

#[allow(unused_imports)] // not every test crate takes them
pub use reeb::verify::samples::{first_var, problem};

/// The GPU context shared by a test binary, or `None` (after printing SKIP)
/// when no adapter exists. With `REEB_REQUIRE_GPU=1` (CI, after installing
/// lavapipe) a missing adapter fails the test instead: GPU tests never skip
/// silently there.
pub fn gpu() -> Option<&'static GpuContext> {
    static CTX: OnceLock<Option<GpuContext>> = OnceLock::new();
    CTX.get_or_init(|| match GpuContext::new() {
        Ok(c) => Some(c),
        Err(e) => {
            if std::env::var("REEB_REQUIRE_GPU").is_ok_and(|v| v == "1") {
                panic!("REEB_REQUIRE_GPU=1 but no GPU adapter: {e}");
            }
            eprintln!("SKIP: no GPU adapter ({e})");
            None
        }
    })
    .as_ref()
}
