/* A structure as libas holds it: its META record and typed sections, owned
 * (just built) or borrowed from a mapped file. */
#ifndef AS_STRUCTURE_H
#define AS_STRUCTURE_H

#include "as_internal.h"
#include "asf_container.h"
#include "asf_format.h"

#define AS_MAX_SECTIONS 8

typedef struct as_section {
    uint32_t tag;
    uint32_t flags;               /* ASF_SECTION_* as in the file */
    const void *data;             /* raw bytes, 64-byte aligned */
    void *owned;                  /* freed on release when not NULL */
    uint64_t bytes, count;
    uint32_t stride;
    int file_index;               /* index in the file's table, -1 if built */
} as_section_t;

struct as_structure {
    as_meta_t meta;
    as_section_t sections[AS_MAX_SECTIONS];
    uint32_t section_count;
    asf_file_t *file;             /* when loaded */
    double build_ms;              /* when built; files do not store it */
};

/* The section with this tag, or NULL. */
const as_section_t *as_structure_find(const as_structure_t *s, uint32_t tag);

/* Adds an owned section (takes `data`, allocated with as_aligned_alloc). */
void as_structure_add_section(as_structure_t *s, uint32_t tag, void *data, uint64_t count,
                              uint32_t stride);

/* 64-byte aligned allocation for section data; free with free(). */
void *as_aligned_alloc(size_t bytes, const char *what);

/* Builders: fill s->meta (kind, layout, parameters, counts) and sections. */
as_error_t as_bvh_build_sah(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);

/* SAH cost of a BVH2, from the stored layout. */
double as_bvh2_sah_cost(const as_structure_t *s);

/* CPU and GPU tracing back ends. */
as_error_t as_trace_cpu(const as_structure_t *s, const as_ray_t *rays, size_t count,
                        as_hit_t *hits, const as_trace_args_t *args, as_trace_timing_t *timing);
#endif
