//! Conversion options: one place turns a preset and the user's overrides into the complete, validated
//! [`ConvertOptions`] ([`resolve`]), for the command line and the build-script API alike. A setting that would do
//! nothing with the others (a leaf size without leaf merging, a node selection without optimization, a split
//! method without splits, ...) is refused there with an error that names both, never ignored. What each preset
//! sets is in [`preset`]; `bvhc options --preset NAME [flags]` prints the result without converting.

pub mod preset;
mod resolve;
pub mod listing;
mod parse;
mod settings;
mod spec;
pub mod table;
mod value;

pub use crate::import::Instancing;
pub use crate::sampling::{RayTuning, TrainingRays};
pub use preset::Preset;
pub use resolve::{OptionsError, Overrides, resolve};
pub use settings::Settings;
pub use spec::{Kind, OptionSpec, Stage};
pub use table::OPTIONS;
pub use value::OptionValue;

use crate::builders::Builder;
use crate::builders::{MAX_BUDGET, WASTEFUL_RATIO_PRE_SPLIT, WASTEFUL_RATIO_SBVH};
use crate::import::ImportOptions;
use crate::layout::{GpuCosts, WideCosts};
use crate::optimize::OptimizeParams;

/// Everything a conversion does, resolved and checked; [`ConvertOptions::preset`] (or [`resolve`] with
/// overrides) makes one, and `Default` is the balanced preset.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvertOptions {
    /// The preset these options started from (recorded in the metadata for reference).
    pub preset: Preset,
    /// Import options (glTF scene, degenerate triangles, resource limits).
    pub import: ImportOptions,
    /// The initial builder (without split references, or with pre-splitting; the SBVH builds its own tree).
    pub builder: Builder,
    /// Cut triangles into split references; `None`: one reference a triangle.
    pub splits: Option<SplitOptions>,
    /// The optimizer's parameters; their SAH constants also price leaf merging, so they are set without
    /// optimization too.
    pub optimize: OptimizeParams,
    /// What reinsertion optimizes over; `None`: the built tree is not optimized.
    pub reinsertion: Option<OptimizeOver>,
    /// The binary tree's leaves.
    pub leaves: LeafMerge,
    /// Write the wide sections of format 1.1, collapsed with these constants; `None` writes a 1.0 file.
    pub wide: Option<WideCosts>,
    /// Write the GPU sections of format 1.4 (compressed 8-wide nodes and their leaf triangles), collapsed with
    /// these constants; `None` writes none.
    pub gpu: Option<GpuCosts>,
    /// Tune the wide and GPU collapses to sampled rays (`crate::sampling`); `None`: by surface area.
    pub ray_tuning: Option<RayTuning>,
    /// The user's training rays (`--train-rays`), which replace the built-in ones; `ray_tuning` then names
    /// their file's hash.
    pub training_rays: Option<TrainingRays>,
    /// Choose the tree for the average cost over poses sampled from a glTF's animation clips (`--animation`);
    /// needs a file without split references or ray tuning (see [`crate::animation`]).
    pub animation: Option<crate::animation::Animation>,
    /// Write the triangle_ids and source_table sections.
    pub write_ids: bool,
    /// Write the source_vertices section of format 1.2 (each triangle's vertex indices in its source
    /// primitive); needs `write_ids`.
    pub write_source_vertices: bool,
}

impl Default for ConvertOptions {
    fn default() -> Self {
        ConvertOptions::preset(Preset::Balanced)
    }
}

impl ConvertOptions {
    /// The options of a preset, with nothing overridden.
    pub fn preset(preset: Preset) -> ConvertOptions {
        preset.options()
    }

    /// How many candidate trees the conversion may build and compare: two for each `choose` setting in use
    /// (split triangles: wasteful or any; reinsertion: over references or clusters), else one; with ray tuning
    /// (on scenes large enough to sample) each build is also a candidate unoptimized, and `choose` for split
    /// triangles also builds without splits.
    pub fn candidate_count(&self) -> usize {
        let tuned = self.ray_tuning.is_some();
        let cut_choices = match self.splits.map(|s| s.triangles) {
            Some(SplitTriangles::Choose) if tuned => 3,
            Some(SplitTriangles::Choose) => 2,
            _ => 1,
        };
        let over_choices = if self.reinsertion == Some(OptimizeOver::Choose) { 2 } else { 1 };
        let unoptimized = usize::from(tuned && self.reinsertion.is_some());
        cut_choices * (over_choices + unoptimized)
    }

    /// Checks the values: a leaf size of at least 1, a split budget from 0 to [`MAX_BUDGET`], wide constants the
    /// layout can hold, and no builder that the SBVH would ignore. [`resolve`] only returns options that pass.
    pub fn validate(&self) -> Result<(), OptionsError> {
        if let LeafMerge::UpTo(0) = self.leaves {
            return Err(OptionsError::invalid("--max-leaf-size", "a leaf holds at least 1 triangle"));
        }
        if let Some(splits) = self.splits {
            if !(0.0..=MAX_BUDGET).contains(&splits.budget) {
                let why = format!("{} is not a fraction from 0 to {MAX_BUDGET}", splits.budget);
                return Err(OptionsError::invalid("--split-budget", why));
            }
            if splits.method == SplitMethod::Sbvh && self.builder != Builder::BinnedSah {
                return Err(OptionsError::inert(
                    "--builder spatial-median",
                    "--split-method sbvh",
                    "the SBVH builds its own tree; add --no-splits or --split-method pre-split",
                ));
            }
        }
        if self.animation.is_some() {
            self.validate_animation()?;
        }
        if self.write_source_vertices && !self.write_ids {
            return Err(OptionsError::inert(
                "source vertices",
                "--no-ids",
                "the source_vertices section names vertices of the primitive a source id leads to; keep the ids \
                 or add --no-source-vertices",
            ));
        }
        if let Some(wide) = self.wide {
            let fits = (2..=8).contains(&wide.width)
                && (1..=8).contains(&wide.packet_width)
                && (1..=32).contains(&wide.max_leaf_size)
                && wide.node_visit > 0.0
                && wide.packet_test > 0.0;
            if !fits {
                return Err(OptionsError::invalid("wide", format!("{wide:?} does not fit the 8-wide layout")));
            }
        }
        let file_hash = self.training_rays.as_ref().map(|t| t.content_hash);
        if self.ray_tuning.map_or(file_hash.is_some(), |t| t.training_file != file_hash) {
            return Err(OptionsError::invalid(
                "--train-rays",
                "the training rays and ray_tuning.training_file disagree",
            ));
        }
        if let Some(tuning) = self.ray_tuning {
            if tuning.rays == 0 || tuning.prior.is_nan() || tuning.prior <= 0.0 {
                return Err(OptionsError::invalid(
                    "--tune-rays",
                    format!("{tuning:?}: at least one ray and a positive prior"),
                ));
            }
            if self.wide.is_none() && self.gpu.is_none() {
                let setting = if file_hash.is_some() { "--train-rays" } else { "--tune-rays" };
                return Err(OptionsError::inert(
                    setting,
                    "--no-wide without --gpu-layout",
                    "ray tuning steers the wide and GPU collapses; drop --no-wide or add --gpu-layout",
                ));
            }
        }
        if let Some(gpu) = self.gpu {
            let fits = (1..=3).contains(&gpu.max_leaf_size) && gpu.node_visit > 0.0 && gpu.triangle_test > 0.0;
            if !fits {
                return Err(OptionsError::invalid("gpu", format!("{gpu:?} does not fit the GPU layout")));
            }
            if self.import.instancing == crate::import::Instancing::Always {
                return Err(OptionsError::inert(
                    "--gpu-layout",
                    "--instancing always",
                    "the GPU sections of format 1.4 are for one-level files; drop one of them",
                ));
            }
        }
        Ok(())
    }

    /// An animation's tree is refit to every pose: whole triangles (a refit boxes a split reference by its whole
    /// triangle), nodes weighed by the poses (not by sampled rays), and the poses a clip from 1 to
    /// [`crate::animation::MAX_POSES`]. Under [`crate::import::Instancing::Always`] meshes the clips move rigidly
    /// stay instanced.
    fn validate_animation(&self) -> Result<(), OptionsError> {
        let because = "--animation";
        if self.splits.is_some() {
            return Err(OptionsError::inert(
                "split references",
                because,
                "a refit boxes each reference by its whole moved triangle; add --no-splits",
            ));
        }
        if self.ray_tuning.is_some() {
            return Err(OptionsError::inert(
                "ray tuning",
                because,
                "the collapses weigh nodes by the poses' areas; drop --tune-rays and --train-rays",
            ));
        }
        let poses = self.animation.as_ref().map_or(1, |a| a.poses_per_clip as usize);
        if !(1..=crate::animation::MAX_POSES).contains(&poses) {
            return Err(OptionsError::invalid(
                "--animation-poses",
                format!("{poses} is not from 1 to {}", crate::animation::MAX_POSES),
            ));
        }
        Ok(())
    }

    /// The largest binary leaf: `n` for [`LeafMerge::UpTo`], 1 without merging.
    pub fn max_leaf_size(&self) -> usize {
        match self.leaves {
            LeafMerge::Off => 1,
            LeafMerge::UpTo(n) => n.max(1),
        }
    }
}

/// The binary tree's leaves after optimization.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LeafMerge {
    /// One triangle (reference) a leaf, as optimized.
    Off,
    /// Merged bottom-up by SAH into leaves of up to this many triangles (at least 1).
    UpTo(usize),
}

/// What reinsertion optimizes over.
///
/// With one reference a leaf (Bittner et al.'s setting) the optimizer lowers the binary tree's inner areas but
/// breaks up the small subtrees the builder made, which become the file's leaves; over the builder's subtrees of
/// up to [`preset::CLUSTER_SIZE`] references ([`crate::optimize::optimize_over_clusters`]) those stay as built.
/// Which wins depends on the scene (`docs/evaluation.md`), hence `Choose`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum OptimizeOver {
    /// One reference a leaf.
    #[default]
    References,
    /// The built tree's subtrees of up to 4 references, kept as built.
    Clusters,
    /// Both, each optimized and merged; the tree whose wide cost is lower is written.
    Choose,
}

/// How a conversion splits references, and how many it may add.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SplitOptions {
    /// At most `budget * triangles` references beyond one a triangle (0.3: 30% more).
    pub budget: f64,
    /// Where the cuts are made.
    pub method: SplitMethod,
    /// Which triangles may be cut.
    #[serde(skip_serializing_if = "SplitTriangles::is_default")]
    pub triangles: SplitTriangles,
    /// Whether the triangles of geometry meant to deform (glTF primitives of skinned nodes or with morph
    /// targets) may be cut too; `false` keeps them whole, so that a refit of their records keeps tight boxes
    /// (`--no-splits-deforming`). Recorded only when `false`.
    #[serde(skip_serializing_if = "is_true")]
    pub deforming: bool,
}

/// Whether `value` is `true` (for serde's `skip_serializing_if`).
fn is_true(value: &bool) -> bool {
    *value
}

impl SplitOptions {
    /// The default method and triangles with `budget`.
    pub fn with_budget(budget: f64) -> SplitOptions {
        SplitOptions { budget, method: SplitMethod::default(), triangles: SplitTriangles::default(), deforming: true }
    }
}

/// Where triangles are cut into split references.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum SplitMethod {
    /// During the build, where a node's children would overlap (Stich et al. 2009).
    #[default]
    Sbvh,
    /// Before the build, large triangles at grid planes (Karras and Aila 2013).
    PreSplit,
}

impl SplitMethod {
    /// The name used in options and reports.
    pub fn name(self) -> &'static str {
        match self {
            SplitMethod::Sbvh => "sbvh",
            SplitMethod::PreSplit => "pre-split",
        }
    }

    /// The share of its box's area that cutting a triangle must be able to remove for it to count as
    /// wasteful ([`SplitTriangles::Wasteful`]) with this method.
    pub fn wasteful_ratio(self) -> f64 {
        match self {
            SplitMethod::Sbvh => WASTEFUL_RATIO_SBVH,
            SplitMethod::PreSplit => WASTEFUL_RATIO_PRE_SPLIT,
        }
    }
}

/// Which triangles a conversion may cut into split references.
///
/// Triangles that fill half of their box's face (the two halves of an axis-aligned rectangle) are the case that
/// matters: cutting them lowers the binary tree's SAH everywhere, but the wide tree that files are traced by
/// gets cheaper on some scenes and dearer on others, and no per-triangle threshold separates the two
/// (`docs/evaluation.md`). So `Choose` measures both trees.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum SplitTriangles {
    /// Only triangles whose pieces could remove a large part of their box's area.
    #[default]
    Wasteful,
    /// Any triangle the method finds worth cutting.
    Any,
    /// Both, each built, optimized and merged; the tree whose wide cost is lower is written.
    Choose,
}

impl SplitTriangles {
    /// The name used in options.
    pub fn name(self) -> &'static str {
        match self {
            SplitTriangles::Wasteful => "wasteful",
            SplitTriangles::Any => "any",
            SplitTriangles::Choose => "choose",
        }
    }

    fn is_default(&self) -> bool {
        *self == SplitTriangles::Wasteful
    }
}

impl OptimizeOver {
    /// The name used in options.
    pub fn name(self) -> &'static str {
        match self {
            OptimizeOver::References => "references",
            OptimizeOver::Clusters => "clusters",
            OptimizeOver::Choose => "choose",
        }
    }
}
