/* bvhc's batch calls against Embree 4's best call for each workload, from outside, as a C program using both
 * would compare them: the installed bvhc library (bvhc.h: bvhc_closest_hits / bvhc_any_hits, one call for all
 * rays, their _coherent forms, which trace each 8 consecutive rays together, and bvhc_closest_hit_columns, the
 * lean hand-off of t, record, u, v as columns) beside Embree 4.4's C API (one
 * rtcIntersect1 / rtcOccluded1 call a ray; rtcIntersect8 / rtcOccluded8 on each 8 consecutive rays, without and
 * with RTC_RAY_QUERY_FLAG_COHERENT), isa=avx2, threads=1, HIGH quality, plain scene flags, flush-to-zero and
 * denormals-are-zero around Embree's passes as it asks; one thread pinned to one core; the same triangles and the
 * same rays. Embree's rays are filled field by field, as its users do.
 *
 * The workloads are made here from the bvhc file's scene box, so that one command gives the whole table:
 *   camera      1024x768 pinhole camera rays in rows (the peer benchmark's outside view), closest and any hit;
 *   ao          16 cosine-weighted rays from each of up to 65,536 camera hits (evenly spaced over the hits),
 *               leaving the hit by bvhc_spawn_ray, length 10% of the scene's diagonal, any hit (the 16 rays of a
 *               hit share their origin bit for bit);
 *   shadow      from a point light above the scene to each camera hit (t up to 0.999 of the way), any hit; all
 *               share the light's origin;
 *   toward      the same shadow rays from each hit (bvhc_spawn_ray) toward the light, any hit;
 *   incoherent  1M rays, origins uniform in the scene box, directions uniform, unsorted, closest and any hit.
 * Each round times every contender of a workload in turn; medians of the rounds are printed as Mrays/s, one JSON
 * line a workload and query, with bvhc's best over Embree's best, and the count of rays whose answer differs
 * between bvhc's calls (must be 0: the same hits bit for bit) and between bvhc and rtcIntersect1 (hit against
 * miss, or t more than 1e-4 apart relative).
 *
 * Usage: embree_batches FILE.bvh TRIANGLES.bin [ROUNDS]
 * With BVHC_BATCHES_WRITE=DIR set it writes each workload's rays to DIR/WORKLOAD.bin (a ray file,
 * format-spec/rays-and-hits.md: for `bvhc trace`, a profiler) instead of timing them.
 * scripts/peer-outside.sh builds it against the installed library and target/embree4 and runs it. */
#include "embree4_peer.h" /* first: it defines _GNU_SOURCE */

#include <math.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#define ROUNDS_DEFAULT 5
#define CONTENDERS 6
#define CAMERA_WIDTH 1024
#define CAMERA_HEIGHT 768
#define AO_POINTS 65536
#define AO_RAYS 16
#define INCOHERENT_RAYS 1000000

static const char *NAMES[CONTENDERS] = {"bvhc", "bvhc coherent", "bvhc columns", "Embree 1", "Embree 8",
                                        "Embree 8 coherent"};
enum { BVHC = 0, BVHC_COHERENT = 1, BVHC_COLUMNS = 2, EMBREE_1 = 3, EMBREE_8 = 4, EMBREE_8_COHERENT = 5 };

/* xorshift64*: a small fixed generator, so every run makes the same rays. */
static uint64_t rng_state = 0x9e3779b97f4a7c15ull;
static float uniform(void) {
    rng_state ^= rng_state >> 12, rng_state ^= rng_state << 25, rng_state ^= rng_state >> 27;
    return (float)((rng_state * 0x2545f4914f6cdd1dull) >> 40) / 16777216.0f;
}

static void normalize(float v[3]) {
    float l = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int a = 0; a < 3; a++) v[a] /= l;
}

static void cross(const float a[3], const float b[3], float out[3]) {
    out[0] = a[1] * b[2] - a[2] * b[1], out[1] = a[2] * b[0] - a[0] * b[2], out[2] = a[0] * b[1] - a[1] * b[0];
}

static void *allocate(size_t bytes) {
    void *p = malloc(bytes ? bytes : 1);
    if (!p) {
        fprintf(stderr, "embree_batches: out of memory\n");
        exit(1);
    }
    return p;
}

/* The camera of benches/common/rays.rs `camera_rays`: from above and to the side of the box, 45 degrees high. */
static bvhc_ray *camera_rays(const float min[3], const float max[3], size_t *n) {
    float center[3], extent2 = 0, back[3] = {0.9f, 0.6f, 1.3f}, up0[3] = {0, 1, 0}, right[3], up[3], forward[3];
    for (int a = 0; a < 3; a++) center[a] = 0.5f * (min[a] + max[a]), extent2 += (max[a] - min[a]) * (max[a] - min[a]);
    float radius = 0.5f * sqrtf(extent2), eye[3];
    normalize(back);
    for (int a = 0; a < 3; a++) eye[a] = center[a] + back[a] * radius * 2.0f, forward[a] = -back[a];
    cross(forward, up0, right);
    normalize(right);
    cross(right, forward, up);
    float half_height = tanf(22.5f * 3.14159265f / 180.0f), half_width = half_height * CAMERA_WIDTH / CAMERA_HEIGHT;
    bvhc_ray *rays = allocate(sizeof(bvhc_ray) * CAMERA_WIDTH * CAMERA_HEIGHT);
    for (size_t y = 0; y < CAMERA_HEIGHT; y++)
        for (size_t x = 0; x < CAMERA_WIDTH; x++) {
            float sx = (2.0f * ((float)x + 0.5f) / CAMERA_WIDTH - 1.0f) * half_width;
            float sy = (1.0f - 2.0f * ((float)y + 0.5f) / CAMERA_HEIGHT) * half_height;
            bvhc_ray *r = &rays[y * CAMERA_WIDTH + x];
            for (int a = 0; a < 3; a++) r->origin[a] = eye[a], r->direction[a] = forward[a] + sx * right[a] + sy * up[a];
            normalize(r->direction);
            r->t_min = 0.0f, r->t_max = INFINITY;
        }
    *n = CAMERA_WIDTH * CAMERA_HEIGHT;
    return rays;
}

/* The point a camera ray meets at its hit. */
static void hit_point(const bvhc_ray *r, const bvhc_hit *h, float p[3]) {
    for (int a = 0; a < 3; a++) p[a] = r->origin[a] + h->t * r->direction[a];
}

/* Ambient-occlusion rays: AO_RAYS cosine-weighted directions about the hit's normal (turned toward the camera)
 * from each of up to AO_POINTS hits, evenly spaced over the `hits` found. */
static bvhc_ray *ao_rays(const bvhc_file *file, const bvhc_ray *camera, const bvhc_hit *hits, const size_t *found,
                         size_t n_found, float length, size_t *n) {
    size_t points = n_found < AO_POINTS ? n_found : AO_POINTS, k = 0;
    bvhc_ray *rays = allocate(sizeof(bvhc_ray) * points * AO_RAYS);
    for (size_t p = 0; p < points; p++) {
        size_t i = found[p * n_found / points];
        const bvhc_hit *h = &hits[i];
        float normal[3] = {h->normal[0], h->normal[1], h->normal[2]}, t1[3], t2[3];
        const float *d = camera[i].direction;
        if (normal[0] * d[0] + normal[1] * d[1] + normal[2] * d[2] > 0)
            for (int a = 0; a < 3; a++) normal[a] = -normal[a];
        normalize(normal);
        float other[3] = {fabsf(normal[0]) < 0.5f ? 1.0f : 0.0f, fabsf(normal[0]) < 0.5f ? 0.0f : 1.0f, 0.0f};
        cross(normal, other, t1);
        normalize(t1);
        cross(normal, t1, t2);
        for (int s = 0; s < AO_RAYS; s++) {
            float phi = 6.2831853f * uniform(), r2 = uniform(), r = sqrtf(r2), z = sqrtf(1.0f - r2), dir[3];
            for (int a = 0; a < 3; a++) dir[a] = r * cosf(phi) * t1[a] + r * sinf(phi) * t2[a] + z * normal[a];
            if (bvhc_spawn_ray(file, h, dir, &rays[k]) != BVHC_OK) continue;
            rays[k].t_max = length;
            k++;
        }
    }
    *n = k;
    return rays;
}

/* Shadow rays between a point light above the scene and each camera hit: from the light (`from_light`, all
 * sharing its origin, t up to 0.999 of the way) or from the hit toward the light (bvhc_spawn_ray, t up to 1). */
static bvhc_ray *shadow_rays(const bvhc_file *file, const bvhc_ray *camera, const bvhc_hit *hits,
                             const size_t *found, size_t n_found, const float light[3], int from_light, size_t *n) {
    bvhc_ray *rays = allocate(sizeof(bvhc_ray) * (n_found ? n_found : 1));
    size_t k = 0;
    for (size_t f = 0; f < n_found; f++) {
        size_t i = found[f];
        float p[3], dir[3];
        hit_point(&camera[i], &hits[i], p);
        for (int a = 0; a < 3; a++) dir[a] = from_light ? p[a] - light[a] : light[a] - p[a];
        if (from_light) {
            bvhc_ray *r = &rays[k];
            for (int a = 0; a < 3; a++) r->origin[a] = light[a], r->direction[a] = dir[a];
            r->t_min = 0.0f, r->t_max = 0.999f;
        } else {
            if (bvhc_spawn_ray(file, &hits[i], dir, &rays[k]) != BVHC_OK) continue;
            rays[k].t_max = 1.0f;
        }
        if (dir[0] != 0 || dir[1] != 0 || dir[2] != 0) k++;
    }
    *n = k;
    return rays;
}

/* Incoherent rays: origins uniform in the box, directions uniform on the sphere. */
static bvhc_ray *incoherent_rays(const float min[3], const float max[3], size_t *n) {
    bvhc_ray *rays = allocate(sizeof(bvhc_ray) * INCOHERENT_RAYS);
    for (size_t i = 0; i < INCOHERENT_RAYS; i++) {
        bvhc_ray *r = &rays[i];
        for (int a = 0; a < 3; a++) r->origin[a] = min[a] + uniform() * (max[a] - min[a]);
        float z = 2.0f * uniform() - 1.0f, phi = 6.2831853f * uniform(), s = sqrtf(fmaxf(0.0f, 1.0f - z * z));
        r->direction[0] = s * cosf(phi), r->direction[1] = s * sinf(phi), r->direction[2] = z;
        if (r->direction[0] == 0 && r->direction[1] == 0 && r->direction[2] == 0) r->direction[2] = 1.0f;
        r->t_min = 0.0f, r->t_max = INFINITY;
    }
    *n = INCOHERENT_RAYS;
    return rays;
}

/* Lanes `first..first+8` of `rays` (those below n) into Embree's packet, field by field; `valid` marks them. */
static void embree_packet(const bvhc_ray *rays, size_t first, size_t n, struct RTCRayHit8 *rh, int valid[8]) {
    for (int l = 0; l < 8; l++) {
        size_t i = first + (size_t)l < n ? first + (size_t)l : first;
        const bvhc_ray *r = &rays[i];
        valid[l] = first + (size_t)l < n ? -1 : 0;
        rh->ray.org_x[l] = r->origin[0], rh->ray.org_y[l] = r->origin[1], rh->ray.org_z[l] = r->origin[2];
        rh->ray.dir_x[l] = r->direction[0], rh->ray.dir_y[l] = r->direction[1], rh->ray.dir_z[l] = r->direction[2];
        rh->ray.tnear[l] = r->t_min, rh->ray.tfar[l] = r->t_max, rh->ray.time[l] = 0.0f;
        rh->ray.mask[l] = ~0u, rh->ray.id[l] = (unsigned)l, rh->ray.flags[l] = 0;
        rh->hit.geomID[l] = RTC_INVALID_GEOMETRY_ID, rh->hit.primID[l] = RTC_INVALID_GEOMETRY_ID;
        rh->hit.instID[0][l] = RTC_INVALID_GEOMETRY_ID;
    }
}

/* Buffers a pass writes its answers into: each ray's t (INFINITY on a miss or, for any hit, 1 if occluded). */
struct answers {
    bvhc_hit *hits;
    uint8_t *found;
    float *t, *u, *v;
    uint32_t *triangle;
};

/* One timed pass of contender `c` over the rays; seconds. Each contender's answers go to `out->t`. */
static double pass(int c, int any, const bvhc_file *file, RTCScene scene, const bvhc_ray *rays, size_t n,
                   struct answers *out) {
    unsigned csr = _mm_getcsr();
    if (c >= EMBREE_1) _mm_setcsr(csr | 0x8040); /* FTZ and DAZ, as Embree asks */
    struct RTCQueryArguments args = {RTC_RAY_QUERY_FLAG_COHERENT, (unsigned)RTC_FEATURE_FLAG_ALL, NULL, NULL, NULL, 0.0f};
    double start = now();
    bvhc_status status = BVHC_OK;
    if (c == BVHC && any) status = bvhc_any_hits(file, rays, n, out->found);
    if (c == BVHC && !any) status = bvhc_closest_hits(file, rays, n, out->hits, out->found);
    if (c == BVHC_COHERENT && any) status = bvhc_any_hits_coherent(file, rays, n, out->found);
    if (c == BVHC_COHERENT && !any) status = bvhc_closest_hits_coherent(file, rays, n, out->hits, out->found);
    if (c == BVHC_COLUMNS) status = bvhc_closest_hit_columns(file, rays, n, 0, out->t, out->triangle, NULL, out->u, out->v);
    if (c == EMBREE_1)
        for (size_t i = 0; i < n; i++) {
            struct RTCRayHit rh = embree_ray(&rays[i]);
            if (any) {
                rtcOccluded1(scene, &rh.ray, NULL);
                out->t[i] = rh.ray.tfar < 0 ? 1.0f : INFINITY;
            } else {
                rtcIntersect1(scene, &rh, NULL);
                out->t[i] = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID ? rh.ray.tfar : INFINITY;
            }
        }
    if (c >= EMBREE_8)
        for (size_t i = 0; i < n; i += 8) {
            struct RTCRayHit8 rh;
            int valid[8] __attribute__((aligned(32))); /* Embree loads the mask aligned */
            embree_packet(rays, i, n, &rh, valid);
            /* Embree's defaults (no arguments) are the incoherent flag. */
            struct RTCQueryArguments *arguments = c == EMBREE_8_COHERENT ? &args : NULL;
            if (any) rtcOccluded8(valid, scene, &rh.ray, arguments);
            else rtcIntersect8(valid, scene, &rh, arguments);
            for (size_t l = 0; l < 8 && i + l < n; l++) {
                if (any) out->t[i + l] = rh.ray.tfar[l] < 0 ? 1.0f : INFINITY;
                else out->t[i + l] = rh.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID ? rh.ray.tfar[l] : INFINITY;
            }
        }
    double seconds = now() - start;
    _mm_setcsr(csr);
    if (status != BVHC_OK) {
        fprintf(stderr, "embree_batches: %s: %s\n", bvhc_status_name(status), bvhc_last_error_message());
        exit(1);
    }
    if (c <= BVHC_COHERENT)
        for (size_t i = 0; i < n; i++) out->t[i] = !out->found[i] ? INFINITY : any ? 1.0f : out->hits[i].t;
    return seconds;
}

/* Writes `rays` to DIR/WORKLOAD.bin when BVHC_BATCHES_WRITE=DIR is set; whether it did. */
static int written(const char *workload, const bvhc_ray *rays, size_t n) {
    const char *dir = getenv("BVHC_BATCHES_WRITE");
    if (!dir) return 0;
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.bin", dir, workload);
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(rays, sizeof(bvhc_ray), n, f) != n || fclose(f) != 0) {
        fprintf(stderr, "embree_batches: %s: cannot be written\n", path);
        exit(1);
    }
    return 1;
}

/* Times every contender on `rays` over `rounds` interleaved rounds and prints the workload's JSON line. */
static void run(const char *workload, int any, const bvhc_file *file, RTCScene scene, const bvhc_ray *rays,
                size_t n, int rounds) {
    if (written(workload, rays, n)) return;
    struct answers out = {allocate(sizeof(bvhc_hit) * n), allocate(n), NULL, allocate(sizeof(float) * n),
                          allocate(sizeof(float) * n), allocate(sizeof(uint32_t) * n)};
    float *t[CONTENDERS];
    double samples[CONTENDERS][99], mrays[CONTENDERS];
    for (int c = 0; c < CONTENDERS; c++) t[c] = allocate(sizeof(float) * n);
    /* The columns call answers closest hits only. */
    int skip[CONTENDERS] = {0, 0, any, 0, 0, 0};
    for (int round = 0; round < rounds; round++)
        for (int c = 0; c < CONTENDERS; c++) {
            out.t = t[c];
            samples[c][round] = skip[c] ? 0 : pass(c, any, file, scene, rays, n, &out);
        }
    for (int c = 0; c < CONTENDERS; c++) {
        qsort(samples[c], (size_t)rounds, sizeof(double), by_value);
        mrays[c] = skip[c] ? 0 : (double)n / samples[c][rounds / 2] / 1e6;
    }
    size_t packets_differ = 0, differ = 0;
    for (size_t i = 0; i < n; i++) {
        packets_differ += memcmp(&t[BVHC][i], &t[BVHC_COHERENT][i], sizeof(float)) != 0;
        packets_differ += !any && memcmp(&t[BVHC][i], &t[BVHC_COLUMNS][i], sizeof(float)) != 0;
        float b = t[BVHC][i], e = t[EMBREE_1][i];
        differ += isinf(b) != isinf(e) || (!isinf(b) && fabsf(b - e) > 1e-4f * fmaxf(1.0f, fabsf(b)));
    }
    double best_bvhc = fmax(mrays[BVHC], fmax(mrays[BVHC_COHERENT], mrays[BVHC_COLUMNS]));
    double best_embree = fmax(mrays[EMBREE_1], fmax(mrays[EMBREE_8], mrays[EMBREE_8_COHERENT]));
    printf("{\"workload\": \"%s\", \"query\": \"%s\", \"rays\": %zu, \"rounds\": %d", workload,
           any ? "any" : "closest", n, rounds);
    for (int c = 0; c < CONTENDERS; c++) printf(", \"%s\": %.3f", NAMES[c], mrays[c]);
    printf(", \"ratio\": %.3f, \"bvhc_calls_differ\": %zu, \"answered_differently\": %zu}\n",
           best_bvhc / best_embree, packets_differ, differ);
    fflush(stdout);
    for (int c = 0; c < CONTENDERS; c++) free(t[c]);
    free(out.hits), free(out.found), free(out.u), free(out.v), free(out.triangle);
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: embree_batches FILE.bvh TRIANGLES.bin [ROUNDS]\n");
        return 2;
    }
    int rounds = argc > 3 ? atoi(argv[3]) : ROUNDS_DEFAULT;
    if (rounds < 1 || rounds > 99) rounds = ROUNDS_DEFAULT;
    pin_to_one_core();
    bvhc_file *file;
    if (bvhc_open(argv[1], &file) != BVHC_OK) {
        fprintf(stderr, "embree_batches: %s\n", bvhc_last_error_message());
        return 1;
    }
    size_t triangle_bytes;
    float *vertices = read_all(argv[2], &triangle_bytes);
    if (triangle_bytes % 36 != 0 || triangle_bytes == 0) {
        fprintf(stderr, "embree_batches: %s: not whole triangles\n", argv[2]);
        return 1;
    }
    RTCDevice device = rtcNewDevice("threads=1,isa=avx2");
    RTCScene scene = embree_scene(device, vertices, triangle_bytes / 36);

    float min[3], max[3], center[3], diagonal2 = 0;
    bvhc_scene_bounds(file, min, max);
    for (int a = 0; a < 3; a++) center[a] = 0.5f * (min[a] + max[a]), diagonal2 += (max[a] - min[a]) * (max[a] - min[a]);
    float diagonal = sqrtf(diagonal2), light[3] = {center[0], max[1] + 0.5f * diagonal, center[2]};

    size_t n_camera, n;
    bvhc_ray *camera = camera_rays(min, max, &n_camera);
    bvhc_hit *hits = allocate(sizeof(bvhc_hit) * n_camera);
    uint8_t *hit = allocate(n_camera);
    size_t *found = allocate(sizeof(size_t) * n_camera), n_found = 0;
    if (bvhc_closest_hits(file, camera, n_camera, hits, hit) != BVHC_OK) {
        fprintf(stderr, "embree_batches: %s\n", bvhc_last_error_message());
        return 1;
    }
    for (size_t i = 0; i < n_camera; i++)
        if (hit[i]) found[n_found++] = i;

    run("camera", 0, file, scene, camera, n_camera, rounds);
    run("camera", 1, file, scene, camera, n_camera, rounds);
    bvhc_ray *rays = ao_rays(file, camera, hits, found, n_found, 0.1f * diagonal, &n);
    run("ao", 1, file, scene, rays, n, rounds);
    free(rays);
    rays = shadow_rays(file, camera, hits, found, n_found, light, 1, &n);
    run("shadow", 1, file, scene, rays, n, rounds);
    free(rays);
    rays = shadow_rays(file, camera, hits, found, n_found, light, 0, &n);
    run("toward", 1, file, scene, rays, n, rounds);
    free(rays);
    rays = incoherent_rays(min, max, &n);
    run("incoherent", 0, file, scene, rays, n, rounds);
    run("incoherent", 1, file, scene, rays, n, rounds);
    free(rays);

    free(camera), free(hits), free(hit), free(found), free(vertices);
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
    bvhc_close(file);
    return 0;
}
