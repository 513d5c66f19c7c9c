//! From a triangle record back to the source: the identity of split triangles and the source primitive's
//! vertices and their weights.

pub(crate) mod corners;
pub(crate) mod identity;
