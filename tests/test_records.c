/* Ray and hit files: round trips, and every way the parsers refuse a file,
 * each with its code and message (formats/SPEC.md, "Ray and hit files"). */
#define _POSIX_C_SOURCE 200809L
#include "as/as.h"
#include "asf_format.h"
#include "test_util.h"
#include "test_scratch.h"

#include <dirent.h>
#include <math.h>
#include <stdint.h>

#define CHECK_STR_STARTS(s, prefix) do { const char *_s = (s), *_p = (prefix); \
    if (!_s || strncmp(_s, _p, strlen(_p)) != 0) { \
        fprintf(stderr, "%s:%d: \"%s\" does not start with \"%s\"\n", __FILE__, __LINE__, \
                _s ? _s : "(null)", _p); ++test_failures; } } while (0)

static void write_bytes(const char *path, const void *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    if (!f || (size && fwrite(data, 1, size, f) != size)) {
        fprintf(stderr, "cannot write %s\n", path);
        exit(1);
    }
    fclose(f);
}

static uint8_t *read_bytes(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    const long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *p = malloc(n > 0 ? (size_t)n : 1);
    if (n > 0 && fread(p, 1, (size_t)n, f) != (size_t)n) {
        free(p);
        p = NULL;
    }
    fclose(f);
    *size = (size_t)n;
    return p;
}

enum { RAYS = 5 };

static void sample_rays(as_ray_t r[RAYS])
{
    for (int i = 0; i < RAYS; ++i)
        r[i] = (as_ray_t){{(float)i, 1.0f, -2.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY};
    r[3].dir[1] = NAN; /* bad rays are the tracer's business, not the file's */
}

static void sample_hits(as_hit_t h[RAYS])
{
    for (int i = 0; i < RAYS; ++i) h[i] = (as_hit_t){1.5f * (float)i, (uint32_t)i * 7u, 0.25f, 0.5f};
    h[2] = (as_hit_t){INFINITY, AS_NO_HIT, 0.0f, 0.0f};
}

/* A ray file in memory, for the damage tests. */
static uint8_t *ray_file(size_t *size)
{
    as_ray_t r[RAYS];
    sample_rays(r);
    const char *path = tmp_path("sample.rays");
    if (as_rays_write(path, r, RAYS) != AS_OK) {
        fprintf(stderr, "as_rays_write: %s\n", as_get_error_message());
        exit(1);
    }
    uint8_t *p = read_bytes(path, size);
    remove(path);
    return p;
}

static as_records_header_t *header_of(uint8_t *file) { return (as_records_header_t *)file; }

static void expect_rays_refused(const uint8_t *file, size_t size, as_error_t code, const char *needle)
{
    as_ray_t *rays = (as_ray_t *)1;
    size_t count = 99;
    as_clear_error();
    CHECK_EQ_INT(as_rays_parse(file, size, "sample.rays", &rays, &count), code);
    CHECK(rays == NULL);
    CHECK_EQ_U64(count, 0);
    CHECK_STR_STARTS(as_get_error_message(), "sample.rays: ");
    CHECK_STR_CONTAINS(as_get_error_message(), needle);
}

/* ------------------------------------------------------------------------ */

static void rays_round_trip_bit_exact(void)
{
    as_ray_t r[RAYS];
    sample_rays(r);
    const char *path = tmp_path("round_trip.rays");
    CHECK_EQ_INT(as_rays_write(path, r, RAYS), AS_OK);
    CHECK_EQ_INT(temp_leftovers(), 0);
    size_t size = 0;
    uint8_t *bytes = read_bytes(path, &size);
    CHECK_EQ_U64(size, 32 + RAYS * 32);
    CHECK(bytes && memcmp(bytes, AS_RAYS_MAGIC_BYTES, 8) == 0);
    CHECK(bytes && memcmp(bytes + 32, r, sizeof r) == 0);
    as_ray_t *back = NULL;
    size_t count = 0;
    CHECK_EQ_INT(as_rays_read(path, &back, &count), AS_OK);
    CHECK_EQ_U64(count, RAYS);
    CHECK(back && memcmp(back, r, sizeof r) == 0); /* NaN included: bits, not values */
    free(back);
    free(bytes);
    remove(path);
}

static void hits_round_trip_bit_exact(void)
{
    as_hit_t h[RAYS];
    sample_hits(h);
    const char *path = tmp_path("round_trip.hits");
    CHECK_EQ_INT(as_hits_write(path, h, RAYS), AS_OK);
    CHECK_EQ_INT(temp_leftovers(), 0);
    size_t size = 0;
    uint8_t *bytes = read_bytes(path, &size);
    CHECK_EQ_U64(size, 32 + RAYS * 16);
    CHECK(bytes && memcmp(bytes, AS_HITS_MAGIC_BYTES, 8) == 0);
    CHECK(bytes && header_of(bytes)->record_size == 16);
    as_hit_t *back = NULL;
    size_t count = 0;
    CHECK_EQ_INT(as_hits_read(path, &back, &count), AS_OK);
    CHECK_EQ_U64(count, RAYS);
    CHECK(back && memcmp(back, h, sizeof h) == 0);
    CHECK(back && back[2].prim == AS_NO_HIT && isinf(back[2].t));
    free(back);
    free(bytes);
    remove(path);
}

static void empty_ray_file_round_trips(void)
{
    const char *path = tmp_path("empty.rays");
    CHECK_EQ_INT(as_rays_write(path, NULL, 0), AS_OK);
    as_ray_t *back = NULL;
    size_t count = 7;
    CHECK_EQ_INT(as_rays_read(path, &back, &count), AS_OK);
    CHECK_EQ_U64(count, 0);
    CHECK(back != NULL); /* a valid pointer to free, even for no records */
    free(back);
    remove(path);
}

static void rays_reject_bad_magic(void)
{
    size_t size;
    uint8_t *file = ray_file(&size);
    file[0] = 'X';
    expect_rays_refused(file, size, AS_ERROR_CORRUPT, "not a ray file (bad magic at offset 0)");
    free(file);
}

static void hit_file_is_not_read_as_rays(void)
{
    as_hit_t h[RAYS];
    sample_hits(h);
    const char *path = tmp_path("mixed_up.hits");
    CHECK_EQ_INT(as_hits_write(path, h, RAYS), AS_OK);
    as_ray_t *rays = NULL;
    size_t count = 0;
    CHECK_EQ_INT(as_rays_read(path, &rays, &count), AS_ERROR_CORRUPT);
    CHECK_STR_STARTS(as_get_error_message(), path);
    CHECK_STR_CONTAINS(as_get_error_message(), "a hit file, not a ray file");
    remove(path);
}

static void rays_reject_newer_major_and_accept_newer_minor(void)
{
    size_t size;
    uint8_t *file = ray_file(&size);
    header_of(file)->version_major = 2;
    expect_rays_refused(file, size, AS_ERROR_VERSION, "ray file version 2.0 is newer than this reader (1.x)");
    header_of(file)->version_major = 1;
    header_of(file)->version_minor = 3;
    as_ray_t *rays = NULL;
    size_t count = 0;
    CHECK_EQ_INT(as_rays_parse(file, size, "sample.rays", &rays, &count), AS_OK);
    CHECK_EQ_U64(count, RAYS);
    free(rays);
    free(file);
}

static void rays_reject_wrong_record_size(void)
{
    size_t size;
    uint8_t *file = ray_file(&size);
    header_of(file)->record_size = 16;
    expect_rays_refused(file, size, AS_ERROR_CORRUPT, "record_size 16 at offset 12, a ray record is 32 bytes");
    free(file);
}

static void rays_reject_nonzero_reserved(void)
{
    size_t size;
    uint8_t *file = ray_file(&size);
    header_of(file)->reserved = 1;
    expect_rays_refused(file, size, AS_ERROR_CORRUPT, "reserved field at offset 24");
    free(file);
}

static void rays_reject_file_shorter_than_header(void)
{
    size_t size;
    uint8_t *file = ray_file(&size);
    expect_rays_refused(file, 31, AS_ERROR_CORRUPT, "file is 31 bytes, shorter than the 32-byte header");
    expect_rays_refused(NULL, 0, AS_ERROR_CORRUPT, "file is 0 bytes");
    const char *path = tmp_path("empty_file.rays");
    write_bytes(path, "", 0);
    as_ray_t *rays = NULL;
    size_t count = 0;
    CHECK_EQ_INT(as_rays_read(path, &rays, &count), AS_ERROR_CORRUPT);
    CHECK_STR_STARTS(as_get_error_message(), path);
    remove(path);
    free(file);
}

static void rays_reject_truncated_file(void)
{
    size_t size;
    uint8_t *file = ray_file(&size);
    expect_rays_refused(file, size - 1, AS_ERROR_CORRUPT, "truncated: header says 5 records, 192 bytes; file has 191 bytes");
    free(file);
}

static void rays_reject_trailing_bytes(void)
{
    size_t size;
    uint8_t *file = ray_file(&size);
    uint8_t *longer = calloc(1, size + 32);
    memcpy(longer, file, size);
    expect_rays_refused(longer, size + 32, AS_ERROR_CORRUPT, "size mismatch: header says 5 records, 192 bytes; file has 224 bytes");
    free(longer);
    free(file);
}

static void rays_reject_count_that_overflows(void)
{
    size_t size;
    uint8_t *file = ray_file(&size);
    header_of(file)->count = UINT64_MAX / 16;
    expect_rays_refused(file, size, AS_ERROR_CORRUPT, "do not fit in a file");
    header_of(file)->count = (UINT64_MAX - 31) / 32; /* the product fits, adding the header does not */
    expect_rays_refused(file, size, AS_ERROR_CORRUPT, "do not fit in a file");
    free(file);
}

static void hits_reject_wrong_record_size_and_newer_major(void)
{
    as_hit_t h[RAYS];
    sample_hits(h);
    const char *path = tmp_path("damaged.hits");
    CHECK_EQ_INT(as_hits_write(path, h, RAYS), AS_OK);
    size_t size = 0;
    uint8_t *file = read_bytes(path, &size);
    as_hit_t *hits = NULL;
    size_t count = 0;
    header_of(file)->record_size = 32;
    CHECK_EQ_INT(as_hits_parse(file, size, "sample.hits", &hits, &count), AS_ERROR_CORRUPT);
    CHECK_STR_CONTAINS(as_get_error_message(), "sample.hits: record_size 32 at offset 12, a hit record is 16 bytes");
    header_of(file)->record_size = 16;
    header_of(file)->version_major = 7;
    CHECK_EQ_INT(as_hits_parse(file, size, "sample.hits", &hits, &count), AS_ERROR_VERSION);
    CHECK_STR_CONTAINS(as_get_error_message(), "sample.hits: hit file version 7.0 is newer than this reader (1.x)");
    header_of(file)->version_major = 1;
    CHECK_EQ_INT(as_hits_parse(file, size - 16, "sample.hits", &hits, &count), AS_ERROR_CORRUPT);
    CHECK_STR_CONTAINS(as_get_error_message(), "truncated: header says 5 records, 112 bytes; file has 96 bytes");
    CHECK(hits == NULL);
    free(file);
    remove(path);
}

static void readers_report_missing_file(void)
{
    const char *path = tmp_path("missing.rays");
    as_ray_t *rays = NULL;
    as_hit_t *hits = NULL;
    size_t count = 0;
    CHECK_EQ_INT(as_rays_read(path, &rays, &count), AS_ERROR_FILE_NOT_FOUND);
    CHECK_STR_STARTS(as_get_error_message(), path);
    CHECK_EQ_INT(as_hits_read(path, &hits, &count), AS_ERROR_FILE_NOT_FOUND);
    CHECK_STR_STARTS(as_get_error_message(), path);
}

static void writers_report_io_error_naming_the_path(void)
{
    as_ray_t r[RAYS];
    sample_rays(r);
    const char *path = tmp_path("no_such_dir/out.rays");
    CHECK_EQ_INT(as_rays_write(path, r, RAYS), AS_ERROR_IO);
    CHECK_STR_STARTS(as_get_error_message(), path);
    CHECK_STR_CONTAINS(as_get_error_message(), "No such file or directory");
    CHECK_EQ_INT(as_hits_write(path, NULL, 3), AS_ERROR_INVALID_ARGUMENT);
    CHECK_EQ_INT(temp_leftovers(), 0);
}

int main(void)
{
    if (!tmp_dir_make("as_test_records")) return 1;
    RUN_TEST(rays_round_trip_bit_exact);
    RUN_TEST(hits_round_trip_bit_exact);
    RUN_TEST(empty_ray_file_round_trips);
    RUN_TEST(rays_reject_bad_magic);
    RUN_TEST(hit_file_is_not_read_as_rays);
    RUN_TEST(rays_reject_newer_major_and_accept_newer_minor);
    RUN_TEST(rays_reject_wrong_record_size);
    RUN_TEST(rays_reject_nonzero_reserved);
    RUN_TEST(rays_reject_file_shorter_than_header);
    RUN_TEST(rays_reject_truncated_file);
    RUN_TEST(rays_reject_trailing_bytes);
    RUN_TEST(rays_reject_count_that_overflows);
    RUN_TEST(hits_reject_wrong_record_size_and_newer_major);
    RUN_TEST(readers_report_missing_file);
    RUN_TEST(writers_report_io_error_naming_the_path);
    remove_tmp_dir();
    TEST_EXIT();
}
