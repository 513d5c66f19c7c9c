//! The wide kernel alone, for A/B work on it: one thread, Mrays/s (median of `BVHC_KERNEL_RUNS`, default 7) of
//! the binary kernel and the wide kernel (portable path, best path, stream as `Tracer` runs it, stream with
//! rays interleaved whatever the file's size) on the traversal benchmark's ray
//! sets (incoherent `primary_rays` for closest hit, `shadow_rays` for any hit, a 1024x768 camera for closest hit
//! and coherent packets), with wide node visits and packet tests per ray, which change only when the tree does.
//!
//! Files are converted once with the default options into `target/kernel-bench/` and reused while they are up
//! to date (the conversion's own check: same input, options and format version); `BVHC_KERNEL_FORCE=1`
//! reconverts, for changes to the collapse or the packing. `BVHC_KERNEL_SCENES=kitchen,dragon` picks scenes,
//! `BVHC_BENCH_RAYS` the ray count (default 500,000). The Embree comparison is `cargo bench --bench traversal
//! --features embree`; this bench is the quick loop between two of those runs.
//!
//! For a profiler, `BVHC_KERNEL_PROFILE=closest|any|camera` traces only that set with the best path,
//! `BVHC_KERNEL_RUNS` times, and prints only its median speed, on stderr (`perf record`, `valgrind --tool=callgrind`).
//!
//! `cargo bench --bench kernel`

#[path = "common/harness.rs"]
mod harness;

#[path = "common/rays.rs"]
mod rays;

use bvhc::loader::{BvhFile, KernelPath, Ray, Tracer, TraversalStats};
use bvhc_loader::Trace;

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

fn main() {
    if !harness::benchmarking("kernel") {
        return;
    }
    let ray_count = env_usize("BVHC_BENCH_RAYS", 500_000);
    let runs = env_usize("BVHC_KERNEL_RUNS", 7);
    let force = std::env::var_os("BVHC_KERNEL_FORCE").is_some();
    let cache = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/kernel-bench");
    std::fs::create_dir_all(&cache).unwrap();
    println!(
        "{ray_count} incoherent rays a set, one thread, Mrays/s, medians of {runs}; best path {:?}\n",
        KernelPath::best()
    );
    println!(
        "| scene | rays | query | binary | wide portable | wide best | stream | interleaved | coherent 8 | visits / ray | packets / ray |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for (name, input) in harness::scenes(
        &[
            ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
            ("dragon", "stanford-dragon/dragon_vrip.ply.gz"),
            ("engine", "khr-2cylinder-engine/2CylinderEngine.gltf"),
            ("toy car", "khr-toy-car/ToyCar.gltf"),
        ],
        Some("BVHC_KERNEL_SCENES"),
    ) {
        let output = cache.join(format!("{}.bvh", name.replace(' ', "-")));
        bvhc::Conversion::new(&input, &output).force(force).run().unwrap();
        let file = BvhFile::read(&output).unwrap();
        let view = file.view();
        let binary = view.binary_tracer();
        let portable = binary.with_wide(view.wide_tracer(KernelPath::Portable).expect("a converted file is wide"));
        let best = view.tracer();
        let root = view.nodes()[0];
        if let Ok(profile) = std::env::var("BVHC_KERNEL_PROFILE") {
            let rays = match profile.as_str() {
                "any" => rays::shadow_rays(&root, ray_count),
                "camera" => rays::camera_rays(&root, 1024, 768),
                _ => rays::primary_rays(&root, ray_count),
            };
            let time = harness::median_time(runs, || {
                let hits = if profile == "any" {
                    rays.iter().filter(|r| best.any_hit(r)).count()
                } else {
                    rays.iter().filter(|r| best.closest_hit(r).is_some()).count()
                };
                std::hint::black_box(hits);
            });
            eprintln!("{name} {profile} {:.3} Mrays/s", mrays(&rays, time));
            continue;
        }
        let sets = [
            ("incoherent", true, rays::primary_rays(&root, ray_count)),
            ("incoherent", false, rays::shadow_rays(&root, ray_count)),
            ("camera", true, rays::camera_rays(&root, 1024, 768)),
        ];
        for (set, closest, rays) in &sets {
            let single = |tracer: &Tracer<'_>| {
                let time = harness::median_time(runs, || {
                    let hits = if *closest {
                        rays.iter().filter(|r| tracer.closest_hit(r).is_some()).count()
                    } else {
                        rays.iter().filter(|r| tracer.any_hit(r)).count()
                    };
                    std::hint::black_box(hits);
                });
                mrays(rays, time)
            };
            let interleaved =
                binary.with_wide(view.wide_tracer(KernelPath::best()).expect("wide").interleaving_streams(true));
            let interleaved_speed = harness::batch_speed(rays, &interleaved, *closest, false, runs);
            let batch = |coherent: bool| harness::batch_speed(rays, &best, *closest, coherent, runs);
            let mut stats = TraversalStats::default();
            for ray in rays {
                if *closest {
                    best.closest_hit_counted(ray, &mut stats);
                } else {
                    best.any_hit_counted(ray, &mut stats);
                }
            }
            println!(
                "| {name} | {set} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {interleaved_speed:.2} | {:.2} | {:.2} | {:.2} |",
                if *closest { "closest" } else { "any" },
                single(&binary),
                single(&portable),
                single(&best),
                batch(false),
                batch(true),
                stats.node_visits as f64 / rays.len() as f64,
                stats.triangle_tests as f64 / rays.len() as f64,
            );
        }
    }
}

fn mrays(rays: &[Ray], time: std::time::Duration) -> f64 {
    rays.len() as f64 / time.as_secs_f64() / 1e6
}
