//! bvhc's single-ray kernel against Embree on the same rays, one thread, as an outside user would compare them:
//! Embree 4.4 with `--features embree4` (run `scripts/embree4.sh` first), or Embree 3.13.5 with
//! `--features embree` (Debian's `libembree-dev`). Without either feature it only says so.
//!
//! Scenes: the six, then a 2-triangle and a 12-triangle one (the fixed cost of a ray). Per scene: bvhc's
//! default conversion traced by `view.tracer()` (the wide kernel on the best path), and Embree
//! over the scene's triangles (HIGH quality: spatial splits), plain and robust (`RTC_SCENE_FLAG_ROBUST`), each
//! on AVX2 kernels (`isa=avx2`, bvhc's instruction set) and on Embree's native choice for this CPU. Ray sets:
//! 1,000,000 incoherent rays (origins uniform in the scene's box, directions uniform on the sphere, a seed of
//! this benchmark's own) and the 786,432 primary rays of a 1024x768 camera; closest hit and any hit. Every
//! contender traces the whole set once a round, the contenders in turn, for `BVHC_PEER_ROUNDS` rounds (5):
//! the table shows each one's median Mrays/s and bvhc's ratios to them, and how many rays bvhc and plain AVX2
//! Embree answer differently (a hit against a miss, or `t` more than 1e-4 apart relative). Embree runs with
//! flush-to-zero and denormals-are-zero, as it asks, set around its passes only. A second table compares the
//! coherent entry points on the primary rays: bvhc's 8-ray packets (`closest_hits_coherent`) against Embree's
//! `rtcIntersect8` and `rtcIntersect16`.
//!
//! `cargo bench --bench peer --features embree4`; `BVHC_PEER_SCENES=kitchen,engine` picks scenes,
//! `BVHC_BENCH_RAYS` the incoherent ray count, `BVHC_PEER_CAMERA=256x192` the camera's size. Instruction counts: `BVHC_PEER_ONLY=bvhc` (or `embree`,
//! `embree-robust`) with `BVHC_PEER_QUERY=closest|any` and `BVHC_PEER_SET=incoherent|primary` traces that one
//! pass once inside `measured_pass`, for `valgrind --tool=callgrind --toggle-collect='*measured_pass*'`
//! (Embree's AVX2 kernels; docs/kernel-peer.md has the commands); with `BVHC_PEER_ROUNDS` set as well, it
//! also times that pass that many times (a quick A/B of one contender). bvhc runs without the ray check
//! (`Tracer::trusting_rays`), as Embree does; `BVHC_PEER_ONLY=bvhc-checked` with it, and `BVHC_PEER_ONLY=ray-check` times the checking tracer
//! against the trusting one, single rays and batches, rounds interleaved: the check's cost; `BVHC_PEER_BATCH=1`
//! makes the one-contender pass use the batch calls (streams; packets for `BVHC_PEER_SET=primary`), and
//! `BVHC_PEER_TILES=1` lays the primary rays out in blocks of 4 pixels by 2 rows instead of rows.
//! `BVHC_PEER_WRITE=DIR` writes each scene's conversion, Embree's triangles and the ray sets to `DIR` instead of
//! timing, for the same comparison made from outside (`scripts/peer-outside.sh`). Built with `--features tinybvh`
//! for AVX2 and FMA (`docs/kernel-peer.md`, "A second peer"), a third table times tinybvh's `BVH8_CPU` beside
//! bvhc and Embree AVX2 on closest hits, and `BVHC_PEER_ONLY=tinybvh` counts its instructions.

#[path = "common/harness.rs"]
mod harness;

#[path = "common/rays.rs"]
mod rays;

#[cfg(any(feature = "embree", feature = "embree4"))]
#[path = "common/embree.rs"]
mod embree;

#[cfg(all(feature = "tinybvh", target_feature = "avx2", target_feature = "fma"))]
#[path = "common/tinybvh_kernel.rs"]
mod tinybvh_kernel;

fn main() {
    if !harness::benchmarking("peer") {
        return;
    }
    #[cfg(any(feature = "embree", feature = "embree4"))]
    peer::run();
    #[cfg(not(any(feature = "embree", feature = "embree4")))]
    println!("peer: needs --features embree4 (after scripts/embree4.sh) or --features embree (libembree-dev)");
}

#[cfg(any(feature = "embree", feature = "embree4"))]
mod peer {
    use std::time::Instant;

    use bvhc::loader::{BvhFile, BvhView, Ray, Trace, Tracer};

    use crate::embree::{self, Embree, FlushToZero};
    use crate::{harness, rays};

    /// The coherent table (`benches/peer/coherent.rs`).
    #[path = "coherent.rs"]
    mod coherent;
    use coherent::{coherent_row, tile_order};

    /// The seed of the incoherent set (not the other benchmarks' `RAY_SEED`).
    const UNIFORM_SEED: u64 = 4_404;

    /// What one contender answers for a ray set: `t` of each closest hit, or each any-hit flag.
    enum Answers {
        Closest(Vec<Option<f32>>),
        Any(Vec<bool>),
    }

    /// A contender: bvhc's tracer, or an Embree scene (run with flush-to-zero).
    enum Contender<'a> {
        Bvhc(Tracer<'a>),
        Embree(Embree),
        /// tinybvh's `BVH8_CPU` (closest hits only).
        #[cfg(all(feature = "tinybvh", target_feature = "avx2", target_feature = "fma"))]
        Tinybvh(crate::tinybvh_kernel::Bvh8Cpu),
    }

    impl Contender<'_> {
        /// Traces `rays` once; the answers, and the number of hits (kept from the optimizer).
        fn answers(&self, rays: &[Ray], closest: bool) -> Answers {
            let _ftz = matches!(self, Contender::Embree(_)).then(FlushToZero::set);
            match (self, closest) {
                (Contender::Bvhc(t), true) => {
                    Answers::Closest(rays.iter().map(|r| t.closest_hit(r).map(|h| h.t)).collect())
                }
                (Contender::Bvhc(t), false) => Answers::Any(rays.iter().map(|r| t.any_hit(r)).collect()),
                (Contender::Embree(e), true) => {
                    Answers::Closest(rays.iter().map(|r| e.closest(r).map(|h| h.0)).collect())
                }
                (Contender::Embree(e), false) => Answers::Any(rays.iter().map(|r| e.any(r)).collect()),
                #[cfg(all(feature = "tinybvh", target_feature = "avx2", target_feature = "fma"))]
                (Contender::Tinybvh(b), true) => Answers::Closest(rays.iter().map(|r| b.closest(r)).collect()),
                #[cfg(all(feature = "tinybvh", target_feature = "avx2", target_feature = "fma"))]
                (Contender::Tinybvh(_), false) => unreachable!("tinybvh runs closest hits only"),
            }
        }
    }

    /// One timed pass: the hits found (so the work is not optimized away). Out of line, so that callgrind can
    /// count exactly its instructions (`--toggle-collect='*measured_pass*'`).
    #[inline(never)]
    fn measured_pass(contender: &Contender<'_>, rays: &[Ray], closest: bool) -> usize {
        let _ftz = matches!(contender, Contender::Embree(_)).then(FlushToZero::set);
        match (contender, closest) {
            (Contender::Bvhc(t), _) if std::env::var_os("BVHC_PEER_BATCH").is_some() => {
                let coherent = std::env::var("BVHC_PEER_SET").is_ok_and(|set| set == "primary");
                batch_pass(t, rays, closest, coherent)
            }
            (Contender::Bvhc(t), true) => rays.iter().filter(|r| t.closest_hit(r).is_some()).count(),
            (Contender::Bvhc(t), false) => rays.iter().filter(|r| t.any_hit(r)).count(),
            (Contender::Embree(e), true) => rays.iter().filter(|r| e.closest(r).is_some()).count(),
            (Contender::Embree(e), false) => rays.iter().filter(|r| e.any(r)).count(),
            #[cfg(all(feature = "tinybvh", target_feature = "avx2", target_feature = "fma"))]
            (Contender::Tinybvh(b), true) => rays.iter().filter(|r| b.closest(r).is_some()).count(),
            #[cfg(all(feature = "tinybvh", target_feature = "avx2", target_feature = "fma"))]
            (Contender::Tinybvh(_), false) => unreachable!("tinybvh runs closest hits only"),
        }
    }

    /// One timed pass of the batch calls: streams, or 8-ray packets when `coherent`; the hits found.
    #[inline(never)]
    fn batch_pass(tracer: &bvhc::loader::Tracer<'_>, rays: &[Ray], closest: bool, coherent: bool) -> usize {
        // The output buffers are allocated once and reused, as a renderer would: a fresh allocation each pass
        // timed its page faults.
        thread_local! {
            static HITS: std::cell::RefCell<Vec<Option<bvhc::loader::Hit>>> = const { std::cell::RefCell::new(Vec::new()) };
            static OCCLUDED: std::cell::RefCell<Vec<bool>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        if closest {
            HITS.with_borrow_mut(|hits| {
                hits.resize(rays.len(), None);
                match coherent {
                    true => tracer.closest_hits_coherent(rays, hits),
                    false => tracer.closest_hits(rays, hits),
                }
                hits.iter().filter(|h| h.is_some()).count()
            })
        } else {
            OCCLUDED.with_borrow_mut(|occluded| {
                occluded.resize(rays.len(), false);
                match coherent {
                    true => tracer.any_hits_coherent(rays, occluded),
                    false => tracer.any_hits(rays, occluded),
                }
                occluded.iter().filter(|&&o| o).count()
            })
        }
    }

    /// Rays on which two contenders answer differently: a hit against a miss, or `t` more than 1e-4 apart.
    fn disagreements(a: &Answers, b: &Answers) -> usize {
        match (a, b) {
            (Answers::Closest(a), Answers::Closest(b)) => a
                .iter()
                .zip(b)
                .filter(|(x, y)| match (x, y) {
                    (Some(x), Some(y)) => (x - y).abs() > 1e-4 * x.abs().max(1e-6),
                    (None, None) => false,
                    _ => true,
                })
                .count(),
            (Answers::Any(a), Answers::Any(b)) => a.iter().zip(b).filter(|(x, y)| x != y).count(),
            _ => unreachable!("answers of one query"),
        }
    }

    fn median(mut samples: Vec<f64>) -> f64 {
        samples.sort_by(f64::total_cmp);
        samples[samples.len() / 2]
    }

    /// The scenes of the targets, in the shared scenes folder; the last two, of 2 and 12 triangles, show
    /// the fixed cost of a ray (the call, the set-up, the first node), which the tiniest scenes are made of.
    const SCENES: [(&str, &str); 8] = [
        ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
        ("engine", "khr-2cylinder-engine/2CylinderEngine.gltf"),
        ("toy car", "khr-toy-car/ToyCar.gltf"),
        ("dragon", "stanford-dragon/dragon_vrip.ply.gz"),
        ("buddha", "happy-buddha-decimated/stanford-buddha.obj"),
        ("bunny", "stanford-bunny-ply/bun_zipper.ply"),
        ("2-triangles", "trimesh-objcases/face_in_group_name_mid_file.obj"),
        ("box", "khr-box/Box.gltf"),
    ];

    /// The scene's default conversion, kept in `target/peer/` between runs (a conversion whose output is up to
    /// date is skipped, so a run under callgrind does not convert again).
    /// What an outside program needs to run this comparison itself (`benches/c/embree_peer.c`,
    /// `scripts/peer-outside.sh`): into `dir`, the scene's conversion (`NAME.bvh`), the triangles Embree is
    /// built from (`NAME-triangles.bin`, nine f32 a triangle) and each ray set as a ray file
    /// (`NAME-SET.bin`, `format-spec/rays-and-hits.md`).
    fn write_inputs(
        dir: &std::path::Path,
        name: &str,
        view: &BvhView<'_>,
        triangles: &[[[f32; 3]; 3]],
        sets: &[(&str, Vec<Ray>)],
    ) {
        std::fs::create_dir_all(dir).expect("the output folder can be made");
        let stem = name.replace(' ', "-");
        std::fs::write(dir.join(format!("{stem}.bvh")), view.bytes()).expect("the conversion is written");
        let flat: Vec<f32> = triangles.iter().flatten().flatten().copied().collect();
        let bytes: Vec<u8> = flat.iter().flat_map(|c| c.to_le_bytes()).collect();
        std::fs::write(dir.join(format!("{stem}-triangles.bin")), bytes).expect("the triangles are written");
        for (set, rays) in sets {
            let bytes: Vec<u8> = rays
                .iter()
                .flat_map(|r| r.origin.into_iter().chain(r.direction).chain([r.t_min, r.t_max]))
                .flat_map(|c| c.to_le_bytes())
                .collect();
            std::fs::write(dir.join(format!("{stem}-{set}.bin")), bytes).expect("the rays are written");
        }
        println!("{name}: {} triangles and rays written to {}", triangles.len(), dir.display());
    }

    fn converted(name: &str, path: &std::path::Path) -> BvhFile {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/peer");
        std::fs::create_dir_all(&dir).expect("target/peer can be made");
        let output = dir.join(format!("{}.bvh", name.replace(' ', "-")));
        bvhc::Conversion::new(path, &output).run().expect("the scene converts");
        BvhFile::read(&output).expect("the conversion reads back")
    }

    pub fn run() {
        let ray_count = std::env::var("BVHC_BENCH_RAYS").ok().and_then(|v| v.parse().ok()).unwrap_or(1_000_000);
        let rounds: usize = std::env::var("BVHC_PEER_ROUNDS").ok().and_then(|v| v.parse().ok()).unwrap_or(5);
        let only = std::env::var("BVHC_PEER_ONLY").ok();
        let camera = std::env::var("BVHC_PEER_CAMERA")
            .ok()
            .and_then(|v| v.split_once('x').and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?))))
            .unwrap_or((1024usize, 768usize));
        let mut coherent_rows = Vec::new();
        let mut tinybvh_rows = Vec::new();
        if only.is_none() {
            println!(
                "{} against bvhc, one thread, Mrays/s: medians of {rounds} interleaved rounds in this run; {} \
                 incoherent rays (uniform origins in the box, uniform directions) and {}x{} primary rays.\n",
                embree::VERSION,
                ray_count,
                camera.0,
                camera.1
            );
            println!(
                "| scene | rays | query | bvhc | Embree AVX2 | Embree native | robust AVX2 | robust native | bvhc / Embree AVX2 | bvhc / native | bvhc / robust AVX2 | answers unlike Embree AVX2 |"
            );
            println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
        }
        for (name, path) in harness::scenes(&SCENES, Some("BVHC_PEER_SCENES")) {
            let file = converted(name, &path);
            let view = file.view();
            let triangles = bvhc::import::import(&path, &Default::default()).unwrap().soup.triangle_vertices();
            let root = view.nodes()[0];
            let contenders: Vec<(&str, Contender<'_>)> = match only.as_deref() {
                Some("bvhc") => vec![("bvhc", Contender::Bvhc(view.tracer().trusting_rays()))],
                Some("bvhc-checked") => vec![("bvhc checked", Contender::Bvhc(view.tracer()))],
                // The ray check's cost: the checking tracer against the trusting one, rounds interleaved.
                Some("ray-check") => vec![
                    ("bvhc", Contender::Bvhc(view.tracer())),
                    ("bvhc trusting", Contender::Bvhc(view.tracer().trusting_rays())),
                ],
                Some("embree") => {
                    vec![("embree", Contender::Embree(Embree::with_isa(&triangles, false, Some("avx2"))))]
                }
                Some("embree-robust") => {
                    vec![("embree robust", Contender::Embree(Embree::with_isa(&triangles, true, Some("avx2"))))]
                }
                #[cfg(all(feature = "tinybvh", target_feature = "avx2", target_feature = "fma"))]
                Some("tinybvh") => {
                    vec![("tinybvh", Contender::Tinybvh(crate::tinybvh_kernel::Bvh8Cpu::new(&triangles)))]
                }
                Some(other) => {
                    panic!("BVHC_PEER_ONLY={other}: bvhc, bvhc-checked, ray-check, embree, embree-robust or tinybvh")
                }
                // bvhc's kernel without the ray check, as Embree runs without one (`ray-check` measures it).
                None => vec![
                    ("bvhc", Contender::Bvhc(view.tracer().trusting_rays())),
                    ("Embree AVX2", Contender::Embree(Embree::with_isa(&triangles, false, Some("avx2")))),
                    ("Embree native", Contender::Embree(Embree::with_isa(&triangles, false, None))),
                    ("robust AVX2", Contender::Embree(Embree::with_isa(&triangles, true, Some("avx2")))),
                    ("robust native", Contender::Embree(Embree::with_isa(&triangles, true, None))),
                ],
            };
            let sets = [
                ("incoherent", rays::uniform_rays(&root, ray_count, UNIFORM_SEED)),
                ("primary", {
                    let rays = rays::camera_rays(&root, camera.0, camera.1);
                    match std::env::var_os("BVHC_PEER_TILES").is_some() && only.is_some() {
                        true => tile_order(camera).into_iter().map(|i| rays[i]).collect(),
                        false => rays,
                    }
                }),
            ];
            if let Some(dir) = std::env::var_os("BVHC_PEER_WRITE") {
                write_inputs(std::path::Path::new(&dir), name, &view, &triangles, &sets);
                continue;
            }
            for (set, rays) in &sets {
                for closest in [true, false] {
                    let query = if closest { "closest" } else { "any" };
                    if only.as_deref() == Some("ray-check") {
                        // Single-ray calls, then the batch calls (streams for incoherent rays, packets for primary
                        // ones), each checked and trusting, rounds interleaved.
                        let coherent = *set == "primary";
                        let mut samples = [Vec::new(), Vec::new(), Vec::new(), Vec::new()];
                        for _ in 0..rounds {
                            for (c, (_, contender)) in contenders.iter().enumerate() {
                                let Contender::Bvhc(tracer) = contender else { unreachable!("bvhc only") };
                                let start = Instant::now();
                                std::hint::black_box(measured_pass(contender, rays, closest));
                                samples[c].push(rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6);
                                let start = Instant::now();
                                std::hint::black_box(batch_pass(tracer, rays, closest, coherent));
                                samples[2 + c].push(rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6);
                            }
                        }
                        let [single, single_trusting, batch, batch_trusting] = samples.map(median);
                        println!(
                            "| {name} | {set} | {query} | {single:.2} | {single_trusting:.2} | {:.4} | {batch:.2} | {batch_trusting:.2} | {:.4} |",
                            single / single_trusting,
                            batch / batch_trusting
                        );
                        continue;
                    }
                    if let Some(contender) = &only {
                        if contender == "tinybvh" && !closest {
                            continue; // closest hits only
                        }
                        let wanted_set = std::env::var("BVHC_PEER_SET").unwrap_or_else(|_| "incoherent".into());
                        let wanted_query = std::env::var("BVHC_PEER_QUERY").unwrap_or_else(|_| "closest".into());
                        if *set == wanted_set && query == wanted_query {
                            let hits = measured_pass(&contenders[0].1, rays, closest);
                            println!("{name} {set} {query} {}: {} rays, {hits} hits", contenders[0].0, rays.len());
                            if std::env::var_os("BVHC_PEER_ROUNDS").is_some() {
                                let speeds: Vec<f64> = (0..rounds)
                                    .map(|_| {
                                        let start = Instant::now();
                                        std::hint::black_box(measured_pass(&contenders[0].1, rays, closest));
                                        rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6
                                    })
                                    .collect();
                                println!("  {:.2} Mrays/s (median of {rounds})", median(speeds));
                            }
                            if let Contender::Bvhc(tracer) = &contenders[0].1 {
                                let mut stats = bvhc::loader::TraversalStats::default();
                                for ray in rays {
                                    if closest {
                                        tracer.closest_hit_counted(ray, &mut stats);
                                    } else {
                                        tracer.any_hit_counted(ray, &mut stats);
                                    }
                                }
                                let per_ray = |n: u64| n as f64 / rays.len() as f64;
                                println!(
                                    "  wide node visits {:.2} and packet tests {:.2} a ray",
                                    per_ray(stats.node_visits),
                                    per_ray(stats.triangle_tests)
                                );
                            }
                        }
                        continue;
                    }
                    let reference = contenders[0].1.answers(rays, closest);
                    let unlike = disagreements(&reference, &contenders[1].1.answers(rays, closest));
                    let mut samples = vec![Vec::new(); contenders.len()];
                    for _ in 0..rounds {
                        for (c, (_, contender)) in contenders.iter().enumerate() {
                            let start = Instant::now();
                            std::hint::black_box(measured_pass(contender, rays, closest));
                            samples[c].push(rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6);
                        }
                    }
                    let speeds: Vec<f64> = samples.into_iter().map(median).collect();
                    println!(
                        "| {name} | {set} | {query} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {unlike} |",
                        speeds[0],
                        speeds[1],
                        speeds[2],
                        speeds[3],
                        speeds[4],
                        speeds[0] / speeds[1],
                        speeds[0] / speeds[2],
                        speeds[0] / speeds[3],
                    );
                }
            }
            if only.is_none() {
                coherent_rows.push(coherent_row(name, &view, &triangles, (&sets[1].1, camera), rounds));
            }
            if only.is_none() {
                tinybvh_rows.extend(second_peer_rows(name, &contenders, &triangles, &sets, rounds));
            }
        }
        if only.is_none() {
            println!(
                "\nCoherent primary rays ({}x{}, in rows and in 4x2 tiles), closest hit, Mrays/s, medians of {rounds} interleaved rounds:\n",
                camera.0, camera.1
            );
            println!(
                "| scene | bvhc single rays | bvhc 8-ray packets | bvhc packets, 4x2 tiles | Embree AVX2 rtcIntersect8 | rtcIntersect8, 4x2 tiles | Embree AVX2 rtcIntersect16 | Embree native rtcIntersect16 | packets / best Embree | tiles / best Embree |"
            );
            println!("|---|---|---|---|---|---|---|---|---|---|");
            for row in coherent_rows {
                println!("{row}");
            }
        }
        if !tinybvh_rows.is_empty() {
            println!("\nA second peer, closest hits, Mrays/s, medians of {rounds} interleaved rounds:\n");
            println!(
                "| scene | rays | bvhc | Embree AVX2 | tinybvh BVH8_CPU | bvhc / tinybvh | tinybvh / Embree AVX2 | answers unlike bvhc |"
            );
            println!("|---|---|---|---|---|---|---|---|");
            for row in tinybvh_rows {
                println!("{row}");
            }
        } else if only.is_none() {
            println!(
                "\n(tinybvh's BVH8_CPU as a second peer: `CXX=$PWD/scripts/avx2-cxx.sh RUSTFLAGS=\"-C \
                 target-feature=+avx2,+fma\" CARGO_TARGET_DIR=target/tinybvh cargo bench --bench peer --features \
                 embree4,tinybvh`)"
            );
        }
    }

    /// The second peer's rows of one scene, closest hits on both ray sets: bvhc (`contenders[0]`), Embree AVX2
    /// (`contenders[1]`) and tinybvh's `BVH8_CPU` in turn, and the rays tinybvh answers unlike bvhc.
    #[cfg(all(feature = "tinybvh", target_feature = "avx2", target_feature = "fma"))]
    fn second_peer_rows(
        name: &str,
        contenders: &[(&str, Contender<'_>)],
        triangles: &[[[f32; 3]; 3]],
        sets: &[(&str, Vec<Ray>)],
        rounds: usize,
    ) -> Vec<String> {
        let tinybvh = Contender::Tinybvh(crate::tinybvh_kernel::Bvh8Cpu::new(triangles));
        let trio = [&contenders[0].1, &contenders[1].1, &tinybvh];
        let mut rows = Vec::new();
        for (set, rays) in sets {
            let unlike = disagreements(&trio[0].answers(rays, true), &tinybvh.answers(rays, true));
            let mut samples = vec![Vec::new(); trio.len()];
            for _ in 0..rounds {
                for (c, contender) in trio.iter().enumerate() {
                    let start = Instant::now();
                    std::hint::black_box(measured_pass(contender, rays, true));
                    samples[c].push(rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6);
                }
            }
            let s: Vec<f64> = samples.into_iter().map(median).collect();
            let ratios = (s[0] / s[2], s[2] / s[1]);
            rows.push(format!(
                "| {name} | {set} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {unlike} |",
                s[0], s[1], s[2], ratios.0, ratios.1
            ));
        }
        rows
    }

    /// Without tinybvh's kernel in this build (the feature, or AVX2 and FMA, missing), no rows.
    #[cfg(not(all(feature = "tinybvh", target_feature = "avx2", target_feature = "fma")))]
    fn second_peer_rows(
        _: &str,
        _: &[(&str, Contender<'_>)],
        _: &[[[f32; 3]; 3]],
        _: &[(&str, Vec<Ray>)],
        _: usize,
    ) -> Vec<String> {
        Vec::new()
    }
}
