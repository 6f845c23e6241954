//! The output directory of a run or a report, replaced only when that loses
//! nothing.
//!
//! 1. [`claim`] decides, before any work, whether `DIR` may be written: it
//!    refuses a file, a symbolic link, the working directory or one of its
//!    ancestors, and a folder holding a file to keep (the scene); it replaces
//!    an existing folder only when it is empty or a complete reeb output
//!    holding nothing but the files its `summary.json` lists, unless forced.
//! 2. The work is written into `DIR.partial`, owned through a lock on that
//!    folder (`flock`, released by the kernel when the process ends, however
//!    it ends): a live owner is refused, a stale partial is reported and reused.
//! 3. [`Claim::commit`] fsyncs every file and the folder, then swaps it in
//!    atomically (`renameat2(RENAME_EXCHANGE)` on Linux: never a moment with
//!    neither) and removes the old folder: the files its summary listed, or
//!    everything when forced.
//!
//! A claim dropped without a commit (the work failed) removes its partial.

use std::collections::BTreeSet;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use crate::plan::size::{bytes, RECORD_LESS};

/// The file in `DIR.partial` that names its owner (removed before commit).
const OWNER_FILE: &str = ".reeb-owner";

/// What an existing `DIR` is, and so what replacing it removes.
#[derive(Debug, Clone, PartialEq)]
enum Existing {
    /// No `DIR` yet.
    Nothing,
    /// An empty folder.
    Empty,
    /// A complete reeb output: these names, `summary.json` included.
    ReebOutput(BTreeSet<String>),
    /// Anything else, replaced because `--force` was given.
    Forced,
}

/// `DIR.partial`, locked for this process, to be swapped into `DIR`.
pub struct Claim {
    out: PathBuf,
    partial: PathBuf,
    lock: Option<File>,
    force: bool,
    /// Committed, or kept for a later run: not removed when dropped.
    kept: bool,
}

/// How a run takes `DIR.partial`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Alone, from nothing: a stale partial is emptied.
    Fresh,
    /// Alone, continuing a stale partial's work (`--resume`, `reeb merge`).
    Resume,
    /// Beside other shards of the same run, each holding a shared lock; a
    /// run alone (exclusive) waits for none of them and is refused.
    Shared,
}

/// Claims `out` for writing: every refusal here comes before any work.
/// `keep` are files that must survive (the scene file); `force` allows
/// replacing a folder that holds other files.
pub fn claim(out: &Path, keep: &[&Path], force: bool) -> Result<Claim> {
    claim_as(out, keep, force, Mode::Fresh)
}

/// [`claim`] in a [`Mode`].
pub fn claim_as(out: &Path, keep: &[&Path], force: bool, mode: Mode) -> Result<Claim> {
    let out = &lexical(out);
    let abs = absolute(out, true)?;
    refuse_protected(out, &abs, keep)?;
    classify(out, force)?;
    let partial = partial_path(&abs);
    let lock = lock_partial(&partial, mode)?;
    Ok(Claim {
        out: out.to_path_buf(),
        partial,
        lock: Some(lock),
        force,
        // What a resumed run or a shard finds is not its own to remove.
        kept: mode != Mode::Fresh,
    })
}

/// The refusals of [`claim`], without creating or changing anything (for
/// `reeb check`): `Ok` when a run could write `out`.
pub fn check(out: &Path, keep: &[&Path], force: bool) -> Result<()> {
    let out = &lexical(out);
    let abs = absolute(out, false)?;
    refuse_protected(out, &abs, keep)?;
    classify(out, force)?;
    let partial = partial_path(&abs);
    if std::fs::symlink_metadata(&partial).is_ok() {
        stale_partial(&partial)?;
    }
    Ok(())
}

/// `DIR.partial` of `out`, where a run in progress (or its shards) writes,
/// without creating or changing anything.
pub fn partial_of(out: &Path) -> Result<PathBuf> {
    Ok(partial_path(&absolute(&lexical(out), false)?))
}

impl Claim {
    /// Where the work is written: `DIR.partial`.
    pub fn dir(&self) -> &Path {
        &self.partial
    }

    /// `DIR`, where the work goes when committed.
    pub fn out(&self) -> &Path {
        &self.out
    }

    /// Refuses when the disk holding `DIR.partial` has less free space than
    /// `need` bytes.
    pub fn check_space(&self, need: u64) -> Result<()> {
        let Some(free) = free_space(&self.partial) else {
            return Ok(());
        };
        if need > free {
            bail!(
                "{}: the outputs need about {} on disk and {} is free there; free some space, choose another output folder, or {RECORD_LESS}",
                self.out.display(),
                bytes(need),
                bytes(free)
            );
        }
        Ok(())
    }

    /// Records this process as the partial's owner (a resumed run, once
    /// it is known to continue the run the partial holds).
    pub fn own(&self) -> Result<()> {
        write_owner(&self.partial)
    }

    /// Leaves the partial in place when the claim ends uncommitted (its
    /// finished chunks are kept for `--resume` or `reeb merge`).
    pub fn keep(&mut self) {
        self.kept = true;
    }

    /// Makes the partial durable and swaps it into `DIR`; returns `DIR`.
    pub fn commit(mut self) -> Result<PathBuf> {
        std::fs::remove_file(self.partial.join(OWNER_FILE))
            .with_context(|| format!("removing {}", self.partial.join(OWNER_FILE).display()))?;
        sync_tree(&self.partial)?;
        // The folder may have changed during the run: check it again.
        let now = classify(&self.out, self.force).with_context(|| {
            format!(
                "{} changed during the run; the finished results are kept in {}",
                self.out.display(),
                self.partial.display()
            )
        });
        let now = match now {
            Ok(now) => now,
            Err(e) => {
                self.kept = true; // keep the results
                return Err(e);
            }
        };
        swap_in(&self.partial, &self.out, &now)?;
        self.kept = true;
        self.lock = None;
        sync_dir(parent_of(&self.out))?;
        if now != Existing::Nothing {
            remove_old(&self.partial, &now);
        }
        Ok(self.out.clone())
    }
}

impl Drop for Claim {
    fn drop(&mut self) {
        if !self.kept {
            // Ours, locked: a failed run leaves nothing that looks complete.
            let _ = std::fs::remove_dir_all(&self.partial);
        }
    }
}

/// `out` without `.` components and trailing slashes (`./x/.` is `./x`):
/// the folder the user means, which a rename can target.
fn lexical(out: &Path) -> PathBuf {
    out.components().collect()
}

/// `path` made absolute through the existing folders (created if missing
/// and `create`, so that an unwritable location fails before any work).
fn absolute(out: &Path, create: bool) -> Result<PathBuf> {
    if out.as_os_str().is_empty() {
        bail!("the output folder is empty: name a directory (--out)");
    }
    if let Ok(meta) = std::fs::symlink_metadata(out) {
        if meta.file_type().is_symlink() {
            bail!(
                "{} is a symbolic link; reeb replaces only real directories: pass the directory it points to, or another output folder",
                out.display()
            );
        }
        if !meta.is_dir() {
            bail!(
                "{} is a file, not a directory; reeb writes a directory of results: choose another output folder",
                out.display()
            );
        }
        return out
            .canonicalize()
            .with_context(|| format!("resolving {}", out.display()));
    }
    let Some(name) = out.file_name() else {
        bail!("{}: not a directory name", out.display());
    };
    let parent = parent_of(out);
    if create {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    } else if !parent.exists() {
        // Nothing there yet: what `create` would make is new, hence safe.
        let base = std::env::current_dir().context("reading the working directory")?;
        return Ok(base.join(out));
    }
    let parent = parent
        .canonicalize()
        .with_context(|| format!("resolving {}", parent.display()))?;
    Ok(parent.join(name))
}

/// The folder holding `path` (`.` for a bare name).
fn parent_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Refuses the working directory, its ancestors, and folders holding `keep`.
fn refuse_protected(out: &Path, abs: &Path, keep: &[&Path]) -> Result<()> {
    if let Ok(cwd) = std::env::current_dir().and_then(|d| d.canonicalize()) {
        if cwd.starts_with(abs) {
            let what = if cwd == abs {
                "the working directory".to_string()
            } else {
                format!("an ancestor of the working directory {}", cwd.display())
            };
            bail!(
                "the output folder {} is {what}; reeb replaces its output directory as a whole: choose a new folder, e.g. --out {}",
                out.display(),
                Path::new("runs").join("NAME").display()
            );
        }
    }
    for file in keep {
        let Ok(file) = file.canonicalize() else {
            continue;
        };
        if file.starts_with(abs) {
            bail!(
                "the output folder {} holds {}, which replacing it would delete; choose another output folder",
                out.display(),
                file.display()
            );
        }
    }
    Ok(())
}

/// What `out` holds now, refusing what must not be replaced.
fn classify(out: &Path, force: bool) -> Result<Existing> {
    let meta = match std::fs::symlink_metadata(out) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Existing::Nothing),
        Err(e) => return Err(e).with_context(|| format!("reading {}", out.display())),
        Ok(m) => m,
    };
    if !meta.is_dir() || meta.file_type().is_symlink() {
        bail!(
            "{} is not a directory; choose another output folder",
            out.display()
        );
    }
    let names = entries(out)?;
    if names.is_empty() {
        return Ok(Existing::Empty);
    }
    let listed = listed_files(out);
    let extra: Vec<&String> = match &listed {
        Some(l) => names.iter().filter(|n| !l.contains(*n)).collect(),
        None => names.iter().collect(),
    };
    if extra.is_empty() {
        match (foreign_kind(out, &names), force) {
            (None, _) => return Ok(Existing::ReebOutput(names)),
            (Some(_), true) => return Ok(Existing::Forced),
            (Some(why), false) => bail!(
                "{}: {why}; reeb replaces only the files it wrote: move it away, or pass --force to replace the folder with all it holds",
                out.display()
            ),
        }
    }
    if force {
        return Ok(Existing::Forced);
    }
    let shown: Vec<&str> = extra.iter().take(5).map(|s| s.as_str()).collect();
    let more = if extra.len() > 5 {
        format!(" and {} more", extra.len() - 5)
    } else {
        String::new()
    };
    match listed {
        None => bail!(
            "{} exists and is not a reeb output (no readable summary.json); it holds {}{more}. Pass --force to replace it with all it holds, or choose another output folder",
            out.display(),
            shown.join(", ")
        ),
        Some(_) => bail!(
            "{} holds files that reeb did not write ({}{more}); pass --force to replace it with all it holds, or choose another output folder",
            out.display(),
            shown.join(", ")
        ),
    }
}

/// The first listed name of a reeb output that is no longer what reeb
/// wrote there: every one is a regular file but the Zarr store, a real
/// folder (a symbolic link, or a folder where a file was, may hold the
/// user's files, which replacing the output must not delete).
fn foreign_kind(dir: &Path, names: &BTreeSet<String>) -> Option<String> {
    names.iter().find_map(|n| {
        let meta = std::fs::symlink_metadata(dir.join(n)).ok()?;
        let kind = meta.file_type();
        let (want_dir, ok) = if n == crate::output::zarr::STORE {
            (true, kind.is_dir())
        } else {
            (false, kind.is_file())
        };
        let now = if kind.is_symlink() {
            "a symbolic link"
        } else if kind.is_dir() {
            "a folder"
        } else {
            "not a regular file"
        };
        let was = if want_dir { "a folder" } else { "a file" };
        (!ok).then(|| format!("{n} was {was} reeb wrote and is now {now}"))
    })
}

/// The names directly inside `dir`.
fn entries(dir: &Path) -> Result<BTreeSet<String>> {
    let mut names = BTreeSet::new();
    for e in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let e = e.with_context(|| format!("reading {}", dir.display()))?;
        names.insert(e.file_name().to_string_lossy().into_owned());
    }
    Ok(names)
}

/// The names a reeb `summary.json` in `dir` lists, itself included.
fn listed_files(dir: &Path) -> Option<BTreeSet<String>> {
    let text = std::fs::read_to_string(dir.join("summary.json")).ok()?;
    let summary: serde_json::Value = serde_json::from_str(&text).ok()?;
    summary.get("reeb_version")?;
    let mut names: BTreeSet<String> = summary
        .get("files")?
        .as_array()?
        .iter()
        .filter_map(|f| f.as_str())
        .filter(|f| !f.contains('/') && !f.is_empty())
        .map(str::to_string)
        .collect();
    names.insert("summary.json".into());
    Some(names)
}

/// `<DIR>.partial` beside `DIR`.
fn partial_path(abs: &Path) -> PathBuf {
    let mut name = abs.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    abs.with_file_name(name)
}

/// Creates or takes over `partial`, locked for this process.
fn lock_partial(partial: &Path, mode: Mode) -> Result<File> {
    // A fresh partial is built under a private name, locked, and only then
    // given its public name: another run never sees it unlocked.
    let mut tmp_name = partial.file_name().unwrap_or_default().to_os_string();
    tmp_name.push(format!(".{}.new", std::process::id()));
    let tmp = partial.with_file_name(tmp_name);
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir(&tmp).with_context(|| format!("creating {}", partial.display()))?;
    // A shard's lock is shared from the start: a shard starting beside it
    // never finds the folder locked exclusively.
    let lock = open_locked(&tmp, mode == Mode::Shared)?.context("a folder of our own is locked")?;
    write_owner(&tmp)?;
    match rename_no_replace(&tmp, partial) {
        Ok(()) => Ok(lock),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            drop(lock);
            let _ = std::fs::remove_dir_all(&tmp);
            match mode {
                Mode::Shared => join_shared(partial),
                _ => take_over(partial, mode == Mode::Fresh),
            }
        }
        Err(e) => {
            drop(lock);
            let _ = std::fs::remove_dir_all(&tmp);
            Err(e).with_context(|| format!("creating {}", partial.display()))
        }
    }
}

/// Takes over an existing `partial` whose owner is gone, emptied if
/// `empty`; refuses a live one.
fn take_over(partial: &Path, empty: bool) -> Result<File> {
    let (lock, owner) = stale_partial(partial)?;
    if !empty {
        // The owner's line stays the earlier run's until this one is
        // known to continue it (`Claim::own`): a refused resume leaves
        // the partial as it found it.
        return Ok(lock);
    }
    eprintln!(
        "warning: {} was left by a run that did not finish ({}); reusing it",
        partial.display(),
        owner.trim()
    );
    for name in entries(partial)? {
        let path = partial.join(&name);
        let removed = if path.is_dir() {
            std::fs::remove_dir_all(&path)
        } else {
            std::fs::remove_file(&path)
        };
        removed.with_context(|| format!("removing {}", path.display()))?;
    }
    write_owner(partial)?;
    Ok(lock)
}

/// Joins the shards writing an existing `partial` (a shared lock); refuses
/// one a run alone holds, and one reeb did not make.
fn join_shared(partial: &Path) -> Result<File> {
    must_be_folder(partial)?;
    let Some(f) = open_locked(partial, true)? else {
        bail!(
            "{} is being written by a reeb run that is not a shard ({}); wait for it to finish, or choose another output folder",
            partial.display(),
            std::fs::read_to_string(partial.join(OWNER_FILE)).unwrap_or_default().trim()
        );
    };
    if !partial.join(OWNER_FILE).exists() {
        return Err(not_reeb(partial));
    }
    Ok(f)
}

/// An existing `partial` that reeb left and whose owner is gone: its lock,
/// now ours, and its owner's line. Refuses anything else: not a folder, a
/// live owner, no owner file (not reeb's).
fn stale_partial(partial: &Path) -> Result<(File, String)> {
    must_be_folder(partial)?;
    let owner = std::fs::read_to_string(partial.join(OWNER_FILE)).ok();
    let Some(lock) = open_locked(partial, false)? else {
        bail!(
            "{} is being written by another reeb run ({}); wait for it to finish, or choose another output folder",
            partial.display(),
            owner.as_deref().map(str::trim).unwrap_or("owner unknown")
        );
    };
    let Some(owner) = owner else {
        return Err(match listed_files(partial) {
            Some(_) => left_output(partial),
            None => not_reeb(partial),
        });
    };
    Ok((lock, owner))
}

/// Refuses a `partial` that is not a folder.
fn must_be_folder(partial: &Path) -> Result<()> {
    if !std::fs::symlink_metadata(partial).is_ok_and(|m| m.is_dir()) {
        bail!(
            "{} exists and is not a folder reeb left; remove it or choose another output folder",
            partial.display()
        );
    }
    Ok(())
}

/// The refusal of a `partial` without reeb's owner file.
fn not_reeb(partial: &Path) -> anyhow::Error {
    anyhow::anyhow!(
        "{} exists but was not made by reeb (no {OWNER_FILE}); remove it or choose another output folder",
        partial.display()
    )
}

/// The refusal of a `partial` that holds a complete reeb output: the
/// previous output of `DIR`, which a failed removal left when a new one
/// replaced it ([`remove_old`]).
fn left_output(partial: &Path) -> anyhow::Error {
    anyhow::anyhow!(
        "{} holds an earlier reeb output that could not be removed when a newer one replaced it; remove it by hand (rm -r {}), or choose another output folder",
        partial.display(),
        partial.display()
    )
}

/// The folder opened and locked (`shared`: beside other shared holders;
/// else exclusively), or `None` if another process's lock excludes it.
fn open_locked(dir: &Path, shared: bool) -> Result<Option<File>> {
    let f = File::open(dir).with_context(|| format!("opening {}", dir.display()))?;
    let locked = if shared {
        f.try_lock_shared()
    } else {
        f.try_lock()
    };
    match locked {
        Ok(()) => Ok(Some(f)),
        Err(std::fs::TryLockError::WouldBlock) => Ok(None),
        Err(std::fs::TryLockError::Error(e)) => {
            Err(e).with_context(|| format!("locking {}", dir.display()))
        }
    }
}

/// Records who owns a partial, for the messages of other runs; doubles as
/// the probe that the location is writable.
fn write_owner(dir: &Path) -> Result<()> {
    let path = dir.join(OWNER_FILE);
    let text = format!(
        "pid {} on {}, started {}\n",
        std::process::id(),
        hostname(),
        humantime::format_rfc3339_seconds(std::time::SystemTime::now())
    );
    let mut f = File::create(&path).with_context(|| format!("writing {}", path.display()))?;
    f.write_all(text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))
}

/// This machine's host name.
pub fn hostname() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|s| s.trim().to_string())
        .ok()
        .filter(|s| !s.is_empty())
        .or_else(|| std::env::var("HOSTNAME").ok())
        .unwrap_or_else(|| "unknown".into())
}

/// fsyncs every file in `dir`, then `dir` itself.
pub fn sync_tree(dir: &Path) -> Result<()> {
    for name in entries(dir)? {
        let path = dir.join(name);
        if path.is_file() {
            File::open(&path)
                .and_then(|f| f.sync_all())
                .with_context(|| format!("syncing {}", path.display()))?;
        }
    }
    sync_dir(dir)
}

fn sync_dir(dir: &Path) -> Result<()> {
    File::open(dir)
        .and_then(|f| f.sync_all())
        .with_context(|| format!("syncing {}", dir.display()))
}

/// Moves `partial` to `out`; an existing `out` ends up at `partial`.
fn swap_in(partial: &Path, out: &Path, existing: &Existing) -> Result<()> {
    let moved = if *existing == Existing::Nothing {
        rename_no_replace(partial, out)
    } else {
        exchange(partial, out)
    };
    moved.with_context(|| format!("moving {} to {}", partial.display(), out.display()))
}

/// Removes the old output (now at `old`): what its summary listed, or all
/// of it when forced. Anything left is reported, never deleted.
fn remove_old(old: &Path, existing: &Existing) {
    let result = match existing {
        Existing::Forced => std::fs::remove_dir_all(old),
        // A listed folder is reeb's too (the Zarr store `run.zarr`).
        // `classify` checked their kinds: files, and the Zarr store.
        Existing::ReebOutput(names) => names
            .iter()
            .try_for_each(|n| match old.join(n) {
                p if n == crate::output::zarr::STORE => std::fs::remove_dir_all(p),
                p => std::fs::remove_file(p),
            })
            .and_then(|()| std::fs::remove_dir(old)),
        _ => std::fs::remove_dir(old),
    };
    if let Err(e) = result {
        eprintln!(
            "warning: the previous output, now in {}, was not removed ({e}); remove it by hand",
            old.display()
        );
    }
}

/// `rename` that fails with `AlreadyExists` instead of replacing an empty
/// directory at `to`.
fn rename_no_replace(from: &Path, to: &Path) -> std::io::Result<()> {
    #[cfg(target_os = "linux")]
    {
        match renameat2(from, to, libc::RENAME_NOREPLACE) {
            Err(e) if unsupported(&e) => {}
            other => return other,
        }
    }
    if std::fs::symlink_metadata(to).is_ok() {
        return Err(std::io::ErrorKind::AlreadyExists.into());
    }
    std::fs::rename(from, to)
}

/// Swaps `a` and `b` atomically where the filesystem can; elsewhere moves
/// `b` aside, `a` in, and the old `b` to `a` (the data is never lost).
fn exchange(a: &Path, b: &Path) -> std::io::Result<()> {
    #[cfg(target_os = "linux")]
    {
        match renameat2(a, b, libc::RENAME_EXCHANGE) {
            Err(e) if unsupported(&e) => {}
            other => return other,
        }
    }
    let mut aside = a.as_os_str().to_os_string();
    aside.push(".old");
    let aside = PathBuf::from(aside);
    std::fs::rename(b, &aside)?;
    std::fs::rename(a, b)?;
    std::fs::rename(&aside, a)
}

#[cfg(target_os = "linux")]
fn unsupported(e: &std::io::Error) -> bool {
    matches!(
        e.raw_os_error(),
        Some(libc::EINVAL) | Some(libc::ENOSYS) | Some(libc::EOPNOTSUPP)
    )
}

#[cfg(target_os = "linux")]
fn renameat2(from: &Path, to: &Path, flags: libc::c_uint) -> std::io::Result<()> {
    use std::ffi::CString;
    use std::os::unix::ffi::OsStrExt;
    let c = |p: &Path| {
        CString::new(p.as_os_str().as_bytes())
            .map_err(|_| std::io::Error::from(std::io::ErrorKind::InvalidInput))
    };
    let (from, to) = (c(from)?, c(to)?);
    // SAFETY: two valid NUL-terminated paths, relative to the working directory.
    let rc = unsafe {
        libc::renameat2(
            libc::AT_FDCWD,
            from.as_ptr(),
            libc::AT_FDCWD,
            to.as_ptr(),
            flags,
        )
    };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// The disk space the files under `dir` take (their allocated blocks:
/// the unwritten parts of a run's sparse arrays take none); 0 if absent.
pub fn disk_usage(dir: &Path) -> u64 {
    use std::os::unix::fs::MetadataExt;
    let Ok(list) = std::fs::read_dir(dir) else {
        return 0;
    };
    list.flatten()
        .map(|e| match e.metadata() {
            Ok(m) if m.is_dir() => disk_usage(&e.path()),
            Ok(m) => m.blocks() * 512,
            Err(_) => 0,
        })
        .sum()
}

/// Free bytes for an unprivileged user on the filesystem of `path`.
/// Free bytes on the disk that holds `path` (or would: its nearest
/// existing ancestor); `None` where unknown.
pub fn free_space_for(path: &Path) -> Option<u64> {
    let abs = std::path::absolute(path).ok()?;
    abs.ancestors().find(|a| a.exists()).and_then(free_space)
}

fn free_space(path: &Path) -> Option<u64> {
    #[cfg(unix)]
    {
        use std::ffi::CString;
        use std::os::unix::ffi::OsStrExt;
        let c = CString::new(path.as_os_str().as_bytes()).ok()?;
        // SAFETY: a valid path and a zeroed out-struct the call fills.
        let mut s: libc::statvfs = unsafe { std::mem::zeroed() };
        // A filesystem without blocks (/proc) has no free space to tell.
        if unsafe { libc::statvfs(c.as_ptr(), &mut s) } != 0 || s.f_blocks == 0 {
            return None;
        }
        Some((s.f_bavail as u64).saturating_mul(s.f_frsize as u64))
    }
    #[cfg(not(unix))]
    {
        let _ = path;
        None
    }
}
