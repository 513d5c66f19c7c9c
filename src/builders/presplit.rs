//! Pre-splitting: large triangles cut into pieces before the build, each piece a *reference* (the triangle's
//! index and a box that contains the piece), so that the tree bounds long and diagonal triangles by several
//! small boxes instead of one large one.
//!
//! After T. Karras and T. Aila, "Fast Parallel Construction of High-Quality Bounding Volume Hierarchies", High
//! Performance Graphics 2013, section 5 (triangle splitting; the idea, not their code):
//! - planes come from a grid over the scene's box halved level by level on each axis; a box is cut at the
//!   plane of the coarsest level that crosses it (ties: the axis along which the box is longest), because the
//!   top of a top-down tree splits near those planes, and a triangle straddling one lands high in the tree;
//! - a triangle's priority is `((A_box - A_ideal) / A_scene)^(1/3)` (0 unless `A_box - A_ideal` is at least
//!   the method's wasteful ratio of `A_box`, [`super::WASTEFUL_RATIO_PRE_SPLIT`] by default: a measured choice,
//!   not the paper's), `A_box` the surface area of its box and `A_ideal` the limit of its pieces' summed box
//!   areas (twice its area projected onto the three axis planes): the area splitting can remove. (Karras and
//!   Aila also weight by `2^-k`, `k` the level of the triangle's plane; that gave worse start trees here);
//! - a budget of `budget * n` extra references is shared as `floor(lambda * priority)` splits a triangle, with
//!   the largest `lambda` that fits (found by bisection); a triangle's splits are spent recursively, each
//!   piece at its own coarsest plane, the rest shared between the two sides in proportion to their box areas.
//!
//! Pieces are exact (see [`crate::geometry::clip`]): every piece's box contains it, and a triangle's pieces
//! together are the triangle, which is what makes a tree over references safe to trace (the format's rule V25).
//! Deterministic: every triangle is split on its own, and the budget's bisection sums whole numbers.
//!
//! A leaf that gathers several pieces of one triangle holds it once, with the two trees' record counts kept
//! equal ([`crate::layout::records`]). Conversions cut during the build by default ([`super::sbvh`]);
//! pre-splitting is `--split-method pre-split`.

use rayon::prelude::*;

use crate::geometry::Aabb;
use crate::geometry::clip::{Piece, ideal_box_area};

/// Most splits one triangle gets, whatever its priority (so one huge triangle cannot take the whole budget).
pub const MAX_SPLITS_PER_TRIANGLE: u32 = 64;
/// Finest grid level a plane is taken from: below it boxes are too small for a split to matter in f32.
const FINEST_LEVEL: u32 = 20;

/// The references of a scene: reference `r` is a piece of triangle `triangle[r]` inside `aabb[r]`. Ordered by
/// triangle (a triangle's pieces together, in the order of its recursive splitting).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct References {
    /// The triangle of each reference.
    pub triangle: Vec<u32>,
    /// The box of each reference (it contains the reference's piece of the triangle).
    pub aabb: Vec<Aabb>,
}

impl References {
    /// The number of references.
    pub fn len(&self) -> usize {
        self.triangle.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.triangle.is_empty()
    }
}

/// The largest budget [`split_triangles`] honours (at most five references a triangle on average).
pub const MAX_BUDGET: f64 = 4.0;

/// Splits the triangles into at most `(1 + budget) * n` references (`budget` from 0 to [`MAX_BUDGET`], e.g. 0.3
/// for 30% more; larger budgets are taken as `MAX_BUDGET`, negative or NaN ones as 0).
pub fn split_triangles(triangles: &[[[f32; 3]; 3]], budget: f64) -> References {
    split_triangles_with(triangles, budget, super::WASTEFUL_RATIO_PRE_SPLIT)
}

/// [`split_triangles`] with another waste threshold than [`super::WASTEFUL_RATIO_PRE_SPLIT`]: only triangles whose pieces could
/// remove at least `min_waste_ratio` of their box's area are cut (0: any triangle a grid plane crosses).
pub fn split_triangles_with(triangles: &[[[f32; 3]; 3]], budget: f64, min_waste_ratio: f64) -> References {
    split_triangles_keeping(triangles, budget, min_waste_ratio, &[])
}

/// [`split_triangles_with`] leaving whole every triangle `t` with `whole[t]` (geometry meant to deform; a
/// shorter `whole` leaves the rest free to be cut).
pub fn split_triangles_keeping(
    triangles: &[[[f32; 3]; 3]],
    budget: f64,
    min_waste_ratio: f64,
    whole: &[bool],
) -> References {
    let budget = if budget.is_nan() { 0.0 } else { budget.clamp(0.0, MAX_BUDGET) };
    let scene = triangles.par_iter().map(Aabb::of_triangle).reduce(|| Aabb::EMPTY, |a, b| a.union(&b));
    let grid = Grid::new(&scene);
    let scene_area = scene.surface_area();
    let priorities: Vec<f64> = triangles
        .par_iter()
        .enumerate()
        .map(|(t, v)| if whole.get(t) == Some(&true) { 0.0 } else { priority(v, &grid, scene_area, min_waste_ratio) })
        .collect();
    let extra = (budget * triangles.len() as f64) as u64;
    let lambda = largest_lambda(&priorities, extra);
    let pieces: Vec<(u32, Aabb)> = triangles
        .par_iter()
        .zip(&priorities)
        .enumerate()
        .flat_map_iter(|(t, (vertices, &p))| {
            let mut out = Vec::new();
            let splits = splits_for(p, lambda);
            split_recursively(Piece::of_triangle(vertices), splits, &grid, &mut |aabb| out.push((t as u32, aabb)));
            out
        })
        .collect();
    let (triangle, aabb) = pieces.into_iter().unzip();
    References { triangle, aabb }
}

/// The splits a triangle of priority `p` gets with scale `lambda`.
fn splits_for(p: f64, lambda: f64) -> u32 {
    let s = (p * lambda).floor();
    if s >= 1.0 { (s as u32).min(MAX_SPLITS_PER_TRIANGLE) } else { 0 }
}

/// The largest scale whose splits sum to at most `extra`, to a relative precision of about 2^-40 (bisection on
/// a log scale; the sums are whole numbers, so the result is the same on any number of threads).
fn largest_lambda(priorities: &[f64], extra: u64) -> f64 {
    let total = |lambda: f64| priorities.par_iter().map(|&p| u64::from(splits_for(p, lambda))).sum::<u64>();
    let max_priority = priorities.iter().cloned().fold(0.0f64, f64::max);
    let min_priority = priorities.iter().cloned().filter(|&p| p > 0.0).fold(f64::INFINITY, f64::min);
    if extra == 0 || max_priority <= 0.0 {
        return 0.0;
    }
    // At `high` every triangle with a priority is at its cap; at `low` only the highest get a split.
    let high = f64::from(MAX_SPLITS_PER_TRIANGLE + 1) / min_priority;
    if total(high) <= extra {
        return high;
    }
    let (mut low, mut high) = (1.0 / max_priority, high);
    if total(low) > extra {
        return 0.0;
    }
    for _ in 0..48 {
        let mid = (low * high).sqrt();
        if total(mid) <= extra {
            low = mid;
        } else {
            high = mid;
        }
    }
    low
}

/// `((A_box - A_ideal) / A_scene)^(1/3)`, 0 for a triangle no grid plane crosses or that wastes less than
/// `min_waste_ratio` of its box.
fn priority(vertices: &[[f32; 3]; 3], grid: &Grid, scene_area: f64, min_waste_ratio: f64) -> f64 {
    let aabb = Aabb::of_triangle(vertices);
    if grid.plane_for(&aabb).is_none() {
        return 0.0;
    }
    if scene_area <= 0.0 || !worth_cutting(vertices, min_waste_ratio) {
        return 0.0;
    }
    ((aabb.surface_area() - ideal_box_area(vertices)) / scene_area).cbrt()
}

/// Whether pieces of the triangle could remove at least `min_waste_ratio` of its box's area: `A_box -
/// A_ideal >= min_waste_ratio * A_box` with `A_box > 0` ([`clip::ideal_box_area`]).
pub(crate) fn worth_cutting(vertices: &[[f32; 3]; 3], min_waste_ratio: f64) -> bool {
    let box_area = Aabb::of_triangle(vertices).surface_area();
    box_area > 0.0 && box_area - ideal_box_area(vertices) >= min_waste_ratio * box_area
}

/// Cuts `piece` with `splits` planes in all (fewer where no plane crosses a piece) and hands out each final
/// piece's box.
fn split_recursively(piece: Piece, splits: u32, grid: &Grid, emit: &mut impl FnMut(Aabb)) {
    let plane = if splits == 0 { None } else { grid.plane_for(&piece.aabb) };
    let Some((axis, position, _)) = plane else {
        emit(piece.aabb);
        return;
    };
    let (below, above) = piece.cut(axis, position);
    let rest = splits - 1;
    // A box is a step wider than its piece where the piece's sides came from clipping, so a plane can fall in
    // that margin and leave one side empty: the other side is then the whole piece, with a tighter box.
    if below.corners.is_empty() || above.corners.is_empty() {
        let whole = if below.corners.is_empty() { above } else { below };
        split_recursively(whole, rest, grid, emit);
        return;
    }
    let (a_below, a_above) = (below.aabb.surface_area(), above.aabb.surface_area());
    let to_below = if a_below + a_above > 0.0 {
        ((f64::from(rest) * a_below / (a_below + a_above)).round() as u32).min(rest)
    } else {
        rest / 2
    };
    split_recursively(below, to_below, grid, emit);
    split_recursively(above, rest - to_below, grid, emit);
}

/// The planes: on each axis, `low + j * extent / 2^k` for level `k` >= 1 and `0 < j < 2^k`.
struct Grid {
    low: [f64; 3],
    extent: [f64; 3],
}

impl Grid {
    fn new(scene: &Aabb) -> Grid {
        Grid {
            low: std::array::from_fn(|a| f64::from(scene.min[a])),
            extent: std::array::from_fn(|a| (f64::from(scene.max[a]) - f64::from(scene.min[a])).max(0.0)),
        }
    }

    /// The plane of the coarsest level that lies strictly inside `aabb` on some axis: `(axis, position,
    /// level)`; ties between axes go to the axis along which the box is longest, then the lowest axis. The
    /// position is an f32 value strictly between the box's sides.
    fn plane_for(&self, aabb: &Aabb) -> Option<(usize, f32, u32)> {
        let mut best: Option<(usize, f32, u32)> = None;
        for axis in 0..3 {
            let Some((position, level)) = self.plane_on(aabb, axis) else { continue };
            let longer = |other: usize| aabb.max[axis] - aabb.min[axis] > aabb.max[other] - aabb.min[other];
            match best {
                Some((other, _, best_level)) if level > best_level || (level == best_level && !longer(other)) => {}
                _ => best = Some((axis, position, level)),
            }
        }
        best
    }

    /// The one plane of the coarsest level that crosses `aabb` on `axis` (at the level before it none does, so
    /// at this level exactly one line lies between the box's sides), if its f32 position is strictly inside.
    fn plane_on(&self, aabb: &Aabb, axis: usize) -> Option<(f32, u32)> {
        let (min, max) = (aabb.min[axis], aabb.max[axis]);
        let extent = self.extent[axis];
        if extent <= 0.0 || min >= max {
            return None;
        }
        let u_min = (f64::from(min) - self.low[axis]) / extent;
        let u_max = (f64::from(max) - self.low[axis]) / extent;
        for level in 1..=FINEST_LEVEL {
            let cells = f64::from(1u32 << level);
            let line = (u_min * cells).floor() + 1.0;
            if line > (u_max * cells).floor() {
                continue;
            }
            let position = (self.low[axis] + line / cells * extent) as f32;
            if min < position && position < max {
                return Some((position, level));
            }
        }
        None
    }
}
