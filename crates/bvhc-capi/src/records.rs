//! The plain structs of the C API (`bvhc_ray`, `bvhc_hit`, `bvhc_source_corners`, `bvhc_instance`,
//! `bvhc_mesh` in the header), with the same fields as the Rust records they mirror, and their conversions.

use bvhc_loader::{Hit, Ray, SourceCorners, format::InstanceRecord};

/// `bvhc_ray`: the Rust `Ray` itself (`#[repr(C)]`: origin, direction, `t_min`, `t_max`), so arrays of rays
/// from C are traced in place, without a copy.
pub type BvhcRay = Ray;

/// `bvhc_hit`: the Rust `Hit`, with `0xFFFFFFFF` for "no source id" and a byte for the front-face flag.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhcHit {
    /// Distance along the ray.
    pub t: f32,
    /// Barycentric weight of `v1`.
    pub u: f32,
    /// Barycentric weight of `v2`.
    pub v: f32,
    /// Geometric normal `(v1 - v0) x (v2 - v0)`, not normalized.
    pub normal: [f32; 3],
    /// Index of the record in the triangles section.
    pub triangle_index: u32,
    /// Source id, or `0xFFFFFFFF` without one.
    pub source_triangle_id: u32,
    /// In a two-level file, the instance whose mesh was hit; `0xFFFFFFFF` otherwise.
    pub instance_index: u32,
    /// 1 when the ray met the front side.
    pub front_face: u8,
    /// Zero.
    pub reserved: [u8; 3],
}

impl From<&Hit> for BvhcHit {
    fn from(hit: &Hit) -> BvhcHit {
        BvhcHit {
            t: hit.t,
            u: hit.u,
            v: hit.v,
            normal: hit.normal,
            triangle_index: hit.triangle_index,
            source_triangle_id: hit.source_triangle_id.unwrap_or(u32::MAX),
            instance_index: hit.instance_index.unwrap_or(u32::MAX),
            front_face: u8::from(hit.front_face),
            reserved: [0; 3],
        }
    }
}

impl BvhcHit {
    /// The Rust hit this record was made from.
    pub(crate) fn to_hit(self) -> Hit {
        Hit {
            t: self.t,
            triangle_index: self.triangle_index,
            source_triangle_id: (self.source_triangle_id != u32::MAX).then_some(self.source_triangle_id),
            u: self.u,
            v: self.v,
            normal: self.normal,
            front_face: self.front_face != 0,
            instance_index: (self.instance_index != u32::MAX).then_some(self.instance_index),
        }
    }
}

/// `bvhc_source_corners`: where a hit lies in the source scene (the Rust `SourceCorners`, with the source
/// range's indices inline).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhcSourceCorners {
    /// The source vertex of the record's `v0`, `v1`, `v2` in its primitive.
    pub vertices: [u32; 3],
    /// The hit's weight of each: `1 - u - v`, `u`, `v`.
    pub weights: [f32; 3],
    /// The triangle's source id.
    pub source_triangle_id: u32,
    /// The glTF node that placed the triangle (for a mesh placed by instances, the hit instance's node), or
    /// `0xFFFFFFFF`.
    pub node_index: u32,
    /// The source range's glTF mesh or OBJ model, or `0xFFFFFFFF`.
    pub mesh_index: u32,
    /// The source range's glTF primitive, or `0xFFFFFFFF`.
    pub primitive_index: u32,
    /// The `EXT_mesh_gpu_instancing` instance that placed the triangle (found as `node_index` is), or
    /// `0xFFFFFFFF`.
    pub instance_index: u32,
}

impl From<&SourceCorners<'_>> for BvhcSourceCorners {
    fn from(corners: &SourceCorners<'_>) -> BvhcSourceCorners {
        BvhcSourceCorners {
            vertices: corners.vertices,
            weights: corners.weights,
            source_triangle_id: corners.source_triangle_id,
            node_index: corners.node_index(),
            mesh_index: corners.range.mesh_index,
            primitive_index: corners.range.primitive_index,
            instance_index: corners.gpu_instance_index(),
        }
    }
}

/// `bvhc_instance`: the file's instance record itself (`format-spec/bvh-1.md` 5.11): the object-to-world and
/// world-to-object maps as three rows of four floats (`p'_i = m[i][0] p_0 + m[i][1] p_1 + m[i][2] p_2 +
/// m[i][3]`), the mesh it places, and the glTF node and `EXT_mesh_gpu_instancing` instance it came from.
pub type BvhcInstance = InstanceRecord;

/// `bvhc_mesh`: a mesh of a two-level file, as the range of triangle records it owns (in its object space).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BvhcMesh {
    /// The mesh's first triangle record.
    pub first_triangle: u32,
    /// Its triangle records.
    pub triangle_count: u32,
}
