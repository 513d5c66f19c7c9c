//! The full verifier: rules V11-V53 of `format-spec/bvh-1.md`, on top of the structural V1-V10 checked by open.
//! V14-V20 (the binary tree) are in `tree`, V24-V25 (references) in `references`, V23 and V26-V28 (metadata)
//! in `metadata`, V29-V35 (the wide sections of 1.1) in `wide`, V36-V39 (the metadata against the file) in
//! `consistency`, V40 (the source vertices of 1.2) in `source_vertices`, V41-V46 (the two-level
//! sections of 1.3, and the one-level rules per mesh) in `instances`, V47-V50 (the GPU sections of 1.4) in
//! `gpu`, V52-V53 (the triangle flags of 1.5) in `triangle_flags`; V51 (the version a file's
//! sections need) here.
//!
//! Cost: O(file length) for the checksums plus O(nodes + triangles + ids x log ranges) for the rest. Memory: one
//! bit per node and a stack bounded by `MAX_DEPTH`, never more than the file's own size. No input panics it.

pub(crate) mod consistency;
pub(crate) mod costs;
pub(crate) mod gpu;
pub(crate) mod instances;
pub(crate) mod json;
pub(crate) mod metadata;
pub(crate) mod references;
pub(crate) mod source_vertices;
pub(crate) mod tree;
pub(crate) mod triangle_flags;
pub(crate) mod wide;

pub use tree::verify_tree;

use crate::error::{Rule, Violation, violation};
use crate::format::checksum::{header_checksum, section_checksum};
use crate::format::{
    FileHeader, HEADER_BYTE_LEN, MinorFeatures, SECTION_ENTRY_BYTE_LEN, is_known_minor, written_minor,
};
use crate::open::view::{BvhView, section_bytes};

/// Files at least this long check their wide sections on a second thread (see [`BvhView::verify`]): 64 MiB,
/// where the wide checks take tens of milliseconds and a thread costs tens of microseconds.
pub const PARALLEL_VERIFY_BYTES: usize = 64 << 20;

impl BvhView<'_> {
    /// Checks every validity rule (V11-V53; V1-V10 held when the view was opened).
    ///
    /// Returns the first broken rule found, naming the section, node, triangle or id where it broke. A file of
    /// [`PARALLEL_VERIFY_BYTES`] or more has its wide sections (V29-V35, the last rules checked) checked on a
    /// second, scoped thread beside the other rules, and the first broken rule in the same order is returned;
    /// where no thread can be started, everything runs on the caller's. The metadata's consistency with the
    /// file (V36-V39) is checked after the structure, then the version (V51), so a file whose only fault is its
    /// version label reports V51 (what a reader of a lower minor, which does not judge it, sees as valid).
    pub fn verify(&self) -> Result<(), Violation> {
        if self.bytes().len() < PARALLEL_VERIFY_BYTES {
            return self
                .verify_all_but_wide()
                .and_then(|()| self.verify_wide_sections())
                .and_then(|()| self.verify_consistency())
                .and_then(|()| verify_lowest_minor(self));
        }
        self.verify_in_parallel()
    }

    /// Rules V36-V39: the metadata against the file.
    fn verify_consistency(&self) -> Result<(), Violation> {
        match crate::verify::metadata::parsed_metadata(self)? {
            Some(metadata) => crate::verify::consistency::verify_consistency(self, &metadata),
            None => Ok(()),
        }
    }

    /// [`BvhView::verify`] with the wide sections checked on a second thread whatever the file's size: the
    /// same result (the first broken rule in the same order). Without wide sections, or where no thread can
    /// be started, everything runs on the caller's thread.
    pub fn verify_in_parallel(&self) -> Result<(), Violation> {
        if self.wide_sections().is_none() {
            return self
                .verify_all_but_wide()
                .and_then(|()| self.verify_consistency())
                .and_then(|()| verify_lowest_minor(self));
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
        .and_then(|()| verify_lowest_minor(self))
    }

    /// Rules V29-V35: the wide sections, where the file has them (per mesh in a two-level file).
    fn verify_wide_sections(&self) -> Result<(), Violation> {
        if let Some(sections) = self.two_level() {
            return crate::verify::instances::verify_mesh_wide(self, &sections);
        }
        match self.wide_sections() {
            Some(wide) => crate::verify::wide::verify_wide(wide.nodes, wide.packets, &self.wide_context()),
            None => Ok(()),
        }
    }

    /// Rules V11-V28, V40, V41-V46, V47-V50 and V52-V53: everything but the wide sections, the metadata's
    /// consistency and the version.
    fn verify_all_but_wide(&self) -> Result<(), Violation> {
        verify_checksums(self)?;
        verify_reserved_and_padding(self)?;
        match self.two_level() {
            Some(sections) => crate::verify::instances::verify_meshes(self, &sections)?,
            None => verify_tree(self.nodes(), self.triangles(), self.has_split_references())?,
        }
        verify_sources(self)?;
        crate::verify::metadata::verify_metadata(self)?;
        match self.two_level() {
            Some(sections) => crate::verify::instances::verify_instances(&sections, self.nodes())?,
            None => crate::verify::references::verify_references(
                self.nodes(),
                self.triangles(),
                self.triangle_ids(),
                self.has_split_references(),
            )?,
        }
        if let (Some(ids), Some(table), Some(vertices)) =
            (self.triangle_ids(), self.source_table(), self.source_vertices())
        {
            let split = self.has_split_references();
            crate::verify::source_vertices::verify_source_vertices(self.triangles(), ids, table, vertices, split)?;
        }
        if let Some(gpu) = self.gpu_sections() {
            let context = crate::verify::gpu::GpuContext {
                triangles: self.triangles(),
                triangle_ids: self.triangle_ids(),
                split_references: self.has_split_references(),
            };
            crate::verify::gpu::verify_gpu(&gpu, &context)?;
        }
        match self.triangle_flags() {
            Some(flags) => {
                let known = is_known_minor(self.header().version_minor);
                crate::verify::triangle_flags::verify_triangle_flags(flags, self.triangle_ids(), known)
            }
            None => Ok(()),
        }
    }

    /// What the wide sections are checked against.
    pub(crate) fn wide_context(&self) -> crate::verify::wide::WideContext<'_> {
        crate::verify::wide::WideContext {
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

/// V51: a file whose minor version this reader knows has the lowest minor its sections need (section 2), so a
/// reader can tell from the header alone which sections to expect. A higher minor may need it for features this
/// reader cannot see, so it is not judged.
fn verify_lowest_minor(view: &BvhView<'_>) -> Result<(), Violation> {
    let minor = view.header().version_minor;
    let needed = written_minor(MinorFeatures {
        wide: view.wide_sections().is_some(),
        source_vertices: view.source_vertices().is_some(),
        instances: view.two_level().is_some(),
        gpu: view.gpu_sections().is_some(),
        triangle_flags: view.triangle_flags().is_some(),
    });
    if is_known_minor(minor) && minor != needed {
        return Err(violation(
            Rule::LowestMinor,
            format!(
                "header: version_minor {minor}, but the file's sections need version 1.{needed}, the lowest minor \
                 version whose features it uses (section 2)"
            ),
        ));
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
