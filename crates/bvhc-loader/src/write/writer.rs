//! The writer: packed tree + triangles + ids + source table + metadata -> the bytes of a `.bvh` file.
//!
//! It lays the file out exactly as `format-spec/bvh-1.md` describes (header, section table, sections in
//! table order at 64-byte-aligned offsets, zero padding), fills in the checksums, and then runs the full
//! verifier over the result, so it never hands out a file that a reader would reject.

use std::path::Path;

use crate::error::Error;
use crate::format::checksum::{header_checksum, section_checksum};
use crate::format::{
    FileHeader, GpuNode, GpuTriangle, HEADER_BYTE_LEN, MAGIC, MinorFeatures, PackedNode, PackedTriangle,
    SECTION_ENTRY_BYTE_LEN, SECTION_FLAG_REQUIRED, SECTION_FLAG_SPLIT_REFERENCES, SectionEntry, SectionKind,
    SourceRange, SourceVertexIndices, TrianglePacket4, VERSION_MAJOR, WideNode8, align_up, written_minor,
};
use crate::open::file::{AlignedBuffer, BvhFile};
use crate::open::sections::{GpuSections, SectionSet, TwoLevelSections, WideSections};
use crate::open::view::{BvhView, section_bytes};
use crate::write::atomic::write_atomic;

/// Collects the parts of a `.bvh` file; [`BvhWriter::build`] lays them out.
#[derive(Clone, Debug)]
pub struct BvhWriter<'a> {
    /// The sections of known kinds, laid out in [`SectionKind::ALL`]'s order.
    sections: SectionSet<'a>,
    extra_sections: Vec<ExtraSection<'a>>,
    /// The lowest minor version to write (0 but for a copy of a file, which keeps its version).
    minor_at_least: u16,
}

/// A section of a kind this crate does not define (an extension, or a test of forward compatibility).
#[derive(Clone, Copy, Debug)]
struct ExtraSection<'a> {
    kind: u32,
    section_flags: u32,
    element_byte_len: u32,
    bytes: &'a [u8],
}

/// One section to lay out: its table entry (offset and checksum filled in later) and its bytes.
struct Planned<'a> {
    entry: SectionEntry,
    bytes: &'a [u8],
}

impl<'a> BvhWriter<'a> {
    /// A file holding `nodes` (node 0 the root, in the nodes section's layout) and `triangles` in leaf order.
    pub fn new(nodes: &'a [PackedNode], triangles: &'a [PackedTriangle]) -> Self {
        BvhWriter {
            sections: SectionSet { nodes, triangles, ..SectionSet::EMPTY },
            extra_sections: Vec::new(),
            minor_at_least: 0,
        }
    }

    /// A writer holding every section of `view` as it stands: the sections of kinds this version defines, and
    /// those of other kinds with their table entry's flags, element size and bytes; the file's minor version is
    /// kept (a writer from parts writes the lowest its sections need). Building it lays the same contents out
    /// again, the known kinds in [`SectionKind::ALL`]'s order, then the others in table order; a later call
    /// (say [`BvhWriter::metadata`]) replaces a section.
    pub fn from_view(view: &BvhView<'a>) -> Self {
        let bytes = view.bytes();
        let extra_sections = view
            .sections()
            .filter(|info| info.kind.is_none())
            .map(|info| ExtraSection {
                kind: info.entry.kind,
                section_flags: info.entry.section_flags,
                element_byte_len: info.entry.element_byte_len,
                bytes: section_bytes(bytes, &info.entry),
            })
            .collect();
        BvhWriter { sections: view.section_set(), extra_sections, minor_at_least: view.version().1 }
    }

    /// Adds the triangle_ids section: one source id per triangle.
    pub fn triangle_ids(mut self, ids: &'a [u32]) -> Self {
        self.sections.triangle_ids = Some(ids);
        self
    }

    /// Adds the source_table section (needs triangle ids).
    pub fn source_table(mut self, ranges: &'a [SourceRange]) -> Self {
        self.sections.source_table = Some(ranges);
        self
    }

    /// Adds the source_vertices section (format 1.2; needs the source table): per triangle, in the order of
    /// [`BvhWriter::new`]'s triangles, the source vertex indices of its `v0`, `v1`, `v2`. The file is then
    /// written as version 1.2.
    pub fn source_vertices(mut self, indices: &'a [SourceVertexIndices]) -> Self {
        self.sections.source_vertices = Some(indices);
        self
    }

    /// Adds the triangle_flags section (format 1.5): per triangle, in the order of [`BvhWriter::new`]'s
    /// triangles, its flags ([`crate::format::TRIANGLE_NOT_OPAQUE`]). The file is then written as version 1.5.
    pub fn triangle_flags(mut self, flags: &'a [u8]) -> Self {
        self.sections.triangle_flags = Some(flags);
        self
    }

    /// Adds the metadata section: a JSON object as text.
    pub fn metadata(mut self, json: &'a str) -> Self {
        self.sections.metadata = Some(json.as_bytes());
        self
    }

    /// Marks the triangles section as holding split references (a triangle may appear in several leaves).
    pub fn split_references(mut self, split: bool) -> Self {
        self.sections.split_references = split;
        self
    }

    /// Adds the wide BVH (format 1.1): the `wide_nodes` and `triangle_packets` sections, whose lanes index the
    /// triangles given to [`BvhWriter::new`]. The file is then written as version 1.1.
    pub fn wide(mut self, nodes: &'a [WideNode8], packets: &'a [TrianglePacket4]) -> Self {
        self.sections.wide = Some(WideSections { nodes, packets });
        self
    }

    /// Adds the GPU sections (format 1.4): compressed 8-wide nodes and their leaf triangles over the same
    /// triangles section (`format-spec/bvh-1.md` 5.14-5.15). The file is then written as version 1.4.
    pub fn gpu(mut self, nodes: &'a [GpuNode], triangles: &'a [GpuTriangle]) -> Self {
        self.sections.gpu = Some(GpuSections { nodes, triangles });
        self
    }

    /// Makes the file two-level (format 1.3): the nodes, triangles (and their ids and source vertices) and wide
    /// sections given to the other calls are the meshes' trees laid out as `sections.meshes` says (indices
    /// relative to each mesh's ranges), placed in world space by `sections.instances` under the top-level
    /// tree `sections.top_nodes` (and its 8-wide form `sections.top_wide_nodes`, which a file with wide sections
    /// needs; `format-spec/bvh-1.md` 5.10-5.13). The file is then written as version 1.3.
    pub fn two_level(mut self, sections: TwoLevelSections<'a>) -> Self {
        self.sections.two_level = Some(sections);
        self
    }

    /// The minor version the file will have: the lowest its sections need ([`written_minor`]), or a copied
    /// file's own where that is higher ([`BvhWriter::from_view`]).
    pub fn version_minor(&self) -> u16 {
        self.minor_at_least.max(written_minor(MinorFeatures {
            wide: self.sections.wide.is_some(),
            source_vertices: self.sections.source_vertices.is_some(),
            instances: self.sections.two_level.is_some(),
            gpu: self.sections.gpu.is_some(),
            triangle_flags: self.sections.triangle_flags.is_some(),
        }))
    }

    /// Appends a section of a kind that this version does not define. `required` sets its REQUIRED flag, which
    /// makes readers that do not know `kind` reject the file.
    pub fn extra_section(mut self, kind: u32, required: bool, element_byte_len: u32, bytes: &'a [u8]) -> Self {
        let section_flags = if required { SECTION_FLAG_REQUIRED } else { 0 };
        self.extra_sections.push(ExtraSection { kind, section_flags, element_byte_len, bytes });
        self
    }

    /// Lays the file out, verifies it fully, and returns it opened.
    pub fn build(&self) -> Result<BvhFile, Error> {
        let buffer = self.layout()?;
        let file = BvhFile::from_buffer(buffer)?;
        file.view().verify()?;
        Ok(file)
    }

    /// Builds the file and writes it to `path` atomically (see [`write_atomic`]).
    pub fn write_atomic(&self, path: &Path) -> Result<BvhFile, Error> {
        let file = self.build()?;
        write_atomic(path, file.as_bytes())?;
        Ok(file)
    }

    fn planned_sections(&self) -> Result<Vec<Planned<'a>>, Error> {
        let mut planned = Vec::new();
        let mut known = |kind: SectionKind, bytes: &'a [u8], count: usize, flags: u32| {
            let flags = flags | if kind.is_required() { SECTION_FLAG_REQUIRED } else { 0 };
            planned.push(plan(kind.code(), flags, kind.element_byte_len(), count, bytes));
        };
        for (kind, bytes, count) in self.sections.present() {
            let split = kind == SectionKind::Triangles && self.sections.split_references;
            known(kind, bytes, count, if split { SECTION_FLAG_SPLIT_REFERENCES } else { 0 });
        }
        for extra in &self.extra_sections {
            if extra.element_byte_len == 0 || extra.bytes.len() % extra.element_byte_len as usize != 0 {
                return Err(Error::Unwritable(format!(
                    "extra section of kind {}: {} bytes are not a whole number of {}-byte elements",
                    extra.kind,
                    extra.bytes.len(),
                    extra.element_byte_len
                )));
            }
            let count = extra.bytes.len() / extra.element_byte_len as usize;
            planned.push(plan(extra.kind, extra.section_flags, extra.element_byte_len, count, extra.bytes));
        }
        Ok(planned)
    }

    /// Writes the file's bytes to `out` section by section, from the borrowed slices (the file is never laid
    /// out in memory), and returns its byte length. Unlike [`BvhWriter::build`] this does not verify: the
    /// caller reads the written file back and verifies it (`BvhFile::read` or `read_uncached`, then `verify`)
    /// before using it, after freeing what the sections were borrowed from, so that the file is in memory once
    /// at most. A failed write of `out` (a full disk) is [`Error::Io`] naming `out_path`, the file `out` writes.
    pub fn write_unverified(&self, out: &mut impl std::io::Write, out_path: &Path) -> Result<u64, Error> {
        let (head, sections) = self.plan_layout()?;
        let io = |source| Error::Io { path: out_path.to_path_buf(), source };
        out.write_all(&head).map_err(io)?;
        let mut at = head.len() as u64;
        let zeros = [0u8; 64];
        for section in &sections {
            let padding = (section.entry.section_byte_offset - at) as usize;
            out.write_all(&zeros[..padding]).map_err(io)?;
            out.write_all(section.bytes).map_err(io)?;
            at = section.entry.section_byte_offset + section.entry.section_byte_len;
        }
        Ok(at)
    }

    fn layout(&self) -> Result<AlignedBuffer, Error> {
        let (head, sections) = self.plan_layout()?;
        let file_byte_len =
            sections.last().map_or(head.len() as u64, |s| s.entry.section_byte_offset + s.entry.section_byte_len);
        let file_byte_len = usize::try_from(file_byte_len)
            .map_err(|_| Error::Unwritable("the file would not fit in memory".to_string()))?;
        let mut buffer = AlignedBuffer::zeroed(file_byte_len)?;
        let bytes = buffer.as_bytes_mut();
        bytes[..head.len()].copy_from_slice(&head);
        for section in &sections {
            let offset = section.entry.section_byte_offset as usize;
            bytes[offset..offset + section.bytes.len()].copy_from_slice(section.bytes);
        }
        Ok(buffer)
    }

    /// The header and section table as bytes (checksums filled in) and the sections with their offsets: every
    /// section starts at the next 64-byte boundary after the previous one (or after the table), the gaps zero.
    fn plan_layout(&self) -> Result<(Vec<u8>, Vec<Planned<'a>>), Error> {
        let mut sections = self.planned_sections()?;
        let too_large = || Error::Unwritable("the file would exceed 2^64 bytes".to_string());
        let table_end = HEADER_BYTE_LEN + sections.len() * SECTION_ENTRY_BYTE_LEN;
        let mut end = table_end as u64;
        for section in &mut sections {
            let offset = align_up(end).ok_or_else(too_large)?;
            section.entry.section_byte_offset = offset;
            section.entry.section_checksum = section_checksum(section.bytes);
            end = offset.checked_add(section.entry.section_byte_len).ok_or_else(too_large)?;
        }
        let header = FileHeader {
            magic: MAGIC,
            version_major: VERSION_MAJOR,
            version_minor: self.version_minor(),
            header_flags: 0,
            file_byte_len: end,
            section_count: u32::try_from(sections.len()).map_err(|_| Error::Unwritable("too many sections".into()))?,
            section_entry_byte_len: SECTION_ENTRY_BYTE_LEN as u32,
            header_checksum: 0,
            reserved: [0; 3],
        };
        let mut head = Vec::with_capacity(table_end);
        head.extend_from_slice(bytemuck::bytes_of(&header));
        for section in &sections {
            head.extend_from_slice(bytemuck::bytes_of(&section.entry));
        }
        let header = FileHeader { header_checksum: header_checksum(&head), ..header };
        head[..HEADER_BYTE_LEN].copy_from_slice(bytemuck::bytes_of(&header));
        Ok((head, sections))
    }
}

fn plan(kind: u32, section_flags: u32, element_byte_len: u32, count: usize, bytes: &[u8]) -> Planned<'_> {
    Planned {
        entry: SectionEntry {
            kind,
            section_flags,
            section_byte_offset: 0,
            section_byte_len: bytes.len() as u64,
            element_count: count as u64,
            element_byte_len,
            reserved: 0,
            section_checksum: 0,
        },
        bytes,
    }
}
