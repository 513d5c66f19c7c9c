//! Ray-tuned conversions (`--tune-rays`, `--train-rays`, `bvhc::sampling`): the sample rays' traversal finds
//! the brute-force closest hit, the visit counts are the same for any thread count, weights proportional to the
//! areas give the SAH collapse's and leaf merge's trees, the sample is sized and split as documented, and a tuned
//! conversion verifies, records its training, its sample and the candidates judged on held-out rays (the
//! unoptimized build among them, with `choose` a build without splits), skips tiny scenes, and is the same bytes
//! on 1 and 2 threads.

use std::ops::ControlFlow;

use bvhc::convert::convert_with;
use bvhc::layout::{WideCosts, collapse, collapse_by, merge_leaves, merge_leaves_by, merge_leaves_of_references};
use bvhc::loader::BvhFile;
use bvhc::optimize::OptTree;
use bvhc::options::{OptimizeOver, Overrides, Preset, resolve};
use bvhc::sampling::{
    MAX_RAYS_PER_TRIANGLE, MIN_SAMPLED_TRIANGLES, RaySample, RayTuning, TrainingRays, node_visits, ray_weights,
    trace_counting, training_rays,
};

use crate::common::{brute_force_closest, in_pool, random_triangles};

fn tree_of(triangles: &[[[f32; 3]; 3]]) -> OptTree {
    OptTree::from_build_tree(&bvhc::builders::build_binned_sah(triangles, 1), triangles)
}

#[test]
fn sample_rays_find_the_brute_force_closest_hit_and_count_the_same_on_any_thread_count() {
    let triangles = random_triangles(81, 2000, 5.0);
    let tree = tree_of(&triangles);
    let rays = training_rays(&tree, &triangles, 6000, 7);
    assert_eq!(rays.len(), 6000);
    assert_eq!(rays, training_rays(&tree, &triangles, 6000, 7), "deterministic");
    let mut visits = vec![0u32; tree.nodes.len()];
    for ray in &rays {
        let hit = trace_counting(&tree, &triangles, ray, &mut visits);
        assert_eq!(hit.map(|h| h.t), brute_force_closest(&triangles, ray).map(|(t, _)| t), "{ray:?}");
    }
    let one = in_pool(1, || node_visits(&tree, &triangles, &rays));
    let two = in_pool(2, || node_visits(&tree, &triangles, &rays));
    assert_eq!(one, visits);
    assert_eq!(one, two);
    // A ray that enters a child entered its parent.
    for (n, node) in tree.nodes.iter().enumerate() {
        if node.left != bvhc::optimize::NONE {
            for child in [node.left, node.right] {
                assert!(one[child as usize] <= one[n], "node {n}");
            }
        }
    }
}

#[test]
fn weights_proportional_to_the_areas_give_the_sah_collapse() {
    let triangles = random_triangles(82, 3000, 5.0);
    let tree = tree_of(&triangles);
    let areas: Vec<f64> = tree.nodes.iter().map(|n| n.aabb.surface_area()).collect();
    let costs = WideCosts::default();
    assert_eq!(collapse_by(&tree, &costs, &areas, false), collapse(&tree, &costs));
    let constants = bvhc::cost::SahConstants::default();
    assert_eq!(merge_leaves_by(&tree, constants, 8, false, &areas), merge_leaves(&tree, constants, 8));
    assert_eq!(merge_leaves_by(&tree, constants, 8, true, &areas), merge_leaves_of_references(&tree, constants, 8));
    // No sample ray: the blended weights are the areas' shares.
    let weights = ray_weights(&tree, &vec![0; tree.nodes.len()], 32.0);
    let root_area = areas[tree.root as usize];
    for (w, a) in weights.iter().zip(&areas) {
        assert!((w - a / root_area).abs() <= 1e-12 * (a / root_area).max(1.0));
    }
}

#[test]
fn a_tuned_conversion_verifies_records_its_training_and_does_not_depend_on_threads() {
    let input = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    let dir = tempfile::tempdir().unwrap();
    let overrides = Overrides { tune_rays: Some(4096), gpu_layout: Some(true), ..Overrides::default() };
    let options = resolve(Preset::Balanced, &overrides).unwrap();
    let bytes = |threads: usize| {
        let output = dir.path().join(format!("{threads}.bvh"));
        in_pool(threads, || convert_with(&input, &output, &options, &mut |_| ControlFlow::Continue(())).unwrap());
        std::fs::read(&output).unwrap()
    };
    let one = bytes(1);
    assert_eq!(one, bytes(2));
    let file = BvhFile::from_bytes(&one).unwrap();
    file.view().verify().unwrap();
    let metadata = crate::common::assert_metadata_matches_schema(&file);
    assert_eq!(metadata["build"]["ray_tuning"]["rays"], 4096);
    let sampling = &metadata["sampling"];
    assert_eq!(
        (&sampling["training_rays"], &sampling["held_out_rays"], &sampling["held_out_seed"]),
        (&4096.into(), &4096.into(), &2.into())
    );
    // Judged on the held-out rays: the build as built, and optimized over clusters (the balanced preset).
    let choice = &metadata["choice"];
    assert_eq!(choice["measure"], "sampled_cost");
    let labels: Vec<(&str, &str)> = choice["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| (c["split_triangles"].as_str().unwrap(), c["optimize_over"].as_str().unwrap()))
        .collect();
    assert_eq!(labels, [("wasteful", "none"), ("wasteful", "clusters")]);
    assert_kept_is_cheapest(choice);
    // Nothing to tune without a wide or GPU collapse.
    let inert = Overrides { tune_rays: Some(4096), wide: Some(false), ..Overrides::default() };
    assert!(resolve(Preset::Balanced, &inert).unwrap_err().to_string().contains("--tune-rays"));
}

/// The kept candidate has the lowest cost (the first on a tie).
fn assert_kept_is_cheapest(choice: &serde_json::Value) {
    let costs: Vec<f64> =
        choice["candidates"].as_array().unwrap().iter().map(|c| c["cost"].as_f64().unwrap()).collect();
    let lowest = costs.iter().copied().fold(f64::INFINITY, f64::min);
    let first_lowest = costs.iter().position(|&c| c == lowest).unwrap();
    assert_eq!(choice["kept"], first_lowest, "{costs:?}");
}

#[test]
fn max_quality_with_ray_tuning_judges_every_build_optimized_or_not_with_and_without_splits() {
    let input = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    let dir = tempfile::tempdir().unwrap();
    // The preset optimizes over clusters: each of the three split choices built optimized and not.
    let preset = Overrides { tune_rays: Some(2048), ..Overrides::default() };
    assert_eq!(resolve(Preset::MaxQuality, &preset).unwrap().candidate_count(), 6);
    // With `--optimize-over choose`, also over references: nine builds.
    let overrides = Overrides { optimize_over: Some(OptimizeOver::Choose), ..preset };
    let options = resolve(Preset::MaxQuality, &overrides).unwrap();
    assert_eq!(options.candidate_count(), 9);
    let output = dir.path().join("teapot.bvh");
    convert_with(&input, &output, &options, &mut |_| ControlFlow::Continue(())).unwrap();
    let file = BvhFile::read(&output).unwrap();
    file.view().verify().unwrap();
    let metadata = crate::common::assert_metadata_matches_schema(&file);
    let choice = &metadata["choice"];
    assert_eq!(choice["measure"], "sampled_cost");
    let labels: Vec<String> = choice["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| format!("{}/{}", c["split_triangles"].as_str().unwrap(), c["optimize_over"].as_str().unwrap()))
        .collect();
    let expected: Vec<String> = ["none", "wasteful", "any"]
        .iter()
        .flat_map(|cut| ["none", "references", "clusters"].map(|over| format!("{cut}/{over}")))
        .collect();
    assert_eq!(labels, expected);
    assert_kept_is_cheapest(choice);
}

#[test]
fn a_tiny_scene_is_not_sampled_and_its_file_says_so() {
    let triangles = random_triangles(83, MIN_SAMPLED_TRIANGLES - 1, 5.0);
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("tiny.obj");
    let mut obj = String::new();
    for (i, t) in triangles.iter().enumerate() {
        for v in t {
            obj.push_str(&format!("v {} {} {}\n", v[0], v[1], v[2]));
        }
        obj.push_str(&format!("f {} {} {}\n", 3 * i + 1, 3 * i + 2, 3 * i + 3));
    }
    std::fs::write(&input, obj).unwrap();
    let output = dir.path().join("tiny.bvh");
    let options = resolve(Preset::Balanced, &Overrides { tune_rays: Some(4096), ..Overrides::default() }).unwrap();
    convert_with(&input, &output, &options, &mut |_| ControlFlow::Continue(())).unwrap();
    let file = BvhFile::read(&output).unwrap();
    let metadata = crate::common::assert_metadata_matches_schema(&file);
    let skipped = metadata["sampling"]["skipped"].as_str().unwrap();
    assert!(skipped.contains(&format!("{} triangles", MIN_SAMPLED_TRIANGLES - 1)), "{skipped}");
    assert!(metadata["sampling"].get("training_rays").is_none());
    assert!(metadata.get("choice").is_none(), "one candidate, as without tuning");
}

#[test]
fn the_sample_is_capped_by_the_scene_and_a_users_file_is_split_into_training_and_held_out_rays() {
    let triangles = random_triangles(84, 1500, 5.0);
    let tree = tree_of(&triangles);
    let tuning = RayTuning { rays: 1 << 20, seed: 5, ..RayTuning::default() };
    let sample = RaySample::new(&tree, &triangles, &tuning, None);
    assert!(sample.is_sampled());
    assert_eq!(sample.training.len(), MAX_RAYS_PER_TRIANGLE * 1500);
    assert_eq!(sample.training, training_rays(&tree, &triangles, MAX_RAYS_PER_TRIANGLE * 1500, 5));
    assert_eq!(sample.held_out, training_rays(&tree, &triangles, MAX_RAYS_PER_TRIANGLE * 1500, 6));
    assert_eq!(sample.summary.held_out_seed, Some(6));
    let rays = training_rays(&tree, &triangles, 101, 9);
    let user = TrainingRays { rays: rays.clone().into(), content_hash: 0 };
    let sample = RaySample::new(&tree, &triangles, &tuning, Some(&user));
    let even: Vec<_> = rays.iter().step_by(2).copied().collect();
    let odd: Vec<_> = rays.iter().skip(1).step_by(2).copied().collect();
    assert_eq!((sample.training, sample.held_out), (even, odd));
    assert_eq!(
        (sample.summary.training_rays, sample.summary.held_out_rays, sample.summary.held_out_seed),
        (Some(51), Some(50), None)
    );
    let small = &triangles[..MIN_SAMPLED_TRIANGLES - 1];
    assert!(!RaySample::new(&tree_of(small), small, &tuning, Some(&user)).is_sampled());
}

/// 32-byte ray records (`format-spec/rays-and-hits.md`).
fn ray_file(rays: &[bvhc::loader::Ray]) -> Vec<u8> {
    rays.iter()
        .flat_map(|r| {
            let values = [
                r.origin[0],
                r.origin[1],
                r.origin[2],
                r.direction[0],
                r.direction[1],
                r.direction[2],
                r.t_min,
                r.t_max,
            ];
            values.into_iter().flat_map(f32::to_le_bytes)
        })
        .collect()
}

#[test]
fn a_conversion_trains_on_the_users_ray_file_and_records_its_hash() {
    let input = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    let dir = tempfile::tempdir().unwrap();
    let rays: Vec<bvhc::loader::Ray> = (0..500)
        .map(|i| bvhc::loader::Ray::new([0.0, 1.0, 10.0], [(i % 25) as f32 * 0.02 - 0.25, -0.1, -1.0]))
        .collect();
    let rays_path = dir.path().join("frame.rays");
    std::fs::write(&rays_path, ray_file(&rays)).unwrap();
    let output = dir.path().join("teapot.bvh");
    let run = |extra: &[&str]| {
        let mut args: Vec<&str> = vec![input.to_str().unwrap(), "-o", output.to_str().unwrap(), "-q"];
        args.extend_from_slice(extra);
        let args: Vec<&dyn AsRef<std::ffi::OsStr>> = args.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>).collect();
        crate::cli::bvhc(&args)
    };
    let done = run(&["--train-rays", rays_path.to_str().unwrap()]);
    assert!(done.status.success(), "{}", String::from_utf8_lossy(&done.stderr));
    let file = BvhFile::read(&output).unwrap();
    let metadata = crate::common::assert_metadata_matches_schema(&file);
    let hash = format!("xxh3-64:{:016x}", xxhash_rust::xxh3::xxh3_64(&std::fs::read(&rays_path).unwrap()));
    assert_eq!(metadata["build"]["ray_tuning"]["training_file"], hash.as_str());
    assert_eq!(metadata["build"]["ray_tuning"]["rays"], 500);
    let sampling = &metadata["sampling"];
    assert_eq!((&sampling["training_rays"], &sampling["held_out_rays"]), (&250.into(), &250.into()));
    assert!(sampling.get("held_out_seed").is_none());
    // A bad record: the error names the file and the ray; both flags at once: refused as inert.
    let mut bad = ray_file(&rays);
    bad[32 * 7 + 12..32 * 7 + 24].fill(0);
    std::fs::write(&rays_path, bad).unwrap();
    let failed = run(&["--train-rays", rays_path.to_str().unwrap(), "--force"]);
    let message = String::from_utf8_lossy(&failed.stderr);
    assert_eq!(failed.status.code(), Some(1), "{message}");
    assert!(message.contains("frame.rays") && message.contains("ray 7"), "{message}");
    std::fs::write(&rays_path, ray_file(&rays)).unwrap();
    let both = run(&["--train-rays", rays_path.to_str().unwrap(), "--tune-rays", "100", "--force"]);
    assert_eq!(both.status.code(), Some(2), "{}", String::from_utf8_lossy(&both.stderr));
}
