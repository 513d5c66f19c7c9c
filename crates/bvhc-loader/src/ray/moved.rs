//! Which way a ray crosses a triangle once moved infinitesimally off the edges and vertices it passes exactly
//! through ([`moved_side`]): the rule that makes crossing counts exact (`crate::tracer::crossings` has the
//! argument), shared by the file's triangles and by the caps a winding number closes holes with
//! (`crate::point::caps`), so that a ray through an edge the two share is decided the same way for both.
//!
//! In the ray's sheared 2D space (where the watertight test's edge function `E(p, q) = p_x q_y - p_y q_x` is
//! evaluated at the origin) the ray moves to `(e, e^2)` for an infinitesimal `e` (Edelsbrunner and Muecke's
//! Simulation of Simplicity, 1990): an edge function of exactly 0 becomes `e (p_y - q_y) + e^2 (q_x - p_x)`, of
//! the sign of `p_y - q_y`, or if that is 0 of `q_x - p_x` (differences of f32 values: exact signs). Two
//! triangles sharing an edge see it with opposite orientation and so get opposite signs.

use crate::format::PackedTriangle;
use crate::ray::intersect::PreparedRay;
use crate::ray::watertight::{edge_functions, edge_functions_f64, has_zero_edge, sheared};

/// How the moved ray's line crosses `triangle` (at any `t`): `1` when it passes from the back side to the front
/// side (`dot(direction, normal) > 0`: leaving a mesh wound counter-clockwise seen from outside), `-1`
/// when it arrives at the front side, `0` when the moved ray misses it (a triangle with no area in the ray's 2D
/// space is always missed). The edge functions are the watertight test's (exact signs: an f32 value of 0 is
/// recomputed in f64), so a triangle the test misses is missed here too.
pub(crate) fn moved_side(ray: &PreparedRay, triangle: &PackedTriangle) -> i32 {
    let (_, [sx, sy, _]) = ray.shear();
    let p = sheared(&ray.relative(triangle), sx, sy);
    let mut e = edge_functions(p);
    if has_zero_edge(e, 0.0) {
        e = edge_functions_f64(p);
    }
    let [a, b, c] = p;
    // U = E(c, b), V = E(a, c), W = E(b, a).
    let edges = [(c, b), (a, c), (b, a)];
    let sign = |value: f32, ([px, py], [qx, qy]): ([f32; 2], [f32; 2])| {
        let moved = if value != 0.0 {
            value
        } else if py != qy {
            py - qy
        } else {
            qx - px
        };
        if moved > 0.0 {
            1
        } else if moved < 0.0 {
            -1
        } else {
            0
        }
    };
    let [su, sv, sw] = [0, 1, 2].map(|i| sign(e[i], edges[i]));
    // A positive determinant `U + V + W` is a counter-clockwise triangle in the ray's 2D space, whose z axis is
    // the direction: the ray arrives at its front side.
    if su != 0 && su == sv && sv == sw { -su } else { 0 }
}
