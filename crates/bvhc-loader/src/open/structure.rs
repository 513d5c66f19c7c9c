//! The structural rules V1-V10 of `format-spec/bvh-1.md`, which every open checks in O(number of sections):
//! the header, the section table, each entry's placement, size, kind and flags, which kinds a file has, and how
//! their element counts agree.

use crate::error::{Error, Rule, Violation, violation};
use crate::format::{
    FileHeader, HEADER_BYTE_LEN, MAGIC, MAX_PACKET_COUNT, PACKET_LANES, SECTION_ALIGNMENT, SECTION_ENTRY_BYTE_LEN,
    SECTION_FLAG_REQUIRED, SECTION_FLAG_SPLIT_REFERENCES, SectionEntry, SectionKind, VERSION_MAJOR, is_known_minor,
};

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

/// V1-V10: the header, the table, every entry, which known kinds the file has and their counts. Also refuses a
/// buffer that is not 4-byte aligned and a big-endian host, where sections cannot be viewed in place.
pub(crate) fn check_structure(bytes: &[u8]) -> Result<(FileHeader, KnownSections), Error> {
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
                let detail = format!("section {}: second {} section", info.table_index, kind.name());
                return Err(violation(Rule::SectionMultiplicity, detail).into());
            }
            if header.version_minor < kind.since_minor() {
                let detail = format!(
                    "section {}: a {}.{} file has a {} section, which came with 1.{}: its version_minor must be {} \
                     or more",
                    info.table_index,
                    header.version_major,
                    header.version_minor,
                    kind.name(),
                    kind.since_minor(),
                    kind.since_minor()
                );
                return Err(violation(Rule::SectionMultiplicity, detail).into());
            }
            *slot = Some(info.entry);
        }
    }
    let sections = KnownSections(known);
    for kind in [SectionKind::Nodes, SectionKind::Triangles] {
        sections.get(kind).ok_or_else(|| missing(kind))?;
    }
    if sections.get(SectionKind::WideNodes).is_some() != sections.get(SectionKind::TrianglePackets).is_some() {
        return Err(violation(
            Rule::SectionMultiplicity,
            "a file has both wide_nodes and triangle_packets sections or neither".to_string(),
        )
        .into());
    }
    let two_level = [SectionKind::Meshes, SectionKind::Instances, SectionKind::TopNodes].map(|k| sections.get(k));
    if two_level.iter().any(Option::is_some) && !two_level.iter().all(Option::is_some) {
        return Err(violation(
            Rule::SectionMultiplicity,
            "a file has all of the meshes, instances and top_nodes sections or none".to_string(),
        )
        .into());
    }
    let top_wide = sections.get(SectionKind::TopWideNodes).is_some();
    let wide_two_level = two_level[0].is_some() && sections.get(SectionKind::WideNodes).is_some();
    if top_wide != wide_two_level {
        return Err(violation(
            Rule::SectionMultiplicity,
            "a top_wide_nodes section comes exactly with a two-level file's wide sections".to_string(),
        )
        .into());
    }
    let gpu = [SectionKind::GpuNodes, SectionKind::GpuTriangles].map(|k| sections.get(k).is_some());
    if gpu[0] != gpu[1] {
        return Err(violation(
            Rule::SectionMultiplicity,
            "a file has both gpu_nodes and gpu_triangles sections or neither".to_string(),
        )
        .into());
    }
    if gpu[0] && two_level[0].is_some() {
        return Err(violation(
            Rule::SectionMultiplicity,
            "gpu_nodes and gpu_triangles are defined for one-level files only (1.4), not with meshes".to_string(),
        )
        .into());
    }
    check_counts(&sections)?;
    Ok((header, sections))
}

/// The known sections found in the table, by kind.
pub(crate) struct KnownSections([Option<SectionEntry>; SectionKind::ALL.len()]);

impl KnownSections {
    pub(crate) fn get(&self, kind: SectionKind) -> Option<SectionEntry> {
        self.0[kind_slot(kind)]
    }

    fn count(&self, kind: SectionKind) -> u64 {
        self.get(kind).map_or(0, |e| e.element_count)
    }
}

fn kind_slot(kind: SectionKind) -> usize {
    kind.code() as usize - 1
}

pub(crate) fn missing(kind: SectionKind) -> Error {
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
    // A two-level file's nodes are its meshes' trees, each of odd size (V41), so their sum need not be odd.
    let two_level = sections.get(SectionKind::Meshes).is_some();
    if node_count != 0 && ((!two_level && node_count.is_multiple_of(2)) || node_count > 2 * triangle_count - 1) {
        return fail(format!(
            "node_count {node_count} must be odd (in a one-level file) and at most 2 x triangle_count - 1 = {}",
            2 * triangle_count - 1
        ));
    }
    if two_level {
        check_two_level_counts(sections, triangle_count)?;
    }
    let id_count = sections.get(SectionKind::TriangleIds).map(|ids| ids.element_count);
    if id_count.is_some_and(|count| count != triangle_count) {
        return fail(format!("triangle_ids has {} ids for {triangle_count} triangles", id_count.unwrap_or(0)));
    }
    if sections.get(SectionKind::SourceTable).is_some() && sections.get(SectionKind::TriangleIds).is_none() {
        return fail("a source_table section needs a triangle_ids section".to_string());
    }
    if let Some(entry) = sections.get(SectionKind::SourceVertices) {
        if sections.get(SectionKind::SourceTable).is_none() {
            return fail("a source_vertices section needs a source_table section".to_string());
        }
        if entry.element_count != triangle_count {
            return fail(format!(
                "source_vertices has {} elements for {triangle_count} triangles",
                entry.element_count
            ));
        }
    }
    let flag_count = sections.get(SectionKind::TriangleFlags).map(|flags| flags.element_count);
    if let Some(count) = flag_count.filter(|&count| count != triangle_count) {
        return fail(format!("triangle_flags has {count} elements for {triangle_count} triangles"));
    }
    if let Some(entry) = sections.get(SectionKind::GpuNodes) {
        let split =
            sections.get(SectionKind::Triangles).is_some_and(|t| t.section_flags & SECTION_FLAG_SPLIT_REFERENCES != 0);
        check_gpu_counts(entry.element_count, sections.count(SectionKind::GpuTriangles), triangle_count, split)?;
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
pub(crate) fn check_wide_counts(wide_node_count: u64, packet_count: u64, triangle_count: u64) -> Result<(), Violation> {
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

/// V10 for the GPU sections (1.4): a root exactly when there are triangles; at least one GPU triangle per
/// node (every node but the root has two slots or more, and no more leaves than triangles); below 2^32 GPU
/// triangles; without split references exactly one GPU triangle per record (with them, at least one per
/// distinct triangle, which V49 checks).
fn check_gpu_counts(
    node_count: u64,
    gpu_triangle_count: u64,
    triangle_count: u64,
    split: bool,
) -> Result<(), Violation> {
    let ok = (node_count == 0) == (triangle_count == 0)
        && node_count <= gpu_triangle_count.max(1)
        && gpu_triangle_count <= u64::from(u32::MAX)
        && (gpu_triangle_count == triangle_count || (split && gpu_triangle_count > 0))
        && (gpu_triangle_count == 0) == (triangle_count == 0);
    if ok {
        return Ok(());
    }
    Err(violation(
        Rule::Counts,
        format!(
            "gpu_nodes count {node_count} and gpu_triangles count {gpu_triangle_count} for {triangle_count} \
             triangles: GPU triangles must number triangle_count (without SPLIT_REFERENCES) and below 2^32, GPU \
             nodes 1..=GPU triangles (none without triangles)"
        ),
    ))
}

/// V10 for the two-level sections (1.3): at least one mesh, at most one per triangle; at least one instance,
/// fewer than 2^31 (so the top tree's `2 * instance_count - 1` nodes fit a `u32`); exactly that many top nodes,
/// since every top leaf holds one instance; with a wide top tree at most 2^28 instances and 1 to
/// `instance_count` wide top nodes.
fn check_two_level_counts(sections: &KnownSections, triangle_count: u64) -> Result<(), Violation> {
    let mesh_count = sections.count(SectionKind::Meshes);
    let instance_count = sections.count(SectionKind::Instances);
    let top_node_count = sections.count(SectionKind::TopNodes);
    let top_wide_count = sections.get(SectionKind::TopWideNodes).map(|e| e.element_count);
    // A wide leaf slot names its instance in 28 bits; every wide node but the root has two slots or more.
    let top_wide_ok =
        top_wide_count.is_none_or(|count| instance_count <= 1 << 28 && (1..=instance_count).contains(&count));
    let ok = (1..=triangle_count).contains(&mesh_count)
        && (1..1 << 31).contains(&instance_count)
        && top_node_count == 2 * instance_count - 1
        && top_wide_ok;
    if ok {
        return Ok(());
    }
    Err(violation(
        Rule::Counts,
        format!(
            "meshes count {mesh_count}, instances count {instance_count}, top_nodes count {top_node_count}, \
             top_wide_nodes count {top_wide_count:?} for {triangle_count} triangles: meshes must number \
             1..=triangle_count, instances 1..2^31 (2^28 with top_wide_nodes), top nodes 2 x instances - 1, top \
             wide nodes 1..=instances"
        ),
    ))
}
