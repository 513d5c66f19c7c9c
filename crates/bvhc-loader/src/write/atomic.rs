//! Atomic replacement of an output file, and the temporary files it uses.
//!
//! Bytes go to a temporary file in the output's directory, are flushed to disk, and the file is renamed over the
//! output. So a reader (or a memory map, see `MappedBvh`) sees either the old file or the new one, never a mix;
//! a failed or interrupted write leaves the old file untouched.
//!
//! On Linux the temporary file is **unnamed** (`O_TMPFILE`): it has no name in the directory while it is
//! written, so a run killed by SIGKILL, a power cut or an out-of-memory kill leaves nothing behind; only at
//! commit is it linked under a temporary name (through `/proc/self/fd`) and at once renamed over the output.
//! Where the system or the file system has no unnamed files, the temporary file is named
//! `.bvhc-<pid>-<random>.tmp`: the process id lets a later run sweep the files of a killed run
//! ([`sweep_stale`]) and a signal handler remove this run's own ([`remove_own_temporary_files`]).
//!
//! Rules: the output, when it exists, must be a regular file (a FIFO, device or directory is refused, never
//! opened); a new file gets mode `0666` less the process's umask, as other build tools' outputs do.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::Error;
use crate::open::uncached::UncachedWriter;

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
    temporary: Temporary,
}

/// Where the bytes go before the commit.
#[derive(Debug)]
enum Temporary {
    /// An unnamed file in the output's directory (Linux `O_TMPFILE`), reachable by `/proc/self/fd/<fd>`.
    Unnamed { file: std::fs::File, proc_path: PathBuf },
    /// A named temporary file, removed when dropped.
    Named(tempfile::NamedTempFile),
}

impl AtomicOutput {
    /// Creates the temporary file for `path` (refusing a `path` that exists and is not a regular file, and
    /// sweeping stale temporary files of killed runs first).
    pub fn create(path: &Path) -> Result<AtomicOutput, Error> {
        let io = |source| Error::Io { path: path.to_path_buf(), source };
        check_replaceable(path)?;
        let directory = directory_of(path);
        folder_exists(directory).map_err(io)?;
        sweep_stale(directory);
        if let Some(temporary) = unnamed_in(directory) {
            return Ok(AtomicOutput { path: path.to_path_buf(), temporary });
        }
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
        Ok(AtomicOutput { path: path.to_path_buf(), temporary: Temporary::Named(temporary) })
    }

    /// Whether the temporary file is unnamed (nothing to clean up if the process is killed).
    pub fn is_unnamed(&self) -> bool {
        matches!(self.temporary, Temporary::Unnamed { .. })
    }

    /// The temporary file, to write to (and to read back from its path).
    pub fn file(&mut self) -> &mut std::fs::File {
        match &mut self.temporary {
            Temporary::Unnamed { file, .. } => file,
            Temporary::Named(named) => named.as_file_mut(),
        }
    }

    /// A sink for the temporary file's bytes that bypasses the page cache where it can (see
    /// [`UncachedWriter`]); call its `finish` before reading the file back or committing.
    pub fn uncached_writer(&mut self) -> UncachedWriter<'_> {
        let path = self.temporary_path().to_path_buf();
        UncachedWriter::new(self.file(), &path)
    }

    /// A path that opens the temporary file (for an unnamed one, its `/proc/self/fd` link).
    pub fn temporary_path(&self) -> &Path {
        match &self.temporary {
            Temporary::Unnamed { proc_path, .. } => proc_path,
            Temporary::Named(named) => named.path(),
        }
    }

    /// Flushes the temporary file to disk and renames it over the output.
    pub fn commit(self) -> Result<(), Error> {
        let io = |source| Error::Io { path: self.path.clone(), source };
        match self.temporary {
            Temporary::Named(named) => {
                named.as_file().sync_all().map_err(io)?;
                named.persist(&self.path).map_err(|e| io(e.error))?;
            }
            Temporary::Unnamed { file, proc_path } => {
                file.sync_all().map_err(io)?;
                let name = format!("{TEMPORARY_PREFIX}{}-{}{TEMPORARY_SUFFIX}", std::process::id(), unique_suffix());
                let linked = directory_of(&self.path).join(name);
                link_unnamed(&proc_path, &linked).map_err(io)?;
                if let Err(error) = std::fs::rename(&linked, &self.path) {
                    let _ = std::fs::remove_file(&linked);
                    return Err(io(error));
                }
            }
        }
        Ok(())
    }
}

/// `Ok` when `directory` (empty: the current one) is a folder; an error naming it otherwise, rather than the
/// temporary file that could not be made in it.
fn folder_exists(directory: &Path) -> std::io::Result<()> {
    let shown = if directory.as_os_str().is_empty() { Path::new(".") } else { directory };
    match std::fs::metadata(shown) {
        Ok(metadata) if metadata.is_dir() => Ok(()),
        Ok(_) => Err(std::io::Error::new(
            std::io::ErrorKind::NotADirectory,
            format!("the output's folder {} is not a folder", shown.display()),
        )),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!("the output's folder {} does not exist; create it first", shown.display()),
        )),
        Err(e) => Err(std::io::Error::new(e.kind(), format!("the output's folder {}: {e}", shown.display()))),
    }
}

/// An unnamed temporary file in `directory`, where the system and the file system have them (Linux 3.11+ on
/// ext4, xfs, btrfs, tmpfs, ...), with mode `0666` less the umask once linked.
#[cfg(target_os = "linux")]
fn unnamed_in(directory: &Path) -> Option<Temporary> {
    use std::os::unix::fs::OpenOptionsExt;
    use std::os::unix::io::AsRawFd;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(libc::O_TMPFILE)
        .mode(0o666)
        .open(directory)
        .ok()?;
    let proc_path = PathBuf::from(format!("/proc/self/fd/{}", file.as_raw_fd()));
    // Linking needs /proc; without it fall back to a named file now rather than fail at the commit.
    proc_path.exists().then_some(Temporary::Unnamed { file, proc_path })
}

#[cfg(not(target_os = "linux"))]
fn unnamed_in(_directory: &Path) -> Option<Temporary> {
    None
}

/// Gives the unnamed file behind `proc_path` the name `linked` (`linkat` following the `/proc` link, which
/// needs no privilege, unlike `AT_EMPTY_PATH`).
#[cfg(target_os = "linux")]
#[allow(unsafe_code)] // one FFI call, see the SAFETY note
fn link_unnamed(proc_path: &Path, linked: &Path) -> std::io::Result<()> {
    use std::ffi::CString;
    use std::os::unix::ffi::OsStrExt;
    let source = CString::new(proc_path.as_os_str().as_bytes()).map_err(std::io::Error::other)?;
    let target = CString::new(linked.as_os_str().as_bytes()).map_err(std::io::Error::other)?;
    // SAFETY: both arguments are NUL-terminated C strings that live until the call returns; `linkat` reads
    // them and keeps no pointer. AT_FDCWD makes relative paths relative to the working directory, as std does.
    let result = unsafe {
        libc::linkat(libc::AT_FDCWD, source.as_ptr(), libc::AT_FDCWD, target.as_ptr(), libc::AT_SYMLINK_FOLLOW)
    };
    if result == 0 { Ok(()) } else { Err(std::io::Error::last_os_error()) }
}

#[cfg(not(target_os = "linux"))]
fn link_unnamed(_proc_path: &Path, _linked: &Path) -> std::io::Result<()> {
    Err(std::io::Error::other("unnamed temporary files exist only on Linux"))
}

/// A name part that no other commit of this process uses at the same time: a counter and the clock's nanoseconds.
fn unique_suffix() -> String {
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let count = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.subsec_nanos());
    format!("{count}x{nanos:08x}")
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

#[cfg(test)]
mod tests {
    use super::*;

    fn names_in(directory: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(directory)
            .unwrap()
            .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn an_output_that_is_never_committed_leaves_nothing_even_without_its_destructor() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bvh");
        let mut output = AtomicOutput::create(&path).unwrap();
        output.file().write_all(b"half written").unwrap();
        let unnamed = output.is_unnamed();
        // SIGKILL runs no destructor: forgetting the output is what the directory then sees.
        std::mem::forget(output);
        if cfg!(target_os = "linux") && unnamed {
            assert!(names_in(dir.path()).is_empty(), "{:?}", names_in(dir.path()));
        } else {
            eprintln!("SKIPPED: this file system has no unnamed temporary files (O_TMPFILE); a later run sweeps");
        }
    }

    #[test]
    fn a_committed_output_replaces_the_old_file_with_its_bytes_and_leaves_no_temporary_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.bvh");
        std::fs::write(&path, b"old").unwrap();
        let mut output = AtomicOutput::create(&path).unwrap();
        output.file().write_all(b"new bytes").unwrap();
        output.file().flush().unwrap();
        assert_eq!(std::fs::read(output.temporary_path()).unwrap(), b"new bytes", "readable by its path");
        assert_eq!(std::fs::read(&path).unwrap(), b"old", "the output is untouched until the commit");
        output.commit().unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new bytes");
        assert_eq!(names_in(dir.path()), ["out.bvh"]);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
            assert_eq!(mode & 0o600, 0o600, "readable and writable by its owner: {mode:o}");
            assert_eq!(mode & 0o111, 0, "not executable: {mode:o}");
        }
    }
}
