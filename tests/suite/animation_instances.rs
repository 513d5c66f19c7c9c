//! `--animation --instancing always` on a scene with rigidly animated nodes: the meshes the clips move stay
//! instanced in a two-level file, the deforming rest is flattened into mesh 0 (its tree chosen for the poses), and the file refit to a
//! pose (`bvhc::posed::placed_pose`: the records moved, the instances placed where the nodes stand) traces as
//! an f64 oracle over the asset imported flattened at that pose says, on every kernel, at the sampled times,
//! between them and past the clip's end.

use std::path::{Path, PathBuf};

use bvhc::import::{ClipSelector, ImportOptions, Instancing, PoseSelector, import};
use bvhc::loader::format::{NO_INDEX, SourceRange};
use bvhc::loader::{BvhFile, BvhView};

use crate::animation::{base64_of, convert};
use crate::cli::bvhc;
use crate::common::every_kernel;
use crate::instances::{Expected, Placed, T_TOLERANCE, oracle, test_rays};
use bvhc_loader::Trace;

/// A glTF (one file, its buffer a data URI) with one clip "Swing" over 2 s: node 1 (no mesh) turns about y
/// (LINEAR) and jumps (STEP), carrying nodes 2 and 3, which place the icosphere mesh 0 (node 3 scaled by
/// 0.5); node 4 places mesh 0 standing still; node 0 places a ground quad (mesh 1); node 5 places a quad whose
/// one morph target the clip weighs from 0 to 1 and back (mesh 2).
fn swinging_scene(dir: &Path) -> PathBuf {
    swinging_scene_of(dir, &[0, 1, 4, 5])
}

/// [`swinging_scene`] with only the root nodes `roots` in its scene (of 0, 1, 4 and 5).
fn swinging_scene_of(dir: &Path, roots: &[usize]) -> PathBuf {
    let (vertices, triangles) = crate::common::unit_icosphere(2);
    let mut bytes: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut push = |bytes: &mut Vec<u8>, data: Vec<u8>| {
        views.push(serde_json::json!({"buffer": 0, "byteOffset": bytes.len(), "byteLength": data.len()}));
        bytes.extend(data);
        views.len() - 1
    };
    let floats = |values: &[f32]| values.iter().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
    let indices = |values: &[u32]| values.iter().flat_map(|i| i.to_le_bytes()).collect::<Vec<u8>>();
    let sphere: Vec<f32> = vertices.iter().flat_map(|v| v.map(|c| c as f32)).collect();
    let sphere_indices: Vec<u32> = triangles.iter().flat_map(|t| t.map(|i| i as u32)).collect();
    let ground = [-6.0f32, -1.0, -6.0, 6.0, -1.0, -6.0, 6.0, -1.0, 6.0, -6.0, -1.0, 6.0];
    let quad = [3.0f32, 0.0, 3.0, 4.0, 0.0, 3.0, 4.0, 1.0, 3.0, 3.0, 1.0, 3.0];
    let target = [0.0f32, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];
    let quad_indices = [0u32, 1, 2, 0, 2, 3];
    let times = [0.0f32, 1.0, 2.0];
    let half = std::f32::consts::FRAC_PI_4;
    let rotations = [0.0f32, 0.0, 0.0, 1.0, 0.0, half.sin(), 0.0, half.cos(), 0.0, 1.0, 0.0, 0.0];
    let translations = [0.0f32, 1.0, 0.0, 0.5, 1.5, 0.0, 0.0, 2.0, -1.0];
    let weights = [0.0f32, 1.0, 0.0];
    let views_of = [
        push(&mut bytes, floats(&sphere)),
        push(&mut bytes, indices(&sphere_indices)),
        push(&mut bytes, floats(&ground)),
        push(&mut bytes, indices(&quad_indices)),
        push(&mut bytes, floats(&quad)),
        push(&mut bytes, floats(&target)),
        push(&mut bytes, floats(&times)),
        push(&mut bytes, floats(&rotations)),
        push(&mut bytes, floats(&translations)),
        push(&mut bytes, floats(&weights)),
    ];
    let vec3 = |view: usize, count: usize, min: [f32; 3], max: [f32; 3]| {
        serde_json::json!({"bufferView": views_of[view], "componentType": 5126, "count": count, "type": "VEC3",
            "min": min, "max": max})
    };
    let accessors = serde_json::json!([
        vec3(0, vertices.len(), [-1.0; 3], [1.0; 3]),
        {"bufferView": views_of[1], "componentType": 5125, "count": sphere_indices.len(), "type": "SCALAR"},
        vec3(2, 4, [-6.0, -1.0, -6.0], [6.0, -1.0, 6.0]),
        {"bufferView": views_of[3], "componentType": 5125, "count": 6, "type": "SCALAR"},
        vec3(4, 4, [3.0, 0.0, 3.0], [4.0, 1.0, 3.0]),
        vec3(5, 4, [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        {"bufferView": views_of[6], "componentType": 5126, "count": 3, "type": "SCALAR", "min": [0.0], "max": [2.0]},
        {"bufferView": views_of[7], "componentType": 5126, "count": 3, "type": "VEC4"},
        {"bufferView": views_of[8], "componentType": 5126, "count": 3, "type": "VEC3"},
        {"bufferView": views_of[9], "componentType": 5126, "count": 3, "type": "SCALAR"},
    ]);
    let uri = format!("data:application/octet-stream;base64,{}", base64_of(&bytes));
    let gltf = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": roots}],
        "nodes": [
            {"mesh": 1},
            {"translation": [0.0, 1.0, 0.0], "children": [2, 3]},
            {"mesh": 0, "translation": [2.0, 0.0, 0.0]},
            {"mesh": 0, "translation": [-2.0, 0.0, 0.0], "scale": [0.5, 0.5, 0.5]},
            {"mesh": 0, "translation": [0.0, 0.0, -4.0]},
            {"mesh": 2, "weights": [0.0]},
        ],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]},
            {"primitives": [{"attributes": {"POSITION": 2}, "indices": 3}]},
            {"primitives": [{"attributes": {"POSITION": 4}, "indices": 3, "targets": [{"POSITION": 5}]}]},
        ],
        "animations": [{"name": "Swing",
            "samplers": [
                {"input": 6, "output": 7, "interpolation": "LINEAR"},
                {"input": 6, "output": 8, "interpolation": "STEP"},
                {"input": 6, "output": 9, "interpolation": "LINEAR"},
            ],
            "channels": [
                {"sampler": 0, "target": {"node": 1, "path": "rotation"}},
                {"sampler": 1, "target": {"node": 1, "path": "translation"}},
                {"sampler": 2, "target": {"node": 5, "path": "weights"}},
            ]}],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bytes.len(), "uri": uri}],
    });
    let path = dir.join("swing.gltf");
    std::fs::write(&path, serde_json::to_vec(&gltf).unwrap()).unwrap();
    path
}

/// The asset at `pose` (else in its default pose), imported flattened: every triangle in world space (f64) with
/// its source id in that import, and its source ranges.
fn flattened_at(asset: &Path, pose: Option<&PoseSelector>) -> (Vec<Placed>, Vec<SourceRange>) {
    let options = ImportOptions {
        pose: pose.cloned(),
        instancing: Instancing::Never,
        keep_degenerate: true,
        ..Default::default()
    };
    let soup = import(asset, &options).unwrap().soup;
    let placed = (0..soup.triangles.len())
        .map(|t| Placed {
            vertices: soup.vertices(t).map(|v| v.map(f64::from)),
            instance: 0,
            source_id: soup.source_ids[t],
        })
        .collect();
    (placed, soup.sources)
}

/// The flattened import's source id of the file's hit on record id `id` through instance `instance`: the same
/// node (an instanced mesh's range names none: its instance's node), mesh, primitive and triangle.
fn flattened_id(view: &BvhView<'_>, flattened: &[SourceRange], id: u32, instance: u32) -> u32 {
    let range = view.source_range_of(id).expect("the id's range");
    let placement = view.two_level().and_then(|s| s.placement(instance)).map(|(record, _)| *record);
    let (node, gpu) = match (range.node_index, placement) {
        (NO_INDEX, Some(record)) => (record.node_index, record.gpu_instance_index),
        _ => (range.node_index, range.instance_index),
    };
    let key = |r: &SourceRange| (r.node_index, r.mesh_index, r.primitive_index, r.instance_index);
    let same = flattened
        .iter()
        .find(|r| key(r) == (node, range.mesh_index, range.primitive_index, gpu))
        .unwrap_or_else(|| panic!("no flattened range for node {node}, mesh {}", range.mesh_index));
    same.first_source_triangle + (id - range.first_source_triangle)
}

/// `file` refit to `asset` at each of `seconds` of `clip` traces as the oracle over the flattened import at
/// that time says, on every kernel; returns the hits checked.
fn check_poses(file: &BvhFile, asset: &Path, clip: usize, seconds: &[f64]) -> usize {
    let pose = |at: f64| PoseSelector { clip: ClipSelector::Index(clip), seconds: at };
    seconds.iter().enumerate().map(|(k, &at)| check_pose(file, asset, Some(&pose(at)), 300 + k as u64)).sum()
}

/// `file` refit to `asset` (at `pose`, else in its default pose) traces as the oracle over the asset imported
/// flattened says, on every kernel; returns the hits checked.
fn check_pose(file: &BvhFile, asset: &Path, pose: Option<&PoseSelector>, seed: u64) -> usize {
    let at = pose.map_or(-1.0, |p| p.seconds);
    let placed_pose = bvhc::posed::placed_pose(&file.view(), asset, &Default::default(), pose).unwrap();
    let mut moved = BvhFile::from_bytes(file.as_bytes()).unwrap();
    placed_pose.apply(&mut moved, 2).unwrap();
    let (placed, ranges) = flattened_at(asset, pose);
    let rays = test_rays(&placed, 1500, seed);
    let view = moved.view();
    let mut checked = 0;
    for tracer in every_kernel(&view) {
        for (r, ray) in rays.iter().enumerate() {
            let got = tracer.closest_hit(ray);
            assert_eq!(tracer.any_hit(ray), got.is_some(), "{at} s ray {r}: any hit and closest hit disagree");
            match oracle(&placed, ray) {
                Expected::Ambiguous => {}
                Expected::Miss => assert_eq!(got, None, "{at} s ray {r} {ray:?}: the oracle sees no triangle"),
                Expected::Hit { t, source_id, .. } => {
                    let hit = got.unwrap_or_else(|| panic!("{at} s ray {r} {ray:?}: missed id {source_id}"));
                    let id = hit.source_triangle_id.unwrap();
                    let instance = hit.instance_index.unwrap_or(0);
                    assert_eq!(flattened_id(&view, &ranges, id, instance), source_id, "{at} s ray {r}");
                    let o = ray.origin.iter().fold(0.0f64, |m, c| m.max(f64::from(c.abs())));
                    let d = ray.direction.iter().fold(0.0f64, |m, c| m.max(f64::from(c.abs())));
                    let error = (f64::from(hit.t) - t).abs() / (t + o / d);
                    assert!(error <= T_TOLERANCE, "{at} s ray {r}: t {} against {t}", hit.t);
                    checked += 1;
                }
            }
        }
    }
    checked
}

#[test]
fn a_shared_mesh_exported_with_moved_vertices_is_refit_in_its_instances() {
    let dir = tempfile::tempdir().unwrap();
    // One grid mesh placed by two nodes (one mirrored), stored once; the asset exported again with the grid lifted.
    let rest = crate::cli_refit::grid_gltf(dir.path(), "rest", 0.05);
    let lifted = crate::cli_refit::grid_gltf(dir.path(), "lifted", 0.6);
    let file = convert(&rest, &dir.path().join("grid.bvh"), &["--instancing", "always", "--no-splits"]);
    assert_eq!(file.view().two_level().unwrap().instances.len(), 2);
    assert!(check_pose(&file, &lifted, None, 41) > 500);
    assert!(check_pose(&file, &rest, None, 42) > 500);
}

#[test]
fn rigidly_animated_meshes_stay_instanced_and_trace_right_at_every_pose() {
    let dir = tempfile::tempdir().unwrap();
    let asset = swinging_scene(dir.path());
    let file = convert(
        &asset,
        &dir.path().join("swing.bvh"),
        &["--animation", "--animation-poses", "4", "--instancing", "always"],
    );
    let view = file.view();
    view.verify().unwrap();
    let sections = view.two_level().expect("a two-level file");
    // Mesh 0: the ground and the morphing quad, flattened; mesh 1: the icosphere, placed by nodes 2, 3 and 4.
    assert_eq!(sections.meshes.len(), 2);
    let nodes: Vec<u32> = sections.instances.iter().map(|i| i.node_index).collect();
    assert_eq!(nodes, [NO_INDEX, 2, 3, 4]);
    let metadata = crate::common::assert_metadata_matches_schema(&file);
    let record = &metadata["animation"];
    assert_eq!(record["moving_instances"], serde_json::json!([{"instance": 1, "node": 2}, {"instance": 2, "node": 3}]));
    assert_eq!(record["poses"].as_array().unwrap().len(), 4, "mesh 0 deforms: its poses' costs");
    assert!(record["worst_cost_ratio"].as_f64().unwrap() > 1.0);
    // Applying a pose leaves the instanced mesh's trees untouched (its records are rigid; only its instances
    // move): a mark scribbled on its root box survives, while the flattened mesh's root is refit.
    let mut marked = BvhFile::from_bytes(file.as_bytes()).unwrap();
    let (flat_root, rigid_root) = (sections.meshes[0].first_node as usize, sections.meshes[1].first_node as usize);
    marked.edit().unwrap().nodes[rigid_root].min[0] -= 0.25;
    marked.edit().unwrap().nodes[flat_root].min[0] -= 0.25;
    let pose = PoseSelector { clip: ClipSelector::Index(0), seconds: 1.0 };
    let placed = bvhc::posed::placed_pose(&view, &asset, &Default::default(), Some(&pose)).unwrap();
    placed.apply(&mut marked, 1).unwrap();
    let nodes = marked.view().nodes().to_vec();
    assert_eq!(nodes[rigid_root].min[0], view.nodes()[rigid_root].min[0] - 0.25, "the rigid mesh's tree untouched");
    assert!(nodes[flat_root].min[0] > view.nodes()[flat_root].min[0] - 0.25, "the flattened mesh's tree refit");
    // The sampled times, times between them, a STEP key, and past the clip's end (clamped to its last key).
    let checked = check_poses(&file, &asset, 0, &[0.25, 0.75, 1.0, 1.25, 1.6, 1.75, 0.0, 3.0]);
    assert!(checked > 4000, "{checked} hits checked");
    // By default (`--instancing auto`, which leaves the small sphere flattened) and with `never`: one level, the
    // moving meshes flattened and refit like the rest.
    let auto = convert(&asset, &dir.path().join("auto.bvh"), &["--animation"]);
    assert!(auto.view().two_level().is_none());
    let flat = convert(&asset, &dir.path().join("flat.bvh"), &["--animation", "--instancing", "never"]);
    assert_eq!(flat.view().triangles().len(), auto.view().triangles().len(), "auto flattens it as never does");
    assert!(flat.view().two_level().is_none());
    let metadata = crate::common::assert_metadata_matches_schema(&flat);
    assert!(metadata["animation"].get("moving_instances").is_none());
    assert!(check_poses(&flat, &asset, 0, &[0.6, 1.6]) > 1000);
    assert!(check_poses(&auto, &asset, 0, &[1.1]) > 500);
}

#[test]
fn the_cli_refits_a_two_level_animation_file_as_the_library_does() {
    let dir = tempfile::tempdir().unwrap();
    let asset = swinging_scene(dir.path());
    let path = dir.path().join("swing.bvh");
    let file = convert(&asset, &path, &["--animation", "--instancing", "always"]);
    let output = dir.path().join("posed.bvh");
    let run = bvhc(&[&"refit", &path, &"--positions", &asset, &"--pose", &"Swing@1.3", &"-o", &output]);
    let stdout = String::from_utf8_lossy(&run.stdout).into_owned();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert!(stdout.contains("triangle records and 3 instances refit"), "{stdout}");
    let written = BvhFile::read(&output).unwrap();
    written.view().verify().unwrap();
    let pose = PoseSelector { clip: ClipSelector::Name("Swing".into()), seconds: 1.3 };
    let placed = bvhc::posed::placed_pose(&file.view(), &asset, &Default::default(), Some(&pose)).unwrap();
    let mut moved = BvhFile::from_bytes(file.as_bytes()).unwrap();
    placed.apply(&mut moved, 1).unwrap();
    let shipped = placed.rewritten(&moved.view()).unwrap();
    assert!(shipped.as_bytes() == written.as_bytes(), "the CLI writes the library's refit");
    // The metadata says where the records came from (spec 5.5 `refit`), while `inputs` keeps the conversion's.
    let metadata = crate::common::assert_metadata_matches_schema(&written);
    let hash = bvhc::convert::files::content_hash(&std::fs::read(&asset).unwrap());
    let name = asset.file_name().unwrap().to_str().unwrap();
    assert_eq!(metadata["refit"]["inputs"][0], serde_json::json!({"file_name": name, "content_hash": hash}));
    assert_eq!(metadata["refit"]["pose"], serde_json::json!({"clip": {"name": "Swing"}, "seconds": 1.3}));
    assert_eq!(metadata["inputs"], crate::common::assert_metadata_matches_schema(&file)["inputs"]);
    // One-level callers of record_positions are told what a two-level file needs.
    let error = bvhc::posed::record_positions(&file.view(), &asset, &Default::default(), None).unwrap_err();
    assert!(error.to_string().contains("placed_pose"), "{error}");
}

#[test]
fn the_milk_trucks_wheels_turn_as_instances() {
    let Some(asset) = crate::common::scene("khr-cesium-milk-truck/CesiumMilkTruck.gltf") else { return };
    let dir = tempfile::tempdir().unwrap();
    let file = convert(
        &asset,
        &dir.path().join("truck.bvh"),
        &["--animation", "--animation-poses", "4", "--instancing", "always"],
    );
    let sections = file.view().two_level().expect("a two-level file");
    let metadata = crate::common::assert_metadata_matches_schema(&file);
    let moving = metadata["animation"]["moving_instances"].as_array().unwrap();
    let wheel_nodes: Vec<u64> = moving.iter().map(|m| m["node"].as_u64().unwrap()).collect();
    assert_eq!(wheel_nodes, [0, 2], "the wheels' nodes");
    assert_eq!(sections.instances.len(), 3);
    let checked = check_poses(&file, &asset, 0, &[0.1, 0.4, 0.77, 1.2]);
    assert!(checked > 2000, "{checked} hits checked");
}

#[test]
fn a_scene_whose_every_mesh_is_instanced_records_only_its_moving_instances() {
    let dir = tempfile::tempdir().unwrap();
    // The arm and the still icosphere only: nothing flattened, nothing deformed.
    let asset = swinging_scene_of(dir.path(), &[1, 4]);
    let file = convert(&asset, &dir.path().join("rigid.bvh"), &["--animation", "--instancing", "always"]);
    let sections = file.view().two_level().expect("a two-level file");
    assert_eq!(sections.meshes.len(), 1);
    let metadata = crate::common::assert_metadata_matches_schema(&file);
    let record = &metadata["animation"];
    assert!(record.get("poses").is_none() && record.get("worst_cost_ratio").is_none(), "{record}");
    assert_eq!(record["moving_instances"], serde_json::json!([{"instance": 0, "node": 2}, {"instance": 1, "node": 3}]));
    let info = bvhc(&[&"info", &dir.path().join("rigid.bvh")]);
    let info = String::from_utf8_lossy(&info.stdout).into_owned();
    assert!(info.contains("2 instances moving (nodes 2, 3); nothing flattened deforms"), "{info}");
    assert!(check_poses(&file, &asset, 0, &[0.3, 1.4]) > 1000);
}

#[test]
fn a_pose_that_no_instance_can_hold_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let asset = swinging_scene(dir.path());
    let before = convert(&asset, &dir.path().join("before.bvh"), &["--animation", "--instancing", "always"]);
    // The arm also scaled by its translation keys (STEP): [0, 1, 0] for the first second, a singular transform
    // that no instance can hold, so its placements would be flattened at those poses.
    let mut gltf: serde_json::Value = serde_json::from_slice(&std::fs::read(&asset).unwrap()).unwrap();
    let clip = &mut gltf["animations"][0];
    clip["samplers"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"input": 6, "output": 8, "interpolation": "STEP"}));
    clip["channels"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"sampler": 3, "target": {"node": 1, "path": "scale"}}));
    std::fs::write(&asset, serde_json::to_vec(&gltf).unwrap()).unwrap();
    let output = dir.path().join("collapsing.bvh");
    let run = bvhc(&[&asset, &"-o", &output, &"-q", &"--animation", &"--instancing", &"always"]);
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    assert!(!run.status.success(), "refused");
    assert!(stderr.contains("clip 0 at 0.125 s places the scene's primitives otherwise"), "{stderr}");
    assert!(stderr.contains("convert with --instancing never"), "{stderr}");
    assert!(!output.exists(), "nothing written");
    let flat = convert(&asset, &output, &["--animation", "--instancing", "never"]);
    assert!(flat.view().two_level().is_none());
    // Posing the file converted before the change at such a time is refused too, naming what differs.
    let pose = PoseSelector { clip: ClipSelector::Index(0), seconds: 0.5 };
    let error = bvhc::posed::placed_pose(&before.view(), &asset, &Default::default(), Some(&pose)).unwrap_err();
    assert!(error.to_string().contains("topology differs"), "{error}");
}
