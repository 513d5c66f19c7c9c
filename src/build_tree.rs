//! The flat binary tree that the builders produce and the leaf layout writes back: nodes with boxes, leaves
//! holding ranges of a triangle order. The packer flattens it into the file's layout ([`crate::pack`]); the
//! optimizer works on its linked form ([`crate::optimize::OptTree`]).

use crate::cost::{SahConstants, SahCost, sah_of_nodes};
use crate::geometry::Aabb;

/// A node of the mutable build tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BuildNode {
    /// Two children, indices into [`BuildTree::nodes`].
    Inner {
        /// The node's box.
        aabb: Aabb,
        /// Left child.
        left: u32,
        /// Right child.
        right: u32,
    },
    /// Triangles `triangle_order[first .. first + count]`.
    Leaf {
        /// The node's box.
        aabb: Aabb,
        /// First position in [`BuildTree::triangle_order`].
        first: u32,
        /// Number of triangles, at least 1.
        count: u32,
    },
}

impl BuildNode {
    /// The node's box.
    pub fn aabb(&self) -> &Aabb {
        match self {
            BuildNode::Inner { aabb, .. } | BuildNode::Leaf { aabb, .. } => aabb,
        }
    }
}

/// A BVH over a triangle array; the root is node 0 (no nodes for no triangles).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildTree {
    /// The nodes.
    pub nodes: Vec<BuildNode>,
    /// Triangle indices in leaf order.
    pub triangle_order: Vec<u32>,
}

impl BuildTree {
    /// The tree's SAH cost ([`crate::cost`]; an empty tree costs 0).
    pub fn sah_cost(&self, constants: SahConstants) -> SahCost {
        let nodes = self.nodes.iter().map(|node| match node {
            BuildNode::Inner { aabb, .. } => (*aabb, 0),
            BuildNode::Leaf { aabb, count, .. } => (*aabb, *count),
        });
        sah_of_nodes(nodes, constants)
    }
}
