//! Writing into an owned file in place ([`BvhFile::edit`]): typed mutable slices of the sections a layout's
//! encoder rewrites (node boxes, triangle records, GPU nodes, instance transforms), with the checksums of those
//! sections and of the header recomputed when the edit ends, so the file's bytes stay a valid file whenever the
//! new contents keep the rules (section offsets, sizes and every other section are untouched).
//!
//! The metadata is not rewritten here (its length may change, which moves every later section): an edit that
//! changes boxes changes the tree's costs, which rule V37 compares with the metadata's, so such a file verifies
//! again once `BvhFile::rewritten` (feature `write`) has written it anew with its costs recomputed.

use crate::error::Error;
use crate::format::checksum::{HEADER_CHECKSUM_BYTE_OFFSET, header_checksum, section_checksum};
use crate::format::{
    GpuNode, GpuTriangle, HEADER_BYTE_LEN, InstanceRecord, MeshRecord, PackedNode, PackedTriangle, SectionEntry,
    SectionKind, SourceRange, SourceVertexIndices, TrianglePacket4, WideNode8,
};
use crate::open::view::BvhView;

/// The sections of a file (`BvhFile::edit`, `BvhViewMut::edit`) that an edit may rewrite, as typed mutable slices (`None`: the file has no such
/// section). Dropping it recomputes their checksums and the header's.
pub struct SectionsMut<'a> {
    /// The `nodes` section.
    pub nodes: &'a mut [PackedNode],
    /// The `triangles` section.
    pub triangles: &'a mut [PackedTriangle],
    /// The `wide_nodes` section.
    pub wide_nodes: Option<&'a mut [WideNode8]>,
    /// The `triangle_packets` section.
    pub triangle_packets: Option<&'a mut [TrianglePacket4]>,
    /// The `gpu_nodes` section.
    pub gpu_nodes: Option<&'a mut [GpuNode]>,
    /// The `gpu_triangles` section.
    pub gpu_triangles: Option<&'a mut [GpuTriangle]>,
    /// The `instances` section of a two-level file.
    pub instances: Option<&'a mut [InstanceRecord]>,
    /// The `top_nodes` section of a two-level file.
    pub top_nodes: Option<&'a mut [PackedNode]>,
    /// The `top_wide_nodes` section of a two-level file.
    pub top_wide_nodes: Option<&'a mut [WideNode8]>,
    /// The `triangle_ids` section, read only (an edit keeps the records' identities).
    pub triangle_ids: Option<&'a [u32]>,
    /// The `source_table` section, read only.
    pub source_table: Option<&'a [SourceRange]>,
    /// The `source_vertices` section, read only.
    pub source_vertices: Option<&'a [SourceVertexIndices]>,
    /// The `meshes` section of a two-level file, read only.
    pub meshes: Option<&'a [MeshRecord]>,
    /// The header and the section table, where the checksums go.
    table: &'a mut [u8],
    /// The section table's stride and, per editable section, its table index.
    stride: usize,
    entries: Vec<(usize, SectionKind)>,
    /// Whether the edit ended without recomputing the checksums (`end_without_checksums`).
    checksums_left: bool,
}

/// The kinds an edit hands out read only, beside the editable ones.
const READ_ONLY: [SectionKind; 4] =
    [SectionKind::TriangleIds, SectionKind::SourceTable, SectionKind::SourceVertices, SectionKind::Meshes];

/// The kinds an edit hands out.
const EDITABLE: [SectionKind; 9] = [
    SectionKind::Nodes,
    SectionKind::Triangles,
    SectionKind::WideNodes,
    SectionKind::TrianglePackets,
    SectionKind::GpuNodes,
    SectionKind::GpuTriangles,
    SectionKind::Instances,
    SectionKind::TopNodes,
    SectionKind::TopWideNodes,
];

impl<'a> SectionsMut<'a> {
    /// `bytes` (an opened file's, V1-V10 holding) split into the editable sections.
    pub(crate) fn split(bytes: &'a mut [u8]) -> Result<SectionsMut<'a>, Error> {
        let view = BvhView::open(bytes)?;
        let header = *view.header();
        let handed_out = |k: SectionKind| EDITABLE.contains(&k) || READ_ONLY.contains(&k);
        let mut editable: Vec<_> = view.sections().filter(|s| s.kind.is_some_and(handed_out)).collect::<Vec<_>>();
        editable.sort_by_key(|s| s.entry.section_byte_offset);
        let stride = header.section_entry_byte_len as usize;
        let table_len = HEADER_BYTE_LEN + header.section_count as usize * stride;
        let bad = |why: String| Error::Unwritable(format!("editing the file: {why}"));
        let (table, mut rest) = bytes.split_at_mut(table_len.min(bytes.len()));
        let mut consumed = table.len();
        let mut sections: [Option<&mut [u8]>; EDITABLE.len()] = Default::default();
        let mut read_only: [Option<&[u8]>; READ_ONLY.len()] = Default::default();
        let mut entries = Vec::with_capacity(editable.len());
        for info in &editable {
            let kind = info.kind.unwrap_or(SectionKind::Nodes);
            let (offset, len) = (info.entry.section_byte_offset as usize, info.entry.section_byte_len as usize);
            let gap = offset.checked_sub(consumed).ok_or_else(|| bad(format!("section {kind:?} overlaps another")))?;
            let tail = std::mem::take(&mut rest);
            if gap.saturating_add(len) > tail.len() {
                return Err(bad(format!("section {kind:?} lies outside the file")));
            }
            let (section, tail) = tail[gap..].split_at_mut(len);
            rest = tail;
            consumed = offset + len;
            if let Some(slot) = READ_ONLY.iter().position(|&k| k == kind) {
                let section: &[u8] = section;
                read_only[slot] = Some(section);
                continue;
            }
            let slot = EDITABLE.iter().position(|&k| k == kind).unwrap_or(0);
            sections[slot] = Some(section);
            entries.push((info.table_index, kind));
        }
        let [nodes, triangles, wide_nodes, packets, gpu_nodes, gpu_triangles, instances, top_nodes, top_wide] =
            sections;
        fn typed<T: bytemuck::Pod>(bytes: Option<&mut [u8]>) -> Result<Option<&mut [T]>, Error> {
            bytes
                .map(|b| bytemuck::try_cast_slice_mut(b))
                .transpose()
                .map_err(|e| Error::Unwritable(format!("editing the file: a section cannot be typed: {e}")))
        }
        fn typed_ref<T: bytemuck::Pod>(bytes: Option<&[u8]>) -> Result<Option<&[T]>, Error> {
            bytes
                .map(|b| bytemuck::try_cast_slice(b))
                .transpose()
                .map_err(|e| Error::Unwritable(format!("editing the file: a section cannot be typed: {e}")))
        }
        let [triangle_ids, source_table, source_vertices, meshes] = read_only;
        let nodes = typed(Some(nodes.ok_or_else(|| bad("no nodes section".to_string()))?))?;
        let triangles = typed(Some(triangles.ok_or_else(|| bad("no triangles section".to_string()))?))?;
        Ok(SectionsMut {
            nodes: nodes.unwrap_or_default(),
            triangles: triangles.unwrap_or_default(),
            wide_nodes: typed(wide_nodes)?,
            triangle_packets: typed(packets)?,
            gpu_nodes: typed(gpu_nodes)?,
            gpu_triangles: typed(gpu_triangles)?,
            instances: typed(instances)?,
            top_nodes: typed(top_nodes)?,
            top_wide_nodes: typed(top_wide)?,
            triangle_ids: typed_ref(triangle_ids)?,
            source_table: typed_ref(source_table)?,
            source_vertices: typed_ref(source_vertices)?,
            meshes: typed_ref(meshes)?,
            table,
            stride,
            entries,
            checksums_left: false,
        })
    }
}

impl SectionsMut<'_> {
    /// The bytes of the editable section `kind`, as they stand now.
    fn bytes_of(&self, kind: SectionKind) -> &[u8] {
        fn raw<'s, T: bytemuck::Pod>(slice: Option<&'s &mut [T]>) -> &'s [u8] {
            slice.map_or(&[], |s| bytemuck::cast_slice(s))
        }
        match kind {
            SectionKind::Nodes => bytemuck::cast_slice(self.nodes),
            SectionKind::Triangles => bytemuck::cast_slice(self.triangles),
            SectionKind::WideNodes => raw(self.wide_nodes.as_ref()),
            SectionKind::TrianglePackets => raw(self.triangle_packets.as_ref()),
            SectionKind::GpuNodes => raw(self.gpu_nodes.as_ref()),
            SectionKind::GpuTriangles => raw(self.gpu_triangles.as_ref()),
            SectionKind::Instances => raw(self.instances.as_ref()),
            SectionKind::TopNodes => raw(self.top_nodes.as_ref()),
            SectionKind::TopWideNodes => raw(self.top_wide_nodes.as_ref()),
            _ => &[],
        }
    }
}

impl SectionsMut<'_> {
    /// Ends the edit leaving the checksums as they were, so that they describe the bytes before it: for a refit,
    /// whose file verifies again only once `BvhFile::rewritten` has recomputed the metadata's costs, which
    /// computes the checksums too. Hashing every section of a large file costs about a tenth of its refit.
    pub(crate) fn end_without_checksums(mut self) {
        self.checksums_left = true;
    }

    /// Writes each editable section's checksum into its table entry, then the header's checksum.
    fn write_checksums(&mut self) {
        let field = std::mem::offset_of!(SectionEntry, section_checksum);
        for index in 0..self.entries.len() {
            let (table_index, kind) = self.entries[index];
            let checksum = section_checksum(self.bytes_of(kind));
            let at = HEADER_BYTE_LEN + table_index * self.stride + field;
            if let Some(slot) = self.table.get_mut(at..at + 8) {
                slot.copy_from_slice(&checksum.to_le_bytes());
            }
        }
        let checksum = header_checksum(self.table);
        if let Some(slot) = self.table.get_mut(HEADER_CHECKSUM_BYTE_OFFSET..HEADER_CHECKSUM_BYTE_OFFSET + 8) {
            slot.copy_from_slice(&checksum.to_le_bytes());
        }
    }
}

impl Drop for SectionsMut<'_> {
    /// Writes the checksums, unless the edit ended without them (a refit's).
    fn drop(&mut self) {
        if !self.checksums_left {
            self.write_checksums();
        }
    }
}
