//! A `UsdGeomMesh` as triangles, as USD's renderers triangulate it (Hydra's `HdMeshUtil::ComputeTriangleIndices`):
//! each face of `faceVertexCounts` a fan from its first vertex, `(v0, v[k], v[k+1])`, the faces that
//! `holeIndices` lists left out, faces of fewer than 3 vertices skipped, and with `orientation = "leftHanded"`
//! each triangle's winding reversed so that its front is bvhc's (counter-clockwise). A subdivision surface is
//! read as its control cage. Points are read at the import's time (time samples interpolated as USD does).

use openusd::sdf::Value;
use openusd::usd::{Prim, TimeCode};

use super::xform::value_kind;

/// A mesh's positions (in its own space, f64 as authored; or skinned, in its skeleton's space) and triangles as
/// vertex indices.
pub(super) struct MeshGeometry {
    pub points: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
    /// For a skinned mesh, the skeleton's transform, which places its points instead of the mesh's own.
    pub skeleton_to_world: Option<glam::DMat4>,
}

/// The triangles a mesh's topology declares, counted from `faceVertexCounts` alone (holes included), for the
/// memory estimate before any points are read.
pub(super) fn declared_triangles(prim: &Prim) -> Result<u64, String> {
    Ok(face_vertex_counts(prim)?.iter().map(|&n| u64::try_from(n).unwrap_or(0).saturating_sub(2)).sum())
}

fn face_vertex_counts(prim: &Prim) -> Result<Vec<i32>, String> {
    int_array(prim, "faceVertexCounts", None)
}

/// An `int[]` attribute (empty when not authored).
pub(super) fn int_array(prim: &Prim, name: &str, time: Option<TimeCode>) -> Result<Vec<i32>, String> {
    match prim.attribute(name).get_at::<Value>(time).map_err(|e| format!("{name}: {e}"))? {
        None => Ok(Vec::new()),
        Some(Value::IntVec(values)) => Ok(values),
        Some(other) => Err(format!("{name} holds {}, not an int array", value_kind(&other))),
    }
}

/// A `point3f[]`-like attribute (float, double or half 3-vectors) as f64 triples; `None` when not authored.
pub(super) fn points_array(prim: &Prim, name: &str, time: Option<TimeCode>) -> Result<Option<Vec<[f64; 3]>>, String> {
    let value = prim.attribute(name).get_at::<Value>(time).map_err(|e| format!("{name}: {e}"))?;
    Ok(match value {
        None => None,
        Some(Value::Vec3fVec(v)) => Some(v.iter().map(|p| [p.x, p.y, p.z].map(f64::from)).collect()),
        Some(Value::Vec3dVec(v)) => Some(v.iter().map(|p| [p.x, p.y, p.z]).collect()),
        Some(Value::Vec3hVec(v)) => Some(v.iter().map(|p| [p.x, p.y, p.z].map(|c| f64::from(c.to_f32()))).collect()),
        Some(other) => return Err(format!("{name} holds {}, not an array of 3-vectors", value_kind(&other))),
    })
}

/// A uniform token attribute's value, or `None`.
pub(super) fn token(prim: &Prim, name: &str) -> Result<Option<String>, String> {
    match prim.attribute(name).get::<Value>().map_err(|e| format!("{name}: {e}"))? {
        None => Ok(None),
        Some(Value::Token(t)) => Ok(Some(t.as_str().to_string())),
        Some(Value::String(s)) => Ok(Some(s)),
        Some(other) => Err(format!("{name} holds {}, not a token", value_kind(&other))),
    }
}

/// The mesh's points at `time` (`points` may be replaced by the caller, e.g. skinned) and its triangles.
pub(super) fn read(prim: &Prim, time: Option<TimeCode>) -> Result<MeshGeometry, String> {
    let counts = face_vertex_counts(prim)?;
    let indices = int_array(prim, "faceVertexIndices", None)?;
    let holes = int_array(prim, "holeIndices", None)?;
    let points = points_array(prim, "points", time)?.unwrap_or_default();
    let left_handed = match token(prim, "orientation")?.as_deref() {
        None | Some("rightHanded") => false,
        Some("leftHanded") => true,
        Some(other) => return Err(format!("orientation '{other}' is neither rightHanded nor leftHanded")),
    };
    let mut is_hole = vec![false; counts.len()];
    for &hole in &holes {
        // USD ignores hole indices that name no face; so does this import.
        if let Some(flag) = usize::try_from(hole).ok().and_then(|h| is_hole.get_mut(h)) {
            *flag = true;
        }
    }
    let declared: u64 = counts.iter().map(|&n| u64::try_from(n).unwrap_or(0)).sum();
    if counts.iter().any(|&n| n < 0) {
        return Err("faceVertexCounts holds a negative count".to_string());
    }
    if declared != indices.len() as u64 {
        return Err(format!(
            "faceVertexCounts sum to {declared} but faceVertexIndices holds {} indices",
            indices.len()
        ));
    }
    let vertex_count = points.len();
    let vertex = |i: i32| -> Result<u32, String> {
        match usize::try_from(i) {
            Ok(v) if v < vertex_count => Ok(v as u32),
            _ => Err(format!("faceVertexIndices holds {i}, not a point index (the mesh has {vertex_count} points)")),
        }
    };
    let mut triangles = Vec::new();
    triangles
        .try_reserve(declared.saturating_sub(2 * counts.len() as u64) as usize)
        .map_err(|_| "no memory for the mesh's triangles".to_string())?;
    let mut start = 0usize;
    for (face, &count) in counts.iter().enumerate() {
        let corners = &indices[start..start + count as usize];
        start += count as usize;
        if count < 3 || is_hole[face] {
            continue;
        }
        let first = vertex(corners[0])?;
        for k in 1..corners.len() - 1 {
            let (b, c) = (vertex(corners[k])?, vertex(corners[k + 1])?);
            triangles.push(if left_handed { [first, c, b] } else { [first, b, c] });
        }
    }
    Ok(MeshGeometry { points, triangles, skeleton_to_world: None })
}
