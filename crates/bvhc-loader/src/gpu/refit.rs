//! The GPU layout's refit: each GPU triangle's vertices copied from the triangle record it names, then every
//! node's grid and quantized slot boxes encoded again bottom up from the exact boxes beneath each slot, keeping
//! the tree's shape. The nodes are stored breadth first (V47), so each depth of the tree is a run of nodes whose
//! children all lie in the next run: the runs are refit deepest first, each in parallel over chunks.

use crate::error::Error;
use crate::format::{
    Bounds, EMPTY_BOUNDS, GPU_WIDE, GpuNode, GpuSlot, GpuTriangle, PackedTriangle, triangle_bounds, union_bounds,
};
use crate::parallel::Workers;

/// GPU triangles a thread takes at least in the parallel pass (below, a thread's start costs more than it saves).
const MIN_CHUNK: usize = 1 << 18;

/// GPU nodes a thread takes at least (each costs about half a microsecond to encode).
const MIN_NODE_CHUNK: usize = 1 << 11;

/// Rewrites `gpu_triangles` from `triangles` (each one's `triangle_index` record) and every node of `nodes` (a
/// verified file's GPU tree, breadth first) bottom up: each slot's exact box (an inner slot's the union of its
/// child's slots', a leaf slot's its triangles' bounds) quantized as the converter encodes them
/// ([`GpuNode::encode_slot_boxes`]). Fails, naming the node, where a box is too large for a finite grid (some
/// nodes are then refit, others not: the caller discards the copy). A tree that is not breadth first (a file
/// that does not verify) is refit in one run, on one thread, in reverse order, and never panics.
pub(crate) fn refit_gpu(
    nodes: &mut [GpuNode],
    gpu_triangles: &mut [GpuTriangle],
    triangles: &[PackedTriangle],
    workers: Workers,
) -> Result<(), Error> {
    workers.for_chunks(gpu_triangles, MIN_CHUNK, |_, chunk| {
        for gpu_triangle in chunk {
            if let Some(record) = triangles.get(gpu_triangle.triangle_index as usize) {
                gpu_triangle.vertices = record.vertices;
            }
        }
    });
    let gpu_triangles: &[GpuTriangle] = gpu_triangles;
    // The exact content of each node (the union of its slots' exact boxes), filled deepest run first.
    let mut content = vec![EMPTY_BOUNDS; nodes.len()];
    let Some(runs) = depth_runs(nodes) else {
        let count = nodes.len();
        return refit_run(nodes, &mut content, 0, count, &[], gpu_triangles, true);
    };
    for run in runs.iter().rev() {
        let (above, deeper) = content.split_at_mut(run.end);
        let run_content = &mut above[run.start..];
        let deeper: &[Bounds] = deeper;
        let results = workers.for_chunks(&mut nodes[run.clone()], MIN_NODE_CHUNK, |first, chunk| {
            let mut chunk_content = vec![EMPTY_BOUNDS; chunk.len()];
            let start = run.start + first;
            refit_run(chunk, &mut chunk_content, start, run.end, deeper, gpu_triangles, false).map(|()| chunk_content)
        });
        let mut filled = 0;
        for result in results {
            let chunk_content = result?;
            run_content[filled..filled + chunk_content.len()].copy_from_slice(&chunk_content);
            filled += chunk_content.len();
        }
    }
    Ok(())
}

/// Refits `nodes` (the file's nodes `start..start + nodes.len()`), writing each one's exact content into
/// `content` (parallel to `nodes`): an inner slot's child is looked up in `deeper` (the contents from node `end`
/// on) or, with `within`, among `nodes` themselves, already refit in reverse order.
fn refit_run(
    nodes: &mut [GpuNode],
    content: &mut [Bounds],
    start: usize,
    end: usize,
    deeper: &[Bounds],
    gpu_triangles: &[GpuTriangle],
    within: bool,
) -> Result<(), Error> {
    for i in (0..nodes.len()).rev() {
        let boxes: [Option<Bounds>; GPU_WIDE] = std::array::from_fn(|slot| match nodes[i].slot(slot) {
            GpuSlot::Inner(child) => {
                let child = child as usize;
                let exact = match child.checked_sub(end) {
                    Some(below) => deeper.get(below),
                    None if within => child.checked_sub(start).and_then(|k| content.get(k)),
                    None => None,
                };
                Some(exact.copied().unwrap_or(EMPTY_BOUNDS))
            }
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
            let node = start + i;
            return Err(Error::Refit(format!("GPU node {node}: a box too large for the layout's 8-bit grid")));
        }
    }
    Ok(())
}

/// The runs of nodes of each depth, root first: run `d + 1` is exactly the inner children of run `d`, in order
/// (breadth-first placement). `None` where the nodes are not placed so (a file that does not verify).
fn depth_runs(nodes: &[GpuNode]) -> Option<Vec<std::ops::Range<usize>>> {
    let mut runs = Vec::new();
    let mut run = 0..nodes.len().min(1);
    while !run.is_empty() {
        let mut next = run.end;
        for node in &nodes[run.clone()] {
            for slot in 0..GPU_WIDE {
                if let GpuSlot::Inner(child) = node.slot(slot) {
                    (child as usize == next && next < nodes.len()).then_some(())?;
                    next += 1;
                }
            }
        }
        runs.push(run.clone());
        run = run.end..next.min(nodes.len());
    }
    (runs.last().map_or(0, |r| r.end) == nodes.len()).then_some(runs)
}
