//! From a preset and the user's overrides to the complete options: every interaction of two settings is decided
//! here, and a setting the others would make inert is an error naming both (after ripgrep's split of parsed
//! flags from resolved options).

use std::time::Duration;

use super::{ConvertOptions, LeafMerge, OptimizeOver, Preset, SplitMethod, SplitOptions, SplitTriangles};
use crate::builders::Builder;
use crate::import::{ImportLimits, Instancing, SceneSelector};
use crate::optimize::Selection;

/// What the user set; `None` leaves the preset's choice. The command line's flags map one to one onto these.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overrides {
    /// Import: the glTF scene to convert.
    pub scene: Option<SceneSelector>,
    /// Import: the glTF scene as it stands at a time of an animation clip, or an OpenUSD stage at a time code.
    pub pose: Option<crate::import::Pose>,
    /// Import: the USD purposes kept besides `default`.
    pub purposes: Option<crate::import::Purposes>,
    /// The tree chosen for the average cost over poses of these clips (`--animation`, `--animation-poses`):
    /// turns off the preset's split references and instancing.
    pub animation: Option<crate::animation::Animation>,
    /// Poses sampled in each clip of `animation` (`--animation-poses`), instead of its `poses_per_clip`.
    pub animation_poses: Option<u32>,
    /// The part of each clip of `animation` sampled (`--animation-window`), instead of its `window`.
    pub animation_window: Option<crate::animation::TimeWindow>,
    /// Import: keep degenerate triangles.
    pub keep_degenerate: Option<bool>,
    /// Import: the resource budget.
    pub limits: Option<ImportLimits>,
    /// Import: follow glTF buffer URIs that leave the scene's folder.
    pub allow_buffers_outside_input_folder: Option<bool>,
    /// Import: which glTF meshes placed more than once stay instanced (format 1.3).
    pub instancing: Option<Instancing>,
    /// Import: which triangles the file marks not opaque.
    pub opacity: Option<crate::import::Opacity>,
    /// Build: the initial builder.
    pub builder: Option<Builder>,
    /// Splits: `Some(false)` makes none whatever the preset; `Some(true)` needs a budget from the preset or
    /// from `split_budget`.
    pub splits: Option<bool>,
    /// Splits: the budget (turns splits on under `fast`).
    pub split_budget: Option<f64>,
    /// Splits: where triangles are cut.
    pub split_method: Option<SplitMethod>,
    /// Splits: which triangles may be cut.
    pub split_triangles: Option<SplitTriangles>,
    /// `Some(false)`: no split references in geometry meant to deform (`--no-splits-deforming`).
    pub splits_deforming: Option<bool>,
    /// Optimize: `Some(false)` skips the optimizer.
    pub optimize: Option<bool>,
    /// Optimize: how batch nodes are ranked.
    pub selection: Option<Selection>,
    /// Optimize: a wall-clock budget (the result then depends on the machine's speed).
    pub time_budget: Option<Duration>,
    /// Optimize: what reinsertion moves.
    pub optimize_over: Option<OptimizeOver>,
    /// Leaves: `Some(false)` keeps one triangle a leaf.
    pub merge_leaves: Option<bool>,
    /// Leaves: the largest merged leaf.
    pub max_leaf_size: Option<usize>,
    /// Output: write the wide sections.
    pub wide: Option<bool>,
    /// Output: write the GPU sections (format 1.4).
    pub gpu_layout: Option<bool>,
    /// Leaves: tune the wide and GPU collapses to this many sampled training rays.
    pub tune_rays: Option<usize>,
    /// Leaves: tune the wide and GPU collapses to the user's rays (a ray file, read).
    pub train_rays: Option<crate::sampling::TrainingRays>,
    /// Output: write the triangle_ids and source_table sections.
    pub write_ids: Option<bool>,
    /// Output: write the source_vertices section (needs the ids; leaving the ids out leaves it out too).
    pub write_source_vertices: Option<bool>,
}

/// A setting that cannot be honoured.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum OptionsError {
    /// `setting` would have no effect because of `because`.
    #[error("{setting} does nothing with {because}: {advice}")]
    Inert {
        /// The setting that would be ignored.
        setting: String,
        /// The setting that makes it inert.
        because: String,
        /// What to do instead.
        advice: String,
    },
    /// No option has this name.
    #[error("{name}: not a conversion option (`bvhc options --list` lists them)")]
    Unknown {
        /// The name given.
        name: String,
    },
    /// `setting` has a value outside its range.
    #[error("{setting}: {why}")]
    Invalid {
        /// The setting.
        setting: String,
        /// The rule it breaks.
        why: String,
    },
}

impl OptionsError {
    /// `setting` would do nothing because of `because`; `advice` says what to do.
    pub(crate) fn inert(setting: &str, because: &str, advice: &str) -> OptionsError {
        OptionsError::Inert { setting: setting.into(), because: because.into(), advice: advice.into() }
    }

    pub(super) fn invalid(setting: &str, why: impl Into<String>) -> OptionsError {
        OptionsError::Invalid { setting: setting.into(), why: why.into() }
    }
}

/// The options of `preset` with `overrides` applied, checked: every setting given either takes effect or is an
/// error that names it and the setting that would make it inert.
pub fn resolve(preset: Preset, overrides: &Overrides) -> Result<ConvertOptions, OptionsError> {
    let o = overrides;
    let mut options = preset.options();
    if let Some(scene) = &o.scene {
        options.import.scene = Some(scene.clone());
    }
    match &o.pose {
        Some(crate::import::Pose::Clip(pose)) => options.import.pose = Some(pose.clone()),
        Some(crate::import::Pose::TimeCode(code)) => options.import.time_code = Some(*code),
        None => {}
    }
    if let Some(purposes) = o.purposes {
        options.import.purposes = purposes;
    }
    options.import.keep_degenerate = o.keep_degenerate.unwrap_or(options.import.keep_degenerate);
    if let Some(limits) = &o.limits {
        options.import.limits = limits.clone();
    }
    options.import.allow_buffers_outside_input_folder =
        o.allow_buffers_outside_input_folder.unwrap_or(options.import.allow_buffers_outside_input_folder);
    options.import.instancing = o.instancing.unwrap_or(options.import.instancing);
    options.import.opacity = o.opacity.unwrap_or(options.import.opacity);
    options.builder = o.builder.unwrap_or(options.builder);
    options.splits = resolve_splits(preset, o)?;
    if o.animation.is_some() {
        resolve_animation(o, &mut options)?;
    } else if o.animation_poses.is_some() || o.animation_window.is_some() {
        let setting = if o.animation_poses.is_some() { "--animation-poses" } else { "--animation-window" };
        return Err(OptionsError::invalid(setting, "needs --animation (it says how the animation is sampled)"));
    }
    options.reinsertion = resolve_reinsertion(preset, o)?;
    if let Some(selection) = o.selection {
        options.optimize.selection = selection;
    }
    options.optimize.time_budget = o.time_budget;
    options.leaves = resolve_leaves(o)?;
    if o.wide == Some(false) {
        options.wide = None;
    } else if o.wide == Some(true) {
        options.wide = Some(options.wide.unwrap_or_default());
    }
    match (o.tune_rays, &o.train_rays) {
        (Some(_), Some(_)) => {
            return Err(OptionsError::inert(
                "--tune-rays",
                "--train-rays",
                "the training rays come from the file; drop --tune-rays",
            ));
        }
        (Some(rays), None) => options.ray_tuning = Some(crate::sampling::RayTuning { rays, ..Default::default() }),
        (None, Some(file)) => {
            let training_file = Some(file.content_hash);
            let rays = file.rays.len();
            options.ray_tuning =
                Some(crate::sampling::RayTuning { rays, seed: 0, training_file, ..Default::default() });
            options.training_rays = Some(file.clone());
        }
        (None, None) => {}
    }
    if let Some(gpu_layout) = o.gpu_layout {
        options.gpu = gpu_layout.then(|| options.gpu.unwrap_or_default());
    }
    options.write_ids = o.write_ids.unwrap_or(options.write_ids);
    if o.write_source_vertices == Some(false) && o.write_ids == Some(false) {
        return Err(OptionsError::inert(
            "--no-source-vertices",
            "--no-ids",
            "without ids the source vertices are left out already; drop --no-source-vertices",
        ));
    }
    options.write_source_vertices =
        o.write_source_vertices.unwrap_or(options.write_source_vertices && options.write_ids);
    if o.builder == Some(Builder::SpatialMedian) && options.splits.is_some_and(|s| s.method == SplitMethod::Sbvh) {
        let because = if o.split_method.is_some() { "--split-method sbvh" } else { "the preset's SBVH splits" };
        return Err(OptionsError::inert(
            "--builder spatial-median",
            because,
            "the SBVH builds its own tree; add --no-splits or --split-method pre-split",
        ));
    }
    options.validate()?;
    Ok(options)
}

/// Refuses the first given setting of `settings` (given, name): `because` makes it inert.
fn refuse_any(settings: &[(bool, &str)], because: &str, advice: &str) -> Result<(), OptionsError> {
    match settings.iter().find(|(given, _)| *given) {
        Some((_, setting)) => Err(OptionsError::inert(setting, because, advice)),
        None => Ok(()),
    }
}

/// The split references: the preset's, turned off by `splits: Some(false)`, on with a budget given.
fn resolve_splits(preset: Preset, o: &Overrides) -> Result<Option<SplitOptions>, OptionsError> {
    if o.splits == Some(false) {
        let given = [
            (o.split_budget.is_some(), "--split-budget"),
            (o.split_method.is_some(), "--split-method"),
            (o.split_triangles.is_some(), "--split-triangles"),
            (o.splits_deforming.is_some(), "--no-splits-deforming"),
        ];
        refuse_any(&given, "--no-splits", "drop one of them")?;
        return Ok(None);
    }
    let from_preset = preset.splits();
    let Some(budget) = o.split_budget.or(from_preset.map(|s| s.budget)) else {
        let given = [
            (o.split_method.is_some(), "--split-method"),
            (o.split_triangles.is_some(), "--split-triangles"),
            (o.splits_deforming.is_some(), "--no-splits-deforming"),
        ];
        let because = format!("the {} preset, which makes no split references", preset.name());
        refuse_any(&given, &because, "add --split-budget FRACTION")?;
        if o.splits == Some(true) {
            return Err(OptionsError::invalid(
                "splits",
                format!("the {} preset has no split budget: give one", preset.name()),
            ));
        }
        return Ok(None);
    };
    let base = from_preset.unwrap_or(SplitOptions::with_budget(budget));
    Ok(Some(SplitOptions {
        budget,
        method: o.split_method.unwrap_or(base.method),
        triangles: o.split_triangles.unwrap_or(base.triangles),
        deforming: o.splits_deforming.unwrap_or(base.deforming),
    }))
}

/// `--animation`: no split references whatever the preset says; a split or ray-tuning setting given with it
/// would do nothing, and is refused naming it. `--instancing` stays the user's: `never` flattens the meshes the
/// clips move rigidly too (a one-level file).
fn resolve_animation(o: &Overrides, options: &mut ConvertOptions) -> Result<(), OptionsError> {
    let given = [
        (o.splits == Some(true), "--splits"),
        (o.split_budget.is_some(), "--split-budget"),
        (o.split_method.is_some(), "--split-method"),
        (o.split_triangles.is_some(), "--split-triangles"),
        (o.splits_deforming.is_some(), "--no-splits-deforming"),
        (o.tune_rays.is_some(), "--tune-rays"),
        (o.train_rays.is_some(), "--train-rays"),
    ];
    let advice = "an animation's tree is refit to every pose: its triangles are kept whole and its nodes weighed by \
                  the poses; drop the setting";
    refuse_any(&given, "--animation", advice)?;
    options.splits = None;
    options.animation = o.animation.clone().map(|mut animation| {
        animation.poses_per_clip = o.animation_poses.unwrap_or(animation.poses_per_clip);
        animation.window = o.animation_window.or(animation.window);
        animation
    });
    Ok(())
}

/// What reinsertion optimizes over, or `None` when optimization is off (then no optimizer setting may be given).
fn resolve_reinsertion(preset: Preset, o: &Overrides) -> Result<Option<OptimizeOver>, OptionsError> {
    if o.optimize == Some(false) {
        let given = [
            (o.selection.is_some(), "--selection"),
            (o.time_budget.is_some(), "--time-budget"),
            (o.optimize_over.is_some(), "--optimize-over"),
        ];
        refuse_any(&given, "--no-optimize", "drop one of them")?;
        return Ok(None);
    }
    Ok(Some(o.optimize_over.unwrap_or(preset.reinsertion())))
}

/// The binary leaves: merged up to the preset's or the given size, or not merged.
fn resolve_leaves(o: &Overrides) -> Result<LeafMerge, OptionsError> {
    match (o.merge_leaves, o.max_leaf_size) {
        (Some(false), Some(_)) => Err(OptionsError::inert("--max-leaf-size", "--no-merge", "drop one of them")),
        (Some(false), None) => Ok(LeafMerge::Off),
        (_, Some(0)) => Err(OptionsError::invalid("--max-leaf-size", "a leaf holds at least 1 triangle")),
        (_, Some(n)) if u32::try_from(n).is_err() => {
            Err(OptionsError::invalid("--max-leaf-size", format!("{n} is more than a leaf can hold (2^32 - 1)")))
        }
        (_, Some(n)) => Ok(LeafMerge::UpTo(n)),
        (_, None) => Ok(LeafMerge::UpTo(super::preset::MAX_LEAF_SIZE)),
    }
}
