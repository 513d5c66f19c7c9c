//! BVH optimization by reinsertion, and leaf merging.
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

mod merge;
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

pub use merge::merge_leaves;
pub use params::{Algorithm, OptimizeParams, Preset};
pub use search::{Move, SearchQueue, best_in_subtree, best_insertion, best_move};
pub use select::{Selection, is_eligible, select_batch};
pub use tree::{NONE, OptNode, OptTree, area};

use crate::cost::{SahConstants, SahCost, sah_of_sums};

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

fn seconds<S: serde::Serializer>(d: &Duration, s: S) -> Result<S::Ok, S::Error> {
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
    let start = Instant::now();
    let initial = cost_of(tree, params.constants);
    let mut report = OptimizeReport {
        initial,
        best: initial,
        batches: 0,
        moves: 0,
        elapsed: Duration::ZERO,
        stop: StopReason::NothingToDo,
    };
    let mut best_nodes = tree.nodes.clone();
    let mut best_root = tree.root;
    let mut progress_cost = initial.cost;
    let mut stagnant = 0u32;
    let mut rng = Pcg64Mcg::seed_from_u64(params.seed);
    let mut queue = SearchQueue::default();
    report.stop = loop {
        if report.batches >= params.max_batches {
            break StopReason::MaxBatches;
        }
        let selection = if stagnant >= params.random_after { Selection::Random } else { params.selection };
        let batch = select_batch(tree, selection, params.batch_fraction, &mut rng);
        if batch.is_empty() {
            break StopReason::NothingToDo;
        }
        report.moves += match params.algorithm {
            Algorithm::Sequential => sequential::run_batch(tree, &batch, &mut queue),
            Algorithm::Parallel => parallel::run_round(tree, &batch),
        };
        report.batches += 1;
        let cost = cost_of(tree, params.constants);
        if cost.cost < report.best.cost {
            report.best = cost;
            best_nodes.copy_from_slice(&tree.nodes);
            best_root = tree.root;
        }
        if cost.cost < progress_cost * (1.0 - params.min_relative_improvement) {
            progress_cost = cost.cost;
            stagnant = 0;
        } else {
            stagnant += 1;
        }
        let elapsed = start.elapsed();
        let now = Progress { batch: report.batches, cost: cost.cost, best_cost: report.best.cost, elapsed };
        if progress(&now).is_break() {
            break StopReason::Cancelled;
        }
        if stagnant >= params.stop_after {
            break StopReason::Converged;
        }
        if params.time_budget.is_some_and(|budget| elapsed >= budget) {
            break StopReason::TimeBudget;
        }
    };
    tree.nodes.copy_from_slice(&best_nodes);
    tree.root = best_root;
    report.elapsed = start.elapsed();
    report
}
