//! The build-script API: a builder-style conversion of one input into one output.
//!
//! ```no_run
//! // build.rs
//! let out = std::path::PathBuf::from(std::env::var("OUT_DIR").unwrap()).join("scene.bvh");
//! let outcome = bvhc::Conversion::new("assets/scene.gltf", &out).preset(bvhc::Preset::Balanced).run()?;
//! for file in &outcome.files_read {
//!     println!("cargo:rerun-if-changed={}", file.display());
//! }
//! # Ok::<(), bvhc::convert::ConvertError>(())
//! ```
//!
//! It never prints; it skips the work when the output is up to date (same inputs by content, same options,
//! same format version) unless forced; the output is written atomically and is byte-identical for identical
//! inputs and options, whatever the number of threads.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::builders::Builder;
use crate::convert::{ConvertError, ConvertOptions, ConvertReport, Event, convert_with};
use crate::import::{ImportLimits, SceneSelector};
use crate::optimize::{Preset, Selection};
use crate::up_to_date::is_up_to_date;

/// One input, one output, options; [`Conversion::run`] does the work.
#[derive(Clone, Debug)]
pub struct Conversion {
    input: PathBuf,
    output: PathBuf,
    options: ConvertOptions,
    force: bool,
}

/// What [`Conversion::run`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct ConversionOutcome {
    /// Every input file the conversion depends on (for `cargo:rerun-if-changed`), the input first.
    pub files_read: Vec<PathBuf>,
    /// The output was up to date and nothing was done.
    pub up_to_date: bool,
    /// The conversion's report, when it ran.
    pub report: Option<ConvertReport>,
}

impl Conversion {
    /// Converts `input` into `output` with the `balanced` preset.
    pub fn new(input: impl AsRef<Path>, output: impl AsRef<Path>) -> Conversion {
        Conversion {
            input: input.as_ref().to_path_buf(),
            output: output.as_ref().to_path_buf(),
            options: ConvertOptions::default(),
            force: false,
        }
    }

    /// Uses a preset's optimizer parameters and splits (other options are kept; call [`Conversion::splits`]
    /// after this to override the splits).
    pub fn preset(mut self, preset: Preset) -> Self {
        let constants = self.options.optimize.constants;
        self.options.preset = preset;
        self.options.splits = crate::convert::SplitOptions::for_preset(preset);
        self.options.optimize_over = crate::convert::OptimizeOver::for_preset(preset);
        self.options.optimize =
            crate::optimize::OptimizeParams { constants, ..crate::optimize::OptimizeParams::preset(preset) };
        self
    }

    /// The initial builder.
    pub fn builder(mut self, builder: Builder) -> Self {
        self.options.builder = builder;
        self
    }

    /// The optimizer's node selection.
    pub fn selection(mut self, selection: Selection) -> Self {
        self.options.optimize.selection = selection;
        self
    }

    /// Largest merged leaf (1 disables merging in effect).
    pub fn max_leaf_size(mut self, max_leaf_size: usize) -> Self {
        self.options.max_leaf_size = max_leaf_size.max(1);
        self
    }

    /// Whether to merge leaves.
    pub fn merge_leaves(mut self, merge: bool) -> Self {
        self.options.merge_leaves = merge;
        self
    }

    /// A wall-clock budget for the optimizer. Note: the result then depends on the machine's speed.
    pub fn time_budget(mut self, budget: Duration) -> Self {
        self.options.optimize.time_budget = Some(budget);
        self
    }

    /// Keep degenerate triangles.
    pub fn keep_degenerate(mut self, keep: bool) -> Self {
        self.options.import.keep_degenerate = keep;
        self
    }

    /// Whether to write the triangle_ids and source_table sections.
    pub fn write_ids(mut self, write: bool) -> Self {
        self.options.write_ids = write;
        self
    }

    /// Whether to write the wide sections of format 1.1 (on by default), collapsed with the default
    /// [`crate::layout::WideCosts`]; without them the file is version 1.0 and traced by the binary kernel.
    pub fn write_wide(mut self, write: bool) -> Self {
        self.options.wide = write.then(crate::layout::WideCosts::default);
        self
    }

    /// Split references: `Some(budget)` cuts triangles into at most `budget * triangles` extra references
    /// (see [`crate::builders::presplit`]), by the method set with [`Conversion::split_method`] (the SBVH unless told);
    /// `None` keeps one a triangle. Without this call the preset decides (the SBVH within
    /// [`crate::convert::DEFAULT_SPLIT_BUDGET`] except for `fast`).
    pub fn splits(mut self, budget: Option<f64>) -> Self {
        let (method, triangles) = self.options.splits.map(|s| (s.method, s.triangles)).unwrap_or_default();
        self.options.splits = budget.map(|budget| crate::convert::SplitOptions { budget, method, triangles });
        self
    }

    /// Where split references are cut (used when [`Conversion::splits`] turns them on).
    pub fn split_method(mut self, method: crate::convert::SplitMethod) -> Self {
        if let Some(splits) = &mut self.options.splits {
            splits.method = method;
        }
        self
    }

    /// Which triangles split references are cut from (used when splits are on; the preset decides otherwise:
    /// [`crate::convert::SplitTriangles::Choose`] for `max-quality`, `Wasteful` for `balanced`).
    pub fn split_triangles(mut self, triangles: crate::convert::SplitTriangles) -> Self {
        if let Some(splits) = &mut self.options.splits {
            splits.triangles = triangles;
        }
        self
    }

    /// What reinsertion optimizes over (the preset decides otherwise, see
    /// [`crate::convert::OptimizeOver::for_preset`]).
    pub fn optimize_over(mut self, over: crate::convert::OptimizeOver) -> Self {
        self.options.optimize_over = over;
        self
    }

    /// The glTF scene to convert.
    pub fn scene(mut self, scene: SceneSelector) -> Self {
        self.options.import.scene = Some(scene);
        self
    }

    /// The import's resource budget (see [`ImportLimits`]; the defaults bound an import to a few GiB).
    pub fn import_limits(mut self, limits: ImportLimits) -> Self {
        self.options.import.limits = limits;
        self
    }

    /// Follow glTF buffer URIs that leave the scene's folder (off by default: an untrusted asset must not copy
    /// other files into the output).
    pub fn allow_buffers_outside_input_folder(mut self, allow: bool) -> Self {
        self.options.import.allow_buffers_outside_input_folder = allow;
        self
    }

    /// Convert even when the output is up to date.
    pub fn force(mut self, force: bool) -> Self {
        self.force = force;
        self
    }

    /// Replaces all options.
    pub fn options(mut self, options: ConvertOptions) -> Self {
        self.options = options;
        self
    }

    /// The options in effect.
    pub fn current_options(&self) -> &ConvertOptions {
        &self.options
    }

    /// Runs the conversion (or recognizes that the output is up to date).
    pub fn run(&self) -> Result<ConversionOutcome, ConvertError> {
        self.run_with_progress(&mut |_| ControlFlow::Continue(()))
    }

    /// [`Conversion::run`], reporting stages and optimizer batches to `observer`, which may cancel.
    pub fn run_with_progress(
        &self,
        observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
    ) -> Result<ConversionOutcome, ConvertError> {
        // Before the up-to-date check opens the output: a FIFO there would block it, and the output must never be
        // the input.
        bvhc_loader::check_replaceable(&self.output)?;
        crate::convert::refuse_output_among(&self.output, std::slice::from_ref(&self.input))?;
        if !self.force && is_up_to_date(&self.output, &self.input, &self.options.recorded()) {
            let files_read = crate::convert::recorded_inputs(&self.output, &self.input);
            return Ok(ConversionOutcome { files_read, up_to_date: true, report: None });
        }
        let report = convert_with(&self.input, &self.output, &self.options, observer)?;
        Ok(ConversionOutcome { files_read: report.files_read.clone(), up_to_date: false, report: Some(report) })
    }
}
