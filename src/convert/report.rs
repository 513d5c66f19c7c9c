//! What a conversion reports: its result and measurements ([`ConvertReport`]), the events its observer sees, and
//! why it failed ([`ConvertError`]).

use std::path::PathBuf;

use serde::Serialize;

use crate::cost::SahCost;
use crate::import::ImportReport;
use crate::optimize::{OptimizeReport, Progress};
use crate::options::OptionsError;
use crate::sampling::SamplingSummary;

/// What a conversion produced and measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ConvertReport {
    /// The output file.
    pub output: PathBuf,
    /// Every input file read.
    pub files_read: Vec<PathBuf>,
    /// What the import read and skipped.
    pub import: ImportReport,
    /// The optimizer's report (absent when skipped).
    pub optimization: Option<OptimizeReport>,
    /// Cost of the written tree (of a two-level file: its largest mesh's).
    pub cost: SahCost,
    /// Triangles written (distinct; with split references some are stored more than once).
    pub triangle_count: usize,
    /// The references the tree was built over (`triangle_count` without splits).
    pub reference_count: usize,
    /// Triangle records written (more than `triangle_count` when leaves repeat split triangles).
    pub stored_triangle_count: usize,
    /// Nodes written.
    pub node_count: usize,
    /// Wide nodes and triangle packets written (absent without wide sections).
    pub wide: Option<WideSummary>,
    /// GPU nodes and triangles written (absent without GPU sections).
    pub gpu: Option<GpuSummary>,
    /// Bytes written.
    pub file_byte_len: usize,
    /// Seconds per stage: import, build, optimize, merge, pack, write.
    pub timings: Timings,
    /// With `choose` for split triangles or reinsertion, or ray tuning: the candidates' costs and the one written
    /// (absent when a cancelled optimization ended the search at the first, and in a two-level file).
    pub choice: Option<Choice>,
    /// With ray tuning: the sample's sizes, or why it was skipped (absent without tuning and in a two-level file).
    pub sampling: Option<SamplingSummary>,
    /// What a two-level file (format 1.3) holds; absent for a one-level file.
    pub two_level: Option<TwoLevelSummary>,
    /// With `--animation`: the poses sampled and the written trees' costs in each (the metadata's `animation`).
    pub animation: Option<crate::animation::AnimationRecord>,
    /// Notes on options the input satisfies by its nature (an `--instancing` setting on an OBJ or PLY input,
    /// which places each model once); empty for most conversions.
    pub notes: Vec<String>,
}

/// The meshes and instances of a two-level file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct TwoLevelSummary {
    /// Meshes written: the instanced ones, and the flattened rest when there is any.
    pub mesh_count: usize,
    /// Instances written.
    pub instance_count: usize,
    /// Triangles in the scene as placed.
    pub placed_triangle_count: u64,
    /// Triangles flattened into world space.
    pub flattened_triangle_count: u64,
}

/// The wide sections of a conversion: their sizes and the collapsed tree's cost.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct WideSummary {
    /// Elements of `wide_nodes`.
    pub node_count: usize,
    /// Elements of `triangle_packets`.
    pub packet_count: usize,
    /// The wide tree's cost under the collapse's constants ([`crate::layout::WideTree::cost`]; of a two-level
    /// file: its largest mesh's).
    pub cost: f64,
}

/// The GPU sections of a conversion (format 1.4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct GpuSummary {
    /// Elements of `gpu_nodes`.
    pub node_count: usize,
    /// Elements of `gpu_triangles`.
    pub triangle_count: usize,
}

impl GpuSummary {
    /// The two sections' bytes.
    pub fn byte_len(&self) -> usize {
        self.node_count * size_of::<bvhc_loader::format::GpuNode>()
            + self.triangle_count * size_of::<bvhc_loader::format::GpuTriangle>()
    }
}

/// Seconds spent per stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Timings {
    /// Import.
    pub import: f64,
    /// Initial build.
    pub build: f64,
    /// Optimization by reinsertion.
    pub optimize: f64,
    /// Depth limiting, the wide collapse and leaf merging.
    pub merge: f64,
    /// Packing the binary and the wide trees into the file's arrays.
    pub pack: f64,
    /// Writing the file (metadata, checksums, atomic rename).
    pub write: f64,
}

impl Timings {
    /// All stages together.
    pub fn total(&self) -> f64 {
        self.import + self.build + self.optimize + self.merge + self.pack + self.write
    }
}

/// Why a conversion failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConvertError {
    /// The options cannot be honoured (a value out of range, or a setting another makes inert).
    #[error(transparent)]
    Options(#[from] OptionsError),
    /// The input could not be imported.
    #[error(transparent)]
    Import(#[from] crate::import::ImportError),
    /// The output could not be written.
    #[error(transparent)]
    Write(#[from] bvhc_loader::Error),
    /// The system refused memory the conversion needs (beyond what the memory budget estimated).
    #[error(
        "{}: {source} while {stage}; the conversion needs more memory than this process may use (free memory, \
         raise the address-space or cgroup limit, or convert on a larger machine)",
        path.display()
    )]
    OutOfMemory {
        /// The scene.
        path: std::path::PathBuf,
        /// The stage that needed the memory.
        stage: &'static str,
        /// The refused allocation.
        source: bvhc_loader::Error,
    },
    /// A bug in bvhc was caught before writing: please report it with the input.
    #[error("internal error (please report with the input): {0}")]
    Internal(String),
    /// The output names one of the files the conversion reads (the input, or a glTF buffer): writing it would
    /// destroy the input.
    #[error("{}: the output is one of the inputs ({}); choose another output path", output.display(), input.display())]
    OutputIsInput {
        /// The output path.
        output: PathBuf,
        /// The input file it names.
        input: PathBuf,
    },
    /// The scene has more triangles than the format's u32 indices allow.
    #[error("{}: {count} triangles (or split references) exceed the .bvh limit of 2^32 - 1", path.display())]
    TooLarge {
        /// The input.
        path: PathBuf,
        /// Its triangle count.
        count: usize,
    },
}

/// A stage of the pipeline, as reported to the observer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Reading the scene.
    Import,
    /// The initial build.
    Build,
    /// Optimization and leaf merging.
    Optimize,
    /// Packing, writing and verifying.
    Write,
}

/// What the pipeline tells its observer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event<'a> {
    /// A stage begins.
    Stage(Stage),
    /// An optimizer batch ended.
    Batch(&'a Progress),
}

/// How a conversion chose among candidate trees (`choose` for split triangles or reinsertion
/// ([`crate::options::SplitTriangles`], [`crate::options::OptimizeOver`]), or ray tuning).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Choice {
    /// What was compared: `sampled_cost` (with ray tuning: the wide kernel's mean cost for the held-out sample
    /// rays, [`crate::sampling::WideWork::cost_per_ray`], or the GPU kernel's without wide sections),
    /// `wide_cost` (the wide collapse's cost, [`crate::layout::WideTree::cost`]) or `sah_cost` (the binary
    /// tree's, for files without wide sections).
    pub measure: &'static str,
    /// Every candidate made, in the order made.
    pub candidates: Vec<CandidateCost>,
    /// The index in `candidates` of the one written.
    pub kept: usize,
}

/// One candidate of a [`Choice`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CandidateCost {
    /// Which triangles it could cut: `wasteful` or `any` ([`crate::options::SplitTriangles::name`]), or `none`
    /// (built without split references).
    pub split_triangles: &'static str,
    /// What its optimizer's leaves were: `references` or `clusters` ([`crate::options::OptimizeOver::name`]), or
    /// `none` (not optimized).
    pub optimize_over: &'static str,
    /// Its cost under the choice's measure.
    pub cost: f64,
}
