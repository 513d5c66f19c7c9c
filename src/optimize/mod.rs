//! The optimize stage: BVH optimization by reinsertion.
//!
//! References: J. Bittner, M. Hapala, V. Havran, "Fast Insertion-Based Optimization of Bounding Volume
//! Hierarchies", Computer Graphics Forum 32(1):85-100, 2013 (the sequential reference loop); D. Meister,
//! J. Bittner, "Parallel Reinsertion for Bounding Volume Hierarchy Optimization", Computer Graphics Forum
//! 37(2):463-473, 2018 (the parallel loop's search without removal).
//!
//! Glossary: `SA` surface area; `C_D`, `C_I` direct and induced cost of an insertion (see `search`);
//! `M_SUM`, `M_MIN`, `M_AREA`, `M_COMB` the selection measures (see `select`); `k` the batch fraction; `p_R`,
//! `p_T` the stagnation limits (see `params`). Costs are `(c_T, c_I)` SAH costs from [`crate::cost`].
//!
//! Both loops keep the best tree seen (batch costs are not monotone) and return it; both are deterministic, and
//! the parallel one gives the same tree for any number of threads.

mod clusters;
mod edit_log;
mod invariants;
mod measure;
mod measure_index;
mod parallel;
mod params;
mod search;
mod select;
mod sequential;
mod tree;

use std::ops::ControlFlow;
use std::time::{Duration, Instant};

use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;
use serde::Serialize;

pub use clusters::optimize_over_clusters;
pub use edit_log::EditLog;
pub(crate) use measure::measure;
pub use measure::{Selection, is_eligible};
pub use measure_index::MeasureIndex;
pub use params::{Algorithm, OptimizeParams};
pub(crate) use search::Candidate;
pub use search::{Move, SearchQueue, best_in_subtree, best_insertion, best_move};
pub use select::{select_batch, select_batch_with};
pub use tree::{ChildrenFirst, NONE, OptNode, OptTree, TreeEdits, area};

use crate::cost::{SahConstants, SahCost, sah_of_sums};

/// Relative change below which the running cost of a batch (see [`EditLog`]) does not count as a new best.
const RUNNING_COST_TOLERANCE: f64 = 1e-12;

/// The relative gain below which a round of a scheduled sequence ends the sequence (see `Run::phase`), for
/// the parallel loop alone (`fast`, `balanced`). In the alternating loop (`max-quality`) a sequence ends only
/// at a round that gains nothing: there the small late rounds still pay (`docs/choices.md`).
const SEQUENCE_ROUND_GAIN: f64 = 5e-5;

/// What the optimizer reports after each batch.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Progress {
    /// Batches done.
    pub batch: u32,
    /// Cost after this batch.
    pub cost: f64,
    /// Lowest cost so far.
    pub best_cost: f64,
    /// Time since the optimizer started.
    #[serde(serialize_with = "seconds")]
    pub elapsed: Duration,
}

/// A duration as seconds (f64), for serde; also the animation optimizer's report's.
pub(crate) fn seconds<S: serde::Serializer>(d: &Duration, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(d.as_secs_f64())
}

/// Why the optimizer stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// `p_T` batches without progress.
    Converged,
    /// The time budget ran out.
    TimeBudget,
    /// The progress callback asked to stop.
    Cancelled,
    /// `max_batches` were run.
    MaxBatches,
    /// The tree is too small to change (fewer than two levels below the root).
    NothingToDo,
}

/// The outcome of [`optimize`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OptimizeReport {
    /// Cost of the input tree.
    pub initial: SahCost,
    /// Cost of the returned (best) tree.
    pub best: SahCost,
    /// Batches run.
    pub batches: u32,
    /// Reinsertions (sequential) or moves (parallel) applied.
    pub moves: u64,
    /// Wall-clock time.
    #[serde(serialize_with = "seconds")]
    pub elapsed: Duration,
    /// Why it stopped.
    pub stop: StopReason,
}

/// The cost of an optimizer tree (one triangle per leaf).
pub fn cost_of(tree: &OptTree, constants: SahConstants) -> SahCost {
    let (inner, leaves) = tree.area_sums();
    sah_of_sums(inner, leaves, tree.root_area(), constants)
}

/// Optimizes `tree` in place and leaves the best tree seen in it. `progress` is called after every batch;
/// returning `ControlFlow::Break` cancels (the best tree so far is kept).
pub fn optimize(
    tree: &mut OptTree,
    params: &OptimizeParams,
    progress: &mut dyn FnMut(&Progress) -> ControlFlow<()>,
) -> OptimizeReport {
    optimize_inspected(tree, params, progress, &mut |_| {})
}

/// [`optimize`], with `inspect` called on the tree after every batch (before its cost is taken): for property
/// tests that check [`OptTree::check_invariants`] after every round, and for debugging.
pub fn optimize_inspected(
    tree: &mut OptTree,
    params: &OptimizeParams,
    progress: &mut dyn FnMut(&Progress) -> ControlFlow<()>,
    inspect: &mut dyn FnMut(&OptTree),
) -> OptimizeReport {
    let mut run = Run::new(tree, params, inspect);
    let stop = match params.algorithm {
        Algorithm::Parallel | Algorithm::Sequential => run.phase(tree, params, SEQUENCE_ROUND_GAIN, progress),
        Algorithm::Alternating => 'cycles: loop {
            let cycle_start = run.report.best.cost;
            let first_cycle = run.report.batches == 0;
            let parallel = OptimizeParams { algorithm: Algorithm::Parallel, ..params.clone() };
            // The published loop with this run's selection, so that a chosen measure steers every phase.
            let reference = OptimizeParams {
                selection: params.selection,
                time_budget: params.time_budget,
                seed: params.seed,
                constants: params.constants,
                ..OptimizeParams::bittner_2013()
            };
            // One full sequential pass (every eligible node once, in measure order), then the published loop.
            let full_pass = OptimizeParams { batch_fraction: 1.0, stop_after: 1, ..reference.clone() };
            let converged = |cost: f64| cost >= cycle_start * (1.0 - params.min_relative_improvement.max(1e-6));
            let mut stop = StopReason::Converged;
            for phase in [&parallel, &full_pass, &reference] {
                stop = run.phase(tree, phase, 0.0, progress);
                if stop != StopReason::Converged {
                    break;
                }
                // A later cycle whose parallel rounds gain nothing from the tree the last sequential phases left
                // ends the run: its sequential phases would perturb the same local optimum again (on eight
                // scenes, the same trees in 20-35% less time: `docs/choices.md`).
                if !first_cycle && phase.algorithm == Algorithm::Parallel && converged(run.report.best.cost) {
                    break 'cycles StopReason::Converged;
                }
            }
            if stop != StopReason::Converged {
                break stop;
            }
            if converged(run.report.best.cost) {
                break StopReason::Converged;
            }
        },
    };
    run.finish(tree, stop, params.constants)
}

/// The state shared by the phases of one optimization: the edits since the best tree, counts, the clock.
struct Run<'i> {
    start: Instant,
    report: OptimizeReport,
    /// The current tree is the best one plus the edits in this log.
    edits: EditLog,
    /// Leaf areas and the root's area, which no move changes.
    leaf_area: f64,
    root_area: f64,
    rng: Pcg64Mcg,
    /// The measures of the parallel loop's partial rounds, once one ran; kept up to date from the edit log.
    measures: Option<MeasureIndex>,
    queue: SearchQueue,
    inspect: &'i mut dyn FnMut(&OptTree),
}

impl<'i> Run<'i> {
    fn new(tree: &OptTree, params: &OptimizeParams, inspect: &'i mut dyn FnMut(&OptTree)) -> Run<'i> {
        let (inner_area, leaf_area) = tree.area_sums();
        let root_area = tree.root_area();
        let initial = sah_of_sums(inner_area, leaf_area, root_area, params.constants);
        Run {
            start: Instant::now(),
            report: OptimizeReport {
                initial,
                best: initial,
                batches: 0,
                moves: 0,
                elapsed: Duration::ZERO,
                stop: StopReason::NothingToDo,
            },
            edits: EditLog::new(tree, inner_area),
            leaf_area,
            root_area,
            rng: Pcg64Mcg::seed_from_u64(params.seed),
            measures: None,
            queue: SearchQueue::default(),
            inspect,
        }
    }

    /// The cost of the current tree, from the running area sum.
    fn current_cost(&self, constants: SahConstants) -> SahCost {
        sah_of_sums(self.edits.inner_area(), self.leaf_area, self.root_area, constants)
    }

    /// Brings the measure index up to date with the edits since its last update (taking the edit log's touched
    /// list), or creates it, for a round whose selection uses it: unordered, not `Random`, less than every
    /// eligible node; returns whether it does. Other rounds leave the touched list to grow (at most one entry
    /// a node): updating the index after every batch of the sequential loop, which never reads it, made
    /// `max-quality` 5-10% slower on the dragon.
    fn sync_measures(&mut self, tree: &OptTree, selection: Selection, fraction: f64, ordered: bool) -> bool {
        if ordered || selection == Selection::Random || fraction >= 1.0 {
            return false;
        }
        let touched = self.edits.take_touched();
        match &mut self.measures {
            Some(index) if index.selection() == selection => index.update(tree, &touched),
            _ => self.measures = Some(MeasureIndex::new(tree, selection)),
        }
        true
    }

    /// Batches of one loop (`params.algorithm` is Parallel or Sequential) until one of the stop rules holds.
    fn phase(
        &mut self,
        tree: &mut OptTree,
        params: &OptimizeParams,
        sequence_round_gain: f64,
        progress: &mut dyn FnMut(&Progress) -> ControlFlow<()>,
    ) -> StopReason {
        let mut progress_cost = self.current_cost(params.constants).cost;
        let mut stagnant = 0u32;
        let scheduled = params.decreasing_fractions && params.algorithm != Algorithm::Sequential;
        let mut round = 0u32;
        loop {
            if self.report.batches >= params.max_batches {
                return StopReason::MaxBatches;
            }
            let selection = if stagnant >= params.random_after { Selection::Random } else { params.selection };
            let step = if scheduled { round % 16 } else { 0 };
            let fraction = params.batch_fraction / f64::from(2 * step + 1);
            round += 1;
            let ordered = params.algorithm == Algorithm::Sequential;
            let uses_index = self.sync_measures(tree, selection, fraction, ordered);
            let index = if uses_index { self.measures.as_ref() } else { None };
            let batch = select_batch_with(tree, selection, fraction, ordered, &mut self.rng, index);
            if batch.is_empty() {
                return StopReason::NothingToDo;
            }
            self.report.moves += match params.algorithm {
                Algorithm::Sequential => sequential::run_batch(tree, &batch, &mut self.queue, &mut self.edits),
                Algorithm::Parallel | Algorithm::Alternating => parallel::run_round(tree, &batch, &mut self.edits),
            };
            self.report.batches += 1;
            (self.inspect)(tree);
            let cost = self.current_cost(params.constants);
            // The running cost drifts from a fresh sum by rounding, so an "improvement" at that level is not
            // one: counting it could return a tree that a fresh sum prices above the initial one.
            let improved = cost.cost < self.report.best.cost * (1.0 - RUNNING_COST_TOLERANCE);
            let round_gain = 1.0 - cost.cost / self.report.best.cost;
            if improved {
                self.report.best = cost;
                self.edits.mark(tree);
            }
            // A sequence ends after its 16th round, or early at its first round that lowers the best cost by
            // less than `sequence_round_gain` (by nothing, where that is 0): the later, smaller rounds then mostly
            // move the same few nodes back and forth and gain less than they cost. The next sequence goes on from
            // the tree as it is (restoring the best tree first gave worse trees: `docs/choices.md`).
            let sequence_ends = step == 15 || !improved || round_gain < sequence_round_gain;
            if scheduled && sequence_ends {
                round = round.next_multiple_of(16);
            }
            let judged = !scheduled || sequence_ends;
            if judged && self.report.best.cost < progress_cost * (1.0 - params.min_relative_improvement) {
                progress_cost = self.report.best.cost;
                stagnant = 0;
            } else if judged {
                stagnant += 1;
            }
            let elapsed = self.start.elapsed();
            let now =
                Progress { batch: self.report.batches, cost: cost.cost, best_cost: self.report.best.cost, elapsed };
            if progress(&now).is_break() {
                return StopReason::Cancelled;
            }
            if stagnant >= params.stop_after {
                // Continue the next phase from the best tree, not from a worse last batch.
                self.edits.restore(tree);
                return StopReason::Converged;
            }
            if params.time_budget.is_some_and(|budget| elapsed >= budget) {
                return StopReason::TimeBudget;
            }
        }
    }

    fn finish(mut self, tree: &mut OptTree, stop: StopReason, constants: SahConstants) -> OptimizeReport {
        self.edits.restore(tree);
        // A fresh sum for the report (the running one differs by rounding only).
        self.report.best = cost_of(tree, constants);
        self.report.stop = stop;
        self.report.elapsed = self.start.elapsed();
        self.report
    }
}
