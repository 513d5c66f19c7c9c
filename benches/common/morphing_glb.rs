//! A long procedural deformation of a large mesh as a glTF asset: the mesh with two morph targets (a twist about
//! the vertical axis growing with height, and a travelling sideways wave) whose weights a 20-second clip drives
//! through 81 LINEAR keyframes (the twist swings both ways, the wave rises and falls out of step with it), written
//! as a GLB that the importer reads like any animated glTF.

#![allow(dead_code)] // each benchmark uses the part it needs

use std::path::Path;

/// The clip's length in seconds.
pub const SECONDS: f64 = 20.0;
const KEYS: usize = 81;

/// Writes the GLB of the mesh with `positions` and `triangles` (vertex indices) to `path`.
pub fn write(path: &Path, positions: &[[f32; 3]], triangles: &[[u32; 3]]) {
    let (lo, hi) = positions.iter().fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), p| {
        (std::array::from_fn(|a| lo[a].min(p[a])), std::array::from_fn(|a| hi[a].max(p[a])))
    });
    let center = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[2] + hi[2])];
    let height = (hi[1] - lo[1]).max(1e-6);
    let width = (hi[0] - lo[0]).max(hi[2] - lo[2]);
    // Target 0: a twist of 1.2 rad at the top; target 1: a wave of a fifth of the width along x.
    let twist: Vec<[f32; 3]> = positions
        .iter()
        .map(|p| {
            let angle = 1.2 * (p[1] - lo[1]) / height;
            let (x, z) = (p[0] - center[0], p[2] - center[1]);
            let (s, c) = angle.sin_cos();
            [x * c - z * s - x, 0.0, x * s + z * c - z]
        })
        .collect();
    let wave: Vec<[f32; 3]> = positions
        .iter()
        .map(|p| [0.2 * width * (std::f32::consts::TAU * (p[1] - lo[1]) / height).sin(), 0.0, 0.0])
        .collect();
    let times: Vec<f32> = (0..KEYS).map(|k| (SECONDS * k as f64 / (KEYS - 1) as f64) as f32).collect();
    let weights: Vec<f32> = times
        .iter()
        .flat_map(|&t| {
            let t = f64::from(t);
            [(t * 0.45).sin() as f32, (0.5 - 0.5 * (t * 0.7).cos()) as f32]
        })
        .collect();
    let mut chunk = BinaryChunk::default();
    let floats = |v: &[[f32; 3]]| v.iter().flatten().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
    chunk.push(floats(positions));
    chunk.push(triangles.iter().flatten().flat_map(|i| i.to_le_bytes()).collect());
    chunk.push(floats(&twist));
    chunk.push(floats(&wave));
    chunk.push(times.iter().flat_map(|f| f.to_le_bytes()).collect());
    chunk.push(weights.iter().flat_map(|f| f.to_le_bytes()).collect());
    let n = positions.len();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0,"name":"morphing"}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"targets":[{{"POSITION":2}},{{"POSITION":3}}]}}],"weights":[0,0]}}],
"animations":[{{"name":"Deform","channels":[{{"sampler":0,"target":{{"node":0,"path":"weights"}}}}],"samplers":[{{"input":4,"output":5,"interpolation":"LINEAR"}}]}}],
"accessors":[
{{"bufferView":0,"componentType":5126,"count":{n},"type":"VEC3",{}}},
{{"bufferView":1,"componentType":5125,"count":{},"type":"SCALAR"}},
{{"bufferView":2,"componentType":5126,"count":{n},"type":"VEC3",{}}},
{{"bufferView":3,"componentType":5126,"count":{n},"type":"VEC3",{}}},
{{"bufferView":4,"componentType":5126,"count":{KEYS},"type":"SCALAR","min":[0],"max":[{SECONDS}]}},
{{"bufferView":5,"componentType":5126,"count":{},"type":"SCALAR"}}],
"bufferViews":[{}],"buffers":[{{"byteLength":{}}}]}}"#,
        range(positions),
        3 * triangles.len(),
        range(&twist),
        range(&wave),
        2 * KEYS,
        chunk.views.join(","),
        chunk.bin.len()
    );
    let glb = glb_bytes(&json, chunk.bin);
    std::fs::write(path, glb).expect("the GLB is written");
}

/// An accessor's `"min"` and `"max"` keys for positions `v`.
pub fn range(v: &[[f32; 3]]) -> String {
    let (lo, hi) = v.iter().fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), p| {
        (std::array::from_fn(|a| lo[a].min(p[a])), std::array::from_fn(|a| hi[a].max(p[a])))
    });
    format!(r#""min":[{},{},{}],"max":[{},{},{}]"#, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2])
}

/// A GLB container of `json` (its line breaks dropped) and the binary chunk `bin` (4-byte aligned).
pub fn glb_bytes(json: &str, bin: Vec<u8>) -> Vec<u8> {
    let mut json = json.replace('\n', "").into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut glb = Vec::with_capacity(total);
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend((total as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(json);
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(bin);
    glb
}

/// A GLB's binary chunk and the buffer views of what it holds.
#[derive(Default)]
pub struct BinaryChunk {
    /// The bytes, each view's start 4-byte aligned.
    pub bin: Vec<u8>,
    /// Each view's JSON, in order.
    pub views: Vec<String>,
}

impl BinaryChunk {
    /// Appends `bytes` as the next buffer view.
    pub fn push(&mut self, bytes: Vec<u8>) {
        let offset = self.bin.len();
        self.views.push(format!(r#"{{"buffer":0,"byteOffset":{offset},"byteLength":{}}}"#, bytes.len()));
        self.bin.extend(bytes);
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
    }
}
