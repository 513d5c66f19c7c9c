//! [`BvhViewMut`]: a structurally checked `.bvh` file over bytes the caller lets it change in place: an owned
//! buffer ([`BvhFile`] hands one out), a writable array of a binding (numpy), a private (copy-on-write) memory
//! map. Edits ([`BvhViewMut::edit`]) rewrite section contents and checksums only, never the header's layout or
//! the section table's offsets and sizes, so the structural rules V1-V10 checked on opening keep holding.

use crate::error::Error;
use crate::open::edit::SectionsMut;
use crate::open::file::BvhFile;
use crate::open::view::BvhView;

/// A `.bvh` file borrowed mutably from bytes, opened (rules V1-V10) once; refit it
/// ([`BvhViewMut::refit`]), move its instances ([`BvhViewMut::move_instances`]) or edit its sections
/// ([`BvhViewMut::edit`]) in place.
#[derive(Debug)]
pub struct BvhViewMut<'a> {
    bytes: &'a mut [u8],
}

impl<'a> BvhViewMut<'a> {
    /// Opens `bytes` as [`BvhView::open`] does (4-byte aligned, rules V1-V10).
    pub fn open(bytes: &'a mut [u8]) -> Result<BvhViewMut<'a>, Error> {
        BvhView::open(bytes)?;
        Ok(BvhViewMut { bytes })
    }

    /// A view of the bytes as they stand now.
    #[allow(unsafe_code)]
    pub fn view(&self) -> BvhView<'_> {
        // SAFETY: `open` checked rules V1-V10 on these bytes, and they change only through `edit`, which
        // rewrites section contents and checksums, never the header or the table that V1-V10 read.
        unsafe { BvhView::open_unchecked(self.bytes) }
    }

    /// The file's geometric sections for writing in place ([`SectionsMut`]); the checksums are recomputed when
    /// the returned value is dropped. An error only for a file whose sections overlap or are misaligned, which
    /// opening refuses (rules V1-V10), so never for an opened file.
    pub fn edit(&mut self) -> Result<SectionsMut<'_>, Error> {
        SectionsMut::split(self.bytes)
    }
}

impl BvhFile {
    /// The file's bytes as a [`BvhViewMut`], to refit or edit them in place.
    pub fn view_mut(&mut self) -> BvhViewMut<'_> {
        BvhViewMut { bytes: self.bytes_mut() }
    }

    /// [`BvhViewMut::edit`] of the file's bytes.
    pub fn edit(&mut self) -> Result<SectionsMut<'_>, Error> {
        SectionsMut::split(self.bytes_mut())
    }
}
