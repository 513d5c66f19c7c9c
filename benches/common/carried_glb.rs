//! A rigid animation of a large mesh as a glTF asset: a still mesh at the origin (node 0) and a moving mesh
//! (node 1) that a 10-second clip ("Carry", 41 LINEAR keyframes) turns once about the vertical axis while it
//! travels along x and back, written as a GLB that the importer reads like any animated glTF. Its vertices never
//! move in its own space: only the node's transform does. (Needs `common/morphing_glb.rs` as `morphing_glb`.)

#![allow(dead_code)] // each benchmark uses the part it needs

use std::path::Path;

use crate::morphing_glb::{BinaryChunk, glb_bytes, range};

/// The clip's length in seconds.
pub const SECONDS: f64 = 10.0;
const KEYS: usize = 41;

/// A mesh: positions and triangles (vertex indices).
pub type Mesh<'a> = (&'a [[f32; 3]], &'a [[u32; 3]]);

/// Writes the GLB to `path`: `still` at the origin, `moving` turned and carried from `-travel` to `travel` along
/// x and back.
pub fn write(path: &Path, still: Mesh<'_>, moving: Mesh<'_>, travel: f32) {
    let times: Vec<f32> = (0..KEYS).map(|k| (SECONDS * k as f64 / (KEYS - 1) as f64) as f32).collect();
    let phase = |t: f32| f64::from(t) / SECONDS;
    let translations: Vec<[f32; 3]> =
        times.iter().map(|&t| [-travel * (std::f64::consts::TAU * phase(t)).cos() as f32, 0.0, 0.0]).collect();
    let rotations: Vec<[f32; 4]> = times
        .iter()
        .map(|&t| {
            let half = std::f64::consts::PI * phase(t);
            [0.0, half.sin() as f32, 0.0, half.cos() as f32]
        })
        .collect();
    let mut chunk = BinaryChunk::default();
    let floats = |v: &[f32]| v.iter().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
    let indices = |t: &[[u32; 3]]| t.iter().flatten().flat_map(|i| i.to_le_bytes()).collect::<Vec<u8>>();
    chunk.push(floats(still.0.as_flattened()));
    chunk.push(indices(still.1));
    chunk.push(floats(moving.0.as_flattened()));
    chunk.push(indices(moving.1));
    chunk.push(floats(&times));
    chunk.push(floats(translations.as_flattened()));
    chunk.push(floats(rotations.as_flattened()));
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1]}}],
"nodes":[{{"mesh":0,"name":"still"}},{{"mesh":1,"name":"carried"}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}},{{"primitives":[{{"attributes":{{"POSITION":2}},"indices":3}}]}}],
"animations":[{{"name":"Carry","channels":[{{"sampler":0,"target":{{"node":1,"path":"translation"}}}},{{"sampler":1,"target":{{"node":1,"path":"rotation"}}}}],
"samplers":[{{"input":4,"output":5,"interpolation":"LINEAR"}},{{"input":4,"output":6,"interpolation":"LINEAR"}}]}}],
"accessors":[
{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3",{}}},
{{"bufferView":1,"componentType":5125,"count":{},"type":"SCALAR"}},
{{"bufferView":2,"componentType":5126,"count":{},"type":"VEC3",{}}},
{{"bufferView":3,"componentType":5125,"count":{},"type":"SCALAR"}},
{{"bufferView":4,"componentType":5126,"count":{KEYS},"type":"SCALAR","min":[0],"max":[{SECONDS}]}},
{{"bufferView":5,"componentType":5126,"count":{KEYS},"type":"VEC3"}},
{{"bufferView":6,"componentType":5126,"count":{KEYS},"type":"VEC4"}}],
"bufferViews":[{}],"buffers":[{{"byteLength":{}}}]}}"#,
        still.0.len(),
        range(still.0),
        3 * still.1.len(),
        moving.0.len(),
        range(moving.0),
        3 * moving.1.len(),
        chunk.views.join(","),
        chunk.bin.len()
    );
    let glb = glb_bytes(&json, chunk.bin);
    std::fs::write(path, glb).expect("the GLB is written");
}
