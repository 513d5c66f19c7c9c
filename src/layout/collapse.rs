//! Collapse of a binary BVH into an N-wide one by dynamic programming, after H. Ylitie, T. Karras, S. Laine,
//! "Efficient Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs", High Performance Graphics 2017,
//! section 3: optimal under the SAH for the given binary topology.
//!
//! Symbols: for a binary node `n` and a slot count `i` in `1..=N`, `C(n, i)` is the lowest cost of covering
//! `n`'s subtree with at most `i` wide children (leaves or wide nodes), areas unnormalized:
//! - `C_leaf(n) = packet_test * ceil(t(n) / W) * SA(n)` when `t(n) <= max_leaf_size` triangles, else infinite;
//! - `C_internal(n) = node_visit * SA(n) + C_distribute(n, N)`, with
//!   `C_distribute(n, j) = min over k in 1..j of C(left, k) + C(right, j - k)`;
//! - `C(n, 1) = min(C_leaf(n), C_internal(n))`, and `C(n, i) = min(C(n, i - 1), C_distribute(n, i))` for `i > 1`;
//! - a binary leaf (one triangle) has `C(n, i) = C_leaf(n)` for every `i`.
//!
//! The root is always a wide node (unless the scene has one leaf's worth of triangles and a leaf is cheaper).
//! Deviations from the paper: leaves are priced per packet of `W` triangles tested together (the SIMD
//! kernel's unit of work) rather than per triangle; no quantization (the CPU layout stores f32 boxes). O(n N^2)
//! time; O(n N) bytes of decisions, the costs only along the current path.

use super::leaf_counts::LeafCounts;
use super::wide_tree::{WideChild, WideCosts, WideNode, WideTree};
use crate::geometry::Aabb;
use crate::optimize::{NONE, OptTree};

/// Per binary node: how each `C(n, i)` was reached, as `width` decisions of 4 bits (two a byte; every decision
/// is below 16): the table takes `width / 2` bytes a node. The costs themselves are kept only while they are
/// needed (see [`fill_table`]).
///
/// Decision `i - 1` for `i` in `2..=N`: 0 when `C(n, i) = C(n, 1)` (one child), else `k`: `k` slots to the left
/// child and `i - k` to the right one. Decision 0 (`C(n, 1)` has no split to record): 0 when `C(n, 1)` is a
/// leaf, else the left child's share `k` (1 to `N - 1`) of `C_distribute(n, N)`, how the wide node made from
/// `n` spreads its `N` slots. The root may be a wide node even where `C(root, 1)` is a leaf (its node visit is
/// paid either way), so its share is kept apart.
struct Table {
    width: usize,
    decisions: Vec<u8>,
    /// `C_distribute(root, N)` and the left child's share in it.
    root_distribution: (f64, u8),
    /// Triangles under the root.
    root_triangles: usize,
}

impl Table {
    fn decision(&self, n: u32, index: usize) -> usize {
        let at = n as usize * self.width + index;
        ((self.decisions[at / 2] >> (4 * (at % 2))) & 0xf) as usize
    }

    fn set_decision(&mut self, n: u32, index: usize, value: usize) {
        debug_assert!(value < 16, "a decision is a slot count below 16");
        let at = n as usize * self.width + index;
        let shift = 4 * (at % 2);
        self.decisions[at / 2] = (self.decisions[at / 2] & !(0xf << shift)) | ((value as u8) << shift);
    }

    /// Whether `C(n, 1)` is a leaf (else a wide node).
    fn is_leaf(&self, n: u32) -> bool {
        self.decision(n, 0) == 0
    }

    /// The left child's share of the slots of the wide node made from inner node `n`.
    fn distribution_split(&self, n: u32, root: u32) -> usize {
        if n == root { self.root_distribution.1 as usize } else { self.decision(n, 0) }
    }
}

/// The costs `C(n, 1..=N)` of one node (`N` <= 16).
type CostRow = [f64; 16];

/// Collapses `tree` (the optimizer's binary tree, one triangle per leaf) into a `costs.width`-wide tree.
pub fn collapse(tree: &OptTree, costs: &WideCosts) -> WideTree {
    collapse_with(tree, costs, false, None)
}

/// [`collapse`] for a tree over split references, where several leaves may hold pieces of one triangle: a wide
/// leaf holds each triangle once (see [`super::records`]), so `t(n)` counts the distinct triangles of
/// `n`'s subtree. The same tree as [`collapse`] where no triangle repeats.
pub fn collapse_references(tree: &OptTree, costs: &WideCosts) -> WideTree {
    collapse_with(tree, costs, true, None)
}

/// [`collapse`] (or with `references`, [`collapse_references`]) with each binary node's surface area replaced by
/// `weights[n]` in the costs: the probability that a ray reaches the node, as sampled rays measure it
/// (`crate::sampling::ray_weights`; Gu, He, Blelloch 2015 contract by the same measure). `weights` has one entry
/// per node of `tree`; weights proportional to the areas give the SAH collapse's tree.
pub fn collapse_by(tree: &OptTree, costs: &WideCosts, weights: &[f64], references: bool) -> WideTree {
    collapse_with(tree, costs, references, Some(weights))
}

fn collapse_with(tree: &OptTree, costs: &WideCosts, distinct: bool, weights: Option<&[f64]>) -> WideTree {
    let width = costs.width.clamp(2, 16);
    let costs = WideCosts {
        width,
        packet_width: costs.packet_width.max(1),
        max_leaf_size: costs.max_leaf_size.max(1),
        ..*costs
    };
    let mut wide = WideTree { width, nodes: Vec::new(), triangle_order: Vec::new(), root_box: Aabb::EMPTY };
    if tree.root == NONE {
        return wide;
    }
    let weight = |n: u32| match weights {
        Some(w) => w.get(n as usize).copied().unwrap_or(0.0),
        None => tree.nodes[n as usize].aabb.surface_area(),
    };
    let table = fill_table(tree, &costs, distinct, &weight);
    wide.root_box = tree.nodes[tree.root as usize].aabb;
    let root = tree.root;
    // The root is stored as a wide node either way: with one leaf child (cost node + leaf) or with the DP's
    // children (node + C_distribute), so compare the leaf with C_distribute alone.
    let root_node = tree.nodes[root as usize];
    let root_as_leaf = root_node.left == NONE
        || (table.root_triangles <= costs.max_leaf_size
            && costs.leaf(table.root_triangles) * weight(root) <= table.root_distribution.0);
    if root_as_leaf {
        // The whole scene is cheapest as one leaf: a root node with that single leaf child.
        let mut children = Vec::new();
        push_leaf(tree, root, &mut wide.triangle_order, &mut children);
        wide.nodes.push(WideNode { children });
        return wide;
    }
    // Depth first: each wide node's children are gathered from the DP's decisions, inner ones expanded in order.
    wide.nodes.push(WideNode { children: Vec::new() });
    let mut stack = vec![(0u32, root)];
    while let Some((wide_index, binary)) = stack.pop() {
        let mut slots = Vec::new();
        distribute(&table, tree, binary, &mut slots);
        let mut children = Vec::with_capacity(slots.len());
        let mut expand = Vec::new();
        for n in slots {
            if table.is_leaf(n) {
                push_leaf(tree, n, &mut wide.triangle_order, &mut children);
            } else {
                let index = wide.nodes.len() as u32 + expand.len() as u32;
                children.push((tree.nodes[n as usize].aabb, WideChild::Node(index)));
                expand.push(n);
            }
        }
        wide.nodes[wide_index as usize].children = children;
        // Reserve the child nodes now (so indices are as assigned), fill them in child order.
        let first_new = wide.nodes.len() as u32;
        wide.nodes.extend(expand.iter().map(|_| WideNode { children: Vec::new() }));
        for (k, &n) in expand.iter().enumerate().rev() {
            stack.push((first_new + k as u32, n));
        }
    }
    // Leaves were appended in the order nodes were expanded, which is not depth-first child order; renumber so
    // that leaf ranges are consecutive in depth-first order, as the file format requires.
    relayout_leaves(&mut wide);
    wide
}

/// Fills the table bottom-up. Nodes are taken children first ([`OptTree::children_first`]): the cost rows and
/// triangle counts wait on a stack (the left child's on top), and only those of subtrees whose parent is not
/// done yet are held, at most the tree's depth plus one (a full table of costs took 64 bytes a node, about the
/// size of the optimizer's tree).
fn fill_table(tree: &OptTree, costs: &WideCosts, distinct: bool, weight: &dyn Fn(u32) -> f64) -> Table {
    let width = costs.width;
    let mut table = Table {
        width,
        decisions: vec![0; (tree.nodes.len() * width).div_ceil(2)],
        root_distribution: (f64::INFINITY, 0),
        root_triangles: 0,
    };
    let mut rows: Vec<(CostRow, u32)> = Vec::new();
    let mut counts = LeafCounts::new(costs.max_leaf_size, distinct);
    for node_index in tree.children_first() {
        let node = tree.nodes[node_index as usize];
        let area = weight(node_index);
        let mut row = [f64::INFINITY; 16];
        if node.left == NONE {
            row[..width].fill(costs.leaf(1) * area);
            rows.push((row, counts.leaf(node.right)));
            continue;
        }
        let ((left_row, left_triangles), (right_row, right_triangles)) = match (rows.pop(), rows.pop()) {
            (Some(left), Some(right)) => (left, right),
            _ => unreachable!("reverse depth-first order finishes both children before their parent"),
        };
        let triangles = counts.join(left_triangles, right_triangles);
        let leaf = if triangles as usize <= costs.max_leaf_size {
            costs.leaf(triangles as usize) * area
        } else {
            f64::INFINITY
        };
        let (distribute_all, k_all) = best_distribution(&left_row, &right_row, width);
        if node_index == tree.root {
            table.root_distribution = (distribute_all, k_all as u8);
        }
        let internal = costs.node_visit * area + distribute_all;
        let is_leaf = leaf <= internal;
        table.set_decision(node_index, 0, if is_leaf { 0 } else { k_all });
        row[0] = leaf.min(internal);
        let mut split = 0;
        for slots in 2..=width {
            let (distributed, k) = best_distribution(&left_row, &right_row, slots);
            if distributed < row[slots - 2] {
                row[slots - 1] = distributed;
                split = k;
            } else {
                row[slots - 1] = row[slots - 2];
            }
            table.set_decision(node_index, slots - 1, split);
        }
        rows.push((row, triangles));
    }
    table.root_triangles = rows.last().map_or(0, |&(_, triangles)| triangles as usize);
    table
}

/// `C_distribute` over `slots` slots for children with cost rows `left`, `right`: the best cost and the left
/// child's share.
fn best_distribution(left: &CostRow, right: &CostRow, slots: usize) -> (f64, usize) {
    (1..slots)
        .map(|k| (left[k - 1] + right[slots - k - 1], k))
        .fold((f64::INFINITY, 1), |best, candidate| if candidate.0 < best.0 { candidate } else { best })
}

/// The binary nodes that become the children of the wide node made from inner binary node `n`.
fn distribute(table: &Table, tree: &OptTree, n: u32, out: &mut Vec<u32>) {
    let node = tree.nodes[n as usize];
    let k = table.distribution_split(n, tree.root);
    gather(table, tree, node.left, k, out);
    gather(table, tree, node.right, table.width - k, out);
}

/// The children that binary node `n` contributes with at most `slots` slots.
fn gather(table: &Table, tree: &OptTree, n: u32, slots: usize, out: &mut Vec<u32>) {
    let node = tree.nodes[n as usize];
    // One slot has no split (decision 0 means something else, see `Table`).
    let split = if node.left == NONE || slots == 1 { 0 } else { table.decision(n, slots - 1) };
    if split == 0 {
        out.push(n);
    } else {
        gather(table, tree, node.left, split, out);
        gather(table, tree, node.right, slots - split, out);
    }
}

/// Appends a leaf over the triangles under binary node `n`.
fn push_leaf(tree: &OptTree, n: u32, order: &mut Vec<u32>, children: &mut Vec<(Aabb, WideChild)>) {
    let first = order.len() as u32;
    let mut stack = vec![n];
    while let Some(j) = stack.pop() {
        let node = tree.nodes[j as usize];
        if node.left == NONE {
            order.push(node.right);
        } else {
            stack.push(node.right);
            stack.push(node.left);
        }
    }
    let count = order.len() as u32 - first;
    children.push((tree.nodes[n as usize].aabb, WideChild::Leaf { first, count }));
}

/// Renumbers leaf ranges so that, depth first in child order, they are consecutive from 0.
fn relayout_leaves(wide: &mut WideTree) {
    let old_order = std::mem::take(&mut wide.triangle_order);
    let mut order = Vec::with_capacity(old_order.len());
    // Leaves are renumbered in depth-first order: a node's leaves and subtrees interleave as its children do.
    let mut pending = vec![(0u32, 0usize)];
    while let Some((i, next_child)) = pending.pop() {
        let children = &mut wide.nodes[i as usize].children;
        let mut k = next_child;
        while k < children.len() {
            match children[k].1 {
                WideChild::Leaf { first, count } => {
                    let new_first = order.len() as u32;
                    order.extend_from_slice(&old_order[first as usize..(first + count) as usize]);
                    children[k].1 = WideChild::Leaf { first: new_first, count };
                    k += 1;
                }
                WideChild::Node(c) => {
                    pending.push((i, k + 1));
                    pending.push((c, 0));
                    break;
                }
            }
        }
    }
    wide.triangle_order = order;
}
