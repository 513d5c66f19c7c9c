//! The import's resource budget: every count that a small file can declare and that would make bvhc allocate
//! is checked against it before the allocation, so a few hundred hostile bytes cannot exhaust memory. The
//! defaults bound an import to a few GiB (see [`ImportLimits`]) and every limit can be raised (the command line's
//! `--max-*` options).

use std::io::Read;
use std::path::Path;

use super::memory::MemoryLimit;
use super::{ErrorKind, Located};

/// Limits on what one import may read and hold. With the defaults, the largest allocations are about 1 GiB per
/// file read, 1 GiB of decoded glTF accessor values (f64), and 64 Mi triangles (about 2.5 GiB in the soup); the
/// whole conversion's estimated peak ([`super::memory`]) is held to [`ImportLimits::max_memory`].
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ImportLimits {
    /// Bytes of any one file read (the input, after gunzip; each external glTF buffer; a decoded data URI).
    pub max_input_bytes: u64,
    /// Triangles placed in the scene, counted before degenerate ones are dropped (instancing multiplies).
    pub max_triangles: u64,
    /// Scalar values decoded: the components of all glTF accessors read (positions, indices, instance
    /// attributes), of OBJ `v` records, of PLY vertices.
    pub max_decoded_values: u64,
    /// Mesh placements: glTF nodes with a mesh, times their `EXT_mesh_gpu_instancing` instances.
    pub max_placements: u64,
    /// Vertices of one OBJ or PLY polygon (the ear clipper's cost grows with the square of it).
    pub max_polygon_vertices: u64,
    /// The memory the whole conversion may use; placed triangles are counted against it at
    /// [`super::memory::BYTES_PER_TRIANGLE`] each before they are held.
    pub max_memory: MemoryLimit,
}

impl Default for ImportLimits {
    fn default() -> Self {
        ImportLimits {
            max_input_bytes: 1 << 30,
            max_triangles: 1 << 26,
            max_decoded_values: 1 << 27,
            max_placements: 1 << 24,
            max_polygon_vertices: 1 << 13,
            max_memory: MemoryLimit::Detect,
        }
    }
}

impl ImportLimits {
    /// No limits at all (for trusted inputs; memory is then bounded only by the machine).
    pub fn unlimited() -> Self {
        ImportLimits {
            max_input_bytes: u64::MAX,
            max_triangles: u64::MAX,
            max_decoded_values: u64::MAX,
            max_placements: u64::MAX,
            max_polygon_vertices: u64::MAX,
            max_memory: MemoryLimit::Unlimited,
        }
    }
}

/// A running count against one limit of [`ImportLimits`].
#[derive(Clone, Debug)]
pub(crate) struct Meter {
    used: u64,
    limit: u64,
    what: &'static str,
    option: &'static str,
}

impl Meter {
    pub(crate) fn new(limit: u64, what: &'static str, option: &'static str) -> Meter {
        Meter { used: 0, limit, what, option }
    }

    /// Takes `amount` more, or says which limit it would break (nothing is taken then).
    pub(crate) fn take(&mut self, amount: u64) -> Result<(), String> {
        match self.used.checked_add(amount).filter(|&total| total <= self.limit) {
            Some(total) => {
                self.used = total;
                Ok(())
            }
            None => Err(limit_message(self.used.saturating_add(amount), self.limit, self.what, self.option)),
        }
    }
}

/// "N <what> exceed the limit of L (raise it with <option>)".
pub(crate) fn limit_message(amount: u64, limit: u64, what: &str, option: &str) -> String {
    format!("{amount} {what} exceed the import limit of {limit} (raise it with {option})")
}

/// Reads a whole regular file of at most `max_bytes` bytes (gunzipped first when `gzipped`, the limit then
/// applying to the decompressed bytes), refusing FIFOs, devices and directories before opening them for
/// reading, and turning a failed allocation into an error.
pub(crate) fn read_regular_file(path: &Path, gzipped: bool, max_bytes: u64) -> Result<Vec<u8>, Located> {
    let metadata = std::fs::metadata(path)
        .map_err(|e| Located::of_kind(ErrorKind::Unreadable, "file", format!("cannot read: {e}")))?;
    if !metadata.is_file() {
        let kind = if metadata.is_dir() { "a directory" } else { "not a regular file (a FIFO, socket or device)" };
        return Err(Located::of_kind(ErrorKind::Unreadable, "file", format!("cannot read: {kind}")));
    }
    if metadata.len() > max_bytes {
        let message = limit_message(metadata.len(), max_bytes, "bytes", "--max-input-bytes");
        return Err(Located::of_kind(ErrorKind::Limit, "file", message));
    }
    let file = std::fs::File::open(path)
        .map_err(|e| Located::of_kind(ErrorKind::Unreadable, "file", format!("cannot read: {e}")))?;
    let raw =
        read_bounded(file, metadata.len(), max_bytes).map_err(|e| e.with_message(|m| format!("cannot read: {m}")))?;
    if !gzipped {
        return Ok(raw);
    }
    let guess = (raw.len() as u64).saturating_mul(4).min(max_bytes);
    read_bounded(flate2::read::MultiGzDecoder::new(raw.as_slice()), guess, max_bytes)
        .map_err(|e| e.with_message(|m| format!("gzip: {m}")))
}

/// Everything `reader` yields, at most `max_bytes` (one byte more is an error), with `expected` bytes
/// reserved up front; an allocation failure is an error, not an abort.
fn read_bounded(reader: impl Read, expected: u64, max_bytes: u64) -> Result<Vec<u8>, Located> {
    let mut bytes = Vec::new();
    bytes
        .try_reserve_exact(usize::try_from(expected.min(max_bytes)).unwrap_or(usize::MAX))
        .map_err(|_| Located::of_kind(ErrorKind::Limit, "file", format!("out of memory reserving {expected} bytes")))?;
    let mut limited = reader.take(max_bytes.saturating_add(1));
    let mut chunk = vec![0u8; 1 << 16];
    loop {
        let n = match limited.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => {
                let kind =
                    if e.kind() == std::io::ErrorKind::InvalidInput || e.kind() == std::io::ErrorKind::InvalidData {
                        ErrorKind::Invalid
                    } else {
                        ErrorKind::Unreadable
                    };
                return Err(Located::of_kind(kind, "file", e.to_string()));
            }
        };
        if bytes.len() as u64 + n as u64 > max_bytes {
            let message = format!("more than {max_bytes} bytes (the import limit; raise it with --max-input-bytes)");
            return Err(Located::of_kind(ErrorKind::Limit, "file", message));
        }
        bytes.try_reserve(n).map_err(|_| {
            Located::of_kind(ErrorKind::Limit, "file", format!("out of memory after {} bytes", bytes.len()))
        })?;
        bytes.extend_from_slice(&chunk[..n]);
    }
    Ok(bytes)
}

/// The first `byte_len` bytes of a regular file that may be longer.
pub(crate) fn read_prefix(path: &Path, byte_len: u64) -> Result<Vec<u8>, String> {
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    read_bounded(file.take(byte_len), byte_len, byte_len).map_err(|e| e.message().to_string())
}
