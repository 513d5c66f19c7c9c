//! What the top-down builders move around: [`Reference`]s, each a box in four lanes ([`Box4`]) with its triangle's
//! index, and the helpers both builders (binned SAH and SBVH) share: unions, the median split, and squeezing the
//! unused node slots out of a tree written in preorder into room reserved for one reference a leaf.

use rayon::prelude::*;

use crate::build_tree::{BuildNode, BuildTree};
use crate::geometry::Aabb;

/// Ranges larger than this are reduced in parallel chunks of this size (exact in any order).
pub(crate) const CHUNK: usize = 64 * 1024;

/// A box in four lanes (the fourth lane unused by the geometry), so that a union is one `minps` and one `maxps`.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub(crate) struct Box4 {
    pub(crate) min: [f32; 4],
    pub(crate) max: [f32; 4],
}

impl Box4 {
    pub(crate) const EMPTY: Box4 = Box4 { min: [f32::INFINITY; 4], max: [f32::NEG_INFINITY; 4] };

    #[inline(always)]
    pub(crate) fn union(&self, other: &Box4) -> Box4 {
        Box4 {
            min: std::array::from_fn(|a| if other.min[a] < self.min[a] { other.min[a] } else { self.min[a] }),
            max: std::array::from_fn(|a| if other.max[a] > self.max[a] { other.max[a] } else { self.max[a] }),
        }
    }

    /// The box `aabb` (lane 3 empty).
    pub(crate) fn of(aabb: &Aabb) -> Box4 {
        let ([x, y, z], [u, v, w]) = (aabb.min, aabb.max);
        Box4 { min: [x, y, z, f32::INFINITY], max: [u, v, w, f32::NEG_INFINITY] }
    }

    /// The box as a point: `min == max == p` (lane 3 of `p` is copied as well).
    pub(crate) fn point(p: [f32; 4]) -> Box4 {
        Box4 { min: p, max: p }
    }

    pub(crate) fn to_aabb(self) -> Aabb {
        Aabb { min: [self.min[0], self.min[1], self.min[2]], max: [self.max[0], self.max[1], self.max[2]] }
    }
}

/// A triangle's box and its index: 32 bytes that the builder moves around. The index is kept in lane 3 as two
/// small whole numbers, its low 16 bits in `min` and its high 16 bits in `max`: exact in f32 and never
/// subnormal (the index's bits as a float would be, and arithmetic on subnormals is many times slower).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Reference {
    pub(crate) bounds: Box4,
}

impl Reference {
    pub(crate) fn new(aabb: &Aabb, triangle: u32) -> Reference {
        let [x, y, z] = aabb.min;
        let [u, v, w] = aabb.max;
        let (low, high) = ((triangle & 0xFFFF) as f32, (triangle >> 16) as f32);
        Reference { bounds: Box4 { min: [x, y, z, low], max: [u, v, w, high] } }
    }

    pub(crate) fn triangle(&self) -> u32 {
        self.bounds.min[3] as u32 | (self.bounds.max[3] as u32) << 16
    }

    /// Twice the box center (`min + max`): the builder bins and splits on these, so halving would only cost.
    #[inline(always)]
    pub(crate) fn centroid2(&self) -> [f32; 4] {
        std::array::from_fn(|a| self.bounds.min[a] + self.bounds.max[a])
    }

    pub(crate) fn centroid_box(&self) -> Box4 {
        Box4::point(self.centroid2())
    }
}

impl Reference {
    /// The reference's box.
    pub(crate) fn aabb(&self) -> Aabb {
        self.bounds.to_aabb()
    }
}

/// The union of `item(r)` over `references` (in parallel chunks for large ranges; exact either way).
pub(crate) fn union_of(references: &[Reference], item: impl Fn(&Reference) -> Box4 + Sync) -> Box4 {
    let fold = |chunk: &[Reference]| chunk.iter().fold(Box4::EMPTY, |b, r| b.union(&item(r)));
    if references.len() > CHUNK {
        references.par_chunks(CHUNK).map(fold).reduce(|| Box4::EMPTY, |a, b| a.union(&b))
    } else {
        fold(references)
    }
}

/// Reorders `references` so that the first half (`len / 2`) lies below the rest by centroid along `axis` (ties by
/// triangle index, so the split is deterministic) and returns that position.
pub(crate) fn median(references: &mut [Reference], axis: usize) -> usize {
    let mid = references.len() / 2;
    references.select_nth_unstable_by(mid, |a, b| {
        a.centroid2()[axis].total_cmp(&b.centroid2()[axis]).then(a.triangle().cmp(&b.triangle()))
    });
    mid
}

/// A node slot no node was written to.
pub(crate) const UNUSED_NODE: BuildNode = BuildNode::Leaf { aabb: Aabb::EMPTY, first: 0, count: 0 };
/// A leaf-order slot no reference was written to.
pub(crate) const UNUSED_POSITION: u32 = u32::MAX;

/// The tree without the unused slots of `nodes` ([`UNUSED_NODE`]) and of `order` ([`UNUSED_POSITION`]), nodes
/// and leaf positions renumbered; both arrays are in preorder with gaps, so dropping the gaps keeps preorder.
pub(crate) fn squeeze_unused(nodes: Vec<BuildNode>, mut order: Vec<u32>) -> BuildTree {
    let new_position = renumbering(order.iter().map(|&t| t != UNUSED_POSITION));
    order.retain(|&t| t != UNUSED_POSITION);
    BuildTree { nodes: squeeze_unused_nodes(nodes, Some(&new_position)), triangle_order: order }
}

/// `nodes` without the unused slots ([`UNUSED_NODE`]), child indices renumbered and each leaf's first position
/// mapped through `new_position` when given (in preorder with gaps, so dropping the gaps keeps preorder).
pub(crate) fn squeeze_unused_nodes(nodes: Vec<BuildNode>, new_position: Option<&[u32]>) -> Vec<BuildNode> {
    let is_used = |node: &BuildNode| !matches!(node, BuildNode::Leaf { count: 0, .. });
    if new_position.is_none() && nodes.iter().all(is_used) {
        return nodes;
    }
    let position = |first: u32| new_position.map_or(first, |p| p[first as usize]);
    let new_index = renumbering(nodes.iter().map(is_used));
    nodes
        .into_iter()
        .filter(is_used)
        .map(|node| match node {
            BuildNode::Inner { aabb, left, right } => {
                BuildNode::Inner { aabb, left: new_index[left as usize], right: new_index[right as usize] }
            }
            BuildNode::Leaf { aabb, first, count } => BuildNode::Leaf { aabb, first: position(first), count },
        })
        .collect()
}

/// For each slot, the number of used slots before it.
fn renumbering(used: impl Iterator<Item = bool>) -> Vec<u32> {
    let mut next = 0u32;
    used.map(|u| {
        let index = next;
        next += u32::from(u);
        index
    })
    .collect()
}
