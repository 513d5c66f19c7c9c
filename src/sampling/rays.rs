//! The built-in training rays: what a renderer traces through a scene, made from the scene itself and a seed.
//! A third are camera rays from eight viewpoints (six around the scene's box, two inside it) towards random
//! points of the box; a third are ambient-occlusion rays spawned from the camera rays' hits (cosine-distributed
//! about the hit triangle's normal, facing the camera, a fifth of the scene's size long); the rest are uniform:
//! origins uniform in the box, directions uniform on the sphere. Deterministic: the same tree, triangles, count
//! and seed give the same rays whatever the thread count.

use bvhc_loader::Ray;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;

use super::trace::trace_counting;
use crate::geometry::Aabb;
use crate::optimize::{NONE, OptTree};

/// `count` training rays for `tree` over `triangles` (see the module documentation), from `seed`.
pub fn training_rays(tree: &OptTree, triangles: &[[[f32; 3]; 3]], count: usize, seed: u64) -> Vec<Ray> {
    if tree.root == NONE || count == 0 {
        return Vec::new();
    }
    let scene = tree.nodes[tree.root as usize].aabb;
    let size = (0..3).map(|a| scene.max[a] - scene.min[a]).fold(0.0f32, f32::max).max(f32::MIN_POSITIVE);
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let camera_count = count / 3;
    let mut rays = camera_rays(&scene, camera_count, &mut rng);
    // Ambient occlusion from the camera rays' hits (traced in parallel; the spawned rays are made in order).
    let hits: Vec<Option<(f32, u32)>> = rays
        .par_iter()
        .map_init(
            || vec![0u32; tree.nodes.len()],
            |visits, ray| trace_counting(tree, triangles, ray, visits).map(|h| (h.t, h.triangle)),
        )
        .collect();
    let ao_count = count / 3;
    let hit_rays: Vec<(Ray, f32, u32)> =
        rays.iter().zip(&hits).filter_map(|(r, h)| h.map(|(t, tri)| (*r, t, tri))).collect();
    for k in 0..ao_count.min(hit_rays.len() * 4) {
        let (ray, t, triangle) = hit_rays[k % hit_rays.len()];
        let point: [f32; 3] = std::array::from_fn(|a| ray.origin[a] + t * ray.direction[a]);
        let normal = facing_normal(&triangles[triangle as usize], &ray.direction);
        let direction = cosine_direction(normal, &mut rng);
        rays.push(Ray { origin: point, direction, t_min: size * 1e-4, t_max: size * 0.2 });
    }
    while rays.len() < count {
        let origin: [f32; 3] =
            std::array::from_fn(|a| scene.min[a] + rng.random::<f32>() * (scene.max[a] - scene.min[a]));
        rays.push(Ray::new(origin, uniform_direction(&mut rng)));
    }
    rays
}

/// Camera rays from eight viewpoints: six outside (along the axes' diagonals, 1.6 half-diagonals from the
/// center) and two inside the box, each towards random points of the box.
fn camera_rays(scene: &Aabb, count: usize, rng: &mut Pcg64Mcg) -> Vec<Ray> {
    let center: [f32; 3] = std::array::from_fn(|a| 0.5 * (scene.min[a] + scene.max[a]));
    let half: [f32; 3] = std::array::from_fn(|a| 0.5 * (scene.max[a] - scene.min[a]));
    let radius = 1.6 * (half[0] * half[0] + half[1] * half[1] + half[2] * half[2]).sqrt();
    let outside =
        [[1.0, 0.6, 0.8], [-0.9, 0.5, 0.7], [0.7, 0.8, -0.9], [-0.8, 0.4, -0.6], [0.2, 1.0, 0.1], [0.5, -0.9, 0.4]];
    let mut eyes: Vec<[f32; 3]> = outside
        .iter()
        .map(|d: &[f32; 3]| {
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            std::array::from_fn(|a| center[a] + radius * d[a] / l)
        })
        .collect();
    eyes.push(std::array::from_fn(|a| center[a] + 0.25 * half[a]));
    eyes.push(std::array::from_fn(|a| center[a] - 0.4 * half[a]));
    (0..count)
        .map(|i| {
            let eye = eyes[i % eyes.len()];
            let target: [f32; 3] = std::array::from_fn(|a| center[a] + half[a] * rng.random_range(-1.0f32..=1.0));
            let direction: [f32; 3] = std::array::from_fn(|a| target[a] - eye[a]);
            let direction = if direction == [0.0; 3] { [0.0, 0.0, 1.0] } else { direction };
            Ray::new(eye, direction)
        })
        .collect()
}

/// The triangle's unit normal, turned towards where the ray came from (or `+z` for a degenerate triangle).
fn facing_normal(v: &[[f32; 3]; 3], direction: &[f32; 3]) -> [f32; 3] {
    let e1: [f32; 3] = std::array::from_fn(|a| v[1][a] - v[0][a]);
    let e2: [f32; 3] = std::array::from_fn(|a| v[2][a] - v[0][a]);
    let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if !(length > 0.0 && length.is_finite()) {
        return [0.0, 0.0, 1.0];
    }
    let facing = if n[0] * direction[0] + n[1] * direction[1] + n[2] * direction[2] > 0.0 { -1.0 } else { 1.0 };
    n.map(|c| facing * c / length)
}

/// A direction cosine-distributed about the unit `normal` (a uniform point on the sphere added to the normal).
fn cosine_direction(normal: [f32; 3], rng: &mut Pcg64Mcg) -> [f32; 3] {
    let u = uniform_direction(rng);
    let d: [f32; 3] = std::array::from_fn(|a| normal[a] + u[a]);
    if d.iter().all(|c| c.abs() < 1e-6) { normal } else { d }
}

/// A direction uniform on the unit sphere.
fn uniform_direction(rng: &mut Pcg64Mcg) -> [f32; 3] {
    let z: f32 = rng.random_range(-1.0f32..1.0);
    let phi: f32 = rng.random_range(0.0f32..std::f32::consts::TAU);
    let r = (1.0 - z * z).max(0.0).sqrt();
    [r * phi.cos(), r * phi.sin(), z]
}
