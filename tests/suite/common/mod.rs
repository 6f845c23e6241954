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

/// The single plan of a scene text.
pub fn plan(text: &str) -> reeb::plan::Plan {
    let path = std::path::Path::new("test.toml");
    let s = reeb::scene::Scene::parse(path, text).unwrap_or_else(|e| panic!("{e}"));
    let mut subs = s.sub_runs().unwrap();
    assert_eq!(subs.len(), 1);
    subs.remove(0).plan
}

/// The data of a `.npy` file reeb wrote (version 1.0, little-endian), and
/// its header.
pub fn npy(path: &std::path::Path) -> (String, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = String::from_utf8_lossy(&bytes[10..10 + len]).into_owned();
    (header, bytes[10 + len..].to_vec())
}

/// A real `.npy` array (`<f4` or `<f8`) as f64.
pub fn npy_f64(path: &std::path::Path) -> Vec<f64> {
    match npy(path) {
        (h, data) if h.contains("'<f4'") => {
            let v: Vec<f32> = bytemuck::pod_collect_to_vec(&data);
            v.into_iter().map(f64::from).collect()
        }
        (h, data) if h.contains("'<f8'") => bytemuck::pod_collect_to_vec(&data),
        (h, _) => panic!("{}: not a real array ({h})", path.display()),
    }
}

/// An integer `.npy` array of element type `T` (`<i4`, `<u4`, …).
pub fn npy_ints<T: bytemuck::Pod>(path: &std::path::Path) -> Vec<T> {
    bytemuck::pod_collect_to_vec(&npy(path).1)
}
