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
 * Embree 4.4.0's C API is declared in embree4_peer.h, shared with embree_batches.c. */
#include "embree4_peer.h" /* first: it defines _GNU_SOURCE */

#include <math.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#define ROUNDS_DEFAULT 5
#define CONTENDERS 3

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

int main(int argc, char **argv) {
    if (argc < 4) {
        fprintf(stderr, "usage: embree_peer FILE.bvh TRIANGLES.bin RAYS.bin [ROUNDS]\n");
        return 2;
    }
    int rounds = argc > 4 ? atoi(argv[4]) : ROUNDS_DEFAULT;
    if (rounds < 1 || rounds > 99) rounds = ROUNDS_DEFAULT;
    pin_to_one_core();

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
    RTCScene scene = embree_scene(device, vertices, triangles);

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
