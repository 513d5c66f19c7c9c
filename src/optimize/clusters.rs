//! Reinsertion over clusters: the optimizer run on the part of a built tree above its small subtrees.
//!
//! The reinsertion loop (Bittner et al. 2013, see [`super`]) prices a tree with one reference a leaf, but the
//! file's leaves are the subtrees of up to 8 references that leaf merging and the wide collapse make
//! afterwards. Reinsertion lowers the inner nodes' areas and breaks up the small, tight subtrees a top-down
//! builder makes at the bottom: on the kitchen the wide tree's leaf part (packets times leaf areas) rose by
//! 7-22% while its node part fell (`docs/evaluation.md`). Here the built tree's subtrees that leaf merging
//! would make a leaf of at most `max_cluster` references (the merge's own rule, with the optimizer's
//! constants) are kept as they were built, each standing in as one leaf of a smaller tree, and reinsertion
//! optimizes that tree; the clusters are then put back under its leaves, in place. The optimizer works on
//! boxes only, so a cluster is just its root's box; the clusters' insides are never changed.

use std::ops::ControlFlow;

use super::tree::{NONE, OptNode, OptTree};
use super::{OptimizeParams, OptimizeReport, Progress, cost_of, optimize};

/// Optimizes `tree` (with one reference a leaf) by reinsertion over the clusters at `roots`, in place: the
/// roots of disjoint subtrees that together hold every leaf, in depth-first order (the leaf layout's
/// [`crate::layout::cluster_roots`]). The report's costs are those of the whole tree before and after, and its
/// batches those of the tree over clusters. Deterministic for any number of threads, as [`optimize`] is.
pub fn optimize_over_clusters(
    tree: &mut OptTree,
    params: &OptimizeParams,
    roots: &[u32],
    progress: &mut dyn FnMut(&Progress) -> ControlFlow<()>,
) -> OptimizeReport {
    let initial = cost_of(tree, params.constants);
    let (mut upper, slots) = tree_over(tree, roots);
    let mut report = optimize(&mut upper, params, progress);
    put_back(&upper, &slots, roots, tree);
    report.initial = initial;
    report.best = cost_of(tree, params.constants);
    report
}

/// The part of `tree` above `roots`: the same inner nodes, and one leaf per cluster with the cluster's box,
/// whose `right` is the cluster's index in `roots`; and for each of its nodes, the node of `tree` it stands for.
fn tree_over(tree: &OptTree, roots: &[u32]) -> (OptTree, Vec<u32>) {
    let mut upper = OptTree { nodes: Vec::with_capacity(2 * roots.len()), root: NONE };
    let mut slots = Vec::with_capacity(2 * roots.len());
    if roots.is_empty() {
        return (upper, slots);
    }
    let mut next_root = 0u32;
    // (node of `tree`, parent in `upper`, whether it is the parent's left child)
    let mut stack = vec![(tree.root, NONE, true)];
    while let Some((i, parent, is_left)) = stack.pop() {
        let node = &tree.nodes[i as usize];
        let index = upper.nodes.len() as u32;
        let right = if roots.get(next_root as usize) == Some(&i) {
            next_root += 1;
            next_root - 1
        } else {
            stack.push((node.right, index, false));
            stack.push((node.left, index, true));
            NONE
        };
        upper.nodes.push(OptNode { aabb: node.aabb, parent, left: NONE, right });
        slots.push(i);
        link(&mut upper, parent, index, is_left);
    }
    upper.root = 0;
    (upper, slots)
}

/// Writes the optimized `upper` back into `tree`, in place: reinsertion keeps every node in its slot (it only
/// relinks them), so each of `upper`'s inner nodes still stands for the inner node of `tree` in `slots`, and
/// each leaf for its cluster's root; those nodes take `upper`'s links and boxes (a cluster keeps its box and
/// everything below it).
fn put_back(upper: &OptTree, slots: &[u32], roots: &[u32], tree: &mut OptTree) {
    if upper.root == NONE {
        return;
    }
    let slot_of = |u: u32| {
        let node = &upper.nodes[u as usize];
        if node.left == NONE { roots[node.right as usize] } else { slots[u as usize] }
    };
    for (u, node) in upper.nodes.iter().enumerate() {
        let slot = slot_of(u as u32) as usize;
        tree.nodes[slot].parent = if node.parent == NONE { NONE } else { slot_of(node.parent) };
        if node.left != NONE {
            tree.nodes[slot].aabb = node.aabb;
            tree.nodes[slot].left = slot_of(node.left);
            tree.nodes[slot].right = slot_of(node.right);
        }
    }
    tree.root = slot_of(upper.root);
}

/// Makes `child` the left or right child of `parent` (nothing for the root).
fn link(tree: &mut OptTree, parent: u32, child: u32, is_left: bool) {
    if parent == NONE {
        return;
    }
    let parent = &mut tree.nodes[parent as usize];
    if is_left {
        parent.left = child;
    } else {
        parent.right = child;
    }
}
