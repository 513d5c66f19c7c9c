//! Rules V36-V39 of `format-spec/bvh-1.md`: what the metadata says about the file agrees with the file. Each
//! applies only to the keys a file has (metadata is optional, and so is every key), so a writer that records
//! less is never judged by what it left out.
//!
//! * V36 counts: `wide.node_count`, `wide.packet_count`, `wide: null`, the `triangles` object, and a two-level
//!   file's `two_level` object;
//! * V37 costs: `cost` (section 5.6) and `wide.cost` (section 6.1), recomputed from the file;
//! * V38 build: `build.wide`, `build.gpu` and `build.write_ids` against the sections, leaf sizes against the
//!   `max_leaf_size`s (binary, wide and GPU);
//! * V39 choice: `choice.kept` is the first candidate of lowest cost, and that cost is the file's.

use crate::verify::json::{Map, Value};

use crate::error::{Rule, Violation, violation};
use crate::format::{
    EMPTY_SLOT, GPU_WIDE, GpuSlot, LEAF_BIT, PACKET_LANES, PackedNode, PackedTriangle, TrianglePacket4, UNUSED_LANE,
    WIDE, WideNode8,
};
use crate::open::view::BvhView;
use crate::verify::costs::{close, verify_costs};

/// V36-V39 on `metadata`, the parsed metadata section (V23 held).
pub(crate) fn verify_consistency(view: &BvhView<'_>, metadata: &Map) -> Result<(), Violation> {
    verify_wide_counts(view, metadata)?;
    verify_triangle_counts(view, metadata)?;
    verify_two_level_counts(view, metadata)?;
    verify_costs(view, metadata)?;
    verify_build(view, metadata)?;
    verify_choice(metadata)
}

/// V36, the `wide` object: present exactly as the sections are, with their element counts.
fn verify_wide_counts(view: &BvhView<'_>, metadata: &Map) -> Result<(), Violation> {
    let fail = |detail: String| Err(violation(Rule::MetadataCounts, format!("metadata wide: {detail}")));
    let sections = view.wide_sections();
    match (metadata.get("wide"), sections) {
        (None, _) => Ok(()),
        (Some(Value::Null), None) => Ok(()),
        (Some(Value::Null), Some(_)) => fail("null, but the file has wide sections".into()),
        (Some(Value::Object(_)), None) => fail("an object, but the file has no wide sections".into()),
        (Some(Value::Object(wide)), Some(sections)) => {
            for (key, count) in [("node_count", sections.nodes.len()), ("packet_count", sections.packets.len())] {
                if let Some(stated) = wide.get(key)
                    && stated.as_u64() != Some(count as u64)
                {
                    return fail(format!("{key} {stated}, but the section holds {count}"));
                }
            }
            Ok(())
        }
        (Some(other), _) => fail(format!("{other} is neither an object nor null")),
    }
}

/// V36, the `triangles` object: ids below `source_triangle_count`; stored plus dropped is the source count;
/// `stored_count` is the number of distinct source triangles the file holds.
fn verify_triangle_counts(view: &BvhView<'_>, metadata: &Map) -> Result<(), Violation> {
    let Some(record) = metadata.object("triangles") else { return Ok(()) };
    let fail = |detail: String| Err(violation(Rule::MetadataCounts, format!("metadata triangles: {detail}")));
    let count = |key: &str| record.get(key).and_then(Value::as_u64);
    let dropped: Option<u64> = record.object("dropped").and_then(|d| {
        ["repeated_index", "zero_area", "zero_area_after_placement"]
            .iter()
            .map(|k| d.get(k).and_then(Value::as_u64))
            .try_fold(0u64, |sum, n| sum.checked_add(n?))
    });
    let (source, stored) = (count("source_triangle_count"), count("stored_count"));
    if let (Some(source), Some(stored), Some(dropped)) = (source, stored, dropped)
        && stored.checked_add(dropped) != Some(source)
    {
        return fail(format!("stored_count {stored} + dropped {dropped} is not source_triangle_count {source}"));
    }
    if let (Some(kept), Some(stored)) = (count("degenerate_kept"), stored)
        && kept > stored
    {
        return fail(format!("degenerate_kept {kept} is more than stored_count {stored}"));
    }
    let ids = view.triangle_ids();
    if let (Some(source), Some(ids)) = (source, ids)
        && let Some(i) = ids.iter().position(|&id| u64::from(id) >= source)
    {
        return fail(format!("triangle {i} has source id {}, not below source_triangle_count {source}", ids[i]));
    }
    let Some(stored) = stored else { return Ok(()) };
    let records = view.triangles().len() as u64;
    let distinct = match ids {
        Some(ids) => distinct_id_count(ids),
        None if !view.has_split_references() => records,
        None => distinct_count(view.triangles().iter().map(PackedTriangle::coordinate_bits).collect()),
    };
    // Without ids a split file cannot tell a repeated reference from two source triangles with the same
    // vertices, so the distinct records bound the count from below and the records from above.
    let holds = if ids.is_none() && view.has_split_references() {
        (distinct..=records).contains(&stored)
    } else {
        stored == distinct
    };
    if !holds {
        let what = match ids {
            Some(_) => format!("the file holds {distinct} distinct source ids"),
            None if view.has_split_references() => {
                format!("the file holds {records} records of {distinct} distinct vertex triples")
            }
            None => format!("the file holds {records} triangles"),
        };
        return fail(format!("stored_count {stored}, but {what}"));
    }
    Ok(())
}

/// V36, the `two_level` object: only in a two-level file; `mesh_count` and `instance_count` are the sections'
/// element counts; `placed_triangle_count` sums, over the instances, the distinct triangles of each one's mesh;
/// `flattened_triangle_count` is 0 when the meshes are exactly the listed `instanced_meshes`, else the distinct
/// triangles of mesh 0 (the flattened rest). Distinct as in V38; without ids in a split file, where a repeated
/// reference and two source triangles with the same vertices look alike, between the distinct vertex triples and
/// the records.
fn verify_two_level_counts(view: &BvhView<'_>, metadata: &Map) -> Result<(), Violation> {
    let Some(record) = metadata.object("two_level") else { return Ok(()) };
    let fail = |detail: String| Err(violation(Rule::MetadataCounts, format!("metadata two_level: {detail}")));
    let Some(sections) = view.two_level() else {
        return fail("present, but the file is not two-level".into());
    };
    let count = |key: &str| record.get(key).and_then(Value::as_u64);
    for (key, actual) in [("mesh_count", sections.meshes.len()), ("instance_count", sections.instances.len())] {
        if let Some(stated) = record.get(key)
            && stated.as_u64() != Some(actual as u64)
        {
            return fail(format!("{key} {stated}, but the section holds {actual}"));
        }
    }
    let mut identity = TriangleIdentity { view, ids: Vec::new(), records: Vec::new() };
    let bounded = view.triangle_ids().is_none() && view.has_split_references();
    let per_mesh: Vec<(u64, u64)> = (sections.meshes.iter())
        .map(|mesh| {
            let first = mesh.first_triangle;
            let distinct = identity.distinct((0..mesh.triangle_count).map(|k| first.wrapping_add(k)));
            (distinct, if bounded { u64::from(mesh.triangle_count) } else { distinct })
        })
        .collect();
    let in_range = |stated: u64, (low, high): (u64, u64)| (low..=high).contains(&stated);
    let describe = |(low, high): (u64, u64)| if low == high { format!("{low}") } else { format!("{low} to {high}") };
    if let Some(stated) = count("placed_triangle_count") {
        let placed = (sections.instances.iter())
            .filter_map(|instance| per_mesh.get(instance.mesh_index as usize))
            .fold((0u64, 0u64), |(low, high), &(l, h)| (low.saturating_add(l), high.saturating_add(h)));
        if !in_range(stated, placed) {
            return fail(format!(
                "placed_triangle_count {stated}, but the instances place {} distinct triangles",
                describe(placed)
            ));
        }
    }
    let listed = record.get("instanced_meshes").and_then(Value::as_array).map(Vec::len);
    if let (Some(stated), Some(listed)) = (count("flattened_triangle_count"), listed) {
        let meshes = sections.meshes.len();
        let flattened = match meshes.checked_sub(listed) {
            Some(0) => (0, 0),
            Some(1) => per_mesh[0],
            _ => {
                return fail(format!(
                    "{meshes} meshes, but instanced_meshes lists {listed}: the meshes are the listed ones and, when \
                     there is any, the flattened rest"
                ));
            }
        };
        if !in_range(stated, flattened) {
            return fail(format!(
                "flattened_triangle_count {stated}, but {}",
                if meshes == listed {
                    "every mesh is a listed instanced mesh, so none is flattened".to_string()
                } else {
                    format!("mesh 0, the flattened rest, holds {} distinct triangles", describe(flattened))
                }
            ));
        }
    }
    Ok(())
}

fn distinct_count<T: Ord>(mut keys: Vec<T>) -> u64 {
    keys.sort_unstable();
    keys.dedup();
    keys.len() as u64
}

/// The number of distinct ids: with a bitmap over `0..=max id` when it is no larger than the ids themselves
/// (files whose ids number the scene's triangles), else on a sorted copy.
fn distinct_id_count(ids: &[u32]) -> u64 {
    let Some(&max_id) = ids.iter().max() else { return 0 };
    let words = (max_id as usize + 1).div_ceil(64);
    if words * 8 > ids.len() * 4 {
        return distinct_count(ids.to_vec());
    }
    let mut seen = vec![0u64; words];
    for &id in ids {
        seen[id as usize / 64] |= 1 << (id % 64);
    }
    seen.iter().map(|w| u64::from(w.count_ones())).sum()
}

/// V38: `build.wide`, `build.gpu`, `build.write_ids`, `build.write_source_vertices` and `build.opacity` agree
/// with the sections; binary, wide and GPU leaves hold at most their `max_leaf_size` distinct triangles.
fn verify_build(view: &BvhView<'_>, metadata: &Map) -> Result<(), Violation> {
    let Some(build) = metadata.object("build") else { return Ok(()) };
    let fail = |detail: String| Err(violation(Rule::MetadataBuild, format!("metadata build: {detail}")));
    match (build.get("wide"), view.wide_sections()) {
        (Some(Value::Null), Some(_)) => return fail("wide is null, but the file has wide sections".into()),
        (Some(Value::Object(_)), None) => return fail("wide is an object, but the file has no wide sections".into()),
        (Some(Value::Object(wide)), Some(_)) => {
            for (key, layout) in [("width", WIDE), ("packet_width", PACKET_LANES)] {
                if let Some(stated) = wide.get(key)
                    && stated.as_u64() != Some(layout as u64)
                {
                    return fail(format!("wide.{key} {stated}, but the layout's is {layout}"));
                }
            }
        }
        _ => {}
    }
    if let Some(write_ids) = build.get("write_ids").and_then(Value::as_bool)
        && write_ids != view.triangle_ids().is_some()
    {
        let has = if view.triangle_ids().is_some() { "has" } else { "has no" };
        return fail(format!("write_ids is {write_ids}, but the file {has} triangle_ids section"));
    }
    if let Some(write) = build.get("write_source_vertices").and_then(Value::as_bool)
        && write != view.source_vertices().is_some()
    {
        let has = if view.source_vertices().is_some() { "has" } else { "has no" };
        return fail(format!("write_source_vertices is {write}, but the file {has} source_vertices section"));
    }
    verify_opacity(build, view.triangle_flags()).map_err(|detail| violation(Rule::MetadataBuild, detail))?;
    match (build.get("gpu"), view.gpu_sections()) {
        (Some(Value::Null), Some(_)) => return fail("gpu is null, but the file has GPU sections".into()),
        (Some(Value::Object(_)), None) => return fail("gpu is an object, but the file has no GPU sections".into()),
        (Some(Value::Object(gpu)), Some(sections)) => {
            // A GPU leaf holds each of its triangles once (6.3), so its GPU triangles are distinct triangles.
            if let Some(limit) = gpu.get("max_leaf_size").and_then(Value::as_u64) {
                for (i, node) in sections.nodes.iter().enumerate() {
                    for slot in 0..GPU_WIDE {
                        if let GpuSlot::Leaf { count, .. } = node.slot(slot)
                            && u64::from(count) > limit
                        {
                            return fail(format!(
                                "gpu node {i} slot {slot} is a leaf of {count} triangles, gpu.max_leaf_size {limit}"
                            ));
                        }
                    }
                }
            }
        }
        _ => {}
    }
    let mut identity = TriangleIdentity { view, ids: Vec::new(), records: Vec::new() };
    // Each tree's ranges with the offset of its triangle indices: the file's, or each mesh's (6.2).
    let trees: Vec<TreeRanges<'_>> = match view.two_level() {
        None => vec![TreeRanges {
            name: String::new(),
            nodes: view.nodes(),
            wide: view.wide_sections().map(|w| (w.nodes, w.packets)),
            first_triangle: 0,
        }],
        Some(sections) => sections
            .meshes
            .iter()
            .enumerate()
            .map(|(m, mesh)| {
                let range = |first: u32, count: u32| first as usize..(first as usize).saturating_add(count as usize);
                let wide = view.wide_sections().map(|w| {
                    let nodes = w.nodes.get(range(mesh.first_wide_node, mesh.wide_node_count)).unwrap_or(&[]);
                    (nodes, w.packets.get(range(mesh.first_packet, mesh.packet_count)).unwrap_or(&[]))
                });
                TreeRanges {
                    name: format!("mesh {m}: "),
                    nodes: view.nodes().get(range(mesh.first_node, mesh.node_count)).unwrap_or(&[]),
                    wide,
                    first_triangle: mesh.first_triangle,
                }
            })
            .collect(),
    };
    if let Some(limit) = build.get("max_leaf_size").and_then(Value::as_u64) {
        for tree in &trees {
            for (i, node) in tree.nodes.iter().enumerate().filter(|(_, n)| n.count > 0) {
                let first = tree.first_triangle.wrapping_add(node.index);
                let distinct = identity.distinct((0..node.count).map(|k| first.wrapping_add(k)));
                if distinct > limit {
                    return fail(format!(
                        "{}node {i} is a leaf of {distinct} distinct triangles, max_leaf_size {limit}",
                        tree.name
                    ));
                }
            }
        }
    }
    let wide_limit = build.object("wide").and_then(|wide| wide.get("max_leaf_size")).and_then(Value::as_u64);
    let Some(limit) = wide_limit else { return Ok(()) };
    for tree in &trees {
        let Some((nodes, packets)) = tree.wide else { continue };
        for (i, node) in nodes.iter().enumerate() {
            for (slot, &child) in node.child.iter().enumerate() {
                if child == EMPTY_SLOT || child & LEAF_BIT == 0 {
                    continue;
                }
                let (first, count) = WideNode8::leaf_packets(child);
                let leaf = packets.get(first as usize..(first + count) as usize).unwrap_or(&[]);
                let lanes = leaf.iter().flat_map(|p| p.triangle_index).filter(|&t| t != UNUSED_LANE);
                let distinct = identity.distinct(lanes.map(|t| tree.first_triangle.wrapping_add(t)));
                if distinct > limit {
                    return fail(format!(
                        "{}wide node {i} slot {slot} is a leaf of {distinct} distinct triangles, wide.max_leaf_size \
                         {limit}",
                        tree.name
                    ));
                }
            }
        }
    }
    Ok(())
}

/// One tree's nodes (binary and wide) and where its triangle indices start in the triangles section: the whole
/// file's, or a mesh's in a two-level file.
struct TreeRanges<'a> {
    /// `"mesh m: "` in a two-level file, empty otherwise.
    name: String,
    nodes: &'a [PackedNode],
    wide: Option<(&'a [WideNode8], &'a [TrianglePacket4])>,
    first_triangle: u32,
}

/// Which records are the same triangle: the same source id with ids, the same vertex bits without; with one
/// scratch buffer for all leaves.
struct TriangleIdentity<'v, 'a> {
    view: &'v BvhView<'a>,
    ids: Vec<u32>,
    records: Vec<[u32; 9]>,
}

impl TriangleIdentity<'_, '_> {
    /// The number of distinct triangles among the records `records` (indices into the triangles section).
    fn distinct(&mut self, records: impl Iterator<Item = u32>) -> u64 {
        let triangles = self.view.triangles();
        match self.view.triangle_ids() {
            Some(ids) => {
                self.ids.clear();
                self.ids.extend(records.filter_map(|t| ids.get(t as usize).copied()));
                self.ids.sort_unstable();
                self.ids.dedup();
                self.ids.len() as u64
            }
            None if !self.view.has_split_references() => records.count() as u64,
            None => {
                self.records.clear();
                self.records
                    .extend(records.filter_map(|t| triangles.get(t as usize).map(PackedTriangle::coordinate_bits)));
                self.records.sort_unstable();
                self.records.dedup();
                self.records.len() as u64
            }
        }
    }
}

/// V39: `choice.kept` names a candidate, the first of lowest cost, and its cost is the file's under `measure`.
fn verify_choice(metadata: &Map) -> Result<(), Violation> {
    let Some(choice) = metadata.object("choice") else { return Ok(()) };
    let fail = |detail: String| Err(violation(Rule::MetadataChoice, format!("metadata choice: {detail}")));
    let Some(candidates) = choice.get("candidates").and_then(Value::as_array) else { return Ok(()) };
    let costs: Vec<Option<f64>> = candidates.iter().map(|c| c.get("cost").and_then(Value::as_f64)).collect();
    let Some(kept) = choice.get("kept") else { return Ok(()) };
    let Some(index) = kept.as_u64().filter(|&k| k < costs.len() as u64).map(|k| k as usize) else {
        return fail(format!("kept {kept} does not index the {} candidates", costs.len()));
    };
    let Some(kept_cost) = costs[index] else { return Ok(()) };
    if let Some(first_lowest) = costs.iter().position(|c| c.is_some_and(|c| c <= kept_cost))
        && first_lowest != index
    {
        return fail(format!("kept {index} (cost {kept_cost}), but candidate {first_lowest} costs as little or less"));
    }
    let file_cost = match choice.get("measure").and_then(Value::as_str) {
        Some("wide_cost") => metadata.object("wide").and_then(|w| w.number("cost")),
        Some("sah_cost") => metadata.object("cost").and_then(|c| c.number("sah_cost")),
        _ => None,
    };
    if let Some(file_cost) = file_cost
        && !close(kept_cost, file_cost)
    {
        return fail(format!("the kept candidate's cost {kept_cost} is not the file's {file_cost}"));
    }
    Ok(())
}

/// V38's `build.opacity` clause (since 1.5): where present it is `materials`, `opaque` or `filtered`; `opaque`
/// means the file has no `triangle_flags` section, `filtered` that it has one with every triangle marked not
/// opaque (an empty one in a file without triangles).
fn verify_opacity(build: &Map, flags: Option<&[u8]>) -> Result<(), String> {
    let not_opaque = |f: &u8| f & crate::format::TRIANGLE_NOT_OPAQUE != 0;
    let opacity = build.get("opacity");
    if let Some(value) = opacity
        && !matches!(value.as_str(), Some("materials" | "opaque" | "filtered"))
    {
        return Err(format!("metadata build: opacity is {value}; expected \"materials\", \"opaque\" or \"filtered\""));
    }
    match (opacity.and_then(Value::as_str), flags) {
        (Some("opaque"), Some(_)) => Err("metadata build: opacity is opaque, but the file has triangle_flags".into()),
        (Some("filtered"), None) => {
            Err("metadata build: opacity is filtered, but the file has no triangle_flags section".into())
        }
        (Some("filtered"), Some(flags)) => match flags.iter().position(|f| !not_opaque(f)) {
            Some(i) => Err(format!("metadata build: opacity is filtered, but triangle {i} is not marked not opaque")),
            None => Ok(()),
        },
        _ => Ok(()),
    }
}
