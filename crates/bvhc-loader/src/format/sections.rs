//! The kinds of section a file may hold: codes, names, element sizes, and the order the writer stores them.

use crate::format::{
    GpuNode, GpuTriangle, InstanceRecord, MeshRecord, PackedNode, PackedTriangle, SECTION_FLAG_REQUIRED,
    SECTION_FLAG_SPLIT_REFERENCES, SourceRange, SourceVertexIndices, TrianglePacket4, WideNode8,
};

/// The kinds of section that major version 1 defines. Other values are unknown kinds (rule V7).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum SectionKind {
    /// Binary BVH nodes ([`PackedNode`]), required.
    Nodes,
    /// Triangle vertices in leaf order ([`PackedTriangle`]), required.
    Triangles,
    /// One `u32` source triangle id per triangle, optional.
    TriangleIds,
    /// Source ranges ([`SourceRange`]) mapping ids to mesh/primitive/node/instance, optional.
    SourceTable,
    /// UTF-8 JSON object with build metadata, optional.
    Metadata,
    /// 8-wide BVH nodes ([`WideNode8`]) for SIMD traversal, optional, since 1.1; comes with `TrianglePackets`.
    WideNodes,
    /// Leaf triangles of the wide BVH in packets of four ([`TrianglePacket4`]), optional, since 1.1.
    TrianglePackets,
    /// Each triangle's three vertex indices in its source primitive ([`SourceVertexIndices`]), optional, since
    /// 1.2; needs the source table.
    SourceVertices,
    /// The mesh table of a two-level file ([`MeshRecord`]), required, since 1.3; comes with `Instances` and
    /// `TopNodes`.
    Meshes,
    /// The instance table of a two-level file ([`InstanceRecord`]), required, since 1.3.
    Instances,
    /// The top-level tree of a two-level file ([`PackedNode`]s whose leaves hold one instance each), required,
    /// since 1.3.
    TopNodes,
    /// The top-level tree in the 8-wide layout ([`WideNode8`]s whose leaf slots hold one instance each),
    /// optional, since 1.3; in a two-level file exactly when it has the wide sections.
    TopWideNodes,
    /// Compressed 8-wide nodes for GPU traversal ([`GpuNode`]), optional, since 1.4; comes with `GpuTriangles`.
    GpuNodes,
    /// The GPU nodes' leaf triangles with their vertices ([`GpuTriangle`]), optional, since 1.4.
    GpuTriangles,
    /// One byte of flags per triangle ([`TRIANGLE_NOT_OPAQUE`](crate::format::TRIANGLE_NOT_OPAQUE)), optional, since 1.5.
    TriangleFlags,
}

impl SectionKind {
    /// Every kind defined by this version, in the order the writer stores them.
    pub const ALL: [SectionKind; 15] = [
        SectionKind::Nodes,
        SectionKind::Triangles,
        SectionKind::TriangleIds,
        SectionKind::SourceTable,
        SectionKind::Metadata,
        SectionKind::WideNodes,
        SectionKind::TrianglePackets,
        SectionKind::SourceVertices,
        SectionKind::Meshes,
        SectionKind::Instances,
        SectionKind::TopNodes,
        SectionKind::TopWideNodes,
        SectionKind::GpuNodes,
        SectionKind::GpuTriangles,
        SectionKind::TriangleFlags,
    ];

    /// The `kind` value stored in the section table.
    pub const fn code(self) -> u32 {
        match self {
            SectionKind::Nodes => 1,
            SectionKind::Triangles => 2,
            SectionKind::TriangleIds => 3,
            SectionKind::SourceTable => 4,
            SectionKind::Metadata => 5,
            SectionKind::WideNodes => 6,
            SectionKind::TrianglePackets => 7,
            SectionKind::SourceVertices => 8,
            SectionKind::Meshes => 9,
            SectionKind::Instances => 10,
            SectionKind::TopNodes => 11,
            SectionKind::TopWideNodes => 12,
            SectionKind::GpuNodes => 13,
            SectionKind::GpuTriangles => 14,
            SectionKind::TriangleFlags => 15,
        }
    }

    /// The kind for a stored `kind` value, `None` for kinds this version does not define.
    pub const fn from_code(code: u32) -> Option<SectionKind> {
        match code {
            1 => Some(SectionKind::Nodes),
            2 => Some(SectionKind::Triangles),
            3 => Some(SectionKind::TriangleIds),
            4 => Some(SectionKind::SourceTable),
            5 => Some(SectionKind::Metadata),
            6 => Some(SectionKind::WideNodes),
            7 => Some(SectionKind::TrianglePackets),
            8 => Some(SectionKind::SourceVertices),
            9 => Some(SectionKind::Meshes),
            10 => Some(SectionKind::Instances),
            11 => Some(SectionKind::TopNodes),
            12 => Some(SectionKind::TopWideNodes),
            13 => Some(SectionKind::GpuNodes),
            14 => Some(SectionKind::GpuTriangles),
            15 => Some(SectionKind::TriangleFlags),
            _ => None,
        }
    }

    /// Byte size of one element (`element_byte_len`).
    pub const fn element_byte_len(self) -> u32 {
        match self {
            SectionKind::Nodes => size_of::<PackedNode>() as u32,
            SectionKind::Triangles => size_of::<PackedTriangle>() as u32,
            SectionKind::TriangleIds => size_of::<u32>() as u32,
            SectionKind::SourceTable => size_of::<SourceRange>() as u32,
            SectionKind::Metadata => 1,
            SectionKind::WideNodes => size_of::<WideNode8>() as u32,
            SectionKind::TrianglePackets => size_of::<TrianglePacket4>() as u32,
            SectionKind::SourceVertices => size_of::<SourceVertexIndices>() as u32,
            SectionKind::Meshes => size_of::<MeshRecord>() as u32,
            SectionKind::Instances => size_of::<InstanceRecord>() as u32,
            SectionKind::TopNodes => size_of::<PackedNode>() as u32,
            SectionKind::TopWideNodes => size_of::<WideNode8>() as u32,
            SectionKind::GpuNodes => size_of::<GpuNode>() as u32,
            SectionKind::GpuTriangles => size_of::<GpuTriangle>() as u32,
            SectionKind::TriangleFlags => 1,
        }
    }

    /// The minor version that defined the kind: a file of a lower minor version must not have it (rule V8).
    pub const fn since_minor(self) -> u16 {
        match self {
            SectionKind::WideNodes | SectionKind::TrianglePackets => 1,
            SectionKind::SourceVertices => 2,
            SectionKind::Meshes | SectionKind::Instances | SectionKind::TopNodes | SectionKind::TopWideNodes => 3,
            SectionKind::GpuNodes | SectionKind::GpuTriangles => 4,
            SectionKind::TriangleFlags => 5,
            _ => 0,
        }
    }

    /// Whether the section's `REQUIRED` flag must be set (nodes, triangles and the two-level sections, without
    /// which a reader would trace the meshes' object-space trees as if they were the scene) or clear (the others).
    pub const fn is_required(self) -> bool {
        matches!(
            self,
            SectionKind::Nodes
                | SectionKind::Triangles
                | SectionKind::Meshes
                | SectionKind::Instances
                | SectionKind::TopNodes
        )
    }

    /// Flag bits this version defines for the kind; all other bits are reserved and zero.
    pub const fn defined_flags(self) -> u32 {
        match self {
            SectionKind::Triangles => SECTION_FLAG_REQUIRED | SECTION_FLAG_SPLIT_REFERENCES,
            _ => SECTION_FLAG_REQUIRED,
        }
    }

    /// The spec's name of the kind, used in error messages.
    pub const fn name(self) -> &'static str {
        match self {
            SectionKind::Nodes => "nodes",
            SectionKind::Triangles => "triangles",
            SectionKind::TriangleIds => "triangle_ids",
            SectionKind::SourceTable => "source_table",
            SectionKind::Metadata => "metadata",
            SectionKind::WideNodes => "wide_nodes",
            SectionKind::TrianglePackets => "triangle_packets",
            SectionKind::SourceVertices => "source_vertices",
            SectionKind::Meshes => "meshes",
            SectionKind::Instances => "instances",
            SectionKind::TopNodes => "top_nodes",
            SectionKind::TopWideNodes => "top_wide_nodes",
            SectionKind::GpuNodes => "gpu_nodes",
            SectionKind::GpuTriangles => "gpu_triangles",
            SectionKind::TriangleFlags => "triangle_flags",
        }
    }
}
