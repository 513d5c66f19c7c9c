//! What the SBVH's object and spatial splits share: the bin count, the two sides of a split, and how a plane
//! is priced.

use crate::builders::reference::{Box4, Reference, union_of};
use crate::geometry::Aabb;

/// Bins (object splits) and slabs (spatial splits) an axis.
pub const BINS: usize = 16;

/// The two sides of a split, and the references it added.
pub(super) struct Split {
    pub left: Vec<Reference>,
    pub right: Vec<Reference>,
    /// The union of each side's boxes.
    pub boxes: [Aabb; 2],
    pub added: usize,
}

/// The cost of a plane in the SBVH's decisions: `A_left n_left + A_right n_right`, areas in f64.
pub(super) fn area_cost(left: &Box4, n_left: u32, right: &Box4, n_right: u32) -> f64 {
    left.to_aabb().surface_area() * f64::from(n_left) + right.to_aabb().surface_area() * f64::from(n_right)
}

/// The union of the references' boxes.
pub(super) fn boxes_union(references: &[Reference]) -> Aabb {
    union_of(references, |r| r.bounds).to_aabb()
}

/// The centre of a reference's box along `axis` (the spatial splits' side for a reference kept whole).
pub(super) fn center(reference: &Reference, axis: usize) -> f32 {
    0.5 * reference.bounds.min[axis] + 0.5 * reference.bounds.max[axis]
}
