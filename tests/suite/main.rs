//! The integration test suite: one binary, one module per subject.

mod cli;
mod cli_hardening;
mod common;
mod compat;
mod convert;
mod golden;
mod hardening;
mod import_errors;
mod import_formats;
mod import_gltf;
mod import_mutation;
mod import_scenes;
mod metadata_schema;
mod mutation;
mod optimize;
mod optimize_property;
mod roundtrip;
mod rules;
mod rules_wide;
mod scenes;
mod spec;
mod stress;
mod trace;
mod traversal;
mod watertight;
mod wide;
