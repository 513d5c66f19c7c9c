//! The build-script API: one conversion request (an input, an output, a preset and overrides), run with
//! [`Conversion::run`].
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
//! inputs and options, whatever the number of threads. The setters record overrides; [`Conversion::run`]
//! resolves them with the preset ([`crate::options::resolve`]) and refuses a setting that would do nothing.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Duration;

use super::files::{is_up_to_date, recorded_inputs, refuse_output_among};
use super::metadata::BuildRecord;
use super::pipeline::convert_with;
use super::report::{ConvertError, ConvertReport, Event};
use crate::builders::Builder;
use crate::import::{ImportLimits, Instancing, SceneSelector};
use crate::optimize::Selection;
use crate::options::{
    ConvertOptions, OptimizeOver, OptionValue, OptionsError, Overrides, Preset, Settings, SplitMethod, SplitTriangles,
};

/// One input, one output, a preset and overrides; [`Conversion::run`] does the work.
#[derive(Clone, Debug)]
pub struct Conversion {
    input: PathBuf,
    output: PathBuf,
    settings: Settings,
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
            settings: Settings::default(),
            force: false,
        }
    }

    /// The preset the overrides apply to.
    pub fn preset(mut self, preset: Preset) -> Self {
        self.settings.preset = preset;
        self
    }

    /// All overrides at once.
    pub fn overrides(mut self, overrides: Overrides) -> Self {
        self.settings.overrides = overrides;
        self
    }

    /// The preset and overrides at once (what the command line's flags, Python's keywords and a manifest's
    /// options set).
    pub fn settings(mut self, settings: Settings) -> Self {
        self.settings = settings;
        self
    }

    /// Sets the option `name` of the options table ([`crate::options::OPTIONS`]: the command line's long flags
    /// with `_` for `-`, a switch `true`), as the command line, Python and a manifest do:
    /// `.set("split_budget", 0.1)?.set("no_optimize", true)?`.
    pub fn set(mut self, name: &str, value: impl Into<OptionValue>) -> Result<Self, OptionsError> {
        self.settings.set(name, value)?;
        Ok(self)
    }

    /// The initial builder.
    pub fn builder(mut self, builder: Builder) -> Self {
        self.settings.overrides.builder = Some(builder);
        self
    }

    /// The optimizer's node selection (every phase of the preset's loop).
    pub fn selection(mut self, selection: Selection) -> Self {
        self.settings.overrides.selection = Some(selection);
        self
    }

    /// Whether to optimize the built tree.
    pub fn optimize(mut self, optimize: bool) -> Self {
        self.settings.overrides.optimize = Some(optimize);
        self
    }

    /// Largest merged leaf (at least 1).
    pub fn max_leaf_size(mut self, max_leaf_size: usize) -> Self {
        self.settings.overrides.max_leaf_size = Some(max_leaf_size);
        self
    }

    /// Whether to merge leaves.
    pub fn merge_leaves(mut self, merge: bool) -> Self {
        self.settings.overrides.merge_leaves = Some(merge);
        self
    }

    /// A wall-clock budget for the optimizer. Note: the result then depends on the machine's speed.
    pub fn time_budget(mut self, budget: Duration) -> Self {
        self.settings.overrides.time_budget = Some(budget);
        self
    }

    /// Which glTF meshes placed more than once stay instanced in a two-level file (format 1.3); default
    /// [`Instancing::Auto`].
    pub fn instancing(mut self, instancing: Instancing) -> Self {
        self.settings.overrides.instancing = Some(instancing);
        self
    }

    /// Which triangles the file marks not opaque (format 1.5's `triangle_flags`, read by hit filters); default
    /// [`Opacity::Materials`](crate::import::Opacity::Materials).
    pub fn opacity(mut self, opacity: crate::import::Opacity) -> Self {
        self.settings.overrides.opacity = Some(opacity);
        self
    }

    /// Keep degenerate triangles.
    pub fn keep_degenerate(mut self, keep: bool) -> Self {
        self.settings.overrides.keep_degenerate = Some(keep);
        self
    }

    /// Whether to write the triangle_ids and source_table sections.
    pub fn write_ids(mut self, write: bool) -> Self {
        self.settings.overrides.write_ids = Some(write);
        self
    }

    /// Whether to write the source_vertices section of format 1.2 (on by default; it needs the ids, so
    /// `write_ids(false)` leaves it out unless this asks for it, which is then an error).
    pub fn write_source_vertices(mut self, write: bool) -> Self {
        self.settings.overrides.write_source_vertices = Some(write);
        self
    }

    /// Whether to write the wide sections of format 1.1 (on by default); without them the file is version 1.0
    /// and traced by the binary kernel.
    pub fn write_wide(mut self, write: bool) -> Self {
        self.settings.overrides.wide = Some(write);
        self
    }

    /// Split references: `Some(budget)` cuts triangles into at most `budget * triangles` extra references;
    /// `None` keeps one a triangle, whatever the preset.
    pub fn splits(mut self, budget: Option<f64>) -> Self {
        self.settings.overrides.splits = Some(budget.is_some());
        self.settings.overrides.split_budget = budget;
        self
    }

    /// Where split references are cut.
    pub fn split_method(mut self, method: SplitMethod) -> Self {
        self.settings.overrides.split_method = Some(method);
        self
    }

    /// Which triangles split references are cut from.
    pub fn split_triangles(mut self, triangles: SplitTriangles) -> Self {
        self.settings.overrides.split_triangles = Some(triangles);
        self
    }

    /// What reinsertion optimizes over.
    pub fn optimize_over(mut self, over: OptimizeOver) -> Self {
        self.settings.overrides.optimize_over = Some(over);
        self
    }

    /// The glTF scene to convert.
    pub fn scene(mut self, scene: SceneSelector) -> Self {
        self.settings.overrides.scene = Some(scene);
        self
    }

    /// An OpenUSD stage read at this time code (time samples interpolated) instead of the default time.
    pub fn time_code(mut self, code: f64) -> Self {
        self.settings.overrides.pose = Some(crate::import::Pose::TimeCode(code));
        self
    }

    /// The USD purposes whose geometry is kept besides `default` (`render` unless set).
    pub fn purposes(mut self, purposes: crate::import::Purposes) -> Self {
        self.settings.overrides.purposes = Some(purposes);
        self
    }

    /// The import's resource budget (see [`ImportLimits`]; the defaults bound an import to a few GiB).
    pub fn import_limits(mut self, limits: ImportLimits) -> Self {
        self.settings.overrides.limits = Some(limits);
        self
    }

    /// Follow glTF buffer URIs that leave the scene's folder (off by default: an untrusted asset must not copy
    /// other files into the output).
    pub fn allow_buffers_outside_input_folder(mut self, allow: bool) -> Self {
        self.settings.overrides.allow_buffers_outside_input_folder = Some(allow);
        self
    }

    /// Convert even when the output is up to date.
    pub fn force(mut self, force: bool) -> Self {
        self.force = force;
        self
    }

    /// The options the conversion will use: the preset with the overrides, checked.
    pub fn resolved_options(&self) -> Result<ConvertOptions, ConvertError> {
        Ok(self.settings.resolve()?)
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
        let options = self.resolved_options()?;
        // Before the up-to-date check opens the output: a FIFO there would block it, and the output must never be
        // the input.
        bvhc_loader::write::check_replaceable(&self.output)?;
        refuse_output_among(&self.output, std::slice::from_ref(&self.input))?;
        if !self.force && is_up_to_date(&self.output, &self.input, &BuildRecord::of(&options)) {
            let files_read = recorded_inputs(&self.output, &self.input);
            return Ok(ConversionOutcome { files_read, up_to_date: true, report: None });
        }
        let report = convert_with(&self.input, &self.output, &options, observer)?;
        Ok(ConversionOutcome { files_read: report.files_read.clone(), up_to_date: false, report: Some(report) })
    }
}
