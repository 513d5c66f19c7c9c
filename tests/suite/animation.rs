//! `--animation`: trees chosen for the cost averaged over poses sampled from a glTF's clips. The oracle for the
//! costs the metadata records is the loader's own refit (another path: the file's records moved to each pose by
//! `bvhc::posed::record_positions`, boxes and costs recomputed from the bytes), and the tree is judged against the
//! default pose's tree refit to the same poses.

#[path = "../../benches/common/morphing_glb.rs"]
mod morphing_glb;

use std::path::{Path, PathBuf};

use bvhc::import::{ClipSelector, PoseSelector};
use bvhc::loader::{BvhFile, RebuildPolicy, RefitPositions};

use crate::cli::bvhc;

/// A twisting, waving icosphere (5,120 triangles, one 20-second clip named "Deform") as a GLB in `dir`.
fn morphing_sphere(dir: &Path) -> PathBuf {
    let (vertices, triangles) = crate::common::unit_icosphere(4);
    let positions: Vec<[f32; 3]> = vertices.iter().map(|v| [v[0] as f32, 2.0 * v[1] as f32, v[2] as f32]).collect();
    let triangles: Vec<[u32; 3]> = triangles.iter().map(|t| t.map(|i| i as u32)).collect();
    let path = dir.join("sphere.glb");
    morphing_glb::write(&path, &positions, &triangles);
    path
}

/// Converts `input` to `output` with `args`; panics with the error otherwise.
pub fn convert(input: &Path, output: &Path, args: &[&str]) -> BvhFile {
    let mut all: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&input, &"-o", &output, &"-q", &"--force"];
    all.extend(args.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>));
    let run = bvhc(&all);
    assert!(run.status.success(), "{args:?}: {}", String::from_utf8_lossy(&run.stderr));
    BvhFile::read(output).unwrap()
}

/// `file` refit to `asset` at each time of `clip` in `seconds`: the (binary, wide) costs the loader reports.
fn refit_costs(file: &BvhFile, asset: &Path, clip: usize, seconds: &[f64]) -> Vec<(f64, f64)> {
    seconds
        .iter()
        .map(|&seconds| {
            let pose = PoseSelector { clip: ClipSelector::Index(clip), seconds };
            let positions =
                bvhc::posed::record_positions(&file.view(), asset, &Default::default(), Some(&pose)).unwrap();
            let mut copy = BvhFile::from_bytes(file.as_bytes()).unwrap();
            let report = copy.refit(RefitPositions::Triangles(&positions), 1).unwrap();
            (report.cost.unwrap(), report.wide_cost.unwrap())
        })
        .collect()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs())
}

/// The animation's record checked against the loader's refits, and the mean refit wide cost of the animation's
/// tree over its poses and of the default pose's tree over the same poses.
fn check_against_rest(asset: &Path, dir: &Path, clip: usize, args: &[&str]) -> (f64, f64) {
    let animated = convert(asset, &dir.join("animated.bvh"), args);
    let rest = convert(asset, &dir.join("rest.bvh"), &["--no-splits", "--instancing", "never"]);
    animated.view().verify().unwrap();
    assert!(!animated.view().has_split_references() && animated.view().two_level().is_none());
    let metadata = crate::common::assert_metadata_matches_schema(&animated);
    let record = &metadata["animation"];
    let poses = record["poses"].as_array().unwrap();
    assert!(poses.iter().all(|p| p["clip"] == clip));
    let seconds: Vec<f64> = poses.iter().map(|p| p["seconds"].as_f64().unwrap()).collect();
    let measured = refit_costs(&animated, asset, clip, &seconds);
    for (pose, (sah, wide)) in poses.iter().zip(&measured) {
        assert!(close(pose["sah_cost"].as_f64().unwrap(), *sah), "{pose} against {sah}");
        assert!(close(pose["wide_cost"].as_f64().unwrap(), *wide), "{pose} against {wide}");
    }
    let count = measured.len() as f64;
    let mean_wide = measured.iter().map(|c| c.1).sum::<f64>() / count;
    let mean_sah = measured.iter().map(|c| c.0).sum::<f64>() / count;
    assert!(close(record["expected_wide_cost"].as_f64().unwrap(), mean_wide));
    assert!(close(record["expected_sah_cost"].as_f64().unwrap(), mean_sah));
    let worst = (0..measured.len()).fold(0, |w, k| if measured[k].1 > measured[w].1 { k } else { w });
    assert_eq!(record["worst_pose"], worst);
    let stated = metadata["wide"]["cost"].as_f64().unwrap();
    assert!(close(record["worst_cost_ratio"].as_f64().unwrap(), measured[worst].1 / stated));
    let reinsertion = &record["reinsertion"];
    assert!(reinsertion["final_cost"].as_f64().unwrap() <= reinsertion["initial_cost"].as_f64().unwrap());
    assert!(crate::common::assert_metadata_matches_schema(&rest).get("animation").is_none());
    let rest_mean = refit_costs(&rest, asset, clip, &seconds).iter().map(|c| c.1).sum::<f64>() / count;
    (mean_wide, rest_mean)
}

#[test]
fn an_animation_tree_records_its_poses_costs_and_costs_less_over_them_than_the_default_poses_tree() {
    let dir = tempfile::tempdir().unwrap();
    let asset = morphing_sphere(dir.path());
    let (animated, rest) = check_against_rest(&asset, dir.path(), 0, &["--animation", "--animation-poses", "4"]);
    assert!(animated < 0.98 * rest, "animation's tree {animated}, default pose's {rest}");
    let metadata =
        crate::common::assert_metadata_matches_schema(&BvhFile::read(dir.path().join("animated.bvh")).unwrap());
    assert_eq!(metadata["build"]["animation"], serde_json::json!({"clips": [], "poses_per_clip": 4}));
    assert_eq!(
        metadata["animation"]["clips"],
        serde_json::json!([{"index": 0, "name": "Deform", "start": 0.0, "end": 20.0}])
    );
    let seconds: Vec<f64> =
        metadata["animation"]["poses"].as_array().unwrap().iter().map(|p| p["seconds"].as_f64().unwrap()).collect();
    assert_eq!(seconds, [2.5, 7.5, 12.5, 17.5]);
    let info = bvhc(&[&"info", &dir.path().join("animated.bvh")]);
    let info = String::from_utf8_lossy(&info.stdout).into_owned();
    assert!(info.contains("animation: tree chosen for 4 poses of Deform 0.00-20.00 s; refit wide cost mean"), "{info}");
    // Named clips are recorded as given.
    convert(&asset, &dir.path().join("named.bvh"), &["--animation", "Deform", "--animation-poses", "2"]);
    let named = crate::common::assert_metadata_matches_schema(&BvhFile::read(dir.path().join("named.bvh")).unwrap());
    assert_eq!(named["build"]["animation"]["clips"], serde_json::json!([{"name": "Deform"}]));
}

#[test]
fn a_tree_for_a_part_of_the_clip_samples_that_part_and_costs_less_there_than_the_whole_clips_tree() {
    let dir = tempfile::tempdir().unwrap();
    let asset = morphing_sphere(dir.path());
    // The part's tree, stored in the pose of the part's middle; its record checked against the loader's refits.
    let part = ["--animation", "--animation-window", "2..6", "--animation-poses", "4", "--pose", "0@4"];
    check_against_rest(&asset, dir.path(), 0, &part);
    let file = BvhFile::read(dir.path().join("animated.bvh")).unwrap();
    let metadata = crate::common::assert_metadata_matches_schema(&file);
    assert_eq!(
        metadata["build"]["animation"],
        serde_json::json!({"clips": [], "poses_per_clip": 4, "window": {"start": 2.0, "end": 6.0}})
    );
    let seconds: Vec<f64> =
        metadata["animation"]["poses"].as_array().unwrap().iter().map(|p| p["seconds"].as_f64().unwrap()).collect();
    assert_eq!(seconds, [2.5, 3.5, 4.5, 5.5]);
    let info = bvhc(&[&"info", &dir.path().join("animated.bvh")]);
    let info = String::from_utf8_lossy(&info.stdout).into_owned();
    assert!(info.contains("chosen for 4 poses of Deform 2.00-6.00 s (of 0.00-20.00 s)"), "{info}");
    // Over the part's times (sampled and between), the part's tree costs less than the whole clip's tree.
    let whole = convert(&asset, &dir.path().join("whole.bvh"), &["--animation", "--animation-poses", "4"]);
    let times = [2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0];
    let mean = |file: &BvhFile| refit_costs(file, &asset, 0, &times).iter().map(|c| c.1).sum::<f64>() / 9.0;
    let (part_mean, whole_mean) = (mean(&file), mean(&whole));
    assert!(part_mean < whole_mean, "part's tree {part_mean}, whole clip's {whole_mean}");
}

#[test]
fn skinned_shared_scenes_get_trees_that_cost_less_over_their_clips() {
    for (relative, clip) in [("khr-cesium-man/CesiumMan.gltf", 0usize), ("khr-fox/Fox.gltf", 2)] {
        let Some(asset) = crate::common::scene(relative) else { continue };
        let dir = tempfile::tempdir().unwrap();
        let clip_arg = clip.to_string();
        let (animated, rest) = check_against_rest(&asset, dir.path(), clip, &["--animation", &clip_arg]);
        assert!(animated < rest, "{relative}: animation's tree {animated}, default pose's {rest}");
    }
}

#[test]
fn an_animation_tree_does_not_depend_on_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let asset = morphing_sphere(dir.path());
    let one = convert(&asset, &dir.path().join("one.bvh"), &["--animation", "--threads", "1"]);
    let two = convert(&asset, &dir.path().join("two.bvh"), &["--animation", "--threads", "2"]);
    assert!(one.as_bytes() == two.as_bytes());
}

#[test]
fn animation_settings_that_cannot_be_honoured_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let asset = morphing_sphere(dir.path());
    let output = dir.path().join("out.bvh");
    let refused = |input: &Path, args: &[&str], expected: &str| {
        let mut all: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&input, &"-o", &output, &"-q"];
        all.extend(args.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>));
        let run = bvhc(&all);
        let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
        assert!(!run.status.success() && stderr.contains(expected), "{args:?}: {stderr}");
        assert!(!output.exists(), "{args:?} left an output");
    };
    refused(&asset, &["--animation", "Fly"], "no animation is named 'Fly' (names: [\"Deform\"])");
    refused(&asset, &["--animation", "3"], "animation 3 does not exist (the file has 1)");
    refused(&asset, &["--animation", "0,,Deform"], "an empty clip name");
    refused(&asset, &["--animation", "--animation-poses", "0"], "--animation-poses: 0 is not from 1 to 64");
    refused(&asset, &["--animation", "--animation-poses", "65"], "65 is not from 1 to 64");
    refused(&asset, &["--animation-poses", "4"], "--animation");
    refused(&asset, &["--animation-window", "0..1"], "--animation");
    refused(&asset, &["--animation", "--animation-window", "6..2"], "'6..2': the window ends before it starts");
    refused(&asset, &["--animation", "--animation-window", "0,5"], "'0,5': not START..END (seconds)");
    refused(
        &asset,
        &["--animation", "--animation-window", "25..30"],
        "--animation-window 25..30 leaves no time of clip 0 (its keyframes span 0..20 s)",
    );
    for (flag, value) in [("--split-budget", "0.2"), ("--tune-rays", "5000")] {
        refused(&asset, &["--animation", flag, value], &format!("{flag} does nothing with --animation"));
    }
    let teapot = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    refused(&teapot, &["--animation"], "only a glTF file or an OpenUSD stage has animation clips");
    // The memory budget counts every pose's triangles and boxes: a budget the still scene fits in refuses 64
    // poses of it.
    let budget = ["--max-memory", "110M"];
    assert!(bvhc(&[&asset, &"-o", &output, &"-q", &budget[0], &budget[1]]).status.success());
    std::fs::remove_file(&output).unwrap();
    refused(
        &asset,
        &["--animation", "--animation-poses", "64", budget[0], budget[1]],
        "more than the 110M --max-memory allows",
    );
    // A glTF without clips: one triangle, its buffer a data URI.
    let still = dir.path().join("still.gltf");
    let bytes: Vec<u8> =
        [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0].iter().flat_map(|f| f.to_le_bytes()).collect();
    let uri = format!("data:application/octet-stream;base64,{}", base64_of(&bytes));
    let gltf = serde_json::json!({"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}], "buffers": [{"byteLength": 36, "uri": uri}]});
    std::fs::write(&still, serde_json::to_vec(&gltf).unwrap()).unwrap();
    refused(&still, &["--animation"], "the file has no animation clips to sample");
}

/// Standard base64 with padding (RFC 4648), for a data URI.
pub fn base64_of(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[test]
fn a_refit_report_plans_for_the_poses_the_tree_was_chosen_for() {
    let dir = tempfile::tempdir().unwrap();
    let asset = morphing_sphere(dir.path());
    let animated = convert(&asset, &dir.path().join("animated.bvh"), &["--animation", "--animation-poses", "4"]);
    let rest = convert(&asset, &dir.path().join("rest.bvh"), &["--no-splits", "--instancing", "never"]);
    let metadata = crate::common::assert_metadata_matches_schema(&animated);
    let poses = metadata["animation"]["poses"].as_array().unwrap();
    let planned = metadata["animation"]["worst_cost_ratio"].as_f64().unwrap();
    assert!(planned > 1.0, "{planned}");
    assert!(close(animated.view().planned_cost_ratio().unwrap(), planned));
    assert_eq!(rest.view().planned_cost_ratio(), None);
    let refit_to = |file: &BvhFile, seconds: f64| {
        let pose = PoseSelector { clip: ClipSelector::Index(0), seconds };
        let positions = bvhc::posed::record_positions(&file.view(), &asset, &Default::default(), Some(&pose)).unwrap();
        let mut copy = BvhFile::from_bytes(file.as_bytes()).unwrap();
        let report = copy.refit(RefitPositions::Triangles(&positions), 1).unwrap();
        (copy, report)
    };
    for pose in poses {
        let (_, report) = refit_to(&animated, pose["seconds"].as_f64().unwrap());
        assert!(close(report.planned_cost_ratio.unwrap(), planned));
        assert!(report.cost_ratio() <= planned * (1.0 + 1e-9));
        assert!(!RebuildPolicy::DEFAULT.should_rebuild(&report), "{report:?}");
        // The same threshold without the plan: what a file converted without --animation gets.
        let plain = bvhc::loader::RefitReport { planned_cost_ratio: None, ..report };
        assert_eq!(RebuildPolicy::DEFAULT.should_rebuild(&plain), plain.cost_ratio() > 1.2);
        let (_, rest_report) = refit_to(&rest, pose["seconds"].as_f64().unwrap());
        assert_eq!(rest_report.planned_cost_ratio, None);
    }
    // A ratio past 1.2 times the plan asks for a rebuild.
    let (_, report) = refit_to(&animated, 5.0);
    let beyond = bvhc::loader::RefitReport { file_wide_cost: report.wide_cost.map(|c| c / (1.21 * planned)), ..report };
    assert!(RebuildPolicy::DEFAULT.should_rebuild(&beyond));
    // After a refit restated the file's costs (at 5 s), the plan is the poses' costs over the new stated cost.
    let (moved, _) = refit_to(&animated, 5.0);
    let restated = BvhFile::from_bytes(moved.rewritten().unwrap().as_bytes()).unwrap();
    let stated = crate::common::assert_metadata_matches_schema(&restated)["wide"]["cost"].as_f64().unwrap();
    let worst = poses.iter().map(|p| p["wide_cost"].as_f64().unwrap()).fold(0.0, f64::max);
    let (_, report) = refit_to(&restated, 15.0);
    assert!(close(report.planned_cost_ratio.unwrap(), worst / stated), "{report:?} against {worst} / {stated}");
    // The command line prints the plan and keeps quiet about a rebuild within it.
    let output = dir.path().join("refit.bvh");
    let seconds = format!("0@{}", poses[0]["seconds"]);
    let run = bvhc(&[
        &"refit",
        &dir.path().join("animated.bvh"),
        &"--positions",
        &asset,
        &"--pose",
        &seconds,
        &"-o",
        &output,
        &"--json",
    ]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let json: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert!(close(json["planned_cost_ratio"].as_f64().unwrap(), planned));
    assert_eq!(json["rebuild_recommended"], false);
}
