//! What the optimizer changed since the best tree: an undo log and the running change of the cost.
//!
//! The loops keep the best tree seen (batch costs are not monotone). Instead of copying the whole tree after
//! every improving batch (`O(n)` time and a second tree's memory), the current tree *is* the best tree plus
//! the edits made since it was marked: before a node is first written after [`EditLog::mark`], its old value is
//! saved (a bit per node says whether it was). Restoring writes the saved values back, in any order (each node
//! is saved once). Marking forgets the saved values, clearing only their bits. Both cost what was edited, not
//! the size of the tree.
//!
//! The log also lists the nodes written since the list was last taken ([`EditLog::take_touched`]), restores
//! included, which keeps the parallel loop's selection measures up to date (`measure_index`).
//!
//! The log also sums the change of the inner nodes' total surface area (in f64, as [`Aabb::surface_area`]),
//! so a batch's cost is known without summing the whole tree. The sum is taken in the order the edits are
//! made, which the loops fix, so it is the same for any number of threads; it drifts from a fresh sum by
//! rounding only (about 1e-15 relative an edit), and the loops take a fresh sum of the tree they return.

use super::tree::{NONE, OptNode, OptTree, TreeEdits};
use crate::geometry::Aabb;

/// The undo log and the area change since the start; see the module documentation.
#[derive(Debug)]
pub struct EditLog {
    /// Bit `i` is set when node `i`'s value at the mark is in `saved`. Empty only for an empty tree.
    is_saved: Vec<u64>,
    saved: Vec<(u32, OptNode)>,
    /// Bit `i` is set when node `i` is in `touched`.
    is_touched: Vec<u64>,
    /// Nodes written since the list was last taken, each once.
    touched: Vec<u32>,
    root_at_mark: u32,
    inner_area_at_mark: f64,
    inner_area: f64,
}

impl EditLog {
    /// A log for `tree` whose inner nodes' areas sum to `inner_area`, marked at the tree as it is.
    pub fn new(tree: &OptTree, inner_area: f64) -> EditLog {
        EditLog {
            is_saved: vec![0; tree.nodes.len().div_ceil(64)],
            saved: Vec::new(),
            is_touched: vec![0; tree.nodes.len().div_ceil(64)],
            touched: Vec::new(),
            root_at_mark: tree.root,
            inner_area_at_mark: inner_area,
            inner_area,
        }
    }

    /// The sum of the inner nodes' areas now.
    pub fn inner_area(&self) -> f64 {
        self.inner_area
    }

    /// Saves node `i` of `tree` unless it was saved since the mark (or `i` is `NONE`). Call before writing it.
    #[inline]
    pub fn save(&mut self, tree: &OptTree, i: u32) {
        if i == NONE || self.is_saved.is_empty() {
            return;
        }
        let (word, bit) = (i as usize / 64, 1u64 << (i % 64));
        self.touch(word, bit, i);
        if self.is_saved[word] & bit == 0 {
            self.is_saved[word] |= bit;
            self.saved.push((i, tree.nodes[i as usize]));
        }
    }

    #[inline]
    fn touch(&mut self, word: usize, bit: u64, i: u32) {
        if self.is_touched[word] & bit == 0 {
            self.is_touched[word] |= bit;
            self.touched.push(i);
        }
    }

    /// The nodes written (restores included) since the last call, each once, in the order first written.
    pub fn take_touched(&mut self) -> Vec<u32> {
        for &i in &self.touched {
            self.is_touched[i as usize / 64] = 0;
        }
        std::mem::take(&mut self.touched)
    }

    /// Records that an inner node's box changed from `old` to `new`.
    #[inline]
    pub fn box_changed(&mut self, old: &Aabb, new: &Aabb) {
        self.inner_area += new.surface_area() - old.surface_area();
    }

    /// Makes the tree as it is now the one [`EditLog::restore`] returns to.
    pub fn mark(&mut self, tree: &OptTree) {
        for &(i, _) in &self.saved {
            self.is_saved[i as usize / 64] = 0;
        }
        self.saved.clear();
        self.root_at_mark = tree.root;
        self.inner_area_at_mark = self.inner_area;
    }

    /// Undoes every edit since the mark (the log stays marked there).
    pub fn restore(&mut self, tree: &mut OptTree) {
        for k in 0..self.saved.len() {
            let (i, node) = self.saved[k];
            tree.nodes[i as usize] = node;
            let (word, bit) = (i as usize / 64, 1u64 << (i % 64));
            self.is_saved[word] = 0;
            self.touch(word, bit, i);
        }
        self.saved.clear();
        tree.root = self.root_at_mark;
        self.inner_area = self.inner_area_at_mark;
    }
}

impl TreeEdits for EditLog {
    #[inline(always)]
    fn before_write(&mut self, tree: &OptTree, i: u32) {
        self.save(tree, i);
    }

    #[inline(always)]
    fn box_changed(&mut self, old: &Aabb, new: &Aabb) {
        EditLog::box_changed(self, old, new);
    }
}
