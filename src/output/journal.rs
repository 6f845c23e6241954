//! What a streamed run keeps in `DIR.partial` besides its arrays, so that a
//! resumed run, a shard or `reeb merge` knows it continues the same run:
//! the run's record (`.reeb-run.json`: the scene's text, precision,
//! backend, chunks) and one marker per finished chunk (`.reeb-chunks/K`),
//! written after the chunk's rows are durable. A chunk without its marker
//! is integrated again, from its checkpoint (`.reeb-chunks/K.state`, the
//! integrator's state inside the chunk, `--checkpoint-every`) if it has
//! one, so a kill at any moment loses at most the work since then.

use std::io::{BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

use crate::backend::checkpoint::Contents;
use crate::backend::phases::Phases;
use crate::output::chunks::Chunks;

pub const RECORD_FILE: &str = ".reeb-run.json";
pub const CHUNKS_DIR: &str = ".reeb-chunks";

/// What makes two runs the same run: their outputs agree bit for bit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Record {
    pub reeb_version: String,
    /// The scene file as given, and its text.
    pub scene_path: String,
    pub scene_text: String,
    /// `(values, steps)` if the run is the scene's `--preview`.
    pub preview: Option<(usize, u64)>,
    pub precision: String,
    pub backend: String,
    /// The adapter's description (not compared: a shard may run on any
    /// GPU of its kind).
    pub adapter: String,
    /// Why this backend (`--backend auto`'s notice), if it was chosen.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub choice: Option<String>,
    pub format: String,
    pub chunks: Chunks,
}

/// A finished chunk: what the summary adds up, and what it wrote.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Done {
    /// Trajectories that finished with a finite state.
    pub ok: u64,
    pub traj_steps: u64,
    pub seconds: f64,
    /// How `seconds` was measured (GPU timestamps or the wall clock).
    pub timing: String,
    /// The seconds of the chunk's phases (integration: `seconds`; all 0 in
    /// a marker written before reeb timed them).
    #[serde(default)]
    pub phases: Phases,
    /// The chunk's bytes in every array, checked before the chunk is
    /// trusted (empty in a marker of a reeb before 0.3: not trusted).
    #[serde(default)]
    pub arrays: Vec<Written>,
    /// The CPU kernels' instruction set, if the CPU integrated the chunk.
    #[serde(default)]
    pub cpu_isa: Option<String>,
    /// The GPU device that integrated the chunk (`#1 adapter 0: NAME` when
    /// a run spread over several), if a GPU did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device: Option<String>,
}

/// What a chunk wrote into one array: its size and CRC-32.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Written {
    pub file: String,
    pub bytes: u64,
    pub crc32: u32,
}

impl Written {
    pub fn of(file: &str, bytes: &[u8]) -> Written {
        Written {
            file: file.into(),
            bytes: bytes.len() as u64,
            crc32: crc32fast::hash(bytes),
        }
    }

    /// Why `found` (the array's bytes read back) is not what was written.
    pub fn differs(&self, found: &[u8]) -> Option<String> {
        if found.len() as u64 != self.bytes {
            return Some(format!(
                "{} holds {} of its {} bytes",
                self.file,
                found.len(),
                self.bytes
            ));
        }
        (crc32fast::hash(found) != self.crc32)
            .then(|| format!("{}'s bytes differ from those written", self.file))
    }
}

impl Record {
    /// Reads the record of `dir`, if it has one.
    pub fn read(dir: &Path) -> Result<Option<Record>> {
        let path = dir.join(RECORD_FILE);
        match std::fs::read_to_string(&path) {
            Ok(text) => serde_json::from_str(&text).map(Some).map_err(|e| {
                anyhow::anyhow!(
                    "{} is not the record of a reeb run ({e}): it was damaged or replaced; run the scene again without --resume to start over (its chunks are then integrated again)",
                    path.display()
                )
            }),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(e).with_context(|| format!("reading {}", path.display())),
        }
    }

    /// The record of `dir`: the one there, or this one written if there is
    /// none (then `true`). Shards starting together agree on the first one
    /// written (a hard link creates it or fails, atomically).
    pub fn establish(&self, dir: &Path) -> Result<(Record, bool)> {
        std::fs::create_dir_all(dir.join(CHUNKS_DIR))
            .with_context(|| format!("creating {}", dir.join(CHUNKS_DIR).display()))?;
        let path = dir.join(RECORD_FILE);
        let text = serde_json::to_string_pretty(self)?;
        let tmp = write_temporary(&path, &|w| w.write_all(text.as_bytes()))?;
        let linked = std::fs::hard_link(&tmp, &path);
        let _ = std::fs::remove_file(&tmp);
        match linked {
            Ok(()) => Ok((self.clone(), true)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                let old = Record::read(dir)?;
                Ok((
                    old.with_context(|| format!("reading {}", path.display()))?,
                    false,
                ))
            }
            Err(e) => Err(e).with_context(|| format!("writing {}", path.display())),
        }
    }

    /// Refuses to continue `old` as `self`, saying what changed.
    pub fn check_same(&self, old: &Record, dir: &Path, advice: &str) -> Result<()> {
        let mut changes = vec![];
        for (what, a, b) in [
            ("precision", &old.precision, &self.precision),
            ("backend", &old.backend, &self.backend),
            ("format", &old.format, &self.format),
        ] {
            if a != b {
                changes.push(format!("{what} {a} → {b}"));
            }
        }
        if old.preview != self.preview {
            let show = |p: Option<(usize, u64)>| {
                if p.is_some() {
                    "a preview"
                } else {
                    "the whole scene"
                }
            };
            changes.push(format!("{} → {}", show(old.preview), show(self.preview)));
        }
        if old.chunks != self.chunks {
            changes.push(format!(
                "chunks of {} → {} trajectories",
                old.chunks.largest(),
                self.chunks.largest()
            ));
        }
        if let Some(line) = first_difference(&old.scene_text, &self.scene_text) {
            changes.push(line);
        }
        if changes.is_empty() {
            return Ok(());
        }
        bail!(
            "{} holds part of a different run: {}; {advice}",
            dir.display(),
            changes.join("; ")
        )
    }
}

/// The first line where two scene texts differ, as the user reads it.
fn first_difference(old: &str, new: &str) -> Option<String> {
    let (a, b): (Vec<&str>, Vec<&str>) = (old.lines().collect(), new.lines().collect());
    let n = a.len().max(b.len());
    (0..n)
        .find(|k| a.get(*k).map(|s| s.trim()) != b.get(*k).map(|s| s.trim()))
        .map(|k| {
            let show =
                |s: Option<&&str>| s.map_or("(nothing)".to_string(), |s| format!("`{}`", s.trim()));
            format!(
                "the scene's line {} was {} and is now {}",
                k + 1,
                show(a.get(k)),
                show(b.get(k))
            )
        })
}

fn marker(dir: &Path, k: usize) -> PathBuf {
    dir.join(CHUNKS_DIR).join(format!("{k}.json"))
}

/// Marks chunk `k` of `dir` finished (after its rows are durable).
pub fn mark_done(dir: &Path, k: usize, done: &Done) -> Result<()> {
    let text = serde_json::to_string(done)?;
    write_atomic(&marker(dir, k), text.as_bytes())
}

/// The finished chunk `k` of `dir`, if it is (its marker reads as one).
pub fn done(dir: &Path, k: usize) -> Option<Done> {
    let text = std::fs::read_to_string(marker(dir, k)).ok()?;
    serde_json::from_str(&text).ok()
}

/// Takes back chunk `k`'s marker: its data is to be integrated again.
pub fn unmark(dir: &Path, k: usize) -> Result<()> {
    let path = marker(dir, k);
    match std::fs::remove_file(&path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            Err(e).with_context(|| format!("removing {}", path.display()))
        }
        _ => Ok(()),
    }
}

fn state(dir: &Path, k: usize) -> PathBuf {
    dir.join(CHUNKS_DIR).join(format!("{k}.state"))
}

/// The end of a checkpoint file: its length and CRC-32 before this
/// trailer, then this tag. A file that does not end so (cut short by a
/// full disk, damaged) is not continued.
const STATE_TAG: &[u8; 8] = b"reeb-cp1";
const TRAILER: u64 = 8 + 4 + 8;

/// A writer that counts and checksums what passes through.
struct Summed<'w> {
    inner: &'w mut dyn Write,
    crc: crc32fast::Hasher,
    len: u64,
}

impl Write for Summed<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.crc.update(&buf[..n]);
        self.len += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// Replaces chunk `k`'s checkpoint (the integrator's state inside the
/// chunk) with what `write` writes and its trailer, durably and
/// atomically: a kill while writing leaves the previous one.
pub fn save_state(dir: &Path, k: usize, write: Contents) -> std::io::Result<()> {
    let path = state(dir, k);
    let tmp = write_temporary(&path, &|w| {
        let mut summed = Summed {
            inner: w,
            crc: crc32fast::Hasher::new(),
            len: 0,
        };
        write(&mut summed)?;
        let (len, crc) = (summed.len, summed.crc.finalize());
        w.write_all(&len.to_le_bytes())?;
        w.write_all(&crc.to_le_bytes())?;
        w.write_all(STATE_TAG)
    })?;
    std::fs::rename(&tmp, &path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        std::io::Error::new(e.kind(), format!("writing {}: {e}", path.display()))
    })
}

/// Chunk `k`'s checkpoint, if it has one that is whole: one that is not
/// (cut short, damaged, unreadable) is set aside with a warning, and the
/// chunk starts over.
pub fn open_state(dir: &Path, k: usize) -> Result<Option<BufReader<std::fs::File>>> {
    let path = state(dir, k);
    let f = match std::fs::File::open(&path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
    };
    match whole(&f) {
        Ok(()) => {
            let mut f = f;
            std::io::Seek::rewind(&mut f).with_context(|| format!("reading {}", path.display()))?;
            Ok(Some(BufReader::with_capacity(1 << 20, f)))
        }
        Err(why) => {
            eprintln!(
                "warning: chunk {k}'s checkpoint {} cannot be continued ({why}); it is discarded and the chunk starts over",
                path.display()
            );
            drop(f);
            remove_state(dir, k)?;
            Ok(None)
        }
    }
}

/// Whether a checkpoint file ends in its trailer and its bytes before it
/// have the length and checksum the trailer records.
fn whole(f: &std::fs::File) -> std::result::Result<(), String> {
    use std::io::Read;
    use std::os::unix::fs::FileExt;
    let size = f.metadata().map_err(|e| e.to_string())?.len();
    let mut trailer = [0u8; TRAILER as usize];
    if size < TRAILER || f.read_exact_at(&mut trailer, size - TRAILER).is_err() {
        return Err(format!("{size} bytes: shorter than its trailer"));
    }
    let len = u64::from_le_bytes(trailer[..8].try_into().expect("8 bytes"));
    let crc = u32::from_le_bytes(trailer[8..12].try_into().expect("4 bytes"));
    if &trailer[12..] != STATE_TAG || len != size - TRAILER {
        return Err(format!("{size} bytes: cut short or not a reeb checkpoint"));
    }
    let mut hasher = crc32fast::Hasher::new();
    let mut r = BufReader::with_capacity(1 << 20, f).take(len);
    let mut buf = vec![0u8; 1 << 20];
    loop {
        match r.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => hasher.update(&buf[..n]),
            Err(e) => return Err(e.to_string()),
        }
    }
    if hasher.finalize() != crc {
        return Err("its bytes differ from those written".into());
    }
    Ok(())
}

/// Removes chunk `k`'s checkpoint (once the chunk is marked finished).
pub fn remove_state(dir: &Path, k: usize) -> Result<()> {
    let path = state(dir, k);
    match std::fs::remove_file(&path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            Err(e).with_context(|| format!("removing {}", path.display()))
        }
        _ => Ok(()),
    }
}

/// Writes `path` through a temporary file and a rename, durably.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = write_temporary(path, &|w| w.write_all(bytes))?;
    std::fs::rename(&tmp, path).with_context(|| format!("writing {}", path.display()))
}

/// Writes what `write` writes durably to a file of this process beside
/// `path` (removed again if that fails); returns its path.
fn write_temporary(path: &Path, write: Contents) -> std::io::Result<PathBuf> {
    let tmp = temporary_name(path);
    let written = || -> std::io::Result<()> {
        let f = std::fs::File::create(&tmp)?;
        let mut w = BufWriter::with_capacity(1 << 20, &f);
        write(&mut w)?;
        w.flush()?;
        drop(w);
        f.sync_all()
    };
    match written() {
        Ok(()) => Ok(tmp),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(std::io::Error::new(
                e.kind(),
                format!("writing {}: {e}", tmp.display()),
            ))
        }
    }
}

/// A file of this process beside `path`.
fn temporary_name(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".{}.tmp", std::process::id()));
    path.with_file_name(name)
}

/// Removes the journal from a finished run's folder (before it is
/// committed: a complete output holds only its listed files).
pub fn remove(dir: &Path) -> Result<()> {
    let chunks = dir.join(CHUNKS_DIR);
    if chunks.exists() {
        std::fs::remove_dir_all(&chunks)
            .with_context(|| format!("removing {}", chunks.display()))?;
    }
    let record = dir.join(RECORD_FILE);
    if record.exists() {
        std::fs::remove_file(&record).with_context(|| format!("removing {}", record.display()))?;
    }
    Ok(())
}
