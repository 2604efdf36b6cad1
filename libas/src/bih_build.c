/* BIH builder: Wachter & Keller 2006, "Instant ray tracing: the bounding
 * interval hierarchy", with their global heuristic (section 2.2): a node
 * splits its candidate box, not its objects' box, in the middle of the
 * longest axis; objects go left or right by their box centre; the left
 * child's clip plane is the largest upper bound of its objects, the right
 * child's the smallest lower bound. When every centre falls on one side,
 * the candidate box shrinks to that half and the split is retried, so empty
 * space is cut off without creating a node. The children's candidate boxes
 * are the two halves of the parent's.
 *
 * Termination: a node becomes a leaf at max_leaf_size objects or at the
 * depth limit (never deeper than the traversal stack). When all centres
 * coincide, or the candidate box can no longer be halved in floats, the
 * objects are split into two halves of their list (like the BVH's fallback),
 * which keeps the depth logarithmic for many copies of one triangle.
 *
 * Determinism: the shape depends only on the input, and each node's
 * partition is Hoare's, whether one thread runs its loop or a big node's
 * pieces run on several (partition_bits.h); node and PRIM order come from
 * one depth-first walk
 * after the build, so the output is byte-identical for any thread count.
 * A right child of at least PARALLEL_MIN_PRIMS objects goes to a thread
 * that waits for work (task_pool.h). */
#include "spatial_common.h"
#include "bih_layout.h"
#include "simd4.h"
#include "partition_bits.h"
#include "task_pool.h"

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

/* A right child of this many objects or more goes to a waiting thread:
 * with 4,096, a scene of 30,000 triangles made about 8 such subtrees, and
 * 16 threads built its tree at 4 or 5 at a time while the others slept. */
#define PARALLEL_MIN_PRIMS 1024
/* Leaves report the build's progress in steps of this share of it, not one
 * by one on a counter that every thread writes. */
#define REPORT_STEPS 1024
/* Retries of the global heuristic before the list-half fallback. */
#define MAX_EMPTY_RETRIES 128
/* Nodes of this many objects or more are partitioned in pieces on the
 * threads that are idle (partition_pieces): one thread's passes over the
 * root and the next levels had left the others waiting. */
#define PIECES_MIN_PRIMS 16384
#define PIECE_PRIMS 4096
#define PIECES_MAX 256

typedef struct bih_ref {
    float lo[3];
    uint32_t id;
    float hi[3];
    float pad;
} bih_ref;

_Static_assert(sizeof(bih_ref) == AS_PARTITION_ITEM_BYTES, "references are partitioned as 32-byte items");

typedef struct bih_tmp {
    int32_t left;            /* tmp index of the left child, -1 for a leaf; right = left + 1 */
    uint32_t axis;
    float clip[2];
    uint32_t first, count;   /* leaf range in refs */
} bih_tmp;

typedef struct bih_builder {
    const as_build_args_t *args;
    bih_ref *refs;
    bih_tmp *nodes;
    uint64_t node_capacity;
    atomic_uint_fast64_t node_next;   /* the next node chunk */
    atomic_uint_fast64_t nodes_used;  /* below the root, summed as tasks end */
    atomic_uint shared_tasks;
    uint32_t depth_limit;
    atomic_uint_fast64_t done;
    uint64_t total;
    atomic_int cancelled;
    pthread_mutex_t progress_lock;
    double next_report;
} bih_builder;

static void report(bih_builder *b, uint64_t prims)
{
    const uint64_t done = atomic_fetch_add(&b->done, prims) + prims;
    if (!b->args->progress) return;
    const double fraction = b->total ? (double)done / (double)b->total : 1.0;
    pthread_mutex_lock(&b->progress_lock);
    if (fraction >= b->next_report) {
        b->next_report = fraction + 0.01;
        if (!b->args->progress(b->args->progress_user, fraction)) atomic_store(&b->cancelled, 1);
    }
    pthread_mutex_unlock(&b->progress_lock);
}

/* What a task keeps for itself: the objects in its leaves not yet
 * reported (reported once they make a step of the build, REPORT_STEPS, and
 * when the task ends), and its chunk of nodes (as_slots_take, NODE_CHUNK at
 * a time); a task leaves at most a chunk unused, and at most
 * MAX_SHARED_TASKS are handed over, which bounds the array. */
#define NODE_CHUNK 64
#define MAX_SHARED_TASKS 1024

typedef struct bih_local {
    uint64_t count, step;
    uint64_t chunk_next, chunk_end, used;
    as_pending_stack pending;   /* the right children this task has not started (task_pool.h) */
} bih_local;

/* Two adjacent nodes from the task's chunk; -1 when the array is full,
 * which the array's bound rules out. */
static int64_t take_pair(bih_builder *b, bih_local *u)
{
    if (u->chunk_next + 2 > u->chunk_end &&
        !as_slots_take(&b->node_next, b->node_capacity, NODE_CHUNK, 2, &u->chunk_next, &u->chunk_end))
        return -1;
    const uint64_t l = u->chunk_next;
    u->chunk_next += 2;
    u->used += 2;
    return (int64_t)l;
}

static void make_leaf(bih_builder *b, bih_local *u, int32_t node, uint32_t first, uint32_t count)
{
    bih_tmp *n = &b->nodes[node];
    n->left = -1;
    n->axis = AS_BIH_LEAF;
    n->first = first;
    n->count = count;
    u->count += count;
    if (u->count >= u->step) {
        report(b, u->count);
        u->count = 0;
    }
}

static float centre(const bih_ref *r, int axis) { return 0.5f * (r->lo[axis] + r->hi[axis]); }

/* A node's candidate box and the box of its objects' centres; the parent's
 * partition computes the latter, so a node makes one pass over its objects. */
typedef struct bih_boxes {
    float cand_lo[3], cand_hi[3];
    float clo[3], chi[3];
} bih_boxes;

typedef struct bih_task {
    int32_t node;
    uint32_t first, count, depth;
    bih_boxes boxes;
} bih_task;

static void build_node(as_task_pool *pool, bih_builder *b, bih_local *u, int32_t node, uint32_t first,
                       uint32_t count, uint32_t depth, const bih_boxes *in);

static void centre_grow(const bih_ref *r, float lo[3], float hi[3])
{
    for (int k = 0; k < 3; ++k) {
        const float c = centre(r, k);
        if (c < lo[k]) lo[k] = c;
        if (c > hi[k]) hi[k] = c;
    }
}

static void box_reset(float lo[3], float hi[3])
{
    for (int k = 0; k < 3; ++k) {
        lo[k] = FLT_MAX;
        hi[k] = -FLT_MAX;
    }
}

/* A whole subtree on one thread of the pool, or the whole tree without
 * one (pool NULL). */
static void build_subtree(as_task_pool *pool, bih_builder *b, const bih_task *t)
{
    const uint64_t step = b->total / REPORT_STEPS;
    bih_local u;
    memset(&u, 0, sizeof u);
    u.step = step ? step : 1;
    build_node(pool, b, &u, t->node, t->first, t->count, t->depth, &t->boxes);
    if (u.count) report(b, u.count);
    atomic_fetch_add(&b->nodes_used, u.used);
}

static void build_task(as_task_pool *pool, void *task, void *user)
{
    bih_task t;
    memcpy(&t, task, sizeof t);
    build_subtree(pool, user, &t);
}

/* A node's side of the split and what its partition gathers from the
 * objects on either side: the clip bounds and the centre boxes (maxima
 * and minima, which do not depend on the order). */
typedef struct bih_sides {
    v4f llo, lhi, rlo, rhi;
    float lmax, rmin;
} bih_sides;

static void sides_reset(bih_sides *s)
{
    s->llo = s->rlo = v4f_set1(FLT_MAX);
    s->lhi = s->rhi = v4f_set1(-FLT_MAX);
    s->lmax = -FLT_MAX;
    s->rmin = FLT_MAX;
}

static inline void sides_left(bih_sides *s, const bih_ref *r, int axis)
{
    const v4f c = v4f_mul(v4f_set1(0.5f), v4f_add(v4f_load3(r->lo), v4f_load3(r->hi)));
    s->llo = v4f_min(s->llo, c);
    s->lhi = v4f_max(s->lhi, c);
    if (r->hi[axis] > s->lmax) s->lmax = r->hi[axis];
}

static inline void sides_right(bih_sides *s, const bih_ref *r, int axis)
{
    const v4f c = v4f_mul(v4f_set1(0.5f), v4f_add(v4f_load3(r->lo), v4f_load3(r->hi)));
    s->rlo = v4f_min(s->rlo, c);
    s->rhi = v4f_max(s->rhi, c);
    if (r->lo[axis] < s->rmin) s->rmin = r->lo[axis];
}

static void sides_merge(bih_sides *to, const bih_sides *from)
{
    to->llo = v4f_min(to->llo, from->llo);
    to->lhi = v4f_max(to->lhi, from->lhi);
    to->rlo = v4f_min(to->rlo, from->rlo);
    to->rhi = v4f_max(to->rhi, from->rhi);
    if (from->lmax > to->lmax) to->lmax = from->lmax;
    if (from->rmin < to->rmin) to->rmin = from->rmin;
}

/* Hoare's partition of refs[first, first + count) by centre, on this
 * thread; returns the first object of the right side. */
static uint32_t partition_hoare(bih_ref *refs, uint32_t first, uint32_t count, int axis, float split, bih_sides *s)
{
    uint32_t i = first, j = first + count;
    for (;;) {
        while (i < j && centre(&refs[i], axis) < split) sides_left(s, &refs[i++], axis);
        while (i < j && !(centre(&refs[j - 1], axis) < split)) sides_right(s, &refs[--j], axis);
        if (i >= j) break;
        sides_right(s, &refs[i], axis);
        sides_left(s, &refs[j - 1], axis);
        const bih_ref t = refs[i];
        refs[i++] = refs[j - 1];
        refs[--j] = t;
    }
    return i;
}

/* A big node's partition on the pool's idle threads, in pieces of 64-word
 * runs of a bit mask of sides: Hoare's permutation (partition_bits.h), so
 * the same order as partition_hoare. */
typedef struct bih_piece_job {
    bih_ref *refs;
    uint32_t count, nwords, nl, misplaced;
    int axis;
    float split;
    uint64_t *bits;
    uint32_t piece_nl[PIECES_MAX];
    bih_sides piece_sides[PIECES_MAX];
} bih_piece_job;

static void piece_mark(void *user, unsigned i, unsigned n)
{
    bih_piece_job *j = user;
    uint32_t w0, w1, nl = 0;
    as_chunk_range(j->nwords, i, n, &w0, &w1);
    bih_sides s;
    sides_reset(&s);
    for (uint32_t w = w0; w < w1; ++w) {
        const uint32_t first = 64 * w, end = j->count - first < 64 ? j->count : first + 64;
        uint64_t word = 0;
        for (uint32_t k = first; k < end; ++k) {
            const bih_ref *r = &j->refs[k];
            if (centre(r, j->axis) < j->split) {
                word |= (uint64_t)1 << (k - first);
                sides_left(&s, r, j->axis);
            } else {
                sides_right(&s, r, j->axis);
            }
        }
        j->bits[w] = word;
        nl += (uint32_t)as_popcount64(word);
    }
    j->piece_nl[i] = nl;
    j->piece_sides[i] = s;
}

static void piece_swap(void *user, unsigned i, unsigned n)
{
    bih_piece_job *j = user;
    uint32_t k0, k1;
    as_chunk_range(j->misplaced, i, n, &k0, &k1);
    as_partition_swap(j->refs, j->bits, j->nl, j->nwords, k0, k1);
}

/* partition_hoare's result for a node of PIECES_MIN_PRIMS objects or more,
 * on the pool's threads; UINT32_MAX when there is no memory for the mask
 * (the caller then runs partition_hoare). */
static __attribute__((noinline)) uint32_t partition_pieces(bih_ref *refs, uint32_t first, uint32_t count, int axis,
                                                         float split, bih_sides *s)
{
    const uint32_t nwords = (count + 63) / 64;
    bih_piece_job *j = malloc(sizeof *j);
    uint64_t *bits = j ? malloc(sizeof(uint64_t) * nwords) : NULL;
    if (!bits) {
        free(j);
        return UINT32_MAX;
    }
    j->refs = refs + first;
    j->count = count;
    j->nwords = nwords;
    j->axis = axis;
    j->split = split;
    j->bits = bits;
    const unsigned pieces = count / PIECE_PRIMS < PIECES_MAX ? count / PIECE_PRIMS : PIECES_MAX;
    as_parallel_run(pieces, piece_mark, j);
    uint32_t nl = 0;
    for (unsigned i = 0; i < pieces; ++i) {
        nl += j->piece_nl[i];
        sides_merge(s, &j->piece_sides[i]);
    }
    j->nl = nl;
    j->misplaced = as_partition_misplaced(bits, nl);
    as_parallel_run(pieces, piece_swap, j);
    free(bits);
    free(j);
    return first + nl;
}

/* Hands the oldest right child this task has not started to a waiting
 * thread, if one waits (task_pool.h), within the shared-task cap. */
static void offer_pending(as_task_pool *pool, bih_builder *b, bih_local *u)
{
    as_pending *p = as_pending_next_offer(pool, &u->pending);
    if (p) p->given = atomic_fetch_add(&b->shared_tasks, 1) < MAX_SHARED_TASKS && as_task_pool_push(pool, p->task);
}

static void build_node(as_task_pool *pool, bih_builder *b, bih_local *u, int32_t node, uint32_t first,
                       uint32_t count, uint32_t depth, const bih_boxes *in)
{
    offer_pending(pool, b, u);
    if (atomic_load(&b->cancelled) || count <= b->args->max_leaf_size || depth >= b->depth_limit) {
        make_leaf(b, u, node, first, count);
        return;
    }
    float cand_lo[3], cand_hi[3];
    memcpy(cand_lo, in->cand_lo, sizeof cand_lo);
    memcpy(cand_hi, in->cand_hi, sizeof cand_hi);
    const float *clo = in->clo, *chi = in->chi;
    int axis = -1;
    float split = 0.0f;
    if (clo[0] < chi[0] || clo[1] < chi[1] || clo[2] < chi[2]) {
        /* The global heuristic: halve the candidate box until the plane
         * separates the centres (the centre box decides without a pass over
         * the objects). */
        for (int tries = 0; tries < MAX_EMPTY_RETRIES; ++tries) {
            int k = 0;
            for (int j = 1; j < 3; ++j)
                if (cand_hi[j] - cand_lo[j] > cand_hi[k] - cand_lo[k]) k = j;
            const float s = 0.5f * (cand_lo[k] + cand_hi[k]);
            if (!(s > cand_lo[k] && s < cand_hi[k])) break; /* cannot halve further */
            if (chi[k] < s) { cand_hi[k] = s; continue; }    /* all left: keep the left half */
            if (clo[k] >= s) { cand_lo[k] = s; continue; }   /* all right */
            axis = k;
            split = s;
            break;
        }
    }
    bih_boxes lb, rb;
    box_reset(lb.clo, lb.chi);
    box_reset(rb.clo, rb.chi);
    float lmax = -FLT_MAX, rmin = FLT_MAX;
    uint32_t mid;
    if (axis >= 0) {
        /* One pass: the partition, each side's clip bound and the children's
         * centre boxes; a big node's on the pool's idle threads too. */
        bih_sides sd;
        sides_reset(&sd);
        mid = pool && count >= PIECES_MIN_PRIMS ? partition_pieces(b->refs, first, count, axis, split, &sd) : UINT32_MAX;
        if (mid == UINT32_MAX) mid = partition_hoare(b->refs, first, count, axis, split, &sd);
        lmax = sd.lmax;
        rmin = sd.rmin;
        float tmp[4];
        v4f_store(tmp, sd.llo);
        memcpy(lb.clo, tmp, sizeof lb.clo);
        v4f_store(tmp, sd.lhi);
        memcpy(lb.chi, tmp, sizeof lb.chi);
        v4f_store(tmp, sd.rlo);
        memcpy(rb.clo, tmp, sizeof rb.clo);
        v4f_store(tmp, sd.rhi);
        memcpy(rb.chi, tmp, sizeof rb.chi);
        memcpy(lb.cand_lo, cand_lo, sizeof cand_lo);
        memcpy(lb.cand_hi, cand_hi, sizeof cand_hi);
        memcpy(rb.cand_lo, cand_lo, sizeof cand_lo);
        memcpy(rb.cand_hi, cand_hi, sizeof cand_hi);
        lb.cand_hi[axis] = split;
        rb.cand_lo[axis] = split;
    } else {
        /* Coincident centres: halve the list on the longest axis of the
         * candidate box; both children keep the parent's candidate box. */
        axis = 0;
        for (int j = 1; j < 3; ++j)
            if (cand_hi[j] - cand_lo[j] > cand_hi[axis] - cand_lo[axis]) axis = j;
        mid = first + count / 2;
        for (uint32_t i = first; i < mid; ++i) {
            centre_grow(&b->refs[i], lb.clo, lb.chi);
            if (b->refs[i].hi[axis] > lmax) lmax = b->refs[i].hi[axis];
        }
        for (uint32_t i = mid; i < first + count; ++i) {
            centre_grow(&b->refs[i], rb.clo, rb.chi);
            if (b->refs[i].lo[axis] < rmin) rmin = b->refs[i].lo[axis];
        }
        memcpy(lb.cand_lo, cand_lo, sizeof cand_lo);
        memcpy(lb.cand_hi, cand_hi, sizeof cand_hi);
        memcpy(rb.cand_lo, cand_lo, sizeof cand_lo);
        memcpy(rb.cand_hi, cand_hi, sizeof cand_hi);
    }
    const int64_t l = take_pair(b, u);
    if (l < 0) { /* cannot happen: see MAX_SHARED_TASKS */
        make_leaf(b, u, node, first, count);
        return;
    }
    bih_tmp *n = &b->nodes[node];
    n->left = (int32_t)l;
    n->axis = (uint32_t)axis;
    n->clip[0] = lmax;
    n->clip[1] = rmin;
    /* An inner node keeps its objects' range: the walk on several threads
     * sizes subtrees by it. */
    n->first = first;
    n->count = count;
    const uint32_t lcount = mid - first, rcount = first + count - mid;
    const bih_task right = {(int32_t)l + 1, mid, rcount, depth + 1, rb};
    const int shared = pool && rcount >= PARALLEL_MIN_PRIMS && as_task_pool_hungry(pool) &&
                       atomic_fetch_add(&b->shared_tasks, 1) < MAX_SHARED_TASKS && as_task_pool_push(pool, &right);
    /* Kept: offered again while the left subtree is built. */
    as_pending rp = {&right, 0};
    const int tracked = !shared && pool && rcount >= PARALLEL_MIN_PRIMS && as_pending_push(&u->pending, &rp);
    build_node(pool, b, u, (int32_t)l, first, lcount, depth + 1, &lb);
    if (tracked) as_pending_pop(&u->pending);
    if (!shared && !rp.given) build_node(pool, b, u, (int32_t)l + 1, mid, rcount, depth + 1, &rb);
}

#define INIT_CHUNKS 64

typedef struct bih_init_job {
    const as_mesh_t *mesh;
    bih_ref *refs;
    unsigned chunks;
    uint32_t offset[INIT_CHUNKS];
    float lo[INIT_CHUNKS][3], hi[INIT_CHUNKS][3], clo[INIT_CHUNKS][3], chi[INIT_CHUNKS][3];
} bih_init_job;

static void init_chunk(void *user, size_t ch)
{
    bih_init_job *j = user;
    const as_mesh_t *mesh = j->mesh;
    uint32_t first, end;
    as_chunk_range(mesh->triangle_count, (unsigned)ch, j->chunks, &first, &end);
    float lo[3], hi[3], clo[3], chi[3];
    box_reset(lo, hi);
    box_reset(clo, chi);
    uint32_t k = j->offset[ch];
    for (uint32_t i = first; i < end; ++i) {
        if (as_mesh_triangle_is_degenerate(mesh, i)) continue;
        bih_ref *r = &j->refs[k++];
        const uint32_t *ix = mesh->indices + 3 * (size_t)i;
        for (int a = 0; a < 3; ++a) { r->lo[a] = FLT_MAX; r->hi[a] = -FLT_MAX; }
        for (int v = 0; v < 3; ++v) {
            const float *p = mesh->positions + 3 * (size_t)ix[v];
            for (int a = 0; a < 3; ++a) {
                if (p[a] < r->lo[a]) r->lo[a] = p[a];
                if (p[a] > r->hi[a]) r->hi[a] = p[a];
            }
        }
        /* -0 becomes +0: the clip planes come from these bounds, and the
         * sign of a zero in them must not depend on which of two equal
         * references a pass meets first. */
        for (int a = 0; a < 3; ++a) {
            r->lo[a] += 0.0f;
            r->hi[a] += 0.0f;
        }
        r->id = i;
        r->pad = 0.0f;
        for (int a = 0; a < 3; ++a) {
            if (r->lo[a] < lo[a]) lo[a] = r->lo[a];
            if (r->hi[a] > hi[a]) hi[a] = r->hi[a];
        }
        centre_grow(r, clo, chi);
    }
    memcpy(j->lo[ch], lo, sizeof lo);
    memcpy(j->hi[ch], hi, sizeof hi);
    memcpy(j->clo[ch], clo, sizeof clo);
    memcpy(j->chi[ch], chi, sizeof chi);
}

typedef struct bih_flat {
    const bih_builder *b;
    as_bih_node_t *out;
    uint64_t out_count;      /* the next free slot */
    uint32_t *prims;
    uint64_t prim_count;
    uint64_t leaves, empty_leaves;
    uint32_t max_depth;
    double ci, ct, root_area;
    as_sah_sum sah;
    double *terms;           /* each node's SAH term by pre-order position, or NULL: summed into sah */
    uint64_t term_pos;
} bih_flat;

/* A node's SAH term, the one as_bih_sah_cost adds for it. */
static double flat_term(const bih_flat *f, const bih_tmp *n, const float lo[3], const float hi[3])
{
    const double rel = f->root_area > 0 ? as_spatial_half_area(lo, hi) / f->root_area : 1.0;
    return n->left < 0 ? f->ci * n->count * rel : f->ct * rel;
}

static void flat_add(bih_flat *f, double term)
{
    if (f->terms) f->terms[f->term_pos++] = term;
    else as_sah_sum_add(&f->sah, term);
}

/* Writes leaf `n` at d. A leaf's PRIM entries are its objects' place in
 * refs: the walk meets the leaves in the order of their ranges there. */
static void flat_leaf(bih_flat *f, const bih_tmp *n, as_bih_node_t *d, uint32_t depth)
{
    d->info = (n->first << 2) | AS_BIH_LEAF;
    d->clip[0] = as_uint_as_float(n->count);
    d->clip[1] = 0.0f;
    for (uint32_t i = 0; i < n->count; ++i) f->prims[n->first + i] = f->b->refs[n->first + i].id;
    f->prim_count += n->count;
    if (n->count) f->leaves++; else f->empty_leaves++;
    if (depth > f->max_depth) f->max_depth = depth;
}

/* Writes inner node `n` at d with its children at the next two free slots
 * (returned), and their boxes. */
static uint64_t flat_inner(bih_flat *f, const bih_tmp *n, as_bih_node_t *d, const float lo[3], const float hi[3],
                           float box[2][2][3])
{
    const uint64_t c = f->out_count;
    f->out_count += 2;
    d->info = ((uint32_t)c << 2) | n->axis;
    d->clip[0] = n->clip[0];
    d->clip[1] = n->clip[1];
    memcpy(box[0][0], lo, sizeof box[0][0]);
    memcpy(box[0][1], hi, sizeof box[0][1]);
    memcpy(box[1][0], lo, sizeof box[1][0]);
    memcpy(box[1][1], hi, sizeof box[1][1]);
    if (n->clip[0] < box[0][1][n->axis]) box[0][1][n->axis] = n->clip[0];
    if (n->clip[1] > box[1][0][n->axis]) box[1][0][n->axis] = n->clip[1];
    return c;
}

/* The walk on several threads. The top of the tree is walked on one
 * thread down to subtrees of at most `grain` objects; each such subtree's
 * nodes take a range of slots and of pre-order positions that its size
 * (counted first, on every thread) fixes, whatever is in it, so the
 * subtrees are then written on every thread with the bytes and terms of
 * one walk, and the terms added in pre-order afterwards. */
typedef struct bih_flat_task {
    int32_t t;
    uint32_t depth;
    uint64_t o, out_next, term_pos, size;
    float lo[3], hi[3];
    /* what writing it found */
    uint64_t leaves, empty_leaves, prims;
    uint32_t max_depth;
    int bad;
} bih_flat_task;

typedef struct bih_flat_plan {
    bih_flat *top;
    uint32_t grain;
    bih_flat_task *tasks;
    size_t count, capacity;
    size_t next;             /* the top walk: the next subtree it meets */
} bih_flat_plan;

/* Writes tmp node `t`, whose box is lo-hi, at out[o]; its children go to
 * two adjacent slots. The SAH terms come in the order of as_bih_sah_cost's
 * walk (pre-order), so their sum is that walk's to the last bit without a
 * second walk. With a plan (the top of a walk on several threads) a
 * listed subtree is not written: it gets its box and its ranges, in the
 * order plan_collect listed them. */
static void flatten(bih_flat *f, int32_t t, uint64_t o, uint32_t depth, const float lo[3], const float hi[3],
                    bih_flat_plan *p)
{
    if (p && p->next < p->count && p->tasks[p->next].t == t) {
        bih_flat_task *k = &p->tasks[p->next++];
        k->o = o;
        k->depth = depth;
        memcpy(k->lo, lo, sizeof k->lo);
        memcpy(k->hi, hi, sizeof k->hi);
        k->out_next = f->out_count;
        k->term_pos = f->term_pos;
        f->out_count += k->size - 1;
        f->term_pos += k->size;
        return;
    }
    const bih_tmp *n = &f->b->nodes[t];
    flat_add(f, flat_term(f, n, lo, hi));
    if (n->left < 0) {
        flat_leaf(f, n, &f->out[o], depth);
        return;
    }
    float box[2][2][3];
    const uint64_t c = flat_inner(f, n, &f->out[o], lo, hi, box);
    flatten(f, n->left, c, depth + 1, box[0][0], box[0][1], p);
    flatten(f, n->left + 1, c + 1, depth + 1, box[1][0], box[1][1], p);
}

static uint64_t subtree_size(const bih_tmp *nodes, int32_t t)
{
    const bih_tmp *n = &nodes[t];
    return n->left < 0 ? 1 : 1 + subtree_size(nodes, n->left) + subtree_size(nodes, n->left + 1);
}

/* Collects the subtrees of at most `grain` objects in pre-order; 0 when the
 * list cannot grow. */
static int plan_collect(bih_flat_plan *p, int32_t t)
{
    const bih_tmp *n = &p->top->b->nodes[t];
    if (n->left < 0 || n->count <= p->grain) {
        if (p->count == p->capacity) {
            const size_t cap = p->capacity ? 2 * p->capacity : 256;
            bih_flat_task *grown = realloc(p->tasks, sizeof *grown * cap);
            if (!grown) return 0;
            p->tasks = grown;
            p->capacity = cap;
        }
        memset(&p->tasks[p->count], 0, sizeof p->tasks[0]);
        p->tasks[p->count++].t = t;
        return 1;
    }
    return plan_collect(p, n->left) && plan_collect(p, n->left + 1);
}

static void plan_size(void *user, size_t i)
{
    bih_flat_plan *p = user;
    p->tasks[i].size = subtree_size(p->top->b->nodes, p->tasks[i].t);
}

static void plan_write(void *user, size_t i)
{
    bih_flat_plan *p = user;
    bih_flat_task *k = &p->tasks[i];
    bih_flat f = *p->top;
    f.out_count = k->out_next;
    f.term_pos = k->term_pos;
    f.prim_count = f.leaves = f.empty_leaves = 0;
    f.max_depth = 0;
    flatten(&f, k->t, k->o, k->depth, k->lo, k->hi, NULL);
    k->leaves = f.leaves;
    k->empty_leaves = f.empty_leaves;
    k->prims = f.prim_count;
    k->max_depth = f.max_depth;
    k->bad = f.out_count != k->out_next + k->size - 1 || f.term_pos != k->term_pos + k->size;
}

/* Trees of fewer nodes than this are written on one thread. */
#define FLAT_MT_MIN_NODES 4096

/* Writes the whole tree (node_count nodes) into f; 0 when the walk's
 * bookkeeping disagrees with the tree. */
static int flatten_tree(bih_flat *f, uint64_t node_count, uint32_t n, unsigned threads, const float lo[3],
                        const float hi[3])
{
    bih_flat_plan p = {f, 0, NULL, 0, 0, 0};
    if (threads > 1 && node_count >= FLAT_MT_MIN_NODES) {
        f->terms = as_temp_take(sizeof(double) * node_count, "BIH SAH terms");
        /* About 32 subtrees per thread, so that the last one to finish
         * leaves the others idle for little. */
        p.grain = n / (32 * threads);
        if (!f->terms || !plan_collect(&p, 0)) {
            as_temp_give(f->terms);
            f->terms = NULL;
            free(p.tasks);
            p.tasks = NULL;
        }
    }
    if (!f->terms) {
        flatten(f, 0, 0, 0, lo, hi, NULL);
        return f->out_count == node_count;
    }
    as_parallel_for(threads, p.count, plan_size, &p);
    flatten(f, 0, 0, 0, lo, hi, &p);
    int ok = p.next == p.count && f->out_count == node_count && f->term_pos == node_count;
    if (ok) as_parallel_for(threads, p.count, plan_write, &p);
    for (size_t i = 0; ok && i < p.count; ++i) {
        const bih_flat_task *k = &p.tasks[i];
        f->leaves += k->leaves;
        f->empty_leaves += k->empty_leaves;
        f->prim_count += k->prims;
        if (k->max_depth > f->max_depth) f->max_depth = k->max_depth;
        ok = !k->bad;
    }
    if (ok) f->sah = as_sah_sum_terms(f->terms, node_count, threads);
    as_temp_give(f->terms);
    f->terms = NULL;
    free(p.tasks);
    return ok;
}

as_error_t as_bih_build(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s)
{
    const double t_start = as_now_ms();
    if (args->max_leaf_size < 1) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "max leaf size must be at least 1");
    if (!(args->cost_traversal >= 0.0f) || !(args->cost_intersection > 0.0f))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "SAH costs must be finite, traversal >= 0, intersection > 0");
    if (args->layout != AS_LAYOUT_BIH)
        return as_set_error(AS_ERROR_UNSUPPORTED, "the BIH builder writes only the bih layout");
    bih_builder b;
    memset(&b, 0, sizeof b);
    b.args = args;
    /* Node depth d needs d stack entries; leaves at AS_BIH_MAX_DEPTH at most. */
    b.depth_limit = args->max_depth && args->max_depth < AS_BIH_MAX_DEPTH ? args->max_depth : AS_BIH_MAX_DEPTH;
    pthread_mutex_init(&b.progress_lock, NULL);
    const uint32_t n = mesh->triangle_count - mesh->degenerate_count;
    b.total = n;
    /* The build's arrays and the sections from blocks earlier builds gave
     * back (as the BVH builders): fresh ones cost a page fault per 4 KB at
     * every build, and the faults of many threads wait on each other. */
    const size_t refs_bytes = sizeof(bih_ref) * (size_t)(n ? n : 1);
    b.refs = as_block_take(refs_bytes, 0, "BIH references");
    /* 2n - 1 nodes at most, and a chunk each task may leave unused: the
     * root's task and those handed over (at most one per node of
     * PARALLEL_MIN_PRIMS objects or more, so at most 2n / that). */
    const uint64_t tasks = 1 + (2 * (uint64_t)n / PARALLEL_MIN_PRIMS < MAX_SHARED_TASKS
                                    ? 2 * (uint64_t)n / PARALLEL_MIN_PRIMS
                                    : MAX_SHARED_TASKS);
    b.node_capacity = 2 * (uint64_t)n + 1 + NODE_CHUNK * tasks;
    const size_t nodes_bytes = sizeof(bih_tmp) * b.node_capacity;
    b.nodes = as_block_take(nodes_bytes, 0, "BIH build nodes");
    as_bih_node_t *out = NULL;
    uint32_t *prims = NULL;
    as_tri4_t *tris = NULL;
    if (!b.refs || !b.nodes) goto fail;
    if (n > AS_BIH_MAX_INDEX / 2) {
        as_set_error(AS_ERROR_UNSUPPORTED, "%u triangles exceed the BIH layout's 30-bit indices", n);
        goto fail;
    }
    float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
    bih_boxes root;
    box_reset(root.clo, root.chi);
    {
        /* The references in contiguous chunks on every thread, each from
         * where the chunks before it end (the mesh's bits count the zero-area
         * triangles), in source order; the chunks' boxes merged in order. */
        bih_init_job init;
        memset(&init, 0, sizeof init);
        init.mesh = mesh;
        init.refs = b.refs;
        init.chunks = mesh->triangle_count >= 8192 ? INIT_CHUNKS : 1;
        uint32_t k = 0;
        for (unsigned ch = 0; ch < init.chunks; ++ch) {
            uint32_t first, end;
            as_chunk_range(mesh->triangle_count, ch, init.chunks, &first, &end);
            init.offset[ch] = k;
            k += end - first - as_mesh_degenerate_in_range(mesh, first, end);
        }
        as_parallel_for(as_thread_count(args->thread_count), init.chunks, init_chunk, &init);
        for (unsigned ch = 0; ch < init.chunks; ++ch)
            for (int a = 0; a < 3; ++a) {
                if (init.lo[ch][a] < lo[a]) lo[a] = init.lo[ch][a];
                if (init.hi[ch][a] > hi[a]) hi[a] = init.hi[ch][a];
                if (init.clo[ch][a] < root.clo[a]) root.clo[a] = init.clo[ch][a];
                if (init.chi[ch][a] > root.chi[a]) root.chi[a] = init.chi[ch][a];
            }
    }
    if (n == 0) for (int a = 0; a < 3; ++a) lo[a] = hi[a] = 0.0f;
    memcpy(root.cand_lo, lo, sizeof lo);
    memcpy(root.cand_hi, hi, sizeof hi);
    atomic_store(&b.node_next, 1);
    const bih_task first_task = {0, 0, n, 0, root};
    const unsigned threads = as_thread_count(args->thread_count);
    if (threads < 2 || n < 2 * PARALLEL_MIN_PRIMS ||
        !as_task_pool_run(threads, sizeof first_task, &first_task, build_task, &b))
        build_subtree(NULL, &b, &first_task);
    if (atomic_load(&b.cancelled)) {
        as_set_error(AS_ERROR_CANCELLED, "BIH build cancelled by the progress callback");
        goto fail;
    }
    const uint64_t node_count = 1 + atomic_load(&b.nodes_used);
    out = as_aligned_alloc(sizeof(as_bih_node_t) * node_count, "BIH nodes");
    prims = as_aligned_alloc(sizeof(uint32_t) * (size_t)(n ? n : 1), "BIH PRIM");
    tris = as_spatial_tris(mesh, as_thread_count(args->thread_count));
    if (!out || !prims || !tris) goto fail;
    /* No clearing: the walk writes all three fields of every node made
     * (flatten_tree checks that it met them all). */
    bih_flat f = {&b, out, 1, prims, 0, 0, 0, 0, args->cost_intersection, args->cost_traversal,
                  as_spatial_half_area(mesh->bounds_lo, mesh->bounds_hi), {0.0, 0.0, 0}, NULL, 0};
    if (!flatten_tree(&f, node_count, n, threads, mesh->bounds_lo, mesh->bounds_hi) || f.prim_count != n) {
        as_set_error(AS_ERROR_UNKNOWN, "BIH build bookkeeping: %llu nodes and %llu objects written, %llu and %u made",
                     (unsigned long long)f.out_count, (unsigned long long)f.prim_count,
                     (unsigned long long)node_count, n);
        goto fail;
    }

    as_spatial_meta(s, mesh, args, AS_STRUCT_BIH, AS_LAYOUT_BIH, AS_BIH_LAYOUT_VERSION, AS_BUILDER_BIH);
    s->meta.node_count = f.out_count - f.leaves - f.empty_leaves;
    s->meta.leaf_count = f.leaves;
    s->meta.empty_leaf_count = f.empty_leaves;
    s->meta.reference_count = f.prim_count;
    s->meta.max_depth = f.max_depth;
    s->meta.max_depth_limit = b.depth_limit;
    as_structure_add_kept_section(s, ASF_TAG_BIHN, out, f.out_count, sizeof(as_bih_node_t),
                                  sizeof(as_bih_node_t) * node_count);
    as_structure_add_kept_section(s, ASF_TAG_PRIM, prims, f.prim_count, sizeof(uint32_t),
                                  sizeof(uint32_t) * (size_t)(n ? n : 1));
    as_spatial_add_tris(s, tris, mesh->triangle_count);
    s->meta.sah_cost = as_sah_sum_value(&f.sah);
    s->build_ms = as_now_ms() - t_start;
    as_block_give(b.refs, refs_bytes, 0);
    as_block_give(b.nodes, nodes_bytes, 0);
    pthread_mutex_destroy(&b.progress_lock);
    return AS_OK;
fail:
    as_block_give(b.refs, refs_bytes, 0);
    as_block_give(b.nodes, nodes_bytes, 0);
    free(out);
    free(prims);
    free(tris);
    pthread_mutex_destroy(&b.progress_lock);
    return as_get_error();
}
