//! The pack stage: the leaf layout's trees in the file's layout. [`pack`] flattens the binary tree into the
//! nodes and triangles sections; [`pack_wide`] lays the wide tree out as the wide sections over those triangles.

mod binary;
mod wide;

pub use binary::{PackedTree, RecordCursor, pack};
pub use wide::pack_wide;
