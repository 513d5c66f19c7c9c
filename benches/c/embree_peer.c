/* bvhc against Embree 4 from outside, as a C program using both would compare them: the installed bvhc library
 * (bvhc.h, one bvhc_closest_hit / bvhc_any_hit call a ray, and the _unchecked forms) beside Embree 4's C API
 * (one rtcIntersect1 / rtcOccluded1 call a ray, isa=avx2, threads=1, HIGH quality, plain scene flags, flush-to-
 * zero and denormals-are-zero set around its passes as Embree asks; bvhc's passes run without them, which its
 * kernel needs), the same triangles and the same rays, one thread pinned to one core. Each round times every
 * contender over all rays in turn; the medians of the rounds are printed as Mrays/s, with bvhc's ratios to
 * Embree and how many rays the two answer differently (hit against miss, or t more than 1e-4 apart relative).
 *
 * Usage: embree_peer FILE.bvh TRIANGLES.bin RAYS.bin [ROUNDS]
 *   FILE.bvh       a bvhc conversion of the scene
 *   TRIANGLES.bin  the triangles Embree is built from, nine little-endian f32 a triangle (the benchmark's
 *                  import of the scene: `BVHC_PEER_WRITE=DIR cargo bench --bench peer --features embree4`)
 *   RAYS.bin       a ray file (format-spec/rays-and-hits.md)
 * scripts/peer-outside.sh builds it against the installed library and target/embree4 and runs it.
 *
 * Embree 4.4.0's C API is declared here from its headers (RenderKit/embree, tag v4.4.0, include/embree4/
 * rtcore_*.h), as the Rust benchmarks declare it, so no Embree header is needed: the library of the embreex
 * wheel (scripts/embree4.sh) is built with one instance level. */
#define _GNU_SOURCE
#include <math.h>
#include <pmmintrin.h>
#include <sched.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <xmmintrin.h>

#include <bvhc.h>

/* Embree 4.4.0, rtcore_device.h, rtcore_scene.h, rtcore_geometry.h, rtcore_buffer.h, rtcore_ray.h. */
typedef struct RTCDeviceTy *RTCDevice;
typedef struct RTCSceneTy *RTCScene;
typedef struct RTCGeometryTy *RTCGeometry;
enum { RTC_GEOMETRY_TYPE_TRIANGLE = 0, RTC_BUFFER_TYPE_INDEX = 0, RTC_BUFFER_TYPE_VERTEX = 1 };
enum { RTC_FORMAT_UINT3 = 0x5003, RTC_FORMAT_FLOAT3 = 0x9003, RTC_BUILD_QUALITY_HIGH = 2 };
struct __attribute__((aligned(16))) RTCRay {
    float org_x, org_y, org_z, tnear, dir_x, dir_y, dir_z, time, tfar;
    unsigned mask, id, flags;
};
struct __attribute__((aligned(16))) RTCHit {
    float Ng_x, Ng_y, Ng_z, u, v;
    unsigned primID, geomID, instID[1], instPrimID[1];
};
struct __attribute__((aligned(16))) RTCRayHit {
    struct RTCRay ray;
    struct RTCHit hit;
};
RTCDevice rtcNewDevice(const char *config);
void rtcReleaseDevice(RTCDevice device);
int rtcGetDeviceError(RTCDevice device);
RTCScene rtcNewScene(RTCDevice device);
void rtcSetSceneBuildQuality(RTCScene scene, int quality);
RTCGeometry rtcNewGeometry(RTCDevice device, int type);
void rtcSetGeometryBuildQuality(RTCGeometry geometry, int quality);
void *rtcSetNewGeometryBuffer(RTCGeometry geometry, int type, unsigned slot, int format, size_t byte_stride,
                              size_t item_count);
void rtcCommitGeometry(RTCGeometry geometry);
unsigned rtcAttachGeometry(RTCScene scene, RTCGeometry geometry);
void rtcReleaseGeometry(RTCGeometry geometry);
void rtcCommitScene(RTCScene scene);
void rtcReleaseScene(RTCScene scene);
void rtcIntersect1(RTCScene scene, struct RTCRayHit *rayhit, void *arguments);
void rtcOccluded1(RTCScene scene, struct RTCRay *ray, void *arguments);

#define RTC_INVALID_GEOMETRY_ID 0xffffffffu
#define ROUNDS_DEFAULT 5
#define CONTENDERS 3

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* The whole of `path`, and its length; exits with a message naming the file when it cannot be read. */
static void *read_all(const char *path, size_t *len) {
    FILE *f = fopen(path, "rb");
    if (!f || fseek(f, 0, SEEK_END) != 0) {
        fprintf(stderr, "embree_peer: %s: cannot be read\n", path);
        exit(1);
    }
    long size = ftell(f);
    void *bytes = malloc(size > 0 ? (size_t)size : 1);
    if (size < 0 || !bytes || fseek(f, 0, SEEK_SET) != 0 || fread(bytes, 1, (size_t)size, f) != (size_t)size) {
        fprintf(stderr, "embree_peer: %s: cannot be read\n", path);
        exit(1);
    }
    fclose(f);
    *len = (size_t)size;
    return bytes;
}

/* The ray as Embree's users set one up: each field Embree reads written once (a memset of the whole record
 * first stalls Embree's wide loads of it: Embree ran 15-25% slower, which flattered bvhc's ratios). */
static struct RTCRayHit embree_ray(const bvhc_ray *r) {
    struct RTCRayHit rh;
    rh.ray.org_x = r->origin[0], rh.ray.org_y = r->origin[1], rh.ray.org_z = r->origin[2];
    rh.ray.dir_x = r->direction[0], rh.ray.dir_y = r->direction[1], rh.ray.dir_z = r->direction[2];
    rh.ray.tnear = r->t_min, rh.ray.tfar = r->t_max, rh.ray.time = 0.0f;
    rh.ray.mask = ~0u, rh.ray.id = 0, rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID, rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    return rh;
}

/* One timed pass of contender `c` (0: bvhc, 1: bvhc unchecked, 2: Embree) over the rays; seconds. The hits'
 * distances are summed into *sink, so no call can be dropped. */
static double pass(int c, int any, const bvhc_file *file, RTCScene scene, const bvhc_ray *rays, size_t n,
                   double *sink) {
    unsigned csr = _mm_getcsr();
    if (c == 2) _mm_setcsr(csr | 0x8040); /* FTZ and DAZ, as Embree asks */
    double acc = 0, start = now();
    for (size_t i = 0; i < n; i++) {
        bvhc_hit h;
        if (c == 0) {
            if (any) acc += bvhc_any_hit(file, &rays[i]);
            else if (bvhc_closest_hit(file, &rays[i], &h) == 1) acc += h.t;
        } else if (c == 1) {
            if (any) acc += bvhc_any_hit_unchecked(file, &rays[i]);
            else if (bvhc_closest_hit_unchecked(file, &rays[i], &h) == 1) acc += h.t;
        } else {
            struct RTCRayHit rh = embree_ray(&rays[i]);
            if (any) {
                rtcOccluded1(scene, &rh.ray, NULL);
                acc += rh.ray.tfar < 0;
            } else {
                rtcIntersect1(scene, &rh, NULL);
                if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) acc += rh.ray.tfar;
            }
        }
    }
    double seconds = now() - start;
    _mm_setcsr(csr);
    *sink += acc;
    return seconds;
}

static int by_value(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv) {
    if (argc < 4) {
        fprintf(stderr, "usage: embree_peer FILE.bvh TRIANGLES.bin RAYS.bin [ROUNDS]\n");
        return 2;
    }
    int rounds = argc > 4 ? atoi(argv[4]) : ROUNDS_DEFAULT;
    if (rounds < 1 || rounds > 99) rounds = ROUNDS_DEFAULT;
    /* One core for the whole run: the one this process starts on. */
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(sched_getcpu(), &one);
    sched_setaffinity(0, sizeof one, &one);

    bvhc_file *file;
    if (bvhc_open(argv[1], &file) != BVHC_OK) {
        fprintf(stderr, "embree_peer: %s\n", bvhc_last_error_message());
        return 1;
    }
    size_t triangle_bytes, ray_bytes;
    float *vertices = read_all(argv[2], &triangle_bytes);
    bvhc_ray *rays = read_all(argv[3], &ray_bytes);
    size_t triangles = triangle_bytes / 36, n = ray_bytes / sizeof(bvhc_ray);
    if (triangle_bytes % 36 != 0 || ray_bytes % sizeof(bvhc_ray) != 0 || n == 0) {
        fprintf(stderr, "embree_peer: %s or %s: not whole records\n", argv[2], argv[3]);
        return 1;
    }

    RTCDevice device = rtcNewDevice("threads=1,isa=avx2");
    RTCScene scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(geometry, RTC_BUILD_QUALITY_HIGH);
    float *v = rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, 3 * triangles);
    unsigned *index = rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, triangles);
    if (!v || !index) {
        fprintf(stderr, "embree_peer: Embree error %d\n", rtcGetDeviceError(device));
        return 1;
    }
    memcpy(v, vertices, 36 * triangles);
    for (size_t k = 0; k < 3 * triangles; k++) index[k] = (unsigned)k;
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(scene, geometry);
    rtcReleaseGeometry(geometry);
    rtcCommitScene(scene);

    const char *names[CONTENDERS] = {"bvhc", "bvhc unchecked", "Embree"};
    for (int any = 0; any < 2; any++) {
        double samples[CONTENDERS][99], sink = 0;
        for (int round = 0; round < rounds; round++)
            for (int c = 0; c < CONTENDERS; c++) samples[c][round] = pass(c, any, file, scene, rays, n, &sink);
        double mrays[CONTENDERS];
        for (int c = 0; c < CONTENDERS; c++) {
            qsort(samples[c], (size_t)rounds, sizeof(double), by_value);
            mrays[c] = (double)n / samples[c][rounds / 2] / 1e6;
        }
        size_t differ = 0;
        for (size_t i = 0; i < n; i++) {
            struct RTCRayHit rh = embree_ray(&rays[i]);
            bvhc_hit h;
            if (any) {
                int b = bvhc_any_hit(file, &rays[i]);
                rtcOccluded1(scene, &rh.ray, NULL);
                differ += b != (rh.ray.tfar < 0);
            } else {
                int b = bvhc_closest_hit(file, &rays[i], &h) == 1;
                rtcIntersect1(scene, &rh, NULL);
                int e = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
                differ += b != e || (b && fabsf(h.t - rh.ray.tfar) > 1e-4f * fmaxf(1.0f, fabsf(h.t)));
            }
        }
        printf("{\"query\": \"%s\", \"rays\": %zu, \"rounds\": %d", any ? "any" : "closest", n, rounds);
        for (int c = 0; c < CONTENDERS; c++) printf(", \"%s\": %.3f", names[c], mrays[c]);
        printf(", \"ratio\": %.3f, \"ratio_unchecked\": %.3f, \"answered_differently\": %zu, \"sink\": %.1f}\n",
               mrays[0] / mrays[2], mrays[1] / mrays[2], differ, sink > 0 ? 1.0 : 0.0);
    }
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
    bvhc_close(file);
    free(vertices);
    free(rays);
    return 0;
}
