//! Writing files (feature `write`): the writer that lays out and verifies a file, and atomic outputs (a
//! temporary file renamed into place, never a half-written file).

pub(crate) mod atomic;
pub(crate) mod writer;
