/* The .asf container (asf_container.h, formats/SPEC.md).
 *
 * The reader trusts nothing in the file: every field is checked against the
 * real size before it is used, all size arithmetic is overflow-checked, and
 * header and entries are copied out with memcpy, so that a caller buffer of
 * any alignment can be read. It runs under the fuzzers with ASan and UBSan. */
#define _POSIX_C_SOURCE 200809L
#include "asf_container.h"

#include "as_internal.h"
#include "atomic_file.h"
#include "task_pool.h"

#include <inttypes.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <zstd.h>

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the .asf structs are read in place: libas supports little-endian hosts only"
#endif

/* Limits this reader imposes (SPEC.md, "Limits"). A header or entry larger
 * than 4 KiB is not a plausible future minor version but a damaged file. */
#define ASF_MAX_HEADER_SIZE 4096u
#define ASF_MAX_ENTRY_SIZE 4096u
/* No zstd frame expands by more than 32768 (a 4-byte RLE block yields at
 * most 128 KiB); twice that leaves a margin. A larger claim is damage, and
 * refusing it keeps a 100-byte input from asking for terabytes. */
#define ASF_MAX_ZSTD_RATIO 65536u

_Static_assert(ASF_SECTION_ALIGNMENT == 64, "SPEC.md fixes the alignment at 64");

static const uint8_t asf_magic[8] = ASF_MAGIC_BYTES;

/* A tag as four printable characters, for messages. */
typedef struct tag_text {
    char s[5];
} tag_text_t;

static tag_text_t tag_text(uint32_t tag)
{
    tag_text_t t;
    for (int i = 0; i < 4; ++i) {
        const unsigned char c = (unsigned char)(tag >> (8 * i));
        t.s[i] = (c >= 0x20 && c < 0x7f) ? (char)c : '?';
    }
    t.s[4] = '\0';
    return t;
}

static uint64_t align_up_64(uint64_t x)
{
    return (x + (ASF_SECTION_ALIGNMENT - 1)) & ~(uint64_t)(ASF_SECTION_ALIGNMENT - 1);
}

static void *aligned_buffer(uint64_t bytes, const char *what);

/* ------------------------------------------------------------------------ */
/* Writer                                                                   */

/* What will be written: the header and table, and for each section the
 * bytes to store (the caller's or a compressed copy). Both asf_write and
 * asf_write_memory serialize the same plan, so their output is identical. */
typedef struct asf_plan {
    uint8_t *head;                 /* header + section table */
    size_t head_size;
    const void **stored;           /* per section: bytes to write */
    void **compressed;             /* per section: owned zstd frame or NULL */
    uint8_t *csum;                 /* the CSUM section written last */
    asf_section_entry_t *entries;  /* aligned view into head */
    uint32_t count;
    uint64_t file_size;
} asf_plan_t;

static void plan_free(asf_plan_t *p)
{
    if (p->compressed)
        for (uint32_t i = 0; i < p->count; ++i) free(p->compressed[i]);
    free(p->compressed);
    free(p->csum);
    free(p->stored);
    free(p->head);
    memset(p, 0, sizeof *p);
}

static as_error_t check_desc(const asf_section_desc_t *d, uint32_t i)
{
    const tag_text_t t = tag_text(d->tag);
    uint64_t bytes;
    if (d->flags & ~ASF_SECTION_KNOWN_FLAGS)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "asf_write: section %s (index %" PRIu32
                            "): unknown flags 0x%" PRIx32, t.s, i, d->flags);
    if (d->stride == 0)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "asf_write: section %s (index %" PRIu32
                            "): stride is 0", t.s, i);
    if (!as_mul_u64(d->element_count, d->stride, &bytes) || bytes != d->size)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "asf_write: section %s (index %" PRIu32
                            "): %" PRIu64 " elements of %" PRIu32 " bytes is not %" PRIu64 " bytes",
                            t.s, i, d->element_count, d->stride, d->size);
    if (d->size > 0 && !d->data)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "asf_write: section %s (index %" PRIu32
                            "): no data", t.s, i);
    if (d->size > SIZE_MAX)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "asf_write: section %s (index %" PRIu32
                            "): %" PRIu64 " bytes do not fit in memory", t.s, i, d->size);
    if (d->compression_level < 0 || d->compression_level > ZSTD_maxCLevel())
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "asf_write: section %s (index %" PRIu32
                            "): compression level %d is not in 0..%d", t.s, i,
                            d->compression_level, ZSTD_maxCLevel());
    return AS_OK;
}

/* ------------------------------------------------------------------------ */
/* Chunk checksums (CSUM)                                                   */

/* One XXH3-64 per fixed-size chunk, seeded with the section's index and the
 * chunk's, so that chunks moved within or between sections do not verify.
 * The chunks are fixed by the file, not by the thread count, so any number
 * of threads computes the same hashes. */
typedef struct chunk_job {
    const uint8_t *const *data;    /* per covered section */
    const uint64_t *size;
    const uint64_t *first;         /* per covered section: index of its first hash */
    uint32_t sections;
    uint32_t chunk_log2;
    uint64_t hash_count;
    const uint64_t *expect;        /* reader: stored hashes; NULL when writing */
    uint64_t *out;                 /* writer: computed hashes */
    _Atomic uint64_t next;
    _Atomic uint64_t first_bad;    /* reader: smallest mismatching hash index */
} chunk_job_t;

static uint64_t chunks_of(uint64_t bytes, uint32_t log2)
{
    return (bytes >> log2) + ((bytes & (((uint64_t)1 << log2) - 1)) != 0);
}

static void hash_chunks(void *user, unsigned thread, unsigned threads)
{
    (void)thread;
    (void)threads;
    chunk_job_t *j = user;
    /* Batches of 8 chunks keep the shared counter cold. */
    for (;;) {
        const uint64_t begin = atomic_fetch_add(&j->next, 8);
        if (begin >= j->hash_count) break;
        const uint64_t end = begin + 8 < j->hash_count ? begin + 8 : j->hash_count;
        uint32_t sct = 0;
        while (sct + 1 < j->sections && j->first[sct + 1] <= begin) ++sct;
        for (uint64_t k = begin; k < end; ++k) {
            while (k >= j->first[sct] + chunks_of(j->size[sct], j->chunk_log2)) ++sct;
            const uint64_t c = k - j->first[sct];
            const uint64_t at = c << j->chunk_log2;
            const uint64_t left = j->size[sct] - at;
            const size_t n = (size_t)(left < ((uint64_t)1 << j->chunk_log2) ? left : ((uint64_t)1 << j->chunk_log2));
            if (!j->data[sct]) continue; /* a section the reader skipped */
            const uint64_t h = as_hash64_seeded(j->data[sct] + at, n, ((uint64_t)sct << 32) | c);
            if (j->out) j->out[k] = h;
            if (j->expect && h != j->expect[k]) {
                uint64_t seen = atomic_load(&j->first_bad);
                while (k < seen && !atomic_compare_exchange_weak(&j->first_bad, &seen, k)) {
                }
            }
        }
    }
}

/* Runs the job on every core, fewer when there are few chunks. */
static void run_chunk_job(chunk_job_t *j)
{
    atomic_init(&j->next, 0);
    atomic_init(&j->first_bad, UINT64_MAX);
    const unsigned cores = as_thread_count(0);
    const uint64_t batches = (j->hash_count + 7) / 8;
    const unsigned threads = batches < cores ? (unsigned)(batches ? batches : 1) : cores;
    if (threads <= 1)
        hash_chunks(j, 0, 1);
    else
        as_parallel_run(threads, hash_chunks, j);
}

/* The CSUM section of the sections described: its head and hashes. */
static as_error_t csum_build(const asf_section_desc_t *sections, uint32_t count, uint8_t **out, uint64_t *out_size)
{
    const uint32_t log2 = ASF_CSUM_CHUNK_LOG2;
    const uint8_t **data = as_calloc(count ? count : 1, sizeof *data, "the CSUM plan");
    uint64_t *size = as_calloc(count ? count : 1, sizeof *size, "the CSUM plan");
    uint64_t *first = as_calloc(count ? count : 1, sizeof *first, "the CSUM plan");
    if (!data || !size || !first) {
        free(data);
        free(size);
        free(first);
        return AS_ERROR_OUT_OF_MEMORY;
    }
    uint64_t total = 0;
    for (uint32_t i = 0; i < count; ++i) {
        data[i] = sections[i].data;
        size[i] = sections[i].size;
        first[i] = total;
        total += chunks_of(size[i], log2);
    }
    const uint64_t bytes = sizeof(asf_csum_head_t) + total * 8;
    uint8_t *buf = as_malloc((size_t)bytes, "the CSUM section");
    if (!buf) {
        free(data);
        free(size);
        free(first);
        return AS_ERROR_OUT_OF_MEMORY;
    }
    const asf_csum_head_t head = {log2, count, total};
    memcpy(buf, &head, sizeof head);
    chunk_job_t job = {data, size, first, count, log2, total, NULL, (uint64_t *)(buf + sizeof head), 0, 0};
    run_chunk_job(&job);
    free(data);
    free(size);
    free(first);
    *out = buf;
    *out_size = bytes;
    return AS_OK;
}

static as_error_t plan_build(const asf_section_desc_t *sections, uint32_t count, asf_plan_t *p)
{
    memset(p, 0, sizeof *p);
    /* One place is kept for the CSUM section every file ends with. */
    if (count > ASF_MAX_SECTIONS - 1)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "asf_write: %" PRIu32
                            " sections, more than the %d a file can hold beside its CSUM", count,
                            ASF_MAX_SECTIONS - 1);
    if (count > 0 && !sections)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "asf_write: no section descriptions");
    for (uint32_t i = 0; i < count; ++i) {
        const as_error_t err = check_desc(&sections[i], i);
        if (err != AS_OK) return err;
        if (sections[i].tag == ASF_TAG_CSUM)
            return as_set_error(AS_ERROR_INVALID_ARGUMENT, "asf_write: section index %" PRIu32
                                " is a CSUM section: the writer adds it", i);
    }

    p->count = count + 1;
    p->head_size = sizeof(asf_header_t) + (size_t)p->count * sizeof(asf_section_entry_t);
    /* calloc: padding and reserved fields must be zero. The table follows
     * the 64-byte header, so the entries are 8-byte aligned in place. */
    p->head = as_calloc(1, p->head_size, "the .asf header");
    p->stored = as_calloc(p->count, sizeof *p->stored, "the .asf section list");
    p->compressed = as_calloc(p->count, sizeof *p->compressed, "the .asf section list");
    if (!p->head || !p->stored || !p->compressed) {
        plan_free(p);
        return AS_ERROR_OUT_OF_MEMORY;
    }
    p->entries = (asf_section_entry_t *)(p->head + sizeof(asf_header_t));

    ZSTD_CCtx *cctx = NULL;
    uint64_t cursor = p->head_size; /* a multiple of 64: header and entries are */
    for (uint32_t i = 0; i < count; ++i) {
        const asf_section_desc_t *d = &sections[i];
        asf_section_entry_t *e = &p->entries[i];
        e->tag = d->tag;
        e->flags = d->flags & ASF_SECTION_REQUIRED;
        e->raw_size = d->size;
        e->stored_size = d->size;
        e->element_count = d->element_count;
        e->stride = d->stride;
        e->checksum = as_hash64(d->size ? d->data : (const void *)"", (size_t)d->size);
        p->stored[i] = d->data;

        if (d->compression_level > 0 && d->size > 0) {
            if (!cctx && !(cctx = ZSTD_createCCtx())) {
                plan_free(p);
                return as_set_error(AS_ERROR_OUT_OF_MEMORY, "asf_write: cannot create a zstd context");
            }
            const size_t bound = ZSTD_compressBound((size_t)d->size);
            void *buf = as_malloc(bound, "a compressed .asf section");
            if (!buf) {
                ZSTD_freeCCtx(cctx);
                plan_free(p);
                return AS_ERROR_OUT_OF_MEMORY;
            }
            /* One-shot compression records the content size in the frame
             * header, which the reader requires. */
            const size_t n = ZSTD_compressCCtx(cctx, buf, bound, d->data, (size_t)d->size,
                                               d->compression_level);
            if (ZSTD_isError(n)) {
                const tag_text_t t = tag_text(d->tag);
                free(buf);
                ZSTD_freeCCtx(cctx);
                plan_free(p);
                return as_set_error(AS_ERROR_UNKNOWN, "asf_write: section %s (index %" PRIu32
                                    "): zstd: %s", t.s, i, ZSTD_getErrorName(n));
            }
            if (n < d->size) {
                p->compressed[i] = buf;
                p->stored[i] = buf;
                e->stored_size = n;
                e->flags |= ASF_SECTION_ZSTD;
            } else {
                free(buf); /* incompressible: storing it raw is smaller and mappable */
            }
        }
        e->offset = cursor;
        cursor = align_up_64(cursor + e->stored_size);
    }
    ZSTD_freeCCtx(cctx);

    uint64_t csum_bytes = 0;
    const as_error_t cerr = csum_build(sections, count, &p->csum, &csum_bytes);
    if (cerr != AS_OK) {
        plan_free(p);
        return cerr;
    }
    asf_section_entry_t *ce = &p->entries[count];
    ce->tag = ASF_TAG_CSUM;
    ce->raw_size = ce->stored_size = csum_bytes;
    ce->element_count = csum_bytes;
    ce->stride = 1;
    ce->checksum = as_hash64(p->csum, (size_t)csum_bytes);
    ce->offset = cursor;
    p->stored[count] = p->csum;
    cursor = align_up_64(cursor + csum_bytes);
    /* The file ends padded to 64 too, so that every offset, even that of an
     * empty last section, lies within the file. */
    p->file_size = cursor;

    asf_header_t h;
    memset(&h, 0, sizeof h);
    memcpy(h.magic, asf_magic, sizeof h.magic);
    h.version_major = ASF_VERSION_MAJOR;
    h.version_minor = ASF_VERSION_MINOR;
    h.header_size = sizeof(asf_header_t);
    h.section_count = p->count;
    h.section_entry_size = sizeof(asf_section_entry_t);
    h.section_table_offset = sizeof(asf_header_t);
    h.file_size = p->file_size;
    h.table_checksum = as_hash64(p->entries, (size_t)p->count * sizeof(asf_section_entry_t));
    memcpy(p->head, &h, sizeof h);
    return AS_OK;
}

static const uint8_t zero_padding[ASF_SECTION_ALIGNMENT];

as_error_t asf_write_memory(const asf_section_desc_t *sections, uint32_t count,
                            void **out, size_t *out_size)
{
    if (!out || !out_size)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "asf_write_memory: no output pointer");
    *out = NULL;
    *out_size = 0;
    asf_plan_t p;
    const as_error_t err = plan_build(sections, count, &p);
    if (err != AS_OK) return err;
    if (p.file_size > SIZE_MAX) {
        plan_free(&p);
        return as_set_error(AS_ERROR_OUT_OF_MEMORY, "asf_write_memory: %" PRIu64
                            " bytes do not fit in memory", p.file_size);
    }
    /* 64-aligned like a mapping, so that a reader uses its raw sections in
     * place; the file size is a multiple of 64 already. */
    uint8_t *buf = aligned_buffer(p.file_size, "an .asf file in memory");
    if (!buf) {
        plan_free(&p);
        return AS_ERROR_OUT_OF_MEMORY;
    }
    memset(buf, 0, (size_t)p.file_size);
    memcpy(buf, p.head, p.head_size);
    for (uint32_t i = 0; i < p.count; ++i)
        if (p.entries[i].stored_size)
            memcpy(buf + p.entries[i].offset, p.stored[i], (size_t)p.entries[i].stored_size);
    *out = buf;
    *out_size = (size_t)p.file_size;
    plan_free(&p);
    return AS_OK;
}

as_error_t asf_write(const char *path, const asf_section_desc_t *sections, uint32_t count)
{
    if (!path || !*path) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "asf_write: empty path");
    asf_plan_t p;
    as_error_t err = plan_build(sections, count, &p);
    if (err != AS_OK) return err;

    /* Gathered, so that raw sections go from the caller's arrays straight to
     * the file: the header and table, then padding and data per section. */
    as_file_part_t *parts = as_calloc(2 + 2 * (size_t)p.count, sizeof *parts, "the .asf write list");
    if (!parts) {
        plan_free(&p);
        return AS_ERROR_OUT_OF_MEMORY;
    }
    size_t n = 0;
    uint64_t at = p.head_size;
    parts[n++] = (as_file_part_t){p.head, p.head_size};
    for (uint32_t i = 0; i < p.count; ++i) {
        const asf_section_entry_t *e = &p.entries[i];
        if (e->offset > at) parts[n++] = (as_file_part_t){zero_padding, (size_t)(e->offset - at)};
        parts[n++] = (as_file_part_t){p.stored[i], (size_t)e->stored_size};
        at = e->offset + e->stored_size;
    }
    if (p.file_size > at) parts[n++] = (as_file_part_t){zero_padding, (size_t)(p.file_size - at)};
    err = as_atomic_write(path, parts, n);
    free(parts);
    plan_free(&p);
    return err;
}

/* ------------------------------------------------------------------------ */
/* Reader                                                                   */

struct asf_file {
    char *name;
    const uint8_t *data;
    size_t size;
    as_file_map_t map;             /* when opened from a path */
    asf_header_t header;           /* copies: aligned whatever the input */
    asf_section_entry_t *entries;
    const void **section_data;
    void **owned;                  /* decompressed or realigned copies */
    uint8_t *verified;
};

/* Stands in for the data of empty sections: a valid, aligned pointer. */
static _Alignas(ASF_SECTION_ALIGNMENT) const uint8_t empty_section[ASF_SECTION_ALIGNMENT];

static int tag_known(const asf_open_args_t *args, uint32_t tag)
{
    for (uint32_t i = 0; i < args->known_tag_count; ++i)
        if (args->known_tags[i] == tag) return 1;
    return 0;
}

/* Every message about a section starts the same way. */
#define SECTION_FMT "%s: section %s (index %" PRIu32 ", offset %" PRIu64 "): "
#define SECTION_ARGS(f, e, i) (f)->name, tag_text((e)->tag).s, (i), (e)->offset

static as_error_t check_header(asf_file_t *f)
{
    const char *name = f->name;
    const uint64_t size = f->size;
    if (size < sizeof(asf_header_t))
        return as_set_error(AS_ERROR_CORRUPT, "%s: file is %" PRIu64
                            " bytes, shorter than the 64-byte header", name, size);
    asf_header_t *h = &f->header;
    memcpy(h, f->data, sizeof *h);

    if (memcmp(h->magic, asf_magic, sizeof h->magic) != 0)
        return as_set_error(AS_ERROR_CORRUPT, "%s: not an .asf file (bad magic at offset 0)", name);
    if (h->version_major > ASF_VERSION_MAJOR)
        return as_set_error(AS_ERROR_VERSION, "%s: container version %u.%u is newer than this reader (%d.x)",
                            name, h->version_major, h->version_minor, ASF_VERSION_MAJOR);
    if (h->version_major == 0)
        return as_set_error(AS_ERROR_CORRUPT, "%s: container version 0.%u at offset 8 was never defined",
                            name, h->version_minor);
    if (h->header_size < sizeof(asf_header_t) || h->header_size > ASF_MAX_HEADER_SIZE ||
        h->header_size % 8 != 0)
        return as_set_error(AS_ERROR_CORRUPT, "%s: header_size %" PRIu32 " at offset 12 is not a "
                            "multiple of 8 from 64 to %u", name, h->header_size, ASF_MAX_HEADER_SIZE);
    if (h->section_entry_size < sizeof(asf_section_entry_t) ||
        h->section_entry_size > ASF_MAX_ENTRY_SIZE || h->section_entry_size % 8 != 0)
        return as_set_error(AS_ERROR_CORRUPT, "%s: section_entry_size %" PRIu32 " at offset 20 is not a "
                            "multiple of 8 from 64 to %u", name, h->section_entry_size, ASF_MAX_ENTRY_SIZE);
    for (size_t i = 0; i < sizeof h->reserved; ++i)
        if (h->reserved[i] != 0)
            return as_set_error(AS_ERROR_CORRUPT, "%s: reserved header byte at offset %zu is 0x%02x, "
                                "not zero", name, offsetof(asf_header_t, reserved) + i, h->reserved[i]);
    if (h->file_size > size)
        return as_set_error(AS_ERROR_CORRUPT, "%s: truncated: header says %" PRIu64
                            " bytes, file has %" PRIu64, name, h->file_size, size);
    if (h->file_size < size)
        return as_set_error(AS_ERROR_CORRUPT, "%s: file_size at offset 32 says %" PRIu64
                            " bytes, file has %" PRIu64, name, h->file_size, size);
    if (h->header_size > size)
        return as_set_error(AS_ERROR_CORRUPT, "%s: header_size %" PRIu32 " is larger than the file (%"
                            PRIu64 " bytes)", name, h->header_size, size);

    uint64_t table_bytes, table_end;
    as_mul_u64(h->section_count, h->section_entry_size, &table_bytes); /* < 2^44: no overflow */
    if (h->section_table_offset % 8 != 0 || h->section_table_offset < h->header_size)
        return as_set_error(AS_ERROR_CORRUPT, "%s: section_table_offset %" PRIu64 " at offset 24 is "
                            "not a multiple of 8 after the %" PRIu32 "-byte header",
                            name, h->section_table_offset, h->header_size);
    if (!as_add_u64(h->section_table_offset, table_bytes, &table_end) || table_end > size)
        return as_set_error(AS_ERROR_CORRUPT, "%s: section table (offset %" PRIu64 ", %" PRIu32
                            " entries of %" PRIu32 " bytes) extends past the end of the file (%" PRIu64
                            " bytes)", name, h->section_table_offset, h->section_count,
                            h->section_entry_size, size);
    if (h->section_count > ASF_MAX_SECTIONS)
        return as_set_error(AS_ERROR_CORRUPT, "%s: section_count %" PRIu32 " at offset 16 is more than "
                            "the %d this reader accepts", name, h->section_count, ASF_MAX_SECTIONS);
    const uint64_t computed = as_hash64(f->data + h->section_table_offset, (size_t)table_bytes);
    if (computed != h->table_checksum)
        return as_set_error(AS_ERROR_CHECKSUM, "%s: section table (offset %" PRIu64 ", %" PRIu64
                            " bytes): checksum mismatch (stored 0x%016" PRIx64 ", computed 0x%016"
                            PRIx64 ")", name, h->section_table_offset, table_bytes,
                            h->table_checksum, computed);
    return AS_OK;
}

static as_error_t check_entry(const asf_file_t *f, uint32_t i)
{
    const asf_header_t *h = &f->header;
    const asf_section_entry_t *e = &f->entries[i];
    const uint64_t at = h->section_table_offset + (uint64_t)i * h->section_entry_size;
    uint64_t end, bytes;

    if (e->flags & ~ASF_SECTION_KNOWN_FLAGS)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "unknown flag bits 0x%" PRIx32
                            " (entry at offset %" PRIu64 ")", SECTION_ARGS(f, e, i),
                            e->flags & ~ASF_SECTION_KNOWN_FLAGS, at);
    if (e->offset % ASF_SECTION_ALIGNMENT != 0)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "offset is not a multiple of %d "
                            "(entry at offset %" PRIu64 ")", SECTION_ARGS(f, e, i),
                            ASF_SECTION_ALIGNMENT, at);
    if (!as_add_u64(e->offset, e->stored_size, &end) || end > f->size)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "%" PRIu64 " stored bytes extend past the "
                            "end of the file (%zu bytes)", SECTION_ARGS(f, e, i), e->stored_size, f->size);
    if (e->stride == 0)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "stride is 0 (entry at offset %" PRIu64 ")",
                            SECTION_ARGS(f, e, i), at);
    if (!as_mul_u64(e->element_count, e->stride, &bytes) || bytes != e->raw_size)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "%" PRIu64 " elements of %" PRIu32
                            " bytes are not the raw size of %" PRIu64 " bytes", SECTION_ARGS(f, e, i),
                            e->element_count, e->stride, e->raw_size);
    if (!(e->flags & ASF_SECTION_ZSTD) && e->stored_size != e->raw_size)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "uncompressed, but stored size %" PRIu64
                            " is not the raw size %" PRIu64, SECTION_ARGS(f, e, i),
                            e->stored_size, e->raw_size);
    if ((e->flags & ASF_SECTION_ZSTD) && e->raw_size / ASF_MAX_ZSTD_RATIO > e->stored_size)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "raw size %" PRIu64 " is more than %u times "
                            "the stored size %" PRIu64, SECTION_ARGS(f, e, i), e->raw_size,
                            ASF_MAX_ZSTD_RATIO, e->stored_size);
    if (e->raw_size > SIZE_MAX - ASF_SECTION_ALIGNMENT)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "raw size %" PRIu64 " does not fit in memory",
                            SECTION_ARGS(f, e, i), e->raw_size);
    /* Empty sections occupy no bytes and so overlap nothing. */
    if (e->stored_size > 0) {
        const uint64_t table_end = h->section_table_offset + (uint64_t)h->section_count * h->section_entry_size;
        if (e->offset < h->header_size || (e->offset < table_end && end > h->section_table_offset))
            return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "overlaps the header or the section table",
                                SECTION_ARGS(f, e, i));
    }
    if (e->reserved0 != 0 || e->reserved1 != 0)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "reserved fields are not zero (entry at "
                            "offset %" PRIu64 ")", SECTION_ARGS(f, e, i), at);
    return AS_OK;
}

typedef struct span {
    uint64_t begin, end;
    uint32_t index;
} span_t;

static int span_order(const void *a, const void *b)
{
    const span_t *x = a, *y = b;
    if (x->begin != y->begin) return x->begin < y->begin ? -1 : 1;
    return x->index < y->index ? -1 : (x->index > y->index);
}

static as_error_t check_overlap(const asf_file_t *f)
{
    const uint32_t count = f->header.section_count;
    span_t *spans = as_calloc(count ? count : 1, sizeof *spans, "the .asf overlap check");
    if (!spans) return AS_ERROR_OUT_OF_MEMORY;
    uint32_t n = 0;
    for (uint32_t i = 0; i < count; ++i) {
        const asf_section_entry_t *e = &f->entries[i];
        if (e->stored_size > 0) spans[n++] = (span_t){e->offset, e->offset + e->stored_size, i};
    }
    qsort(spans, n, sizeof *spans, span_order);
    as_error_t err = AS_OK;
    for (uint32_t k = 1; k < n && err == AS_OK; ++k) {
        if (spans[k].begin < spans[k - 1].end) {
            const asf_section_entry_t *e = &f->entries[spans[k].index];
            const asf_section_entry_t *o = &f->entries[spans[k - 1].index];
            err = as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "overlaps section %s (index %" PRIu32
                               ", offset %" PRIu64 ", %" PRIu64 " bytes)", SECTION_ARGS(f, e, spans[k].index),
                               tag_text(o->tag).s, spans[k - 1].index, o->offset, o->stored_size);
        }
    }
    free(spans);
    return err;
}

static void *aligned_buffer(uint64_t bytes, const char *what)
{
    /* C11 wants the size to be a multiple of the alignment (ASan checks). */
    const size_t rounded = (size_t)align_up_64(bytes);
    void *p = aligned_alloc(ASF_SECTION_ALIGNMENT, rounded);
    if (!p) as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory allocating %zu bytes for %s", rounded, what);
    return p;
}

static as_error_t load_zstd(asf_file_t *f, uint32_t i, ZSTD_DCtx **dctx)
{
    const asf_section_entry_t *e = &f->entries[i];
    const uint8_t *src = f->data + e->offset;
    const size_t stored = (size_t)e->stored_size;

    /* A skippable frame would pass the checks below as an empty section. */
    uint32_t magic = 0;
    if (stored >= sizeof magic) memcpy(&magic, src, sizeof magic);
    if (magic != ZSTD_MAGICNUMBER)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "not a zstd frame", SECTION_ARGS(f, e, i));
    const unsigned long long content = ZSTD_getFrameContentSize(src, stored);
    if (content == ZSTD_CONTENTSIZE_ERROR)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "not a zstd frame", SECTION_ARGS(f, e, i));
    if (content == ZSTD_CONTENTSIZE_UNKNOWN)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "the zstd frame does not record its content size",
                            SECTION_ARGS(f, e, i));
    if (content != e->raw_size)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "the zstd frame holds %llu bytes, the raw size "
                            "is %" PRIu64, SECTION_ARGS(f, e, i), content, e->raw_size);
    /* Walks the block headers without decompressing: damaged frames are
     * refused before the output is allocated. */
    const size_t frame = ZSTD_findFrameCompressedSize(src, stored);
    if (ZSTD_isError(frame))
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "the zstd frame is damaged (%s)",
                            SECTION_ARGS(f, e, i), ZSTD_getErrorName(frame));
    if (frame != stored)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "%zu bytes follow the zstd frame of %zu bytes",
                            SECTION_ARGS(f, e, i), stored - frame, frame);

    if (!*dctx && !(*dctx = ZSTD_createDCtx()))
        return as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: cannot create a zstd context", f->name);
    uint8_t none[1];
    uint8_t *dst = none;
    if (e->raw_size > 0) {
        dst = aligned_buffer(e->raw_size, "a decompressed .asf section");
        if (!dst) return AS_ERROR_OUT_OF_MEMORY;
    }
    const size_t n = ZSTD_decompressDCtx(*dctx, dst, (size_t)e->raw_size, src, stored);
    if (ZSTD_isError(n) || n != e->raw_size) {
        if (dst != none) free(dst);
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "the zstd frame is damaged (%s)",
                            SECTION_ARGS(f, e, i),
                            ZSTD_isError(n) ? ZSTD_getErrorName(n) : "short output");
    }
    if (dst == none) {
        f->section_data[i] = empty_section;
    } else {
        f->owned[i] = dst;
        f->section_data[i] = dst;
    }
    return AS_OK;
}

/* Verifies every covered section chunk by chunk on every core, against the
 * CSUM section at index `ci` (the last), whose own checksum is verified first. */
static as_error_t csum_verify(asf_file_t *f, uint32_t ci)
{
    const asf_section_entry_t *ce = &f->entries[ci];
    const uint8_t *cs = f->section_data[ci];
    const uint64_t own = as_hash64(cs, (size_t)ce->raw_size);
    if (own != ce->checksum)
        return as_set_error(AS_ERROR_CHECKSUM, SECTION_FMT "checksum mismatch (stored 0x%016" PRIx64
                            ", computed 0x%016" PRIx64 ")", SECTION_ARGS(f, ce, ci), ce->checksum, own);
    asf_csum_head_t head;
    if (ce->raw_size < sizeof head)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "%" PRIu64 " bytes, shorter than its 16-byte head",
                            SECTION_ARGS(f, ce, ci), ce->raw_size);
    memcpy(&head, cs, sizeof head);
    if (head.chunk_log2 < ASF_CSUM_MIN_CHUNK_LOG2 || head.chunk_log2 > ASF_CSUM_MAX_CHUNK_LOG2)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "chunk_log2 %" PRIu32 " (byte 0 of the section) is not "
                            "in %u..%u", SECTION_ARGS(f, ce, ci), head.chunk_log2, ASF_CSUM_MIN_CHUNK_LOG2,
                            ASF_CSUM_MAX_CHUNK_LOG2);
    if (head.covered_sections != ci)
        return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "covers %" PRIu32 " sections (byte 4 of the section), "
                            "not the %" PRIu32 " before it", SECTION_ARGS(f, ce, ci), head.covered_sections, ci);
    uint64_t *size = as_calloc(ci ? ci : 1, sizeof *size, "the CSUM check");
    uint64_t *first = as_calloc(ci ? ci : 1, sizeof *first, "the CSUM check");
    const uint8_t **data = as_calloc(ci ? ci : 1, sizeof *data, "the CSUM check");
    as_error_t err = AS_OK;
    if (!size || !first || !data) {
        err = AS_ERROR_OUT_OF_MEMORY;
        goto done;
    }
    uint64_t total = 0;
    for (uint32_t i = 0; i < ci; ++i) {
        size[i] = f->entries[i].raw_size;
        first[i] = total;
        data[i] = f->section_data[i]; /* NULL for a skipped section: not checked */
        total += chunks_of(size[i], head.chunk_log2);
    }
    if (head.hash_count != total || (ce->raw_size - sizeof head) / 8 != total || (ce->raw_size - sizeof head) % 8) {
        err = as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "hash_count %" PRIu64 " (byte 8 of the section) and size %"
                           PRIu64 " do not match the %" PRIu64 " chunks of %" PRIu64 " bytes in the sections before it",
                           SECTION_ARGS(f, ce, ci), head.hash_count, ce->raw_size, total,
                           (uint64_t)1 << head.chunk_log2);
        goto done;
    }
    chunk_job_t job = {data, size, first, ci, head.chunk_log2, total, (const uint64_t *)(cs + sizeof head), NULL, 0, 0};
    run_chunk_job(&job);
    const uint64_t bad = atomic_load(&job.first_bad);
    if (bad != UINT64_MAX) {
        uint32_t i = 0;
        while (i + 1 < ci && first[i + 1] <= bad) ++i;
        const uint64_t c = bad - first[i];
        const uint64_t at = c << head.chunk_log2;
        const uint64_t end = at + ((uint64_t)1 << head.chunk_log2) < size[i] ? at + ((uint64_t)1 << head.chunk_log2)
                                                                            : size[i];
        const asf_section_entry_t *e = &f->entries[i];
        err = as_set_error(AS_ERROR_CHECKSUM, SECTION_FMT "checksum mismatch in bytes %" PRIu64 "..%" PRIu64
                           " of the section (chunk %" PRIu64 " in CSUM)", SECTION_ARGS(f, e, i), at, end, c);
        goto done;
    }
    for (uint32_t i = 0; i < ci; ++i) f->verified[i] = data[i] != NULL;
    f->verified[ci] = 1;
done:
    free(size);
    free(first);
    free(data);
    return err;
}

static as_error_t load_sections(asf_file_t *f, const asf_open_args_t *args)
{
    const uint32_t count = f->header.section_count;
    /* A CSUM section, always the last, replaces the sequential pass over each
     * section by a parallel one over its chunks. */
    for (uint32_t i = 0; i + 1 < count; ++i)
        if (f->entries[i].tag == ASF_TAG_CSUM)
            return as_set_error(AS_ERROR_CORRUPT, SECTION_FMT "a CSUM section must be the last of the table",
                                SECTION_ARGS(f, &f->entries[i], i));
    const int has_csum = count > 0 && f->entries[count - 1].tag == ASF_TAG_CSUM;
    ZSTD_DCtx *dctx = NULL;
    as_error_t err = AS_OK;
    for (uint32_t i = 0; i < count && err == AS_OK; ++i) {
        const asf_section_entry_t *e = &f->entries[i];
        /* Unknown optional sections are skipped: not decompressed, not
         * verified, no data; their entry stays visible. */
        if (!tag_known(args, e->tag) && e->tag != ASF_TAG_CSUM) continue;
        if (e->flags & ASF_SECTION_ZSTD) {
            err = load_zstd(f, i, &dctx);
            if (err != AS_OK) break;
        } else if (e->raw_size == 0) {
            f->section_data[i] = empty_section;
        } else if ((uintptr_t)(f->data + e->offset) % ASF_SECTION_ALIGNMENT == 0) {
            f->section_data[i] = f->data + e->offset; /* in place: no copy */
        } else {
            /* Only a caller buffer can be misaligned; a mapping starts on a page. */
            void *copy = aligned_buffer(e->raw_size, "an aligned .asf section");
            if (!copy) {
                err = AS_ERROR_OUT_OF_MEMORY;
                break;
            }
            memcpy(copy, f->data + e->offset, (size_t)e->raw_size);
            f->owned[i] = copy;
            f->section_data[i] = copy;
        }
        if (args->verify_checksums && !has_csum) {
            const uint64_t computed = as_hash64(f->section_data[i], (size_t)e->raw_size);
            if (computed != e->checksum) {
                err = as_set_error(AS_ERROR_CHECKSUM, SECTION_FMT "checksum mismatch (stored 0x%016" PRIx64
                                   ", computed 0x%016" PRIx64 ")", SECTION_ARGS(f, e, i),
                                   e->checksum, computed);
                break;
            }
            f->verified[i] = 1;
        }
    }
    ZSTD_freeDCtx(dctx);
    if (err == AS_OK && args->verify_checksums && has_csum) err = csum_verify(f, count - 1);
    return err;
}

static as_error_t check_and_load(asf_file_t *f, const asf_open_args_t *args)
{
    as_error_t err = check_header(f);
    if (err != AS_OK) return err;

    const asf_header_t *h = &f->header;
    const uint32_t count = h->section_count;
    const size_t n = count ? count : 1;
    f->entries = as_calloc(n, sizeof *f->entries, "the .asf section table");
    f->section_data = as_calloc(n, sizeof *f->section_data, "the .asf section table");
    f->owned = as_calloc(n, sizeof *f->owned, "the .asf section table");
    f->verified = as_calloc(n, 1, "the .asf section table");
    if (!f->entries || !f->section_data || !f->owned || !f->verified) return AS_ERROR_OUT_OF_MEMORY;

    for (uint32_t i = 0; i < count; ++i) {
        /* Only the first 64 bytes of a longer (newer minor) entry are known. */
        memcpy(&f->entries[i], f->data + h->section_table_offset + (uint64_t)i * h->section_entry_size,
               sizeof *f->entries);
        err = check_entry(f, i);
        if (err != AS_OK) return err;
    }
    err = check_overlap(f);
    if (err != AS_OK) return err;
    for (uint32_t i = 0; i < count; ++i) {
        const asf_section_entry_t *e = &f->entries[i];
        if ((e->flags & ASF_SECTION_REQUIRED) && !tag_known(args, e->tag))
            return as_set_error(AS_ERROR_UNSUPPORTED, SECTION_FMT "required section %s is unknown to "
                                "this reader", SECTION_ARGS(f, e, i), tag_text(e->tag).s);
    }
    return load_sections(f, args);
}

/* NULL arguments: verify checksums; know the tags asf_format.h defines. */
static const uint32_t default_known_tags[] = {ASF_TAG_META, ASF_TAG_BVH2, ASF_TAG_TRI4};

static asf_file_t *open_common(asf_file_t *f, const asf_open_args_t *args)
{
    asf_open_args_t defaults = {1, default_known_tags,
                                (uint32_t)(sizeof default_known_tags / sizeof default_known_tags[0])};
    if (!args) args = &defaults;
    if (args->known_tag_count > 0 && !args->known_tags) {
        as_set_error(AS_ERROR_INVALID_ARGUMENT, "%s: known_tag_count is %" PRIu32 " but known_tags is NULL",
                     f->name, args->known_tag_count);
        asf_close(f);
        return NULL;
    }
    if (check_and_load(f, args) != AS_OK) {
        asf_close(f);
        return NULL;
    }
    return f;
}

static asf_file_t *file_new(const char *name)
{
    asf_file_t *f = as_calloc(1, sizeof *f, "an .asf file handle");
    if (!f) return NULL;
    const size_t len = strlen(name);
    f->name = as_malloc(len + 1, "a file name");
    if (!f->name) {
        free(f);
        return NULL;
    }
    memcpy(f->name, name, len + 1);
    return f;
}

asf_file_t *asf_open(const char *path, const asf_open_args_t *args)
{
    if (!path || !*path) {
        as_set_error(AS_ERROR_INVALID_ARGUMENT, "asf_open: empty path");
        return NULL;
    }
    asf_file_t *f = file_new(path);
    if (!f) return NULL;
    if (as_file_map(path, &f->map) != AS_OK) {
        asf_close(f);
        return NULL;
    }
    f->data = f->map.data;
    f->size = f->map.size;
    return open_common(f, args);
}

asf_file_t *asf_open_memory(const void *data, size_t size, const char *name,
                            const asf_open_args_t *args)
{
    if (!name) name = "(memory)";
    if (!data && size > 0) {
        as_set_error(AS_ERROR_INVALID_ARGUMENT, "%s: no data", name);
        return NULL;
    }
    asf_file_t *f = file_new(name);
    if (!f) return NULL;
    f->data = data;
    f->size = data ? size : 0;
    return open_common(f, args);
}

void asf_close(asf_file_t *f)
{
    if (!f) return;
    if (f->owned)
        for (uint32_t i = 0; i < f->header.section_count; ++i) free(f->owned[i]);
    free(f->owned);
    free(f->section_data);
    free(f->verified);
    free(f->entries);
    as_file_unmap(&f->map);
    free(f->name);
    free(f);
}

const void *asf_bytes(const asf_file_t *f) { return f ? f->data : NULL; }

const char *asf_name(const asf_file_t *f) { return f->name; }
uint64_t asf_size(const asf_file_t *f) { return f->size; }
const asf_header_t *asf_header(const asf_file_t *f) { return &f->header; }
uint32_t asf_section_count(const asf_file_t *f) { return f->header.section_count; }

const asf_section_entry_t *asf_section_entry(const asf_file_t *f, uint32_t index)
{
    return index < f->header.section_count ? &f->entries[index] : NULL;
}

const void *asf_section_data(const asf_file_t *f, uint32_t index)
{
    return index < f->header.section_count ? f->section_data[index] : NULL;
}

int asf_section_checksum_verified(const asf_file_t *f, uint32_t index)
{
    return index < f->header.section_count ? f->verified[index] : 0;
}

int asf_find_section(const asf_file_t *f, uint32_t tag)
{
    for (uint32_t i = 0; i < f->header.section_count; ++i)
        if (f->entries[i].tag == tag) return (int)i;
    return -1;
}
