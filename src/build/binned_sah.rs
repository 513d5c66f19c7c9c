//! Initial BVH construction: a binned SAH builder (I. Wald, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies", IEEE RT 2007).
//!
//! Centroids are binned into [`BIN_COUNT`] bins along each axis; the split plane with the lowest SAH cost
//! `c_T + c_I (A_left n_left + A_right n_right) / A_node` wins, and a node becomes a leaf when that is not
//! cheaper than `c_I n` and it holds at most `max_leaf_size` triangles. Where the centroids coincide, or below
//! [`MEDIAN_FALLBACK_DEPTH`], the node is split at the median triangle instead, which bounds the depth by
//! `MEDIAN_FALLBACK_DEPTH + log2(n)` and keeps every tree within the format's depth rule. The result depends
//! only on the input (no threads, no hashing), so builds are deterministic.

use super::{BuildNode, BuildTree};
use crate::aabb::Aabb;

/// Bins per axis.
pub const BIN_COUNT: usize = 16;
/// Depth from which nodes are split at the median triangle, whatever the SAH says.
pub const MEDIAN_FALLBACK_DEPTH: usize = 160;
/// Cost of a traversal step in the split decisions (the reference convention's c_T).
const TRAVERSAL_COST: f64 = 3.0;
/// Cost of a triangle test in the split decisions (the reference convention's c_I).
const INTERSECTION_COST: f64 = 2.0;

/// Builds a binned SAH tree over `triangles` with at most `max_leaf_size` (>= 1) triangles per leaf.
pub fn build_binned_sah(triangles: &[[[f32; 3]; 3]], max_leaf_size: usize) -> BuildTree {
    let boxes: Vec<Aabb> = triangles.iter().map(Aabb::of_triangle).collect();
    let centroids: Vec<[f32; 3]> = boxes.iter().map(Aabb::center).collect();
    let mut builder =
        Builder { boxes: &boxes, centroids: &centroids, max_leaf_size: max_leaf_size.max(1), nodes: Vec::new() };
    let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
    if !order.is_empty() {
        builder.nodes.push(BuildNode::Leaf { aabb: Aabb::EMPTY, first: 0, count: 0 });
        builder.split(0, &mut order, 0, 0);
    }
    BuildTree { nodes: builder.nodes, triangle_order: order }
}

struct Builder<'a> {
    boxes: &'a [Aabb],
    centroids: &'a [[f32; 3]],
    max_leaf_size: usize,
    nodes: Vec<BuildNode>,
}

impl Builder<'_> {
    /// Fills node `slot` with a subtree over `order` (which starts at `first` of the whole order).
    fn split(&mut self, slot: usize, order: &mut [u32], first: usize, depth: usize) {
        let aabb = order.iter().fold(Aabb::EMPTY, |b, &t| b.union(&self.boxes[t as usize]));
        let leaf = BuildNode::Leaf { aabb, first: first as u32, count: order.len() as u32 };
        if order.len() == 1 {
            self.nodes[slot] = leaf;
            return;
        }
        let mid = match self.best_sah_split(order, &aabb, depth) {
            SplitChoice::Leaf if order.len() <= self.max_leaf_size => {
                self.nodes[slot] = leaf;
                return;
            }
            SplitChoice::Plane { axis, position } => partition(order, |t| self.centroids[t as usize][axis] < position),
            SplitChoice::Leaf | SplitChoice::Median => {
                let axis = aabb.longest_axis();
                let mid = order.len() / 2;
                order.select_nth_unstable_by(mid, |&a, &b| {
                    self.centroids[a as usize][axis].total_cmp(&self.centroids[b as usize][axis]).then(a.cmp(&b))
                });
                mid
            }
        };
        let left = self.nodes.len() as u32;
        self.nodes.push(leaf);
        self.nodes.push(leaf);
        self.nodes[slot] = BuildNode::Inner { aabb, left, right: left + 1 };
        let (left_order, right_order) = order.split_at_mut(mid);
        self.split(left as usize, left_order, first, depth + 1);
        self.split(left as usize + 1, right_order, first + mid, depth + 1);
    }

    fn best_sah_split(&self, order: &[u32], aabb: &Aabb, depth: usize) -> SplitChoice {
        if depth >= MEDIAN_FALLBACK_DEPTH {
            return SplitChoice::Median;
        }
        let centroid_box = order.iter().fold(Aabb::EMPTY, |b, &t| b.grow(&self.centroids[t as usize]));
        let leaf_cost = INTERSECTION_COST * order.len() as f64;
        let mut best = (f64::INFINITY, SplitChoice::Median);
        for axis in 0..3 {
            let (lo, hi) = (centroid_box.min[axis], centroid_box.max[axis]);
            if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
                continue;
            }
            let scale = BIN_COUNT as f32 / (hi - lo);
            let bin_of = |c: f32| (((c - lo) * scale) as usize).min(BIN_COUNT - 1);
            let mut bins = [(Aabb::EMPTY, 0usize); BIN_COUNT];
            for &t in order {
                let bin = &mut bins[bin_of(self.centroids[t as usize][axis])];
                bin.0 = bin.0.union(&self.boxes[t as usize]);
                bin.1 += 1;
            }
            // Sweep from the right to get the right-side areas, then from the left.
            let mut right_area = [0.0f64; BIN_COUNT];
            let mut acc = (Aabb::EMPTY, 0usize);
            for b in (1..BIN_COUNT).rev() {
                acc = (acc.0.union(&bins[b].0), acc.1 + bins[b].1);
                right_area[b] = acc.0.surface_area() * acc.1 as f64;
            }
            let mut left = (Aabb::EMPTY, 0usize);
            for b in 1..BIN_COUNT {
                left = (left.0.union(&bins[b - 1].0), left.1 + bins[b - 1].1);
                if left.1 == 0 || left.1 == order.len() {
                    continue;
                }
                let cost = left.0.surface_area() * left.1 as f64 + right_area[b];
                if cost < best.0 {
                    best = (cost, SplitChoice::Plane { axis, position: lo + b as f32 / scale });
                }
            }
        }
        let area = aabb.surface_area();
        if let SplitChoice::Plane { .. } = best.1 {
            let split_cost =
                if area > 0.0 { TRAVERSAL_COST + INTERSECTION_COST * best.0 / area } else { f64::INFINITY };
            if split_cost >= leaf_cost {
                return SplitChoice::Leaf;
            }
        }
        best.1
    }
}

enum SplitChoice {
    Leaf,
    Median,
    Plane { axis: usize, position: f32 },
}

/// Moves the items satisfying `goes_left` to the front, keeping a stable order; returns their count. Falls back
/// to the middle when one side would be empty (possible through rounding at a bin boundary).
fn partition(order: &mut [u32], goes_left: impl Fn(u32) -> bool) -> usize {
    let (left, right): (Vec<u32>, Vec<u32>) = order.iter().partition(|&&t| goes_left(t));
    if left.is_empty() || right.is_empty() {
        return order.len() / 2;
    }
    let mid = left.len();
    order[..mid].copy_from_slice(&left);
    order[mid..].copy_from_slice(&right);
    mid
}
