//! Wide (N-ary) BVHs collapsed from the optimizer's binary tree: the in-memory form from which a wide node
//! section will be packed (issue 10). `collapse` is Ylitie, Karras and Laine's SAH-optimal dynamic program;
//! `WideTree` keeps each child's box and either a child node or a leaf's triangle range.

mod collapse;
mod pack;

pub use collapse::{WideCosts, collapse, collapse_references};
pub use pack::pack_wide;

use crate::aabb::Aabb;

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
