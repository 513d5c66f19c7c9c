//! Optimizer parameters and their defaults.

use std::time::Duration;

use serde::Serialize;

use super::measure::Selection;
use crate::cost::SahConstants;

/// Which optimization loop runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Algorithm {
    /// Rounds of moves searched in parallel on a frozen tree and applied by gain (after Meister and Bittner
    /// 2018); the same result for any number of threads.
    #[default]
    Parallel,
    /// Bittner et al. 2013 exactly: one node at a time removed and its children reinserted; single-threaded.
    /// The reference the parallel loop is checked against.
    Sequential,
    /// Cycles of three phases, each run until it converges: parallel rounds; one full sequential pass (every
    /// eligible node once, in measure order); the sequential loop with the published constants. Repeated while
    /// a cycle lowers the cost by more than `min_relative_improvement` (at least 1e-6): the sequential loop's
    /// forced reinsertions move the tree out of the parallel loop's local optimum. A cycle after the first ends
    /// the run as soon as its parallel rounds gain no more than that.
    Alternating,
}

/// Everything the optimizer can be told; the defaults are the `balanced` preset's.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OptimizeParams {
    /// The loop.
    pub algorithm: Algorithm,
    /// How batch nodes are ranked (switches to random after `random_after` batches without progress).
    pub selection: Selection,
    /// Fraction of the eligible inner nodes per batch (`k`; the paper's 1% = 0.01).
    pub batch_fraction: f64,
    /// Parallel loop only: round `r` takes `batch_fraction / (2 (r mod 16) + 1)` of the ranked nodes (the
    /// sequence obvhs uses: full rounds alternate with rounds on the most inefficient nodes only); a sequence
    /// ends early at a round that gains little (the parallel loop: less than 5e-5 of the cost; within
    /// `Alternating`: nothing), and the next goes on from the tree as it is. Progress is judged once per
    /// sequence; `random_after` and `stop_after` then count sequences.
    pub decreasing_fractions: bool,
    /// `p_R`: batches without progress before selection turns random (until the next progress).
    pub random_after: u32,
    /// `p_T`: batches without progress before the optimizer stops.
    pub stop_after: u32,
    /// A batch makes progress when it lowers the best cost by more than this fraction.
    pub min_relative_improvement: f64,
    /// Upper bound on batches.
    pub max_batches: u32,
    /// Wall-clock budget; the best tree so far is returned when it runs out.
    #[serde(serialize_with = "serialize_seconds")]
    pub time_budget: Option<Duration>,
    /// Seed of the random selection.
    pub seed: u64,
    /// SAH constants of the reported cost and of leaf merging.
    pub constants: SahConstants,
}

fn serialize_seconds<S: serde::Serializer>(budget: &Option<Duration>, s: S) -> Result<S::Ok, S::Error> {
    match budget {
        Some(d) => s.serialize_some(&d.as_secs_f64()),
        None => s.serialize_none(),
    }
}

impl Default for OptimizeParams {
    /// The parallel loop with full rounds (every eligible node a candidate: on this CPU that converges in far
    /// fewer rounds, and less time, than 1% batches), until a sequence gains less than 0.1%. The presets of
    /// [`crate::options::Preset`] vary how long it persists.
    fn default() -> Self {
        OptimizeParams {
            algorithm: Algorithm::Parallel,
            selection: Selection::Comb,
            batch_fraction: 1.0,
            decreasing_fractions: true,
            random_after: 2,
            stop_after: 1,
            min_relative_improvement: 1e-3,
            max_batches: 10_000,
            time_budget: None,
            seed: 0x6276_6863,
            constants: SahConstants::default(),
        }
    }
}

impl OptimizeParams {
    /// The sequential reference with the published constants of Bittner et al. 2013: `k = 1%`, `p_R = 5`,
    /// `p_T = 10`, selection by `M_COMB`.
    pub fn bittner_2013() -> OptimizeParams {
        OptimizeParams {
            algorithm: Algorithm::Sequential,
            batch_fraction: 0.01,
            decreasing_fractions: false,
            random_after: 5,
            stop_after: 10,
            min_relative_improvement: 0.0,
            ..OptimizeParams::default()
        }
    }
}
