/* The parts every BVH builder shares (see bvh_build_common.h).
 *
 * Determinism: a builder decides each node's split from that node's
 * references alone, sequentially, and the final node and triangle order comes
 * from one depth-first walk after the build, so the output is byte-identical
 * whatever the thread count and however threads were scheduled (tmp node
 * indices, which do depend on scheduling, never reach the file). */
#include "bvh_build_common.h"
#include "task_pool.h"
#include "spatial_common.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct init_job {
    bvh_builder *b;
    unsigned chunks;
    uint32_t offset[256];
    bvh_box box[256], cbox[256];
} init_job;

static void init_fill(void *user, unsigned c, unsigned n)
{
    init_job *job = user;
    const as_mesh_t *mesh = job->b->mesh;
    uint32_t first, end, k = job->offset[c];
    as_chunk_range(mesh->triangle_count, c, n, &first, &end);
    bvh_box box = bvh_box_empty(), cbox = bvh_box_empty();
    for (uint32_t i = first; i < end; ++i) {
        if (as_mesh_triangle_is_degenerate(mesh, i)) continue;
        bvh_ref *r = &job->b->refs[k++];
        const uint32_t *ix = mesh->indices + 3 * (size_t)i;
        bvh_box bx = bvh_box_empty();
        for (int v = 0; v < 3; ++v) {
            const float *p = mesh->positions + 3 * (size_t)ix[v];
            bvh_box_grow(&bx, p, p);
        }
        bvh_box_no_negative_zero(&bx);
        memcpy(r->lo, bx.lo, sizeof r->lo);
        memcpy(r->hi, bx.hi, sizeof r->hi);
        r->id = i;
        r->pad = 0.0f;
        bvh_box_grow(&box, bx.lo, bx.hi);
        const float c2[3] = {bx.lo[0] + bx.hi[0], bx.lo[1] + bx.hi[1], bx.lo[2] + bx.hi[2]};
        bvh_box_grow(&cbox, c2, c2);
    }
    job->box[c] = box;
    job->cbox[c] = cbox;
}

as_error_t bvh_builder_init(bvh_builder *b, const as_mesh_t *mesh, const as_build_args_t *args,
                            uint64_t node_capacity_per_ref)
{
    memset(b, 0, sizeof *b);
    if (args->bin_count < 2 || args->bin_count > BVH_MAX_BINS)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "bin count %u is outside [2, %d]", args->bin_count, BVH_MAX_BINS);
    if (args->max_leaf_size < 1)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "max leaf size must be at least 1");
    if (!(args->cost_traversal >= 0.0f) || !(args->cost_intersection > 0.0f) || !isfinite(args->cost_traversal) ||
        !isfinite(args->cost_intersection))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "SAH costs must be finite, traversal >= 0, intersection > 0");
    if (args->layout != AS_LAYOUT_DEFAULT && args->layout != AS_LAYOUT_BVH2_CHILD_BOUNDS &&
        args->layout != AS_LAYOUT_BVH2_OWN_BOUNDS)
        return as_set_error(AS_ERROR_UNSUPPORTED, "layout 0x%04x is not a BVH layout (bvh2-child-bounds, bvh2-own-bounds)",
                            (unsigned)args->layout);
    b->args = args;
    b->mesh = mesh;
    b->max_threads = (int)as_thread_count(args->thread_count) - 1;
    b->depth_limit = args->max_depth && args->max_depth < AS_BVH2_MAX_DEPTH ? args->max_depth : AS_BVH2_MAX_DEPTH;
    if (b->depth_limit < 2) b->depth_limit = 2; /* the root is always an inner node */
    pthread_mutex_init(&b->progress_lock, NULL);

    /* Zero-area triangles can never be hit: they stay in the mesh (and keep
     * their index) but not in the structure. Filling runs on every build
     * thread over contiguous chunks, so the references keep the source
     * order. */
    init_job job;
    memset(&job, 0, sizeof job);
    job.b = b;
    job.chunks = mesh->triangle_count >= BVH_SPLIT_MT_MIN_PRIMS ? (unsigned)b->max_threads + 1 : 1;
    if (job.chunks > 256) job.chunks = 256;
    /* Each chunk's references start where the earlier chunks' end; the
     * mesh's bits count the degenerate triangles without a thread. */
    uint32_t n = 0;
    for (unsigned c = 0; c < job.chunks; ++c) {
        uint32_t first, end;
        as_chunk_range(mesh->triangle_count, c, job.chunks, &first, &end);
        job.offset[c] = n;
        n += end - first - as_mesh_degenerate_in_range(mesh, first, end);
    }
    b->ref_count = n;
    b->prim_total = n;
    /* Blocks given back by an earlier build are used again: fresh ones cost
     * a page fault per 4 KB touched in every build (the tmp nodes, 57 MB
     * reserved and 28 MB touched on bathroom, are above malloc's largest
     * threshold for reusing freed memory). */
    b->refs = as_block_take(sizeof(bvh_ref) * (size_t)(n ? n : 1), 0, "BVH primitive references");
    /* A binary tree over n leaves has n - 1 inner nodes. */
    b->node_capacity = node_capacity_per_ref * (uint64_t)n + 3 + BVH_NODE_SLACK;
    b->nodes = as_block_take(sizeof(bvh_tmp_node) * b->node_capacity, 0, "BVH build nodes");
    if (!b->refs || !b->nodes) {
        bvh_builder_free(b);
        return as_get_error();
    }
    as_parallel_run(job.chunks, init_fill, &job);
    b->root_box = b->root_cbox = bvh_box_empty();
    for (unsigned c = 0; c < job.chunks; ++c) {
        bvh_box_grow(&b->root_box, job.box[c].lo, job.box[c].hi);
        bvh_box_grow(&b->root_cbox, job.cbox[c].lo, job.cbox[c].hi);
    }
    return AS_OK;
}

void bvh_builder_free(bvh_builder *b)
{
    as_block_give(b->refs, sizeof(bvh_ref) * (size_t)(b->ref_count ? b->ref_count : 1), 0);
    as_block_give(b->nodes, sizeof(bvh_tmp_node) * b->node_capacity, 0);
    as_block_give(b->ref_bins, sizeof(uint32_t) * (size_t)(b->ref_count ? b->ref_count : 1), 0);
    b->refs = NULL;
    b->nodes = NULL;
    b->ref_bins = NULL;
    if (b->args) pthread_mutex_destroy(&b->progress_lock);
    b->args = NULL;
}

as_error_t bvh_builder_renew_nodes(bvh_builder *b, uint64_t capacity)
{
    as_block_give(b->nodes, sizeof(bvh_tmp_node) * b->node_capacity, 0);
    b->node_capacity = capacity;
    b->nodes = as_block_take(sizeof(bvh_tmp_node) * capacity, 0, "BVH build nodes");
    if (!b->nodes) {
        b->node_capacity = 0;
        return as_get_error();
    }
    return AS_OK;
}

bvh_box bvh_refs_box(const bvh_ref *refs, uint32_t count)
{
    v4f lo = v4f_set1(INFINITY), hi = v4f_set1(-INFINITY);
    for (uint32_t i = 0; i < count; ++i) {
        lo = v4f_min(lo, v4f_load3(refs[i].lo));
        hi = v4f_max(hi, bvh_ref_load_hi(refs[i].hi));
    }
    return bvh_box_from_v4f(lo, hi);
}

bvh_box bvh_refs_centroid2_box(const bvh_ref *refs, uint32_t count)
{
    v4f lo = v4f_set1(INFINITY), hi = v4f_set1(-INFINITY);
    for (uint32_t i = 0; i < count; ++i) {
        const v4f c = v4f_add(v4f_load3(refs[i].lo), bvh_ref_load_hi(refs[i].hi));
        lo = v4f_min(lo, c);
        hi = v4f_max(hi, c);
    }
    return bvh_box_from_v4f(lo, hi);
}

void bvh_range_bound(const bvh_builder *b, bvh_range *r)
{
    const bvh_ref *refs = b->refs + r->first;
    v4f lo = v4f_set1(INFINITY), hi = v4f_set1(-INFINITY), clo = lo, chi = hi;
    for (uint32_t i = 0; i < r->count; ++i) {
        const v4f l = v4f_load3(refs[i].lo), h = bvh_ref_load_hi(refs[i].hi), c = v4f_add(l, h);
        lo = v4f_min(lo, l);
        hi = v4f_max(hi, h);
        clo = v4f_min(clo, c);
        chi = v4f_max(chi, c);
    }
    r->box = bvh_box_from_v4f(lo, hi);
    r->cbox = bvh_box_from_v4f(clo, chi);
}

/* The bin of every axis for one reference, clamped into [0, nb - 1]. The
 * partition (bvh_object_split_left) repeats the same float operations on
 * one axis, so both always agree. */
static inline void bin_of(v4f lo, v4f hi, v4f cmin, v4f scale, v4f last, int32_t k[4])
{
    v4f f = v4f_mul(v4f_sub(v4f_add(lo, hi), cmin), scale);
    f = v4f_min(v4f_max(f, v4f_set1(0.0f)), last);
    v4f_to_i32(f, k);
}

int bvh_sweep_bins(const v4f *lo, const v4f *hi, const uint32_t *enter, const uint32_t *leave, uint32_t nb,
                   int counts_in_occupied_only, const uint32_t *occ, uint32_t m, double best_cost, bvh_bin_sweep *out)
{
    if (m < 2) return 0;
    const v4f empty_lo = v4f_set1(INFINITY), empty_hi = v4f_set1(-INFINITY);
    float right_area[BVH_MAX_BINS];
    uint32_t right_count[BVH_MAX_BINS];
    v4f rlo[BVH_MAX_BINS], rhi[BVH_MAX_BINS];
    v4f alo = empty_lo, ahi = empty_hi;
    uint32_t n = 0;
    for (uint32_t j = m; j-- > 1;) {
        const uint32_t x = occ[j];
        alo = v4f_min(alo, lo[x]);
        ahi = v4f_max(ahi, hi[x]);
        /* right_count[j] is for the plane after occ[j - 1]: every right end
         * beyond that bin, empty bins included (a spatial reference may end
         * in a bin where its part is empty). */
        if (counts_in_occupied_only) {
            n += leave[x];
        } else {
            for (uint32_t y = occ[j - 1] + 1; y <= x; ++y) n += leave[y];
            if (j + 1 == m)
                for (uint32_t y = x + 1; y < nb; ++y) n += leave[y];
        }
        right_area[j] = v4f_box_half_area(alo, ahi);
        right_count[j] = n;
        rlo[j] = alo;
        rhi[j] = ahi;
    }
    alo = empty_lo;
    ahi = empty_hi;
    n = 0;
    int found = 0;
    for (uint32_t j = 0; j + 1 < m; ++j) {
        const uint32_t x = occ[j];
        alo = v4f_min(alo, lo[x]);
        ahi = v4f_max(ahi, hi[x]);
        if (counts_in_occupied_only)
            n += enter[x];
        else
            for (uint32_t y = j ? occ[j - 1] + 1 : 0; y <= x; ++y) n += enter[y];
        if (n == 0 || right_count[j + 1] == 0) continue;
        const double cost = (double)v4f_box_half_area(alo, ahi) * n + (double)right_area[j + 1] * right_count[j + 1];
        if (cost < best_cost) {
            best_cost = cost;
            found = 1;
            out->bin = x;
            out->cost = cost;
            out->left = bvh_box_from_v4f(alo, ahi);
            out->right = bvh_box_from_v4f(rlo[j + 1], rhi[j + 1]);
            out->left_count = n;
            out->right_count = right_count[j + 1];
        }
    }
    return found;
}

/* The three axes' bins of one reference, a byte each (bins_out). */
_Static_assert(BVH_MAX_BINS <= 256, "a bin index fits a byte");
static inline uint32_t bins_packed(const int32_t k[4])
{
    return (uint32_t)k[0] | (uint32_t)k[1] << 8 | (uint32_t)k[2] << 16;
}

/* Object bins of all three axes. */
typedef struct obj_bins {
    v4f lo[3][BVH_MAX_BINS], hi[3][BVH_MAX_BINS];
    uint32_t n[3][BVH_MAX_BINS];
} obj_bins;

/* Bins refs[0, count) into every bin of `out`: two sets of bins, even
 * references into one and odd into the other, so that neighbours in the
 * same bin (meshes are coherent) do not wait on each other's stores. Every
 * bin ends as the exact min, max and count of its references, whatever the
 * order or grouping they were binned in, so chunks binned apart and merged
 * give the bins of one pass. */
static void bin_all(const bvh_ref *refs, uint32_t count, v4f vcmin, v4f vscale, v4f last, uint32_t nb, obj_bins *out,
                    uint32_t *bins_out)
{
    const v4f empty_lo = v4f_set1(INFINITY), empty_hi = v4f_set1(-INFINITY);
    v4f blo2[3][BVH_MAX_BINS], bhi2[3][BVH_MAX_BINS];
    uint32_t bn2[3][BVH_MAX_BINS];
    for (int axis = 0; axis < 3; ++axis)
        for (uint32_t x = 0; x < nb; ++x) {
            out->lo[axis][x] = blo2[axis][x] = empty_lo;
            out->hi[axis][x] = bhi2[axis][x] = empty_hi;
            out->n[axis][x] = bn2[axis][x] = 0;
        }
    uint32_t i = 0;
    for (; i + 1 < count; i += 2) {
        const v4f lo0 = v4f_load3(refs[i].lo), hi0 = bvh_ref_load_hi(refs[i].hi);
        const v4f lo1 = v4f_load3(refs[i + 1].lo), hi1 = bvh_ref_load_hi(refs[i + 1].hi);
        int32_t k0[4], k1[4];
        bin_of(lo0, hi0, vcmin, vscale, last, k0);
        bin_of(lo1, hi1, vcmin, vscale, last, k1);
        if (bins_out) {
            bins_out[i] = bins_packed(k0);
            bins_out[i + 1] = bins_packed(k1);
        }
        for (int axis = 0; axis < 3; ++axis) {
            const int32_t x0 = k0[axis], x1 = k1[axis];
            out->lo[axis][x0] = v4f_min(out->lo[axis][x0], lo0);
            out->hi[axis][x0] = v4f_max(out->hi[axis][x0], hi0);
            out->n[axis][x0]++;
            blo2[axis][x1] = v4f_min(blo2[axis][x1], lo1);
            bhi2[axis][x1] = v4f_max(bhi2[axis][x1], hi1);
            bn2[axis][x1]++;
        }
    }
    if (i < count) {
        const v4f lo0 = v4f_load3(refs[i].lo), hi0 = bvh_ref_load_hi(refs[i].hi);
        int32_t k0[4];
        bin_of(lo0, hi0, vcmin, vscale, last, k0);
        if (bins_out) bins_out[i] = bins_packed(k0);
        for (int axis = 0; axis < 3; ++axis) {
            out->lo[axis][k0[axis]] = v4f_min(out->lo[axis][k0[axis]], lo0);
            out->hi[axis][k0[axis]] = v4f_max(out->hi[axis][k0[axis]], hi0);
            out->n[axis][k0[axis]]++;
        }
    }
    for (int axis = 0; axis < 3; ++axis)
        for (uint32_t x = 0; x < nb; ++x) {
            out->lo[axis][x] = v4f_min(out->lo[axis][x], blo2[axis][x]);
            out->hi[axis][x] = v4f_max(out->hi[axis][x], bhi2[axis][x]);
            out->n[axis][x] += bn2[axis][x];
        }
}

/* The binning's frame cb2 (a box holding the node's lo + hi, exactly or
 * loosely): per axis its low corner and the scale to bins; 0 when no axis
 * can be binned (the frame is flat on every axis). */
static int object_frame(const bvh_box *cb2, uint32_t nb, bvh_object_split *best, int use[3])
{
    memset(best, 0, sizeof *best);
    best->axis = -1;
    best->cost = INFINITY;
    best->bin_count = nb;
    for (int axis = 0; axis < 3; ++axis) {
        const float extent = cb2->hi[axis] - cb2->lo[axis];
        use[axis] = extent > 0.0f;
        best->cmin[axis] = cb2->lo[axis];
        best->scale[axis] = use[axis] ? (float)nb / extent : 0.0f;
        /* An extent so small that the scale overflows cannot be binned. */
        if (!isfinite(best->scale[axis])) {
            use[axis] = 0;
            best->scale[axis] = 0.0f;
        }
    }
    return use[0] || use[1] || use[2];
}

/* Sweeps the occupied bins only: a plane between two empty bins splits
 * like the plane after the last occupied bin on its left. */
static void sweep_object_bins(const obj_bins *bins, const uint64_t occupied[3][BVH_MAX_BINS / 64], const int use[3],
                              uint32_t nb, bvh_object_split *best)
{
    for (int axis = 0; axis < 3; ++axis) {
        if (!use[axis]) continue;
        uint32_t occ[BVH_MAX_BINS], m = 0;
        for (uint32_t w = 0; w < (nb + 63) / 64; ++w)
            for (uint64_t bits = occupied[axis][w]; bits; bits &= bits - 1)
                occ[m++] = 64 * w + (uint32_t)__builtin_ctzll(bits);
        bvh_bin_sweep sw;
        if (!bvh_sweep_bins(bins->lo[axis], bins->hi[axis], bins->n[axis], bins->n[axis], nb, 1, occ, m, best->cost, &sw))
            continue;
        best->axis = axis;
        best->bin = (int)sw.bin;
        best->limit = (float)(sw.bin + 1);
        best->cost = sw.cost;
        best->left = sw.left;
        best->right = sw.right;
        best->left_count = sw.left_count;
        best->right_count = sw.right_count;
    }
}

static void occupied_from_counts(const obj_bins *bins, uint32_t nb, uint64_t occupied[3][BVH_MAX_BINS / 64])
{
    memset(occupied, 0, sizeof(uint64_t) * 3 * (BVH_MAX_BINS / 64));
    for (int axis = 0; axis < 3; ++axis)
        for (uint32_t x = 0; x < nb; ++x)
            if (bins->n[axis][x]) occupied[axis][x >> 6] |= (uint64_t)1 << (x & 63);
}

bvh_object_split bvh_find_object_split(const bvh_ref *refs, uint32_t count, const bvh_box *cb2, uint32_t nb,
                                       uint32_t *bins_out)
{
    bvh_object_split best;
    int use[3];
    if (!object_frame(cb2, nb, &best, use)) return best;
    obj_bins bins;
    uint64_t occupied[3][BVH_MAX_BINS / 64];
    const float cmin[4] = {best.cmin[0], best.cmin[1], best.cmin[2], 0.0f};
    const float scale[4] = {best.scale[0], best.scale[1], best.scale[2], 0.0f};
    const v4f vcmin = v4f_load(cmin), vscale = v4f_load(scale), last = v4f_set1((float)(nb - 1));
    if (count >= 4 * nb) {
        bin_all(refs, count, vcmin, vscale, last, nb, &bins, bins_out);
        occupied_from_counts(&bins, nb, occupied);
    } else {
        /* Small node: only the bins its references fall in are set up, in
         * a first pass that remembers the bins, so the node costs what its
         * references cost, not what the bins do, and no branch depends on
         * the data. */
        const v4f empty_lo = v4f_set1(INFINITY), empty_hi = v4f_set1(-INFINITY);
        memset(occupied, 0, sizeof occupied);
        uint8_t kk[4 * BVH_MAX_BINS][3];
        for (uint32_t i = 0; i < count; ++i) {
            const v4f lo = v4f_load3(refs[i].lo), hi = bvh_ref_load_hi(refs[i].hi);
            int32_t k[4];
            bin_of(lo, hi, vcmin, vscale, last, k);
            if (bins_out) bins_out[i] = bins_packed(k);
            for (int axis = 0; axis < 3; ++axis) {
                const int32_t x = k[axis];
                kk[i][axis] = (uint8_t)x;
                occupied[axis][x >> 6] |= (uint64_t)1 << (x & 63);
                bins.lo[axis][x] = empty_lo;
                bins.hi[axis][x] = empty_hi;
                bins.n[axis][x] = 0;
            }
        }
        for (uint32_t i = 0; i < count; ++i) {
            const v4f lo = v4f_load3(refs[i].lo), hi = bvh_ref_load_hi(refs[i].hi);
            for (int axis = 0; axis < 3; ++axis) {
                const uint32_t x = kk[i][axis];
                bins.lo[axis][x] = v4f_min(bins.lo[axis][x], lo);
                bins.hi[axis][x] = v4f_max(bins.hi[axis][x], hi);
                bins.n[axis][x]++;
            }
        }
    }
    sweep_object_bins(&bins, occupied, use, nb, &best);
    return best;
}

/* ---- one node's work on several threads (bvh_split_threads) */

/* A node's references are binned in pieces of at least this many, up to 8
 * per thread. At 4,096 a node of 16,000 references (the bunny's third
 * level) kept at most 4 of 16 threads busy while the others waited; a
 * piece of 1,024 is binned in a few microseconds, and its bins merged in a
 * fraction of one. */
#define BVH_PIECE_MIN_PRIMS 1024

uint32_t bvh_piece_count(uint32_t count, unsigned threads)
{
    uint32_t n = 8 * threads;
    if (n > count / BVH_PIECE_MIN_PRIMS) n = count / BVH_PIECE_MIN_PRIMS;
    return n ? n : 1;
}

static void obj_bins_merge(obj_bins *to, const obj_bins *from, uint32_t nb)
{
    for (int axis = 0; axis < 3; ++axis)
        for (uint32_t x = 0; x < nb; ++x) {
            to->lo[axis][x] = v4f_min(to->lo[axis][x], from->lo[axis][x]);
            to->hi[axis][x] = v4f_max(to->hi[axis][x], from->hi[axis][x]);
            to->n[axis][x] += from->n[axis][x];
        }
}

typedef struct par_bin_job {
    const bvh_ref *refs;
    uint32_t count, nb, pieces;
    atomic_uint next;
    v4f vcmin, vscale, last;
    obj_bins *bins;   /* 2 per thread: bins[c] its sum, bins[n + c] its scratch */
    uint32_t *bins_out;
} par_bin_job;

static void par_bin(void *user, unsigned c, unsigned n)
{
    par_bin_job *j = user;
    obj_bins *acc = &j->bins[c], *tmp = &j->bins[n + c];
    /* Each piece is binned alone and merged: min, max and counts are exact,
     * so the merged bins are those of one pass whoever binned what. */
    bin_all(j->refs, 0, j->vcmin, j->vscale, j->last, j->nb, acc, NULL); /* empty bins */
    for (;;) {
        const uint32_t k = atomic_fetch_add_explicit(&j->next, 1, memory_order_relaxed);
        if (k >= j->pieces) break;
        uint32_t first, end;
        as_chunk_range(j->count, k, j->pieces, &first, &end);
        bin_all(j->refs + first, end - first, j->vcmin, j->vscale, j->last, j->nb, tmp, j->bins_out ? j->bins_out + first : NULL);
        obj_bins_merge(acc, tmp, j->nb);
    }
}

bvh_object_split bvh_find_object_split_mt(const bvh_ref *refs, uint32_t count, const bvh_box *cb2, uint32_t nb,
                                          unsigned threads, uint32_t *bins_out)
{
    /* No index without a piece to take: each index costs two sets of bins
     * to clear and merge. */
    const uint32_t pieces = bvh_piece_count(count, threads);
    if (threads > pieces) threads = pieces;
    /* The threads' bins (880 KB for 16) are a build temporary: from
     * malloc they were fresh pages for every node, as the threads' malloc
     * arenas gave them back to the system. */
    obj_bins *bins = threads > 1 ? as_temp_take(sizeof(obj_bins) * 2 * threads, "BVH bins") : NULL;
    if (!bins) return bvh_find_object_split(refs, count, cb2, nb, bins_out);
    bvh_object_split best;
    int use[3];
    if (!object_frame(cb2, nb, &best, use)) {
        as_temp_give(bins);
        return best;
    }
    const float cmin[4] = {best.cmin[0], best.cmin[1], best.cmin[2], 0.0f};
    const float scale[4] = {best.scale[0], best.scale[1], best.scale[2], 0.0f};
    par_bin_job j;
    j.refs = refs;
    j.count = count;
    j.nb = nb;
    j.pieces = pieces;
    atomic_init(&j.next, 0);
    j.vcmin = v4f_load(cmin);
    j.vscale = v4f_load(scale);
    j.last = v4f_set1((float)(nb - 1));
    j.bins = bins;
    j.bins_out = bins_out;
    as_parallel_run(threads, par_bin, &j);
    /* min, max and sums are exact: the merged bins are those of one pass. */
    for (unsigned c = 1; c < threads; ++c) obj_bins_merge(&bins[0], &bins[c], nb);
    uint64_t occupied[3][BVH_MAX_BINS / 64];
    occupied_from_counts(&bins[0], nb, occupied);
    sweep_object_bins(&bins[0], occupied, use, nb, &best);
    as_temp_give(bins);
    return best;
}

void bvh_report_progress(bvh_builder *b, uint64_t prims)
{
    const uint64_t done = atomic_fetch_add(&b->prims_done, prims) + prims;
    if (!b->args->progress) return;
    double fraction = b->prim_total ? (double)done / (double)b->prim_total : 1.0;
    if (fraction > 1.0) fraction = 1.0; /* SBVH leaves count split references */
    pthread_mutex_lock(&b->progress_lock);
    if (fraction >= b->next_report) {
        b->next_report = fraction + 0.01;
        if (!b->args->progress(b->args->progress_user, fraction)) atomic_store(&b->cancelled, 1);
    }
    pthread_mutex_unlock(&b->progress_lock);
}

int32_t bvh_new_node(bvh_builder *b)
{
    const uint64_t i = atomic_fetch_add(&b->node_next, 1);
    return i < b->node_capacity ? (int32_t)i : -1;
}

void bvh_make_leaf(bvh_builder *b, int32_t node, const bvh_ref *refs, uint32_t count)
{
    bvh_tmp_node *n = &b->nodes[node];
    n->left = n->right = -1;
    n->refs = refs; /* in b->refs, or for the SBVH in its leaf store */
    n->count = count;
    n->inner = 0;
    bvh_report_progress(b, count);
}

int bvh_local_pair(bvh_local *l, int32_t *left, int32_t *right)
{
    if (l->next + 2 > l->end) {
        bvh_builder *b = l->b;
        bvh_local_flush(l);
        if (!as_slots_take(&b->node_next, b->node_capacity, BVH_NODE_CHUNK, 2, &l->next, &l->end)) return 0;
    }
    *left = (int32_t)l->next;
    *right = (int32_t)l->next + 1;
    l->next += 2;
    l->splits++;
    return 1;
}

void bvh_local_leaf(bvh_local *l, int32_t node, const bvh_ref *refs, uint32_t count)
{
    bvh_tmp_node *n = &l->b->nodes[node];
    n->left = n->right = -1;
    n->refs = refs; /* in b->refs, or for the SBVH in its leaf store */
    n->count = count;
    n->inner = 0;
    l->prims += count;
    /* Progress is reported in steps below its 1% granularity. */
    if (l->prims > (l->b->prim_total >> 8)) {
        bvh_report_progress(l->b, l->prims);
        l->prims = 0;
    }
}

void bvh_local_flush(bvh_local *l)
{
    bvh_builder *b = l->b;
    for (; l->next < l->end; ++l->next) {
        bvh_tmp_node *n = &b->nodes[l->next];
        n->left = n->right = -1;
        n->count = n->inner = 0;
        n->refs = NULL;
    }
    if (l->prims) bvh_report_progress(b, l->prims);
    if (l->splits) atomic_fetch_add(&b->inner_count, l->splits);
    l->prims = l->splits = 0;
}

int bvh_share_task(bvh_builder *b, as_task_pool *pool, const void *task)
{
    if (!pool || !as_task_pool_hungry(pool)) return 0;
    if (atomic_fetch_add(&b->tasks_shared, 1) >= BVH_MAX_SHARED_TASKS) return 0;
    return as_task_pool_push(pool, task);
}

unsigned bvh_split_threads(const bvh_builder *b, uint32_t count)
{
    /* Inside the pool a step's pieces go to whichever threads are idle
     * while it runs (as_parallel_run), so asking for every thread costs
     * nothing when they are busy with other subtrees. */
    return count < BVH_SPLIT_MT_MIN_PRIMS ? 1 : b->root_threads;
}

void bvh_pending_offer(bvh_builder *b, as_task_pool *pool, as_pending_stack *s)
{
    as_pending *p = as_pending_next_offer(pool, s);
    if (p) p->given = bvh_share_task(b, pool, p->task);
}

uint32_t bvh_find_small_split(bvh_ref *refs, uint32_t count, double *cost)
{
    *cost = INFINITY;
    if (count < 2 || count > BVH_SMALL_NODE) return 0;
    if (count == 2) {
        /* The most frequent case (every pair of references decides whether
         * to become two leaves): one plane per axis, and each costs the
         * two references' areas, so the general loops below pick the first
         * axis whose centroids differ, with the lower centroid left. */
        const v4f lo0 = v4f_load3(refs[0].lo), hi0 = bvh_ref_load_hi(refs[0].hi);
        const v4f lo1 = v4f_load3(refs[1].lo), hi1 = bvh_ref_load_hi(refs[1].hi);
        const v4f c0 = v4f_add(lo0, hi0), c1 = v4f_add(lo1, hi1);
        const int lt = v4f_lt_mask(c1, c0) & 7, gt = v4f_lt_mask(c0, c1) & 7;
        const int differ = lt | gt;
        if (!differ) return 0;
        const int axis_bit = differ & -differ;
        const float a0 = v4f_box_half_area(lo0, hi0), a1 = v4f_box_half_area(lo1, hi1);
        if (lt & axis_bit) {
            *cost = (double)a1 + (double)a0;
            const bvh_ref t = refs[0];
            refs[0] = refs[1];
            refs[1] = t;
        } else {
            *cost = (double)a0 + (double)a1;
        }
        return 1;
    }
    v4f lo[BVH_SMALL_NODE], hi[BVH_SMALL_NODE];
    float key[3][BVH_SMALL_NODE];
    for (uint32_t i = 0; i < count; ++i) {
        lo[i] = v4f_load3(refs[i].lo);
        hi[i] = bvh_ref_load_hi(refs[i].hi);
        float c[4];
        v4f_store(c, v4f_add(lo[i], hi[i]));
        for (int axis = 0; axis < 3; ++axis) key[axis][i] = c[axis];
    }
    int best_axis = -1;
    uint32_t best_mid = 0;
    uint8_t best_order[BVH_SMALL_NODE];
    for (int axis = 0; axis < 3; ++axis) {
        /* Each reference's rank by (centroid, position): counting, without
         * data-dependent branches. */
        const float *k = key[axis];
        uint8_t order[BVH_SMALL_NODE];
        for (uint32_t i = 0; i < count; ++i) {
            uint32_t rank = 0;
            for (uint32_t j = 0; j < count; ++j) rank += (k[j] < k[i]) | ((k[j] == k[i]) & (j < i));
            order[rank] = (uint8_t)i;
        }
        if (!(k[order[count - 1]] > k[order[0]])) continue; /* every centroid on one plane */
        float right_area[BVH_SMALL_NODE];
        v4f a = v4f_set1(INFINITY), z = v4f_set1(-INFINITY);
        for (uint32_t i = count; i-- > 1;) {
            a = v4f_min(a, lo[order[i]]);
            z = v4f_max(z, hi[order[i]]);
            right_area[i] = v4f_box_half_area(a, z);
        }
        a = v4f_set1(INFINITY);
        z = v4f_set1(-INFINITY);
        for (uint32_t i = 0; i + 1 < count; ++i) {
            a = v4f_min(a, lo[order[i]]);
            z = v4f_max(z, hi[order[i]]);
            const double c = (double)v4f_box_half_area(a, z) * (i + 1) + (double)right_area[i + 1] * (count - i - 1);
            if (c < *cost) {
                *cost = c;
                best_axis = axis;
                best_mid = i + 1;
                memcpy(best_order, order, sizeof order);
            }
        }
    }
    if (best_axis < 0) return 0;
    bvh_ref tmp[BVH_SMALL_NODE];
    for (uint32_t i = 0; i < count; ++i) tmp[i] = refs[best_order[i]];
    memcpy(refs, tmp, sizeof(bvh_ref) * count);
    return best_mid;
}

/* ---- the in-place recursion shared by the binned, sweep and mid-cut builders */

/* The children's frames for their binning (bvh_find_object_split's cb2):
 * on each axis the parent's frame clipped to twice the child's box (every
 * lo + hi of a child lies there, the sum's rounding included), and on the
 * split axis cut at the split plane. Exact centroid boxes cost the
 * partition a read of every reference (32 bytes) and four selects, 15% of a
 * one-thread build of staircase; the trees' SAH costs with these frames
 * moved by -0.4% to +0.6% on the benchmark scenes. A frame that rounding
 * would invert is left uncut. */
static void split_frames(const bvh_range *node, const bvh_object_split *s, bvh_range *left, bvh_range *right)
{
    bvh_range *const side[2] = {left, right};
    for (int c = 0; c < 2; ++c) {
        bvh_box *f = &side[c]->cbox;
        const bvh_box *bx = &side[c]->box;
        for (int k = 0; k < 3; ++k) {
            const float lo = 2.0f * bx->lo[k], hi = 2.0f * bx->hi[k];
            f->lo[k] = node->cbox.lo[k] > lo ? node->cbox.lo[k] : lo;
            f->hi[k] = node->cbox.hi[k] < hi ? node->cbox.hi[k] : hi;
            if (!(f->lo[k] <= f->hi[k])) {
                f->lo[k] = lo;
                f->hi[k] = hi;
            }
        }
    }
    const int a = s->axis;
    const float cut = s->cmin[a] + s->limit / s->scale[a];
    if (cut > left->cbox.lo[a] && cut < left->cbox.hi[a]) left->cbox.hi[a] = cut;
    if (cut > right->cbox.lo[a] && cut < right->cbox.hi[a]) right->cbox.lo[a] = cut;
}

static void finish_partition(const bvh_range *node, const bvh_object_split *s, uint32_t nl, bvh_range *left,
                             bvh_range *right)
{
    left->first = node->first;
    left->count = nl;
    left->box = s->left;
    right->first = node->first + nl;
    right->count = node->count - nl;
    right->box = s->right;
    split_frames(node, s, left, right);
}

/* Hoare's partition, sequential, so the order is reproducible: the one the
 * bit masks below reproduce, used where their memory cannot be had. */
static uint32_t partition_hoare(bvh_builder *b, const bvh_range *node, const bvh_object_split *s, bvh_range *left,
                                bvh_range *right)
{
    bvh_ref *refs = b->refs;
    uint32_t i = node->first, j = node->first + node->count;
    for (;;) {
        while (i < j && bvh_object_split_left(&refs[i], s)) ++i;
        while (i < j && !bvh_object_split_left(&refs[j - 1], s)) --j;
        if (i >= j) break;
        const bvh_ref t = refs[i];
        refs[i] = refs[j - 1];
        refs[j - 1] = t;
        /* Now refs[i] goes left and refs[j - 1] right; the loops above take
         * them on their next turn. */
    }
    finish_partition(node, s, i - node->first, left, right);
    return i;
}

/* Each reference's side in a bit mask (1: left) over refs[64 w0, ...) up
 * to word w1, from the bins the node's binning wrote (4 bytes a reference
 * instead of its 32): bin <= s->bin goes left. Returns the number that go
 * left. */
static uint32_t mark_sides(const uint32_t *bins, uint32_t count, const bvh_object_split *s, uint64_t *bits, uint32_t w0,
                           uint32_t w1)
{
    const unsigned shift = 8u * (unsigned)s->axis;
    const uint32_t bin = (uint32_t)s->bin;
    uint32_t nl = 0;
    for (uint32_t w = w0; w < w1; ++w) {
        const uint32_t first = 64 * w, n = count - first < 64 ? count - first : 64;
        const uint32_t *id = bins + first;
        uint64_t word = 0;
        uint32_t k = 0;
#if defined(__SSE2__)
        const __m128i limit = _mm_set1_epi32((int)bin + 1), byte = _mm_set1_epi32(0xff);
        const __m128i by = _mm_cvtsi32_si128((int)shift);
        for (; k + 4 <= n; k += 4) {
            const __m128i x = _mm_and_si128(_mm_srl_epi32(_mm_loadu_si128((const __m128i *)(id + k)), by), byte);
            word |= (uint64_t)(uint32_t)_mm_movemask_ps(_mm_castsi128_ps(_mm_cmplt_epi32(x, limit))) << k;
        }
#endif
        for (; k < n; ++k) word |= (uint64_t)(((id[k] >> shift) & 0xffu) <= bin) << k;
        bits[w] = word;
        nl += (uint32_t)as_popcount64(word);
    }
    return nl;
}

/* The same permutation as Hoare's partition above, found without its
 * data-dependent branches: a first pass writes each reference's side into a
 * bit mask, a second visits only the misplaced references through the
 * masks' set bits. */
uint32_t bvh_partition_object(bvh_builder *b, const bvh_range *node, const bvh_object_split *s, bvh_range *left,
                              bvh_range *right)
{
    const uint32_t count = node->count, nwords = (count + 63) / 64;
    if (!b->ref_bins) return partition_hoare(b, node, s, left, right);
    uint64_t stack_bits[256];
    uint64_t *bits = stack_bits;
    if (nwords > sizeof stack_bits / sizeof stack_bits[0]) {
        bits = malloc(sizeof(uint64_t) * nwords);
        if (!bits) return partition_hoare(b, node, s, left, right);
    }
    bvh_ref *refs = b->refs + node->first;
    const uint32_t nl = mark_sides(b->ref_bins + node->first, count, s, bits, 0, nwords);
    as_partition_swap(refs, bits, nl, nwords, 0, as_partition_misplaced(bits, nl));
    if (bits != stack_bits) free(bits);
    finish_partition(node, s, nl, left, right);
    return node->first + nl;
}

typedef struct par_part_job {
    bvh_ref *refs;
    const uint32_t *bins;
    uint32_t count, nwords, nl, misplaced;
    const bvh_object_split *s;
    uint64_t *bits;
    uint32_t part_nl[256];
} par_part_job;

static void par_mark(void *user, unsigned c, unsigned n)
{
    par_part_job *j = user;
    uint32_t w0, w1;
    as_chunk_range(j->nwords, c, n, &w0, &w1);
    j->part_nl[c] = mark_sides(j->bins, j->count, j->s, j->bits, w0, w1);
}

static void par_swap(void *user, unsigned c, unsigned n)
{
    par_part_job *j = user;
    uint32_t k0, k1;
    as_chunk_range(j->misplaced, c, n, &k0, &k1);
    as_partition_swap(j->refs, j->bits, j->nl, j->nwords, k0, k1);
}

uint32_t bvh_partition_object_mt(bvh_builder *b, const bvh_range *node, const bvh_object_split *s, bvh_range *left,
                                 bvh_range *right, unsigned threads)
{
    const uint32_t nwords = (node->count + 63) / 64;
    par_part_job *j = threads > 1 && threads <= 256 && b->ref_bins ? malloc(sizeof *j) : NULL;
    uint64_t *bits = j ? malloc(sizeof(uint64_t) * nwords) : NULL;
    if (!bits) {
        free(j);
        return bvh_partition_object(b, node, s, left, right);
    }
    j->refs = b->refs + node->first;
    j->bins = b->ref_bins + node->first;
    j->count = node->count;
    j->nwords = nwords;
    j->s = s;
    j->bits = bits;
    /* Pieces of at least 64 words, taken in turn (as_parallel_run inside
     * the pool): a helper that arrives late takes fewer of them instead of
     * holding the owner up for half the node. */
    unsigned pieces = nwords / 64;
    if (pieces < threads) pieces = threads;
    if (pieces > 256) pieces = 256;
    as_parallel_run(pieces, par_mark, j);
    uint32_t nl = 0;
    for (unsigned c = 0; c < pieces; ++c) nl += j->part_nl[c];
    j->nl = nl;
    j->misplaced = as_partition_misplaced(bits, nl);
    as_parallel_run(pieces, par_swap, j);
    free(bits);
    free(j);
    finish_partition(node, s, nl, left, right);
    return node->first + nl;
}

typedef struct inplace_task {
    bvh_range range;
    int32_t node;
    uint32_t depth;
} inplace_task;

typedef struct inplace_ctx {
    bvh_builder *b;
    bvh_split_fn split;
} inplace_ctx;

/* Builds the subtree of task t, handing its oldest large right child not
 * yet started to a thread that waits for work (bvh_pending_offer), and
 * records the subtree's size once both children are done (the recursion is
 * no deeper than the depth cap). */
static void inplace_subtree(as_task_pool *pool, const inplace_ctx *ctx, bvh_local *loc, as_pending_stack *pend,
                            const inplace_task *t)
{
    bvh_builder *b = ctx->b;
    bvh_pending_offer(b, pool, pend);
    if (t->range.count <= b->exact_max && !atomic_load_explicit(&b->cancelled, memory_order_relaxed)) {
        bvh_build_exact_subtree(b, loc, t->node, b->refs + t->range.first, t->range.count, &t->range.box, t->depth);
        return;
    }
    b->nodes[t->node].box = t->range.box;
    bvh_range l, r;
    int32_t ln, rn;
    /* A leaf at the stack's depth whatever its size: the traversal stack
     * holds one entry per level. */
    if (atomic_load_explicit(&b->cancelled, memory_order_relaxed) || t->range.count <= 1 ||
        t->depth + 1 >= b->depth_limit ||
        !ctx->split(b, &t->range, bvh_split_threads(b, t->range.count), &l, &r) ||
        !bvh_local_pair(loc, &ln, &rn)) {
        bvh_local_leaf(loc, t->node, b->refs + t->range.first, t->range.count);
        return;
    }
    bvh_make_inner(b, t->node, ln, rn);
    const inplace_task lt = {l, ln, t->depth + 1}, rt = {r, rn, t->depth + 1};
    as_pending rp = {&rt, 0};
    const int tracked = pool && rt.range.count >= BVH_SHARE_MIN_PRIMS && as_pending_push(pend, &rp);
    inplace_subtree(pool, ctx, loc, pend, &lt);
    if (tracked) as_pending_pop(pend);
    if (!rp.given) inplace_subtree(pool, ctx, loc, pend, &rt);
    bvh_node_complete(b, t->node, rp.given);
}

static void inplace_run(as_task_pool *pool, void *task, void *user)
{
    const inplace_ctx *ctx = user;
    inplace_task t;
    memcpy(&t, task, sizeof t);
    bvh_local loc;
    bvh_local_init(&loc, ctx->b);
    as_pending_stack pend;
    as_pending_init(&pend);
    inplace_subtree(pool, ctx, &loc, &pend, &t);
    bvh_local_flush(&loc);
}

int32_t bvh_build_inplace(bvh_builder *b, bvh_split_fn split)
{
    const int32_t root = bvh_new_node(b);
    b->nodes[root].left = b->nodes[root].right = -1;
    inplace_task t;
    memset(&t, 0, sizeof t);
    t.range.first = 0;
    t.range.count = b->ref_count;
    t.range.box = b->root_box;
    t.range.cbox = b->root_cbox;
    t.node = root;
    t.depth = 0;
    const inplace_ctx ctx = {b, split};
    const unsigned threads = (unsigned)b->max_threads + 1;
    /* Until the root is split, its task is the only one: the split
     * functions may spread its work over every thread. */
    b->root_threads = threads > 256 ? 256 : threads;
    if (threads < 2 || b->ref_count < 2 * BVH_PARALLEL_MIN_PRIMS ||
        !as_task_pool_run(threads, sizeof t, &t, inplace_run, (void *)&ctx))
        inplace_run(NULL, &t, (void *)&ctx);
    return root;
}

/* ---- the depth-first walk that fixes the output order
 *
 * The walk writes node n, gives its inner children the next two output
 * slots (siblings adjacent) and its leaf children the next TRI4 entries,
 * then walks its left subtree and its right one. A subtree of i inner nodes
 * and c references therefore takes the i - 1 slots and the c triangles that
 * follow wherever the walk has got to when it reaches the subtree, whatever
 * is in it. So the top of the tree is walked on one thread, which only
 * reserves those ranges for subtrees of up to a grain's size, and the
 * subtrees are then written on every thread: the same bytes as one walk.
 * The SAH sums are floating-point, so their order matters: in that case
 * each node's and leaf's term is stored at its pre-order position, and the
 * terms are added afterwards in the blocks of as_sah_sum, the blocks on
 * every thread and their sums in order, as the one walk adds them. */

typedef struct flatten_task {
    int32_t tnode;
    uint32_t depth;
    uint64_t out_index;           /* the subtree root's slot */
    uint64_t out_next;            /* the first slot of its descendants */
    uint64_t inner_pos, leaf_pos; /* the first positions of its SAH terms */
    uint32_t tri_next;            /* its first TRI4 entry */
    double area;                  /* the root's half area */
} flatten_task;

typedef struct flatten_state {
    const bvh_builder *b;
    as_bvh2_node_t *out;
    uint64_t out_count;
    as_tri4_t *tris;
    uint32_t tri_count;
    uint64_t leaf_count;
    uint32_t max_depth;
    as_sah_sum inner_sum, leaf_sum;       /* SAH sums, in bvh2_walk's order (one walk) */
    double *inner_terms, *leaf_terms;     /* or their terms by pre-order position (NULL: summed) */
    uint64_t inner_pos, leaf_pos;
    uint32_t grain;          /* subtrees of at most this many inner nodes become tasks; 0: none */
    flatten_task *tasks;
    uint32_t task_count, task_capacity;
} flatten_state;

static void set_child_box(as_bvh2_node_t *o, int which, const bvh_box *bx)
{
    if (which == 0) {
        o->xy0.x = bx->lo[0]; o->xy0.y = bx->hi[0]; o->xy0.z = bx->lo[1]; o->xy0.w = bx->hi[1];
        o->z01.x = bx->lo[2]; o->z01.y = bx->hi[2];
    } else {
        o->xy1.x = bx->lo[0]; o->xy1.y = bx->hi[0]; o->xy1.z = bx->lo[1]; o->xy1.w = bx->hi[1];
        o->z01.z = bx->lo[2]; o->z01.w = bx->hi[2];
    }
}

/* The walk writes each leaf's triangles as it reaches the leaf: the tasks
 * below the top of the tree write their own, so the vertices are gathered
 * on every thread with no second pass over the section. */
static int32_t emit_leaf(flatten_state *st, const bvh_tmp_node *t)
{
    const uint32_t start = st->tri_count;
    for (uint32_t i = 0; i < t->count; ++i) as_spatial_tri4(st->b->mesh, t->refs[i].id, &st->tris[st->tri_count++]);
    if (t->count) st->leaf_count++; /* the empty sibling of a one-leaf tree is no leaf */
    return ~(int32_t)start;
}

static double box_area(const bvh_box *bx)
{
    return as_half_area6(bx->lo[0], bx->hi[0], bx->lo[1], bx->hi[1], bx->lo[2], bx->hi[2]);
}

static void flatten(flatten_state *st, int32_t tnode, uint64_t out_index, uint32_t depth, double area);

/* Reserves the ranges of the subtree under tnode for a task, or walks it
 * here when the task list cannot grow. */
static void defer_subtree(flatten_state *st, int32_t tnode, uint64_t out_index, uint32_t depth, double area)
{
    if (st->task_count == st->task_capacity) {
        const uint32_t cap = st->task_capacity ? 2 * st->task_capacity : 256;
        flatten_task *grown = realloc(st->tasks, sizeof(flatten_task) * cap);
        if (!grown) {
            flatten(st, tnode, out_index, depth, area);
            return;
        }
        st->tasks = grown;
        st->task_capacity = cap;
    }
    const bvh_tmp_node *t = &st->b->nodes[tnode];
    st->tasks[st->task_count++] = (flatten_task){tnode, depth, out_index, st->out_count, st->inner_pos, st->leaf_pos,
                                                 st->tri_count, area};
    st->out_count += t->inner - 1;
    st->tri_count += t->count;
    st->inner_pos += t->inner;
    st->leaf_pos += (uint64_t)t->inner + 1; /* a binary tree's leaves */
}

static void flatten(flatten_state *st, int32_t tnode, uint64_t out_index, uint32_t depth, double area)
{
    const bvh_tmp_node *t = &st->b->nodes[tnode];
    if (st->inner_terms) st->inner_terms[st->inner_pos++] = area;
    else as_sah_sum_add(&st->inner_sum, area);
    if (depth > st->max_depth) st->max_depth = depth;
    const int32_t kids[2] = {t->left, t->right};
    /* Reserve both inner children first so siblings are adjacent. The
     * own-bounds conversion back (bvh2_own_layout_ops.c) follows this very
     * rule, so that a round trip gives the same bytes. */
    int64_t slot[2] = {-1, -1};
    for (int k = 0; k < 2; ++k) {
        const bvh_tmp_node *c = &st->b->nodes[kids[k]];
        if (c->left >= 0) slot[k] = (int64_t)st->out_count++;
    }
    as_bvh2_node_t *o = &st->out[out_index];
    for (int k = 0; k < 2; ++k) {
        const bvh_tmp_node *c = &st->b->nodes[kids[k]];
        set_child_box(o, k, &c->box);
        if (slot[k] >= 0) {
            o->child[k] = (int32_t)slot[k];
            o->count[k] = 0;
        } else {
            if (c->count && depth + 1 > st->max_depth) st->max_depth = depth + 1;
            o->child[k] = emit_leaf(st, c);
            o->count[k] = c->count;
            if (c->count == 0) {
                const bvh_box inverted = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};
                set_child_box(o, k, &inverted);
            }
            /* An empty leaf's term is +0, which leaves the sum's bits alone. */
            const double term = c->count ? box_area(&c->box) * c->count : 0.0;
            if (st->leaf_terms) st->leaf_terms[st->leaf_pos++] = term;
            else as_sah_sum_add(&st->leaf_sum, term);
        }
    }
    for (int k = 0; k < 2; ++k) {
        if (slot[k] < 0) continue;
        const bvh_tmp_node *c = &st->b->nodes[kids[k]];
        if (c->inner <= st->grain) defer_subtree(st, kids[k], (uint64_t)slot[k], depth + 1, box_area(&c->box));
        else flatten(st, kids[k], (uint64_t)slot[k], depth + 1, box_area(&c->box));
    }
}

/* Subtree sizes of the inner nodes whose subtrees were built by more than
 * one task (bvh_node_complete left them unknown): the top of the tree. */
static void complete_counts(bvh_builder *b, int32_t node)
{
    bvh_tmp_node *n = &b->nodes[node];
    if (n->left < 0 || n->inner) return;
    complete_counts(b, n->left);
    complete_counts(b, n->right);
    bvh_node_complete(b, node, 0);
}

typedef struct walk_job {
    const flatten_state *top;
    atomic_uint next;
    struct {
        uint64_t leaf_count;
        uint32_t max_depth;
        int bad;
    } part[256];
} walk_job;

/* Writes tasks, taken in order from a shared counter, until none is left. */
static void walk_tasks(void *user, unsigned i, unsigned n)
{
    (void)n;
    walk_job *j = user;
    flatten_state st = *j->top;
    st.grain = 0;
    st.leaf_count = 0;
    st.max_depth = 0;
    int bad = 0;
    for (;;) {
        const uint32_t k = atomic_fetch_add_explicit(&j->next, 1, memory_order_relaxed);
        if (k >= j->top->task_count) break;
        const flatten_task *t = &j->top->tasks[k];
        const bvh_tmp_node *tn = &st.b->nodes[t->tnode];
        st.out_count = t->out_next;
        st.tri_count = t->tri_next;
        st.inner_pos = t->inner_pos;
        st.leaf_pos = t->leaf_pos;
        flatten(&st, t->tnode, t->out_index, t->depth, t->area);
        if (st.out_count != t->out_next + tn->inner - 1 || st.tri_count != t->tri_next + tn->count) bad = 1;
    }
    j->part[i].leaf_count = st.leaf_count;
    j->part[i].max_depth = st.max_depth;
    j->part[i].bad = bad;
}

/* Trees with fewer inner nodes than this are written by one thread. */
#define BVH_WALK_MT_MIN_NODES 2048

/* Writes the tree under root into out and tris, filling st's counts and SAH
 * sums; on several threads when asked and the tree is big enough. Returns 0
 * when the subtree sizes disagree with what was written. */
static int write_tree(flatten_state *st, int32_t root, double root_area, unsigned threads)
{
    const uint32_t inner = st->b->nodes[root].inner;
    if (threads > 256) threads = 256;
    if (threads > 1 && inner >= BVH_WALK_MT_MIN_NODES) {
        st->inner_terms = as_temp_take(sizeof(double) * inner, "BVH SAH terms");
        st->leaf_terms = as_temp_take(sizeof(double) * ((size_t)inner + 1), "BVH SAH terms");
        if (!st->inner_terms || !st->leaf_terms) {
            as_temp_give(st->inner_terms);
            as_temp_give(st->leaf_terms);
            st->inner_terms = st->leaf_terms = NULL;
        }
    }
    if (!st->inner_terms) {
        flatten(st, root, 0, 0, root_area);
        return 1;
    }
    /* About 32 tasks per thread, so that the last one to finish leaves the
     * others idle for little. */
    st->grain = inner / (32 * threads);
    flatten(st, root, 0, 0, root_area);
    /* The reserved ranges cover every position exactly. */
    const int ok = st->inner_pos == inner && st->leaf_pos == (uint64_t)inner + 1;
    int bad = 0;
    if (ok) {
        walk_job job;
        job.top = st;
        atomic_init(&job.next, 0);
        as_parallel_run(threads, walk_tasks, &job);
        for (unsigned i = 0; i < threads; ++i) {
            st->leaf_count += job.part[i].leaf_count;
            if (job.part[i].max_depth > st->max_depth) st->max_depth = job.part[i].max_depth;
            bad |= job.part[i].bad;
        }
        st->inner_sum = as_sah_sum_terms(st->inner_terms, inner, threads);
        st->leaf_sum = as_sah_sum_terms(st->leaf_terms, (uint64_t)inner + 1, threads);
    }
    as_temp_give(st->inner_terms);
    as_temp_give(st->leaf_terms);
    free(st->tasks);
    st->inner_terms = st->leaf_terms = NULL;
    st->tasks = NULL;
    return ok && !bad;
}

as_error_t bvh_builder_finish(bvh_builder *b, int32_t root, uint32_t builder_id, as_structure_t *s,
                              double t_start)
{
    if (atomic_load(&b->cancelled))
        return as_set_error(AS_ERROR_CANCELLED, "BVH build cancelled by the progress callback");
    /* The root is always an inner node: a tree of one leaf becomes a root
     * with that leaf and an empty sibling. */
    if (b->nodes[root].left < 0) {
        const int32_t l = bvh_new_node(b), r = bvh_new_node(b);
        if (l < 0 || r < 0) return as_set_error(AS_ERROR_UNKNOWN, "BVH build node capacity exhausted");
        b->nodes[l] = b->nodes[root];
        b->nodes[r].box = bvh_box_empty();
        b->nodes[r].left = b->nodes[r].right = -1;
        b->nodes[r].refs = NULL;
        b->nodes[r].count = b->nodes[r].inner = 0;
        bvh_make_inner(b, root, l, r);
        atomic_fetch_add(&b->inner_count, 1);
    }
    complete_counts(b, root);
    /* One per split (bvh_local_flush counted them); every leaf
     * reported its references to the progress count. */
    const uint64_t inner = atomic_load(&b->inner_count);
    const uint64_t refs = atomic_load(&b->prims_done);
    if (refs > INT32_MAX) return as_set_error(AS_ERROR_UNSUPPORTED, "%llu references exceed the 31-bit TRI4 range",
                                              (unsigned long long)refs);
    if (b->nodes[root].inner != inner || b->nodes[root].count != refs)
        return as_set_error(AS_ERROR_UNKNOWN, "BVH build bookkeeping: %u inner nodes and %u references in the tree, %llu and %llu counted",
                            b->nodes[root].inner, b->nodes[root].count, (unsigned long long)inner,
                            (unsigned long long)refs);
    as_bvh2_node_t *out = as_aligned_alloc(sizeof(as_bvh2_node_t) * inner, "BVH2 nodes");
    as_tri4_t *tris = as_aligned_alloc(sizeof(as_tri4_t) * (size_t)(refs ? refs : 1), "TRI4 triangles");
    if (!out || !tris) {
        free(out);
        free(tris);
        return as_get_error();
    }
    /* No memset: the walk writes every field of every node (64 bytes, no
     * padding, asserted in bvh2_layout.h). */
    const as_mesh_t *mesh = b->mesh;
    const double root_area = as_half_area6(mesh->bounds_lo[0], mesh->bounds_hi[0], mesh->bounds_lo[1],
                                           mesh->bounds_hi[1], mesh->bounds_lo[2], mesh->bounds_hi[2]);
    flatten_state st;
    memset(&st, 0, sizeof st);
    st.b = b;
    st.out = out;
    st.out_count = 1;
    st.tris = tris;
    const unsigned threads = (unsigned)b->max_threads + 1;
    const int ok = write_tree(&st, root, root_area, threads);
    if (!ok || st.out_count != inner || st.tri_count != refs) {
        free(out);
        free(tris);
        return as_set_error(AS_ERROR_UNKNOWN, "BVH build bookkeeping: %llu nodes and %u references written, %llu and %llu counted",
                            (unsigned long long)st.out_count, st.tri_count, (unsigned long long)inner,
                            (unsigned long long)refs);
    }

    const as_build_args_t *args = b->args;
    as_structure_t cb;
    memset(&cb, 0, sizeof cb);
    as_structure_t *d = args->layout == AS_LAYOUT_BVH2_OWN_BOUNDS ? &cb : s;
    as_spatial_meta(d, mesh, args, AS_STRUCT_BVH, AS_LAYOUT_BVH2_CHILD_BOUNDS, AS_BVH2_LAYOUT_VERSION, builder_id);
    d->meta.bin_count = args->bin_count;
    d->meta.node_count = st.out_count;
    d->meta.leaf_count = st.leaf_count;
    d->meta.max_depth = st.max_depth;
    d->meta.reference_count = st.tri_count;
    d->meta.max_depth_limit = b->depth_limit;
    if (builder_id == AS_BUILDER_BVH_SBVH) {
        d->meta.split_budget = args->split_budget;
        d->meta.sbvh_alpha = args->sbvh_alpha;
    }
    as_structure_add_kept_section(d, ASF_TAG_BVH2, out, st.out_count, sizeof(as_bvh2_node_t),
                                  sizeof(as_bvh2_node_t) * inner);
    as_structure_add_kept_section(d, ASF_TAG_TRI4, tris, st.tri_count, sizeof(as_tri4_t),
                                  sizeof(as_tri4_t) * (size_t)(refs ? refs : 1));
    d->meta.sah_cost = as_bvh2_sah_from_sums(args->cost_traversal, args->cost_intersection, root_area,
                                             as_sah_sum_value(&st.inner_sum), as_sah_sum_value(&st.leaf_sum), st.out_count,
                                             st.tri_count);
    as_error_t err = AS_OK;
    if (d == &cb) {
        err = as_bvh2_to_own_bounds(&cb, s);
        for (uint32_t i = 0; i < cb.section_count; ++i) free(cb.sections[i].owned);
    }
    s->build_ms = as_now_ms() - t_start;
    return err;
}
