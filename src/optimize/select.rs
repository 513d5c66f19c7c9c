//! Choosing the nodes of a batch: the inefficiency measures of Bittner et al. 2013 (section 4.1) or random.
//!
//! For an inner node `N` with children `L`, `R`: `M_SUM = SA(N) / ((SA(L) + SA(R)) / 2)`,
//! `M_MIN = SA(N) / min(SA(L), SA(R))`, `M_AREA = SA(N)`, `M_COMB = M_SUM * M_MIN * M_AREA`. Computed in f64
//! (the product overflows f32 on large scenes), divisions guarded with `max(eps, x)`. Eligible nodes are inner
//! nodes with a grandparent. Ranking is by measure, then by node index, so batches are deterministic.

use rand::RngExt;
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use serde::Serialize;

use super::tree::{NONE, OptTree};

/// How a batch's nodes are chosen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
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

/// The measure of inner node `i` (larger: more in need of a fix).
fn measure(tree: &OptTree, i: u32, selection: Selection) -> f64 {
    let node = &tree.nodes[i as usize];
    let a = f64::from(tree.area(i));
    let (l, r) = (f64::from(tree.area(node.left)), f64::from(tree.area(node.right)));
    let sum = a / (0.5 * (l + r)).max(EPSILON);
    let min = a / l.min(r).max(EPSILON);
    match selection {
        Selection::Comb => sum * min * a,
        Selection::Sum => sum,
        Selection::Min => min,
        Selection::Area | Selection::Random => a,
    }
}

/// Whether `i` may be chosen: an inner node with a grandparent.
pub fn is_eligible(tree: &OptTree, i: u32) -> bool {
    let node = &tree.nodes[i as usize];
    node.left != NONE && node.parent != NONE && tree.nodes[node.parent as usize].parent != NONE
}

/// The batch: `fraction` of the eligible nodes (at least one), most inefficient first.
pub fn select_batch(tree: &OptTree, selection: Selection, fraction: f64, rng: &mut Pcg64Mcg) -> Vec<u32> {
    let eligible: Vec<u32> = (0..tree.nodes.len() as u32).into_par_iter().filter(|&i| is_eligible(tree, i)).collect();
    if eligible.is_empty() {
        return eligible;
    }
    let k = ((eligible.len() as f64 * fraction).ceil() as usize).clamp(1, eligible.len());
    if selection == Selection::Random {
        let mut pool = eligible;
        for i in 0..k {
            let j = rng.random_range(i..pool.len());
            pool.swap(i, j);
        }
        pool.truncate(k);
        return pool;
    }
    let mut ranked: Vec<(f64, u32)> = eligible.par_iter().map(|&i| (measure(tree, i, selection), i)).collect();
    let by_measure = |a: &(f64, u32), b: &(f64, u32)| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1));
    if k < ranked.len() {
        ranked.select_nth_unstable_by(k, by_measure);
        ranked.truncate(k);
    }
    ranked.sort_unstable_by(by_measure);
    ranked.into_iter().map(|(_, i)| i).collect()
}
