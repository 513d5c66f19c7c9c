//! `bvhc refit FILE --positions MESH -o OUTPUT`: a converted file refit to its asset exported again with moved
//! vertices gives the records a fresh conversion of the moved asset gives each triangle (glTF placements,
//! mirrored ones included, and OBJ), verifies, traces the moved triangles, equals the library's refit; another
//! topology, a file with split references or without ids is refused naming why, with nothing written.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use bvhc::loader::{BvhFile, RefitPositions};

use crate::cli::{bvhc, files_in, stderr, stdout, teapot};
use crate::common::{assert_matches_brute_force, every_kernel, random_rays};

type Triangle = [[f32; 3]; 3];

/// A wavy grid of `n` x `n` quads, its vertices moved by `lift`.
fn grid(n: usize, lift: f32) -> (Vec<[f32; 3]>, Vec<[u16; 3]>) {
    let mut positions = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
            positions.push([x, lift * (3.0 * x).sin() * (2.0 * z + 0.5).cos() + 0.1 * x * z, z]);
        }
    }
    let mut triangles = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let a = (i * (n + 1) + j) as u16;
            let (b, c, d) = (a + 1, a + n as u16 + 1, a + n as u16 + 2);
            triangles.extend([[a, c, b], [b, c, d]]);
        }
    }
    (positions, triangles)
}

/// A glTF of one grid mesh placed by two nodes (one translated and turned, one mirrored), with `lift`.
pub fn grid_gltf(dir: &Path, name: &str, lift: f32) -> PathBuf {
    let (positions, triangles) = grid(6, lift);
    let mut bin: Vec<u8> = bytemuck::cast_slice(&positions).to_vec();
    let index_offset = bin.len();
    bin.extend_from_slice(bytemuck::cast_slice(&triangles));
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let lo = positions.iter().fold([f32::INFINITY; 3], |m, p| std::array::from_fn(|a| m[a].min(p[a])));
    let hi = positions.iter().fold([f32::NEG_INFINITY; 3], |m, p| std::array::from_fn(|a| m[a].max(p[a])));
    let gltf = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [
            {"mesh": 0, "translation": [1.5, 0.0, 0.0], "rotation": [0.0, 0.38268343, 0.0, 0.9238795]},
            {"mesh": 0, "scale": [-1.0, 1.0, 1.0], "translation": [-0.5, 0.25, 0.0]}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"uri": format!("{name}.bin"), "byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": index_offset},
            {"buffer": 0, "byteOffset": index_offset, "byteLength": triangles.len() * 6}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": positions.len(), "type": "VEC3", "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5123, "count": triangles.len() * 3, "type": "SCALAR"}
        ]
    });
    std::fs::write(dir.join(format!("{name}.bin")), bin).unwrap();
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, gltf.to_string()).unwrap();
    path
}

/// Each record's vertices by its source id (the file has no split references: one record an id).
fn records_by_id(file: &BvhFile) -> HashMap<u32, Triangle> {
    let view = file.view();
    let ids = view.triangle_ids().unwrap();
    view.triangles().iter().zip(ids).map(|(t, &id)| (id, t.vertices)).collect()
}

fn convert(input: &Path, output: &Path, extra: &[&str]) {
    let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&input, &"-o", &output, &"--quiet"];
    args.extend(extra.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>));
    let run = bvhc(&args);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
}

#[test]
fn a_refit_to_a_moved_gltf_gives_each_triangle_a_fresh_conversions_positions() {
    let dir = tempfile::tempdir().unwrap();
    let rest = grid_gltf(dir.path(), "rest", 0.05);
    let moved = grid_gltf(dir.path(), "moved", 0.4);
    let (file, fresh, output) = (dir.path().join("rest.bvh"), dir.path().join("fresh.bvh"), dir.path().join("out.bvh"));
    convert(&rest, &file, &["--no-splits", "--instancing", "never"]);
    convert(&moved, &fresh, &["--no-splits", "--instancing", "never"]);
    let run = bvhc(&[&"refit", &file, &"--positions", &moved, &"-o", &output]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    assert!(stdout(&run).contains("144 triangle records refit"), "{}", stdout(&run));
    assert!(stdout(&run).contains("cost ratio"), "{}", stdout(&run));
    let refit = BvhFile::read(&output).unwrap();
    refit.view().verify().unwrap();
    // Both placements (the mirrored one's corners swapped by the importer) moved as a fresh import places them.
    assert_eq!(records_by_id(&refit), records_by_id(&BvhFile::read(&fresh).unwrap()));
    let before = BvhFile::read(&file).unwrap();
    // The metadata records the asset the records now hold (`refit`, spec 5.5: its files and their hashes, no
    // pose for the default one); `inputs` and `build` still describe the conversion.
    let metadata = crate::common::assert_metadata_matches_schema(&refit);
    let original = crate::common::assert_metadata_matches_schema(&before);
    let hash = |name: &str| bvhc::convert::files::content_hash(&std::fs::read(dir.path().join(name)).unwrap());
    let moved_inputs = serde_json::json!([
        {"file_name": "moved.gltf", "content_hash": hash("moved.gltf")},
        {"file_name": "moved.bin", "content_hash": hash("moved.bin")},
    ]);
    assert_eq!(metadata["refit"], serde_json::json!({"inputs": moved_inputs}));
    assert_eq!((&metadata["inputs"], &metadata["build"]), (&original["inputs"], &original["build"]));
    // Refit again, in place: the last refit is recorded, once; back at the conversion's own asset and pose, the
    // file records none and has its converted bytes.
    let again = dir.path().join("again.bvh");
    std::fs::copy(&output, &again).unwrap();
    let other = grid_gltf(dir.path(), "other", 0.2);
    for asset in [&other, &rest] {
        let run = bvhc(&[&"refit", &again, &"--positions", asset, &"-o", &again, &"--quiet"]);
        assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    }
    let run = bvhc(&[&"refit", &output, &"--positions", &other, &"-o", &again, &"--quiet"]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    let twice = BvhFile::read(&again).unwrap();
    let text = twice.view().metadata_str().unwrap().unwrap().to_string();
    assert_eq!(text.matches("\"refit\"").count(), 1, "{text}");
    assert_eq!(crate::common::assert_metadata_matches_schema(&twice)["refit"]["inputs"][0]["file_name"], "other.gltf");
    let run = bvhc(&[&"refit", &again, &"--positions", &rest, &"-o", &again, &"--quiet"]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    assert!(std::fs::read(&again).unwrap() == std::fs::read(&file).unwrap(), "back at the rest pose: its bytes");
    assert_eq!(refit.view().nodes().len(), before.view().nodes().len(), "the same tree");
    assert_eq!(refit.view().triangle_ids(), before.view().triangle_ids(), "the same record order");
    // The JSON report.
    let run = bvhc(&[&"refit", &file, &"--positions", &moved, &"-o", &output, &"--json"]);
    let report: serde_json::Value = serde_json::from_str(&stdout(&run)).unwrap();
    assert_eq!(report["triangle_records"], 144);
    let ratio = report["cost_ratio"].as_f64().unwrap();
    assert!(ratio > 0.0);
    assert_eq!(report["rebuild_recommended"], ratio > 1.2, "the default policy, {ratio}");
    let run = bvhc(&[&"refit", &file, &"--positions", &moved, &"-o", &output, &"--json", &"--max-cost-ratio", &"1e9"]);
    let report: serde_json::Value = serde_json::from_str(&stdout(&run)).unwrap();
    assert_eq!(report["rebuild_recommended"], false);
    let run = bvhc(&[&"refit", &file, &"--positions", &moved, &"-o", &output, &"--max-cost-ratio", &"0.5"]);
    assert_eq!(run.status.code(), Some(2), "a ratio below 1 is a usage error: {}", stderr(&run));
}

#[test]
fn a_refit_to_a_moved_obj_equals_the_librarys_and_traces_the_moved_triangles() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("teapot.bvh");
    convert(&teapot(), &file, &["--no-splits"]);
    // Every `v` line moved by a smooth function (faces untouched).
    let text = std::fs::read_to_string(teapot()).unwrap();
    let bend = |[x, y, z]: [f32; 3]| [x + 0.1 * y * y, y * 1.2, z - 0.05 * x * y];
    let mut moved_text = String::new();
    for line in text.lines() {
        match line.strip_prefix("v ") {
            Some(rest) => {
                let v: Vec<f32> = rest.split_whitespace().map(|c| c.parse().unwrap()).collect();
                let [x, y, z] = bend([v[0], v[1], v[2]]);
                moved_text.push_str(&format!("v {x} {y} {z}\n"));
            }
            None => moved_text.push_str(&format!("{line}\n")),
        }
    }
    let moved = dir.path().join("moved.obj");
    std::fs::write(&moved, &moved_text).unwrap();
    // Written over the file itself.
    let run = bvhc(&[&"refit", &file, &"--positions", &moved, &"-o", &file, &"--quiet"]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    assert_eq!(stdout(&run), "");
    let refit = BvhFile::read(&file).unwrap();
    refit.view().verify().unwrap();
    // The library's refit to the positions a fresh import gives, rewritten: the same bytes.
    let rest = dir.path().join("rest.bvh");
    convert(&teapot(), &rest, &["--no-splits"]);
    let mut library = BvhFile::read(&rest).unwrap();
    let placed = bvhc::posed::placed_pose(&library.view(), &moved, &Default::default(), None).unwrap();
    library.refit(RefitPositions::Triangles(&placed.positions), 1).unwrap();
    assert!(placed.rewritten(&library.view()).unwrap().as_bytes() == refit.as_bytes(), "the CLI and the library");
    // The hits are the moved triangles'.
    let moved_triangles: Vec<Triangle> = refit.view().triangles().iter().map(|t| t.vertices).collect();
    let rays = random_rays(5, 1500, 6.0);
    let ids: Vec<u32> = (0..moved_triangles.len() as u32).collect();
    for tracer in every_kernel(&refit.view()) {
        assert!(assert_matches_brute_force(&tracer, &moved_triangles, &rays, &ids) > 50);
    }
}

#[test]
fn what_refit_cannot_take_is_refused_naming_why_with_nothing_written() {
    let dir = tempfile::tempdir().unwrap();
    let rest = grid_gltf(dir.path(), "rest", 0.05);
    let file = dir.path().join("rest.bvh");
    convert(&rest, &file, &["--no-splits", "--instancing", "never"]);
    let output = dir.path().join("out.bvh");
    let refused = |file: &Path, positions: &Path, expected: &str| {
        let run = bvhc(&[&"refit", &file, &"--positions", &positions, &"-o", &output]);
        assert_eq!(run.status.code(), Some(1), "{}", stderr(&run));
        assert!(stderr(&run).contains(expected), "expected {expected:?} in {}", stderr(&run));
        assert!(!output.exists(), "nothing written");
    };
    // One triangle fewer: the source range's count differs.
    let (positions, mut triangles) = grid(6, 0.3);
    triangles.pop();
    let obj = dir.path().join("fewer.obj");
    let mut text: String = positions.iter().map(|v| format!("v {} {} {}\n", v[0], v[1], v[2])).collect();
    text.extend(triangles.iter().map(|t| format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1)));
    std::fs::write(&obj, &text).unwrap();
    let grid_file = dir.path().join("grid.bvh");
    let (_, all) = grid(6, 0.3);
    let mut full: String = positions.iter().map(|v| format!("v {} {} {}\n", v[0], v[1], v[2])).collect();
    full.extend(all.iter().map(|t| format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1)));
    let full_obj = dir.path().join("grid.obj");
    std::fs::write(&full_obj, &full).unwrap();
    convert(&full_obj, &grid_file, &["--no-splits"]);
    refused(&grid_file, &obj, "72 triangles from id 0 in the file but mesh 0, 71 triangles");
    // The same count, one triangle's corners turned: its vertices differ.
    let turned: String = full.replacen("f 1 8 2", "f 8 2 1", 1);
    assert_ne!(turned, full);
    let turned_obj = dir.path().join("turned.obj");
    std::fs::write(&turned_obj, turned).unwrap();
    refused(&grid_file, &turned_obj, "triangle 0 has the vertices");
    // The glTF asset against the OBJ's file: other primitives.
    refused(&grid_file, &rest, "the file has 1 source ranges (primitives placed), the asset 2");
    // A file with split references refits each reference to its whole triangle (tests/suite/refit.rs); without
    // ids, refused.
    let split = dir.path().join("split.bvh");
    convert(&teapot(), &split, &["--split-budget", "1"]);
    assert!(BvhFile::read(&split).unwrap().view().has_split_references());
    let split_out = dir.path().join("split-out.bvh");
    let run = bvhc(&[&"refit", &split, &"--positions", &teapot(), &"-o", &split_out]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    BvhFile::read(&split_out).unwrap().view().verify().unwrap();
    std::fs::remove_file(&split_out).unwrap();
    let bare = dir.path().join("bare.bvh");
    convert(&full_obj, &bare, &["--no-splits", "--no-ids"]);
    refused(&bare, &full_obj, "no triangle ids");
    // A two-level file takes its records in their meshes' spaces and its instances where the asset's nodes
    // stand: refit to its own asset, it verifies and holds its bytes; against the OBJ, other primitives.
    let two_level = dir.path().join("two-level.bvh");
    convert(&rest, &two_level, &["--no-splits", "--instancing", "always"]);
    let original = BvhFile::read(&two_level).unwrap();
    assert!(original.view().two_level().is_some());
    let two_level_out = dir.path().join("two-level-out.bvh");
    let run = bvhc(&[&"refit", &two_level, &"--positions", &rest, &"-o", &two_level_out]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    assert!(
        String::from_utf8_lossy(&run.stdout).contains("instances refit"),
        "{}",
        String::from_utf8_lossy(&run.stdout)
    );
    let refit_two_level = BvhFile::read(&two_level_out).unwrap();
    refit_two_level.view().verify().unwrap();
    assert!(refit_two_level.as_bytes() == original.as_bytes(), "refit to its own pose, the same bytes");
    std::fs::remove_file(&two_level_out).unwrap();
    refused(&two_level, &full_obj, "source range 0 is mesh 0, primitive 0");
    assert!(
        !files_in(dir.path()).iter().any(|n| n.contains(".tmp") || n.starts_with(".bvhc")),
        "{:?}",
        files_in(dir.path())
    );
}
