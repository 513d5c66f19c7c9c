//! The batch nodes of the parallel loop without ranking the tree every round: every node's measure kept as a
//! sortable key, updated where the last rounds wrote, with a count of keys per bucket.
//!
//! A round of the decreasing-fraction schedule takes the `k` most inefficient eligible nodes (see `select`).
//! Ranking every eligible node for it would be an `O(n)` pass with random reads per round, whatever `k`, which
//! dominates the late, small rounds on large trees. Here a node's key changes only when the node,
//! its parent, a child, or the root was written, and the edit log lists the nodes written ([`EditLog`]'s
//! touched list), so a round recomputes the keys of those nodes and their neighbours; choosing the batch is
//! then a scan of a 65,536-bucket histogram and one sequential pass over the keys.
//!
//! Invariant: between updates, `keys[i]` is [`key`] of node `i` in the tree as it was at the last update, and
//! `histogram[b]` counts the keys whose top 16 bits are `b`. The selected set is exactly the one a full
//! ranking by (measure descending, node index) would take first, so batches, and trees, do not depend on
//! whether the index is fresh or updated (a property test checks this after every round).

use rayon::prelude::*;

use super::measure::{Selection, is_eligible, measure};
use super::tree::{NONE, OptTree, area};

/// Bits of a key that pick its histogram bucket: the top 16.
const BUCKET_SHIFT: u32 = 48;

/// Buckets of the histogram.
const BUCKETS: usize = 1 << (64 - BUCKET_SHIFT);

/// An update that touched more than `1 / REBUILD_FRACTION` of the nodes builds the index afresh instead.
const REBUILD_FRACTION: usize = 32;

/// Nodes per parallel task of the full passes (each task of the counting pass fills a histogram).
const NODES_PER_TASK: usize = 1 << 16;

/// Node `i`'s selection key: its measure's bits plus one when it is eligible (measures are not negative, so
/// their bits order as they do, and every eligible key is above 0), else 0.
fn key(tree: &OptTree, selection: Selection, i: u32) -> u64 {
    if !is_eligible(tree, i) {
        return 0;
    }
    let node = &tree.nodes[i as usize];
    let area_of = |j: u32| area(&tree.nodes[j as usize].aabb);
    measure(area_of(i), area_of(node.left), area_of(node.right), selection).to_bits() + 1
}

/// One chunk of keys split by the boundary bucket: the nodes above it, and the keys and nodes in it.
type ChunkSplit = (Vec<u32>, Vec<(u64, u32)>);

fn bucket(key: u64) -> usize {
    (key >> BUCKET_SHIFT) as usize
}

/// Every node's key under one selection measure, and the count of keys per bucket (see the module doc).
#[derive(Debug, PartialEq)]
pub struct MeasureIndex {
    selection: Selection,
    keys: Vec<u64>,
    histogram: Vec<usize>,
    /// The root at the last update (a new root changes its children's eligibility).
    root: u32,
}

impl MeasureIndex {
    /// The index of `tree` under `selection` (not `Random`), in two parallel passes.
    pub fn new(tree: &OptTree, selection: Selection) -> MeasureIndex {
        let keys: Vec<u64> = (0..tree.nodes.len() as u32).into_par_iter().map(|i| key(tree, selection, i)).collect();
        let histogram = keys
            .par_chunks(NODES_PER_TASK)
            .map(|chunk| {
                let mut counts = vec![0usize; BUCKETS];
                chunk.iter().for_each(|&k| counts[bucket(k)] += 1);
                counts
            })
            .reduce_with(|mut a, b| {
                a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                a
            })
            .unwrap_or_else(|| vec![0; BUCKETS]);
        MeasureIndex { selection, keys, histogram, root: tree.root }
    }

    /// The measure the keys rank by.
    pub fn selection(&self) -> Selection {
        self.selection
    }

    /// Brings the keys up to date with `tree` after the nodes in `touched` (and no others) were written:
    /// their keys, their parents' (a child's area changed) and their children's (a parent, hence eligibility,
    /// may have changed) are recomputed, and the old and new roots' children's when the root changed.
    pub fn update(&mut self, tree: &OptTree, touched: &[u32]) {
        if touched.len() > tree.nodes.len() / REBUILD_FRACTION {
            // After a round that wrote much of the tree, the parallel passes of a fresh index beat updating
            // each node.
            *self = MeasureIndex::new(tree, self.selection);
            return;
        }
        let with_neighbours = |i: u32| {
            let node = &tree.nodes[i as usize];
            let (left, right) = if node.left == NONE { (NONE, NONE) } else { (node.left, node.right) };
            [i, node.parent, left, right]
        };
        let mut stale: Vec<u32> = touched.par_iter().flat_map_iter(|&t| with_neighbours(t)).collect();
        if self.root != tree.root {
            for r in [self.root, tree.root].into_iter().filter(|&r| r != NONE) {
                stale.extend(with_neighbours(r));
            }
            self.root = tree.root;
        }
        // New keys in parallel (the reads are the cost), written in order; a node listed twice gets the same key.
        let selection = self.selection;
        let fresh: Vec<(u32, u64)> =
            stale.into_par_iter().filter(|&i| i != NONE).map(|i| (i, key(tree, selection, i))).collect();
        for (i, new) in fresh {
            let old = std::mem::replace(&mut self.keys[i as usize], new);
            if old != new {
                self.histogram[bucket(old)] -= 1;
                self.histogram[bucket(new)] += 1;
            }
        }
    }

    /// The `k` nodes with the largest keys, ties going to the smaller index: a set, in index order within a
    /// bucket. `k` must not exceed the number of eligible nodes.
    pub fn select(&self, k: usize) -> Vec<u32> {
        // The bucket holding the k-th largest key, and how many keys lie in higher buckets.
        let mut higher = 0;
        let mut boundary = 0;
        for (b, &count) in self.histogram.iter().enumerate().rev() {
            if higher + count >= k {
                boundary = b;
                break;
            }
            higher += count;
        }
        let parts: Vec<ChunkSplit> = self
            .keys
            .par_chunks(NODES_PER_TASK)
            .enumerate()
            .map(|(chunk_index, chunk)| {
                let first = (chunk_index * NODES_PER_TASK) as u32;
                let (mut taken, mut tied) = (Vec::new(), Vec::new());
                for (i, &key) in (first..).zip(chunk) {
                    match bucket(key).cmp(&boundary) {
                        std::cmp::Ordering::Greater => taken.push(i),
                        std::cmp::Ordering::Equal => tied.push((key, i)),
                        std::cmp::Ordering::Less => {}
                    }
                }
                (taken, tied)
            })
            .collect();
        let mut taken: Vec<u32> = Vec::with_capacity(k);
        let mut tied: Vec<(u64, u32)> = Vec::new();
        for (part_taken, part_tied) in parts {
            taken.extend(part_taken);
            tied.extend(part_tied);
        }
        let rest = k - taken.len();
        let by_key = |a: &(u64, u32), b: &(u64, u32)| b.0.cmp(&a.0).then(a.1.cmp(&b.1));
        if rest < tied.len() {
            tied.select_nth_unstable_by(rest, by_key);
        }
        taken.extend(tied[..rest].iter().map(|&(_, i)| i));
        taken
    }
}
