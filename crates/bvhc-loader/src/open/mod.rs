//! Opening a file: its bytes (owned, aligned, or mapped), the structural rules checked on opening (header,
//! section table, section sizes), the view that hands out typed sections, and edits of an owned file in place.

pub(crate) mod edit;
pub(crate) mod file;
pub(crate) mod sections;
pub(crate) mod structure;
#[cfg(feature = "write")]
pub(crate) mod uncached;
pub(crate) mod view;
pub(crate) mod view_mut;
