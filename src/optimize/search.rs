//! The branch-and-bound searches for insertion positions (Bittner et al. 2013, section 4.2; Meister and Bittner
//! 2018, section 4).
//!
//! Symbols: inserting a box `L` as the sibling of node `X` creates a parent with box `X u L` (the *direct* cost
//! `C_D(X) = SA(X u L)`) and enlarges every ancestor `A` of `X` to `A u L` (the *induced* cost
//! `C_I(X) = sum_A SA(A u L) - SA(A)`). Below `X` the induced cost grows by `SA(X u L) - SA(X)` and the direct
//! cost is at least `SA(L)`, which bounds every candidate under `X`. Candidates pop from a min-heap on `C_I`;
//! the search stops when the smallest `C_I + SA(L)` cannot beat the best total found. Ties go to the candidate
//! found first (smallest `C_I`, then smallest node index), so the result is deterministic.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use super::tree::{NONE, OptTree, area};
use crate::geometry::Aabb;

/// A heap entry: a candidate and its induced cost, ordered so that `BinaryHeap` pops the smallest cost first
/// (then the smallest node index). Also the animation optimizer's (`crate::animation`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Candidate {
    pub(crate) induced: f32,
    pub(crate) node: u32,
}

impl PartialEq for Candidate {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Candidate {}
impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Candidate {
    fn cmp(&self, other: &Self) -> Ordering {
        other.induced.total_cmp(&self.induced).then(other.node.cmp(&self.node))
    }
}

/// A reusable search queue (it grows as needed and keeps its allocation between searches).
#[derive(Debug, Default)]
pub struct SearchQueue {
    heap: BinaryHeap<Candidate>,
}

/// The best sibling `X` for a box `l` among the subtree of `start`, with `base` added to every total, if one
/// beats `best`. Returns `(total, X)`.
pub fn best_in_subtree(
    tree: &OptTree,
    queue: &mut SearchQueue,
    l: &Aabb,
    start: u32,
    base: f32,
    best: f32,
) -> Option<(f32, u32)> {
    search(tree, queue, l, area(l), start, base, best)
}

/// [`best_in_subtree`] with `SA(L)` given, inlined into the move search's loop over levels (a call per level
/// was a tenth of its instructions).
#[inline(always)]
fn search(
    tree: &OptTree,
    queue: &mut SearchQueue,
    l: &Aabb,
    area_l: f32,
    start: u32,
    base: f32,
    mut best: f32,
) -> Option<(f32, u32)> {
    let mut found = None;
    queue.heap.clear();
    // The start is taken without the heap: in the upper levels of a move's search it is often the only
    // candidate (its children pruned), and then the heap is never touched.
    let mut candidate = Candidate { induced: 0.0, node: start };
    loop {
        let Candidate { induced, node } = candidate;
        if base + induced + area_l >= best {
            break;
        }
        let x = &tree.nodes[node as usize];
        let direct = area(&x.aabb.union(l));
        let total = base + induced + direct;
        if total < best {
            best = total;
            found = Some((total, node));
        }
        if x.left != NONE {
            let below = induced + direct - area(&x.aabb);
            if base + below + area_l < best {
                queue.heap.push(Candidate { induced: below, node: x.left });
                queue.heap.push(Candidate { induced: below, node: x.right });
            }
        }
        // Most levels' searches end here with an empty heap; the check spares them a call to `pop`.
        if queue.heap.is_empty() {
            break;
        }
        match queue.heap.pop() {
            Some(next) => candidate = next,
            None => break,
        }
    }
    found
}

/// Bittner's search: the best sibling for a detached subtree with box `l` in the whole tree (root included).
pub fn best_insertion(tree: &OptTree, queue: &mut SearchQueue, l: &Aabb) -> u32 {
    best_in_subtree(tree, queue, l, tree.root, 0.0, f32::INFINITY).map_or(tree.root, |(_, x)| x)
}

/// A subtree move of the parallel optimizer: node `node` leaves its place (its parent is spliced out) and
/// becomes the sibling of `target`, reusing the spliced-out parent. `delta` is the change of the inner-area
/// sum (negative: an improvement).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Move {
    /// The node that moves, with its subtree.
    pub node: u32,
    /// Its new sibling.
    pub target: u32,
    /// Change of the sum of inner areas.
    pub delta: f32,
}

/// The best move of `n` (not the root) on a frozen tree, if any lowers the inner-area sum (Meister and Bittner
/// 2018: search without removal).
///
/// With `P` the parent of `n`, `A_1 .. A_m` the ancestors of `P` and `C_k` the child of `A_k` off the path
/// (`C_0` = the sibling of `n`), removal boxes `B_0 = box(C_0)`, `B_k = B_(k-1) u box(C_k)`:
/// * `X` in the subtree of `C_k`: `delta = base_k + SA(X u n) + C_I(X)` with `C_I(C_k) = 0`,
/// * `X = A_k`: `delta = base_k + SA(B_k)`,
///
/// where `base_0 = -SA(P)` and `base_(k+1) = base_k + SA(B_k) - SA(A_k)`: the ancestors below the insertion
/// level lose `n`'s box, those above keep their boxes.
pub fn best_move(tree: &OptTree, queue: &mut SearchQueue, n: u32) -> Option<Move> {
    let node = &tree.nodes[n as usize];
    let p = node.parent;
    if p == NONE {
        return None;
    }
    let l = node.aabb;
    let mut base = -tree.area(p);
    let mut best = 0.0f32;
    let mut found: Option<(f32, u32)> = None;
    let sibling = tree.sibling(n);
    let mut removal_box = tree.nodes[sibling as usize].aabb;
    let area_l = area(&l);
    if let Some(hit) = search(tree, queue, &l, area_l, sibling, base, best) {
        (best, found) = (hit.0, Some(hit));
    }
    let mut ancestor = p;
    loop {
        let above = tree.nodes[ancestor as usize].parent;
        if above == NONE {
            break;
        }
        // Level k: A_k = `above`, C_k = its child off the path, searched with base_k.
        let above_node = &tree.nodes[above as usize];
        let off_path = if above_node.left == ancestor { above_node.right } else { above_node.left };
        if let Some(hit) = search(tree, queue, &l, area_l, off_path, base, best) {
            (best, found) = (hit.0, Some(hit));
        }
        removal_box = removal_box.union(&tree.nodes[off_path as usize].aabb);
        let removal_area = area(&removal_box);
        if base + removal_area < best {
            best = base + removal_area;
            found = Some((best, above));
        }
        base += removal_area - area(&above_node.aabb);
        ancestor = above;
    }
    found.map(|(delta, target)| Move { node: n, target, delta })
}
