//! The binary layout's refit: every node's box recomputed from the triangle records beneath it, children before
//! parents, keeping the tree's shape (which node holds which records).

use crate::format::{EMPTY_BOUNDS, PackedNode, PackedTriangle, grow_bounds, union_bounds};
use crate::parallel::Workers;

/// Nodes a thread takes at least in the leaf pass.
const MIN_CHUNK: usize = 1 << 18;

/// Recomputes every node's box of `nodes` (a verified file's binary tree over `triangles`, children after their
/// parent, V16-V18) bottom up: a leaf's box the union of its records' bounds (the leaves in parallel over chunks
/// of nodes), then an inner node's the union of its two children's boxes (in reverse node order, on one thread),
/// as the converter's packing computes them. Indices out of range (a file that does not verify) leave the node's
/// box empty rather than panic.
pub(crate) fn refit_binary(nodes: &mut [PackedNode], triangles: &[PackedTriangle], workers: Workers) {
    workers.for_chunks(nodes, MIN_CHUNK, |_, chunk| {
        for node in chunk.iter_mut().filter(|n| n.is_leaf()) {
            let (first, count) = (node.index as usize, node.count as usize);
            let records = triangles.get(first..first.saturating_add(count)).unwrap_or(&[]);
            (node.min, node.max) = records.iter().fold(EMPTY_BOUNDS, |b, t| grow_bounds(b, &t.vertices));
        }
    });
    for i in (0..nodes.len()).rev() {
        let node = nodes[i];
        if node.is_leaf() {
            continue;
        }
        let first = node.index as usize;
        let child = |c: usize| nodes.get(c).map_or(EMPTY_BOUNDS, |n| (n.min, n.max));
        (nodes[i].min, nodes[i].max) = union_bounds(child(first), child(first.saturating_add(1)));
    }
}
