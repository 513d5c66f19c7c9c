//! The conversion's stages from the triangles to the two trees before packing: build (with split references
//! where the options allow them), optimize, leaf layout. Where the options ask to choose (which triangles to
//! cut, what reinsertion moves), each candidate is made and the one whose wide cost is lowest is kept.

use std::ops::ControlFlow;
use std::path::Path;
use std::time::{Duration, Instant};

use bvhc_loader::format::MAX_DEPTH;

use super::report::{CandidateCost, Choice, ConvertError, Event, Stage, Timings};
use crate::build_tree::BuildTree;
use crate::builders::sbvh::{SbvhParams, build_sbvh};
use crate::builders::split_triangles_with;
use crate::layout::{WideCosts, WideTree, cluster_roots, collapse, collapse_by, collapse_references};
use crate::optimize::{OptTree, OptimizeReport, Progress, StopReason, optimize, optimize_over_clusters};
use crate::options::preset::CLUSTER_SIZE;
use crate::options::{ConvertOptions, OptimizeOver, SplitMethod, SplitOptions, SplitTriangles};

/// A conversion's tree before packing: built, optimized and merged.
pub(super) struct Candidate {
    pub final_tree: BuildTree,
    pub wide_tree: Option<(WideTree, WideCosts)>,
    /// The GPU layout's collapse (leaves of at most 3), when the options write it.
    pub gpu_tree: Option<WideTree>,
    /// The references the tree was built over.
    pub reference_count: usize,
    pub optimization: Option<OptimizeReport>,
}

impl Candidate {
    /// What a [`Choice`] compares: the wide tree's cost, or the binary SAH without wide sections.
    fn score(&self, options: &ConvertOptions) -> f64 {
        match &self.wide_tree {
            Some((wide, costs)) => wide.cost(costs),
            None => self.final_tree.sah_cost(options.optimize.constants).cost,
        }
    }
}

/// Every candidate the options ask for (which triangles may be cut, what the optimizer's leaves are: one each
/// unless told to choose), built, optimized and merged, and the one whose [`Candidate::score`] is lowest (the
/// first on a tie), with the costs of all when there were several. A time budget is shared equally; a
/// cancelled optimization ends the search (its tree competes with those made before it).
pub(super) fn best_candidate(
    input: &Path,
    triangles: &[[[f32; 3]; 3]],
    options: &ConvertOptions,
    observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
    timings: &mut Timings,
) -> Result<(Candidate, Option<Choice>), ConvertError> {
    let cut_any: &[bool] = match options.splits.map(|s| s.triangles) {
        Some(SplitTriangles::Choose) => &[false, true],
        Some(SplitTriangles::Any) => &[true],
        _ => &[false],
    };
    // Without optimization there is one tree.
    let over_clusters: &[bool] = match options.reinsertion {
        None | Some(OptimizeOver::References) => &[false],
        Some(OptimizeOver::Clusters) => &[true],
        Some(OptimizeOver::Choose) => &[false, true],
    };
    let mut shared = options.clone();
    let count = options.candidate_count() as u32;
    debug_assert_eq!(count as usize, cut_any.len() * over_clusters.len());
    shared.optimize.time_budget = options.optimize.time_budget.map(|t| t / count);
    // (candidate, its score, its index in `costs`)
    let mut best: Option<(Candidate, f64, usize)> = None;
    let mut costs = Vec::new();
    'search: for &any_triangle in cut_any {
        let (built, reference_count) = build_stage(input, triangles, &shared, any_triangle, observer, timings)?;
        let mut built = Some(built);
        for (k, &clusters) in over_clusters.iter().enumerate() {
            // The last candidate of this build takes the tree; the others optimize a copy.
            let tree = if k + 1 < over_clusters.len() { built.clone() } else { built.take() };
            let Some(tree) = tree else { unreachable!("the built tree is taken by the last candidate only") };
            let candidate = optimize_and_merge(tree, reference_count, triangles, &shared, clusters, observer, timings);
            let score = candidate.score(options);
            let cancelled = candidate.optimization.as_ref().is_some_and(|r| r.stop == StopReason::Cancelled);
            costs.push(CandidateCost {
                split_triangles: if any_triangle { SplitTriangles::Any } else { SplitTriangles::Wasteful },
                optimize_over: if clusters { OptimizeOver::Clusters } else { OptimizeOver::References },
                cost: score,
            });
            if best.as_ref().is_none_or(|(_, lowest, _)| score < *lowest) {
                best = Some((candidate, score, costs.len() - 1));
            }
            if cancelled {
                break 'search;
            }
        }
    }
    let Some((kept, _, kept_index)) = best else { unreachable!("at least one candidate is made") };
    let choice = (costs.len() > 1).then(|| Choice {
        measure: if options.wide.is_some() { "wide_cost" } else { "sah_cost" },
        kept: kept_index,
        candidates: costs,
    });
    Ok((kept, choice))
}

/// The build stage: the initial tree, cutting split references (where `options.splits` allows them) in any
/// triangle worth cutting when `any_triangle`, else only in triangles that waste a large part of their box;
/// and the number of references it holds.
fn build_stage(
    input: &Path,
    triangles: &[[[f32; 3]; 3]],
    options: &ConvertOptions,
    any_triangle: bool,
    observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
    timings: &mut Timings,
) -> Result<(OptTree, usize), ConvertError> {
    let _ = observer(Event::Stage(Stage::Build));
    let clock = Instant::now();
    let too_large = |count: usize| ConvertError::TooLarge { path: input.to_path_buf(), count };
    let (build, reference_count) = match options.splits {
        Some(SplitOptions { budget, method: SplitMethod::PreSplit, .. }) => {
            let ratio = if any_triangle { 0.0 } else { SplitMethod::PreSplit.wasteful_ratio() };
            let references = split_triangles_with(triangles, budget, ratio);
            u32::try_from(references.len()).map_err(|_| too_large(references.len()))?;
            (options.builder.build_references(&references), references.len())
        }
        Some(SplitOptions { budget, method: SplitMethod::Sbvh, .. }) => {
            let ratio = if any_triangle { 0.0 } else { SplitMethod::Sbvh.wasteful_ratio() };
            let params = SbvhParams { min_waste_ratio: ratio, ..SbvhParams::with_budget(budget) };
            let build = build_sbvh(triangles, &params);
            let reference_count = build.triangle_order.len();
            u32::try_from(reference_count).map_err(|_| too_large(reference_count))?;
            (build, reference_count)
        }
        None => (options.builder.build(triangles, 1), triangles.len()),
    };
    let tree = OptTree::from_build(build, triangles);
    timings.build += lap(clock);
    Ok((tree, reference_count))
}

/// The optimize and merge stages of a conversion (their times added to `timings`): reinsertion over one
/// reference a leaf, or with `clusters` over the built tree's small subtrees ([`optimize_over_clusters`]).
fn optimize_and_merge(
    mut tree: OptTree,
    reference_count: usize,
    triangles: &[[[f32; 3]; 3]],
    options: &ConvertOptions,
    clusters: bool,
    observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
    timings: &mut Timings,
) -> Candidate {
    let _ = observer(Event::Stage(Stage::Optimize));
    let clock = Instant::now();
    let mut progress = |p: &Progress| observer(Event::Batch(p));
    let optimization = options.reinsertion.is_some().then(|| match clusters {
        true => {
            let roots = cluster_roots(&tree, options.optimize.constants, CLUSTER_SIZE);
            optimize_over_clusters(&mut tree, &options.optimize, &roots, &mut progress)
        }
        false => optimize(&mut tree, &options.optimize, &mut progress),
    });
    timings.optimize += lap(clock);
    let clock = Instant::now();
    tree.limit_depth(MAX_DEPTH);
    let triangle_count = triangles.len();
    let repeats = reference_count > triangle_count;
    // With ray tuning, the collapses weigh nodes by the training rays that reach them (the binary leaves are
    // merged by SAH either way).
    let user_rays = options.training_rays.as_ref();
    let weights = options.ray_tuning.map(|tuning| crate::sampling::tuned_weights(&tree, triangles, &tuning, user_rays));
    let weights = weights.as_deref();
    let constants = options.optimize.constants;
    let ((final_tree, wide_tree), gpu_tree) = rayon::join(
        || {
            let leaf_size = options.max_leaf_size();
            crate::layout::merge_and_collapse(
                &tree,
                constants,
                leaf_size,
                options.wide,
                triangle_count,
                repeats,
                weights,
            )
        },
        || {
            options.gpu.map(|gpu| match (weights, repeats) {
                (Some(w), _) => collapse_by(&tree, &gpu.wide_costs(), w, repeats),
                (None, true) => collapse_references(&tree, &gpu.wide_costs()),
                (None, false) => collapse(&tree, &gpu.wide_costs()),
            })
        },
    );
    drop(tree);
    timings.merge += lap(clock);
    Candidate { final_tree, wide_tree, gpu_tree, reference_count, optimization }
}

/// The merge stage of a conversion: [`crate::layout::merge_and_collapse`] with the options' leaf size and
/// wide costs.
pub fn merge_and_collapse(
    tree: &OptTree,
    options: &ConvertOptions,
    triangle_count: usize,
    repeats: bool,
) -> (BuildTree, Option<(WideTree, WideCosts)>) {
    let constants = options.optimize.constants;
    let leaf_size = options.max_leaf_size();
    crate::layout::merge_and_collapse(tree, constants, leaf_size, options.wide, triangle_count, repeats, None)
}

pub(super) fn lap(start: Instant) -> f64 {
    Duration::as_secs_f64(&start.elapsed())
}
