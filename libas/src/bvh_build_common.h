/* What every BVH builder shares: primitive references, the temporary tree,
 * progress and cancellation, subtrees on the task pool, and the final depth-first walk
 * that writes the BVH2 child-bounds layout (and, when asked, converts it to
 * the own-bounds layout). Each builder only decides how a node splits. */
#ifndef AS_BVH_BUILD_COMMON_H
#define AS_BVH_BUILD_COMMON_H

#include "structure.h"
#include "mesh.h"
#include "bvh2_layout.h"
#include "simd4.h"
#include "partition_bits.h"
#include "task_pool.h"

#include <pthread.h>
#include <stdatomic.h>

/* Subtrees larger than this may be built on another thread. */
#define BVH_PARALLEL_MIN_PRIMS 4096
/* The in-place builders (binned SAH, mid-cut) share right children down to
 * this size: a thread that runs out of work waits until the other's
 * subtree is done, and at 4,096 that wait (up to a 4,096-reference
 * subtree's build) was a tenth of a 2-thread build of staircase2's 30,927
 * triangles. At 1,024, 16 threads still spent the last fifth of a bunny
 * build waiting on a few such subtrees; at 256 the build took 0.93 of the
 * time (staircase2 0.91), the same on 2 cores. A shared subtree costs a
 * lock, and a wake-up only where no thread is watching for work. */
#define BVH_SHARE_MIN_PRIMS 256
#define BVH_MAX_BINS 256

/* 32 bytes: a triangle's (possibly clipped, SBVH) box and its source index. */
typedef struct bvh_ref {
    float lo[3];
    uint32_t id;
    float hi[3];
    float pad;
} bvh_ref;

/* A reference's hi corner as four lanes, the fourth its pad: every
 * reference is made with pad 0 (bvh_builder_init) and copied whole since,
 * so the lane is +0 and the load needs no mask, unlike lo's, whose fourth
 * lane is the index and would be a denormal in arithmetic. */
static inline v4f bvh_ref_load_hi(const float *hi)
{
#if defined(__SSE2__)
    return v4f_load(hi); /* 16 bytes from hi: hi[3] and pad */
#else
    return v4f_load3(hi);
#endif
}

typedef struct bvh_box {
    float lo[3], hi[3];
} bvh_box;

/* A node of the temporary tree, 48 bytes, read and written only on the
 * CPU. A leaf points at its references: a range of the builder's array
 * (in-place builders) or an array of its own (SBVH). An inner node carries
 * its subtree's size once the thread that built the subtree has finished it
 * (bvh_node_complete; bvh_builder_finish completes the rest), so that the
 * output walk knows where each subtree's nodes and triangles go before it
 * writes them, and can write subtrees on several threads. */
typedef struct bvh_tmp_node {
    bvh_box box;
    int32_t left, right;   /* tmp indices; -1 for a leaf */
    uint32_t count;        /* leaf: its references; inner: its subtree's leaves' references */
    uint32_t inner;        /* leaf: 0; inner: inner nodes of its subtree (itself included), 0 while not known */
    const bvh_ref *refs;   /* leaf references, NULL when count is 0; NULL for an inner node */
} bvh_tmp_node;
_Static_assert(sizeof(bvh_tmp_node) == 48, "bvh_tmp_node is 48 bytes");
_Static_assert(sizeof(bvh_ref) == AS_PARTITION_ITEM_BYTES, "references are partitioned as 32-byte items");

typedef struct bvh_builder {
    const as_build_args_t *args;
    const as_mesh_t *mesh;
    bvh_ref *refs;            /* one per non-degenerate triangle, source order */
    uint32_t ref_count;
    bvh_box root_box;
    bvh_box root_cbox;        /* of lo + hi (see bvh_refs_centroid2_box) */
    unsigned root_threads;    /* threads that may split the root together */
    bvh_tmp_node *nodes;      /* node_capacity; both arrays from as_block_take, given back by bvh_builder_free */
    atomic_uint_fast64_t node_next;
    uint64_t node_capacity;
    int max_threads;
    atomic_uint_fast64_t prims_done;
    uint64_t prim_total;
    atomic_int cancelled;
    pthread_mutex_t progress_lock;
    double next_report;
    uint32_t depth_limit;     /* a node at depth + 1 >= depth_limit is a leaf */
    atomic_uint_fast64_t inner_count;  /* splits, summed by bvh_local_flush */
    atomic_uint tasks_shared;          /* bvh_share_task's pushes */
    uint32_t exact_max;       /* in-place builders: subtrees up to this size go to bvh_build_exact_subtree; 0: none */
    /* Binned SAH: each reference's bin on every axis, a byte per axis
     * (bvh_find_object_split's bins_out), by position in refs: written by
     * a node's binning and read by its partition (ref_count entries, from
     * as_block_take; NULL for the other builders). */
    uint32_t *ref_bins;
} bvh_builder;

/* Tmp nodes are taken from the shared array in chunks of this many per
 * task, and at most BVH_MAX_SHARED_TASKS tasks are shared, so the array
 * needs BVH_NODE_SLACK nodes beyond the tree's for the chunks' unused
 * tails. */
#define BVH_NODE_CHUNK 64
#define BVH_MAX_SHARED_TASKS 1024
#define BVH_NODE_SLACK ((uint64_t)(BVH_MAX_SHARED_TASKS + 2) * BVH_NODE_CHUNK)

/* What one task (a subtree on one thread) allocates and counts on its own:
 * a chunk of tmp nodes and the references and splits it has not yet added
 * to the builder's shared counters. With a shared counter per node and per
 * leaf, two threads spent their time passing its cache line back and forth
 * (and writing neighbouring nodes of one cache line). */
typedef struct bvh_local {
    bvh_builder *b;
    uint64_t next, end;   /* the chunk: node indices [next, end) */
    uint64_t prims;       /* leaf references not yet reported */
    uint64_t splits;      /* inner nodes not yet counted */
} bvh_local;

static inline void bvh_local_init(bvh_local *l, bvh_builder *b)
{
    l->b = b;
    l->next = l->end = 0;
    l->prims = l->splits = 0;
}
/* Two fresh tmp nodes (*left, *right) for one split; 0 when the capacity
 * is exhausted. */
int bvh_local_pair(bvh_local *l, int32_t *left, int32_t *right);
/* As bvh_make_leaf, counting the references locally. */
void bvh_local_leaf(bvh_local *l, int32_t node, const bvh_ref *refs, uint32_t count);
/* Adds the local counts to the builder's and marks the chunk's unused
 * nodes as empty leaves (so that a scan of the array meets no garbage). */
void bvh_local_flush(bvh_local *l);
/* Pushes a task to the pool if a thread is hungry and the shared-task cap
 * allows; 0 when the caller must run it itself. */
struct as_task_pool;
int bvh_share_task(bvh_builder *b, struct as_task_pool *pool, const void *task);

/* When a thread of the pool waits for work, shares the oldest entry
 * (task_pool.h) within the shared-task cap. */
void bvh_pending_offer(bvh_builder *b, struct as_task_pool *pool, as_pending_stack *s);
/* How many threads may split a node of `count` references together: 1
 * below BVH_SPLIT_MT_MIN_PRIMS, where threads would cost more than they
 * save, else every build thread. Inside the builders' pool that asks for no
 * thread of its own: the node's steps (as_parallel_run) are taken in pieces
 * by the thread that splits it and by whichever of the pool's threads are
 * idle meanwhile, such as the one done with the small side of a lopsided
 * split (bmw-m6's first SBVH splits leave 733,338 and 608,590 of 792,582
 * references on one side; staircase's binned root 260,094 of 262,508). */
unsigned bvh_split_threads(const bvh_builder *b, uint32_t count);
/* A node's references in pieces that the threads of a split take in turn
 * from a shared counter, so that a helper thread which gets no core (its
 * build thread's partner is busy with a task of its own) delays nothing: the
 * others take its pieces. About 8 per thread, of at least 4,096. */
uint32_t bvh_piece_count(uint32_t count, unsigned threads);

/* Checks the arguments shared by every BVH builder, fills the references
 * (degenerate triangles left out) and allocates node_capacity_per_ref x
 * references + 3 tmp nodes. Both arrays are blocks that earlier builds gave
 * back (as_block_take) when one fits. */
as_error_t bvh_builder_init(bvh_builder *b, const as_mesh_t *mesh, const as_build_args_t *args,
                            uint64_t node_capacity_per_ref);
void bvh_builder_free(bvh_builder *b);
/* Replaces the tmp node array by one of `capacity` nodes (its contents are
 * lost); the error is set when out of memory. */
as_error_t bvh_builder_renew_nodes(bvh_builder *b, uint64_t capacity);

static inline bvh_box bvh_box_empty(void)
{
    bvh_box b = {{3.402823466e38f, 3.402823466e38f, 3.402823466e38f},
                 {-3.402823466e38f, -3.402823466e38f, -3.402823466e38f}};
    return b;
}

static inline void bvh_box_grow(bvh_box *b, const float lo[3], const float hi[3])
{
    for (int k = 0; k < 3; ++k) {
        if (lo[k] < b->lo[k]) b->lo[k] = lo[k];
        if (hi[k] > b->hi[k]) b->hi[k] = hi[k];
    }
}

/* -0 becomes +0 (x + 0 is x otherwise). Where several threads bin pieces
 * of a node, a tie between +0 and -0 in a min or max keeps the operand that
 * the merge order puts second, so a reference's box must hold no -0 for the
 * tree to be the same whatever the thread count. */
static inline void bvh_box_no_negative_zero(bvh_box *b)
{
    for (int k = 0; k < 3; ++k) {
        b->lo[k] += 0.0f;
        b->hi[k] += 0.0f;
    }
}

static inline float bvh_ref_centroid(const bvh_ref *r, int axis) { return 0.5f * (r->lo[axis] + r->hi[axis]); }

/* Half the surface area, in double: SAH only compares ratios. */
static inline double bvh_box_half_area(const bvh_box *b)
{
    const double dx = (double)b->hi[0] - b->lo[0], dy = (double)b->hi[1] - b->lo[1],
                 dz = (double)b->hi[2] - b->lo[2];
    if (dx < 0 || dy < 0 || dz < 0) return 0.0;
    return dx * dy + dy * dz + dz * dx;
}

static inline bvh_box bvh_box_from_v4f(v4f lo, v4f hi)
{
    float l[4], h[4];
    v4f_store(l, lo);
    v4f_store(h, hi);
    const bvh_box bx = {{l[0], l[1], l[2]}, {h[0], h[1], h[2]}};
    return bx;
}

/* Half the surface area in float, for comparing bins; 0 when inverted. */
static inline float v4f_box_half_area(v4f lo, v4f hi) { return v4f_half_area(lo, hi); }

bvh_box bvh_refs_box(const bvh_ref *refs, uint32_t count);
/* The box of lo + hi over the references: twice their centroids' box, the
 * space in which the binned builders bin (one add per reference, no
 * multiply). */
bvh_box bvh_refs_centroid2_box(const bvh_ref *refs, uint32_t count);

/* The best plane among one axis's bins by the SAH, sweeping only the
 * occupied bins occ[0..m) (ascending): a plane between bins without
 * anything in them splits like the plane after the last occupied bin on
 * its left, and ties keep the lower bin. enter[x] counts the references
 * whose lowest bin is x, leave[x] those whose highest bin is x (both the
 * bin's count for object bins, which hold counts in occupied bins only:
 * counts_in_occupied_only, and the others are not read). Returns 1 and
 * fills `out` only for a cost below best_cost; the left side is bins
 * [0, out->bin]. */
typedef struct bvh_bin_sweep {
    uint32_t bin;
    double cost;
    bvh_box left, right;
    uint32_t left_count, right_count;
} bvh_bin_sweep;
int bvh_sweep_bins(const v4f *lo, const v4f *hi, const uint32_t *enter, const uint32_t *leave, uint32_t nb,
                   int counts_in_occupied_only, const uint32_t *occ, uint32_t m, double best_cost, bvh_bin_sweep *out);

/* The best binned SAH object split (Wald 2007) of refs[0, count) whose
 * doubled centroid box is cb2: axis -1 when every centroid falls in one
 * bin (they coincide, or a loose frame is too wide for them); cost
 * is the sum of half-area x count of both sides, whose boxes and counts come
 * with it. Ties go to the lower axis, then bin. Only occupied bins are
 * swept, so a small node costs what its references cost, not what the bins
 * do. */
typedef struct bvh_object_split {
    int axis;
    int bin;         /* left side: bins [0, bin] */
    double cost;
    float cmin[3], scale[3];  /* per axis: bin = (lo + hi - cmin) x scale, clamped */
    uint32_t bin_count;
    float limit;              /* bin + 1 */
    bvh_box left, right;
    uint32_t left_count, right_count;
} bvh_object_split;
/* The frame cb2 need only bound the node's lo + hi loosely: a reference
 * outside it is binned into the first or last bin, which still hold the
 * exact bounds and counts of their references. When bins_out is not NULL,
 * bins_out[i] is set to refs[i]'s bin on axis k in byte k, for
 * bvh_partition_object. */
bvh_object_split bvh_find_object_split(const bvh_ref *refs, uint32_t count, const bvh_box *cb2, uint32_t bin_count,
                                       uint32_t *bins_out);
/* The same split, binned in `threads` chunks on as many threads and merged:
 * the bins, and so the split, are those of bvh_find_object_split. */
bvh_object_split bvh_find_object_split_mt(const bvh_ref *refs, uint32_t count, const bvh_box *cb2, uint32_t bin_count,
                                          unsigned threads, uint32_t *bins_out);
/* Whether r goes left: the float operations of the binning, on one axis,
 * so the partition and the bins always agree. The binning truncates
 * f = (lo + hi - cmin) x scale, clamped into [0, bins - 1], and f is never
 * NaN there (scale is finite). A negative f is bin 0 and below the limit,
 * an f at or above the bin count the last bin and above it (the last bin
 * is never a split's left side), and otherwise "bin <= s->bin" is
 * "f < s->bin + 1": one comparison either way. */
static inline int bvh_object_split_left(const bvh_ref *r, const bvh_object_split *s)
{
    const int a = s->axis;
    return ((r->lo[a] + r->hi[a]) - s->cmin[a]) * s->scale[a] < s->limit;
}

/* Small nodes are split exactly: every object partition along each axis's
 * centroid order (ties by position in refs), which costs less than setting
 * up bins and is never worse. Returns the left count, in (0, count), with
 * refs reordered along the best axis and *cost the sum of half-area x count
 * of both sides; 0 when count is outside [2, BVH_SMALL_NODE] or every
 * centroid coincides. */
/* 16 rather than 8: nodes of 9 to 16 references went through the
 * occupied-bin path, whose two passes and three sweeps cost more than the
 * exact ranks at that size (bathroom: 7% less build CPU time, SAH cost
 * within 0.01%). */
#define BVH_SMALL_NODE 16
uint32_t bvh_find_small_split(bvh_ref *refs, uint32_t count, double *cost);

/* Adds finished primitives to the progress and calls the callback (at most
 * every 1%); a false return sets b->cancelled. */
void bvh_report_progress(bvh_builder *b, uint64_t prims);
/* A fresh tmp node index, or -1 when the capacity is exhausted. */
int32_t bvh_new_node(bvh_builder *b);
void bvh_make_leaf(bvh_builder *b, int32_t node, const bvh_ref *refs, uint32_t count);
/* Makes `node` inner with children left and right, its subtree size not yet
 * known. */
static inline void bvh_make_inner(bvh_builder *b, int32_t node, int32_t left, int32_t right)
{
    bvh_tmp_node *n = &b->nodes[node];
    n->left = left;
    n->right = right;
    n->count = 0;
    n->inner = 0;
    n->refs = NULL;
}
/* Sets an inner node's subtree size from its children's, once the calling
 * thread has built both children's subtrees itself. When another task took
 * one of them (child_shared), the size stays unknown: the node is not read,
 * since that task may still be writing it. */
static inline void bvh_node_complete(bvh_builder *b, int32_t node, int child_shared)
{
    bvh_tmp_node *n = &b->nodes[node];
    if (child_shared) return;
    const bvh_tmp_node *l = &b->nodes[n->left], *r = &b->nodes[n->right];
    if ((l->left >= 0 && !l->inner) || (r->left >= 0 && !r->inner)) return;
    n->inner = 1 + l->inner + r->inner;
    n->count = l->count + r->count;
}

/* A range of the builder's reference array with its bounds. */
typedef struct bvh_range {
    uint32_t first, count;
    bvh_box box;   /* of the references */
    bvh_box cbox;  /* a frame that holds its references' lo + hi: exact for the root and where
                    * bvh_range_bound set it, loose below a binned split (split_frames) */
} bvh_range;
/* Sets r's box and cbox from its references. */
void bvh_range_bound(const bvh_builder *b, bvh_range *r);

/* Partitions node's references in place by an object split found with
 * bins_out = b->ref_bins + node->first, filling both sides with their
 * boxes and with frames for their binning (split_frames in
 * bvh_build_common.c); returns the first index of the right side. */
uint32_t bvh_partition_object(bvh_builder *b, const bvh_range *node, const bvh_object_split *s, bvh_range *left,
                              bvh_range *right);
/* The same permutation on `threads` threads. */
uint32_t bvh_partition_object_mt(bvh_builder *b, const bvh_range *node, const bvh_object_split *s, bvh_range *left,
                                 bvh_range *right, unsigned threads);
/* Nodes with at least this many references are split on several threads
 * when nothing else could run (bvh_split_threads): below a scene of 65,536
 * triangles (the earlier threshold) the first splits ran on one thread
 * while the others waited. */
#define BVH_SPLIT_MT_MIN_PRIMS 8192

/* In-place builders: a split function partitions node's references and
 * fills `left` and `right` (node's range in two non-empty parts, in order,
 * with their bounds), returning 1, or returns 0 to make a leaf. It is called
 * only for count >= 2 below the depth cap; it may spread its work over
 * `threads` threads (the root: every build thread), with the result of
 * one. */
typedef int (*bvh_split_fn)(bvh_builder *b, const bvh_range *node, unsigned threads, bvh_range *left, bvh_range *right);
/* Builds the subtree of the `count` (at most BVH_EXACT_MAX) references at
 * `refs`, whose box is `box`, under `node` (at `depth`) by the exact SAH
 * sweep, with the binned builder's leaf rule: a split where it costs less
 * than a leaf or the node holds more than max_leaf_size references, halving
 * where every centroid coincides, a leaf at the depth cap. Reorders the
 * references into the leaves' order; the leaves point into `refs`, which
 * must outlive the tree. */
#define BVH_EXACT_MAX 32
/* The order in which the exact subtree builder takes n (at most
 * BVH_EXACT_MAX) keys: 0..n-1 by (keys[i], i), into order. plain_only
 * picks the form without AVX2 where the processor would run the other.
 * Returns 0 when n is too large. For tests: both forms give one order. */
int bvh_exact_order(const float *keys, uint32_t n, uint8_t *order, int plain_only);
void bvh_build_exact_subtree(bvh_builder *b, bvh_local *loc, int32_t node, bvh_ref *refs, uint32_t count,
                             const bvh_box *box, uint32_t depth);

/* Builds the whole tree over b->refs with `split` on every build thread
 * (and bvh_build_exact_subtree below b->exact_max references); returns the
 * root. */
int32_t bvh_build_inplace(bvh_builder *b, bvh_split_fn split);

/* Writes the tmp tree under `root` into `s` (META, BVH2 or BVHO, TRI4) in the
 * layout args->layout asks for; sets the cancellation error if the build was
 * cancelled. */
as_error_t bvh_builder_finish(bvh_builder *b, int32_t root, uint32_t builder_id, as_structure_t *s,
                              double t_start);

#endif
