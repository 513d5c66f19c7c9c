//! `bvhc verify FILE` and `bvhc info FILE [--json]`.

use std::path::Path;

use bvhc::inspect::{Inspection, gpu_byte_len, inspect, not_opaque_count, not_opaque_triangle_count};
use bvhc::loader::BvhFile;

use super::output::{outln, print};
use super::{Exit, fail, loader_exit};

/// Reads and fully verifies a file; the error exit when it cannot be read or is invalid.
pub(super) fn read_verified(path: &Path) -> Result<BvhFile, Exit> {
    let file = BvhFile::read(path).map_err(|e| fail(loader_exit(&e), e.for_file(path)))?;
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

/// `bvhc info`.
pub fn info(path: &Path, json: bool) -> Exit {
    let file = match read_verified(path) {
        Ok(file) => file,
        Err(exit) => return exit,
    };
    let view = file.view();
    let two_level = view.two_level();
    let inspection = inspect(&view);
    if json {
        let report = inspection.to_json(path, &view);
        return print(&format!("{report:#}\n"), Exit::Success);
    }
    let Inspection { stats, metadata, constants, cost, sections, unique_triangles, .. } = inspection;
    let (major, minor) = view.version();
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
    match (not_opaque_count(&view), not_opaque_triangle_count(&view)) {
        (Some(count), Some(triangles)) => outln!(
            out,
            "opacity: {count} of {} triangle records ({triangles} distinct triangles) not opaque (a filtered tracer \
             asks its filter about these alone)",
            view.triangles().len()
        ),
        _ => outln!(out, "opacity: every triangle opaque (no triangle_flags section)"),
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
        if let Some(line) = animation_line(&metadata["animation"], &metadata["build"]["animation"]["window"]) {
            outln!(out, "{line}");
        }
        super::stage_info::stage_lines(&mut out, &view, &metadata);
        outln!(
            out,
            "timings: not recorded in the file (they would make identical builds differ); see `bvhc ... --json`"
        );
    }
    print(&out, Exit::Success)
}

/// The metadata's `animation` object in a line: the clips (and the part of them sampled, from `window`, the
/// `build` record's) and poses the tree was chosen for, the mean refit cost and the costliest pose, and a
/// two-level file's instances the clips move (`None` without one).
fn animation_line(animation: &serde_json::Value, window: &serde_json::Value) -> Option<String> {
    let clips: Vec<String> = animation["clips"]
        .as_array()?
        .iter()
        .map(|c| {
            let name = c["name"].as_str().map_or_else(|| format!("clip {}", c["index"]), str::to_string);
            let (start, end) = (c["start"].as_f64().unwrap_or(0.0), c["end"].as_f64().unwrap_or(0.0));
            match (window["start"].as_f64(), window["end"].as_f64()) {
                (Some(from), Some(to)) => {
                    format!("{name} {:.2}-{:.2} s (of {start:.2}-{end:.2} s)", start.max(from), end.min(to))
                }
                _ => format!("{name} {start:.2}-{end:.2} s"),
            }
        })
        .collect();
    let moving = animation["moving_instances"].as_array().map_or(String::new(), |moving| {
        let nodes: Vec<String> = moving.iter().map(|m| m["node"].to_string()).collect();
        format!("; {} instances moving (nodes {})", moving.len(), nodes.join(", "))
    });
    let Some(poses) = animation["poses"].as_array() else {
        return Some(format!("animation: {}{moving}; nothing flattened deforms", clips.join(", ")));
    };
    let (mean, of) = match animation["expected_wide_cost"].as_f64() {
        Some(wide) => (wide, "wide cost"),
        None => (animation["expected_sah_cost"].as_f64().unwrap_or(0.0), "SAH cost"),
    };
    let of_mesh = if moving.is_empty() { "" } else { " of mesh 0" };
    let worst = &poses.get(animation["worst_pose"].as_u64()? as usize)?;
    Some(format!(
        "animation: tree{of_mesh} chosen for {} poses of {}; refit {of} mean {mean:.3}, worst {:.3}x the stored (clip {} at {:.2} s){moving}",
        poses.len(),
        clips.join(", "),
        animation["worst_cost_ratio"].as_f64().unwrap_or(0.0),
        worst["clip"],
        worst["seconds"].as_f64().unwrap_or(0.0)
    ))
}
