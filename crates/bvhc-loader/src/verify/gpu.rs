//! Rules V47-V50 of `format-spec/bvh-1.md`: the GPU sections of format 1.4 (compressed 8-wide nodes and their
//! leaf triangles). The nodes are laid out breadth first, so one pass in node order checks the shape (every
//! node's children and triangles are the next unclaimed block), the meta bytes, the depth and the decoded
//! boxes (each node's box is known when it is reached: the slot that references it comes earlier).
//!
//! Cost: O(GPU nodes + GPU triangles), plus the coverage test of split references. Memory: a box and a depth
//! per GPU node, a bit per triangle record.

use crate::error::{Rule, Violation, violation};
use crate::format::{
    EMPTY_BOUNDS, GPU_MAX_DEPTH, GPU_WIDE, GpuNode, GpuSlot, GpuTriangle, PackedTriangle, SectionKind, inner_meta,
    triangle_bounds, union_bounds,
};
use crate::open::sections::GpuSections;
use crate::verify::references::{leaf_may_hold, verify_coverage};

/// What the GPU sections are checked against: the file's triangles, ids, and split-references flag.
pub(crate) struct GpuContext<'a> {
    pub triangles: &'a [PackedTriangle],
    pub triangle_ids: Option<&'a [u32]>,
    pub split_references: bool,
}

type Box3 = ([f32; 3], [f32; 3]);

/// V47-V50.
pub(crate) fn verify_gpu(gpu: &GpuSections<'_>, context: &GpuContext<'_>) -> Result<(), Violation> {
    check_shape(gpu.nodes, gpu.triangles.len())?;
    check_boxes(gpu, context.split_references)?;
    check_triangles(gpu.triangles, context)?;
    check_leaves(gpu, context)
}

fn shape_error(detail: String) -> Violation {
    violation(Rule::GpuTreeShape, detail)
}

/// V47: breadth-first layout (each node's children and leaf triangles are the next blocks), meta bytes that
/// agree with the inner mask, leaves at consecutive offsets in slot order, occupancy, depth.
fn check_shape(nodes: &[GpuNode], gpu_triangle_count: usize) -> Result<(), Violation> {
    let mut depth = vec![0u8; nodes.len()];
    let (mut next_child, mut next_triangle) = (1u64, 0u64);
    for (i, node) in nodes.iter().enumerate() {
        let at = format!("gpu node {i}");
        if i > 0 && i as u64 >= next_child {
            return Err(shape_error(format!("{at}: referenced by no slot of an earlier node")));
        }
        if u64::from(node.child_base) != next_child || u64::from(node.triangle_base) != next_triangle {
            return Err(shape_error(format!(
                "{at}: child_base {} and triangle_base {} must be {next_child} and {next_triangle} (children and \
                 triangles follow in node order)",
                node.child_base, node.triangle_base
            )));
        }
        let (mut occupied, mut offset) = (0, 0u32);
        for slot in 0..GPU_WIDE {
            let inner_bit = node.inner_mask & (1 << slot) != 0;
            match node.slot(slot) {
                GpuSlot::Empty if !inner_bit => {
                    let bytes = (0..3).flat_map(|a| [node.quantized_min[a][slot], node.quantized_max[a][slot]]);
                    if bytes.into_iter().any(|q| q != 0) {
                        return Err(shape_error(format!("{at} slot {slot}: an empty slot's box bytes must be 0")));
                    }
                }
                GpuSlot::Inner(_) if inner_bit => occupied += 1,
                GpuSlot::Leaf { first, count } if !inner_bit => {
                    if first.wrapping_sub(node.triangle_base) != offset {
                        return Err(shape_error(format!(
                            "{at} slot {slot}: leaf at offset {} but the node's leaves so far end at {offset} \
                             (leaves take consecutive offsets in slot order)",
                            first.wrapping_sub(node.triangle_base)
                        )));
                    }
                    offset += count;
                    occupied += 1;
                }
                _ => {
                    return Err(shape_error(format!(
                        "{at} slot {slot}: meta {:#04x} with inner_mask bit {} (inner: {:#04x}; leaf: 1-3 unary \
                         count bits over an offset below 24; empty: 0)",
                        node.meta[slot],
                        u8::from(inner_bit),
                        inner_meta(slot)
                    )));
                }
            }
        }
        if occupied < if i == 0 { 1 } else { 2 } {
            return Err(shape_error(format!("{at}: {occupied} occupied slots (the root needs 1, other nodes 2)")));
        }
        let children = u64::from(node.inner_mask.count_ones());
        let child_depth = depth[i] + 1;
        for child in next_child..next_child + children {
            let Some(d) = depth.get_mut(child as usize) else {
                return Err(shape_error(format!("{at}: child {child} is beyond the {} GPU nodes", nodes.len())));
            };
            *d = child_depth;
            if usize::from(child_depth) > GPU_MAX_DEPTH {
                return Err(shape_error(format!("{at}: child {child} is deeper than {GPU_MAX_DEPTH}")));
            }
        }
        next_child += children;
        next_triangle += u64::from(offset);
    }
    let count = nodes.len() as u64;
    if !nodes.is_empty() && (next_child != count || next_triangle != gpu_triangle_count as u64) {
        return Err(shape_error(format!(
            "the slots reference {next_child} nodes (with the root) and {next_triangle} GPU triangles; the \
             sections hold {count} and {gpu_triangle_count}"
        )));
    }
    Ok(())
}

/// V48: grid steps in the normal range; every decoded value finite, zero or normal (the origin, which empty slots
/// decode to, and every occupied slot's box), occupied boxes ordered;
/// and every inner slot's decoded box containing its child node's **content**, the union of the child's
/// occupied slots' contents: an inner slot's is its child's content, a leaf's the bounds of its triangles (with
/// split references, each clipped to the leaf's decoded box). Computed children first (in reverse node order,
/// as children follow their parents). Requires V47.
fn check_boxes(gpu: &GpuSections<'_>, split_references: bool) -> Result<(), Violation> {
    let fail = |detail: String| Err(violation(Rule::GpuBox, detail));
    for (i, node) in gpu.nodes.iter().enumerate() {
        if let Some(a) = (0..3).find(|&a| !(1..=254).contains(&node.exponents[a])) {
            return fail(format!("gpu node {i}: exponent {} of axis {a} is not 1..=254", node.exponents[a]));
        }
        let usable = |v: f32| v.is_finite() && (v == 0.0 || v.abs() >= f32::MIN_POSITIVE);
        // An empty slot's box bytes are 0 (V47), so its decoded values are the origin's.
        if !node.origin.iter().all(|&v| usable(v)) {
            return fail(format!(
                "gpu node {i}: origin {:?} (the decoded values of its empty slots) must be finite, zero or normal",
                node.origin
            ));
        }
        for slot in (0..GPU_WIDE).filter(|&s| node.meta[s] != 0) {
            let (min, max) = node.slot_box(slot);
            if !min.iter().chain(&max).all(|&v| usable(v)) || (0..3).any(|a| min[a] > max[a]) {
                return fail(format!(
                    "gpu node {i} slot {slot}: decoded box {min:?}..{max:?} must be finite, zero or normal, min <= max"
                ));
            }
        }
    }
    let mut content: Vec<Box3> = vec![EMPTY_BOUNDS; gpu.nodes.len()];
    for (i, node) in gpu.nodes.iter().enumerate().rev() {
        let mut node_content = EMPTY_BOUNDS;
        for slot in 0..GPU_WIDE {
            let slot_content = match node.slot(slot) {
                GpuSlot::Inner(child) => {
                    let child_content = content[child as usize];
                    let (min, max) = node.slot_box(slot);
                    let inside = (0..3).all(|a| {
                        child_content.0[a] > child_content.1[a]
                            || (min[a] <= child_content.0[a] && child_content.1[a] <= max[a])
                    });
                    if !inside {
                        return fail(format!(
                            "gpu node {i} slot {slot}: decoded box {min:?}..{max:?} does not contain the content \
                             {:?}..{:?} of its child, gpu node {child}",
                            child_content.0, child_content.1
                        ));
                    }
                    child_content
                }
                GpuSlot::Leaf { first, count } => {
                    let clip = node.slot_box(slot);
                    gpu.triangles[first as usize..(first + count) as usize].iter().fold(EMPTY_BOUNDS, |b, t| {
                        let bounds = triangle_bounds(&t.vertices);
                        union_bounds(b, if split_references { clipped(bounds, clip) } else { bounds })
                    })
                }
                _ => EMPTY_BOUNDS,
            };
            node_content = union_bounds(node_content, slot_content);
        }
        content[i] = node_content;
    }
    Ok(())
}

/// `a` inside `clip`, or [`EMPTY_BOUNDS`] where they do not overlap.
fn clipped(a: Box3, clip: Box3) -> Box3 {
    let b: Box3 = (std::array::from_fn(|k| a.0[k].max(clip.0[k])), std::array::from_fn(|k| a.1[k].min(clip.1[k])));
    if (0..3).all(|k| b.0[k] <= b.1[k]) { b } else { EMPTY_BOUNDS }
}

/// V49: every GPU triangle names a record and repeats its vertices bit for bit; every record is named (exactly
/// once without split references; with them, each record's triangle, by id and vertices, is named by some GPU
/// triangle).
fn check_triangles(gpu_triangles: &[GpuTriangle], context: &GpuContext<'_>) -> Result<(), Violation> {
    let triangles = context.triangles;
    let mut named = vec![false; triangles.len()];
    for (g, gpu) in gpu_triangles.iter().enumerate() {
        let record = triangles.get(gpu.triangle_index as usize);
        let same = record.is_some_and(|r| {
            (0..3).all(|v| (0..3).all(|a| r.vertices[v][a].to_bits() == gpu.vertices[v][a].to_bits()))
        });
        if !same {
            return Err(violation(
                Rule::GpuTriangles,
                format!(
                    "gpu triangle {g}: triangle_index {} must name a record of the {} in the triangles section \
                     with the same vertices bit for bit",
                    gpu.triangle_index,
                    triangles.len()
                ),
            ));
        }
        let seen = &mut named[gpu.triangle_index as usize];
        if *seen && !context.split_references {
            return Err(violation(
                Rule::GpuTriangles,
                format!("gpu triangle {g}: triangle {} is named twice without split references", gpu.triangle_index),
            ));
        }
        *seen = true;
    }
    let key = |t: usize| (context.triangle_ids.map_or(0, |ids| ids[t]), triangles[t].coordinate_bits());
    let mut named_keys: Vec<_> = (0..triangles.len()).filter(|&t| named[t]).map(key).collect();
    if named_keys.len() == triangles.len() {
        return Ok(());
    }
    named_keys.sort_unstable();
    match (0..triangles.len()).find(|&t| !named[t] && named_keys.binary_search(&key(t)).is_err()) {
        Some(t) => Err(violation(
            Rule::GpuTriangles,
            format!("triangle {t}: no GPU triangle names it or another reference of it"),
        )),
        None => Ok(()),
    }
}

/// V50: each leaf's triangles inside the leaf slot's decoded box; with split references overlapping it, and
/// the GPU leaves holding a triangle's references covering it. Requires V47-V49.
fn check_leaves(gpu: &GpuSections<'_>, context: &GpuContext<'_>) -> Result<(), Violation> {
    let mut placements = Vec::new();
    for (i, node) in gpu.nodes.iter().enumerate() {
        for slot in 0..GPU_WIDE {
            let GpuSlot::Leaf { first, count } = node.slot(slot) else { continue };
            let (min, max) = node.slot_box(slot);
            for g in first..first + count {
                let triangle = &gpu.triangles[g as usize];
                let v = &triangle.vertices;
                let inside = leaf_may_hold(&(min, max), v, context.split_references);
                if !inside {
                    return Err(violation(
                        Rule::GpuLeafBox,
                        format!(
                            "gpu triangle {g} (triangle {}): {v:?} not inside its leaf, gpu node {i} slot {slot} \
                             decoded box {min:?}..{max:?}",
                            triangle.triangle_index
                        ),
                    ));
                }
                if context.split_references {
                    placements.push((triangle.triangle_index, (i * GPU_WIDE + slot) as u32));
                }
            }
        }
    }
    if !context.split_references {
        return Ok(());
    }
    let box_of = |container: u32| gpu.nodes[container as usize / GPU_WIDE].slot_box(container as usize % GPU_WIDE);
    verify_coverage(
        &placements,
        box_of,
        context.triangles,
        context.triangle_ids,
        Rule::GpuLeafBox,
        &format!("{} leaf slots (node x 8 + slot)", SectionKind::GpuNodes.name()),
    )
}
