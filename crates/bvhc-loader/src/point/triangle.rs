//! The closest point of one triangle to a query point, in the normative f64 arithmetic of
//! `format-spec/point-queries.md` (section "One triangle"): every reader that follows it gets the same squared
//! distance bit for bit, so ties between triangles are decided the same way everywhere.
//!
//! The point is tested against the triangle's plane first (the signed areas of the three sub-triangles the
//! point's projection makes, measured along the normal, all `>= 0`: the projection is inside and the plane's
//! distance is the answer); otherwise the nearest of the edges the projection lies beyond (a negative area), and
//! for a triangle with no area the nearest of its three edges, is (Ericson,
//! "Real-Time Collision Detection", 2005, 5.1.5, states the same regions by a different arithmetic). Each edge is
//! measured from its lexicographically smaller endpoint, so that two triangles sharing an edge (or a vertex) get
//! the same bits for it whichever way they wind it: a point over a shared edge is an exact tie, which the tie
//! rule then decides, not rounding.

/// Three f64 coordinates.
pub type Point3 = [f64; 3];

/// The closest point of a triangle: squared distance, the point, and its barycentric weights `u` (of `v1`) and
/// `v` (of `v2`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrianglePoint {
    /// The squared distance.
    pub d2: f64,
    /// The closest point.
    pub point: Point3,
    /// Barycentric weight of `v1` at the point.
    pub u: f64,
    /// Barycentric weight of `v2` at the point.
    pub v: f64,
}

#[inline(always)]
fn sub(a: Point3, b: Point3) -> Point3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
fn dot(a: Point3, b: Point3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn cross(a: Point3, b: Point3) -> Point3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// The closest point of the triangle `v0 v1 v2` to `p` (all finite), as the spec computes it: the function an
/// outside reader checks its own against, and tests use for brute force.
#[inline]
pub fn closest_on_triangle(p: Point3, triangle: [Point3; 3]) -> TrianglePoint {
    closest_from_plane(p, triangle, plane_values(p, triangle))
}

/// The [`PlaneValues`] of the triangle `v0 v1 v2` for `p`.
#[inline(always)]
pub(crate) fn plane_values(p: Point3, [a, b, c]: [Point3; 3]) -> PlaneValues {
    let n = cross(sub(b, a), sub(c, a));
    let weights =
        [dot(cross(sub(c, b), sub(p, b)), n), dot(cross(sub(a, c), sub(p, c)), n), dot(cross(sub(b, a), sub(p, a)), n)];
    PlaneValues { n, nn: dot(n, n), weights }
}

/// The first values of [`closest_on_triangle`]: the normal `n = (v1 - v0) x (v2 - v0)`, `n . n`, and the
/// weights of `v0`, `v1`, `v2` (the signed areas of the sub-triangles of the point's projection, along `n`).
/// Computed in lanes for four triangles at once by the wide walk, which then finishes each with
/// [`closest_from_plane`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PlaneValues {
    pub n: Point3,
    pub nn: f64,
    pub weights: [f64; 3],
}

/// [`closest_on_triangle`] from its plane values.
#[inline(always)]
pub(crate) fn closest_from_plane(p: Point3, [a, b, c]: [Point3; 3], plane: PlaneValues) -> TrianglePoint {
    let PlaneValues { n, nn, weights: [weight_a, weight_b, weight_c] } = plane;
    // Which edges may hold the closest point: every edge of a triangle with no area; else the edges the
    // projection lies beyond (the weight of the opposite vertex negative), none when it lies inside.
    let mut edges = [true; 3]; // v0v1, v1v2, v2v0
    if nn > 0.0 && nn.is_finite() {
        if weight_a >= 0.0 && weight_b >= 0.0 && weight_c >= 0.0 {
            let w = dot(sub(p, a), n);
            let h = w / nn;
            let point = [p[0] - n[0] * h, p[1] - n[1] * h, p[2] - n[2] * h];
            return TrianglePoint { d2: w * h, point, u: weight_b / nn, v: weight_c / nn };
        }
        edges = [weight_c < 0.0, weight_a < 0.0, weight_b < 0.0];
        if edges == [false; 3] {
            edges = [true; 3]; // NaN weights (coordinates near the f64 range's end)
        }
    }
    // The nearest of those edges, the first of v0v1, v1v2, v2v0 on a tie.
    let mut best = TrianglePoint { d2: f64::INFINITY, point: [f64::NAN; 3], u: 0.0, v: 0.0 };
    if edges[0] {
        let (d2, t, point) = closest_on_segment(p, a, b);
        best = TrianglePoint { d2, point, u: t, v: 0.0 };
    }
    if edges[1] {
        let (d2, t, point) = closest_on_segment(p, b, c);
        if d2 < best.d2 {
            best = TrianglePoint { d2, point, u: 1.0 - t, v: t };
        }
    }
    if edges[2] {
        let (d2, t, point) = closest_on_segment(p, c, a);
        if d2 < best.d2 {
            best = TrianglePoint { d2, point, u: 0.0, v: 1.0 - t };
        }
    }
    best
}

/// The closest point of the segment `x y` to `p`: squared distance, its parameter from `x` (0 at `x`, 1 at
/// `y`) and the point. Measured from the lexicographically smaller endpoint (its coordinates compared in x, y, z
/// order), so the segment `y x` gives the same distance and point bit for bit.
#[inline(always)]
fn closest_on_segment(p: Point3, x: Point3, y: Point3) -> (f64, f64, Point3) {
    let swapped = y < x;
    let (from, to) = if swapped { (y, x) } else { (x, y) };
    let d = sub(to, from);
    let dd = dot(d, d);
    let t = if dd > 0.0 { (dot(sub(p, from), d) / dd).clamp(0.0, 1.0) } else { 0.0 };
    let point = [from[0] + d[0] * t, from[1] + d[1] * t, from[2] + d[2] * t];
    let e = sub(p, point);
    (dot(e, e), if swapped { 1.0 - t } else { t }, point)
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: [Point3; 3] = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]];

    #[test]
    fn inside_the_triangle_the_plane_answers() {
        let r = closest_on_triangle([0.5, 0.5, 3.0], T);
        assert_eq!(r, TrianglePoint { d2: 9.0, point: [0.5, 0.5, 0.0], u: 0.25, v: 0.25 });
    }

    #[test]
    fn outside_an_edge_or_vertex_the_edge_answers() {
        let below = closest_on_triangle([1.0, -1.0, 0.0], T);
        assert_eq!((below.d2, below.point, below.u, below.v), (1.0, [1.0, 0.0, 0.0], 0.5, 0.0));
        let corner = closest_on_triangle([-1.0, -1.0, 1.0], T);
        assert_eq!((corner.d2, corner.point, corner.u, corner.v), (3.0, [0.0, 0.0, 0.0], 0.0, 0.0));
        let hypotenuse = closest_on_triangle([2.0, 2.0, 0.0], T);
        assert_eq!((hypotenuse.d2, hypotenuse.point, hypotenuse.u, hypotenuse.v), (2.0, [1.0, 1.0, 0.0], 0.5, 0.5));
    }

    #[test]
    fn a_shared_edge_gives_the_same_bits_either_way_round() {
        let (a, b) = ([0.1, 0.7, -0.3], [1.3, -0.2, 0.9]);
        let p = [0.37, 2.1, 0.05];
        let (d_forward, t_forward, q_forward) = closest_on_segment(p, a, b);
        let (d_back, t_back, q_back) = closest_on_segment(p, b, a);
        assert_eq!((d_forward, q_forward), (d_back, q_back));
        assert!((t_forward + t_back - 1.0).abs() < 1e-15);
    }

    #[test]
    fn degenerate_triangles_answer_by_their_edges() {
        let line = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert_eq!(closest_on_triangle([1.5, 1.0, 0.0], line).d2, 1.0);
        let dot_triangle = [[1.0, 1.0, 1.0]; 3];
        assert_eq!(closest_on_triangle([1.0, 1.0, 4.0], dot_triangle).d2, 9.0);
    }
}
