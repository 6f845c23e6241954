//! The GPU launch tuned per adapter and cached (issue 35, points 2–4), end
//! to end through the command line on whatever adapter the machine has
//! (lavapipe in CI): `reeb tune`, the cache file and `reeb info`, the
//! environment's overrides, `--adapters`, and `--backend auto` weighing
//! the GPU against the CPU.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common;

use common::runs::{grid_scene, s, same_arrays};

/// `reeb args` with the tuning cache in `cache` and `env` set.
fn reeb_in(cache: &Path, env: &[(&str, &str)], args: &[&str]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_reeb"));
    c.args(args).env("XDG_CACHE_HOME", cache);
    for v in reeb::backend::gpu::tuning::ENV {
        c.env_remove(v);
    }
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("reeb runs")
}

fn text(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr)
}

fn succeeds(o: Output) -> String {
    assert!(o.status.success(), "{}", text(&o));
    text(&o)
}

fn fails(o: Output) -> String {
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    text(&o)
}

/// The JSON file at `p`.
fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn cache_file(cache: &Path) -> PathBuf {
    cache.join("reeb").join("gpu-tuning.json")
}

fn setup(name: &str) -> Option<PathBuf> {
    common::gpu()?;
    let d = common::runs::tmp("tuning", name);
    Some(d)
}

#[test]
fn tune_caches_each_shape_and_info_shows_it() {
    let Some(d) = setup("tune") else { return };
    let cache = d.join("cache");
    let out = succeeds(reeb_in(
        &cache,
        &[("REEB_GPU_PROBE_LOG", "1")],
        &["tune", "--precision", "f32"],
    ));
    assert!(
        out.contains("f32 van_der_pol") && out.contains("workgroup"),
        "{out}"
    );
    // The log names each candidate; blocks of 8 steps are measured whatever
    // the budget (van der Pol's kernel has them: on a software adapter
    // beside 4 and 1, on a hardware GPU as the first candidate).
    assert!(
        out.lines()
            .any(|l| l.starts_with("probe f32: ") && l.contains("finite test every 8 steps: ")),
        "{out}"
    );
    let json: serde_json::Value = json(&cache_file(&cache));
    assert_eq!(json["reeb_version"], env!("CARGO_PKG_VERSION"));
    let (_, shapes) = json["tuned"].as_object().unwrap().iter().next().unwrap();
    let shapes = shapes.as_object().unwrap();
    assert!(shapes.len() >= 4, "{shapes:?}");
    for (shape, t) in shapes {
        assert!(shape.starts_with("f32 "), "{shape}");
        assert!(t["gpu_rate"].as_f64().unwrap() > 0.0 && t["cpu_rate"].as_f64().unwrap() > 0.0);
        let probe = t["probe_seconds"].as_f64().unwrap();
        let compile = t["compile_seconds"].as_f64().unwrap();
        assert!(probe < 5.0 && (0.0..=probe).contains(&compile), "{t}");
    }
    let info = succeeds(reeb_in(&cache, &[], &["info"]));
    assert!(
        (info.contains("adapter 0, f32 van_der_pol 2^20")
            || info.contains("adapter 0, f32 van_der_pol 2^12"))
            && info.contains("s compiling"),
        "{info}"
    );
    let info = succeeds(reeb_in(&cache, &[("REEB_GPU_WORKGROUP", "128")], &["info"]));
    assert!(info.contains("overridden by the environment"), "{info}");
    // An adapter that does not exist.
    let e = fails(reeb_in(&cache, &[], &["tune", "--adapter", "97"]));
    assert!(e.contains("--adapter 97"), "{e}");
}

#[test]
fn a_corrupt_or_foreign_cache_is_measured_again() {
    let Some(d) = setup("corrupt") else { return };
    let cache = d.join("cache");
    let scene = grid_scene(&d, 0.5, 10, "gpu");
    std::fs::create_dir_all(cache.join("reeb")).unwrap();
    // Corrupt; another version; this version from an earlier probe (no
    // `probe`: before blocks of 8 steps were tried).
    let earlier = format!(
        r#"{{"reeb_version": "{}", "tuned": {{}}}}"#,
        env!("CARGO_PKG_VERSION")
    );
    for bad in [
        "{not json",
        r#"{"reeb_version": "0.0.1", "tuned": {}}"#,
        &earlier,
    ] {
        std::fs::write(cache_file(&cache), bad).unwrap();
        succeeds(reeb_in(
            &cache,
            &[],
            &["run", s(&scene), "--out", s(&d.join("run")), "--force"],
        ));
        let json: serde_json::Value = json(&cache_file(&cache));
        assert_eq!(json["reeb_version"], env!("CARGO_PKG_VERSION"), "{bad}");
        assert_eq!(json["probe"], reeb::backend::gpu::tuning::PROBE, "{bad}");
    }
}

#[test]
fn the_environment_overrides_the_launch_and_bad_values_are_refused() {
    let Some(d) = setup("env") else { return };
    let cache = d.join("cache");
    let scene = grid_scene(&d, 0.5, 10, "gpu");
    let one = d.join("default");
    succeeds(reeb_in(&cache, &[], &["run", s(&scene), "--out", s(&one)]));
    let fixed = d.join("fixed");
    let env = [
        ("REEB_GPU_WORKGROUP", "32"),
        ("REEB_GPU_PER_THREAD", "3"),
        ("REEB_GPU_DISPATCH_SECONDS", "0.01"),
        ("REEB_GPU_WINDOW", "7"),
        ("REEB_GPU_FINITE_BLOCK", "3"),
    ];
    succeeds(reeb_in(
        &cache,
        &env,
        &["run", s(&scene), "--out", s(&fixed)],
    ));
    same_arrays(&one, &fixed);
    // The exp: lavapipe's default is reeb's polynomial; its exp2 form is
    // another function, and the summary says so.
    let exact = d.join("exact");
    let exp = |form| [("REEB_GPU_EXP", form)];
    succeeds(reeb_in(
        &cache,
        &exp("exact"),
        &["run", s(&scene), "--out", s(&exact)],
    ));
    same_arrays(&one, &exact);
    let hardware = d.join("hardware");
    succeeds(reeb_in(
        &cache,
        &exp("hardware"),
        &["run", s(&scene), "--out", s(&hardware)],
    ));
    let adapter = json(&hardware.join("summary.json"))["adapter"].to_string();
    assert!(
        adapter.contains("f32 exp from the adapter's exp2"),
        "{adapter}"
    );
    // A bad exp setting is an error under `auto` too, not a missing GPU.
    let e = fails(reeb_in(
        &cache,
        &exp("fast"),
        &[
            "run",
            s(&scene),
            "--out",
            s(&d.join("auto")),
            "--backend",
            "auto",
        ],
    ));
    assert!(e.contains("REEB_GPU_EXP=\"fast\""), "{e}");
    assert!(!json(&one.join("summary.json"))["adapter"]
        .to_string()
        .contains("exp2"));
    for (var, value, says) in [
        ("REEB_GPU_WORKGROUP", "100000", "this adapter allows"),
        ("REEB_GPU_WORKGROUP", "0", "a workgroup of 0 invocations"),
        ("REEB_GPU_PER_THREAD", "0", "per invocation"),
        ("REEB_GPU_WINDOW", "abc", "REEB_GPU_WINDOW"),
        ("REEB_GPU_DISPATCH_SECONDS", "-1", "per dispatch"),
        ("REEB_GPU_FINITE_BLOCK", "9", "finite test every 9 steps"),
        (
            "REEB_GPU_EXP",
            "fast",
            "REEB_GPU_EXP=\"fast\": expected `exact`",
        ),
        ("WGPU_BACKEND", "nonsense", "names no wgpu backend"),
    ] {
        let out = d.join(format!("bad-{var}"));
        let e = fails(reeb_in(
            &cache,
            &[(var, value)],
            &["run", s(&scene), "--out", s(&out)],
        ));
        assert!(e.contains(says), "{var}={value}: {e}");
        // The variable at fault, and no other.
        assert!(e.contains(var), "{var}={value}: {e}");
        let others = reeb::backend::gpu::tuning::ENV
            .iter()
            .filter(|o| **o != var);
        for other in others {
            assert!(!e.contains(other), "{var}={value} names {other}: {e}");
        }
        assert!(!out.exists() && !Path::new(&format!("{}.partial", s(&out))).exists());
    }
}

#[test]
fn adapters_share_the_chunks_with_the_bits_of_one() {
    let Some(d) = setup("adapters") else { return };
    let cache = d.join("cache");
    let scene = grid_scene(&d, 0.5, 10, "gpu");
    let one = d.join("one");
    succeeds(reeb_in(
        &cache,
        &[],
        &["run", s(&scene), "--out", s(&one), "--adapter", "0"],
    ));
    let two = d.join("two");
    let line = succeeds(reeb_in(
        &cache,
        &[],
        &[
            "run",
            s(&scene),
            "--out",
            s(&two),
            "--adapters",
            "0,0",
            "--chunk-trajectories",
            "5",
        ],
    ));
    same_arrays(&one, &two);
    assert!(
        line.contains("chunks by device: #0 adapter 0") && line.contains("#1 adapter 0"),
        "{line}"
    );
    let summary: serde_json::Value = json(&two.join("summary.json"));
    let devices = summary["devices"].as_array().unwrap();
    assert_eq!(devices.len(), 2, "{devices:?}");
    let chunks: u64 = devices.iter().map(|d| d["chunks"].as_u64().unwrap()).sum();
    assert_eq!(chunks, summary["chunks"]["count"].as_u64().unwrap());
    // `all` is every hardware GPU, or the adapter `--backend gpu` takes.
    succeeds(reeb_in(
        &cache,
        &[],
        &[
            "run",
            s(&scene),
            "--out",
            s(&d.join("all")),
            "--adapters",
            "all",
        ],
    ));
    same_arrays(&one, &d.join("all"));
    for (args, says) in [
        (vec!["--adapters", "0,97"], "--adapter 97"),
        (vec!["--adapters", "zero"], "not an adapter index"),
        (
            vec!["--adapters", "0", "--adapter", "0"],
            "cannot be used with",
        ),
        (
            vec!["--adapters", "0", "--backend", "cpu"],
            "backend is cpu",
        ),
    ] {
        let out = d.join("refused");
        let mut a = vec!["run", s(&scene), "--out", s(&out)];
        a.extend(args.iter().copied());
        let e = fails_or_usage(reeb_in(&cache, &[], &a));
        assert!(e.contains(says), "{args:?}: {e}");
        assert!(!out.exists());
    }
}

/// A refusal: exit status 1, or clap's usage error (2).
fn fails_or_usage(o: Output) -> String {
    assert!(matches!(o.status.code(), Some(1 | 2)), "{}", text(&o));
    text(&o)
}

#[test]
fn auto_takes_the_faster_backend_and_says_why() {
    let Some(d) = setup("auto") else { return };
    let cache = d.join("cache");
    let scene = grid_scene(&d, 0.5, 10, "auto");
    // A pinned adapter is weighed against the CPU, even a software one.
    let out = d.join("run");
    let line = succeeds(reeb_in(
        &cache,
        &[],
        &["run", s(&scene), "--out", s(&out), "--adapter", "0"],
    ));
    assert!(line.contains("--backend auto: running on the"), "{line}");
    assert!(
        line.contains("42 trajectories × 50 steps in f64 would take about")
            && line.contains("aside (tuning probe of 42 trajectories"),
        "{line}"
    );
    let summary: serde_json::Value = json(&out.join("summary.json"));
    let why = summary["backend_choice"].as_str().unwrap();
    let backend = summary["backend"].as_str().unwrap();
    assert!(
        why.contains(&format!("running on the {}", backend.to_uppercase())),
        "{backend}: {why}"
    );
    // The numbers that decided it are the cache's, and decide the same way:
    // on the whole run of the first plan (42 × 50), host work included.
    let json: serde_json::Value = json(&cache_file(&cache));
    let (_, shapes) = json["tuned"].as_object().unwrap().iter().next().unwrap();
    let t = &shapes["f64 van_der_pol 2^4"];
    let f = |k: &str| t[k].as_f64().unwrap();
    let whole = |rate: &str, host: &str| 42.0 * 50.0 / f(rate) + 42.0 * f(host);
    let gpu_faster = whole("gpu_rate", "gpu_host_per_trajectory")
        <= whole("cpu_rate", "cpu_host_per_trajectory");
    assert!(f("gpu_host_per_trajectory") > 0.0, "{t}");
    assert_eq!(backend == "gpu", gpu_faster, "{t}");
}
