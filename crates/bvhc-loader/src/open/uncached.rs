//! Writing and reading a large file past the page cache.
//!
//! A converted file is written once, read back once for verification, flushed to disk and renamed; passing
//! its bytes through the page cache costs a copy each way and fills the cache with up to the file's size of
//! pages. Filling the cache was the slowest part of writing a 1 GB file on this project's build machines
//! (virtual machines with a balloon driver, where memory freed for a few seconds is slow to reuse; figures in
//! `docs/scale.md`).
//!
//! On Linux the file is opened a second time with `O_DIRECT` and the bytes go through a page-aligned staging
//! buffer in whole pages; the last, partial page is written padded with zeros and the file then cut to its
//! length. Where `O_DIRECT` is refused (`EINVAL`: tmpfs, some network file systems), and on other systems,
//! ordinary buffered I/O is used instead. Either way the file holds exactly the bytes written.

use std::fs::File;
use std::io::{Read, Write};
use std::path::Path;

/// The alignment of `O_DIRECT` transfers: buffer address, length and file offset. 4096 covers the logical
/// block size of every common device (512 or 4096).
const PAGE_BYTE_LEN: usize = 4096;

/// Pages in the staging buffer (8 MiB: large transfers, small next to any file worth bypassing the cache for).
const STAGE_PAGES: usize = 2048;

/// One page, aligned as `O_DIRECT` requires.
#[repr(C, align(4096))]
#[derive(Clone, Copy)]
struct Page([u8; PAGE_BYTE_LEN]);

crate::format::plain_data::plain_data! { Page { [u8; PAGE_BYTE_LEN] } }

/// A page-aligned buffer of `STAGE_PAGES` pages.
struct Stage {
    pages: Vec<Page>,
}

impl Stage {
    /// The staging buffer, or an `OutOfMemory` error where the system refuses it.
    fn new() -> std::io::Result<Stage> {
        let pages = bytemuck::allocation::try_zeroed_vec(STAGE_PAGES).map_err(|_| {
            std::io::Error::new(std::io::ErrorKind::OutOfMemory, "no memory for the direct-transfer staging buffer")
        })?;
        Ok(Stage { pages })
    }

    fn bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.pages)
    }

    fn bytes_mut(&mut self) -> &mut [u8] {
        bytemuck::cast_slice_mut(&mut self.pages)
    }
}

/// Opens `path` for `O_DIRECT` transfers (writing or reading), or `None` where the system or the file system
/// does not offer them (the caller then uses buffered I/O).
fn open_direct(path: &Path, write: bool) -> Option<File> {
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::fs::OpenOptionsExt;
        std::fs::OpenOptions::new().read(!write).write(write).custom_flags(libc::O_DIRECT).open(path).ok()
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = (path, write);
        None
    }
}

/// Whether `error` is a refusal of `O_DIRECT` by the file system (rather than a failure of the device).
fn is_direct_refused(error: &std::io::Error) -> bool {
    error.kind() == std::io::ErrorKind::InvalidInput
}

/// A [`Write`] sink for a new, empty file that bypasses the page cache where it can (see the module doc).
/// Call [`UncachedWriter::finish`] after the last write: until then up to a staging buffer of bytes is held
/// back.
pub struct UncachedWriter<'f> {
    /// The file as opened by its creator: used for buffered writes and for setting the final length.
    buffered: &'f mut File,
    /// The same file opened with `O_DIRECT`, while direct writes work.
    direct: Option<File>,
    stage: Stage,
    /// Bytes in the stage not yet written.
    staged: usize,
    /// Bytes written to the file through `direct` (whole stages, so a multiple of the page size).
    written: u64,
}

impl<'f> UncachedWriter<'f> {
    /// A writer for the new, empty file `file` at `path` (the path opens the second, direct handle).
    pub fn new(file: &'f mut File, path: &Path) -> UncachedWriter<'f> {
        UncachedWriter::with_direct(file, open_direct(path, true))
    }

    /// A writer that never bypasses the cache: for tests of the buffered path, and for systems without it.
    pub fn buffered(file: &'f mut File) -> UncachedWriter<'f> {
        UncachedWriter::with_direct(file, None)
    }

    fn with_direct(buffered: &'f mut File, direct: Option<File>) -> UncachedWriter<'f> {
        // Without memory for the staging buffer, the writer goes through the page cache instead.
        let stage = direct.as_ref().and_then(|_| Stage::new().ok());
        let direct = direct.filter(|_| stage.is_some());
        let stage = stage.unwrap_or(Stage { pages: Vec::new() });
        UncachedWriter { buffered, direct, stage, staged: 0, written: 0 }
    }

    /// Writes the staged bytes padded to whole pages through the direct handle. On a refusal before anything
    /// was written there, falls back to buffered writes (the staged bytes go to the buffered handle).
    fn write_stage(&mut self) -> std::io::Result<()> {
        let Some(direct) = self.direct.as_mut() else {
            return Ok(());
        };
        let padded = self.staged.next_multiple_of(PAGE_BYTE_LEN);
        self.stage.bytes_mut()[self.staged..padded].fill(0);
        match direct.write_all(&self.stage.bytes()[..padded]) {
            Ok(()) => {
                self.written += padded as u64;
                self.staged = 0;
                Ok(())
            }
            Err(error) if is_direct_refused(&error) && self.written == 0 => {
                // Nothing reached the file through the direct handle, and the buffered handle's offset is 0.
                self.direct = None;
                self.buffered.write_all(&self.stage.bytes()[..self.staged])?;
                self.staged = 0;
                Ok(())
            }
            Err(error) => Err(error),
        }
    }

    /// Writes what is still staged and sets the file's length to the bytes written; returns that length.
    pub fn finish(mut self) -> std::io::Result<u64> {
        if self.direct.is_none() {
            self.buffered.flush()?;
            return self.buffered.metadata().map(|m| m.len());
        }
        let length = self.written + self.staged as u64;
        self.write_stage()?;
        if self.direct.is_some() {
            // The last page went out padded with zeros: cut them off.
            self.buffered.set_len(length)?;
        }
        Ok(length)
    }
}

impl Write for UncachedWriter<'_> {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        if self.direct.is_none() {
            return self.buffered.write(bytes);
        }
        let room = self.stage.bytes().len() - self.staged;
        let taken = bytes.len().min(room);
        self.stage.bytes_mut()[self.staged..self.staged + taken].copy_from_slice(&bytes[..taken]);
        self.staged += taken;
        if self.staged == self.stage.bytes().len() {
            self.write_stage()?;
        }
        Ok(taken)
    }

    /// Does not write a partial stage (direct writes are whole pages); [`UncachedWriter::finish`] does.
    fn flush(&mut self) -> std::io::Result<()> {
        if self.direct.is_none() { self.buffered.flush() } else { Ok(()) }
    }
}

/// Threads that read a file back at once: the device serves two requests in parallel faster than one after
/// the other, and each thread also copies its pages out of its staging buffer.
const READ_THREADS: usize = 2;

/// A part of the output to read: its offset in the file and its bytes, taken by whichever thread reads it.
type Part<'a> = std::sync::Mutex<Option<(u64, &'a mut [u8])>>;

/// Reads the whole file at `path`, whose length is `out.len()`, into `out`, past the page cache where it can
/// (see the module doc).
pub(crate) fn read_uncached(path: &Path, out: &mut [u8]) -> std::io::Result<()> {
    let expected = out.len() as u64;
    if std::fs::metadata(path)?.len() != expected {
        return Err(changed_length(expected));
    }
    if let Some(direct) = open_direct(path, false) {
        // Each thread reads a run of whole stages, so every offset stays page-aligned.
        let stage_len = STAGE_PAGES * PAGE_BYTE_LEN;
        let per_thread = out.len().div_ceil(stage_len).div_ceil(READ_THREADS) * stage_len;
        // Each part is taken by the thread that reads it; where no thread can be started (an address-space
        // limit), the caller's thread takes and reads it after the others have started.
        let parts: Vec<Part<'_>> = out
            .chunks_mut(per_thread.max(1))
            .enumerate()
            .map(|(i, part)| std::sync::Mutex::new(Some(((i * per_thread) as u64, part))))
            .collect();
        let direct = &direct;
        let read_part = |part: &Part<'_>| {
            let taken = part.lock().ok().and_then(|mut slot| slot.take());
            taken.map_or(Ok(()), |(offset, bytes)| read_direct_at(direct, offset, bytes))
        };
        let outcome = std::thread::scope(|scope| {
            let workers: Vec<_> = parts
                .iter()
                .map(|part| std::thread::Builder::new().spawn_scoped(scope, move || read_part(part)))
                .collect();
            let joined = workers.into_iter().zip(&parts).map(|(worker, part)| match worker {
                Ok(thread) => thread.join().unwrap_or_else(|_| Err(std::io::Error::other("a reader panicked"))),
                Err(_) => read_part(part),
            });
            joined.collect::<Vec<_>>()
        });
        match outcome.into_iter().find_map(Result::err) {
            None => return Ok(()),
            Some(error) if !is_direct_refused(&error) => return Err(error),
            Some(_) => {} // refused: read it buffered below
        }
    }
    File::open(path)?.read_exact(out)
}

/// Fills `part` from `file` at `offset` (page-aligned) with direct reads through a staging buffer.
fn read_direct_at(file: &File, offset: u64, part: &mut [u8]) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileExt;
        let mut stage = Stage::new()?;
        let mut done = 0;
        while done < part.len() {
            let want = (part.len() - done).next_multiple_of(PAGE_BYTE_LEN).min(stage.bytes().len());
            let read = file.read_at(&mut stage.bytes_mut()[..want], offset + done as u64)?;
            let useful = read.min(part.len() - done);
            if read == 0 || (read < want && done + useful < part.len()) {
                return Err(changed_length(offset + part.len() as u64));
            }
            part[done..done + useful].copy_from_slice(&stage.bytes()[..useful]);
            done += useful;
        }
        Ok(())
    }
    #[cfg(not(unix))]
    {
        let _ = (file, offset, part);
        Err(std::io::Error::from(std::io::ErrorKind::InvalidInput))
    }
}

fn changed_length(expected: u64) -> std::io::Error {
    std::io::Error::new(
        std::io::ErrorKind::UnexpectedEof,
        format!("the file changed length while being read (expected {expected} bytes)"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic bytes that differ from page to page and from zero padding.
    fn pattern(len: usize) -> Vec<u8> {
        (0..len).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8 | 1).collect()
    }

    const STAGE: usize = STAGE_PAGES * PAGE_BYTE_LEN;
    const LENGTHS: [usize; 9] = [0, 1, 4095, 4096, 4097, STAGE - 1, STAGE, STAGE + 4097, 2 * STAGE + 3];

    /// Writes `bytes` in uneven pieces (1 byte, 7, a page, 100,000 ...) and returns the length `finish` gave.
    fn write_in_pieces(writer: &mut UncachedWriter<'_>, bytes: &[u8]) {
        let pieces = [1usize, 7, 4096, 100_000, 3, STAGE + 5];
        let mut at = 0;
        for piece in pieces.iter().cycle() {
            if at == bytes.len() {
                break;
            }
            let end = (at + piece).min(bytes.len());
            writer.write_all(&bytes[at..end]).unwrap();
            at = end;
        }
    }

    #[test]
    fn written_and_read_back_bytes_are_the_bytes_given_direct_or_buffered() {
        let dir = tempfile::tempdir().unwrap();
        for direct in [true, false] {
            for len in LENGTHS {
                let bytes = pattern(len);
                let path = dir.path().join(format!("{direct}-{len}.bin"));
                let mut file = File::create(&path).unwrap();
                let mut writer =
                    if direct { UncachedWriter::new(&mut file, &path) } else { UncachedWriter::buffered(&mut file) };
                write_in_pieces(&mut writer, &bytes);
                assert_eq!(writer.finish().unwrap(), len as u64, "direct {direct}, {len} bytes");
                drop(file);
                assert!(std::fs::read(&path).unwrap() == bytes, "direct {direct}, {len} bytes");
                let mut back = vec![0u8; len];
                read_uncached(&path, &mut back).unwrap();
                assert!(back == bytes, "read back, direct {direct}, {len} bytes");
            }
        }
    }

    #[test]
    fn a_read_back_of_the_wrong_length_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("short.bin");
        std::fs::write(&path, pattern(5000)).unwrap();
        for expected in [4999, 5001, 3 * STAGE] {
            let mut back = vec![0u8; expected];
            assert!(read_uncached(&path, &mut back).is_err(), "{expected} bytes expected");
        }
    }
}
