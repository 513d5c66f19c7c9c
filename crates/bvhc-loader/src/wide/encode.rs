//! The wide node's encoder, beside its decoder: a slot's box and child written into a [`WideNode8`], and read
//! back. The converter packs its wide trees with it, and an edit of a file's wide nodes
//! ([`crate::BvhFile::edit`]) re-encodes them with it.

use crate::format::{Bounds, EMPTY_SLOT, WideNode8};

impl WideNode8 {
    /// Writes slot `slot` (below `WIDE`): the box `(min, max)` and the child reference (an inner node's index,
    /// or a leaf reference from [`WideNode8::leaf`]).
    pub fn set_slot(&mut self, slot: usize, (min, max): Bounds, child: u32) {
        for axis in 0..3 {
            self.min[axis][slot] = min[axis];
            self.max[axis][slot] = max[axis];
        }
        self.child[slot] = child;
    }

    /// Writes the box of slot `slot` alone, keeping its child.
    pub fn set_slot_box(&mut self, slot: usize, (min, max): Bounds) {
        self.set_slot(slot, (min, max), self.child[slot]);
    }

    /// The box of slot `slot`, `(min, max)`, and its child reference; `None` for an empty slot.
    pub fn slot(&self, slot: usize) -> Option<(Bounds, u32)> {
        let child = self.child[slot];
        (child != EMPTY_SLOT).then(|| {
            let min = std::array::from_fn(|a| self.min[a][slot]);
            let max = std::array::from_fn(|a| self.max[a][slot]);
            ((min, max), child)
        })
    }
}
