//! Self-hits of secondary rays at scale: each scene is scaled and moved (scales 1e-3, 1 and 1e4 of the scene's
//! size, offsets up to 1e6), converted with the default options (split references, wide sections), and camera
//! rays' hits spawn ambient-occlusion rays with `SurfacePoint::spawn` (`t_min = 0`). A self-hit is a spawned
//! ray whose closest hit is the triangle it left (the same source id, so another reference of a split triangle
//! counts too). The same rays spawned naively (from the interpolated hit point) are counted for comparison.
//!
//! `BVHC_SPAWN_RAYS` AO rays per scene and placement (default 700,000: over 10M in all on the three scenes),
//! `BVHC_SPAWN_SCENES=kitchen,dragon,building` picks scenes. `cargo bench --bench spawn`

#[path = "common/harness.rs"]
mod harness;

use bvhc_loader::Trace;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

use bvhc::import::{ImportOptions, import};
use bvhc::loader::{BvhFile, Ray, Tracer};
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;

const SCENES: [(&str, &str); 3] = [
    ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
    ("dragon", "stanford-dragon/dragon_vrip.ply.gz"),
    ("building", "trimesh-no-indices-3storybuilding/no_indices_3storybuilding.glb"),
];

/// (scale relative to the scene's largest coordinate, offset).
const PLACEMENTS: [(f64, f64); 6] = [(1.0, 0.0), (1e-3, 0.0), (1e-3, 0.5), (1e4, 0.0), (1.0, 1e3), (1e4, 1e6)];

/// Writes `triangles` as a binary little-endian PLY (vertices not shared).
fn write_ply(path: &Path, triangles: &[[[f32; 3]; 3]]) {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let header = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        triangles.len() * 3,
        triangles.len()
    );
    out.write_all(header.as_bytes()).unwrap();
    for v in triangles.iter().flatten().flatten() {
        out.write_all(&v.to_le_bytes()).unwrap();
    }
    for t in 0..triangles.len() as i32 {
        out.write_all(&[3]).unwrap();
        for k in 0..3 {
            out.write_all(&(3 * t + k).to_le_bytes()).unwrap();
        }
    }
}

/// (AO rays, self-hits with the helper, self-hits when spawned naively) for `camera` rays, 8 AO rays a hit.
fn trace(tracer: &Tracer<'_>, camera: &[Ray]) -> (u64, u64, u64) {
    camera
        .par_chunks(1024)
        .enumerate()
        .map(|(chunk, rays)| {
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(chunk as u64);
            let mut counts = (0u64, 0u64, 0u64);
            for ray in rays {
                let Some(hit) = tracer.closest_hit(ray) else { continue };
                let surface = tracer.surface(&hit).unwrap();
                if surface.normal == [0.0; 3] {
                    continue;
                }
                let own = |found: Option<bvhc::loader::Hit>| {
                    found.is_some_and(|h| h.source_triangle_id == hit.source_triangle_id)
                };
                for _ in 0..8 {
                    let direction = surface.cosine_direction([rng.random(), rng.random()]);
                    counts.0 += 1;
                    counts.1 +=
                        u64::from(own(tracer.closest_hit(&surface.spawn(direction).expect("a unit direction"))));
                    let naive = Ray { origin: surface.position, direction, t_min: 0.0, t_max: f32::INFINITY };
                    counts.2 += u64::from(own(tracer.closest_hit(&naive)));
                }
            }
            counts
        })
        .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2))
}

fn main() {
    if !harness::benchmarking("spawn") {
        return;
    }
    let per_placement: usize = std::env::var("BVHC_SPAWN_RAYS").ok().and_then(|v| v.parse().ok()).unwrap_or(700_000);
    let wanted = std::env::var("BVHC_SPAWN_SCENES").ok();
    let dir = tempfile::tempdir().unwrap();
    println!("| scene | scale | offset | AO rays | self-hits | naive self-hits | Mrays/s |");
    println!("|---|---|---|---|---|---|---|");
    let (mut all_rays, mut all_self) = (0u64, 0u64);
    for (name, relative) in SCENES {
        if wanted.as_deref().is_some_and(|w| !w.split(',').any(|s| s == name)) {
            continue;
        }
        let path = harness::scenes_dir().join(relative);
        if !path.is_file() {
            println!("SKIPPED: {name}: {} not found", path.display());
            continue;
        }
        let triangles = import(&path, &ImportOptions::default()).unwrap().soup.triangle_vertices();
        let extent = triangles.iter().flatten().flatten().fold(0.0f32, |m, c| m.max(c.abs()));
        for (i, &(scale, offset)) in PLACEMENTS.iter().enumerate() {
            let factor = scale / f64::from(extent);
            let placed: Vec<[[f32; 3]; 3]> =
                triangles.iter().map(|t| t.map(|v| v.map(|c| (f64::from(c) * factor + offset) as f32))).collect();
            let ply = dir.path().join("placed.ply");
            let bvh = dir.path().join("placed.bvh");
            write_ply(&ply, &placed);
            bvhc::Conversion::new(&ply, &bvh).force(true).run().unwrap();
            let file = BvhFile::read(&bvh).unwrap();
            let tracer = file.view().tracer();
            let root = file.view().nodes()[0];
            let center: [f64; 3] = std::array::from_fn(|a| 0.5 * (f64::from(root.min[a]) + f64::from(root.max[a])));
            let radius = (0..3).map(|a| f64::from(root.max[a]) - f64::from(root.min[a])).fold(0.0, f64::max);
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(40 + i as u64);
            let camera: Vec<Ray> = (0..per_placement / 4)
                .map(|_| {
                    let from: [f64; 3] = std::array::from_fn(|a| center[a] + radius * rng.random_range(-1.0..1.0));
                    let to: [f64; 3] = std::array::from_fn(|a| center[a] + 0.3 * radius * rng.random_range(-1.0..1.0));
                    Ray::new(from.map(|c| c as f32), std::array::from_fn(|a| (to[a] - from[a]) as f32))
                })
                .collect();
            let clock = Instant::now();
            let (rays, self_hits, naive) = trace(&tracer, &camera);
            let seconds = clock.elapsed().as_secs_f64();
            all_rays += rays;
            all_self += self_hits;
            println!(
                "| {name} | {scale:e} | {offset:e} | {rays} | {self_hits} | {naive} | {:.2} |",
                2.0 * rays as f64 / seconds / 1e6
            );
        }
    }
    println!("\n{all_rays} AO rays spawned in all, {all_self} self-hits");
}
