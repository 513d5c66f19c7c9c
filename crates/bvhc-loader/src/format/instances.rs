//! On-disk types of two-level files (format 1.3, `format-spec/bvh-1.md` 5.10-5.12): the mesh table (each
//! bottom-level tree's ranges of the existing sections), the instance table (a mesh placed by an affine
//! transform and its inverse) and the top-level tree over the instances (the `top_nodes` section, whose
//! [`crate::format::PackedNode`]s have leaves of exactly one instance).
//!
//! Two-level scenes follow Embree's instances and tinybvh's `BLASInstance`: traversal maps the ray into the
//! mesh's object space by the stored inverse (origin and direction, the direction not renormalized, so `t` is
//! the world-space parameter) and runs the one-level kernel there.

/// One bottom-level tree of a two-level file: the ranges of the `nodes`, `triangles`, `wide_nodes` and
/// `triangle_packets` sections it owns (and of `triangle_ids` and `source_vertices`, which run parallel to the
/// triangles). Inside a mesh every index is relative to its own range: a node's child and triangle indices count
/// from `first_node` and `first_triangle`, a wide node's children and leaf packets from `first_wide_node` and
/// `first_packet`, a packet lane's triangle index from `first_triangle`. So each mesh's ranges are a one-level
/// tree in the layout of sections 5.1-5.8, its root first. The meshes tile every section in order (rule V41).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MeshRecord {
    /// First node of the mesh's binary tree (its root) in the `nodes` section.
    pub first_node: u32,
    /// Nodes of the mesh's binary tree; odd, at most `2 * triangle_count - 1`.
    pub node_count: u32,
    /// First triangle record of the mesh in the `triangles` section.
    pub first_triangle: u32,
    /// Triangle records of the mesh; at least 1.
    pub triangle_count: u32,
    /// First wide node (the mesh's wide root) in the `wide_nodes` section; 0 in a file without wide sections.
    pub first_wide_node: u32,
    /// Wide nodes of the mesh; 0 exactly when the file has no wide sections.
    pub wide_node_count: u32,
    /// First packet of the mesh in the `triangle_packets` section; 0 in a file without wide sections.
    pub first_packet: u32,
    /// Packets of the mesh; 0 exactly when the file has no wide sections.
    pub packet_count: u32,
}

/// An affine map of 3D points as three rows `[a, b, c, d]`: `p' = (a.p + d)` per row, that is `p'_i =
/// m[i][0] p_0 + m[i][1] p_1 + m[i][2] p_2 + m[i][3]`. Directions use the first three columns only.
pub type Affine3x4 = [[f32; 4]; 3];

/// One placement of a mesh (the `instances` section, 5.11): the transform from the mesh's object space to
/// world space, its inverse as stored (the kernel maps rays by it), the mesh, and where the placement came from.
/// An instance's index in the section is its **instance index**, which hits report; the converter stores
/// instances in the order the scene places them.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InstanceRecord {
    /// Object space to world space; finite, its 3x3 part invertible (rule V42).
    pub object_to_world: Affine3x4,
    /// World space to object space: the inverse of `object_to_world` within the tolerance of rule V42.
    pub world_to_object: Affine3x4,
    /// The placed mesh's index in the `meshes` section.
    pub mesh_index: u32,
    /// The glTF node that places the mesh, or [`crate::format::NO_INDEX`].
    pub node_index: u32,
    /// The node's `EXT_mesh_gpu_instancing` instance, or [`crate::format::NO_INDEX`].
    pub gpu_instance_index: u32,
    /// Zero.
    pub reserved: u32,
}

/// Rule V42: each entry of `world_to_object . object_to_world - identity` (the 3x4 composition, computed in
/// f64) is at most this, relative to the entry's scale (see [`crate::format::InstanceRecord`] and the spec).
pub const INVERSE_TOLERANCE: f64 = 1.0 / 8192.0;

/// Rule V42: `|det L| >= MIN_ORTHOGONALITY * |row 0| |row 1| |row 2|` for the 3x3 part `L` of
/// `object_to_world` (Hadamard's bound makes the ratio at most 1; 0 is a singular map). Scale does not change
/// the ratio, only how close the rows come to lying in one plane.
pub const MIN_ORTHOGONALITY: f64 = 1.0 / 1_048_576.0;

/// The padding the writer adds to an instance's world box on each side, relative to the box's magnitude (its
/// largest absolute coordinate): it covers the rounding of the object-space ray (`format-spec/bvh-1.md` 11.3).
pub const INSTANCE_BOX_PADDING: f64 = 1.0 / 1_048_576.0;

const _: () = assert!(size_of::<MeshRecord>() == 32);
const _: () = assert!(size_of::<InstanceRecord>() == 112);

crate::format::plain_data::plain_data! {
    MeshRecord { u32, u32, u32, u32, u32, u32, u32, u32 }
    InstanceRecord { Affine3x4, Affine3x4, u32, u32, u32, u32 }
}
