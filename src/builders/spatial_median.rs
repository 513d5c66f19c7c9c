//! The spatial median builder: each node's box is split in the middle of one axis, the longest at the root and
//! then round robin (x, y, z, x, ...), triangles going to the side of their centroid. When one side would be
//! empty, or below `MEDIAN_FALLBACK_DEPTH`, the node is split at the median triangle instead.

use super::MEDIAN_FALLBACK_DEPTH;
use crate::build_tree::{BuildNode, BuildTree};
use crate::geometry::Aabb;

/// Builds a spatial-median tree over `triangles` with at most `max_leaf_size` (>= 1) triangles per leaf.
pub fn build_spatial_median(triangles: &[[[f32; 3]; 3]], max_leaf_size: usize) -> BuildTree {
    let boxes: Vec<Aabb> = triangles.iter().map(Aabb::of_triangle).collect();
    build_spatial_median_boxes(&boxes, max_leaf_size)
}

/// [`build_spatial_median`] over boxes (e.g. split references): the tree's `triangle_order` holds box indices.
pub fn build_spatial_median_boxes(boxes: &[Aabb], max_leaf_size: usize) -> BuildTree {
    let centroids: Vec<[f32; 3]> = boxes.iter().map(Aabb::center).collect();
    let mut order: Vec<u32> = (0..boxes.len() as u32).collect();
    let mut nodes = Vec::new();
    if !order.is_empty() {
        let root_axis = order.iter().fold(Aabb::EMPTY, |b, &t| b.union(&boxes[t as usize])).longest_axis();
        let mut stack = vec![(0usize, 0usize, order.len(), root_axis, 0usize)];
        nodes.push(BuildNode::Leaf { aabb: Aabb::EMPTY, first: 0, count: 0 });
        while let Some((slot, first, end, axis, depth)) = stack.pop() {
            let items = &mut order[first..end];
            let aabb = items.iter().fold(Aabb::EMPTY, |b, &t| b.union(&boxes[t as usize]));
            if items.len() <= max_leaf_size.max(1) {
                nodes[slot] = BuildNode::Leaf { aabb, first: first as u32, count: items.len() as u32 };
                continue;
            }
            let middle = 0.5 * aabb.min[axis] + 0.5 * aabb.max[axis];
            let mut mid = if depth < MEDIAN_FALLBACK_DEPTH {
                partition_in_place(items, |t| centroids[t as usize][axis] < middle)
            } else {
                0
            };
            if mid == 0 || mid == items.len() {
                mid = items.len() / 2;
                items.select_nth_unstable_by(mid, |&a, &b| {
                    centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis]).then(a.cmp(&b))
                });
            }
            let left = nodes.len();
            nodes.push(BuildNode::Leaf { aabb, first: 0, count: 0 });
            nodes.push(BuildNode::Leaf { aabb, first: 0, count: 0 });
            nodes[slot] = BuildNode::Inner { aabb, left: left as u32, right: left as u32 + 1 };
            let next = (axis + 1) % 3;
            stack.push((left + 1, first + mid, end, next, depth + 1));
            stack.push((left, first, first + mid, next, depth + 1));
        }
    }
    BuildTree { nodes, triangle_order: order }
}

/// Stable partition: items satisfying `goes_left` first; returns their count.
fn partition_in_place(items: &mut [u32], goes_left: impl Fn(u32) -> bool) -> usize {
    let (left, right): (Vec<u32>, Vec<u32>) = items.iter().partition(|&&t| goes_left(t));
    let mid = left.len();
    items[..mid].copy_from_slice(&left);
    items[mid..].copy_from_slice(&right);
    mid
}
