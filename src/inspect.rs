//! What `bvhc info` reports of a `.bvh` file: tree statistics, costs recomputed from the file, section table and
//! metadata, as one JSON object (the keys the README lists under `bvhc info --json`). Shared by the command line
//! and the Python package, so both say the same.

use std::collections::BTreeMap;
use std::path::Path;

use bvhc_loader::{BvhView, format::PackedNode};

use crate::cost::{SahConstants, SahCost, sah_of_packed};

/// A file's statistics and recomputed costs.
pub struct Inspection {
    /// The binary tree's (of a two-level file: every mesh's trees, together).
    pub stats: TreeStats,
    /// The metadata section, parsed (null without one).
    pub metadata: serde_json::Value,
    /// The cost constants the metadata records (the defaults without).
    pub constants: SahConstants,
    /// The binary tree's cost (none for a two-level file: no tree spans the scene, format-spec 6.2).
    pub cost: Option<SahCost>,
    /// The wide tree's cost under the metadata's `build.wide` constants (one-level files with wide sections).
    pub wide_cost: Option<f64>,
    /// Each section's `kind`, `name`, `flags`, `byte_offset`, `byte_len`, `element_count`.
    pub sections: Vec<serde_json::Value>,
    /// Distinct source triangles ([`unique_triangle_count`]).
    pub unique_triangles: usize,
}

/// Measures `view` (a verified file's, for statistics that mean something).
pub fn inspect(view: &BvhView<'_>) -> Inspection {
    let two_level = view.two_level();
    let stats = match &two_level {
        None => tree_stats(view.nodes()),
        Some(sections) => meshes_stats(view.nodes(), sections.meshes),
    };
    let metadata = metadata(view);
    let constants = SahConstants {
        traversal: metadata["cost"]["c_t"].as_f64().unwrap_or(SahConstants::default().traversal),
        intersection: metadata["cost"]["c_i"].as_f64().unwrap_or(SahConstants::default().intersection),
    };
    let cost = two_level.is_none().then(|| sah_of_packed(view.nodes(), constants));
    let sections = view
        .sections()
        .map(|s| {
            serde_json::json!({
                "kind": s.entry.kind,
                "name": s.kind.map_or("unknown", |k| k.name()),
                "flags": s.entry.section_flags,
                "byte_offset": s.entry.section_byte_offset,
                "byte_len": s.entry.section_byte_len,
                "element_count": s.entry.element_count,
            })
        })
        .collect();
    let unique_triangles = unique_triangle_count(view, &metadata);
    let wide_constants = &metadata["build"]["wide"];
    let wide_cost = view.wide_sections().filter(|_| two_level.is_none()).map(|wide| {
        let node_visit = wide_constants["node_visit"].as_f64().unwrap_or(1.0);
        let packet_test = wide_constants["packet_test"].as_f64().unwrap_or(1.0);
        bvhc_loader::format::cost::wide_cost(view.nodes().first(), wide.nodes, node_visit, packet_test)
    });
    Inspection { stats, metadata, constants, cost, wide_cost, sections, unique_triangles }
}

impl Inspection {
    /// The `bvhc info --json` object for the file at `path` whose view is `view`.
    pub fn to_json(&self, path: &Path, view: &BvhView<'_>) -> serde_json::Value {
        serde_json::json!({
            "file": path,
            "format_version": format!("{}.{}", view.version().0, view.version().1),
            "file_byte_len": view.bytes().len(),
            "sections": self.sections,
            "triangle_count": view.triangles().len(),
            "reference_count": view.triangles().len(),
            "unique_triangle_count": self.unique_triangles,
            "split_references": view.has_split_references(),
            "source_vertices": view.source_vertices().is_some(),
            "not_opaque_count": not_opaque_count(view),
            "not_opaque_triangle_count": not_opaque_triangle_count(view),
            "node_count": view.nodes().len(),
            "wide_node_count": view.wide_sections().map(|w| w.nodes.len()),
            "packet_count": view.wide_sections().map(|w| w.packets.len()),
            "gpu_node_count": view.gpu_sections().map(|g| g.nodes.len()),
            "gpu_triangle_count": view.gpu_sections().map(|g| g.triangles.len()),
            "gpu_byte_len": view.gpu_sections().map(|g| gpu_byte_len(&g)),
            "kernel": format!("{:?}", view.tracer().kernel()),
            "leaf_count": self.stats.leaf_count,
            "max_depth": self.stats.max_depth,
            "leaf_size_histogram": self.stats.leaf_sizes,
            "sah_cost": self.cost.map(|c| c.cost),
            "c_t": self.constants.traversal,
            "c_i": self.constants.intersection,
            "inner_area_ratio": self.cost.map(|c| c.inner_area_ratio),
            "leaf_area_ratio": self.cost.map(|c| c.leaf_area_ratio),
            "wide_cost": self.wide_cost,
            "two_level": view.two_level().map(|sections| serde_json::json!({
                "mesh_count": sections.meshes.len(),
                "instance_count": sections.instances.len(),
                "top_node_count": sections.top_nodes.len(),
                "top_wide_node_count": sections.top_wide_nodes.len(),
                "placed_record_count": sections.placed_record_count(),
            })),
            "metadata": self.metadata,
        })
    }
}

/// Tree statistics of a verified file.
pub struct TreeStats {
    /// Leaves.
    pub leaf_count: usize,
    /// The deepest leaf's depth (the root's is 0).
    pub max_depth: usize,
    /// Leaves by record count.
    pub leaf_sizes: BTreeMap<u32, usize>,
}

fn tree_stats(nodes: &[PackedNode]) -> TreeStats {
    let mut stats = TreeStats { leaf_count: 0, max_depth: 0, leaf_sizes: BTreeMap::new() };
    let mut stack = if nodes.is_empty() { vec![] } else { vec![(0usize, 0usize)] };
    while let Some((i, depth)) = stack.pop() {
        stats.max_depth = stats.max_depth.max(depth);
        let node = &nodes[i];
        if node.is_leaf() {
            stats.leaf_count += 1;
            *stats.leaf_sizes.entry(node.count).or_default() += 1;
        } else {
            stack.push((node.index as usize, depth + 1));
            stack.push((node.index as usize + 1, depth + 1));
        }
    }
    stats
}

/// [`tree_stats`] of every mesh's tree of a two-level file, together (the deepest mesh's depth).
fn meshes_stats(nodes: &[PackedNode], meshes: &[bvhc_loader::format::MeshRecord]) -> TreeStats {
    let mut stats = TreeStats { leaf_count: 0, max_depth: 0, leaf_sizes: BTreeMap::new() };
    for mesh in meshes {
        let start = mesh.first_node as usize;
        let mesh_stats = tree_stats(&nodes[start..start + mesh.node_count as usize]);
        stats.leaf_count += mesh_stats.leaf_count;
        stats.max_depth = stats.max_depth.max(mesh_stats.max_depth);
        for (size, count) in mesh_stats.leaf_sizes {
            *stats.leaf_sizes.entry(size).or_default() += count;
        }
    }
    stats
}

/// The metadata section parsed, or null.
pub fn metadata(view: &BvhView<'_>) -> serde_json::Value {
    view.metadata_str()
        .and_then(|text| text.ok())
        .and_then(|text| serde_json::from_str(text).ok())
        .unwrap_or(serde_json::Value::Null)
}

/// Distinct source triangles in the triangles section: its records, unless `SPLIT_REFERENCES` lets one triangle
/// be stored several times; then the distinct ids (records with one id are one triangle), or without ids the
/// metadata's `triangles.stored_count` (rule V36 keeps it between the distinct vertex triples and the records:
/// two source triangles may have the same vertices), and only without that the distinct vertex triples.
pub fn unique_triangle_count(view: &BvhView<'_>, metadata: &serde_json::Value) -> usize {
    let stored = metadata["triangles"]["stored_count"].as_u64();
    match (view.has_split_references(), view.triangle_ids(), stored) {
        (true, None, Some(stored)) => stored as usize,
        _ => distinct_triangles(view, |_| true),
    }
}

/// Distinct source triangles among the records `keep` accepts: the records themselves without
/// `SPLIT_REFERENCES`; with it, their distinct ids, or without ids their distinct vertex triples.
fn distinct_triangles(view: &BvhView<'_>, keep: impl Fn(usize) -> bool) -> usize {
    let records = 0..view.triangles().len();
    if !view.has_split_references() {
        return records.filter(|&r| keep(r)).count();
    }
    match view.triangle_ids() {
        Some(ids) => {
            let mut kept: Vec<u32> = records.filter(|&r| keep(r)).map(|r| ids[r]).collect();
            kept.sort_unstable();
            kept.dedup();
            kept.len()
        }
        None => {
            let triangles = view.triangles();
            let mut keys: Vec<[u32; 9]> =
                records.filter(|&r| keep(r)).map(|r| triangles[r].coordinate_bits()).collect();
            keys.sort_unstable();
            keys.dedup();
            keys.len()
        }
    }
}

/// Bytes of the two GPU sections.
pub fn gpu_byte_len(gpu: &bvhc_loader::GpuSections<'_>) -> usize {
    size_of_val(gpu.nodes) + size_of_val(gpu.triangles)
}

/// The records the `triangle_flags` section marks not opaque, or `None` without the section (all opaque).
pub fn not_opaque_count(view: &BvhView<'_>) -> Option<usize> {
    let flags = view.triangle_flags()?;
    Some(flags.iter().filter(|&&f| f & bvhc_loader::format::TRIANGLE_NOT_OPAQUE != 0).count())
}

/// The distinct source triangles among the records the `triangle_flags` section marks not opaque (counted as
/// [`unique_triangle_count`] counts, by vertex triples without ids), or `None` without the section.
pub fn not_opaque_triangle_count(view: &BvhView<'_>) -> Option<usize> {
    view.triangle_flags()?;
    Some(distinct_triangles(view, |r| view.is_not_opaque(r as u32)))
}
