//! The GPU sections of format 1.4 and their traversal as the WGSL kernel runs it, modelled on the CPU
//! ([`GpuLayoutTracer`]): written by the conversion with `--gpu-layout` (verified, deterministic), and traced
//! with the same hits as the CPU kernel on the stress scenes, random scenes and real scenes, within the classes
//! of `format-spec/bvh-1.md` 11.4 (ties between triangles that meet at one point, edges decided in f32), with
//! no missed hit.
//!
//! `cargo test --release gpu_layout -- --nocapture` prints the tables kept in `docs/gpu.md`.

use bvhc_loader::Trace;
use std::ops::ControlFlow;
use std::path::Path;

use bvhc::convert::convert_with;
use bvhc::loader::{BvhFile, BvhView, Ray, gpu::GpuLayoutTracer};
use bvhc::options::{ConvertOptions, Overrides, Preset, resolve};
use rand::RngExt;

use crate::common::{random_rays, random_triangles, rng, scene};
use crate::gpu_compare::{Tally, compare, gpu_file, table_header};

/// Compares the GPU model with the file's CPU kernel on every ray.
pub fn tally(view: &BvhView<'_>, rays: &[Ray]) -> Tally {
    let gpu = view.gpu_sections().expect("a file with the GPU sections");
    let model = GpuLayoutTracer::new(gpu, view.triangles(), view.triangle_ids())
        .with_split_references(view.has_split_references());
    let cpu = view.tracer();
    let mut tally = Tally::default();
    for ray in rays {
        let (c, g) = (cpu.closest_hit(ray), model.closest_hit(ray));
        tally.hits += usize::from(c.is_some());
        let agreement = compare(view, ray, c, g, &mut tally.worst_t);
        tally.add(agreement);
        if cpu.any_hit(ray) != model.any_hit(ray) {
            tally.any_hit_differs += 1;
        }
    }
    tally
}

/// Asserts what 11.4 promises: every closest hit is the CPU's record bit for bit, the same triangle or a tie at
/// a `t` within the bound (never a miss, a farther hit or a record the CPU's test rejects), and every any-hit
/// answer is the CPU's.
pub fn assert_within_classes(name: &str, tally: &Tally) {
    assert_eq!(tally.differs, 0, "{name}: {tally}");
    assert_eq!(tally.any_hit_differs, 0, "{name}: {tally}");
}

#[test]
fn the_model_of_the_gpu_kernel_agrees_with_the_cpu_kernel_under_stress() {
    println!("\n{}", table_header(&[]));
    for case in crate::stress::stress_cases() {
        let file = gpu_file(&case.triangles);
        let view = file.view();
        view.verify().expect("the GPU layout verifies");
        let tally = tally(&view, &case.rays);
        println!("| {} {tally}", case.name);
        assert_within_classes(&case.name, &tally);
        if case.must_hit {
            let model = view.gpu_layout_tracer().unwrap();
            let missed = case.rays.iter().filter(|r| model.closest_hit(r).is_none()).count();
            assert_eq!(missed, 0, "{}: rays from inside a closed mesh missed it", case.name);
        }
    }
}

#[test]
fn the_model_agrees_on_random_scenes_with_zero_direction_components() {
    for seed in 0..4 {
        let triangles = random_triangles(seed, 3000, 10.0);
        let file = gpu_file(&triangles);
        file.view().verify().expect("verifies");
        let tally = tally(&file.view(), &random_rays(seed + 100, 4000, 10.0));
        assert_within_classes(&format!("random scene {seed}"), &tally);
        assert!(tally.hits > 1000);
    }
}

#[test]
fn an_empty_scene_and_a_single_triangle_have_gpu_sections() {
    for triangles in [vec![], vec![[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]]] {
        let file = gpu_file(&triangles);
        let view = file.view();
        view.verify().expect("verifies");
        let gpu = view.gpu_sections().unwrap();
        assert_eq!(gpu.nodes.len(), triangles.len());
        let model = GpuLayoutTracer::new(gpu, view.triangles(), view.triangle_ids())
            .with_split_references(view.has_split_references());
        let hit = model.closest_hit(&Ray::new([0.25, 0.25, 1.0], [0.0, 0.0, -1.0]));
        assert_eq!(hit.map(|h| h.t), (!triangles.is_empty()).then_some(1.0));
    }
}

/// Options with the GPU layout, from the balanced preset.
pub fn gpu_options() -> ConvertOptions {
    resolve(Preset::Balanced, &Overrides { gpu_layout: Some(true), ..Overrides::default() }).expect("valid")
}

/// Converts `input` with the GPU layout into `dir`.
pub fn convert_gpu(input: &Path, dir: &Path) -> BvhFile {
    let output = dir.join("scene.bvh");
    convert_with(input, &output, &gpu_options(), &mut |_| ControlFlow::Continue(())).expect("converts");
    BvhFile::read(&output).expect("reads")
}

/// Rays between random points of the scene's box grown by a quarter, so most cross the geometry.
pub fn scene_rays(view: &BvhView<'_>, seed: u64, count: usize) -> Vec<Ray> {
    let (min, max) = view.scene_box().expect("a scene");
    let mut r = rng(seed);
    let point = |r: &mut rand_pcg::Pcg64Mcg| -> [f32; 3] {
        std::array::from_fn(|a| {
            let pad = (max[a] - min[a]) * 0.25;
            r.random_range(min[a] - pad..=max[a] + pad)
        })
    };
    (0..count)
        .map(|_| {
            let o = point(&mut r);
            let t = point(&mut r);
            Ray::new(o, std::array::from_fn(|a| t[a] - o[a]))
        })
        .collect()
}

/// Real scenes with split references (the default conversion's SBVH), architectural and scanned.
pub const REAL_SCENES: [&str; 5] = [
    "utah-teapot/teapot.obj",
    "khr-lantern/Lantern.gltf",
    "khr-cesium-milk-truck/CesiumMilkTruck.gltf",
    "stanford-dragon/dragon_vrip_res3.ply.gz",
    "khr-damaged-helmet/DamagedHelmet.gltf",
];

#[test]
fn the_model_agrees_on_real_scenes_converted_with_the_gpu_layout() {
    println!("\n{}", table_header(&[]));
    for relative in REAL_SCENES {
        let Some(input) = scene(relative) else { continue };
        let dir = tempfile::tempdir().unwrap();
        let file = convert_gpu(&input, dir.path());
        let view = file.view();
        let gpu = view.gpu_sections().expect("written with --gpu-layout");
        assert!(!gpu.nodes.is_empty());
        let tally = tally(&view, &scene_rays(&view, 5, 20_000));
        println!("| {relative} {tally}");
        assert_within_classes(relative, &tally);
        assert!(tally.hits > 2000, "{relative}: {tally}");
    }
}

#[test]
fn the_gpu_layout_is_the_same_bytes_on_one_and_two_threads_and_recorded_in_the_build_key() {
    let Some(input) = scene("khr-lantern/Lantern.gltf") else { return };
    let dir = tempfile::tempdir().unwrap();
    let bytes = |threads: usize| {
        let path = dir.path().join(format!("{threads}.bvh"));
        crate::common::in_pool(threads, || {
            convert_with(&input, &path, &gpu_options(), &mut |_| ControlFlow::Continue(())).expect("converts")
        });
        std::fs::read(&path).unwrap()
    };
    let one = bytes(1);
    assert_eq!(one, bytes(2));
    let file = BvhFile::from_bytes(&one).unwrap();
    assert_eq!(file.view().version(), (1, 4));
    let metadata: serde_json::Value = serde_json::from_str(file.view().metadata_str().unwrap().unwrap()).unwrap();
    assert_eq!(metadata["build"]["gpu"]["max_leaf_size"], 3);
    // A conversion without the layout records no `gpu` key, so files converted before 1.4 keep their bytes.
    let plain = dir.path().join("plain.bvh");
    convert_with(&input, &plain, &ConvertOptions::default(), &mut |_| ControlFlow::Continue(())).unwrap();
    let plain = BvhFile::read(&plain).unwrap();
    assert!(plain.view().gpu_sections().is_none());
    assert!(!plain.view().metadata_str().unwrap().unwrap().contains("\"gpu\""));
}
