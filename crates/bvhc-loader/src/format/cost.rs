//! The costs a file's metadata reports, computed from the file as `format-spec/bvh-1.md` defines them: the SAH
//! cost of the binary tree (section 5.6) and the cost of the wide tree (section 6.1). The verifier checks the
//! metadata against these (V37), and `bvhc info` prints them.
//!
//! Every sum is one running f64 sum in the order the spec states (nodes in index order; for the wide tree, the
//! root's term, then each node's occupied slots in slot order), so any reader that follows the text gets the
//! same bits.

use crate::format::{EMPTY_SLOT, LEAF_BIT, PackedNode, WIDE, WideNode8};

/// Surface area `2 (x y + y z + z x)` of the box `min..max`, with each extent `max(0, f64(max) - f64(min))`
/// (the f32 bounds widened to f64 exactly before subtracting).
#[inline]
pub fn box_area(min: &[f32; 3], max: &[f32; 3]) -> f64 {
    let e: [f64; 3] = std::array::from_fn(|a| (f64::from(max[a]) - f64::from(min[a])).max(0.0));
    2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0])
}

/// The SAH cost of a binary tree and its two area ratios (section 5.6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BinaryCost {
    /// `c_t * inner_area_ratio + c_i * leaf_area_ratio`.
    pub sah_cost: f64,
    /// `A_I`: the inner nodes' areas (the root included when inner) over the root's.
    pub inner_area_ratio: f64,
    /// `A_L`: the leaves' areas, each times its triangle count, over the root's.
    pub leaf_area_ratio: f64,
}

/// The SAH cost of `nodes` (node 0 the root) under the constants `c_t` and `c_i`: sums in node index order; all
/// three numbers 0 when the root's area is 0 or there is no node.
pub fn binary_cost(nodes: &[PackedNode], c_t: f64, c_i: f64) -> BinaryCost {
    let root_area = nodes.first().map_or(0.0, |root| box_area(&root.min, &root.max));
    if root_area <= 0.0 {
        return BinaryCost { sah_cost: 0.0, inner_area_ratio: 0.0, leaf_area_ratio: 0.0 };
    }
    let (mut inner, mut leaf) = (0.0f64, 0.0f64);
    for node in nodes {
        let area = box_area(&node.min, &node.max);
        if node.count == 0 {
            inner += area;
        } else {
            leaf += area * f64::from(node.count);
        }
    }
    let (inner_area_ratio, leaf_area_ratio) = (inner / root_area, leaf / root_area);
    BinaryCost { sah_cost: c_t * inner_area_ratio + c_i * leaf_area_ratio, inner_area_ratio, leaf_area_ratio }
}

/// The cost of a wide tree (section 6.1) whose root box is `root` (the binary root's), under the kernel's costs
/// `node_visit` and `packet_test`:
///
/// `total = node_visit * SA(root)`, then for each wide node in index order and each occupied slot in slot order
/// `total += node_visit * SA(slot)` for an inner reference or `total += (packet_test * packet_count) * SA(slot)`
/// for a leaf reference, and the result is `total / SA(root)`; 0 when `SA(root) = 0` or there is no node.
pub fn wide_cost(root: Option<&PackedNode>, nodes: &[WideNode8], node_visit: f64, packet_test: f64) -> f64 {
    let root_area = root.map_or(0.0, |root| box_area(&root.min, &root.max));
    if root_area <= 0.0 || nodes.is_empty() {
        return 0.0;
    }
    let mut total = node_visit * root_area;
    for node in nodes {
        for slot in 0..WIDE {
            let child = node.child[slot];
            if child == EMPTY_SLOT {
                break;
            }
            let min = std::array::from_fn(|a| node.min[a][slot]);
            let max = std::array::from_fn(|a| node.max[a][slot]);
            let weight = if child & LEAF_BIT == 0 {
                node_visit
            } else {
                packet_test * f64::from(WideNode8::leaf_packets(child).1)
            };
            total += weight * box_area(&min, &max);
        }
    }
    total / root_area
}

/// A tree's box areas as a refit sums them on its way (in its own order, so equal to the spec's running sums
/// within rounding, not bit for bit): `inner`, the inner nodes' (or inner slots') areas; `leaf`, the leaves'
/// areas each times its triangle count (binary) or packet count (wide).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct AreaSums {
    pub inner: f64,
    pub leaf: f64,
}

impl AreaSums {
    /// The sums with one more node: an inner node's (or inner slot's) `area` when `count` is 0, else a leaf's
    /// `area` times its `count` (triangles, or packets).
    #[inline(always)]
    pub(crate) fn with_node(self, area: f64, count: u32) -> AreaSums {
        match count {
            0 => AreaSums { inner: self.inner + area, ..self },
            count => AreaSums { leaf: self.leaf + area * f64::from(count), ..self },
        }
    }

    /// Both sums added.
    pub(crate) fn plus(self, other: AreaSums) -> AreaSums {
        AreaSums { inner: self.inner + other.inner, leaf: self.leaf + other.leaf }
    }

    /// The binary tree's cost (section 5.6) from its sums and its root's area.
    pub(crate) fn binary_cost(&self, root_area: f64, c_t: f64, c_i: f64) -> BinaryCost {
        if root_area <= 0.0 {
            return BinaryCost { sah_cost: 0.0, inner_area_ratio: 0.0, leaf_area_ratio: 0.0 };
        }
        let (inner_area_ratio, leaf_area_ratio) = (self.inner / root_area, self.leaf / root_area);
        BinaryCost { sah_cost: c_t * inner_area_ratio + c_i * leaf_area_ratio, inner_area_ratio, leaf_area_ratio }
    }

    /// The wide tree's cost (section 6.1) from its slots' sums and the binary root's area.
    pub(crate) fn wide_cost(&self, root_area: f64, node_visit: f64, packet_test: f64) -> f64 {
        if root_area <= 0.0 {
            return 0.0;
        }
        (node_visit * (root_area + self.inner) + packet_test * self.leaf) / root_area
    }
}
