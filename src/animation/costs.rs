//! The written trees' costs in each sampled pose, and the record of them in the metadata (`animation`, format
//! spec section 5.5): the binary tree's SAH cost and the wide tree's cost (section 6.1) after a refit to each pose,
//! computed as the loader's refit computes them (every box the union of its triangles' boxes in that pose).

use serde::Serialize;

use super::pose_boxes::PoseBoxes;
use super::reinsert::PoseReinsertionReport;
use super::sample::{PoseSet, SampledPose};
use crate::build_tree::{BuildNode, BuildTree};
use crate::cost::SahConstants;
use crate::geometry::Aabb;
use crate::import::ClipSpan;
use crate::layout::{WideChild, WideCosts, WideTree};

/// The binary tree's SAH cost with every box refit to `triangles` (the tree's triangle indices into it).
pub fn binary_cost_at(tree: &BuildTree, triangles: &[[[f32; 3]; 3]], constants: SahConstants) -> f64 {
    let mut refit = tree.clone();
    let mut order = Vec::with_capacity(tree.nodes.len());
    let mut stack = if tree.nodes.is_empty() { Vec::new() } else { vec![0u32] };
    while let Some(i) = stack.pop() {
        order.push(i);
        if let BuildNode::Inner { left, right, .. } = tree.nodes[i as usize] {
            stack.extend([left, right]);
        }
    }
    for &i in order.iter().rev() {
        let aabb = match refit.nodes[i as usize] {
            BuildNode::Inner { left, right, .. } => {
                box_of(&refit.nodes[left as usize]).union(box_of(&refit.nodes[right as usize]))
            }
            BuildNode::Leaf { first, count, .. } => {
                triangles_box(&tree.triangle_order[first as usize..(first + count) as usize], triangles)
            }
        };
        match &mut refit.nodes[i as usize] {
            BuildNode::Inner { aabb: b, .. } | BuildNode::Leaf { aabb: b, .. } => *b = aabb,
        }
    }
    refit.sah_cost(constants).cost
}

/// The wide tree's cost with every box refit to `triangles` (its triangle indices into it).
pub fn wide_cost_at(tree: &WideTree, costs: &WideCosts, triangles: &[[[f32; 3]; 3]]) -> f64 {
    let mut refit = tree.clone();
    let mut node_boxes = vec![Aabb::EMPTY; tree.nodes.len()];
    // Every node comes after its parent, so children are done before their parent in reverse order.
    for i in (0..tree.nodes.len()).rev() {
        let mut whole = Aabb::EMPTY;
        for (aabb, child) in &mut refit.nodes[i].children {
            *aabb = match *child {
                WideChild::Node(j) => node_boxes[j as usize],
                WideChild::Leaf { first, count } => {
                    triangles_box(&tree.triangle_order[first as usize..(first + count) as usize], triangles)
                }
            };
            whole = whole.union(aabb);
        }
        node_boxes[i] = whole;
    }
    refit.root_box = node_boxes.first().copied().unwrap_or(refit.root_box);
    refit.cost(costs)
}

fn box_of(node: &BuildNode) -> &Aabb {
    match node {
        BuildNode::Inner { aabb, .. } | BuildNode::Leaf { aabb, .. } => aabb,
    }
}

fn triangles_box(order: &[u32], triangles: &[[[f32; 3]; 3]]) -> Aabb {
    order.iter().fold(Aabb::EMPTY, |b, &t| b.union(&Aabb::of_triangle(&triangles[t as usize])))
}

/// Each node's pose-averaged probability of being reached by a ray through the scene's box, `A(n)` of
/// [`PoseBoxes`](super::PoseBoxes) in f64: the weights the leaf merging and the collapses take in place of the stored
/// pose's areas (`crate::layout::collapse_by`).
pub fn node_weights(boxes: &PoseBoxes, node_count: usize) -> Vec<f64> {
    let weights = boxes.weights();
    (0..node_count as u32)
        .map(|i| (0..boxes.pose_count()).map(|k| f64::from(weights[k]) * boxes.pose_box(i, k).surface_area()).sum())
        .collect()
}

/// A sampled pose's costs in the metadata.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PoseCost {
    /// The clip's index.
    pub clip: usize,
    /// The time, in seconds.
    pub seconds: f64,
    /// The binary tree's SAH cost refit to this pose.
    pub sah_cost: f64,
    /// The wide tree's cost refit to this pose (absent without wide sections).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wide_cost: Option<f64>,
}

/// The metadata's `animation` object (format spec section 5.5).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AnimationRecord {
    /// The clips sampled: index, name where there is one, first and last keyframe times.
    pub clips: Vec<ClipSpan>,
    /// The refit costs of the tree the poses deform (a one-level file's; a two-level file's flattened mesh 0,
    /// absent when nothing is flattened): each pose's, their means, the worst.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub costs: Option<PoseCosts>,
    /// A two-level file's instances that the clips move rigidly (each placement of a mesh that a moving node
    /// places): their transforms at a pose are the asset's, applied by moving the instances (their meshes do
    /// not deform). Empty in a one-level file.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub moving_instances: Vec<MovingInstance>,
}

/// An instance of a two-level file that an animation moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct MovingInstance {
    /// The instance's index in the file.
    pub instance: u32,
    /// The glTF node that places it.
    pub node: u32,
}

/// A deforming tree's costs over an animation's sampled poses.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PoseCosts {
    /// Each sampled pose's costs, clip by clip in time order.
    pub poses: Vec<PoseCost>,
    /// The mean of the poses' `sah_cost`.
    pub expected_sah_cost: f64,
    /// The mean of the poses' `wide_cost` (absent without wide sections).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub expected_wide_cost: Option<f64>,
    /// The index in `poses` of the costliest pose (by the wide cost where there is one).
    pub worst_pose: usize,
    /// The costliest pose's cost over the stored tree's (the wide costs where there are, else the binary ones):
    /// the largest ratio a refit to a sampled pose reports.
    pub worst_cost_ratio: f64,
    /// The reinsertion for the average cost: that average (one triangle a leaf) before and after it, and its
    /// moves.
    pub reinsertion: ReinsertionRecord,
}

/// What reinsertion did, without its time (the metadata holds nothing that varies between runs).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReinsertionRecord {
    /// The average cost of the tree before.
    pub initial_cost: f64,
    /// The average cost of the tree after.
    pub final_cost: f64,
    /// Rounds run.
    pub rounds: u32,
    /// Moves applied.
    pub moves: u64,
}

/// The record of the written trees (`binary` and, with wide sections, `wide` under `wide_costs`) over `poses`:
/// every pose's costs after a refit, their means, and the costliest pose against the stored costs
/// (`stored_sah`, `stored_wide`).
#[allow(clippy::too_many_arguments)] // the trees, their constants and the stored costs they are compared with
pub fn animation_record(
    poses: &PoseSet,
    binary: &BuildTree,
    constants: SahConstants,
    wide: Option<(&WideTree, &WideCosts)>,
    stored_sah: f64,
    stored_wide: Option<f64>,
    reinsertion: &PoseReinsertionReport,
) -> AnimationRecord {
    let costs: Vec<PoseCost> = poses
        .poses
        .iter()
        .zip(&poses.triangles)
        .map(|(SampledPose { clip, seconds }, triangles)| PoseCost {
            clip: *clip,
            seconds: *seconds,
            sah_cost: binary_cost_at(binary, triangles, constants),
            wide_cost: wide.map(|(tree, costs)| wide_cost_at(tree, costs, triangles)),
        })
        .collect();
    let count = costs.len().max(1) as f64;
    let expected_sah_cost = costs.iter().map(|c| c.sah_cost).sum::<f64>() / count;
    let expected_wide_cost = wide.map(|_| costs.iter().filter_map(|c| c.wide_cost).sum::<f64>() / count);
    let judged = |c: &PoseCost| c.wide_cost.unwrap_or(c.sah_cost);
    let worst_pose = (0..costs.len()).fold(0, |w, k| if judged(&costs[k]) > judged(&costs[w]) { k } else { w });
    let stored = stored_wide.unwrap_or(stored_sah);
    let worst_cost_ratio = match costs.get(worst_pose) {
        Some(worst) if stored > 0.0 => judged(worst) / stored,
        _ => 1.0,
    };
    AnimationRecord {
        clips: poses.clips.clone(),
        costs: Some(PoseCosts {
            poses: costs,
            expected_sah_cost,
            expected_wide_cost,
            worst_pose,
            worst_cost_ratio,
            reinsertion: ReinsertionRecord {
                initial_cost: reinsertion.initial_cost,
                final_cost: reinsertion.final_cost,
                rounds: reinsertion.rounds,
                moves: reinsertion.moves,
            },
        }),
        moving_instances: Vec::new(),
    }
}
