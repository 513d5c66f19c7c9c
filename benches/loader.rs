//! Loader benchmarks: open time against file size, full-verify throughput, and closest-hit / any-hit rays per
//! second on one thread, on the full Stanford dragon and the kitchen from the shared scenes.
//!
//! `cargo bench --bench loader` prints a Markdown table. Every figure is the median of several repetitions in
//! this one run. Environment: `BVHC_SCENES` (scenes folder), `BVHC_BENCH_RAYS` (default 1,000,000).

use bvhc_loader::Trace;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;

use bvhc::builders::build_binned_sah;
use bvhc::import::{ImportOptions, import};
use bvhc::loader::{BvhFile, BvhView, MappedBvh, TraversalStats, write::BvhWriter};
use bvhc::pack::pack;

#[path = "common/harness.rs"]
mod harness;
#[path = "common/rays.rs"]
mod rays;

use rays::{RAY_SEED, primary_rays, shadow_rays};

/// Converts a scene (binned SAH, at most 4 triangles per leaf, ids) into a `.bvh` file in `dir`.
fn convert(scene: &Path, dir: &Path) -> (PathBuf, f64) {
    let start = Instant::now();
    let soup = import(scene, &ImportOptions::default()).expect("scene imports").soup;
    let triangles = soup.triangle_vertices();
    let packed = pack(&build_binned_sah(&triangles, 4), &triangles).expect("memory for the packed tree");
    let path = dir.join(scene.file_name().unwrap()).with_extension("bvh");
    BvhWriter::new(&packed.nodes, &packed.triangles)
        .triangle_ids(&packed.triangle_ids)
        .metadata(r#"{"generator":"bvhc loader benchmark"}"#)
        .write_atomic(&path)
        .expect("write");
    (path, start.elapsed().as_secs_f64())
}

struct Row {
    name: String,
    triangles: usize,
    file_mib: f64,
    open_ns: f64,
    map_us: f64,
    verify_gbs: f64,
    closest_mrays: f64,
    any_mrays: f64,
    closest_hit_fraction: f64,
    occluded_fraction: f64,
    steps: f64,
    tests: f64,
}

fn measure(name: &str, path: &Path, ray_count: usize) -> Row {
    let file = BvhFile::read(path).expect("read");
    let bytes = file.as_bytes();
    let view = file.view();
    let open = harness::median_time(2001, || {
        black_box(BvhView::open(black_box(bytes)).unwrap());
    });
    let map = harness::median_time(201, || {
        // SAFETY: the benchmark's private temporary file is not modified while mapped.
        #[allow(unsafe_code)]
        let mapped = unsafe { MappedBvh::open(path) }.unwrap();
        black_box(mapped.view().nodes().len());
    });
    let verify_repetitions = if bytes.len() > 1 << 20 { 5 } else { 201 };
    let verify = harness::median_time(verify_repetitions, || view.verify().unwrap());
    let mut row = Row {
        name: name.to_string(),
        triangles: view.triangles().len(),
        file_mib: bytes.len() as f64 / (1 << 20) as f64,
        open_ns: open.as_nanos() as f64,
        map_us: map.as_secs_f64() * 1e6,
        verify_gbs: bytes.len() as f64 / verify.as_secs_f64() / 1e9,
        closest_mrays: f64::NAN,
        any_mrays: f64::NAN,
        closest_hit_fraction: f64::NAN,
        occluded_fraction: f64::NAN,
        steps: f64::NAN,
        tests: f64::NAN,
    };
    if ray_count == 0 {
        return row;
    }
    let tracer = view.tracer();
    let root = &view.nodes()[0];
    let primary = primary_rays(root, ray_count);
    let shadow = shadow_rays(root, ray_count);
    let mut hits = 0usize;
    let closest = harness::median_time(3, || {
        hits = primary.iter().filter(|r| black_box(tracer.closest_hit(r)).is_some()).count()
    });
    let mut occluded = 0usize;
    let any = harness::median_time(3, || occluded = shadow.iter().filter(|r| black_box(tracer.any_hit(r))).count());
    let mut stats = TraversalStats::default();
    for ray in &primary {
        tracer.closest_hit_counted(ray, &mut stats);
    }
    row.closest_mrays = ray_count as f64 / closest.as_secs_f64() / 1e6;
    row.any_mrays = ray_count as f64 / any.as_secs_f64() / 1e6;
    row.closest_hit_fraction = hits as f64 / ray_count as f64;
    row.occluded_fraction = occluded as f64 / ray_count as f64;
    row.steps = stats.node_visits as f64 / ray_count as f64;
    row.tests = stats.triangle_tests as f64 / ray_count as f64;
    row
}

fn main() {
    // `cargo bench` passes `--bench`; `cargo test --benches` passes nothing: then only check that it runs.
    let benchmarking = harness::benchmarking("loader");
    let ray_count = std::env::var("BVHC_BENCH_RAYS").ok().and_then(|v| v.parse().ok()).unwrap_or(1_000_000);
    let dir = tempfile::tempdir().expect("temporary directory");
    let golden = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/golden/quad-v1.0.bvh");
    let mut rows = vec![measure("golden quad (fixture)", &golden, 0)];
    if !benchmarking {
        return;
    }
    let scenes = [
        ("stanford dragon", "stanford-dragon/dragon_vrip.ply.gz"),
        ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
    ];
    for (name, scene) in harness::scenes(&scenes, None) {
        let (path, seconds) = convert(&scene, dir.path());
        eprintln!("{name}: converted in {seconds:.2} s (import + binned SAH + write)");
        rows.push(measure(name, &path, ray_count));
    }
    println!("rays per measurement: {ray_count} (seed {RAY_SEED}); single thread; medians of this run\n");
    println!(
        "| file | triangles | MiB | open (ns) | mmap+open (us) | verify (GB/s) | closest hit (Mrays/s) | any hit (Mrays/s) | hit / occluded | steps / ray | tri tests / ray |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for r in &rows {
        let rays = match r.closest_mrays.is_nan() {
            true => "- | - | - | - | -".to_string(),
            false => format!(
                "{:.2} | {:.2} | {:.2} / {:.2} | {:.1} | {:.1}",
                r.closest_mrays, r.any_mrays, r.closest_hit_fraction, r.occluded_fraction, r.steps, r.tests
            ),
        };
        println!(
            "| {} | {} | {:.2} | {:.0} | {:.1} | {:.2} | {rays} |",
            r.name, r.triangles, r.file_mib, r.open_ns, r.map_us, r.verify_gbs
        );
    }
}
