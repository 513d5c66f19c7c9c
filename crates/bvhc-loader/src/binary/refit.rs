//! The binary layout's refit: the triangle records moved, and every node's box recomputed from the records
//! beneath it, children before parents, keeping the tree's shape (which node holds which records).

use std::ops::Range;

use crate::format::cost::{AreaSums, box_area};
use crate::format::{Bounds, EMPTY_BOUNDS, PackedNode, PackedTriangle, merge_bounds};
use crate::parallel::Workers;
use crate::subtrees::{TreeShape, carve, cut};

/// Nodes from which the tree is cut into subtrees, each refit on its own while it is in cache, on threads where
/// the caller allows them (below, the tree is one run on one thread: a thread's start costs more than it saves).
const CUT_NODES: usize = 1 << 14;

/// Parts a cut aims at: several a thread, so that threads balance subtrees of unequal sizes.
const PARTS: usize = 32;

/// The deepest a leaf may lie (V20), bounding a descent.
const MAX_DEPTH: usize = 256;

/// Where a refit's records take their new vertices from.
pub(crate) trait NewRecords: Sync {
    /// Writes the new vertices of the records `first .. first + records.len()` into `records` (a record whose
    /// position is not given keeps its vertices), and returns their box ([`crate::format::TriangleFold`]),
    /// folded from the vertices as they are written rather than read back.
    fn write(&self, first: usize, records: &mut [PackedTriangle]) -> Bounds;
}

/// Moves `records` (all of the file's, in order) to `new` and recomputes every box of `nodes` (a verified file's
/// binary tree over them, children after their parent, V14-V15) bottom up, as the converter's packing computes
/// them: a leaf's box the union of its records' bounds, an inner node's the union of its children's boxes.
/// Returns the refit tree's area sums (section 5.6's, summed as the boxes are made). A large tree in the layout
/// bvhc writes is cut into subtrees (`crate::subtrees`), each refit in one forward pass over its leaves (which
/// write their records and box them as they go, the records streaming in order) and one backward pass over its
/// inner nodes (in cache by then), the subtrees on `workers`' threads; any other tree is refit whole, node by
/// node on one thread, with the same result. Indices out of range (a file that does not verify) leave a box empty rather than panic.
pub(crate) fn refit_binary(
    nodes: &mut [PackedNode],
    records: &mut [PackedTriangle],
    new: &(impl NewRecords + ?Sized),
    workers: Workers,
) -> AreaSums {
    let refit = match nodes.len() >= CUT_NODES {
        true => refit_by_parts(nodes, records, new, workers),
        false => refit_run(nodes, 0, records, 0, new),
    };
    refit.unwrap_or_else(|| refit_whole(nodes, records, new))
}

/// The binary tree as [`cut`] sees it: an inner node's children are the pair at its `index`.
struct Pairs<'a>(&'a [PackedNode]);

impl TreeShape for Pairs<'_> {
    fn node_count(&self) -> usize {
        self.0.len()
    }

    fn for_each_inner_child(&self, node: usize, mut child: impl FnMut(usize)) {
        if let Some(node) = self.0.get(node).filter(|n| !n.is_leaf()) {
            child(node.index as usize);
            child(node.index as usize + 1);
        }
    }
}

/// Refits the tree cut into parts (each with its run of nodes and of records) on `workers`' threads, then its
/// top on this one. `None`, with some records and boxes written, where the tree does not keep to bvhc's layout.
fn refit_by_parts(
    nodes: &mut [PackedNode],
    records: &mut [PackedTriangle],
    new: &(impl NewRecords + ?Sized),
    workers: Workers,
) -> Option<AreaSums> {
    let cut = cut(&Pairs(nodes), PARTS)?;
    let record_runs: Vec<Range<usize>> =
        cut.parts.iter().map(|part| leaf_records(nodes, part.start)).collect::<Option<_>>()?;
    let part_records = carve(records, &record_runs)?;
    let tasks: Vec<_> = carve(nodes, &cut.parts)?
        .into_iter()
        .zip(part_records)
        .zip(cut.parts.iter().zip(&record_runs))
        .map(|((nodes, records), (part, run))| {
            (part.len(), move || refit_run(nodes, part.start, records, run.start, new))
        })
        .collect();
    let mut sums = AreaSums::default();
    for part_sums in workers.run_largest_first(tasks) {
        sums = sums.plus(part_sums?);
    }
    Some(cut.top.iter().fold(sums, |sums, &node| sums.plus(refit_node(nodes, node, records, new))))
}

/// Refits node `node` from what lies below it, refit already: a leaf moves its records and takes their box, an
/// inner node the union of its children's boxes. Returns its area sums. Indices out of range (a file that does
/// not verify) give an empty box rather than panic.
fn refit_node(
    nodes: &mut [PackedNode],
    node: usize,
    records: &mut [PackedTriangle],
    new: &(impl NewRecords + ?Sized),
) -> AreaSums {
    let (bounds, count) = match nodes[node] {
        leaf if leaf.is_leaf() => {
            let first = leaf.index as usize;
            let leaf_records = records.get_mut(first..first.saturating_add(leaf.count as usize)).unwrap_or(&mut []);
            (new.write(first, leaf_records), leaf.count)
        }
        inner => {
            let child = |c: usize| nodes.get(c).map_or(EMPTY_BOUNDS, |n| (n.min, n.max));
            (merge_bounds(child(inner.index as usize), child((inner.index as usize).saturating_add(1))), 0)
        }
    };
    (nodes[node].min, nodes[node].max) = bounds;
    AreaSums::default().with_node(box_area(&bounds.0, &bounds.1), count)
}

/// The records under the pair of nodes at `pair` (a part's first two nodes): from its first node's first leaf to
/// its second node's last, depth first. `None` for a descent that leaves the nodes or goes deeper than V20.
fn leaf_records(nodes: &[PackedNode], pair: usize) -> Option<Range<usize>> {
    let descend = |mut node: usize, last: bool| {
        for _ in 0..=MAX_DEPTH {
            let at = nodes.get(node)?;
            if at.is_leaf() {
                return Some(*at);
            }
            node = at.index as usize + usize::from(last);
        }
        None
    };
    let (first, last) = (descend(pair, false)?, descend(pair + 1, true)?);
    Some(first.index as usize..(last.index as usize).checked_add(last.count as usize)?)
}

/// Refits a run of nodes that holds whole subtrees (the nodes `node_base ..`, children after parents) over the
/// run of records `record_base ..`: forwards over its leaves, each moving its records and taking their box, then
/// backwards over its inner nodes, each taking the union of its children's boxes. Returns the run's area sums;
/// `None` where a child or a record lies outside the runs (or a child before its parent): the run is then partly
/// refit.
fn refit_run(
    nodes: &mut [PackedNode],
    node_base: usize,
    records: &mut [PackedTriangle],
    record_base: usize,
    new: &(impl NewRecords + ?Sized),
) -> Option<AreaSums> {
    let mut sums = AreaSums::default();
    for node in nodes.iter_mut().filter(|node| node.is_leaf()) {
        let first = (node.index as usize).wrapping_sub(record_base);
        let leaf = records.get_mut(first..first.saturating_add(node.count as usize))?;
        (node.min, node.max) = new.write(node.index as usize, leaf);
        sums = sums.with_node(box_area(&node.min, &node.max), node.count);
    }
    for i in (0..nodes.len()).rev() {
        let node = nodes[i];
        if node.is_leaf() {
            continue;
        }
        let first = (node.index as usize).wrapping_sub(node_base);
        if first <= i || first.saturating_add(1) >= nodes.len() {
            return None;
        }
        let (min, max) =
            merge_bounds((nodes[first].min, nodes[first].max), (nodes[first + 1].min, nodes[first + 1].max));
        (nodes[i].min, nodes[i].max) = (min, max);
        sums = sums.with_node(box_area(&min, &max), 0);
    }
    Some(sums)
}

/// Refits any tree (one not in bvhc's layout, or one that does not verify) node by node in reverse node order,
/// on one thread: children come after their parent (V14), so each node's children are refit before it.
fn refit_whole(nodes: &mut [PackedNode], records: &mut [PackedTriangle], new: &(impl NewRecords + ?Sized)) -> AreaSums {
    (0..nodes.len()).rev().fold(AreaSums::default(), |sums, node| sums.plus(refit_node(nodes, node, records, new)))
}
