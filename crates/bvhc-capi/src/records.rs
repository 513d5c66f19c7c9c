//! The plain structs of the C API (`bvhc_ray`, `bvhc_hit`, `bvhc_source_corners` in the header), with the
//! same fields as the Rust records they mirror, and their conversions.

use bvhc_loader::{Hit, Ray};

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
    /// The source range's glTF node, or `0xFFFFFFFF`.
    pub node_index: u32,
    /// The source range's glTF mesh or OBJ model, or `0xFFFFFFFF`.
    pub mesh_index: u32,
    /// The source range's glTF primitive, or `0xFFFFFFFF`.
    pub primitive_index: u32,
    /// The source range's `EXT_mesh_gpu_instancing` instance, or `0xFFFFFFFF`.
    pub instance_index: u32,
}
