//! Flattening a [`BuildTree`] into the loader's on-disk node layout.
//!
//! Depth-first, left subtree first: each inner node's two children are stored as an adjacent pair, and the
//! pairs of a subtree follow the pair that holds its root, so a parent always precedes its children and a
//! subtree's nodes are close together in memory. Triangles are emitted in the same depth-first leaf order,
//! which makes the leaves partition the triangles section exactly as rule V15 requires.

use bvhc_loader::{Error, format::PackedNode, format::PackedTriangle};

use crate::build_tree::{BuildNode, BuildTree};
use crate::fallible::{vec_of, vec_with_capacity};

/// The packed form the writer sees: nodes, triangles in leaf order, and each triangle's source index.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PackedTree {
    /// Nodes in the nodes-section layout; node 0 is the root.
    pub nodes: Vec<PackedNode>,
    /// Triangle vertices in leaf order.
    pub triangles: Vec<PackedTriangle>,
    /// For each packed triangle, its index in the input triangle array.
    pub triangle_ids: Vec<u32>,
}

impl PackedTree {
    /// For each input triangle, its index in the packed triangles (the inverse of `triangle_ids`; 0 for an
    /// input triangle the tree does not hold).
    pub fn file_index_of(&self, input_triangle_count: usize) -> Result<Vec<u32>, Error> {
        let mut file_index_of = vec_of(0u32, input_triangle_count, "the file index of each triangle")?;
        for (file_index, &t) in self.triangle_ids.iter().enumerate() {
            if let Some(slot) = file_index_of.get_mut(t as usize) {
                *slot = file_index as u32;
            }
        }
        Ok(file_index_of)
    }

    /// Every input triangle's records, in file order (for [`super::pack_wide`] over split references).
    pub fn record_cursor(&self, input_triangle_count: usize) -> Result<RecordCursor, Error> {
        let n = input_triangle_count;
        let mut start = vec_of(0u32, n + 1, "the records of each triangle")?;
        for &t in self.triangle_ids.iter().filter(|&&t| (t as usize) < n) {
            start[t as usize + 1] += 1;
        }
        for t in 0..n {
            start[t + 1] += start[t];
        }
        let mut fill = vec_with_capacity(n + 1, "the records of each triangle")?;
        fill.extend_from_slice(&start);
        let mut records = vec_of(0u32, start[n] as usize, "the records of each triangle")?;
        for (record, &t) in self.triangle_ids.iter().enumerate().filter(|(_, t)| (**t as usize) < n) {
            records[fill[t as usize] as usize] = record as u32;
            fill[t as usize] += 1;
        }
        Ok(RecordCursor { start, records, taken: vec_of(0, n, "the records of each triangle")? })
    }
}

/// For each triangle, its records in the packed triangles, handed out one at a time: what the wide packer
/// needs when split references store a triangle several times (each record in exactly one lane, V34).
#[derive(Clone, Debug)]
pub struct RecordCursor {
    /// Triangle `t`'s records are `records[start[t] as usize..start[t + 1] as usize]`.
    start: Vec<u32>,
    records: Vec<u32>,
    /// How many of each triangle's records were handed out.
    taken: Vec<u32>,
}

impl RecordCursor {
    /// The next record of triangle `t` not handed out yet.
    pub fn next(&mut self, t: u32) -> Option<u32> {
        let t = t as usize;
        let (first, end) = (*self.start.get(t)? as usize, *self.start.get(t + 1)? as usize);
        let taken = self.taken.get_mut(t)?;
        let at = first + *taken as usize;
        if at >= end {
            return None;
        }
        *taken += 1;
        self.records.get(at).copied()
    }
}

/// Packs `tree`, built over `triangles`; [`Error::OutOfMemory`] when the packed arrays do not fit.
pub fn pack(tree: &BuildTree, triangles: &[[[f32; 3]; 3]]) -> Result<PackedTree, Error> {
    let mut packed = PackedTree {
        nodes: vec_with_capacity(tree.nodes.len(), "the packed nodes")?,
        triangles: vec_with_capacity(tree.triangle_order.len(), "the packed triangles")?,
        triangle_ids: vec_with_capacity(tree.triangle_order.len(), "the packed triangle ids")?,
    };
    if tree.nodes.is_empty() {
        return Ok(packed);
    }
    packed.nodes.push(placeholder());
    // (build node, packed slot); left children are popped first.
    let mut stack = vec![(0u32, 0usize)];
    while let Some((build_index, slot)) = stack.pop() {
        match tree.nodes[build_index as usize] {
            BuildNode::Inner { aabb, left, right } => {
                let first_child = packed.nodes.len();
                packed.nodes.push(placeholder());
                packed.nodes.push(placeholder());
                packed.nodes[slot] = PackedNode { min: aabb.min, max: aabb.max, index: first_child as u32, count: 0 };
                stack.push((right, first_child + 1));
                stack.push((left, first_child));
            }
            BuildNode::Leaf { aabb, first, count } => {
                let index = packed.triangles.len() as u32;
                for &t in &tree.triangle_order[first as usize..(first + count) as usize] {
                    packed.triangles.push(PackedTriangle { vertices: triangles[t as usize] });
                    packed.triangle_ids.push(t);
                }
                packed.nodes[slot] = PackedNode { min: aabb.min, max: aabb.max, index, count };
            }
        }
    }
    Ok(packed)
}

fn placeholder() -> PackedNode {
    PackedNode { min: [0.0; 3], max: [0.0; 3], index: 0, count: 0 }
}
