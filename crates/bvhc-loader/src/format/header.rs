//! The file's header and section table entries (`format-spec/bvh-1.md` sections 2 and 3), re-exported by
//! [`crate::format`] with the other on-disk types.

/// The file header: the first 64 bytes of the file.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FileHeader {
    /// [`crate::format::MAGIC`].
    pub magic: [u8; 8],
    /// Major version; 1 for this format.
    pub version_major: u16,
    /// Minor version; higher minors only add.
    pub version_minor: u16,
    /// File-wide flags; none are defined in 1.0, so zero.
    pub header_flags: u32,
    /// Byte length of the whole file; catches truncation and appended bytes.
    pub file_byte_len: u64,
    /// Number of entries in the section table that follows the header.
    pub section_count: u32,
    /// Byte size of one section table entry; 48 in 1.0. Lets a later minor grow the entry.
    pub section_entry_byte_len: u32,
    /// XXH3-64 (seed 0) of the header and the section table, computed with this field set to zero.
    pub header_checksum: u64,
    /// Zero.
    pub reserved: [u64; 3],
}

/// One entry of the section table, which follows the header directly.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SectionEntry {
    /// What the section holds ([`crate::format::SectionKind::code`]).
    pub kind: u32,
    /// [`crate::format::SECTION_FLAG_REQUIRED`], [`crate::format::SECTION_FLAG_SPLIT_REFERENCES`]; other bits zero.
    pub section_flags: u32,
    /// Offset of the section's first byte from the start of the file; a multiple of 64.
    pub section_byte_offset: u64,
    /// Byte length of the section, without padding; equals `element_count * element_byte_len`.
    pub section_byte_len: u64,
    /// Number of elements (nodes, triangles, ids, ranges, metadata bytes).
    pub element_count: u64,
    /// Byte size of one element.
    pub element_byte_len: u32,
    /// Zero.
    pub reserved: u32,
    /// XXH3-64 (seed 0) of the section's `section_byte_len` bytes.
    pub section_checksum: u64,
}

/// Byte size of the header.
pub const HEADER_BYTE_LEN: usize = size_of::<FileHeader>();
/// Byte size of a section table entry in 1.0.
pub const SECTION_ENTRY_BYTE_LEN: usize = size_of::<SectionEntry>();

crate::format::plain_data::plain_data! {
    FileHeader { [u8; 8], u16, u16, u32, u64, u32, u32, u64, [u64; 3] }
    SectionEntry { u32, u32, u64, u64, u64, u32, u32, u64 }
}
