//! reeb never replaces a file it did not write, and never hands back a
//! number without saying when it is doubtful: each refusal and warning
//! here was once missing (a script written through a link, a skip that
//! left no sample, exponents lost to collapsed vectors, an indicator's
//! overflow that took the state with it, points dropped without a word,
//! stopped orbits painted as regular, …), through the command line as a
//! user meets them.

use std::path::{Path, PathBuf};

use crate::common;

use common::npy_f64;
use common::runs::{ok, reeb, s, summary};

fn tmp(name: &str) -> PathBuf {
    common::runs::tmp("trust", name)
}

/// Runs `reeb args`, which must fail with a message; returns stderr.
fn refused(args: &[&str]) -> String {
    let o = reeb(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "reeb {args:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// `text` written as `dir/name.toml`.
fn scene(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// A van der Pol scene with `output` lines.
fn vdp(output: &str) -> String {
    format!("model = \"van_der_pol\"\n[params]\nepsilon = 1.0\n[initial]\nq = 2.0\n[integrator]\nscheme = \"s2\"\ndt = 0.01\nsteps = 1000\n[output]\nfinal = [\"q\"]\n{output}\n[run]\nbackend = \"cpu\"\n")
}

/// The backends a run of the tests can use: the CPU, and the GPU where
/// there is an adapter (lavapipe in CI, which requires it).
fn backends() -> Vec<&'static str> {
    match common::gpu() {
        Some(_) => vec!["cpu", "gpu"],
        None => vec!["cpu"],
    }
}

#[test]
fn slurm_replaces_only_the_scripts_it_wrote_and_follows_no_link() {
    let d = tmp("slurm");
    let path = scene(&d, "grid", &vdp(""));
    let out = d.join("o");
    let slurm = d.join("o.slurm");
    let args = [
        "slurm",
        s(&path),
        "--shards",
        "2",
        "--out",
        s(&out),
        "--dry-run",
    ];
    ok(&args);
    // Its own scripts it replaces (a second dry run, the same or another run).
    ok(&args);
    ok(&[
        "slurm",
        s(&path),
        "--shards",
        "3",
        "--out",
        s(&out),
        "--dry-run",
    ]);
    assert!(std::fs::read_to_string(slurm.join("shards.sbatch"))
        .unwrap()
        .contains("/3"));

    // A hand-edited script is the user's: refused, kept as it is.
    std::fs::write(slurm.join("shards.sbatch"), "#!/bin/bash\n# mine\n").unwrap();
    let err = refused(&args);
    assert!(
        err.contains("shards.sbatch") && err.contains("not written by reeb"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(slurm.join("shards.sbatch")).unwrap(),
        "#!/bin/bash\n# mine\n"
    );
    std::fs::remove_file(slurm.join("shards.sbatch")).unwrap();

    // A link in a script's place is never written through.
    let precious = d.join("precious.txt");
    std::fs::write(&precious, "keep me\n").unwrap();
    std::fs::remove_file(slurm.join("merge.sbatch")).unwrap();
    std::os::unix::fs::symlink(&precious, slurm.join("merge.sbatch")).unwrap();
    let err = refused(&args);
    assert!(
        err.contains("merge.sbatch") && err.contains("symbolic link"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&precious).unwrap(), "keep me\n");

    // Nor is a link in the folder's place, nor one for its logs.
    std::fs::remove_dir_all(&slurm).unwrap();
    let elsewhere = d.join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    std::os::unix::fs::symlink(&elsewhere, &slurm).unwrap();
    let err = refused(&args);
    assert!(
        err.contains("o.slurm") && err.contains("symbolic link"),
        "{err}"
    );
    assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 0);
    std::fs::remove_file(&slurm).unwrap();
    std::fs::create_dir(&slurm).unwrap();
    std::os::unix::fs::symlink(&elsewhere, slurm.join("logs")).unwrap();
    let err = refused(&args);
    assert!(
        err.contains("logs") && err.contains("symbolic link"),
        "{err}"
    );
    assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 0);
}

#[test]
fn a_lyapunov_skip_that_leaves_no_sample_is_refused() {
    let d = tmp("skip");
    let path = scene(
        &d,
        "skip",
        &vdp("lyapunov = { vectors = 2, every = 600, skip = 0.5 }"),
    );
    for verb in ["check", "run"] {
        let err = refused(&[verb, s(&path), "--out", s(&d.join("o"))]);
        assert!(
            err.contains("skip.toml:12: output.lyapunov.skip:") && err.contains("no sample"),
            "{verb}: {err}"
        );
    }
    assert!(!d.join("o").exists());
    // One sample after the skip is enough.
    let path = scene(
        &d,
        "enough",
        &vdp("lyapunov = { vectors = 2, every = 500, skip = 0.5 }"),
    );
    ok(&["check", s(&path)]);
}

/// The saddle V = −q²/2 at its fixed point, exponents ±0.9996 (dt 0.1,
/// 3000 steps), two vectors re-orthonormalised every `every` steps.
fn saddle(dir: &Path, precision: &str, every: u64, backend: &str) -> PathBuf {
    let name = format!("saddle-{precision}-{every}-{backend}");
    let text = format!(
        "model = \"mechanical\"\n[formula]\ndof = 1\npotential = \"-q^2/2\"\n[initial]\nq = 0.0\np = 0.0\n[integrator]\nscheme = \"s2\"\ndt = 0.1\nsteps = 3000\n[output]\nfinal = [\"q\", \"p\"]\nlyapunov = {{ vectors = 2, every = {every} }}\n[run]\nprecision = \"{precision}\"\nbackend = \"{backend}\"\n"
    );
    let path = scene(dir, &name, &text);
    let out = dir.join(&name);
    ok(&["run", s(&path), "--out", s(&out)]);
    out
}

#[test]
fn exponents_the_samples_cannot_resolve_are_said_so() {
    let d = tmp("collapse");
    for backend in backends() {
        for (precision, every) in [("f64", 300), ("f64", 1000), ("f32", 100)] {
            let out = saddle(&d, precision, every, backend);
            let sum = summary(&out);
            let what = format!("{precision} every = {every} on {backend}");
            let warnings = sum["warnings"].to_string();
            let l = npy_f64(&out.join("lyapunov.npy"));
            // λ₂ is round-off (λ₁ itself stays right), or the collapse was
            // total and took both with it: either is said.
            if sum["indicators"]["lost"] == 1 {
                assert!(warnings.contains("left the range"), "{what}: {warnings}");
                assert!(l.iter().all(|x| x.is_nan()), "{what}: {l:?}");
                continue;
            }
            assert_eq!(
                sum["indicators"]["unresolved"],
                serde_json::json!([0, 1]),
                "{what}"
            );
            assert!(
                warnings.contains("λ2 in 1 of 1 trajectories not resolved"),
                "{what}: {warnings}"
            );
            assert!((l[0] - 0.9984).abs() < 1e-3, "{what}: {l:?}");
        }
        // Sampled often enough: resolved, and the sum rule λ₁ + λ₂ = 0 holds.
        for (precision, every) in [("f64", 10), ("f32", 10)] {
            let out = saddle(&d, precision, every, backend);
            let sum = summary(&out);
            assert_eq!(sum["indicators"]["unresolved"], serde_json::json!([0, 0]));
            assert_eq!(sum["warnings"], serde_json::json!([]));
            let l = npy_f64(&out.join("lyapunov.npy"));
            assert!((l[0] + l[1]).abs() < 1e-5, "{precision}: {l:?}");
        }
    }
}

#[test]
fn an_indicator_that_overflows_keeps_its_trajectorys_state() {
    let d = tmp("overflow");
    for backend in backends() {
        let out = saddle(&d, "f32", 300, backend);
        let sum = summary(&out);
        assert_eq!(sum["status"]["ok"], 1, "{backend}: {sum}");
        assert_eq!(sum["indicators"]["lost"], 1, "{backend}");
        assert!(
            sum["warnings"]
                .to_string()
                .contains("left the range of f32"),
            "{backend}"
        );
        assert_eq!(npy_f64(&out.join("final_q.npy")), [0.0], "{backend}");
        assert_eq!(npy_f64(&out.join("final_p.npy")), [0.0], "{backend}");
        assert!(npy_f64(&out.join("lyapunov.npy"))
            .iter()
            .all(|x| x.is_nan()));
    }
}

#[test]
fn poincare_points_beyond_max_points_are_counted_and_said() {
    let d = tmp("points");
    let path = scene(
        &d,
        "points",
        &vdp("poincare = { crossing = \"q\", value = 0.0, max_points = 5 }")
            .replace("steps = 1000", "steps = 10000"),
    );
    let out = d.join("o");
    let said = ok(&["run", s(&path), "--out", s(&out)]);
    assert!(
        said.contains("warning: output.poincare.max_points = 5: 1 of 1 trajectories"),
        "{said}"
    );
    let sum = summary(&out);
    let p = &sum["poincare"];
    assert_eq!(
        (p["kept"].as_u64(), p["trajectories_over"].as_u64()),
        (Some(5), Some(1))
    );
    assert_eq!(
        p["found"].as_u64().unwrap() - p["dropped"].as_u64().unwrap(),
        5,
        "{p}"
    );
    assert!(p["dropped"].as_u64().unwrap() > 0);
}

#[test]
fn keys_of_the_other_kind_of_section_are_refused() {
    let d = tmp("section-keys");
    for (body, field) in [
        ("crossing = \"q\", skip = 50", "output.poincare.skip"),
        ("crossing = \"q\", skip = 0.5", "output.poincare.skip"),
        ("crossing = \"q\", phase = 1.0", "output.poincare.phase"),
        (
            "period = 1.0, direction = \"down\"",
            "output.poincare.direction",
        ),
        ("period = 1.0, value = 1.0", "output.poincare.value"),
    ] {
        let path = scene(&d, "keys", &vdp(&format!("poincare = {{ {body} }}")));
        let err = refused(&["check", s(&path)]);
        assert!(
            err.contains(&format!("keys.toml:12: {field}: belongs to")),
            "{body}: {err}"
        );
    }
}

#[test]
fn stopped_orbits_are_counted_and_grey_in_the_indicator_maps() {
    let d = tmp("stopped");
    // Hénon–Heiles, some orbits escaping (stopped) before the end.
    let text = "model = \"mechanical\"\n[formula]\ndof = 2\npotential = \"(q1^2 + q2^2)/2 + q1^2*q2 - q2^3/3\"\n[initial]\nq1 = 0.0\np1 = 0.45\nq2 = { linspace = [-0.45, 0.65, 12] }\np2 = { linspace = [-0.45, 0.45, 12] }\n[integrator]\nscheme = \"s2\"\ndt = 0.05\nt_end = 100.0\n[output]\nfinal = [\"q\", \"p\"]\nmegno = { every = 10 }\nstop = \"q1^2 + q2^2 > 4\"\n[run]\nprecision = \"f64\"\nbackend = \"cpu\"\n";
    let path = scene(&d, "hh", text);
    let out = d.join("o");
    let said = ok(&["run", s(&path), "--out", s(&out)]);
    let sum = summary(&out);
    let stopped = sum["status"]["stopped"].as_u64().unwrap();
    assert!(stopped > 0 && stopped < 144, "{sum}");
    assert_eq!(sum["indicators"]["stopped"].as_u64(), Some(stopped));
    assert!(
        said.contains(&format!(
            "warning: {stopped} of 144 trajectories stopped (output.stop)"
        )),
        "{said}"
    );
    // The map paints them in the grey of its "stopped" legend entry.
    let png = png::Decoder::new(std::fs::File::open(out.join("megno.png")).unwrap());
    let mut reader = png.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let step = info.color_type.samples();
    let grey = buf[..info.buffer_size()]
        .chunks(step)
        .filter(|p| p[..3] == [150, 150, 150])
        .count();
    assert!(grey > 1000, "{grey} pixels of the stopped grey");
}

#[test]
fn formulas_out_of_range_or_undefined_at_the_start_are_refused() {
    let d = tmp("formulas");
    let text = |potential: &str, q: &str| {
        format!("model = \"mechanical\"\n[formula]\ndof = 1\npotential = \"{potential}\"\n[initial]\nq = {q}\np = 0.0\n[integrator]\nscheme = \"s2\"\ndt = 0.01\nsteps = 100\n[output]\nfinal = [\"q\"]\n")
    };
    for (potential, q, says) in [
        (
            "1e999*q",
            "0.5",
            "formula.potential: column 1: `1e999` is out of range",
        ),
        (
            "log(q-1)",
            "0.5",
            "formula.potential: V is NaN where a trajectory starts (q = 0.5",
        ),
        (
            "log(q-1)",
            "{ linspace = [3.0, 1.0, 3] }",
            "formula.potential: V is -inf where a trajectory starts (q = 1,",
        ),
        ("sqrt(q)*q", "-1.0", "formula.potential: V is NaN"),
        ("q^3/3 + 1/q", "0.0", "formula.potential: V is"),
    ] {
        let path = scene(&d, "f", &text(potential, q));
        for verb in ["check", "run"] {
            let err = refused(&[verb, s(&path), "--out", s(&d.join("o"))]);
            assert!(err.contains(says), "{potential} at q = {q}: {err}");
        }
    }
    // A damping undefined at t0 names its own field.
    let path = scene(
        &d,
        "f",
        &text("q^2", "1.0").replace("dof = 1", "dof = 1\ndamping = \"1/t\""),
    );
    let err = refused(&["check", s(&path)]);
    assert!(
        err.contains("formula.damping: f is inf where a trajectory starts"),
        "{err}"
    );
    // Initial values out of range say so in the same words.
    let path = scene(&d, "f", &text("q^2", "1e999"));
    let err = refused(&["check", s(&path)]);
    assert!(err.contains("initial.q: 1e999 is out of range"), "{err}");
}

#[test]
fn resonance_ratios_that_could_never_be_chosen_are_refused() {
    let d = tmp("ratios");
    let text = |ratios: &str| {
        format!("model = \"spin_orbit\"\n[initial]\nq = 0.0\np = 1.0\n[integrator]\nscheme = \"s2\"\ndt = 0.01\nsteps = 100\n[output]\nfinal = [\"q\"]\naverage = [\"p\"]\nresonance = {{ var = \"p\", ratios = {ratios}, tolerance = 0.01 }}\n")
    };
    let path = scene(&d, "r", &text("[[1, 1], [2, 2], [201, 200]]"));
    let err = refused(&["check", s(&path)]);
    assert!(
        err.contains("r.toml:12: output.resonance.ratios: 2:2 is the same ratio as 1:1"),
        "{err}"
    );
    let path = scene(&d, "r", &text("[[1, 1], [201, 200], [3, 2]]"));
    let said = ok(&["check", s(&path)]);
    assert!(
        said.contains("warning: ")
            && said.contains("the windows of 1:1 and 201:200 (each ± tolerance 0.01) overlap"),
        "{said}"
    );
    assert!(!said.contains("3:2"), "{said}");
}

#[test]
fn a_refused_resume_leaves_the_partial_as_it_was() {
    let d = tmp("resume");
    let grid = |q: &str| {
        vdp("")
            .replace("epsilon = 1.0", "epsilon = { linspace = [0.5, 2.0, 4] }")
            .replace("q = 2.0", q)
    };
    let path = scene(&d, "a", &grid("q = 2.0"));
    let out = d.join("o");
    let partial = d.join("o.partial");
    // A run killed half-way leaves its partial: made here as a shard does.
    ok(&[
        "run",
        s(&path),
        "--out",
        s(&out),
        "--shard",
        "0/2",
        "--chunk-trajectories",
        "1",
    ]);
    let owner = std::fs::read_to_string(partial.join(".reeb-owner")).unwrap();
    let changed = scene(&d, "a", &grid("q = 1.5"));
    let err = refused(&["run", s(&changed), "--out", s(&out), "--resume"]);
    assert!(
        err.contains("different run") && err.contains("without --resume"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(partial.join(".reeb-owner")).unwrap(),
        owner
    );
    // A shard is not told to leave out --resume.
    let err = refused(&["run", s(&changed), "--out", s(&out), "--shard", "1/2"]);
    assert!(
        err.contains("different run") && !err.contains("without --resume"),
        "{err}"
    );
    assert!(err.contains("shards of one run"), "{err}");
}

#[test]
fn an_old_output_a_failed_removal_left_is_called_reebs() {
    let d = tmp("left");
    let path = scene(&d, "a", &vdp(""));
    let out = d.join("o");
    ok(&["run", s(&path), "--out", s(&out)]);
    // What a replacement leaves at DIR.partial when it cannot remove the
    // previous output: that output, complete.
    std::fs::rename(&out, d.join("o.partial")).unwrap();
    let err = refused(&["run", s(&path), "--out", s(&out)]);
    assert!(
        err.contains("earlier reeb output") && !err.contains("not made by reeb"),
        "{err}"
    );
}

#[test]
fn a_tuning_cache_that_cannot_be_written_leaves_nothing_behind() {
    if common::gpu().is_none() {
        return;
    }
    let d = tmp("cache");
    let cache = d.join("cache");
    std::fs::create_dir_all(cache.join("reeb").join("gpu-tuning.json")).unwrap();
    let path = scene(&d, "a", &vdp("").replace("\"cpu\"", "\"gpu\""));
    for k in 0..2 {
        let o = std::process::Command::new(common::runs::REEB)
            .args(["run", s(&path), "--out", s(&d.join(format!("o{k}")))])
            .env("XDG_CACHE_HOME", &cache)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        assert!(err.contains("could not be cached"), "{err}");
    }
    let left: Vec<_> = std::fs::read_dir(cache.join("reeb"))
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, ["gpu-tuning.json"], "{left:?}");
}

#[test]
fn integers_too_large_say_so() {
    let d = tmp("integers");
    let path = scene(
        &d,
        "i",
        &vdp("").replace("steps = 1000", "steps = 18446744073709551616"),
    );
    let err = refused(&["check", s(&path)]);
    assert!(
        err.contains("integrator.steps: is too large: at most 18446744073709551615"),
        "{err}"
    );
    let path = scene(
        &d,
        "i",
        &vdp("trajectory = { every = 99999999999999999999 }"),
    );
    let err = refused(&["check", s(&path)]);
    assert!(
        err.contains("output.trajectory.every: is too large"),
        "{err}"
    );
    let path = scene(&d, "i", &vdp("trajectory = { every = -3 }"));
    let err = refused(&["check", s(&path)]);
    assert!(err.contains("expected a non-negative integer"), "{err}");
}

#[test]
fn a_preview_keeps_its_stroboscopic_section() {
    let d = tmp("preview");
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    for name in ["forced_van_der_pol", "duffing"] {
        let out = d.join(name);
        ok(&[
            "run",
            s(&root.join(format!("{name}.toml"))),
            "--preview",
            "--backend",
            "cpu",
            "--out",
            s(&out),
        ]);
        let counts: Vec<u32> = common::npy_ints(&out.join("poincare_count.npy"));
        assert!(counts.iter().all(|c| *c > 0), "{name}: {counts:?}");
    }
}
