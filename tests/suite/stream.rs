//! Streamed runs (issue 12): a run in chunks, a run killed and resumed, and
//! a run in shards merged all give arrays bitwise identical to one run in
//! one chunk; a changed scene is refused on resume; `reeb merge` refuses a
//! run whose shards have not all finished.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use crate::common;

use common::runs::{grid_scene, ok, reeb, s, same_arrays, summary, REEB};

fn tmp(name: &str) -> PathBuf {
    common::runs::tmp("stream", name)
}

#[test]
fn chunks_of_any_size_give_the_same_bits_as_one() {
    let d = tmp("chunks");
    let scene = grid_scene(&d, 4.0, 50, "cpu");
    let one = d.join("one");
    chunked(&scene, &one, "1000000");
    for rows in ["1", "5", "7", "30"] {
        let out = d.join(format!("c{rows}"));
        chunked(&scene, &out, rows);
        same_arrays(&one, &out);
    }
    let summary = std::fs::read_to_string(d.join("c5/summary.json")).unwrap();
    assert!(summary.contains("\"count\": 24"), "{summary}");
}

#[test]
fn chunks_on_the_gpu_give_the_same_bits_as_one() {
    if common::gpu().is_none() {
        return;
    }
    let d = tmp("gpu-chunks");
    let scene = grid_scene(&d, 4.0, 50, "gpu");
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    let out = d.join("c7");
    chunked(&scene, &out, "7");
    same_arrays(&one, &out);
    // One GPU writes a chunk while it integrates the next: the two spans
    // overlap on the host's clock; a run of one chunk has nothing to overlap.
    assert!(overlap(&out) > 0.0, "{}", out.display());
    assert_eq!(overlap(&one), 0.0);
}

#[test]
fn one_gpu_reads_a_chunk_back_and_writes_it_while_it_integrates_the_next() {
    if common::gpu().is_none() {
        return;
    }
    let d = tmp("gpu-pipeline");
    let scene = d.join("pipeline.toml");
    std::fs::write(
        &scene,
        r#"model = "van_der_pol"
[params]
epsilon = { linspace = [0.1, 5.0, 262144] }
[initial]
q = 2.0
s = 0.0
[integrator]
scheme = "s2"
dt = 0.01
steps = 150
[output]
final = ["q", "s"]
cycle = { var = "q", level = 0.0, skip = 0.5 }
average = ["q", "s"]
[run]
backend = "gpu"
precision = "f32"
"#,
    )
    .unwrap();
    let (one, out) = (d.join("one"), d.join("chunked"));
    ok(&["run", s(&scene), "--out", s(&one)]);
    chunked(&scene, &out, "16384");
    same_arrays(&one, &out);
    let t = timing(&out);
    let of = |k: &str| t[k].as_f64().unwrap();
    // lavapipe has timestamp queries: the integration is the kernels'
    // time on the device's own clock, the other phases the host's.
    assert_eq!(summary(&out)["integration_clock"], "GPU timestamps");
    // Timed apart, the phases add up to more than the wall clock they ran
    // in: the read-back and writing of one chunk ran while the kernels of
    // the next did (in sequence they add up to less, as on the CPU).
    let phases = ["setup", "compile", "integration", "read_back", "writing"];
    let sum: f64 = phases.iter().map(|k| of(k)).sum::<f64>() + of("pictures");
    assert!(sum > of("wall"), "{sum} <= wall: {t:?}");
    assert!(of("overlap") > 0.0, "{t:?}");
}

/// `reeb run SCENE --out OUT --chunk-trajectories ROWS`, which must succeed.
fn chunked(scene: &Path, out: &Path, rows: &str) -> String {
    ok(&[
        "run",
        s(scene),
        "--out",
        s(out),
        "--chunk-trajectories",
        rows,
    ])
}

/// `summary.json`'s `timing` of the run in `out`.
fn timing(out: &Path) -> serde_json::Map<String, serde_json::Value> {
    summary(out)["timing"].as_object().unwrap().clone()
}

fn overlap(out: &Path) -> f64 {
    timing(out)["overlap"].as_f64().unwrap()
}

#[test]
fn the_summary_times_each_phase_and_the_run_line_says_wall_and_integration() {
    let d = tmp("timing");
    let scene = grid_scene(&d, 4.0, 50, "cpu");
    let out = d.join("run");
    let said = chunked(&scene, &out, "30");
    assert!(
        said.contains(" s wall, ") && said.contains(" s integrating ("),
        "{said}"
    );
    let t = timing(&out);
    let phases = [
        "setup",
        "compile",
        "integration",
        "read_back",
        "writing",
        "pictures",
    ];
    let of = |k: &str| t[k].as_f64().unwrap_or_else(|| panic!("timing.{k}: {t:?}"));
    for k in phases.iter().chain(&["overlap", "wall"]) {
        assert!(of(k) >= 0.0, "timing.{k}: {t:?}");
    }
    assert!(of("integration") > 0.0 && of("writing") > 0.0, "{t:?}");
    // On the CPU the phases follow one another within the wall clock.
    let sum: f64 = phases.iter().map(|k| of(k)).sum();
    assert!(sum <= of("wall"), "{sum} > wall: {t:?}");
    assert_eq!(
        (of("compile"), of("read_back"), of("overlap")),
        (0.0, 0.0, 0.0)
    );
    // The papers of S2 (contact splitting) and of van der Pol (Liénard).
    let summary = summary(&out);
    let cited: Vec<&str> = summary["references"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_str().unwrap())
        .collect();
    assert_eq!(cited.len(), 2, "{cited:?}");
    assert!(
        cited[0].contains("a case for contact geometry"),
        "{cited:?}"
    );
    assert!(cited[1].contains("Liénard systems"), "{cited:?}");
}

/// Waits until `partial` has a finished chunk (and the run has not ended).
fn wait_for_a_chunk(partial: &Path, child: &mut std::process::Child) {
    let start = Instant::now();
    while std::fs::read_dir(partial.join(".reeb-chunks")).map_or(0, |d| d.count()) == 0 {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before it was killed"
        );
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no chunk finished"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn a_run_killed_with_sigkill_resumes_to_the_same_bits() {
    let d = tmp("resume");
    // 14 chunks of 6 trajectories; the kill comes after the first.
    let scene = grid_scene(&d, 1000.0, 5000, "cpu");
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    let out = d.join("killed");
    let args = [
        "run",
        s(&scene),
        "--out",
        s(&out),
        "--chunk-trajectories",
        "6",
    ];
    let mut child = Command::new(REEB).args(args).spawn().unwrap();
    let partial = d.join("killed.partial");
    wait_for_a_chunk(&partial, &mut child);
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    assert!(!out.exists(), "a killed run looks complete");
    let done = std::fs::read_dir(partial.join(".reeb-chunks"))
        .unwrap()
        .count();
    assert!(
        (1..14).contains(&done),
        "{done} chunks finished before the kill"
    );
    // A changed scene is refused, and the finished chunks are kept.
    let changed = d.join("changed.toml");
    let text = std::fs::read_to_string(&scene).unwrap();
    std::fs::write(&changed, text.replace("max_points = 20", "max_points = 21")).unwrap();
    let o = reeb(&["run", s(&changed), "--out", s(&out), "--resume"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("different run") && err.contains("max_points = 21"),
        "{err}"
    );
    assert!(
        partial.join(".reeb-chunks").exists(),
        "the refusal removed the finished chunks"
    );
    ok(&["run", s(&scene), "--out", s(&out), "--resume"]);
    same_arrays(&one, &out);
}

/// Runs `scene` as one chunk with a checkpoint every 0.2 s, kills it
/// (SIGKILL) after its second checkpoint, before the chunk finished, and
/// resumes it: the arrays are those of the uninterrupted run `one`.
fn killed_inside_a_chunk(d: &Path, scene: &Path, one: &Path) {
    let out = d.join("killed");
    let partial = d.join("killed.partial");
    let args = [
        "run",
        s(scene),
        "--out",
        s(&out),
        "--checkpoint-every",
        "0.2",
    ];
    let mut child = Command::new(REEB).args(args).spawn().unwrap();
    let state = partial.join(".reeb-chunks/0.state");
    let start = Instant::now();
    let mut seen = None;
    // The second checkpoint: a new file replaces the first.
    while seen.is_none_or(|first| {
        std::fs::metadata(&state).and_then(|m| m.modified()).ok() == Some(first)
    }) {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before it was killed"
        );
        assert!(start.elapsed() < Duration::from_secs(120), "no checkpoint");
        if seen.is_none() {
            seen = std::fs::metadata(&state).and_then(|m| m.modified()).ok();
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    assert!(
        !partial.join(".reeb-chunks/0.json").exists(),
        "the chunk finished before the kill"
    );
    let said = ok(&["run", s(scene), "--out", s(&out), "--resume"]);
    let share: f64 = said
        .split("chunk 0: continuing from its checkpoint (")
        .nth(1)
        .and_then(|rest| rest.split(" %").next())
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("the resumed run did not continue the checkpoint: {said}"));
    assert!(share > 0.0 && share < 100.0, "{said}");
    same_arrays(one, &out);
    assert!(!out.join(".reeb-chunks").exists());
}

#[test]
fn a_run_killed_inside_a_chunk_continues_from_its_checkpoint() {
    let d = tmp("checkpoint");
    // Two sub-runs (a dt axis) in one chunk, 4·10⁶ steps for the longest
    // (long enough to be killed after its second checkpoint).
    let scene = grid_scene(&d, 40_000.0, 100_000, "cpu");
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    killed_inside_a_chunk(&d, &scene, &one);
}

#[test]
fn a_gpu_run_killed_inside_a_chunk_continues_from_its_checkpoint() {
    if common::gpu().is_none() {
        return;
    }
    let d = tmp("checkpoint-gpu");
    let scene = grid_scene(&d, 4_000.0, 10_000, "gpu");
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    killed_inside_a_chunk(&d, &scene, &one);
}

#[test]
fn checkpoint_every_is_validated_naming_the_flag() {
    for bad in ["-1", "soon", "inf"] {
        let o = reeb(&[
            "run",
            "scenes/duffing.toml",
            &format!("--checkpoint-every={bad}"),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success());
        assert!(
            err.contains("--checkpoint-every") && err.contains("seconds"),
            "{err}"
        );
    }
}

#[test]
fn shards_run_together_and_merged_give_the_same_bits_as_one_run() {
    let d = tmp("shards");
    let scene = grid_scene(&d, 20.0, 50, "cpu");
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    let out = d.join("sharded");
    // Merging before every shard has finished is refused.
    ok(&[
        "run",
        s(&scene),
        "--out",
        s(&out),
        "--shard",
        "1/4",
        "--chunk-trajectories",
        "5",
    ]);
    let o = reeb(&["merge", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("have not finished"),
        "{err}"
    );
    // All four at once, into one folder.
    let children: Vec<_> = (0..4)
        .map(|k| {
            let shard = format!("{k}/4");
            Command::new(REEB)
                .args(["run", s(&scene), "--out", s(&out), "--shard", &shard])
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for c in children {
        let c = c.wait_with_output().unwrap();
        assert!(c.status.success(), "{}", String::from_utf8_lossy(&c.stderr));
    }
    let line = ok(&["merge", s(&out)]);
    assert!(line.contains("84 trajectories"), "{line}");
    same_arrays(&one, &out);
    assert!(out.join("summary.json").exists() && !d.join("sharded.partial").exists());
}

#[test]
fn bad_shards_are_refused_naming_the_flag() {
    let d = tmp("bad-shard");
    let scene = grid_scene(&d, 1.0, 50, "cpu");
    for bad in ["4/4", "1/0", "a/b", "3"] {
        let o = reeb(&["run", s(&scene), "--out", s(&d.join("o")), "--shard", bad]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains("--shard"),
            "{bad}: {err}"
        );
    }
    let o = reeb(&["merge", s(&d.join("nothing"))]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("no sharded run"),
        "{err}"
    );
}
