//! Optimal bottom-up leaf merging over a fixed topology (the reference table's M = 3).
//!
//! `C(N) = min(c_I * t_N * SA(N), c_T * SA(N) + C(L) + C(R))`, where the first term (one leaf holding all of
//! `N`'s triangles) is allowed only when `t_N <= max_leaf_size`. The recursion is exact for the SAH over
//! all trees obtainable by collapsing subtrees, so merging never raises the cost (keeping every node is one of
//! the options).

use super::tree::{NONE, OptTree};
use crate::build::BuildTree;
use crate::cost::SahConstants;

/// The tree with leaves merged; `max_leaf_size` >= 1.
pub fn merge_leaves(tree: &OptTree, constants: SahConstants, max_leaf_size: usize) -> BuildTree {
    merge_leaves_in_order(tree, constants, max_leaf_size, &tree.depth_first())
}

/// [`merge_leaves`], given the tree's [`OptTree::depth_first`] order (the conversion computes it once for this
/// and the wide collapse, which run side by side).
pub fn merge_leaves_in_order(
    tree: &OptTree,
    constants: SahConstants,
    max_leaf_size: usize,
    order: &[u32],
) -> BuildTree {
    let mut cost = vec![0.0f64; tree.nodes.len()];
    let mut count = vec![0u32; tree.nodes.len()];
    let mut collapse = vec![false; tree.nodes.len()];
    for &i in order.iter().rev() {
        let node = &tree.nodes[i as usize];
        let a = node.aabb.surface_area();
        let i = i as usize;
        if node.left == NONE {
            count[i] = 1;
            cost[i] = constants.intersection * a;
            continue;
        }
        let (l, r) = (node.left as usize, node.right as usize);
        count[i] = count[l] + count[r];
        let split = constants.traversal * a + cost[l] + cost[r];
        let leaf = constants.intersection * count[i] as f64 * a;
        if count[i] as usize <= max_leaf_size && leaf <= split {
            cost[i] = leaf;
            collapse[i] = true;
        } else {
            cost[i] = split;
        }
    }
    tree.to_build_tree_with_leaves(&|i| collapse[i as usize])
}
