//! The binary layout's walk: depth first over [`crate::format::PackedNode`]s, generic over what a leaf holds
//! (a range of triangle records in a mesh's tree, one instance in a two-level file's top tree).

pub(crate) mod refit;
pub(crate) mod walk;
