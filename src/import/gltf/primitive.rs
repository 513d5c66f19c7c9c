//! One glTF primitive's geometry: POSITION decoded, indices checked, and the triangles of its mode.

use std::rc::Rc;

use gltf::json::mesh::{Mode, Semantic};
use gltf::json::validation::Checked;

use super::buffers::{Buffers, Decoded};
use crate::import::Problem;
use crate::import::report::ImportReport;

/// A primitive's positions (local space) and triangles (local indices, in the primitive's order).
pub(super) struct Geometry {
    pub positions: Rc<Decoded>,
    pub triangles: Vec<[u32; 3]>,
}

/// The geometry of `primitive`, or `None` (counted in `report`) for points, lines and primitives without
/// positions.
pub(super) fn geometry(
    primitive: &gltf::json::mesh::Primitive,
    buffers: &mut Buffers<'_>,
    report: &mut ImportReport,
) -> Result<Option<Geometry>, Problem> {
    let Checked::Valid(mode) = primitive.mode else { return Err("invalid mode".to_string().into()) };
    if matches!(mode, Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip) {
        report.skipped_point_and_line_primitives += 1;
        return Ok(None);
    }
    let Some(position_accessor) = primitive.attributes.get(&Checked::Valid(Semantic::Positions)) else {
        report.skipped_primitives_without_positions += 1;
        return Ok(None);
    };
    let positions = buffers.accessor(position_accessor.value()).map_err(|e| e.prefixed("POSITION "))?;
    if positions.components != 3 {
        return Err(format!("POSITION accessor {} is not VEC3", position_accessor.value()).into());
    }
    if let Some(i) = positions.values.iter().position(|v| !v.is_finite()) {
        return Err(format!("POSITION accessor {}: vertex {} is not finite", position_accessor.value(), i / 3).into());
    }
    let vertex_count = positions.count();
    let indices: Vec<u32> = match primitive.indices {
        Some(accessor) => {
            let decoded = buffers.accessor(accessor.value()).map_err(|e| e.prefixed("indices "))?;
            if decoded.components != 1 {
                return Err(format!("indices accessor {} is not SCALAR", accessor.value()).into());
            }
            let mut indices = Vec::with_capacity(decoded.values.len());
            for (k, &v) in decoded.values.iter().enumerate() {
                if !(v >= 0.0 && v < vertex_count as f64 && v.fract() == 0.0) {
                    return Err(format!(
                        "indices accessor {}: index {k} is {v}, not below the vertex count {vertex_count}",
                        accessor.value()
                    )
                    .into());
                }
                indices.push(v as u32);
            }
            indices
        }
        None => (0..u32::try_from(vertex_count).map_err(|_| "too many vertices")?).collect(),
    };
    let triangles = assemble(mode, &indices)?;
    Ok(Some(Geometry { positions, triangles }))
}

/// The triangles of a TRIANGLES, TRIANGLE_STRIP or TRIANGLE_FAN index sequence (glTF 2.0, section 3.7.2.1).
fn assemble(mode: Mode, indices: &[u32]) -> Result<Vec<[u32; 3]>, String> {
    let n = indices.len();
    Ok(match mode {
        Mode::Triangles => {
            if !n.is_multiple_of(3) {
                return Err(format!("TRIANGLES with {n} indices, not a multiple of 3"));
            }
            indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect()
        }
        // Triangle i is (i, i + 1 + i % 2, i + 2 - i % 2): every other one reversed, keeping the winding.
        Mode::TriangleStrip => {
            (0..n.saturating_sub(2)).map(|i| [indices[i], indices[i + 1 + i % 2], indices[i + 2 - i % 2]]).collect()
        }
        Mode::TriangleFan => (0..n.saturating_sub(2)).map(|i| [indices[i + 1], indices[i + 2], indices[0]]).collect(),
        Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip => Vec::new(),
    })
}

/// Triangles of every mesh in the file, from the accessors' counts alone (nothing is decoded).
pub(super) fn file_mesh_triangles(root: &gltf::json::Root) -> u64 {
    root.meshes.iter().map(|mesh| mesh_triangles(root, mesh)).fold(0, u64::saturating_add)
}

/// The triangles one placement of `mesh` adds, from the accessors' declared counts (nothing is decoded).
pub(super) fn mesh_triangles(root: &gltf::json::Root, mesh: &gltf::json::Mesh) -> u64 {
    let count_of = |accessor: usize| root.accessors.get(accessor).map_or(0, |a| a.count.0);
    mesh.primitives
        .iter()
        .map(|primitive| {
            let positions = primitive.attributes.get(&Checked::Valid(Semantic::Positions));
            let n = match (primitive.indices, positions) {
                (Some(indices), _) => count_of(indices.value()),
                (None, Some(positions)) => count_of(positions.value()),
                (None, None) => 0,
            };
            match primitive.mode {
                Checked::Valid(Mode::Triangles) => n / 3,
                Checked::Valid(Mode::TriangleStrip | Mode::TriangleFan) => n.saturating_sub(2),
                _ => 0,
            }
        })
        .fold(0, u64::saturating_add)
}

/// Whether `primitive`'s material may cut its triangles out: its `alphaMode` is `MASK` or `BLEND` (glTF 2.0
/// 3.9.4); a primitive without a material uses the default material, which is opaque. A material index out of
/// range, or an `alphaMode` that is not one of the three, breaks the glTF schema.
pub(super) fn cuts_out(root: &gltf::json::Root, primitive: &gltf::json::mesh::Primitive) -> Result<bool, String> {
    use gltf::json::material::AlphaMode;
    let Some(index) = primitive.material else { return Ok(false) };
    let material = root.materials.get(index.value()).ok_or_else(|| {
        format!("material {} does not exist (the file has {} materials)", index.value(), root.materials.len())
    })?;
    match material.alpha_mode {
        Checked::Valid(AlphaMode::Opaque) => Ok(false),
        Checked::Valid(AlphaMode::Mask | AlphaMode::Blend) => Ok(true),
        Checked::Invalid => Err(format!("material {}: alphaMode is not OPAQUE, MASK or BLEND", index.value())),
    }
}
