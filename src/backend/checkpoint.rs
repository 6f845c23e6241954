//! Mid-run checkpoints (`--checkpoint-every`): how often a backend takes a
//! snapshot of an integration (`plan/snapshot.rs`), where it hands it, and
//! the snapshot an integration continues from. The backends pause where
//! their state is whole (the CPU between steps of its blocks, the GPU
//! between windows), so a snapshot is exactly what continuing needs.

use std::io::{self, Read, Write};
use std::time::{Duration, Instant};

use super::gpu::GpuError;
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
}

impl Checkpoints<'_> {
    /// When the next snapshot is due, if ever.
    pub fn deadline(&self) -> Option<Instant> {
        self.every.and_then(|e| self.since.checked_add(e))
    }

    pub fn due(&self) -> bool {
        self.deadline().is_some_and(|d| Instant::now() >= d)
    }

    /// Saves a snapshot: `header`, the observations so far, then the
    /// backend's `body`.
    pub fn take<R: Real>(
        &mut self,
        header: &Header,
        obs: &Observations<R>,
        body: Contents,
    ) -> Result<(), GpuError> {
        (self.save)(&|w| {
            header.write(w)?;
            write_observations(w, obs)?;
            body(w)
        })
        .map_err(|e| GpuError::Checkpoint(e.to_string()))?;
        self.since = Instant::now();
        self.taken += 1;
        Ok(())
    }

    /// The snapshot to continue from, if any: its observations are read into
    /// `obs`; returns its header and the reader at the backend's body.
    pub fn restore<R: Real>(
        &mut self,
        obs: &mut Observations<R>,
    ) -> Result<Option<(Header, &mut dyn Read)>, GpuError> {
        let Some((header, r)) = self.resume.take() else {
            return Ok(None);
        };
        read_observations(r, obs).map_err(unreadable)?;
        Ok(Some((header, r)))
    }
}

/// A snapshot's body that cannot be read back.
pub fn unreadable(e: io::Error) -> GpuError {
    GpuError::Checkpoint(format!("reading the snapshot: {e}"))
}
