//! [`BvhView`]: a borrowed, structurally checked view of a `.bvh` file's bytes.
//!
//! Opening reads the header and the section table and checks rules V1-V10 of `format-spec/bvh-1.md` (in
//! `structure`); it costs O(number of sections) and never touches node or triangle data. [`BvhView::verify`]
//! checks the rest.

use crate::error::{Error, Rule, Violation, violation};
use crate::format::{
    FileHeader, GpuNode, GpuTriangle, InstanceRecord, MeshRecord, PackedNode, PackedTriangle,
    SECTION_FLAG_SPLIT_REFERENCES, SectionEntry, SectionKind, SourceRange, SourceVertexIndices, TrianglePacket4,
    WideNode8,
};
use crate::open::sections::{GpuSections, TwoLevelSections, WideSections};
use crate::open::structure::{SectionInfo, check_structure, missing, section_infos};

/// A structurally checked `.bvh` file borrowed from bytes: typed zero-copy slices of its sections.
///
/// Invariants (established by [`BvhView::open`]): rules V1-V10 hold, so every section lies inside `bytes`,
/// the known kinds have their element sizes, and the slices below are exactly those sections.
#[derive(Clone, Copy, Debug)]
pub struct BvhView<'a> {
    bytes: &'a [u8],
    header: FileHeader,
    nodes: &'a [PackedNode],
    triangles: &'a [PackedTriangle],
    triangle_ids: Option<&'a [u32]>,
    source_table: Option<&'a [SourceRange]>,
    source_vertices: Option<&'a [SourceVertexIndices]>,
    triangle_flags: Option<&'a [u8]>,
    metadata: Option<&'a [u8]>,
    wide: Option<WideSections<'a>>,
    gpu: Option<GpuSections<'a>>,
    two_level: Option<TwoLevelSections<'a>>,
    split_references: bool,
}

impl<'a> BvhView<'a> {
    /// Opens `bytes` as a `.bvh` file, checking rules V1-V10 (O(number of sections)).
    ///
    /// `bytes` must start at a 4-byte-aligned address (a [`crate::open::file::BvhFile`] or a memory map always does);
    /// otherwise [`Error::Misaligned`] is returned. Call [`BvhView::verify`] before trusting the contents.
    pub fn open(bytes: &'a [u8]) -> Result<BvhView<'a>, Error> {
        let (header, sections) = check_structure(bytes)?;
        let nodes_entry = sections.get(SectionKind::Nodes).ok_or_else(|| missing(SectionKind::Nodes))?;
        let triangles_entry = sections.get(SectionKind::Triangles).ok_or_else(|| missing(SectionKind::Triangles))?;
        Ok(BvhView {
            bytes,
            header,
            nodes: cast_section(bytes, &nodes_entry)?,
            triangles: cast_section(bytes, &triangles_entry)?,
            triangle_ids: sections.get(SectionKind::TriangleIds).map(|e| cast_section(bytes, &e)).transpose()?,
            source_table: sections.get(SectionKind::SourceTable).map(|e| cast_section(bytes, &e)).transpose()?,
            source_vertices: sections.get(SectionKind::SourceVertices).map(|e| cast_section(bytes, &e)).transpose()?,
            triangle_flags: sections.get(SectionKind::TriangleFlags).map(|e| section_bytes(bytes, &e)),
            metadata: sections.get(SectionKind::Metadata).map(|e| section_bytes(bytes, &e)),
            wide: match (sections.get(SectionKind::WideNodes), sections.get(SectionKind::TrianglePackets)) {
                (Some(nodes), Some(packets)) => {
                    Some(WideSections { nodes: cast_section(bytes, &nodes)?, packets: cast_section(bytes, &packets)? })
                }
                _ => None,
            },
            gpu: match (sections.get(SectionKind::GpuNodes), sections.get(SectionKind::GpuTriangles)) {
                (Some(nodes), Some(triangles)) => Some(GpuSections {
                    nodes: cast_section(bytes, &nodes)?,
                    triangles: cast_section(bytes, &triangles)?,
                }),
                _ => None,
            },
            two_level: match (
                sections.get(SectionKind::Meshes),
                sections.get(SectionKind::Instances),
                sections.get(SectionKind::TopNodes),
            ) {
                (Some(meshes), Some(instances), Some(top_nodes)) => Some(TwoLevelSections {
                    meshes: cast_section(bytes, &meshes)?,
                    instances: cast_section(bytes, &instances)?,
                    top_nodes: cast_section(bytes, &top_nodes)?,
                    top_wide_nodes: match sections.get(SectionKind::TopWideNodes) {
                        Some(entry) => cast_section(bytes, &entry)?,
                        None => &[],
                    },
                }),
                _ => None,
            },
            split_references: triangles_entry.section_flags & SECTION_FLAG_SPLIT_REFERENCES != 0,
        })
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
        self.nodes
    }

    /// The triangles in leaf order.
    pub fn triangles(&self) -> &'a [PackedTriangle] {
        self.triangles
    }

    /// The source triangle id of each triangle, when the file has the optional ids section.
    pub fn triangle_ids(&self) -> Option<&'a [u32]> {
        self.triangle_ids
    }

    /// The source table, when present.
    pub fn source_table(&self) -> Option<&'a [SourceRange]> {
        self.source_table
    }

    /// The `triangle_flags` section (1.5), when present: element `i` holds the flags of triangle `i`
    /// ([`crate::format::TRIANGLE_NOT_OPAQUE`]). Without it every triangle is opaque.
    pub fn triangle_flags(&self) -> Option<&'a [u8]> {
        self.triangle_flags
    }

    /// Whether triangle record `index` is marked not opaque (its material may cut it out: a filtered tracer
    /// asks its filter about hits on it); `false` without a `triangle_flags` section or for an index out of range.
    pub fn is_not_opaque(&self, index: u32) -> bool {
        self.triangle_flags
            .and_then(|flags| flags.get(index as usize))
            .is_some_and(|&f| f & crate::format::TRIANGLE_NOT_OPAQUE != 0)
    }

    /// The `source_vertices` section (1.2), when present: element `i` holds the source vertex indices of
    /// triangle `i`'s `v0`, `v1`, `v2` ([`SourceVertexIndices`]; [`BvhView::source_corners`] pairs them with
    /// a hit's weights).
    pub fn source_vertices(&self) -> Option<&'a [SourceVertexIndices]> {
        self.source_vertices
    }

    /// The source range that a source triangle id belongs to (binary search; needs the source table).
    pub fn source_range_of(&self, source_triangle_id: u32) -> Option<&'a SourceRange> {
        let table = self.source_table?;
        let after = table.partition_point(|r| r.first_source_triangle <= source_triangle_id);
        let range = table.get(after.checked_sub(1)?)?;
        let offset = source_triangle_id - range.first_source_triangle;
        (offset < range.source_triangle_count).then_some(range)
    }

    /// The metadata section as raw bytes, when present.
    pub fn metadata_bytes(&self) -> Option<&'a [u8]> {
        self.metadata
    }

    /// The metadata as text; `Err` (rule V23) when it is not UTF-8. Checks O(metadata length) bytes.
    pub fn metadata_str(&self) -> Option<Result<&'a str, Violation>> {
        self.metadata.map(|bytes| {
            std::str::from_utf8(bytes)
                .map_err(|e| violation(Rule::Metadata, format!("metadata section: not UTF-8 ({e})")))
        })
    }

    /// Whether the triangles section allows a triangle to be referenced from several leaves.
    pub fn has_split_references(&self) -> bool {
        self.split_references
    }

    /// The wide BVH's sections, when the file has them (1.1).
    pub fn wide_sections(&self) -> Option<WideSections<'a>> {
        self.wide
    }

    /// The GPU layout's sections, when the file has them (1.4).
    pub fn gpu_sections(&self) -> Option<GpuSections<'a>> {
        self.gpu
    }

    /// The box of the whole scene in world space: the top-level root's in a two-level file, the root node's
    /// otherwise; `None` for an empty file.
    pub fn scene_box(&self) -> Option<([f32; 3], [f32; 3])> {
        let root = match self.two_level {
            Some(sections) => sections.top_nodes.first(),
            None => self.nodes.first(),
        };
        root.map(|root| (root.min, root.max))
    }

    /// The two-level sections (1.3), when the file places meshes by instances: its nodes, triangles and wide
    /// sections are then the meshes' trees, each in its object space, and the scene is the instances.
    pub fn two_level(&self) -> Option<TwoLevelSections<'a>> {
        self.two_level
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
        let mut view = BvhView {
            bytes,
            header,
            nodes: &[],
            triangles: &[],
            triangle_ids: None,
            source_table: None,
            source_vertices: None,
            triangle_flags: None,
            metadata: None,
            wide: None,
            gpu: None,
            two_level: None,
            split_references: false,
        };
        let mut wide_nodes: Option<&[WideNode8]> = None;
        let mut packets: Option<&[TrianglePacket4]> = None;
        let mut meshes: Option<&[MeshRecord]> = None;
        let mut instances: Option<&[InstanceRecord]> = None;
        let mut top_nodes: Option<&[PackedNode]> = None;
        let mut top_wide_nodes: &[WideNode8] = &[];
        let mut gpu_nodes: Option<&[GpuNode]> = None;
        let mut gpu_triangles: Option<&[GpuTriangle]> = None;
        for info in section_infos(bytes, &header) {
            let entry = &info.entry;
            let start = entry.section_byte_offset as usize;
            let len = entry.element_count as usize;
            // SAFETY: for all arms, V5 and V6 (guaranteed by the caller) place `len` elements of the kind's size at
            // `start`, inside `bytes`; `start` is a multiple of 64 and `bytes` is 4-byte aligned (checked by
            // `open`), so the pointer is aligned for the element type, which is Pod (any bit pattern is valid).
            unsafe {
                let base = bytes.as_ptr().add(start);
                match info.kind {
                    Some(SectionKind::Nodes) => view.nodes = std::slice::from_raw_parts(base.cast(), len),
                    Some(SectionKind::Triangles) => {
                        view.triangles = std::slice::from_raw_parts(base.cast(), len);
                        view.split_references = entry.section_flags & SECTION_FLAG_SPLIT_REFERENCES != 0;
                    }
                    Some(SectionKind::TriangleIds) => {
                        view.triangle_ids = Some(std::slice::from_raw_parts(base.cast(), len))
                    }
                    Some(SectionKind::SourceTable) => {
                        view.source_table = Some(std::slice::from_raw_parts(base.cast(), len))
                    }
                    Some(SectionKind::Metadata) => view.metadata = Some(std::slice::from_raw_parts(base, len)),
                    Some(SectionKind::SourceVertices) => {
                        view.source_vertices = Some(std::slice::from_raw_parts(base.cast(), len))
                    }
                    Some(SectionKind::TriangleFlags) => {
                        view.triangle_flags = Some(std::slice::from_raw_parts(base, len))
                    }
                    Some(SectionKind::WideNodes) => wide_nodes = Some(std::slice::from_raw_parts(base.cast(), len)),
                    Some(SectionKind::TrianglePackets) => packets = Some(std::slice::from_raw_parts(base.cast(), len)),
                    Some(SectionKind::Meshes) => meshes = Some(std::slice::from_raw_parts(base.cast(), len)),
                    Some(SectionKind::Instances) => instances = Some(std::slice::from_raw_parts(base.cast(), len)),
                    Some(SectionKind::TopNodes) => top_nodes = Some(std::slice::from_raw_parts(base.cast(), len)),
                    Some(SectionKind::TopWideNodes) => top_wide_nodes = std::slice::from_raw_parts(base.cast(), len),
                    Some(SectionKind::GpuNodes) => gpu_nodes = Some(std::slice::from_raw_parts(base.cast(), len)),
                    Some(SectionKind::GpuTriangles) => {
                        gpu_triangles = Some(std::slice::from_raw_parts(base.cast(), len))
                    }
                    _ => {}
                }
            }
        }
        if let (Some(nodes), Some(packets)) = (wide_nodes, packets) {
            view.wide = Some(WideSections { nodes, packets });
        }
        if let (Some(nodes), Some(triangles)) = (gpu_nodes, gpu_triangles) {
            view.gpu = Some(GpuSections { nodes, triangles });
        }
        if let (Some(meshes), Some(instances), Some(top_nodes)) = (meshes, instances, top_nodes) {
            view.two_level = Some(TwoLevelSections { meshes, instances, top_nodes, top_wide_nodes });
        }
        view
    }
}

/// The bytes of a section. Requires V5 (the section lies inside `bytes`).
pub(crate) fn section_bytes<'a>(bytes: &'a [u8], entry: &SectionEntry) -> &'a [u8] {
    let start = entry.section_byte_offset as usize;
    let end = start + entry.section_byte_len as usize;
    bytes.get(start..end).unwrap_or(&[])
}

/// A section as a typed slice. Requires V5, V6 and V9.
fn cast_section<'a, T: bytemuck::Pod>(bytes: &'a [u8], entry: &SectionEntry) -> Result<&'a [T], Violation> {
    bytemuck::try_cast_slice(section_bytes(bytes, entry)).map_err(|e| {
        violation(
            Rule::SectionKindLayout,
            format!("section at byte {}: cannot be viewed ({e})", entry.section_byte_offset),
        )
    })
}
