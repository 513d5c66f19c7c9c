/* Hit filters through the C API. Usage: capi_filter FILE.bvh RAYS.bin (bvhc trace's ray format). The filter
 * rejects candidates whose source id hashes to a multiple of 3, and those with u > 0.7 (the test's filter in
 * tests/suite/filters.rs). For each ray one line: "hit t triangle" (t as bit pattern in hex) or "miss", then
 * "any 0|1", for BVHC_FILTER_NOT_OPAQUE; batches, on one thread and on four, must agree with single calls. The
 * filter checks each candidate's source primitive and vertices against the inline readers of bvhc_sections,
 * which must agree with the exported getters. Last line: "asked N opaque M wrong W" (calls of the filter, of
 * those on triangles the file marks opaque: must be 0, and candidates whose source fields disagree: must be 0).
 * Exit codes name a failed check. tests/suite/capi.rs compares the lines with Rust's filtered tracer. */
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../crates/bvhc-capi/include/bvhc.h"
#include "test_io.h"

_Static_assert(sizeof(void *) != 8 || sizeof(bvhc_candidate) == 56, "bvhc_candidate as Rust lays it out");
_Static_assert(sizeof(void *) != 8 || sizeof(bvhc_sections) == 56, "bvhc_sections as Rust lays it out");
_Static_assert(sizeof(bvhc_source_range) == 32, "bvhc_source_range is the file's SourceRange");

/* Counted atomically: the threaded batches call the filter from several threads at once. */
typedef struct counts {
    const bvhc_file *file;
    bvhc_sections sections;
    atomic_ulong asked, opaque, wrong;
} counts;

/* Whether the candidate's source fields are what the file's arrays say. */
static int source_fields_agree(const counts *c, const bvhc_candidate *candidate) {
    const bvhc_sections *s = &c->sections;
    if (bvhc_sections_source_id(s, candidate->triangle_index) != candidate->source_triangle_id) return 0;
    const bvhc_source_range *range = bvhc_sections_source_range(s, candidate->source_triangle_id);
    uint32_t mesh = range ? range->mesh_index : BVHC_NO_INDEX, primitive = range ? range->primitive_index : BVHC_NO_INDEX;
    uint32_t node = range ? range->node_index : BVHC_NO_INDEX;
    if (node == BVHC_NO_INDEX && candidate->instance_index != BVHC_NO_INSTANCE) {
        bvhc_instance instance;
        if (bvhc_get_instance(c->file, candidate->instance_index, &instance) != BVHC_OK) return 0;
        node = instance.node_index;
    }
    if (candidate->mesh_index != mesh || candidate->primitive_index != primitive || candidate->node_index != node)
        return 0;
    const uint32_t *vertices = bvhc_sections_source_vertices(s, candidate->triangle_index);
    for (int k = 0; k < 3; k++)
        if (candidate->source_vertices[k] != (vertices ? vertices[k] : BVHC_NO_INDEX)) return 0;
    return 1;
}

static int accepts(void *user_data, const bvhc_candidate *candidate) {
    counts *c = user_data;
    atomic_fetch_add(&c->asked, 1);
    if (!(bvhc_triangle_flags(c->file, candidate->triangle_index) & BVHC_TRIANGLE_NOT_OPAQUE))
        atomic_fetch_add(&c->opaque, 1);
    if (!source_fields_agree(c, candidate)) atomic_fetch_add(&c->wrong, 1);
    unsigned instance = candidate->instance_index == BVHC_NO_INSTANCE ? 0u : candidate->instance_index + 1u;
    unsigned hash = (candidate->source_triangle_id * 2654435761u) ^ (instance * 40503u);
    return hash % 3u != 0u && candidate->u <= 0.7f;
}

int main(int argc, char **argv) {
    if (argc < 3) return 2;
    bvhc_file *file = NULL;
    if (bvhc_open(argv[1], &file) != BVHC_OK) return 1;
    FILE *f = fopen(argv[2], "rb");
    if (!f) return 3;
    fseek(f, 0, SEEK_END);
    size_t count = (size_t)ftell(f) / sizeof(bvhc_ray);
    rewind(f);
    bvhc_ray *rays = malloc(count * sizeof(bvhc_ray) + 1);
    bvhc_hit *hits = malloc(count * sizeof(bvhc_hit) + 1);
    uint8_t *found = malloc(count + 1), *occluded = malloc(count + 1);
    if (!rays || !hits || !found || !occluded || fread(rays, sizeof(bvhc_ray), count, f) != count) return 4;
    fclose(f);
    static counts c;
    c.file = file;
    if (bvhc_get_sections(file, &c.sections) != BVHC_OK || c.sections.triangle_count != bvhc_triangle_count(file))
        return 20;
    /* The inline readers agree with the exported getters. */
    for (uint32_t t = 0; t <= c.sections.triangle_count; t++) {
        if (bvhc_sections_source_id(&c.sections, t) != bvhc_source_id(file, t)) return 21;
        if (bvhc_sections_triangle_flags(&c.sections, t) != bvhc_triangle_flags(file, t)) return 22;
        uint32_t id = bvhc_source_id(file, t);
        bvhc_source_range range;
        const bvhc_source_range *inline_range = bvhc_sections_source_range(&c.sections, id);
        int status = bvhc_source_range_of(file, id, &range);
        if (inline_range ? status != BVHC_OK || memcmp(inline_range, &range, sizeof range) != 0 : status == BVHC_OK)
            return 23;
        float vertices[9];
        if (t < c.sections.triangle_count &&
            (bvhc_triangle_vertices(file, t, vertices) != BVHC_OK || memcmp(vertices, c.sections.triangles[t], 36) != 0))
            return 24;
    }
    if (bvhc_closest_hits_filtered(file, rays, count, hits, found, accepts, &c, BVHC_FILTER_NOT_OPAQUE) != BVHC_OK)
        return 5;
    if (bvhc_any_hits_filtered(file, rays, count, occluded, accepts, &c, BVHC_FILTER_NOT_OPAQUE) != BVHC_OK) return 6;
    /* On four threads (and on every core): the same results. */
    bvhc_hit *threaded_hits = malloc(count * sizeof(bvhc_hit) + 1);
    uint8_t *threaded_found = malloc(count + 1), *threaded_occluded = malloc(count + 1);
    if (!threaded_hits || !threaded_found || !threaded_occluded) return 4;
    for (size_t threads = 0; threads <= 4; threads += 4) {
        if (bvhc_closest_hits_filtered_threads(file, rays, count, threaded_hits, threaded_found, accepts, &c,
                                               BVHC_FILTER_NOT_OPAQUE, threads) != BVHC_OK ||
            bvhc_any_hits_filtered_threads(file, rays, count, threaded_occluded, accepts, &c, BVHC_FILTER_NOT_OPAQUE,
                                           threads) != BVHC_OK)
            return 25;
        if (memcmp(threaded_found, found, count) != 0 || memcmp(threaded_occluded, occluded, count) != 0) return 26;
        for (size_t i = 0; i < count; i++)
            if (found[i] && memcmp(&threaded_hits[i], &hits[i], sizeof(bvhc_hit)) != 0) return 27;
    }
    free(threaded_hits);
    free(threaded_found);
    free(threaded_occluded);
    for (size_t i = 0; i < count; i++) {
        bvhc_hit hit;
        int closest = bvhc_closest_hit_filtered(file, &rays[i], &hit, accepts, &c, BVHC_FILTER_NOT_OPAQUE);
        int any = bvhc_any_hit_filtered(file, &rays[i], accepts, &c, BVHC_FILTER_NOT_OPAQUE);
        if (closest < 0 || any < 0) return 7;
        if (closest != found[i] || any != occluded[i]) return 8;
        if (closest && memcmp(&hit, &hits[i], sizeof hit) != 0) return 9;
        if (closest)
            printf("hit %08x %u\n", bits(hit.t), hit.triangle_index);
        else
            printf("miss\n");
        printf("any %d\n", any);
    }
    /* Errors: a null filter, an unknown scope, a broken ray, an index out of range. */
    bvhc_hit hit;
    if (bvhc_closest_hit_filtered(file, &rays[0], &hit, NULL, NULL, BVHC_FILTER_EVERY) != -1) return 10;
    if (!strstr(bvhc_last_error_message(), "filter must not be null")) return 11;
    if (bvhc_any_hit_filtered(file, &rays[0], accepts, &c, 7) != -1) return 12;
    if (!strstr(bvhc_last_error_message(), "scope 7")) return 13;
    bvhc_ray bad = rays[0];
    bad.t_min = -1.0f;
    if (bvhc_closest_hit_filtered(file, &bad, &hit, accepts, &c, BVHC_FILTER_EVERY) != -1) return 14;
    if (bvhc_any_hits_filtered(file, &bad, 1, occluded, accepts, &c, BVHC_FILTER_EVERY) != BVHC_ERROR_RAY) return 15;
    if (bvhc_triangle_flags(file, (uint32_t)bvhc_triangle_count(file)) != -1) return 16;
    printf("asked %lu opaque %lu wrong %lu\n", (unsigned long)c.asked, (unsigned long)c.opaque,
           (unsigned long)c.wrong);
    bvhc_close(file);
    free(rays);
    free(hits);
    free(found);
    free(occluded);
    return 0;
}
