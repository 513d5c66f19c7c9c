//! Wide (N-ary) BVHs collapsed from the optimizer's binary tree ([`mod@super::collapse`]): the in-memory form that
//! [`crate::pack::pack_wide`] lays out as the file's wide sections. Each child slot keeps its box and either a
//! child node or a leaf's triangle range.

use crate::geometry::Aabb;

/// A child slot of a wide node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WideChild {
    /// An inner wide node, by index into [`WideTree::nodes`].
    Node(u32),
    /// A leaf: triangles `first .. first + count` of [`WideTree::triangle_order`].
    Leaf {
        /// First position in `triangle_order`.
        first: u32,
        /// Number of triangles, at least 1.
        count: u32,
    },
}

/// An inner node: up to `width` children, each with its exact box, in the binary tree's left-to-right order.
#[derive(Clone, Debug, PartialEq)]
pub struct WideNode {
    /// The children; at least 2 unless the whole tree is one leaf.
    pub children: Vec<(Aabb, WideChild)>,
}

/// A wide BVH over the triangles of a binary optimizer tree.
///
/// Invariants: node 0 is the root (absent for an empty scene); every node but the root is the child of exactly
/// one node, which comes before it; the leaves, visited depth first in child order, hold consecutive ranges of
/// `triangle_order` that cover it exactly once; every box is the exact union of the triangles below it.
#[derive(Clone, Debug, PartialEq)]
pub struct WideTree {
    /// The branching factor (children per node at most).
    pub width: usize,
    /// Inner nodes, the root first.
    pub nodes: Vec<WideNode>,
    /// Triangle indices (into the soup) in leaf order.
    pub triangle_order: Vec<u32>,
    /// The root's box.
    pub root_box: Aabb,
}

impl WideTree {
    /// The cost of this tree under `costs` (see [`WideCosts`]), normalized by the root's area: every inner node
    /// weighs `node_visit * SA(node)`, every leaf `packet_test * ceil(count / packet_width) * SA(leaf)`.
    pub fn cost(&self, costs: &WideCosts) -> f64 {
        let root_area = self.root_box.surface_area();
        if root_area <= 0.0 || self.nodes.is_empty() {
            return 0.0;
        }
        let mut total = costs.node_visit * root_area;
        for node in &self.nodes {
            for (aabb, child) in &node.children {
                total += match child {
                    WideChild::Node(_) => costs.node_visit * aabb.surface_area(),
                    WideChild::Leaf { count, .. } => costs.leaf(*count as usize) * aabb.surface_area(),
                };
            }
        }
        total / root_area
    }
}

/// The collapse's parameters: the width, the leaf limit, and the two costs of the kernel.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct WideCosts {
    /// Children per wide node (2 to 16; 4 and 8 are what SIMD kernels use).
    pub width: usize,
    /// Triangles tested together in one packet (`W`).
    pub packet_width: usize,
    /// Most triangles in one leaf.
    pub max_leaf_size: usize,
    /// Cost of visiting one wide node (testing all its child boxes).
    pub node_visit: f64,
    /// Cost of testing one packet of triangles.
    pub packet_test: f64,
}

impl Default for WideCosts {
    /// 8-wide nodes, packets of 4, leaves of up to 8 triangles, and a packet test priced like a node visit (the
    /// fitted ratio traced no faster, and width 8 beats width 4: `docs/choices.md`). The values used are
    /// recorded in the metadata (`build.wide`).
    fn default() -> Self {
        WideCosts { width: 8, packet_width: 4, max_leaf_size: 8, node_visit: 1.0, packet_test: 1.0 }
    }
}

impl WideCosts {
    /// The cost factor of a leaf of `count` triangles (times its area).
    pub fn leaf(&self, count: usize) -> f64 {
        self.packet_test * count.div_ceil(self.packet_width.max(1)) as f64
    }
}

/// The GPU layout's collapse (format 1.4): 8-wide, triangles tested one at a time, leaves of at most 3 (the
/// compressed node's unary count), and the two costs of the GPU kernel that the dynamic program minimizes.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct GpuCosts {
    /// Most triangles in one leaf, 1 to 3.
    pub max_leaf_size: usize,
    /// Cost of visiting one compressed node (decoding and testing its eight boxes).
    pub node_visit: f64,
    /// Cost of testing one triangle.
    pub triangle_test: f64,
}

impl Default for GpuCosts {
    /// Leaves of up to 3 triangles as in Ylitie et al. (2017), and a triangle test at 0.3 of a node visit
    /// (`docs/gpu.md` compares the ratios on the GPU kernel's node visits and bytes read).
    fn default() -> Self {
        GpuCosts { max_leaf_size: 3, node_visit: 1.0, triangle_test: 0.3 }
    }
}

impl GpuCosts {
    /// The collapse's parameters for these costs.
    pub fn wide_costs(&self) -> WideCosts {
        WideCosts {
            width: 8,
            packet_width: 1,
            max_leaf_size: self.max_leaf_size,
            node_visit: self.node_visit,
            packet_test: self.triangle_test,
        }
    }
}
