//! Exact pieces of a triangle cut by axis-aligned planes, and f32 boxes that always contain them.
//!
//! A piece is a convex polygon kept in f64 (Sutherland and Hodgman's clipping, both sides of one plane at once).
//! Its box is rounded outward to f32 and widened by one more f32 step on every side that did not come from the
//! cutting plane: the f64 clip points are off the true ones by a few units in the 53rd bit, far below one step
//! of the 24-bit f32 grid, so the widened box contains the true piece. Along the cut the pieces end exactly at
//! the plane (an f32 value), so the two sides' boxes meet there without overlapping. Every box is also clipped
//! to the box of the piece it was cut from, which contains it too.

use glam::DVec3;

use super::Aabb;

/// A convex polygon in f64: a triangle, or a piece of one.
#[derive(Clone, Debug, PartialEq)]
pub struct Piece {
    /// The corners in order (at least 3 for a piece with area; a cut through a corner may leave fewer).
    pub corners: Vec<[f64; 3]>,
    /// A box that contains the piece, in f32.
    pub aabb: Aabb,
}

impl Piece {
    /// The whole triangle, with its exact box.
    pub fn of_triangle(vertices: &[[f32; 3]; 3]) -> Piece {
        Piece { corners: vertices.iter().map(|v| v.map(f64::from)).collect(), aabb: Aabb::of_triangle(vertices) }
    }

    /// The part of the triangle inside `aabb` (a box that holds part of it, such as a split reference's box),
    /// cut exactly by those of the box's sides that cross the triangle's box; `None` when nothing of the triangle
    /// is left (the box then only meets it in the one-step margins that clipped boxes keep).
    pub fn within(vertices: &[[f32; 3]; 3], aabb: &Aabb) -> Option<Piece> {
        let mut piece = Piece::of_triangle(vertices);
        for axis in 0..3 {
            let (low, high) = (aabb.min[axis], aabb.max[axis]);
            if piece.aabb.min[axis] < low && low < piece.aabb.max[axis] {
                piece = piece.cut(axis, low).1;
            }
            if piece.corners.len() >= 3 && piece.aabb.min[axis] < high && high < piece.aabb.max[axis] {
                piece = piece.cut(axis, high).0;
            }
            if piece.corners.len() < 3 {
                return None;
            }
        }
        Some(piece)
    }

    /// The two pieces on either side of the plane `x[axis] = plane`, which must lie strictly inside this piece's
    /// box along `axis` (so both sides hold part of the piece's box; a side may still be a sliver).
    pub fn cut(&self, axis: usize, plane: f32) -> (Piece, Piece) {
        let (below, above) = split_polygon(&self.corners, axis, f64::from(plane));
        let below_box = self.bounds_of(&below, axis, None, Some(plane));
        let above_box = self.bounds_of(&above, axis, Some(plane), None);
        (Piece { corners: below, aabb: below_box }, Piece { corners: above, aabb: above_box })
    }

    /// The f32 box of `corners`, a side of a cut of this piece along `axis`: exact at the cut (`low` or
    /// `high`), one step wider than the f64 corners elsewhere, and never outside this piece's box.
    fn bounds_of(&self, corners: &[[f64; 3]], axis: usize, low: Option<f32>, high: Option<f32>) -> Aabb {
        let mut aabb = Aabb::EMPTY;
        for a in 0..3 {
            let (lo, hi) =
                corners.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p[a]), hi.max(p[a])));
            let mut min = round_down(lo).next_down();
            let mut max = round_up(hi).next_up();
            if a == axis {
                if let Some(l) = low {
                    min = l;
                }
                if let Some(h) = high {
                    max = h;
                }
            }
            aabb.min[a] = min.max(self.aabb.min[a]);
            aabb.max[a] = max.min(self.aabb.max[a]);
        }
        aabb
    }
}

/// The largest f32 at most `x` (`x` finite).
fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) > x { f.next_down() } else { f }
}

/// The smallest f32 at least `x` (`x` finite).
fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) < x { f.next_up() } else { f }
}

/// The two parts of the convex polygon `corners` on either side of the plane `x[axis] = c` (Sutherland and
/// Hodgman's clipping, both sides at once): corners on the plane belong to both, and an edge that crosses it
/// adds its crossing point, exactly on the plane, to both.
pub fn split_polygon(corners: &[[f64; 3]], axis: usize, c: f64) -> (Vec<[f64; 3]>, Vec<[f64; 3]>) {
    let (mut below, mut above) = (Vec::with_capacity(corners.len() + 1), Vec::with_capacity(corners.len() + 1));
    let n = corners.len();
    for i in 0..n {
        let (p, q) = (corners[i], corners[(i + 1) % n]);
        let (side_p, side_q) = (p[axis] - c, q[axis] - c);
        if side_p <= 0.0 {
            below.push(p);
        }
        if side_p >= 0.0 {
            above.push(p);
        }
        if (side_p < 0.0 && side_q > 0.0) || (side_p > 0.0 && side_q < 0.0) {
            let s = side_p / (side_p - side_q);
            let mut x: [f64; 3] = std::array::from_fn(|a| p[a] + s * (q[a] - p[a]));
            x[axis] = c;
            below.push(x);
            above.push(x);
        }
    }
    (below, above)
}

/// The part of the convex polygon `corners` inside `aabb`.
pub fn clip_to_box(mut corners: Vec<[f64; 3]>, aabb: &Aabb) -> Vec<[f64; 3]> {
    for axis in 0..3 {
        for (bound, keep_below) in [(f64::from(aabb.min[axis]), false), (f64::from(aabb.max[axis]), true)] {
            if corners.is_empty() {
                return corners;
            }
            let (below, above) = split_polygon(&corners, axis, bound);
            corners = if keep_below { below } else { above };
        }
    }
    corners
}

/// The area of a planar convex polygon (half the length of the summed cross products of a fan).
pub fn polygon_area(corners: &[[f64; 3]]) -> f64 {
    let Some(&origin) = corners.first() else { return 0.0 };
    let origin = DVec3::from(origin);
    let normal: DVec3 =
        corners[1..].windows(2).map(|pair| (DVec3::from(pair[0]) - origin).cross(DVec3::from(pair[1]) - origin)).sum();
    0.5 * normal.length()
}

/// The triangle's area (f64).
pub fn triangle_area(vertices: &[[f32; 3]; 3]) -> f64 {
    0.5 * triangle_normal(vertices).length()
}

/// The limit of the summed surface areas of a triangle's pieces' boxes as the pieces shrink: twice the sum of
/// its areas projected onto the three axis planes (`|n_x| + |n_y| + |n_z|`, `n` the cross product).
pub fn ideal_box_area(vertices: &[[f32; 3]; 3]) -> f64 {
    triangle_normal(vertices).abs().element_sum()
}

/// `(v1 - v0) x (v2 - v0)` in f64.
fn triangle_normal(vertices: &[[f32; 3]; 3]) -> DVec3 {
    let [a, b, c] = vertices.map(|v| DVec3::from(v.map(f64::from)));
    (b - a).cross(c - a)
}
