//! Initial BVH construction: a binned SAH builder (I. Wald, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies", IEEE RT 2007).
//!
//! Centroids are binned into [`BIN_COUNT`] bins along each axis; the split plane with the lowest SAH cost
//! `c_T + c_I (A_left n_left + A_right n_right) / A_node` wins, and a node becomes a leaf when that is not
//! cheaper than `c_I n` and it holds at most `max_leaf_size` triangles. Where the centroids coincide, or below
//! [`MEDIAN_FALLBACK_DEPTH`], the node is split at the median triangle instead, which bounds the depth by
//! `MEDIAN_FALLBACK_DEPTH + log2(n)` and keeps every tree within the format's depth rule.
//!
//! Nodes are laid out in preorder. Subtrees of more than [`PARALLEL_THRESHOLD`] triangles are built in parallel
//! (rayon) into their own arrays and concatenated left then right, so the result is the same for any number
//! of threads.

use rayon::prelude::*;

use super::{BuildNode, BuildTree};
use crate::aabb::Aabb;

/// Bins per axis.
pub const BIN_COUNT: usize = 16;
/// Depth from which nodes are split at the median triangle, whatever the SAH says.
pub const MEDIAN_FALLBACK_DEPTH: usize = 160;
/// Subtrees with more triangles than this are built in parallel.
const PARALLEL_THRESHOLD: usize = 4096;
/// Cost of a traversal step in the split decisions (the reference convention's c_T).
const TRAVERSAL_COST: f64 = 3.0;
/// Cost of a triangle test in the split decisions (the reference convention's c_I).
const INTERSECTION_COST: f64 = 2.0;

/// Builds a binned SAH tree over `triangles` with at most `max_leaf_size` (>= 1) triangles per leaf.
pub fn build_binned_sah(triangles: &[[[f32; 3]; 3]], max_leaf_size: usize) -> BuildTree {
    let boxes: Vec<Aabb> = triangles.par_iter().map(Aabb::of_triangle).collect();
    let centroids: Vec<[f32; 3]> = boxes.par_iter().map(Aabb::center).collect();
    let builder = Builder { boxes: &boxes, centroids: &centroids, max_leaf_size: max_leaf_size.max(1) };
    let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
    let mut nodes = Vec::with_capacity(2 * triangles.len());
    if !order.is_empty() {
        builder.build(&mut nodes, &mut order, 0, 0);
    }
    BuildTree { nodes, triangle_order: order }
}

struct Builder<'a> {
    boxes: &'a [Aabb],
    centroids: &'a [[f32; 3]],
    max_leaf_size: usize,
}

impl Builder<'_> {
    /// Appends the subtree over `order` (positions `first..` of the whole order) to `nodes`, in preorder.
    fn build(&self, nodes: &mut Vec<BuildNode>, order: &mut [u32], first: usize, depth: usize) {
        let aabb = self.bounds(order, |t| self.boxes[t as usize]);
        let leaf = BuildNode::Leaf { aabb, first: first as u32, count: order.len() as u32 };
        if order.len() == 1 {
            nodes.push(leaf);
            return;
        }
        let mid = match self.best_sah_split(order, &aabb, depth) {
            SplitChoice::Leaf if order.len() <= self.max_leaf_size => {
                nodes.push(leaf);
                return;
            }
            SplitChoice::Plane { axis, position } => partition(order, |t| self.centroids[t as usize][axis] < position),
            SplitChoice::Leaf | SplitChoice::Median => self.median_split(order, &aabb),
        };
        let at = nodes.len();
        nodes.push(leaf); // replaced below
        let (left_order, right_order) = order.split_at_mut(mid);
        if order_len_is_large(left_order.len() + right_order.len()) {
            let (left, right) = rayon::join(
                || self.build_detached(left_order, first, depth + 1),
                || self.build_detached(right_order, first + mid, depth + 1),
            );
            append_shifted(nodes, &left);
            let right_at = append_shifted(nodes, &right);
            nodes[at] = BuildNode::Inner { aabb, left: at as u32 + 1, right: right_at as u32 };
        } else {
            self.build(nodes, left_order, first, depth + 1);
            let right_at = nodes.len();
            self.build(nodes, right_order, first + mid, depth + 1);
            nodes[at] = BuildNode::Inner { aabb, left: at as u32 + 1, right: right_at as u32 };
        }
    }

    /// A subtree in its own array (indices from 0).
    fn build_detached(&self, order: &mut [u32], first: usize, depth: usize) -> Vec<BuildNode> {
        let mut nodes = Vec::with_capacity(2 * order.len());
        self.build(&mut nodes, order, first, depth);
        nodes
    }

    fn median_split(&self, order: &mut [u32], aabb: &Aabb) -> usize {
        let axis = aabb.longest_axis();
        let mid = order.len() / 2;
        order.select_nth_unstable_by(mid, |&a, &b| {
            self.centroids[a as usize][axis].total_cmp(&self.centroids[b as usize][axis]).then(a.cmp(&b))
        });
        mid
    }

    fn best_sah_split(&self, order: &[u32], aabb: &Aabb, depth: usize) -> SplitChoice {
        if depth >= MEDIAN_FALLBACK_DEPTH {
            return SplitChoice::Median;
        }
        let centroid_box = self.bounds(order, |t| {
            let c = self.centroids[t as usize];
            Aabb { min: c, max: c }
        });
        let leaf_cost = INTERSECTION_COST * order.len() as f64;
        let mut best = (f64::INFINITY, SplitChoice::Median);
        for axis in 0..3 {
            let (lo, hi) = (centroid_box.min[axis], centroid_box.max[axis]);
            if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
                continue;
            }
            let scale = BIN_COUNT as f32 / (hi - lo);
            let bin_of = |c: f32| (((c - lo) * scale) as usize).min(BIN_COUNT - 1);
            let fill = |chunk: &[u32]| {
                let mut bins = EMPTY_BINS;
                for &t in chunk {
                    let bin = &mut bins[bin_of(self.centroids[t as usize][axis])];
                    bin.0 = bin.0.union(&self.boxes[t as usize]);
                    bin.1 += 1;
                }
                bins
            };
            // Unions and counts do not depend on the order of reduction, so the parallel form is exact.
            let bins = if order_len_is_large(order.len()) {
                order.par_chunks(PARALLEL_THRESHOLD).map(fill).reduce(|| EMPTY_BINS, merge_bins)
            } else {
                fill(order)
            };
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

/// Per bin: the box and the count of the triangles whose centroid falls into it.
type Bins = [(Aabb, usize); BIN_COUNT];
const EMPTY_BINS: Bins = [(Aabb::EMPTY, 0); BIN_COUNT];

fn merge_bins(mut a: Bins, b: Bins) -> Bins {
    for (x, y) in a.iter_mut().zip(b) {
        *x = (x.0.union(&y.0), x.1 + y.1);
    }
    a
}

impl Builder<'_> {
    /// The union of `item(t)` over `order` (in parallel chunks for large nodes; exact either way).
    fn bounds(&self, order: &[u32], item: impl Fn(u32) -> Aabb + Sync) -> Aabb {
        let fold = |chunk: &[u32]| chunk.iter().fold(Aabb::EMPTY, |b, &t| b.union(&item(t)));
        if order_len_is_large(order.len()) {
            order.par_chunks(PARALLEL_THRESHOLD).map(fold).reduce(|| Aabb::EMPTY, |a, b| a.union(&b))
        } else {
            fold(order)
        }
    }
}

fn order_len_is_large(len: usize) -> bool {
    len > PARALLEL_THRESHOLD
}

/// Appends `src` (indices from 0) to `dst`, shifting its child indices; returns where it starts.
fn append_shifted(dst: &mut Vec<BuildNode>, src: &[BuildNode]) -> usize {
    let offset = dst.len();
    dst.extend(src.iter().map(|node| match *node {
        BuildNode::Inner { aabb, left, right } => {
            BuildNode::Inner { aabb, left: left + offset as u32, right: right + offset as u32 }
        }
        leaf => leaf,
    }));
    offset
}

enum SplitChoice {
    Leaf,
    Median,
    Plane { axis: usize, position: f32 },
}

/// Moves the items satisfying `goes_left` to the front (in place, deterministic); returns their count. Falls
/// back to the middle when one side would be empty (possible through rounding at a bin boundary).
fn partition(order: &mut [u32], goes_left: impl Fn(u32) -> bool) -> usize {
    let mut mid = 0;
    for i in 0..order.len() {
        if goes_left(order[i]) {
            order.swap(i, mid);
            mid += 1;
        }
    }
    if mid == 0 || mid == order.len() { order.len() / 2 } else { mid }
}
