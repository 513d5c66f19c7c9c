/* Opens a .bvh through the C API, verifies it, traces the rays of a ray file (bvhc trace's format) one at a
 * time and in a batch, and writes one line per ray: "hit t u v nx ny nz triangle source front any s0 s1 s2 mesh
 * w0 instance node" (s: the source vertices, w0 the weight of s0, node the glTF node that placed it) or "miss any", floats as bit patterns in hex; first the
 * struct sizes. tests/suite/capi.rs compares with Rust. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../crates/bvhc-capi/include/bvhc.h"
#include "test_io.h"

int main(int argc, char **argv) {
    printf("sizeof_ray %zu\nsizeof_hit %zu\nsizeof_source_corners %zu\n", sizeof(bvhc_ray), sizeof(bvhc_hit),
           sizeof(bvhc_source_corners));
    if (argc < 3) return 0;
    bvhc_file *file = NULL;
    if (bvhc_open(NULL, &file) != BVHC_ERROR_ARGUMENT) return 10;
    if (bvhc_open("/nonexistent/x.bvh", &file) != BVHC_ERROR_IO || strlen(bvhc_last_error_message()) == 0) return 11;
    if (bvhc_open(argv[1], &file) != BVHC_OK) {
        fprintf(stderr, "open: %s\n", bvhc_last_error_message());
        return 1;
    }
    if (bvhc_verify(file) != BVHC_OK) return 2;
    FILE *f = fopen(argv[2], "rb");
    if (!f) return 3;
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    rewind(f);
    size_t count = (size_t)len / sizeof(bvhc_ray);
    bvhc_ray *rays = malloc(count * sizeof(bvhc_ray) + 1);
    bvhc_hit *hits = malloc(count * sizeof(bvhc_hit) + 1);
    bvhc_hit *coherent_hits = malloc(count * sizeof(bvhc_hit) + 1);
    uint8_t *found = malloc(count + 1), *occluded = malloc(count + 1);
    uint8_t *coherent_found = malloc(count + 1), *coherent_occluded = malloc(count + 1);
    if (!rays || !hits || !found || !occluded || !coherent_hits || !coherent_found || !coherent_occluded ||
        fread(rays, sizeof(bvhc_ray), count, f) != count)
        return 4;
    fclose(f);
    if (bvhc_closest_hits(file, rays, count, hits, found) != BVHC_OK) return 5;
    if (bvhc_any_hits(file, rays, count, occluded) != BVHC_OK) return 6;
    if (bvhc_closest_hits_coherent(file, rays, count, coherent_hits, coherent_found) != BVHC_OK) return 16;
    if (bvhc_any_hits_coherent(file, rays, count, coherent_occluded) != BVHC_OK) return 17;
    if (bvhc_closest_hit(file, NULL, hits) != -1) return 7;
    for (size_t i = 0; i < count; i++) {
        bvhc_hit one;
        int hit = bvhc_closest_hit(file, &rays[i], &one);
        int any = bvhc_any_hit(file, &rays[i]);
        if (hit != found[i] || any != occluded[i]) return 8;
        if (hit && memcmp(&one, &hits[i], sizeof one) != 0) return 9;
        /* Coherent groups: the same answers, and the same t (a tie may name another triangle). */
        if (coherent_found[i] != found[i] || coherent_occluded[i] != occluded[i]) return 18;
        if (hit && bits(coherent_hits[i].t) != bits(one.t)) return 19;
        if (!hit) {
            printf("miss %d\n", any);
            continue;
        }
        bvhc_source_corners corners;
        if (bvhc_hit_source_corners(file, &one, &corners) != BVHC_OK) return 15;
        printf("hit %08x %08x %08x %08x %08x %08x %u %u %u %d %u %u %u %u %08x %u %u\n", bits(one.t), bits(one.u),
               bits(one.v), bits(one.normal[0]), bits(one.normal[1]), bits(one.normal[2]), one.triangle_index,
               one.source_triangle_id, one.front_face, any, corners.vertices[0], corners.vertices[1],
               corners.vertices[2], corners.mesh_index, bits(corners.weights[0]), one.instance_index,
               corners.node_index);
        if (bvhc_source_id(file, one.triangle_index) != one.source_triangle_id) return 12;
        /* A secondary ray away from the surface never meets the triangle it leaves. */
        float away[3] = {one.normal[0], one.normal[1], one.normal[2]};
        if (!one.front_face) away[0] = -away[0], away[1] = -away[1], away[2] = -away[2];
        bvhc_ray spawned;
        bvhc_hit again;
        if (bvhc_spawn_ray(file, &one, away, &spawned) != BVHC_OK) return 13;
        if (bvhc_closest_hit(file, &spawned, &again) == 1 && again.source_triangle_id == one.source_triangle_id &&
            again.instance_index == one.instance_index)
            return 14;
    }
    bvhc_close(file);
    free(rays);
    free(hits);
    free(found);
    free(occluded);
    free(coherent_hits);
    free(coherent_found);
    free(coherent_occluded);
    return 0;
}
