//! Writing a conversion's file: streamed to a temporary file beside the output, read back and verified once
//! the arrays it was written from are freed, then moved into place (`AtomicOutput`).

use std::path::Path;

use bvhc_loader::{BvhFile, write::AtomicOutput, write::BvhWriter};

use super::part::out_of_memory;
use super::report::ConvertError;

/// Streams `writer`'s file to a temporary file beside `output`; returns it, not yet in place, and the file's
/// length. The file is read back and verified by [`verify_and_commit`] once the caller has freed the arrays
/// the writer borrowed, so the file is in memory once (laying it out in memory beside the arrays took twice its
/// size); the output is replaced only by a verified file. Both transfers bypass the page cache where the system
/// allows it (see `UncachedWriter`), which was most of the write stage's time for large files.
pub(super) fn stream(writer: &BvhWriter<'_>, output: &Path) -> Result<(AtomicOutput, u64), ConvertError> {
    let mut atomic = AtomicOutput::create(output)?;
    let mut sink = atomic.uncached_writer();
    writer.write_unverified(&mut sink, output)?;
    let file_byte_len =
        sink.finish().map_err(|source| bvhc_loader::Error::Io { path: output.to_path_buf(), source })?;
    Ok((atomic, file_byte_len))
}

/// Reads the streamed file back, verifies every rule, and moves it into place.
pub(super) fn verify_and_commit(atomic: AtomicOutput, input: &Path) -> Result<(), ConvertError> {
    let file = BvhFile::read_uncached(atomic.temporary_path())
        .map_err(|e| out_of_memory(input, "reading the written file back", e))?;
    file.view().verify().map_err(bvhc_loader::Error::from)?;
    drop(file);
    atomic.commit()?;
    Ok(())
}
