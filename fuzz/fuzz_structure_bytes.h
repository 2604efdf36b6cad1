/* An .asf image of a structure in memory, as as_structure_save writes it
 * (META, the layout's sections, no build record): what the seed generator
 * stores and what fuzz_structure_trace reads back after a conversion,
 * without going through the file system. */
#ifndef AS_FUZZ_STRUCTURE_BYTES_H
#define AS_FUZZ_STRUCTURE_BYTES_H

#include "structure.h"

static inline as_error_t fuzz_structure_bytes(const as_structure_t *s, int compression_level, void **out,
                                              size_t *size)
{
    asf_section_desc_t desc[AS_MAX_SECTIONS + 1];
    uint32_t n = 0;
    desc[n++] = (asf_section_desc_t){ASF_TAG_META, ASF_SECTION_REQUIRED, &s->meta, sizeof s->meta, 1,
                                     sizeof s->meta, compression_level};
    for (uint32_t i = 0; i < s->section_count; ++i) {
        const as_section_t *sec = &s->sections[i];
        desc[n++] = (asf_section_desc_t){sec->tag, sec->flags & ASF_SECTION_REQUIRED, sec->data, sec->bytes,
                                         sec->count, sec->stride, compression_level};
    }
    return asf_write_memory(desc, n, out, size);
}

#endif
