//! OBJ and PLY details: concave polygons, negative indices, missing .mtl, groups, gzip, binary big-endian PLY,
//! triangle strips with restarts, degenerate triangles dropped or kept.

use std::io::Write;
use std::path::{Path, PathBuf};

use bvhc::import::{ImportOptions, import};

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn area(v: [[f32; 3]; 3]) -> f64 {
    let [a, b, c] = v.map(|p| p.map(f64::from));
    0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
}

const L_SHAPE: &str = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\n";

#[test]
fn obj_concave_polygons_negative_indices_groups_and_missing_mtl() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!(
        "mtllib missing.mtl\no first\n{L_SHAPE}f 1 2 3 4 5 6\ng second\nv 5 5 0\nv 6 5 0\nv 5 6 0\nf -3 -2 -1\n"
    );
    let path = write(dir.path(), "shapes.obj", text.as_bytes());
    let imported = import(&path, &ImportOptions::default()).unwrap();
    let soup = &imported.soup;
    assert_eq!(soup.triangles.len(), 5);
    assert_eq!(imported.files_read, [path], "the missing .mtl is neither read nor an error");
    // The L (area 3) is covered exactly by counter-clockwise triangles: ear clipping, not a fan.
    let l_area: f64 = (0..4).map(|t| area(soup.vertices(t))).sum();
    assert!((l_area - 3.0).abs() < 1e-9, "{l_area}");
    assert!((0..5).all(|t| area(soup.vertices(t)) > 0.0));
    let meshes: Vec<u32> = soup.sources.iter().map(|r| r.mesh_index).collect();
    assert_eq!(meshes, [0, 1], "objects and groups are separate models");
    assert_eq!(soup.vertices(4), [[5.0, 5.0, 0.0], [6.0, 5.0, 0.0], [5.0, 6.0, 0.0]], "negative indices");
}

#[test]
fn gzipped_obj_equals_plain() {
    let dir = tempfile::tempdir().unwrap();
    let text = format!("{L_SHAPE}f 1 2 3 4 5 6\n");
    let plain = write(dir.path(), "l.obj", text.as_bytes());
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    encoder.write_all(text.as_bytes()).unwrap();
    let gz = write(dir.path(), "l.obj.gz", &encoder.finish().unwrap());
    let options = ImportOptions::default();
    assert_eq!(import(&plain, &options).unwrap().soup, import(&gz, &options).unwrap().soup);
}

fn ply_header(format: &str, vertices: usize, element: &str, count: usize) -> String {
    format!(
        "ply\nformat {format} 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\nproperty float z\n\
         element {element} {count}\nproperty list uchar int vertex_indices\nend_header\n"
    )
}

#[test]
fn binary_big_endian_ply_equals_ascii() {
    let dir = tempfile::tempdir().unwrap();
    let points = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    let mut ascii = ply_header("ascii", 4, "face", 1);
    for p in &points {
        ascii += &format!("{} {} {}\n", p[0], p[1], p[2]);
    }
    ascii += "4 0 1 2 3\n";
    let mut binary = ply_header("binary_big_endian", 4, "face", 1).into_bytes();
    for p in &points {
        binary.extend(p.iter().flat_map(|c| c.to_be_bytes()));
    }
    binary.push(4);
    binary.extend([0i32, 1, 2, 3].iter().flat_map(|i| i.to_be_bytes()));
    let options = ImportOptions::default();
    let a = import(&write(dir.path(), "a.ply", ascii.as_bytes()), &options).unwrap().soup;
    let b = import(&write(dir.path(), "b.ply", &binary), &options).unwrap().soup;
    assert_eq!(a.triangles.len(), 2);
    assert_eq!(a, b);
}

#[test]
fn ply_triangle_strips_restart_at_minus_one_and_keep_their_winding() {
    let dir = tempfile::tempdir().unwrap();
    // Two strips of two triangles each over a 3 x 2 grid in z = 0, separated by -1.
    let mut text = ply_header("ascii", 6, "tristrips", 1);
    for (x, y) in [(0, 0), (0, 1), (1, 0), (1, 1), (2, 0), (2, 1)] {
        text += &format!("{x} {y} 0\n");
    }
    text += "9 0 2 1 3 -1 2 4 3 5\n";
    let soup = import(&write(dir.path(), "strip.ply", text.as_bytes()), &ImportOptions::default()).unwrap().soup;
    assert_eq!(soup.triangles.len(), 4);
    let orientations: Vec<bool> = (0..4).map(|t| area(soup.vertices(t)) > 0.0).collect();
    assert!(orientations.iter().all(|&o| o == orientations[0]), "{orientations:?}");
}

#[test]
fn degenerate_triangles_are_dropped_and_counted_or_kept() {
    let dir = tempfile::tempdir().unwrap();
    // A good triangle, a repeated index, a zero-area (collinear) one, and an unused vertex.
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 9 9 9\nf 1 2 3\nf 1 1 2\nf 1 2 4\n";
    let path = write(dir.path(), "degenerate.obj", text.as_bytes());
    let dropped = import(&path, &ImportOptions::default()).unwrap();
    assert_eq!(dropped.soup.triangles.len(), 1);
    assert_eq!((dropped.report.degenerate_repeated_index, dropped.report.degenerate_zero_area), (1, 1));
    assert_eq!(dropped.report.unreferenced_vertices, 1);
    assert_eq!(dropped.soup.positions.len(), 3, "only the vertices of kept triangles are copied");
    assert_eq!(dropped.soup.source_ids, [0]);
    let kept = import(&path, &ImportOptions { keep_degenerate: true, ..Default::default() }).unwrap();
    assert_eq!(kept.soup.triangles.len(), 3);
    assert_eq!(kept.soup.source_ids, [0, 1, 2]);
    assert_eq!(kept.report.degenerate(), 2);
}

/// A glTF whose POSITION accessor stores `components` (bytes already encoded) with the given component type,
/// normalization and byte stride, and no indices.
fn quantized_gltf(component_type: u32, normalized: bool, stride: usize, data: &[u8], count: usize) -> String {
    use base64::Engine;
    let uri = base64::engine::general_purpose::STANDARD.encode(data);
    format!(
        r#"{{"asset":{{"version":"2.0"}},"extensionsRequired":["KHR_mesh_quantization"],"extensionsUsed":["KHR_mesh_quantization"],
        "scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
        "accessors":[{{"bufferView":0,"componentType":{component_type},"normalized":{normalized},"count":{count},"type":"VEC3"}}],
        "bufferViews":[{{"buffer":0,"byteLength":{},"byteStride":{stride}}}],
        "buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{uri}"}}]}}"#,
        data.len(),
        data.len()
    )
}

#[test]
fn quantized_positions_decode_as_khr_mesh_quantization_says() {
    let dir = tempfile::tempdir().unwrap();
    let options = ImportOptions { keep_degenerate: true, ..Default::default() };
    // Signed bytes, normalized, stride 4: -128 clamps to -1, 127 is 1, 64 is 64/127.
    let bytes: Vec<u8> =
        [[-128i8, 0, 0, 0], [127, 0, 0, 0], [0, 64, 0, 0]].iter().flatten().map(|&b| b as u8).collect();
    let path = write(dir.path(), "i8.gltf", quantized_gltf(5120, true, 4, &bytes, 3).as_bytes());
    let soup = import(&path, &options).unwrap().soup;
    assert_eq!(soup.vertices(0), [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, (64.0f64 / 127.0) as f32, 0.0]]);
    // Unsigned bytes, normalized: 255 is 1.
    let bytes = [255u8, 0, 0, 0, 0, 255, 0, 0, 0, 0, 51, 0];
    let path = write(dir.path(), "u8.gltf", quantized_gltf(5121, true, 4, &bytes, 3).as_bytes());
    let soup = import(&path, &options).unwrap().soup;
    assert_eq!(soup.vertices(0), [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.2]]);
    // Signed shorts, not normalized, stride 8: the integers themselves.
    let shorts: Vec<u8> =
        [[300i16, -2, 7, 0], [0, 1, 0, 0], [-32768, 0, 0, 0]].iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    let path = write(dir.path(), "i16.gltf", quantized_gltf(5122, false, 8, &shorts, 3).as_bytes());
    let soup = import(&path, &options).unwrap().soup;
    assert_eq!(soup.vertices(0), [[300.0, -2.0, 7.0], [0.0, 1.0, 0.0], [-32768.0, 0.0, 0.0]]);
    // Unsigned shorts, normalized.
    let shorts: Vec<u8> = [[65535u16, 0, 0, 0], [0, 65535, 0, 0], [0, 0, 13107, 0]]
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let path = write(dir.path(), "u16.gltf", quantized_gltf(5123, true, 8, &shorts, 3).as_bytes());
    let soup = import(&path, &options).unwrap().soup;
    assert_eq!(soup.vertices(0), [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.2]]);
}
