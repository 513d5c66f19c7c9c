/* A C program against the installed libbvhc, built as a user builds it:
 *
 *   cc trace.c $(pkg-config --cflags --libs bvhc) -o trace      # or CMake: find_package(bvhc), bvhc::bvhc
 *   ./trace scene.bvh
 *
 * It opens and verifies a .bvh file, shoots a grid of rays straight down (-y) through the scene's bounds, one
 * batch, and prints how many hit, the nearest hit, and where it came from in the source scene (glTF node and
 * mesh, through the instance of a two-level file), then a secondary ray spawned from it. Errors are printed
 * with their status name and message, and give exit status 1. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include <bvhc.h>

#define GRID 64

static int fail(const char *what, bvhc_status status) {
    char message[512];
    bvhc_error_message(message, sizeof message);
    fprintf(stderr, "%s: %s: %s\n", what, bvhc_status_name(status), message);
    return 1;
}

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s scene.bvh\n", argv[0]);
        return 2;
    }
    bvhc_file *file = NULL;
    bvhc_status status = bvhc_open(argv[1], &file);
    if (status != BVHC_OK) return fail("open", status);
    if ((status = bvhc_verify(file)) != BVHC_OK) return fail("verify", status);
    float min[3], max[3];
    if ((status = bvhc_scene_bounds(file, min, max)) != BVHC_OK) return fail("bounds", status);
    printf("%zu triangles, %zu meshes, %zu instances\n", bvhc_triangle_count(file), bvhc_mesh_count(file),
           bvhc_instance_count(file));

    static bvhc_ray rays[GRID * GRID];
    static bvhc_hit hits[GRID * GRID];
    static uint8_t found[GRID * GRID];
    for (int j = 0; j < GRID; j++)
        for (int i = 0; i < GRID; i++) {
            bvhc_ray *ray = &rays[j * GRID + i];
            ray->origin[0] = min[0] + (max[0] - min[0]) * ((float)i + 0.5f) / GRID;
            ray->origin[1] = max[1] + 1.0f;
            ray->origin[2] = min[2] + (max[2] - min[2]) * ((float)j + 0.5f) / GRID;
            ray->direction[0] = 0.0f, ray->direction[1] = -1.0f, ray->direction[2] = 0.0f;
            ray->t_min = 0.0f;
            ray->t_max = INFINITY;
        }
    if ((status = bvhc_closest_hits(file, rays, GRID * GRID, hits, found)) != BVHC_OK) return fail("trace", status);
    size_t hit_count = 0, nearest = 0;
    for (size_t k = 0; k < GRID * GRID; k++)
        if (found[k] && (hit_count++ == 0 || hits[k].t < hits[nearest].t)) nearest = k;
    printf("%zu of %d rays hit\n", hit_count, GRID * GRID);
    if (hit_count > 0) {
        const bvhc_hit *hit = &hits[nearest];
        printf("nearest: t %.6g, triangle %u, source id %u, instance %d\n", hit->t, hit->triangle_index,
               hit->source_triangle_id, hit->instance_index == BVHC_NO_INSTANCE ? -1 : (int)hit->instance_index);
        bvhc_source_corners corners;
        status = bvhc_hit_source_corners(file, hit, &corners);
        if (status == BVHC_OK)
            printf("source: node %d, mesh %u, primitive %u, vertices %u %u %u\n",
                   corners.node_index == BVHC_NO_INDEX ? -1 : (int)corners.node_index, corners.mesh_index,
                   corners.primitive_index, corners.vertices[0], corners.vertices[1], corners.vertices[2]);
        else if (status != BVHC_ERROR_NOT_IN_FILE)
            return fail("source corners", status);
        /* Upwards, away from the surface: the spawned ray leaves the triangle it starts on. */
        float up[3] = {0.0f, 1.0f, 0.0f};
        bvhc_ray spawned;
        if ((status = bvhc_spawn_ray(file, hit, up, &spawned)) != BVHC_OK) return fail("spawn", status);
        int blocked = bvhc_any_hit(file, &spawned);
        if (blocked < 0) return fail("any hit", BVHC_ERROR_ARGUMENT);
        printf("the way up from it is %s\n", blocked ? "blocked" : "open");
    }
    bvhc_close(file);
    return 0;
}
