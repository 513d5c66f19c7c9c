/* Hit filters through the C API. Usage: capi_filter FILE.bvh RAYS.bin (bvhc trace's ray format). The filter
 * rejects candidates whose source id hashes to a multiple of 3, and those with u > 0.7 (the test's filter in
 * tests/suite/filters.rs). For each ray one line: "hit t triangle" (t as bit pattern in hex) or "miss", then
 * "any 0|1", for BVHC_FILTER_NOT_OPAQUE; batches must agree with single calls. Last line: "asked N opaque M"
 * (calls of the filter, and of those on triangles the file marks opaque: must be 0). Exit codes name a failed
 * check. tests/suite/capi.rs compares the lines with Rust's filtered tracer. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../crates/bvhc-capi/include/bvhc.h"

typedef struct counts {
    const bvhc_file *file;
    unsigned long asked, opaque;
} counts;

static unsigned bits(float f) {
    unsigned u;
    memcpy(&u, &f, 4);
    return u;
}

static int accepts(void *user_data, const bvhc_candidate *candidate) {
    counts *c = user_data;
    c->asked++;
    if (!(bvhc_triangle_flags(c->file, candidate->triangle_index) & BVHC_TRIANGLE_NOT_OPAQUE)) c->opaque++;
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
    counts c = {file, 0, 0};
    if (bvhc_closest_hits_filtered(file, rays, count, hits, found, accepts, &c, BVHC_FILTER_NOT_OPAQUE) != BVHC_OK)
        return 5;
    if (bvhc_any_hits_filtered(file, rays, count, occluded, accepts, &c, BVHC_FILTER_NOT_OPAQUE) != BVHC_OK) return 6;
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
    printf("asked %lu opaque %lu\n", c.asked, c.opaque);
    bvhc_close(file);
    free(rays);
    free(hits);
    free(found);
    free(occluded);
    return 0;
}
