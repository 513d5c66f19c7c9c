//! The GPU layout's refit: each GPU triangle's vertices copied from the triangle record it names, then every
//! node's grid and quantized slot boxes encoded again bottom up from the exact boxes beneath each slot, keeping
//! the tree's shape.

use crate::error::Error;
use crate::format::{
    Bounds, EMPTY_BOUNDS, GPU_WIDE, GpuNode, GpuSlot, GpuTriangle, PackedTriangle, triangle_bounds, union_bounds,
};

/// Rewrites `gpu_triangles` from `triangles` (each one's `triangle_index` record) and every node of `nodes` (a
/// verified file's GPU tree, breadth first, so children after parents) bottom up: each slot's exact box (an inner
/// slot's the union of its child's slots', a leaf slot's its triangles' bounds) quantized as the converter
/// encodes them ([`GpuNode::encode_slot_boxes`]). Fails, naming the node, where a box is too large for a finite
/// grid (the nodes before it in this order are then refit, the others not: the caller discards the copy).
pub(crate) fn refit_gpu(
    nodes: &mut [GpuNode],
    gpu_triangles: &mut [GpuTriangle],
    triangles: &[PackedTriangle],
) -> Result<(), Error> {
    for gpu_triangle in gpu_triangles.iter_mut() {
        if let Some(record) = triangles.get(gpu_triangle.triangle_index as usize) {
            gpu_triangle.vertices = record.vertices;
        }
    }
    // The exact content of each node (the union of its slots' exact boxes), children first.
    let mut content = vec![EMPTY_BOUNDS; nodes.len()];
    for i in (0..nodes.len()).rev() {
        let boxes: [Option<Bounds>; GPU_WIDE] = std::array::from_fn(|slot| match nodes[i].slot(slot) {
            GpuSlot::Inner(child) => Some(content.get(child as usize).copied().unwrap_or(EMPTY_BOUNDS)),
            GpuSlot::Leaf { first, count } => {
                let leaf = gpu_triangles.get(first as usize..(first as usize).saturating_add(count as usize));
                Some(
                    leaf.unwrap_or(&[]).iter().fold(EMPTY_BOUNDS, |b, t| union_bounds(b, triangle_bounds(&t.vertices))),
                )
            }
            _ => None,
        });
        content[i] = boxes.iter().flatten().fold(EMPTY_BOUNDS, |b, s| union_bounds(b, *s));
        if !nodes[i].encode_slot_boxes(&boxes) {
            return Err(Error::Refit(format!("GPU node {i}: a box too large for the layout's 8-bit grid")));
        }
    }
    Ok(())
}
