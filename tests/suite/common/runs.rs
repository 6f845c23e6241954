//! Helpers of the tests that run the `reeb` binary on streamed runs
//! (`stream.rs`, `zarr.rs`, `slurm.rs`): folders, commands, a scene that
//! exercises every output, and the bitwise comparison of two runs.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub const REEB: &str = env!("CARGO_BIN_EXE_reeb");

/// A fresh folder `<prefix>-<name>` under the target directory.
pub fn tmp(prefix: &str, name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("{prefix}-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A path as a command-line argument.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

pub fn reeb(args: &[&str]) -> Output {
    Command::new(REEB).args(args).output().unwrap()
}

/// `summary.json` of the run in `dir`.
pub fn summary(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("summary.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// Runs `reeb args`, which must succeed; returns its stdout and stderr.
pub fn ok(args: &[&str]) -> String {
    let o = reeb(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "reeb {args:?}: {err}");
    String::from_utf8_lossy(&o.stdout).into_owned() + &err
}

/// A van der Pol grid (6 × 7 × 2) with a `dt` axis (two plans interleaved
/// in the rows), frames every `every` steps, cycle statistics and a
/// stroboscopic section, up to `t_end`; written as `dir/grid.toml`.
pub fn grid_scene(dir: &Path, t_end: f64, every: u64, backend: &str) -> PathBuf {
    let text = format!(
        r#"model = "van_der_pol"
[params]
epsilon = {{ linspace = [0.5, 2.0, 6] }}
[initial]
q = {{ linspace = [0.5, 2.5, 7] }}
[integrator]
scheme = "s2"
dt = [0.01, 0.02]
t_end = {t_end}
[output]
final = ["q", "s"]
trajectory = {{ every = {every}, vars = ["q"] }}
cycle = true
poincare = {{ period = 1.0, max_points = 20, vars = ["q", "p"] }}
[run]
backend = "{backend}"
precision = "f64"
"#
    );
    let path = dir.join("grid.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// Every `.npy` of `a` and `b` (the same names, at least 8), byte for byte.
pub fn same_arrays(a: &Path, b: &Path) {
    let list = |d: &Path| {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".npy"))
            .collect();
        v.sort();
        v
    };
    let (la, lb) = (list(a), list(b));
    assert_eq!(la, lb, "{} vs {}", a.display(), b.display());
    assert!(la.len() >= 8, "{la:?}");
    for f in &la {
        let (x, y) = (
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
        );
        assert!(
            x == y,
            "{f} differs between {} and {}",
            a.display(),
            b.display()
        );
    }
}

/// `s` as a TOML basic string.
pub fn toml_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", c as u32)),
            c => out.push(c),
        }
    }
    out + "\""
}
