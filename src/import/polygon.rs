//! Polygon triangulation for OBJ and PLY faces: convex polygons are fanned (the usual triangle count of n - 2,
//! in the usual order), concave ones are ear-clipped (earcutr) in the plane of their Newell normal.

use glam::DVec2;

/// Appends the triangles of `polygon` (vertex indices into `positions`, all in range) to `out`.
pub(super) fn triangulate(polygon: &[u32], positions: &[[f32; 3]], out: &mut Vec<[u32; 3]>) {
    let n = polygon.len();
    if n < 3 {
        return;
    }
    if n == 3 {
        out.push([polygon[0], polygon[1], polygon[2]]);
        return;
    }
    let points: Vec<[f64; 3]> = polygon.iter().map(|&v| positions[v as usize].map(f64::from)).collect();
    let Some(flat) = project(&points) else {
        return fan(polygon, out);
    };
    if is_convex(&flat) {
        return fan(polygon, out);
    }
    let coordinates: Vec<f64> = flat.iter().flat_map(|p| [p[0], p[1]]).collect();
    match earcutr::earcut(&coordinates, &[], 2) {
        Ok(corners) if corners.len() == 3 * (n - 2) => {
            for t in corners.chunks_exact(3) {
                let (a, b, c) = (t[0], t[1], t[2]);
                // Keep the polygon's own orientation, whatever order the ear clipper returns.
                let area = orientation(flat[a], flat[b], flat[c]);
                out.push(if area >= 0.0 {
                    [polygon[a], polygon[b], polygon[c]]
                } else {
                    [polygon[a], polygon[c], polygon[b]]
                });
            }
        }
        _ => fan(polygon, out),
    }
}

fn fan(polygon: &[u32], out: &mut Vec<[u32; 3]>) {
    for k in 2..polygon.len() {
        out.push([polygon[0], polygon[k - 1], polygon[k]]);
    }
}

/// The polygon in 2D, dropping the dominant axis of its Newell normal so that it stays counter-clockwise;
/// `None` when the normal is zero (a degenerate polygon).
fn project(points: &[[f64; 3]]) -> Option<Vec<[f64; 2]>> {
    let mut normal = [0.0f64; 3];
    for (i, p) in points.iter().enumerate() {
        let q = points[(i + 1) % points.len()];
        normal[0] += (p[1] - q[1]) * (p[2] + q[2]);
        normal[1] += (p[2] - q[2]) * (p[0] + q[0]);
        normal[2] += (p[0] - q[0]) * (p[1] + q[1]);
    }
    let abs = normal.map(f64::abs);
    let axis = if abs[0] >= abs[1] && abs[0] >= abs[2] {
        0
    } else if abs[1] >= abs[2] {
        1
    } else {
        2
    };
    if abs[axis] == 0.0 || !abs[axis].is_finite() {
        return None;
    }
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let flip = normal[axis] < 0.0;
    Some(points.iter().map(|p| if flip { [p[v], p[u]] } else { [p[u], p[v]] }).collect())
}

/// Twice the signed area of the triangle `a`, `b`, `c`: positive when it turns counter-clockwise.
fn orientation(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    let a = DVec2::from(a);
    (DVec2::from(b) - a).perp_dot(DVec2::from(c) - a)
}

/// Whether a counter-clockwise polygon has no reflex corner.
fn is_convex(flat: &[[f64; 2]]) -> bool {
    let n = flat.len();
    (0..n).all(|i| orientation(flat[i], flat[(i + 1) % n], flat[(i + 2) % n]) >= 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(triangles: &[[u32; 3]], positions: &[[f32; 3]]) -> f64 {
        triangles
            .iter()
            .map(|t| {
                let p = t.map(|v| positions[v as usize].map(f64::from));
                orientation([p[0][0], p[0][1]], [p[1][0], p[1][1]], [p[2][0], p[2][1]]) / 2.0
            })
            .sum()
    }

    #[test]
    fn a_concave_polygon_is_ear_clipped_with_its_area_and_orientation() {
        // An L shape (area 3) in the z = 0 plane, counter-clockwise.
        let positions =
            [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0], [1.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 2.0, 0.0]];
        let mut out = Vec::new();
        triangulate(&[0, 1, 2, 3, 4, 5], &positions, &mut out);
        assert_eq!(out.len(), 4);
        assert!((area(&out, &positions) - 3.0).abs() < 1e-12);
        for t in &out {
            assert!(area(&[*t], &positions) > 0.0, "{t:?} is clockwise");
        }
        // A fan from vertex 0 would cover area outside the L: the fan's triangle (0, 3, 4) is clockwise.
    }

    #[test]
    fn a_convex_polygon_is_fanned() {
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        let mut out = Vec::new();
        triangulate(&[0, 1, 2, 3], &positions, &mut out);
        assert_eq!(out, [[0, 1, 2], [0, 2, 3]]);
    }
}
