//! Mid-run checkpoints (`--checkpoint-every`): how often a backend takes a
//! snapshot of an integration (`plan/snapshot.rs`), where it hands it, and
//! the snapshot an integration continues from. The backends pause where
//! their state is whole (the CPU between steps of its blocks, the GPU
//! between windows), so a snapshot is exactly what continuing needs.

use std::io::{self, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::num::precision::Real;
use crate::plan::observations::Observations;
use crate::plan::snapshot::{read_observations, write_observations, Header};

/// Writes a snapshot's bytes.
pub type Contents<'c> = &'c dyn Fn(&mut dyn Write) -> io::Result<()>;

/// Checkpoints of one or more integrations (the sub-runs of a chunk share
/// one, so the clock runs across them).
pub struct Checkpoints<'a> {
    /// Time between snapshots; `None`: none is taken.
    pub every: Option<Duration>,
    /// When the last one was taken (or the work began).
    pub since: Instant,
    /// A snapshot to continue from: its header, already checked against the
    /// integration's (`Header::continues`), and the rest of its bytes.
    pub resume: Option<(Header, &'a mut dyn Read)>,
    /// Keeps a snapshot durably: writes it with the given contents.
    pub save: &'a mut dyn FnMut(Contents) -> io::Result<()>,
    /// Snapshots taken.
    pub taken: usize,
    /// Set from another thread to stop the integration (Ctrl-C in Python):
    /// the backends stop where they would take a snapshot and return
    /// `GpuError::Stopped`.
    pub stop: Option<&'a AtomicBool>,
}

impl Checkpoints<'_> {
    /// When the next snapshot is due, if ever.
    pub fn deadline(&self) -> Option<Instant> {
        self.every.and_then(|e| self.since.checked_add(e))
    }

    pub fn due(&self) -> bool {
        self.deadline().is_some_and(|d| Instant::now() >= d)
    }

    /// Whether the integration was asked to stop.
    pub fn stopped(&self) -> bool {
        self.stop.is_some_and(|s| s.load(Ordering::Relaxed))
    }

    /// Saves a snapshot: `header`, the observations so far, then the
    /// backend's `body`.
    pub fn take<R: Real>(
        &mut self,
        header: &Header,
        obs: &Observations<R>,
        body: Contents,
    ) -> io::Result<()> {
        (self.save)(&|w| {
            header.write(w)?;
            write_observations(w, obs)?;
            body(w)
        })?;
        self.since = Instant::now();
        self.taken += 1;
        Ok(())
    }

    /// The snapshot to continue from, if any: its observations are read into
    /// `obs`; returns its header and the reader at the backend's body.
    pub fn restore<R: Real>(
        &mut self,
        obs: &mut Observations<R>,
    ) -> io::Result<Option<(Header, &mut dyn Read)>> {
        let Some((header, r)) = self.resume.take() else {
            return Ok(None);
        };
        read_observations(r, obs)?;
        Ok(Some((header, r)))
    }
}
