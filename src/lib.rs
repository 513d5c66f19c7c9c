//! bvhc: an offline BVH compiler. Import a scene, build and optimize a BVH, write a `.bvh` file that the
//! `bvhc-loader` crate maps at run time.
#![forbid(unsafe_code)]

pub mod build_tree;
pub mod builders;
pub mod conversion;
pub mod convert;
pub mod cost;
pub mod epo;
pub mod geometry;
pub mod import;
pub mod layout;
pub mod optimize;
pub mod pack;
pub mod up_to_date;

pub use conversion::{Conversion, ConversionOutcome};
pub use optimize::Preset;

pub use bvhc_loader as loader;
