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
//! Layout: node `i`'s boxes are `6 K` consecutive floats, the `K` minima of x, then of y and z, then the maxima,
//! so that a union and its area over the poses are one vectorizable loop.

use crate::geometry::Aabb;

/// `K` boxes a node, with the poses' weights: the *pose area* of a node is `A(n) = sum_k w_k SA_k(n)` with
/// `w_k = 1 / (K SA_k(root_k))`, so that the SAH cost averaged over the poses is `sum_n c(n) A(n)`, and `A(n)` is
/// the probability, averaged over the poses, that a ray through the scene's box reaches `n`.
#[derive(Clone, Debug)]
pub struct PoseBoxes {
    poses: usize,
    values: Vec<f32>,
    weights: Vec<f32>,
}

impl PoseBoxes {
    /// `node_count` nodes' boxes in `poses` poses, all empty, weights 0 (set by [`PoseBoxes::weigh_by_root`]).
    pub fn new(node_count: usize, poses: usize) -> PoseBoxes {
        let mut values = vec![0.0; node_count * 6 * poses];
        for slot in values.chunks_exact_mut(6 * poses) {
            slot[..3 * poses].fill(f32::INFINITY);
            slot[3 * poses..].fill(f32::NEG_INFINITY);
        }
        PoseBoxes { poses, values, weights: vec![0.0; poses] }
    }

    /// The number of poses.
    pub fn pose_count(&self) -> usize {
        self.poses
    }

    /// Node `i`'s boxes (`6 K` floats).
    #[inline(always)]
    pub fn slot(&self, i: u32) -> &[f32] {
        let width = 6 * self.poses;
        &self.values[i as usize * width..(i as usize + 1) * width]
    }

    /// Node `i`'s box in pose `k`.
    pub fn pose_box(&self, i: u32, k: usize) -> Aabb {
        let s = self.slot(i);
        let p = self.poses;
        Aabb { min: [s[k], s[p + k], s[2 * p + k]], max: [s[3 * p + k], s[4 * p + k], s[5 * p + k]] }
    }

    /// Sets node `i`'s box in pose `k`.
    pub fn set_pose_box(&mut self, i: u32, k: usize, aabb: &Aabb) {
        let p = self.poses;
        let width = 6 * p;
        let s = &mut self.values[i as usize * width..(i as usize + 1) * width];
        for a in 0..3 {
            s[a * p + k] = aabb.min[a];
            s[(3 + a) * p + k] = aabb.max[a];
        }
    }

    /// Node `i`'s boxes become the unions of nodes `a`'s and `b`'s; returns whether they changed.
    pub fn set_union(&mut self, i: u32, a: u32, b: u32) -> bool {
        let width = 6 * self.poses;
        let half = 3 * self.poses;
        let mut union = [0.0f32; 6 * 64];
        let union = &mut union[..width];
        let (sa, sb) = (self.slot(a), self.slot(b));
        for j in 0..half {
            union[j] = if sb[j] < sa[j] { sb[j] } else { sa[j] };
        }
        for j in half..width {
            union[j] = if sb[j] > sa[j] { sb[j] } else { sa[j] };
        }
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
        let (count, p) = (self.poses as f64, self.poses);
        self.weights = (0..p)
            .map(|k| {
                let aabb = Aabb {
                    min: [scene[k], scene[p + k], scene[2 * p + k]],
                    max: [scene[3 * p + k], scene[4 * p + k], scene[5 * p + k]],
                };
                let area = aabb.surface_area();
                if area > 0.0 && area.is_finite() { (1.0 / (count * area)) as f32 } else { 0.0 }
            })
            .collect();
    }

    /// The pose area `A(i)` of node `i`.
    #[inline(always)]
    pub fn area(&self, i: u32) -> f32 {
        pose_area(self.slot(i), &self.weights, self.poses)
    }

    /// The pose area of the union of node `i`'s boxes with `other` (a slot of this set or a copy of one).
    #[inline(always)]
    pub fn union_area(&self, i: u32, other: &[f32]) -> f32 {
        let p = self.poses;
        let s = self.slot(i);
        let mut total = 0.0;
        for k in 0..p {
            let lo = |a: usize| if other[a * p + k] < s[a * p + k] { other[a * p + k] } else { s[a * p + k] };
            let hi = |a: usize| {
                if other[(3 + a) * p + k] > s[(3 + a) * p + k] { other[(3 + a) * p + k] } else { s[(3 + a) * p + k] }
            };
            let (dx, dy, dz) = (hi(0) - lo(0), hi(1) - lo(1), hi(2) - lo(2));
            total += self.weights[k] * (2.0 * (dx * dy + dy * dz + dz * dx)).min(f32::MAX);
        }
        total
    }

    /// The pose area of a slot (`6 K` floats) of this set's layout.
    pub fn slot_area(&self, slot: &[f32]) -> f32 {
        pose_area(slot, &self.weights, self.poses)
    }

    /// Each pose's weight `w_k`.
    pub fn weights(&self) -> &[f32] {
        &self.weights
    }
}

/// `sum_k w_k SA_k` of a slot of `poses` poses; a pose's empty box counts 0.
#[inline(always)]
fn pose_area(s: &[f32], weights: &[f32], poses: usize) -> f32 {
    let p = poses;
    let mut total = 0.0;
    for k in 0..p {
        let (dx, dy, dz) = (s[3 * p + k] - s[k], s[4 * p + k] - s[p + k], s[5 * p + k] - s[2 * p + k]);
        if dx >= 0.0 && dy >= 0.0 && dz >= 0.0 {
            total += weights[k] * (2.0 * (dx * dy + dy * dz + dz * dx)).min(f32::MAX);
        }
    }
    total
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
