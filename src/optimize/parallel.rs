//! The parallel loop, after D. Meister and J. Bittner, "Parallel Reinsertion for Bounding Volume Hierarchy
//! Optimization", Computer Graphics Forum 37(2), 2018: moves are searched without removal on a frozen tree, in
//! parallel, then applied one by one in order of gain, skipping any move that touches a node already changed in
//! this round.
//!
//! Deviations from the paper, for a CPU and for determinism: only the children of the batch's nodes (chosen as
//! in Bittner et al. 2013) are candidates, each batch node proposing the better move of its two children; moves
//! are ordered by (gain, node index) instead of being resolved by atomic priority locks, so the result does not
//! depend on the number of threads; the locked set is the six nodes whose links change (the moved node, its
//! parent, sibling and grandparent, the target and its parent), and a move whose target has meanwhile moved
//! into the moved subtree is skipped.

use rayon::prelude::*;

use super::edit_log::EditLog;
use super::search::{Move, SearchQueue, best_move};
use super::tree::{NONE, OptTree};

/// Runs one round over the batch `batch`; returns the moves applied.
pub fn run_round(tree: &mut OptTree, batch: &[u32], log: &mut EditLog) -> u64 {
    let frozen: &OptTree = tree;
    let proposals: Vec<Option<Move>> = batch
        .par_iter()
        .map_init(SearchQueue::default, |queue, &n| {
            let node = frozen.nodes[n as usize];
            let left = best_move(frozen, queue, node.left);
            let right = best_move(frozen, queue, node.right);
            match (left, right) {
                (Some(a), Some(b)) => Some(if b.delta < a.delta { b } else { a }),
                (a, b) => a.or(b),
            }
        })
        .collect();
    let mut moves: Vec<Move> = proposals.into_iter().flatten().collect();
    moves.par_sort_unstable_by(|a, b| a.delta.total_cmp(&b.delta).then(a.node.cmp(&b.node)));
    let mut locked = vec![0u64; tree.nodes.len().div_ceil(64)];
    let mut applied = 0;
    for m in moves {
        let Some(touched) = touched_if_free(tree, &locked, m) else {
            continue;
        };
        tree.move_beside_logged(m.node, m.target, log);
        for i in touched.into_iter().filter(|&i| i != NONE) {
            locked[i as usize / 64] |= 1 << (i % 64);
        }
        applied += 1;
    }
    applied
}

/// Whether node `i` was touched by a move applied earlier in this round.
fn is_locked(locked: &[u64], i: u32) -> bool {
    i != NONE && locked[i as usize / 64] & (1 << (i % 64)) != 0
}

/// The six nodes whose links move `m` changes (the moved node `c`, its parent `p`, sibling `s` and grandparent
/// `g`, the target `x` and its parent `y`), or `None` when an earlier move of this round touched one of them or
/// the move is no longer legal.
///
/// Invariant relied on: a move rewires only its six touched nodes, so a node that is not locked has the links
/// it had in the frozen tree the proposals were searched on. The links are therefore read one step at a time,
/// each only after the node it is read from was found unlocked: `c` before its parent, `p` before its children
/// and parent, `x` before its parent. (Reading `c`'s sibling first was the bug behind a panic on real scenes:
/// when an earlier move in the round had removed the root's child, `c` could have become the root.)
fn touched_if_free(tree: &OptTree, locked: &[u64], m: Move) -> Option<[u32; 6]> {
    let (c, x) = (m.node, m.target);
    if is_locked(locked, c) || is_locked(locked, x) {
        return None;
    }
    let p = tree.nodes[c as usize].parent;
    if p == NONE || is_locked(locked, p) {
        return None;
    }
    let s = tree.sibling(c);
    let g = tree.nodes[p as usize].parent;
    let y = tree.nodes[x as usize].parent;
    let touched = [c, p, s, g, x, y];
    if touched.iter().any(|&i| is_locked(locked, i)) || x == p || tree.is_in_subtree(x, c) {
        return None;
    }
    Some(touched)
}
