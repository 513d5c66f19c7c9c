//! Geometry every stage shares: axis-aligned boxes, and exact pieces of triangles cut by axis-aligned planes.

pub mod aabb;
pub mod clip;

pub use aabb::Aabb;
pub use clip::Piece;
