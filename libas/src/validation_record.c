/* Fingerprints and the record of validated structures.
 *
 * Validation is a walk over the whole tree and costs far more than reading
 * the bytes; a file that passed once need not be walked again if its bytes
 * are the same. The fingerprint says whether they are: XXH3-128 over META
 * and every section's tag, size and bytes, hashed in fixed 16 MB pieces on
 * every thread (the pieces do not depend on the thread count, so neither
 * does the fingerprint). The build record is left out: it does not change
 * what a traversal reads.
 *
 * The record is a text file, one fingerprint per line in hex. XXH3 is not a
 * cryptographic hash, and whoever can write the record can make a reader
 * skip validation: docs/SECURITY.md says when that is acceptable. */
#define _POSIX_C_SOURCE 200809L
#include "structure.h"
#include "atomic_file.h"
#include "task_pool.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define XXH_INLINE_ALL
#include <xxhash.h>

#define PIECE_BYTES ((uint64_t)16 << 20)

typedef struct piece {
    const unsigned char *data;
    size_t bytes;
    XXH128_hash_t hash;
} piece;

typedef struct piece_job {
    piece *pieces;
    size_t count;
} piece_job;

static void hash_pieces(void *user, unsigned i, unsigned n)
{
    piece_job *j = user;
    for (size_t k = i; k < j->count; k += n) j->pieces[k].hash = XXH3_128bits(j->pieces[k].data, j->pieces[k].bytes);
}

as_error_t as_structure_fingerprint(const as_structure_t *s, uint8_t fingerprint[16])
{
    if (!s || !fingerprint) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_structure_fingerprint: NULL argument");
    size_t count = 0;
    for (uint32_t i = 0; i < s->section_count; ++i)
        count += (size_t)((s->sections[i].bytes + PIECE_BYTES - 1) / PIECE_BYTES);
    piece *pieces = as_malloc(sizeof *pieces * (count ? count : 1), "fingerprint pieces");
    if (!pieces) return as_get_error();
    size_t k = 0;
    for (uint32_t i = 0; i < s->section_count; ++i) {
        const as_section_t *sec = &s->sections[i];
        for (uint64_t at = 0; at < sec->bytes; at += PIECE_BYTES) {
            pieces[k].data = (const unsigned char *)sec->data + at;
            pieces[k].bytes = (size_t)(sec->bytes - at < PIECE_BYTES ? sec->bytes - at : PIECE_BYTES);
            ++k;
        }
    }
    piece_job job = {pieces, count};
    const unsigned threads = as_thread_count(0);
    as_parallel_run(count < threads ? (unsigned)(count ? count : 1) : threads, hash_pieces, &job);

    XXH3_state_t *st = XXH3_createState();
    if (!st) {
        free(pieces);
        return as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory for a fingerprint");
    }
    XXH3_128bits_reset(st);
    XXH3_128bits_update(st, &s->meta, sizeof s->meta);
    k = 0;
    for (uint32_t i = 0; i < s->section_count; ++i) {
        const as_section_t *sec = &s->sections[i];
        const uint64_t head[2] = {sec->tag, sec->bytes};
        XXH3_128bits_update(st, head, sizeof head);
        for (uint64_t at = 0; at < sec->bytes; at += PIECE_BYTES, ++k) {
            XXH128_canonical_t c;
            XXH128_canonicalFromHash(&c, pieces[k].hash);
            XXH3_128bits_update(st, &c, sizeof c);
        }
    }
    XXH128_canonical_t out;
    XXH128_canonicalFromHash(&out, XXH3_128bits_digest(st));
    XXH3_freeState(st);
    free(pieces);
    memcpy(fingerprint, out.digest, 16);
    return AS_OK;
}

static void to_hex(const uint8_t fp[16], char hex[33])
{
    static const char digits[] = "0123456789abcdef";
    for (int i = 0; i < 16; ++i) {
        hex[2 * i] = digits[fp[i] >> 4];
        hex[2 * i + 1] = digits[fp[i] & 15];
    }
    hex[32] = '\0';
}

/* The record's bytes; NULL with *size 0 when the file does not exist. */
static as_error_t read_record(const char *record, char **text, size_t *size)
{
    *text = NULL;
    *size = 0;
    FILE *f = fopen(record, "rb");
    if (!f) {
        if (errno == ENOENT) return AS_OK;
        return as_set_error(AS_ERROR_IO, "%s: cannot open the validation record: %s", record, strerror(errno));
    }
    size_t cap = 4096, n = 0;
    char *buf = malloc(cap);
    for (;;) {
        if (!buf) {
            fclose(f);
            return as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory reading the validation record", record);
        }
        n += fread(buf + n, 1, cap - n, f);
        if (n < cap) break;
        char *grown = realloc(buf, cap * 2);
        if (!grown) free(buf);
        buf = grown;
        cap *= 2;
    }
    const int failed = ferror(f);
    fclose(f);
    if (failed) {
        free(buf);
        return as_set_error(AS_ERROR_IO, "%s: cannot read the validation record", record);
    }
    *text = buf;
    *size = n;
    return AS_OK;
}

/* Whether `text` has `hex` as a whole line. */
static int lists(const char *text, size_t size, const char hex[33])
{
    for (size_t at = 0; at + 32 <= size;) {
        const char *nl = memchr(text + at, '\n', size - at);
        const size_t end = nl ? (size_t)(nl - text) : size;
        if (end - at == 32 && memcmp(text + at, hex, 32) == 0) return 1;
        at = end + 1;
    }
    return 0;
}

static as_error_t record_lists(const char *record, const uint8_t fingerprint[16], bool *listed)
{
    if (!record || !fingerprint || !listed)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "validation record: NULL argument");
    *listed = false;
    char *text;
    size_t size;
    const as_error_t err = read_record(record, &text, &size);
    if (err != AS_OK) return err;
    char hex[33];
    to_hex(fingerprint, hex);
    *listed = text && lists(text, size, hex);
    free(text);
    return AS_OK;
}

static as_error_t record_add(const char *record, const uint8_t fingerprint[16])
{
    if (!record || !fingerprint) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "validation record: NULL argument");
    char *text;
    size_t size;
    as_error_t err = read_record(record, &text, &size);
    if (err != AS_OK) return err;
    char line[34];
    to_hex(fingerprint, line);
    if (text && lists(text, size, line)) {
        free(text);
        return AS_OK;
    }
    line[32] = '\n';
    line[33] = '\0';
    /* A record that does not end its last line gets the newline first. */
    const int joined = size > 0 && text[size - 1] != '\n';
    const as_file_part_t parts[3] = {{text, size}, {"\n", joined ? 1u : 0u}, {line, 33}};
    err = as_atomic_write(record, parts, 3);
    free(text);
    return err;
}

as_error_t as_structure_validate_recorded(const as_structure_t *s, const char *record, as_validation_info_t *info)
{
    as_validation_info_t local;
    if (!info) info = &local;
    memset(info, 0, sizeof *info);
    if (!s) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_structure_validate_recorded: NULL structure");
    as_structure_t *mut = (as_structure_t *)s; /* only the atomic flag changes */
    as_error_t err;
    if (record) {
        const double t0 = as_now_ms();
        err = as_structure_fingerprint(s, info->fingerprint);
        info->fingerprint_ms = as_now_ms() - t0;
        if (err != AS_OK) return err;
        bool listed = false;
        if ((err = record_lists(record, info->fingerprint, &listed)) != AS_OK) return err;
        if (listed) {
            info->skipped = true;
            atomic_store(&mut->validated, 1);
            return AS_OK;
        }
    }
    const double t1 = as_now_ms();
    err = as_structure_validate(s);
    info->validate_ms = as_now_ms() - t1;
    if (err != AS_OK) return err;
    atomic_store(&mut->validated, 1);
    if (record && (err = record_add(record, info->fingerprint)) != AS_OK) return err;
    return AS_OK;
}
