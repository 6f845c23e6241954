//! `reeb slurm` on a real Slurm (issue 12, point 6): a 4-shard job array of
//! a real scene, merged by its dependent job, bitwise identical to one run;
//! and a task killed mid-way and requeued (`scontrol requeue`), which
//! resumes its finished chunks.
//!
//! Needs a Slurm this process can submit to (`sinfo` answers; `.ci/slurm-up`
//! starts a one-node cluster); without one the tests print SKIP, unless
//! `REEB_REQUIRE_SLURM=1` (CI).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use crate::common;

use common::runs::{grid_scene, ok, s, same_arrays};

fn slurm() -> bool {
    let up = Command::new("sinfo")
        .arg("-h")
        .output()
        .is_ok_and(|o| o.status.success() && !o.stdout.is_empty());
    if !up {
        assert!(
            std::env::var_os("REEB_REQUIRE_SLURM").is_none(),
            "REEB_REQUIRE_SLURM is set but sinfo does not answer (is SLURM_CONF set? .ci/slurm-up starts a cluster)"
        );
        eprintln!("SKIP: no Slurm (sinfo does not answer)");
    }
    up
}

fn tmp(name: &str) -> PathBuf {
    common::runs::tmp("slurm", name)
}

/// Waits for `out/summary.json` (the merge job's last file).
fn wait_for_merge(out: &Path, logs: &Path) {
    let start = Instant::now();
    while !out.join("summary.json").exists() {
        if start.elapsed() > Duration::from_secs(600) {
            let log = std::fs::read_to_string(logs.join("merge.out")).unwrap_or_default();
            let q = Command::new("squeue")
                .output()
                .map(|o| o.stdout)
                .unwrap_or_default();
            panic!(
                "no merge after 600 s; merge log: {log}; squeue: {}",
                String::from_utf8_lossy(&q)
            );
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// The job array's id from `reeb slurm`'s line.
fn array_id(line: &str) -> String {
    let after = line.split("job array ").nth(1).expect(line);
    after.split_whitespace().next().unwrap().to_string()
}

#[test]
fn four_shards_through_slurm_merge_to_the_bits_of_one_run() {
    if !slurm() {
        return;
    }
    let d = tmp("four");
    let scene = grid_scene(&d, 40.0, 500, "cpu");
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    let out = d.join("sharded");
    let args = [
        "slurm",
        s(&scene),
        "--shards",
        "4",
        "--out",
        s(&out),
        "--chunk-trajectories",
        "5",
    ];
    let line = ok(&args);
    assert!(line.contains("merge job"), "{line}");
    wait_for_merge(&out, &d.join("sharded.slurm/logs"));
    same_arrays(&one, &out);
    let log = std::fs::read_to_string(d.join("sharded.slurm/logs/shard-3.out")).unwrap();
    assert!(log.contains("shard 3/4"), "{log}");
}

#[test]
fn a_task_killed_and_requeued_resumes_its_chunks() {
    if !slurm() {
        return;
    }
    let d = tmp("requeue");
    // Long enough that shard 0 is still running when the test requeues it
    // after its first chunk (7 chunks of 6 trajectories a shard).
    let scene = grid_scene(&d, 3_000.0, 500, "cpu");
    let out = d.join("run");
    let line = ok(&[
        "slurm",
        s(&scene),
        "--shards",
        "2",
        "--out",
        s(&out),
        "--chunk-trajectories",
        "6",
    ]);
    let task = format!("{}_0", array_id(&line));
    // Shard 0 holds chunks 0..7: wait for its first, then kill and requeue it.
    let marker = d.join("run.partial/.reeb-chunks/0.json");
    let start = Instant::now();
    while !marker.exists() {
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "no chunk finished"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let rq = Command::new("scontrol")
        .args(["requeue", &task])
        .output()
        .unwrap();
    assert!(
        rq.status.success(),
        "scontrol requeue {task}: {}",
        String::from_utf8_lossy(&rq.stderr)
    );
    wait_for_merge(&out, &d.join("run.slurm/logs"));
    let log = std::fs::read_to_string(d.join("run.slurm/logs/shard-0.out")).unwrap();
    assert!(
        log.contains("attempt 1") && log.contains("resuming:"),
        "{log}"
    );
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    same_arrays(&one, &out);
}

#[test]
fn a_folder_with_spaces_quotes_and_percent_signs_runs_through_slurm() {
    if !slurm() {
        return;
    }
    let d = tmp("hostile");
    let scene = grid_scene(&d, 40.0, 500, "cpu");
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    // Slurm's #SBATCH parser reads quotes, `#` and `%` patterns; bash reads
    // `$( )` and quotes: every one of them stays a plain character.
    let out = d.join("my run's \"100%\" #1 $(touch pwned) %j");
    let line = ok(&["slurm", s(&scene), "--shards", "2", "--out", s(&out)]);
    assert!(line.contains("merge job"), "{line}");
    let mut slurm = out.clone().into_os_string();
    slurm.push(".slurm");
    let logs = PathBuf::from(slurm).join("logs");
    wait_for_merge(&out, &logs);
    same_arrays(&one, &out);
    for f in ["shard-0.out", "shard-1.out", "merge.out"] {
        assert!(logs.join(f).is_file(), "no {f} in {}", logs.display());
    }
    assert!(!d.join("pwned").exists() && !Path::new("pwned").exists());
}
