/* Structures: building (dispatch to one builder per kind), saving to and
 * loading from .asf files, statistics and section listing. */
#define _DEFAULT_SOURCE /* madvise */
#include "structure.h"
#include "mesh.h"
#include "trace_gpu.h"
#include "bvh2_layout.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <pthread.h>
#include <sys/mman.h>

/* Sections of 4 MB and more (AS_HUGE_MIN_BYTES) are aligned to 2 MB and marked for transparent
 * huge pages, as Embree marks its BVH memory: a build writes its output
 * arrays once, fresh from the kernel, and at 4 KB a page their faults took
 * about half of the output phase (bathroom, one thread: 31 ms against 17 ms
 * with huge pages, medians of 15 builds). Where the kernel gives no huge
 * pages the hint does nothing. Huge pages for the builders' temporary
 * arrays as well made the output phase slower: each build then asks for
 * more huge pages at once than the kernel had ready. */
#define AS_HUGE_PAGE ((size_t)2 << 20)

#define AS_HUGE_MIN_BYTES ((size_t)4 << 20)

/* What a huge block of `bytes` really takes: whole 2 MB pages. */
static size_t huge_rounded(size_t bytes) { return (bytes + AS_HUGE_PAGE - 1) / AS_HUGE_PAGE * AS_HUGE_PAGE; }

/* Whether a block asked for as huge (section data) gets huge pages. */
static int block_is_huge(size_t bytes, int huge) { return huge && bytes >= AS_HUGE_MIN_BYTES; }

static void *fresh_block(size_t bytes, int huge)
{
    /* 64-byte aligned either way: sections are (as_aligned_alloc). */
    if (!huge) return aligned_alloc(64, (bytes + 63) / 64 * 64);
    const size_t rounded = huge_rounded(bytes);
    void *p = aligned_alloc(AS_HUGE_PAGE, rounded);
#ifdef MADV_HUGEPAGE
    if (p) (void)madvise(p, rounded, MADV_HUGEPAGE);
#endif
    return p;
}

/* Large blocks given back by builds (as_block_give), kept for the next
 * build of the process. Memory fresh from the kernel costs a page fault and
 * a cleared page per 4 KB (or a cleared 2 MB page), and in the VM this was
 * measured on, a page the host has taken back costs the host's fault too:
 * the output phase of one and the same 2-thread staircase build took 5 to
 * 30 ms, nearly all of it clearing pages, and the binned build's tmp nodes
 * (57 MB reserved on bathroom) faulted in about 7,200 pages in every build.
 * Embree keeps its allocator's blocks in the same way when a scene is
 * committed again. At most AS_BLOCKS_KEPT blocks and AS_BLOCKS_KEPT_BYTES
 * bytes are kept, counted at the sizes given back (a reused block may be up
 * to twice its taker's request, which is what comes back), the oldest freed
 * first; blocks under AS_BLOCK_MIN_BYTES are left to malloc. From 1 MB
 * rather than 4: malloc hands arrays of a few MB back to the kernel when
 * they are freed, so on bunny every build faulted in its output sections
 * and references afresh (on a 16-core host, 1,952 to 2,439 faults and 5.5
 * to 13.3 ms of system time per build of 4 to 6 ms, the threads' faults
 * waiting on each other). */
#define AS_BLOCKS_KEPT 16
#define AS_BLOCKS_KEPT_BYTES ((size_t)512 << 20)
#define AS_BLOCK_MIN_BYTES ((size_t)1 << 20)

static struct {
    pthread_mutex_t lock;
    struct { void *p; size_t bytes; int huge; } e[AS_BLOCKS_KEPT]; /* oldest first */
    unsigned n;
    size_t total;
} kept = {PTHREAD_MUTEX_INITIALIZER, {{NULL, 0, 0}}, 0, 0};

static void caches_fork_init(void);

void *as_block_take(size_t bytes, int huge, const char *what)
{
    caches_fork_init();
    if (!bytes) bytes = 1;
    void *p = NULL;
    if (bytes >= AS_BLOCK_MIN_BYTES) {
        /* The smallest kept block that holds `bytes` and is at most twice
         * as large (a far larger one would stay resident for little). */
        pthread_mutex_lock(&kept.lock);
        unsigned best = kept.n;
        for (unsigned i = 0; i < kept.n; ++i)
            if (kept.e[i].huge == block_is_huge(bytes, huge) && kept.e[i].bytes >= bytes && kept.e[i].bytes / 2 <= bytes &&
                (best == kept.n || kept.e[i].bytes < kept.e[best].bytes))
                best = i;
        if (best < kept.n) {
            p = kept.e[best].p;
            kept.total -= kept.e[best].bytes;
            memmove(&kept.e[best], &kept.e[best + 1], sizeof kept.e[0] * (kept.n - best - 1));
            kept.n--;
        }
        pthread_mutex_unlock(&kept.lock);
    }
    if (!p) p = fresh_block(bytes, block_is_huge(bytes, huge));
    if (!p) as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory allocating %zu bytes for %s", bytes, what);
    return p;
}

void as_block_give(void *p, size_t bytes, int huge)
{
    if (!p) return;
    /* Below AS_BLOCK_MIN_BYTES as_aligned_alloc took no huge block. */
    if (bytes < AS_BLOCK_MIN_BYTES || bytes > AS_BLOCKS_KEPT_BYTES) {
        free(p);
        return;
    }
    huge = block_is_huge(bytes, huge);
    if (huge) bytes = huge_rounded(bytes); /* what fresh_block took */
    void *drop[AS_BLOCKS_KEPT + 1];
    unsigned nd = 0;
    pthread_mutex_lock(&kept.lock);
    while (kept.n && (kept.n == AS_BLOCKS_KEPT || kept.total + bytes > AS_BLOCKS_KEPT_BYTES)) {
        drop[nd++] = kept.e[0].p;
        kept.total -= kept.e[0].bytes;
        memmove(&kept.e[0], &kept.e[1], sizeof kept.e[0] * (kept.n - 1));
        kept.n--;
    }
    kept.e[kept.n].p = p;
    kept.e[kept.n].bytes = bytes;
    kept.e[kept.n].huge = huge;
    kept.n++;
    kept.total += bytes;
    pthread_mutex_unlock(&kept.lock);
    for (unsigned i = 0; i < nd; ++i) free(drop[i]);
}

/* Temporaries by power-of-two size class (as_temp_take), kept for the
 * next ones. A KD SAH build frees and makes its nodes' event lists and
 * reference arrays level after level, and malloc gave many of their pages
 * back to the kernel between one and the next (it trims the top of its
 * heaps and maps large blocks afresh): on staircase with 2 threads, 22,000
 * page faults a build. Kept by size class, a build reuses what its upper
 * levels freed, and the next build all of it. Only the pages a request
 * writes are ever touched, so a class's rounding costs address space, not
 * memory. */
#define AS_TEMP_MIN_CLASS 16 /* 64 KB: smaller ones are malloc's (class 0 in their header) */
#define AS_TEMPS_KEPT_BYTES ((size_t)256 << 20)
#define AS_TEMP_CLASSES 64

static struct {
    pthread_mutex_t lock;
    void *head[AS_TEMP_CLASSES]; /* free blocks of 2^k bytes, each holding the next */
    size_t total;
} temps = {PTHREAD_MUTEX_INITIALIZER, {NULL}, 0};

static unsigned temp_class(size_t bytes)
{
    unsigned k = AS_TEMP_MIN_CLASS;
    while (k + 1 < AS_TEMP_CLASSES && ((size_t)1 << k) < bytes) ++k;
    return k;
}

/* Each block starts with its class, so that a request may take a block up
 * to AS_TEMP_REACH classes larger and it still goes back to its own. */
#define AS_TEMP_HEADER 16
#define AS_TEMP_REACH 2

void *as_temp_take(size_t bytes, const char *what)
{
    caches_fork_init();
    unsigned char *p = NULL;
    unsigned got = 0;
    if (bytes + AS_TEMP_HEADER < ((size_t)1 << AS_TEMP_MIN_CLASS)) {
        p = malloc(bytes + AS_TEMP_HEADER);
    } else {
        const unsigned k = temp_class(bytes + AS_TEMP_HEADER);
        pthread_mutex_lock(&temps.lock);
        for (got = k; got <= k + AS_TEMP_REACH && got < AS_TEMP_CLASSES; ++got)
            if ((p = temps.head[got]) != NULL) {
                temps.head[got] = *(void **)(p + AS_TEMP_HEADER);
                temps.total -= (size_t)1 << got;
                break;
            }
        pthread_mutex_unlock(&temps.lock);
        if (!p) {
            got = k;
            p = malloc((size_t)1 << k);
        }
    }
    if (!p) {
        as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory allocating %zu bytes for %s", bytes, what);
        return NULL;
    }
    p[0] = (unsigned char)got;
    return p + AS_TEMP_HEADER;
}

void as_temp_give(void *block)
{
    if (!block) return;
    unsigned char *p = (unsigned char *)block - AS_TEMP_HEADER;
    const unsigned k = p[0];
    if (!k) {
        free(p);
        return;
    }
    pthread_mutex_lock(&temps.lock);
    if (temps.total + ((size_t)1 << k) <= AS_TEMPS_KEPT_BYTES) {
        *(void **)block = temps.head[k];
        temps.head[k] = p;
        temps.total += (size_t)1 << k;
        p = NULL;
    }
    pthread_mutex_unlock(&temps.lock);
    free(p);
}

/* A fork while another thread holds a cache's lock would leave the
 * child's next build waiting for ever: both locks are taken around the
 * fork, so the child starts with consistent lists and free locks. */
static void caches_before_fork(void)
{
    pthread_mutex_lock(&kept.lock);
    pthread_mutex_lock(&temps.lock);
}

static void caches_after_fork(void)
{
    pthread_mutex_unlock(&temps.lock);
    pthread_mutex_unlock(&kept.lock);
}

static pthread_once_t caches_fork_once = PTHREAD_ONCE_INIT;

static void caches_fork_register(void) { pthread_atfork(caches_before_fork, caches_after_fork, caches_after_fork); }

static void caches_fork_init(void) { pthread_once(&caches_fork_once, caches_fork_register); }

size_t as_release_cached_memory(void)
{
    void *drop[AS_BLOCKS_KEPT];
    pthread_mutex_lock(&kept.lock);
    const unsigned nd = kept.n;
    const size_t freed = kept.total;
    for (unsigned i = 0; i < nd; ++i) drop[i] = kept.e[i].p;
    kept.n = 0;
    kept.total = 0;
    pthread_mutex_unlock(&kept.lock);
    for (unsigned i = 0; i < nd; ++i) free(drop[i]);
    pthread_mutex_lock(&temps.lock);
    void *head[AS_TEMP_CLASSES];
    memcpy(head, temps.head, sizeof head);
    memset(temps.head, 0, sizeof temps.head);
    const size_t temp_bytes = temps.total;
    temps.total = 0;
    pthread_mutex_unlock(&temps.lock);
    for (unsigned k = 0; k < AS_TEMP_CLASSES; ++k)
        while (head[k]) {
            void *next = *(void **)((unsigned char *)head[k] + AS_TEMP_HEADER);
            free(head[k]);
            head[k] = next;
        }
    return freed + temp_bytes;
}

typedef struct sah_sum_job {
    const double *terms;
    uint64_t count;
    double *block;
} sah_sum_job;

static void sah_sum_block(void *user, size_t j)
{
    const sah_sum_job *job = user;
    const uint64_t first = (uint64_t)j * AS_SAH_SUM_BLOCK;
    const uint64_t end = job->count - first < AS_SAH_SUM_BLOCK ? job->count : first + AS_SAH_SUM_BLOCK;
    double b = 0.0;
    for (uint64_t i = first; i < end; ++i) b += job->terms[i];
    job->block[j] = b;
}

as_sah_sum as_sah_sum_terms(const double *terms, uint64_t count, unsigned threads)
{
    as_sah_sum sum = {0.0, 0.0, 0};
    const uint64_t blocks = (count + AS_SAH_SUM_BLOCK - 1) / AS_SAH_SUM_BLOCK;
    double *block = malloc(sizeof(double) * (size_t)(blocks ? blocks : 1));
    if (!block) {
        for (uint64_t i = 0; i < count; ++i) as_sah_sum_add(&sum, terms[i]);
        return sum;
    }
    sah_sum_job job = {terms, count, block};
    as_parallel_for(threads, (size_t)blocks, sah_sum_block, &job);
    for (uint64_t j = 0; j < blocks; ++j) sum.total += block[j];
    sum.count = count;
    free(block);
    return sum;
}

void *as_aligned_alloc(size_t bytes, const char *what)
{
    if (bytes >= AS_BLOCK_MIN_BYTES) return as_block_take(bytes, 1, what);
    const size_t rounded = (bytes + 63) / 64 * 64;
    void *p = aligned_alloc(64, rounded ? rounded : 64);
    if (!p) as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory allocating %zu bytes for %s", bytes, what);
    return p;
}

void as_structure_add_section(as_structure_t *s, uint32_t tag, void *data, uint64_t count,
                              uint32_t stride)
{
    as_section_t *sec = &s->sections[s->section_count++];
    memset(sec, 0, sizeof *sec);
    sec->tag = tag;
    sec->flags = ASF_SECTION_REQUIRED;
    sec->data = data;
    sec->owned = data;
    sec->count = count;
    sec->stride = stride;
    sec->bytes = count * stride;
    sec->file_index = -1;
}

void as_structure_add_kept_section(as_structure_t *s, uint32_t tag, void *data, uint64_t count, uint32_t stride,
                                   size_t alloc_bytes)
{
    as_structure_add_section(s, tag, data, count, stride);
    s->sections[s->section_count - 1].give_bytes = alloc_bytes;
}

const as_section_t *as_structure_find(const as_structure_t *s, uint32_t tag)
{
    for (uint32_t i = 0; i < s->section_count; ++i)
        if (s->sections[i].tag == tag) return &s->sections[i];
    return NULL;
}

void as_build_args_default(as_build_args_t *args)
{
    memset(args, 0, sizeof *args);
    args->size = sizeof *args;
    args->structure = AS_STRUCT_BVH;
    args->builder = AS_BUILDER_DEFAULT;
    args->max_leaf_size = 4;
    args->bin_count = 32;
    /* Aila & Laine's GPU measurements put a node visit at about the cost of
     * one triangle test with the child-bounds layout. */
    args->cost_traversal = 1.0f;
    args->cost_intersection = 1.0f;
    args->grid_lambda = 4.0f;
    args->split_budget = 4.0f;
    args->sbvh_alpha = 1e-5f;
}

void as_save_args_default(as_save_args_t *args)
{
    memset(args, 0, sizeof *args);
    args->size = sizeof *args;
}

void as_load_args_default(as_load_args_t *args)
{
    memset(args, 0, sizeof *args);
    args->size = sizeof *args;
    args->verify_checksums = true;
}

/* Copies the fields a caller's (possibly older, smaller) struct has over the
 * defaults. */
#define AS_ARGS_FROM_CALLER(type, dst, src, defaults_fn) do { \
    defaults_fn(&(dst)); \
    if (src) { \
        const size_t _n = (src)->size < sizeof(type) ? (src)->size : sizeof(type); \
        memcpy(&(dst), (src), _n); \
        (dst).size = sizeof(type); \
    } } while (0)

/* Every builder of this version. */
typedef struct as_builder_entry {
    uint32_t structure_kind;
    uint32_t builder;
    uint32_t default_layout;
    const char *name;            /* short name, unique within the kind */
    as_error_t (*build)(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s);
} as_builder_entry_t;

static const as_builder_entry_t builders[] = {
    {AS_STRUCT_BVH, AS_BUILDER_BVH_SAH_BINNED, AS_LAYOUT_BVH2_CHILD_BOUNDS, "sah", as_bvh_build_sah},
    {AS_STRUCT_BVH, AS_BUILDER_BVH_MIDCUT, AS_LAYOUT_BVH2_CHILD_BOUNDS, "midcut", as_bvh_build_midcut},
    {AS_STRUCT_BVH, AS_BUILDER_BVH_SAH_SWEEP, AS_LAYOUT_BVH2_CHILD_BOUNDS, "sweep", as_bvh_build_sweep},
    {AS_STRUCT_BVH, AS_BUILDER_BVH_SBVH, AS_LAYOUT_BVH2_CHILD_BOUNDS, "sbvh", as_bvh_build_sbvh},
    {AS_STRUCT_KD, AS_BUILDER_KD_SAH, AS_LAYOUT_KD_STANDARD, "sah", as_kd_build_sah},
    {AS_STRUCT_KD, AS_BUILDER_KD_MIDCUT, AS_LAYOUT_KD_STANDARD, "midcut", as_kd_build_midcut},
    {AS_STRUCT_BIH, AS_BUILDER_BIH, AS_LAYOUT_BIH, "bih", as_bih_build},
    {AS_STRUCT_OCTREE, AS_BUILDER_OCTREE, AS_LAYOUT_OCTREE, "octree", as_octree_build},
    {AS_STRUCT_GRID, AS_BUILDER_GRID, AS_LAYOUT_GRID, "grid", as_grid_build},
};

/* The kind's first builder stands for AS_BUILDER_DEFAULT. */
static const as_builder_entry_t *find_builder(uint32_t kind, uint32_t builder)
{
    for (size_t i = 0; i < sizeof builders / sizeof builders[0]; ++i)
        if (builders[i].structure_kind == kind && (builder == AS_BUILDER_DEFAULT || builders[i].builder == builder))
            return &builders[i];
    return NULL;
}

static const struct { uint32_t value; const char *name; } kind_names[] = {
    {AS_STRUCT_BVH, "bvh"}, {AS_STRUCT_KD, "kd"}, {AS_STRUCT_BIH, "bih"},
    {AS_STRUCT_OCTREE, "octree"}, {AS_STRUCT_GRID, "grid"},
}, layout_names[] = {
    {AS_LAYOUT_BVH2_CHILD_BOUNDS, "bvh2-child-bounds"}, {AS_LAYOUT_BVH2_OWN_BOUNDS, "bvh2-own-bounds"},
    {AS_LAYOUT_BVH_CWBVH, "cwbvh"},
    {AS_LAYOUT_KD_STANDARD, "kd-standard"}, {AS_LAYOUT_KD_ROPES, "kd-ropes"}, {AS_LAYOUT_BIH, "bih"},
    {AS_LAYOUT_OCTREE, "octree"}, {AS_LAYOUT_GRID, "grid"},
}, builder_names[] = {
    {AS_BUILDER_BVH_SAH_BINNED, "sah"}, {AS_BUILDER_BVH_SAH_SWEEP, "sweep"}, {AS_BUILDER_BVH_MIDCUT, "midcut"},
    {AS_BUILDER_BVH_SBVH, "sbvh"}, {AS_BUILDER_KD_MIDCUT, "midcut"}, {AS_BUILDER_KD_SAH, "sah"},
    {AS_BUILDER_BIH, "bih"}, {AS_BUILDER_OCTREE, "octree"}, {AS_BUILDER_GRID, "grid"},
};

#define NAME_OF(table, v) do { \
    for (size_t _i = 0; _i < sizeof table / sizeof table[0]; ++_i) \
        if (table[_i].value == (uint32_t)(v)) return table[_i].name; \
    return NULL; } while (0)
#define VALUE_OF(table, n) do { \
    for (size_t _i = 0; n && _i < sizeof table / sizeof table[0]; ++_i) \
        if (strcmp(table[_i].name, n) == 0) return table[_i].value; \
    return 0; } while (0)

const char *as_structure_kind_name(as_structure_kind_t kind) { NAME_OF(kind_names, kind); }
const char *as_layout_name(as_layout_t layout) { NAME_OF(layout_names, layout); }
const char *as_builder_name(as_builder_t builder) { NAME_OF(builder_names, builder); }
as_structure_kind_t as_structure_kind_from_name(const char *name) { VALUE_OF(kind_names, name); }
as_layout_t as_layout_from_name(const char *name) { VALUE_OF(layout_names, name); }

as_builder_t as_builder_from_name(as_structure_kind_t kind, const char *name)
{
    for (size_t i = 0; name && i < sizeof builder_names / sizeof builder_names[0]; ++i)
        if ((builder_names[i].value >> 8) == ((uint32_t)kind >> 8) && strcmp(builder_names[i].name, name) == 0)
            return (as_builder_t)builder_names[i].value;
    return AS_BUILDER_DEFAULT;
}

as_structure_t *as_structure_build(const as_mesh_t *mesh, const as_build_args_t *user_args)
{
    if (!mesh) {
        as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_structure_build: mesh is NULL");
        return NULL;
    }
    as_build_args_t args;
    AS_ARGS_FROM_CALLER(as_build_args_t, args, user_args, as_build_args_default);
    as_structure_t *s = as_calloc(1, sizeof *s, "structure");
    if (!s) return NULL;
    as_error_t err;
    const as_builder_entry_t *b = find_builder(args.structure, args.builder);
    if (!b) {
        err = as_set_error(AS_ERROR_UNSUPPORTED, "no builder 0x%04x for structure kind 0x%04x (%s) in this version",
                           (unsigned)args.builder, (unsigned)args.structure,
                           as_structure_kind_name(args.structure) ? as_structure_kind_name(args.structure) : "unknown");
    } else {
        if (args.layout == AS_LAYOUT_DEFAULT) args.layout = (as_layout_t)b->default_layout;
        if (args.structure == AS_STRUCT_BVH && args.layout == AS_LAYOUT_BVH_CWBVH)
            err = as_cwbvh_build(mesh, &args, b->build, s);
        else
            err = b->build(mesh, &args, s);
        if (err == AS_OK) {
            memset(&s->record, 0, sizeof s->record);
            s->record.build_ms = s->build_ms;
            s->record.thread_count = as_thread_count(args.thread_count);
            s->record.core_count = as_thread_count(0);
            s->has_record = 1;
        }
    }
    if (err != AS_OK) {
        as_structure_release(s);
        return NULL;
    }
    return s;
}

void as_structure_release(as_structure_t *s)
{
    if (!s) return;
#ifdef AS_HAVE_CUDA
    as_gpu_release(s->gpu);
#endif
    for (uint32_t i = 0; i < s->section_count; ++i) {
        as_section_t *sec = &s->sections[i];
        if (sec->give_bytes) as_block_give(sec->owned, sec->give_bytes, 1);
        else free(sec->owned);
    }
    asf_close(s->file);
    free(s);
}

as_error_t as_structure_save(const as_structure_t *s, const char *path, const as_save_args_t *user_args)
{
    if (!s || !path) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_structure_save: NULL argument");
    as_save_args_t args;
    AS_ARGS_FROM_CALLER(as_save_args_t, args, user_args, as_save_args_default);
    if (args.compression_level < 0 || args.compression_level > 22)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "compression level %d is outside 0..22", args.compression_level);
    asf_section_desc_t desc[AS_MAX_SECTIONS + 2];
    uint32_t n = 0;
    desc[n++] = (asf_section_desc_t){ASF_TAG_META, ASF_SECTION_REQUIRED, &s->meta, sizeof s->meta, 1,
                                     sizeof s->meta, args.compression_level};
    for (uint32_t i = 0; i < s->section_count; ++i) {
        const as_section_t *sec = &s->sections[i];
        desc[n++] = (asf_section_desc_t){sec->tag, sec->flags & ASF_SECTION_REQUIRED, sec->data, sec->bytes,
                                         sec->count, sec->stride, args.compression_level};
    }
    if (s->has_record && !args.omit_build_record)
        desc[n++] = (asf_section_desc_t){ASF_TAG_BREC, 0, &s->record, sizeof s->record, 1, sizeof s->record,
                                         args.compression_level};
    return asf_write(path, desc, n);
}

static const as_layout_ops_t *const layouts[] = {
    &as_layout_bvh2_child_bounds,
    &as_layout_bvh2_own_bounds,
    &as_layout_cwbvh,
    &as_layout_kd_standard,
    &as_layout_kd_ropes,
    &as_layout_bih,
    &as_layout_octree,
    &as_layout_grid,
};

const as_layout_ops_t *as_layout_find(uint32_t structure_kind, uint32_t layout)
{
    for (size_t i = 0; i < sizeof layouts / sizeof layouts[0]; ++i)
        if (layouts[i]->structure_kind == structure_kind && layouts[i]->layout == layout) return layouts[i];
    return NULL;
}

const as_layout_ops_t *as_structure_ops(const as_structure_t *s)
{
    return as_layout_find(s->meta.structure_kind, s->meta.layout);
}

/* Every section tag some layout of this build reads: the container refuses
 * unknown required sections and skips unknown optional ones. */
static uint32_t known_tags(uint32_t *tags, uint32_t capacity)
{
    uint32_t n = 0;
    tags[n++] = ASF_TAG_META;
    tags[n++] = ASF_TAG_BREC;
    for (size_t i = 0; i < sizeof layouts / sizeof layouts[0]; ++i)
        for (uint32_t k = 0; k < layouts[i]->section_count && n < capacity; ++k) tags[n++] = layouts[i]->sections[k].tag;
    return n;
}

/* The optional build record: absent is fine, damaged is not. */
static as_error_t adopt_build_record(as_structure_t *s, const char *name)
{
    const int i = asf_find_section(s->file, ASF_TAG_BREC);
    if (i < 0) return AS_OK;
    const asf_section_entry_t *e = asf_section_entry(s->file, (uint32_t)i);
    if (e->raw_size != sizeof(as_build_record_t) || e->element_count != 1)
        return as_set_error(AS_ERROR_CORRUPT, "%s: BREC section (offset %llu) is %llu bytes in %llu elements, expected "
                            "one of %zu", name, (unsigned long long)e->offset, (unsigned long long)e->raw_size,
                            (unsigned long long)e->element_count, sizeof(as_build_record_t));
    as_build_record_t r;
    memcpy(&r, asf_section_data(s->file, (uint32_t)i), sizeof r);
    if (!(r.build_ms >= 0.0) || !isfinite(r.build_ms) || r.reserved[0] || r.reserved[1])
        return as_set_error(AS_ERROR_CORRUPT, "%s: BREC section (offset %llu): build time %g ms is not a finite "
                            "non-negative number, or reserved fields are set", name, (unsigned long long)e->offset,
                            r.build_ms);
    s->record = r;
    s->has_record = 1;
    return AS_OK;
}

/* Checks that the sections a kind needs are there with the right strides,
 * and takes them from the file. */
static as_error_t adopt_sections(as_structure_t *s, const char *name)
{
    asf_file_t *f = s->file;
    const int mi = asf_find_section(f, ASF_TAG_META);
    if (mi < 0) return as_set_error(AS_ERROR_CORRUPT, "%s: no META section", name);
    const asf_section_entry_t *me = asf_section_entry(f, (uint32_t)mi);
    if (me->raw_size != sizeof(as_meta_t))
        return as_set_error(AS_ERROR_CORRUPT, "%s: META section (offset %llu) is %llu bytes, expected %zu", name,
                            (unsigned long long)me->offset, (unsigned long long)me->raw_size, sizeof(as_meta_t));
    memcpy(&s->meta, asf_section_data(f, (uint32_t)mi), sizeof s->meta);
    int reserved_set = s->meta.reserved0 != 0 || s->meta.reserved1 != 0;
    for (size_t i = 0; i < sizeof s->meta.reserved; ++i) reserved_set |= s->meta.reserved[i] != 0;
    if (reserved_set)
        return as_set_error(AS_ERROR_CORRUPT, "%s: META section (offset %llu) has non-zero reserved fields", name,
                            (unsigned long long)me->offset);
    if (memchr(s->meta.writer, '\0', sizeof s->meta.writer) == NULL)
        return as_set_error(AS_ERROR_CORRUPT, "%s: META writer name is not NUL-terminated", name);
    const as_layout_ops_t *ops = as_layout_find(s->meta.structure_kind, s->meta.layout);
    if (!ops) {
        int kind_known = 0;
        for (size_t i = 0; i < sizeof layouts / sizeof layouts[0]; ++i)
            kind_known |= layouts[i]->structure_kind == s->meta.structure_kind;
        if (!kind_known)
            return as_set_error(AS_ERROR_UNSUPPORTED, "%s: structure kind 0x%04x cannot be traced by this build (libas %s)",
                                name, s->meta.structure_kind, AS_VERSION_STRING);
        return as_set_error(AS_ERROR_UNSUPPORTED, "%s: layout 0x%04x cannot be traced by this build (structure kind 0x%04x, libas %s)",
                            name, s->meta.layout, s->meta.structure_kind, AS_VERSION_STRING);
    }
    if (s->meta.layout_version > ops->layout_version)
        return as_set_error(AS_ERROR_VERSION, "%s: %s layout version %u is newer than this build reads (%u)", name,
                            ops->layout_name, s->meta.layout_version, ops->layout_version);
    for (uint32_t k = 0; k < ops->section_count; ++k) {
        const as_layout_section_t *need = &ops->sections[k];
        char tag[5];
        memcpy(tag, &need->tag, 4);
        tag[4] = '\0';
        const int i = asf_find_section(f, need->tag);
        if (i < 0)
            return as_set_error(AS_ERROR_CORRUPT, "%s: the %s layout needs a %s section and the file has none", name,
                                ops->layout_name, tag);
        const asf_section_entry_t *e = asf_section_entry(f, (uint32_t)i);
        if (e->stride != need->stride)
            return as_set_error(AS_ERROR_CORRUPT, "%s: section %s (offset %llu) has stride %u, expected %u", name, tag,
                                (unsigned long long)e->offset, e->stride, need->stride);
        as_section_t *sec = &s->sections[s->section_count++];
        memset(sec, 0, sizeof *sec);
        sec->tag = e->tag;
        sec->flags = e->flags;
        sec->data = asf_section_data(f, (uint32_t)i);
        sec->bytes = e->raw_size;
        sec->count = e->element_count;
        sec->stride = e->stride;
        sec->file_index = i;
    }
    return adopt_build_record(s, name);
}

static as_structure_t *finish_load(asf_file_t *f, const char *name)
{
    if (!f) return NULL;
    as_structure_t *s = as_calloc(1, sizeof *s, "structure");
    if (!s) { asf_close(f); return NULL; }
    s->file = f;
    if (adopt_sections(s, name) != AS_OK) {
        as_structure_release(s);
        return NULL;
    }
    return s;
}

as_structure_t *as_structure_load(const char *path, const as_load_args_t *user_args)
{
    if (!path) { as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_structure_load: path is NULL"); return NULL; }
    as_load_args_t args;
    AS_ARGS_FROM_CALLER(as_load_args_t, args, user_args, as_load_args_default);
    uint32_t tags[1 + AS_LAYOUT_MAX_SECTIONS * 8];
    const asf_open_args_t oa = {args.verify_checksums, tags, known_tags(tags, sizeof tags / sizeof tags[0])};
    return finish_load(asf_open(path, &oa), path);
}

as_structure_t *as_structure_load_memory(const void *data, size_t size, const char *name,
                                         const as_load_args_t *user_args)
{
    if (!name) name = "(memory)";
    as_load_args_t args;
    AS_ARGS_FROM_CALLER(as_load_args_t, args, user_args, as_load_args_default);
    uint32_t tags[1 + AS_LAYOUT_MAX_SECTIONS * 8];
    const asf_open_args_t oa = {args.verify_checksums, tags, known_tags(tags, sizeof tags / sizeof tags[0])};
    return finish_load(asf_open_memory(data, size, name, &oa), name);
}

as_structure_t *as_structure_convert(const as_structure_t *s, as_layout_t layout)
{
    if (!s) {
        as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_structure_convert: NULL structure");
        return NULL;
    }
    const as_layout_ops_t *from = as_structure_ops(s);
    const as_layout_ops_t *to = as_layout_find(s->meta.structure_kind, layout);
    if (!to || !from->convert) {
        as_set_error(AS_ERROR_UNSUPPORTED, "no conversion from layout %s to %s", from->layout_name,
                     as_layout_name(layout) ? as_layout_name(layout) : "(unknown)");
        return NULL;
    }
    if (as_structure_validate(s) != AS_OK) return NULL;
    as_structure_t *d = as_calloc(1, sizeof *d, "structure");
    if (!d) return NULL;
    if (from->convert(s, layout, d) != AS_OK) {
        as_structure_release(d);
        return NULL;
    }
    /* The tree is the one that build made: its record goes along. */
    d->record = s->record;
    d->has_record = s->has_record;
    return d;
}

as_error_t as_structure_validate(const as_structure_t *s)
{
    if (!s) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_structure_validate: NULL structure");
    return as_structure_ops(s)->validate(s, s->file ? asf_name(s->file) : "(built structure)");
}

as_error_t as_structure_check_valid(const as_structure_t *s)
{
    if (s && atomic_load(&s->validated)) return AS_OK;
    return as_structure_validate(s);
}

/* What META and the build record say; no walk. */
static void stats_from_header(const as_structure_t *s, as_structure_stats_t *st)
{
    memset(st, 0, sizeof *st);
    st->structure = (as_structure_kind_t)s->meta.structure_kind;
    st->layout = (as_layout_t)s->meta.layout;
    st->layout_version = s->meta.layout_version;
    st->builder = (as_builder_t)s->meta.builder;
    st->max_leaf_size = s->meta.max_leaf_size;
    st->bin_count = s->meta.bin_count;
    st->cost_traversal = s->meta.cost_traversal;
    st->cost_intersection = s->meta.cost_intersection;
    st->triangle_count = s->meta.triangle_count;
    if (s->has_record) {
        st->build_ms = s->record.build_ms;
        st->build_threads = s->record.thread_count;
        st->build_cores = s->record.core_count;
    }
    st->source_hash = s->meta.source_hash;
    memcpy(st->bounds_lo, s->meta.bounds_lo, sizeof st->bounds_lo);
    memcpy(st->bounds_hi, s->meta.bounds_hi, sizeof st->bounds_hi);
    memcpy(st->writer, s->meta.writer, sizeof st->writer);
    st->writer_version = s->meta.writer_version;
    st->structure_bytes = sizeof(as_meta_t);
    for (uint32_t i = 0; i < s->section_count; ++i) st->structure_bytes += s->sections[i].bytes;
    st->empty_leaf_count = s->meta.empty_leaf_count;
    st->reference_count = s->meta.reference_count;
}

as_error_t as_structure_get_header_stats(const as_structure_t *s, as_structure_stats_t *st)
{
    if (!s || !st) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_structure_get_header_stats: NULL argument");
    stats_from_header(s, st);
    return AS_OK;
}

as_error_t as_structure_get_stats(const as_structure_t *s, as_structure_stats_t *st)
{
    if (!s || !st) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_structure_get_stats: NULL argument");
    memset(st, 0, sizeof *st);
    /* The walk below follows child indices: only a valid tree may be walked. */
    const as_error_t err = as_structure_check_valid(s);
    if (err != AS_OK) return err;
    stats_from_header(s, st);
    as_structure_ops(s)->stats(s, st);
    st->average_leaf_size = st->leaf_count ? (double)st->reference_count / (double)st->leaf_count : 0.0;
    return AS_OK;
}

const struct as_tri4 **as_structure_triangles_by_prim(const as_structure_t *s)
{
    const uint32_t n = s->meta.triangle_count;
    const as_tri4_t **map = as_calloc(n ? n : 1, sizeof *map, "triangle index");
    if (!map) return NULL;
    const as_section_t *sec = as_structure_find(s, ASF_TAG('T', 'R', 'I', 'S'));
    if (!sec) sec = as_structure_find(s, ASF_TAG_TRI4);
    if (!sec) return map;
    const as_tri4_t *t = sec->data;
    for (uint64_t i = 0; i < sec->count; ++i) {
        const uint32_t prim = as_float_as_uint(t[i].v0.w);
        if (prim < n && !map[prim]) map[prim] = &t[i];
    }
    return map;
}

static const char *section_purpose(const as_structure_t *s, uint32_t tag)
{
    if (tag == ASF_TAG_META) return "writer, structure kind, layout and build parameters";
    if (tag == ASF_TAG_BREC) return "build time and threads, as the builder recorded them (optional)";
    if (tag == ASF_TAG_CSUM) return "checksums of 1 MiB chunks of the other sections, verified on every core (optional)";
    const as_layout_ops_t *ops = as_structure_ops(s);
    for (uint32_t i = 0; i < ops->section_count; ++i)
        if (ops->sections[i].tag == tag) return ops->sections[i].purpose;
    return "unknown to this version (optional, skipped)";
}

uint32_t as_structure_section_count(const as_structure_t *s)
{
    if (!s) return 0;
    return s->file ? asf_section_count(s->file) : s->section_count + 1;
}

as_error_t as_structure_section_info(const as_structure_t *s, uint32_t index, as_section_info_t *info)
{
    if (!s || !info) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_structure_section_info: NULL argument");
    if (index >= as_structure_section_count(s))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "section index %u out of range", index);
    memset(info, 0, sizeof *info);
    uint32_t tag;
    if (s->file) {
        const asf_section_entry_t *e = asf_section_entry(s->file, index);
        tag = e->tag;
        info->required = (e->flags & ASF_SECTION_REQUIRED) != 0;
        info->compressed = (e->flags & ASF_SECTION_ZSTD) != 0;
        info->checksum_status = asf_section_checksum_verified(s->file, index) ? 1 : 0;
        info->offset = e->offset;
        info->stored_bytes = e->stored_size;
        info->raw_bytes = e->raw_size;
        info->element_count = e->element_count;
        info->stride = e->stride;
        info->checksum = e->checksum;
    } else if (index == 0) {
        tag = ASF_TAG_META;
        info->required = true;
        info->stored_bytes = info->raw_bytes = sizeof s->meta;
        info->element_count = 1;
        info->stride = sizeof s->meta;
        info->checksum = as_hash64(&s->meta, sizeof s->meta);
    } else {
        const as_section_t *sec = &s->sections[index - 1];
        tag = sec->tag;
        info->required = (sec->flags & ASF_SECTION_REQUIRED) != 0;
        info->stored_bytes = info->raw_bytes = sec->bytes;
        info->element_count = sec->count;
        info->stride = sec->stride;
        info->checksum = as_hash64(sec->data, sec->bytes);
    }
    memcpy(info->tag, &tag, 4);
    info->tag[4] = '\0';
    info->purpose = section_purpose(s, tag);
    return AS_OK;
}
