//! A run's progress for the person waiting on it: a bar on a terminal, and
//! elsewhere (a Slurm log, `nohup`, CI) a line every few seconds with the
//! fraction done, the rate and the time left, each flushed, so that a run
//! killed after a minute has still said how far it got
//! (`REEB_PROGRESS_EVERY=SECONDS` sets the interval of the lines).

use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// How often a line is printed where there is no terminal: every
/// [`FIRST_EVERY`] for the first [`FIRST_FOR`], then every [`LATER_EVERY`]
/// (a day-long run's log stays readable).
const FIRST_EVERY: Duration = Duration::from_secs(5);
const FIRST_FOR: Duration = Duration::from_secs(120);
const LATER_EVERY: Duration = Duration::from_secs(30);

/// What is followed: `label` (scene and engine), the trajectory-steps in
/// all, `done` as it grows (from `start`, the work finished before), and
/// `finished`, set when the work ends.
pub struct Followed<'a> {
    pub label: String,
    pub total: u64,
    pub start: u64,
    pub done: &'a AtomicU64,
    pub finished: &'a AtomicBool,
}

/// Shows the progress of `f` on stderr until it finishes: a bar on a
/// terminal, lines elsewhere. Runs on a thread of its own.
pub fn follow(f: &Followed) {
    if std::io::stderr().is_terminal() {
        bar(f);
    } else {
        lines(f);
    }
}

/// The bar spans the terminal (`wide_bar`): indicatif pads a shorter line
/// with spaces to the terminal's width on every redraw.
fn bar(f: &Followed) {
    let b = indicatif::ProgressBar::with_draw_target(
        Some(f.total),
        indicatif::ProgressDrawTarget::stderr(),
    );
    let start = f.start;
    let style = indicatif::ProgressStyle::with_template(
        "{spinner} {msg} [{wide_bar}] {percent:>3}% {elapsed} (eta {eta}) {rate}",
    )
    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
    .with_key(
        "rate",
        move |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = w.write_str(&rate(s.pos().saturating_sub(start), s.elapsed()));
        },
    )
    .progress_chars("=> ");
    b.set_style(style);
    b.set_message(f.label.clone());
    b.set_position(f.start);
    while !f.finished.load(Ordering::Relaxed) {
        b.set_position(f.done.load(Ordering::Relaxed));
        // Woken early when the run ends ([`Followed::finished`]).
        std::thread::park_timeout(Duration::from_millis(100));
    }
    b.finish_and_clear();
}

fn lines(f: &Followed) {
    let fixed = every_from_env();
    let since = Instant::now();
    let mut next = since;
    while !f.finished.load(Ordering::Relaxed) {
        if Instant::now() >= next {
            say(&line(f, f.done.load(Ordering::Relaxed), since.elapsed()));
            next += fixed.unwrap_or(match since.elapsed() < FIRST_FOR {
                true => FIRST_EVERY,
                false => LATER_EVERY,
            });
        }
        std::thread::park_timeout(Duration::from_millis(20));
    }
}

/// `REEB_PROGRESS_EVERY=SECONDS`: the lines' interval, if set to a number
/// of seconds (at least 0.1).
fn every_from_env() -> Option<Duration> {
    let text = std::env::var("REEB_PROGRESS_EVERY").ok()?;
    match text.trim().parse::<f64>() {
        Ok(s) if s.is_finite() && s >= 0.1 => Some(Duration::from_secs_f64(s)),
        _ => {
            say(&format!(
                "warning: REEB_PROGRESS_EVERY={text:?} is not a number of seconds (0.1 or more); progress every {} s",
                FIRST_EVERY.as_secs()
            ));
            None
        }
    }
}

/// One line: `NAME on cpu: 37.2 % of 4.20e9 trajectory-steps, 1.76e8/s, about 15 s left`.
fn line(f: &Followed, done: u64, elapsed: Duration) -> String {
    let share = done as f64 / f.total.max(1) as f64;
    let this_run = done.saturating_sub(f.start);
    let mut text = format!(
        "{}: {:.1} % of {} trajectory-steps",
        f.label,
        100.0 * share,
        sig3(f.total as f64)
    );
    if elapsed.as_secs_f64() > 0.5 && this_run > 0 {
        let per_s = this_run as f64 / elapsed.as_secs_f64();
        let left = f.total.saturating_sub(done) as f64 / per_s;
        text += &format!(
            ", {}, about {} left",
            rate(this_run, elapsed),
            humantime::format_duration(Duration::from_secs(left.ceil() as u64))
        );
    }
    text
}

/// Writes `text` as one line of stderr, at once.
fn say(text: &str) {
    let mut err = std::io::stderr().lock();
    let _ = writeln!(err, "{text}");
    let _ = err.flush();
}

/// Trajectory-steps per second, to 3 significant digits: `1.76e8/s`.
pub fn rate(steps: u64, elapsed: Duration) -> String {
    let s = elapsed.as_secs_f64();
    if s <= 0.0 {
        return "–/s".into();
    }
    format!("{}/s", sig3(steps as f64 / s))
}

/// `x` to 3 significant digits: `0.512`, `17.6`, `942`, `1.76e7`.
pub fn sig3(x: f64) -> String {
    if !x.is_finite() || x == 0.0 {
        return format!("{x}");
    }
    if (0.01..1000.0).contains(&x.abs()) {
        let digits = (2 - x.abs().log10().floor() as i32).max(0) as usize;
        format!("{x:.digits$}")
    } else {
        format!("{x:.2e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_have_three_significant_digits() {
        assert_eq!(sig3(17_600_844.276_2), "1.76e7");
        assert_eq!(sig3(942.4), "942");
        assert_eq!(sig3(17.64), "17.6");
        assert_eq!(sig3(0.5123), "0.512");
        assert_eq!(sig3(0.001234), "1.23e-3");
        assert_eq!(rate(17_600_844, Duration::from_secs(1)), "1.76e7/s");
    }

    #[test]
    fn a_line_says_the_fraction_the_rate_and_the_time_left() {
        let (done, finished) = (AtomicU64::new(0), AtomicBool::new(false));
        let f = Followed {
            label: "vdp on cpu".into(),
            total: 4_000_000_000,
            start: 1_000_000_000,
            done: &done,
            finished: &finished,
        };
        let l = line(&f, 2_000_000_000, Duration::from_secs(10));
        assert_eq!(
            l,
            "vdp on cpu: 50.0 % of 4.00e9 trajectory-steps, 1.00e8/s, about 20s left"
        );
        // Nothing done yet by this run: no rate to tell.
        assert_eq!(
            line(&f, 1_000_000_000, Duration::from_secs(10)),
            "vdp on cpu: 25.0 % of 4.00e9 trajectory-steps"
        );
    }
}
