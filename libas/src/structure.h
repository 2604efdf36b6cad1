/* A structure as libas holds it: its META record and typed sections, owned
 * (just built) or borrowed from a mapped file. */
#ifndef AS_STRUCTURE_H
#define AS_STRUCTURE_H

#include "as_internal.h"

#include <stdatomic.h>
#include "asf_container.h"
#include "asf_format.h"

#define AS_MAX_SECTIONS 8

typedef struct as_section {
    uint32_t tag;
    uint32_t flags;               /* ASF_SECTION_* as in the file */
    const void *data;             /* raw bytes, 64-byte aligned */
    void *owned;                  /* freed on release when not NULL */
    size_t give_bytes;            /* not 0: owned came from as_aligned_alloc(give_bytes) and goes back
                                     to as_block_give on release, for the next build */
    uint64_t bytes, count;
    uint32_t stride;
    int file_index;               /* index in the file's table, -1 if built */
} as_section_t;

struct as_structure {
    as_meta_t meta;
    as_section_t sections[AS_MAX_SECTIONS];
    uint32_t section_count;
    asf_file_t *file;             /* when loaded */
    struct as_gpu_resident *gpu;  /* the sections on the GPU, after the first GPU use */
    double build_ms;              /* when built; files do not store it */
    as_build_record_t record;     /* BREC: set by a build or read from the file */
    int has_record;
    /* Set by as_structure_validate_recorded once the structure passed (or
     * its fingerprint was in the caller's record): later walks need not
     * validate again. Plain as_structure_validate leaves it alone, so a
     * structure changed in memory after it is checked again. */
    atomic_int validated;
};

/* as_structure_validate, unless as_structure_validate_recorded has
 * already vouched for the structure. For walks that must not follow a bad
 * index (statistics, closest points). */
as_error_t as_structure_check_valid(const as_structure_t *s);

/* The section with this tag, or NULL. */
const as_section_t *as_structure_find(const as_structure_t *s, uint32_t tag);

/* Adds an owned section (takes `data`, allocated with as_aligned_alloc). */
void as_structure_add_section(as_structure_t *s, uint32_t tag, void *data, uint64_t count,
                              uint32_t stride);
/* The same for `data` from as_aligned_alloc(alloc_bytes): on release it goes
 * back to the build memory kept for the next build (as_block_give). */
void as_structure_add_kept_section(as_structure_t *s, uint32_t tag, void *data, uint64_t count, uint32_t stride,
                                   size_t alloc_bytes);

/* For each source triangle index, its vertices in the structure (TRIS in
 * source order, or TRI4 in leaf order inverted); NULL where the structure
 * has none (zero-area triangles). malloc'd; the caller frees it. */
struct as_tri4;
const struct as_tri4 **as_structure_triangles_by_prim(const as_structure_t *s);

/* 64-byte aligned allocation for section data (from 1 MB taken from the
 * blocks earlier builds gave back when one fits: as_block_take; from 4 MB
 * 2 MB aligned and marked for transparent huge pages); free with free(), or
 * give back with as_block_give(p, bytes, 1). */
void *as_aligned_alloc(size_t bytes, const char *what);

/* A block of `bytes` for a build's arrays, from the large blocks earlier
 * builds of the process gave back (as_block_give) when one holds `bytes`
 * and is at most twice as large, else fresh (64-byte aligned; huge and 4 MB
 * or more: 2 MB aligned and marked for transparent huge pages, as
 * as_aligned_alloc). Its contents are
 * undefined. NULL with the error set when out of memory. Thread-safe. Any
 * block may be freed with free() instead of given back. */
void *as_block_take(size_t bytes, int huge, const char *what);
/* Gives back a block from as_block_take or as_aligned_alloc of at least
 * `bytes` (and of the same `huge`): kept for a later as_block_take when it
 * is 1 MB or more (at most 16 blocks and 512 MB counted at the sizes given
 * back, which may be half a reused block's; the oldest freed first),
 * else freed. NULL is ignored. Thread-safe. */
void as_block_give(void *p, size_t bytes, int huge);

/* A temporary array of `bytes` for a build's work that is freed and asked
 * for again many times in a build (the KD builder's event lists and
 * reference arrays): from AS_TEMP_MIN_BYTES on, a block of the next power of
 * two that an earlier temporary of this or an earlier build gave back
 * (as_temp_give), else fresh; smaller ones from malloc. Its contents are
 * undefined. NULL with the error set when out of memory. Thread-safe. */
void *as_temp_take(size_t bytes, const char *what);
/* Gives back a temporary from as_temp_take of `bytes` (the same figure):
 * kept for a later as_temp_take of its size class while the kept ones come
 * to at most 256 MB of blocks, else freed. NULL is ignored. Thread-safe. */
void as_temp_give(void *p);

/* What libas knows of one stored layout: its sections, and how to validate,
 * describe and trace it. One table per layout, in the layout's own file
 * (bvh2_layout_ops.c, ...); adding a structure adds a table to as_layouts. */
#define AS_LAYOUT_MAX_SECTIONS 6

struct as_gpu_launch; /* kernels/trace_gpu.h */

/* Traversal counters summed over rays, with their maxima. */
typedef struct as_cpu_stats {
    uint64_t steps, tests;
    uint32_t steps_max, tests_max;
} as_cpu_stats_t;

/* The per-ray loop of every layout's trace_cpu (whose parameters it uses:
 * rays, hits, count, ray_flags, stats): prepares each ray and, when READY
 * holds (the sections have what the traversal starts from: a file loaded
 * without validation may have no root), evaluates TRAVERSE, which traces
 * `pre` into `h` and counts into `ctrp` (NULL unless counting); bad rays
 * and the rest miss. */
#define AS_TRACE_CPU_LOOP(READY, TRAVERSE)                                                   \
    for (size_t i_ = 0; i_ < count; ++i_) {                                                  \
        const as_ray_t *ray_ = &rays[i_];                                                    \
        as_hit_rec_t h;                                                                      \
        as_ray_pre_t pre;                                                                    \
        as_trace_counters_t ctr_ = {0, 0};                                                   \
        as_trace_counters_t *ctrp = stats ? &ctr_ : NULL;                                    \
        if ((READY) && as_ray_prepare(ray_->org, ray_->tmin, ray_->dir, ray_->tmax, ray_flags, &pre)) \
            TRAVERSE;                                                                        \
        else                                                                                 \
            as_hit_rec_miss(&h);                                                             \
        if (stats) as_cpu_stats_add(stats, ctr_.node_visits, ctr_.tri_tests);               \
        hits[i_].t = h.t;                                                                    \
        hits[i_].prim = h.prim;                                                              \
        hits[i_].u = h.u;                                                                    \
        hits[i_].v = h.v;                                                                    \
    }

/* Adds one ray's counters. */
static inline void as_cpu_stats_add(as_cpu_stats_t *s, uint32_t steps, uint32_t tests)
{
    s->steps += steps;
    s->tests += tests;
    if (steps > s->steps_max) s->steps_max = steps;
    if (tests > s->tests_max) s->tests_max = tests;
}

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
    /* Traces rays [0, count) on the calling thread; ray_flags go to
     * as_ray_prepare (AS_RAY_PRECISE). With `stats`, also counts each ray's
     * steps and triangle tests into it. */
    void (*trace_cpu)(const as_structure_t *s, const as_ray_t *rays, as_hit_t *hits, size_t count,
                      int any_hit, int ray_flags, struct as_cpu_stats *stats);
    /* Fills `dst` (zeroed) with the same structure in `target` layout, or
     * returns AS_ERROR_UNSUPPORTED; NULL when the layout converts to none. */
    as_error_t (*convert)(const as_structure_t *src, uint32_t target, as_structure_t *dst);
    /* The CUDA back end, or NULL where this build has none. */
    as_error_t (*trace_gpu)(const as_structure_t *s, const as_ray_t *rays, size_t count, as_hit_t *hits,
                            const struct as_gpu_launch *launch, as_trace_timing_t *timing);
    /* The checks of `validate`, run on the GPU over the uploaded sections
     * (s->gpu, in device memory); NULL where the layout has none. */
    as_error_t (*validate_gpu)(const as_structure_t *s, const char *name);
} as_layout_ops_t;

/* The table for a kind and layout, or NULL when this build has none. */
const as_layout_ops_t *as_layout_find(uint32_t structure_kind, uint32_t layout);
/* The table of a structure (never NULL for a built or loaded one). */
const as_layout_ops_t *as_structure_ops(const as_structure_t *s);

extern const as_layout_ops_t as_layout_bvh2_child_bounds;
extern const as_layout_ops_t as_layout_bvh2_own_bounds;
extern const as_layout_ops_t as_layout_cwbvh;

/* The trace_gpu of every layout with a CUDA kernel: launches the kernel of
 * s->meta.layout over the resident sections. */
as_error_t as_layout_trace_gpu(const as_structure_t *s, const as_ray_t *rays, size_t count, as_hit_t *hits,
                               const struct as_gpu_launch *launch, as_trace_timing_t *timing);

/* Builders: fill s->meta (kind, layout, parameters, counts) and sections. */
as_error_t as_bvh_build_sah(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);
as_error_t as_bvh_build_midcut(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);
as_error_t as_bvh_build_sweep(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);
as_error_t as_bvh_build_sbvh(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);

/* SAH cost of a BVH2, from the stored layout. */
double as_bvh2_sah_cost(const as_structure_t *s);
/* The SAH cost from its sums: inner nodes' half areas, leaves' half area x
 * count (root_area 0: every area counts 1). */
double as_bvh2_sah_from_sums(double ct, double ci, double root_area, double inner_area, double leaf_area_count,
                             uint64_t inner_count, uint64_t ref_count);
/* SAH sums (a BVH2's, a KD tree's, a BIH's): their terms in pre-order, added in blocks of
 * AS_SAH_SUM_BLOCK (each block summed from zero, then the blocks' sums in
 * order), so that a builder writing the tree on several threads can sum
 * the blocks on several threads too and get the bits one walk gets. */
#define AS_SAH_SUM_BLOCK 4096
typedef struct as_sah_sum {
    double total, block;
    uint64_t count;
} as_sah_sum;
static inline void as_sah_sum_add(as_sah_sum *s, double term)
{
    s->block += term;
    if (++s->count % AS_SAH_SUM_BLOCK == 0) {
        s->total += s->block;
        s->block = 0.0;
    }
}
static inline double as_sah_sum_value(const as_sah_sum *s) { return s->total + s->block; }
/* The as_sah_sum of count terms, its blocks added on up to `threads`
 * threads (on this one when there is no memory for the blocks' sums). */
as_sah_sum as_sah_sum_terms(const double *terms, uint64_t count, unsigned threads);
/* Half the surface area of a box, in double; 0 for an inverted box. */
static inline double as_half_area6(float lox, float hix, float loy, float hiy, float loz, float hiz)
{
    const double dx = (double)hix - lox, dy = (double)hiy - loy, dz = (double)hiz - loz;
    if (!(dx >= 0 && dy >= 0 && dz >= 0)) return 0.0;
    return dx * dy + dy * dz + dz * dx;
}
as_error_t as_bvh2_validate(const as_structure_t *s, const char *name);
#ifdef AS_HAVE_CUDA
struct as_gpu_meta_expect;
/* What META says, as every GPU validator compares it (trace.c). */
void as_gpu_meta_expect(const as_structure_t *s, struct as_gpu_meta_expect *meta);
#endif
/* The same checks on the GPU, over s->gpu (CUDA builds). */
as_error_t as_bvh2_validate_gpu(const as_structure_t *s, const char *name);
/* Parts of the BVH2 validation shared by both BVH layouts (bvh2_validate.c):
 * the TRI4 triangles; one leaf (range, box, each entry in one leaf only,
 * triangles inside the box or, for an SBVH, overlapping it; `where` names
 * the node); META's counts against the arrays. */
struct as_tri4;
as_error_t as_bvh2_validate_tris(const as_structure_t *s, const char *name, const struct as_tri4 *tris,
                                 uint64_t tri_count);
/* Where a leaf sits, for messages: "<node_label> <node>", then " <slot_label>
 * <slot>" when slot_label is not NULL ("node 12 child 1", "BVHO node 12").
 * Formatted only when a check fails: a string per leaf was most of the
 * validation's time. */
typedef struct as_leaf_where {
    const char *node_label;
    long long node;
    const char *slot_label;
    int slot;
} as_leaf_where;
as_error_t as_bvh2_validate_leaf(const as_structure_t *s, const char *name, const struct as_tri4 *tris,
                                 uint64_t tri_count, uint8_t *tri_seen, uint64_t first, uint64_t count,
                                 const float box[6], const as_leaf_where *where);
as_error_t as_bvh2_validate_counts(const as_structure_t *s, const char *name, const char *section, uint64_t node_count,
                                   uint64_t tri_count, uint64_t leaves, uint64_t references, uint32_t max_leaf_depth);
/* The BVH2 layouts into each other (bvh2_own_layout_ops.c): `dst` is zeroed
 * and receives the same tree, META (counts, SAH cost) and a copy of TRI4.
 * Child-bounds -> own-bounds -> child-bounds gives the same bytes for any
 * tree a builder wrote. */
as_error_t as_bvh2_to_own_bounds(const as_structure_t *src, as_structure_t *dst);
as_error_t as_bvh2_own_to_child_bounds(const as_structure_t *src, as_structure_t *dst);
as_error_t as_bvh2_own_validate(const as_structure_t *s, const char *name);
as_error_t as_bvh2_own_validate_gpu(const as_structure_t *s, const char *name);

/* The compressed wide BVH (cwbvh_build.c): collapses a child-bounds BVH2
 * into `dst` (zeroed), leaves of at most leaf_max (1..3) triangles; META
 * as the source's but for the layout and the counts. as_cwbvh_build runs
 * `build` (a BVH2 builder) with one triangle per leaf, then collapses. */
as_error_t as_bvh2_to_cwbvh(const as_structure_t *src, uint32_t leaf_max, as_structure_t *dst);
as_error_t as_cwbvh_build(const as_mesh_t *mesh, const as_build_args_t *args,
                          as_error_t (*build)(const as_mesh_t *, const as_build_args_t *, as_structure_t *),
                          as_structure_t *s);
as_error_t as_cwbvh_validate(const as_structure_t *s, const char *name);
/* The same checks on the GPU, over s->gpu (CUDA builds). */
as_error_t as_cwbvh_validate_gpu(const as_structure_t *s, const char *name);
/* SAH cost over the decoded boxes (cwbvh_layout_ops.c). */
double as_cwbvh_sah_cost(const as_structure_t *s);

/* BIH, octree and uniform grid: builders, validators, SAH costs (from the
 * stored structure; `st` may be NULL, else its counts and histograms are
 * filled too). */
extern const as_layout_ops_t as_layout_bih;
extern const as_layout_ops_t as_layout_octree;
extern const as_layout_ops_t as_layout_grid;
as_error_t as_bih_build(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);
as_error_t as_octree_build(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);
as_error_t as_grid_build(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);
as_error_t as_bih_validate(const as_structure_t *s, const char *name);
as_error_t as_octree_validate(const as_structure_t *s, const char *name);
as_error_t as_grid_validate(const as_structure_t *s, const char *name);
/* The same checks on the GPU, over s->gpu (CUDA builds). */
as_error_t as_bih_validate_gpu(const as_structure_t *s, const char *name);
as_error_t as_octree_validate_gpu(const as_structure_t *s, const char *name);
as_error_t as_grid_validate_gpu(const as_structure_t *s, const char *name);
double as_bih_sah_cost(const as_structure_t *s, as_structure_stats_t *st);
double as_octree_sah_cost(const as_structure_t *s, as_structure_stats_t *st);
double as_grid_sah_cost(const as_structure_t *s, as_structure_stats_t *st);

extern const as_layout_ops_t as_layout_kd_standard;
extern const as_layout_ops_t as_layout_kd_ropes;
as_error_t as_kd_build_midcut(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);
as_error_t as_kd_build_sah(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);
/* SAH cost of a KD tree from its stored sections (kd_layout_ops.c). */
double as_kd_sah_cost(const as_structure_t *s);
as_error_t as_kd_validate(const as_structure_t *s, const char *name);
as_error_t as_kd_ropes_validate(const as_structure_t *s, const char *name);
/* The same checks on the GPU, over s->gpu (CUDA builds). */
as_error_t as_kd_validate_gpu(const as_structure_t *s, const char *name);
as_error_t as_kd_ropes_validate_gpu(const as_structure_t *s, const char *name);
/* Adds KDRP and KDLB to a KD-standard structure and makes it kd-ropes. */
as_error_t as_kd_add_ropes(as_structure_t *s);

/* The CPU back end: a layout's trace_cpu on every core. */
/* The as_ray_prepare flags (ray_triangle.h) that select an intersector. */
int as_intersector_ray_flags(as_intersector_t intersector);

as_error_t as_trace_cpu(const as_structure_t *s, const as_ray_t *rays, size_t count, as_hit_t *hits,
                        const as_trace_args_t *args, as_trace_timing_t *timing);

#endif
