/* Fuzzes the .asf container reader (asf_open_memory).
 *
 * Asserts, through ASan and UBSan: no input makes the reader read outside
 * the buffer or its own allocations, overflow, or leak; every section it
 * accepts lies in memory it may read (each byte is hashed), is 64-byte
 * aligned, and has the raw size its entry states; every refusal sets an
 * error with a message.
 *
 * The first byte carves the parameters, the rest is the file:
 *   bit 0  verify section checksums;
 *   bit 1  rewrite the table checksum first, so that mutations of the
 *          table reach the entry checks instead of stopping at the hash;
 *   bit 2  know no tags (every required section is refused);
 *   bit 3  place the file 8 bytes into its buffer, off the 64-byte
 *          alignment, so that raw sections take the copying path. */
#include "asf_container.h"
#include "as_internal.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* abort, not return: libFuzzer and the replay driver both report it. */
static void fail(const char *what)
{
    fprintf(stderr, "fuzz_asf_reader: %s\n", what);
    abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    const uint8_t params = data[0];
    ++data;
    --size;

    /* A private copy: the table checksum may be rewritten, and a buffer
     * ending right after the file lets ASan see a read one past the end. */
    const size_t shift = (params & 8) ? 8 : 0;
    uint8_t *buffer = malloc(shift + size + (size ? 0 : 1));
    if (!buffer) return 0;
    uint8_t *copy = buffer + shift;
    if (size) memcpy(copy, data, size);

    if ((params & 2) && size >= sizeof(asf_header_t)) {
        asf_header_t h;
        memcpy(&h, copy, sizeof h);
        uint64_t bytes, end;
        if (h.section_count <= ASF_MAX_SECTIONS &&
            as_mul_u64(h.section_count, h.section_entry_size, &bytes) &&
            as_add_u64(h.section_table_offset, bytes, &end) && end <= size) {
            h.table_checksum = as_hash64(copy + h.section_table_offset, (size_t)bytes);
            memcpy(copy, &h, sizeof h);
        }
    }

    static const uint32_t known[] = {ASF_TAG_META, ASF_TAG_BVH2, ASF_TAG_TRI4};
    const asf_open_args_t args = {params & 1, known, (params & 4) ? 0 : 3};

    as_clear_error();
    asf_file_t *f = asf_open_memory(copy, size, "fuzz.asf", &args);
    if (!f) {
        if (as_get_error() == AS_OK || as_get_error_message()[0] == '\0') fail("refusal without error");
    } else {
        uint64_t sink = 0;
        for (uint32_t i = 0; i < asf_section_count(f); ++i) {
            const asf_section_entry_t *e = asf_section_entry(f, i);
            const void *p = asf_section_data(f, i);
            if (!e) fail("missing entry");
            if (!p) continue; /* an unknown optional section, skipped */
            if ((uintptr_t)p % ASF_SECTION_ALIGNMENT != 0) fail("misaligned section");
            sink ^= as_hash64(p, (size_t)e->raw_size);
            if ((params & 1) && !asf_section_checksum_verified(f, i)) fail("unverified section");
        }
        /* Keeps the hashing from being optimised away. */
        volatile uint64_t keep = sink;
        (void)keep;
        asf_close(f);
    }
    free(buffer);
    return 0;
}
