//! The one SAH cost definition used by the builders, the optimizer, the reports and the tests.
//!
//! `C = (c_T * sum_{inner N} SA(N) + c_I * sum_{leaves N} SA(N) * t_N) / SA(root)` (MacDonald and Booth 1990;
//! the convention of Bittner et al. 2013 and `../shared/guide/algorithm.md`: full surface area, the root counted
//! among the inner nodes, default `(c_T, c_I) = (3, 2)`). Its parts `A_I = sum_inner SA / SA(root)` and
//! `A_L = sum_leaf t * SA / SA(root)` are reported too, so any other convention can be recomputed from them:
//! `C = c_T * A_I + c_I * A_L`. Sums run in f64 in node-index order, so the figure is deterministic.

use bvhc_loader::format::PackedNode;
use serde::Serialize;

use crate::geometry::Aabb;

/// The SAH constants.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SahConstants {
    /// Cost of a traversal step (c_T).
    pub traversal: f64,
    /// Cost of a ray-triangle test (c_I).
    pub intersection: f64,
}

impl Default for SahConstants {
    /// The reference convention (3, 2).
    fn default() -> Self {
        SahConstants { traversal: 3.0, intersection: 2.0 }
    }
}

/// A tree's SAH cost and its parts.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SahCost {
    /// `c_T * A_I + c_I * A_L`.
    pub cost: f64,
    /// `A_I`: the inner nodes' surface areas (root included) over the root's.
    pub inner_area_ratio: f64,
    /// `A_L`: the leaves' surface areas times their triangle counts, over the root's.
    pub leaf_area_ratio: f64,
}

impl SahCost {
    /// The cost of the parts under `constants`.
    pub fn from_parts(inner_area_ratio: f64, leaf_area_ratio: f64, constants: SahConstants) -> SahCost {
        SahCost {
            cost: constants.traversal * inner_area_ratio + constants.intersection * leaf_area_ratio,
            inner_area_ratio,
            leaf_area_ratio,
        }
    }
}

/// Accumulates areas node by node.
#[derive(Default)]
struct Sums {
    inner: f64,
    leaf: f64,
}

impl Sums {
    fn finish(self, root_area: f64, constants: SahConstants) -> SahCost {
        if root_area > 0.0 {
            SahCost::from_parts(self.inner / root_area, self.leaf / root_area, constants)
        } else {
            // A flat or empty scene: every ray misses the root's zero area; count nodes instead of areas.
            SahCost::from_parts(0.0, 0.0, constants)
        }
    }
}

/// The cost of a packed tree, as stored in a `.bvh` file (node 0 the root): the format's definition
/// ([`bvhc_loader::format::cost::binary_cost`]), which the verifier checks the metadata against.
pub fn sah_of_packed(nodes: &[PackedNode], constants: SahConstants) -> SahCost {
    let cost = bvhc_loader::format::cost::binary_cost(nodes, constants.traversal, constants.intersection);
    SahCost { cost: cost.sah_cost, inner_area_ratio: cost.inner_area_ratio, leaf_area_ratio: cost.leaf_area_ratio }
}

/// The cost of any tree given as `(box, triangle count)` per node, 0 for inner nodes, the root first (for
/// example another library's tree, so that every tree is measured by this one definition).
pub fn sah_of_nodes(nodes: impl IntoIterator<Item = (Aabb, u32)>, constants: SahConstants) -> SahCost {
    let mut sums = Sums::default();
    let mut root_area = None;
    for (aabb, count) in nodes {
        let area = aabb.surface_area();
        root_area.get_or_insert(area);
        if count == 0 {
            sums.inner += area;
        } else {
            sums.leaf += area * f64::from(count);
        }
    }
    sums.finish(root_area.unwrap_or(0.0), constants)
}

/// The cost from raw sums (for the optimizer's own tree): `inner` and `leaf` are the unnormalized sums.
pub fn sah_of_sums(inner: f64, leaf: f64, root_area: f64, constants: SahConstants) -> SahCost {
    Sums { inner, leaf }.finish(root_area, constants)
}
