//! Spatial splits during the top-down build: the SBVH of M. Stich, H. Friedrich and A. Dietrich, "Spatial
//! Splits in Bounding Volume Hierarchies", High Performance Graphics 2009 (the method, not any code).
//!
//! Each node weighs the best binned *object* split (centroids of its references' boxes, [`BINS`] bins an axis)
//! against the best *spatial* split: [`BINS`] equal slabs of the node's box an axis, each reference's piece
//! of its triangle chopped exactly at the slab planes it crosses (see [`clip`](crate::geometry::clip)), a plane's cost
//! `A_left n_left + A_right n_right` with the references that cross it counted on both sides. Spatial splits are
//! tried only where the object split's children overlap by more than `alpha` times the root's surface area
//! (the paper's overlap threshold), and a crossing reference is kept whole on one side where that is cheaper
//! than cutting it (the paper's reference unsplitting).
//!
//! A reference budget bounds the tree: the root may add `budget * n` references, and every node hands what its
//! own split did not spend to its children in proportion to their reference counts (floored), so the whole
//! tree stays within `(1 + budget) n` references and the choice at a node never depends on the order in which
//! other subtrees are built. The build recurses down to one reference a leaf, as the optimizer takes it; a leaf
//! box is its reference's box, which contains the reference's piece, and a triangle's references' boxes
//! together cover it (each cut hands both sides a box containing its part), which is the format's rule V25.
//!
//! Deterministic: boxes are unions and counts sums, exact in any order, and subtrees built in parallel are laid
//! out in preorder exactly as a sequential build lays them out.

mod object;
mod sides;
mod spatial;

use rayon::prelude::*;

use super::presplit::worth_cutting;
use super::reference::{Reference, UNUSED_NODE, UNUSED_POSITION, squeeze_unused, union_of};
use super::{MEDIAN_FALLBACK_DEPTH, build_binned_sah_boxes};
use crate::build_tree::{BuildNode, BuildTree};
use crate::geometry::Aabb;
use crate::geometry::clip::Piece;
use object::{best_object_split, median_split};
pub use sides::BINS;
use sides::Split;
use spatial::{best_spatial_split, spatial_partition};

/// The overlap threshold: spatial splits are tried where the object split's children overlap by more than this
/// fraction of the root's surface area. Stich et al. suggest 10^-5; 10^-3 gives trees of the same cost at a third
/// of the build time (`docs/choices.md`).
pub const DEFAULT_ALPHA: f64 = 1e-3;
/// Subtrees with more references than this are built in parallel.
const PARALLEL_THRESHOLD: usize = 4096;

/// How the SBVH may split.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SbvhParams {
    /// At most `budget * n` references beyond one a triangle (clamped to 0 ..= [`super::MAX_BUDGET`]).
    pub budget: f64,
    /// Overlap threshold, relative to the root's surface area.
    pub alpha: f64,
    /// Only triangles whose pieces could remove at least this fraction of their box's area are cut.
    pub min_waste_ratio: f64,
}

impl SbvhParams {
    /// `budget` with the default thresholds.
    pub fn with_budget(budget: f64) -> SbvhParams {
        SbvhParams { budget, alpha: DEFAULT_ALPHA, min_waste_ratio: super::WASTEFUL_RATIO_SBVH }
    }
}

/// Builds an SBVH over `triangles` with one reference a leaf; the tree's `triangle_order` holds each leaf's
/// triangle (a triangle may lie in several leaves, each with its own box), as
/// [`Builder::build_references`](super::Builder::build_references) returns for pre-split references.
pub fn build_sbvh(triangles: &[[[f32; 3]; 3]], params: &SbvhParams) -> BuildTree {
    build_sbvh_keeping(triangles, params, &[])
}

/// [`build_sbvh`] leaving whole every triangle `t` with `whole[t]` (geometry meant to deform; a shorter `whole`
/// leaves the rest free to be cut).
pub fn build_sbvh_keeping(triangles: &[[[f32; 3]; 3]], params: &SbvhParams, whole: &[bool]) -> BuildTree {
    let references: Vec<Reference> =
        triangles.par_iter().enumerate().map(|(t, v)| Reference::new(&Aabb::of_triangle(v), t as u32)).collect();
    if references.is_empty() {
        return BuildTree::default();
    }
    let budget = if params.budget.is_nan() { 0.0 } else { params.budget.clamp(0.0, super::MAX_BUDGET) };
    let root = union_of(&references, |r| r.bounds).to_aabb();
    let alpha = if params.alpha.is_nan() { 0.0 } else { params.alpha.max(0.0) };
    let min_waste_ratio = if params.min_waste_ratio.is_nan() { 0.0 } else { params.min_waste_ratio };
    let splittable = triangles
        .par_iter()
        .enumerate()
        .map(|(t, v)| whole.get(t) != Some(&true) && worth_cutting(v, min_waste_ratio))
        .collect();
    let builder = Sbvh { triangles, splittable, min_overlap: alpha * root.surface_area() };
    // At most `2 (n + extra) - 1` nodes, numbered in u32.
    let most_leaves = (u32::MAX as usize).div_ceil(2);
    let extra = ((budget * triangles.len() as f64) as usize).min(most_leaves.saturating_sub(triangles.len()));
    // Every subtree gets the slots its references and budget could fill (see `Slots`); unused ones are squeezed
    // out at the end, which keeps preorder.
    let capacity = references.len() + extra;
    let mut nodes = Vec::with_capacity(2 * capacity - 1);
    nodes.par_extend(rayon::iter::repeat_n(UNUSED_NODE, 2 * capacity - 1));
    let mut order = Vec::with_capacity(capacity);
    order.par_extend(rayon::iter::repeat_n(UNUSED_POSITION, capacity));
    let slots = Slots { nodes: &mut nodes, node_at: 0, order: &mut order, order_at: 0 };
    builder.build(references, root, extra, 0, slots);
    squeeze_unused(nodes, order)
}

/// Writes the binned SAH builder's tree over `references` (object splits only, one reference a leaf, built in
/// place in one pair of arrays instead of new vectors at every node) into `slots`, which hold room for it.
fn write_object_split_subtree(references: &[Reference], slots: Slots<'_>) {
    let boxes: Vec<Aabb> = references.iter().map(Reference::aabb).collect();
    let subtree = build_binned_sah_boxes(&boxes, 1);
    for (slot, node) in slots.nodes.iter_mut().zip(&subtree.nodes) {
        *slot = match *node {
            BuildNode::Inner { aabb, left, right } => {
                BuildNode::Inner { aabb, left: slots.node_at + left, right: slots.node_at + right }
            }
            BuildNode::Leaf { aabb, first, count } => BuildNode::Leaf { aabb, first: slots.order_at + first, count },
        };
    }
    for (slot, &i) in slots.order.iter_mut().zip(&subtree.triangle_order) {
        *slot = references[i as usize].triangle();
    }
}

/// Where a subtree over `m` references with a budget of `e` is written: `2 (m + e) - 1` node slots and `m + e`
/// leaf-order slots, as many as it can fill (`m + e` leaves at most). A node takes its first slot and hands its
/// children `2 (m_l + e_l) - 1` and `2 (m_r + e_r) - 1`, which add up: `m_l + m_r = m + added` and `e_l + e_r
/// = e - added`. `node_at` and `order_at` are the first slots' positions in the whole arrays.
struct Slots<'s> {
    nodes: &'s mut [BuildNode],
    node_at: u32,
    order: &'s mut [u32],
    order_at: u32,
}

impl<'s> Slots<'s> {
    /// This node's slot, then the slots of a left child that may have `left_leaves` leaves, then the rest.
    fn split(self, left_leaves: usize) -> (&'s mut BuildNode, Slots<'s>, Slots<'s>) {
        let (node, rest) = self.nodes.split_first_mut().expect("a node has a slot");
        let (left_nodes, right_nodes) = rest.split_at_mut(2 * left_leaves - 1);
        let (left_order, right_order) = self.order.split_at_mut(left_leaves);
        let left = Slots { nodes: left_nodes, node_at: self.node_at + 1, order: left_order, order_at: self.order_at };
        let right = Slots {
            nodes: right_nodes,
            node_at: self.node_at + 2 * left_leaves as u32,
            order: right_order,
            order_at: self.order_at + left_leaves as u32,
        };
        (node, left, right)
    }
}

struct Sbvh<'a> {
    triangles: &'a [[[f32; 3]; 3]],
    /// Per triangle: whether its references may be cut (`min_waste_ratio`).
    splittable: Vec<bool>,
    /// `alpha` times the root's surface area.
    min_overlap: f64,
}

impl Sbvh<'_> {
    /// Writes the subtree over `references` (box `aabb`, at most `extra` more references) into `slots`.
    fn build(&self, references: Vec<Reference>, aabb: Aabb, extra: usize, depth: usize, slots: Slots<'_>) {
        if let [only] = references[..] {
            slots.nodes[0] = BuildNode::Leaf { aabb: only.aabb(), first: slots.order_at, count: 1 };
            slots.order[0] = only.triangle();
            return;
        }
        // No spatial split can happen in this subtree: without budget, or where the node's whole box is not
        // larger than the overlap that makes one worth trying (the children's overlap lies inside it).
        if extra == 0 || aabb.surface_area() <= self.min_overlap {
            return write_object_split_subtree(&references, slots);
        }
        let count = references.len();
        let Split { left, right, boxes: [left_box, right_box], added } = self.split(references, &aabb, extra, depth);
        let rest = extra - added;
        let left_extra = (rest as u128 * left.len() as u128 / (left.len() + right.len()) as u128) as usize;
        let right_extra = rest - left_extra;
        let (node, left_slots, right_slots) = slots.split(left.len() + left_extra);
        *node = BuildNode::Inner { aabb, left: left_slots.node_at, right: right_slots.node_at };
        let depth = depth + 1;
        if count > PARALLEL_THRESHOLD {
            rayon::join(
                || self.build(left, left_box, left_extra, depth, left_slots),
                || self.build(right, right_box, right_extra, depth, right_slots),
            );
        } else {
            self.build(left, left_box, left_extra, depth, left_slots);
            self.build(right, right_box, right_extra, depth, right_slots);
        }
    }

    /// The cheaper of the best object split and (where its children overlap enough and the budget allows) the
    /// best spatial split; the median reference where no centroids spread or the node is too deep.
    fn split(&self, references: Vec<Reference>, aabb: &Aabb, extra: usize, depth: usize) -> Split {
        if depth >= MEDIAN_FALLBACK_DEPTH {
            return median_split(references);
        }
        let Some(object) = best_object_split(&references) else { return median_split(references) };
        let spatial = (extra > 0 && object.overlap > self.min_overlap)
            .then(|| best_spatial_split(&references, aabb, &|r| self.piece(r)))
            .flatten()
            .filter(|plane| plane.cost < object.cost)
            .and_then(|plane| spatial_partition(&references, &plane, extra, &|r| self.piece(r)));
        // The binned estimate assumed every crossing reference cut; the split as made must still win.
        if let Some((split, cost)) = spatial
            && cost < object.cost
        {
            return split;
        }
        let mut left = Vec::with_capacity(object.left_count);
        let mut right = Vec::with_capacity(references.len() - object.left_count);
        for r in references {
            if object.goes_left(&r) { left.push(r) } else { right.push(r) }
        }
        Split { left, right, boxes: object.boxes, added: 0 }
    }

    /// The piece of `reference`'s triangle inside its box; `None` (the reference then stays whole) where its
    /// triangle is not to be cut or clipping leaves no area.
    fn piece(&self, reference: &Reference) -> Option<Piece> {
        let triangle = reference.triangle() as usize;
        if !self.splittable[triangle] {
            return None;
        }
        Piece::within(&self.triangles[triangle], &reference.aabb())
    }
}
