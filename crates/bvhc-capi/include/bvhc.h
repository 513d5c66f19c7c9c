/*
 * bvhc.h: the C API of bvhc-loader (crates/bvhc-capi). Link libbvhc_capi (static: also -lpthread -ldl -lm).
 *
 * Open a .bvh file (from a path or from memory), verify it, and trace rays: the hit records are the Rust API's,
 * field for field (t, u, v, normal, triangle index, source id, front face). Conventions:
 * - functions returning bvhc_status give BVHC_OK (0) or an error code, with a message in
 *   bvhc_last_error_message() (per thread, valid until the next call on that thread);
 * - bvhc_closest_hit and bvhc_any_hit return 1 (hit), 0 (miss) or -1 (an argument error);
 * - null pointers are argument errors, never crashes; no exception or panic crosses the boundary;
 * - a bvhc_file is immutable: any number of threads may trace through one at once; only bvhc_close must not
 *   race with them.
 * The point a hit describes is (1 - u - v) v0 + u v1 + v v2 of the record's vertices; bvhc_hit_source_corners
 * names them in the source scene's own primitive (format-spec/bvh-1.md 5.9), to interpolate its normals, texture
 * coordinates or colours. bvhc_spawn_ray gives a secondary ray with t_min = 0 that does not meet
 * the triangle it leaves, at any scale, with no epsilon to choose.
 */
#ifndef BVHC_H
#define BVHC_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef int bvhc_status;
#define BVHC_OK 0
#define BVHC_ERROR_IO 1
#define BVHC_ERROR_INVALID 2
#define BVHC_ERROR_ARGUMENT 3
#define BVHC_ERROR_MEMORY 4
#define BVHC_ERROR_PANIC 5
#define BVHC_ERROR_NOT_IN_FILE 6 /* the file lacks an optional section the call needs */

/* No source id (a file without a triangle_ids section). */
#define BVHC_NO_SOURCE_ID 0xFFFFFFFFu

/* No instance (a hit in a one-level file). */
#define BVHC_NO_INSTANCE 0xFFFFFFFFu

typedef struct bvhc_file bvhc_file;

typedef struct bvhc_ray {
    float origin[3];
    float direction[3]; /* need not be normalized; t is measured in its units */
    float t_min;        /* >= 0 */
    float t_max;        /* INFINITY for an unbounded ray */
} bvhc_ray;

typedef struct bvhc_hit {
    float t;
    float u; /* weight of the record's v1 */
    float v; /* weight of the record's v2 */
    float normal[3]; /* (v1 - v0) x (v2 - v0), not normalized; in world space for an instance's hit */
    uint32_t triangle_index;
    uint32_t source_triangle_id; /* BVHC_NO_SOURCE_ID without ids */
    uint32_t instance_index;     /* two-level files: the instance hit; BVHC_NO_INSTANCE otherwise */
    uint8_t front_face;          /* 1 when the ray met the counter-clockwise side */
    uint8_t reserved[3];
} bvhc_hit;

/* Where a hit lies in the source scene: attribute(hit) = sum of weights[i] * attribute[vertices[i]] over the
 * vertex arrays of the glTF primitive (node, mesh, primitive, instance), OBJ file or PLY file it came from. */
typedef struct bvhc_source_corners {
    uint32_t vertices[3]; /* source vertex of the record's v0, v1, v2 */
    float weights[3];     /* 1 - u - v, u, v */
    uint32_t source_triangle_id;
    uint32_t node_index;      /* 0xFFFFFFFF where it does not apply */
    uint32_t mesh_index;      /* glTF mesh or OBJ model */
    uint32_t primitive_index; /* glTF primitive within the mesh */
    uint32_t instance_index;  /* EXT_mesh_gpu_instancing instance */
} bvhc_source_corners;

bvhc_status bvhc_open(const char *path, bvhc_file **out);
bvhc_status bvhc_open_memory(const void *bytes, size_t len, bvhc_file **out);
bvhc_status bvhc_verify(const bvhc_file *file);
void bvhc_close(bvhc_file *file);

int bvhc_closest_hit(const bvhc_file *file, const bvhc_ray *ray, bvhc_hit *hit);
int bvhc_any_hit(const bvhc_file *file, const bvhc_ray *ray);
bvhc_status bvhc_closest_hits(const bvhc_file *file, const bvhc_ray *rays, size_t count, bvhc_hit *hits,
                              uint8_t *found);
bvhc_status bvhc_any_hits(const bvhc_file *file, const bvhc_ray *rays, size_t count, uint8_t *occluded);
/* Coherent rays (camera rays of neighbouring pixels): each 8 consecutive rays traced together; the same t and
 * occlusion as one at a time (on a tie at t, possibly another triangle). */
bvhc_status bvhc_closest_hits_coherent(const bvhc_file *file, const bvhc_ray *rays, size_t count, bvhc_hit *hits,
                                       uint8_t *found);
bvhc_status bvhc_any_hits_coherent(const bvhc_file *file, const bvhc_ray *rays, size_t count, uint8_t *occluded);
bvhc_status bvhc_spawn_ray(const bvhc_file *file, const bvhc_hit *hit, const float direction[3], bvhc_ray *out);

uint32_t bvhc_source_id(const bvhc_file *file, uint32_t triangle_index);
bvhc_status bvhc_hit_source_corners(const bvhc_file *file, const bvhc_hit *hit, bvhc_source_corners *out);
size_t bvhc_triangle_count(const bvhc_file *file);
const char *bvhc_last_error_message(void);

#ifdef __cplusplus
}
#endif

#endif /* BVHC_H */
