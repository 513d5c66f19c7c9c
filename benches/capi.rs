//! What the C API costs over the Rust API on the same rays and file, one thread: single-ray calls
//! (`bvhc_closest_hit`, `bvhc_any_hit` against `Tracer::closest_hit`, `any_hit`) and batch calls
//! (`bvhc_closest_hits`, `bvhc_any_hits` against `Tracer::closest_hits`, `any_hits`), Mrays/s as medians of
//! `BVHC_CAPI_ROUNDS` (7) interleaved rounds and the ratio C / Rust. The C functions are called through their C
//! ABI from Rust, which is what a C caller pays (the boundary's null checks, panic guard and record copies).
//!
//! Then, from C itself (`benches/c/lookups.c`, built with the system's `cc` against the static library, which
//! `cargo build --release -p bvhc-capi` makes): the exported getters against the header's `static inline`
//! readers over `bvhc_sections`, a material-and-texture filter finding its data through `bvhc_hit_source_corners`
//! against reading the candidate's fields, and filtered batches on one thread and on every core, on the alpha
//! scenes (glass vase, alpha blend test).
//!
//! `cargo bench --bench capi`; `BVHC_CAPI_SCENES=kitchen` picks scenes (the teapot fixture without the shared
//! scenes), `BVHC_BENCH_RAYS` the ray count (1,000,000).
#![allow(unsafe_code)] // calling the C API's extern "C" functions, each call's contract stated beside it

#[path = "common/harness.rs"]
mod harness;

#[path = "common/rays.rs"]
mod rays;

use bvhc_loader::Trace;
use std::time::Instant;

use bvhc::loader::BvhFile;
use bvhc_capi::{BvhcFile, BvhcHit, BvhcRay};

fn median(mut samples: Vec<f64>) -> f64 {
    samples.sort_by(f64::total_cmp);
    samples[samples.len() / 2]
}

fn main() {
    if !harness::benchmarking("capi") {
        return;
    }
    let ray_count = std::env::var("BVHC_BENCH_RAYS").ok().and_then(|v| v.parse().ok()).unwrap_or(1_000_000);
    let rounds: usize = std::env::var("BVHC_CAPI_ROUNDS").ok().and_then(|v| v.parse().ok()).unwrap_or(7);
    let dir = tempfile::tempdir().unwrap();
    let mut scenes = harness::scenes(
        &[
            ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
            ("engine", "khr-2cylinder-engine/2CylinderEngine.gltf"),
        ],
        Some("BVHC_CAPI_SCENES"),
    );
    if scenes.is_empty() {
        scenes.push(("teapot", std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj")));
    }
    println!("C API against Rust, one thread, Mrays/s, medians of {rounds} interleaved rounds, {ray_count} rays\n");
    println!("| scene | call | Rust | C | C / Rust |");
    println!("|---|---|---|---|---|");
    for (name, path) in scenes {
        let output = dir.path().join("scene.bvh");
        bvhc::Conversion::new(&path, &output).force(true).run().unwrap();
        let file = BvhFile::read(&output).unwrap();
        let tracer = file.view().tracer();
        let rays = rays::uniform_rays(&file.view().nodes()[0], ray_count, 4_404);
        let c_rays: Vec<BvhcRay> = rays.clone();
        let path = std::ffi::CString::new(output.to_str().unwrap()).unwrap();
        let mut handle: *mut BvhcFile = std::ptr::null_mut();
        // SAFETY: a NUL-terminated path and storage for the handle.
        assert_eq!(unsafe { bvhc_capi::bvhc_open(path.as_ptr(), &mut handle) }, 0);
        let zero_hit = BvhcHit::default();
        let mut hits = vec![None; rays.len()];
        let mut occluded = vec![false; rays.len()];
        let mut c_hits = vec![zero_hit; rays.len()];
        let mut found = vec![0u8; rays.len()];
        let mut any_found = vec![0u8; rays.len()];
        type Pass<'p> = Box<dyn FnMut() -> usize + 'p>;
        let passes: Vec<(&str, Pass<'_>, Pass<'_>)> = vec![
            (
                "closest hit, one ray a call",
                Box::new(|| rays.iter().filter(|r| tracer.closest_hit(r).is_some()).count()),
                Box::new(|| {
                    let mut hit = zero_hit;
                    // SAFETY: a live handle, a valid ray and storage for a hit.
                    c_rays.iter().filter(|r| unsafe { bvhc_capi::bvhc_closest_hit(handle, *r, &mut hit) } == 1).count()
                }),
            ),
            (
                "any hit, one ray a call",
                Box::new(|| rays.iter().filter(|r| tracer.any_hit(r)).count()),
                // SAFETY: a live handle and a valid ray.
                Box::new(|| c_rays.iter().filter(|r| unsafe { bvhc_capi::bvhc_any_hit(handle, *r) } == 1).count()),
            ),
            (
                "closest hits, one batch",
                Box::new(|| {
                    tracer.closest_hits(&rays, &mut hits);
                    hits.iter().filter(|h| h.is_some()).count()
                }),
                Box::new(|| {
                    let (r, n) = (c_rays.as_ptr(), c_rays.len());
                    // SAFETY: `n` rays, hits and flags.
                    let status =
                        unsafe { bvhc_capi::bvhc_closest_hits(handle, r, n, c_hits.as_mut_ptr(), found.as_mut_ptr()) };
                    assert_eq!(status, 0);
                    found.iter().filter(|&&f| f == 1).count()
                }),
            ),
            (
                "any hits, one batch",
                Box::new(|| {
                    tracer.any_hits(&rays, &mut occluded);
                    occluded.iter().filter(|&&o| o).count()
                }),
                Box::new(|| {
                    // SAFETY: `n` rays and flags.
                    let status = unsafe {
                        bvhc_capi::bvhc_any_hits(handle, c_rays.as_ptr(), c_rays.len(), any_found.as_mut_ptr())
                    };
                    assert_eq!(status, 0);
                    any_found.iter().filter(|&&f| f == 1).count()
                }),
            ),
        ];
        for (call, mut rust, mut c) in passes {
            let (mut rust_speeds, mut c_speeds) = (Vec::new(), Vec::new());
            for _ in 0..rounds {
                let start = Instant::now();
                let rust_hits = std::hint::black_box(rust());
                rust_speeds.push(rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6);
                let start = Instant::now();
                let c_hits = std::hint::black_box(c());
                c_speeds.push(rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6);
                assert_eq!(rust_hits, c_hits, "{name} {call}: the C API finds other hits");
            }
            let (rust, c) = (median(rust_speeds), median(c_speeds));
            println!("| {name} | {call} | {rust:.2} | {c:.2} | {:.3} |", c / rust);
        }
        // SAFETY: the handle came from `bvhc_open` and is closed once.
        unsafe { bvhc_capi::bvhc_close(handle) };
    }
    from_c(dir.path(), ray_count);
}

/// The C program's look-ups and filters (see the module doc), on the alpha scenes, or the teapot fixture.
fn from_c(dir: &std::path::Path, ray_count: usize) {
    let library = std::env::current_exe().ok().and_then(|e| Some(e.parent()?.parent()?.join("libbvhc_capi.a")));
    let Some(library) = library.filter(|l| l.is_file()) else {
        println!("\n(C look-ups skipped: build the static library with `cargo build --release -p bvhc-capi`)");
        return;
    };
    let binary = dir.join("lookups");
    let compiler = std::env::var("CC").unwrap_or_else(|_| "cc".to_string());
    let built = std::process::Command::new(&compiler)
        .args(["-O2", "-std=c11"])
        .arg(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/c/lookups.c"))
        .arg(&library)
        .args(["-lpthread", "-ldl", "-lm", "-o"])
        .arg(&binary)
        .status();
    if !built.is_ok_and(|s| s.success()) {
        println!("\n(C look-ups skipped: {compiler} could not build benches/c/lookups.c)");
        return;
    }
    let mut scenes = harness::scenes(
        &[
            ("glass vase", "khr-glass-vase-flowers/GlassVaseFlowers.gltf"),
            ("alpha blend test", "khr-alpha-blend-mode-test/AlphaBlendModeTest.gltf"),
        ],
        Some("BVHC_CAPI_SCENES"),
    );
    if scenes.is_empty() {
        scenes.push(("teapot", std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj")));
    }
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("\nFrom C (benches/c/lookups.c, cc -O2, medians of 5; {threads} cores):\n");
    for (name, path) in scenes {
        let output = dir.join("lookups.bvh");
        bvhc::Conversion::new(&path, &output).force(true).run().unwrap();
        let file = BvhFile::read(&output).unwrap();
        let rays = rays::uniform_rays(&file.view().nodes()[0], ray_count.min(200_000), 4_405);
        let ray_file = dir.join("lookups.rays");
        let bytes: Vec<u8> = rays
            .iter()
            .flat_map(|r| r.origin.into_iter().chain(r.direction).chain([r.t_min, r.t_max]).flat_map(f32::to_le_bytes))
            .collect();
        std::fs::write(&ray_file, bytes).unwrap();
        let run = std::process::Command::new(&binary).arg(&output).arg(&ray_file).output().unwrap();
        assert!(run.status.success(), "{name}: lookups exit {:?}", run.status.code());
        println!("| {name} | |\n|---|---|\n{}", String::from_utf8_lossy(&run.stdout));
    }
}
