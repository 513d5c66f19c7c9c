//! bvhc: an offline BVH compiler. Import a scene, build and optimize a BVH, write a `.bvh` file that the
//! `bvhc-loader` crate maps at run time.
//!
//! The modules in the order the data flows through them: [`import`] (scene files to triangles), [`builders`]
//! (initial trees, split references), [`optimize`] (reinsertion), [`layout`] (leaf merging, the wide collapse),
//! [`pack`] (the file's arrays), [`instancing`] (two-level scenes: the top tree, the sections), [`convert`] (the pipeline, metadata, the build-script API), with [`options`]
//! (presets and overrides, resolved in one place). Shared below them: [`geometry`] (boxes, clipping), [`cost`]
//! (the one SAH definition), [`build_tree`] (the flat binary tree); [`epo`] measures trees for the evaluation, [`inspect`] reports a file as `bvhc info` does, [`posed`] gives a file's records the positions of a re-exported asset (`bvhc refit`).
#![forbid(unsafe_code)]

/// The Rust snippets of the README and of the docs about the loader, compiled by `cargo test` (doctests) so
/// that a wrong example fails the tests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
#[doc = include_str!("../docs/loader.md")]
#[doc = include_str!("../docs/gpu.md")]
pub struct DocSnippets;

// Shared below every stage.
pub mod geometry;
pub mod cost;
pub mod fallible;
pub mod build_tree;
// The stages, in flow order.
pub mod import;
pub mod builders;
pub mod optimize;
pub mod layout;
pub mod sampling;
pub mod pack;
pub mod instancing;
pub mod animation;
// Options and the pipeline over the stages.
pub mod options;
pub mod convert;
pub mod batch;
// Tree quality for the evaluation; what `bvhc info` reports of a file; a moved asset's positions for a refit.
pub mod epo;
pub mod inspect;
pub mod posed;

pub use convert::{Conversion, ConversionOutcome};
pub use options::Preset;

pub use bvhc_loader as loader;
