//! The reference loop of Bittner, Hapala and Havran, "Fast Insertion-Based Optimization of Bounding Volume
//! Hierarchies", Computer Graphics Forum 32(1), 2013, section 4: for each node `N` of the batch, remove `N` and
//! its parent `P` (the sibling takes `P`'s place), then reinsert `N`'s children, the larger first, each at the
//! position found by the exact branch-and-bound search over the whole tree, reusing `N` and `P` as the new
//! parents; refit upwards after every change.
//!
//! Deviation from the paper: none in the loop; the search breaks ties deterministically (see `search`).

use super::edit_log::EditLog;
use super::measure::is_eligible;
use super::search::{SearchQueue, best_insertion};
use super::tree::{OptNode, OptTree};

/// Runs one batch over `batch` (nodes skipped when they became ineligible); returns the reinsertions made.
pub fn run_batch(tree: &mut OptTree, batch: &[u32], queue: &mut SearchQueue, log: &mut EditLog) -> u64 {
    let mut reinsertions = 0;
    for &n in batch {
        if !is_eligible(tree, n) {
            continue;
        }
        let p = tree.nodes[n as usize].parent;
        let s = tree.sibling(n);
        let g = tree.nodes[p as usize].parent;
        tree.replace_child_logged(g, p, s, log);
        tree.refit_from_logged(g, log);
        let node = tree.nodes[n as usize];
        let (first, second) = if tree.area(node.right) > tree.area(node.left) {
            (node.right, node.left)
        } else {
            (node.left, node.right)
        };
        for (child, free) in [(first, n), (second, p)] {
            let child_box = tree.nodes[child as usize].aabb;
            let x = best_insertion(tree, queue, &child_box);
            let y = tree.nodes[x as usize].parent;
            let aabb = tree.nodes[x as usize].aabb.union(&child_box);
            tree.set_inner_logged(free, OptNode { aabb, parent: y, left: x, right: child }, log);
            tree.replace_child_logged(y, x, free, log);
            tree.set_parent_logged(x, free, log);
            tree.set_parent_logged(child, free, log);
            tree.refit_from_logged(y, log);
        }
        reinsertions += 1;
    }
    reinsertions
}
