//! The integration test suite: one binary, one module per subject.

mod common;
mod compat;
mod golden;
mod mutation;
mod roundtrip;
mod rules;
mod scenes;
mod traversal;
mod watertight;
