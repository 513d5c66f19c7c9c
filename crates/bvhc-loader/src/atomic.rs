//! Atomic replacement of an output file, and the temporary files it uses.
//!
//! Bytes go to a temporary file `.bvhc-<pid>-<random>.tmp` in the output's directory, are flushed to disk, and
//! the file is renamed over the output. So a reader (or a memory map, see `MappedBvh`) sees either the
//! old file or the new one, never a mix; a failed or interrupted write leaves the old file untouched.
//!
//! Rules: the output, when it exists, must be a regular file (a FIFO, device or directory is refused, never
//! opened); a new file gets mode `0666` less the process's umask, as other build tools' outputs do; the
//! process id in the name lets a later run sweep the temporary files of a killed run ([`sweep_stale`]) and a
//! signal handler remove this run's own ([`remove_own_temporary_files`]).

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::Error;
use crate::uncached::UncachedWriter;

/// The prefix of every temporary file name.
pub const TEMPORARY_PREFIX: &str = ".bvhc-";
/// The suffix of every temporary file name.
pub const TEMPORARY_SUFFIX: &str = ".tmp";

/// Writes `bytes` to `path` atomically (see the module doc). A failure leaves any previous file at `path`
/// untouched and no partial file behind.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    let mut output = AtomicOutput::create(path)?;
    output.file().write_all(bytes).map_err(|source| Error::Io { path: path.to_path_buf(), source })?;
    output.commit()
}

/// An output being written: a temporary file in the output's directory (named as the module doc says) that
/// replaces the output on [`AtomicOutput::commit`], and is removed when dropped before (an error, a failed
/// check), so nothing half-written is ever left at the output path.
#[derive(Debug)]
pub struct AtomicOutput {
    path: PathBuf,
    temporary: tempfile::NamedTempFile,
}

impl AtomicOutput {
    /// Creates the temporary file for `path` (refusing a `path` that exists and is not a regular file, and
    /// sweeping stale temporary files of killed runs first).
    pub fn create(path: &Path) -> Result<AtomicOutput, Error> {
        let io = |source| Error::Io { path: path.to_path_buf(), source };
        check_replaceable(path)?;
        let directory = directory_of(path);
        sweep_stale(directory);
        let prefix = format!("{TEMPORARY_PREFIX}{}-", std::process::id());
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(TEMPORARY_SUFFIX);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            // The kernel applies the umask to the mode given at creation.
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        let temporary = builder.tempfile_in(directory).map_err(io)?;
        Ok(AtomicOutput { path: path.to_path_buf(), temporary })
    }

    /// The temporary file, to write to (and to read back from its path).
    pub fn file(&mut self) -> &mut std::fs::File {
        self.temporary.as_file_mut()
    }

    /// A sink for the temporary file's bytes that bypasses the page cache where it can (see
    /// [`UncachedWriter`]); call its `finish` before reading the file back or committing.
    pub fn uncached_writer(&mut self) -> UncachedWriter<'_> {
        let path = self.temporary.path().to_path_buf();
        UncachedWriter::new(self.temporary.as_file_mut(), &path)
    }

    /// The temporary file's path.
    pub fn temporary_path(&self) -> &Path {
        self.temporary.path()
    }

    /// Flushes the temporary file to disk and renames it over the output.
    pub fn commit(self) -> Result<(), Error> {
        let io = |source| Error::Io { path: self.path.clone(), source };
        self.temporary.as_file().sync_all().map_err(io)?;
        self.temporary.persist(&self.path).map_err(|e| io(e.error))?;
        Ok(())
    }
}

/// Refuses an existing `path` that is not a regular file (FIFO, socket, device, directory).
pub fn check_replaceable(path: &Path) -> Result<(), Error> {
    match std::fs::metadata(path) {
        Ok(metadata) if !metadata.is_file() => Err(Error::Io {
            path: path.to_path_buf(),
            source: std::io::Error::other(
                "the output exists and is not a regular file (a directory, FIFO or device); refusing to replace it",
            ),
        }),
        _ => Ok(()),
    }
}

/// The directory a file is written in (`.` for a bare name).
pub fn directory_of(path: &Path) -> &Path {
    match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    }
}

/// The process id in a temporary file's name, if `name` is one.
fn temporary_owner(name: &str) -> Option<u32> {
    let rest = name.strip_prefix(TEMPORARY_PREFIX)?.strip_suffix(TEMPORARY_SUFFIX)?;
    rest.split_once('-')?.0.parse().ok()
}

/// Our temporary files in `directory` whose owner `is_stale` says is gone.
fn temporary_files(directory: &Path, is_stale: impl Fn(u32) -> bool) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(directory) else { return Vec::new() };
    entries
        .flatten()
        .filter(|entry| entry.file_type().is_ok_and(|t| t.is_file()))
        .filter(|entry| entry.file_name().to_str().and_then(temporary_owner).is_some_and(&is_stale))
        .map(|entry| entry.path())
        .collect()
}

/// Removes the temporary files in `directory` left by runs that were killed (their process no longer exists;
/// where that cannot be told, files older than a day). Errors are ignored: sweeping is a courtesy.
pub fn sweep_stale(directory: &Path) {
    let own = std::process::id();
    for path in temporary_files(directory, |pid| pid != own) {
        let stale = match owner_alive(&path) {
            Some(alive) => !alive,
            None => std::fs::metadata(&path)
                .and_then(|m| m.modified())
                .is_ok_and(|t| t.elapsed().is_ok_and(|age| age.as_secs() > 24 * 3600)),
        };
        if stale {
            let _ = std::fs::remove_file(path);
        }
    }
}

/// Removes this process's own temporary files in `directory` (for a signal handler: the process is about to
/// exit, so no write of its own is still wanted). Returns how many were removed.
pub fn remove_own_temporary_files(directory: &Path) -> usize {
    let own = std::process::id();
    temporary_files(directory, |pid| pid == own).into_iter().filter(|p| std::fs::remove_file(p).is_ok()).count()
}

/// Whether the process named in a temporary file's name is alive: `Some` on Linux (`/proc/<pid>` exists),
/// `None` where that cannot be told.
fn owner_alive(path: &Path) -> Option<bool> {
    let pid = path.file_name()?.to_str().and_then(temporary_owner)?;
    cfg!(target_os = "linux").then(|| Path::new(&format!("/proc/{pid}")).exists())
}
