//! The OpenUSD part of `bvhc info`: for a file converted from a stage (its metadata's `usd` object), the stage's
//! units, each source range's mesh prim and the prim that places it, and each instance's placing prim and
//! the prototype it draws, as prim paths (`format-spec/bvh-1.md` 5.5, `usd`).

use bvhc::loader::BvhView;
use bvhc::loader::format::NO_INDEX;

use super::output::outln;

/// How many source ranges and instances are listed before the rest is counted.
const LISTED: usize = 40;

/// The lines, appended to `out`; nothing for a file from another format.
pub(super) fn stage_lines(out: &mut String, view: &BvhView<'_>, metadata: &serde_json::Value) {
    let usd = &metadata["usd"];
    let Some(prims) = usd["prims"].as_array() else { return };
    let prim = |index: u32| -> &str {
        if index == NO_INDEX {
            return "-";
        }
        prims.get(index as usize).and_then(|p| p.as_str()).unwrap_or("?")
    };
    let units = match (usd["meters_per_unit"].as_f64(), usd["up_axis"].as_str()) {
        (Some(m), Some(axis)) => format!("{m} m a unit, {axis} up"),
        (Some(m), None) => format!("{m} m a unit"),
        (None, Some(axis)) => format!("{axis} up"),
        (None, None) => "units not authored".to_string(),
    };
    outln!(out, "usd stage: {} prims named, {units} (recorded, not applied)", prims.len());
    for layer in usd["unread_material_layers"].as_array().into_iter().flatten() {
        outln!(out, "usd: MaterialX document not read (materials only): {}", layer.as_str().unwrap_or("?"));
    }
    if let Some(ranges) = view.source_table() {
        for (i, range) in ranges.iter().enumerate().take(LISTED) {
            let placed = match (range.node_index, range.instance_index) {
                (NO_INDEX, _) => String::new(),
                (node, NO_INDEX) => format!(" placed by {}", prim(node)),
                (node, instance) => format!(" placed by {} instance {instance}", prim(node)),
            };
            let ids = range.first_source_triangle..range.first_source_triangle + range.source_triangle_count;
            outln!(out, "source {i}: ids {ids:?}: {}{placed}", prim(range.mesh_index));
        }
        if ranges.len() > LISTED {
            outln!(out, "source ...: {} more", ranges.len() - LISTED);
        }
    }
    let Some(two_level) = view.two_level() else { return };
    let instanced: Vec<u32> = metadata["two_level"]["instanced_meshes"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|m| m.as_u64().map(|m| m as u32))
        .collect();
    // The file's meshes are the flattened rest (when there is any) and then the instanced prototypes in order.
    let offset = two_level.meshes.len() - instanced.len();
    for (i, instance) in two_level.instances.iter().enumerate().take(LISTED) {
        let mesh = instance.mesh_index as usize;
        let drawn = match mesh.checked_sub(offset).and_then(|m| instanced.get(m)) {
            Some(&root) => prim(root).to_string(),
            None => "the flattened rest of the stage".to_string(),
        };
        let placer = match (instance.node_index, instance.gpu_instance_index) {
            (NO_INDEX, _) => String::new(),
            (node, NO_INDEX) => format!(", placed by {}", prim(node)),
            (node, k) => format!(", placed by {} instance {k}", prim(node)),
        };
        outln!(out, "instance {i}: mesh {mesh} ({drawn}){placer}");
    }
    if two_level.instances.len() > LISTED {
        outln!(out, "instance ...: {} more", two_level.instances.len() - LISTED);
    }
}
