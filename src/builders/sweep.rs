//! The binned sweep both top-down builders use to choose a split plane: bins along one axis, each with the box
//! of what fell into it and counts, and for each plane between bins the cost of the two sides (Wald 2007). The
//! binned SAH builder prices sides in f32 half areas, the SBVH in f64 surface areas, and the SBVH's spatial
//! splits count references that enter and leave each slab apart; the sweep is the same.

use super::reference::Box4;

/// The best plane of a sweep.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Plane<C> {
    /// Bins `..bin` are left of the plane, `bin..` right of it.
    pub bin: usize,
    /// The plane's cost.
    pub cost: C,
    /// The union of the left bins' boxes.
    pub left: Box4,
    /// The union of the right bins' boxes.
    pub right: Box4,
    /// What the left bins hold (the sum of their `enters`).
    pub left_count: u32,
}

/// The plane between bins of lowest `cost(left box, left count, right box, right count)`, the first on a tie,
/// over planes whose sides both hold something; `None` when no plane costs less than `ceiling`. The left side
/// counts `enters` of its bins and the right side `exits` of its bins (the same array for object splits; for
/// spatial splits a reference that spans several slabs enters in its first and exits in its last).
#[inline(always)]
pub(crate) fn best_plane<const N: usize, C: PartialOrd + Copy>(
    bounds: &[Box4; N],
    enters: &[u32; N],
    exits: &[u32; N],
    ceiling: C,
    cost: impl Fn(&Box4, u32, &Box4, u32) -> C,
) -> Option<Plane<C>> {
    // Sweep from the right to get the right sides, then from the left.
    let mut right_sides = [(Box4::EMPTY, 0u32); N];
    let mut right = (Box4::EMPTY, 0u32);
    for b in (1..N).rev() {
        right = (right.0.union(&bounds[b]), right.1 + exits[b]);
        right_sides[b] = right;
    }
    let mut best: Option<Plane<C>> = None;
    let mut lowest = ceiling;
    let mut left = (Box4::EMPTY, 0u32);
    for b in 1..N {
        left = (left.0.union(&bounds[b - 1]), left.1 + enters[b - 1]);
        let right = &right_sides[b];
        if left.1 == 0 || right.1 == 0 {
            continue;
        }
        let c = cost(&left.0, left.1, &right.0, right.1);
        if c < lowest {
            lowest = c;
            best = Some(Plane { bin: b, cost: c, left: left.0, right: right.0, left_count: left.1 });
        }
    }
    best
}
