//! The scripts `reeb slurm` writes are safe by construction (issue 31,
//! point 1): hostile names and paths are refused naming their field, or
//! quoted for the shell and for Slurm's `#SBATCH` parser; the scripts are
//! then run by bash with a stub `sbatch` (no Slurm needed), and nothing but
//! reeb runs.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common;

use common::runs::{grid_scene, ok, reeb, s, same_arrays, toml_string, REEB};

fn tmp(name: &str) -> PathBuf {
    common::runs::tmp("slurm-scripts", name)
}

/// Runs `reeb args`, which must fail; returns its stderr.
fn refused(args: &[&str]) -> String {
    let o = reeb(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "reeb {args:?}: {err}");
    err
}

/// A small scene named by `name = …` (TOML-escaped), written to `path`.
fn named_scene(path: &Path, name: &str) {
    let text = format!(
        "name = {}\nmodel = \"van_der_pol\"\n[params]\nepsilon = {{ linspace = [0.5, 2.0, 4] }}\n[initial]\nq = 1.0\n[integrator]\nscheme = \"s2\"\ndt = 0.01\nt_end = 1.0\n[run]\nbackend = \"cpu\"\n",
        toml_string(name)
    );
    std::fs::write(path, text).unwrap();
}

#[test]
fn a_newline_in_the_scene_name_is_refused_naming_the_field() {
    let d = tmp("name");
    let scene = d.join("evil.toml");
    named_scene(&scene, "x\ntouch pwned;#");
    for verb in ["slurm", "run", "check"] {
        let mut args = vec![verb, s(&scene)];
        if verb == "slurm" {
            args.extend(["--shards", "2", "--dry-run"]);
        }
        let err = refused(&args);
        assert!(
            err.contains("name") && err.contains("control"),
            "{verb}: {err}"
        );
    }
    assert!(!d.join("pwned").exists());
    assert!(!Path::new("runs").join("x\ntouch pwned;#").exists());
}

#[test]
fn a_newline_in_out_or_the_scene_path_is_refused_naming_it() {
    let d = tmp("paths");
    let scene = grid_scene(&d, 1.0, 50, "cpu");
    let out = d.join("run\ntouch pwned;#");
    let err = refused(&[
        "slurm",
        s(&scene),
        "--shards",
        "2",
        "--out",
        s(&out),
        "--dry-run",
    ]);
    assert!(err.contains("--out") && err.contains("\\n"), "{err}");
    // The scene file's own path.
    let sub = d.join("a\nb");
    std::fs::create_dir_all(&sub).unwrap();
    let evil = sub.join("grid.toml");
    std::fs::copy(&scene, &evil).unwrap();
    let err = refused(&[
        "slurm",
        s(&evil),
        "--shards",
        "2",
        "--out",
        s(&d.join("ok")),
        "--dry-run",
    ]);
    assert!(err.contains("scene file's path"), "{err}");
    assert!(!d.join("ok.slurm").exists(), "nothing written on a refusal");
}

/// A folder whose name every layer reads differently: spaces, both quotes,
/// `$( )`, backticks, `#` (Slurm's comment), `%` (its filename patterns),
/// `;` and `*`.
const HOSTILE: &str = "r u'n\"$(touch pwned)`touch pwned2`#;%j*";

/// The value of `#SBATCH --output=` in `script` as Slurm's `_get_argument`
/// reads it: quotes group (`#` inside them is no comment), a backslash
/// escapes the next character, an unquoted `#` ends the line; then its
/// filename pattern with `%%` → `%` and `%a` → `index`.
fn slurm_output(script: &str, index: usize) -> String {
    let line = script
        .lines()
        .find_map(|l| l.strip_prefix("#SBATCH --output="))
        .expect("an --output line");
    let (mut arg, mut quote, mut escape) = (String::new(), None, false);
    for c in line.chars() {
        if escape {
            escape = false;
            arg.push(c);
        } else if c == '\\' {
            escape = true;
        } else if let Some(q) = quote {
            if c == q {
                quote = None;
            } else {
                arg.push(c);
            }
        } else if c == '"' || c == '\'' {
            quote = Some(c);
        } else if c == '#' || c.is_whitespace() {
            break;
        } else {
            arg.push(c);
        }
    }
    assert!(quote.is_none() && !escape, "unbalanced: {line}");
    arg.replace("%%", "\u{0}")
        .replace("%a", &index.to_string())
        .replace('\u{0}', "%")
}

/// A stub `sbatch` in `bin/`: records its arguments, one per line, and
/// answers a job id as `--parsable` does.
fn stub_sbatch(bin: &Path, log: &Path) {
    std::fs::create_dir_all(bin).unwrap();
    let path = bin.join("sbatch");
    let script = format!(
        "#!/bin/bash\nfor a in \"$@\"; do printf '%s\\n' \"$a\" >> {}; done\necho '---' >> {}\necho 4242\n",
        shell(log),
        shell(log)
    );
    std::fs::write(&path, script).unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
}

fn shell(p: &Path) -> String {
    format!("'{}'", s(p).replace('\'', r"'\''"))
}

#[test]
fn hostile_paths_are_quoted_and_the_scripts_run_only_reeb() {
    let d = tmp("hostile");
    let scene = grid_scene(&d, 2.0, 50, "cpu");
    let out = d.join(HOSTILE);
    let (bin, log) = (d.join("bin"), d.join("sbatch.log"));
    stub_sbatch(&bin, &log);
    let path = format!("{}:{}", s(&bin), std::env::var("PATH").unwrap_or_default());
    let o = Command::new(REEB)
        .args(["slurm", s(&scene), "--shards", "2", "--out", s(&out)])
        .args(["--chunk-trajectories", "20"])
        .env("PATH", &path)
        .current_dir(&d)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{text}");
    assert!(text.contains("job array 4242"), "{text}");
    // Each script reached sbatch as one argument, whole.
    let mut slurm = out.clone().into_os_string();
    slurm.push(".slurm");
    let slurm = PathBuf::from(slurm);
    let (array, merge) = (slurm.join("shards.sbatch"), slurm.join("merge.sbatch"));
    let args = std::fs::read_to_string(&log).unwrap();
    assert!(args.lines().any(|l| l == s(&array)), "{args}");
    assert!(args.lines().any(|l| l == s(&merge)), "{args}");
    assert!(args.contains("--dependency=afterok:4242"), "{args}");
    // Slurm reads the log paths back as they are.
    let (a, m) = (
        std::fs::read_to_string(&array).unwrap(),
        std::fs::read_to_string(&merge).unwrap(),
    );
    let logs = slurm.join("logs");
    assert_eq!(slurm_output(&a, 1), s(&logs.join("shard-1.out")), "{a}");
    assert_eq!(slurm_output(&m, 0), s(&logs.join("merge.out")), "{m}");
    // bash runs the tasks and the merge: reeb integrates into the hostile
    // folder, and nothing else runs.
    for k in 0..2 {
        let o = Command::new("bash")
            .arg(&array)
            .env("SLURM_ARRAY_TASK_ID", k.to_string())
            .current_dir(&d)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let o = Command::new("bash")
        .arg(&merge)
        .current_dir(&d)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["pwned", "pwned2"] {
        assert!(!d.join(f).exists(), "{f} was created");
    }
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    same_arrays(&one, &out);
}

#[test]
fn the_dry_run_hint_is_quoted_for_the_shell() {
    let d = tmp("hint");
    let scene = grid_scene(&d, 1.0, 50, "cpu");
    let out = d.join("my run");
    let line = ok(&[
        "slurm",
        s(&scene),
        "--shards",
        "2",
        "--out",
        s(&out),
        "--dry-run",
    ]);
    let array = format!("{}.slurm/shards.sbatch", s(&out));
    assert!(
        line.contains(&format!("sbatch --parsable '{array}'")),
        "{line}"
    );
}

/// Every option a task takes travels to it: written back as arguments by
/// `TaskOptions::to_args`, parsed by `reeb run`'s own definition, they are
/// the same options (issue 35, point 5).
#[test]
fn every_task_option_reaches_each_task_unchanged() {
    use reeb::output::run::{RunOptions, TaskOptions};
    let all = TaskOptions {
        backend: Some(reeb::scene::BackendChoice::Gpu),
        precision: Some(reeb::num::precision::Precision::F32),
        format: Some(reeb::scene::Format::Zarr),
        chunk_trajectories: Some(4096),
        checkpoint_every: Some(std::time::Duration::from_secs_f64(2.5)),
        adapter: Some(1),
        adapters: None,
    };
    let back = RunOptions::parse_args(&all.to_args()).unwrap();
    assert_eq!(back.task, all);
    // `--adapters` excludes `--adapter`.
    let spread = TaskOptions {
        adapter: None,
        adapters: Some(reeb::backend::Adapters::List(vec![0, 1, 1])),
        ..all
    };
    assert_eq!(
        RunOptions::parse_args(&spread.to_args()).unwrap().task,
        spread
    );
    assert_eq!(
        RunOptions::parse_args(&[]).unwrap().task,
        TaskOptions::default()
    );

    let d = tmp("task-options");
    let scene = grid_scene(&d, 1.0, 50, "cpu");
    let out = d.join("run");
    ok(&[
        "slurm",
        s(&scene),
        "--shards",
        "2",
        "--out",
        s(&out),
        "--dry-run",
        "--precision",
        "f32",
        "--chunk-trajectories",
        "7",
        "--checkpoint-every",
        "2.5",
    ]);
    let script = std::fs::read_to_string(format!("{}.slurm/shards.sbatch", s(&out))).unwrap();
    assert!(
        script.contains(
            "--resume '--precision' 'f32' '--chunk-trajectories' '7' '--checkpoint-every' '2.5'\n"
        ),
        "{script}"
    );
}

/// The Python keywords are `reeb run`'s options, by name, and a wrong
/// value is refused naming its keyword.
#[test]
fn run_options_by_keyword_name_the_keyword_they_refuse() {
    use reeb::output::run::RunOptions;
    let names = RunOptions::names();
    for n in [
        "out",
        "force",
        "resume",
        "shard",
        "backend",
        "precision",
        "format",
        "chunk_trajectories",
        "checkpoint_every",
        "adapter",
    ] {
        assert!(names.iter().any(|x| x == n), "{n} in {names:?}");
    }
    let pair = |k: &str, v: &str| vec![(k.to_string(), Some(v.to_string()))];
    let e = RunOptions::from_pairs(&pair("chunk_trajectories", "0")).unwrap_err();
    assert!(e.starts_with("chunk_trajectories: "), "{e}");
    let e = RunOptions::from_pairs(&pair("checkpoint_every", "-1")).unwrap_err();
    assert!(
        e.starts_with("checkpoint_every: ") && e.contains("0 or more"),
        "{e}"
    );
    let e = RunOptions::from_pairs(&pair("colour", "red")).unwrap_err();
    assert!(e.starts_with("colour: not an option"), "{e}");
    let o = RunOptions::from_pairs(&[
        ("shard".into(), Some("1/4".into())),
        ("resume".into(), None),
    ])
    .unwrap();
    assert!(o.resume && o.shard.is_some_and(|s| (s.index, s.count) == (1, 4)));
}
