//! Ray sets shared by the benchmarks: camera-like rays and occlusion rays over a scene's box, from fixed seeds.

use bvhc::loader::{PackedNode, Ray};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// Seed of the primary rays; the shadow rays use the next one.
pub const RAY_SEED: u64 = 2026;

/// Camera-like rays: from a sphere around the scene's box towards random points inside it.
pub fn primary_rays(root: &PackedNode, count: usize) -> Vec<Ray> {
    let mut rng = Pcg64Mcg::seed_from_u64(RAY_SEED);
    let center: [f32; 3] = std::array::from_fn(|a| 0.5 * (root.min[a] + root.max[a]));
    let half: [f32; 3] = std::array::from_fn(|a| 0.5 * (root.max[a] - root.min[a]));
    let radius = 1.5 * (half[0] * half[0] + half[1] * half[1] + half[2] * half[2]).sqrt();
    (0..count)
        .map(|_| {
            let direction = loop {
                let d: [f32; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0f32));
                let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if length > 0.1 && length <= 1.0 {
                    break d.map(|c| c / length);
                }
            };
            let origin: [f32; 3] = std::array::from_fn(|a| center[a] + radius * direction[a]);
            let target: [f32; 3] = std::array::from_fn(|a| center[a] + half[a] * rng.random_range(-1.0..1.0f32));
            Ray::new(origin, std::array::from_fn(|a| target[a] - origin[a]))
        })
        .collect()
}

/// Occlusion rays between two random points of the scene's box, `t` in `[0, 1]`.
pub fn shadow_rays(root: &PackedNode, count: usize) -> Vec<Ray> {
    let mut rng = Pcg64Mcg::seed_from_u64(RAY_SEED + 1);
    let mut point = || -> [f32; 3] { std::array::from_fn(|a| rng.random_range(root.min[a]..=root.max[a])) };
    (0..count)
        .map(|_| {
            let (from, to) = (point(), point());
            Ray { origin: from, direction: std::array::from_fn(|a| to[a] - from[a]), t_min: 0.0, t_max: 1.0 }
        })
        .collect()
}
