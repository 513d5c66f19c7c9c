//! On-disk types of the `.bvh` format, major version 1 (`format-spec/bvh-1.md`).
//!
//! These `#[repr(C)]` structs are the single source of truth for the writer and the reader: both cast the same
//! types to and from bytes with bytemuck, so they cannot drift. Field names equal the spec's field names. Every
//! struct is plain data (`u32`, `u64`, `f32`, arrays of them), every padding byte is a named `reserved*` field,
//! and the sizes are asserted at compile time. The file is little-endian; the zero-copy casts are only valid on
//! little-endian hosts, which `BvhView::open` checks.

/// The 8 bytes every `.bvh` file of bvhc starts with: `\x89 B V H C \r \n \x1a`.
///
/// Like PNG's signature: the high first byte catches 7-bit transfers and tells the file apart from text files,
/// in particular Biovision motion-capture `.bvh` files (which start with the ASCII word `HIERARCHY`); the CR LF
/// pair catches line-ending conversion; 0x1A stops `type` on DOS-like systems.
pub const MAGIC: [u8; 8] = *b"\x89BVHC\r\n\x1a";

/// Major version written and read by this crate. Readers reject any other major version.
pub const VERSION_MAJOR: u16 = 1;
/// Highest minor version this crate reads knowingly and writes. Readers accept any minor version of their
/// major version.
pub const VERSION_MINOR: u16 = 5;

/// The sections of a file that decide its minor version ([`written_minor`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MinorFeatures {
    /// The wide sections (1.1).
    pub wide: bool,
    /// The `source_vertices` section (1.2).
    pub source_vertices: bool,
    /// The two-level sections (1.3).
    pub instances: bool,
    /// The GPU sections (1.4).
    pub gpu: bool,
    /// The `triangle_flags` section (1.5).
    pub triangle_flags: bool,
}

/// The minor version a writer stores: the lowest whose features the file uses (1.5 for the `triangle_flags`
/// section, 1.4 for the GPU sections, 1.3 for the two-level sections, 1.2 for the `source_vertices` section, 1.1
/// for the wide sections, otherwise 1.0, so files without them stay readable as 1.0 byte for byte).
pub const fn written_minor(features: MinorFeatures) -> u16 {
    let MinorFeatures {
        wide: has_wide_sections,
        source_vertices: has_source_vertices,
        instances: has_instances,
        gpu: has_gpu_sections,
        triangle_flags,
    } = features;
    if triangle_flags {
        5
    } else if has_gpu_sections {
        4
    } else if has_instances {
        3
    } else if has_source_vertices {
        2
    } else if has_wide_sections {
        1
    } else {
        0
    }
}

/// Whether this reader knows every field of a file with minor version `minor` (so reserved fields and undefined
/// flag bits must be zero); files of higher minors may give them a meaning, and readers then ignore them.
pub const fn is_known_minor(minor: u16) -> bool {
    minor <= VERSION_MINOR
}

/// Alignment of every section's byte offset, counted from the start of the file.
pub const SECTION_ALIGNMENT: u64 = 64;

/// Deepest allowed leaf: the root has depth 0 and no node may have a depth above this (rule V20).
///
/// It bounds the traversal stack, so a verified file can be traced with a fixed stack and no heap allocation.
pub const MAX_DEPTH: usize = 256;

/// `SectionEntry::section_flags` bit: a reader that does not know the section's kind must reject the file.
pub const SECTION_FLAG_REQUIRED: u32 = 1 << 0;
/// `SectionEntry::section_flags` bit, triangles section only: triangles may be referenced from several leaves
/// (spatial splits), so a triangle's vertices need not lie inside its leaf's box (rule V19 is relaxed).
pub const SECTION_FLAG_SPLIT_REFERENCES: u32 = 1 << 1;

/// Marks an absent field in a [`SourceRange`] (for example the node of an OBJ group).
pub const NO_INDEX: u32 = u32::MAX;

/// A `triangle_flags` element's bit (since 1.5): the triangle's material may cut it out (glTF `alphaMode`
/// `MASK` or `BLEND`), so a tracer with a hit filter asks the filter before accepting a hit on it; a triangle
/// without the bit (or in a file without the section) is opaque and accepted at once (`format-spec/bvh-1.md` 5.16).
pub const TRIANGLE_NOT_OPAQUE: u8 = 1 << 0;
/// Every bit of a `triangle_flags` element this version defines; the others are reserved and zero (rule V52).
pub const TRIANGLE_FLAGS_DEFINED: u8 = TRIANGLE_NOT_OPAQUE;

pub use crate::format_gpu::{
    GPU_MAX_DEPTH, GPU_MAX_LEAF_TRIANGLES, GPU_MAX_NODE_TRIANGLES, GPU_WIDE, GpuNode, GpuSlot, GpuTriangle, inner_meta,
    leaf_meta,
};
pub use crate::format_header::{FileHeader, HEADER_BYTE_LEN, SECTION_ENTRY_BYTE_LEN, SectionEntry};
pub use crate::format_instances::{
    Affine3x4, INSTANCE_BOX_PADDING, INVERSE_TOLERANCE, InstanceRecord, MIN_ORTHOGONALITY, MeshRecord,
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
    /// One byte of flags per triangle ([`TRIANGLE_NOT_OPAQUE`]), optional, since 1.5.
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

/// A node of the binary BVH: an axis-aligned box and one index and one count.
///
/// * inner node: `count == 0`; its children are nodes `index` and `index + 1`, both after the node itself
///   (`index > ` the node's own index). The first child is the left one, visited first by depth-first order.
/// * leaf: `count >= 1`; it holds triangles `index .. index + count` of the triangles section.
///
/// Node 0 is the root. The box encloses the boxes of its children (inner) or its triangles (leaf).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PackedNode {
    /// Minimum corner of the box.
    pub min: [f32; 3],
    /// Maximum corner of the box.
    pub max: [f32; 3],
    /// First child (inner) or first triangle (leaf).
    pub index: u32,
    /// Zero for an inner node, the number of triangles for a leaf.
    pub count: u32,
}

impl PackedNode {
    /// Whether this node is a leaf (`count >= 1`).
    #[inline]
    pub const fn is_leaf(&self) -> bool {
        self.count != 0
    }
}

/// The three vertices of one triangle, stored in leaf order so traversal reads them without indirection.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PackedTriangle {
    /// The vertices `v0, v1, v2`; the front face is counter-clockwise seen from the front.
    pub vertices: [[f32; 3]; 3],
}

/// One record of the source table: a range of source triangle ids and the part of the input it came from.
///
/// Ids `first_source_triangle .. first_source_triangle + source_triangle_count` belong to this range; the
/// triangle index within the primitive is `id - first_source_triangle`. Fields that do not apply to an input
/// format hold [`NO_INDEX`].
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SourceRange {
    /// First source triangle id of the range.
    pub first_source_triangle: u32,
    /// Number of ids in the range; at least 1.
    pub source_triangle_count: u32,
    /// Index of the input file in the metadata's `inputs` list (0 for a single input).
    pub file_index: u32,
    /// glTF node index, or [`NO_INDEX`].
    pub node_index: u32,
    /// glTF mesh index, OBJ model index, or [`NO_INDEX`].
    pub mesh_index: u32,
    /// glTF primitive index within the mesh, or [`NO_INDEX`].
    pub primitive_index: u32,
    /// `EXT_mesh_gpu_instancing` instance index, or [`NO_INDEX`].
    pub instance_index: u32,
    /// Zero.
    pub reserved: u32,
}

/// One element of the `source_vertices` section (since 1.2): the vertex indices, in the triangle's source
/// primitive, of the record's `v0`, `v1` and `v2`, so that a hit's barycentrics weigh a renderer's own vertex
/// attributes: `(1 - u - v) attribute[indices[0]] + u attribute[indices[1]] + v attribute[indices[2]]`.
///
/// The index space is the source's (`format-spec/bvh-1.md` 5.9): a glTF primitive's vertex index (the value in
/// its index accessor), a PLY file's `vertex` record, an OBJ file's `v` record counted from 0. The primitive is
/// the triangle's source range, found from its source id.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SourceVertexIndices {
    /// The source vertex of `v0`, `v1`, `v2`.
    pub indices: [u32; 3],
}

/// Child slots of a wide node.
pub const WIDE: usize = 8;
/// Triangles in one packet.
pub const PACKET_LANES: usize = 4;
/// `WideNode8::child` bit that marks a leaf reference.
pub const LEAF_BIT: u32 = 1 << 31;
/// `WideNode8::child` value of an empty slot (whose box is `+inf..-inf`).
pub const EMPTY_SLOT: u32 = u32::MAX;
/// Largest first packet index a leaf reference can hold (28 bits).
pub const MAX_LEAF_FIRST_PACKET: u32 = (1 << 28) - 1;
/// Most elements of the `triangle_packets` section (rule V10): every packet index fits a leaf reference's
/// 28-bit `first_packet`.
pub const MAX_PACKET_COUNT: u64 = 1 << 28;
/// Most packets one leaf reference can hold (3 bits of `packet_count - 1`).
pub const MAX_LEAF_PACKETS: u32 = 8;
/// `TrianglePacket4::triangle_index` of an unused lane.
pub const UNUSED_LANE: u32 = u32::MAX;
/// The bits of every coordinate of an unused lane: the quiet NaN `0x7FC00000`, which no ray hits.
pub const UNUSED_LANE_COORDINATE_BITS: u32 = 0x7FC0_0000;

/// One node of the wide tree (the `wide_nodes` section, since 1.1): the boxes of up to eight children in structure-of-arrays order (`min[axis][slot]`), so one 256-bit
/// load feeds one slab test of all eight, and one child reference per slot:
///
/// * `EMPTY_SLOT`: no child; the slot's box is `min = +inf`, `max = -inf`, which no ray enters;
/// * `LEAF_BIT | (packet_count - 1) << 28 | first_packet`: a leaf, packets `first_packet .. + packet_count` of
///   the packets (`packet_count` 1 to 8);
/// * otherwise: the index of an inner wide node, greater than this node's own index.
///
/// Occupied slots come first; the root has at least one, every other node at least two. Node 0 is the root;
/// its own box is the binary root's (`nodes[0]`). 256 bytes, so nodes stay 64-byte aligned in the section.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WideNode8 {
    /// Children's box minima, per axis then per slot.
    pub min: [[f32; WIDE]; 3],
    /// Children's box maxima, per axis then per slot.
    pub max: [[f32; WIDE]; 3],
    /// Child references, per slot.
    pub child: [u32; WIDE],
    /// Zero.
    pub reserved: [u32; WIDE],
}

impl WideNode8 {
    /// A node with every slot empty.
    pub const EMPTY: WideNode8 = WideNode8 {
        min: [[f32::INFINITY; WIDE]; 3],
        max: [[f32::NEG_INFINITY; WIDE]; 3],
        child: [EMPTY_SLOT; WIDE],
        reserved: [0; WIDE],
    };

    /// The leaf reference for packets `first_packet .. first_packet + packet_count`, if it fits the encoding.
    pub fn leaf(first_packet: u32, packet_count: u32) -> Option<u32> {
        ((1..=MAX_LEAF_PACKETS).contains(&packet_count) && first_packet <= MAX_LEAF_FIRST_PACKET)
            .then_some(LEAF_BIT | ((packet_count - 1) << 28) | first_packet)
    }

    /// `(first_packet, packet_count)` of a leaf reference (`child & LEAF_BIT != 0`, not `EMPTY_SLOT`).
    pub const fn leaf_packets(child: u32) -> (u32, u32) {
        (child & MAX_LEAF_FIRST_PACKET, ((child >> 28) & 7) + 1)
    }
}

/// Four leaf triangles (the `triangle_packets` section, since 1.1),
/// vertices in structure-of-arrays order (`vertices[vertex][axis][lane]`) for a watertight test of all four in
/// SIMD lanes, and each lane's index into the `triangles` section, whose vertices the lane repeats bit for bit. Used lanes come first; an unused lane
/// has index `UNUSED_LANE` and every coordinate `UNUSED_LANE_COORDINATE_BITS`. 160 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrianglePacket4 {
    /// Coordinates, per vertex, axis, lane.
    pub vertices: [[[f32; PACKET_LANES]; 3]; 3],
    /// Index in the triangles section, per lane.
    pub triangle_index: [u32; PACKET_LANES],
}

impl PackedTriangle {
    /// The nine coordinates' bit patterns, `v0.x, v0.y, v0.z, v1.x, ...`: records are the same triangle's
    /// references exactly when these are equal (and, with ids, their ids are), `format-spec/bvh-1.md` 5.2.
    pub fn coordinate_bits(&self) -> [u32; 9] {
        std::array::from_fn(|k| self.vertices[k / 3][k % 3].to_bits())
    }
}

impl TrianglePacket4 {
    /// The packet of up to four triangles `(index, triangle)`; missing lanes are unused.
    pub fn new(triangles: &[(u32, PackedTriangle)]) -> TrianglePacket4 {
        let nan = f32::from_bits(UNUSED_LANE_COORDINATE_BITS);
        let mut packet =
            TrianglePacket4 { vertices: [[[nan; PACKET_LANES]; 3]; 3], triangle_index: [UNUSED_LANE; PACKET_LANES] };
        for (lane, (index, triangle)) in triangles.iter().take(PACKET_LANES).enumerate() {
            packet.triangle_index[lane] = *index;
            for vertex in 0..3 {
                for axis in 0..3 {
                    packet.vertices[vertex][axis][lane] = triangle.vertices[vertex][axis];
                }
            }
        }
        packet
    }

    /// The triangle in `lane`.
    pub fn triangle(&self, lane: usize) -> PackedTriangle {
        let v = &self.vertices;
        let corner = |vertex: usize| [v[vertex][0][lane], v[vertex][1][lane], v[vertex][2][lane]];
        PackedTriangle { vertices: [corner(0), corner(1), corner(2)] }
    }

    /// Number of used lanes (lanes before the first unused one).
    pub fn used_lanes(&self) -> usize {
        self.triangle_index.iter().take_while(|&&i| i != UNUSED_LANE).count()
    }
}

const _: () = assert!(size_of::<WideNode8>() == 256);
// The wide kernel finds a node's `min` and `max` rows by offset (`PreparedRay::wide_plane_offsets`).
const _: () = assert!(std::mem::offset_of!(WideNode8, min) == 0 && std::mem::offset_of!(WideNode8, max) == 96);
const _: () = assert!(size_of::<TrianglePacket4>() == 160);
const _: () = assert!(size_of::<FileHeader>() == 64);
const _: () = assert!(size_of::<SectionEntry>() == 48);
const _: () = assert!(size_of::<PackedNode>() == 32);
const _: () = assert!(size_of::<PackedTriangle>() == 36);
const _: () = assert!(size_of::<SourceRange>() == 32);
const _: () = assert!(size_of::<SourceVertexIndices>() == 12);

use crate::plain_data::plain_data;

plain_data! {
    PackedNode { [f32; 3], [f32; 3], u32, u32 }
    PackedTriangle { [[f32; 3]; 3] }
    SourceRange { u32, u32, u32, u32, u32, u32, u32, u32 }
    WideNode8 { [[f32; WIDE]; 3], [[f32; WIDE]; 3], [u32; WIDE], [u32; WIDE] }
    TrianglePacket4 { [[[f32; PACKET_LANES]; 3]; 3], [u32; PACKET_LANES] }
    SourceVertexIndices { [u32; 3] }
}

/// Rounds `value` up to the next multiple of [`SECTION_ALIGNMENT`], `None` on overflow.
pub const fn align_up(value: u64) -> Option<u64> {
    match value.checked_add(SECTION_ALIGNMENT - 1) {
        Some(v) => Some(v / SECTION_ALIGNMENT * SECTION_ALIGNMENT),
        None => None,
    }
}
