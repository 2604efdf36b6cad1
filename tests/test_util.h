/* A small test harness: each test is a function; CHECK macros print both
 * operands and the line on failure. A test program exits 0 when every check
 * passed, 1 otherwise, and 77 (ctest's SKIP_RETURN_CODE) when it skipped. */
#ifndef AS_TEST_UTIL_H
#define AS_TEST_UTIL_H

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static int test_failures;

#define CHECK(cond) do { if (!(cond)) { \
    fprintf(stderr, "%s:%d: CHECK(%s) failed\n", __FILE__, __LINE__, #cond); ++test_failures; } } while (0)
#define CHECK_EQ_INT(a, b) do { long long _a = (long long)(a), _b = (long long)(b); if (_a != _b) { \
    fprintf(stderr, "%s:%d: %s == %s failed: %lld != %lld\n", __FILE__, __LINE__, #a, #b, _a, _b); ++test_failures; } } while (0)
#define CHECK_EQ_U64(a, b) do { unsigned long long _a = (unsigned long long)(a), _b = (unsigned long long)(b); if (_a != _b) { \
    fprintf(stderr, "%s:%d: %s == %s failed: %llu != %llu\n", __FILE__, __LINE__, #a, #b, _a, _b); ++test_failures; } } while (0)
#define CHECK_STR_CONTAINS(hay, needle) do { const char *_h = (hay), *_n = (needle); if (!_h || !strstr(_h, _n)) { \
    fprintf(stderr, "%s:%d: \"%s\" does not contain \"%s\"\n", __FILE__, __LINE__, _h ? _h : "(null)", _n); ++test_failures; } } while (0)

#define RUN_TEST(fn) do { int _before = test_failures; fn(); \
    fprintf(stderr, "%s %s\n", test_failures == _before ? "ok  " : "FAIL", #fn); } while (0)
#define TEST_EXIT() return test_failures ? 1 : 0

#define TEST_SKIP 77

/* Path of a scene in ../shared/scenes (AS_SCENES_DIR), or NULL when it is
 * absent: then the caller skips, except under CI=true, where a missing scene
 * is a failure (test_scene_or_skip exits accordingly). */
/* Reads a whole file into a malloc'd buffer; 0 when it cannot. */
static inline int test_read_file(const char *path, unsigned char **data, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    fseek(f, 0, SEEK_END);
    *size = (size_t)ftell(f);
    fseek(f, 0, SEEK_SET);
    *data = malloc(*size ? *size : 1);
    const int ok = fread(*data, 1, *size, f) == *size;
    fclose(f);
    return ok;
}

/* Whether two files hold the same bytes. */
static inline int test_files_equal(const char *a, const char *b)
{
    unsigned char *x = NULL, *y = NULL;
    size_t nx = 0, ny = 0;
    const int ok = test_read_file(a, &x, &nx) && test_read_file(b, &y, &ny) && nx == ny && memcmp(x, y, nx) == 0;
    free(x);
    free(y);
    return ok;
}

/* Saves without the build record (BREC), whose build time differs from run
 * to run: what a test compares byte for byte. */
static inline as_error_t test_save_reproducible(const as_structure_t *s, const char *path)
{
    as_save_args_t args;
    as_save_args_default(&args);
    args.omit_build_record = true;
    return as_structure_save(s, path, &args);
}

/* An unindexed mesh of n triangles from the 9 n floats at p (triangle t's
 * corners at p[9 t], p[9 t + 3], p[9 t + 6]); frees p. */
static inline as_mesh_t *test_mesh_from_soup(float *p, uint32_t n)
{
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * n);
    for (uint32_t i = 0; i < 3 * n; ++i) ix[i] = i;
    as_mesh_t *m = as_mesh_create(3 * n, p, n, ix);
    free(p);
    free(ix);
    return m;
}

/* The variant named by STRUCTURE BUILDER LAYOUT on a test's command line,
 * into `variant` (defaults otherwise) and "S/B/L" into `name`; 0, or 2
 * (the usage status) with a message when one of the three is unknown. */
static inline int test_parse_variant(char *const words[3], as_build_args_t *variant, char *name, size_t len)
{
    as_build_args_default(variant);
    variant->structure = as_structure_kind_from_name(words[0]);
    variant->builder = as_builder_from_name(variant->structure, words[1]);
    variant->layout = as_layout_from_name(words[2]);
    if (!variant->structure || !variant->builder || !variant->layout) {
        fprintf(stderr, "unknown variant %s/%s/%s\n", words[0], words[1], words[2]);
        return 2;
    }
    snprintf(name, len, "%s/%s/%s", words[0], words[1], words[2]);
    return 0;
}

static inline const char *test_scene_or_exit(const char *name, char *buf, size_t len)
{
#ifdef AS_SCENES_DIR
    snprintf(buf, len, "%s/%s", AS_SCENES_DIR, name);
#else
    snprintf(buf, len, "../shared/scenes/%s", name);
#endif
    if (access(buf, R_OK) == 0) return buf;
    const char *ci = getenv("CI");
    if (ci && strcmp(ci, "true") == 0) {
        fprintf(stderr, "FAIL: scene %s is missing and CI=true\n", buf);
        exit(1);
    }
    fprintf(stderr, "SKIP: scene %s is absent (../shared/scenes not beside the checkout)\n", buf);
    exit(TEST_SKIP);
}

#endif
