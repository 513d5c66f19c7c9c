//! Initial BVH builders and the mutable build tree they produce.
//!
//! * [`build_spatial_median`]: split the node's box in the middle, axes round robin from the longest at the
//!   root (the reference table's M = 1 start).
//! * [`build_binned_sah`]: binned SAH (Wald 2007), the default start of the optimizer.
//!
//! Both are deterministic and bound the depth (median splits deep in the tree), and both make one triangle per
//! leaf when asked for `max_leaf_size = 1`, as the optimizer needs.

mod binned_sah;
mod spatial_median;

pub use binned_sah::{BIN_COUNT, MEDIAN_FALLBACK_DEPTH, build_binned_sah, build_binned_sah_boxes};
pub use spatial_median::{build_spatial_median, build_spatial_median_boxes};

use crate::aabb::Aabb;

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

/// Which initial builder to use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Builder {
    /// Spatial median, round-robin axes.
    SpatialMedian,
    /// Binned SAH.
    #[default]
    BinnedSah,
}

impl Builder {
    /// Builds a tree over `triangles` with at most `max_leaf_size` triangles per leaf.
    pub fn build(self, triangles: &[[[f32; 3]; 3]], max_leaf_size: usize) -> BuildTree {
        match self {
            Builder::SpatialMedian => build_spatial_median(triangles, max_leaf_size),
            Builder::BinnedSah => build_binned_sah(triangles, max_leaf_size),
        }
    }

    /// Builds a tree over `boxes` (split references, say): leaves hold box indices.
    pub fn build_boxes(self, boxes: &[Aabb], max_leaf_size: usize) -> BuildTree {
        match self {
            Builder::SpatialMedian => build_spatial_median_boxes(boxes, max_leaf_size),
            Builder::BinnedSah => build_binned_sah_boxes(boxes, max_leaf_size),
        }
    }

    /// Builds a one-reference-per-leaf tree over `references` whose leaves hold the references' *triangles*
    /// (a triangle may then sit in several leaves, each leaf's box being its reference's box), as the optimizer
    /// takes it.
    pub fn build_references(self, references: &crate::split::References) -> BuildTree {
        let mut tree = self.build_boxes(&references.aabb, 1);
        for r in &mut tree.triangle_order {
            *r = references.triangle[*r as usize];
        }
        tree
    }

    /// The name used in options and reports.
    pub fn name(self) -> &'static str {
        match self {
            Builder::SpatialMedian => "spatial_median",
            Builder::BinnedSah => "binned_sah",
        }
    }
}
