//! What other processes, nodes and days left on disk is checked before it
//! is trusted (issue 31): finished chunks against the sizes and checksums
//! their markers recorded (points 2 and 8), checkpoints against their
//! trailers (point 2), what replacing an output may remove (point 5), and
//! the smaller findings of point 8.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use crate::common;

use common::runs::{grid_scene, ok, reeb, s, same_arrays, REEB};

fn tmp(name: &str) -> PathBuf {
    common::runs::tmp("on-disk", name)
}

/// Runs `reeb args`, which must fail; returns its stderr.
fn refused(args: &[&str]) -> String {
    let o = reeb(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "reeb {args:?} succeeded: {err}");
    err
}

/// The two shards of `scene` in chunks of at most 7 trajectories.
fn two_shards(scene: &Path, out: &Path) {
    for k in ["0/2", "1/2"] {
        let args = ["run", s(scene), "--out", s(out), "--shard", k];
        ok(&[&args[..], &["--chunk-trajectories", "7"]].concat());
    }
}

fn partial(out: &Path) -> PathBuf {
    let mut p = out.as_os_str().to_owned();
    p.push(".partial");
    PathBuf::from(p)
}

#[test]
fn deleted_or_cut_arrays_are_integrated_again_on_resume() {
    let d = tmp("resume");
    let scene = grid_scene(&d, 20.0, 100, "cpu");
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    let out = d.join("run");
    let args = ["run", s(&scene), "--out", s(&out), "--shard", "0/2"];
    ok(&[&args[..], &["--chunk-trajectories", "7"]].concat());
    let p = partial(&out);
    std::fs::remove_file(p.join("final_q.npy")).unwrap();
    let cut = std::fs::OpenOptions::new()
        .write(true)
        .open(p.join("trajectory_q.npy"))
        .unwrap();
    cut.set_len(1000).unwrap();
    let said = ok(&["run", s(&scene), "--out", s(&out), "--resume"]);
    assert!(
        said.contains("chunk 0 (trajectories 0..") && said.contains("was marked finished, but"),
        "{said}"
    );
    same_arrays(&one, &out);
}

#[test]
fn merge_integrates_a_damaged_chunk_again() {
    let d = tmp("merge");
    let scene = grid_scene(&d, 20.0, 100, "cpu");
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    let out = d.join("run");
    two_shards(&scene, &out);
    // One byte of row 65 of cycle_period.npy (8-byte f64 per row, a
    // 128-byte header) flipped, as a bad disk or a stray writer would.
    let path = partial(&out).join("cycle_period.npy");
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[128 + 8 * 65 + 3] ^= 0x40;
    std::fs::write(&path, bytes).unwrap();
    let said = ok(&["merge", s(&out)]);
    assert!(
        said.contains("was marked finished, but cycle_period.npy's bytes differ"),
        "{said}"
    );
    assert!(said.contains("integrating 1 chunk(s) again"), "{said}");
    same_arrays(&one, &out);
}

#[test]
fn a_deleted_zarr_chunk_is_integrated_again() {
    let d = tmp("zarr");
    let scene = grid_scene(&d, 20.0, 100, "cpu");
    let zarr = |out: &Path, extra: &[&str]| {
        let args = ["run", s(&scene), "--out", s(out), "--format", "zarr"];
        ok(&[&args[..], &["--chunk-trajectories", "7"], extra].concat())
    };
    let one = d.join("one");
    zarr(&one, &[]);
    let out = d.join("run");
    zarr(&out, &["--shard", "0/2"]);
    zarr(&out, &["--shard", "1/2"]);
    let chunks = files(&partial(&out));
    let chunk = chunks
        .iter()
        .filter(|f| f.starts_with("run.zarr/final_q/c"))
        .nth(1)
        .expect("a second chunk of final_q");
    std::fs::remove_file(partial(&out).join(chunk)).unwrap();
    let said = ok(&["merge", s(&out)]);
    assert!(said.contains("final_q.npy's bytes differ"), "{said}");
    let (a, b) = (files(&one), files(&out));
    assert_eq!(a, b);
    assert!(a.len() > 50, "{a:?}");
    for f in &a {
        let same = std::fs::read(one.join(f)).unwrap() == std::fs::read(out.join(f)).unwrap();
        assert!(same, "{} differs", f.display());
    }
}

/// The chunk files of every array of the Zarr store in `root` (not its
/// metadata, which holds the summary's times).
fn files(root: &Path) -> Vec<PathBuf> {
    let mut v = vec![];
    let mut stack = vec![root.join("run.zarr")];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.file_name().unwrap() != "zarr.json" {
                v.push(p.strip_prefix(root).unwrap().to_path_buf());
            }
        }
    }
    v.sort();
    v
}

/// Starts `scene` as one chunk with a checkpoint every 0.2 s and kills it
/// (SIGKILL) once its checkpoint exists; returns the checkpoint's path.
fn killed_with_a_checkpoint(scene: &Path, out: &Path) -> PathBuf {
    let args = [
        "run",
        s(scene),
        "--out",
        s(out),
        "--checkpoint-every",
        "0.2",
    ];
    let mut child = Command::new(REEB).args(args).spawn().unwrap();
    let state = partial(out).join(".reeb-chunks/0.state");
    let start = Instant::now();
    while !state.exists() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "ended before a checkpoint"
        );
        assert!(start.elapsed() < Duration::from_secs(120), "no checkpoint");
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(Duration::from_millis(50));
    child.kill().unwrap();
    child.wait().unwrap();
    state
}

#[test]
fn a_cut_checkpoint_is_discarded_and_its_chunk_integrated_again() {
    let d = tmp("checkpoint");
    let scene = grid_scene(&d, 40_000.0, 100_000, "cpu");
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    let out = d.join("run");
    let state = killed_with_a_checkpoint(&scene, &out);
    let len = std::fs::metadata(&state).unwrap().len();
    let f = std::fs::OpenOptions::new()
        .write(true)
        .open(&state)
        .unwrap();
    f.set_len(len * 2 / 3).unwrap();
    let said = ok(&["run", s(&scene), "--out", s(&out), "--resume"]);
    assert!(
        said.contains("chunk 0's checkpoint") && said.contains("cannot be continued"),
        "{said}"
    );
    same_arrays(&one, &out);
}

/// A finished run of `scene` in `out`.
fn finished(d: &Path, out: &Path) -> PathBuf {
    let scene = grid_scene(d, 2.0, 100, "cpu");
    ok(&["run", s(&scene), "--out", s(out)]);
    scene
}

#[test]
fn a_listed_file_now_a_folder_or_a_link_is_not_deleted() {
    let d = tmp("replace");
    let out = d.join("run");
    let scene = finished(&d, &out);
    // A folder of the user's where reeb wrote a picture.
    let pic = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|x| x == "png"))
        .expect("a picture");
    std::fs::remove_file(&pic).unwrap();
    std::fs::create_dir(&pic).unwrap();
    std::fs::write(pic.join("notes.txt"), "mine").unwrap();
    let err = refused(&["run", s(&scene), "--out", s(&out)]);
    assert!(err.contains("is now a folder"), "{err}");
    assert!(pic.join("notes.txt").exists());
    // A symbolic link to a file of the user's where reeb wrote an array.
    std::fs::remove_dir_all(&pic).unwrap();
    std::fs::write(&pic, "").unwrap();
    let mine = d.join("mine.npy");
    std::fs::write(&mine, "mine").unwrap();
    let q = out.join("final_q.npy");
    std::fs::remove_file(&q).unwrap();
    std::os::unix::fs::symlink(&mine, &q).unwrap();
    let err = refused(&["run", s(&scene), "--out", s(&out)]);
    assert!(err.contains("is now a symbolic link"), "{err}");
    assert_eq!(std::fs::read_to_string(&mine).unwrap(), "mine");
    // Asked for: replaced, and the link's target is still not touched.
    ok(&["run", s(&scene), "--out", s(&out), "--force"]);
    assert!(out.join("final_q.npy").is_file() && !out.join("final_q.npy").is_symlink());
    assert_eq!(std::fs::read_to_string(&mine).unwrap(), "mine");
}

#[test]
fn merge_on_a_folder_that_is_no_run_leaves_nothing_behind() {
    let d = tmp("merge-nothing");
    let x = d.join("x");
    std::fs::create_dir(&x).unwrap();
    std::fs::write(x.join("mine.txt"), "mine").unwrap();
    let err = refused(&["merge", s(&x)]);
    assert!(err.contains("there is no sharded run to merge"), "{err}");
    assert!(
        !err.contains("--out X") && !err.contains("another --out"),
        "{err}"
    );
    assert!(!partial(&x).exists(), "left {}", partial(&x).display());
    let err = refused(&["merge", s(&d.join("never"))]);
    assert!(err.contains("there is no sharded run to merge"), "{err}");
    assert!(!partial(&d.join("never")).exists());
}

#[test]
fn an_out_ending_in_a_dot_is_the_folder_it_names() {
    let d = tmp("dot");
    let scene = grid_scene(&d, 2.0, 100, "cpu");
    let dotted = format!("{}/x/.", s(&d));
    ok(&["run", s(&scene), "--out", &dotted]);
    assert!(d.join("x/summary.json").is_file());
    ok(&["run", s(&scene), "--out", &format!("{}/y/", s(&d))]);
    assert!(d.join("y/summary.json").is_file());
}

#[test]
fn a_damaged_run_record_is_named_not_a_serde_message() {
    let d = tmp("record");
    let scene = grid_scene(&d, 20.0, 100, "cpu");
    let out = d.join("run");
    let args = ["run", s(&scene), "--out", s(&out), "--shard", "0/2"];
    ok(&[&args[..], &["--chunk-trajectories", "7"]].concat());
    std::fs::write(partial(&out).join(".reeb-run.json"), "{}").unwrap();
    let err = refused(&["run", s(&scene), "--out", s(&out), "--resume"]);
    assert!(
        err.contains(".reeb-run.json is not the record of a reeb run")
            && err.contains("without --resume"),
        "{err}"
    );
    // As asked: started over.
    ok(&["run", s(&scene), "--out", s(&out)]);
}

#[test]
fn shards_at_different_cpu_levels_are_named_in_the_summary() {
    let d = tmp("levels");
    let scene = grid_scene(&d, 20.0, 100, "cpu");
    let out = d.join("run");
    for (k, level) in [("0/2", "baseline"), ("1/2", "")] {
        let o = Command::new(REEB)
            .args(["run", s(&scene), "--out", s(&out), "--shard", k])
            .args(["--chunk-trajectories", "7"])
            .env("REEB_CPU_ISA", level)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let said = ok(&["merge", s(&out)]);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let isa = summary["cpu_isa"].as_str().unwrap().to_string();
    let native = std::env::var("REEB_CPU_ISA").unwrap_or_default();
    if native == "baseline"
        || reeb::backend::cpu::kernels::isa()
            .name()
            .starts_with("baseline")
    {
        assert!(!isa.contains('+'), "{isa}");
        return;
    }
    assert!(
        isa.contains("baseline") && isa.contains(" chunks) + "),
        "{isa}"
    );
    assert!(
        said.contains("different CPU instruction-set levels"),
        "{said}"
    );
    let warned = summary["warnings"].as_array().unwrap();
    assert!(
        warned
            .iter()
            .any(|w| w.as_str().unwrap().contains("round-off")),
        "{warned:?}"
    );
}
