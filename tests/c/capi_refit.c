/* Moves geometry through the C API: refits a one-level .bvh to the positions of a float file (9 a record), on
 * two threads, checks the refusals, traces the rays of a ray file and writes the file back; then moves the
 * instances of a two-level .bvh by the 3x4 maps of a float file (12 an instance, instance k by map k) and traces
 * the same rays, then rebuilds its top trees (printing their cost before and after as "top") and traces them
 * again. One line per ray: "hit t triangle instance" (t as a bit pattern in hex) or "miss"; the report's
 * cost ratio as "ratio" and 17 significant digits. tests/suite/capi_refit.rs compares with Rust.
 * Usage: capi_refit ONE.bvh POSITIONS.bin RAYS.bin OUT.bvh TWO.bvh TRANSFORMS.bin */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../crates/bvhc-capi/include/bvhc.h"
#include "test_io.h"

int main(int argc, char **argv) {
    if (argc < 7) return 100;
    size_t positions_len, rays_len, transforms_len;
    float *positions = read_all(argv[2], &positions_len);
    bvhc_ray *rays = read_all(argv[3], &rays_len);
    float *transforms = read_all(argv[6], &transforms_len);
    if (!positions || !rays || !transforms) return 101;
    size_t records = positions_len / (9 * sizeof(float)), ray_count = rays_len / sizeof(bvhc_ray);
    size_t moved = transforms_len / (12 * sizeof(float));
    bvhc_file *one = NULL, *two = NULL;
    if (bvhc_open(argv[1], &one) != BVHC_OK || bvhc_open(argv[5], &two) != BVHC_OK) return 102;
    /* Refusals, each leaving the file as it was: another count, a NaN, another file's count, nulls. */
    bvhc_refit_report report;
    if (bvhc_refit_triangles(one, positions, records - 1, 2, &report) != BVHC_ERROR_ARGUMENT) return 103;
    printf("refused: %s\n", bvhc_last_error_message());
    float saved = positions[4];
    positions[4] = NAN;
    if (bvhc_refit_triangles(one, positions, records, 2, NULL) != BVHC_ERROR_ARGUMENT) return 104;
    printf("refused: %s\n", bvhc_last_error_message());
    positions[4] = saved;
    if (bvhc_refit_triangles(two, positions, records, 2, NULL) != BVHC_ERROR_ARGUMENT) return 105;
    if (bvhc_refit_triangles(NULL, positions, records, 2, NULL) != BVHC_ERROR_ARGUMENT) return 106;
    if (bvhc_move_instances(one, NULL, NULL, 0) != BVHC_ERROR_ARGUMENT) return 107;
    printf("refused: %s\n", bvhc_last_error_message());
    /* The refit, then a per-source-vertex call that keeps every range (one range: the OBJ's vertices). */
    if (bvhc_refit_triangles(one, positions, records, 2, &report) != BVHC_OK) {
        fprintf(stderr, "refit: %s\n", bvhc_last_error_message());
        return 108;
    }
    double planned = 0.0;
    int plan = bvhc_planned_cost_ratio(one, &planned);
    printf("ratio %.17g planned %s\n", report.cost_ratio, plan == BVHC_ERROR_NOT_IN_FILE ? "none" : "some");
    const float *keep[1] = {NULL};
    size_t counts[1] = {0};
    if (bvhc_refit_source_vertices(one, keep, counts, 1, 1, NULL) != BVHC_OK) return 109;
    if (bvhc_refit_source_vertices(one, keep, counts, 2, 1, NULL) != BVHC_ERROR_ARGUMENT) return 110;
    printf("refused: %s\n", bvhc_last_error_message());
    if (bvhc_verify(one) == BVHC_OK) return 111; /* the stated costs describe the converted pose */
    print_closest_hits(one, rays, ray_count);
    if (bvhc_write(one, argv[4]) != BVHC_OK) {
        fprintf(stderr, "write: %s\n", bvhc_last_error_message());
        return 112;
    }
    /* Instances. */
    uint32_t *indices = malloc(moved * sizeof(uint32_t) + 1);
    if (!indices) return 113;
    for (size_t k = 0; k < moved; k++) indices[k] = (uint32_t)k;
    if (bvhc_move_instances(two, indices, transforms, moved) != BVHC_OK) {
        fprintf(stderr, "move: %s\n", bvhc_last_error_message());
        return 114;
    }
    if (bvhc_verify(two) != BVHC_OK) return 115;
    print_closest_hits(two, rays, ray_count);
    /* The top trees built anew over the moved instances: their cost before and after, then the same rays. */
    double before, after;
    if (bvhc_top_tree_cost(one, &before) != BVHC_ERROR_NOT_IN_FILE) return 116;
    if (bvhc_rebuild_top_trees(one) != BVHC_ERROR_ARGUMENT) return 117;
    if (bvhc_top_tree_cost(two, &before) != BVHC_OK || bvhc_rebuild_top_trees(two) != BVHC_OK) return 118;
    if (bvhc_top_tree_cost(two, &after) != BVHC_OK || bvhc_verify(two) != BVHC_OK) return 119;
    printf("top %.17g %.17g\n", before, after);
    print_closest_hits(two, rays, ray_count);
    bvhc_close(one);
    bvhc_close(two);
    free(positions);
    free(rays);
    free(transforms);
    free(indices);
    return 0;
}
