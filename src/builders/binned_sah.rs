//! Initial BVH construction: a binned SAH builder (I. Wald, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies", IEEE RT 2007).
//!
//! Centroids are binned into up to [`BIN_COUNT`] bins along each axis (2, 4 or 8 for nodes of at most that many
//! triangles); the split plane with the lowest SAH cost `c_T + c_I (A_left n_left + A_right n_right) /
//! A_node` wins, and a node becomes a leaf when that is not cheaper than `c_I n` and it holds at most
//! `max_leaf_size` triangles. Where the centroids coincide, or below [`MEDIAN_FALLBACK_DEPTH`], the node is
//! split at the median triangle instead, which bounds the depth by `MEDIAN_FALLBACK_DEPTH + log2(n)` and keeps
//! every tree within the format's depth rule.
//!
//! Layout for speed (O(n log n) with small constants): each triangle's box travels with its index in one
//! array of [`Reference`]s that is partitioned in place, so a node reads a contiguous range; one pass bins all
//! three axes; the children's boxes come from the bins and their centroid bounds from the partition pass, so a
//! node touches its references twice. Nodes are written in preorder straight into their final slots: a
//! subtree over `m` triangles owns `2m - 1` slots (exactly what it needs with one triangle per leaf; the unused
//! slots of larger leaves are squeezed out at the end, which keeps preorder). Subtrees of more than
//! [`PARALLEL_THRESHOLD`] triangles are built in parallel (rayon) and large nodes are binned in parallel chunks;
//! unions and counts are exact in any order, so the tree is the same for any number of threads.

use rayon::prelude::*;

use super::reference::{Box4, CHUNK, Reference, UNUSED_NODE, median, squeeze_unused_nodes, union_of};
use super::sweep::best_plane as sweep;
use crate::build_tree::{BuildNode, BuildTree};
use crate::geometry::Aabb;

/// Most bins per axis.
pub const BIN_COUNT: usize = 16;
/// Depth from which nodes are split at the median triangle, whatever the SAH says.
pub const MEDIAN_FALLBACK_DEPTH: usize = 160;
/// Subtrees with more triangles than this are built in parallel.
const PARALLEL_THRESHOLD: usize = 4096;
/// Cost of a traversal step in the split decisions (the reference convention's c_T).
const TRAVERSAL_COST: f64 = 3.0;
/// Cost of a triangle test in the split decisions (the reference convention's c_I).
const INTERSECTION_COST: f64 = 2.0;

/// Builds a binned SAH tree over `triangles` with at most `max_leaf_size` (>= 1) triangles per leaf.
pub fn build_binned_sah(triangles: &[[[f32; 3]; 3]], max_leaf_size: usize) -> BuildTree {
    build_binned_sah_over(triangles.len(), |t| Aabb::of_triangle(&triangles[t]), max_leaf_size)
}

/// [`build_binned_sah`] over `count` boxes (`box_of(i)` for `i < count`, e.g. split references): the tree's
/// `triangle_order` holds box indices.
pub fn build_binned_sah_boxes(boxes: &[Aabb], max_leaf_size: usize) -> BuildTree {
    build_binned_sah_over(boxes.len(), |i| boxes[i], max_leaf_size)
}

fn build_binned_sah_over(count: usize, box_of: impl Fn(usize) -> Aabb + Sync, max_leaf_size: usize) -> BuildTree {
    let mut references: Vec<Reference> =
        (0..count).into_par_iter().map(|i| Reference::new(&box_of(i), i as u32)).collect();
    if references.is_empty() {
        return BuildTree::default();
    }
    let node = NodeRange {
        first: 0,
        at: 0,
        depth: 0,
        bounds: union_of(&references, |r| r.bounds),
        centroids: union_of(&references, Reference::centroid_box),
    };
    // Filled in parallel: at millions of triangles the new pages themselves take a noticeable time.
    let mut nodes = Vec::with_capacity(2 * references.len() - 1);
    nodes.par_extend(rayon::iter::repeat_n(UNUSED_NODE, 2 * references.len() - 1));
    let builder = Builder { max_leaf_size: max_leaf_size.max(1) };
    builder.build(&mut references, &mut nodes, node);
    let triangle_order = references.par_iter().map(Reference::triangle).collect();
    BuildTree { nodes: squeeze_unused_nodes(nodes, None), triangle_order }
}

/// What a node knows before it is split: where its references and its slot are, its box and the box of its
/// references' doubled centroids.
#[derive(Clone, Copy, Debug)]
struct NodeRange {
    /// Position of the node's first reference in the whole array.
    first: usize,
    /// The node's slot in the whole node array.
    at: u32,
    depth: usize,
    bounds: Box4,
    centroids: Box4,
}

struct Builder {
    max_leaf_size: usize,
}

impl Builder {
    /// Writes the subtree over `references` (positions `range.first..`) into `nodes` (`2 * len - 1` slots, the
    /// first at `range.at`) in preorder.
    fn build(&self, references: &mut [Reference], nodes: &mut [BuildNode], range: NodeRange) {
        let count = references.len();
        let aabb = range.bounds.to_aabb();
        let leaf = BuildNode::Leaf { aabb, first: range.first as u32, count: count as u32 };
        if count == 1 {
            nodes[0] = leaf;
            return;
        }
        let (mid, sides) = match self.choose_split(references, &range) {
            SplitChoice::Leaf if count <= self.max_leaf_size => {
                nodes[0] = leaf;
                return;
            }
            SplitChoice::Plane { axis, bin, binning, left_bounds, right_bounds } => {
                let (mid, left, right) = partition(references, |r| binning.bin_of(r.centroid2()[axis], axis) < bin);
                (mid, Sides { bounds: [left_bounds, right_bounds], centroids: [left, right] })
            }
            SplitChoice::Leaf | SplitChoice::Median => median_split(references, &range.centroids),
        };
        let Sides { bounds: [left_bounds, right_bounds], centroids: [left, right] } = sides;
        let (left_references, right_references) = references.split_at_mut(mid);
        let right_at = range.at + 2 * mid as u32;
        nodes[0] = BuildNode::Inner { aabb, left: range.at + 1, right: right_at };
        let (left_nodes, right_nodes) = nodes[1..].split_at_mut(2 * mid - 1);
        let depth = range.depth + 1;
        let left_range =
            NodeRange { first: range.first, at: range.at + 1, depth, bounds: left_bounds, centroids: left };
        let right_range =
            NodeRange { first: range.first + mid, at: right_at, depth, bounds: right_bounds, centroids: right };
        if count > PARALLEL_THRESHOLD {
            rayon::join(
                || self.build(left_references, left_nodes, left_range),
                || self.build(right_references, right_nodes, right_range),
            );
        } else {
            self.build(left_references, left_nodes, left_range);
            self.build(right_references, right_nodes, right_range);
        }
    }

    /// The split the SAH prefers, a leaf where splitting does not pay, or the median where binning cannot
    /// separate the centroids (or the node is too deep). Bins are sized to the node: 2, 4, 8 or
    /// [`BIN_COUNT`], the smallest at least the triangle count.
    fn choose_split(&self, references: &[Reference], range: &NodeRange) -> SplitChoice {
        if range.depth >= MEDIAN_FALLBACK_DEPTH {
            return SplitChoice::Median;
        }
        let (best_cost, best) = match references.len() {
            0..=2 => best_plane::<2>(references, &range.centroids),
            3..=4 => best_plane::<4>(references, &range.centroids),
            5..=8 => best_plane::<8>(references, &range.centroids),
            _ => best_plane::<BIN_COUNT>(references, &range.centroids),
        };
        if let SplitChoice::Plane { .. } = best {
            let area = f64::from(half_area(&range.bounds));
            let split_cost = if area > 0.0 {
                TRAVERSAL_COST + INTERSECTION_COST * f64::from(best_cost) / area
            } else {
                f64::INFINITY
            };
            if split_cost >= INTERSECTION_COST * references.len() as f64 {
                return SplitChoice::Leaf;
            }
        }
        best
    }
}

/// Per axis and bin: the box of the references whose centroid falls into the bin, and their count.
struct Bins<const N: usize> {
    bounds: [[Box4; N]; 3],
    counts: [[u32; N]; 3],
}

impl<const N: usize> Bins<N> {
    const EMPTY: Bins<N> = Bins { bounds: [[Box4::EMPTY; N]; 3], counts: [[0; N]; 3] };

    fn merge(mut self, other: Bins<N>) -> Bins<N> {
        for axis in 0..3 {
            for b in 0..N {
                self.bounds[axis][b] = self.bounds[axis][b].union(&other.bounds[axis][b]);
                self.counts[axis][b] += other.counts[axis][b];
            }
        }
        self
    }
}

/// The binned plane of lowest `A_left n_left + A_right n_right` over `N` bins an axis (`Median` when no axis
/// has spread centroids), with that sum in half areas.
fn best_plane<const N: usize>(references: &[Reference], centroids: &Box4) -> (f32, SplitChoice) {
    let count = references.len();
    let binning = Binning::new(centroids, N);
    let fill = |chunk: &[Reference]| {
        let mut bins = Bins::<N>::EMPTY;
        for reference in chunk {
            for (axis, &c) in reference.centroid2()[..3].iter().enumerate() {
                let b = binning.bin_of(c, axis);
                bins.bounds[axis][b] = bins.bounds[axis][b].union(&reference.bounds);
                bins.counts[axis][b] += 1;
            }
        }
        bins
    };
    // Unions and counts do not depend on the order of reduction, so the parallel form is exact.
    let bins = if count > CHUNK {
        references.par_chunks(CHUNK).map(fill).reduce(|| Bins::EMPTY, Bins::merge)
    } else {
        fill(references)
    };
    let mut best = (f32::INFINITY, SplitChoice::Median);
    for axis in (0..3).filter(|&axis| binning.spreads(axis)) {
        let counts = &bins.counts[axis];
        let half_areas = |l: &Box4, nl: u32, r: &Box4, nr: u32| half_area(l) * nl as f32 + half_area(r) * nr as f32;
        if let Some(plane) = sweep(&bins.bounds[axis], counts, counts, best.0, half_areas) {
            let (left_bounds, right_bounds) = (plane.left, plane.right);
            best = (plane.cost, SplitChoice::Plane { axis, bin: plane.bin, binning, left_bounds, right_bounds });
        }
    }
    best
}

/// Half the surface area, in f32 (the split decisions compare ratios, so the factor 2 does not matter), saturated
/// at `f32::MAX` so that huge boxes compare as large instead of infinite or NaN.
#[inline(always)]
fn half_area(bounds: &Box4) -> f32 {
    let e: [f32; 3] = std::array::from_fn(|a| bounds.max[a] - bounds.min[a]);
    (e[0] * e[1] + e[1] * e[2] + e[2] * e[0]).min(f32::MAX)
}

/// The mapping of (doubled) centroids to bins along the three axes of a node.
#[derive(Clone, Copy, Debug)]
struct Binning {
    low: [f32; 3],
    /// 0 along an axis where the centroids do not spread (everything falls into bin 0 there).
    scale: [f32; 3],
    last: usize,
}

impl Binning {
    fn new(centroids: &Box4, bin_count: usize) -> Binning {
        let scale = std::array::from_fn(|a| {
            let (low, high) = (centroids.min[a], centroids.max[a]);
            if high > low { bin_count as f32 / (high - low) } else { 0.0 }
        });
        let scale = scale.map(|s: f32| if s.is_finite() { s } else { 0.0 });
        Binning { low: [centroids.min[0], centroids.min[1], centroids.min[2]], scale, last: bin_count - 1 }
    }

    /// Whether the centroids spread along `axis`, so that its bins are worth a sweep.
    fn spreads(&self, axis: usize) -> bool {
        self.scale[axis] > 0.0
    }

    /// The bin of doubled centroid coordinate `c` along `axis` (the partition uses the same function, so both
    /// agree exactly).
    #[inline(always)]
    fn bin_of(&self, c: f32, axis: usize) -> usize {
        (((c - self.low[axis]) * self.scale[axis]) as usize).min(self.last)
    }
}

enum SplitChoice {
    Leaf,
    Median,
    /// Centroids in bins `< bin` along `axis` go left; the sides' boxes come from the bins.
    Plane {
        axis: usize,
        bin: usize,
        binning: Binning,
        left_bounds: Box4,
        right_bounds: Box4,
    },
}

/// The two children's boxes and centroid boxes, left then right.
struct Sides {
    bounds: [Box4; 2],
    centroids: [Box4; 2],
}

/// Splits at the median reference by centroid along the longest axis of the centroid box; returns the split
/// position and the two sides.
fn median_split(references: &mut [Reference], centroids: &Box4) -> (usize, Sides) {
    let mid = median(references, centroids.to_aabb().longest_axis());
    let (left, right) = references.split_at(mid);
    let sides = Sides {
        bounds: [union_of(left, |r| r.bounds), union_of(right, |r| r.bounds)],
        centroids: [union_of(left, Reference::centroid_box), union_of(right, Reference::centroid_box)],
    };
    (mid, sides)
}

/// Moves the references satisfying `goes_left` to the front (in place, deterministic); returns their count and
/// the centroid boxes of both sides, gathered on the way. The split choice guarantees both sides are non-empty.
fn partition(references: &mut [Reference], goes_left: impl Fn(&Reference) -> bool) -> (usize, Box4, Box4) {
    let (mut i, mut j) = (0, references.len());
    let (mut left, mut right) = (Box4::EMPTY, Box4::EMPTY);
    while i < j {
        let centroid = references[i].centroid_box();
        if goes_left(&references[i]) {
            left = left.union(&centroid);
            i += 1;
        } else {
            right = right.union(&centroid);
            j -= 1;
            references.swap(i, j);
        }
    }
    (i, left, right)
}
