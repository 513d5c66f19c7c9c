/* What a renderer's per-candidate look-ups cost through the C API (benches/capi.rs builds and runs this against
 * the static library). Usage: lookups FILE.bvh RAYS.bin. Prints markdown rows "| what | value |":
 * - nanoseconds a call of each exported getter against its static inline reader over bvhc_sections, over
 *   1,000,000 pseudo-random records;
 * - a filter that needs its candidate's material (glTF mesh, primitive) and texture-coordinate vertices, asked
 *   about every candidate: once finding them as before (a bvhc_hit made from the candidate and
 *   bvhc_hit_source_corners), once reading the candidate's own fields; nanoseconds a filter call more than a
 *   filter that reads nothing, both answering alike;
 * - filtered batches on one thread and on every core (Mrays/s).
 * Medians of 5 runs each. Linux/POSIX (clock_gettime). */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../../crates/bvhc-capi/include/bvhc.h"

#define RUNS 5
#define LOOKUPS 1000000u

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int compare(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *values) {
    qsort(values, RUNS, sizeof(double), compare);
    return values[RUNS / 2];
}

static const bvhc_file *file;
static bvhc_sections sections;
static volatile unsigned long sink;

/* Pseudo-random record indices (an LCG), the same sequence for every getter. */
static uint32_t *indices;

typedef unsigned long (*pass)(void);

static unsigned long exported_source_id(void) {
    unsigned long sum = 0;
    for (uint32_t i = 0; i < LOOKUPS; i++) sum += bvhc_source_id(file, indices[i]);
    return sum;
}
static unsigned long inline_source_id(void) {
    unsigned long sum = 0;
    for (uint32_t i = 0; i < LOOKUPS; i++) sum += bvhc_sections_source_id(&sections, indices[i]);
    return sum;
}
static unsigned long exported_flags(void) {
    unsigned long sum = 0;
    for (uint32_t i = 0; i < LOOKUPS; i++) sum += (unsigned long)bvhc_triangle_flags(file, indices[i]);
    return sum;
}
static unsigned long inline_flags(void) {
    unsigned long sum = 0;
    for (uint32_t i = 0; i < LOOKUPS; i++) sum += (unsigned long)bvhc_sections_triangle_flags(&sections, indices[i]);
    return sum;
}
static unsigned long exported_source_vertices(void) {
    unsigned long sum = 0;
    uint32_t v[3];
    for (uint32_t i = 0; i < LOOKUPS; i++)
        if (bvhc_triangle_source_vertices(file, indices[i], v) == BVHC_OK) sum += v[0] + v[1] + v[2];
    return sum;
}
static unsigned long inline_source_vertices(void) {
    unsigned long sum = 0;
    for (uint32_t i = 0; i < LOOKUPS; i++) {
        const uint32_t *v = bvhc_sections_source_vertices(&sections, indices[i]);
        if (v) sum += v[0] + v[1] + v[2];
    }
    return sum;
}
static unsigned long exported_range(void) {
    unsigned long sum = 0;
    bvhc_source_range range;
    for (uint32_t i = 0; i < LOOKUPS; i++)
        if (bvhc_source_range_of(file, bvhc_sections_source_id(&sections, indices[i]), &range) == BVHC_OK)
            sum += range.primitive_index;
    return sum;
}
static unsigned long inline_range(void) {
    unsigned long sum = 0;
    for (uint32_t i = 0; i < LOOKUPS; i++) {
        const bvhc_source_range *r = bvhc_sections_source_range(&sections, bvhc_sections_source_id(&sections, indices[i]));
        if (r) sum += r->primitive_index;
    }
    return sum;
}

static double ns_a_call(pass p) {
    double runs[RUNS];
    for (int r = 0; r < RUNS; r++) {
        double start = now();
        sink = p();
        runs[r] = (now() - start) * 1e9 / LOOKUPS;
    }
    return median(runs);
}

/* Filters: each accepts a candidate unless its material and texture coordinates hash to a multiple of 7. */
static unsigned decide(uint32_t mesh, uint32_t primitive, const uint32_t vertices[3], float u, float v) {
    unsigned h = mesh * 2654435761u ^ primitive * 40503u ^ vertices[0] * 97u ^ vertices[1] * 13u ^ vertices[2];
    return (h + (unsigned)(u * 8.0f) + (unsigned)(v * 8.0f)) % 7u != 0u;
}

static int reads_nothing(void *user_data, const bvhc_candidate *candidate) {
    (void)user_data;
    return candidate->u <= 2.0f; /* accepts everything */
}

static int through_source_corners(void *user_data, const bvhc_candidate *candidate) {
    (void)user_data;
    bvhc_hit hit;
    memset(&hit, 0, sizeof hit);
    hit.t = candidate->t;
    hit.u = candidate->u;
    hit.v = candidate->v;
    hit.triangle_index = candidate->triangle_index;
    hit.source_triangle_id = candidate->source_triangle_id;
    hit.instance_index = candidate->instance_index;
    bvhc_source_corners corners;
    if (bvhc_hit_source_corners(file, &hit, &corners) != BVHC_OK) return 1;
    return (int)decide(corners.mesh_index, corners.primitive_index, corners.vertices, candidate->u, candidate->v);
}

static int from_the_candidate(void *user_data, const bvhc_candidate *candidate) {
    (void)user_data;
    return (int)decide(candidate->mesh_index, candidate->primitive_index, candidate->source_vertices, candidate->u,
                       candidate->v);
}

static long calls;
static int counting(void *user_data, const bvhc_candidate *candidate) {
    (void)user_data;
    (void)candidate;
    calls++;
    return 1;
}

int main(int argc, char **argv) {
    if (argc < 3) return 2;
    bvhc_file *opened = NULL;
    if (bvhc_open(argv[1], &opened) != BVHC_OK) {
        fprintf(stderr, "%s\n", bvhc_last_error_message());
        return 1;
    }
    file = opened;
    if (bvhc_get_sections(file, &sections) != BVHC_OK || sections.triangle_count == 0) return 3;
    FILE *f = fopen(argv[2], "rb");
    if (!f) return 4;
    fseek(f, 0, SEEK_END);
    size_t count = (size_t)ftell(f) / sizeof(bvhc_ray);
    rewind(f);
    bvhc_ray *rays = malloc(count * sizeof(bvhc_ray));
    bvhc_hit *hits = malloc(count * sizeof(bvhc_hit)), *other = malloc(count * sizeof(bvhc_hit));
    uint8_t *found = malloc(count), *other_found = malloc(count);
    indices = malloc(LOOKUPS * sizeof(uint32_t));
    if (!rays || !hits || !other || !found || !other_found || !indices || fread(rays, sizeof(bvhc_ray), count, f) != count)
        return 5;
    fclose(f);
    uint32_t state = 2026u;
    for (uint32_t i = 0; i < LOOKUPS; i++) {
        state = state * 1664525u + 1013904223u;
        indices[i] = (uint32_t)(((uint64_t)state * sections.triangle_count) >> 32);
    }
    struct {
        const char *what;
        pass exported, inlined;
    } getters[] = {
        {"source id", exported_source_id, inline_source_id},
        {"triangle flags", exported_flags, inline_flags},
        {"source vertices", exported_source_vertices, inline_source_vertices},
        {"source range of an id", exported_range, inline_range},
    };
    for (size_t g = 0; g < sizeof getters / sizeof getters[0]; g++) {
        if (getters[g].exported() != getters[g].inlined()) return 6;
        printf("| %s: exported call / static inline reader, ns | %.1f / %.1f |\n", getters[g].what,
               ns_a_call(getters[g].exported), ns_a_call(getters[g].inlined));
    }
    /* The filters, asked about every candidate, one thread. */
    calls = 0;
    if (bvhc_closest_hits_filtered(file, rays, count, hits, found, counting, NULL, BVHC_FILTER_EVERY)) return 7;
    long asked = calls;
    bvhc_filter filters[3] = {reads_nothing, through_source_corners, from_the_candidate};
    double seconds[3];
    for (int k = 0; k < 3; k++) {
        double runs[RUNS];
        for (int r = 0; r < RUNS; r++) {
            double start = now();
            if (bvhc_closest_hits_filtered(file, rays, count, k == 2 ? other : hits, k == 2 ? other_found : found,
                                           filters[k], NULL, BVHC_FILTER_EVERY))
                return 8;
            runs[r] = now() - start;
        }
        seconds[k] = median(runs);
    }
    if (memcmp(found, other_found, count) != 0) return 9;
    for (size_t i = 0; i < count; i++)
        if (found[i] && memcmp(&hits[i], &other[i], sizeof(bvhc_hit)) != 0) return 10;
    printf("| filter calls a ray (every candidate asked) | %.2f |\n", (double)asked / (double)count);
    printf("| a filter finding material and texture vertices: through bvhc_hit_source_corners, ns a call more | %.1f |\n",
           (seconds[1] - seconds[0]) * 1e9 / (double)asked);
    printf("| the same from the candidate's fields, ns a call more | %.1f |\n",
           (seconds[2] - seconds[0]) * 1e9 / (double)asked);
    /* Threads. */
    for (size_t threads = 1; threads <= 2; threads++) {
        double runs[RUNS];
        size_t use = threads == 1 ? 1 : 0;
        for (int r = 0; r < RUNS; r++) {
            double start = now();
            if (bvhc_closest_hits_filtered_threads(file, rays, count, other, other_found, from_the_candidate, NULL,
                                                   BVHC_FILTER_NOT_OPAQUE, use))
                return 11;
            runs[r] = now() - start;
        }
        printf("| filtered closest hits (not-opaque scope), %s, Mrays/s | %.2f |\n",
               use == 1 ? "one thread" : "every core", (double)count / median(runs) / 1e6);
    }
    bvhc_close(opened);
    return 0;
}
