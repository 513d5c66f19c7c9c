/* What the C test programs share: reading a whole binary file, a float's bit pattern, and the closest hit of
 * each ray printed as one line ("hit t triangle instance", t as a bit pattern in hex, or "miss"). */
#ifndef BVHC_TEST_IO_H
#define BVHC_TEST_IO_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../crates/bvhc-capi/include/bvhc.h"

/* The bytes of the file at `path` (one spare byte allocated, so an empty file is not a null pointer) and their
 * count in `len`; NULL when it cannot be read. */
static inline void *read_all(const char *path, size_t *len) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    *len = (size_t)ftell(f);
    rewind(f);
    void *bytes = malloc(*len + 1);
    if (!bytes || fread(bytes, 1, *len, f) != *len) return NULL;
    fclose(f);
    return bytes;
}

static inline unsigned bits(float f) {
    unsigned u;
    memcpy(&u, &f, 4);
    return u;
}

static inline void print_closest_hits(const bvhc_file *file, const bvhc_ray *rays, size_t count) {
    for (size_t i = 0; i < count; i++) {
        bvhc_hit hit;
        if (bvhc_closest_hit(file, &rays[i], &hit) == 1)
            printf("hit %08x %u %d\n", bits(hit.t), hit.triangle_index, (int)hit.instance_index);
        else
            printf("miss\n");
    }
}

#endif
