//! The WGSL kernel (`crates/bvhc-loader/src/gpu/gpu.wgsl`) run through wgpu on the first adapter (in CI, Mesa's
//! software Vulkan driver, lavapipe, which `.ci/run` installs): its hits against the CPU kernel's on the stress
//! scenes, random scenes and real scenes, within the classes of `format-spec/bvh-1.md` 11.4, and against the CPU
//! model of the same walk ([`GpuLayoutTracer`]). SKIPPED, with the reason, where no adapter exists.
//!
//! `cargo test --release gpu_shader -- --nocapture` prints the tables kept in `docs/gpu.md`.

use bvhc::loader::{BvhView, Hit, Ray, gpu::GpuError, gpu::GpuTracer};
use bvhc_loader::Trace;

use crate::common::{Triangle, random_rays, random_triangles, scene};
use crate::gpu_compare::{Tally, compare, gpu_file, table_header};
use crate::gpu_layout::{REAL_SCENES, assert_within_classes, convert_gpu, scene_rays};

/// A tracer on the first adapter, or `None` (reported as SKIPPED) where there is none.
fn gpu_tracer<'a>(view: &BvhView<'a>) -> Option<GpuTracer<'a>> {
    match GpuTracer::new(view) {
        Ok(tracer) => Some(tracer),
        Err(GpuError::NoAdapter(why)) => {
            let what = format!(
                "the WGSL kernel (no GPU adapter: {why}; install a Vulkan driver, Debian: mesa-vulkan-drivers)"
            );
            crate::skips::skipped(crate::skips::Needs::Vulkan, what);
            None
        }
        Err(e) => panic!("{e}"),
    }
}

/// The shader's hits against the CPU kernel's (and the model's) on `rays`.
fn tally(view: &BvhView<'_>, tracer: &GpuTracer<'_>, rays: &[Ray]) -> (Tally, usize) {
    let cpu = view.tracer();
    let model = view.gpu_layout_tracer().unwrap();
    let closest = tracer.closest_hits(rays).expect("traces");
    let any = tracer.any_hits(rays).expect("traces");
    let mut tally = Tally::default();
    let mut unlike_model = 0;
    for ((ray, gpu), gpu_any) in rays.iter().zip(closest).zip(any) {
        let c = cpu.closest_hit(ray);
        tally.hits += usize::from(c.is_some());
        let agreement = compare(view, ray, c, gpu, &mut tally.worst_t);
        tally.add(agreement);
        if cpu.any_hit(ray) != gpu_any {
            tally.any_hit_differs += 1;
        }
        let bits = |h: Hit| (h.triangle_index, h.t.to_bits(), h.u.to_bits(), h.v.to_bits());
        if model.closest_hit(ray).map(bits) != gpu.map(bits) {
            unlike_model += 1;
        }
    }
    (tally, unlike_model)
}

/// On Mesa's lavapipe, whose arithmetic is correctly rounded and unfused, the shader's records are the CPU model's
/// bit for bit (11.4); other adapters may fuse or divide within 2.5 ulp, and are only held to the classes.
fn assert_like_the_model(tracer: &GpuTracer<'_>, name: &str, unlike_model: usize) {
    if tracer.adapter_info().is_some_and(|a| a.name.contains("llvmpipe")) {
        assert_eq!(unlike_model, 0, "{name}: records unlike the model's on lavapipe");
    }
}

#[test]
fn the_wgsl_kernel_agrees_with_the_cpu_kernel_under_stress_and_on_random_scenes() {
    let probe = gpu_file(&random_triangles(0, 10, 1.0));
    let Some(tracer) = gpu_tracer(&probe.view()) else { return };
    let adapter = tracer.adapter_info().map_or(String::new(), |a| format!("{} ({:?})", a.name, a.backend));
    println!("\nadapter: {adapter}\n{}", table_header(&["unlike the model"]));
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
        assert_like_the_model(&tracer, &name, unlike_model);
    }
}

/// Needles and slivers (`needles.rs`): the kernel leaves rays whose closest hit may be ill-conditioned to the CPU
/// (11.1 step 5, 11.4), and every other record is the model's, whose ill-conditioned hits are exact: so after
/// the CPU has traced those rays, the records are the model's and the CPU kernel's bit for bit on lavapipe.
#[test]
fn rays_with_ill_conditioned_hits_are_left_to_the_cpu_and_the_others_are_the_models() {
    let probe = gpu_file(&random_triangles(0, 10, 1.0));
    let Some(_) = gpu_tracer(&probe.view()) else { return };
    println!("\n| scene | rays | closest hits left to the CPU | any hits left to the CPU |\n|---|---|---|---|");
    for scene in crate::needles::needle_scenes() {
        let file = gpu_file(&scene.triangles);
        let view = file.view();
        let tracer = gpu_tracer(&view).expect("the adapter found above");
        let model = view.gpu_layout_tracer().unwrap();
        let (closest, any) = (tracer.trace(&scene.rays, false).unwrap(), tracer.trace(&scene.rays, true).unwrap());
        println!("| {} | {} | {} | {} |", scene.name, scene.rays.len(), closest.cpu_rays, any.cpu_rays);
        assert!(
            closest.cpu_rays > 0 && closest.cpu_rays < scene.rays.len() / 4,
            "{}: {}",
            scene.name,
            closest.cpu_rays
        );
        if tracer.adapter_info().is_some_and(|a| a.name.contains("llvmpipe")) {
            for (i, ray) in scene.rays.iter().enumerate() {
                assert_eq!(closest.records[i], model.record(ray, false), "{}: ray {i} {ray:?}", scene.name);
                assert_eq!(
                    any.records[i].triangle == u32::MAX,
                    !model.any_hit(ray),
                    "{}: any hit, ray {i}",
                    scene.name
                );
            }
        }
        let (tally, unlike_model) = tally(&view, &tracer, &scene.rays);
        assert_within_classes(&scene.name, &tally);
        assert_like_the_model(&tracer, &scene.name, unlike_model);
    }
}

#[test]
fn the_wgsl_kernel_agrees_with_the_cpu_kernel_on_real_scenes() {
    let rays_per_scene: usize =
        std::env::var("BVHC_GPU_TEST_RAYS").ok().and_then(|v| v.parse().ok()).unwrap_or(1_000_000);
    println!("\n{}", table_header(&["unlike the model"]));
    for relative in REAL_SCENES {
        let Some(input) = scene(relative) else { continue };
        let dir = tempfile::tempdir().unwrap();
        let file = convert_gpu(&input, dir.path());
        let view = file.view();
        let Some(tracer) = gpu_tracer(&view) else { return };
        let (tally, unlike_model) = tally(&view, &tracer, &scene_rays(&view, 9, rays_per_scene));
        println!("| {relative} {tally} {unlike_model} |");
        assert_within_classes(relative, &tally);
        assert_like_the_model(&tracer, relative, unlike_model);
    }
}

#[test]
fn a_file_without_gpu_sections_is_refused_with_the_way_to_add_them() {
    let file = crate::common::write_wide_file(&random_triangles(1, 100, 1.0), 4);
    let error = GpuTracer::new(&file.view()).err().expect("no GPU sections");
    assert_eq!(error, GpuError::NoGpuSections);
    assert!(error.to_string().contains("--gpu-layout"), "{error}");
}

/// 11.1's value of an edge function that is exactly 0 in f32, as 11.4 says a GPU kernel computes it: `a b - c d`
/// in f64 (exact here), rounded to f32, or `+-2^-126` below the normal range.
fn reference_exact_difference(a: f32, b: f32, c: f32, d: f32) -> f32 {
    let x = f64::from(a) * f64::from(b) - f64::from(c) * f64::from(d);
    if x != 0.0 && x.abs() < f64::from(f32::MIN_POSITIVE) { f32::MIN_POSITIVE.copysign(x as f32) } else { x as f32 }
}

/// Operands `(a, b, c, d)` whose f32 products `a b` and `c d` round to the same normal value, over magnitudes
/// from `2^-120` to `2^100` and both signs, most of them with different exact products.
fn equal_product_operands(count: usize) -> Vec<[f32; 4]> {
    use rand::RngExt;
    let mut rng = crate::common::rng(3701);
    let mut operands = Vec::with_capacity(count);
    while operands.len() < count {
        let scale = |r: &mut rand_pcg::Pcg64Mcg| 2f32.powi(r.random_range(-60..50));
        let a = rng.random_range(1.0..2.0f32) * scale(&mut rng) * if rng.random() { -1.0 } else { 1.0 };
        let b = rng.random_range(1.0..2.0f32) * scale(&mut rng);
        let p = a * b;
        if !p.is_normal() {
            continue;
        }
        let c = a * rng.random_range(0.25..4.0f32);
        let d0 = (f64::from(p) / f64::from(c)) as f32;
        for step in -3i32..=3 {
            let d = f32::from_bits((d0.to_bits() as i32 + step) as u32);
            if c * d == p {
                operands.push([a, b, c, d]);
            }
        }
        if operands.len() % 97 == 0 {
            operands.push([a, b, b, a]); // the same exact product: 0
        }
    }
    operands.truncate(count);
    operands
}

#[test]
fn the_wgsl_exact_edge_function_equals_the_f64_recomputation() {
    // The shader's integer arithmetic for an edge function whose f32 value is 0 (`exact_product_difference` in
    // gpu.wgsl), run through its `edge_function` on an adapter, against 11.1's f64 recomputation bit for bit.
    use wgpu::util::DeviceExt;
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let options = wgpu::RequestAdapterOptions { force_fallback_adapter: false, ..Default::default() };
    let adapter = match pollster::block_on(instance.request_adapter(&options)) {
        Ok(adapter) => adapter,
        Err(why) => {
            let what = format!("the WGSL edge function (no GPU adapter: {why}; install mesa-vulkan-drivers)");
            return crate::skips::skipped(crate::skips::Needs::Vulkan, what);
        }
    };
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor::default())).unwrap();
    let source = format!(
        "{}\n@group(0) @binding(5) var<storage, read> edge_operands: array<vec4<f32>>;\n\
         @group(0) @binding(6) var<storage, read_write> edge_values: array<f32>;\n\
         @compute @workgroup_size(64)\nfn edge_check(@builtin(global_invocation_id) id: vec3<u32>) {{\n\
         if (id.x < arrayLength(&edge_operands)) {{ let o = edge_operands[id.x]; \
         edge_values[id.x] = edge_function(o.x, o.y, o.z, o.w); }}\n}}\n",
        bvhc::loader::gpu::shader::GPU_TRAVERSAL_WGSL
    );
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("edge check"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("edge check"),
        layout: None,
        module: &module,
        entry_point: Some("edge_check"),
        compilation_options: Default::default(),
        cache: None,
    });
    let operands = equal_product_operands(262_144);
    let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: None,
        contents: bytemuck::cast_slice(&operands),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let size = (operands.len() * 4) as u64;
    let output = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry { binding: 5, resource: input.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 6, resource: output.as_entire_binding() },
        ],
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.dispatch_workgroups(operands.len().div_ceil(64) as u32, 1, 1);
    }
    encoder.copy_buffer_to_buffer(&output, 0, &staging, 0, size);
    queue.submit([encoder.finish()]);
    staging.slice(..).map_async(wgpu::MapMode::Read, |result| result.unwrap());
    device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let values: Vec<f32> = bytemuck::cast_slice(&staging.slice(..).get_mapped_range().unwrap()).to_vec();
    let (mut nonzero, mut clamped) = (0, 0);
    for (o, &got) in operands.iter().zip(&values) {
        let expected = reference_exact_difference(o[0], o[1], o[2], o[3]);
        assert_eq!(got.to_bits(), expected.to_bits(), "{o:?}: shader {got:e}, f64 {expected:e}");
        nonzero += usize::from(expected != 0.0);
        clamped += usize::from(expected.abs() == f32::MIN_POSITIVE);
    }
    let adapter = adapter.get_info().name;
    println!(
        "{adapter}: {} operand sets, {nonzero} nonzero exact values ({clamped} below 2^-126), all equal",
        values.len()
    );
    assert!(nonzero > operands.len() / 2 && clamped > 0, "{nonzero} nonzero, {clamped} clamped");
}

/// Ties on the device (11.1's key, 11.4): a triangle stored three times in the source, two coplanar triangles
/// overlapping and a grid, converted with and without split references; on the rays inside those triangles
/// (where the f32 edge test is the CPU's) the kernel names the hit the brute force does, with split
/// references the copy of lowest source id (binding 5).
#[test]
fn the_wgsl_kernel_decides_ties_by_record_or_by_coordinates_then_id() {
    use crate::ties::{converted, expected, key_of, marked_split, rays_at, tie_scene};
    let dir = tempfile::tempdir().unwrap();
    let (input, _, interior_targets) = tie_scene(dir.path());
    let rays = rays_at(&interior_targets, 52);
    let converted = converted(&input, &dir.path().join("ties.bvh"), false);
    let files = [
        ("split references", marked_split(&converted.view(), false).0),
        ("ids reversed", marked_split(&converted.view(), true).0),
        ("records", converted),
    ];
    for (name, file) in &files {
        let view = file.view();
        let Some(tracer) = gpu_tracer(&view) else { return };
        let trace = tracer.trace(&rays, false).unwrap();
        for (r, (ray, record)) in rays.iter().zip(&trace.records).enumerate() {
            let want = expected(&view, ray).map(|((t, _, key), _)| (t, key));
            let got = (record.triangle != u32::MAX).then(|| (record.t.to_bits(), key_of(&view, record.triangle)));
            assert_eq!(got, want, "{name}: ray {r} {ray:?}");
        }
    }
}
