//! A folder of files reeb writes beside a run (the batch scripts of `reeb
//! slurm`, `DIR.slurm/`), in which reeb replaces a file only while it is
//! still what reeb wrote: a ledger in the folder records the size and
//! CRC-32 of every version written. Nothing is followed through a symbolic
//! link, neither the folder nor a file in it.

use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

/// The ledger: one line `crc32 size name` per version reeb wrote.
const LEDGER: &str = ".reeb-written";

/// A folder reeb may write its files into (see the module documentation).
pub struct Owned {
    dir: PathBuf,
    /// `(crc32, size, name)` of every version reeb wrote here.
    written: BTreeSet<(u32, u64, String)>,
}

impl Owned {
    /// Takes `dir` (created if missing) for the files `names` and the
    /// folders `folders`; refuses a link, a file where a folder belongs, and
    /// any of `names` that is not a regular file reeb wrote.
    pub fn claim(dir: &Path, names: &[&str], folders: &[&str]) -> Result<Owned> {
        match std::fs::symlink_metadata(dir) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                std::fs::create_dir(dir).with_context(|| format!("creating {}", dir.display()))?
            }
            Err(e) => return Err(e).with_context(|| format!("reading {}", dir.display())),
            Ok(m) => real_folder(dir, &m)?,
        }
        let owned = Owned {
            dir: dir.to_path_buf(),
            written: read_ledger(dir)?,
        };
        for name in names {
            owned.replaceable(name)?;
        }
        for folder in folders {
            let path = dir.join(folder);
            match std::fs::symlink_metadata(&path) {
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => std::fs::create_dir(&path)
                    .with_context(|| format!("creating {}", path.display()))?,
                Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
                Ok(m) => real_folder(&path, &m)?,
            }
        }
        Ok(owned)
    }

    /// Refuses `name` unless it is absent or a regular file whose bytes are
    /// a version reeb wrote.
    fn replaceable(&self, name: &str) -> Result<()> {
        let path = self.dir.join(name);
        let meta = match std::fs::symlink_metadata(&path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
            Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
            Ok(m) => m,
        };
        if meta.file_type().is_symlink() {
            bail!(
                "{} is a symbolic link; reeb does not write through links: remove it, or choose another --out",
                path.display()
            );
        }
        if !meta.is_file() {
            bail!(
                "{} is not a regular file; move it away, or choose another --out",
                path.display()
            );
        }
        let bytes = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
        if !self.written.contains(&entry(name, &bytes)) {
            bail!(
                "{} was not written by reeb, or was changed since; reeb replaces only its own files: move it away (or rename it), or choose another --out",
                path.display()
            );
        }
        Ok(())
    }

    /// Writes `text` as `name` (one of the names claimed): recorded in the
    /// ledger first, then written under a private name and renamed over the
    /// old version, so a link put in its place meanwhile is replaced, never
    /// followed.
    pub fn write(&mut self, name: &str, text: &str) -> Result<PathBuf> {
        self.written.insert(entry(name, text.as_bytes()));
        let ledger: String = self
            .written
            .iter()
            .map(|(crc, size, n)| format!("{crc:08x} {size} {n}\n"))
            .collect();
        replace(&self.dir, LEDGER, ledger.as_bytes())?;
        replace(&self.dir, name, text.as_bytes())
    }
}

/// The ledger line of `bytes` written as `name`.
fn entry(name: &str, bytes: &[u8]) -> (u32, u64, String) {
    (crc32fast::hash(bytes), bytes.len() as u64, name.to_string())
}

/// Refuses a folder that is a link or not a folder.
fn real_folder(path: &Path, meta: &std::fs::Metadata) -> Result<()> {
    if meta.file_type().is_symlink() {
        bail!(
            "{} is a symbolic link; reeb writes only into a real folder of its own: remove the link, or choose another --out",
            path.display()
        );
    }
    if !meta.is_dir() {
        bail!(
            "{} exists and is not a folder; move it away, or choose another --out",
            path.display()
        );
    }
    Ok(())
}

/// The versions the ledger of `dir` records (none when it has no ledger;
/// a ledger that is a link or unreadable is refused).
fn read_ledger(dir: &Path) -> Result<BTreeSet<(u32, u64, String)>> {
    let path = dir.join(LEDGER);
    match std::fs::symlink_metadata(&path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(BTreeSet::new()),
        Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
        Ok(m) if !m.is_file() => bail!(
            "{} is not the file reeb keeps there; remove it, or choose another --out",
            path.display()
        ),
        Ok(_) => {}
    }
    let text =
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
    let line = |l: &str| {
        let mut w = l.splitn(3, ' ');
        let crc = u32::from_str_radix(w.next()?, 16).ok()?;
        let size = w.next()?.parse().ok()?;
        Some((crc, size, w.next()?.to_string()))
    };
    Ok(text.lines().filter_map(line).collect())
}

/// `bytes` as `dir/name`, written under a private name (created new, so
/// never through a link) and renamed into place.
fn replace(dir: &Path, name: &str, bytes: &[u8]) -> Result<PathBuf> {
    let path = dir.join(name);
    let tmp = dir.join(format!(".{name}.{}.new", std::process::id()));
    let _ = std::fs::remove_file(&tmp);
    let written = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .and_then(|mut f| f.write_all(bytes))
        .and_then(|()| std::fs::rename(&tmp, &path));
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(e).with_context(|| format!("writing {}", path.display()));
    }
    Ok(path)
}
