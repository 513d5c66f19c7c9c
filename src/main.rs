//! The `bvhc` command line.
#![forbid(unsafe_code)]
fn main() {}
