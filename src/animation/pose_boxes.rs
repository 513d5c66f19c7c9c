//! Every node's box in each of `K` sampled poses, and the pose-averaged surface area the animation's optimizer
//! minimizes.
//!
//! A tree refit to pose `k` has the SAH cost `sum_n c(n) SA_k(n) / SA_k(root_k)` (the root's box in pose `k` is
//! the box of every triangle there, so it does not depend on the tree). Averaged over the poses, the cost is
//! `sum_n c(n) A(n)` with the *pose area* `A(n) = sum_k w_k SA_k(n)` and `w_k = 1 / (K SA_k(root_k))`: the
//! probability that a ray through the scene's box reaches `n`, averaged over the poses. Every search and measure
//! of the optimizer reads `A` where the static optimizer reads `SA`, so the bounds of Bittner et al. carry over
//! (`A` of a union is at least `A` of each part, and adding a box to a node never lowers `A`).
//!
//! Layout: node `i`'s boxes are 6 rows of `L` floats (the minima of x, y, z, then the maxima), `L` the pose count
//! rounded up to a multiple of 8, so that a union and its area are loops over 8-float chunks the compiler keeps in
//! vector registers. The rows' padding lanes hold the point 0 and weigh 0 (a union of points is a point, its area
//! 0). The sums over lanes run in a fixed order: the same result on every machine and thread count.

use crate::geometry::Aabb;

/// Floats a chunk: one AVX register.
const CHUNK: usize = 8;

/// `K` boxes a node, with the poses' weights: the *pose area* of a node is `A(n) = sum_k w_k SA_k(n)` with
/// `w_k = 1 / (K SA_k(root_k))`, so that the SAH cost averaged over the poses is `sum_n c(n) A(n)`, and `A(n)` is
/// the probability, averaged over the poses, that a ray through the scene's box reaches `n`.
#[derive(Clone, Debug)]
pub struct PoseBoxes {
    poses: usize,
    /// Floats a row: `poses` rounded up to a multiple of [`CHUNK`].
    lanes: usize,
    values: Vec<f32>,
    /// `lanes` weights, 0 past `poses`.
    weights: Vec<f32>,
}

impl PoseBoxes {
    /// `node_count` nodes' boxes in `poses` poses, all empty, weights 0 (set by [`PoseBoxes::weigh_by_root`]).
    pub fn new(node_count: usize, poses: usize) -> PoseBoxes {
        let lanes = poses.next_multiple_of(CHUNK).max(CHUNK);
        let mut values = vec![0.0; node_count * 6 * lanes];
        for slot in values.chunks_exact_mut(6 * lanes) {
            for row in 0..6 {
                let fill = if row < 3 { f32::INFINITY } else { f32::NEG_INFINITY };
                slot[row * lanes..row * lanes + poses].fill(fill);
            }
        }
        PoseBoxes { poses, lanes, values, weights: vec![0.0; lanes] }
    }

    /// The number of poses.
    pub fn pose_count(&self) -> usize {
        self.poses
    }

    /// Node `i`'s boxes (`6 L` floats).
    #[inline(always)]
    pub fn slot(&self, i: u32) -> &[f32] {
        let width = 6 * self.lanes;
        &self.values[i as usize * width..(i as usize + 1) * width]
    }

    /// Node `i`'s box in pose `k`.
    pub fn pose_box(&self, i: u32, k: usize) -> Aabb {
        self.box_of(self.slot(i), k)
    }

    /// Pose `k`'s box in `slot`.
    fn box_of(&self, slot: &[f32], k: usize) -> Aabb {
        let l = self.lanes;
        Aabb { min: [slot[k], slot[l + k], slot[2 * l + k]], max: [slot[3 * l + k], slot[4 * l + k], slot[5 * l + k]] }
    }

    /// Sets node `i`'s box in pose `k`.
    pub fn set_pose_box(&mut self, i: u32, k: usize, aabb: &Aabb) {
        let l = self.lanes;
        let width = 6 * l;
        let s = &mut self.values[i as usize * width..(i as usize + 1) * width];
        for a in 0..3 {
            s[a * l + k] = aabb.min[a];
            s[(3 + a) * l + k] = aabb.max[a];
        }
    }

    /// Node `i`'s boxes become the unions of nodes `a`'s and `b`'s; returns whether they changed.
    pub fn set_union(&mut self, i: u32, a: u32, b: u32) -> bool {
        let width = 6 * self.lanes;
        let mut union = [0.0f32; 6 * MAX_POSES];
        let union = &mut union[..width];
        union.copy_from_slice(self.slot(a));
        union_into(union, self.slot(b));
        let target = &mut self.values[i as usize * width..(i as usize + 1) * width];
        if target == union {
            return false;
        }
        target.copy_from_slice(union);
        true
    }

    /// The weights become `1 / (K SA_k(root))` (0 for a pose whose root has no area), from node `root`'s boxes.
    pub fn weigh_by_root(&mut self, root: u32) {
        let slot = self.slot(root).to_vec();
        self.set_weights_of(&slot);
    }

    /// The weights become `1 / (K SA_k)` of the boxes of `scene` (a slot: the scene's box in each pose), 0 for a
    /// pose where it has no area.
    pub fn set_weights_of(&mut self, scene: &[f32]) {
        let count = self.poses as f64;
        let mut weights = vec![0.0; self.lanes];
        for (k, weight) in weights.iter_mut().enumerate().take(self.poses) {
            let area = self.box_of(scene, k).surface_area();
            *weight = if area > 0.0 && area.is_finite() { (1.0 / (count * area)) as f32 } else { 0.0 };
        }
        self.weights = weights;
    }

    /// The pose area `A(i)` of node `i`.
    #[inline(always)]
    pub fn area(&self, i: u32) -> f32 {
        self.slot_area(self.slot(i))
    }

    /// The pose area of the union of node `i`'s boxes with `other` (a slot of this set or a copy of one).
    #[inline(always)]
    pub fn union_area(&self, i: u32, other: &[f32]) -> f32 {
        let (l, s) = (self.lanes, self.slot(i));
        let mut total = [0.0f32; CHUNK];
        for c in (0..l).step_by(CHUNK) {
            let row = |slot: &[f32], r: usize| -> [f32; CHUNK] {
                slot[r * l + c..r * l + c + CHUNK].try_into().unwrap_or([0.0; CHUNK])
            };
            let extent = |r: usize| -> [f32; CHUNK] {
                let (lo_a, lo_b, hi_a, hi_b) = (row(s, r), row(other, r), row(s, r + 3), row(other, r + 3));
                std::array::from_fn(|j| {
                    let lo = if lo_b[j] < lo_a[j] { lo_b[j] } else { lo_a[j] };
                    let hi = if hi_b[j] > hi_a[j] { hi_b[j] } else { hi_a[j] };
                    hi - lo
                })
            };
            let (dx, dy, dz) = (extent(0), extent(1), extent(2));
            let w: [f32; CHUNK] = self.weights[c..c + CHUNK].try_into().unwrap_or([0.0; CHUNK]);
            for j in 0..CHUNK {
                total[j] += w[j] * (2.0 * (dx[j] * dy[j] + dy[j] * dz[j] + dz[j] * dx[j])).min(f32::MAX);
            }
        }
        total.iter().sum()
    }

    /// The pose area of a slot (`6 L` floats) of this set's layout; a pose's empty box counts 0.
    pub fn slot_area(&self, s: &[f32]) -> f32 {
        let l = self.lanes;
        let mut total = [0.0f32; CHUNK];
        for c in (0..l).step_by(CHUNK) {
            let row = |r: usize| -> [f32; CHUNK] { s[r * l + c..r * l + c + CHUNK].try_into().unwrap_or([0.0; CHUNK]) };
            let extent = |r: usize| -> [f32; CHUNK] {
                let (lo, hi) = (row(r), row(r + 3));
                std::array::from_fn(|j| hi[j] - lo[j])
            };
            let (dx, dy, dz) = (extent(0), extent(1), extent(2));
            let w: [f32; CHUNK] = self.weights[c..c + CHUNK].try_into().unwrap_or([0.0; CHUNK]);
            for j in 0..CHUNK {
                let area = if dx[j] >= 0.0 && dy[j] >= 0.0 && dz[j] >= 0.0 {
                    (2.0 * (dx[j] * dy[j] + dy[j] * dz[j] + dz[j] * dx[j])).min(f32::MAX)
                } else {
                    0.0
                };
                total[j] += w[j] * area;
            }
        }
        total.iter().sum()
    }

    /// Each pose's weight `w_k` (then the padding lanes' zeros).
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }
}

/// `into` becomes its union with `other` (two slots of one layout).
#[inline(always)]
pub fn union_into(into: &mut [f32], other: &[f32]) {
    let half = into.len() / 2;
    let (lows, highs) = into.split_at_mut(half);
    for (a, &b) in lows.iter_mut().zip(&other[..half]) {
        *a = if b < *a { b } else { *a };
    }
    for (a, &b) in highs.iter_mut().zip(&other[half..]) {
        *a = if b > *a { b } else { *a };
    }
}

/// The most poses a conversion samples (a slot's scratch union lives on the stack).
pub const MAX_POSES: usize = 64;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn union_and_areas_match_the_boxes_of_each_pose() {
        let mut boxes = PoseBoxes::new(3, 2);
        let unit = Aabb { min: [0.0; 3], max: [1.0; 3] };
        let moved = Aabb { min: [2.0, 0.0, 0.0], max: [3.0, 1.0, 1.0] };
        boxes.set_pose_box(0, 0, &unit);
        boxes.set_pose_box(0, 1, &unit);
        boxes.set_pose_box(1, 0, &unit);
        boxes.set_pose_box(1, 1, &moved);
        assert!(boxes.set_union(2, 0, 1));
        assert!(!boxes.set_union(2, 0, 1));
        assert_eq!(boxes.pose_box(2, 0), unit);
        assert_eq!(boxes.pose_box(2, 1), unit.union(&moved));
        boxes.weigh_by_root(2);
        // Pose 0: the root is the unit cube (area 6); pose 1: 3 x 1 x 1 (area 14); each pose weighs half.
        assert!((boxes.area(2) - 1.0).abs() < 1e-6);
        assert!((boxes.area(1) - (0.5 + 0.5 * 6.0 / 14.0)).abs() < 1e-6);
        assert!((boxes.union_area(0, boxes.slot(1)) - 1.0).abs() < 1e-6);
    }
}
