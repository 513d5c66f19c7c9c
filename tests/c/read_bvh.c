/* A reader written against format-spec/bvh.h alone: checks the structural rules it needs (V1-V6 for the
 * sections it reads), then prints the layout constants and what it found, one "key value" per line, for
 * tests/suite/c_header.rs to compare with the Rust reader. Exit 1 with a message on any broken rule. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../format-spec/bvh.h"

static int fail(const char *what) {
    fprintf(stderr, "read_bvh: %s\n", what);
    return 1;
}

int main(int argc, char **argv) {
    printf("sizeof_header %zu\nsizeof_entry %zu\nsizeof_node %zu\nsizeof_triangle %zu\n", sizeof(BvhFileHeader),
           sizeof(BvhSectionEntry), sizeof(BvhPackedNode), sizeof(BvhPackedTriangle));
    printf("sizeof_source_range %zu\nsizeof_wide_node %zu\nsizeof_packet %zu\n", sizeof(BvhSourceRange),
           sizeof(BvhWideNode8), sizeof(BvhTrianglePacket4));
    printf("sizeof_gpu_node %zu\nsizeof_gpu_triangle %zu\n", sizeof(BvhGpuNode), sizeof(BvhGpuTriangle));
    if (argc < 2) return 0;
    FILE *f = fopen(argv[1], "rb");
    if (!f) return fail("cannot open the file");
    if (fseek(f, 0, SEEK_END) != 0) return fail("cannot seek");
    long len = ftell(f);
    if (len < (long)sizeof(BvhFileHeader)) return fail("V1: shorter than the header");
    rewind(f);
    /* uint64_t storage keeps the buffer 8-byte aligned, as the header and the table need. */
    uint64_t *words = calloc((size_t)len / 8 + 1, 8);
    if (!words) return fail("out of memory");
    unsigned char *bytes = (unsigned char *)words;
    if (fread(bytes, 1, (size_t)len, f) != (size_t)len) return fail("short read");
    fclose(f);
    const BvhFileHeader *header = (const BvhFileHeader *)bytes;
    if (memcmp(header->magic, BVH_MAGIC, BVH_MAGIC_BYTE_LEN) != 0) return fail("V1: magic");
    if (header->version_major != BVH_VERSION_MAJOR) return fail("V2: version_major");
    if (header->file_byte_len != (uint64_t)len) return fail("V3: file_byte_len");
    uint64_t table_end = BVH_HEADER_BYTE_LEN + (uint64_t)header->section_count * header->section_entry_byte_len;
    if (header->section_entry_byte_len < BVH_SECTION_ENTRY_BYTE_LEN || table_end > (uint64_t)len)
        return fail("V4: section table");
    printf("version %u.%u\n", header->version_major, header->version_minor);
    const BvhPackedNode *nodes = NULL;
    uint64_t node_count = 0, triangle_count = 0, wide_count = 0, packet_count = 0;
    const BvhWideNode8 *wide = NULL;
    const BvhGpuNode *gpu = NULL;
    uint64_t gpu_count = 0, gpu_triangle_count = 0;
    for (uint32_t i = 0; i < header->section_count; i++) {
        const BvhSectionEntry *e =
            (const BvhSectionEntry *)(bytes + BVH_HEADER_BYTE_LEN + (uint64_t)i * header->section_entry_byte_len);
        if (e->section_byte_offset % BVH_SECTION_ALIGNMENT != 0 || e->section_byte_offset > (uint64_t)len ||
            e->section_byte_len > (uint64_t)len - e->section_byte_offset)
            return fail("V5: section placement");
        if (e->element_byte_len == 0 || e->section_byte_len / e->element_byte_len != e->element_count ||
            e->section_byte_len % e->element_byte_len != 0)
            return fail("V6: section size");
        const void *data = bytes + e->section_byte_offset;
        switch (e->kind) {
        case BVH_KIND_NODES:
            if (e->element_byte_len != sizeof(BvhPackedNode)) return fail("V9: node size");
            nodes = data;
            node_count = e->element_count;
            break;
        case BVH_KIND_TRIANGLES:
            if (e->element_byte_len != sizeof(BvhPackedTriangle)) return fail("V9: triangle size");
            triangle_count = e->element_count;
            printf("split_references %d\n", (e->section_flags & BVH_SECTION_FLAG_SPLIT_REFERENCES) != 0);
            break;
        case BVH_KIND_WIDE_NODES:
            if (e->element_byte_len != sizeof(BvhWideNode8)) return fail("V9: wide node size");
            wide = data;
            wide_count = e->element_count;
            break;
        case BVH_KIND_TRIANGLE_PACKETS:
            if (e->element_byte_len != sizeof(BvhTrianglePacket4)) return fail("V9: packet size");
            packet_count = e->element_count;
            break;
        case BVH_KIND_GPU_NODES:
            if (e->element_byte_len != sizeof(BvhGpuNode)) return fail("V9: GPU node size");
            gpu = data;
            gpu_count = e->element_count;
            break;
        case BVH_KIND_GPU_TRIANGLES:
            if (e->element_byte_len != sizeof(BvhGpuTriangle)) return fail("V9: GPU triangle size");
            gpu_triangle_count = e->element_count;
            break;
        default:
            break;
        }
    }
    printf("node_count %llu\ntriangle_count %llu\n", (unsigned long long)node_count,
           (unsigned long long)triangle_count);
    printf("wide_node_count %llu\npacket_count %llu\n", (unsigned long long)wide_count,
           (unsigned long long)packet_count);
    uint64_t leaves = 0;
    for (uint64_t n = 0; n < node_count; n++) leaves += nodes[n].count != 0;
    printf("leaf_count %llu\n", (unsigned long long)leaves);
    uint64_t leaf_packets = 0;
    for (uint64_t n = 0; n < wide_count; n++)
        for (int s = 0; s < BVH_WIDE && wide[n].child[s] != BVH_EMPTY_SLOT; s++)
            if (wide[n].child[s] & BVH_LEAF_BIT) leaf_packets += BVH_LEAF_PACKET_COUNT(wide[n].child[s]);
    printf("leaf_packets %llu\n", (unsigned long long)leaf_packets);
    uint64_t gpu_leaf_triangles = 0, gpu_inner = 0;
    for (uint64_t n = 0; n < gpu_count; n++)
        for (unsigned s = 0; s < 8; s++) {
            uint8_t meta = gpu[n].meta[s];
            if (meta == BVH_GPU_INNER_META(s)) gpu_inner++;
            else if (meta != 0) gpu_leaf_triangles += BVH_GPU_LEAF_COUNT(meta);
        }
    printf("gpu_node_count %llu\ngpu_triangle_count %llu\n", (unsigned long long)gpu_count,
           (unsigned long long)gpu_triangle_count);
    printf("gpu_inner_slots %llu\ngpu_leaf_triangles %llu\n", (unsigned long long)gpu_inner,
           (unsigned long long)gpu_leaf_triangles);
    free(words);
    return 0;
}
