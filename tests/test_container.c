/* The .asf container: what the writer produces, and every way the reader
 * refuses a damaged file, each with its code and message (formats/SPEC.md,
 * "What a reader must check"). */
#define _POSIX_C_SOURCE 200809L
#include "asf_container.h"
#include "as_internal.h"
#include "test_util.h"
#include "test_scratch.h"

#include <dirent.h>
#include <stdint.h>
#include <sys/stat.h>

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

/* A sample structure: META (raw), BVH2 (compressible nodes), TRI4
 * (pseudo-random floats, which zstd cannot shrink: stored raw). */
enum { NODES = 96, TRIS = 40 };
static as_meta_t meta;
static uint8_t nodes[NODES * 64];
static uint8_t tris[TRIS * 48];

static void make_sample(asf_section_desc_t desc[3], int level)
{
    memset(&meta, 0, sizeof meta);
    strcpy(meta.writer, "libas");
    meta.structure_kind = AS_STRUCT_BVH;
    meta.layout = AS_LAYOUT_BVH2_CHILD_BOUNDS;
    meta.layout_version = 1;
    meta.triangle_count = TRIS;
    for (size_t i = 0; i < sizeof nodes; ++i) nodes[i] = (uint8_t)(i % 64 < 48 ? i / 64 : 0);
    uint64_t x = 0x9E3779B97F4A7C15ull;
    for (size_t i = 0; i < sizeof tris; ++i) {
        x ^= x << 13; x ^= x >> 7; x ^= x << 17;
        tris[i] = (uint8_t)x;
    }
    desc[0] = (asf_section_desc_t){ASF_TAG_META, ASF_SECTION_REQUIRED, &meta, sizeof meta, 1, sizeof meta, level};
    desc[1] = (asf_section_desc_t){ASF_TAG_BVH2, ASF_SECTION_REQUIRED, nodes, sizeof nodes, NODES, 64, level};
    desc[2] = (asf_section_desc_t){ASF_TAG_TRI4, ASF_SECTION_REQUIRED, tris, sizeof tris, TRIS, 48, level};
}

static uint8_t *sample_file(int level, size_t *size)
{
    asf_section_desc_t desc[3];
    make_sample(desc, level);
    void *buf = NULL;
    const as_error_t err = asf_write_memory(desc, 3, &buf, size);
    if (err != AS_OK) {
        fprintf(stderr, "asf_write_memory: %s\n", as_get_error_message());
        exit(1);
    }
    return buf;
}

/* The same file as a 1.0 writer made it: no CSUM, so that the reader
 * verifies each section's own checksum. CSUM is the last section, so
 * cutting the file at its offset leaves a valid 1.0 file. */
static uint8_t *sample_file_1_0(int level, size_t *size)
{
    uint8_t *file = sample_file(level, size);
    asf_header_t *h = (asf_header_t *)file;
    const asf_section_entry_t *csum = (const asf_section_entry_t *)(file + 64 + 64 * (size_t)(h->section_count - 1));
    if (csum->tag != ASF_TAG_CSUM) {
        fprintf(stderr, "sample_file: the last section is not CSUM\n");
        exit(1);
    }
    *size = (size_t)csum->offset;
    h->file_size = csum->offset;
    h->version_minor = 0;
    h->section_count -= 1;
    h->table_checksum = as_hash64(file + 64, (size_t)h->section_count * 64);
    return file;
}

static const uint32_t known[] = {ASF_TAG_META, ASF_TAG_BVH2, ASF_TAG_TRI4};
static const asf_open_args_t verify = {1, known, 3};
static const asf_open_args_t no_verify = {0, known, 3};

static asf_header_t *header_of(uint8_t *file) { return (asf_header_t *)file; }
static asf_section_entry_t *entry_of(uint8_t *file, uint32_t i)
{
    return (asf_section_entry_t *)(file + 64 + 64 * (size_t)i);
}

/* After editing an entry, so that the reader gets past the table checksum
 * to the check under test. */
static void fix_table(uint8_t *file)
{
    asf_header_t *h = header_of(file);
    h->table_checksum = as_hash64(file + h->section_table_offset,
                                  (size_t)h->section_count * h->section_entry_size);
}

/* Opens from memory, expects failure with `code` and a message that starts
 * with the name and contains `needle`. */
static void expect_refused(const uint8_t *file, size_t size, const asf_open_args_t *args,
                           as_error_t code, const char *needle)
{
    as_clear_error();
    asf_file_t *f = asf_open_memory(file, size, "sample.asf", args);
    CHECK(f == NULL);
    asf_close(f);
    CHECK_EQ_INT(as_get_error(), code);
    CHECK_STR_STARTS(as_get_error_message(), "sample.asf: ");
    CHECK_STR_CONTAINS(as_get_error_message(), needle);
}

static void check_sections_match(const asf_file_t *f)
{
    CHECK_EQ_U64(asf_section_count(f), 4);
    CHECK_EQ_INT(asf_find_section(f, ASF_TAG_CSUM), 3);
    const void *want[3] = {&meta, nodes, tris};
    const size_t size[3] = {sizeof meta, sizeof nodes, sizeof tris};
    for (uint32_t i = 0; i < 3; ++i) {
        const asf_section_entry_t *e = asf_section_entry(f, i);
        const void *data = asf_section_data(f, i);
        CHECK(data != NULL);
        CHECK_EQ_U64(e->raw_size, size[i]);
        CHECK_EQ_U64((uintptr_t)data % 64, 0);
        CHECK(data && memcmp(data, want[i], size[i]) == 0);
    }
    CHECK_EQ_INT(asf_find_section(f, ASF_TAG_TRI4), 2);
    CHECK_EQ_INT(asf_find_section(f, ASF_TAG('N', 'O', 'N', 'E')), -1);
}

/* ------------------------------------------------------------------------ */

static void writer_lays_out_header_table_and_aligned_sections(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    const asf_header_t *h = header_of(file);
    CHECK(memcmp(h->magic, ASF_MAGIC_BYTES, 8) == 0);
    CHECK_EQ_INT(h->version_major, ASF_VERSION_MAJOR);
    CHECK_EQ_INT(h->version_minor, ASF_VERSION_MINOR);
    CHECK_EQ_INT(h->header_size, 64);
    CHECK_EQ_INT(h->section_entry_size, 64);
    CHECK_EQ_U64(h->section_table_offset, 64);
    CHECK_EQ_U64(h->file_size, size);
    CHECK_EQ_INT(h->section_count, 4);
    CHECK_EQ_U64(h->table_checksum, as_hash64(file + 64, 4 * 64));
    uint64_t end = 64 + 4 * 64;
    for (uint32_t i = 0; i < 3; ++i) {
        const asf_section_entry_t *e = entry_of(file, i);
        CHECK_EQ_U64(e->offset % 64, 0);
        CHECK(e->offset >= end);
        for (uint64_t b = end; b < e->offset; ++b) CHECK_EQ_INT(file[b], 0); /* padding */
        CHECK_EQ_U64(e->stored_size, e->raw_size);
        CHECK_EQ_INT(e->flags, ASF_SECTION_REQUIRED);
        CHECK_EQ_U64(e->checksum, as_hash64(file + e->offset, (size_t)e->raw_size));
        end = e->offset + e->stored_size;
    }
    /* Last, CSUM: optional, raw, one hash per 1 MiB chunk of each section
     * (one each here), seeded with the section's index and the chunk's. */
    const asf_section_entry_t *c = entry_of(file, 3);
    CHECK_EQ_U64(c->tag, ASF_TAG_CSUM);
    CHECK_EQ_INT(c->flags, 0);
    CHECK(c->offset >= end && c->offset % 64 == 0);
    CHECK_EQ_U64(c->raw_size, 16 + 3 * 8);
    CHECK_EQ_U64(c->stored_size, c->raw_size);
    CHECK_EQ_U64(c->checksum, as_hash64(file + c->offset, (size_t)c->raw_size));
    asf_csum_head_t head;
    memcpy(&head, file + c->offset, sizeof head);
    CHECK_EQ_INT(head.chunk_log2, 20);
    CHECK_EQ_INT(head.covered_sections, 3);
    CHECK_EQ_U64(head.hash_count, 3);
    const void *data[3] = {&meta, nodes, tris};
    const size_t bytes[3] = {sizeof meta, sizeof nodes, sizeof tris};
    for (uint32_t i = 0; i < 3; ++i) {
        uint64_t stored;
        memcpy(&stored, file + c->offset + 16 + 8 * i, 8);
        CHECK_EQ_U64(stored, as_hash64_seeded(data[i], bytes[i], (uint64_t)i << 32));
    }
    CHECK_EQ_U64(size % 64, 0);
    free(file);
}

static void round_trip_in_memory_uncompressed(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    asf_file_t *f = asf_open_memory(file, size, "sample.asf", &verify);
    CHECK(f != NULL);
    if (f) {
        check_sections_match(f);
        for (uint32_t i = 0; i < 4; ++i) CHECK_EQ_INT(asf_section_checksum_verified(f, i), 1);
        /* Raw sections of a 64-aligned buffer are used in place. */
        CHECK(asf_section_data(f, 1) == file + entry_of(file, 1)->offset);
        CHECK_EQ_U64(asf_size(f), size);
        CHECK(strcmp(asf_name(f), "sample.asf") == 0);
    }
    asf_close(f);
    free(file);
}

static void round_trip_in_memory_compressed(void)
{
    size_t size;
    uint8_t *file = sample_file(3, &size);
    const asf_section_entry_t *bvh = entry_of(file, 1), *tri = entry_of(file, 2);
    CHECK_EQ_INT(bvh->flags, ASF_SECTION_REQUIRED | ASF_SECTION_ZSTD);
    CHECK(bvh->stored_size < bvh->raw_size);
    CHECK_EQ_U64(bvh->checksum, as_hash64(nodes, sizeof nodes)); /* of the raw bytes */
    asf_file_t *f = asf_open_memory(file, size, "sample.asf", &verify);
    CHECK(f != NULL);
    if (f) check_sections_match(f);
    asf_close(f);
    /* Random bytes do not shrink: stored raw, no ZSTD flag. */
    CHECK_EQ_INT(tri->flags, ASF_SECTION_REQUIRED);
    CHECK_EQ_U64(tri->stored_size, tri->raw_size);
    free(file);
}

static void round_trip_on_disk_matches_memory_writer(void)
{
    for (int level = 0; level <= 19; level += 19) {
        asf_section_desc_t desc[3];
        make_sample(desc, level);
        const char *path = tmp_path("round_trip.asf");
        CHECK_EQ_INT(asf_write(path, desc, 3), AS_OK);
        CHECK_EQ_INT(temp_leftovers(), 0);
        size_t disk_size = 0, mem_size = 0;
        uint8_t *disk = read_bytes(path, &disk_size);
        uint8_t *mem = sample_file(level, &mem_size);
        CHECK_EQ_U64(disk_size, mem_size);
        CHECK(disk && mem && disk_size == mem_size && memcmp(disk, mem, mem_size) == 0);
        asf_file_t *f = asf_open(path, &verify);
        CHECK(f != NULL);
        if (f) {
            check_sections_match(f);
            CHECK_EQ_U64(asf_header(f)->file_size, disk_size);
        }
        asf_close(f);
        free(disk);
        free(mem);
        remove(path);
    }
}

static void writer_replaces_an_existing_file(void)
{
    const char *path = tmp_path("replace.asf");
    write_bytes(path, "old contents", 12);
    chmod(path, 0640);
    asf_section_desc_t desc[3];
    make_sample(desc, 0);
    CHECK_EQ_INT(asf_write(path, desc, 3), AS_OK);
    asf_file_t *f = asf_open(path, &verify);
    CHECK(f != NULL);
    asf_close(f);
    struct stat st;
    CHECK_EQ_INT(stat(path, &st), 0);
    CHECK_EQ_INT(st.st_mode & 0777, 0640);
    CHECK_EQ_INT(temp_leftovers(), 0);
    remove(path);
}

static void writer_reports_io_error_naming_the_path(void)
{
    const char *path = tmp_path("no_such_dir/out.asf");
    asf_section_desc_t desc[3];
    make_sample(desc, 0);
    CHECK_EQ_INT(asf_write(path, desc, 3), AS_ERROR_IO);
    CHECK_STR_STARTS(as_get_error_message(), path);
    CHECK_STR_CONTAINS(as_get_error_message(), "No such file or directory");
    CHECK_EQ_INT(temp_leftovers(), 0);
}

static void writer_rejects_inconsistent_sections(void)
{
    asf_section_desc_t desc[3];
    void *buf = NULL;
    size_t size = 0;
    make_sample(desc, 0);
    desc[1].stride = 0;
    CHECK_EQ_INT(asf_write_memory(desc, 3, &buf, &size), AS_ERROR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(as_get_error_message(), "section BVH2 (index 1): stride is 0");
    make_sample(desc, 0);
    desc[2].element_count += 1;
    CHECK_EQ_INT(asf_write_memory(desc, 3, &buf, &size), AS_ERROR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(as_get_error_message(), "41 elements of 48 bytes is not 1920 bytes");
    make_sample(desc, 0);
    desc[0].flags = 0x100;
    CHECK_EQ_INT(asf_write_memory(desc, 3, &buf, &size), AS_ERROR_INVALID_ARGUMENT);
    make_sample(desc, 23);
    CHECK_EQ_INT(asf_write_memory(desc, 3, &buf, &size), AS_ERROR_INVALID_ARGUMENT);
    CHECK(buf == NULL);
}

static void empty_container_and_empty_section_round_trip(void)
{
    void *buf = NULL;
    size_t size = 0;
    CHECK_EQ_INT(asf_write_memory(NULL, 0, &buf, &size), AS_OK);
    CHECK_EQ_U64(size, 64 + 64 + 64); /* header, CSUM's entry, its 16 bytes padded */
    asf_file_t *f = asf_open_memory(buf, size, "empty.asf", &verify);
    CHECK(f != NULL);
    if (f) CHECK_EQ_U64(asf_section_count(f), 1);
    asf_close(f);
    free(buf);

    const asf_section_desc_t desc[2] = {{ASF_TAG_TRI4, ASF_SECTION_REQUIRED, NULL, 0, 0, 48, 3},
                                        {ASF_TAG_META, ASF_SECTION_REQUIRED, NULL, 0, 0, 256, 0}};
    CHECK_EQ_INT(asf_write_memory(desc, 2, &buf, &size), AS_OK);
    f = asf_open_memory(buf, size, "empty_sections.asf", &verify);
    CHECK(f != NULL);
    if (f) {
        CHECK(asf_section_data(f, 0) != NULL);
        CHECK_EQ_U64(asf_section_entry(f, 1)->raw_size, 0);
    }
    asf_close(f);
    free(buf);
}

static void reader_copies_sections_of_a_misaligned_buffer_to_aligned_memory(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    uint8_t *shifted = malloc(size + 1);
    memcpy(shifted + 1, file, size);
    asf_file_t *f = asf_open_memory(shifted + 1, size, "sample.asf", &verify);
    CHECK(f != NULL);
    if (f) check_sections_match(f);
    asf_close(f);
    free(shifted);
    free(file);
}

static void reader_accepts_newer_minor_with_longer_header_and_entries(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    const asf_section_entry_t *e = entry_of(file, 1);
    /* A newer minor version as a future writer might make it: 128-byte
     * header and entries whose extra bytes this reader ignores. */
    const size_t out_size = 256 + (size_t)((e->raw_size + 63) / 64 * 64);
    uint8_t *out = calloc(1, out_size);
    memcpy(out, file, 64);
    asf_header_t *h = header_of(out);
    h->version_minor = ASF_VERSION_MINOR + 1;
    h->header_size = 128;
    h->section_entry_size = 128;
    h->section_count = 1;
    h->section_table_offset = 128;
    h->file_size = out_size;
    memset(out + 64, 0xAB, 64);               /* header bytes 1.0 does not know */
    memcpy(out + 128, e, 64);
    memset(out + 192, 0xCD, 64);              /* entry bytes 1.0 does not know */
    ((asf_section_entry_t *)(out + 128))->offset = 256;
    memcpy(out + 256, file + e->offset, (size_t)e->raw_size);
    h->table_checksum = as_hash64(out + 128, 128);
    asf_file_t *f = asf_open_memory(out, out_size, "sample.asf", &verify);
    CHECK(f != NULL);
    if (f) {
        CHECK_EQ_INT(asf_header(f)->version_minor, ASF_VERSION_MINOR + 1);
        CHECK(memcmp(asf_section_data(f, 0), nodes, sizeof nodes) == 0);
    }
    asf_close(f);
    free(out);
    free(file);
}

static void reader_rejects_bad_magic(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    file[1] = 'X';
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "not an .asf file (bad magic at offset 0)");
    free(file);
}

static void reader_rejects_newer_major_version(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    header_of(file)->version_major = 2;
    expect_refused(file, size, &verify, AS_ERROR_VERSION,
                   "sample.asf: container version 2.1 is newer than this reader (1.x)");
    free(file);
}

static void reader_accepts_newer_minor_version(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    header_of(file)->version_minor = 9;
    asf_file_t *f = asf_open_memory(file, size, "sample.asf", &verify);
    CHECK(f != NULL);
    asf_close(f);
    free(file);
}

static void reader_rejects_file_shorter_than_header(void)
{
    const char *path = tmp_path("empty.asf");
    write_bytes(path, "", 0);
    char want[300];
    snprintf(want, sizeof want, "%s: file is 0 bytes, shorter than the 64-byte header", path);
    CHECK(asf_open(path, &verify) == NULL);
    CHECK_EQ_INT(as_get_error(), AS_ERROR_CORRUPT);
    CHECK_STR_CONTAINS(as_get_error_message(), want);
    remove(path);

    size_t size;
    uint8_t *file = sample_file(0, &size);
    expect_refused(file, 63, &verify, AS_ERROR_CORRUPT, "file is 63 bytes, shorter than the 64-byte header");
    free(file);
}

static void reader_rejects_truncated_file(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    const char *path = tmp_path("truncated.asf");
    write_bytes(path, file, size - 100);
    char want[300];
    snprintf(want, sizeof want, "%s: truncated: header says %zu bytes, file has %zu", path, size, size - 100);
    CHECK(asf_open(path, &verify) == NULL);
    CHECK_EQ_INT(as_get_error(), AS_ERROR_CORRUPT);
    CHECK_STR_CONTAINS(as_get_error_message(), want);
    remove(path);
    free(file);
}

static void reader_rejects_file_longer_than_file_size(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    uint8_t *longer = calloc(1, size + 64);
    memcpy(longer, file, size);
    char want[100];
    snprintf(want, sizeof want, "file_size at offset 32 says %zu bytes, file has %zu", size, size + 64);
    expect_refused(longer, size + 64, &verify, AS_ERROR_CORRUPT, want);
    free(longer);
    free(file);
}

static void reader_rejects_nonzero_reserved_fields(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    header_of(file)->reserved[3] = 1;
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "reserved header byte at offset 51 is 0x01");
    header_of(file)->reserved[3] = 0;
    entry_of(file, 2)->reserved1 = 7;
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "section TRI4 (index 2, offset");
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "reserved fields are not zero");
    free(file);
}

static void reader_rejects_bad_header_and_entry_sizes(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    header_of(file)->header_size = 32;
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "header_size 32 at offset 12");
    header_of(file)->header_size = 64;
    header_of(file)->section_entry_size = 1u << 31;
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "section_entry_size 2147483648 at offset 20");
    free(file);
}

static void reader_rejects_table_past_end(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    header_of(file)->section_table_offset = UINT64_MAX - 7;
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "section table (offset 18446744073709551608, "
                   "4 entries of 64 bytes) extends past the end of the file");
    header_of(file)->section_table_offset = 64;
    header_of(file)->section_count = 1000;
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "extends past the end of the file");
    free(file);
}

static void reader_rejects_too_many_sections(void)
{
    const uint32_t count = ASF_MAX_SECTIONS + 1;
    const size_t size = 64 + (size_t)count * 64;
    uint8_t *file = calloc(1, size);
    asf_header_t *h = header_of(file);
    memcpy(h->magic, ASF_MAGIC_BYTES, 8);
    h->version_major = 1;
    h->header_size = 64;
    h->section_entry_size = 64;
    h->section_count = count;
    h->section_table_offset = 64;
    h->file_size = size;
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "section_count 1025 at offset 16 is more than the 1024");
    free(file);
}

static void reader_rejects_table_checksum_mismatch(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    entry_of(file, 1)->stride = 32; /* consistent on its own, but the table changed */
    entry_of(file, 1)->element_count *= 2;
    char want[200];
    snprintf(want, sizeof want, "section table (offset 64, 256 bytes): checksum mismatch (stored 0x%016" PRIx64,
             header_of(file)->table_checksum);
    expect_refused(file, size, &verify, AS_ERROR_CHECKSUM, want);
    /* Not switched off with the section checksums: the table is the map of
     * every other check. */
    expect_refused(file, size, &no_verify, AS_ERROR_CHECKSUM, "section table");
    free(file);
}

static void reader_rejects_unknown_flag_bit(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    entry_of(file, 0)->flags |= 0x80;
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "section META (index 0, offset 320): unknown flag bits 0x80");
    free(file);
}

static void reader_rejects_misaligned_section(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    entry_of(file, 2)->offset += 8;
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "offset is not a multiple of 64");
    free(file);
}

static void reader_rejects_section_past_end(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    entry_of(file, 2)->stored_size += 64 * 100;
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "section TRI4 (index 2, offset");
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "stored bytes extend past the end of the file");
    free(file);
}

static void reader_rejects_offset_that_overflows(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    entry_of(file, 1)->offset = UINT64_MAX - 63; /* aligned, so the sum is what overflows */
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT,
                   "section BVH2 (index 1, offset 18446744073709551552): 6144 stored bytes extend past the end");
    free(file);
}

static void reader_rejects_overlapping_sections(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    entry_of(file, 2)->offset = entry_of(file, 1)->offset + 64;
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "overlaps section BVH2 (index 1");
    free(file);
}

static void reader_rejects_section_over_header_or_table(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    entry_of(file, 0)->offset = 128; /* inside the table */
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "overlaps the header or the section table");
    entry_of(file, 0)->offset = 0;
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "overlaps the header or the section table");
    free(file);
}

static void reader_rejects_inconsistent_sizes(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    entry_of(file, 1)->stride = 0;
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "stride is 0");
    entry_of(file, 1)->stride = 64;
    entry_of(file, 1)->element_count = UINT64_MAX / 2;
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "are not the raw size of 6144 bytes");
    entry_of(file, 1)->element_count = NODES - 1;
    entry_of(file, 1)->raw_size -= 64;
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "uncompressed, but stored size 6144 is not the raw size 6080");
    free(file);
}

static void reader_refuses_unknown_required_section(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    entry_of(file, 2)->tag = ASF_TAG('X', 'T', 'R', 'A');
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_UNSUPPORTED, "required section XTRA is unknown to this reader");
    free(file);
}

static void reader_skips_unknown_optional_section(void)
{
    size_t size;
    uint8_t *file = sample_file(0, &size);
    entry_of(file, 2)->tag = ASF_TAG('X', 'T', 'R', 'A');
    entry_of(file, 2)->flags = 0;
    entry_of(file, 2)->checksum ^= 1; /* not verified: skipped */
    fix_table(file);
    asf_file_t *f = asf_open_memory(file, size, "sample.asf", &verify);
    CHECK(f != NULL);
    if (f) {
        CHECK_EQ_U64(asf_section_count(f), 4);
        CHECK_EQ_INT(asf_find_section(f, ASF_TAG('X', 'T', 'R', 'A')), 2);
        CHECK(asf_section_data(f, 2) == NULL);
        CHECK_EQ_INT(asf_section_checksum_verified(f, 2), 0);
        CHECK_EQ_INT(asf_section_checksum_verified(f, 1), 1);
    }
    asf_close(f);
    free(file);
}

static void reader_rejects_section_checksum_mismatch_in_a_1_0_file(void)
{
    size_t size;
    uint8_t *file = sample_file_1_0(3, &size);
    asf_section_entry_t *tri = entry_of(file, 2);
    file[tri->offset + 5] ^= 0x10;
    char want[200];
    snprintf(want, sizeof want, "sample.asf: section TRI4 (index 2, offset %" PRIu64 "): checksum mismatch "
             "(stored 0x%016" PRIx64 ", computed 0x%016" PRIx64 ")", tri->offset, tri->checksum,
             as_hash64(file + tri->offset, sizeof tris));
    expect_refused(file, size, &verify, AS_ERROR_CHECKSUM, want);

    /* A compressed section's checksum is of its decompressed bytes. */
    file[tri->offset + 5] ^= 0x10;
    entry_of(file, 1)->checksum ^= 1;
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CHECKSUM, "section BVH2 (index 1, offset");
    free(file);
}

/* A 2.5 MiB section: chunks 0 and 1 full, chunk 2 half. */
enum { BIG_BYTES = 5 << 19 };
static uint8_t *big_file(size_t *size)
{
    static uint8_t big[BIG_BYTES];
    for (size_t i = 0; i < sizeof big; ++i) big[i] = (uint8_t)(i * 2654435761u >> 13);
    asf_section_desc_t desc[2];
    asf_section_desc_t tmp[3];
    make_sample(tmp, 0);
    desc[0] = tmp[0];
    desc[1] = (asf_section_desc_t){ASF_TAG_TRI4, ASF_SECTION_REQUIRED, big, sizeof big, sizeof big / 64, 64, 0};
    void *buf = NULL;
    if (asf_write_memory(desc, 2, &buf, size) != AS_OK) {
        fprintf(stderr, "asf_write_memory: %s\n", as_get_error_message());
        exit(1);
    }
    return buf;
}

/* After editing CSUM's bytes, so that its own checksum and the table pass. */
static void fix_csum(uint8_t *file, uint32_t index)
{
    asf_section_entry_t *c = entry_of(file, index);
    c->checksum = as_hash64(file + c->offset, (size_t)c->raw_size);
    fix_table(file);
}

static void reader_rejects_chunk_checksum_mismatch_naming_the_bytes(void)
{
    size_t size;
    uint8_t *file = big_file(&size);
    CHECK_EQ_U64(entry_of(file, 2)->raw_size, 16 + 8 * (1 + 3));
    asf_file_t *f = asf_open_memory(file, size, "sample.asf", &verify);
    CHECK(f != NULL);
    if (f)
        for (uint32_t i = 0; i < 3; ++i) CHECK_EQ_INT(asf_section_checksum_verified(f, i), 1);
    asf_close(f);

    const asf_section_entry_t *tri = entry_of(file, 1);
    file[tri->offset + (1u << 20) + 12345] ^= 4;
    char want[200];
    snprintf(want, sizeof want, "sample.asf: section TRI4 (index 1, offset %" PRIu64 "): checksum mismatch in "
             "bytes 1048576..2097152 of the section (chunk 1 in CSUM)", tri->offset);
    expect_refused(file, size, &verify, AS_ERROR_CHECKSUM, want);
    file[tri->offset + (1u << 20) + 12345] ^= 4;
    file[tri->offset + BIG_BYTES - 1] ^= 4;
    expect_refused(file, size, &verify, AS_ERROR_CHECKSUM, "bytes 2097152..2621440 of the section (chunk 2 in CSUM)");
    /* CSUM stands in for the sections' own checksums, but not for its own. */
    file[tri->offset + BIG_BYTES - 1] ^= 4;
    file[entry_of(file, 2)->offset + 20] ^= 1;
    expect_refused(file, size, &verify, AS_ERROR_CHECKSUM, "section CSUM (index 2, offset");
    free(file);
}

static void reader_rejects_chunk_hashes_exchanged(void)
{
    /* Two chunks and their hashes swapped together: each chunk still has its
     * own hash, but the seed says where it belongs. */
    size_t size;
    uint8_t *file = big_file(&size);
    const asf_section_entry_t *tri = entry_of(file, 1);
    uint8_t *a = file + tri->offset, *b = file + tri->offset + (1u << 20);
    for (size_t i = 0; i < (1u << 20); ++i) {
        const uint8_t t = a[i];
        a[i] = b[i];
        b[i] = t;
    }
    uint8_t *hashes = file + entry_of(file, 2)->offset + 16;
    uint64_t h1, h2;
    memcpy(&h1, hashes + 8, 8);
    memcpy(&h2, hashes + 16, 8);
    memcpy(hashes + 8, &h2, 8);
    memcpy(hashes + 16, &h1, 8);
    fix_csum(file, 2);
    expect_refused(file, size, &verify, AS_ERROR_CHECKSUM, "bytes 0..1048576 of the section (chunk 0 in CSUM)");
    free(file);
}

static void reader_rejects_malformed_csum(void)
{
    size_t size;
    uint8_t *file = big_file(&size);
    asf_section_entry_t *c = entry_of(file, 2);
    asf_csum_head_t *head = (asf_csum_head_t *)(file + c->offset);
    const asf_csum_head_t good = *head;

    head->chunk_log2 = 12;
    fix_csum(file, 2);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "chunk_log2 12 (byte 0 of the section) is not in 16..30");
    *head = good;
    head->covered_sections = 1;
    fix_csum(file, 2);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "covers 1 sections (byte 4 of the section), not the 2");
    *head = good;
    head->hash_count = 5;
    fix_csum(file, 2);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "hash_count 5 (byte 8 of the section)");
    /* 2 MiB chunks: the right count is 1 + 2, not the 4 hashes stored. */
    *head = good;
    head->chunk_log2 = 21;
    fix_csum(file, 2);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "do not match the 3 chunks of 2097152 bytes");
    *head = good;
    fix_csum(file, 2);
    /* Anywhere but last. */
    entry_of(file, 0)->tag = ASF_TAG_CSUM;
    entry_of(file, 0)->flags = 0;
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "section CSUM (index 0, offset 256): a CSUM section must "
                   "be the last of the table");
    free(file);
}

static void writer_refuses_a_csum_section_from_the_caller(void)
{
    const uint8_t bytes[16] = {20};
    const asf_section_desc_t desc = {ASF_TAG_CSUM, 0, bytes, 16, 16, 1, 0};
    void *buf = NULL;
    size_t size = 0;
    CHECK_EQ_INT(asf_write_memory(&desc, 1, &buf, &size), AS_ERROR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(as_get_error_message(), "section index 0 is a CSUM section: the writer adds it");
    CHECK(buf == NULL);
}

static void reader_skips_checksums_when_not_asked(void)
{
    size_t size;
    uint8_t *file = sample_file(3, &size);
    file[entry_of(file, 2)->offset + 5] ^= 0x10;
    asf_file_t *f = asf_open_memory(file, size, "sample.asf", &no_verify);
    CHECK(f != NULL);
    if (f)
        for (uint32_t i = 0; i < 3; ++i) CHECK_EQ_INT(asf_section_checksum_verified(f, i), 0);
    asf_close(f);
    free(file);
}

static void reader_rejects_damaged_zstd_frame(void)
{
    size_t size;
    uint8_t *file = sample_file(3, &size);
    asf_section_entry_t *bvh = entry_of(file, 1);
    CHECK(bvh->flags & ASF_SECTION_ZSTD);
    char prefix[100];
    snprintf(prefix, sizeof prefix, "section BVH2 (index 1, offset %" PRIu64 "): ", bvh->offset);

    uint8_t magic[4];
    memcpy(magic, file + bvh->offset, 4);
    memset(file + bvh->offset, 0, 4);
    expect_refused(file, size, &no_verify, AS_ERROR_CORRUPT, prefix);
    expect_refused(file, size, &no_verify, AS_ERROR_CORRUPT, "not a zstd frame");
    memcpy(file + bvh->offset, magic, 4);

    bvh->stored_size -= 1;
    fix_table(file);
    expect_refused(file, size, &no_verify, AS_ERROR_CORRUPT, prefix);
    expect_refused(file, size, &no_verify, AS_ERROR_CORRUPT, "the zstd frame is damaged");
    bvh->stored_size += 1;

    bvh->element_count -= 1;
    bvh->raw_size -= 64;
    fix_table(file);
    expect_refused(file, size, &no_verify, AS_ERROR_CORRUPT, "the zstd frame holds 6144 bytes, the raw size is 6080");
    free(file);
}

static void reader_refuses_zstd_section_claiming_impossible_ratio(void)
{
    size_t size;
    uint8_t *file = sample_file(3, &size);
    asf_section_entry_t *bvh = entry_of(file, 1);
    /* No zstd frame expands 65536 times: refused before any allocation. */
    bvh->raw_size = (bvh->stored_size + 1) * 65536;
    bvh->element_count = bvh->raw_size / 64;
    fix_table(file);
    expect_refused(file, size, &verify, AS_ERROR_CORRUPT, "is more than 65536 times the stored size");
    free(file);
}

static void reader_rejects_skippable_frame_as_section(void)
{
    /* A skippable frame (magic 0x184D2A50, 4-byte length, no content)
     * decompresses to nothing; it is still not the frame SPEC.md asks for. */
    static const uint8_t skippable[64] = {0x50, 0x2A, 0x4D, 0x18, 56};
    const asf_section_desc_t raw = {ASF_TAG_TRI4, ASF_SECTION_REQUIRED, skippable, 64, 1, 64, 0};
    void *buf = NULL;
    size_t size = 0;
    CHECK_EQ_INT(asf_write_memory(&raw, 1, &buf, &size), AS_OK);
    uint8_t *file = buf;
    entry_of(file, 0)->flags |= ASF_SECTION_ZSTD;
    entry_of(file, 0)->raw_size = 0;
    entry_of(file, 0)->element_count = 0;
    fix_table(file);
    expect_refused(file, size, &no_verify, AS_ERROR_CORRUPT, "section TRI4 (index 0, offset 192): not a zstd frame");
    free(file);
}

static void reader_reports_missing_file(void)
{
    const char *path = tmp_path("missing.asf");
    CHECK(asf_open(path, &verify) == NULL);
    CHECK_EQ_INT(as_get_error(), AS_ERROR_FILE_NOT_FOUND);
    CHECK_STR_STARTS(as_get_error_message(), path);
}

int main(void)
{
    if (!tmp_dir_make("as_test_container")) return 1;
    RUN_TEST(writer_lays_out_header_table_and_aligned_sections);
    RUN_TEST(round_trip_in_memory_uncompressed);
    RUN_TEST(round_trip_in_memory_compressed);
    RUN_TEST(round_trip_on_disk_matches_memory_writer);
    RUN_TEST(writer_replaces_an_existing_file);
    RUN_TEST(writer_reports_io_error_naming_the_path);
    RUN_TEST(writer_rejects_inconsistent_sections);
    RUN_TEST(empty_container_and_empty_section_round_trip);
    RUN_TEST(reader_copies_sections_of_a_misaligned_buffer_to_aligned_memory);
    RUN_TEST(reader_accepts_newer_minor_with_longer_header_and_entries);
    RUN_TEST(reader_rejects_bad_magic);
    RUN_TEST(reader_rejects_newer_major_version);
    RUN_TEST(reader_accepts_newer_minor_version);
    RUN_TEST(reader_rejects_file_shorter_than_header);
    RUN_TEST(reader_rejects_truncated_file);
    RUN_TEST(reader_rejects_file_longer_than_file_size);
    RUN_TEST(reader_rejects_nonzero_reserved_fields);
    RUN_TEST(reader_rejects_bad_header_and_entry_sizes);
    RUN_TEST(reader_rejects_table_past_end);
    RUN_TEST(reader_rejects_too_many_sections);
    RUN_TEST(reader_rejects_table_checksum_mismatch);
    RUN_TEST(reader_rejects_unknown_flag_bit);
    RUN_TEST(reader_rejects_misaligned_section);
    RUN_TEST(reader_rejects_section_past_end);
    RUN_TEST(reader_rejects_offset_that_overflows);
    RUN_TEST(reader_rejects_overlapping_sections);
    RUN_TEST(reader_rejects_section_over_header_or_table);
    RUN_TEST(reader_rejects_inconsistent_sizes);
    RUN_TEST(reader_refuses_unknown_required_section);
    RUN_TEST(reader_skips_unknown_optional_section);
    RUN_TEST(reader_rejects_section_checksum_mismatch_in_a_1_0_file);
    RUN_TEST(reader_rejects_chunk_checksum_mismatch_naming_the_bytes);
    RUN_TEST(reader_rejects_chunk_hashes_exchanged);
    RUN_TEST(reader_rejects_malformed_csum);
    RUN_TEST(writer_refuses_a_csum_section_from_the_caller);
    RUN_TEST(reader_skips_checksums_when_not_asked);
    RUN_TEST(reader_rejects_damaged_zstd_frame);
    RUN_TEST(reader_refuses_zstd_section_claiming_impossible_ratio);
    RUN_TEST(reader_rejects_skippable_frame_as_section);
    RUN_TEST(reader_reports_missing_file);
    remove_tmp_dir();
    TEST_EXIT();
}
