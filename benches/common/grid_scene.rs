//! Large scenes for the scale benchmark, generated (never committed): a binary glTF (GLB) that places one
//! indexed mesh `copies` times in a square grid on the x-z plane, one glTF node per copy, so the conversion
//! reads it through the real importer as a level with repeated props would be.

use std::io::Write;
use std::path::Path;

/// The JSON chunk's and the binary chunk's type codes, and the GLB magic (glTF 2.0, section 4.4).
const GLB_MAGIC: u32 = 0x4654_6C67;
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// Writes the grid of `copies` placements of the mesh (`positions`, `triangles` as vertex indices) to `path`.
/// Neighbouring copies are `1.05` mesh extents apart on x and z.
pub fn write_grid_glb(
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
    copies: usize,
    path: &Path,
) -> std::io::Result<()> {
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for p in positions {
        for axis in 0..3 {
            min[axis] = min[axis].min(p[axis]);
            max[axis] = max[axis].max(p[axis]);
        }
    }
    let side = (copies as f64).sqrt().ceil() as usize;
    let step = |axis: usize| 1.05 * (max[axis] - min[axis]);
    let nodes: Vec<String> = (0..copies)
        .map(|i| {
            let (x, z) = ((i % side) as f32 * step(0), (i / side) as f32 * step(2));
            format!(r#"{{"mesh":0,"translation":[{x},0,{z}]}}"#)
        })
        .collect();
    let position_bytes = positions.len() * 12;
    let index_bytes = triangles.len() * 12;
    let json = format!(
        concat!(
            r#"{{"asset":{{"version":"2.0","generator":"bvhc scale benchmark"}},"scene":0,"#,
            r#""scenes":[{{"nodes":[{}]}}],"nodes":[{}],"#,
            r#""meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"mode":4}}]}}],"#,
            r#""buffers":[{{"byteLength":{}}}],"#,
            r#""bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{}}},"#,
            r#"{{"buffer":0,"byteOffset":{},"byteLength":{}}}],"#,
            r#""accessors":[{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3","min":[{},{},{}],"max":[{},{},{}]}},"#,
            r#"{{"bufferView":1,"componentType":5125,"count":{},"type":"SCALAR"}}]}}"#
        ),
        (0..copies).map(|i| i.to_string()).collect::<Vec<_>>().join(","),
        nodes.join(","),
        position_bytes + index_bytes,
        position_bytes,
        position_bytes,
        index_bytes,
        positions.len(),
        min[0],
        min[1],
        min[2],
        max[0],
        max[1],
        max[2],
        triangles.len() * 3,
    );
    let mut json = json.into_bytes();
    json.resize(json.len().next_multiple_of(4), b' ');
    let bin_len = position_bytes + index_bytes;
    let total = 12 + 8 + json.len() + 8 + bin_len;
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    for word in [GLB_MAGIC, 2, total as u32, json.len() as u32, CHUNK_JSON] {
        out.write_all(&word.to_le_bytes())?;
    }
    out.write_all(&json)?;
    for word in [bin_len as u32, CHUNK_BIN] {
        out.write_all(&word.to_le_bytes())?;
    }
    for p in positions {
        for c in p {
            out.write_all(&c.to_le_bytes())?;
        }
    }
    for t in triangles {
        for i in t {
            out.write_all(&i.to_le_bytes())?;
        }
    }
    out.flush()
}
