//! The leaf layout stage: the optimized binary tree (one reference a leaf) becomes the file's two trees. The
//! binary tree's leaves are merged bottom-up by SAH ([`merge`]), and the 8-wide tree is collapsed from the same
//! tree by Ylitie et al.'s dynamic program ([`mod@collapse`]); over split references both count a triangle once a
//! leaf ([`leaf_counts`]) and [`records`] makes them hold each triangle equally often.

pub mod collapse;
pub mod leaf_counts;
pub mod merge;
pub mod records;
pub mod wide_tree;

pub use collapse::{collapse, collapse_by, collapse_references};
pub use merge::{cluster_roots, merge_leaves, merge_leaves_by, merge_leaves_of_references, merged_nodes};
pub use wide_tree::{GpuCosts, WideChild, WideCosts, WideNode, WideTree};

use crate::build_tree::BuildTree;
use crate::cost::SahConstants;
use crate::optimize::OptTree;

/// The leaf merging (leaves of up to `max_leaf_size` triangles; 1 keeps every leaf) and, with `wide`, the wide
/// collapse of an optimized tree with one reference a leaf. Both start from that tree (the collapse's dynamic
/// program chooses its own leaves) and run side by side. With `repeats` (some triangle lies in several leaves:
/// split references) both count a triangle once a leaf, and leaves that gathered several pieces of a triangle
/// then hold it once, with the two trees' record counts kept equal (where the wide leaves have no room for
/// that, both keep every piece); without repeats that is the plain count, which the plain programs get faster.
/// With `weights` (one per node: sampled ray probabilities, `crate::sampling`) both weigh nodes by them instead
/// of by surface area ([`collapse_by`], [`merge_leaves_by`]).
pub fn merge_and_collapse(
    tree: &OptTree,
    constants: SahConstants,
    max_leaf_size: usize,
    wide: Option<WideCosts>,
    triangle_count: usize,
    repeats: bool,
    weights: Option<&[f64]>,
) -> (BuildTree, Option<(WideTree, WideCosts)>) {
    let leaf_size = max_leaf_size.max(1);
    let (mut wide_tree, mut final_tree) = rayon::join(
        || {
            wide.map(|costs| match (weights, repeats) {
                (Some(w), _) => (collapse_by(tree, &costs, w, repeats), costs),
                (None, true) => (collapse_references(tree, &costs), costs),
                (None, false) => (collapse(tree, &costs), costs),
            })
        },
        || match (weights, repeats) {
            (Some(w), _) => merge_leaves_by(tree, constants, leaf_size, repeats, w),
            (None, true) => merge_leaves_of_references(tree, constants, leaf_size),
            (None, false) => merge_leaves(tree, constants, leaf_size),
        },
    );
    if repeats {
        match &mut wide_tree {
            Some((wide, _)) => {
                records::remove_repeats_and_balance(&mut final_tree, wide, triangle_count);
            }
            None => records::remove_binary_repeats(&mut final_tree, triangle_count),
        }
    }
    (final_tree, wide_tree)
}
