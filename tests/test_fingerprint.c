/* A structure's fingerprint is its content: the same for the structure as
 * built, as saved and loaded (with or without its build record, raw or
 * with zstd sections), different when one byte of a section or of META
 * changes, and different between two structures of the same mesh. */
#include "structure.h"
#include "test_util.h"

#include <string.h>
#include <unistd.h>

static void fingerprint_follows_the_bytes(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(m != NULL);
    if (!m) return;
    as_structure_t *built = as_structure_build(m, NULL);
    CHECK(built != NULL);
    uint8_t fb[16], fl[16], fz[16], fo[16];
    CHECK_EQ_INT(as_structure_fingerprint(built, fb), AS_OK);

    char raw[] = "/tmp/as_fp_raw_XXXXXX", packed[] = "/tmp/as_fp_zst_XXXXXX";
    close(mkstemp(raw));
    close(mkstemp(packed));
    CHECK_EQ_INT(test_save_reproducible(built, raw), AS_OK);
    as_save_args_t sa;
    as_save_args_default(&sa);
    sa.compression_level = 3;
    CHECK_EQ_INT(as_structure_save(built, packed, &sa), AS_OK);
    as_structure_t *loaded = as_structure_load(raw, NULL), *unpacked = as_structure_load(packed, NULL);
    CHECK(loaded && unpacked);
    if (loaded && unpacked) {
        CHECK_EQ_INT(as_structure_fingerprint(loaded, fl), AS_OK);
        CHECK_EQ_INT(as_structure_fingerprint(unpacked, fz), AS_OK);
        CHECK(memcmp(fb, fl, 16) == 0);
        CHECK(memcmp(fb, fz, 16) == 0);
    }

    /* One flipped bit in the last section's last byte, then in META. */
    as_section_t *last = &built->sections[built->section_count - 1];
    unsigned char *byte = (unsigned char *)last->data + last->bytes - 1;
    *byte ^= 1;
    CHECK_EQ_INT(as_structure_fingerprint(built, fo), AS_OK);
    CHECK(memcmp(fb, fo, 16) != 0);
    *byte ^= 1;
    const double sah = built->meta.sah_cost;
    built->meta.sah_cost = sah + 1.0;
    CHECK_EQ_INT(as_structure_fingerprint(built, fo), AS_OK);
    CHECK(memcmp(fb, fo, 16) != 0);
    built->meta.sah_cost = sah;
    CHECK_EQ_INT(as_structure_fingerprint(built, fo), AS_OK);
    CHECK(memcmp(fb, fo, 16) == 0);

    /* Another structure of the same mesh. */
    as_build_args_t args;
    as_build_args_default(&args);
    args.structure = AS_STRUCT_GRID;
    args.builder = as_builder_from_name(args.structure, "grid");
    as_structure_t *grid = as_structure_build(m, &args);
    CHECK(grid != NULL);
    if (grid) {
        CHECK_EQ_INT(as_structure_fingerprint(grid, fo), AS_OK);
        CHECK(memcmp(fb, fo, 16) != 0);
    }
    as_structure_release(grid);
    as_structure_release(loaded);
    as_structure_release(unpacked);
    as_structure_release(built);
    as_mesh_release(m);
    unlink(raw);
    unlink(packed);
}

/* Validation remembered: a structure that passed as_structure_validate_recorded
 * is not walked again by later calls, a record lists it, and plain
 * as_structure_validate still walks (so damage made in memory is found). */
static void validate_recorded_walks_once_per_fingerprint(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(m != NULL);
    if (!m) return;
    as_structure_t *s = as_structure_build(m, NULL);
    char record[] = "/tmp/as_fp_record_XXXXXX";
    close(mkstemp(record));
    unlink(record); /* a missing record lists nothing */
    as_validation_info_t info;
    CHECK_EQ_INT(as_structure_validate_recorded(s, record, &info), AS_OK);
    CHECK(!info.skipped);
    CHECK(info.validate_ms > 0.0);
    as_structure_t *again = as_structure_build(m, NULL);
    CHECK_EQ_INT(as_structure_validate_recorded(again, record, &info), AS_OK);
    CHECK(info.skipped);
    CHECK(info.validate_ms == 0.0);

    /* Damage in memory: the plain walk finds it. */
    /* The root's first child index (node layout: formats/SPEC.md). */
    const as_section_t *nodes = as_structure_find(s, ASF_TAG_BVH2);
    CHECK(nodes != NULL);
    if (!nodes) return;
    int32_t *child = (int32_t *)((unsigned char *)nodes->data + 48);
    const int32_t saved = *child;
    *child = -12345;
    CHECK_EQ_INT(as_structure_validate(s), AS_ERROR_INVALID_STRUCTURE);
    *child = saved;
    CHECK_EQ_INT(as_structure_validate(s), AS_OK);
    as_structure_release(s);
    as_structure_release(again);
    as_mesh_release(m);
    unlink(record);
}

int main(void)
{
    RUN_TEST(fingerprint_follows_the_bytes);
    RUN_TEST(validate_recorded_walks_once_per_fingerprint);
    TEST_EXIT();
}
