//! Fuzzing the command line (issue 10, point 6): generated argument lists
//! for every verb (valid, wrong and absurd values; real scenes, broken
//! scenes, files that are not scenes; output paths that must not be
//! touched) run the binary in a sandbox. For every input reeb either
//! succeeds or exits 1 or 2 with a message: never a panic, an abort, a
//! signal, a hang, or a deleted file the user did not ask it to replace.
//!
//! CI runs 48 cases; `REEB_FUZZ_CASES=N` runs more (the long run of the
//! issue: `REEB_FUZZ_CASES=3000 cargo test --release --test cli_fuzz`).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use proptest::prelude::*;
use proptest::test_runner::RngSeed;

/// Deterministic runs (fixed seed, no regression files): CI reproduces them.
/// `REEB_FUZZ_CASES` and `REEB_FUZZ_SEED` run more, or others (long runs).
fn config() -> ProptestConfig {
    let env = |k: &str| std::env::var(k).ok().and_then(|s| s.parse::<u64>().ok());
    ProptestConfig {
        cases: env("REEB_FUZZ_CASES").map_or(48, |c| c as u32),
        rng_seed: RngSeed::Fixed(env("REEB_FUZZ_SEED").unwrap_or(0x636c_6966_757a)),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// A small scene that runs in milliseconds.
const SCENE: &str = r#"
model = "van_der_pol"
[params]
epsilon = { linspace = [0.5, 2.0, 3] }
[initial]
q = 1.0
[integrator]
scheme = "s2"
dt = 0.01
t_end = 2.0
[output]
final = ["q", "p"]
trajectory = { every = 10 }
"#;

/// Files every sandbox holds; none may disappear unless `--force` named a
/// folder holding it.
const SENTINELS: &[&str] = &[
    "notes.txt",
    "keep/data.csv",
    "scene.toml",
    "bad.toml",
    "mutated.toml",
];

/// Values a number of [`SCENE`] is replaced with in `mutated.toml`.
const EXTREMES: &[&str] = &[
    "0",
    "-1",
    "1e-300",
    "1e-50",
    "1e300",
    "1e39",
    "65536",
    "1e12",
    "4294967297",
    "nan",
    "inf",
    "-inf",
    "0.3",
];

/// `SCENE` with its `k`-th number replaced, in f32 or f64.
fn mutated(k: usize, value: &str, f32: bool) -> String {
    let mut count = 0;
    let mut out = String::new();
    let mut chars = SCENE.char_indices().peekable();
    while let Some((i, c)) = chars.next() {
        let starts = c.is_ascii_digit()
            && !SCENE[..i].ends_with(|p: char| p.is_alphanumeric() || p == '.' || p == '_');
        if !starts {
            out.push(c);
            continue;
        }
        let mut end = i + 1;
        while let Some(&(j, d)) = chars.peek() {
            if d.is_ascii_digit() || d == '.' || d == 'e' || d == '-' {
                end = j + 1;
                chars.next();
            } else {
                break;
            }
        }
        out.push_str(if count == k { value } else { &SCENE[i..end] });
        count += 1;
    }
    if f32 {
        out.push_str("[run]\nprecision = \"f32\"\n");
    }
    out
}

/// No run may take longer than this (a hang otherwise).
const LIMIT: Duration = Duration::from_secs(120);

fn pick(v: &'static [&'static str]) -> BoxedStrategy<String> {
    proptest::sample::select(v).prop_map(str::to_string).boxed()
}

fn maybe(flag: &'static str, values: &'static [&'static str]) -> BoxedStrategy<Vec<String>> {
    prop_oneof![
        2 => Just(vec![]),
        3 => pick(values).prop_map(move |v| vec![flag.to_string(), v]),
    ]
    .boxed()
}

fn switch(flag: &'static str) -> BoxedStrategy<Vec<String>> {
    prop_oneof![Just(vec![]), Just(vec![flag.to_string()])].boxed()
}

/// The scene argument: real, broken, missing, not a scene.
fn scene_arg() -> BoxedStrategy<String> {
    let real: Vec<String> = real_scenes()
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    prop_oneof![
        3 => Just("scene.toml".to_string()),
        3 => Just("bad.toml".to_string()),
        6 => Just("mutated.toml".to_string()),
        3 => proptest::sample::select(real),
        1 => pick(&["missing.toml", "notes.txt", "keep", "/dev/null", "", "-", "scene.toml/x"]),
    ]
    .boxed()
}

/// Output paths, the dangerous ones included.
const OUTS: &[&str] = &[
    "res",
    "res",
    "res/deeper/run",
    ".",
    "..",
    "/",
    "keep",
    "notes.txt",
    "scene.toml",
    "res.partial",
    "",
    "/proc/reeb-fuzz",
    "a b",
    "keep/..",
];

fn run_args() -> BoxedStrategy<Vec<String>> {
    (
        scene_arg(),
        maybe("--out", OUTS),
        maybe("--backend", &["cpu", "cpu", "gpu", "auto", "tpu"]),
        maybe("--precision", &["f32", "f64", "f16"]),
        switch("--force"),
        switch("--preview"),
    )
        .prop_map(|(scene, out, backend, precision, force, preview)| {
            let mut a = vec!["run".to_string(), scene.clone()];
            a.extend(out);
            a.extend(backend);
            a.extend(precision);
            a.extend(force);
            // Real scenes run as previews: the fuzz is about arguments.
            if !preview.is_empty() || scene.contains("scenes/") {
                a.push("--preview".into());
            }
            a
        })
        .boxed()
}

fn report_args() -> BoxedStrategy<Vec<String>> {
    (
        pick(&["stability", "work-precision", "bogus"]),
        prop_oneof![
            Just("scene.toml".to_string()),
            Just("mutated.toml".to_string()),
            Just("bad.toml".to_string()),
            pick(&["missing.toml", "notes.txt"])
        ],
        maybe("--out", OUTS),
        maybe("--precision", &["f32", "f64", "f8"]),
        switch("--force"),
    )
        .prop_map(|(kind, scene, out, precision, force)| {
            let mut a = vec!["report".to_string(), kind, scene];
            a.extend(out);
            a.push("--backend".into());
            a.push("cpu".into());
            a.extend(precision);
            a.extend(force);
            a
        })
        .boxed()
}

fn bench_args() -> BoxedStrategy<Vec<String>> {
    (
        pick(&["van_der_pol/s2", "kepler/s2", "spin_orbit/s2", "nope/s2"]),
        pick(&["0", "1", "64", "-3", "1e12", "abc", "18446744073709551616"]),
        pick(&["0", "1", "20", "99999999999999999999", "x"]),
        maybe("--threads", &["0", "1", "2", "100000"]),
        maybe("--repeats", &["0", "1", "2"]),
        maybe("--backend", &["cpu", "gpu", "fpga"]),
        maybe("--precision", &["f32", "f64", "f128"]),
    )
        .prop_map(
            |(scenario, n, steps, threads, repeats, backend, precision)| {
                let mut a = vec!["bench".to_string(), "--scenario".into(), scenario];
                a.extend(["--n".to_string(), n, "--steps".into(), steps]);
                a.extend(threads);
                a.extend(repeats);
                a.extend(backend);
                a.extend(precision);
                a
            },
        )
        .boxed()
}

/// Arguments for any verb, sometimes with a stray token.
fn argv() -> BoxedStrategy<Vec<String>> {
    let verb = prop_oneof![
        5 => run_args(),
        2 => report_args(),
        2 => scene_arg().prop_map(|s| vec!["check".to_string(), s]),
        2 => bench_args(),
        1 => pick(&["info", "--version", "--help", "verify --backend tpu", "verify --precision f16", "frobnicate", ""])
            .prop_map(|s| s.split_whitespace().map(str::to_string).collect()),
    ];
    (
        verb,
        proptest::option::of(pick(&["--bogus", "extra", "--out", "-x", "--", "--force"])),
    )
        .prop_map(|(mut a, stray)| {
            if let Some(s) = stray {
                a.push(s);
            }
            a
        })
        .boxed()
}

fn real_scenes() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    v
}

/// A fresh sandbox with the sentinel files.
fn sandbox(k: u64, mutated: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("reeb-cli-fuzz-{}-{k}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("keep")).unwrap();
    std::fs::write(dir.join("notes.txt"), "notes").unwrap();
    std::fs::write(dir.join("keep/data.csv"), "1,2").unwrap();
    std::fs::write(dir.join("scene.toml"), SCENE).unwrap();
    let bad = SCENE
        .replace("0.01", "1e-300")
        .replace("[0.5, 2.0, 3]", "[0.5, 1e300, 4]");
    std::fs::write(dir.join("bad.toml"), bad).unwrap();
    std::fs::write(dir.join("mutated.toml"), mutated).unwrap();
    dir
}

/// Runs reeb with `args` in `dir`: exit code and stderr, or why it failed.
fn run(dir: &Path, args: &[String]) -> Result<(i32, String), String> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_reeb"))
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .env("RUST_BACKTRACE", "0")
        .spawn()
        .map_err(|e| e.to_string())?;
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().map_err(|e| e.to_string())? {
            break s;
        }
        if start.elapsed() > LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("no answer after {LIMIT:?} (a hang)"));
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    use std::io::Read;
    let _ = child.stderr.take().map(|mut s| s.read_to_string(&mut err));
    match status.code() {
        Some(c) => Ok((c, err)),
        None => Err(format!("killed by a signal ({status:?}): {err}")),
    }
}

/// The folder `--force` allowed reeb to replace, if any.
fn forced_out(dir: &Path, args: &[String]) -> Option<PathBuf> {
    if !args.iter().any(|a| a == "--force") {
        return None;
    }
    let k = args.iter().position(|a| a == "--out")?;
    args.get(k + 1).map(|o| dir.join(o))
}

/// Inputs tried so far, and when the first began (progress of long runs).
static TRIED: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
static START: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();

fn count_input() {
    let start = *START.get_or_init(Instant::now);
    let n = TRIED.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
    if n.is_multiple_of(500) {
        eprintln!(
            "cli fuzz: {n} inputs in {:.0} s",
            start.elapsed().as_secs_f64()
        );
    }
}

fn check(k: u64, scene: &str, args: &[String]) -> Result<(), String> {
    count_input();
    let dir = sandbox(k, scene);
    // What `--force` may replace, resolved before the run.
    let forced = forced_out(&dir, args).and_then(|f| f.canonicalize().ok());
    let (code, err) = run(&dir, args)?;
    let fail = |why: String| {
        Err(format!(
            "reeb {args:?}: {why}\nstderr: {err}\nmutated.toml:\n{scene}"
        ))
    };
    if err.contains("panicked") || err.contains("memory allocation") {
        return fail("a panic or an abort".into());
    }
    if !(0..=2).contains(&code) {
        return fail(format!("exit code {code}"));
    }
    if code != 0 && !err.contains("error") {
        return fail("a failure without a message".into());
    }
    for s in SENTINELS {
        let path = dir.join(s);
        let allowed = forced.as_ref().is_some_and(|f| path.starts_with(f));
        if !path.exists() && !allowed {
            return fail(format!("{s} was deleted"));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn every_command_line_runs_or_says_why(
        args in argv(),
        k in any::<u64>(),
        (number, value, f32) in (0..8usize, proptest::sample::select(EXTREMES), any::<bool>()),
    ) {
        check(k, &mutated(number, value, f32), &args).map_err(TestCaseError::fail)?;
    }
}

/// The mutation reaches every number of the scene (the fuzz is not blind).
#[test]
fn mutations_replace_each_number() {
    assert!(mutated(2, "1e12", false).contains("linspace = [0.5, 2.0, 1e12]"));
    assert!(mutated(4, "1e-50", true).contains("dt = 1e-50"));
    assert!(mutated(4, "1e-50", true).contains("precision = \"f32\""));
    assert!(mutated(6, "0", false).contains("every = 0"));
}
