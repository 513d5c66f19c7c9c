/*
 * bvh.h: C11 declarations of the on-disk types of the .bvh format, major version 1 (format-spec/bvh-1.md,
 * version 1.5). Normative together with bvh-1.md, section 15: where the two disagree, bvh-1.md is right.
 *
 * Every type is plain data with no padding: each byte belongs to a named field, reserved fields included, and the
 * static assertions below pin every size and field offset. All values are little-endian; a reader on a
 * little-endian host with a 4-byte-aligned buffer (8-byte for the header and the section table) can use the
 * arrays of a file in place, after checking rules V1-V10 (and V11-V53 to trust the contents).
 *
 * Floating point: the traversal relies on IEEE 754 binary32 with infinities, NaN, signed zeros and subnormal
 * numbers (bvh-1.md section 11.1). Do not compile code that traces these arrays with -ffast-math,
 * -ffinite-math-only or /fp:fast, and do not run it with flush-to-zero or denormals-are-zero set.
 *
 * This file declares types and constants only; it has no functions and needs nothing but <stdint.h> and
 * <assert.h>.
 */
#ifndef BVHC_BVH_H
#define BVHC_BVH_H

#include <assert.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Header (section 2). */
#define BVH_MAGIC "\x89" "BVHC\r\n\x1a" /* 8 bytes, without the string's terminating zero */
#define BVH_MAGIC_BYTE_LEN 8
#define BVH_VERSION_MAJOR 1
#define BVH_VERSION_MINOR 5 /* the highest minor version these declarations cover */
#define BVH_HEADER_BYTE_LEN 64
#define BVH_SECTION_ENTRY_BYTE_LEN 48 /* the entry's first 48 bytes; section_entry_byte_len may be larger */
#define BVH_SECTION_ALIGNMENT 64
#define BVH_MAX_DEPTH 256

/* Section kinds (section 5) and flags (section 3). */
#define BVH_KIND_NODES 1u
#define BVH_KIND_TRIANGLES 2u
#define BVH_KIND_TRIANGLE_IDS 3u
#define BVH_KIND_SOURCE_TABLE 4u
#define BVH_KIND_METADATA 5u
#define BVH_KIND_WIDE_NODES 6u       /* since 1.1 */
#define BVH_KIND_TRIANGLE_PACKETS 7u /* since 1.1 */
#define BVH_KIND_SOURCE_VERTICES 8u  /* since 1.2 */
#define BVH_KIND_MESHES 9u           /* since 1.3, REQUIRED */
#define BVH_KIND_INSTANCES 10u       /* since 1.3, REQUIRED */
#define BVH_KIND_TOP_NODES 11u       /* since 1.3, REQUIRED; elements are BvhPackedNode */
#define BVH_KIND_TOP_WIDE_NODES 12u  /* since 1.3; elements are BvhWideNode8, leaf slots LEAF_BIT | instance */
#define BVH_KIND_GPU_NODES 13u       /* since 1.4 */
#define BVH_KIND_GPU_TRIANGLES 14u   /* since 1.4 */
#define BVH_KIND_TRIANGLE_FLAGS 15u  /* since 1.5; elements are uint8_t, one per triangle */
#define BVH_KIND_PRIVATE_FIRST 0x80000000u
#define BVH_SECTION_FLAG_REQUIRED (1u << 0)
#define BVH_SECTION_FLAG_SPLIT_REFERENCES (1u << 1) /* triangles only */

/* Sentinels. */
#define BVH_NO_INDEX 0xFFFFFFFFu     /* a source_table field that does not apply */
#define BVH_WIDE 8                   /* slots of a wide node */
#define BVH_PACKET_LANES 4           /* lanes of a triangle packet */
#define BVH_EMPTY_SLOT 0xFFFFFFFFu   /* wide node: no child; its box is +inf..-inf */
#define BVH_LEAF_BIT 0x80000000u     /* wide node: the child reference is a leaf */
#define BVH_FIRST_PACKET_MASK 0x0FFFFFFFu
#define BVH_UNUSED_LANE 0xFFFFFFFFu  /* packet: no triangle in this lane */
#define BVH_UNUSED_LANE_COORDINATE_BITS 0x7FC00000u /* every coordinate of an unused lane: a quiet NaN */
#define BVH_EMPTY_SLOT_MIN_BITS 0x7F800000u         /* +inf */
#define BVH_EMPTY_SLOT_MAX_BITS 0xFF800000u         /* -inf */
#define BVH_TRIANGLE_NOT_OPAQUE 0x01u /* triangle_flags: the material may cut the triangle out (section 5.16) */

/* A leaf reference's first packet and number of packets (1 to 8): leaf_packet_count in the spec. */
#define BVH_LEAF_FIRST_PACKET(c) ((uint32_t)(c) & BVH_FIRST_PACKET_MASK)
#define BVH_LEAF_PACKET_COUNT(c) ((((uint32_t)(c) >> 28) & 7u) + 1u)

/* The first 64 bytes of the file (section 2). */
typedef struct BvhFileHeader {
    uint8_t magic[8];
    uint16_t version_major;
    uint16_t version_minor;
    uint32_t header_flags;
    uint64_t file_byte_len;
    uint32_t section_count;
    uint32_t section_entry_byte_len;
    uint64_t header_checksum; /* XXH3-64, seed 0, of the header and table with this field taken as 0 */
    uint64_t reserved[3];
} BvhFileHeader;

/* The first 48 bytes of a section table entry (section 3); entry i starts at 64 + i * section_entry_byte_len. */
typedef struct BvhSectionEntry {
    uint32_t kind;
    uint32_t section_flags;
    uint64_t section_byte_offset;
    uint64_t section_byte_len;
    uint64_t element_count;
    uint32_t element_byte_len;
    uint32_t reserved;
    uint64_t section_checksum; /* XXH3-64, seed 0, of the section's section_byte_len bytes */
} BvhSectionEntry;

/* One binary node (section 5.1): count 0 for an inner node (children index, index + 1), else a leaf of
 * triangles index .. index + count. */
typedef struct BvhPackedNode {
    float min[3];
    float max[3];
    uint32_t index;
    uint32_t count;
} BvhPackedNode;

/* One triangle record (section 5.2): vertices[vertex][axis]. */
typedef struct BvhPackedTriangle {
    float vertices[3][3];
} BvhPackedTriangle;

/* Element of the triangle_ids section (section 5.3). */
typedef uint32_t BvhTriangleId;

/* One source range (section 5.4). */
typedef struct BvhSourceRange {
    uint32_t first_source_triangle;
    uint32_t source_triangle_count;
    uint32_t file_index;
    uint32_t node_index;
    uint32_t mesh_index;
    uint32_t primitive_index;
    uint32_t instance_index;
    uint32_t reserved;
} BvhSourceRange;

/* One wide node (section 5.7, since 1.1): min[axis][slot], max[axis][slot], child[slot]. */
typedef struct BvhWideNode8 {
    float min[3][BVH_WIDE];
    float max[3][BVH_WIDE];
    uint32_t child[BVH_WIDE];
    uint32_t reserved[BVH_WIDE];
} BvhWideNode8;

/* One triangle packet (section 5.8, since 1.1): vertices[vertex][axis][lane], triangle_index[lane]. */
typedef struct BvhTrianglePacket4 {
    float vertices[3][3][BVH_PACKET_LANES];
    uint32_t triangle_index[BVH_PACKET_LANES];
} BvhTrianglePacket4;

/* Element of the source_vertices section (section 5.9, since 1.2): the source vertex of v0, v1, v2. */
typedef struct BvhSourceVertexIndices {
    uint32_t indices[3];
} BvhSourceVertexIndices;

/* Element of the meshes section (section 5.10, since 1.3): a mesh's ranges of the one-level sections; indices
 * inside a mesh count from its ranges' starts. */
typedef struct BvhMeshRecord {
    uint32_t first_node;
    uint32_t node_count;
    uint32_t first_triangle;
    uint32_t triangle_count;
    uint32_t first_wide_node;
    uint32_t wide_node_count;
    uint32_t first_packet;
    uint32_t packet_count;
} BvhMeshRecord;

/* Element of the instances section (section 5.11, since 1.3): rows [a, b, c, d], p' = a.p + d per row. */
typedef struct BvhInstanceRecord {
    float object_to_world[3][4];
    float world_to_object[3][4];
    uint32_t mesh_index;
    uint32_t node_index;         /* BVH_NO_INDEX where it does not apply */
    uint32_t gpu_instance_index; /* BVH_NO_INDEX where it does not apply */
    uint32_t reserved;
} BvhInstanceRecord;

/* Element of the gpu_nodes section (section 5.14, since 1.4): a compressed 8-wide node. A slot's box decodes per
 * axis a as origin[a] + q * step[a] in binary32, step[a] the float with bits exponents[a] << 23; meta[s] is 0
 * (empty), BVH_GPU_INNER_META(s) (inner: node child_base + popcount(inner_mask & ((1 << s) - 1))) or a leaf of
 * 1-3 triangles in unary in the top three bits over an offset from triangle_base in the low five. */
typedef struct BvhGpuNode {
    float origin[3];
    uint8_t exponents[3];
    uint8_t inner_mask;
    uint32_t child_base;
    uint32_t triangle_base;
    uint8_t meta[8];
    uint8_t quantized_min[3][8];
    uint8_t quantized_max[3][8];
} BvhGpuNode;

#define BVH_GPU_MAX_DEPTH 64
#define BVH_GPU_INNER_META(slot) ((uint8_t)(0x20u | (24u + (slot))))
/* For a leaf's meta byte: its triangle count (unary 0b001, 0b011, 0b111) and its offset from triangle_base. */
#define BVH_GPU_LEAF_COUNT(meta) ((meta) >> 5 == 7u ? 3u : (meta) >> 5 == 3u ? 2u : 1u)
#define BVH_GPU_LEAF_OFFSET(meta) ((meta) & 31u)

/* Element of the gpu_triangles section (section 5.15, since 1.4): a leaf triangle with its record's vertices. */
typedef struct BvhGpuTriangle {
    float vertices[3][3];
    uint32_t triangle_index;
} BvhGpuTriangle;

/* The layout is the spec's byte for byte. */
static_assert(sizeof(float) == 4, "f32 is IEEE 754 binary32");
static_assert(sizeof(BvhFileHeader) == 64, "FileHeader is 64 bytes");
static_assert(offsetof(BvhFileHeader, magic) == 0, "magic");
static_assert(offsetof(BvhFileHeader, version_major) == 8, "version_major");
static_assert(offsetof(BvhFileHeader, version_minor) == 10, "version_minor");
static_assert(offsetof(BvhFileHeader, header_flags) == 12, "header_flags");
static_assert(offsetof(BvhFileHeader, file_byte_len) == 16, "file_byte_len");
static_assert(offsetof(BvhFileHeader, section_count) == 24, "section_count");
static_assert(offsetof(BvhFileHeader, section_entry_byte_len) == 28, "section_entry_byte_len");
static_assert(offsetof(BvhFileHeader, header_checksum) == 32, "header_checksum");
static_assert(offsetof(BvhFileHeader, reserved) == 40, "reserved");

static_assert(sizeof(BvhSectionEntry) == 48, "SectionEntry is 48 bytes");
static_assert(offsetof(BvhSectionEntry, kind) == 0, "kind");
static_assert(offsetof(BvhSectionEntry, section_flags) == 4, "section_flags");
static_assert(offsetof(BvhSectionEntry, section_byte_offset) == 8, "section_byte_offset");
static_assert(offsetof(BvhSectionEntry, section_byte_len) == 16, "section_byte_len");
static_assert(offsetof(BvhSectionEntry, element_count) == 24, "element_count");
static_assert(offsetof(BvhSectionEntry, element_byte_len) == 32, "element_byte_len");
static_assert(offsetof(BvhSectionEntry, reserved) == 36, "reserved");
static_assert(offsetof(BvhSectionEntry, section_checksum) == 40, "section_checksum");

static_assert(sizeof(BvhPackedNode) == 32, "PackedNode is 32 bytes");
static_assert(offsetof(BvhPackedNode, min) == 0, "min");
static_assert(offsetof(BvhPackedNode, max) == 12, "max");
static_assert(offsetof(BvhPackedNode, index) == 24, "index");
static_assert(offsetof(BvhPackedNode, count) == 28, "count");

static_assert(sizeof(BvhPackedTriangle) == 36, "PackedTriangle is 36 bytes");
static_assert(offsetof(BvhPackedTriangle, vertices) == 0, "vertices");

static_assert(sizeof(BvhTriangleId) == 4, "a triangle id is 4 bytes");

static_assert(sizeof(BvhSourceRange) == 32, "SourceRange is 32 bytes");
static_assert(offsetof(BvhSourceRange, first_source_triangle) == 0, "first_source_triangle");
static_assert(offsetof(BvhSourceRange, source_triangle_count) == 4, "source_triangle_count");
static_assert(offsetof(BvhSourceRange, file_index) == 8, "file_index");
static_assert(offsetof(BvhSourceRange, node_index) == 12, "node_index");
static_assert(offsetof(BvhSourceRange, mesh_index) == 16, "mesh_index");
static_assert(offsetof(BvhSourceRange, primitive_index) == 20, "primitive_index");
static_assert(offsetof(BvhSourceRange, instance_index) == 24, "instance_index");
static_assert(offsetof(BvhSourceRange, reserved) == 28, "reserved");

static_assert(sizeof(BvhWideNode8) == 256, "WideNode8 is 256 bytes");
static_assert(offsetof(BvhWideNode8, min) == 0, "min");
static_assert(offsetof(BvhWideNode8, max) == 96, "max");
static_assert(offsetof(BvhWideNode8, child) == 192, "child");
static_assert(offsetof(BvhWideNode8, reserved) == 224, "reserved");

static_assert(sizeof(BvhTrianglePacket4) == 160, "TrianglePacket4 is 160 bytes");
static_assert(offsetof(BvhTrianglePacket4, vertices) == 0, "vertices");
static_assert(offsetof(BvhTrianglePacket4, triangle_index) == 144, "triangle_index");

static_assert(sizeof(BvhSourceVertexIndices) == 12, "SourceVertexIndices is 12 bytes");
static_assert(offsetof(BvhSourceVertexIndices, indices) == 0, "indices");

static_assert(sizeof(BvhMeshRecord) == 32, "MeshRecord is 32 bytes");
static_assert(offsetof(BvhMeshRecord, first_node) == 0, "first_node");
static_assert(offsetof(BvhMeshRecord, node_count) == 4, "node_count");
static_assert(offsetof(BvhMeshRecord, first_triangle) == 8, "first_triangle");
static_assert(offsetof(BvhMeshRecord, triangle_count) == 12, "triangle_count");
static_assert(offsetof(BvhMeshRecord, first_wide_node) == 16, "first_wide_node");
static_assert(offsetof(BvhMeshRecord, wide_node_count) == 20, "wide_node_count");
static_assert(offsetof(BvhMeshRecord, first_packet) == 24, "first_packet");
static_assert(offsetof(BvhMeshRecord, packet_count) == 28, "packet_count");

static_assert(sizeof(BvhInstanceRecord) == 112, "InstanceRecord is 112 bytes");
static_assert(offsetof(BvhInstanceRecord, object_to_world) == 0, "object_to_world");
static_assert(offsetof(BvhInstanceRecord, world_to_object) == 48, "world_to_object");
static_assert(offsetof(BvhInstanceRecord, mesh_index) == 96, "mesh_index");
static_assert(offsetof(BvhInstanceRecord, node_index) == 100, "node_index");
static_assert(offsetof(BvhInstanceRecord, gpu_instance_index) == 104, "gpu_instance_index");
static_assert(offsetof(BvhInstanceRecord, reserved) == 108, "reserved");

static_assert(sizeof(BvhGpuNode) == 80, "GpuNode is 80 bytes");
static_assert(offsetof(BvhGpuNode, origin) == 0, "origin");
static_assert(offsetof(BvhGpuNode, exponents) == 12, "exponents");
static_assert(offsetof(BvhGpuNode, inner_mask) == 15, "inner_mask");
static_assert(offsetof(BvhGpuNode, child_base) == 16, "child_base");
static_assert(offsetof(BvhGpuNode, triangle_base) == 20, "triangle_base");
static_assert(offsetof(BvhGpuNode, meta) == 24, "meta");
static_assert(offsetof(BvhGpuNode, quantized_min) == 32, "quantized_min");
static_assert(offsetof(BvhGpuNode, quantized_max) == 56, "quantized_max");

static_assert(sizeof(BvhGpuTriangle) == 40, "GpuTriangle is 40 bytes");
static_assert(offsetof(BvhGpuTriangle, vertices) == 0, "vertices");
static_assert(offsetof(BvhGpuTriangle, triangle_index) == 36, "triangle_index");

#ifdef __cplusplus
}
#endif

#endif /* BVHC_BVH_H */
