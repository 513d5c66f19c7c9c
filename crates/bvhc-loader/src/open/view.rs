//! [`BvhView`]: a borrowed, structurally checked view of a `.bvh` file's bytes.
//!
//! Opening reads the header and the section table and checks rules V1-V10 of `format-spec/bvh-1.md` (in
//! `structure`); it costs O(number of sections) and never touches node or triangle data. [`BvhView::verify`]
//! checks the rest.

use crate::error::{Error, Rule, Violation, violation};
use crate::format::{
    FileHeader, PackedNode, PackedTriangle, SectionEntry, SectionKind, SourceRange, SourceVertexIndices,
};
use crate::open::sections::{CheckedSlices, GpuSections, SectionSet, TwoLevelSections, UncheckedSlices, WideSections};
use crate::open::structure::{SectionInfo, check_structure, section_infos};

/// A structurally checked `.bvh` file borrowed from bytes: typed zero-copy slices of its sections.
///
/// Invariants (established by [`BvhView::open`]): rules V1-V10 hold, so every section lies inside `bytes`,
/// the known kinds have their element sizes, and the slices below are exactly those sections.
#[derive(Clone, Copy, Debug)]
pub struct BvhView<'a> {
    bytes: &'a [u8],
    header: FileHeader,
    sections: SectionSet<'a>,
}

impl<'a> BvhView<'a> {
    /// Opens `bytes` as a `.bvh` file, checking rules V1-V10 (O(number of sections)).
    ///
    /// `bytes` must start at a 4-byte-aligned address (a [`crate::open::file::BvhFile`] or a memory map always does);
    /// otherwise [`Error::Misaligned`] is returned. Call [`BvhView::verify`] before trusting the contents.
    pub fn open(bytes: &'a [u8]) -> Result<BvhView<'a>, Error> {
        let (header, known) = check_structure(bytes)?;
        let sections = SectionSet::assemble(|kind| known.get(kind), &CheckedSlices(bytes))?;
        Ok(BvhView { bytes, header, sections })
    }

    /// The whole file.
    pub fn bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// The header.
    pub fn header(&self) -> &FileHeader {
        &self.header
    }

    /// `(major, minor)` version of the file.
    pub fn version(&self) -> (u16, u16) {
        (self.header.version_major, self.header.version_minor)
    }

    /// Every entry of the section table, known kinds and unknown ones, in table order.
    pub fn sections(&self) -> impl Iterator<Item = SectionInfo> + 'a {
        section_infos(self.bytes, &self.header)
    }

    /// The nodes; node 0 is the root (empty only for a file without triangles).
    pub fn nodes(&self) -> &'a [PackedNode] {
        self.sections.nodes
    }

    /// The triangles in leaf order.
    pub fn triangles(&self) -> &'a [PackedTriangle] {
        self.sections.triangles
    }

    /// The source triangle id of each triangle, when the file has the optional ids section.
    pub fn triangle_ids(&self) -> Option<&'a [u32]> {
        self.sections.triangle_ids
    }

    /// The source table, when present.
    pub fn source_table(&self) -> Option<&'a [SourceRange]> {
        self.sections.source_table
    }

    /// The `triangle_flags` section (1.5), when present: element `i` holds the flags of triangle `i`
    /// ([`crate::format::TRIANGLE_NOT_OPAQUE`]). Without it every triangle is opaque.
    pub fn triangle_flags(&self) -> Option<&'a [u8]> {
        self.sections.triangle_flags
    }

    /// Whether triangle record `index` is marked not opaque (its material may cut it out: a filtered tracer
    /// asks its filter about hits on it); `false` without a `triangle_flags` section or for an index out of range.
    pub fn is_not_opaque(&self, index: u32) -> bool {
        self.sections
            .triangle_flags
            .and_then(|flags| flags.get(index as usize))
            .is_some_and(|&f| f & crate::format::TRIANGLE_NOT_OPAQUE != 0)
    }

    /// The `source_vertices` section (1.2), when present: element `i` holds the source vertex indices of
    /// triangle `i`'s `v0`, `v1`, `v2` ([`SourceVertexIndices`]; [`BvhView::source_corners`] pairs them with
    /// a hit's weights).
    pub fn source_vertices(&self) -> Option<&'a [SourceVertexIndices]> {
        self.sections.source_vertices
    }

    /// The source range that a source triangle id belongs to (binary search; needs the source table).
    pub fn source_range_of(&self, source_triangle_id: u32) -> Option<&'a SourceRange> {
        let table = self.sections.source_table?;
        let after = table.partition_point(|r| r.first_source_triangle <= source_triangle_id);
        let range = table.get(after.checked_sub(1)?)?;
        let offset = source_triangle_id - range.first_source_triangle;
        (offset < range.source_triangle_count).then_some(range)
    }

    /// The metadata section as raw bytes, when present.
    pub fn metadata_bytes(&self) -> Option<&'a [u8]> {
        self.sections.metadata
    }

    /// The metadata as text; `Err` (rule V23) when it is not UTF-8. Checks O(metadata length) bytes.
    pub fn metadata_str(&self) -> Option<Result<&'a str, Violation>> {
        self.sections.metadata.map(|bytes| {
            std::str::from_utf8(bytes)
                .map_err(|e| violation(Rule::Metadata, format!("metadata section: not UTF-8 ({e})")))
        })
    }

    /// Whether the triangles section allows a triangle to be referenced from several leaves.
    pub fn has_split_references(&self) -> bool {
        self.sections.split_references
    }

    /// The wide BVH's sections, when the file has them (1.1).
    pub fn wide_sections(&self) -> Option<WideSections<'a>> {
        self.sections.wide
    }

    /// The GPU layout's sections, when the file has them (1.4).
    pub fn gpu_sections(&self) -> Option<GpuSections<'a>> {
        self.sections.gpu
    }

    /// The box of the whole scene in world space: the top-level root's in a two-level file, the root node's
    /// otherwise; `None` for an empty file.
    pub fn scene_box(&self) -> Option<([f32; 3], [f32; 3])> {
        let root = match self.sections.two_level {
            Some(sections) => sections.top_nodes.first(),
            None => self.sections.nodes.first(),
        };
        root.map(|root| (root.min, root.max))
    }

    /// The two-level sections (1.3), when the file places meshes by instances: its nodes, triangles and wide
    /// sections are then the meshes' trees, each in its object space, and the scene is the instances.
    pub fn two_level(&self) -> Option<TwoLevelSections<'a>> {
        self.sections.two_level
    }

    /// Every typed section of the file (what a writer copying the file lays out).
    #[cfg(feature = "write")]
    pub(crate) fn section_set(&self) -> SectionSet<'a> {
        self.sections
    }

    /// Builds a view without checking any rule.
    ///
    /// # Safety
    ///
    /// `bytes` must be a buffer that [`BvhView::open`] accepts (for example one it accepted before, unchanged
    /// since). Otherwise slices may be built over memory outside `bytes` or with the wrong alignment.
    #[allow(unsafe_code)]
    pub unsafe fn open_unchecked(bytes: &'a [u8]) -> BvhView<'a> {
        // SAFETY: V1 guarantees at least HEADER_BYTE_LEN bytes; `FileHeader` is Pod, read unaligned.
        let header: FileHeader = unsafe { std::ptr::read_unaligned(bytes.as_ptr().cast::<FileHeader>()) };
        let mut entries = [None; SectionKind::ALL.len()];
        for info in section_infos(bytes, &header) {
            if let Some(kind) = info.kind {
                entries[kind as usize] = Some(info.entry);
            }
        }
        // SAFETY: `bytes` is a buffer `open` accepts (this function's contract), and the entries are its table's.
        let slices = unsafe { UncheckedSlices::new(bytes) };
        let unchecked = SectionSet::assemble(|kind| entries[kind as usize], &slices);
        // Never `Err`: the nodes and triangles sections are there (V8), and unchecked slices never fail.
        let sections = unchecked.unwrap_or(SectionSet::EMPTY);
        BvhView { bytes, header, sections }
    }
}

/// The bytes of a section. Requires V5 (the section lies inside `bytes`).
pub(crate) fn section_bytes<'a>(bytes: &'a [u8], entry: &SectionEntry) -> &'a [u8] {
    let start = entry.section_byte_offset as usize;
    let end = start + entry.section_byte_len as usize;
    bytes.get(start..end).unwrap_or(&[])
}
