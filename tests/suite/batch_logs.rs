//! A run in a batch log (issue 31, point 6): with stderr not a terminal,
//! progress lines with the fraction, rate and time left; and Ctrl-C or
//! SIGTERM end it with its work kept and the command that continues it.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::common;

use common::runs::{grid_scene, ok, s, same_arrays, REEB};

#[test]
fn progress_lines_reach_a_log_that_is_not_a_terminal() {
    let d = common::runs::tmp("logs", "lines");
    let scene = grid_scene(&d, 40_000.0, 100_000, "cpu");
    let o = Command::new(REEB)
        .args(["run", s(&scene), "--out", s(&d.join("run"))])
        .env("REEB_PROGRESS_EVERY", "0.1")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("grid on cpu: ") && l.contains("% of"))
        .collect();
    assert!(lines.len() >= 2, "{err}");
    let rated = lines
        .iter()
        .find(|l| l.contains("/s, about") && l.ends_with(" left"))
        .unwrap_or_else(|| panic!("no line with a rate: {err}"));
    // 3 significant digits: `1.23e8/s`, `942/s`.
    let rate = rated.split(", ").nth(1).unwrap().trim_end_matches("/s");
    let digits = rate.split('e').next().unwrap().replace('.', "");
    assert!(digits.len() == 3, "{rated}");
    assert!(!err.contains("\r") && !err.contains("  \n"), "{err:?}");
}

/// Sends `signal` to a run of `scene` once it is under way and waits for
/// it; returns its exit code and stderr.
fn interrupted(scene: &Path, out: &Path, signal: i32) -> (Option<i32>, String) {
    let log = out.with_extension("log");
    let mut child = Command::new(REEB)
        .args(["run", s(scene), "--out", s(out)])
        .env("REEB_PROGRESS_EVERY", "0.1")
        .stderr(Stdio::from(std::fs::File::create(&log).unwrap()))
        .spawn()
        .unwrap();
    let start = Instant::now();
    // Under way: a progress line with a rate.
    while !std::fs::read_to_string(&log).unwrap().contains("/s, about") {
        assert!(child.try_wait().unwrap().is_none(), "ended too soon");
        assert!(start.elapsed() < Duration::from_secs(120), "no progress");
        std::thread::sleep(Duration::from_millis(20));
    }
    // SAFETY: a signal to our own child.
    unsafe { libc::kill(child.id() as i32, signal) };
    let status = child.wait().unwrap();
    (status.code(), std::fs::read_to_string(&log).unwrap())
}

fn stopped_and_continued(signal: i32, name: &str) {
    let d = common::runs::tmp("logs", name);
    let scene = grid_scene(&d, 60_000.0, 600_000, "cpu");
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    let out = d.join("run");
    let (code, err) = interrupted(&scene, &out, signal);
    assert_eq!(code, Some(128 + signal), "{err}");
    let hint = err
        .split("to continue where it stopped:\n")
        .nth(1)
        .unwrap_or_else(|| panic!("no hint: {err}"))
        .lines()
        .next()
        .unwrap()
        .trim()
        .to_string();
    assert!(
        hint.ends_with("--resume") && hint.contains(s(&out)),
        "{hint}"
    );
    assert!(
        d.join("run.partial/.reeb-chunks/0.state").exists(),
        "no checkpoint of the work so far: {err}"
    );
    // The hint, as a shell reads it, continues the run where it stopped.
    let o = Command::new("sh")
        .args(["-c", &format!("exec {hint}")])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{said}");
    assert!(said.contains("continuing from its checkpoint"), "{said}");
    same_arrays(&one, &out);
}

#[test]
fn sigterm_keeps_the_work_and_says_how_to_continue() {
    stopped_and_continued(libc::SIGTERM, "sigterm");
}

#[test]
fn ctrl_c_keeps_the_work_and_says_how_to_continue() {
    stopped_and_continued(libc::SIGINT, "sigint");
}

#[test]
fn on_a_terminal_the_bar_leaves_no_trailing_spaces_and_a_short_rate() {
    let d = common::runs::tmp("logs", "terminal");
    let scene = grid_scene(&d, 40_000.0, 100_000, "cpu");
    let log = d.join("tty.log");
    let command = format!("{REEB} run {} --out {}", s(&scene), s(&d.join("run")));
    // `script` runs the command on a pseudo-terminal and keeps what it drew.
    let o = Command::new("script")
        .args(["-q", "-e", "-c", &command, s(&log)])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let drawn = std::fs::read_to_string(&log)
        .unwrap()
        .replace("\x1b[2K", "");
    let redraws: Vec<&str> = drawn
        .split(['\r', '\n'])
        .filter(|l| l.contains("grid on cpu ["))
        .collect();
    assert!(!redraws.is_empty(), "{drawn:?}");
    for l in &redraws {
        assert!(!l.ends_with("  "), "trailing spaces: {l:?}");
        let rate = l.split_whitespace().last().unwrap();
        assert!(!rate.contains(','), "{l:?}");
        let digits = rate.trim_end_matches("/s").split('e').next().unwrap();
        assert!(
            rate == "0/s" || digits.replace('.', "").len() == 3,
            "not 3 significant digits: {l:?}"
        );
    }
}
