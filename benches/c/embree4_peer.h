/* What the two outside peer programs (embree_peer.c: one call a ray; embree_batches.c: the batch calls on camera,
 * ambient-occlusion, shadow and incoherent workloads) share: Embree 4.4.0's C API declared from its headers
 * (RenderKit/embree, tag v4.4.0, include/embree4/rtcore_*.h; the embreex wheel's library has one instance level
 * and no RTC_MIN_WIDTH), so no Embree header is needed; reading a file whole; building Embree's scene as its
 * users do (HIGH quality, plain scene flags, isa=avx2, one thread); pinning the process to one core. */
#ifndef BVHC_EMBREE4_PEER_H
#define BVHC_EMBREE4_PEER_H
#define _GNU_SOURCE
#include <sched.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

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

/* rtcore_ray.h: the 8-wide packets, structure of arrays, aligned to 32 bytes. */
struct __attribute__((aligned(32))) RTCRay8 {
    float org_x[8], org_y[8], org_z[8], tnear[8], dir_x[8], dir_y[8], dir_z[8], time[8], tfar[8];
    unsigned mask[8], id[8], flags[8];
};
struct __attribute__((aligned(32))) RTCHit8 {
    float Ng_x[8], Ng_y[8], Ng_z[8], u[8], v[8];
    unsigned primID[8], geomID[8], instID[1][8], instPrimID[1][8];
};
struct __attribute__((aligned(32))) RTCRayHit8 {
    struct RTCRay8 ray;
    struct RTCHit8 hit;
};
/* RTCIntersectArguments and RTCOccludedArguments share this layout (the last pointer is the intersect or occluded
 * callback). flags: RTC_RAY_QUERY_FLAG_INCOHERENT (0, Embree's default) or RTC_RAY_QUERY_FLAG_COHERENT. */
struct RTCQueryArguments {
    unsigned flags, feature_mask;
    void *context, *filter, *callback;
    float min_width_distance_factor; /* read only by builds with RTC_MIN_WIDTH */
};
enum { RTC_RAY_QUERY_FLAG_INCOHERENT = 0, RTC_RAY_QUERY_FLAG_COHERENT = 1 << 16, RTC_FEATURE_FLAG_ALL = ~0 };
void rtcIntersect8(const int *valid, RTCScene scene, struct RTCRayHit8 *rayhit, struct RTCQueryArguments *args);
void rtcOccluded8(const int *valid, RTCScene scene, struct RTCRay8 *ray, struct RTCQueryArguments *args);

#define RTC_INVALID_GEOMETRY_ID 0xffffffffu

static inline double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* The whole of `path`, and its length; exits with a message naming the file when it cannot be read. */
static inline void *read_all(const char *path, size_t *len) {
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
static inline struct RTCRayHit embree_ray(const bvhc_ray *r) {
    struct RTCRayHit rh;
    rh.ray.org_x = r->origin[0], rh.ray.org_y = r->origin[1], rh.ray.org_z = r->origin[2];
    rh.ray.dir_x = r->direction[0], rh.ray.dir_y = r->direction[1], rh.ray.dir_z = r->direction[2];
    rh.ray.tnear = r->t_min, rh.ray.tfar = r->t_max, rh.ray.time = 0.0f;
    rh.ray.mask = ~0u, rh.ray.id = 0, rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID, rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    return rh;
}

/* Embree's scene of `triangles` triangles (nine floats each, unindexed), HIGH quality, plain flags; exits with a
 * message when Embree refuses. */
static inline RTCScene embree_scene(RTCDevice device, const float *vertices, size_t triangles) {
    RTCScene scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(geometry, RTC_BUILD_QUALITY_HIGH);
    float *v = rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, 3 * triangles);
    unsigned *index = rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, triangles);
    if (!v || !index) {
        fprintf(stderr, "Embree error %d\n", rtcGetDeviceError(device));
        exit(1);
    }
    memcpy(v, vertices, 36 * triangles);
    for (size_t k = 0; k < 3 * triangles; k++) index[k] = (unsigned)k;
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(scene, geometry);
    rtcReleaseGeometry(geometry);
    rtcCommitScene(scene);
    return scene;
}

/* One core for the whole run: the one this process starts on. */
static inline void pin_to_one_core(void) {
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(sched_getcpu(), &one);
    sched_setaffinity(0, sizeof one, &one);
}

static inline int by_value(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}
#endif
