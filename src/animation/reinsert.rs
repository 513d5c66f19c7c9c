//! Reinsertion for the cost averaged over an animation's sampled poses.
//!
//! The move and its search are those of the parallel optimizer (D. Meister, J. Bittner, "Parallel Reinsertion
//! for Bounding Volume Hierarchy Optimization", Computer Graphics Forum 37(2), 2018, section 4: a node leaves its
//! place and becomes the sibling of the node where the branch-and-bound search of J. Bittner, M. Hapala,
//! V. Havran, "Fast Insertion-Based Optimization of Bounding Volume Hierarchies", CGF 32(1), 2013, section 4.2
//! finds the largest drop), with every surface area replaced by the pose area `A` of
//! [`PoseBoxes`](super::PoseBoxes): the tree refit to each pose, its SAH cost averaged. Moves are applied one at a time, each
//! searched on the tree as the previous ones left it and applied only when the average drops, so the average
//! never rises. Rounds take the inner nodes by Bittner's `M_COMB` measure (on pose areas), largest first, and try
//! to move each and its two children.
//!
//! Symbols as in `crate::optimize::search`: `C_D(X) = A(X u L)`, `C_I(X) = sum_anc A(anc u L) - A(anc)`, the
//! search bounds a subtree by `C_I + A(L)`.

use std::collections::BinaryHeap;
use std::time::{Duration, Instant};

use super::pose_boxes::{PoseBoxes, union_into};
use crate::cost::SahConstants;
use crate::optimize::{Candidate, NONE, OptTree, Selection, is_eligible, measure};

/// When the optimizer stops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseReinsertion {
    /// The largest share of the inner nodes a round tries (the most inefficient by `M_COMB`).
    pub round_fraction: f64,
    /// A round that lowers the average cost by less than this share ends the optimization.
    pub min_round_gain: f64,
    /// The most rounds.
    pub max_rounds: u32,
}

impl Default for PoseReinsertion {
    /// A quarter of the inner nodes a round, until a round gains under 0.1%, at most 32 rounds (measured on the
    /// shared skinned scenes: `docs/animation.md`).
    fn default() -> Self {
        PoseReinsertion { round_fraction: 0.25, min_round_gain: 1e-3, max_rounds: 32 }
    }
}

/// What the optimization did.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PoseReinsertionReport {
    /// The average SAH cost over the poses of the tree it was given (one triangle a leaf).
    pub initial_cost: f64,
    /// The same of the tree it returned.
    pub final_cost: f64,
    /// Rounds run.
    pub rounds: u32,
    /// Moves applied.
    pub moves: u64,
    /// Wall-clock time.
    #[serde(serialize_with = "crate::optimize::seconds")]
    pub elapsed: Duration,
}

/// The pose boxes of every node of `tree` (one triangle a leaf, `right` its index): leaf `t`'s box in pose `k`
/// is `pose_triangles[k][t]`'s, inner boxes the unions; weighted by the root's area in each pose.
pub fn pose_boxes_of(tree: &OptTree, pose_triangles: &[Vec<[[f32; 3]; 3]>]) -> PoseBoxes {
    let mut boxes = PoseBoxes::new(tree.nodes.len(), pose_triangles.len());
    if tree.root == NONE {
        return boxes;
    }
    for i in tree.children_first().collect::<Vec<u32>>() {
        let node = tree.nodes[i as usize];
        if node.left == NONE {
            for (k, triangles) in pose_triangles.iter().enumerate() {
                boxes.set_pose_box(i, k, &crate::geometry::Aabb::of_triangle(&triangles[node.right as usize]));
            }
        } else {
            boxes.set_union(i, node.left, node.right);
        }
    }
    boxes.weigh_by_root(tree.root);
    boxes
}

/// The average over the poses of the tree's SAH cost (`c_T` an inner node, `c_I` a leaf's triangle): see
/// [`PoseBoxes`](super::PoseBoxes).
pub fn average_cost(tree: &OptTree, boxes: &PoseBoxes, constants: SahConstants) -> f64 {
    tree.nodes
        .iter()
        .enumerate()
        .map(|(i, node)| {
            let a = f64::from(boxes.area(i as u32));
            if node.left == NONE { constants.intersection * a } else { constants.traversal * a }
        })
        .sum()
}

/// Reinserts nodes of `tree` (one triangle a leaf) while the cost averaged over the poses of `boxes` drops (see
/// the module documentation); `tree`'s own boxes (the stored pose's) and `boxes` are kept exact.
pub fn optimize_for_poses(
    tree: &mut OptTree,
    boxes: &mut PoseBoxes,
    constants: SahConstants,
    params: &PoseReinsertion,
) -> PoseReinsertionReport {
    let start = Instant::now();
    let initial_cost = average_cost(tree, boxes, constants);
    let mut report =
        PoseReinsertionReport { initial_cost, final_cost: initial_cost, rounds: 0, moves: 0, elapsed: Duration::ZERO };
    let mut search = Search { heap: BinaryHeap::new(), leaf: Vec::new(), removal: Vec::new() };
    let mut cost = initial_cost;
    while report.rounds < params.max_rounds {
        let batch = inefficient_nodes(tree, boxes, params.round_fraction);
        if batch.is_empty() {
            break;
        }
        report.rounds += 1;
        let mut drop = 0.0f64;
        for n in batch {
            let node = tree.nodes[n as usize];
            if node.left == NONE {
                continue;
            }
            for c in [n, node.left, node.right] {
                if let Some((target, delta)) = search.best_move(tree, boxes, c) {
                    apply_move(tree, boxes, c, target);
                    drop -= f64::from(delta) * constants.traversal;
                    report.moves += 1;
                }
            }
        }
        let gain = drop / cost.max(f64::MIN_POSITIVE);
        cost -= drop;
        if gain < params.min_round_gain {
            break;
        }
    }
    report.final_cost = average_cost(tree, boxes, constants);
    report.elapsed = start.elapsed();
    report
}

/// `fraction` of the inner nodes below the root's children, the largest `M_COMB` (on pose areas) first, ties by
/// index.
fn inefficient_nodes(tree: &OptTree, boxes: &PoseBoxes, fraction: f64) -> Vec<u32> {
    let mut ranked: Vec<(f64, u32)> = (0..tree.nodes.len() as u32)
        .filter(|&i| is_eligible(tree, i))
        .map(|i| {
            let node = &tree.nodes[i as usize];
            (measure(boxes.area(i), boxes.area(node.left), boxes.area(node.right), Selection::Comb), i)
        })
        .collect();
    let k = ((ranked.len() as f64 * fraction).ceil() as usize).min(ranked.len());
    let by_measure = |a: &(f64, u32), b: &(f64, u32)| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1));
    if k < ranked.len() {
        ranked.select_nth_unstable_by(k, by_measure);
        ranked.truncate(k);
    }
    ranked.sort_unstable_by(by_measure);
    ranked.into_iter().map(|(_, i)| i).collect()
}

/// Moves `c` beside `x` (see `OptTree::move_beside_logged`) and refits the pose boxes above both places.
fn apply_move(tree: &mut OptTree, boxes: &mut PoseBoxes, c: u32, x: u32) {
    let p = tree.nodes[c as usize].parent;
    let g = tree.nodes[p as usize].parent;
    tree.move_beside_logged(c, x, &mut ());
    refit_poses_from(tree, boxes, g);
    boxes.set_union(p, x, c);
    refit_poses_from(tree, boxes, tree.nodes[p as usize].parent);
}

/// Recomputes pose boxes from `i` up, stopping where they do not change.
fn refit_poses_from(tree: &OptTree, boxes: &mut PoseBoxes, mut i: u32) {
    while i != NONE {
        let node = tree.nodes[i as usize];
        if !boxes.set_union(i, node.left, node.right) {
            return;
        }
        i = node.parent;
    }
}

/// The searches' scratch: the heap, the moving node's boxes and the removal boxes.
struct Search {
    heap: BinaryHeap<Candidate>,
    leaf: Vec<f32>,
    removal: Vec<f32>,
}

impl Search {
    /// The best new sibling for `n` and the change of the inner pose-area sum, when it is a drop (see
    /// `crate::optimize::best_move` for the symbols: the levels above `n`'s parent, each searched with its
    /// base, and each ancestor itself as a target).
    fn best_move(&mut self, tree: &OptTree, boxes: &PoseBoxes, n: u32) -> Option<(u32, f32)> {
        let p = tree.nodes[n as usize].parent;
        if p == NONE {
            return None;
        }
        self.leaf.clear();
        self.leaf.extend_from_slice(boxes.slot(n));
        let area_l = boxes.area(n);
        let mut base = -boxes.area(p);
        // A move must gain more than rounding: a drop of a millionth of the root's pose area (1) or less is none.
        let mut best = -1e-6f32;
        let mut found = None;
        let sibling = tree.sibling(n);
        self.removal.clear();
        self.removal.extend_from_slice(boxes.slot(sibling));
        if let Some(hit) = self.search(tree, boxes, area_l, sibling, base, best) {
            (best, found) = (hit.0, Some(hit));
        }
        let mut ancestor = p;
        loop {
            let above = tree.nodes[ancestor as usize].parent;
            if above == NONE {
                break;
            }
            let above_node = &tree.nodes[above as usize];
            let off_path = if above_node.left == ancestor { above_node.right } else { above_node.left };
            if let Some(hit) = self.search(tree, boxes, area_l, off_path, base, best) {
                (best, found) = (hit.0, Some(hit));
            }
            union_into(&mut self.removal, boxes.slot(off_path));
            let removal_area = boxes.slot_area(&self.removal);
            if base + removal_area < best {
                best = base + removal_area;
                found = Some((best, above));
            }
            base += removal_area - boxes.area(above);
            ancestor = above;
        }
        found.map(|(delta, target)| (target, delta))
    }

    /// The best sibling in the subtree of `start` for the moving boxes, totals offset by `base`, if one beats
    /// `best`: `(total, node)`.
    fn search(
        &mut self,
        tree: &OptTree,
        boxes: &PoseBoxes,
        area_l: f32,
        start: u32,
        base: f32,
        mut best: f32,
    ) -> Option<(f32, u32)> {
        let mut found = None;
        self.heap.clear();
        let mut candidate = Candidate { induced: 0.0, node: start };
        loop {
            let Candidate { induced, node } = candidate;
            if base + induced + area_l >= best {
                break;
            }
            let x = &tree.nodes[node as usize];
            let direct = boxes.union_area(node, &self.leaf);
            let total = base + induced + direct;
            if total < best {
                best = total;
                found = Some((total, node));
            }
            if x.left != NONE {
                let below = induced + direct - boxes.area(node);
                if base + below + area_l < best {
                    self.heap.push(Candidate { induced: below, node: x.left });
                    self.heap.push(Candidate { induced: below, node: x.right });
                }
            }
            match self.heap.pop() {
                Some(next) => candidate = next,
                None => break,
            }
        }
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builders::build_binned_sah;
    use rand::{RngExt, SeedableRng};

    /// `count` small random triangles and `poses` poses of them, each a random rigid shift of every triangle
    /// plus a shared shear that grows with the pose.
    type Triangles = Vec<[[f32; 3]; 3]>;

    fn scene(seed: u64, count: usize, poses: usize) -> (Triangles, Vec<Triangles>) {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
        let mut point = |scale: f32| -> [f32; 3] { std::array::from_fn(|_| scale * (rng.random::<f32>() - 0.5)) };
        let rest: Vec<[[f32; 3]; 3]> = (0..count)
            .map(|_| {
                let c = point(10.0);
                std::array::from_fn(|_| {
                    let d = point(0.6);
                    std::array::from_fn(|a| c[a] + d[a])
                })
            })
            .collect();
        let posed = (0..poses)
            .map(|k| {
                let shear = 0.4 * k as f32;
                rest.iter()
                    .map(|t| {
                        let jitter = point(2.0);
                        t.map(|v| [v[0] + shear * v[1] + jitter[0], v[1] + jitter[1], v[2] + jitter[2]])
                    })
                    .collect()
            })
            .collect();
        (rest, posed)
    }

    #[test]
    fn reinsertion_lowers_the_average_cost_and_keeps_every_box_exact() {
        let constants = SahConstants::default();
        for (seed, count, poses) in [(1, 300, 1), (2, 500, 4), (3, 64, 8), (4, 2, 3), (5, 1000, 16)] {
            let (rest, posed) = scene(seed, count, poses);
            let mut tree = OptTree::from_build(build_binned_sah(&rest, 1), &rest);
            let mut boxes = pose_boxes_of(&tree, &posed);
            let before = average_cost(&tree, &boxes, constants);
            let report = optimize_for_poses(&mut tree, &mut boxes, constants, &PoseReinsertion::default());
            tree.check_invariants(&rest).unwrap();
            // The boxes kept up to date move by move equal boxes made afresh, bit for bit.
            let fresh = pose_boxes_of(&tree, &posed);
            for i in 0..tree.nodes.len() as u32 {
                assert_eq!(boxes.slot(i), fresh.slot(i), "seed {seed}: node {i}");
            }
            let after = average_cost(&tree, &fresh, constants);
            assert_eq!(report.initial_cost, before);
            assert!((report.final_cost - after).abs() <= 1e-9 * after, "seed {seed}");
            assert!(after <= before, "seed {seed}: {before} -> {after}");
            if count >= 300 {
                assert!(report.moves > 0 && after < 0.999 * before, "seed {seed}: {before} -> {after}");
            }
        }
    }

    #[test]
    fn one_pose_equal_to_the_stored_one_is_the_stored_cost() {
        let (rest, _) = scene(7, 200, 1);
        let tree = OptTree::from_build(build_binned_sah(&rest, 1), &rest);
        let boxes = pose_boxes_of(&tree, std::slice::from_ref(&rest));
        let constants = SahConstants::default();
        let stored = crate::optimize::cost_of(&tree, constants).cost;
        assert!((average_cost(&tree, &boxes, constants) - stored).abs() <= 1e-5 * stored);
    }
}
