//! The presets, in one place: what `fast`, `balanced` and `max-quality` set at every stage. The measurements
//! behind each choice are in `docs/evaluation.md`.
//!
//! | stage | fast | balanced (default) | max-quality |
//! |---|---|---|---|
//! | build | binned SAH | SBVH, budget [`SPLIT_BUDGET`], wasteful triangles | SBVH, budget [`SPLIT_BUDGET`], choose the triangles |
//! | optimize | one sequence of parallel rounds | parallel rounds until a sequence gains < 0.1% | parallel and sequential phases until a cycle gains < 0.02% |
//! | optimize over | clusters of up to [`CLUSTER_SIZE`] | clusters of up to [`CLUSTER_SIZE`] | clusters of up to [`CLUSTER_SIZE`] |
//! | leaves | up to [`MAX_LEAF_SIZE`] triangles | the same | the same |
//! | wide sections | 8-wide, [`WideCosts::default`] | the same | the same |

use super::{ConvertOptions, LeafMerge, OptimizeOver, SplitOptions, SplitTriangles};
use crate::builders::Builder;
use crate::import::ImportOptions;
use crate::layout::WideCosts;
use crate::optimize::{Algorithm, OptimizeParams};

/// Largest merged leaf of every preset (the reference table's M = 3 uses 8).
pub const MAX_LEAF_SIZE: usize = 8;

/// The split budget of `balanced` and `max-quality`: at most 30% more references. A cap rather than a target:
/// with the SBVH's thresholds the evaluated scenes used 0.1-2.7% more references at 0.1 and 0.3 alike.
pub const SPLIT_BUDGET: f64 = 0.3;

/// The clusters reinsertion optimizes over: the built tree's subtrees that leaf merging would make a leaf of at
/// most this many references (against 2, 3, 6 and 8, 4 gave the lowest wide cost on the architectural scenes).
pub const CLUSTER_SIZE: usize = 4;

/// Named option sets.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum Preset {
    /// No split references, one sequence of parallel rounds: most of the gain in a fraction of the time.
    Fast,
    /// The default: spatial splits, parallel rounds until a sequence gains less than 0.1%.
    #[default]
    Balanced,
    /// Spatial splits with both triangle choices, parallel and sequential phases until a cycle gains less than
    /// 0.02%: the lowest cost, in 2-5 times balanced's time.
    MaxQuality,
}

impl Preset {
    /// Every preset.
    pub const ALL: [Preset; 3] = [Preset::Fast, Preset::Balanced, Preset::MaxQuality];

    /// The name used in options and reports.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Fast => "fast",
            Preset::Balanced => "balanced",
            Preset::MaxQuality => "max-quality",
        }
    }

    /// The optimizer's parameters: all use the parallel loop with full rounds and differ in how long they persist
    /// (`max-quality` alternates it with the sequential loop of Bittner et al.).
    pub fn optimize_params(self) -> OptimizeParams {
        let balanced = OptimizeParams::default();
        match self {
            Preset::Fast => OptimizeParams { min_relative_improvement: 1.0, ..balanced },
            Preset::Balanced => balanced,
            Preset::MaxQuality => {
                OptimizeParams { algorithm: Algorithm::Alternating, min_relative_improvement: 2e-4, ..balanced }
            }
        }
    }

    /// The split references: none for `fast` (whose point is the conversion's speed: the SBVH build takes about
    /// four times the binned one), the SBVH within [`SPLIT_BUDGET`] otherwise; `max-quality` converts with both
    /// triangle choices and keeps the better tree.
    pub fn splits(self) -> Option<SplitOptions> {
        match self {
            Preset::Fast => None,
            Preset::Balanced => Some(SplitOptions::with_budget(SPLIT_BUDGET)),
            Preset::MaxQuality => {
                Some(SplitOptions { triangles: SplitTriangles::Choose, ..SplitOptions::with_budget(SPLIT_BUDGET) })
            }
        }
    }

    /// What reinsertion optimizes over: clusters for every preset (the architectural scenes render faster, the
    /// large conversions take half the optimization time; for `max-quality` trees over references won only on
    /// the bunny, by 0.7% of the wide cost, and took 2-5 times as long: `docs/choices.md`).
    pub fn reinsertion(self) -> OptimizeOver {
        OptimizeOver::Clusters
    }

    /// The complete options of this preset.
    pub fn options(self) -> ConvertOptions {
        ConvertOptions {
            preset: self,
            import: ImportOptions::default(),
            builder: Builder::BinnedSah,
            splits: self.splits(),
            optimize: self.optimize_params(),
            reinsertion: Some(self.reinsertion()),
            leaves: LeafMerge::UpTo(MAX_LEAF_SIZE),
            wide: Some(WideCosts::default()),
            gpu: None,
            ray_tuning: None,
            training_rays: None,
            animation: None,
            write_ids: true,
            write_source_vertices: true,
        }
    }
}
