//! Helpers shared by the benchmark binaries: the smoke-run check, the scenes folder, the median of timed runs.

#![allow(dead_code)] // each benchmark uses the part it needs

use bvhc_loader::Trace;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Whether `cargo bench` runs this binary (it passes `--bench`); under `cargo test --benches` it says so and
/// the benchmark returns after its smoke checks.
pub fn benchmarking(name: &str) -> bool {
    let yes = std::env::args().any(|a| a == "--bench");
    if !yes {
        println!("{name}: smoke run only (use cargo bench --bench {name})");
    }
    yes
}

/// The shared scenes folder: `BVHC_SCENES`, else `../shared/scenes` beside the repository.
pub fn scenes_dir() -> PathBuf {
    std::env::var_os("BVHC_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes"))
}

/// The median wall-clock time of `repetitions` runs of `f`.
pub fn median_time(repetitions: usize, mut f: impl FnMut()) -> Duration {
    let mut samples: Vec<Duration> = (0..repetitions)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed()
        })
        .collect();
    samples.sort();
    samples[samples.len() / 2]
}

/// The scene names listed in the environment variable `variable` (comma-separated), or `None` for all.
pub fn wanted_scenes(variable: &str) -> Option<Vec<String>> {
    std::env::var(variable).ok().map(|s| s.split(',').map(String::from).collect())
}

/// The scenes of `list` (a name, a path under the shared scenes) that this run measures, with their paths: those
/// named in the environment variable `filter` when it is set (comma-separated), and on this machine; a missing
/// one is reported as SKIPPED.
pub fn scenes<'a>(list: &[(&'a str, &str)], filter: Option<&str>) -> Vec<(&'a str, PathBuf)> {
    let wanted = filter.and_then(wanted_scenes);
    let dir = scenes_dir();
    list.iter()
        .filter(|(name, _)| wanted.as_ref().is_none_or(|w| w.iter().any(|n| n == name)))
        .filter_map(|&(name, relative)| {
            let path = dir.join(relative);
            if !path.is_file() {
                eprintln!("SKIPPED: {} not found (set BVHC_SCENES to the shared scenes folder)", path.display());
            }
            path.is_file().then_some((name, path))
        })
        .collect()
}

/// Triangles in obvhs's type, for building its trees over the same geometry.
pub fn obvhs_triangles(triangles: &[[[f32; 3]; 3]]) -> Vec<obvhs::triangle::Triangle> {
    triangles
        .iter()
        .map(|t| obvhs::triangle::Triangle {
            v0: glam::Vec3A::from_array(t[0]),
            v1: glam::Vec3A::from_array(t[1]),
            v2: glam::Vec3A::from_array(t[2]),
        })
        .collect()
}

/// Mrays/s (median of `runs`) of `tracer`'s batch entry points over all `rays` at once on this thread: the
/// stream (`closest_hits` / `any_hits`), or with `coherent` the 8-ray packets (`closest_hits_coherent` /
/// `any_hits_coherent`).
pub fn batch_speed(
    rays: &[bvhc::loader::Ray],
    tracer: &bvhc::loader::Tracer<'_>,
    closest: bool,
    coherent: bool,
    runs: usize,
) -> f64 {
    let mut hits = vec![None; rays.len()];
    let mut occluded = vec![false; rays.len()];
    let time = median_time(runs, || {
        match (closest, coherent) {
            (true, false) => tracer.closest_hits(rays, &mut hits),
            (false, false) => tracer.any_hits(rays, &mut occluded),
            (true, true) => tracer.closest_hits_coherent(rays, &mut hits),
            (false, true) => tracer.any_hits_coherent(rays, &mut occluded),
        }
        std::hint::black_box((&hits, &occluded));
    });
    rays.len() as f64 / time.as_secs_f64() / 1e6
}
