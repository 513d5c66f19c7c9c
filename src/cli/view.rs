//! The default camera of `bvhc render`: a view that shows the scene, not only its outer shell.
//!
//! Candidates: the view from outside (above and to the side of the scene's box, the whole box in frame), and
//! views from the box's centre looking along +x, -x, +z and -z. Each is traced at a small probe resolution. An
//! inside view is chosen when, from the centre, the scene encloses the camera (at least 90% of the probe rays
//! hit), the camera looks at interior surfaces (at least a fifth of the hits are on front faces: inside a closed
//! object such as a scan or a teapot nearly all hits are on back faces), and it sees at least as many distinct
//! triangles as the outside view; among those, the one seeing the most. So a building or a closed room is shown
//! from inside, and objects, and rooms open to the outside, from outside.

use bvhc_loader::Trace;
use std::collections::HashSet;

use bvhc::loader::{Tracer, format::PackedTriangle};
use glam::Vec3;

use super::camera::Camera;

/// Probe resolution (width x height) for scoring candidate views.
const PROBE: (usize, usize) = (64, 48);

/// The outside view of the box `min..max`: from above and to the side, far enough to see it whole.
pub fn outside(min: Vec3, max: Vec3) -> Camera {
    let center = 0.5 * (min + max);
    let radius = 0.5 * (max - min).length();
    let direction = Vec3::new(0.9, 0.6, 1.3).normalize();
    // A 45 degree field of view sees a sphere of this radius whole from 2.6 radii; the box rarely fills it.
    Camera { eye: center + direction * radius * 2.0, target: center, fov_degrees: 45.0 }
}

/// The default view (see the module doc) and whether it is an inside view.
pub fn default_camera(tracer: &Tracer<'_>, triangles: &[PackedTriangle], min: Vec3, max: Vec3) -> (Camera, bool) {
    let outside_view = outside(min, max);
    let outside_probe = probe(tracer, triangles, &outside_view);
    let center = 0.5 * (min + max);
    let mut best: Option<(Camera, usize)> = None;
    for direction in [Vec3::X, Vec3::NEG_X, Vec3::Z, Vec3::NEG_Z] {
        let inside = Camera { eye: center, target: center + direction, fov_degrees: 75.0 };
        let seen = probe(tracer, triangles, &inside);
        let enclosed = seen.hits * 10 >= 9 * PROBE.0 * PROBE.1;
        let interior = seen.front * 5 >= seen.hits;
        let informative = seen.distinct >= outside_probe.distinct.max(1);
        if enclosed && interior && informative && best.as_ref().is_none_or(|(_, score)| seen.distinct > *score) {
            best = Some((inside, seen.distinct));
        }
    }
    match best {
        Some((inside, _)) => (inside, true),
        None => (outside_view, false),
    }
}

/// What a view's probe rays see.
#[derive(Debug)]
struct Probe {
    /// Distinct triangles hit.
    distinct: usize,
    /// Rays that hit.
    hits: usize,
    /// Hits on a triangle's front face (the side from which its vertices run counter-clockwise).
    front: usize,
}

fn probe(tracer: &Tracer<'_>, triangles: &[PackedTriangle], camera: &Camera) -> Probe {
    let (width, height) = PROBE;
    let mut seen = HashSet::new();
    let mut result = Probe { distinct: 0, hits: 0, front: 0 };
    for y in 0..height {
        for x in 0..width {
            let ray = camera.primary_ray(x, y, width, height);
            if let Some(hit) = tracer.closest_hit(&ray) {
                seen.insert(hit.triangle_index);
                result.hits += 1;
                if geometric_normal(&triangles[hit.triangle_index as usize]).dot(ray.direction.into()) < 0.0 {
                    result.front += 1;
                }
            }
        }
    }
    result.distinct = seen.len();
    result
}

/// The unnormalized normal `(v1 - v0) x (v2 - v0)`, on the side from which the vertices run counter-clockwise.
pub fn geometric_normal(triangle: &PackedTriangle) -> Vec3 {
    let [v0, v1, v2] = triangle.vertices.map(Vec3::from_array);
    (v1 - v0).cross(v2 - v0)
}
