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

use std::borrow::Cow;

use rayon::prelude::*;

use super::presplit::worth_cutting;
use super::{MEDIAN_FALLBACK_DEPTH, build_binned_sah_boxes};
use crate::build_tree::{BuildNode, BuildTree};
use crate::geometry::Aabb;
use crate::geometry::clip::Piece;

/// Bins (object splits) and slabs (spatial splits) an axis.
pub const BINS: usize = 16;
/// The overlap threshold: spatial splits are tried where the object split's children overlap by more than this
/// fraction of the root's surface area. Stich et al. suggest 10^-5; here that tries spatial splits in nearly
/// every node, and 10^-3 gives the same trees' quality at a third of the build time (balanced preset, budget
/// 0.1, wide cost of kitchen / 2CylinderEngine / toy car 10.843 / 26.333 / 9.357 at 10^-5, 10.844 / 26.262 /
/// 9.342 at 10^-3; SBVH build of the 871k-triangle dragon 3.1 s against 1.06 s, binned SAH 0.24 s).
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

/// A piece of triangle `triangle` inside `aabb`.
#[derive(Clone, Copy, Debug)]
struct Reference {
    aabb: Aabb,
    triangle: u32,
}

impl Reference {
    fn centroid(&self, axis: usize) -> f32 {
        0.5 * self.aabb.min[axis] + 0.5 * self.aabb.max[axis]
    }
}

/// Builds an SBVH over `triangles` with one reference a leaf; the tree's `triangle_order` holds each leaf's
/// triangle (a triangle may lie in several leaves, each with its own box), as
/// [`Builder::build_references`](super::Builder::build_references) returns for pre-split references.
pub fn build_sbvh(triangles: &[[[f32; 3]; 3]], params: &SbvhParams) -> BuildTree {
    let references: Vec<Reference> = triangles
        .par_iter()
        .enumerate()
        .map(|(t, v)| Reference { aabb: Aabb::of_triangle(v), triangle: t as u32 })
        .collect();
    if references.is_empty() {
        return BuildTree::default();
    }
    let budget = if params.budget.is_nan() { 0.0 } else { params.budget.clamp(0.0, super::MAX_BUDGET) };
    let root = union_of(&references);
    let alpha = if params.alpha.is_nan() { 0.0 } else { params.alpha.max(0.0) };
    let min_waste_ratio = if params.min_waste_ratio.is_nan() { 0.0 } else { params.min_waste_ratio };
    let splittable = triangles.par_iter().map(|t| worth_cutting(t, min_waste_ratio)).collect();
    let builder = Sbvh { triangles, splittable, min_overlap: alpha * root.surface_area() };
    // At most `2 (n + extra) - 1` nodes, numbered in u32.
    let most_leaves = (u32::MAX as usize).div_ceil(2);
    let extra = ((budget * triangles.len() as f64) as usize).min(most_leaves.saturating_sub(triangles.len()));
    // Every subtree gets the slots its references and budget could fill (see `Slots`); unused ones are squeezed
    // out at the end, which keeps preorder.
    let capacity = references.len() + extra;
    let mut nodes = Vec::with_capacity(2 * capacity - 1);
    nodes.par_extend(rayon::iter::repeat_n(UNUSED, 2 * capacity - 1));
    let mut order = Vec::with_capacity(capacity);
    order.par_extend(rayon::iter::repeat_n(UNUSED_POSITION, capacity));
    let slots = Slots { nodes: &mut nodes, node_at: 0, order: &mut order, order_at: 0 };
    builder.build(references, root, extra, 0, slots);
    squeeze_unused(nodes, order)
}

/// Writes the binned SAH builder's tree over `references` (object splits only, one reference a leaf, built in
/// place in one pair of arrays instead of new vectors at every node) into `slots`, which hold room for it.
fn write_object_split_subtree(references: &[Reference], slots: Slots<'_>) {
    let boxes: Vec<Aabb> = references.iter().map(|r| r.aabb).collect();
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
        *slot = references[i as usize].triangle;
    }
}

/// A node slot no node was written to.
const UNUSED: BuildNode = BuildNode::Leaf { aabb: Aabb::EMPTY, first: 0, count: 0 };
/// A leaf-order slot no reference was written to.
const UNUSED_POSITION: u32 = u32::MAX;

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

/// The tree without the unused slots: nodes and leaf positions renumbered (in place; both arrays are in
/// preorder with gaps, so dropping the gaps keeps preorder).
fn squeeze_unused(mut nodes: Vec<BuildNode>, mut order: Vec<u32>) -> BuildTree {
    let renumbering = |used: &mut dyn Iterator<Item = bool>| {
        let mut next = 0u32;
        used.map(|u| {
            let index = next;
            next += u32::from(u);
            index
        })
        .collect::<Vec<u32>>()
    };
    let new_position = renumbering(&mut order.iter().map(|&t| t != UNUSED_POSITION));
    order.retain(|&t| t != UNUSED_POSITION);
    let is_used = |node: &BuildNode| !matches!(node, BuildNode::Leaf { count: 0, .. });
    let new_index = renumbering(&mut nodes.iter().map(is_used));
    let mut kept = 0;
    for i in 0..nodes.len() {
        let node = match nodes[i] {
            BuildNode::Inner { aabb, left, right } => {
                BuildNode::Inner { aabb, left: new_index[left as usize], right: new_index[right as usize] }
            }
            BuildNode::Leaf { aabb, first, count } if count > 0 => {
                BuildNode::Leaf { aabb, first: new_position[first as usize], count }
            }
            BuildNode::Leaf { .. } => continue,
        };
        nodes[kept] = node;
        kept += 1;
    }
    nodes.truncate(kept);
    BuildTree { nodes, triangle_order: order }
}

struct Sbvh<'a> {
    triangles: &'a [[[f32; 3]; 3]],
    /// Per triangle: whether its references may be cut (`min_waste_ratio`).
    splittable: Vec<bool>,
    /// `alpha` times the root's surface area.
    min_overlap: f64,
}

/// The two sides of a split, and the references it added.
struct Split {
    left: Vec<Reference>,
    right: Vec<Reference>,
    /// The union of each side's boxes.
    boxes: [Aabb; 2],
    added: usize,
}

impl Sbvh<'_> {
    /// Writes the subtree over `references` (box `aabb`, at most `extra` more references) into `slots`.
    fn build(&self, references: Vec<Reference>, aabb: Aabb, extra: usize, depth: usize, slots: Slots<'_>) {
        if let [only] = references[..] {
            slots.nodes[0] = BuildNode::Leaf { aabb: only.aabb, first: slots.order_at, count: 1 };
            slots.order[0] = only.triangle;
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
            .then(|| self.best_spatial_split(&references, aabb))
            .flatten()
            .filter(|plane| plane.cost < object.cost)
            .and_then(|plane| self.spatial_partition(&references, &plane, extra));
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
        if !self.splittable[reference.triangle as usize] {
            return None;
        }
        Piece::within(&self.triangles[reference.triangle as usize], &reference.aabb)
    }

    /// The spatial plane of lowest binned cost on any axis (every reference that crosses it counted on both
    /// sides).
    fn best_spatial_split(&self, references: &[Reference], aabb: &Aabb) -> Option<SpatialPlane> {
        let slabs: [Option<Slabs>; 3] = std::array::from_fn(|axis| Slabs::new(aabb, axis));
        let mut bins = [[(Aabb::EMPTY, 0u32, 0u32); BINS]; 3];
        for reference in references {
            // Most references lie in one slab an axis; only those that cross a plane are clipped (once, for all
            // the axes on which they cross one).
            let mut piece = None;
            for (axis, slabs) in slabs.iter().enumerate() {
                let Some(slabs) = slabs else { continue };
                let mut add = |bin: usize, aabb: Aabb, enters: bool, exits: bool| {
                    let b = &mut bins[axis][bin];
                    b.0 = b.0.union(&aabb);
                    b.1 += u32::from(enters);
                    b.2 += u32::from(exits);
                };
                let first = slabs.slab_from(reference.aabb.min[axis]);
                if first >= slabs.slab_to(reference.aabb.max[axis]) {
                    add(first, reference.aabb, true, true);
                } else {
                    let piece = piece.get_or_insert_with(|| self.piece(reference));
                    chop(reference, piece.as_ref(), slabs, &mut add);
                }
            }
        }
        let mut best: Option<SpatialPlane> = None;
        for (axis, (slabs, bins)) in slabs.iter().zip(&bins).enumerate() {
            let Some(slabs) = slabs else { continue };
            let mut right_areas = [0.0f64; BINS];
            let mut right = Aabb::EMPTY;
            for k in (1..BINS).rev() {
                right = right.union(&bins[k].0);
                right_areas[k] = right.surface_area();
            }
            let (mut left, mut n_left) = (Aabb::EMPTY, 0usize);
            let mut n_right: usize = bins.iter().map(|b| b.2 as usize).sum();
            for k in 1..BINS {
                left = left.union(&bins[k - 1].0);
                n_left += bins[k - 1].1 as usize;
                n_right -= bins[k - 1].2 as usize;
                if n_left == 0 || n_right == 0 {
                    continue;
                }
                let cost = left.surface_area() * n_left as f64 + right_areas[k] * n_right as f64;
                if best.as_ref().is_none_or(|b| cost < b.cost) {
                    best = Some(SpatialPlane { axis, position: slabs.planes[k - 1], cost });
                }
            }
        }
        best
    }

    /// Sends each reference to the side of `plane` it lies on. One that crosses it is cut in two, or kept whole
    /// on one side where the paper's unsplitting test finds that cheaper; at most `extra` are cut, the largest
    /// first, and the rest go whole to their cheaper side. Returns the split and its cost (`A_left n_left +
    /// A_right n_right` of the sides as they are), `None` when a side ends up empty.
    fn spatial_partition(&self, references: &[Reference], plane: &SpatialPlane, extra: usize) -> Option<(Split, f64)> {
        let (axis, position) = (plane.axis, plane.position);
        let (mut left, mut right) = (Vec::new(), Vec::new());
        let mut crossing = Vec::new();
        for r in references {
            if r.aabb.max[axis] <= position {
                left.push(*r);
            } else if r.aabb.min[axis] >= position {
                right.push(*r);
            } else {
                crossing.push(*r);
            }
        }
        let (mut left_box, mut right_box) = (union_of(&left), union_of(&right));
        let mut cut: Vec<(Reference, Piece, Piece)> = Vec::new();
        for r in crossing {
            match self.piece(&r).map(|p| p.cut(axis, position)) {
                Some((below, above)) if below.corners.len() >= 3 && above.corners.len() >= 3 => {
                    left_box = left_box.union(&below.aabb);
                    right_box = right_box.union(&above.aabb);
                    cut.push((r, below, above));
                }
                // No area on one side (or not to be cut): the reference goes whole to the side of its centre.
                _ => {
                    if r.centroid(axis) < position {
                        left_box = left_box.union(&r.aabb);
                        left.push(r);
                    } else {
                        right_box = right_box.union(&r.aabb);
                        right.push(r);
                    }
                }
            }
        }
        // The largest references first (a node holds one reference of a triangle at most, so the order is
        // total), since cutting them removes the most area.
        cut.sort_unstable_by(|(a, ..), (b, ..)| {
            b.aabb.surface_area().total_cmp(&a.aabb.surface_area()).then(a.triangle.cmp(&b.triangle))
        });
        // Unsplitting (Stich et al., section 4.3): with the sides as they stand, cutting costs
        // A_l n_l + A_r n_r against the whole reference on one side (one fewer on the other).
        let mut added = 0;
        let (n_left, n_right) = (left.len() + cut.len(), right.len() + cut.len());
        let (mut n_left, mut n_right) = (n_left as f64, n_right as f64);
        for (r, below, above) in cut {
            let (a_left, a_right) = (left_box.surface_area(), right_box.surface_area());
            let split_cost = if added < extra { a_left * n_left + a_right * n_right } else { f64::INFINITY };
            let whole_left = left_box.union(&r.aabb).surface_area() * n_left + a_right * (n_right - 1.0);
            let whole_right = a_left * (n_left - 1.0) + right_box.union(&r.aabb).surface_area() * n_right;
            if whole_left <= split_cost && whole_left <= whole_right {
                left_box = left_box.union(&r.aabb);
                n_right -= 1.0;
                left.push(r);
            } else if whole_right <= split_cost {
                right_box = right_box.union(&r.aabb);
                n_left -= 1.0;
                right.push(r);
            } else {
                left.push(Reference { aabb: below.aabb, triangle: r.triangle });
                right.push(Reference { aabb: above.aabb, triangle: r.triangle });
                added += 1;
            }
        }
        if left.is_empty() || right.is_empty() {
            return None;
        }
        let boxes = [union_of(&left), union_of(&right)];
        let cost = boxes[0].surface_area() * left.len() as f64 + boxes[1].surface_area() * right.len() as f64;
        Some((Split { left, right, boxes, added }, cost))
    }
}

/// The slab planes of a node's box along one axis: `BINS - 1` increasing f32 positions strictly inside it.
struct Slabs {
    axis: usize,
    planes: [f32; BINS - 1],
}

impl Slabs {
    /// `None` where the box is too thin along `axis` for distinct planes strictly inside it.
    fn new(aabb: &Aabb, axis: usize) -> Option<Slabs> {
        let (low, high) = (f64::from(aabb.min[axis]), f64::from(aabb.max[axis]));
        let planes: [f32; BINS - 1] =
            std::array::from_fn(|k| (low + (high - low) * (k + 1) as f64 / BINS as f64) as f32);
        let inside = planes.iter().all(|&p| aabb.min[axis] < p && p < aabb.max[axis]);
        let increasing = planes.windows(2).all(|w| w[0] < w[1]);
        (inside && increasing).then_some(Slabs { axis, planes })
    }

    /// The slab holding coordinate `x` at its low end: planes at or below `x`.
    fn slab_from(&self, x: f32) -> usize {
        self.planes.partition_point(|&p| p <= x)
    }

    /// The slab holding coordinate `x` at its high end: planes below `x`.
    fn slab_to(&self, x: f32) -> usize {
        self.planes.partition_point(|&p| p < x)
    }
}

/// Hands `emit(slab, box, enters, exits)` the box of each slab's part of `reference` (its `piece`, cut exactly
/// at the planes it crosses; a reference without a piece goes whole to the slab of its centre). `enters` is
/// true in the reference's first slab and `exits` in its last.
fn chop(reference: &Reference, piece: Option<&Piece>, slabs: &Slabs, emit: &mut impl FnMut(usize, Aabb, bool, bool)) {
    let axis = slabs.axis;
    let Some(piece) = piece else {
        let slab = slabs.slab_from(reference.centroid(axis));
        emit(slab, reference.aabb, true, true);
        return;
    };
    let (first, last) = (slabs.slab_from(piece.aabb.min[axis]), slabs.slab_to(piece.aabb.max[axis]));
    if first >= last {
        emit(first, piece.aabb, true, true);
        return;
    }
    let mut rest = Cow::Borrowed(piece);
    let (mut slab, mut entered) = (first, false);
    for k in first..last {
        let plane = slabs.planes[k];
        if !(rest.aabb.min[axis] < plane && plane < rest.aabb.max[axis]) {
            break;
        }
        let (below, above) = rest.cut(axis, plane);
        if above.corners.len() < 3 {
            rest = Cow::Owned(below);
            break;
        }
        if below.corners.len() >= 3 {
            emit(slab, below.aabb, !entered, false);
            entered = true;
        }
        rest = Cow::Owned(above);
        slab = k + 1;
    }
    emit(slab, rest.aabb, !entered, true);
}

/// A spatial split: references left of `position` along `axis` go left, those right of it right.
struct SpatialPlane {
    axis: usize,
    position: f32,
    cost: f64,
}

/// An object split: references whose centroid lies in a bin below `bin` go left.
#[derive(Clone, Copy)]
struct ObjectSplit {
    axis: usize,
    low: f32,
    scale: f32,
    /// The number of bins used.
    bins: usize,
    bin: usize,
    /// References that go left.
    left_count: usize,
    /// The union of the boxes of the references that go left, then right (from the bins, exact).
    boxes: [Aabb; 2],
    cost: f64,
    /// Surface area of the intersection of the two children's boxes.
    overlap: f64,
}

impl ObjectSplit {
    fn bin_of(&self, c: f32) -> usize {
        (((c - self.low) * self.scale) as usize).min(self.bins - 1)
    }

    fn goes_left(&self, r: &Reference) -> bool {
        self.bin_of(r.centroid(self.axis)) < self.bin
    }
}

/// The binned SAH object split of lowest `A_left n_left + A_right n_right`; `None` where no axis has spread
/// centroids. Nodes of at most 2, 4 or 8 references use that many bins (as the binned builder does): most nodes
/// are small, and sweeping 16 bins on three axes for two references made the SBVH build twice as slow.
fn best_object_split(references: &[Reference]) -> Option<ObjectSplit> {
    match references.len() {
        0..=2 => best_object_split_in::<2>(references),
        3..=4 => best_object_split_in::<4>(references),
        5..=8 => best_object_split_in::<8>(references),
        _ => best_object_split_in::<BINS>(references),
    }
}

/// [`best_object_split`] with `B` bins an axis.
fn best_object_split_in<const B: usize>(references: &[Reference]) -> Option<ObjectSplit> {
    let centroids = references.iter().fold(Aabb::EMPTY, |b, r| b.grow(&std::array::from_fn(|a| r.centroid(a))));
    let splits: [Option<ObjectSplit>; 3] = std::array::from_fn(|axis| {
        let (low, high) = (centroids.min[axis], centroids.max[axis]);
        let scale = B as f32 / (high - low);
        (high > low && scale.is_finite()).then_some(ObjectSplit {
            axis,
            low,
            scale,
            bins: B,
            bin: 0,
            left_count: 0,
            boxes: [Aabb::EMPTY; 2],
            cost: f64::INFINITY,
            overlap: 0.0,
        })
    });
    // One pass bins all three axes.
    let mut bins = [[(Aabb::EMPTY, 0usize); B]; 3];
    for r in references {
        for (axis, split) in splits.iter().enumerate() {
            if let Some(split) = split {
                let b = &mut bins[axis][split.bin_of(r.centroid(axis))];
                b.0 = b.0.union(&r.aabb);
                b.1 += 1;
            }
        }
    }
    let mut best: Option<ObjectSplit> = None;
    for (mut split, bins) in splits.into_iter().zip(&bins).filter_map(|(s, b)| s.map(|s| (s, b))) {
        let mut right_boxes = [Aabb::EMPTY; B];
        let mut right = Aabb::EMPTY;
        for k in (1..B).rev() {
            right = right.union(&bins[k].0);
            right_boxes[k] = right;
        }
        let (mut left, mut n_left) = (Aabb::EMPTY, 0);
        for k in 1..B {
            left = left.union(&bins[k - 1].0);
            n_left += bins[k - 1].1;
            let n_right = references.len() - n_left;
            if n_left == 0 || n_right == 0 {
                continue;
            }
            let cost = left.surface_area() * n_left as f64 + right_boxes[k].surface_area() * n_right as f64;
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                (split.bin, split.left_count, split.cost, split.boxes) = (k, n_left, cost, [left, right_boxes[k]]);
                best = Some(split);
            }
        }
    }
    best.map(|mut split| {
        split.overlap = intersection(&split.boxes[0], &split.boxes[1]).surface_area();
        split
    })
}

/// The intersection of two boxes (empty, with zero area, when they are apart).
fn intersection(a: &Aabb, b: &Aabb) -> Aabb {
    Aabb { min: std::array::from_fn(|i| a.min[i].max(b.min[i])), max: std::array::from_fn(|i| a.max[i].min(b.max[i])) }
}

/// Splits at the median reference by centroid along the longest axis of the node's centroids (ties by
/// triangle: a node holds at most one reference of a triangle, so the order is total and the split
/// deterministic).
fn median_split(mut references: Vec<Reference>) -> Split {
    let centroids = references.iter().fold(Aabb::EMPTY, |b, r| b.grow(&std::array::from_fn(|a| r.centroid(a))));
    let axis = centroids.longest_axis();
    let mid = references.len() / 2;
    references.select_nth_unstable_by(mid, |a, b| {
        a.centroid(axis).total_cmp(&b.centroid(axis)).then(a.triangle.cmp(&b.triangle))
    });
    let right = references.split_off(mid);
    Split { boxes: [union_of(&references), union_of(&right)], left: references, right, added: 0 }
}

fn union_of(references: &[Reference]) -> Aabb {
    references.iter().fold(Aabb::EMPTY, |b, r| b.union(&r.aabb))
}
