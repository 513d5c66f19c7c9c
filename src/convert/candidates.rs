//! The conversion's stages from the triangles to the two trees before packing: build (with split references
//! where the options allow them), optimize, leaf layout. Where the options ask to choose (which triangles to
//! cut, what reinsertion moves), each candidate is made and the one whose cost is lowest is kept: the wide cost,
//! or with ray tuning the work a wide kernel does for held-out sample rays, which also judges whether
//! optimization and (with `choose`) splits pay.

use std::ops::ControlFlow;
use std::path::Path;
use std::time::{Duration, Instant};

use bvhc_loader::format::MAX_DEPTH;

use super::report::{CandidateCost, Choice, ConvertError, Event, Stage, Timings};
use crate::animation::{
    AnimationRecord, PoseReinsertion, PoseReinsertionReport, PoseSet, animation_record, average_cost, node_weights,
    optimize_for_poses, pose_boxes_of,
};
use crate::build_tree::BuildTree;
use crate::builders::sbvh::{SbvhParams, build_sbvh_keeping};
use crate::builders::split_triangles_keeping;
use crate::layout::{WideCosts, WideTree, cluster_roots, collapse, collapse_by, collapse_references};
use crate::optimize::{OptTree, OptimizeReport, Progress, StopReason, optimize, optimize_over_clusters};
use crate::options::preset::CLUSTER_SIZE;
use crate::options::{ConvertOptions, OptimizeOver, SplitMethod, SplitOptions, SplitTriangles};
use crate::sampling::{RaySample, SamplingSummary, sampled_wide_work, scene_is_sampled, tuned_weights};

/// A conversion's tree before packing: built, optimized and merged.
pub(super) struct Candidate {
    pub final_tree: BuildTree,
    pub wide_tree: Option<(WideTree, WideCosts)>,
    /// The GPU layout's collapse (leaves of at most 3), when the options write it.
    pub gpu_tree: Option<WideTree>,
    /// The references the tree was built over.
    pub reference_count: usize,
    pub optimization: Option<OptimizeReport>,
    /// With ray tuning: the wide kernel's mean cost for the held-out rays (of the GPU kernel without wide
    /// sections).
    pub sampled_cost: Option<f64>,
    /// With an animation: the trees' costs in each sampled pose.
    pub animation: Option<AnimationRecord>,
}

impl Candidate {
    /// What a [`Choice`] compares: the sampled cost, else with an animation the average cost over its poses,
    /// else the wide tree's cost, else the binary SAH.
    fn score(&self, options: &ConvertOptions) -> f64 {
        if let Some(costs) = self.animation.as_ref().and_then(|record| record.costs.as_ref()) {
            return costs.expected_wide_cost.unwrap_or(costs.expected_sah_cost);
        }
        match (&self.sampled_cost, &self.wide_tree) {
            (Some(cost), _) => *cost,
            (None, Some((wide, costs))) => wide.cost(costs),
            (None, None) => self.final_tree.sah_cost(options.optimize.constants).cost,
        }
    }
}

/// The tree a conversion writes, how it was chosen, and what its ray sampling did.
pub(super) struct Chosen {
    pub candidate: Candidate,
    pub choice: Option<Choice>,
    /// With ray tuning: the sample's sizes, or why it was skipped.
    pub sampling: Option<SamplingSummary>,
}

/// The candidates made so far and the lowest-scoring one.
struct Contest {
    /// (candidate, its score, its index in `costs`)
    best: Option<(Candidate, f64, usize)>,
    costs: Vec<CandidateCost>,
}

impl Contest {
    /// Enters `candidate`, made with `split_triangles` and `optimize_over` (see [`CandidateCost`]); it becomes the
    /// best when it scores strictly lower (the first is kept on a tie).
    fn enter(&mut self, candidate: Candidate, options: &ConvertOptions, labels: (&'static str, &'static str)) {
        let score = candidate.score(options);
        self.costs.push(CandidateCost { split_triangles: labels.0, optimize_over: labels.1, cost: score });
        if self.best.as_ref().is_none_or(|(_, lowest, _)| score < *lowest) {
            self.best = Some((candidate, score, self.costs.len() - 1));
        }
    }
}

/// Every candidate the options ask for (which triangles may be cut, what the optimizer's leaves are: one each
/// unless told to choose; with ray tuning also each build unoptimized, and with `choose` a build without
/// splits), built, optimized and merged, and the one whose [`Candidate::score`] is lowest (the first on a tie),
/// with the costs of all when there were several. A time budget is shared equally among the optimizations; a
/// cancelled optimization ends the search (its tree competes with those made before it).
#[allow(clippy::too_many_arguments)] // the part's arrays, then the conversion's context
pub(super) fn best_candidate(
    input: &Path,
    triangles: &[[[f32; 3]; 3]],
    whole: &[bool],
    poses: Option<&PoseSet>,
    options: &ConvertOptions,
    observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
    timings: &mut Timings,
) -> Result<Chosen, ConvertError> {
    // Scenes too small to sample are converted as without tuning (the sample says it skipped them).
    let judged_by_rays = options.ray_tuning.is_some() && scene_is_sampled(triangles.len());
    // Each build as the triangles it may cut: none (no splits), or whether any triangle may be cut.
    let builds: &[Option<bool>] = match options.splits.map(|s| s.triangles) {
        None => &[None],
        Some(SplitTriangles::Choose) if judged_by_rays => &[None, Some(false), Some(true)],
        Some(SplitTriangles::Choose) => &[Some(false), Some(true)],
        Some(SplitTriangles::Any) => &[Some(true)],
        Some(SplitTriangles::Wasteful) => &[Some(false)],
    };
    // Without optimization there is one tree a build.
    let over_clusters: &[bool] = match options.reinsertion {
        None | Some(OptimizeOver::References) => &[false],
        Some(OptimizeOver::Clusters) => &[true],
        Some(OptimizeOver::Choose) => &[false, true],
    };
    let unoptimized_too = judged_by_rays && options.reinsertion.is_some();
    let mut shared = options.clone();
    let optimizations = (builds.len() * over_clusters.len()) as u32;
    shared.optimize.time_budget = options.optimize.time_budget.map(|t| t / optimizations);
    let mut sample: Option<RaySample> = None;
    let mut contest = Contest { best: None, costs: Vec::new() };
    'search: for &cut in builds {
        let (mut built, reference_count) = build_stage(input, triangles, whole, &shared, cut, observer, timings)?;
        let cut_label = match cut {
            None => "none",
            Some(false) => SplitTriangles::Wasteful.name(),
            Some(true) => SplitTriangles::Any.name(),
        };
        if unoptimized_too {
            // Whether optimizing pays: this build as it is, judged beside its optimized trees.
            built.limit_depth(MAX_DEPTH);
            let made = Optimized { optimization: None, for_poses: None };
            let candidate = merge_stage(&built, reference_count, triangles, options, made, &mut sample, timings);
            contest.enter(candidate, options, (cut_label, "none"));
        }
        let mut built = Some(built);
        for (k, &clusters) in over_clusters.iter().enumerate() {
            // The last candidate of this build takes the tree; the others optimize a copy.
            let tree = if k + 1 < over_clusters.len() { built.clone() } else { built.take() };
            let Some(mut tree) = tree else { unreachable!("the built tree is taken by the last candidate only") };
            let optimization = optimize_stage(&mut tree, &shared, clusters, observer, timings);
            let for_poses = poses.map(|poses| optimize_for_animation(&mut tree, poses, &shared, timings));
            let made = Optimized { optimization, for_poses };
            let candidate = merge_stage(&tree, reference_count, triangles, &shared, made, &mut sample, timings);
            drop(tree);
            let cancelled = candidate.optimization.as_ref().is_some_and(|r| r.stop == StopReason::Cancelled);
            let over = if clusters { OptimizeOver::Clusters } else { OptimizeOver::References };
            contest.enter(candidate, options, (cut_label, over.name()));
            if cancelled {
                break 'search;
            }
        }
    }
    let Contest { best, costs } = contest;
    let Some((candidate, _, kept)) = best else { unreachable!("at least one candidate is made") };
    let measure = match (judged_by_rays, options.wide.is_some()) {
        (true, _) => "sampled_cost",
        (false, true) => "wide_cost",
        (false, false) => "sah_cost",
    };
    let choice = (costs.len() > 1).then_some(Choice { measure, kept, candidates: costs });
    // Made by the first merge whenever the options tune by rays.
    let sampling = sample.map(|sample| sample.summary);
    Ok(Chosen { candidate, choice, sampling })
}

/// The build stage: the initial tree and the number of references it holds. `cut` is `None` for a build without
/// split references, else whether any triangle worth cutting may be cut (else only triangles that waste a large
/// part of their box); split references need `options.splits`. The triangles `whole` marks are never cut.
fn build_stage(
    input: &Path,
    triangles: &[[[f32; 3]; 3]],
    whole: &[bool],
    options: &ConvertOptions,
    cut: Option<bool>,
    observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
    timings: &mut Timings,
) -> Result<(OptTree, usize), ConvertError> {
    let _ = observer(Event::Stage(Stage::Build));
    let clock = Instant::now();
    let too_large = |count: usize| ConvertError::TooLarge { path: input.to_path_buf(), count };
    let any_triangle = cut == Some(true);
    let (build, reference_count) = match cut.and(options.splits) {
        Some(SplitOptions { budget, method: SplitMethod::PreSplit, .. }) => {
            let ratio = if any_triangle { 0.0 } else { SplitMethod::PreSplit.wasteful_ratio() };
            let references = split_triangles_keeping(triangles, budget, ratio, whole);
            u32::try_from(references.len()).map_err(|_| too_large(references.len()))?;
            (options.builder.build_references(&references), references.len())
        }
        Some(SplitOptions { budget, method: SplitMethod::Sbvh, .. }) => {
            let ratio = if any_triangle { 0.0 } else { SplitMethod::Sbvh.wasteful_ratio() };
            let params = SbvhParams { min_waste_ratio: ratio, ..SbvhParams::with_budget(budget) };
            let build = build_sbvh_keeping(triangles, &params, whole);
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

/// The optimize stage of a conversion (its time added to `timings`): reinsertion over one reference a leaf, or
/// with `clusters` over the built tree's small subtrees ([`optimize_over_clusters`]), none without reinsertion;
/// the tree is then limited to the format's depth.
fn optimize_stage(
    tree: &mut OptTree,
    options: &ConvertOptions,
    clusters: bool,
    observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
    timings: &mut Timings,
) -> Option<OptimizeReport> {
    let _ = observer(Event::Stage(Stage::Optimize));
    let clock = Instant::now();
    let mut progress = |p: &Progress| observer(Event::Batch(p));
    let optimization = options.reinsertion.is_some().then(|| match clusters {
        true => {
            let roots = cluster_roots(tree, options.optimize.constants, CLUSTER_SIZE);
            optimize_over_clusters(tree, &options.optimize, &roots, &mut progress)
        }
        false => optimize(tree, &options.optimize, &mut progress),
    });
    timings.optimize += lap(clock);
    tree.limit_depth(MAX_DEPTH);
    optimization
}

/// What the optimize stage did to a candidate's tree.
struct Optimized<'p> {
    optimization: Option<OptimizeReport>,
    /// With an animation: its reinsertion for the poses.
    for_poses: Option<ForPoses<'p>>,
}

/// An animation's reinsertion: the poses, what it did, and each node's pose-averaged weight.
struct ForPoses<'p> {
    poses: &'p PoseSet,
    reinsertion: PoseReinsertionReport,
    weights: Vec<f64>,
}

/// The tree of an animation's candidate after the optimize stage, when reinsertion is on: reinserted for the
/// cost averaged over `poses` (its time added to the optimize stage's), limited to the format's depth again.
/// Returns what that did and each node's pose-averaged weight for the merge stage.
fn optimize_for_animation<'p>(
    tree: &mut OptTree,
    poses: &'p PoseSet,
    options: &ConvertOptions,
    timings: &mut Timings,
) -> ForPoses<'p> {
    let clock = Instant::now();
    let constants = options.optimize.constants;
    let mut boxes = pose_boxes_of(tree, &poses.triangles);
    let report = match options.reinsertion {
        Some(_) => optimize_for_poses(tree, &mut boxes, constants, &PoseReinsertion::default()),
        None => {
            let cost = average_cost(tree, &boxes, constants);
            PoseReinsertionReport { initial_cost: cost, final_cost: cost, rounds: 0, moves: 0, elapsed: Duration::ZERO }
        }
    };
    if tree.max_depth() > MAX_DEPTH {
        tree.limit_depth(MAX_DEPTH);
        boxes = pose_boxes_of(tree, &poses.triangles);
    }
    let weights = node_weights(&boxes, tree.nodes.len());
    timings.optimize += lap(clock);
    ForPoses { poses, reinsertion: report, weights }
}

/// The merge stage of one candidate (its time added to `timings`): the binary leaves merged, the wide and GPU
/// collapses, and with ray tuning the sample (made over this tree when it is the first), the collapses weighed by
/// its training rays and the candidate's [`Candidate::sampled_cost`] on its held-out rays. `made` is what the
/// optimize stage did and, for an animation, what its reinsertion for the poses did and the nodes' pose weights,
/// which the merging and collapses then weigh nodes by (the record of the poses' costs made here too).
fn merge_stage(
    tree: &OptTree,
    reference_count: usize,
    triangles: &[[[f32; 3]; 3]],
    options: &ConvertOptions,
    made: Optimized<'_>,
    sample: &mut Option<RaySample>,
    timings: &mut Timings,
) -> Candidate {
    let Optimized { optimization, for_poses } = made;
    let clock = Instant::now();
    let triangle_count = triangles.len();
    let repeats = reference_count > triangle_count;
    let sample = options.ray_tuning.map(|tuning| {
        &*sample.get_or_insert_with(|| RaySample::new(tree, triangles, &tuning, options.training_rays.as_ref()))
    });
    let sample = sample.filter(|s| s.is_sampled());
    let (animation, pose_weights) = match for_poses {
        Some(ForPoses { poses, reinsertion, weights }) => (Some((poses, reinsertion)), Some(weights)),
        None => (None, None),
    };
    let weights = match (options.ray_tuning, sample) {
        (Some(tuning), Some(sample)) => Some(tuned_weights(tree, triangles, &tuning, sample)),
        _ => pose_weights,
    };
    let weights = weights.as_deref();
    let constants = options.optimize.constants;
    let ((final_tree, wide_tree), gpu_tree) = rayon::join(
        || {
            let leaf_size = options.max_leaf_size();
            crate::layout::merge_and_collapse(
                tree,
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
                (Some(w), _) => collapse_by(tree, &gpu.wide_costs(), w, repeats),
                (None, true) => collapse_references(tree, &gpu.wide_costs()),
                (None, false) => collapse(tree, &gpu.wide_costs()),
            })
        },
    );
    // Judged by the kernel the file is for: the CPU wide layout, else the GPU one.
    let sampled_cost = sample.and_then(|sample| {
        let (wide, costs) = match (&wide_tree, &gpu_tree, options.gpu) {
            (Some((wide, costs)), _, _) => (wide, *costs),
            (None, Some(gpu_tree), Some(gpu)) => (gpu_tree, gpu.wide_costs()),
            _ => return None,
        };
        Some(sampled_wide_work(wide, triangles, &sample.held_out, costs.packet_width).cost_per_ray(&costs))
    });
    let animation = animation.map(|(poses, report)| {
        let wide = wide_tree.as_ref().map(|(tree, costs)| (tree, costs));
        let stored_wide = wide.map(|(tree, costs)| tree.cost(costs));
        let stored = final_tree.sah_cost(constants).cost;
        animation_record(poses, &final_tree, constants, wide, stored, stored_wide, &report)
    });
    timings.merge += lap(clock);
    Candidate { final_tree, wide_tree, gpu_tree, reference_count, optimization, sampled_cost, animation }
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
