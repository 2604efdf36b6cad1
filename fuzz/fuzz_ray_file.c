/* Fuzzes the ray and hit file parsers (as_rays_parse, as_hits_parse).
 *
 * Asserts, through ASan and UBSan: no input makes them read outside the
 * buffer, overflow or leak; an accepted file has exactly 32 + count *
 * record_size bytes and its records are the bytes after the header; a
 * refused one sets an error with a message and returns no records. */
#include "as/as.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check(const uint8_t *data, size_t size, as_error_t err, const void *records,
                  size_t count, size_t record_size)
{
    if (err != AS_OK) {
        if (records || count || as_get_error_message()[0] == '\0') abort();
        return;
    }
    if (!records || size != 32 + count * record_size) abort();
    if (count && memcmp(records, data + 32, count * record_size) != 0) abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    /* A copy of exactly `size` bytes, so that ASan sees a read past it. */
    uint8_t *copy = malloc(size ? size : 1);
    if (!copy) return 0;
    if (size) memcpy(copy, data, size);

    as_ray_t *rays = NULL;
    size_t count = 0;
    as_clear_error();
    as_error_t err = as_rays_parse(copy, size, "fuzz.rays", &rays, &count);
    check(copy, size, err, rays, count, sizeof(as_ray_t));
    free(rays);

    as_hit_t *hits = NULL;
    count = 0;
    as_clear_error();
    err = as_hits_parse(copy, size, "fuzz.hits", &hits, &count);
    check(copy, size, err, hits, count, sizeof(as_hit_t));
    free(hits);

    free(copy);
    return 0;
}
