//! [`BvhView`]: a borrowed, structurally checked view of a `.bvh` file's bytes.
//!
//! Opening reads the header and the section table and checks rules V1-V10 of `format-spec/bvh-1.md`; it costs
//! O(number of sections) and never touches node or triangle data. [`BvhView::verify`] checks the rest.

use crate::error::{Error, Rule, Violation, violation};
use crate::format::{
    FileHeader, HEADER_BYTE_LEN, MAGIC, MAX_PACKET_COUNT, PACKET_LANES, PackedNode, PackedTriangle, SECTION_ALIGNMENT,
    SECTION_ENTRY_BYTE_LEN, SECTION_FLAG_REQUIRED, SECTION_FLAG_SPLIT_REFERENCES, SectionEntry, SectionKind,
    SourceRange, TrianglePacket4, VERSION_MAJOR, WideNode8, is_known_minor,
};
use crate::simd::KernelPath;
use crate::traverse::Tracer;
use crate::wide::WideTracer;

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
    metadata: Option<&'a [u8]>,
    wide: Option<WideSections<'a>>,
    split_references: bool,
}

/// The two sections of the wide BVH (since 1.1), which a file has together or not at all (rule V8).
#[derive(Clone, Copy, Debug)]
pub struct WideSections<'a> {
    /// The `wide_nodes` section; node 0 is the root.
    pub nodes: &'a [WideNode8],
    /// The `triangle_packets` section.
    pub packets: &'a [TrianglePacket4],
}

/// One entry of the section table, with its kind decoded when this version defines it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SectionInfo {
    /// Position in the section table.
    pub table_index: usize,
    /// The kind, or `None` for a kind this reader does not know (skipped, as the compatibility rules say).
    pub kind: Option<SectionKind>,
    /// The raw entry.
    pub entry: SectionEntry,
}

impl<'a> BvhView<'a> {
    /// Opens `bytes` as a `.bvh` file, checking rules V1-V10 (O(number of sections)).
    ///
    /// `bytes` must start at a 4-byte-aligned address (a [`crate::file::BvhFile`] or a memory map always does);
    /// otherwise [`Error::Misaligned`] is returned. Call [`BvhView::verify`] before trusting the contents.
    pub fn open(bytes: &'a [u8]) -> Result<BvhView<'a>, Error> {
        if cfg!(target_endian = "big") {
            return Err(Error::BigEndianHost);
        }
        let header = read_header(bytes)?;
        let address = bytes.as_ptr() as usize;
        if !address.is_multiple_of(align_of::<u32>()) {
            return Err(Error::Misaligned { address });
        }
        let table_end = check_table(bytes, &header)?;
        let mut known: [Option<SectionEntry>; SectionKind::ALL.len()] = [None; SectionKind::ALL.len()];
        let mut previous_end = table_end;
        for info in section_infos(bytes, &header) {
            let previous = previous_end;
            previous_end = check_entry(&info, &header, previous)?;
            if let Some(kind) = info.kind {
                let slot = &mut known[kind_slot(kind)];
                if slot.is_some() {
                    return Err(violation(
                        Rule::SectionMultiplicity,
                        format!("section {}: second {} section", info.table_index, kind.name()),
                    )
                    .into());
                }
                *slot = Some(info.entry);
            }
        }
        let sections = KnownSections(known);
        let nodes_entry = sections.get(SectionKind::Nodes).ok_or_else(|| missing(SectionKind::Nodes))?;
        let triangles_entry = sections.get(SectionKind::Triangles).ok_or_else(|| missing(SectionKind::Triangles))?;
        if sections.get(SectionKind::WideNodes).is_some() != sections.get(SectionKind::TrianglePackets).is_some() {
            return Err(violation(
                Rule::SectionMultiplicity,
                "a file has both wide_nodes and triangle_packets sections or neither".to_string(),
            )
            .into());
        }
        if header.version_minor == 0 && sections.get(SectionKind::WideNodes).is_some() {
            return Err(violation(
                Rule::SectionMultiplicity,
                "a 1.0 file has wide_nodes and triangle_packets sections, which came with 1.1: its version_minor \
                 must be 1"
                    .to_string(),
            )
            .into());
        }
        check_counts(&sections)?;
        Ok(BvhView {
            bytes,
            header,
            nodes: cast_section(bytes, &nodes_entry)?,
            triangles: cast_section(bytes, &triangles_entry)?,
            triangle_ids: sections.get(SectionKind::TriangleIds).map(|e| cast_section(bytes, &e)).transpose()?,
            source_table: sections.get(SectionKind::SourceTable).map(|e| cast_section(bytes, &e)).transpose()?,
            metadata: sections.get(SectionKind::Metadata).map(|e| section_bytes(bytes, &e)),
            wide: match (sections.get(SectionKind::WideNodes), sections.get(SectionKind::TrianglePackets)) {
                (Some(nodes), Some(packets)) => {
                    Some(WideSections { nodes: cast_section(bytes, &nodes)?, packets: cast_section(bytes, &packets)? })
                }
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

    /// The fastest traversal kernel for this file on this machine: the wide kernel on the best SIMD path when
    /// the file has wide sections, the binary kernel otherwise. Both report the same closest `t` and any-hit
    /// answers (the tests check it); triangle indices refer to the triangles section either way.
    ///
    /// Tracing never panics or loops forever, whatever the bytes; on a file that fails [`BvhView::verify`] the
    /// hits it returns are unspecified.
    pub fn tracer(&self) -> Tracer<'a> {
        match self.wide_tracer(KernelPath::best()) {
            Some(wide) => self.binary_tracer().with_wide(wide),
            None => self.binary_tracer(),
        }
    }

    /// The binary kernel over the nodes and triangles sections: the reference traversal.
    pub fn binary_tracer(&self) -> Tracer<'a> {
        Tracer::new(self.nodes, self.triangles, self.triangle_ids)
    }

    /// The wide kernel on `path` (the portable one where `path` is not supported), when the file has wide
    /// sections.
    pub fn wide_tracer(&self, path: KernelPath) -> Option<WideTracer<'a>> {
        let wide = self.wide?;
        let root = self.nodes.first()?;
        Some(WideTracer::over(wide.nodes, wide.packets, (root.min, root.max), self.triangles, self.triangle_ids, path))
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
            metadata: None,
            wide: None,
            split_references: false,
        };
        let mut wide_nodes: Option<&[WideNode8]> = None;
        let mut packets: Option<&[TrianglePacket4]> = None;
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
                    Some(SectionKind::WideNodes) => wide_nodes = Some(std::slice::from_raw_parts(base.cast(), len)),
                    Some(SectionKind::TrianglePackets) => packets = Some(std::slice::from_raw_parts(base.cast(), len)),
                    None => {}
                }
            }
        }
        if let (Some(nodes), Some(packets)) = (wide_nodes, packets) {
            view.wide = Some(WideSections { nodes, packets });
        }
        view
    }
}

/// The known sections found in the table, by kind.
struct KnownSections([Option<SectionEntry>; SectionKind::ALL.len()]);

impl KnownSections {
    fn get(&self, kind: SectionKind) -> Option<SectionEntry> {
        self.0[kind_slot(kind)]
    }

    fn count(&self, kind: SectionKind) -> u64 {
        self.get(kind).map_or(0, |e| e.element_count)
    }
}

fn kind_slot(kind: SectionKind) -> usize {
    kind.code() as usize - 1
}

fn missing(kind: SectionKind) -> Error {
    violation(Rule::SectionMultiplicity, format!("no {} section", kind.name())).into()
}

/// V1-V3: reads the header.
fn read_header(bytes: &[u8]) -> Result<FileHeader, Violation> {
    let Some(head) = bytes.get(..HEADER_BYTE_LEN) else {
        return Err(violation(Rule::Magic, format!("file is {} bytes, shorter than the 64-byte header", bytes.len())));
    };
    let header: FileHeader = bytemuck::pod_read_unaligned(head);
    if header.magic != MAGIC {
        let hint = if head.starts_with(b"HIERARCHY") { " (this is a Biovision motion capture file)" } else { "" };
        return Err(violation(Rule::Magic, format!("header: bytes 0..8 are not the .bvh magic{hint}")));
    }
    if header.version_major != VERSION_MAJOR {
        return Err(violation(
            Rule::MajorVersion,
            format!(
                "header: version {}.{}, this reader reads major version {VERSION_MAJOR}",
                header.version_major, header.version_minor
            ),
        ));
    }
    if header.file_byte_len != bytes.len() as u64 {
        return Err(violation(
            Rule::FileByteLen,
            format!("header: file_byte_len {} but the file has {} bytes", header.file_byte_len, bytes.len()),
        ));
    }
    Ok(header)
}

/// V4: the section table fits; returns its end offset.
fn check_table(bytes: &[u8], header: &FileHeader) -> Result<u64, Violation> {
    let entry_len = header.section_entry_byte_len;
    if (entry_len as usize) < SECTION_ENTRY_BYTE_LEN || !entry_len.is_multiple_of(8) {
        return Err(violation(
            Rule::SectionTable,
            format!("header: section_entry_byte_len {entry_len} is below 48 or not a multiple of 8"),
        ));
    }
    u64::from(header.section_count)
        .checked_mul(u64::from(entry_len))
        .and_then(|table| table.checked_add(HEADER_BYTE_LEN as u64))
        .filter(|&end| end <= bytes.len() as u64)
        .ok_or_else(|| {
            violation(
                Rule::SectionTable,
                format!(
                    "header: section table of {} entries of {entry_len} bytes does not fit in {} bytes",
                    header.section_count,
                    bytes.len()
                ),
            )
        })
}

/// The section table's entries. Requires V4 (the table lies inside `bytes`).
pub(crate) fn section_infos<'a>(bytes: &'a [u8], header: &FileHeader) -> impl Iterator<Item = SectionInfo> + 'a {
    let stride = header.section_entry_byte_len as usize;
    (0..header.section_count as usize).filter_map(move |table_index| {
        let start = HEADER_BYTE_LEN + table_index * stride;
        let raw = bytes.get(start..start + SECTION_ENTRY_BYTE_LEN)?;
        let entry: SectionEntry = bytemuck::pod_read_unaligned(raw);
        Some(SectionInfo { table_index, kind: SectionKind::from_code(entry.kind), entry })
    })
}

/// V5-V9 for one entry; returns the section's end offset.
fn check_entry(info: &SectionInfo, header: &FileHeader, previous_end: u64) -> Result<u64, Violation> {
    let entry = &info.entry;
    let name = info.kind.map_or_else(|| format!("kind {}", entry.kind), |k| k.name().to_string());
    let at = format!("section {} ({name})", info.table_index);
    let offset = entry.section_byte_offset;
    let end = offset.checked_add(entry.section_byte_len).filter(|&end| end <= header.file_byte_len);
    let Some(end) = end.filter(|_| offset.is_multiple_of(SECTION_ALIGNMENT) && offset >= previous_end) else {
        return Err(violation(
            Rule::SectionPlacement,
            format!(
                "{at}: bytes {offset}..+{} must start at a multiple of 64, at or after byte {previous_end} \
                 (end of the table or of the previous section), and end within the file ({} bytes)",
                entry.section_byte_len, header.file_byte_len
            ),
        ));
    };
    let expected_len = entry.element_count.checked_mul(u64::from(entry.element_byte_len));
    if entry.element_byte_len == 0 || expected_len != Some(entry.section_byte_len) {
        return Err(violation(
            Rule::SectionSize,
            format!(
                "{at}: section_byte_len {} != element_count {} x element_byte_len {}",
                entry.section_byte_len, entry.element_count, entry.element_byte_len
            ),
        ));
    }
    let required = entry.section_flags & SECTION_FLAG_REQUIRED != 0;
    let Some(kind) = info.kind else {
        if required {
            return Err(violation(
                Rule::UnknownRequiredSection,
                format!(
                    "{at}: unknown section kind {} is marked required; this reader cannot use the file",
                    entry.kind
                ),
            ));
        }
        return Ok(end);
    };
    if entry.element_byte_len != kind.element_byte_len() {
        return Err(violation(
            Rule::SectionKindLayout,
            format!(
                "{at}: element_byte_len {} but {} elements are {} bytes",
                entry.element_byte_len,
                kind.name(),
                kind.element_byte_len()
            ),
        ));
    }
    if required != kind.is_required() {
        let should = if kind.is_required() { "set" } else { "clear" };
        return Err(violation(Rule::SectionKindLayout, format!("{at}: the REQUIRED flag must be {should}")));
    }
    let undefined = entry.section_flags & !kind.defined_flags();
    if undefined != 0 && is_known_minor(header.version_minor) {
        return Err(violation(Rule::SectionKindLayout, format!("{at}: undefined flag bits {undefined:#x} are set")));
    }
    Ok(end)
}

/// V10: counts agree with each other.
fn check_counts(sections: &KnownSections) -> Result<(), Violation> {
    let node_count = sections.count(SectionKind::Nodes);
    let triangle_count = sections.count(SectionKind::Triangles);
    let limit = u64::from(u32::MAX);
    let fail = |detail: String| Err(violation(Rule::Counts, detail));
    if node_count > limit || triangle_count > limit || sections.count(SectionKind::SourceTable) > limit {
        return fail(format!("node_count {node_count} or triangle_count {triangle_count} exceeds 2^32 - 1"));
    }
    if (node_count == 0) != (triangle_count == 0) {
        return fail(format!("node_count {node_count} and triangle_count {triangle_count}: both or neither must be 0"));
    }
    if node_count != 0 && (node_count.is_multiple_of(2) || node_count > 2 * triangle_count - 1) {
        return fail(format!(
            "node_count {node_count} must be odd and at most 2 x triangle_count - 1 = {}",
            2 * triangle_count - 1
        ));
    }
    let id_count = sections.get(SectionKind::TriangleIds).map(|ids| ids.element_count);
    if id_count.is_some_and(|count| count != triangle_count) {
        return fail(format!("triangle_ids has {} ids for {triangle_count} triangles", id_count.unwrap_or(0)));
    }
    if sections.get(SectionKind::SourceTable).is_some() && sections.get(SectionKind::TriangleIds).is_none() {
        return fail("a source_table section needs a triangle_ids section".to_string());
    }
    if sections.get(SectionKind::WideNodes).is_some() {
        check_wide_counts(
            sections.count(SectionKind::WideNodes),
            sections.count(SectionKind::TrianglePackets),
            triangle_count,
        )?;
    }
    Ok(())
}

/// V10 for the wide sections: a root exactly when there are triangles; between `ceil(triangle_count / 4)` and
/// `triangle_count` packets (each lane holds one triangle, each triangle one lane, a packet at least one lane),
/// at most one wide node per packet (every node but the root has two children or more), and packets within
/// what a leaf reference encodes.
fn check_wide_counts(wide_node_count: u64, packet_count: u64, triangle_count: u64) -> Result<(), Violation> {
    let min_packets = triangle_count.div_ceil(PACKET_LANES as u64);
    // `wide_node_count <= packet_count <= 2^28` also keeps every inner reference below `LEAF_BIT`.
    let ok = packet_count <= MAX_PACKET_COUNT
        && (wide_node_count == 0) == (triangle_count == 0)
        && (min_packets..=triangle_count).contains(&packet_count)
        && wide_node_count <= packet_count.max(1);
    if ok {
        return Ok(());
    }
    Err(violation(
        Rule::Counts,
        format!(
            "wide_nodes count {wide_node_count} and triangle_packets count {packet_count} for {triangle_count} \
             triangles: packets must number {min_packets}..={triangle_count} (at most 2^28), wide nodes 1..=packets \
             (none without triangles)"
        ),
    ))
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
