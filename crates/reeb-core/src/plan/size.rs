//! Sizes before anything is allocated: the memory a run may use, bytes in
//! words, and the gate on the outputs of a scene's plans (`reeb run` and
//! `reeb check` apply the same one). Every count here is checked: a product
//! that does not fit in 64 bits is refused, never wrapped.

use std::path::Path;

use crate::num::precision::Precision;

use super::observations::bytes_per_trajectory;
use super::Plan;

/// Memory this process may still allocate, in bytes, if known: the smaller
/// of the system's available memory (`MemAvailable` of `/proc/meminfo`) and
/// what the address-space limit (`ulimit -v`) leaves to the process.
pub fn available_memory() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok();
    let available = meminfo
        .as_deref()
        .and_then(|t| kib_field(t, "MemAvailable:"));
    match (available, address_space_left()) {
        (Some(a), Some(l)) => Some(a.min(l)),
        (a, l) => a.or(l),
    }
}

/// A `<name> <n> kB` line of a `/proc` file, in bytes.
fn kib_field(text: &str, name: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    line.split_whitespace()
        .nth(1)?
        .parse::<u64>()
        .ok()
        .map(|kb| kb.saturating_mul(1024))
}

/// The address space the process may still map under `RLIMIT_AS`, if limited.
#[cfg(unix)]
fn address_space_left() -> Option<u64> {
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes the limit into the struct it is given.
    if unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut lim) } != 0
        || lim.rlim_cur == libc::RLIM_INFINITY
    {
        return None;
    }
    let used = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|t| kib_field(&t, "VmSize:"))
        .unwrap_or(0);
    // rlim_t is u64 on Linux, not on every unix.
    #[allow(clippy::unnecessary_cast)]
    let cur = lim.rlim_cur as u64;
    Some(cur.saturating_sub(used))
}

#[cfg(not(unix))]
fn address_space_left() -> Option<u64> {
    None
}

/// The memory a run may take by default: 70 % of [`available_memory`]
/// (no limit where that is unknown).
pub fn default_limit() -> u64 {
    available_memory().map_or(u64::MAX, |m| m / 10 * 7)
}

/// Human-readable bytes.
pub fn bytes(b: u64) -> String {
    let units = ["B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut x = b as f64;
    let mut u = 0;
    while x >= 1024.0 && u + 1 < units.len() {
        x /= 1024.0;
        u += 1;
    }
    format!("{x:.1} {}", units[u])
}

/// What a scene's run will take, as the gate estimated it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Estimate {
    /// Trajectories of all the plans together.
    pub trajectories: u64,
    /// Bytes of the scene's arrays.
    pub bytes: u64,
    /// The limit they were checked against.
    pub limit: u64,
}

/// A run refused by [`output_gate`] (the message names what to change).
#[derive(Debug, Clone, thiserror::Error)]
#[error("{0}")]
pub struct SizeError(pub String);

/// The knobs that make a run's outputs smaller.
pub const RECORD_LESS: &str = "record less: a larger output.trajectory.every, fewer output.trajectory.vars or output.poincare.vars, a smaller output.poincare.max_points, or fewer values along an axis";

/// The gate on the outputs of `plans` (the sub-runs of the scene at `path`)
/// in `precision`: the scene's arrays (shaped by the longest plan) must fit
/// in `limit` bytes, the free disk where they go (`reeb run` streams them
/// there chunk by chunk, so memory does not bound them). Refused with the
/// estimate and the knobs to change.
pub fn output_gate(
    path: &Path,
    plans: &[&Plan],
    precision: Precision,
    limit: u64,
) -> Result<Estimate, SizeError> {
    let trajectories = plans
        .iter()
        .try_fold(0u64, |t, p| t.checked_add(p.n as u64))
        .ok_or_else(|| {
            SizeError(format!(
                "{}: the plans have more than 2^64 trajectories together; use fewer values along an axis",
                path.display()
            ))
        })?;
    let need = outputs_bytes(plans, trajectories, precision);
    match need {
        Some(b) if b <= limit => Ok(Estimate {
            trajectories,
            bytes: b,
            limit,
        }),
        _ => Err(SizeError(format!(
            "{}: the outputs of {trajectories} {} need {} and {} is available on disk; {RECORD_LESS}",
            path.display(),
            if trajectories == 1 {
                "trajectory"
            } else {
                "trajectories"
            },
            need.map_or_else(
                || "more than 16 EiB".to_string(),
                |b| format!("about {}", bytes(b))
            ),
            bytes(limit)
        ))),
    }
}

/// The bytes [`output_gate`] compares with its limit; `None` beyond 64 bits.
fn outputs_bytes(plans: &[&Plan], trajectories: u64, precision: Precision) -> Option<u64> {
    let longest = plans.iter().max_by_key(|p| p.steps)?;
    trajectories.checked_mul(bytes_per_trajectory(longest, precision)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_in_words() {
        assert_eq!(bytes(0), "0.0 B");
        assert_eq!(bytes(1536), "1.5 KiB");
        assert_eq!(bytes(8_000_000_000_000), "7.3 TiB");
        assert_eq!(bytes(u64::MAX), "16.0 EiB");
    }

    #[test]
    fn available_memory_is_known_on_linux() {
        if cfg!(target_os = "linux") {
            let m = available_memory().unwrap();
            assert!(m > 0);
            assert!(default_limit() < m);
        }
    }
}
