/* Point queries through the C API. Usage: capi_points FILE.bvh POINTS.bin MAX_DISTANCE, POINTS.bin holding
 * float[3] records. Prints a line a point, "near <distance bits> <triangle> <instance> <x y z bits>" or "none",
 * from bvhc_closest_points on 2 threads, after checking that bvhc_closest_point gives the same record a point;
 * then a line a point "signed <bits> winding <double bits>" (bvhc_signed_distances, bvhc_winding_numbers); then the
 * first kind of line again from bvhc_closest_points_filtered keeping the odd records; then checks
 * that the argument errors are refused; last line "checks ok". tests/suite/capi_points.rs compares with Rust. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../crates/bvhc-capi/include/bvhc.h"
#include "test_io.h"

static int failed(const char *what) {
    fprintf(stderr, "check failed: %s (last message: %s)\n", what, bvhc_last_error_message());
    return 1;
}

#define CHECK(condition)                             \
    do {                                             \
        if (!(condition)) return failed(#condition); \
    } while (0)

static int expected_user_data;

/* Keeps the odd records; refuses everything when called with other user data. */
static int keep_odd(void *user_data, uint32_t triangle_index, uint32_t source_triangle_id, uint32_t instance_index) {
    (void)source_triangle_id, (void)instance_index;
    return user_data == &expected_user_data && triangle_index % 2 == 1;
}

static void print_record(const bvhc_nearest_point *p) {
    if (p->triangle_index != BVHC_NO_INDEX)
        printf("near %08x %u %d %08x %08x %08x\n", bits(p->distance), p->triangle_index, (int)p->instance_index,
               bits(p->point[0]), bits(p->point[1]), bits(p->point[2]));
    else
        printf("none\n");
}

int main(int argc, char **argv) {
    if (argc != 4) return failed("usage: capi_points FILE.bvh POINTS.bin MAX_DISTANCE");
    bvhc_file *file = NULL;
    CHECK(bvhc_open(argv[1], &file) == BVHC_OK);
    size_t len = 0;
    float *points = read_all(argv[2], &len);
    CHECK(points != NULL && len % 12 == 0);
    size_t count = len / 12;
    float max_distance = strcmp(argv[3], "inf") == 0 ? INFINITY : strtof(argv[3], NULL);
    bvhc_nearest_point *out = calloc(count + 1, sizeof *out);
    CHECK(out != NULL);
    CHECK(bvhc_closest_points(file, points, count, max_distance, 2, out) == BVHC_OK);
    for (size_t i = 0; i < count; i++) {
        bvhc_nearest_point one;
        int status = bvhc_closest_point(file, &points[3 * i], max_distance, &one);
        CHECK(status == 0 || status == 1);
        CHECK(memcmp(&one, &out[i], sizeof one) == 0 || (status == 0 && isinf(out[i].distance)));
        CHECK(status == (out[i].triangle_index != BVHC_NO_INDEX));
        print_record(&out[i]);
    }
    /* Signed distances and winding numbers, a line a point. */
    float *signed_distance = malloc(sizeof(float) * (count + 1));
    double *winding = malloc(sizeof(double) * (count + 1));
    CHECK(signed_distance != NULL && winding != NULL);
    CHECK(bvhc_signed_distances(file, points, count, 2, signed_distance) == BVHC_OK);
    CHECK(bvhc_winding_numbers(file, points, count, 0, winding) == BVHC_OK);
    for (size_t i = 0; i < count; i++) {
        unsigned long long w;
        memcpy(&w, &winding[i], sizeof w);
        printf("signed %08x winding %016llx\n", bits(signed_distance[i]), w);
    }
    free(signed_distance);
    free(winding);
    /* Filtered: the odd records only, a line a point. */
    CHECK(bvhc_closest_points_filtered(file, points, count, max_distance, 2, keep_odd, &expected_user_data, out) ==
          BVHC_OK);
    for (size_t i = 0; i < count; i++) {
        CHECK(out[i].triangle_index == BVHC_NO_INDEX || out[i].triangle_index % 2 == 1);
        print_record(&out[i]);
    }
    CHECK(bvhc_closest_points_filtered(file, points, count, max_distance, 1, NULL, NULL, out) == BVHC_ERROR_ARGUMENT);
    CHECK(strstr(bvhc_last_error_message(), "keep") != NULL);
    /* What the calls refuse, by name. */
    float bad[6] = {0, 0, 0, NAN, 0, 0};
    CHECK(bvhc_closest_points(file, bad, 2, INFINITY, 1, out) == BVHC_ERROR_ARGUMENT);
    CHECK(strstr(bvhc_last_error_message(), "point 1") != NULL);
    CHECK(bvhc_closest_point(file, bad, -1.0f, out) == BVHC_ERROR_ARGUMENT);
    CHECK(strstr(bvhc_last_error_message(), "max_distance") != NULL);
    CHECK(bvhc_closest_point(NULL, bad, 1.0f, out) == BVHC_ERROR_ARGUMENT);
    CHECK(bvhc_closest_point(file, NULL, 1.0f, out) == BVHC_ERROR_ARGUMENT);
    CHECK(bvhc_closest_points(file, points, 0, INFINITY, 0, NULL) == BVHC_OK);
    float one;
    CHECK(bvhc_signed_distances(file, bad, 2, 1, &one) == BVHC_ERROR_ARGUMENT);
    CHECK(strstr(bvhc_last_error_message(), "point 1") != NULL);
    free(out);
    free(points);
    bvhc_close(file);
    printf("checks ok\n");
    return 0;
}
