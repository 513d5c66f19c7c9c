//! The full verifier: rules V11-V46 of `format-spec/bvh-1.md`, on top of the structural V1-V10 checked by open.
//! V24-V25 (references) are in `verify_references`, V23 and V26-V28 (metadata) in `verify_metadata`, V29-V35
//! (the wide sections of 1.1) in `verify_wide`, V36-V39 (the metadata against the file) in
//! `verify_consistency`, V40 (the source vertices of 1.2) in `verify_source_vertices`, V41-V46 (the two-level
//! sections of 1.3, and the one-level rules per mesh) in `verify_instances`.
//!
//! Cost: O(file length) for the checksums plus O(nodes + triangles + ids x log ranges) for the rest. Memory: one
//! bit per node and a stack bounded by `MAX_DEPTH`, never more than the file's own size. No input panics it.

use crate::checksum::{header_checksum, section_checksum};
use crate::error::{Rule, Violation, violation};
use crate::format::{
    FileHeader, HEADER_BYTE_LEN, MAX_DEPTH, PackedNode, PackedTriangle, SECTION_ENTRY_BYTE_LEN, is_known_minor,
};
use crate::view::{BvhView, section_bytes};

/// Files at least this long check their wide sections on a second thread (see [`BvhView::verify`]): 64 MiB,
/// where the wide checks take tens of milliseconds and a thread costs tens of microseconds.
pub const PARALLEL_VERIFY_BYTES: usize = 64 << 20;

impl BvhView<'_> {
    /// Checks every validity rule (V11-V46; V1-V10 held when the view was opened).
    ///
    /// Returns the first broken rule found, naming the section, node, triangle or id where it broke. A file of
    /// [`PARALLEL_VERIFY_BYTES`] or more has its wide sections (V29-V35, the last rules checked) checked on a
    /// second, scoped thread beside the other rules, and the first broken rule in the same order is returned;
    /// where no thread can be started, everything runs on the caller's. The metadata's consistency with the
    /// file (V36-V39) is checked last, on a file whose structure every other rule has proven.
    pub fn verify(&self) -> Result<(), Violation> {
        if self.bytes().len() < PARALLEL_VERIFY_BYTES {
            return self
                .verify_all_but_wide()
                .and_then(|()| self.verify_wide_sections())
                .and_then(|()| self.verify_consistency());
        }
        self.verify_in_parallel()
    }

    /// Rules V36-V39: the metadata against the file.
    fn verify_consistency(&self) -> Result<(), Violation> {
        match crate::verify_metadata::parsed_metadata(self)? {
            Some(metadata) => crate::verify_consistency::verify_consistency(self, &metadata),
            None => Ok(()),
        }
    }

    /// [`BvhView::verify`] with the wide sections checked on a second thread whatever the file's size: the
    /// same result (the first broken rule in the same order). Without wide sections, or where no thread can
    /// be started, everything runs on the caller's thread.
    pub fn verify_in_parallel(&self) -> Result<(), Violation> {
        if self.wide_sections().is_none() {
            return self.verify_all_but_wide().and_then(|()| self.verify_consistency());
        }
        std::thread::scope(|scope| {
            let Ok(wide_check) = std::thread::Builder::new().spawn_scoped(scope, || self.verify_wide_sections()) else {
                return self.verify_all_but_wide().and_then(|()| self.verify_wide_sections());
            };
            let rest = self.verify_all_but_wide();
            let wide_result = wide_check.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            rest.and(wide_result)
        })
        .and_then(|()| self.verify_consistency())
    }

    /// Rules V29-V35: the wide sections, where the file has them (per mesh in a two-level file).
    fn verify_wide_sections(&self) -> Result<(), Violation> {
        if let Some(sections) = self.two_level() {
            return crate::verify_instances::verify_mesh_wide(self, &sections);
        }
        match self.wide_sections() {
            Some(wide) => crate::verify_wide::verify_wide(wide.nodes, wide.packets, &self.wide_context()),
            None => Ok(()),
        }
    }

    /// Rules V11-V28, V40 and V41-V46: everything but the wide sections and the metadata's consistency.
    fn verify_all_but_wide(&self) -> Result<(), Violation> {
        verify_checksums(self)?;
        verify_reserved_and_padding(self)?;
        match self.two_level() {
            Some(sections) => crate::verify_instances::verify_meshes(self, &sections)?,
            None => verify_tree(self.nodes(), self.triangles(), self.has_split_references())?,
        }
        verify_sources(self)?;
        crate::verify_metadata::verify_metadata(self)?;
        match self.two_level() {
            Some(sections) => crate::verify_instances::verify_instances(&sections, self.nodes())?,
            None => crate::verify_references::verify_references(
                self.nodes(),
                self.triangles(),
                self.triangle_ids(),
                self.has_split_references(),
            )?,
        }
        match (self.triangle_ids(), self.source_table(), self.source_vertices()) {
            (Some(ids), Some(table), Some(vertices)) => {
                let split = self.has_split_references();
                crate::verify_source_vertices::verify_source_vertices(self.triangles(), ids, table, vertices, split)
            }
            _ => Ok(()),
        }
    }

    /// What the wide sections are checked against.
    pub(crate) fn wide_context(&self) -> crate::verify_wide::WideContext<'_> {
        crate::verify_wide::WideContext {
            triangles: self.triangles(),
            triangle_ids: self.triangle_ids(),
            root_box: self.nodes().first().map(|root| (root.min, root.max)),
            split_references: self.has_split_references(),
        }
    }
}

/// V11, V12.
fn verify_checksums(view: &BvhView<'_>) -> Result<(), Violation> {
    let header = view.header();
    let table_end = table_end(header);
    let stored = header.header_checksum;
    let computed = header_checksum(view.bytes().get(..table_end).unwrap_or(&[]));
    if stored != computed {
        return Err(violation(
            Rule::HeaderChecksum,
            format!("header: header_checksum {stored:#018x}, computed {computed:#018x}"),
        ));
    }
    for info in view.sections() {
        let stored = info.entry.section_checksum;
        let computed = section_checksum(section_bytes(view.bytes(), &info.entry));
        if stored != computed {
            return Err(violation(
                Rule::SectionChecksum,
                format!("section {}: section_checksum {stored:#018x}, computed {computed:#018x}", info.table_index),
            ));
        }
    }
    Ok(())
}

fn table_end(header: &FileHeader) -> usize {
    HEADER_BYTE_LEN + header.section_count as usize * header.section_entry_byte_len as usize
}

/// V13: reserved fields and padding are zero. Fields that a later minor version may have given a meaning are
/// only checked in files whose minor version this reader knows.
fn verify_reserved_and_padding(view: &BvhView<'_>) -> Result<(), Violation> {
    let header = view.header();
    let fail = |detail: String| Err(violation(Rule::ReservedZero, detail));
    let known_minor = is_known_minor(header.version_minor);
    if known_minor && (header.header_flags != 0 || header.reserved != [0; 3]) {
        return fail("header: header_flags and reserved must be zero".to_string());
    }
    let bytes = view.bytes();
    let stride = header.section_entry_byte_len as usize;
    let mut covered_end = table_end(header);
    for info in view.sections() {
        let entry_start = HEADER_BYTE_LEN + info.table_index * stride;
        let entry_tail = bytes.get(entry_start + SECTION_ENTRY_BYTE_LEN..entry_start + stride).unwrap_or(&[]);
        if known_minor && (info.entry.reserved != 0 || entry_tail.iter().any(|&b| b != 0)) {
            return fail(format!("section {}: reserved bytes of the table entry must be zero", info.table_index));
        }
        let start = info.entry.section_byte_offset as usize;
        check_zero_padding(bytes, covered_end, start)?;
        covered_end = start + info.entry.section_byte_len as usize;
    }
    check_zero_padding(bytes, covered_end, bytes.len())?;
    let table = view.source_table().filter(|_| known_minor).unwrap_or(&[]);
    if let Some(i) = table.iter().position(|r| r.reserved != 0) {
        return fail(format!("source_table range {i}: reserved must be zero"));
    }
    let wide_nodes = view.wide_sections().filter(|_| known_minor).map_or(&[][..], |wide| wide.nodes);
    if let Some(i) = wide_nodes.iter().position(|n| n.reserved != [0; 8]) {
        return fail(format!("wide node {i}: reserved must be zero"));
    }
    let instances = view.two_level().filter(|_| known_minor).map_or(&[][..], |sections| sections.instances);
    if let Some(i) = instances.iter().position(|instance| instance.reserved != 0) {
        return fail(format!("instance {i}: reserved must be zero"));
    }
    let top_wide = view.two_level().filter(|_| known_minor).map_or(&[][..], |sections| sections.top_wide_nodes);
    if let Some(i) = top_wide.iter().position(|n| n.reserved != [0; 8]) {
        return fail(format!("top wide node {i}: reserved must be zero"));
    }
    Ok(())
}

fn check_zero_padding(bytes: &[u8], start: usize, end: usize) -> Result<(), Violation> {
    let padding = bytes.get(start..end).unwrap_or(&[]);
    match padding.iter().position(|&b| b != 0) {
        Some(i) => Err(violation(Rule::ReservedZero, format!("padding byte {} is not zero", start + i))),
        None => Ok(()),
    }
}

/// V14-V20 over the node and triangle arrays.
///
/// First pass (index order): boxes (V16), child indices and single parents (V14), leaf ranges in bounds (V15).
/// Since every child comes after its parent and every non-root node has exactly one parent, the nodes form one
/// tree rooted at node 0. Second pass (depth first, left child first): depth (V20), child boxes (V17), leaves
/// consecutive over the triangles (V15), and each triangle checked once against its leaf (V18, V19).
pub fn verify_tree(
    nodes: &[PackedNode],
    triangles: &[PackedTriangle],
    split_references: bool,
) -> Result<(), Violation> {
    if nodes.is_empty() {
        return match triangles.len() {
            0 => Ok(()),
            n => Err(violation(Rule::LeafPartition, format!("no nodes for {n} triangles"))),
        };
    }
    let node_count = nodes.len();
    let mut has_parent = vec![0u64; node_count.div_ceil(64)];
    for (i, node) in nodes.iter().enumerate() {
        check_box(i, node)?;
        if node.is_leaf() {
            let end = u64::from(node.index) + u64::from(node.count);
            if end > triangles.len() as u64 {
                return Err(violation(
                    Rule::LeafPartition,
                    format!(
                        "node {i}: leaf triangles {}..{end} out of range (triangle_count {})",
                        node.index,
                        triangles.len()
                    ),
                ));
            }
            continue;
        }
        let first = node.index as usize;
        if first <= i || first + 1 >= node_count {
            return Err(violation(
                Rule::TreeShape,
                format!(
                    "node {i}: children {first} and {} must come after it and be < node_count {node_count}",
                    first + 1
                ),
            ));
        }
        for child in [first, first + 1] {
            let (word, bit) = (child / 64, 1u64 << (child % 64));
            if has_parent[word] & bit != 0 {
                return Err(violation(Rule::TreeShape, format!("node {child}: second parent {i}")));
            }
            has_parent[word] |= bit;
        }
    }
    if let Some(orphan) = (1..node_count).find(|&j| has_parent[j / 64] & (1 << (j % 64)) == 0) {
        return Err(violation(Rule::TreeShape, format!("node {orphan}: no parent (unreachable from the root)")));
    }
    drop(has_parent);
    walk_depth_first(nodes, triangles, split_references)
}

fn check_box(i: usize, node: &PackedNode) -> Result<(), Violation> {
    let finite = node.min.iter().chain(&node.max).all(|v| v.is_finite());
    if !finite || (0..3).any(|a| node.min[a] > node.max[a]) {
        return Err(violation(
            Rule::NodeBox,
            format!("node {i}: box {:?}..{:?} must be finite with min <= max", node.min, node.max),
        ));
    }
    Ok(())
}

fn walk_depth_first(
    nodes: &[PackedNode],
    triangles: &[PackedTriangle],
    split_references: bool,
) -> Result<(), Violation> {
    let mut next_triangle = 0usize;
    let mut stack: Vec<(usize, usize)> = vec![(0, 0)];
    while let Some((i, depth)) = stack.pop() {
        if depth > MAX_DEPTH {
            return Err(violation(Rule::Depth, format!("node {i}: depth {depth} exceeds {MAX_DEPTH}")));
        }
        let node = &nodes[i];
        if node.is_leaf() {
            let first = node.index as usize;
            if first != next_triangle {
                return Err(violation(
                    Rule::LeafPartition,
                    format!(
                        "node {i}: leaf starts at triangle {first}, expected {next_triangle} (leaves in depth-first order must be consecutive)"
                    ),
                ));
            }
            next_triangle = first + node.count as usize;
            for (t, triangle) in triangles[first..next_triangle].iter().enumerate() {
                check_triangle(first + t, triangle, i, node, split_references)?;
            }
            continue;
        }
        let first = node.index as usize;
        for child in [first, first + 1] {
            let c = &nodes[child];
            if (0..3).any(|a| c.min[a] < node.min[a] || c.max[a] > node.max[a]) {
                return Err(violation(
                    Rule::ChildInParent,
                    format!(
                        "node {child}: box {:?}..{:?} not inside parent {i} {:?}..{:?}",
                        c.min, c.max, node.min, node.max
                    ),
                ));
            }
        }
        // Right child pushed first so the left one is visited first.
        stack.push((first + 1, depth + 1));
        stack.push((first, depth + 1));
    }
    if next_triangle != triangles.len() {
        return Err(violation(
            Rule::LeafPartition,
            format!("leaves cover triangles 0..{next_triangle} of {}", triangles.len()),
        ));
    }
    Ok(())
}

fn check_triangle(
    t: usize,
    triangle: &PackedTriangle,
    leaf_index: usize,
    leaf: &PackedNode,
    split_references: bool,
) -> Result<(), Violation> {
    let v = &triangle.vertices;
    if !v.iter().flatten().all(|c| c.is_finite()) {
        return Err(violation(Rule::TriangleFinite, format!("triangle {t}: vertex {v:?} is not finite")));
    }
    let inside = |p: &[f32; 3]| (0..3).all(|a| leaf.min[a] <= p[a] && p[a] <= leaf.max[a]);
    let ok = if split_references {
        (0..3).all(|a| {
            let lo = v[0][a].min(v[1][a]).min(v[2][a]);
            let hi = v[0][a].max(v[1][a]).max(v[2][a]);
            lo <= leaf.max[a] && hi >= leaf.min[a]
        })
    } else {
        v.iter().all(inside)
    };
    if !ok {
        return Err(violation(
            Rule::TriangleInLeaf,
            format!("triangle {t}: {v:?} not inside leaf node {leaf_index} box {:?}..{:?}", leaf.min, leaf.max),
        ));
    }
    Ok(())
}

/// V21, V22.
fn verify_sources(view: &BvhView<'_>) -> Result<(), Violation> {
    let Some(table) = view.source_table() else {
        return Ok(());
    };
    let mut previous_end = 0u64;
    for (i, range) in table.iter().enumerate() {
        let first = u64::from(range.first_source_triangle);
        let end = first + u64::from(range.source_triangle_count);
        if range.source_triangle_count == 0 || first < previous_end || end > 1 << 32 {
            return Err(violation(
                Rule::SourceTable,
                format!(
                    "source_table range {i}: ids {first}..{end} must be non-empty, ascending, disjoint, below 2^32"
                ),
            ));
        }
        previous_end = end;
    }
    for (t, &id) in view.triangle_ids().unwrap_or(&[]).iter().enumerate() {
        if view.source_range_of(id).is_none() {
            return Err(violation(Rule::TriangleIdRange, format!("triangle {t}: id {id} is in no source range")));
        }
    }
    Ok(())
}
