//! The top-level tree of a two-level file: a binary tree over instance boxes, one instance per leaf, in the
//! layout of the `top_nodes` section (`format-spec/bvh-1.md` 5.12: node 0 the root, an inner node's children
//! at `index` and `index + 1`, after it).
//!
//! Built top down by binned SAH over the boxes' centroids (Wald, "On fast Construction of SAH-based Bounding
//! Volume Hierarchies", 2007): 16 bins per axis, the split of least `A_left N_left + A_right N_right`, and the
//! median of the longest centroid axis where every centroid falls in one bin or the tree would grow deeper
//! than [`MEDIAN_BELOW_DEPTH`] (so it never reaches the format's `MAX_DEPTH`: below that depth every split
//! halves). Deterministic: no threads, ties broken by index.

use crate::format::MAX_DEPTH;
use crate::format::PackedNode;

/// Bins per axis.
const BINS: usize = 16;

/// Below this depth every split is a median split, which halves the instances, so a tree of up to 2^31
/// instances stays within `MAX_DEPTH`.
pub const MEDIAN_BELOW_DEPTH: usize = MAX_DEPTH - 40;

type Aabb = ([f32; 3], [f32; 3]);

fn union(a: &Aabb, b: &Aabb) -> Aabb {
    (std::array::from_fn(|k| a.0[k].min(b.0[k])), std::array::from_fn(|k| a.1[k].max(b.1[k])))
}

const EMPTY: Aabb = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);

fn half_area(b: &Aabb) -> f64 {
    let d: [f64; 3] = std::array::from_fn(|k| f64::from(b.1[k] - b.0[k]).max(0.0));
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

fn centroid(b: &Aabb, axis: usize) -> f32 {
    0.5 * b.0[axis] + 0.5 * b.1[axis]
}

/// The top tree over `boxes` (instance `i`'s world box is `boxes[i]`); empty for no boxes.
pub fn build_top_tree(boxes: &[Aabb]) -> Vec<PackedNode> {
    if boxes.is_empty() {
        return Vec::new();
    }
    let mut order: Vec<u32> = (0..boxes.len() as u32).collect();
    let mut nodes = vec![PackedNode { min: [0.0; 3], max: [0.0; 3], index: 0, count: 0 }];
    // (node index, range of `order`, depth)
    let mut pending = vec![(0usize, 0..boxes.len(), 0usize)];
    while let Some((node, range, depth)) = pending.pop() {
        let bounds = order[range.clone()].iter().fold(EMPTY, |acc, &i| union(&acc, &boxes[i as usize]));
        nodes[node].min = bounds.0;
        nodes[node].max = bounds.1;
        if range.len() == 1 {
            nodes[node].index = order[range.start];
            nodes[node].count = 1;
            continue;
        }
        let mid = split(boxes, &mut order[range.clone()], depth) + range.start;
        let first_child = nodes.len();
        nodes[node].index = first_child as u32;
        nodes[node].count = 0;
        nodes.push(PackedNode { min: [0.0; 3], max: [0.0; 3], index: 0, count: 0 });
        nodes.push(PackedNode { min: [0.0; 3], max: [0.0; 3], index: 0, count: 0 });
        pending.push((first_child + 1, mid..range.end, depth + 1));
        pending.push((first_child, range.start..mid, depth + 1));
    }
    nodes
}

/// Reorders `items` (two or more) so that `items[..k]` and `items[k..]` are the two children; returns `k`
/// (between 1 and `items.len() - 1`).
fn split(boxes: &[Aabb], items: &mut [u32], depth: usize) -> usize {
    let (lo, hi) = items.iter().fold(([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]), |(lo, hi), &i| {
        let b = &boxes[i as usize];
        (std::array::from_fn(|k| lo[k].min(centroid(b, k))), std::array::from_fn(|k| hi[k].max(centroid(b, k))))
    });
    let longest = (0..3).fold(0, |best, k| if hi[k] - lo[k] > hi[best] - lo[best] { k } else { best });
    if depth < MEDIAN_BELOW_DEPTH
        && let Some((axis, bin)) = best_binned_split(boxes, items, lo, hi)
    {
        let scale = BINS as f32 / (hi[axis] - lo[axis]);
        let bin_of = |i: &u32| (((centroid(&boxes[*i as usize], axis) - lo[axis]) * scale) as usize).min(BINS - 1);
        let k = partition(items, |i| bin_of(i) <= bin);
        if k > 0 && k < items.len() {
            return k;
        }
    }
    // Median of the longest centroid axis, ties by index: always a split of sizes n/2 and n - n/2.
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| {
        let (ca, cb) = (centroid(&boxes[*a as usize], longest), centroid(&boxes[*b as usize], longest));
        ca.total_cmp(&cb).then(a.cmp(b))
    });
    mid
}

/// The `(axis, last bin of the left side)` of least SAH, `None` when the centroids do not spread.
fn best_binned_split(boxes: &[Aabb], items: &[u32], lo: [f32; 3], hi: [f32; 3]) -> Option<(usize, usize)> {
    let mut best: Option<(f64, usize, usize)> = None;
    for axis in 0..3 {
        let extent = hi[axis] - lo[axis];
        // Also skips a NaN extent (boxes are finite, so it cannot occur).
        if extent.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            continue;
        }
        let scale = BINS as f32 / extent;
        let mut bins = [(EMPTY, 0usize); BINS];
        for &i in items {
            let b = &boxes[i as usize];
            let bin = (((centroid(b, axis) - lo[axis]) * scale) as usize).min(BINS - 1);
            bins[bin] = (union(&bins[bin].0, b), bins[bin].1 + 1);
        }
        let mut right = [(0.0f64, 0usize); BINS];
        let mut acc = (EMPTY, 0usize);
        for bin in (1..BINS).rev() {
            acc = (union(&acc.0, &bins[bin].0), acc.1 + bins[bin].1);
            right[bin] = (half_area(&acc.0), acc.1);
        }
        let mut left = (EMPTY, 0usize);
        for bin in 0..BINS - 1 {
            left = (union(&left.0, &bins[bin].0), left.1 + bins[bin].1);
            let (right_area, right_count) = right[bin + 1];
            if left.1 == 0 || right_count == 0 {
                continue;
            }
            let cost = half_area(&left.0) * left.1 as f64 + right_area * right_count as f64;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, bin));
            }
        }
    }
    best.map(|(_, axis, bin)| (axis, bin))
}

/// Moves the items for which `left` holds to the front, keeping each side's order; returns how many.
fn partition(items: &mut [u32], left: impl Fn(&u32) -> bool) -> usize {
    let (mut front, back): (Vec<u32>, Vec<u32>) = items.iter().partition(|i| left(i));
    let k = front.len();
    front.extend(back);
    items.copy_from_slice(&front);
    k
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box_at(x: f32, y: f32) -> Aabb {
        ([x, y, 0.0], [x + 1.0, y + 1.0, 1.0])
    }

    /// Every instance in exactly one leaf, children after parents, parents enclosing children.
    fn assert_well_formed(nodes: &[PackedNode], boxes: &[Aabb]) {
        assert_eq!(nodes.len(), 2 * boxes.len() - 1);
        let mut seen = vec![false; boxes.len()];
        for (i, node) in nodes.iter().enumerate() {
            if node.count == 1 {
                assert!(!std::mem::replace(&mut seen[node.index as usize], true));
                assert_eq!((node.min, node.max), boxes[node.index as usize]);
            } else {
                assert!(node.index as usize > i);
                for child in &nodes[node.index as usize..node.index as usize + 2] {
                    assert!((0..3).all(|k| child.min[k] >= node.min[k] && child.max[k] <= node.max[k]));
                }
            }
        }
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn grids_coincident_boxes_and_one_box_make_trees_with_every_instance_once() {
        let grid: Vec<Aabb> = (0..100).map(|i| unit_box_at((i % 10) as f32 * 2.0, (i / 10) as f32 * 2.0)).collect();
        assert_well_formed(&build_top_tree(&grid), &grid);
        let same = vec![unit_box_at(0.0, 0.0); 1000];
        assert_well_formed(&build_top_tree(&same), &same);
        let one = vec![unit_box_at(3.0, 4.0)];
        assert_eq!(build_top_tree(&one), vec![PackedNode { min: one[0].0, max: one[0].1, index: 0, count: 1 }]);
    }

    #[test]
    fn a_row_of_exponentially_spread_boxes_stays_within_the_depth_limit() {
        // Centroids 2^k apart put one box per binned split: only the median fallback bounds the depth.
        let boxes: Vec<Aabb> = (0..600).map(|k| unit_box_at(1.1f32.powi(k), 0.0)).collect();
        let nodes = build_top_tree(&boxes);
        assert_well_formed(&nodes, &boxes);
        let mut depth = vec![0usize; nodes.len()];
        for (i, node) in nodes.iter().enumerate().filter(|(_, n)| n.count == 0) {
            depth[node.index as usize] = depth[i] + 1;
            depth[node.index as usize + 1] = depth[i] + 1;
        }
        assert!(depth.iter().all(|&d| d <= MAX_DEPTH), "deepest {}", depth.iter().max().unwrap());
    }
}
