/* What a file holds, through the C API, and how the API refuses what breaks its contracts. Usage:
 * capi_scene FILE.bvh METADATA_OUT. Writes the metadata JSON to METADATA_OUT and prints, floats as bit patterns
 * in hex: "bounds" with the scene's box, "meshes N" and each "mesh i first count", "instances N" and each
 * "instance i <24 floats> mesh node gpu", and each "triangle i <9 floats> s0 s1 s2" (source vertices, or "-"
 * without them). Then it checks the error paths (status names, messages that stay valid, the ray contract in
 * every call, foreign hits, indices out of range) and exits non-zero naming the first that fails; last line
 * "checks ok". tests/suite/capi.rs compares the printed data with Rust. */
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

#define CHECK(condition)                   \
    do {                                   \
        if (!(condition)) return failed(#condition); \
    } while (0)

static int contains(const char *text, const char *part) { return strstr(text, part) != NULL; }

/* The error paths: names, message lifetime, ray contract, foreign hits, ranges. */
static int check_errors(const bvhc_file *file) {
    CHECK(strcmp(bvhc_status_name(BVHC_OK), "BVHC_OK") == 0);
    CHECK(strcmp(bvhc_status_name(BVHC_ERROR_RAY), "BVHC_ERROR_RAY") == 0);
    CHECK(strcmp(bvhc_status_name(BVHC_ERROR_NOT_IN_FILE), "BVHC_ERROR_NOT_IN_FILE") == 0);
    CHECK(strcmp(bvhc_status_name(99), "unknown bvhc_status") == 0);

    /* A message stays valid and unchanged across successful calls, until the next failure. */
    bvhc_file *none = NULL;
    CHECK(bvhc_open("/nonexistent/x.bvh", &none) == BVHC_ERROR_IO);
    const char *message = bvhc_last_error_message();
    char copy[512];
    size_t length = bvhc_error_message(copy, sizeof copy);
    CHECK(length == strlen(message) && length > 0 && strcmp(copy, message) == 0);
    CHECK(contains(message, "/nonexistent/x.bvh"));
    bvhc_ray good = {{0.0f, 0.0f, 10.0f}, {0.0f, 0.0f, -1.0f}, 0.0f, INFINITY};
    bvhc_hit hit;
    CHECK(bvhc_closest_hit(file, &good, &hit) >= 0);
    CHECK(bvhc_verify(file) == BVHC_OK);
    CHECK(strcmp(message, copy) == 0); /* the same pointer, the same text */
    char small[8];
    CHECK(bvhc_error_message(small, sizeof small) == length && strlen(small) == sizeof small - 1);
    CHECK(bvhc_error_message(NULL, 0) == length);
    /* ... and across later failures, until this thread asks again: so a C argument list that calls
       bvhc_last_error_message() before the failing call reads the previous message, never freed memory. */
    CHECK(bvhc_open("/nonexistent/y.bvh", &none) == BVHC_ERROR_IO);
    CHECK(bvhc_open("/nonexistent/z.bvh", &none) == BVHC_ERROR_IO);
    CHECK(strcmp(message, copy) == 0);
    CHECK(contains(bvhc_last_error_message(), "/nonexistent/z.bvh"));
    /* A directory is named as one. */
    CHECK(bvhc_open("/", &none) == BVHC_ERROR_IO && contains(bvhc_last_error_message(), "is a directory"));

    /* The ray contract: each rule refused, naming it; unchecked calls answer without a crash. */
    bvhc_ray bad[6];
    for (int i = 0; i < 6; i++) bad[i] = good;
    bad[0].origin[1] = NAN;
    bad[1].direction[0] = 0.0f, bad[1].direction[1] = 0.0f, bad[1].direction[2] = 0.0f;
    bad[2].origin[0] = INFINITY;
    bad[3].t_max = NAN;
    bad[4].t_min = 2.0f, bad[4].t_max = 1.0f;
    bad[5].t_min = -1.0f;
    const char *rules[6] = {"origin is not finite", "direction is zero", "origin is not finite",
                            "t_max is NaN", "t_max is NaN or below t_min", "t_min is negative"};
    for (int i = 0; i < 6; i++) {
        CHECK(bvhc_closest_hit(file, &bad[i], &hit) == -1);
        CHECK(contains(bvhc_last_error_message(), "bvhc_closest_hit") && contains(bvhc_last_error_message(), rules[i]));
        CHECK(bvhc_any_hit(file, &bad[i]) == -1 && contains(bvhc_last_error_message(), rules[i]));
        int answer = bvhc_closest_hit_unchecked(file, &bad[i], &hit);
        CHECK(answer == 0 || answer == 1);
        answer = bvhc_any_hit_unchecked(file, &bad[i]);
        CHECK(answer == 0 || answer == 1);
    }
    /* A batch with one bad ray: refused before any ray is traced, naming it. */
    bvhc_ray batch[20];
    for (int i = 0; i < 20; i++) batch[i] = good;
    batch[13] = bad[3];
    bvhc_hit hits[20];
    uint8_t found[20], occluded[20];
    memset(found, 7, sizeof found);
    memset(occluded, 7, sizeof occluded);
    CHECK(bvhc_closest_hits(file, batch, 20, hits, found) == BVHC_ERROR_RAY);
    CHECK(contains(bvhc_last_error_message(), "bvhc_closest_hits: ray 13: t_max is NaN"));
    CHECK(bvhc_any_hits(file, batch, 20, occluded) == BVHC_ERROR_RAY);
    CHECK(bvhc_closest_hits_coherent(file, batch, 20, hits, found) == BVHC_ERROR_RAY);
    CHECK(bvhc_any_hits_coherent(file, batch, 20, occluded) == BVHC_ERROR_RAY);
    CHECK(contains(bvhc_last_error_message(), "bvhc_any_hits_coherent: ray 13"));
    for (int i = 0; i < 20; i++) CHECK(found[i] == 7 && occluded[i] == 7);
    size_t first_invalid = 0;
    CHECK(bvhc_check_rays(batch, 20, &first_invalid) == BVHC_ERROR_RAY && first_invalid == 13);
    CHECK(bvhc_check_rays(batch, 13, &first_invalid) == BVHC_OK);
    CHECK(bvhc_closest_hits_unchecked(file, batch, 20, hits, found) == BVHC_OK);
    CHECK(bvhc_any_hits_unchecked(file, batch, 20, occluded) == BVHC_OK);
    CHECK(bvhc_closest_hits_coherent_unchecked(file, batch, 20, hits, found) == BVHC_OK);
    CHECK(bvhc_any_hits_coherent_unchecked(file, batch, 20, occluded) == BVHC_OK);
    for (int i = 0; i < 20; i++) CHECK(found[i] <= 1 && occluded[i] <= 1);

    /* Hits that cannot be this file's. */
    size_t triangles = bvhc_triangle_count(file);
    bvhc_hit foreign = {0};
    foreign.triangle_index = (uint32_t)triangles;
    foreign.instance_index = bvhc_instance_count(file) ? 0 : BVHC_NO_INSTANCE;
    float up[3] = {0.0f, 0.0f, 1.0f};
    bvhc_ray spawned;
    bvhc_source_corners corners;
    CHECK(bvhc_spawn_ray(file, &foreign, up, &spawned) == BVHC_ERROR_ARGUMENT);
    CHECK(contains(bvhc_last_error_message(), "not below the file's"));
    CHECK(bvhc_hit_source_corners(file, &foreign, &corners) == BVHC_ERROR_ARGUMENT);
    foreign.triangle_index = 0;
    foreign.instance_index = bvhc_instance_count(file) ? (uint32_t)bvhc_instance_count(file) : 0;
    CHECK(bvhc_spawn_ray(file, &foreign, up, &spawned) == BVHC_ERROR_ARGUMENT);
    CHECK(bvhc_hit_source_corners(file, &foreign, &corners) == BVHC_ERROR_ARGUMENT);

    /* A real hit with its barycentrics off the triangle or NaN, and directions with no side to leave by. */
    /* Aimed at the centroid of the first record (placed by the first instance in a two-level file). */
    float corner[9], centroid[3];
    CHECK(bvhc_triangle_vertices(file, 0, corner) == BVHC_OK);
    for (int a = 0; a < 3; a++) centroid[a] = (corner[a] + corner[3 + a] + corner[6 + a]) / 3.0f;
    if (bvhc_instance_count(file) > 0) {
        bvhc_instance placing;
        bvhc_mesh first;
        for (uint32_t i = 0; i < bvhc_instance_count(file); i++) {
            CHECK(bvhc_get_instance(file, i, &placing) == BVHC_OK);
            CHECK(bvhc_get_mesh(file, placing.mesh_index, &first) == BVHC_OK);
            if (first.first_triangle == 0) break;
        }
        float object[3] = {centroid[0], centroid[1], centroid[2]};
        for (int r = 0; r < 3; r++)
            centroid[r] = placing.object_to_world[r][0] * object[0] + placing.object_to_world[r][1] * object[1] +
                          placing.object_to_world[r][2] * object[2] + placing.object_to_world[r][3];
    }
    bvhc_ray aimed = {{centroid[0] + 0.3f, centroid[1] + 0.2f, centroid[2] + 10.0f}, {-0.3f, -0.2f, -10.0f}, 0.0f,
                      INFINITY};
    int found_hit = bvhc_closest_hit(file, &aimed, &hit) == 1;
    CHECK(found_hit);
    {
        CHECK(bvhc_spawn_ray(file, &hit, up, &spawned) == BVHC_OK);
        bvhc_hit off = hit;
        off.u = 3.0f;
        off.v = -2.5f;
        CHECK(bvhc_spawn_ray(file, &off, up, &spawned) == BVHC_ERROR_ARGUMENT);
        CHECK(contains(bvhc_last_error_message(), "not on its triangle"));
        off.u = NAN;
        off.v = 0.25f;
        CHECK(bvhc_spawn_ray(file, &off, up, &spawned) == BVHC_ERROR_ARGUMENT);
        float nan_direction[3] = {NAN, 0.0f, 1.0f}, zero_direction[3] = {0.0f, -0.0f, 0.0f};
        CHECK(bvhc_spawn_ray(file, &hit, nan_direction, &spawned) == BVHC_ERROR_RAY);
        CHECK(contains(bvhc_last_error_message(), "not finite"));
        CHECK(bvhc_spawn_ray(file, &hit, zero_direction, &spawned) == BVHC_ERROR_RAY);
        CHECK(contains(bvhc_last_error_message(), "zero"));
    }

    /* Indices out of range and null pointers. */
    float vertices[9];
    uint32_t source[3];
    bvhc_mesh mesh;
    bvhc_instance instance;
    CHECK(bvhc_triangle_vertices(file, (uint32_t)triangles, vertices) == BVHC_ERROR_ARGUMENT);
    CHECK(bvhc_triangle_source_vertices(file, (uint32_t)triangles, source) == BVHC_ERROR_ARGUMENT);
    CHECK(bvhc_get_mesh(file, (uint32_t)bvhc_mesh_count(file), &mesh) == BVHC_ERROR_ARGUMENT);
    CHECK(bvhc_get_instance(file, (uint32_t)bvhc_instance_count(file), &instance) == BVHC_ERROR_ARGUMENT);
    CHECK(bvhc_scene_bounds(file, NULL, vertices) == BVHC_ERROR_ARGUMENT);
    CHECK(bvhc_scene_bounds(NULL, vertices, vertices) == BVHC_ERROR_ARGUMENT);
    CHECK(bvhc_instance_count(NULL) == 0 && bvhc_mesh_count(NULL) == 0 && bvhc_metadata_json(NULL, NULL, 0) == 0);
    return 0;
}

/* bvhc_closest_hit_columns gives bvhc_closest_hits's t, record, instance, u, v bit for bit, with every flag and
 * with columns left out, on rays that share their origin in groups of 8 (traced as packets) and rays that do
 * not; and refuses unknown flags, a null t and a bad ray. */
static int check_columns(const bvhc_file *file) {
    enum { N = 100 };
    float min[3], max[3];
    CHECK(bvhc_scene_bounds(file, min, max) == BVHC_OK);
    bvhc_ray rays[N];
    for (int i = 0; i < N; i++) {
        /* Rays 0-47 from one point above the origin towards points around it (the test scenes lie about the
         * origin), the others each from its own point above the scene's box, across it and past it. */
        float s = (float)(i % 10) / 9.0f * 1.6f - 0.3f, r = (float)(i / 10) / 9.0f * 1.6f - 0.3f;
        float eye[3] = {0.1f, 0.2f, 20.0f}, target[3] = {8.0f * s - 4.0f, 8.0f * r - 4.0f, 0.0f};
        if (i >= 48) {
            eye[0] = min[0] - 0.01f * (float)i, eye[1] = min[1], eye[2] = max[2] + 0.1f * (float)i;
            target[0] = min[0] + s * (max[0] - min[0]), target[1] = min[1] + r * (max[1] - min[1]);
            target[2] = min[2];
        }
        for (int a = 0; a < 3; a++) rays[i].origin[a] = eye[a], rays[i].direction[a] = target[a] - eye[a];
        rays[i].t_min = 0.0f, rays[i].t_max = INFINITY;
    }
    bvhc_hit hits[N];
    uint8_t found[N];
    CHECK(bvhc_closest_hits(file, rays, N, hits, found) == BVHC_OK);
    int some_hit = 0, some_miss = 0;
    for (unsigned flags = 0; flags < 4; flags++) {
        float t[N], u[N], v[N], t_only[N];
        uint32_t triangle[N], instance[N];
        CHECK(bvhc_closest_hit_columns(file, rays, N, flags, t, triangle, instance, u, v) == BVHC_OK);
        CHECK(bvhc_closest_hit_columns(file, rays, N, flags, t_only, NULL, NULL, NULL, NULL) == BVHC_OK);
        for (int i = 0; i < N; i++) {
            CHECK(memcmp(&t[i], &t_only[i], sizeof(float)) == 0);
            if (found[i]) {
                some_hit = 1;
                CHECK(memcmp(&t[i], &hits[i].t, sizeof(float)) == 0 && triangle[i] == hits[i].triangle_index);
                CHECK(instance[i] == hits[i].instance_index);
                CHECK(memcmp(&u[i], &hits[i].u, sizeof(float)) == 0 && memcmp(&v[i], &hits[i].v, sizeof(float)) == 0);
            } else {
                some_miss = 1;
                CHECK(isinf(t[i]) && t[i] > 0 && triangle[i] == BVHC_NO_INDEX && instance[i] == BVHC_NO_INSTANCE);
                CHECK(u[i] == 0.0f && v[i] == 0.0f);
            }
        }
    }
    CHECK(some_hit && some_miss);
    float t[N];
    CHECK(bvhc_closest_hit_columns(file, rays, N, 4, t, NULL, NULL, NULL, NULL) == BVHC_ERROR_ARGUMENT);
    CHECK(contains(bvhc_last_error_message(), "bvhc_closest_hit_columns: flags 0x4"));
    CHECK(bvhc_closest_hit_columns(file, rays, N, 0, NULL, NULL, NULL, NULL, NULL) == BVHC_ERROR_ARGUMENT);
    CHECK(bvhc_closest_hit_columns(file, rays, 0, 0, NULL, NULL, NULL, NULL, NULL) == BVHC_OK);
    rays[57].direction[0] = rays[57].direction[1] = rays[57].direction[2] = 0.0f;
    CHECK(bvhc_closest_hit_columns(file, rays, N, BVHC_RAYS_COHERENT, t, NULL, NULL, NULL, NULL) == BVHC_ERROR_RAY);
    CHECK(contains(bvhc_last_error_message(), "bvhc_closest_hit_columns: ray 57: the direction is zero"));
    return 0;
}

int main(int argc, char **argv) {
    if (argc < 3) return 2;
    bvhc_file *file = NULL;
    if (bvhc_open(argv[1], &file) != BVHC_OK) {
        fprintf(stderr, "open: %s\n", bvhc_last_error_message());
        return 1;
    }
    float min[3], max[3];
    if (bvhc_scene_bounds(file, min, max) != BVHC_OK) return failed("bounds");
    printf("bounds %08x %08x %08x %08x %08x %08x\n", bits(min[0]), bits(min[1]), bits(min[2]), bits(max[0]),
           bits(max[1]), bits(max[2]));
    size_t meshes = bvhc_mesh_count(file);
    printf("meshes %zu\n", meshes);
    for (uint32_t i = 0; i < meshes; i++) {
        bvhc_mesh mesh;
        if (bvhc_get_mesh(file, i, &mesh) != BVHC_OK) return failed("mesh");
        printf("mesh %u %u %u\n", i, mesh.first_triangle, mesh.triangle_count);
    }
    size_t instances = bvhc_instance_count(file);
    printf("instances %zu\n", instances);
    for (uint32_t i = 0; i < instances; i++) {
        bvhc_instance instance;
        if (bvhc_get_instance(file, i, &instance) != BVHC_OK) return failed("instance");
        printf("instance %u", i);
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 4; c++) printf(" %08x", bits(instance.object_to_world[r][c]));
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 4; c++) printf(" %08x", bits(instance.world_to_object[r][c]));
        printf(" %u %u %u\n", instance.mesh_index, instance.node_index, instance.gpu_instance_index);
    }
    size_t triangles = bvhc_triangle_count(file);
    for (uint32_t i = 0; i < triangles; i++) {
        float v[9];
        uint32_t s[3];
        if (bvhc_triangle_vertices(file, i, v) != BVHC_OK) return failed("triangle vertices");
        printf("triangle %u", i);
        for (int k = 0; k < 9; k++) printf(" %08x", bits(v[k]));
        bvhc_status status = bvhc_triangle_source_vertices(file, i, s);
        if (status == BVHC_OK)
            printf(" %u %u %u\n", s[0], s[1], s[2]);
        else if (status == BVHC_ERROR_NOT_IN_FILE)
            printf(" -\n");
        else
            return failed("triangle source vertices");
    }
    size_t json_length = bvhc_metadata_json(file, NULL, 0);
    char *json = malloc(json_length + 1);
    if (!json || bvhc_metadata_json(file, json, json_length + 1) != json_length) return failed("metadata");
    FILE *out = fopen(argv[2], "wb");
    if (!out || fwrite(json, 1, json_length, out) != json_length || fclose(out) != 0) return failed("metadata file");
    free(json);
    int status = check_errors(file);
    if (status == 0) status = check_columns(file);
    bvhc_close(file);
    if (status == 0) printf("checks ok\n");
    return status;
}
