//! Writing files (feature `write`), what a converter needs and a renderer does not: the writer that lays out
//! and verifies a file, atomic outputs (a temporary file renamed into place, never a half-written file, and
//! the sweeping of stale temporaries), and page-cache-bypassing writes.

pub(crate) mod atomic;
pub(crate) mod rewrite;
pub(crate) mod writer;

pub use crate::open::uncached::UncachedWriter;
pub use atomic::{
    AtomicOutput, TEMPORARY_PREFIX, TEMPORARY_SUFFIX, check_replaceable, directory_of, remove_own_temporary_files,
    sweep_stale, write_atomic,
};
pub use writer::BvhWriter;
