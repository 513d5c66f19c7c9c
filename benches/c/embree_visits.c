/* Embree's side of the node-visit count (docs/batches-peer.md, "The tree as well as the kernel"): builds Embree's
 * scene of a triangle file as embree_peer.c does (HIGH quality, isa=avx2, one thread) and traces each ray of a
 * ray file once, rtcIntersect1 then rtcOccluded1, timing nothing. Linked against an Embree built with
 * EMBREE_STAT_COUNTERS=ON, the library prints its counters when the process exits: "normal" for the closest-hit
 * walks, "shadow" for the any-hit walks, node visits ("#nodes") and leaves a ray after dividing by the ray count
 * this program prints. bvhc's counts on the same files: `cargo bench --bench peer` prints "wide node visits".
 *
 *   embree_visits TRIANGLES.bin RAYS.bin        (the files BVHC_PEER_WRITE writes)
 */
#include "embree4_peer.h"

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: embree_visits TRIANGLES.bin RAYS.bin\n");
        return 2;
    }
    size_t triangle_bytes, ray_bytes;
    float *vertices = read_all(argv[1], &triangle_bytes);
    bvhc_ray *rays = read_all(argv[2], &ray_bytes);
    size_t count = ray_bytes / sizeof(bvhc_ray);
    RTCDevice device = rtcNewDevice("threads=1,isa=avx2");
    RTCScene scene = embree_scene(device, vertices, triangle_bytes / 36);
    size_t hits = 0, occluded = 0;
    for (size_t i = 0; i < count; i++) {
        struct RTCRayHit rh = embree_ray(&rays[i]);
        rtcIntersect1(scene, &rh, NULL);
        hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
    }
    for (size_t i = 0; i < count; i++) {
        struct RTCRayHit rh = embree_ray(&rays[i]);
        rtcOccluded1(scene, &rh.ray, NULL);
        occluded += rh.ray.tfar < 0.0f;
    }
    printf("{\"rays\": %zu, \"hits\": %zu, \"occluded\": %zu}\n", count, hits, occluded);
    fflush(stdout);
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
    free(rays);
    free(vertices);
    return 0;
}
