//! The default camera of `bvhc render`: a view that shows the scene, not only its outer shell.
//!
//! Candidates: the view from outside (above and to the side of the scene's box, the whole box in frame), and
//! views from the box's centre looking along +x, -x, +z and -z. Each is traced at a small probe resolution. An
//! inside view is chosen when, from the centre, the scene encloses the camera (at least 90% of the probe rays
//! hit), the camera looks at interior surfaces (at least a fifth of the hits are on front faces: inside a closed
//! object such as a scan or a teapot nearly all hits are on back faces), and it sees at least as many distinct
//! triangles as the outside view; among those, the one seeing the most. So a building or a closed room is shown
//! from inside, and objects, and rooms open to the outside, from outside.

use std::collections::HashSet;

use bvhc::loader::{PackedTriangle, Ray, Tracer};

use super::render::{Camera, Vec3, dot, normalize, sub};

/// Probe resolution (width x height) for scoring candidate views.
const PROBE: (usize, usize) = (64, 48);

/// The outside view of the box `min..max`: from above and to the side, far enough to see it whole.
pub fn outside(min: Vec3, max: Vec3) -> Camera {
    let center: Vec3 = std::array::from_fn(|a| 0.5 * (min[a] + max[a]));
    let radius = 0.5 * dot(sub(max, min), sub(max, min)).sqrt();
    let direction = normalize([0.9, 0.6, 1.3]);
    // A 45 degree field of view sees a sphere of this radius whole from 2.6 radii; the box rarely fills it.
    Camera { eye: std::array::from_fn(|a| center[a] + direction[a] * radius * 2.0), target: center, fov_degrees: 45.0 }
}

/// The default view (see the module doc) and whether it is an inside view.
pub fn default_camera(tracer: &Tracer<'_>, triangles: &[PackedTriangle], min: Vec3, max: Vec3) -> (Camera, bool) {
    let outside_view = outside(min, max);
    let outside_probe = probe(tracer, triangles, &outside_view);
    let center: Vec3 = std::array::from_fn(|a| 0.5 * (min[a] + max[a]));
    let mut best: Option<(Camera, usize)> = None;
    for direction in [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0f32]] {
        let target = std::array::from_fn(|a| center[a] + direction[a]);
        let inside = Camera { eye: center, target, fov_degrees: 75.0 };
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
                let [v0, v1, v2] = triangles[hit.triangle_index as usize].vertices;
                if dot(cross(sub(v1, v0), sub(v2, v0)), ray.direction) < 0.0 {
                    result.front += 1;
                }
            }
        }
    }
    result.distinct = seen.len();
    result
}

impl Camera {
    /// The ray through the centre of pixel `(x, y)` of a `width` x `height` image.
    pub fn primary_ray(&self, x: usize, y: usize, width: usize, height: usize) -> Ray {
        let forward = normalize(sub(self.target, self.eye));
        let mut right = normalize(cross(forward, [0.0, 1.0, 0.0]));
        if dot(right, right) < 0.5 || cross(forward, [0.0, 1.0, 0.0]) == [0.0; 3] {
            right = normalize(cross(forward, [0.0, 0.0, 1.0])); // looking straight up or down
        }
        let up = cross(right, forward);
        let half_height = (0.5 * self.fov_degrees).to_radians().tan();
        let half_width = half_height * width as f32 / height as f32;
        let sx = (2.0 * (x as f32 + 0.5) / width as f32 - 1.0) * half_width;
        let sy = (1.0 - 2.0 * (y as f32 + 0.5) / height as f32) * half_height;
        let direction = normalize(std::array::from_fn(|a| forward[a] + sx * right[a] + sy * up[a]));
        Ray::new(self.eye, direction)
    }
}

fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
