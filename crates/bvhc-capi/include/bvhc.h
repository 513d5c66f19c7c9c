/*
 * bvhc.h: the C API of bvhc-loader (crates/bvhc-capi). Installed as libbvhc with a pkg-config file
 * (`pkg-config --cflags --libs bvhc`) and a CMake package (`find_package(bvhc)`, target `bvhc::bvhc`); see
 * scripts/install-c-library.sh. Linking the static library also needs -lpthread -ldl -lm.
 *
 * Open a .bvh file (from a path or from memory), verify it, and trace rays: the hit records are the Rust API's,
 * field for field (t, u, v, normal, triangle index, source id, instance, front face). Conventions:
 * - functions returning bvhc_status give BVHC_OK (0) or an error code (bvhc_status_name names it), with a
 *   message in bvhc_last_error_message(): per thread; the pointer it returns stays valid, its text unchanged,
 *   until the same thread calls bvhc_last_error_message() again after another call has failed (successful
 *   calls change nothing); bvhc_error_message() copies the newest message. Take the status first, then ask:
 *       bvhc_status status = bvhc_open(path, &file);
 *       if (status != BVHC_OK) fprintf(stderr, "%s: %s\n", bvhc_status_name(status), bvhc_last_error_message());
 *   (printf("%d %s", bvhc_open(...), bvhc_last_error_message()) may ask before opening: C leaves the order of
 *   arguments unspecified; the text is then the previous failure's, never freed memory);
 * - bvhc_closest_hit and bvhc_any_hit return 1 (hit), 0 (miss) or -1 (an error, with its message);
 * - rays are checked against the ray contract (finite origin and direction, the direction's largest component
 *   at least 2^-64 in magnitude, 0 <= t_min <= t_max, t_max not NaN): a ray that breaks it is refused with
 *   BVHC_ERROR_RAY naming the ray and the rule. A batch is checked in chunks of 1024 rays, each just before it
 *   is traced (the rays are then still in the caches), so results of the chunks before the named ray have been
 *   written. The _unchecked calls skip the check (about 30 instructions a ray) for callers that check once
 *   themselves (bvhc_check_rays); a ray that breaks the contract then gets an unspecified answer, never a crash;
 * - null pointers, indices out of range and hits that are not the file's are BVHC_ERROR_ARGUMENT, never
 *   crashes; no exception or panic crosses the boundary;
 * - batch calls read the caller's rays in place and write each result straight into the caller's arrays;
 * - a bvhc_file changes only through the refit calls (bvhc_refit_triangles, bvhc_refit_source_vertices,
 *   bvhc_refit_mesh, bvhc_move_instances, bvhc_move_instances_in_frame, bvhc_rebuild_top_trees); otherwise any
 *   number of threads may trace through one at once; only bvhc_close and the refit calls must not race with them.
 * The point a hit describes is (1 - u - v) v0 + u v1 + v v2 of the record's vertices (bvhc_triangle_vertices);
 * bvhc_hit_source_corners names them in the source scene's own primitive (format-spec/bvh-1.md 5.9), to
 * interpolate its normals, texture coordinates or colours. bvhc_spawn_ray gives a secondary ray with t_min = 0
 * that does not meet the triangle it leaves, at any scale, with no epsilon to choose; it refuses a hit that is
 * not the file's (a record or instance out of range, u or v NaN or off the triangle: u >= 0, v >= 0,
 * u + v <= 1 + 2^-20) with BVHC_ERROR_ARGUMENT and a direction the ray contract refuses (NaN, infinite, zero)
 * with BVHC_ERROR_RAY.
 * Two-level files (format 1.3) place meshes by instances: a hit names its instance, whose transforms, mesh
 * and glTF node bvhc_get_instance gives; the hit's normal is in world space, the record's vertices in the mesh's
 * object space.
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
#define BVHC_ERROR_INVALID 2       /* the bytes break a validity rule of the format */
#define BVHC_ERROR_ARGUMENT 3      /* a null pointer, an index out of range, a hit that is not the file's */
#define BVHC_ERROR_MEMORY 4
#define BVHC_ERROR_PANIC 5         /* a bug inside the library, caught at the boundary */
#define BVHC_ERROR_NOT_IN_FILE 6   /* the file lacks an optional section the call needs */
#define BVHC_ERROR_RAY 7           /* a ray breaks the ray contract */

/* No source id (a file without a triangle_ids section), no index (where one does not apply). */
#define BVHC_NO_SOURCE_ID 0xFFFFFFFFu
#define BVHC_NO_INDEX 0xFFFFFFFFu

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
 * vertex arrays of the glTF primitive (mesh_index, primitive_index), OBJ file or PLY file it came from. */
typedef struct bvhc_source_corners {
    uint32_t vertices[3]; /* source vertex of the record's v0, v1, v2 */
    float weights[3];     /* 1 - u - v, u, v */
    uint32_t source_triangle_id;
    uint32_t node_index;      /* glTF node that placed it (the instance's, through an instance); or BVHC_NO_INDEX */
    uint32_t mesh_index;      /* glTF mesh or OBJ model */
    uint32_t primitive_index; /* glTF primitive within the mesh: its material is the hit's */
    uint32_t instance_index;  /* EXT_mesh_gpu_instancing instance, or BVHC_NO_INDEX */
} bvhc_source_corners;

/* A placement of a mesh in a two-level file. Maps are three rows of four floats:
 * p'[i] = m[i][0] p[0] + m[i][1] p[1] + m[i][2] p[2] + m[i][3]; directions use the first three columns. */
typedef struct bvhc_instance {
    float object_to_world[3][4];
    float world_to_object[3][4]; /* the inverse, as the kernel uses it */
    uint32_t mesh_index;         /* below bvhc_mesh_count */
    uint32_t node_index;         /* glTF node, or BVHC_NO_INDEX */
    uint32_t gpu_instance_index; /* EXT_mesh_gpu_instancing instance, or BVHC_NO_INDEX */
    uint32_t reserved;
} bvhc_instance;

/* A mesh of a two-level file: the triangle records it owns, in its object space. */
typedef struct bvhc_mesh {
    uint32_t first_triangle;
    uint32_t triangle_count;
} bvhc_mesh;

/* Errors. */
const char *bvhc_status_name(bvhc_status status); /* "BVHC_ERROR_RAY"; a static string */
const char *bvhc_last_error_message(void);
size_t bvhc_error_message(char *buffer, size_t capacity); /* snprintf-style copy; returns the full length */

/* Files. */
bvhc_status bvhc_open(const char *path, bvhc_file **out);
bvhc_status bvhc_open_memory(const void *bytes, size_t len, bvhc_file **out); /* copies the bytes */
bvhc_status bvhc_verify(const bvhc_file *file);
void bvhc_close(bvhc_file *file);

/* Tracing one ray. */
int bvhc_closest_hit(const bvhc_file *file, const bvhc_ray *ray, bvhc_hit *hit);
int bvhc_any_hit(const bvhc_file *file, const bvhc_ray *ray);
int bvhc_closest_hit_unchecked(const bvhc_file *file, const bvhc_ray *ray, bvhc_hit *hit);
int bvhc_any_hit_unchecked(const bvhc_file *file, const bvhc_ray *ray);
bvhc_status bvhc_check_rays(const bvhc_ray *rays, size_t count, size_t *first_invalid);

/* Tracing arrays of rays: found[i] / occluded[i] is 1 or 0; hits[i] is zeroed on a miss. Groups of 8 consecutive
 * rays (from the first) whose origins are equal bit for bit, or whose directions lie in one octant and origins
 * within a sixteenth of the scene's size of each other, are traced together as a coherent packet, the others one
 * by one (interleaved over large files): the same hits either way. */
bvhc_status bvhc_closest_hits(const bvhc_file *file, const bvhc_ray *rays, size_t count, bvhc_hit *hits,
                              uint8_t *found);
bvhc_status bvhc_any_hits(const bvhc_file *file, const bvhc_ray *rays, size_t count, uint8_t *occluded);
/* Coherent rays (camera rays of neighbouring pixels): each 8 consecutive rays traced together; the same hits and
 * occlusion as one at a time, ties decided as spec 11.1 says (with split references, possibly another record of
 * the same triangle). A camera's rays laid out in blocks of 4 pixels by 2 rows (each 8 consecutive rays a block)
 * run 5-12% faster than rows. */
bvhc_status bvhc_closest_hits_coherent(const bvhc_file *file, const bvhc_ray *rays, size_t count, bvhc_hit *hits,
                                       uint8_t *found);
bvhc_status bvhc_any_hits_coherent(const bvhc_file *file, const bvhc_ray *rays, size_t count, uint8_t *occluded);
bvhc_status bvhc_closest_hits_unchecked(const bvhc_file *file, const bvhc_ray *rays, size_t count, bvhc_hit *hits,
                                        uint8_t *found);
bvhc_status bvhc_any_hits_unchecked(const bvhc_file *file, const bvhc_ray *rays, size_t count, uint8_t *occluded);
bvhc_status bvhc_closest_hits_coherent_unchecked(const bvhc_file *file, const bvhc_ray *rays, size_t count,
                                                 bvhc_hit *hits, uint8_t *found);
bvhc_status bvhc_any_hits_coherent_unchecked(const bvhc_file *file, const bvhc_ray *rays, size_t count,
                                             uint8_t *occluded);

/* Closest hits handed off lean, as columns (structure of arrays) a caller keeps in its own arrays: t[i] is ray
 * i's hit distance (INFINITY on a miss); where not NULL, triangle_index[i] its record (BVHC_NO_INDEX on a miss),
 * instance_index[i] its instance (BVHC_NO_INSTANCE in a one-level file or on a miss), u[i] and v[i] its weights
 * (0 on a miss). In a one-level file no normal, side or source id is computed (bvhc_closest_hit gives them, for
 * the hits that need them); the values are those bvhc_closest_hits gives. flags: BVHC_RAYS_COHERENT (each 8
 * consecutive rays traced together, as the _coherent calls), BVHC_RAYS_UNCHECKED (no ray check), or 0. Without
 * the flag, groups of 8 consecutive rays that share their origin bit for bit (a camera's, a light's, one point's
 * ambient-occlusion rays) or start close together in one direction octant are traced together too, as in
 * bvhc_closest_hits. */
#define BVHC_RAYS_COHERENT 1u
#define BVHC_RAYS_UNCHECKED 2u
bvhc_status bvhc_closest_hit_columns(const bvhc_file *file, const bvhc_ray *rays, size_t count, unsigned flags,
                                     float *t, uint32_t *triangle_index, uint32_t *instance_index, float *u,
                                     float *v);

/* Point queries (format-spec/point-queries.md): the closest point of the surface to a query point within
 * max_distance (inclusive; INFINITY for no bound), by the spec's binary64 arithmetic a triangle, ties to the
 * lowest instance then the lowest record; point and distance rounded once to float (the distance within 2^-24 of
 * itself plus 2^-40 of the coordinates' scale). Where nothing is that near the record is empty: distance
 * INFINITY, point NaN, indices BVHC_NO_INDEX / BVHC_NO_SOURCE_ID / BVHC_NO_INSTANCE. */
typedef struct bvhc_nearest_point {
    float point[3];              /* on the surface, world space */
    float distance;              /* from the query point */
    float u;                     /* weight of the record's v1 */
    float v;                     /* weight of the record's v2 */
    uint32_t triangle_index;     /* the record */
    uint32_t source_triangle_id; /* BVHC_NO_SOURCE_ID without ids */
    uint32_t instance_index;     /* two-level files: the instance; BVHC_NO_INSTANCE otherwise */
    uint32_t reserved;
} bvhc_nearest_point;

/* 1 and the record in *out, or 0 and the empty record when nothing is within max_distance; BVHC_ERROR_ARGUMENT
 * for a null argument, a point that is not finite, or max_distance below 0 or NaN. */
bvhc_status bvhc_closest_point(const bvhc_file *file, const float point[3], float max_distance,
                               bvhc_nearest_point *out);
/* count points (3 floats each, x y z) into out[count], on up to threads threads (0: every core); the same
 * records as bvhc_closest_point, whatever the thread count. BVHC_ERROR_ARGUMENT naming the first point that is
 * not finite (nothing written then). */
bvhc_status bvhc_closest_points(const bvhc_file *file, const float *points, size_t count, float max_distance,
                                unsigned threads, bvhc_nearest_point *out);
/* Point filters: keep(user_data, triangle_index, source_triangle_id, instance_index) returns nonzero where the
 * record may be the answer (source_triangle_id BVHC_NO_INDEX without ids, instance_index BVHC_NO_INDEX in a
 * one-level file). bvhc_closest_points_filtered answers as bvhc_closest_points among the kept triangles, as if
 * the others were absent; keep is called for records within a query's reach, from up to `threads` threads at
 * once with the same user_data, and must answer alike for the same record (with split references, keep all of
 * a triangle's records or none: by source id does). BVHC_ERROR_ARGUMENT for a null keep. */
typedef int (*bvhc_point_filter)(void *user_data, uint32_t triangle_index, uint32_t source_triangle_id,
                                 uint32_t instance_index);
bvhc_status bvhc_closest_points_filtered(const bvhc_file *file, const float *points, size_t count,
                                         float max_distance, unsigned threads, bvhc_point_filter keep,
                                         void *user_data, bvhc_nearest_point *out);
/* Signed distances: out[i] is point i's distance to the surface, negative where the generalized winding number's
 * magnitude exceeds 1/2 (inside a closed mesh of either winding), 0 on the surface; winding numbers: out[i] is
 * 1 inside a closed mesh wound counter-clockwise seen from outside (-1 for the other winding), 0 outside,
 * fractions near holes (summed fast: within about 0.05 of the exact sum near surfaces). The winding moments are
 * computed by the first such call on a file and kept with it until a refit or instance move (time linear in
 * the triangles, 136 bytes a tree node: BVHC_ERROR_MEMORY when they cannot be had). Calls on one file may run
 * at once. BVHC_ERROR_ARGUMENT naming the first point that is not finite. */
bvhc_status bvhc_signed_distances(const bvhc_file *file, const float *points, size_t count, unsigned threads,
                                  float *out);
bvhc_status bvhc_winding_numbers(const bvhc_file *file, const float *points, size_t count, unsigned threads,
                                 double *out);

/* Hit filters (alpha testing): filter(user_data, candidate) returns nonzero to accept a candidate hit, zero to
 * reject it (traversal then goes on as if the triangle were not hit). With BVHC_FILTER_NOT_OPAQUE it is called
 * only for triangles the file marks not opaque (format 1.5, glTF alphaMode MASK or BLEND; bvhc_triangle_flags),
 * so opaque geometry costs nothing; with BVHC_FILTER_EVERY for every candidate. It may be called for candidates
 * farther than the hit finally returned, and must answer alike for the same candidate. The candidate carries its
 * source primitive (glTF mesh and primitive: the material) and source vertices (with u, v: texture coordinates),
 * so an alpha test needs no call back into the library. Batches trace ray by ray on the calling thread, or with
 * the _threads forms on as many threads as allowed. */
#define BVHC_FILTER_NOT_OPAQUE 0
#define BVHC_FILTER_EVERY 1
#define BVHC_TRIANGLE_NOT_OPAQUE 0x01

typedef struct bvhc_candidate {
    const bvhc_ray *ray;         /* as given to the call */
    float t;
    float u;                     /* weight of the record's v1: with source_vertices below, the texture */
    float v;                     /* coordinates of the source primitive at the candidate */
    uint32_t triangle_index;
    uint32_t source_triangle_id; /* BVHC_NO_SOURCE_ID without ids */
    uint32_t instance_index;     /* BVHC_NO_INSTANCE in a one-level file */
    uint32_t mesh_index;         /* glTF mesh (OBJ model) of its source primitive; BVHC_NO_INDEX without ids */
    uint32_t primitive_index;    /* glTF primitive within that mesh: its material is the candidate's */
    uint32_t node_index;         /* glTF node that placed it (the instance's, through an instance), or BVHC_NO_INDEX */
    uint32_t source_vertices[3]; /* the record's v0, v1, v2 in that primitive (weights 1-u-v, u, v), or
                                    BVHC_NO_INDEX without the source_vertices section (format 1.2) */
} bvhc_candidate;

typedef int (*bvhc_filter)(void *user_data, const bvhc_candidate *candidate);

int bvhc_closest_hit_filtered(const bvhc_file *file, const bvhc_ray *ray, bvhc_hit *hit, bvhc_filter filter,
                              void *user_data, int scope);
int bvhc_any_hit_filtered(const bvhc_file *file, const bvhc_ray *ray, bvhc_filter filter, void *user_data,
                          int scope);
bvhc_status bvhc_closest_hits_filtered(const bvhc_file *file, const bvhc_ray *rays, size_t count, bvhc_hit *hits,
                                       uint8_t *found, bvhc_filter filter, void *user_data, int scope);
bvhc_status bvhc_any_hits_filtered(const bvhc_file *file, const bvhc_ray *rays, size_t count, uint8_t *occluded,
                                   bvhc_filter filter, void *user_data, int scope);
/* The same on up to `threads` threads (0: every core), chunks of at least 1024 rays: the filter is then called
 * from several threads at once, and must be safe to be (no unsynchronized writes to shared state). */
bvhc_status bvhc_closest_hits_filtered_threads(const bvhc_file *file, const bvhc_ray *rays, size_t count,
                                               bvhc_hit *hits, uint8_t *found, bvhc_filter filter, void *user_data,
                                               int scope, size_t threads);
bvhc_status bvhc_any_hits_filtered_threads(const bvhc_file *file, const bvhc_ray *rays, size_t count,
                                           uint8_t *occluded, bvhc_filter filter, void *user_data, int scope,
                                           size_t threads);
int bvhc_triangle_flags(const bvhc_file *file, uint32_t triangle_index); /* -1: out of range */

/* From a hit. */
bvhc_status bvhc_spawn_ray(const bvhc_file *file, const bvhc_hit *hit, const float direction[3], bvhc_ray *out);
bvhc_status bvhc_hit_source_corners(const bvhc_file *file, const bvhc_hit *hit, bvhc_source_corners *out);

/* What the file holds. */
size_t bvhc_triangle_count(const bvhc_file *file);
bvhc_status bvhc_triangle_vertices(const bvhc_file *file, uint32_t triangle_index, float vertices[9]);
bvhc_status bvhc_triangle_source_vertices(const bvhc_file *file, uint32_t triangle_index, uint32_t vertices[3]);
uint32_t bvhc_source_id(const bvhc_file *file, uint32_t triangle_index);
bvhc_status bvhc_scene_bounds(const bvhc_file *file, float min[3], float max[3]);
size_t bvhc_mesh_count(const bvhc_file *file);         /* 0 for a one-level file */
bvhc_status bvhc_get_mesh(const bvhc_file *file, uint32_t mesh_index, bvhc_mesh *out);
size_t bvhc_instance_count(const bvhc_file *file);     /* 0 for a one-level file */
bvhc_status bvhc_get_instance(const bvhc_file *file, uint32_t instance_index, bvhc_instance *out);
size_t bvhc_metadata_json(const bvhc_file *file, char *buffer, size_t capacity); /* snprintf-style; 0: none */

/* Where source ids come from: the source table's ranges (format-spec/bvh-1.md 5.4). */
typedef struct bvhc_source_range {
    uint32_t first_source_triangle;
    uint32_t source_triangle_count;
    uint32_t file_index;      /* the input in the metadata's "inputs" */
    uint32_t node_index;      /* glTF node, or BVHC_NO_INDEX (a mesh placed by instances: see the instance) */
    uint32_t mesh_index;      /* glTF mesh or OBJ model, or BVHC_NO_INDEX */
    uint32_t primitive_index; /* glTF primitive within the mesh (so its material), or BVHC_NO_INDEX */
    uint32_t instance_index;  /* EXT_mesh_gpu_instancing instance, or BVHC_NO_INDEX */
    uint32_t reserved;
} bvhc_source_range;
/* The range holding a source id: BVHC_ERROR_NOT_IN_FILE without a source table, BVHC_ERROR_ARGUMENT if none. */
bvhc_status bvhc_source_range_of(const bvhc_file *file, uint32_t source_triangle_id, bvhc_source_range *out);

/* Moving geometry (docs/loader.md, "Refit"). A refit keeps the file's tree and moves its records: per record
 * (9 floats each, v0 v1 v2 as bvhc_triangle_vertices gives them) or per source vertex of each source range
 * (positions[r]: 3 * vertex_counts[r] floats indexed as the source primitive indexes them, NULL to keep the
 * range), in the records' space (in a two-level file each mesh's own: every instance then follows its mesh);
 * with split references, each reference is boxed as its whole triangle (convert meshes meant to deform with
 * --no-splits or --no-splits-deforming for tighter trees); the same result on any number of threads (0 or 1:
 * the calling thread). The report compares the refit tree's costs with the costs the file states (NaN where it
 * states none, as a two-level file does): rebuild (convert again) once cost_ratio passes a threshold, 1.2 by default
 * in bvhc (times bvhc_planned_cost_ratio for a tree chosen for an animation). bvhc_move_instances places instances of a two-level file anew (3x4 row-major object-to-world maps,
 * 12 floats each), refitting the top trees; after large moves bvhc_rebuild_top_trees builds them anew (the
 * converter's builder) once bvhc_top_tree_cost says the refit ones cost more, replacing the file's bytes (fetch
 * bvhc_get_sections again). bvhc_write writes the file atomically with its stated costs and checksums recomputed (a
 * refit leaves both stale: bvhc_verify fails until then), so it verifies.
 * Refusals are BVHC_ERROR_ARGUMENT with the file unchanged, naming the record, range, vertex or instance. The
 * pointers of bvhc_get_sections stay valid through the other calls (the arrays change in place). */
typedef struct bvhc_refit_report {
    double cost, file_cost;           /* the binary tree's SAH cost now, and the one the file states */
    double wide_cost, file_wide_cost; /* the wide tree's cost now, and the one the file states */
    double cost_ratio;                /* wide cost / stated where both exist, else the binary one's; 1 without */
} bvhc_refit_report;
bvhc_status bvhc_refit_triangles(bvhc_file *file, const float *positions, size_t triangle_count, unsigned threads,
                                 bvhc_refit_report *report);
bvhc_status bvhc_refit_source_vertices(bvhc_file *file, const float *const *positions, const size_t *vertex_counts,
                                       size_t range_count, unsigned threads, bvhc_refit_report *report);
bvhc_status bvhc_move_instances(bvhc_file *file, const uint32_t *instances, const float *transforms, size_t count);
/* Per frame of an animation in a two-level file (docs/animation.md): bvhc_refit_mesh moves one mesh's records
 * (9 floats each, in its own space and record order: bvhc_get_mesh's first_triangle on, triangle_count of them)
 * and refits that mesh, its instances' world boxes and the top trees, leaving the other meshes untouched;
 * bvhc_move_instances_in_frame moves instances as bvhc_move_instances does without recomputing the checksums
 * (bvhc_write does; bvhc_verify fails until then). Refusals as above, and a one-level file or a missing mesh. */
bvhc_status bvhc_refit_mesh(bvhc_file *file, uint32_t mesh, const float *positions, size_t triangle_count,
                            unsigned threads);
bvhc_status bvhc_move_instances_in_frame(bvhc_file *file, const uint32_t *instances, const float *transforms,
                                         size_t count);
bvhc_status bvhc_rebuild_top_trees(bvhc_file *file);
bvhc_status bvhc_top_tree_cost(const bvhc_file *file, double *cost); /* BVHC_ERROR_NOT_IN_FILE if one-level */
/* A tree chosen for an animation (bvhc --animation, docs/animation.md): the largest cost_ratio a refit to one of
 * its sampled poses reaches; rebuild past about 1.2 times it rather than 1.2. BVHC_ERROR_NOT_IN_FILE for a file
 * converted without --animation. */
bvhc_status bvhc_planned_cost_ratio(const bvhc_file *file, double *ratio);
bvhc_status bvhc_write(const bvhc_file *file, const char *path);

/* The file's arrays, for look-ups per candidate or per pixel without a call into the library: fill once with
 * bvhc_get_sections (the pointers stay valid until bvhc_close; NULL where the file has no such section), then
 * read through the static inline functions below, which check their index. */
typedef struct bvhc_sections {
    size_t triangle_count;
    const float (*triangles)[9];          /* each record's v0, v1, v2 */
    const uint32_t *triangle_ids;         /* source ids, or NULL */
    const uint32_t (*source_vertices)[3]; /* source vertices of v0, v1, v2 (format 1.2), or NULL */
    const uint8_t *triangle_flags;        /* bit 0 BVHC_TRIANGLE_NOT_OPAQUE (format 1.5), or NULL: all opaque */
    size_t source_range_count;
    const bvhc_source_range *source_ranges; /* ascending by first_source_triangle, or NULL */
} bvhc_sections;
bvhc_status bvhc_get_sections(const bvhc_file *file, bvhc_sections *out);

/* Source id of a record, or BVHC_NO_SOURCE_ID (no ids, or out of range). */
static inline uint32_t bvhc_sections_source_id(const bvhc_sections *s, uint32_t triangle_index) {
    return s->triangle_ids && triangle_index < s->triangle_count ? s->triangle_ids[triangle_index] : BVHC_NO_SOURCE_ID;
}
/* Flags of a record (0 without the section), or -1 out of range. */
static inline int bvhc_sections_triangle_flags(const bvhc_sections *s, uint32_t triangle_index) {
    if (triangle_index >= s->triangle_count) return -1;
    return s->triangle_flags ? s->triangle_flags[triangle_index] : 0;
}
/* Source vertices of a record's v0, v1, v2, or NULL (no section, or out of range). */
static inline const uint32_t *bvhc_sections_source_vertices(const bvhc_sections *s, uint32_t triangle_index) {
    return s->source_vertices && triangle_index < s->triangle_count ? s->source_vertices[triangle_index] : NULL;
}
/* The source range holding a source id (binary search), or NULL. */
static inline const bvhc_source_range *bvhc_sections_source_range(const bvhc_sections *s, uint32_t source_triangle_id) {
    size_t low = 0, high = s->source_ranges ? s->source_range_count : 0;
    while (low < high) { /* the first range whose first_source_triangle is above the id, then one back */
        size_t middle = low + (high - low) / 2;
        if (s->source_ranges[middle].first_source_triangle <= source_triangle_id) low = middle + 1; else high = middle;
    }
    if (low == 0) return NULL;
    const bvhc_source_range *range = &s->source_ranges[low - 1];
    return source_triangle_id - range->first_source_triangle < range->source_triangle_count ? range : NULL;
}

#ifdef __cplusplus
}
#endif

#endif /* BVHC_H */
