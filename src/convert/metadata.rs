//! The metadata section's JSON (`format-spec/metadata.schema.json`), as serde types whose shape is the schema's:
//! generator, format version, inputs (names relative to the input, content hashes), build options, cost, what
//! became of the scene's triangles, the wide sections' sizes and cost, the choice among candidate trees, and
//! what a two-level file instanced.
//! The `build` object ([`BuildRecord`]) is also what the up-to-date check compares.
//!
//! Keys are written in alphabetical order (through `serde_json::Value`), so the bytes do not depend on the order
//! of the fields here.

use serde::Serialize;

use super::report::{Choice, WideSummary};
use crate::builders::Builder;
use crate::cost::SahCost;
pub use crate::import::inputs::InputEntry;
use crate::import::{ImportReport, Instancing, Opacity, PoseSelector, Purposes, SceneSelector};
use crate::layout::{GpuCosts, WideCosts};
use crate::optimize::OptimizeParams;
use crate::options::{ConvertOptions, LeafMerge, OptimizeOver, Preset, SplitOptions};

/// The whole metadata object.
#[derive(Clone, Debug, Serialize)]
pub struct Metadata<'a> {
    /// `bvhc` and its version.
    pub generator: &'static str,
    /// `major.minor` of the file.
    pub format_version: String,
    /// Every file read: its name relative to the input's folder and its content hash.
    pub inputs: &'a [InputEntry],
    /// The options the file was built with.
    pub build: BuildRecord,
    /// The binary tree's SAH cost (one-level files; 1.3 defines none for two-level files).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cost: Option<CostRecord>,
    /// What became of the scene's triangles.
    pub triangles: TrianglesRecord,
    /// The wide sections' sizes and (one-level files) cost, when there are any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wide: Option<WideRecord>,
    /// How the written tree was chosen among candidates, when there were several (one-level files).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub choice: Option<&'a Choice>,
    /// With ray tuning (one-level files): the sample's sizes, or why it was skipped.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sampling: Option<&'a crate::sampling::SamplingSummary>,
    /// What a two-level file instanced.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub two_level: Option<TwoLevelRecord>,
    /// With `--animation`: the poses sampled and the written trees' costs in each.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub animation: Option<&'a crate::animation::AnimationRecord>,
    /// For an OpenUSD stage: the prim paths that source ranges and instances name, and the stage's units.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub usd: Option<&'a crate::import::StageRecord>,
}

/// The schema's `wide` object.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct WideRecord {
    node_count: usize,
    packet_count: usize,
    /// Absent in two-level files.
    #[serde(skip_serializing_if = "Option::is_none")]
    cost: Option<f64>,
}

impl WideRecord {
    /// A one-level file's wide sections, with their cost.
    pub fn of(summary: &WideSummary) -> WideRecord {
        WideRecord { node_count: summary.node_count, packet_count: summary.packet_count, cost: Some(summary.cost) }
    }

    /// A two-level file's wide sections: the meshes' together, without a cost.
    pub fn counts(node_count: usize, packet_count: usize) -> WideRecord {
        WideRecord { node_count, packet_count, cost: None }
    }
}

/// The schema's `two_level` object: what a conversion instanced (format 1.3).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TwoLevelRecord {
    /// The mode that decided (`build.instancing`, or `auto`).
    pub instancing: Instancing,
    /// The glTF meshes kept instanced, in the order of the file's meshes that place them.
    pub instanced_meshes: Vec<u32>,
    /// Meshes in the file: the instanced ones, and one more for the flattened rest when there is any.
    pub mesh_count: usize,
    /// Instances in the file.
    pub instance_count: usize,
    /// Triangles in the scene as placed (an instanced mesh's counted once a placement).
    pub placed_triangle_count: u64,
    /// Triangles flattened into world space (the file's first mesh when not 0).
    pub flattened_triangle_count: u64,
}

impl Metadata<'_> {
    /// The JSON text of the section.
    pub fn to_json(&self) -> String {
        serde_json::to_value(self).map(|value| value.to_string()).unwrap_or_default()
    }
}

/// The schema's `build` object: the resolved options as recorded, and the up-to-date key.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BuildRecord {
    builder: Builder,
    import: ImportRecord,
    /// 1 when leaves are not merged.
    max_leaf_size: usize,
    merge_leaves: bool,
    optimize: OptimizeParams,
    /// Absent for one reference a leaf.
    #[serde(skip_serializing_if = "Option::is_none")]
    optimize_over: Option<OptimizeOver>,
    preset: Preset,
    skip_optimization: bool,
    /// Absent for the default, `auto`.
    #[serde(skip_serializing_if = "Option::is_none")]
    instancing: Option<Instancing>,
    /// Absent for the default, `materials`.
    #[serde(skip_serializing_if = "Option::is_none")]
    opacity: Option<Opacity>,
    /// Absent without split references.
    #[serde(skip_serializing_if = "Option::is_none")]
    splits: Option<SplitOptions>,
    /// `null` without wide sections.
    wide: Option<WideCosts>,
    /// Absent without GPU sections.
    #[serde(skip_serializing_if = "Option::is_none")]
    gpu: Option<GpuCosts>,
    /// Absent when the collapses weigh nodes by surface area.
    #[serde(skip_serializing_if = "Option::is_none")]
    ray_tuning: Option<crate::sampling::RayTuning>,
    /// Absent unless the tree was chosen for an animation's poses.
    #[serde(skip_serializing_if = "Option::is_none")]
    animation: Option<crate::animation::Animation>,
    write_ids: bool,
    write_source_vertices: bool,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
struct ImportRecord {
    keep_degenerate: bool,
    scene: Option<SceneSelector>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pose: Option<PoseSelector>,
    #[serde(skip_serializing_if = "Option::is_none")]
    time_code: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    purposes: Option<Purposes>,
}

impl BuildRecord {
    /// The record of `options`. Without optimization, what reinsertion would have optimized over is recorded as
    /// the preset's (the optimizer's parameters are recorded either way).
    pub fn of(options: &ConvertOptions) -> BuildRecord {
        let (merge_leaves, max_leaf_size) = match options.leaves {
            LeafMerge::Off => (false, 1),
            LeafMerge::UpTo(n) => (true, n),
        };
        let over = options.reinsertion.unwrap_or(options.preset.reinsertion());
        BuildRecord {
            builder: options.builder,
            import: ImportRecord {
                keep_degenerate: options.import.keep_degenerate,
                scene: options.import.scene.clone(),
                pose: options.import.pose.clone(),
                time_code: options.import.time_code,
                purposes: (options.import.purposes != Purposes::default()).then_some(options.import.purposes),
            },
            instancing: (options.import.instancing != Instancing::Auto).then_some(options.import.instancing),
            opacity: (options.import.opacity != Opacity::Materials).then_some(options.import.opacity),
            max_leaf_size,
            merge_leaves,
            optimize: options.optimize.clone(),
            optimize_over: (over != OptimizeOver::References).then_some(over),
            preset: options.preset,
            skip_optimization: options.reinsertion.is_none(),
            splits: options.splits,
            wide: options.wide,
            gpu: options.gpu,
            ray_tuning: options.ray_tuning,
            animation: options.animation.clone(),
            write_ids: options.write_ids,
            write_source_vertices: options.write_source_vertices,
        }
    }

    /// The record as JSON, as the metadata holds it.
    pub fn to_value(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
}

/// The schema's `cost` object.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CostRecord {
    sah_cost: f64,
    c_t: f64,
    c_i: f64,
    inner_area_ratio: f64,
    leaf_area_ratio: f64,
}

impl CostRecord {
    /// `cost` under the options' SAH constants.
    pub fn of(cost: &SahCost, options: &ConvertOptions) -> CostRecord {
        CostRecord {
            sah_cost: cost.cost,
            c_t: options.optimize.constants.traversal,
            c_i: options.optimize.constants.intersection,
            inner_area_ratio: cost.inner_area_ratio,
            leaf_area_ratio: cost.leaf_area_ratio,
        }
    }
}

/// The schema's `triangles` object: the scene's triangles, those stored, and the degenerate ones dropped by kind
/// (or kept).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TrianglesRecord {
    source_triangle_count: u64,
    stored_count: u64,
    dropped: DroppedRecord,
    degenerate_kept: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
struct DroppedRecord {
    repeated_index: u64,
    zero_area: u64,
    zero_area_after_placement: u64,
}

impl TrianglesRecord {
    /// What the import reported, with degenerate triangles dropped unless `keep_degenerate`.
    pub fn of(import: &ImportReport, keep_degenerate: bool) -> TrianglesRecord {
        let dropped = |count: u64| if keep_degenerate { 0 } else { count };
        TrianglesRecord {
            source_triangle_count: import.source_triangles,
            stored_count: import.triangles,
            dropped: DroppedRecord {
                repeated_index: dropped(import.degenerate_repeated_index),
                zero_area: dropped(import.degenerate_zero_area),
                zero_area_after_placement: dropped(import.degenerate_zero_area_after_placement),
            },
            degenerate_kept: if keep_degenerate { import.degenerate() } else { 0 },
        }
    }
}
