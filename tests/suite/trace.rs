//! `bvhc trace`: the hit file equals `Tracer` on the same file and rays (closest and any hit), is the same for
//! any thread count, the JSON report has its keys, and bad ray files are refused naming the ray.

use bvhc_loader::Trace;
use std::path::Path;

use bvhc::loader::{BvhFile, Ray};

use crate::cli::{bvhc, stderr, stdout, teapot};
use crate::common::{every_kernel, random_rays};

fn ray_bytes(rays: &[Ray]) -> Vec<u8> {
    rays.iter()
        .flat_map(|r| r.origin.into_iter().chain(r.direction).chain([r.t_min, r.t_max]))
        .flat_map(f32::to_le_bytes)
        .collect()
}

fn word(record: &[u8], at: usize) -> [u8; 4] {
    record[at..at + 4].try_into().unwrap()
}

fn teapot_bvh(dir: &Path) -> std::path::PathBuf {
    let bvh = dir.join("teapot.bvh");
    assert!(bvhc(&[&teapot(), &"-o", &bvh, &"-q", &"--preset", &"fast"]).status.success());
    bvh
}

#[test]
fn trace_writes_what_the_tracer_finds() {
    let dir = tempfile::tempdir().unwrap();
    let bvh = teapot_bvh(dir.path());
    let mut rays = random_rays(91, 5_000, 4.0);
    rays.push(Ray { origin: [0.0, 1.5, 10.0], direction: [0.0, 0.0, -1.0], t_min: 0.0, t_max: f32::INFINITY });
    rays.push(Ray { origin: [100.0, 100.0, 100.0], direction: [1.0, 0.0, 0.0], t_min: 0.0, t_max: 1.0 });
    let ray_file = dir.path().join("rays.bin");
    std::fs::write(&ray_file, ray_bytes(&rays)).unwrap();
    let file = BvhFile::read(&bvh).unwrap();
    let tracer = file.view().tracer();
    let mut outputs = Vec::new();
    for threads in ["1", "2"] {
        let hits = dir.path().join(format!("hits{threads}.bin"));
        let run = bvhc(&[&"trace", &bvh, &"--rays", &ray_file, &"-o", &hits, &"--json", &"--threads", &threads]);
        assert!(run.status.success(), "{}", stderr(&run));
        let report: serde_json::Value = serde_json::from_str(&stdout(&run)).unwrap();
        assert_eq!(report["rays"], rays.len());
        let (seconds, total) = (report["seconds"].as_f64().unwrap(), report["total_seconds"].as_f64().unwrap());
        assert!(report["rays_per_second"].as_f64().is_some() && seconds <= total, "{report}");
        assert!(report.get("cpu_rays").is_none(), "cpu_rays is the GPU's: {report}");
        let bytes = std::fs::read(&hits).unwrap();
        assert_eq!(bytes.len(), 24 * rays.len());
        let mut hit_count = 0;
        for (ray, record) in rays.iter().zip(bytes.chunks_exact(24)) {
            let t = f32::from_le_bytes(word(record, 0));
            let triangle = u32::from_le_bytes(word(record, 4));
            let source = u32::from_le_bytes(word(record, 8));
            match tracer.closest_hit(ray) {
                Some(hit) => {
                    hit_count += 1;
                    assert_eq!((t, triangle, Some(source)), (hit.t, hit.triangle_index, hit.source_triangle_id));
                    assert_eq!(f32::from_le_bytes(word(record, 12)), hit.u);
                    assert_eq!(f32::from_le_bytes(word(record, 16)), hit.v);
                }
                None => assert_eq!((t, triangle, source), (f32::INFINITY, u32::MAX, u32::MAX)),
            }
            assert_eq!(u32::from_le_bytes(word(record, 20)), u32::MAX, "a one-level file's hits name no instance");
        }
        assert_eq!(report["hits"], hit_count);
        assert!(hit_count > 100, "the rays hit the teapot");
        outputs.push(bytes);
    }
    assert_eq!(outputs[0], outputs[1], "the same hits for 1 and 2 threads");
    let occluded = dir.path().join("occluded.bin");
    let run = bvhc(&[&"trace", &bvh, &"--rays", &ray_file, &"-o", &occluded, &"--any-hit"]);
    assert!(run.status.success() && stdout(&run).contains("Mrays/s"), "{}", stderr(&run));
    let flags = std::fs::read(&occluded).unwrap();
    let expected: Vec<u8> = rays.iter().map(|r| u8::from(tracer.any_hit(r))).collect();
    assert_eq!(flags, expected);
    // --coherent: the same t for every ray, and the same any-hit bytes.
    let coherent = dir.path().join("coherent.bin");
    let run = bvhc(&[&"trace", &bvh, &"--rays", &ray_file, &"-o", &coherent, &"--coherent"]);
    assert!(run.status.success(), "{}", stderr(&run));
    let t_of = |record: &[u8]| f32::from_le_bytes(word(record, 0));
    let plain: Vec<f32> = outputs[0].chunks_exact(24).map(t_of).collect();
    let grouped: Vec<f32> = std::fs::read(&coherent).unwrap().chunks_exact(24).map(t_of).collect();
    assert_eq!(plain, grouped);
    let run = bvhc(&[&"trace", &bvh, &"--rays", &ray_file, &"-o", &coherent, &"--coherent", &"--any-hit"]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert_eq!(std::fs::read(&coherent).unwrap(), expected);
}

#[test]
fn two_level_hit_records_name_their_instance_and_its_record_gives_them_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let glb = crate::convert_instances::teapot_grid(dir.path(), 4);
    let bvh = dir.path().join("grid.bvh");
    let run = bvhc(&[&glb, &"-o", &bvh, &"-q", &"--preset", &"fast", &"--instancing", &"always"]);
    assert!(run.status.success(), "{}", stderr(&run));
    let file = BvhFile::read(&bvh).unwrap();
    let view = file.view();
    let sections = view.two_level().expect("a two-level file");
    let (lo, hi) = view.scene_box().unwrap();
    let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f32, f32::max);
    let center: [f32; 3] = std::array::from_fn(|a| (lo[a] + hi[a]) / 2.0);
    let rays: Vec<Ray> = random_rays(93, 4_000, extent / 2.0)
        .into_iter()
        .map(|r| Ray { origin: std::array::from_fn(|a| r.origin[a] + center[a]), ..r })
        .collect();
    let ray_file = dir.path().join("rays.bin");
    std::fs::write(&ray_file, ray_bytes(&rays)).unwrap();
    let hits = dir.path().join("hits.bin");
    let run = bvhc(&[&"trace", &bvh, &"--rays", &ray_file, &"-o", &hits]);
    assert!(run.status.success(), "{}", stderr(&run));
    let bytes = std::fs::read(&hits).unwrap();
    let (mut hit_count, mut instances_seen) = (0, std::collections::BTreeSet::new());
    for (ray, record) in rays.iter().zip(bytes.chunks_exact(24)) {
        let (triangle, instance) = (u32::from_le_bytes(word(record, 4)), u32::from_le_bytes(word(record, 20)));
        let hit = view.tracer().closest_hit(ray);
        assert_eq!(instance, hit.and_then(|h| h.instance_index).unwrap_or(u32::MAX));
        let source = u32::from_le_bytes(word(record, 8));
        assert_eq!(source, hit.and_then(|h| h.source_triangle_id).unwrap_or(u32::MAX), "the record's source id");
        let Some(hit) = hit else { continue };
        // What a reader does with the record: map the ray into the named instance and test the named record.
        let object = crate::instances_exact::spec_object_ray(&sections.instances[instance as usize], ray);
        let own = bvhc::loader::ray::PreparedRay::new(&object)
            .intersect_triangle(&view.triangles()[triangle as usize], ray.t_max);
        let own = own.expect("the named record is hit in the named instance");
        let stated = [0, 12, 16].map(|at| f32::from_le_bytes(word(record, at)));
        assert_eq!(stated, [own.t, own.u, own.v]);
        assert_eq!(stated[0], hit.t);
        hit_count += 1;
        instances_seen.insert(instance);
    }
    assert!(hit_count > 200 && instances_seen.len() == 4, "{hit_count} hits in instances {instances_seen:?}");
}

#[test]
fn bad_ray_files_are_refused_naming_the_ray() {
    let dir = tempfile::tempdir().unwrap();
    let bvh = teapot_bvh(dir.path());
    let good = Ray { origin: [0.0; 3], direction: [0.0, 0.0, 1.0], t_min: 0.0, t_max: 1.0 };
    let cases = [
        (ray_bytes(&[good])[..31].to_vec(), "not a whole number"),
        (ray_bytes(&[good, Ray { direction: [f32::NAN, 0.0, 0.0], ..good }]), "ray 1: the direction is not finite"),
        (ray_bytes(&[Ray { direction: [0.0; 3], ..good }]), "ray 0: the direction is zero"),
        (ray_bytes(&[good, Ray { direction: [0.0, 0.0, 1e-45], ..good }]), "ray 1: the direction's largest component"),
        (ray_bytes(&[Ray { direction: [1e-20, -1e-20, 0.0], ..good }]), "is below 2^-64"),
        (ray_bytes(&[good, good, Ray { t_min: 2.0, ..good }]), "ray 2: t_max is NaN or below t_min"),
    ];
    for (bytes, message) in cases {
        let rays = dir.path().join("bad.bin");
        std::fs::write(&rays, bytes).unwrap();
        let run = bvhc(&[&"trace", &bvh, &"--rays", &rays]);
        assert_eq!(run.status.code(), Some(1), "{message}");
        assert!(stderr(&run).contains(message), "{}", stderr(&run));
    }
    let run = bvhc(&[&"trace", &bvh, &"--rays", &dir.path().join("missing.bin")]);
    assert_eq!(run.status.code(), Some(3));
}

#[test]
fn the_shortest_valid_direction_still_hits() {
    // rays-and-hits.md allows directions down to 2^-64 in their largest component: the hit test stays finite.
    let dir = tempfile::tempdir().unwrap();
    let bvh = teapot_bvh(dir.path());
    let file = BvhFile::read(&bvh).unwrap();
    let shortest = 1.0 / (1u128 << 64) as f32;
    let unit = Ray { origin: [0.0, 1.5, 10.0], direction: [0.0, 0.0, -1.0], t_min: 0.0, t_max: f32::INFINITY };
    let short = Ray { direction: [0.0, 0.0, -shortest], ..unit };
    for tracer in every_kernel(&file.view()) {
        let unit_hit = tracer.closest_hit(&unit).expect("the teapot is below");
        let short_hit = tracer.closest_hit(&short).expect("the same ray with a 2^-64 direction");
        assert_eq!(short_hit.triangle_index, unit_hit.triangle_index);
        assert_eq!(short_hit.t, unit_hit.t / shortest, "t in units of the direction");
    }
}

#[test]
fn trace_writes_to_a_device_or_fifo_directly() {
    // `-o /dev/null` (tracing for the timing alone) and a FIFO (hits streamed to a reader) are written in place;
    // a directory stays refused.
    let dir = tempfile::tempdir().unwrap();
    let bvh = teapot_bvh(dir.path());
    let ray_file = dir.path().join("rays.bin");
    std::fs::write(&ray_file, ray_bytes(&random_rays(17, 300, 4.0))).unwrap();
    let hits = dir.path().join("hits.bin");
    assert!(bvhc(&[&"trace", &bvh, &"--rays", &ray_file, &"-o", &hits]).status.success());
    let expected = std::fs::read(&hits).unwrap();
    if Path::new("/dev/null").exists() {
        let run = bvhc(&[&"trace", &bvh, &"--rays", &ray_file, &"-o", &"/dev/null"]);
        assert!(run.status.success(), "{}", stderr(&run));
        assert!(stdout(&run).contains("300 rays"), "{}", stdout(&run));
        assert!(!std::fs::metadata("/dev/null").unwrap().is_file());
    } else {
        crate::skips::skipped(crate::skips::Needs::Tools, "trace -o /dev/null (no /dev/null)");
    }
    #[cfg(unix)]
    {
        let fifo = dir.path().join("hits.fifo");
        if std::process::Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()) {
            let reader = {
                let fifo = fifo.clone();
                std::thread::spawn(move || std::fs::read(fifo).unwrap())
            };
            let run = bvhc(&[&"trace", &bvh, &"--rays", &ray_file, &"-o", &fifo]);
            assert!(run.status.success(), "{}", stderr(&run));
            assert_eq!(reader.join().unwrap(), expected);
        } else {
            crate::skips::skipped(crate::skips::Needs::Tools, "trace -o FIFO (mkfifo is not available)");
        }
    }
    let run = bvhc(&[&"trace", &bvh, &"--rays", &ray_file, &"-o", &dir.path()]);
    assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
    assert!(stderr(&run).contains("not a regular file"), "{}", stderr(&run));
}

/// `bvhc trace --gpu`: the records are the GPU tracer's (rays it leaves to the CPU included), the report counts
/// those rays (`cpu_rays`) and times the tracing apart from the whole command. SKIPPED without a GPU adapter.
#[test]
fn trace_on_the_gpu_writes_the_gpu_tracers_records_and_counts_its_cpu_rays() {
    let dir = tempfile::tempdir().unwrap();
    let bvh = dir.path().join("teapot-gpu.bvh");
    assert!(bvhc(&[&teapot(), &"-o", &bvh, &"-q", &"--preset", &"fast", &"--gpu-layout"]).status.success());
    let file = BvhFile::read(&bvh).unwrap();
    let view = file.view();
    let gpu = match bvhc::loader::gpu::GpuTracer::new(&view) {
        Ok(gpu) => gpu,
        Err(bvhc::loader::gpu::GpuError::NoAdapter(why)) => {
            let what = format!("bvhc trace --gpu (no GPU adapter: {why})");
            return crate::skips::skipped(crate::skips::Needs::Vulkan, what);
        }
        Err(e) => panic!("{e}"),
    };
    let rays = random_rays(95, 3_000, 4.0);
    let ray_file = dir.path().join("rays.bin");
    std::fs::write(&ray_file, ray_bytes(&rays)).unwrap();
    let hits = dir.path().join("hits.bin");
    let run = bvhc(&[&"trace", &bvh, &"--rays", &ray_file, &"-o", &hits, &"--gpu", &"--json"]);
    assert!(run.status.success(), "{}", stderr(&run));
    let report: serde_json::Value = serde_json::from_str(&stdout(&run)).unwrap();
    let trace = gpu.trace(&rays, false).unwrap();
    assert_eq!(report["cpu_rays"].as_u64(), Some(trace.cpu_rays as u64), "{report}");
    assert!(report["seconds"].as_f64().unwrap() <= report["total_seconds"].as_f64().unwrap(), "{report}");
    let bytes = std::fs::read(&hits).unwrap();
    let expected = gpu.closest_hits(&rays).unwrap();
    assert_eq!(report["hits"], expected.iter().filter(|h| h.is_some()).count());
    for (i, (record, hit)) in bytes.chunks_exact(24).zip(&expected).enumerate() {
        let (t, triangle) = (f32::from_le_bytes(word(record, 0)), u32::from_le_bytes(word(record, 4)));
        match hit {
            Some(hit) => assert_eq!((t, triangle), (hit.t, hit.triangle_index), "ray {i}"),
            None => assert_eq!((t, triangle), (f32::INFINITY, u32::MAX), "ray {i}"),
        }
    }
}
