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

/* What libas knows of one stored layout: its sections, and how to validate,
 * describe and trace it. One table per layout, in the layout's own file
 * (bvh2_layout_ops.c, ...); adding a structure adds a table to as_layouts. */
#define AS_LAYOUT_MAX_SECTIONS 6

typedef struct as_layout_section {
    uint32_t tag;
    uint32_t stride;
    const char *purpose;          /* why the section is there (as-inspect) */
} as_layout_section_t;

typedef struct as_layout_ops {
    uint32_t structure_kind;      /* as_structure_kind_t */
    uint32_t layout;              /* as_layout_t */
    uint32_t layout_version;      /* the newest this build reads */
    const char *kind_name;        /* "bvh" */
    const char *layout_name;      /* "bvh2-child-bounds" */
    uint32_t section_count;
    as_layout_section_t sections[AS_LAYOUT_MAX_SECTIONS];
    /* Structural checks before any traversal reads the sections. */
    as_error_t (*validate)(const as_structure_t *s, const char *name);
    /* Counts, depths, histograms, SAH cost; `s` has been validated. */
    void (*stats)(const as_structure_t *s, as_structure_stats_t *st);
    /* Traces rays [0, count) on the calling thread. */
    void (*trace_cpu)(const as_structure_t *s, const as_ray_t *rays, as_hit_t *hits, size_t count,
                      int any_hit);
    /* Fills `dst` (zeroed) with the same structure in `target` layout, or
     * returns AS_ERROR_UNSUPPORTED; NULL when the layout converts to none. */
    as_error_t (*convert)(const as_structure_t *src, uint32_t target, as_structure_t *dst);
    /* The CUDA back end, or NULL where this build has none. */
    as_error_t (*trace_gpu)(const as_structure_t *s, const as_ray_t *rays, size_t count, as_hit_t *hits,
                            int any_hit, unsigned timed_runs, as_trace_timing_t *timing);
} as_layout_ops_t;

/* The table for a kind and layout, or NULL when this build has none. */
const as_layout_ops_t *as_layout_find(uint32_t structure_kind, uint32_t layout);
/* The table of a structure (never NULL for a built or loaded one). */
const as_layout_ops_t *as_structure_ops(const as_structure_t *s);

extern const as_layout_ops_t as_layout_bvh2_child_bounds;

/* Builders: fill s->meta (kind, layout, parameters, counts) and sections. */
as_error_t as_bvh_build_sah(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);

/* SAH cost of a BVH2, from the stored layout. */
double as_bvh2_sah_cost(const as_structure_t *s);
as_error_t as_bvh2_validate(const as_structure_t *s, const char *name);

extern const as_layout_ops_t as_layout_kd_standard;
extern const as_layout_ops_t as_layout_kd_ropes;
as_error_t as_kd_build_midcut(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);
as_error_t as_kd_build_sah(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);
/* SAH cost of a KD tree from its stored sections (kd_layout_ops.c). */
double as_kd_sah_cost(const as_structure_t *s);
as_error_t as_kd_validate(const as_structure_t *s, const char *name);
as_error_t as_kd_ropes_validate(const as_structure_t *s, const char *name);
/* Adds KDRP and KDLB to a KD-standard structure and makes it kd-ropes. */
as_error_t as_kd_add_ropes(as_structure_t *s);

/* The CPU back end: a layout's trace_cpu on every core. */
as_error_t as_trace_cpu(const as_structure_t *s, const as_ray_t *rays, size_t count, as_hit_t *hits,
                        const as_trace_args_t *args, as_trace_timing_t *timing);

#endif
