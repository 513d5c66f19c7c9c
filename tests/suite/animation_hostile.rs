//! Hostile animation, skin and hierarchy data (`shared/repro/README.md`, the robustness round of skins, clips,
//! poses and refit): every case is refused with an error naming the sampler, accessor, vertex or node and the
//! value, the same at each door that reads it (the library's import, `bvhc --pose`, `bvhc --animation`,
//! `bvhc refit --pose`), never a panic; a hostile accessor count is refused before it is allocated, for every
//! reader of accessors, with bounded memory (checked in a subprocess under a lowered address-space limit). The
//! files are made here: a two-quad strip skinned to two joints, the second turned by a clip.

use std::path::{Path, PathBuf};
use std::process::Command;

use bvhc::import::{ClipSelector, ErrorKind, ImportOptions, PoseSelector, animation_clips, import};
use serde_json::{Value, json};

use crate::cli::{bvhc, stderr};

/// The data of the skinned strip, as the cases change it.
#[derive(Clone)]
pub(crate) struct Strip {
    times: Vec<f32>,
    rotations: Vec<[f32; 4]>,
    /// Per vertex (six), four joint indices and four weights.
    joints: Vec<[u8; 4]>,
    weights: Vec<[f32; 4]>,
    /// `componentType` of JOINTS_0 (5121 unsigned byte) and of WEIGHTS_0 (5126 float), and whether WEIGHTS_0
    /// is normalized; joints of another type are stored as floats, weights as unsigned bytes.
    joints_type: u32,
    weights_type: (u32, bool),
}

impl Strip {
    pub(crate) fn new() -> Strip {
        let half = std::f32::consts::FRAC_1_SQRT_2;
        Strip {
            times: vec![0.0, 1.0],
            rotations: vec![[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, half, half]],
            joints: vec![[0, 0, 0, 0], [0, 0, 0, 0], [0, 1, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0]],
            weights: vec![
                [1.0, 0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0, 0.0],
                [0.5, 0.5, 0.0, 0.0],
                [0.5, 0.5, 0.0, 0.0],
                [1.0, 0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0, 0.0],
            ],
            joints_type: 5121,
            weights_type: (5126, false),
        }
    }

    /// The glTF (its buffer beside it, `name.bin`), with `edit` applied to its JSON last.
    pub(crate) fn write(&self, dir: &Path, name: &str, edit: impl FnOnce(&mut Value)) -> PathBuf {
        let mut bin: Vec<u8> = Vec::new();
        let mut views = Vec::new();
        let mut view = |bin: &mut Vec<u8>, bytes: Vec<u8>| {
            while !bin.len().is_multiple_of(4) {
                bin.push(0);
            }
            views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len()}));
            bin.extend(bytes);
            views.len() - 1
        };
        let floats = |values: &[f32]| values.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>();
        let positions: Vec<f32> = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.0, 2.0], [1.0, 2.0]]
            .iter()
            .flat_map(|&[x, y]| [x, y, 0.0])
            .collect();
        let indices: Vec<u8> = [0u16, 1, 3, 0, 3, 2, 2, 3, 5, 2, 5, 4].iter().flat_map(|i| i.to_le_bytes()).collect();
        let joints: Vec<u8> = match self.joints_type {
            5121 => self.joints.iter().flatten().copied().collect(),
            _ => floats(&self.joints.iter().flatten().map(|&j| f32::from(j)).collect::<Vec<_>>()),
        };
        let weights: Vec<u8> = match self.weights_type.0 {
            5126 => floats(&self.weights.concat()),
            _ => self.weights.iter().flatten().map(|&w| (w * 255.0).round() as u8).collect(),
        };
        let inverse_bind: Vec<f32> = [0.0f32, -1.0]
            .iter()
            .flat_map(|&ty| [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, ty, 0.0, 1.0])
            .collect();
        let v_positions = view(&mut bin, floats(&positions));
        let v_indices = view(&mut bin, indices);
        let v_joints = view(&mut bin, joints);
        let v_weights = view(&mut bin, weights);
        let v_inverse = view(&mut bin, floats(&inverse_bind));
        let v_times = view(&mut bin, floats(&self.times));
        let v_rotations = view(&mut bin, floats(&self.rotations.concat()));
        let joints_type = if self.joints_type == 5121 { 5121 } else { 5126 };
        let mut gltf = json!({
            "asset": {"version": "2.0"},
            "scene": 0,
            "scenes": [{"nodes": [0, 1]}],
            "nodes": [
                {"mesh": 0, "skin": 0},
                {"children": [2]},
                {"translation": [0.0, 1.0, 0.0]}
            ],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "JOINTS_0": 2, "WEIGHTS_0": 3}, "indices": 1}]}],
            "skins": [{"joints": [1, 2], "inverseBindMatrices": 4}],
            "animations": [{
                "channels": [{"sampler": 0, "target": {"node": 2, "path": "rotation"}}],
                "samplers": [{"input": 5, "output": 6, "interpolation": "LINEAR"}]
            }],
            "accessors": [
                {"bufferView": v_positions, "componentType": 5126, "count": 6, "type": "VEC3", "min": [0, 0, 0], "max": [1, 2, 0]},
                {"bufferView": v_indices, "componentType": 5123, "count": 12, "type": "SCALAR"},
                {"bufferView": v_joints, "componentType": joints_type, "count": 6, "type": "VEC4"},
                {"bufferView": v_weights, "componentType": self.weights_type.0, "normalized": self.weights_type.1, "count": 6, "type": "VEC4"},
                {"bufferView": v_inverse, "componentType": 5126, "count": 2, "type": "MAT4"},
                {"bufferView": v_times, "componentType": 5126, "count": self.times.len(), "type": "SCALAR"},
                {"bufferView": v_rotations, "componentType": 5126, "count": self.rotations.len(), "type": "VEC4"}
            ],
            "bufferViews": views,
            "buffers": [{"uri": format!("{name}.bin"), "byteLength": bin.len()}]
        });
        edit(&mut gltf);
        std::fs::write(dir.join(format!("{name}.bin")), &bin).unwrap();
        let path = dir.join(format!("{name}.gltf"));
        std::fs::write(&path, serde_json::to_string(&gltf).unwrap()).unwrap();
        path
    }
}

fn posed_at(seconds: f64) -> ImportOptions {
    ImportOptions { pose: Some(PoseSelector { clip: ClipSelector::Index(0), seconds }), ..Default::default() }
}

/// The error importing `path` at `options` gives (a panic, or a success, fails the test).
fn import_error(path: &Path, options: &ImportOptions) -> bvhc::import::ImportError {
    match import(path, options) {
        Ok(_) => panic!("{} imported", path.display()),
        Err(error) => error,
    }
}

/// Every door that reads the clip refuses `path` with exit 1 and a message containing `part`: the library's
/// import at a pose and its clip list, `bvhc --pose`, `bvhc --animation`, and `bvhc refit --pose` of a file
/// converted from `clean` (the same asset before the damage).
fn refused_at_every_door(path: &Path, clean: &Path, part: &str) {
    let error = import_error(path, &posed_at(0.25));
    assert_eq!(error.kind, ErrorKind::Invalid, "{error}");
    assert!(error.to_string().contains(part), "{part:?} missing from {error}");
    let dir = path.parent().unwrap();
    let output = dir.join("out.bvh");
    for extra in [["--pose", "0@0.25"], ["--animation", "0"]] {
        let run = bvhc(&[&path, &"-o", &output, &extra[0], &extra[1]]);
        assert_eq!(run.status.code(), Some(1), "{extra:?}: {}", stderr(&run));
        assert!(stderr(&run).contains(part), "{extra:?}: {part:?} missing from {}", stderr(&run));
        assert!(!output.exists());
    }
    let converted = dir.join("clean.bvh");
    let run = bvhc(&[&clean, &"-o", &converted, &"--no-splits", &"-q"]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    let run = bvhc(&[&"refit", &converted, &"--positions", &path, &"--pose", &"0@0.25", &"-o", &output]);
    assert_eq!(run.status.code(), Some(1), "refit: {}", stderr(&run));
    assert!(stderr(&run).contains(part), "refit: {part:?} missing from {}", stderr(&run));
    assert!(!output.exists());
}

#[test]
fn keyframe_times_that_are_not_finite_or_in_order_are_refused_at_every_door() {
    let dir = tempfile::tempdir().unwrap();
    let clean = Strip::new().write(dir.path(), "clean", |_| {});
    let three =
        |times: [f32; 3]| Strip { times: times.to_vec(), rotations: vec![[0.0, 0.0, 0.0, 1.0]; 3], ..Strip::new() };
    // NaN at both ends (used to panic in the clamp), -inf first (used to read "no keyframes"), out of order.
    let cases = [
        ([f32::NAN, 0.5, f32::NAN], "animation 0 sampler 0 input accessor 5: keyframe time 0 is NaN"),
        ([f32::NEG_INFINITY, 0.5, 1.0], "keyframe time 0 is -inf, not a finite number of seconds"),
        ([0.0, 0.5, f32::INFINITY], "keyframe time 2 is inf"),
        ([0.0, 1.0, 0.5], "keyframe time 2 (0.5 s) is before keyframe 1's (1 s)"),
    ];
    for (i, (times, part)) in cases.into_iter().enumerate() {
        let path = three(times).write(dir.path(), &format!("times{i}"), |_| {});
        refused_at_every_door(&path, &clean, part);
        let error = animation_clips(&path, &ImportOptions::default()).unwrap_err();
        assert!(error.to_string().contains(part), "{error}");
    }
    // Equal neighbours are let through (the later one wins), as real exporters write them.
    let path = three([0.0, 0.5, 0.5]).write(dir.path(), "equal", |_| {});
    import(&path, &posed_at(0.5)).unwrap();
}

#[test]
fn rotation_keyframes_that_name_no_rotation_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let clean = Strip::new().write(dir.path(), "clean", |_| {});
    let nan = Strip { rotations: vec![[0.0, 0.0, 0.0, 1.0], [f32::NAN; 4]], ..Strip::new() };
    let path = nan.write(dir.path(), "nan", |_| {});
    refused_at_every_door(&path, &clean, "sampler 0 output accessor 6: value 4 (element 1, component 0) is NaN");
    let zero = Strip { rotations: vec![[0.0, 0.0, 0.0, 1.0], [0.0; 4]], ..Strip::new() };
    let path = zero.write(dir.path(), "zero", |_| {});
    refused_at_every_door(&path, &clean, "rotation keyframe 1 has length 0");
    // A NaN translation was refused before; it still is, by the same rule.
    let translation = Strip { rotations: vec![[0.0; 4]; 2], ..Strip::new() };
    let path = translation.write(dir.path(), "translation", |gltf| {
        gltf["animations"][0]["channels"][0]["target"]["path"] = json!("translation");
        gltf["accessors"][6]["type"] = json!("VEC3");
        gltf["accessors"][6]["count"] = json!(2);
    });
    let mut bytes = std::fs::read(dir.path().join("translation.bin")).unwrap();
    let at = bytes.len() - 32; // the rotations' view: its first float becomes NaN
    bytes[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    std::fs::write(dir.path().join("translation.bin"), bytes).unwrap();
    let error = import_error(&path, &posed_at(0.5));
    assert!(error.to_string().contains("output accessor 6: value 0 (element 0, component 0) is NaN"), "{error}");
}

#[test]
fn skin_weights_and_joints_are_held_to_what_gltf_allows() {
    let dir = tempfile::tempdir().unwrap();
    let clean = Strip::new().write(dir.path(), "clean", |_| {});
    let with_weight = |vertex: usize, weights: [f32; 4]| {
        let mut strip = Strip::new();
        strip.weights[vertex] = weights;
        strip
    };
    let cases = [
        (with_weight(3, [f32::NAN, 0.5, 0.0, 0.0]), "WEIGHTS_0 accessor 3: vertex 3 weight 0 is NaN"),
        (with_weight(2, [0.5, -0.25, 0.0, 0.0]), "WEIGHTS_0 accessor 3: vertex 2 weight 1 is -0.25"),
        (with_weight(4, [0.0; 4]), "vertex 4: its weights (WEIGHTS_0 accessor 3) sum to 0, so no joint moves it"),
        (Strip { joints_type: 5126, ..Strip::new() }, "JOINTS_0 accessor 2: componentType F32"),
        (Strip { weights_type: (5121, false), ..Strip::new() }, "WEIGHTS_0 accessor 3: componentType U8"),
    ];
    for (i, (strip, part)) in cases.into_iter().enumerate() {
        let path = strip.write(dir.path(), &format!("skin{i}"), |_| {});
        refused_at_every_door(&path, &clean, part);
    }
    // Weights that sum to 2 are normalized: the same pose as weights that sum to 1.
    let doubled = with_weight(2, [1.0, 1.0, 0.0, 0.0]).write(dir.path(), "doubled", |_| {});
    let normalized = with_weight(2, [0.5, 0.5, 0.0, 0.0]).write(dir.path(), "normalized", |_| {});
    let a = import(&doubled, &posed_at(0.5)).unwrap().soup.positions;
    let b = import(&normalized, &posed_at(0.5)).unwrap().soup.positions;
    assert_eq!(a, b);
    // Normalized unsigned bytes are weights glTF allows (128/255 each, normalized to a half).
    let bytes = Strip { weights_type: (5121, true), ..Strip::new() }.write(dir.path(), "bytes", |_| {});
    let c = import(&bytes, &posed_at(0.5)).unwrap().soup.positions;
    assert_eq!(c.len(), b.len());
    for (p, q) in c.iter().zip(&b) {
        assert!((0..3).all(|k| (p[k] - q[k]).abs() <= 1e-6), "{p:?} against {q:?}");
    }
}

#[test]
fn a_node_hierarchy_that_is_not_a_forest_is_refused_even_where_the_scene_does_not_reach() {
    let dir = tempfile::tempdir().unwrap();
    // Joints 1 and 2 in a cycle that the scene (node 0 only) does not reach: they used to keep their local
    // transforms and pose the mesh wrong.
    let cycle = Strip::new().write(dir.path(), "cycle", |gltf| {
        gltf["scenes"][0]["nodes"] = json!([0]);
        gltf["nodes"][2]["children"] = json!([1]);
    });
    for options in [ImportOptions::default(), posed_at(0.5)] {
        let error = import_error(&cycle, &options);
        assert!(error.to_string().contains("the node hierarchy has a cycle"), "{error}");
    }
    let run = bvhc(&[&cycle, &"-o", &dir.path().join("x.bvh")]);
    assert_eq!(run.status.code(), Some(1), "{}", stderr(&run));
    assert!(stderr(&run).contains("node 1: the node hierarchy has a cycle"), "{}", stderr(&run));
    // A node with two parents, and a child that does not exist.
    let shared = Strip::new().write(dir.path(), "shared", |gltf| {
        gltf["nodes"].as_array_mut().unwrap().push(json!({"children": [2]}));
    });
    let error = import_error(&shared, &ImportOptions::default());
    assert!(error.to_string().contains("node 2: is a child of node 1 and of node 3"), "{error}");
    let missing = Strip::new().write(dir.path(), "missing", |gltf| gltf["nodes"][2]["children"] = json!([7]));
    let error = import_error(&missing, &ImportOptions::default());
    assert!(error.to_string().contains("node 2: child 7 does not exist"), "{error}");
}

#[test]
fn a_refit_never_writes_over_its_asset_or_the_assets_buffer() {
    let dir = tempfile::tempdir().unwrap();
    let asset = Strip::new().write(dir.path(), "asset", |_| {});
    let buffer = dir.path().join("asset.bin");
    let (asset_bytes, buffer_bytes) = (std::fs::read(&asset).unwrap(), std::fs::read(&buffer).unwrap());
    let converted = dir.path().join("a.bvh");
    let run = bvhc(&[&asset, &"-o", &converted, &"--no-splits", &"-q"]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    for output in [&asset, &buffer] {
        let run = bvhc(&[&"refit", &converted, &"--positions", &asset, &"-o", output]);
        assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
        assert!(stderr(&run).contains("the output is one of the inputs"), "{}", stderr(&run));
    }
    assert_eq!(std::fs::read(&asset).unwrap(), asset_bytes);
    assert_eq!(std::fs::read(&buffer).unwrap(), buffer_bytes);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 3, "no stray file: the asset, its buffer, the file");
    // The converted file itself may be the output: a refit in place.
    let run = bvhc(&[&"refit", &converted, &"--positions", &asset, &"-o", &converted]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
}

/// Accessors of 44.7M elements without a bufferView, one for each reader of accessors: refused before they are
/// allocated, naming the accessor, within 400 MB of address space.
#[test]
fn a_hostile_count_is_refused_for_every_reader_before_it_is_allocated() {
    let dir = tempfile::tempdir().unwrap();
    const HUGE: u64 = 44_739_240;
    let huge = |gltf: &mut Value, accessor: usize| {
        let entry = &mut gltf["accessors"][accessor];
        entry.as_object_mut().unwrap().remove("bufferView");
        entry["count"] = json!(HUGE);
    };
    // (reader, the accessor made huge, the JSON's other edits, whether the clip is sampled).
    type Edit = fn(&mut Value);
    let cases: [(&str, usize, Edit, bool); 8] = [
        ("POSITION", 0, |_| {}, false),
        ("indices", 1, |_| {}, false),
        ("JOINTS_0", 2, |_| {}, false),
        ("WEIGHTS_0", 3, |_| {}, false),
        ("inverseBindMatrices", 4, |_| {}, false),
        ("sampler input", 5, |_| {}, true),
        ("sampler output", 6, |_| {}, true),
        (
            "morph target POSITION",
            7,
            |gltf| {
                let target = json!({"componentType": 5126, "count": 6, "type": "VEC3"});
                gltf["accessors"].as_array_mut().unwrap().push(target);
                gltf["meshes"][0]["primitives"][0]["targets"] = json!([{"POSITION": 7}]);
                gltf["meshes"][0]["weights"] = json!([0.5]);
            },
            false,
        ),
    ];
    let prlimit = ["/usr/bin/prlimit", "/bin/prlimit"].iter().map(PathBuf::from).find(|p| p.exists());
    if prlimit.is_none() {
        crate::skips::skipped(crate::skips::Needs::Tools, "part: the 400 MB address-space runs (no prlimit)");
    }
    for (i, (reader, accessor, edit, posed)) in cases.into_iter().enumerate() {
        let path = Strip::new().write(dir.path(), &format!("bomb{i}"), |gltf| {
            edit(gltf);
            huge(gltf, accessor);
        });
        let options = if posed { posed_at(0.5) } else { ImportOptions::default() };
        let error = import_error(&path, &options);
        assert_eq!(error.kind, ErrorKind::Limit, "{reader}: {error}");
        assert!(error.location == format!("accessor {accessor}"), "{reader}: {error}");
        assert!(error.message.contains("declares"), "{reader}: {error}");
        let Some(prlimit) = &prlimit else { continue };
        let mut command = Command::new(prlimit);
        command
            .arg("--as=400000000")
            .arg(env!("CARGO_BIN_EXE_bvhc"))
            .arg(&path)
            .arg("-o")
            .arg(dir.path().join("b.bvh"));
        if posed {
            command.args(["--pose", "0@0.5"]);
        }
        let run = command.output().unwrap();
        let message = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{reader}: {message}");
        assert!(message.contains(&format!("accessor {accessor}: declares")), "{reader}: {message}");
    }
    // EXT_mesh_gpu_instancing's attributes and sparse substitutions are readers too.
    let instanced = Strip::new().write(dir.path(), "instanced", |gltf| {
        let translations = json!({"componentType": 5126, "count": HUGE, "type": "VEC3"});
        gltf["accessors"].as_array_mut().unwrap().push(translations);
        gltf["nodes"][0]["extensions"] = json!({"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": 7}}});
        gltf["nodes"][0].as_object_mut().unwrap().remove("skin");
        gltf["extensionsUsed"] = json!(["EXT_mesh_gpu_instancing"]);
    });
    let limits = bvhc::import::ImportLimits { max_placements: u64::MAX, ..Default::default() };
    let error = import_error(&instanced, &ImportOptions { limits, ..Default::default() });
    assert!(error.kind == ErrorKind::Limit && error.location == "accessor 7", "{error}");
    let sparse = Strip::new().write(dir.path(), "sparse", |gltf| {
        gltf["accessors"][0]["sparse"] = json!({
            "count": HUGE,
            "indices": {"bufferView": 0, "componentType": 5125},
            "values": {"bufferView": 0}
        });
    });
    let error = import_error(&sparse, &ImportOptions::default());
    assert!(error.kind == ErrorKind::Limit && error.location == "accessor 0", "{error}");
}

/// A file whose accessors fit their buffers can still hold many vertices for few triangles: the vertices count
/// in the memory estimate, so a small budget refuses it before the accessors are decoded.
#[test]
fn decoded_vertices_count_in_the_memory_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let vertices = 3_000_000u64;
    let path = Strip::new().write(dir.path(), "many", |gltf| {
        gltf["accessors"][0]["count"] = json!(vertices);
        gltf["bufferViews"].as_array_mut().unwrap().push(json!({"buffer": 1, "byteLength": vertices * 12}));
        let view = gltf["bufferViews"].as_array().unwrap().len() - 1;
        gltf["accessors"][0]["bufferView"] = json!(view);
        gltf["buffers"].as_array_mut().unwrap().push(json!({"uri": "many-vertices.bin", "byteLength": vertices * 12}));
        gltf["nodes"][0].as_object_mut().unwrap().remove("skin");
    });
    // The strip's six vertices first, zeros after them.
    let mut bytes = std::fs::read(dir.path().join("many.bin")).unwrap()[..72].to_vec();
    bytes.resize((vertices * 12) as usize, 0);
    std::fs::write(dir.path().join("many-vertices.bin"), bytes).unwrap();
    let run = bvhc(&[&path, &"-o", &dir.path().join("m.bvh"), &"--max-memory", &"150M"]);
    assert_eq!(run.status.code(), Some(1), "{}", stderr(&run));
    assert!(stderr(&run).contains("69M of decoded accessors"), "{}", stderr(&run));
    let run = bvhc(&[&path, &"-o", &dir.path().join("m.bvh"), &"--max-memory", &"1G", &"-q"]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
}
