//! Bad input gives an error that names the file, the part and the rule; generated files, one fault each.

use std::path::{Path, PathBuf};

use base64::Engine;
use bvhc::import::{ImportOptions, import};

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// The import error's text for a file named `name` holding `bytes`.
fn error_of(name: &str, bytes: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), name, bytes);
    let error = import(&path, &ImportOptions::default()).expect_err("must fail").to_string();
    assert!(error.contains(name), "the error names the file: {error}");
    error
}

fn assert_contains(text: &str, parts: &[&str]) {
    for part in parts {
        assert!(text.contains(part), "'{part}' missing from: {text}");
    }
}

/// A one-triangle glTF with its buffer in a data URI; `positions` as f32, `indices` as u16.
fn gltf(positions: &[f32], indices: &[u16], extra: &str) -> String {
    let mut buffer: Vec<u8> = positions.iter().flat_map(|v| v.to_le_bytes()).collect();
    let index_offset = buffer.len();
    buffer.extend(indices.iter().flat_map(|v| v.to_le_bytes()));
    let uri = base64::engine::general_purpose::STANDARD.encode(&buffer);
    format!(
        r#"{{"asset":{{"version":"2.0"}},{extra}"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3"}},
                     {{"bufferView":1,"componentType":5123,"count":{},"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{index_offset}}},
                       {{"buffer":0,"byteOffset":{index_offset},"byteLength":{}}}],
        "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{uri}"}}]}}"#,
        positions.len() / 3,
        indices.len(),
        indices.len() * 2,
        buffer.len()
    )
}

const TRIANGLE: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

#[test]
fn a_good_generated_gltf_imports() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "ok.gltf", gltf(&TRIANGLE, &[0, 1, 2], "").as_bytes());
    let imported = import(&path, &ImportOptions::default()).unwrap();
    assert_eq!(imported.soup.triangles.len(), 1);
    assert_eq!(imported.files_read, [path], "a data URI is not a file");
}

#[test]
fn gltf_faults_are_named() {
    let error = error_of("index.gltf", gltf(&TRIANGLE, &[0, 1, 5], "").as_bytes());
    assert_contains(&error, &["mesh 0 primitive 0", "indices accessor 1", "index 2 is 5", "vertex count 3"]);

    let nan = [f32::NAN, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let error = error_of("nan.gltf", gltf(&nan, &[0, 1, 2], "").as_bytes());
    assert_contains(&error, &["mesh 0 primitive 0", "POSITION accessor 0", "vertex 0 is not finite"]);

    let error = error_of("json.gltf", b"{\"asset\": {\"version\": \"2.0\"},, }");
    assert_contains(&error, &["JSON", "malformed glTF JSON", "line 1"]);

    let unknown = r#""extensionsRequired":["EXT_made_up"],"#;
    let error = error_of("ext.gltf", gltf(&TRIANGLE, &[0, 1, 2], unknown).as_bytes());
    assert_contains(&error, &["extensionsRequired", "EXT_made_up", "does not know"]);

    let draco = r#""extensionsRequired":["KHR_draco_mesh_compression"],"#;
    let error = error_of("draco.gltf", gltf(&TRIANGLE, &[0, 1, 2], draco).as_bytes());
    assert_contains(&error, &["KHR_draco_mesh_compression", "Draco", "Decompress it first"]);

    let meshopt = r#""extensionsRequired":["EXT_meshopt_compression"],"#;
    let error = error_of("meshopt.gltf", gltf(&TRIANGLE, &[0, 1, 2], meshopt).as_bytes());
    assert_contains(&error, &["EXT_meshopt_compression", "meshopt", "Decompress it"]);
}

#[test]
fn geometry_neutral_required_extensions_do_not_stop_a_conversion() {
    let dir = tempfile::tempdir().unwrap();
    let neutral =
        r#""extensionsRequired":["KHR_texture_transform","KHR_materials_emissive_strength","KHR_lights_punctual"],"#;
    let path = write(dir.path(), "neutral.gltf", gltf(&TRIANGLE, &[0, 1, 2], neutral).as_bytes());
    assert_eq!(import(&path, &ImportOptions::default()).unwrap().soup.triangles.len(), 1);
}

#[test]
fn missing_and_short_external_buffers_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let json = |byte_length: usize| {
        format!(
            r#"{{"asset":{{"version":"2.0"}},"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
            "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}}],
            "bufferViews":[{{"buffer":0,"byteLength":36}}],
            "buffers":[{{"byteLength":{byte_length},"uri":"geometry%20data.bin"}}]}}"#
        )
    };
    let path = write(dir.path(), "external.gltf", json(36).as_bytes());
    let error = import(&path, &ImportOptions::default()).unwrap_err().to_string();
    assert_contains(&error, &["external.gltf", "buffer 0", "cannot read", "geometry data.bin"]);

    write(dir.path(), "geometry data.bin", &[0u8; 20]);
    let error = import(&path, &ImportOptions::default()).unwrap_err().to_string();
    assert_contains(&error, &["buffer 0", "byteLength is 36 but only 20 bytes"]);

    let bytes: Vec<u8> = TRIANGLE.iter().flat_map(|v| v.to_le_bytes()).collect();
    write(dir.path(), "geometry data.bin", &bytes);
    let imported = import(&path, &ImportOptions::default()).unwrap();
    assert_eq!(imported.files_read, [path.clone(), dir.path().join("geometry data.bin")]);

    let path =
        write(dir.path(), "view.gltf", json(36).replace("\"byteLength\":36}]", "\"byteLength\":24}]").as_bytes());
    let error = import(&path, &ImportOptions::default()).unwrap_err().to_string();
    assert_contains(&error, &["accessor 0", "do not fit in bufferView 0"]);
}

#[test]
fn obj_faults_name_the_line() {
    let error = error_of("bad_index.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n");
    assert_contains(&error, &["line 5", "malformed OBJ"]);
    let error = error_of("bad_vertex.obj", b"v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n");
    assert_contains(&error, &["line 2", "malformed OBJ"]);
    let error = error_of("nan.obj", b"v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n");
    assert_contains(&error, &["line 3", "not finite"]);
    let error = error_of("huge.obj", b"v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n");
    assert_contains(&error, &["line 2", "not finite in f32"]);
}

#[test]
fn ply_faults_are_named() {
    let error = error_of("header.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n");
    assert_contains(&error, &["element 'vertex'", "has no x, y and z"]);
    let body = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n";
    let error = error_of("range.ply", body);
    assert_contains(&error, &["face 0", "vertex index 7 out of range (3 vertices)"]);
    let error = error_of("garbage.ply", b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nend_heade");
    assert_contains(&error, &["malformed PLY"]);
}

#[test]
fn unsupported_and_missing_files_are_named() {
    let error = error_of("scene.fbx", b"Kaydara FBX Binary");
    assert_contains(&error, &["unsupported file type", ".gltf, .glb, .obj, .ply"]);
    let error = import(Path::new("/nonexistent/scene.obj"), &ImportOptions::default()).unwrap_err().to_string();
    assert_contains(&error, &["/nonexistent/scene.obj", "cannot read"]);
    let error = error_of("broken.obj.gz", b"not gzip at all");
    assert_contains(&error, &["gzip"]);
}
