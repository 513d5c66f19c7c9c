//! The inefficiency measures of Bittner et al. 2013 (section 4.1) that rank nodes for reinsertion, and which
//! nodes may be chosen.
//!
//! For an inner node `N` with children `L`, `R`: `M_SUM = SA(N) / ((SA(L) + SA(R)) / 2)`,
//! `M_MIN = SA(N) / min(SA(L), SA(R))`, `M_AREA = SA(N)`, `M_COMB = M_SUM * M_MIN * M_AREA`. Computed in f64
//! (the product overflows f32 on large scenes), divisions guarded with `max(eps, x)`. Eligible nodes are inner
//! nodes with a grandparent.

use serde::Serialize;

use super::tree::{NONE, OptTree};

/// How a batch's nodes are chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "snake_case")]
pub enum Selection {
    /// `M_COMB`: fewest batches to converge (Bittner et al.).
    #[default]
    Comb,
    /// `M_SUM`.
    Sum,
    /// `M_MIN`.
    Min,
    /// `M_AREA`.
    Area,
    /// Uniformly random eligible nodes (slowest to converge, escapes stagnation).
    Random,
}

impl Selection {
    /// Every strategy.
    pub const ALL: [Selection; 5] =
        [Selection::Comb, Selection::Sum, Selection::Min, Selection::Area, Selection::Random];

    /// The name used in options and reports.
    pub fn name(self) -> &'static str {
        match self {
            Selection::Comb => "comb",
            Selection::Sum => "sum",
            Selection::Min => "min",
            Selection::Area => "area",
            Selection::Random => "random",
        }
    }
}

const EPSILON: f64 = 1e-30;

/// The measure of an inner node with area `a` and children of areas `l`, `r` (larger: more in need of a fix).
pub(crate) fn measure(a: f32, l: f32, r: f32, selection: Selection) -> f64 {
    let (a, l, r) = (f64::from(a), f64::from(l), f64::from(r));
    let sum = a / (0.5 * (l + r)).max(EPSILON);
    let min = a / l.min(r).max(EPSILON);
    match selection {
        Selection::Comb => sum * min * a,
        Selection::Sum => sum,
        Selection::Min => min,
        Selection::Area | Selection::Random => a,
    }
}

/// Whether `i` may be chosen: an inner node with a grandparent, that is neither the root nor a child of the
/// root (only the root has no parent), which reads node `i` alone.
pub fn is_eligible(tree: &OptTree, i: u32) -> bool {
    let node = &tree.nodes[i as usize];
    node.left != NONE && i != tree.root && node.parent != tree.root
}
