//! Triangle counts of subtrees for the bottom-up dynamic programs that choose leaves (the leaf merging and the
//! wide collapse). Over split references a leaf holds each triangle once (see [`super::records`]), so it is
//! priced by how many *distinct* triangles its subtree references. Only counts up to the leaf limit matter, so
//! each pending subtree keeps its distinct triangles while they fit in a leaf, and "too many" otherwise.

/// The triangle counts of the subtrees pending on a dynamic program's stack (children first, the left child's
/// on top). Plain counts add up; distinct counts keep, for each pending subtree that can still become one
/// leaf, its distinct triangles (sorted), concatenated in stack order (a subtree with too many holds none).
pub(crate) struct LeafCounts {
    distinct: bool,
    /// Any count from here up stands for "too many for a leaf".
    too_many: u32,
    ids: Vec<u32>,
    union: Vec<u32>,
}

impl LeafCounts {
    /// Counts for leaves of at most `max_leaf_size` triangles; `distinct` for a tree over split references.
    pub(crate) fn new(max_leaf_size: usize, distinct: bool) -> LeafCounts {
        let too_many = u32::try_from(max_leaf_size).unwrap_or(u32::MAX - 1).saturating_add(1);
        LeafCounts { distinct, too_many, ids: Vec::new(), union: Vec::new() }
    }

    /// The count of a leaf of the binary tree (one reference of `triangle`): 1.
    pub(crate) fn leaf(&mut self, triangle: u32) -> u32 {
        if self.distinct {
            self.ids.push(triangle);
        }
        1
    }

    /// The count of the parent of the top two pending subtrees (counts `left` on top, then `right`), which it
    /// replaces: their sum, or with distinct counts the size of their union (at most the "too many" value).
    pub(crate) fn join(&mut self, left: u32, right: u32) -> u32 {
        if !self.distinct {
            return left.saturating_add(right);
        }
        let too_many = self.too_many;
        let listed = |count: u32| if count < too_many { count as usize } else { 0 };
        let right_start = self.ids.len() - listed(left) - listed(right);
        if left >= too_many || right >= too_many {
            self.ids.truncate(right_start);
            return too_many;
        }
        self.union.clear();
        self.union.extend_from_slice(&self.ids[right_start..]);
        self.union.sort_unstable();
        self.union.dedup();
        self.ids.truncate(right_start);
        if self.union.len() >= too_many as usize {
            return too_many;
        }
        self.ids.extend_from_slice(&self.union);
        self.union.len() as u32
    }
}

#[cfg(test)]
mod tests {
    use super::LeafCounts;
    use crate::geometry::Aabb;
    use crate::optimize::{NONE, OptNode, OptTree};

    /// A random tree over `leaves` (triangle ids, some repeated), split at random points of the list.
    fn random_tree(leaves: &[u32], seed: &mut u64) -> OptTree {
        fn grow(tree: &mut OptTree, leaves: &[u32], parent: u32, seed: &mut u64) -> u32 {
            let index = tree.nodes.len() as u32;
            let aabb = Aabb { min: [0.0; 3], max: [1.0; 3] };
            tree.nodes.push(OptNode { aabb, parent, left: NONE, right: leaves[0] });
            if leaves.len() > 1 {
                *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let cut = 1 + (*seed >> 33) as usize % (leaves.len() - 1);
                let left = grow(tree, &leaves[..cut], index, seed);
                let right = grow(tree, &leaves[cut..], index, seed);
                (tree.nodes[index as usize].left, tree.nodes[index as usize].right) = (left, right);
            }
            index
        }
        let mut tree = OptTree { nodes: Vec::new(), root: 0 };
        grow(&mut tree, leaves, NONE, seed);
        tree
    }

    /// Every subtree's count equals a brute-force count of its distinct triangles (capped at the limit + 1),
    /// over random trees where some triangles are referenced once and others up to four times.
    #[test]
    fn counts_equal_brute_force_distinct_counts() {
        let mut seed = 7u64;
        for round in 0..40u32 {
            let mut leaves: Vec<u32> = (0..60).collect();
            leaves.extend((0..40).map(|i| (i * 7 + round) % 20));
            let tree = random_tree(&leaves, &mut seed);
            for limit in [1usize, 2, 4, 8, 200] {
                let mut counts = LeafCounts::new(limit, true);
                let mut pending: Vec<(u32, Vec<u32>)> = Vec::new();
                for i in tree.children_first() {
                    let node = tree.nodes[i as usize];
                    if node.left == NONE {
                        pending.push((counts.leaf(node.right), vec![node.right]));
                        continue;
                    }
                    let ((left, mut ids), (right, right_ids)) = (pending.pop().unwrap(), pending.pop().unwrap());
                    let count = counts.join(left, right);
                    ids.extend(right_ids);
                    ids.sort_unstable();
                    ids.dedup();
                    assert_eq!(count as usize, ids.len().min(limit + 1), "round {round}, limit {limit}");
                    pending.push((count, ids));
                }
            }
        }
    }
}
