/* Ray and hit files (as.h, formats/SPEC.md): a 32-byte header, then fixed
 * records. The parsers check the header and that the size is exact; record
 * contents are not judged (a NaN ray is the tracer's business). */
#define _POSIX_C_SOURCE 200809L
#include "as_internal.h"
#include "asf_format.h"
#include "atomic_file.h"

#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "ray and hit records are copied as is: libas supports little-endian hosts only"
#endif

_Static_assert(sizeof(as_ray_t) == 32, "a ray record is 32 bytes");
_Static_assert(sizeof(as_hit_t) == 16, "a hit record is 16 bytes");

/* What tells the two kinds apart. */
typedef struct record_kind {
    const char *noun;              /* "ray", for messages */
    uint8_t magic[8];
    uint8_t other_magic[8];        /* the other kind: a clearer message */
    const char *other_noun;
    uint32_t record_size;
} record_kind_t;

static const record_kind_t ray_kind = {
    "ray", AS_RAYS_MAGIC_BYTES, AS_HITS_MAGIC_BYTES, "hit", sizeof(as_ray_t)};
static const record_kind_t hit_kind = {
    "hit", AS_HITS_MAGIC_BYTES, AS_RAYS_MAGIC_BYTES, "ray", sizeof(as_hit_t)};

static as_error_t parse(const record_kind_t *k, const void *data, size_t size, const char *name,
                        void **out, size_t *count)
{
    if (!out || !count)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_%ss_parse: no output pointer", k->noun);
    *out = NULL;
    *count = 0;
    if (!name) name = "(memory)";
    if (!data && size > 0) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "%s: no data", name);

    as_records_header_t h;
    if (size < sizeof h)
        return as_set_error(AS_ERROR_CORRUPT, "%s: file is %zu bytes, shorter than the 32-byte header",
                            name, size);
    memcpy(&h, data, sizeof h);
    if (memcmp(h.magic, k->other_magic, sizeof h.magic) == 0)
        return as_set_error(AS_ERROR_CORRUPT, "%s: a %s file, not a %s file", name, k->other_noun, k->noun);
    if (memcmp(h.magic, k->magic, sizeof h.magic) != 0)
        return as_set_error(AS_ERROR_CORRUPT, "%s: not a %s file (bad magic at offset 0)", name, k->noun);
    if (h.version_major > AS_RECORDS_VERSION_MAJOR)
        return as_set_error(AS_ERROR_VERSION, "%s: %s file version %u.%u is newer than this reader (%d.x)",
                            name, k->noun, h.version_major, h.version_minor, AS_RECORDS_VERSION_MAJOR);
    if (h.version_major == 0)
        return as_set_error(AS_ERROR_CORRUPT, "%s: %s file version 0.%u at offset 8 was never defined",
                            name, k->noun, h.version_minor);
    if (h.record_size != k->record_size)
        return as_set_error(AS_ERROR_CORRUPT, "%s: record_size %" PRIu32 " at offset 12, a %s record is %"
                            PRIu32 " bytes", name, h.record_size, k->noun, k->record_size);
    if (h.reserved != 0)
        return as_set_error(AS_ERROR_CORRUPT, "%s: reserved field at offset 24 is 0x%016" PRIx64
                            ", not zero", name, h.reserved);
    uint64_t body, expected;
    if (!as_mul_u64(h.count, k->record_size, &body) || !as_add_u64(body, sizeof h, &expected))
        return as_set_error(AS_ERROR_CORRUPT, "%s: %" PRIu64 " %s records of %" PRIu32 " bytes do not fit "
                            "in a file (file has %zu bytes)", name, h.count, k->noun, k->record_size, size);
    if (expected != size)
        return as_set_error(AS_ERROR_CORRUPT, "%s: %s: header says %" PRIu64 " records, %" PRIu64
                            " bytes; file has %zu bytes", name, expected > size ? "truncated" : "size mismatch",
                            h.count, expected, size);

    void *records = as_malloc((size_t)body, "records");
    if (!records) return AS_ERROR_OUT_OF_MEMORY;
    if (body) memcpy(records, (const uint8_t *)data + sizeof h, (size_t)body);
    *out = records;
    *count = (size_t)h.count;
    return AS_OK;
}

static as_error_t read_file(const record_kind_t *k, const char *path, void **out, size_t *count)
{
    if (!out || !count)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_%ss_read: no output pointer", k->noun);
    *out = NULL;
    *count = 0;
    as_file_map_t map;
    const as_error_t err = as_file_map(path, &map);
    if (err != AS_OK) return err;
    const as_error_t perr = parse(k, map.data, map.size, path, out, count);
    as_file_unmap(&map);
    return perr;
}

static as_error_t write_file(const record_kind_t *k, const char *path, const void *records, size_t count)
{
    uint64_t body;
    if (count > 0 && !records)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "%s: no %ss to write", path ? path : "(null)", k->noun);
    if (!as_mul_u64(count, k->record_size, &body) || body > SIZE_MAX - sizeof(as_records_header_t))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "%s: %zu %ss are too many", path ? path : "(null)",
                            count, k->noun);
    as_records_header_t h;
    memset(&h, 0, sizeof h);
    memcpy(h.magic, k->magic, sizeof h.magic);
    h.version_major = AS_RECORDS_VERSION_MAJOR;
    h.version_minor = AS_RECORDS_VERSION_MINOR;
    h.record_size = k->record_size;
    h.count = count;
    const as_file_part_t parts[2] = {{&h, sizeof h}, {records, (size_t)body}};
    return as_atomic_write(path, parts, 2);
}

as_error_t as_rays_parse(const void *data, size_t size, const char *name, as_ray_t **out, size_t *count)
{
    if (!out) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "%s: no output pointer", __func__);
    void *p = NULL;
    const as_error_t err = parse(&ray_kind, data, size, name, &p, count);
    *out = p;
    return err;
}

as_error_t as_hits_parse(const void *data, size_t size, const char *name, as_hit_t **out, size_t *count)
{
    if (!out) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "%s: no output pointer", __func__);
    void *p = NULL;
    const as_error_t err = parse(&hit_kind, data, size, name, &p, count);
    *out = p;
    return err;
}

as_error_t as_rays_read(const char *path, as_ray_t **out, size_t *count)
{
    if (!out) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "%s: no output pointer", __func__);
    void *p = NULL;
    const as_error_t err = read_file(&ray_kind, path, &p, count);
    *out = p;
    return err;
}

as_error_t as_hits_read(const char *path, as_hit_t **out, size_t *count)
{
    if (!out) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "%s: no output pointer", __func__);
    void *p = NULL;
    const as_error_t err = read_file(&hit_kind, path, &p, count);
    *out = p;
    return err;
}

as_error_t as_rays_write(const char *path, const as_ray_t *rays, size_t count)
{
    return write_file(&ray_kind, path, rays, count);
}

as_error_t as_hits_write(const char *path, const as_hit_t *hits, size_t count)
{
    return write_file(&hit_kind, path, hits, count);
}
