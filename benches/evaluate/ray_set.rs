//! The fixed ray set every tree is traced with, and the render timings and traversal counts over it.

use bvhc::loader::{Ray, Tracer, TraversalStats};
use bvhc_loader::Trace;
use rayon::prelude::*;

/// The fixed ray set of every method: primary rays (a 512 x 384 camera), 4 ambient occlusion rays per primary
/// hit (any hit, within a fifth of the scene's size), and as many incoherent rays as primary ones (closest hit;
/// origins uniform in the scene's box, directions uniform on the sphere).
pub struct RaySet {
    pub primary: Vec<Ray>,
    pub ao: Vec<Ray>,
    pub incoherent: Vec<Ray>,
}

pub fn ray_set(tracer: &Tracer<'_>, min: [f32; 3], max: [f32; 3]) -> RaySet {
    let (width, height) = (512usize, 384usize);
    let center: [f32; 3] = std::array::from_fn(|a| 0.5 * (min[a] + max[a]));
    let size = (0..3).map(|a| max[a] - min[a]).fold(0.0f32, f32::max);
    let dir = [0.55f32, 0.37, 0.75];
    let eye: [f32; 3] = std::array::from_fn(|a| center[a] + dir[a] * size * 1.6);
    let forward = -glam::Vec3::from(dir);
    let right = glam::Vec3::new(forward.z, 0.0, -forward.x).normalize();
    let up = right.cross(forward);
    let primary: Vec<Ray> = (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f32 / width as f32 - 0.5, 0.5 - (i / width) as f32 / height as f32);
            Ray::new(eye, (forward + 0.8 * x * right + 0.6 * y * up).to_array())
        })
        .collect();
    let mut ao = Vec::new();
    for (i, ray) in primary.iter().enumerate() {
        if let Some(hit) = tracer.closest_hit(ray) {
            let point: [f32; 3] = std::array::from_fn(|a| ray.origin[a] + hit.t * ray.direction[a]);
            for k in 0..4u64 {
                let d = unit_cube_point(i as u64 * 4 + k).map(|c| 2.0 * c - 1.0);
                ao.push(Ray { origin: point, direction: d, t_min: size * 1e-4, t_max: size * 0.2 });
            }
        }
    }
    let incoherent = (0..primary.len() as u64)
        .map(|i| {
            let u = unit_cube_point(0x5EED_0000_0000 + i);
            let origin: [f32; 3] = std::array::from_fn(|a| min[a] + u[a] * (max[a] - min[a]));
            let v = unit_cube_point(0xD1CE_0000_0000 + i);
            let (z, phi) = (2.0 * v[0] - 1.0, std::f32::consts::TAU * v[1]);
            let r = (1.0 - z * z).max(0.0).sqrt();
            Ray::new(origin, [r * phi.cos(), r * phi.sin(), z])
        })
        .collect();
    RaySet { primary, ao, incoherent }
}

/// A point of the unit cube from a counter (three 16-bit fields of a multiplicative hash).
pub fn unit_cube_point(i: u64) -> [f32; 3] {
    let h = i.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    std::array::from_fn(|a| ((h >> (a * 16)) & 0xFFFF) as f32 / 65536.0)
}

/// Seconds to trace the whole ray set once (all threads).
fn render_once(tracer: &Tracer<'_>, rays: &RaySet) -> f64 {
    let closest = |set: &[Ray]| {
        set.par_chunks(1024).map(|c| c.iter().filter(|r| tracer.closest_hit(r).is_some()).count()).sum::<usize>()
    };
    let run = || {
        let hits = closest(&rays.primary) + closest(&rays.incoherent);
        let occluded = rays.ao.par_chunks(1024).map(|c| c.iter().filter(|r| tracer.any_hit(r)).count()).sum::<usize>();
        std::hint::black_box((hits, occluded));
    };
    let start = std::time::Instant::now();
    run();
    start.elapsed().as_secs_f64()
}

/// Node visits and triangle tests per ray.
pub fn traversal_counts(tracer: &Tracer<'_>, rays: &RaySet) -> (f64, f64) {
    let mut stats = TraversalStats::default();
    for r in rays.primary.iter().chain(&rays.incoherent) {
        tracer.closest_hit_counted(r, &mut stats);
    }
    for r in &rays.ao {
        tracer.any_hit_counted(r, &mut stats);
    }
    let count = (rays.primary.len() + rays.ao.len() + rays.incoherent.len()) as f64;
    (stats.node_visits as f64 / count, stats.triangle_tests as f64 / count)
}

/// Traces `rays` through every tracer once a round, `rounds` times, so that the machine's drift falls on all
/// tracers alike. For each tracer: the median of its seconds, and the median of its per-round ratios to the
/// first tracer's seconds.
pub fn render_in_rounds(tracers: &[Tracer<'_>], rays: &RaySet, rounds: usize) -> Vec<(f64, f64)> {
    let mut times = vec![Vec::new(); tracers.len()];
    let mut ratios = vec![Vec::new(); tracers.len()];
    for _ in 0..rounds {
        let round: Vec<f64> = tracers.iter().map(|tracer| render_once(tracer, rays)).collect();
        for (i, &t) in round.iter().enumerate() {
            times[i].push(t);
            ratios[i].push(t / round[0]);
        }
    }
    times.iter_mut().zip(&mut ratios).map(|(t, r)| (median(t), median(r))).collect()
}

/// The median of `values` (the upper one of an even count).
fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}
