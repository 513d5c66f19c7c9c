//! The conversion of one scene into one `.bvh` file: the pipeline of stages ([`pipeline`]), the candidate trees
//! it chooses among ([`candidates`]), the metadata it writes ([`metadata`]), what it reports ([`report`]), the
//! files it reads and writes ([`files`]), and the build-script API over all of it ([`Conversion`]).

pub mod candidates;
pub mod files;
pub mod metadata;
mod part;
pub mod pipeline;
mod sampled_poses;
mod two_level;
mod write;
pub mod report;
mod request;

pub use candidates::merge_and_collapse;
pub use pipeline::{convert, convert_with};
pub use report::{
    CandidateCost, Choice, ConvertError, ConvertReport, Event, Stage, Timings, TwoLevelSummary, WideSummary,
};
pub use request::{Conversion, ConversionOutcome};
