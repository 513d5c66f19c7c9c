//! `bvhc verify FILE` and `bvhc info FILE [--json]`.

use std::collections::BTreeMap;
use std::path::Path;

use bvhc::cost::{SahConstants, sah_of_packed};
use bvhc::loader::{BvhFile, BvhView, PackedNode};

use super::output::{outln, print};
use super::{Exit, fail, loader_exit};

/// Reads and fully verifies a file; the error exit when it cannot be read or is invalid.
pub(super) fn read_verified(path: &Path) -> Result<BvhFile, Exit> {
    let file = BvhFile::read(path).map_err(|e| fail(loader_exit(&e), format!("{}: {e}", path.display())))?;
    file.view()
        .verify()
        .map_err(|v| fail(Exit::InvalidInput, format!("{}: invalid .bvh file: {v}", path.display())))?;
    Ok(file)
}

/// `bvhc verify`: exit 0 only for a valid file.
pub fn verify(path: &Path) -> Exit {
    match read_verified(path) {
        Ok(file) => {
            let view = file.view();
            let (major, minor) = view.version();
            let mut out = String::new();
            outln!(
                out,
                "{}: valid .bvh {major}.{minor} ({} nodes, {} triangles{}, every rule V1-V{} holds)",
                path.display(),
                view.nodes().len(),
                view.triangles().len(),
                view.wide_sections().map_or(String::new(), |wide| format!(
                    ", {} wide nodes, {} triangle packets",
                    wide.nodes.len(),
                    wide.packets.len()
                )),
                bvhc::loader::Rule::ALL.len()
            );
            print(&out, Exit::Success)
        }
        Err(exit) => exit,
    }
}

/// Tree statistics of a verified file.
struct TreeStats {
    leaf_count: usize,
    max_depth: usize,
    leaf_sizes: BTreeMap<u32, usize>,
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
fn meshes_stats(nodes: &[PackedNode], meshes: &[bvhc::loader::MeshRecord]) -> TreeStats {
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

fn metadata(view: &BvhView<'_>) -> serde_json::Value {
    view.metadata_str()
        .and_then(|text| text.ok())
        .and_then(|text| serde_json::from_str(text).ok())
        .unwrap_or(serde_json::Value::Null)
}

/// `bvhc info`.
pub fn info(path: &Path, json: bool) -> Exit {
    let file = match read_verified(path) {
        Ok(file) => file,
        Err(exit) => return exit,
    };
    let view = file.view();
    let two_level = view.two_level();
    let stats = match &two_level {
        None => tree_stats(view.nodes()),
        Some(sections) => meshes_stats(view.nodes(), sections.meshes),
    };
    let metadata = metadata(&view);
    let constants = SahConstants {
        traversal: metadata["cost"]["c_t"].as_f64().unwrap_or(SahConstants::default().traversal),
        intersection: metadata["cost"]["c_i"].as_f64().unwrap_or(SahConstants::default().intersection),
    };
    // A two-level file has no tree over the whole scene, so no cost (format-spec/bvh-1.md 6.2).
    let cost = two_level.is_none().then(|| sah_of_packed(view.nodes(), constants));
    let (major, minor) = view.version();
    let sections: Vec<serde_json::Value> = view
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
    let unique_triangles = unique_triangle_count(&view, &metadata);
    let wide_constants = &metadata["build"]["wide"];
    let wide_cost = view.wide_sections().filter(|_| two_level.is_none()).map(|wide| {
        let node_visit = wide_constants["node_visit"].as_f64().unwrap_or(1.0);
        let packet_test = wide_constants["packet_test"].as_f64().unwrap_or(1.0);
        bvhc::loader::cost::wide_cost(view.nodes().first(), wide.nodes, node_visit, packet_test)
    });
    if json {
        let report = serde_json::json!({
            "file": path,
            "format_version": format!("{major}.{minor}"),
            "file_byte_len": view.bytes().len(),
            "sections": sections,
            "triangle_count": view.triangles().len(),
            "reference_count": view.triangles().len(),
            "unique_triangle_count": unique_triangles,
            "split_references": view.has_split_references(),
            "source_vertices": view.source_vertices().is_some(),
            "not_opaque_count": not_opaque_count(&view),
            "node_count": view.nodes().len(),
            "wide_node_count": view.wide_sections().map(|w| w.nodes.len()),
            "packet_count": view.wide_sections().map(|w| w.packets.len()),
            "gpu_node_count": view.gpu_sections().map(|g| g.nodes.len()),
            "gpu_triangle_count": view.gpu_sections().map(|g| g.triangles.len()),
            "gpu_byte_len": view.gpu_sections().map(|g| gpu_byte_len(&g)),
            "kernel": format!("{:?}", view.tracer().kernel()),
            "leaf_count": stats.leaf_count,
            "max_depth": stats.max_depth,
            "leaf_size_histogram": stats.leaf_sizes,
            "sah_cost": cost.map(|c| c.cost),
            "c_t": constants.traversal,
            "c_i": constants.intersection,
            "inner_area_ratio": cost.map(|c| c.inner_area_ratio),
            "leaf_area_ratio": cost.map(|c| c.leaf_area_ratio),
            "wide_cost": wide_cost,
            "two_level": two_level.map(|sections| serde_json::json!({
                "mesh_count": sections.meshes.len(),
                "instance_count": sections.instances.len(),
                "top_node_count": sections.top_nodes.len(),
                "top_wide_node_count": sections.top_wide_nodes.len(),
                "placed_record_count": sections.placed_record_count(),
            })),
            "metadata": metadata,
        });
        return print(&format!("{report:#}\n"), Exit::Success);
    }
    let mut out = String::new();
    outln!(out, "{}: .bvh {major}.{minor}, {} bytes", path.display(), view.bytes().len());
    outln!(out, "sections:");
    for s in &sections {
        outln!(
            out,
            "  {:<16} offset {:>10}  bytes {:>11}  elements {:>9}  flags {}",
            s["name"].as_str().unwrap_or(""),
            s["byte_offset"],
            s["byte_len"],
            s["element_count"],
            s["flags"]
        );
    }
    outln!(
        out,
        "tree: {} triangles, {} nodes, {} leaves, depth {}",
        view.triangles().len(),
        view.nodes().len(),
        stats.leaf_count,
        stats.max_depth
    );
    if let Some(sections) = &two_level {
        let placed = sections.placed_record_count();
        outln!(
            out,
            "two-level: {} meshes placed by {} instances under a top tree of {} nodes ({} 8-wide): {} triangle \
             records stored, {placed} records placed ({:.1}x); the tree line counts every mesh's trees, depth the deepest",
            sections.meshes.len(),
            sections.instances.len(),
            sections.top_nodes.len(),
            sections.top_wide_nodes.len(),
            view.triangles().len(),
            placed as f64 / view.triangles().len().max(1) as f64
        );
    }
    if view.has_split_references() {
        outln!(
            out,
            "split references: {} records of {} triangles ({:.3} a triangle)",
            view.triangles().len(),
            unique_triangles,
            view.triangles().len() as f64 / unique_triangles.max(1) as f64
        );
    }
    let shading = match (view.triangle_ids().is_some(), view.source_vertices().is_some()) {
        (true, true) => "source ids and source vertices (attributes interpolate at hits)",
        (true, false) => "source ids, no source vertices",
        (false, _) => "no source ids",
    };
    outln!(out, "provenance: {shading}");
    match not_opaque_count(&view) {
        Some(count) => outln!(
            out,
            "opacity: {count} of {} triangle records not opaque (a filtered tracer asks its filter about these alone)",
            view.triangles().len()
        ),
        None => outln!(out, "opacity: every triangle opaque (no triangle_flags section)"),
    }
    match view.wide_sections() {
        Some(wide) => outln!(
            out,
            "wide tree: {} 8-wide nodes, {} packets of 4 ({:.2} triangles a packet); traced by {:?}",
            wide.nodes.len(),
            wide.packets.len(),
            view.triangles().len() as f64 / wide.packets.len().max(1) as f64,
            view.tracer().kernel()
        ),
        None => outln!(out, "wide tree: none (traced by the binary kernel)"),
    }
    match view.gpu_sections() {
        Some(gpu) => {
            let wide_bytes = view.wide_sections().map(|w| size_of_val(w.nodes) + size_of_val(w.packets));
            let ratio = wide_bytes.map_or(String::new(), |b| {
                format!(", {:.2}x the wide sections", gpu_byte_len(&gpu) as f64 / b.max(1) as f64)
            });
            outln!(
                out,
                "gpu layout: {} compressed 8-wide nodes, {} leaf triangles, {} bytes{ratio}; traced by `bvhc trace --gpu`",
                gpu.nodes.len(),
                gpu.triangles.len(),
                gpu_byte_len(&gpu)
            )
        }
        None => outln!(out, "gpu layout: none (convert with --gpu-layout to trace on a GPU)"),
    }
    let histogram: Vec<String> = stats.leaf_sizes.iter().map(|(size, n)| format!("{size}: {n}")).collect();
    outln!(out, "leaf sizes (triangles: leaves): {}", histogram.join(", "));
    match cost {
        Some(cost) => outln!(
            out,
            "SAH cost {:.3} with (c_T, c_I) = ({}, {}): A_I {:.3}, A_L {:.3}",
            cost.cost,
            constants.traversal,
            constants.intersection,
            cost.inner_area_ratio,
            cost.leaf_area_ratio
        ),
        None => outln!(out, "SAH cost: not defined for a two-level file (no tree spans the scene)"),
    }
    if !metadata.is_null() {
        outln!(out, "generator: {}", metadata["generator"].as_str().unwrap_or("?"));
        for input in metadata["inputs"].as_array().into_iter().flatten() {
            outln!(
                out,
                "input: {} ({})",
                input["file_name"].as_str().unwrap_or("?"),
                input["content_hash"].as_str().unwrap_or("no hash")
            );
        }
        outln!(out, "build options: {}", metadata["build"]);
        let choice = &metadata["choice"];
        if let (Some(candidates), Some(kept)) = (choice["candidates"].as_array(), choice["kept"].as_u64()) {
            let name = |c: &serde_json::Value| {
                let optimized = match c["optimize_over"].as_str().unwrap_or("?") {
                    "none" => "not optimized".to_string(),
                    over => format!("over {over}"),
                };
                format!("{} triangles cut, {optimized}", c["split_triangles"].as_str().unwrap_or("?"))
            };
            let costs: Vec<String> = candidates.iter().map(|c| format!("{}: {}", name(c), c["cost"])).collect();
            let kept = candidates.get(kept as usize).map_or("?".to_string(), name);
            outln!(out, "choice by {}: kept {kept} ({})", choice["measure"].as_str().unwrap_or("?"), costs.join("; "));
        }
        let sampling = &metadata["sampling"];
        if let Some(why) = sampling["skipped"].as_str() {
            outln!(out, "ray sampling: skipped ({why})");
        } else if let Some(training) = sampling["training_rays"].as_u64() {
            let held_out = sampling["held_out_rays"].as_u64().unwrap_or(0);
            let seed = sampling["held_out_seed"].as_u64().map_or(String::new(), |s| format!(", seed {s}"));
            outln!(out, "ray sampling: {training} training rays, {held_out} held-out rays{seed}");
        }
        outln!(
            out,
            "timings: not recorded in the file (they would make identical builds differ); see `bvhc ... --json`"
        );
    }
    print(&out, Exit::Success)
}

/// Distinct source triangles in the triangles section: its records, unless `SPLIT_REFERENCES` lets one triangle
/// be stored several times; then the distinct ids (records with one id are one triangle), or without ids the
/// metadata's `triangles.stored_count` (rule V36 keeps it between the distinct vertex triples and the records:
/// two source triangles may have the same vertices), and only without that the distinct vertex triples.
fn unique_triangle_count(view: &bvhc::loader::BvhView<'_>, metadata: &serde_json::Value) -> usize {
    if !view.has_split_references() {
        return view.triangles().len();
    }
    match view.triangle_ids() {
        Some(ids) => {
            let mut ids = ids.to_vec();
            ids.sort_unstable();
            ids.dedup();
            ids.len()
        }
        None => match metadata["triangles"]["stored_count"].as_u64() {
            Some(stored) => stored as usize,
            None => {
                let mut keys: Vec<[u32; 9]> = view.triangles().iter().map(|t| t.coordinate_bits()).collect();
                keys.sort_unstable();
                keys.dedup();
                keys.len()
            }
        },
    }
}

/// Bytes of the two GPU sections.
fn gpu_byte_len(gpu: &bvhc::loader::GpuSections<'_>) -> usize {
    size_of_val(gpu.nodes) + size_of_val(gpu.triangles)
}

/// The records the `triangle_flags` section marks not opaque, or `None` without the section (all opaque).
fn not_opaque_count(view: &BvhView<'_>) -> Option<usize> {
    let flags = view.triangle_flags()?;
    Some(flags.iter().filter(|&&f| f & bvhc::loader::format::TRIANGLE_NOT_OPAQUE != 0).count())
}
