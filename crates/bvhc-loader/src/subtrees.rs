//! Cutting a tree into subtrees that threads refit independently, bottom up, each over its own run of nodes.
//!
//! The format asks only that a child come after its parent (V14, V29), but bvhc's packers store each node's
//! children as one group and the groups of a subtree after the group that holds its root, depth first
//! (`src/pack/binary.rs`, `src/layout/collapse.rs`): so the nodes below a node form one run of indices, from its
//! first child to where the next subtree's nodes begin, and their leaves one run of triangle records or packets.
//! A [`Cut`] takes the nodes of the tree's top levels (the **top**, refit last on one thread, in decreasing index
//! order) and, below each node of its lowest level, the run of its descendants (a **part**). A part is refit
//! children first by walking its run backwards, reading and writing nothing outside its run of nodes and its run
//! of leaf data, so the parts are disjoint slices handed to threads. That a part's nodes and leaves really stay
//! inside it is checked as it is refit (a file of another writer, or one that does not verify, may not keep to
//! the layout), and a caller whose part fails refits the whole tree the slow way instead.

use std::ops::Range;

/// The part of a tree's layout a cut needs.
pub(crate) trait TreeShape {
    /// The number of nodes.
    fn node_count(&self) -> usize;
    /// Calls `child` with each child of `node` that is a node (none for a leaf), in slot order.
    fn for_each_inner_child(&self, node: usize, child: impl FnMut(usize));
}

/// A tree cut into a top and parts (see the module's text).
#[derive(Clone, Debug)]
pub(crate) struct Cut {
    /// The top's nodes, in decreasing index order (children before parents, V14).
    pub(crate) top: Vec<usize>,
    /// Each part's run of nodes, in increasing order, disjoint from each other and from the top.
    pub(crate) parts: Vec<Range<usize>>,
}

/// Deepest level a cut descends to (a tree shallower than wanted, or one whose children repeat, stops there).
const MAX_DEPTH: usize = 24;

/// Cuts `tree` below the first level with at least `want` inner nodes' children (or its leaves' level), each
/// part the run of nodes from that level's nodes' first child to the next part's or top node's index. `None`
/// where the layout cannot be cut so (two runs would start at the same index): refit such a tree whole.
pub(crate) fn cut(tree: &impl TreeShape, want: usize) -> Option<Cut> {
    let count = tree.node_count();
    let mut top = Vec::new();
    let mut level = if count > 0 { vec![0] } else { Vec::new() };
    let mut starts: Vec<usize> = Vec::new();
    for depth in 0.. {
        starts.clear();
        let mut below = Vec::new();
        for &node in &level {
            let mut first: Option<usize> = None;
            tree.for_each_inner_child(node, |child| {
                below.push(child);
                first = Some(first.map_or(child, |f| f.min(child)));
            });
            starts.extend(first);
        }
        if starts.len() >= want || below.is_empty() || depth == MAX_DEPTH {
            break;
        }
        top.append(&mut level);
        level = below;
    }
    top.append(&mut level);
    // Runs start at the parts' first nodes and at each top node; each part ends where the next run starts.
    let mut bounds: Vec<(usize, bool)> =
        starts.iter().map(|&s| (s, true)).chain(top.iter().map(|&t| (t, false))).collect();
    bounds.sort_unstable();
    if bounds.windows(2).any(|w| w[0].0 == w[1].0) || bounds.last().is_some_and(|&(index, _)| index >= count) {
        return None;
    }
    let parts = (0..bounds.len())
        .filter(|&k| bounds[k].1)
        .map(|k| bounds[k].0..bounds.get(k + 1).map_or(count, |next| next.0))
        .collect();
    top.sort_unstable_by(|a, b| b.cmp(a));
    Some(Cut { top, parts })
}

/// `items` cut into the mutable slices `ranges` name, in the order given; `None` where two overlap or one
/// reaches past the end.
pub(crate) fn carve<'a, T>(items: &'a mut [T], ranges: &[Range<usize>]) -> Option<Vec<&'a mut [T]>> {
    let mut order: Vec<usize> = (0..ranges.len()).collect();
    order.sort_unstable_by_key(|&k| (ranges[k].start, ranges[k].end));
    let mut carved: Vec<Option<&'a mut [T]>> = (0..ranges.len()).map(|_| None).collect();
    let (mut rest, mut at) = (items, 0);
    for k in order {
        let range = &ranges[k];
        if range.start < at || range.end < range.start || range.end > at + rest.len() {
            return None;
        }
        let (_, tail) = rest.split_at_mut(range.start - at);
        let (slice, tail) = tail.split_at_mut(range.end - range.start);
        carved[k] = Some(slice);
        (rest, at) = (tail, range.end);
    }
    carved.into_iter().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A binary tree as bvhc packs it: `children[node]` the first of an adjacent pair, or `None` for a leaf.
    struct Pairs(Vec<Option<usize>>);

    impl TreeShape for Pairs {
        fn node_count(&self) -> usize {
            self.0.len()
        }
        fn for_each_inner_child(&self, node: usize, mut child: impl FnMut(usize)) {
            if let Some(first) = self.0[node] {
                child(first);
                child(first + 1);
            }
        }
    }

    /// A complete binary tree of `depth` levels packed depth first by pairs (`src/pack/binary.rs`).
    fn packed(depth: u32) -> Pairs {
        fn place(children: &mut Vec<Option<usize>>, node: usize, depth: u32) {
            if depth == 0 {
                return;
            }
            let first = children.len();
            children[node] = Some(first);
            children.extend([None, None]);
            place(children, first, depth - 1);
            place(children, first + 1, depth - 1);
        }
        let mut children = vec![None];
        place(&mut children, 0, depth);
        Pairs(children)
    }

    #[test]
    fn parts_and_top_cover_every_node_once_and_hold_whole_subtrees() {
        for (depth, want) in [(0, 4), (1, 4), (5, 1), (5, 4), (8, 16), (8, 1000)] {
            let tree = packed(depth);
            let cut = cut(&tree, want).expect("a packed tree cuts");
            let mut seen = vec![0; tree.node_count()];
            cut.top.iter().for_each(|&t| seen[t] += 1);
            cut.parts.iter().flat_map(|p| p.clone()).for_each(|n| seen[n] += 1);
            assert!(seen.iter().all(|&s| s == 1), "depth {depth}, want {want}");
            assert!(cut.top.windows(2).all(|w| w[0] > w[1]));
            for part in &cut.parts {
                for node in part.clone() {
                    tree.for_each_inner_child(node, |child| assert!(part.contains(&child)));
                }
            }
        }
    }

    #[test]
    fn a_layout_whose_runs_collide_is_not_cut() {
        // Node 2 is a child of node 0 and of node 1 (not a tree): it would be a top node twice, and no cut holds it.
        let tree = Pairs(vec![Some(1), Some(2), None, None]);
        assert!(cut(&tree, 2).is_none());
    }

    #[test]
    fn carving_gives_each_range_its_slice_and_refuses_overlaps() {
        let mut items: Vec<u32> = (0..10).collect();
        let slices = carve(&mut items, &[5..7, 0..2, 8..10]).expect("disjoint ranges carve");
        assert_eq!(slices.iter().map(|s| s.to_vec()).collect::<Vec<_>>(), vec![vec![5, 6], vec![0, 1], vec![8, 9]]);
        assert!(carve(&mut items, &[0..3, 2..4]).is_none());
        assert!(carve(&mut items, &[2..4, 9..11]).is_none());
    }
}
