//! Ray sets shared by the benchmarks: camera-like rays and occlusion rays over a scene's box, from fixed seeds.

#![allow(dead_code)] // each benchmark uses the sets it needs

use bvhc::loader::{Ray, format::PackedNode};
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

/// Incoherent rays as an outside user makes them, independently of the other sets: origins uniform in the
/// scene's box, directions uniform on the unit sphere (normalized Gaussian triples), `t` unbounded.
pub fn uniform_rays(root: &PackedNode, count: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let mut gaussian = move || {
        // Box-Muller from two uniforms in (0, 1].
        let (u, v) = (1.0 - rng.random::<f64>(), rng.random::<f64>());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    };
    let mut rng = Pcg64Mcg::seed_from_u64(seed ^ 0x5eed);
    (0..count)
        .map(|_| {
            let origin: [f32; 3] = std::array::from_fn(|a| rng.random_range(root.min[a]..=root.max[a]));
            let direction = loop {
                let d: [f64; 3] = std::array::from_fn(|_| gaussian());
                let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                if length > 1e-9 {
                    break d.map(|c| (c / length) as f32);
                }
            };
            Ray::new(origin, direction)
        })
        .collect()
}

/// A `width` x `height` primary ray set in pixel order (rows top to bottom): a pinhole camera with a 45 degree
/// vertical field of view, from above and to the side of the scene's box (as `bvhc render`'s outside view).
pub fn camera_rays(root: &PackedNode, width: usize, height: usize) -> Vec<Ray> {
    let center: [f32; 3] = std::array::from_fn(|a| 0.5 * (root.min[a] + root.max[a]));
    let extent: [f32; 3] = std::array::from_fn(|a| root.max[a] - root.min[a]);
    let radius = 0.5 * (extent[0] * extent[0] + extent[1] * extent[1] + extent[2] * extent[2]).sqrt();
    let normalize = |v: [f32; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|c| c / l)
    };
    let cross =
        |a: [f32; 3], b: [f32; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let back = normalize([0.9, 0.6, 1.3]);
    let eye: [f32; 3] = std::array::from_fn(|a| center[a] + back[a] * radius * 2.0);
    let forward = back.map(|c| -c);
    let right = normalize(cross(forward, [0.0, 1.0, 0.0]));
    let up = cross(right, forward);
    let half_height = 22.5f32.to_radians().tan();
    let half_width = half_height * width as f32 / height as f32;
    let mut rays = Vec::with_capacity(width * height);
    for y in 0..height {
        for x in 0..width {
            let sx = (2.0 * (x as f32 + 0.5) / width as f32 - 1.0) * half_width;
            let sy = (1.0 - 2.0 * (y as f32 + 0.5) / height as f32) * half_height;
            rays.push(Ray::new(eye, normalize(std::array::from_fn(|a| forward[a] + sx * right[a] + sy * up[a]))));
        }
    }
    rays
}
