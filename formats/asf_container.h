/* Reading and writing the .asf container (formats/SPEC.md). The container
 * knows sections, not structures: it checks the header, the table, bounds,
 * flags and checksums, and hands out each section's raw bytes. */
#ifndef AS_ASF_CONTAINER_H
#define AS_ASF_CONTAINER_H

#include "asf_format.h"
#include "as/as.h"

#include <stddef.h>
#include <stdint.h>

/* A section to write. */
typedef struct asf_section_desc {
    uint32_t tag;
    uint32_t flags;                /* ASF_SECTION_REQUIRED; ZSTD is set by the writer */
    const void *data;
    uint64_t size;
    uint64_t element_count;
    uint32_t stride;
    int compression_level;         /* 0: raw; 1..22: zstd */
} asf_section_desc_t;

/* Writes a container: header, section table, then the sections, each at an
 * aligned offset, padding zero. Writes PATH.tmp.XXXXXX, fsyncs, renames.
 * Errors: AS_ERROR_IO (message names the path and the system error),
 * AS_ERROR_INVALID_ARGUMENT. */
as_error_t asf_write(const char *path, const asf_section_desc_t *sections, uint32_t count);

/* The same into a malloc'd buffer (for tests and fuzz seeds). */
as_error_t asf_write_memory(const asf_section_desc_t *sections, uint32_t count,
                            void **out, size_t *out_size);

typedef struct asf_file asf_file_t;

typedef struct asf_open_args {
    int verify_checksums;          /* nonzero: check every section's XXH3 */
    const uint32_t *known_tags;    /* tags this reader understands */
    uint32_t known_tag_count;
} asf_open_args_t;

/* Maps and checks a file: magic, version (newer major: AS_ERROR_VERSION),
 * reserved fields, table checksum, every offset and size against the file
 * size (overflow-safe), alignment, overlap, flags; unknown required tags
 * (AS_ERROR_UNSUPPORTED); decompresses zstd sections; verifies checksums
 * (AS_ERROR_CHECKSUM). Messages name the file, the section and the offset.
 * Returns NULL and sets the error on failure. */
asf_file_t *asf_open(const char *path, const asf_open_args_t *args);
/* The same over memory the caller keeps alive; `name` is used in messages. */
asf_file_t *asf_open_memory(const void *data, size_t size, const char *name,
                            const asf_open_args_t *args);
void asf_close(asf_file_t *f);

const char *asf_name(const asf_file_t *f);
/* The whole file's bytes (the mapping, page-aligned, when opened from a
 * path), for callers that hand the mapping itself to a device. */
const void *asf_bytes(const asf_file_t *f);
uint64_t asf_size(const asf_file_t *f);
const asf_header_t *asf_header(const asf_file_t *f);
uint32_t asf_section_count(const asf_file_t *f);
const asf_section_entry_t *asf_section_entry(const asf_file_t *f, uint32_t index);
/* Raw (decompressed) bytes of a section, aligned to at least 64 bytes. */
const void *asf_section_data(const asf_file_t *f, uint32_t index);
/* 1 verified, 0 not checked. */
int asf_section_checksum_verified(const asf_file_t *f, uint32_t index);
/* Index of the first section with this tag, or -1. */
int asf_find_section(const asf_file_t *f, uint32_t tag);

#endif
