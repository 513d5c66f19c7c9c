//! Owners of a `.bvh` file's bytes: [`BvhFile`] (an aligned heap buffer, safe) and [`MappedBvh`] (a memory
//! map, `unsafe` to open). Both were opened once (rules V1-V10) and hand out [`BvhView`]s at no cost.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use crate::error::Error;
use crate::open::view::BvhView;

/// `Ok` when `path` is a regular file (after symbolic links); an error saying what it is otherwise: a directory
/// (which the system would report as "No such device" when mapped, or "Is a directory" when read), or a FIFO,
/// socket or device (which opening could block on, or read without end).
fn regular_file(path: &Path) -> std::io::Result<()> {
    let kind = std::fs::metadata(path)?.file_type();
    if kind.is_dir() {
        return Err(std::io::Error::new(std::io::ErrorKind::IsADirectory, "is a directory, not a .bvh file"));
    }
    if !kind.is_file() {
        let why = "is not a regular file (a FIFO, socket or device): read its bytes and use BvhFile::from_bytes";
        return Err(std::io::Error::new(std::io::ErrorKind::InvalidInput, why));
    }
    Ok(())
}

/// 64 bytes aligned to 64, the unit of [`AlignedBuffer`].
#[repr(C, align(64))]
#[derive(Clone, Copy)]
struct Block([u8; 64]);

crate::format::plain_data::plain_data! { Block { [u8; 64] } }

/// A heap buffer whose first byte is 64-byte aligned, as the sections' offsets assume.
pub(crate) struct AlignedBuffer {
    blocks: Vec<Block>,
    byte_len: usize,
}

impl AlignedBuffer {
    /// `byte_len` zero bytes; an allocation the system refuses is [`Error::OutOfMemory`].
    pub(crate) fn zeroed(byte_len: usize) -> Result<AlignedBuffer, Error> {
        let block_count = byte_len.div_ceil(64);
        let mut blocks = Vec::new();
        blocks
            .try_reserve_exact(block_count)
            .map_err(|_| Error::OutOfMemory { what: "the file's bytes".to_string(), bytes: byte_len as u64 })?;
        blocks.resize(block_count, <Block as bytemuck::Zeroable>::zeroed());
        Ok(AlignedBuffer { blocks, byte_len })
    }

    pub(crate) fn as_bytes(&self) -> &[u8] {
        &bytemuck::cast_slice(&self.blocks)[..self.byte_len]
    }

    pub(crate) fn as_bytes_mut(&mut self) -> &mut [u8] {
        &mut bytemuck::cast_slice_mut(&mut self.blocks)[..self.byte_len]
    }
}

/// A `.bvh` file in an owned, 64-byte-aligned buffer. Safe: nothing else can change the bytes.
pub struct BvhFile {
    buffer: AlignedBuffer,
}

impl BvhFile {
    /// Copies `bytes` into an aligned buffer and opens it (rules V1-V10). Use for `include_bytes!` data or any
    /// buffer of unknown alignment.
    pub fn from_bytes(bytes: &[u8]) -> Result<BvhFile, Error> {
        let mut buffer = AlignedBuffer::zeroed(bytes.len())?;
        buffer.as_bytes_mut().copy_from_slice(bytes);
        BvhFile::from_buffer(buffer)
    }

    /// Reads the file at `path` into an aligned buffer and opens it (rules V1-V10). A directory or another file
    /// that is not a regular one (a FIFO, a device) is refused as such, before it is opened.
    pub fn read(path: impl AsRef<Path>) -> Result<BvhFile, Error> {
        let path = path.as_ref();
        let io = |source| Error::Io { path: path.to_path_buf(), source };
        regular_file(path).map_err(io)?;
        let mut file = File::open(path).map_err(io)?;
        let byte_len = file.metadata().map_err(io)?.len();
        let byte_len = usize::try_from(byte_len)
            .map_err(|_| io(std::io::Error::new(std::io::ErrorKind::OutOfMemory, "file too large for memory")))?;
        let mut buffer = AlignedBuffer::zeroed(byte_len)?;
        file.read_exact(buffer.as_bytes_mut()).map_err(io)?;
        BvhFile::from_buffer(buffer)
    }

    /// [`BvhFile::read`] past the page cache where the system allows it (Linux `O_DIRECT`; buffered reads
    /// elsewhere): for reading back a large file just written, whose pages nothing else will want.
    #[cfg(feature = "write")]
    pub fn read_uncached(path: impl AsRef<Path>) -> Result<BvhFile, Error> {
        let path = path.as_ref();
        let io = |source| Error::Io { path: path.to_path_buf(), source };
        let byte_len = std::fs::metadata(path).map_err(io)?.len();
        let byte_len = usize::try_from(byte_len)
            .map_err(|_| io(std::io::Error::new(std::io::ErrorKind::OutOfMemory, "file too large for memory")))?;
        let mut buffer = AlignedBuffer::zeroed(byte_len)?;
        crate::open::uncached::read_uncached(path, buffer.as_bytes_mut()).map_err(io)?;
        BvhFile::from_buffer(buffer)
    }

    pub(crate) fn from_buffer(buffer: AlignedBuffer) -> Result<BvhFile, Error> {
        BvhView::open(buffer.as_bytes())?;
        Ok(BvhFile { buffer })
    }

    /// The file's bytes, for an edit in place ([`BvhFile::edit`], which keeps the section table as it is).
    pub(crate) fn bytes_mut(&mut self) -> &mut [u8] {
        self.buffer.as_bytes_mut()
    }

    /// The file's bytes.
    pub fn as_bytes(&self) -> &[u8] {
        self.buffer.as_bytes()
    }

    /// A view of the file (O(number of sections)).
    #[allow(unsafe_code)]
    pub fn view(&self) -> BvhView<'_> {
        // SAFETY: `from_buffer` opened these bytes with `BvhView::open`, and `buffer` is private and never
        // changed afterwards, so they are still bytes that `open` accepts.
        unsafe { BvhView::open_unchecked(self.buffer.as_bytes()) }
    }
}

impl std::fmt::Debug for BvhFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BvhFile").field("byte_len", &self.as_bytes().len()).finish_non_exhaustive()
    }
}

#[cfg(feature = "mmap")]
impl std::fmt::Debug for MappedBvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MappedBvh").field("byte_len", &self.as_bytes().len()).finish_non_exhaustive()
    }
}

/// A `.bvh` file mapped into memory: opening costs O(number of sections) whatever the file's size (feature
/// `mmap`, on by default).
#[cfg(feature = "mmap")]
pub struct MappedBvh {
    map: memmap2::Mmap,
}

#[cfg(feature = "mmap")]
impl MappedBvh {
    /// Maps the file at `path` and opens it (rules V1-V10).
    ///
    /// # Safety
    ///
    /// The file must not be modified or truncated while the map lives: the view's slices point into the
    /// mapped pages, so a change is seen as changing `&[u8]` data (undefined behaviour), and truncation makes
    /// reads past the new end raise SIGBUS. Replace files by renaming a new file over them (as bvhc's
    /// writer does), never by writing in place. When that cannot be guaranteed, use
    /// [`BvhFile::read`].
    #[allow(unsafe_code)]
    pub unsafe fn open(path: impl AsRef<Path>) -> Result<MappedBvh, Error> {
        let path = path.as_ref();
        let io = |source| Error::Io { path: path.to_path_buf(), source };
        regular_file(path).map_err(io)?;
        let file = File::open(path).map_err(io)?;
        // SAFETY: the caller guarantees the file is not changed while mapped (this function's contract).
        let map = unsafe { memmap2::Mmap::map(&file) }.map_err(io)?;
        BvhView::open(&map)?;
        Ok(MappedBvh { map })
    }

    /// The mapped bytes.
    pub fn as_bytes(&self) -> &[u8] {
        &self.map
    }

    /// A view of the file (O(number of sections)).
    #[allow(unsafe_code)]
    pub fn view(&self) -> BvhView<'_> {
        // SAFETY: `open` accepted these bytes and the map is private and read-only; the caller of `open`
        // guaranteed that the file behind it does not change while mapped.
        unsafe { BvhView::open_unchecked(&self.map) }
    }
}
