//! A [`WideTree`] collapsed for the GPU (width 8, leaves of at most 3 triangles) in the GPU layout of format 1.4
//! (`format-spec/bvh-1.md` 5.14-5.15): compressed nodes ([`GpuNode`]) breadth first, each node's leaf
//! triangles ([`GpuTriangle`]) in slot order after those of the nodes before it.
//!
//! Children go to slots by ray octant, after Ylitie, Karras, Laine (HPG 2017, section 4): slot `s` takes the
//! child that rays of octant `s` (bit 4: x negative, 2: y, 1: z) should meet first, the one whose centroid lies
//! farthest along `-direction`; pairs are assigned greedily, best score first. The boxes are quantized
//! bottom-up ([`super::quantize`]) so that every inner slot encloses its child node's **content** (the union of
//! its slots' contents: a leaf's triangles' bounds, clipped to the leaf's decoded box with split references),
//! which is what rule V48 checks.

use bvhc_loader::format::{
    GPU_MAX_DEPTH, GPU_MAX_LEAF_TRIANGLES, GPU_MAX_NODE_TRIANGLES, GPU_WIDE, GpuNode, GpuTriangle, PackedTriangle,
    inner_meta, leaf_meta,
};
use bvhc_loader::{Error, GpuSections};

use crate::geometry::Aabb;
use crate::layout::{WideChild, WideTree};

/// The packed GPU sections.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GpuLayout {
    /// The `gpu_nodes` section.
    pub nodes: Vec<GpuNode>,
    /// The `gpu_triangles` section.
    pub triangles: Vec<GpuTriangle>,
}

impl GpuLayout {
    /// The two sections as a view's.
    pub fn sections(&self) -> GpuSections<'_> {
        GpuSections { nodes: &self.nodes, triangles: &self.triangles }
    }
}

/// Lays `tree` (width at most 8, leaves of at most 3 distinct triangles) out over `file_triangles`:
/// `record_of(t)` is the record in `file_triangles` of the tree's triangle `t` (any of its records with split
/// references). A leaf that holds a triangle twice (two pieces of a split triangle) keeps it once.
///
/// Fails with [`Error::Unwritable`] when the tree does not fit the layout: too wide, a leaf of more than 3
/// triangles, deeper than [`GPU_MAX_DEPTH`], or coordinates too large for a finite grid.
pub fn pack_gpu(
    tree: &WideTree,
    file_triangles: &[PackedTriangle],
    record_of: &dyn Fn(u32) -> Option<u32>,
    split_references: bool,
) -> Result<GpuLayout, Error> {
    let unwritable = |why: String| Error::Unwritable(format!("GPU sections: {why}"));
    if tree.nodes.is_empty() {
        return Ok(GpuLayout::default());
    }
    // Per wide node: its children in slot order (None for an empty slot), each leaf's records deduplicated.
    let mut slots: Vec<[Option<(Aabb, Slot)>; GPU_WIDE]> = Vec::with_capacity(tree.nodes.len());
    for (i, node) in tree.nodes.iter().enumerate() {
        if node.children.len() > GPU_WIDE {
            return Err(unwritable(format!("node {i} has {} children", node.children.len())));
        }
        let mut children = Vec::with_capacity(node.children.len());
        for &(aabb, child) in &node.children {
            let slot = match child {
                WideChild::Node(c) => Slot::Inner(c),
                WideChild::Leaf { first, count } => {
                    let mut records = Vec::with_capacity(count as usize);
                    for &t in tree.triangle_order.get(first as usize..(first + count) as usize).unwrap_or(&[]) {
                        let record = record_of(t)
                            .filter(|&r| (r as usize) < file_triangles.len())
                            .ok_or_else(|| unwritable(format!("node {i}: triangle {t} is not in the file")))?;
                        if !records.contains(&record) {
                            records.push(record);
                        }
                    }
                    if records.is_empty() || records.len() > GPU_MAX_LEAF_TRIANGLES {
                        return Err(unwritable(format!("node {i}: a leaf of {} triangles", records.len())));
                    }
                    Slot::Leaf(records)
                }
            };
            children.push((aabb, slot));
        }
        slots.push(assign_octant_slots(children));
    }
    let order = breadth_first(&slots).ok_or_else(|| {
        unwritable(format!("the tree is more than {GPU_MAX_DEPTH} levels deep; convert without --gpu-layout"))
    })?;
    // Bottom-up: each node's content box and its quantized slots.
    let mut content = vec![Aabb::EMPTY; tree.nodes.len()];
    let mut packed = vec![None; tree.nodes.len()];
    for &i in order.iter().rev() {
        let node_slots = &slots[i as usize];
        let targets: Vec<Aabb> = node_slots
            .iter()
            .map(|slot| match slot {
                None => Aabb::EMPTY,
                Some((_, Slot::Inner(c))) => content[*c as usize],
                Some((aabb, Slot::Leaf(_))) if split_references => *aabb,
                Some((_, Slot::Leaf(records))) => triangles_box(file_triangles, records),
            })
            .collect();
        let mut node = GpuNode::EMPTY;
        let boxes = std::array::from_fn(|s| node_slots[s].as_ref().map(|_| (targets[s].min, targets[s].max)));
        if !node.encode_slot_boxes(&boxes) {
            return Err(unwritable(format!("node {i}: coordinates too large for a finite grid (near f32::MAX)")));
        }
        let mut box_of_node = Aabb::EMPTY;
        for slot in (0..GPU_WIDE).filter(|&s| node_slots[s].is_some()) {
            let slot_content = match &node_slots[slot] {
                Some((_, Slot::Leaf(records))) if split_references => {
                    let (min, max) = node.slot_box(slot);
                    clipped_triangles_box(file_triangles, records, &Aabb { min, max })
                }
                _ => targets[slot],
            };
            box_of_node = box_of_node.union(&slot_content);
        }
        content[i as usize] = box_of_node;
        packed[i as usize] = Some(node);
    }
    // Breadth first: child and triangle bases, meta bytes, the triangles.
    let mut layout = GpuLayout { nodes: Vec::with_capacity(order.len()), triangles: Vec::new() };
    let (mut next_child, mut next_triangle) = (1u32, 0u32);
    for &i in &order {
        let mut node = packed[i as usize].take().ok_or_else(|| unwritable(format!("node {i} reached twice")))?;
        node.child_base = next_child;
        node.triangle_base = next_triangle;
        let mut offset = 0;
        for (slot, content) in slots[i as usize].iter().enumerate() {
            match content {
                None => {}
                Some((_, Slot::Inner(_))) => {
                    node.inner_mask |= 1 << slot;
                    node.meta[slot] = inner_meta(slot);
                    next_child += 1;
                }
                Some((_, Slot::Leaf(records))) => {
                    node.meta[slot] = leaf_meta(offset, records.len());
                    offset += records.len();
                    for &record in records {
                        let vertices = file_triangles[record as usize].vertices;
                        layout.triangles.push(GpuTriangle { vertices, triangle_index: record });
                    }
                }
            }
        }
        debug_assert!(offset <= GPU_MAX_NODE_TRIANGLES, "8 leaves of at most 3");
        next_triangle += offset as u32;
        layout.nodes.push(node);
    }
    Ok(layout)
}

/// A child of a wide node on its way to a GPU slot.
#[derive(Clone, Debug, PartialEq)]
enum Slot {
    /// A wide node, by index in the tree.
    Inner(u32),
    /// A leaf's records in the file's triangles section.
    Leaf(Vec<u32>),
}

/// The wide nodes breadth first from node 0, children in slot order: the order of the `gpu_nodes` section.
/// `None` when a node is deeper than [`GPU_MAX_DEPTH`].
fn breadth_first(slots: &[[Option<(Aabb, Slot)>; GPU_WIDE]]) -> Option<Vec<u32>> {
    let mut order = vec![0u32];
    let mut depth = vec![0usize];
    let mut at = 0;
    while at < order.len() {
        for (_, child) in slots[order[at] as usize].iter().flatten() {
            if let Slot::Inner(c) = child {
                if depth[at] + 1 > GPU_MAX_DEPTH {
                    return None;
                }
                order.push(*c);
                depth.push(depth[at] + 1);
            }
        }
        at += 1;
    }
    Some(order)
}

/// Places up to 8 children in the slots by octant: slot `s`'s score for a child is the child centroid's offset
/// from the node's centroid along the axes, counted positive where `s` has the axis's bit (rays going negative
/// meet the high side first) and negative elsewhere; the best remaining (child, slot) pair is taken first, ties
/// to the earlier child and slot, so the assignment is deterministic.
fn assign_octant_slots<T: Clone>(children: Vec<(Aabb, T)>) -> [Option<(Aabb, T)>; GPU_WIDE] {
    let whole = children.iter().fold(Aabb::EMPTY, |b, (c, _)| b.union(c));
    let center = |b: &Aabb| -> [f64; 3] { std::array::from_fn(|a| (f64::from(b.min[a]) + f64::from(b.max[a])) / 2.0) };
    let middle = center(&whole);
    let score = |child: usize, slot: usize| -> f64 {
        let c = center(&children[child].0);
        (0..3)
            .map(|a| {
                let bit = 4 >> a;
                let sign = if slot & bit != 0 { 1.0 } else { -1.0 };
                sign * (c[a] - middle[a])
            })
            .sum()
    };
    let mut result: [Option<(Aabb, T)>; GPU_WIDE] = Default::default();
    let mut child_taken = vec![false; children.len()];
    for _ in 0..children.len() {
        let mut best: Option<(f64, usize, usize)> = None;
        for child in (0..children.len()).filter(|&c| !child_taken[c]) {
            for slot in (0..GPU_WIDE).filter(|&s| result[s].is_none()) {
                let s = score(child, slot);
                if best.is_none_or(|(b, _, _)| s > b) {
                    best = Some((s, child, slot));
                }
            }
        }
        let Some((_, child, slot)) = best else { break };
        child_taken[child] = true;
        result[slot] = Some(children[child].clone());
    }
    result
}

/// The bounds of the records' vertices.
fn triangles_box(triangles: &[PackedTriangle], records: &[u32]) -> Aabb {
    records.iter().fold(Aabb::EMPTY, |b, &r| b.union(&Aabb::of_triangle(&triangles[r as usize].vertices)))
}

/// The union over the records of their bounds clipped to `clip` (empty where they do not overlap).
fn clipped_triangles_box(triangles: &[PackedTriangle], records: &[u32], clip: &Aabb) -> Aabb {
    records
        .iter()
        .fold(Aabb::EMPTY, |b, &r| b.union(&Aabb::of_triangle(&triangles[r as usize].vertices).clipped_to(clip)))
}
