//! Never lose a user's files (issue 10, point 1): `--out` replaces only a
//! complete reeb output, refuses what it must not touch before any work,
//! owns `DIR.partial` through a lock, and reports use the same rules.

use std::path::{Path, PathBuf};
use std::process::Command;

/// A small, fast scene.
const SCENE: &str = r#"
model = "damped_oscillator"
[params]
alpha = [0.1, 0.2]
[initial]
q = 1.0
p = 0.0
[integrator]
scheme = "s2"
dt = 0.01
t_end = 1.0
[output]
final = ["q", "p"]
"#;

/// A scratch folder holding `scene.toml`, removed at the end.
struct Sandbox {
    dir: PathBuf,
}

impl Sandbox {
    fn new(name: &str) -> Sandbox {
        let dir = std::env::temp_dir().join(format!("reeb-safety-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("scene.toml"), SCENE).unwrap();
        Sandbox { dir }
    }
    fn path(&self, rel: &str) -> PathBuf {
        self.dir.join(rel)
    }
    fn write(&self, rel: &str, text: &str) {
        let p = self.path(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }
    /// `reeb ARGS` run in `cwd` (relative to the sandbox): (success, stderr).
    fn reeb_in(&self, cwd: &str, args: &[&str]) -> (bool, String) {
        let out = Command::new(env!("CARGO_BIN_EXE_reeb"))
            .args(args)
            .current_dir(self.path(cwd))
            .output()
            .expect("reeb runs");
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(
            out.status.code().is_some_and(|c| c <= 1),
            "reeb {args:?} ended with {:?}: {err}",
            out.status
        );
        (out.status.success(), err)
    }
    fn reeb(&self, args: &[&str]) -> (bool, String) {
        self.reeb_in("", args)
    }
    fn run_into(&self, out: &str, extra: &[&str]) -> (bool, String) {
        let mut args = vec!["run", "scene.toml", "--backend", "cpu", "--out", out];
        args.extend_from_slice(extra);
        self.reeb(&args)
    }
}

impl Drop for Sandbox {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

fn refused(r: (bool, String), needle: &str) {
    assert!(!r.0, "expected a refusal containing {needle:?}");
    assert!(r.1.contains(needle), "expected {needle:?} in: {}", r.1);
    assert!(
        !r.1.contains("trajectory-steps/s"),
        "refused after the work: {}",
        r.1
    );
}

#[test]
fn a_rerun_replaces_its_own_output_and_only_it() {
    let s = Sandbox::new("rerun");
    assert!(s.run_into("res", &[]).0);
    let first = names(&s.path("res"));
    assert!(first.contains(&"summary.json".to_string()));
    assert!(s.run_into("res", &[]).0, "re-running a scene just works");
    assert_eq!(names(&s.path("res")), first);
    // A file the old summary listed but the new run does not write goes.
    s.write("scene.toml", &SCENE.replace("[\"q\", \"p\"]", "[\"q\"]"));
    assert!(s.run_into("res", &[]).0);
    assert!(!s.path("res/final_p.npy").exists());
    assert!(!s.path("res.partial").exists());
}

#[test]
fn a_folder_with_other_files_is_refused_unless_forced() {
    let s = Sandbox::new("notes");
    assert!(s.run_into("res", &[]).0);
    s.write("res/notes.txt", "my notes");
    refused(s.run_into("res", &[]), "notes.txt");
    assert_eq!(
        std::fs::read_to_string(s.path("res/notes.txt")).unwrap(),
        "my notes"
    );
    s.write("mine/data.csv", "1,2");
    refused(s.run_into("mine", &[]), "is not a reeb output");
    assert!(s.path("mine/data.csv").exists());
    assert!(s.run_into("res", &["--force"]).0);
    assert!(!s.path("res/notes.txt").exists());
}

#[test]
fn protected_places_are_refused_even_when_forced() {
    let s = Sandbox::new("protected");
    s.write("work/keep.txt", "keep");
    std::fs::copy(s.path("scene.toml"), s.path("work/scene.toml")).unwrap();
    for (cwd, scene, out, needle) in [
        ("", "scene.toml", ".", "is the working directory"),
        ("work", "scene.toml", ".", "is the working directory"),
        (
            "work",
            "scene.toml",
            "..",
            "an ancestor of the working directory",
        ),
        (
            "work",
            "scene.toml",
            "/",
            "an ancestor of the working directory",
        ),
        (
            "",
            "work/scene.toml",
            "work",
            "which replacing it would delete",
        ),
    ] {
        for force in [false, true] {
            let mut args = vec!["run", scene, "--backend", "cpu", "--out", out];
            if force {
                args.push("--force");
            }
            refused(s.reeb_in(cwd, &args), needle);
        }
    }
    assert_eq!(names(&s.path("work")), ["keep.txt", "scene.toml"]);
    assert!(s.path("scene.toml").exists());
}

#[test]
fn a_file_or_a_link_as_out_is_refused() {
    let s = Sandbox::new("file");
    s.write("results", "a file");
    refused(s.run_into("results", &["--force"]), "is a file");
    assert_eq!(
        std::fs::read_to_string(s.path("results")).unwrap(),
        "a file"
    );
    assert!(!s.path("results.partial").exists());
    #[cfg(unix)]
    {
        s.write("target/x.txt", "x");
        std::os::unix::fs::symlink(s.path("target"), s.path("link")).unwrap();
        refused(s.run_into("link", &["--force"]), "symbolic link");
        assert!(s.path("target/x.txt").exists());
    }
}

#[test]
fn a_partial_is_owned_through_a_lock() {
    let s = Sandbox::new("partial");
    // Left by a killed run: reported and reused.
    s.write("res.partial/.reeb-owner", "pid 999999 on elsewhere\n");
    s.write("res.partial/final_q.npy", "half-written");
    let (ok, err) = s.run_into("res", &[]);
    assert!(ok, "{err}");
    assert!(
        err.contains("was left by a run that did not finish"),
        "{err}"
    );
    assert!(!s.path("res.partial").exists());
    assert!(s.path("res/summary.json").exists());
    // Held by a live run: refused, untouched.
    s.write("res2.partial/.reeb-owner", "pid 1 on here\n");
    let held = std::fs::File::open(s.path("res2.partial")).unwrap();
    held.lock().unwrap();
    refused(
        s.run_into("res2", &[]),
        "is being written by another reeb run",
    );
    assert!(s.path("res2.partial/.reeb-owner").exists());
    drop(held);
    // Not reeb's: refused, untouched.
    s.write("res3.partial/mine.txt", "mine");
    refused(s.run_into("res3", &[]), "was not made by reeb");
    assert!(s.path("res3.partial/mine.txt").exists());
}

#[test]
fn an_unwritable_location_fails_before_the_work_naming_the_path() {
    let s = Sandbox::new("unwritable");
    // /proc accepts no new folders, even for root.
    let (ok, err) = s.run_into("/proc/reeb-no-such-dir/out", &[]);
    assert!(!ok);
    assert!(err.contains("/proc/reeb-no-such-dir"), "{err}");
    assert!(!err.contains("trajectory-steps/s"), "{err}");
}

#[test]
fn summary_records_where_and_how_the_run_was_made() {
    let s = Sandbox::new("summary");
    assert!(s.run_into("res", &[]).0);
    let text = std::fs::read_to_string(s.path("res/summary.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let args = v["command_line"].as_array().unwrap();
    assert_eq!(args[1], "run");
    assert!(args.iter().any(|a| a == "--out"));
    assert!(!v["host"].as_str().unwrap().is_empty());
    let utc = v["utc"].as_str().unwrap();
    assert!(utc.ends_with('Z') && utc.len() == 20, "{utc}");
    assert!(v["cpu_isa"].as_str().is_some(), "the CPU ran: {v}");
}

#[test]
fn reports_use_the_same_rules_and_leave_nothing_when_they_fail() {
    let s = Sandbox::new("report");
    // A stability report needs a 2-D grid: this one fails after its claim.
    let (ok, _) = s.reeb(&["report", "stability", "scene.toml", "--out", "st"]);
    assert!(!ok);
    assert!(!s.path("st").exists() && !s.path("st.partial").exists());
    s.write("st/notes.txt", "mine");
    refused(
        s.reeb(&["report", "stability", "scene.toml", "--out", "st"]),
        "notes.txt",
    );
    assert!(s.path("st/notes.txt").exists());
    refused(
        s.reeb(&["report", "work-precision", "scene.toml", "--out", "."]),
        "is the working directory",
    );
}

#[test]
fn a_full_disk_is_reported_with_the_path() {
    // /dev/full answers every write with ENOSPC.
    let full = Path::new("/dev/full");
    if !full.exists() {
        return;
    }
    let e = reeb::output::run::write_npy(full, &[4], [1.0f64; 4])
        .expect_err("writing to /dev/full fails");
    let e = format!("{e:#}");
    assert!(
        e.contains("/dev/full") && e.contains("No space left"),
        "{e}"
    );
}

#[test]
fn free_disk_space_is_compared_with_the_estimate_before_the_work() {
    let s = Sandbox::new("space");
    let out = s.path("res");
    let claim = reeb::output::directory::claim(&out, &[], false).unwrap();
    assert!(claim.check_space(1).is_ok());
    let e = format!("{:#}", claim.check_space(u64::MAX).err().unwrap());
    assert!(e.contains("on disk") && e.contains("free there"), "{e}");
    assert!(e.contains(&out.display().to_string()), "{e}");
    let partial = claim.dir().to_path_buf();
    assert!(partial.exists());
    drop(claim);
    // A claim given up removes its partial and creates nothing.
    assert!(!partial.exists() && !out.exists());
}

#[test]
fn check_applies_the_output_gate_of_run_without_writing() {
    let s = Sandbox::new("check");
    let (ok, err) = s.reeb(&["check", "scene.toml", "--out", "res"]);
    assert!(ok, "{err}");
    assert!(!s.path("res").exists() && !s.path("res.partial").exists());
    assert!(s.run_into("res", &[]).0);
    assert!(s.reeb(&["check", "scene.toml", "--out", "res"]).0);
    s.write("res/notes.txt", "mine");
    refused(
        s.reeb(&["check", "scene.toml", "--out", "res"]),
        "notes.txt",
    );
    assert!(
        s.reeb(&["check", "scene.toml", "--out", "res", "--force"])
            .0
    );
    refused(
        s.reeb(&["check", "scene.toml", "--out", "."]),
        "working directory",
    );
    refused(
        s.reeb(&["check", "scene.toml", "--out", "scene.toml"]),
        "is a file",
    );
    assert!(s.path("res/notes.txt").exists());
}
