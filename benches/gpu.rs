//! The GPU layout (format 1.4) against obvhs's compressed wide BVH: per ray, node visits, triangle tests and
//! bytes read by the GPU kernel's walk, counted by its CPU model (`GpuLayoutTracer`, which takes the shader's
//! steps) on both trees, on the same rays; and rays per second of the WGSL kernel itself on the first wgpu
//! adapter, over both trees through the same shader (timestamp queries where the adapter has them, else wall
//! clock), interleaved in rounds. On a software adapter (lavapipe) the speeds are reported, not targets.
//!
//! Trees: bvhc's conversion with `--gpu-layout` (the balanced preset: SBVH splits, reinsertion, the GPU
//! collapse with leaves of at most 3), and obvhs 0.4's `build_cwbvh_from_tris` with `very_slow_build` over the
//! file's distinct triangles, its nodes read into the same 80-byte layout (obvhs stores the six box rows
//! interleaved; its octant order and meta bytes are the paper's, which 1.4 pins) and its leaf triangles into
//! GPU triangle records. Also the file sizes: the GPU sections against the CPU wide sections.
//!
//! Rays (`benches/evaluate/ray_set.rs`'s set): primary rays of a 512 x 384 camera, 4 ambient occlusion rays
//! (any hit) per primary hit, and as many incoherent rays (origins in the box, uniform directions).
//!
//! `cargo bench --bench gpu`; `BVHC_GPU_SCENES=kitchen,dragon` narrows the scenes; `BVHC_GPU_ROUNDS` (default 3);
//! `BVHC_GPU_TRIANGLE_TEST=0.5` converts with another triangle test cost in the GPU collapse (default 0.3);
//! `BVHC_GPU_TUNE_RAYS=65536` tunes the collapses to that many training rays (`--tune-rays`).

#[path = "common/harness.rs"]
mod harness;

#[path = "evaluate/ray_set.rs"]
#[allow(dead_code)]
mod ray_set;

use bvhc_loader::Trace;
use std::ops::ControlFlow;
use std::time::Duration;

use bvhc::convert::convert_with;
use bvhc::loader::format::{GpuNode, GpuTriangle, PackedTriangle};
use bvhc::loader::{
    BvhFile, GpuSections, Ray, TraversalStats, gpu::GPU_NODE_BYTES, gpu::GPU_TRIANGLE_BYTES, gpu::GpuLayoutTracer,
    gpu::GpuTracer,
};
use bvhc::options::{Overrides, Preset, resolve};

const SCENES: [(&str, &str); 8] = [
    ("teapot", "utah-teapot/teapot.obj"),
    ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
    ("toy car", "khr-toy-car/ToyCar.gltf"),
    ("engine", "khr-2cylinder-engine/2CylinderEngine.gltf"),
    ("milk truck", "khr-cesium-milk-truck/CesiumMilkTruck.gltf"),
    ("bunny", "stanford-bunny-ply/bun_zipper.ply"),
    ("buddha", "happy-buddha-decimated/stanford-buddha.obj"),
    ("dragon", "stanford-dragon/dragon_vrip.ply.gz"),
];

fn main() {
    let full = harness::benchmarking("gpu");
    let scenes = harness::scenes(&SCENES, Some("BVHC_GPU_SCENES"));
    let scenes = if full { scenes } else { scenes.into_iter().take(1).collect() };
    let rounds: usize = std::env::var("BVHC_GPU_ROUNDS").ok().and_then(|v| v.parse().ok()).unwrap_or(3);
    println!(
        "| scene | triangles | tree | GPU bytes / CPU wide bytes | the same with 4-byte triangle indices | node visits / \
         ray | triangle tests / ray | bytes read / ray | visits vs obvhs | Mrays/s (kernel) | speed vs bvhc |\n\
         |---|---|---|---|---|---|---|---|---|---|---|"
    );
    for (name, path) in scenes {
        let dir = tempfile::tempdir().expect("a temporary folder");
        let output = dir.path().join("scene.bvh");
        let preset =
            std::env::var("BVHC_GPU_PRESET").ok().and_then(|p| Preset::ALL.into_iter().find(|k| k.name() == p));
        let preset = preset.unwrap_or(Preset::Balanced);
        let mut options =
            resolve(preset, &Overrides { gpu_layout: Some(true), ..Overrides::default() }).expect("valid options");
        if let (Some(gpu), Some(cost)) = (&mut options.gpu, env_number("BVHC_GPU_TRIANGLE_TEST")) {
            gpu.triangle_test = cost;
        }
        if let Some(rays) = env_number("BVHC_GPU_TUNE_RAYS") {
            options.ray_tuning = Some(bvhc::sampling::RayTuning { rays: rays as usize, ..Default::default() });
        }
        convert_with(&path, &output, &options, &mut |_| ControlFlow::Continue(())).expect("converts");
        let file = BvhFile::read(&output).expect("reads");
        let view = file.view();
        let ours = view.gpu_sections().expect("GPU sections");
        let (root_min, root_max) = view.scene_box().expect("a scene");
        let rays = ray_set::ray_set(&view.tracer(), root_min, root_max);
        let rays = if full { rays } else { shorten(rays, 2000) };
        let (peer_nodes, peer_triangles) = obvhs_cwbvh(view.triangles(), view.triangle_ids());
        let peer = GpuSections { nodes: &peer_nodes, triangles: &peer_triangles };
        let counts = [count(ours, &view, &rays), count(peer, &view, &rays)];
        let wide_bytes = view.wide_sections().map_or(0, |w| size_of_val(w.nodes) + size_of_val(w.packets));
        let bytes = |g: GpuSections<'_>| (size_of_val(g.nodes) + size_of_val(g.triangles)) as f64;
        // The design not taken (docs/gpu.md): leaves naming records of the triangles section, 4 bytes each.
        let indexed = |g: GpuSections<'_>| (size_of_val(g.nodes) + 4 * g.triangles.len()) as f64;
        let speeds = gpu_speeds(&[ours, peer], &view, &rays, if full { rounds } else { 1 });
        for (k, (tree, sections)) in [("bvhc", ours), ("obvhs very_slow", peer)].into_iter().enumerate() {
            let c = counts[k];
            let speed = speeds.as_ref().map_or("no adapter".to_string(), |s| format!("{:.2}", s[k].0));
            let ratio = speeds.as_ref().map_or("-".to_string(), |s| format!("{:.3}", s[k].1));
            println!(
                "| {name} | {} | {tree} | {:.3} | {:.3} | {:.2} | {:.2} | {:.0} | {:.3} | {speed} | {ratio} |",
                view.triangles().len(),
                bytes(sections) / wide_bytes.max(1) as f64,
                indexed(sections) / wide_bytes.max(1) as f64,
                c.visits,
                c.tests,
                c.bytes,
                c.visits / counts[1].visits,
            );
        }
        if let Some(speeds) = &speeds {
            println!("|  |  | adapter: {} |  |  |  |  |  |  |  |  |", speeds[0].2);
        }
        let unlike =
            format!("hits unlike the file's CPU kernel: bvhc {}, obvhs {}", counts[0].unlike, counts[1].unlike);
        println!("|  |  | {unlike} |  |  |  |  |  |  |  |  |");
    }
}

/// Per-ray averages of the GPU model's walk over all three ray sets, and the rays whose closest `t` (or any
/// hit) differs from the file's CPU kernel.
#[derive(Clone, Copy, Debug, Default)]
struct Counts {
    visits: f64,
    tests: f64,
    bytes: f64,
    unlike: usize,
}

fn count(sections: GpuSections<'_>, view: &bvhc::loader::BvhView<'_>, rays: &ray_set::RaySet) -> Counts {
    let model = GpuLayoutTracer::new(sections, view.triangles(), view.triangle_ids())
        .with_split_references(view.has_split_references());
    let cpu = view.tracer();
    let mut stats = TraversalStats::default();
    let mut unlike = 0;
    for ray in rays.primary.iter().chain(&rays.incoherent) {
        let t = model.closest_hit_counted(ray, &mut stats).map(|h| h.t);
        let reference = cpu.closest_hit(ray).map(|h| h.t);
        unlike += usize::from(
            t.zip(reference)
                .map_or(t.is_some() != reference.is_some(), |(a, b)| (a - b).abs() > 1e-4 * b.abs().max(1e-3)),
        );
    }
    for ray in &rays.ao {
        unlike += usize::from(model.any_hit_counted(ray, &mut stats) != cpu.any_hit(ray));
    }
    let n = (rays.primary.len() + rays.incoherent.len() + rays.ao.len()) as f64;
    Counts {
        visits: stats.node_visits as f64 / n,
        tests: stats.triangle_tests as f64 / n,
        bytes: (stats.node_visits * GPU_NODE_BYTES + stats.triangle_tests * GPU_TRIANGLE_BYTES) as f64 / n,
        unlike,
    }
}

/// Mrays/s of the WGSL kernel over each of `trees` (all three ray sets, AO rays as any hits), medians of
/// `rounds` interleaved rounds, with the median ratio to the first tree and the adapter's name; `None` without
/// an adapter.
fn gpu_speeds(
    trees: &[GpuSections<'_>],
    view: &bvhc::loader::BvhView<'_>,
    rays: &ray_set::RaySet,
    rounds: usize,
) -> Option<Vec<(f64, f64, String)>> {
    let tracers: Vec<GpuTracer<'_>> = trees
        .iter()
        .map(|&t| GpuTracer::on_sections(t, view.triangles(), view.triangle_ids()))
        .collect::<Result<_, _>>()
        .map_err(|e| eprintln!("SKIPPED: GPU speeds ({e})"))
        .ok()?;
    let adapter = tracers[0].adapter_info().map_or(String::new(), |a| format!("{} ({:?})", a.name, a.backend));
    let closest: Vec<Ray> = rays.primary.iter().chain(&rays.incoherent).copied().collect();
    let total = (closest.len() + rays.ao.len()) as f64;
    let mut seconds = vec![Vec::new(); tracers.len()];
    for _ in 0..rounds {
        for (k, tracer) in tracers.iter().enumerate() {
            let a = tracer.trace(&closest, false).expect("traces");
            let b = tracer.trace(&rays.ao, true).expect("traces");
            let time = |t: &bvhc::loader::gpu::GpuTrace| t.kernel_seconds.unwrap_or(t.seconds);
            seconds[k].push(time(&a) + time(&b));
        }
    }
    let ratios: Vec<Vec<f64>> =
        (0..tracers.len()).map(|k| (0..rounds).map(|r| seconds[0][r] / seconds[k][r]).collect()).collect();
    Some(
        (0..tracers.len())
            .map(|k| (total / median(&mut seconds[k].clone()) / 1e6, median(&mut ratios[k].clone()), adapter.clone()))
            .collect(),
    )
}

/// A number from the environment (the collapse's constants, for comparing them).
fn env_number(variable: &str) -> Option<f64> {
    std::env::var(variable).ok().and_then(|v| v.parse().ok())
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// The first `n` rays of each set (for the smoke run).
fn shorten(rays: ray_set::RaySet, n: usize) -> ray_set::RaySet {
    let cut = |mut v: Vec<Ray>| {
        v.truncate(n);
        v
    };
    ray_set::RaySet { primary: cut(rays.primary), ao: cut(rays.ao), incoherent: cut(rays.incoherent) }
}

/// obvhs's CWBVH (`very_slow_build`) over the file's distinct triangles (the first record of each source id,
/// or every record without ids), in the GPU layout's types: its nodes' fields moved into [`GpuNode`]'s order,
/// its leaf primitives as [`GpuTriangle`]s naming their records.
fn obvhs_cwbvh(triangles: &[PackedTriangle], ids: Option<&[u32]>) -> (Vec<GpuNode>, Vec<GpuTriangle>) {
    let mut records: Vec<u32> = (0..triangles.len() as u32).collect();
    if let Some(ids) = ids {
        let mut seen = std::collections::HashSet::new();
        records.retain(|&r| seen.insert(ids[r as usize]));
    }
    let vertices: Vec<[[f32; 3]; 3]> = records.iter().map(|&r| triangles[r as usize].vertices).collect();
    let tris = harness::obvhs_triangles(&vertices);
    let mut build_time = Duration::ZERO;
    let bvh =
        obvhs::cwbvh::builder::build_cwbvh_from_tris(&tris, obvhs::BvhBuildParams::very_slow_build(), &mut build_time);
    let nodes = bvh
        .nodes
        .iter()
        .map(|n| GpuNode {
            origin: n.p.to_array(),
            exponents: n.e,
            inner_mask: n.imask,
            child_base: n.child_base_idx,
            triangle_base: n.primitive_base_idx,
            meta: n.child_meta,
            quantized_min: [n.child_min_x, n.child_min_y, n.child_min_z],
            quantized_max: [n.child_max_x, n.child_max_y, n.child_max_z],
        })
        .collect();
    let gpu_triangles = bvh
        .primitive_indices
        .iter()
        .map(|&p| {
            let record = records[p as usize];
            GpuTriangle { vertices: triangles[record as usize].vertices, triangle_index: record }
        })
        .collect();
    (nodes, gpu_triangles)
}
