//! The build stage: initial BVHs over a scene's triangles, as [`BuildTree`]s with one triangle (or reference)
//! a leaf for the optimizer.
//!
//! * [`build_spatial_median`]: split the node's box in the middle, axes round robin from the longest at the
//!   root (the reference table's M = 1 start).
//! * [`build_binned_sah`]: binned SAH (Wald 2007), the default start of the optimizer.
//! * [`sbvh`]: spatial splits during the build (Stich et al. 2009), cutting triangles into split references.
//! * [`presplit`]: large triangles cut into references before the build (Karras and Aila 2013).
//!
//! All are deterministic and bound the depth (median splits deep in the tree), and all make one triangle per
//! leaf when asked for `max_leaf_size = 1`, as the optimizer needs.

mod binned_sah;
pub mod presplit;
mod reference;
pub mod sbvh;
mod spatial_median;
mod sweep;

pub use binned_sah::{BIN_COUNT, MEDIAN_FALLBACK_DEPTH, build_binned_sah, build_binned_sah_boxes};
pub use presplit::{MAX_BUDGET, References, split_triangles, split_triangles_keeping, split_triangles_with};
pub use spatial_median::{build_spatial_median, build_spatial_median_boxes};

use crate::build_tree::BuildTree;

/// Split references cut only *wasteful* triangles by default: those whose pieces could remove at least this share
/// of their box's area ([`crate::geometry::clip::ideal_box_area`]). Flat triangles that fill half of their box's
/// face (the two halves of an axis-aligned rectangle: floors, walls, tiles) are at exactly 0.5; cutting them
/// lowers the binary tree's SAH but raises the cost of the wide tree that files are traced by on some scenes
/// (`docs/evaluation.md`). The SBVH's threshold; 0 cuts any triangle.
pub const WASTEFUL_RATIO_SBVH: f64 = 0.55;
/// [`WASTEFUL_RATIO_SBVH`] for pre-splitting, whose grid cuts are coarser.
pub const WASTEFUL_RATIO_PRE_SPLIT: f64 = 0.6;
use crate::geometry::Aabb;

/// Which initial builder to use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
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
    pub fn build_references(self, references: &References) -> BuildTree {
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
