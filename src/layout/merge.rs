//! Optimal bottom-up leaf merging over a fixed topology (the reference table's M = 3).
//!
//! `C(N) = min(c_I * t_N * SA(N), c_T * SA(N) + C(L) + C(R))`, where the first term (one leaf holding all of
//! `N`'s triangles) is allowed only when `t_N <= max_leaf_size`. The recursion is exact for the SAH over
//! all trees obtainable by collapsing subtrees, so merging never raises the cost (keeping every node is one of
//! the options).

use super::leaf_counts::LeafCounts;
use crate::build_tree::BuildTree;
use crate::cost::SahConstants;
use crate::optimize::{NONE, OptTree};

/// The tree with leaves merged; `max_leaf_size` >= 1.
pub fn merge_leaves(tree: &OptTree, constants: SahConstants, max_leaf_size: usize) -> BuildTree {
    merge(tree, constants, max_leaf_size, false)
}

/// [`merge_leaves`] for a tree over split references, where several leaves may hold pieces of one triangle: a
/// merged leaf holds each triangle once (see [`super::records`]), so `t_N` counts the distinct triangles
/// of `N`'s subtree. The same tree as [`merge_leaves`] where no triangle repeats.
pub fn merge_leaves_of_references(tree: &OptTree, constants: SahConstants, max_leaf_size: usize) -> BuildTree {
    merge(tree, constants, max_leaf_size, true)
}

/// [`merge_leaves`] (or with `distinct`, [`merge_leaves_of_references`]) with each node's surface area replaced by
/// `weights[n]` in the costs: the sampled probability that a ray reaches it (`crate::sampling::ray_weights`), so
/// leaf sizes follow where rays go. Weights proportional to the areas give [`merge_leaves`]'s tree.
pub fn merge_leaves_by(
    tree: &OptTree,
    constants: SahConstants,
    max_leaf_size: usize,
    distinct: bool,
    weights: &[f64],
) -> BuildTree {
    let weight = |n: u32| weights.get(n as usize).copied().unwrap_or(0.0);
    let collapse = merged_nodes_weighed(tree, constants, max_leaf_size, distinct, &weight);
    tree.to_build_tree_with_leaves(&|i| collapse[i as usize])
}

fn merge(tree: &OptTree, constants: SahConstants, max_leaf_size: usize, distinct: bool) -> BuildTree {
    let collapse = merged_nodes(tree, constants, max_leaf_size, distinct);
    tree.to_build_tree_with_leaves(&|i| collapse[i as usize])
}

/// For every node, whether the merge makes its whole subtree one leaf (true for the nodes below such a node
/// too): the dynamic program above, with `distinct` counting a triangle once a leaf.
pub fn merged_nodes(tree: &OptTree, constants: SahConstants, max_leaf_size: usize, distinct: bool) -> Vec<bool> {
    let area = |n: u32| tree.nodes[n as usize].aabb.surface_area();
    merged_nodes_weighed(tree, constants, max_leaf_size, distinct, &area)
}

/// [`merged_nodes`] with `weight(n)` in place of node `n`'s surface area.
fn merged_nodes_weighed(
    tree: &OptTree,
    constants: SahConstants,
    max_leaf_size: usize,
    distinct: bool,
    weight: &dyn Fn(u32) -> f64,
) -> Vec<bool> {
    // Children first: the subtrees' (cost, triangle count) pairs wait on a stack, the left child's on top, so
    // only those of nodes whose parent is not done yet are held (at most the depth plus one), not 12 bytes a node.
    let mut collapse = vec![false; tree.nodes.len()];
    let mut pending: Vec<(f64, u32)> = Vec::new();
    let mut counts = LeafCounts::new(max_leaf_size, distinct);
    for i in tree.children_first() {
        let node = &tree.nodes[i as usize];
        let a = weight(i);
        if node.left == NONE {
            pending.push((constants.intersection * a, counts.leaf(node.right)));
            continue;
        }
        let ((left_cost, left_count), (right_cost, right_count)) = match (pending.pop(), pending.pop()) {
            (Some(left), Some(right)) => (left, right),
            _ => unreachable!("reverse depth-first order finishes both children before their parent"),
        };
        let count = counts.join(left_count, right_count);
        let split = constants.traversal * a + left_cost + right_cost;
        let leaf = constants.intersection * count as f64 * a;
        if count as usize <= max_leaf_size && leaf <= split {
            collapse[i as usize] = true;
            pending.push((leaf, count));
        } else {
            pending.push((split, count));
        }
    }
    collapse
}

/// The roots of the clusters, depth first: the topmost nodes whose subtree the leaf merge
/// ([`merge_leaves`], counting references) would make one leaf of at most `max_cluster` references, and
/// the leaves no such node holds.
pub fn cluster_roots(tree: &OptTree, constants: SahConstants, max_cluster: usize) -> Vec<u32> {
    let merged = merged_nodes(tree, constants, max_cluster, false);
    let mut roots = Vec::new();
    if tree.root == NONE {
        return roots;
    }
    let mut stack = vec![tree.root];
    while let Some(i) = stack.pop() {
        let node = &tree.nodes[i as usize];
        if node.left == NONE || merged[i as usize] {
            roots.push(i);
        } else {
            stack.push(node.right);
            stack.push(node.left);
        }
    }
    roots
}
