//! What hit filters cost, and what the converter's opacity flags save: rays per second on one thread of
//!
//! - `plain`: the tracer without a filter (the baseline);
//! - `accept-all`: `tracer.filtered(&|_| true, FilterScope::NotOpaque)`, the filtered kernels with a filter that
//!   keeps everything (the price of the flag lookup and of asking on flagged triangles);
//! - `cut-outs`: the AO example's glTF alpha filter (`examples/ao/cutouts.rs`) with `NotOpaque`, asked only
//!   about triangles of `MASK` and `BLEND` materials;
//! - `cut-outs-every`: the same filter with `FilterScope::Every`, asked about every candidate, as a runtime that
//!   does not know which triangles are opaque must (the saving of the flags is the ratio of the two);
//!
//! for incoherent rays (closest hit) and occlusion rays (any hit), batch calls, with the filter calls a ray
//! counted in a separate pass. The flight helmet is mostly opaque (a few `BLEND` and `MASK` parts; its textures
//! are not kept, so no cut-outs), the kitchen (an OBJ) all opaque, a file without flags.
//! Medians of 5 runs. `BVHC_FILTER_RAYS` (default 200,000), `BVHC_FILTER_SCENES=vase,blend-test,flight-helmet,kitchen`.
//! `cargo bench --bench filter`

#[path = "common/harness.rs"]
mod harness;
#[path = "common/rays.rs"]
mod rays;

#[path = "../examples/ao/cutouts.rs"]
#[allow(dead_code)]
mod cutouts;

use bvhc_loader::Trace;
use std::sync::atomic::{AtomicU64, Ordering};

use bvhc::convert::Conversion;
use bvhc::loader::{BvhFile, BvhView, HitFilter, Ray, Tracer, filter::Candidate, filter::FilterScope};

use harness::median_time;

const SCENES: [(&str, &str); 4] = [
    ("vase", "khr-glass-vase-flowers/GlassVaseFlowers.gltf"),
    ("blend-test", "khr-alpha-blend-mode-test/AlphaBlendModeTest.gltf"),
    ("flight-helmet", "khr-flight-helmet/FlightHelmet.gltf"),
    ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
];

/// Rays a microsecond through `trace`, the median of 5 runs.
fn speed(rays: &[Ray], trace: impl Fn(&[Ray], &mut [Option<bvhc::loader::Hit>], &mut [bool])) -> f64 {
    let mut hits = vec![None; rays.len()];
    let mut occluded = vec![false; rays.len()];
    let time = median_time(5, || {
        trace(rays, &mut hits, &mut occluded);
        std::hint::black_box((&hits, &occluded));
    });
    rays.len() as f64 / time.as_secs_f64() / 1e6
}

/// Mrays/s of closest and any hits without a filter (no calls).
fn plain(tracer: &Tracer<'_>, incoherent: &[Ray], occlusion: &[Ray]) -> [f64; 4] {
    [
        speed(incoherent, |r, h, _| tracer.closest_hits(r, h)),
        speed(occlusion, |r, _, o| tracer.any_hits(r, o)),
        0.0,
        0.0,
    ]
}

/// Mrays/s of closest and any hits through `filter` in `scope`, and its calls a ray.
fn measure<F: HitFilter + Sync>(
    tracer: &Tracer<'_>,
    (filter, scope): (&F, FilterScope),
    incoherent: &[Ray],
    occlusion: &[Ray],
) -> [f64; 4] {
    let filtered = tracer.filtered(filter, scope);
    let calls = AtomicU64::new(0);
    let counting = |c: &Candidate<'_>| {
        calls.fetch_add(1, Ordering::Relaxed);
        filter.accept(c)
    };
    let counted = tracer.filtered(&counting, scope);
    let mut hits = vec![None; incoherent.len()];
    counted.closest_hits(incoherent, &mut hits);
    let closest_calls = calls.swap(0, Ordering::Relaxed) as f64 / incoherent.len() as f64;
    let mut occluded = vec![false; occlusion.len()];
    counted.any_hits(occlusion, &mut occluded);
    let any_calls = calls.load(Ordering::Relaxed) as f64 / occlusion.len() as f64;
    [
        speed(incoherent, |r, h, _| filtered.closest_hits(r, h)),
        speed(occlusion, |r, _, o| filtered.any_hits(r, o)),
        closest_calls,
        any_calls,
    ]
}

fn row(scene: &str, variant: &str, base: [f64; 4], m: [f64; 4]) {
    println!(
        "| {scene} | {variant} | {:.2} ({:.2}x) | {:.2} | {:.2} ({:.2}x) | {:.2} |",
        m[0],
        m[0] / base[0],
        m[2],
        m[1],
        m[1] / base[1],
        m[3]
    );
}

fn main() {
    let benchmarking = harness::benchmarking("filter");
    let count: usize = std::env::var("BVHC_FILTER_RAYS").ok().and_then(|v| v.parse().ok()).unwrap_or(200_000);
    let count = if benchmarking { count } else { 2_000 };
    let dir = tempfile::tempdir().expect("a temporary folder");
    println!(
        "| scene | tracer | closest hits Mrays/s (x plain) | filter calls a ray | any hits Mrays/s (x plain) | filter calls a ray |"
    );
    println!("|---|---|---|---|---|---|");
    rayon::ThreadPoolBuilder::new().num_threads(1).build_global().ok();
    for (name, scene) in harness::scenes(&SCENES, Some("BVHC_FILTER_SCENES")) {
        let output = dir.path().join(format!("{name}.bvh"));
        Conversion::new(&scene, &output).run().expect("the scene converts");
        let file = BvhFile::read(&output).expect("the file reads");
        let view: BvhView<'_> = file.view();
        let tracer = view.tracer();
        let root = &view.nodes()[0];
        let incoherent = rays::uniform_rays(root, count, rays::RAY_SEED);
        let occlusion = rays::shadow_rays(root, count);
        let base = plain(&tracer, &incoherent, &occlusion);
        row(name, "plain", base, base);
        let accept_all = |_: &Candidate<'_>| true;
        row(name, "accept-all", base, measure(&tracer, (&accept_all, FilterScope::NotOpaque), &incoherent, &occlusion));
        let marked = (0..view.triangles().len() as u32).filter(|&r| view.is_not_opaque(r)).count();
        println!("| {name} | ({marked} of {} triangle records not opaque) | | | | |", view.triangles().len());
        // Cut-outs where the glTF's textures are on this machine (the shared scenes keep those of two).
        if let Some(cutouts) =
            scene.extension().is_some_and(|e| e == "gltf").then(|| cutouts::Cutouts::read(&scene).ok()).flatten()
        {
            let keeps = |candidate: &Candidate<'_>| cutouts.keeps(&view, candidate);
            row(name, "cut-outs", base, measure(&tracer, (&keeps, FilterScope::NotOpaque), &incoherent, &occlusion));
            row(name, "cut-outs-every", base, measure(&tracer, (&keeps, FilterScope::Every), &incoherent, &occlusion));
        }
    }
}
