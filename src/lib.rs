//! bvhc: an offline BVH compiler. Import a scene, build and optimize a BVH, write a `.bvh` file that the
//! `bvhc-loader` crate maps at run time.
#![forbid(unsafe_code)]

pub mod aabb;
pub mod build;
pub mod conversion;
pub mod convert;
pub mod cost;
pub mod epo;
pub mod import;
pub mod optimize;
pub mod pack;
pub mod split;
pub mod up_to_date;
pub mod wide;

pub use conversion::{Conversion, ConversionOutcome};
pub use optimize::Preset;

pub use bvhc_loader as loader;
