//! The binary layout's refit: every node's box recomputed from the triangle records beneath it, children before
//! parents, keeping the tree's shape (which node holds which records).

use crate::format::{EMPTY_BOUNDS, PackedNode, PackedTriangle, triangle_bounds, union_bounds};

/// Recomputes every node's box of `nodes` (a verified file's binary tree over `triangles`, children after their
/// parent, V16-V18) bottom up: a leaf's box the union of its records' bounds, an inner node's the union of its
/// two children's boxes, as the converter's packing computes them. Indices out of range (a file that does not
/// verify) leave the node's box empty rather than panic.
pub(crate) fn refit_binary(nodes: &mut [PackedNode], triangles: &[PackedTriangle]) {
    for i in (0..nodes.len()).rev() {
        let node = nodes[i];
        let (first, count) = (node.index as usize, node.count as usize);
        let bounds = if node.is_leaf() {
            let records = triangles.get(first..first.saturating_add(count)).unwrap_or(&[]);
            records.iter().fold(EMPTY_BOUNDS, |b, t| union_bounds(b, triangle_bounds(&t.vertices)))
        } else {
            let child = |c: usize| nodes.get(c).map_or(EMPTY_BOUNDS, |n| (n.min, n.max));
            union_bounds(child(first), child(first.saturating_add(1)))
        };
        (nodes[i].min, nodes[i].max) = bounds;
    }
}
