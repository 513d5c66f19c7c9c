/* A frame of an animated two-level file through the C API: refits mesh 0 of TWO.bvh to the positions of a float
 * file (9 a record of that mesh) on two threads and moves its instances by the 3x4 maps of another (12 an
 * instance, instance k by map k) without recomputing the checksums, checks the refusals (printed as "refused"
 * lines), that the file does not verify before bvhc_write and does after, traces the rays of a ray file and
 * writes the file. One line per ray: "hit t triangle instance" (t as a bit pattern in hex) or "miss".
 * tests/suite/capi_refit.rs compares with Rust.
 * Usage: capi_frame TWO.bvh POSITIONS.bin TRANSFORMS.bin RAYS.bin OUT.bvh ONE.bvh */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../crates/bvhc-capi/include/bvhc.h"
#include "test_io.h"

int main(int argc, char **argv) {
    if (argc < 7) return 100;
    size_t positions_len, transforms_len, rays_len;
    float *positions = read_all(argv[2], &positions_len);
    float *transforms = read_all(argv[3], &transforms_len);
    bvhc_ray *rays = read_all(argv[4], &rays_len);
    if (!positions || !transforms || !rays) return 101;
    size_t records = positions_len / (9 * sizeof(float)), moved = transforms_len / (12 * sizeof(float));
    size_t ray_count = rays_len / sizeof(bvhc_ray);
    bvhc_file *two = NULL, *one = NULL;
    if (bvhc_open(argv[1], &two) != BVHC_OK || bvhc_open(argv[6], &one) != BVHC_OK) return 102;
    bvhc_mesh mesh;
    if (bvhc_get_mesh(two, 0, &mesh) != BVHC_OK || mesh.triangle_count != records) return 103;
    /* Refusals, each leaving the file as it was. */
    if (bvhc_refit_mesh(one, 0, positions, records, 2) != BVHC_ERROR_ARGUMENT) return 104;
    printf("refused: %s\n", bvhc_last_error_message());
    if (bvhc_refit_mesh(two, 7, positions, records, 2) != BVHC_ERROR_ARGUMENT) return 105;
    printf("refused: %s\n", bvhc_last_error_message());
    if (bvhc_refit_mesh(two, 0, positions, records - 1, 2) != BVHC_ERROR_ARGUMENT) return 106;
    printf("refused: %s\n", bvhc_last_error_message());
    if (bvhc_refit_mesh(two, 0, NULL, records, 2) != BVHC_ERROR_ARGUMENT) return 107;
    if (bvhc_move_instances_in_frame(one, NULL, NULL, 0) != BVHC_ERROR_ARGUMENT) return 108;
    printf("refused: %s\n", bvhc_last_error_message());
    if (bvhc_verify(two) != BVHC_OK) return 109;
    /* The frame. */
    uint32_t *indices = malloc(moved * sizeof(uint32_t) + 1);
    if (!indices) return 110;
    for (size_t k = 0; k < moved; k++) indices[k] = (uint32_t)k;
    if (bvhc_refit_mesh(two, 0, positions, records, 2) != BVHC_OK ||
        bvhc_move_instances_in_frame(two, indices, transforms, moved) != BVHC_OK) {
        fprintf(stderr, "frame: %s\n", bvhc_last_error_message());
        return 111;
    }
    printf("verify %s\n", bvhc_verify(two) == BVHC_OK ? "passes" : "fails");
    print_closest_hits(two, rays, ray_count);
    if (bvhc_write(two, argv[5]) != BVHC_OK) {
        fprintf(stderr, "write: %s\n", bvhc_last_error_message());
        return 112;
    }
    bvhc_close(one);
    bvhc_close(two);
    free(positions);
    free(transforms);
    free(rays);
    free(indices);
    return 0;
}
