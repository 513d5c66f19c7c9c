//! One record count a triangle for both trees of a file with split references.
//!
//! A leaf that gathers several pieces of one triangle holds it once ([`remove_repeats_and_balance`]): one test instead of
//! several. But the binary tree's leaves must partition the triangle records (V15) and every record must sit in
//! exactly one wide lane (V34), and the leaf merging and the wide collapse group the pieces differently, so
//! after removing repeats a triangle may be in, say, two binary leaves and one wide leaf.
//! It then repeats it inside a leaf that already holds it, on the side with fewer, until both
//! trees hold it equally often: coverage (V25, V35) is untouched, since no leaf box changes.

use bvhc_loader::format::{MAX_LEAF_PACKETS, PACKET_LANES};

use super::wide_tree::{WideChild, WideTree};
use crate::build_tree::{BuildNode, BuildTree};

/// Most triangles a wide leaf may hold: the format's packets a leaf times the lanes a packet.
const WIDE_LEAF_LIMIT: usize = MAX_LEAF_PACKETS as usize * PACKET_LANES;

/// The entries of a leaf without repeats, each at its first occurrence.
fn distinct(leaf: &[u32]) -> Vec<u32> {
    let mut kept: Vec<u32> = Vec::with_capacity(leaf.len());
    for &t in leaf {
        if !kept.contains(&t) {
            kept.push(t);
        }
    }
    kept
}

/// Removes repeats inside every leaf of both trees, then makes every triangle occur as often in `binary`'s
/// leaves as in `wide`'s by repeating it inside leaves that hold it (the binary side in its first leaf; the wide
/// side spread over its leaves, at most 32 triangles a leaf). Returns `false`, changing nothing, when
/// the wide leaves have no room for that; the trees then keep every reference, which is valid too.
pub fn remove_repeats_and_balance(binary: &mut BuildTree, wide: &mut WideTree, triangle_count: usize) -> bool {
    let mut in_binary = vec![0u32; triangle_count];
    let mut in_wide = vec![0u32; triangle_count];
    for (first, count) in binary_leaves(binary) {
        distinct(&binary.triangle_order[first as usize..(first + count) as usize])
            .into_iter()
            .for_each(|t| in_binary[t as usize] += 1);
    }
    let slots = wide_leaf_slots(wide);
    for &(n, k) in &slots {
        if let WideChild::Leaf { first, count } = wide.nodes[n].children[k].1 {
            distinct(&wide.triangle_order[first as usize..(first + count) as usize])
                .into_iter()
                .for_each(|t| in_wide[t as usize] += 1);
        }
    }
    let binary_extra: Vec<u32> = in_binary.iter().zip(&in_wide).map(|(&b, &w)| w.saturating_sub(b)).collect();
    let mut wide_extra: Vec<u32> = in_binary.iter().zip(&in_wide).map(|(&b, &w)| b.saturating_sub(w)).collect();
    let Some((order, ranges)) = padded_wide(wide, &slots, &mut wide_extra) else { return false };
    for (&(n, k), &(first, count)) in slots.iter().zip(&ranges) {
        wide.nodes[n].children[k].1 = WideChild::Leaf { first, count };
    }
    wide.triangle_order = order;
    pad_binary(binary, binary_extra);
    true
}

/// Removes repeats inside every leaf of a binary tree that has no wide tree beside it.
pub fn remove_binary_repeats(binary: &mut BuildTree, triangle_count: usize) {
    pad_binary(binary, vec![0; triangle_count]);
}

/// The `(first, count)` of every binary leaf, in order of `first`.
fn binary_leaves(tree: &BuildTree) -> Vec<(u32, u32)> {
    let mut leaves: Vec<(u32, u32)> = tree
        .nodes
        .iter()
        .filter_map(|node| match *node {
            BuildNode::Leaf { first, count, .. } => Some((first, count)),
            BuildNode::Inner { .. } => None,
        })
        .collect();
    leaves.sort_unstable();
    leaves
}

/// Each binary leaf without repeats, and triangle `t` repeated `extra[t]` more times in the first leaf that
/// holds it. Leaves are rewritten in order of their ranges, so the new ranges stay disjoint and in order.
fn pad_binary(tree: &mut BuildTree, mut extra: Vec<u32>) {
    let old = std::mem::take(&mut tree.triangle_order);
    let mut order = Vec::with_capacity(old.len());
    let mut leaves: Vec<usize> =
        (0..tree.nodes.len()).filter(|&i| matches!(tree.nodes[i], BuildNode::Leaf { .. })).collect();
    leaves.sort_by_key(|&i| match tree.nodes[i] {
        BuildNode::Leaf { first, .. } => first,
        BuildNode::Inner { .. } => 0,
    });
    for i in leaves {
        if let BuildNode::Leaf { aabb, first, count } = tree.nodes[i] {
            let new_first = order.len() as u32;
            for t in distinct(&old[first as usize..(first + count) as usize]) {
                order.push(t);
                let more = std::mem::take(&mut extra[t as usize]);
                order.extend(std::iter::repeat_n(t, more as usize));
            }
            tree.nodes[i] = BuildNode::Leaf { aabb, first: new_first, count: order.len() as u32 - new_first };
        }
    }
    tree.triangle_order = order;
}

/// The wide tree's leaf slots `(node, child)`, in order of their ranges.
fn wide_leaf_slots(tree: &WideTree) -> Vec<(usize, usize)> {
    let mut slots: Vec<(usize, usize, u32)> = Vec::new();
    for (n, node) in tree.nodes.iter().enumerate() {
        for (k, (_, child)) in node.children.iter().enumerate() {
            if let WideChild::Leaf { first, .. } = *child {
                slots.push((n, k, first));
            }
        }
    }
    slots.sort_unstable_by_key(|&(_, _, first)| first);
    slots.into_iter().map(|(n, k, _)| (n, k)).collect()
}

/// A new `triangle_order` and each leaf slot's `(first, count)` in it.
type PaddedOrder = (Vec<u32>, Vec<(u32, u32)>);

/// The wide tree's order with each leaf without repeats and triangle `t` repeated `extra[t]` more times over
/// the leaves that hold it, none beyond `WIDE_LEAF_LIMIT`, with the new `(first, count)` of each slot; `None`
/// when the leaves cannot take them all.
fn padded_wide(tree: &WideTree, slots: &[(usize, usize)], extra: &mut [u32]) -> Option<PaddedOrder> {
    let old = &tree.triangle_order;
    let mut order = Vec::with_capacity(old.len());
    let mut ranges = Vec::with_capacity(slots.len());
    for &(n, k) in slots {
        let WideChild::Leaf { first, count } = tree.nodes[n].children[k].1 else { continue };
        let new_first = order.len();
        let leaf = distinct(&old[first as usize..(first + count) as usize]);
        order.extend_from_slice(&leaf);
        for &t in &leaf {
            let room = WIDE_LEAF_LIMIT.saturating_sub(order.len() - new_first) as u32;
            let more = extra[t as usize].min(room);
            extra[t as usize] -= more;
            order.extend(std::iter::repeat_n(t, more as usize));
        }
        ranges.push((new_first as u32, (order.len() - new_first) as u32));
    }
    if extra.iter().any(|&e| e > 0) {
        return None;
    }
    Some((order, ranges))
}
