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

pub(crate) mod checksum;
pub mod cost;
mod gpu;
mod header;
mod instances;
pub(crate) mod plain_data;
mod sections;

pub use crate::format::checksum::{header_checksum, section_checksum};
pub use crate::format::gpu::{
    GPU_MAX_DEPTH, GPU_MAX_LEAF_TRIANGLES, GPU_MAX_NODE_TRIANGLES, GPU_WIDE, GpuNode, GpuSlot, GpuTriangle, inner_meta,
    leaf_meta,
};
pub use crate::format::header::{FileHeader, HEADER_BYTE_LEN, SECTION_ENTRY_BYTE_LEN, SectionEntry};
pub use crate::format::instances::{
    Affine3x4, INSTANCE_BOX_PADDING, INVERSE_TOLERANCE, InstanceRecord, MIN_ORTHOGONALITY, MeshRecord,
};
pub use crate::format::sections::SectionKind;

/// An axis-aligned box as the encoders take it: `(min, max)`.
pub type Bounds = ([f32; 3], [f32; 3]);

/// The empty box, the identity of [`union_bounds`].
pub(crate) const EMPTY_BOUNDS: Bounds = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);

/// The smallest box holding `a` and `b`.
pub(crate) fn union_bounds(a: Bounds, b: Bounds) -> Bounds {
    (std::array::from_fn(|k| a.0[k].min(b.0[k])), std::array::from_fn(|k| a.1[k].max(b.1[k])))
}

/// The smallest box holding `a` and `b` where no bound is NaN (the refits' unions of boxes they computed): one
/// compare-and-select a bound, the box [`union_bounds`] gives but for which zero, `+0` or `-0`, a bound at zero
/// takes.
#[inline(always)]
pub(crate) fn merge_bounds(a: Bounds, b: Bounds) -> Bounds {
    (
        std::array::from_fn(|k| if b.0[k] < a.0[k] { b.0[k] } else { a.0[k] }),
        std::array::from_fn(|k| if b.1[k] > a.1[k] { b.1[k] } else { a.1[k] }),
    )
}

/// A box folded from triangles, the refits' fold: each of a triangle's nine coordinates kept apart while
/// triangles are added (nine independent compare-and-selects a triangle, which vectorize, with no chain through
/// the three vertices), the three vertices of each axis folded at the end. A NaN coordinate is passed over (the
/// comparison is false), so the box is the one `f32::min` and `f32::max` give from [`EMPTY_BOUNDS`], but for
/// which zero, `+0` or `-0`, a bound at zero takes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TriangleFold {
    /// The least of each coordinate: `v0.x, v0.y, v0.z, v1.x`, then `v1.y, v1.z, v2.x, v2.y`, then `v2.z`.
    low: ([f32; 4], [f32; 4], f32),
    /// The greatest of each, likewise.
    high: ([f32; 4], [f32; 4], f32),
}

impl TriangleFold {
    /// No triangle yet: the fold of the empty box.
    pub(crate) const EMPTY: TriangleFold = TriangleFold {
        low: ([f32::INFINITY; 4], [f32::INFINITY; 4], f32::INFINITY),
        high: ([f32::NEG_INFINITY; 4], [f32::NEG_INFINITY; 4], f32::NEG_INFINITY),
    };

    /// Adds a triangle's vertices.
    #[inline(always)]
    pub(crate) fn add(&mut self, vertices: &[[f32; 3]; 3]) {
        let [a0, a1, a2, a3, b0, b1, b2, b3, c] = *vertices.as_flattened() else { unreachable!() };
        let (a, b) = ([a0, a1, a2, a3], [b0, b1, b2, b3]);
        let lower = |x: [f32; 4], low: [f32; 4]| -> [f32; 4] {
            std::array::from_fn(|i| if x[i] < low[i] { x[i] } else { low[i] })
        };
        let upper = |x: [f32; 4], high: [f32; 4]| -> [f32; 4] {
            std::array::from_fn(|i| if x[i] > high[i] { x[i] } else { high[i] })
        };
        self.low = (lower(a, self.low.0), lower(b, self.low.1), if c < self.low.2 { c } else { self.low.2 });
        self.high = (upper(a, self.high.0), upper(b, self.high.1), if c > self.high.2 { c } else { self.high.2 });
    }

    /// The box of the triangles added.
    #[inline(always)]
    pub(crate) fn bounds(&self) -> Bounds {
        let lower = |a: f32, b: f32| if b < a { b } else { a };
        let upper = |a: f32, b: f32| if b > a { b } else { a };
        let ((l0, l1, l2), (h0, h1, h2)) = (self.low, self.high);
        // Coordinate k of the nine is v(k / 3), axis k % 3.
        let low = [l0[0], l0[1], l0[2], l0[3], l1[0], l1[1], l1[2], l1[3], l2];
        let high = [h0[0], h0[1], h0[2], h0[3], h1[0], h1[1], h1[2], h1[3], h2];
        (
            std::array::from_fn(|a| lower(lower(low[a], low[3 + a]), low[6 + a])),
            std::array::from_fn(|a| upper(upper(high[a], high[3 + a]), high[6 + a])),
        )
    }
}

/// The bounding box of a triangle's three vertices.
pub(crate) fn triangle_bounds(v: &[[f32; 3]; 3]) -> Bounds {
    (
        std::array::from_fn(|a| v[0][a].min(v[1][a]).min(v[2][a])),
        std::array::from_fn(|a| v[0][a].max(v[1][a]).max(v[2][a])),
    )
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
    /// The box's largest side (the size the walks and batch calls measure a scene by).
    #[inline]
    pub fn largest_extent(&self) -> f32 {
        (0..3).map(|a| self.max[a] - self.min[a]).fold(0.0, f32::max)
    }

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

use crate::format::plain_data::plain_data;

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
