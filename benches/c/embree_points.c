/* Closest points from outside: bvhc's C API (bvhc_closest_points, one thread) against Embree 4's rtcPointQuery
 * with the closest-point callback a user writes (the closest point on a triangle by Ericson's Voronoi regions in
 * float, the query's radius shrunk to each closer distance, as Embree's closest_point tutorial does), on the same
 * triangles and points, one thread pinned to one core. Points: N near the surface (a random point of a random
 * triangle moved by up to 1% of the scene's largest side on each axis) and N uniform in the scene's box.
 *
 *     embree_points FILE.bvh TRIANGLES.bin [N] [ROUNDS]
 *
 * Prints a line a point set: Mpoints/s of each (median of ROUNDS interleaved rounds), their ratio, Embree's rate
 * and ratio once more with the points handed over along a Morton curve (1024 cells an axis, the order bvhc's
 * batch call walks them in inside), and how many distances differ by more than 1e-5 of the scene's size
 * (Embree's float arithmetic against bvhc's binary64). */
#include "embree4_peer.h"

#include <math.h>
#include <stdbool.h>

/* Embree 4.4, rtcore_common.h and rtcore_scene.h (one instance level, instance arrays). */
struct __attribute__((aligned(16))) RTCPointQuery {
    float x, y, z, time, radius;
};
struct __attribute__((aligned(16))) RTCPointQueryContext {
    float world2inst[1][16];
    float inst2world[1][16];
    unsigned instID[1];
    unsigned instPrimID[1];
    unsigned instStackSize;
};
struct __attribute__((aligned(16))) RTCPointQueryFunctionArguments {
    struct RTCPointQuery *query;
    void *userPtr;
    unsigned primID, geomID;
    struct RTCPointQueryContext *context;
    float similarityScale;
};
typedef bool (*RTCPointQueryFunction)(struct RTCPointQueryFunctionArguments *args);
bool rtcPointQuery(RTCScene scene, struct RTCPointQuery *query, struct RTCPointQueryContext *context,
                   RTCPointQueryFunction queryFunc, void *userPtr);

/* What the callback keeps: the triangles, and the closest so far. */
struct nearest {
    const float *vertices;
    float d2;
    unsigned prim;
};

static float dot3(const float *a, const float *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Squared distance from p to the triangle (a, b, c), by the Voronoi regions of its vertices, edges and face. */
static float triangle_d2(const float *p, const float *a, const float *b, const float *c) {
    float ab[3], ac[3], ap[3], bp[3], cp[3], q[3];
    for (int k = 0; k < 3; k++) ab[k] = b[k] - a[k], ac[k] = c[k] - a[k], ap[k] = p[k] - a[k];
    float d1 = dot3(ab, ap), d2 = dot3(ac, ap);
    if (d1 <= 0 && d2 <= 0) return dot3(ap, ap);
    for (int k = 0; k < 3; k++) bp[k] = p[k] - b[k];
    float d3 = dot3(ab, bp), d4 = dot3(ac, bp);
    if (d3 >= 0 && d4 <= d3) return dot3(bp, bp);
    float vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        float t = d1 / (d1 - d3);
        for (int k = 0; k < 3; k++) q[k] = ap[k] - t * ab[k];
        return dot3(q, q);
    }
    for (int k = 0; k < 3; k++) cp[k] = p[k] - c[k];
    float d5 = dot3(ab, cp), d6 = dot3(ac, cp);
    if (d6 >= 0 && d5 <= d6) return dot3(cp, cp);
    float vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        float t = d2 / (d2 - d6);
        for (int k = 0; k < 3; k++) q[k] = ap[k] - t * ac[k];
        return dot3(q, q);
    }
    float va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        float t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int k = 0; k < 3; k++) q[k] = bp[k] - t * (c[k] - b[k]);
        return dot3(q, q);
    }
    float scale = 1.0f / (va + vb + vc), v = vb * scale, w = vc * scale;
    for (int k = 0; k < 3; k++) q[k] = ap[k] - ab[k] * v - ac[k] * w;
    return dot3(q, q);
}

static bool closest_point_callback(struct RTCPointQueryFunctionArguments *args) {
    struct nearest *n = args->userPtr;
    const float *t = n->vertices + 9 * (size_t)args->primID, p[3] = {args->query->x, args->query->y, args->query->z};
    float d2 = triangle_d2(p, t, t + 3, t + 6);
    if (d2 < n->d2) {
        n->d2 = d2;
        n->prim = args->primID;
        args->query->radius = sqrtf(d2);
        return true;
    }
    return false;
}

static uint64_t state = 0x9E3779B97F4A7C15ull;
static float uniform01(void) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return (float)(state >> 40) / (float)(1u << 24);
}

#define ROUNDS_DEFAULT 3

/* x's low 10 bits spread to every third bit. */
static uint64_t spread10(uint64_t x) {
    uint64_t out = 0;
    for (int bit = 0; bit < 10; bit++) out |= ((x >> bit) & 1) << (3 * bit);
    return out;
}

static int by_key(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* `points` (n of them) along a Morton curve over their box into `sorted`; 0 when memory is short. */
static int morton_sorted(const float *points, size_t n, float *sorted) {
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) lo[a] = fminf(lo[a], points[3 * i + a]), hi[a] = fmaxf(hi[a], points[3 * i + a]);
    uint64_t *keys = malloc(sizeof(uint64_t) * n);
    if (!keys) return 0;
    for (size_t i = 0; i < n; i++) {
        uint64_t key = 0;
        for (int a = 0; a < 3; a++) {
            double cell = hi[a] > lo[a] ? (points[3 * i + a] - lo[a]) / ((double)hi[a] - lo[a]) * 1023.0 : 0.0;
            key |= spread10((uint64_t)fmin(fmax(cell, 0.0), 1023.0)) << a;
        }
        keys[i] = key << 32 | (uint64_t)i;
    }
    qsort(keys, n, sizeof(uint64_t), by_key);
    for (size_t i = 0; i < n; i++) memcpy(sorted + 3 * i, points + 3 * (keys[i] & 0xffffffffu), sizeof(float) * 3);
    free(keys);
    return 1;
}

/* Embree's closest point of each of `n` points into `peer` (distances). */
static void embree_points(RTCScene scene, const float *vertices, const float *points, size_t n, float *peer) {
    for (size_t i = 0; i < n; i++) {
        struct RTCPointQuery query = {points[3 * i], points[3 * i + 1], points[3 * i + 2], 0.0f, INFINITY};
        struct RTCPointQueryContext context;
        context.instStackSize = 0, context.instID[0] = RTC_INVALID_GEOMETRY_ID;
        context.instPrimID[0] = RTC_INVALID_GEOMETRY_ID;
        struct nearest nearest = {vertices, INFINITY, RTC_INVALID_GEOMETRY_ID};
        rtcPointQuery(scene, &query, &context, closest_point_callback, &nearest);
        peer[i] = sqrtf(nearest.d2);
    }
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: embree_points FILE.bvh TRIANGLES.bin [N] [ROUNDS]\n");
        return 2;
    }
    size_t n = argc > 3 ? (size_t)atol(argv[3]) : 200000;
    int rounds = argc > 4 ? atoi(argv[4]) : ROUNDS_DEFAULT;
    if (n < 1) n = 200000;
    if (rounds < 1 || rounds > 99) rounds = ROUNDS_DEFAULT;
    pin_to_one_core();
    bvhc_file *file;
    if (bvhc_open(argv[1], &file) != BVHC_OK) {
        fprintf(stderr, "embree_points: %s\n", bvhc_last_error_message());
        return 1;
    }
    size_t bytes;
    float *vertices = read_all(argv[2], &bytes);
    size_t triangles = bytes / 36;
    if (bytes % 36 != 0 || triangles == 0) {
        fprintf(stderr, "embree_points: %s: not whole triangles\n", argv[2]);
        return 1;
    }
    RTCDevice device = rtcNewDevice("threads=1,isa=avx2");
    RTCScene scene = embree_scene(device, vertices, triangles);
    float min[3], max[3], size = 0;
    bvhc_scene_bounds(file, min, max);
    for (int a = 0; a < 3; a++) size = fmaxf(size, max[a] - min[a]);

    float *points = malloc(sizeof(float) * 3 * n), *sorted = malloc(sizeof(float) * 3 * n);
    bvhc_nearest_point *out = malloc(sizeof(bvhc_nearest_point) * n);
    float *peer = malloc(sizeof(float) * n), *peer_sorted = malloc(sizeof(float) * n);
    if (!points || !sorted || !out || !peer || !peer_sorted) return 1;
    printf("| points | bvhc Mpoints/s | Embree Mpoints/s | bvhc / Embree | Embree, points in Morton order | bvhc / that "
           "| distances differing by > 1e-5 of the size |\n");
    printf("|---|---|---|---|---|---|---|\n");
    for (int set = 0; set < 2; set++) {
        for (size_t i = 0; i < n; i++) {
            float *p = points + 3 * i;
            if (set == 0) {
                const float *t = vertices + 9 * (size_t)(uniform01() * (float)triangles) % (9 * triangles);
                float s = uniform01(), r = uniform01();
                if (s + r > 1) s = 1 - s, r = 1 - r;
                for (int a = 0; a < 3; a++)
                    p[a] = t[a] + s * (t[3 + a] - t[a]) + r * (t[6 + a] - t[a]) + (uniform01() * 2 - 1) * 0.01f * size;
            } else {
                for (int a = 0; a < 3; a++) p[a] = min[a] + uniform01() * (max[a] - min[a]);
            }
        }
        if (!morton_sorted(points, n, sorted)) return 1;
        double bvhc_s[99], embree_s[99], sorted_s[99];
        for (int round = 0; round < rounds; round++) {
            double start = now();
            if (bvhc_closest_points(file, points, n, INFINITY, 1, out) != BVHC_OK) {
                fprintf(stderr, "embree_points: %s\n", bvhc_last_error_message());
                return 1;
            }
            bvhc_s[round] = now() - start;
            start = now();
            embree_points(scene, vertices, points, n, peer);
            embree_s[round] = now() - start;
            start = now();
            embree_points(scene, vertices, sorted, n, peer_sorted);
            sorted_s[round] = now() - start;
        }
        qsort(bvhc_s, (size_t)rounds, sizeof(double), by_value);
        qsort(embree_s, (size_t)rounds, sizeof(double), by_value);
        qsort(sorted_s, (size_t)rounds, sizeof(double), by_value);
        double b = bvhc_s[rounds / 2], e = embree_s[rounds / 2], es = sorted_s[rounds / 2];
        size_t differ = 0;
        for (size_t i = 0; i < n; i++) differ += fabsf(out[i].distance - peer[i]) > 1e-5f * size;
        printf("| %s %zu | %.2f | %.2f | %.2f | %.2f | %.2f | %zu |\n", set == 0 ? "near" : "uniform", n, n / b * 1e-6,
               n / e * 1e-6, e / b, n / es * 1e-6, es / b, differ);
    }
    free(points), free(sorted), free(out), free(peer), free(peer_sorted);
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
    bvhc_close(file);
    return 0;
}
