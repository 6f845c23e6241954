//! `reeb doctor` end to end on whatever adapter the machine has (lavapipe in
//! CI): the report's parts, its checks passing, and the file rules of `--out`.

use std::path::Path;
use std::process::Command;

use crate::common;

fn reeb(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_reeb"))
        .args(args)
        .current_dir(dir)
        .env("XDG_CACHE_HOME", dir.join("tuning-cache"))
        .output()
        .expect("reeb runs")
}

#[test]
fn doctor_checks_and_measures_both_backends() {
    if common::gpu().is_none() {
        return;
    }
    let dir = common::runs::tmp("doctor", "report");
    let out = reeb(&dir, &["doctor", "--n", "2000"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("reeb-doctor.json")).unwrap())
            .unwrap();
    let adapters = report["adapters"].as_array().unwrap();
    assert!(!adapters.is_empty() && adapters[0]["features"].is_array());
    // verify in f32, and in f64 where the adapter has it, all passing.
    let verify = report["verify"].as_array().unwrap();
    assert!(!verify.is_empty());
    for v in verify {
        assert_eq!(v["failed"], 0, "{v}");
        assert!(v["passed"].as_u64().unwrap() > 50, "{v}");
    }
    // Every model × scheme the model has, within tolerance.
    let agreement = report["agreement"].as_array().unwrap();
    assert!(agreement.len() >= 2 * 7 * 3, "{}", agreement.len());
    for a in agreement {
        assert_eq!(a["pass"], true, "{a}");
    }
    // Both forms of the f32 exp measured; the one in use within its bound.
    let exp = report["exp"].as_array().unwrap();
    assert_eq!(exp.len(), 2, "{exp:?}");
    let in_use: Vec<_> = exp.iter().filter(|e| e["in_use"] == true).collect();
    assert_eq!(in_use.len(), 1, "{exp:?}");
    assert_eq!(in_use[0]["pass"], true, "{exp:?}");
    assert!(exp
        .iter()
        .all(|e| e["points"] == 1 << 20 && e["max_ulp"].as_f64().unwrap() > 0.0));
    assert!(text.contains("f32 exp, exact (in use): within"), "{text}");
    // Four scenarios × two precisions × one size on each backend.
    let bench = report["bench"].as_array().unwrap();
    for backend in ["cpu", "gpu"] {
        let rows: Vec<_> = bench.iter().filter(|b| b["backend"] == backend).collect();
        assert!(rows.len() >= 4, "{backend}: {rows:?}");
        for r in rows {
            assert!(r["traj_steps_per_s"].as_f64().unwrap() > 0.0, "{r}");
            assert_eq!(r["n"], 2000);
        }
    }
    // The launch of each scenario's model, probed on this adapter.
    let tuning = report["tuning"].as_array().unwrap();
    assert!(tuning.len() >= 4, "{tuning:?}");
    assert!(tuning.iter().all(|t| t["gpu_rate"].as_f64().unwrap() > 0.0));
    assert!(
        text.contains("agreement f32") && text.contains("traj-steps/s"),
        "{text}"
    );
    // A second run replaces its own report…
    let again = reeb(&dir, &["doctor", "--n", "1000", "--skip-verify"]);
    assert!(again.status.success());
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("reeb-doctor.json")).unwrap())
            .unwrap();
    assert!(report["verify"].as_array().unwrap().is_empty());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn doctor_refuses_bad_input_before_measuring() {
    let dir = common::runs::tmp("doctor", "refusals");
    std::fs::write(dir.join("notes.json"), "{\"mine\": 1}").unwrap();
    for (args, says) in [
        (
            vec!["doctor", "--out", "notes.json"],
            "is not a `reeb doctor` report",
        ),
        (
            vec!["doctor", "--out", "no/such/folder.json"],
            "does not exist",
        ),
        (
            vec!["doctor", "--n", "0"],
            "--n: ensemble sizes must be at least 1",
        ),
    ] {
        let out = reeb(&dir, &args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(says),
            "{args:?}: {err}"
        );
    }
    // …and touched nothing.
    assert_eq!(
        std::fs::read_to_string(dir.join("notes.json")).unwrap(),
        "{\"mine\": 1}"
    );
    assert!(!dir.join("reeb-doctor.json").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
