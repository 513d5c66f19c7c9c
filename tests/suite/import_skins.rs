//! glTF skins and morph targets imported as glTF 2.0 says (sections 3.7.3, 3.8): every triangle corner the
//! importer places equals, within float rounding, an independent posing written here in f64 over the `gltf`
//! crate's reader (not the importer's raw-JSON decoder): morph targets by the node's or mesh's default weights,
//! then linear-blend skinning by every influence set with the inverse bind matrices, the skinned mesh node's own
//! transform ignored; other primitives by their node's world matrix. On the shared skinned and morphed scenes (the
//! quantized AnimatedMorphCube, which the `gltf` crate does not read, rests at weight 0: its posed weights are
//! checked by the pose tests), and on a hand-made tiny skin whose answers are worked out by hand: a sparse morph
//! target, node weights over mesh weights, two influence sets of normalized bytes, a node transform ignored.

use std::path::Path;

use bvhc::import::{ClipSelector, ImportOptions, Instancing, PoseSelector, import};
use glam::{DMat4, DQuat, DVec3};

use crate::common::scene;
use crate::gltf_pose::{TestPose, expected_positions, read_gltf};

/// Imports `path` flattened and checks every stored corner against [`expected_positions`]; returns the number
/// of corners checked and the largest difference over the scene's extent.
pub fn check_scene(path: &Path, pose: Option<(usize, f64)>) -> (usize, f64) {
    let selector = pose.map(|(clip, seconds)| PoseSelector { clip: ClipSelector::Index(clip), seconds });
    let options =
        ImportOptions { keep_degenerate: true, instancing: Instancing::Never, pose: selector, ..Default::default() };
    let imported = import(path, &options).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let soup = &imported.soup;
    let (document, buffers) = read_gltf(path);
    let test_pose = match pose {
        Some((clip, seconds)) => TestPose::at(&document, &buffers, clip, seconds),
        None => TestPose::rest(&document),
    };
    let world = test_pose.world(&document);
    let mut expected: std::collections::HashMap<(u32, u32, u32), Vec<DVec3>> = std::collections::HashMap::new();
    for node in document.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        for primitive in mesh.primitives() {
            let key = (node.index() as u32, mesh.index() as u32, primitive.index() as u32);
            expected.insert(key, expected_positions(&node, &primitive, &buffers, &world, &test_pose));
        }
    }
    let extent = soup.positions.iter().flatten().fold(0.0f64, |m, &c| m.max(f64::from(c).abs())).max(1e-30);
    let (mut checked, mut worst) = (0, 0.0f64);
    for t in 0..soup.triangles.len() {
        let range = soup.source_of(soup.source_ids[t]).unwrap();
        let key = (range.node_index, range.mesh_index, range.primitive_index);
        let positions = expected.get(&key).unwrap_or_else(|| panic!("{}: no primitive {key:?}", path.display()));
        for (corner, &index) in soup.vertices(t).iter().zip(&soup.source_vertices[t]) {
            let want = positions[index as usize];
            let got = DVec3::from_array(corner.map(f64::from));
            worst = worst.max((got - want).abs().max_element() / extent);
            checked += 1;
        }
    }
    (checked, worst)
}

#[test]
fn skinned_and_morphed_shared_scenes_are_posed_as_gltf_says() {
    for name in [
        "khr-brainstem/BrainStem.gltf",
        "khr-fox/Fox.gltf",
        "khr-cesium-man/CesiumMan.gltf",
        "khr-rigged-figure/RiggedFigure.gltf",
        "khr-simple-skin/SimpleSkin.gltf",
        "khr-morph-stress-test/MorphStressTest.gltf",
    ] {
        let Some(path) = scene(name) else { continue };
        let (checked, worst) = check_scene(&path, None);
        eprintln!("{name}: {checked} corners, largest difference {worst:e} of the extent");
        assert!(checked > 0, "{name}: nothing imported");
        assert!(worst <= 1e-6, "{name}: a corner {worst:e} of the scene's extent from glTF's pose");
    }
}

/// A tiny skinned glTF (see the test below), its buffer beside it.
fn tiny_skin(dir: &Path) -> std::path::PathBuf {
    let mut bin: Vec<u8> = Vec::new();
    let floats = |bin: &mut Vec<u8>, values: &[f32]| bin.extend(values.iter().flat_map(|v| v.to_le_bytes()));
    floats(&mut bin, &[1.0, 0.0, 0.0, 0.0, 2.0, 0.0, 1.0, 2.0, 0.0]); // POSITION, bytes 0..36
    bin.extend([0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0]); // JOINTS_0, 36..48
    bin.extend([255, 0, 0, 0, 255, 0, 0, 0, 255, 0, 0, 0]); // WEIGHTS_0 (normalized), 48..60
    bin.extend([0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0]); // JOINTS_1, 60..72
    bin.extend([0, 0, 0, 0, 0, 0, 0, 0, 255, 0, 0, 0]); // WEIGHTS_1 (normalized), 72..84
    let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let mut down = identity;
    down[13] = -1.0; // translation (0, -1, 0), column-major
    floats(&mut bin, &identity); // inverse bind matrices, 84..212
    floats(&mut bin, &down);
    bin.extend([0, 0, 0, 0]); // sparse index (vertex 0) and padding, 212..216
    floats(&mut bin, &[0.0, 0.0, 1.0]); // sparse displacement, 216..228
    let view =
        |offset: usize, length: usize| serde_json::json!({"buffer": 0, "byteOffset": offset, "byteLength": length});
    let half = std::f32::consts::FRAC_1_SQRT_2;
    let gltf = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 3]}],
        "nodes": [
            {"children": [1]},
            {"children": [2]},
            {"translation": [0.0, 1.0, 0.0], "rotation": [0.0, 0.0, half, half]},
            {"mesh": 0, "skin": 0, "translation": [100.0, 0.0, 0.0], "weights": [1.0]}
        ],
        "skins": [{"joints": [1, 2], "inverseBindMatrices": 5}],
        "meshes": [{"weights": [0.5], "primitives": [{
            "attributes": {"POSITION": 0, "JOINTS_0": 1, "WEIGHTS_0": 2, "JOINTS_1": 3, "WEIGHTS_1": 4},
            "targets": [{"POSITION": 6}]
        }]}],
        "buffers": [{"uri": "tiny.bin", "byteLength": bin.len()}],
        "bufferViews": [view(0, 36), view(36, 12), view(48, 12), view(60, 12), view(72, 12), view(84, 128), view(212, 1), view(216, 12)],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [1.0, 2.0, 0.0]},
            {"bufferView": 1, "componentType": 5121, "count": 3, "type": "VEC4"},
            {"bufferView": 2, "componentType": 5121, "normalized": true, "count": 3, "type": "VEC4"},
            {"bufferView": 3, "componentType": 5121, "count": 3, "type": "VEC4"},
            {"bufferView": 4, "componentType": 5121, "normalized": true, "count": 3, "type": "VEC4"},
            {"bufferView": 5, "componentType": 5126, "count": 2, "type": "MAT4"},
            {"componentType": 5126, "count": 3, "type": "VEC3", "sparse": {
                "count": 1,
                "indices": {"bufferView": 6, "componentType": 5121},
                "values": {"bufferView": 7}
            }}
        ]
    });
    std::fs::write(dir.join("tiny.bin"), bin).unwrap();
    let path = dir.join("tiny.gltf");
    std::fs::write(&path, serde_json::to_vec(&gltf).unwrap()).unwrap();
    path
}

#[test]
fn a_tiny_skin_is_posed_as_worked_out_by_hand() {
    // Joint 1 at the origin; joint 2 one unit up, turned 90 degrees about z, bound unturned (inverse bind: one
    // unit down). The skinned node's translation by 100 is ignored. Vertex 0, (1, 0, 0), follows joint 1 after
    // its sparse morph target moves it by (0, 0, 1) at the node's weight 1 (the mesh's 0.5 overridden): (1, 0,
    // 1). Vertex 1, (0, 2, 0), follows joint 2: one unit above it, turned to (-1, 0, 0), placed at (-1, 1, 0).
    // Vertex 2, (1, 2, 0), weighs both joints 1:1 over two influence sets: the mean of (1, 2, 0) and (-1, 2, 0).
    let dir = tempfile::tempdir().unwrap();
    let path = tiny_skin(dir.path());
    let imported = import(&path, &ImportOptions { keep_degenerate: true, ..Default::default() }).unwrap();
    let soup = &imported.soup;
    assert_eq!(soup.triangles.len(), 1);
    let expected = [[1.0, 0.0, 1.0], [-1.0, 1.0, 0.0], [0.0, 2.0, 0.0]];
    for (corner, &index) in soup.vertices(0).iter().zip(&soup.source_vertices[0]) {
        let want: [f32; 3] = expected[index as usize];
        assert!((0..3).all(|a| (corner[a] - want[a]).abs() <= 1e-6), "vertex {index}: {corner:?}, expected {want:?}");
    }
    assert_eq!(imported.report.skinned_placements, 1);
    // Placed twice, with instancing forced: a skinned mesh is posed for each node, never shared as an instance.
    let mut gltf: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    gltf["nodes"].as_array_mut().unwrap().push(serde_json::json!({"mesh": 0, "skin": 0}));
    gltf["scenes"][0]["nodes"] = serde_json::json!([0, 3, 4]);
    std::fs::write(&path, serde_json::to_vec(&gltf).unwrap()).unwrap();
    let twice =
        import(&path, &ImportOptions { keep_degenerate: true, instancing: Instancing::Always, ..Default::default() });
    let twice = twice.unwrap();
    assert_eq!((twice.report.instanced_meshes, twice.soup.triangles.len(), twice.report.skinned_placements), (0, 2, 2));
    // The same asset through the independent posing.
    let (checked, worst) = check_scene(&path, None);
    assert_eq!(checked, 6);
    assert!(worst <= 1e-7, "{worst:e}");
}

#[test]
fn shared_scenes_posed_at_times_of_their_clips_match_the_independent_posing() {
    // Node TRS channels (LINEAR, STEP, CUBICSPLINE among these files), morph weight channels and skins, each
    // at several times: before the first keyframe, between keyframes, past the last.
    for (name, clips) in [
        ("khr-brainstem/BrainStem.gltf", 1),
        ("khr-fox/Fox.gltf", 3),
        ("khr-cesium-man/CesiumMan.gltf", 1),
        ("khr-rigged-figure/RiggedFigure.gltf", 1),
        ("khr-simple-skin/SimpleSkin.gltf", 1),
        ("khr-morph-stress-test/MorphStressTest.gltf", 3),
    ] {
        let Some(path) = scene(name) else { continue };
        for clip in 0..clips {
            for seconds in [0.0, 0.37, 1.1, 100.0] {
                let (checked, worst) = check_scene(&path, Some((clip, seconds)));
                assert!(checked > 0, "{name}: nothing imported");
                assert!(worst <= 1e-6, "{name} clip {clip} at {seconds} s: a corner {worst:e} of the extent off");
            }
        }
    }
}

#[test]
fn a_tiny_clip_is_sampled_as_worked_out_by_hand() {
    // The tiny skin with a clip: joint 2's rotation about z goes LINEARly from 0 to 90 degrees over 1 s, and the
    // morph weight steps (STEP) from 0 to 1 at 0.5 s. At 0.25 s the joint has turned 22.5 degrees and vertex 0
    // is not displaced; at 0.75 s, 67.5 degrees and displaced by (0, 0, 1).
    let dir = tempfile::tempdir().unwrap();
    let path = tiny_skin(dir.path());
    let mut gltf: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let mut bin = std::fs::read(dir.path().join("tiny.bin")).unwrap();
    let start = bin.len();
    let half = std::f32::consts::FRAC_1_SQRT_2;
    for v in [0.0f32, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, half, half, 0.0, 0.5, 0.0, 1.0] {
        bin.extend(v.to_le_bytes()); // times (0, 1), rotations (identity, 90 degrees), times (0, 0.5), weights (0, 1)
    }
    gltf["nodes"][2]["rotation"] = serde_json::json!([0.0, 0.0, 0.0, 1.0]);
    gltf["nodes"][3].as_object_mut().unwrap().remove("weights");
    gltf["buffers"][0]["byteLength"] = bin.len().into();
    let views = gltf["bufferViews"].as_array_mut().unwrap();
    let first_view = views.len();
    for (offset, length) in [(0, 8), (8, 32), (40, 8), (48, 8)] {
        views.push(serde_json::json!({"buffer": 0, "byteOffset": start + offset, "byteLength": length}));
    }
    let accessors = gltf["accessors"].as_array_mut().unwrap();
    let first = accessors.len();
    for (k, (kind, min_max)) in
        [("SCALAR", true), ("VEC4", false), ("SCALAR", true), ("SCALAR", false)].iter().enumerate()
    {
        let mut accessor =
            serde_json::json!({"bufferView": first_view + k, "componentType": 5126, "count": 2, "type": kind});
        if *min_max {
            let times = if k == 0 { [0.0, 1.0] } else { [0.0, 0.5] };
            accessor["min"] = serde_json::json!([times[0]]);
            accessor["max"] = serde_json::json!([times[1]]);
        }
        accessors.push(accessor);
    }
    gltf["animations"] = serde_json::json!([{
        "channels": [
            {"sampler": 0, "target": {"node": 2, "path": "rotation"}},
            {"sampler": 1, "target": {"node": 3, "path": "weights"}}
        ],
        "samplers": [
            {"input": first, "output": first + 1, "interpolation": "LINEAR"},
            {"input": first + 2, "output": first + 3, "interpolation": "STEP"}
        ]
    }]);
    std::fs::write(dir.path().join("tiny.bin"), bin).unwrap();
    std::fs::write(&path, serde_json::to_vec(&gltf).unwrap()).unwrap();
    for (seconds, degrees, lift) in [(0.25, 22.5f64, 0.0), (0.75, 67.5, 1.0)] {
        let pose = PoseSelector { clip: ClipSelector::Index(0), seconds };
        let imported = import(&path, &ImportOptions { keep_degenerate: true, pose: Some(pose), ..Default::default() });
        let soup = imported.unwrap().soup;
        // Joint 2 turned by `degrees` about (0, 1, 0): vertex 1 (one unit above the joint) at (-sin, 1 + cos, 0);
        // vertex 2 the mean of (1, 2, 0) and its one unit above the joint, (1, 1, 0), turned about it.
        let (s, c) = degrees.to_radians().sin_cos();
        let expected = [[1.0, 0.0, lift], [-s, 1.0 + c, 0.0], [0.5 * (1.0 + c - s), 0.5 * (3.0 + s + c), 0.0]];
        for (corner, &index) in soup.vertices(0).iter().zip(&soup.source_vertices[0]) {
            let want = expected[index as usize];
            assert!(
                (0..3).all(|a| (f64::from(corner[a]) - want[a]).abs() <= 1e-6),
                "{seconds} s, vertex {index}: {corner:?}, expected {want:?}"
            );
        }
        let (checked, worst) = check_scene(&path, Some((0, seconds)));
        assert!(checked == 3 && worst <= 1e-7, "{worst:e}");
    }
    // Clips that do not exist, by index and by name, are refused naming the clips.
    for clip in [ClipSelector::Index(1), ClipSelector::Name("Run".into())] {
        let pose = PoseSelector { clip, seconds: 0.0 };
        let error = import(&path, &ImportOptions { pose: Some(pose), ..Default::default() }).unwrap_err().to_string();
        assert!(error.contains("animation"), "{error}");
    }
}

#[test]
fn the_command_lines_pose_is_recorded_in_the_metadata_and_bad_ones_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = tiny_skin(dir.path());
    let mut gltf: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    // A clip named "Bend" that turns joint 2 (the tiny skin's buffer holds no keyframes: add two, 0 and 1 s).
    let mut bin = std::fs::read(dir.path().join("tiny.bin")).unwrap();
    let start = bin.len();
    for v in [0.0f32, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0] {
        bin.extend(v.to_le_bytes());
    }
    gltf["buffers"][0]["byteLength"] = bin.len().into();
    let views = gltf["bufferViews"].as_array_mut().unwrap();
    views.push(serde_json::json!({"buffer": 0, "byteOffset": start, "byteLength": 8}));
    views.push(serde_json::json!({"buffer": 0, "byteOffset": start + 8, "byteLength": 32}));
    let view = views.len() - 2;
    let accessors = gltf["accessors"].as_array_mut().unwrap();
    accessors.push(serde_json::json!({"bufferView": view, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0.0], "max": [1.0]}));
    accessors.push(serde_json::json!({"bufferView": view + 1, "componentType": 5126, "count": 2, "type": "VEC4"}));
    let input = accessors.len() - 2;
    gltf["animations"] = serde_json::json!([{"name": "Bend", "channels": [{"sampler": 0, "target": {"node": 2, "path": "rotation"}}],
        "samplers": [{"input": input, "output": input + 1}]}]);
    std::fs::write(dir.path().join("tiny.bin"), bin).unwrap();
    std::fs::write(&path, serde_json::to_vec(&gltf).unwrap()).unwrap();
    let output = dir.path().join("posed.bvh");
    for (pose, clip) in
        [("0@0.75", serde_json::json!({"index": 0})), ("Bend@0.75", serde_json::json!({"name": "Bend"}))]
    {
        let run = crate::cli::bvhc(&[&path, &"--pose", &pose, &"-o", &output, &"-q"]);
        assert!(run.status.success(), "{pose}: {}", String::from_utf8_lossy(&run.stderr));
        let file = bvhc::loader::BvhFile::read(&output).unwrap();
        file.view().verify().unwrap();
        let metadata = crate::common::assert_metadata_matches_schema(&file);
        assert_eq!(metadata["build"]["import"]["pose"], serde_json::json!({"clip": clip, "seconds": 0.75}), "{pose}");
    }
    // The default pose records none.
    assert!(crate::cli::bvhc(&[&path, &"-o", &output, &"-q"]).status.success());
    let metadata = crate::common::assert_metadata_matches_schema(&bvhc::loader::BvhFile::read(&output).unwrap());
    assert!(metadata["build"]["import"].get("pose").is_none());
    // `bvhc refit --pose`: the file converted at rest, refit to the asset as it stands 0.75 s into "Bend", holds
    // the records a conversion at that pose places (matched by source id).
    assert!(crate::cli::bvhc(&[&path, &"-o", &output, &"-q", &"--no-splits"]).status.success());
    let refit = dir.path().join("refit.bvh");
    let run = crate::cli::bvhc(&[&"refit", &output, &"--positions", &path, &"--pose", &"Bend@0.75", &"-o", &refit]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let pose = PoseSelector { clip: ClipSelector::Name("Bend".into()), seconds: 0.75 };
    let posed =
        import(&path, &ImportOptions { keep_degenerate: true, pose: Some(pose), ..Default::default() }).unwrap();
    let file = bvhc::loader::BvhFile::read(&refit).unwrap();
    file.view().verify().unwrap();
    let view = file.view();
    for (record, id) in view.triangles().iter().zip(view.triangle_ids().unwrap()) {
        let t = posed.soup.source_ids.iter().position(|s| s == id).unwrap();
        assert_eq!(record.vertices, posed.soup.vertices(t), "source id {id}");
    }
    // Refused: not CLIP@SECONDS, a negative time, a clip that does not exist, an OBJ.
    let refused = |input: &dyn AsRef<std::ffi::OsStr>, pose: &str, expected: &str| {
        let run = crate::cli::bvhc(&[input, &"--pose", &pose, &"-o", &output, &"-q"]);
        let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
        assert!(!run.status.success() && stderr.contains(expected), "{pose}: {stderr}");
    };
    refused(&path, "Bend", "CLIP@SECONDS");
    refused(&path, "0@-1", "a time from 0 on");
    refused(&path, "Run@1", "no animation is named 'Run'");
    let teapot = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    refused(&teapot, "0@1", "--pose is for glTF");
}

/// Accessor `index` of `gltf` decoded by hand (any component type, normalized as glTF 2.0 section 3.11 says,
/// byte stride honoured; no sparse), as f64 rows: independent of the importer's decoder and of the `gltf` crate,
/// which does not read `KHR_mesh_quantization`.
fn decode_accessor(gltf: &serde_json::Value, bin: &[u8], index: usize) -> Vec<Vec<f64>> {
    let accessor = &gltf["accessors"][index];
    let view = &gltf["bufferViews"][accessor["bufferView"].as_u64().unwrap() as usize];
    let components = match accessor["type"].as_str().unwrap() {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" => 4,
        other => panic!("type {other}"),
    };
    let kind = accessor["componentType"].as_u64().unwrap();
    let size = match kind {
        5120 | 5121 => 1,
        5122 | 5123 => 2,
        _ => 4,
    };
    let normalized = accessor["normalized"].as_bool().unwrap_or(false);
    let stride = view["byteStride"].as_u64().map_or(components * size, |s| s as usize);
    let start =
        view["byteOffset"].as_u64().unwrap_or(0) as usize + accessor["byteOffset"].as_u64().unwrap_or(0) as usize;
    (0..accessor["count"].as_u64().unwrap() as usize)
        .map(|i| {
            (0..components)
                .map(|c| {
                    let at = start + i * stride + c * size;
                    let b = &bin[at..at + size];
                    match (kind, normalized) {
                        (5120, true) => (f64::from(b[0] as i8) / 127.0).max(-1.0),
                        (5120, false) => f64::from(b[0] as i8),
                        (5121, true) => f64::from(b[0]) / 255.0,
                        (5121, false) => f64::from(b[0]),
                        (5122, true) => (f64::from(i16::from_le_bytes([b[0], b[1]])) / 32767.0).max(-1.0),
                        (5122, false) => f64::from(i16::from_le_bytes([b[0], b[1]])),
                        (5123, true) => f64::from(u16::from_le_bytes([b[0], b[1]])) / 65535.0,
                        (5123, false) => f64::from(u16::from_le_bytes([b[0], b[1]])),
                        _ => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                    }
                })
                .collect()
        })
        .collect()
}

#[test]
fn the_quantized_morph_cube_is_posed_by_its_animated_weights() {
    // AnimatedMorphCube (KHR_mesh_quantization): positions and targets as shorts, its clip's weights as
    // normalized bytes (LINEAR); node 0 (scaled by 3.6e-6, under a node turned and scaled by 100) places it.
    let Some(path) = scene("khr-animated-morph-cube-quantized/AnimatedMorphCube.gltf") else { return };
    let gltf: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let bin = std::fs::read(path.with_file_name(gltf["buffers"][0]["uri"].as_str().unwrap())).unwrap();
    let primitive = &gltf["meshes"][0]["primitives"][0];
    let base = decode_accessor(&gltf, &bin, primitive["attributes"]["POSITION"].as_u64().unwrap() as usize);
    let targets: Vec<Vec<Vec<f64>>> = primitive["targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| decode_accessor(&gltf, &bin, t["POSITION"].as_u64().unwrap() as usize))
        .collect();
    let times: Vec<f64> = decode_accessor(&gltf, &bin, 7).into_iter().map(|r| r[0]).collect();
    let weights: Vec<f64> = decode_accessor(&gltf, &bin, 8).into_iter().map(|r| r[0]).collect();
    let node = |n: usize| {
        let node = &gltf["nodes"][n];
        let v = |key: &str, default: [f64; 4]| {
            node[key]
                .as_array()
                .map_or(default, |a| std::array::from_fn(|i| a.get(i).and_then(|x| x.as_f64()).unwrap_or(0.0)))
        };
        let (t, r, s) = (v("translation", [0.0; 4]), v("rotation", [0.0, 0.0, 0.0, 1.0]), v("scale", [1.0; 4]));
        let q = DQuat::from_array(r);
        DMat4::from_scale_rotation_translation(
            DVec3::new(s[0], s[1], s[2]),
            q / q.length(),
            DVec3::new(t[0], t[1], t[2]),
        )
    };
    let world = node(1) * node(0);
    for seconds in [0.0, 0.8, 1.65, 3.3] {
        // LINEAR between the two keyframes around the time, two weights a keyframe.
        let after = times.partition_point(|&t| t <= seconds);
        let (k0, k1) = (after.saturating_sub(1), after.min(times.len() - 1));
        let s = if times[k1] > times[k0] { (seconds - times[k0]) / (times[k1] - times[k0]) } else { 0.0 };
        let w: Vec<f64> =
            (0..2).map(|i| weights[2 * k0 + i] + (weights[2 * k1 + i] - weights[2 * k0 + i]) * s).collect();
        let pose = PoseSelector { clip: ClipSelector::Index(0), seconds };
        let imported =
            import(&path, &ImportOptions { keep_degenerate: true, pose: Some(pose), ..Default::default() }).unwrap();
        let soup = imported.soup;
        let extent = soup.positions.iter().flatten().fold(0.0f64, |m, &c| m.max(f64::from(c).abs()));
        for t in 0..soup.triangles.len() {
            for (corner, &v) in soup.vertices(t).iter().zip(&soup.source_vertices[t]) {
                let v = v as usize;
                let p =
                    (0..3).map(|a| base[v][a] + w[0] * targets[0][v][a] + w[1] * targets[1][v][a]).collect::<Vec<_>>();
                let want = world.transform_point3(DVec3::new(p[0], p[1], p[2]));
                let got = DVec3::from_array(corner.map(f64::from));
                assert!((got - want).abs().max_element() <= 1e-6 * extent, "{seconds} s, vertex {v}: {got} vs {want}");
            }
        }
        assert!(w.iter().any(|&x| x > 0.0) || seconds == 0.0, "the clip moves the cube at {seconds} s");
    }
}
