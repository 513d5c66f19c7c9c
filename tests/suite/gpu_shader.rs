//! The WGSL kernel (`crates/bvhc-loader/src/gpu.wgsl`) run through wgpu on the first adapter (in CI, Mesa's
//! software Vulkan driver, lavapipe, which `.ci/run` installs): its hits against the CPU kernel's on the stress
//! scenes, random scenes and real scenes, within the classes of `format-spec/bvh-1.md` 11.4, and against the CPU
//! model of the same walk ([`GpuLayoutTracer`]). SKIPPED, with the reason, where no adapter exists.
//!
//! `cargo test --release gpu_shader -- --nocapture` prints the tables kept in `docs/gpu.md`.

use bvhc::loader::{BvhView, GpuError, GpuLayoutTracer, GpuTracer, Ray};

use crate::common::{Triangle, random_rays, random_triangles, scene};
use crate::gpu_compare::{Agreement, TABLE_HEADER, Tally, compare, gpu_file};
use crate::gpu_layout::{REAL_SCENES, assert_within_classes, convert_gpu, scene_rays};

/// A tracer on the first adapter, or `None` (reported as SKIPPED) where there is none.
fn gpu_tracer<'a>(view: &BvhView<'a>) -> Option<GpuTracer<'a>> {
    match GpuTracer::new(view) {
        Ok(tracer) => Some(tracer),
        Err(GpuError::NoAdapter(why)) => {
            eprintln!("SKIPPED: no GPU adapter ({why}); install a Vulkan driver (Debian: mesa-vulkan-drivers)");
            None
        }
        Err(e) => panic!("{e}"),
    }
}

/// The shader's hits against the CPU kernel's (and the model's) on `rays`.
fn tally(view: &BvhView<'_>, tracer: &GpuTracer<'_>, rays: &[Ray]) -> (Tally, usize) {
    let cpu = view.tracer();
    let model = GpuLayoutTracer::new(view.gpu_sections().unwrap(), view.triangles(), view.triangle_ids());
    let closest = tracer.closest_hits(rays).expect("traces");
    let any = tracer.any_hits(rays).expect("traces");
    let mut tally = Tally::default();
    let mut unlike_model = 0;
    for ((ray, gpu), gpu_any) in rays.iter().zip(closest).zip(any) {
        let c = cpu.closest_hit(ray);
        tally.hits += usize::from(c.is_some());
        let agreement = compare(view, ray, c, gpu, &mut tally.worst_t);
        tally.add(agreement);
        if cpu.any_hit(ray) != gpu_any && agreement != Agreement::F32Edge {
            tally.any_hit_differs += 1;
        }
        let m = model.closest_hit(ray);
        if m.map(|h| (h.triangle_index, h.t.to_bits())) != gpu.map(|h| (h.triangle_index, h.t.to_bits())) {
            unlike_model += 1;
        }
    }
    (tally, unlike_model)
}

#[test]
fn the_wgsl_kernel_agrees_with_the_cpu_kernel_under_stress_and_on_random_scenes() {
    let probe = gpu_file(&random_triangles(0, 10, 1.0));
    let Some(tracer) = gpu_tracer(&probe.view()) else { return };
    let adapter = tracer.adapter_info().map_or(String::new(), |a| format!("{} ({:?})", a.name, a.backend));
    println!("\nadapter: {adapter}\n{TABLE_HEADER} unlike the model |");
    let mut cases: Vec<(String, Vec<Triangle>, Vec<Ray>)> =
        crate::stress::stress_cases().into_iter().map(|c| (c.name, c.triangles, c.rays)).collect();
    for seed in 0..2 {
        cases.push((
            format!("random scene {seed}"),
            random_triangles(seed, 3000, 10.0),
            random_rays(seed + 100, 4000, 10.0),
        ));
    }
    for (name, triangles, rays) in cases {
        let file = gpu_file(&triangles);
        let view = file.view();
        let tracer = gpu_tracer(&view).expect("the adapter found above");
        let (tally, unlike_model) = tally(&view, &tracer, &rays);
        println!("| {name} {tally} {unlike_model} |");
        assert_within_classes(&name, &tally);
    }
}

#[test]
fn the_wgsl_kernel_agrees_with_the_cpu_kernel_on_real_scenes() {
    let rays_per_scene: usize =
        std::env::var("BVHC_GPU_TEST_RAYS").ok().and_then(|v| v.parse().ok()).unwrap_or(1_000_000);
    println!("\n{TABLE_HEADER} unlike the model |");
    for relative in REAL_SCENES {
        let Some(input) = scene(relative) else { continue };
        let dir = tempfile::tempdir().unwrap();
        let file = convert_gpu(&input, dir.path());
        let view = file.view();
        let Some(tracer) = gpu_tracer(&view) else { return };
        let (tally, unlike_model) = tally(&view, &tracer, &scene_rays(&view, 9, rays_per_scene));
        println!("| {relative} {tally} {unlike_model} |");
        assert_within_classes(relative, &tally);
    }
}

#[test]
fn a_file_without_gpu_sections_is_refused_with_the_way_to_add_them() {
    let file = crate::common::write_wide_file(&random_triangles(1, 100, 1.0), 4);
    let error = GpuTracer::new(&file.view()).err().expect("no GPU sections");
    assert_eq!(error, GpuError::NoGpuSections);
    assert!(error.to_string().contains("--gpu-layout"), "{error}");
}
