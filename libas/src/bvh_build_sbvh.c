/* BVH builder with spatial splits, SBVH (Stich, Friedrich & Dietrich 2009,
 * "Spatial splits in bounding volume hierarchies"), written into the BVH2
 * child-bounds layout by bvh_build_common.c. A triangle may be referenced by
 * several leaves: TRI4 then holds one entry per reference.
 *
 * At each node: the binned SAH object split (Wald 2007); when its two
 * children overlap by more than sbvh_alpha of the root's area, also the
 * binned spatial split (section 4.3: each reference chopped into the bins
 * it spans, entry and exit counts per bin), then the cheapest of leaf,
 * object split and spatial split. A reference that straddles the chosen
 * plane is clipped (section 4.4: the box of the triangle's part on each side,
 * computed from its edges' intersections with the plane, within the
 * reference's box), or kept whole on one side when that is cheaper
 * (reference unsplitting, section 4.5).
 *
 * Exactness: clipped boxes are rounded outward (the intersection points are
 * computed in double, then rounded down for lo and up for hi, one ulp more),
 * so the boxes of a triangle's references always cover the whole triangle
 * and no ray slips between two pieces.
 *
 * Budget and termination: the tree may hold at most split_budget x N
 * references. Each node receives a share of the remaining extra references
 * (the root: (split_budget - 1) x N), spends what its split duplicates and
 * passes the rest to its children in proportion to their sizes, so the
 * budget, and with it the tree, depends on nothing but the input: the output
 * is the same for any thread count. The depth cap ends every path. */
#include "bvh_build_common.h"
#include "task_pool.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Spatial bins per axis, at most: a reference costs one cut per bin it
 * spans, and 16 bins gave the same SAH cost as 32 on our scenes (within the
 * few per cent that greedy top-down choices move it either way) in 20% less
 * time. */
#define SBVH_SPATIAL_BINS 16u
/* Nodes of at most SBVH_SMALL_NODE references bin into this many. */
#define SBVH_SMALL_NODE 32u
#define SBVH_SMALL_NODE_SPATIAL_BINS 8u

/* Where a spatial split is searched for, beside the paper's rule (the
 * object split's children overlap by more than sbvh_alpha of the root's
 * area):
 * - nodes of more than SBVH_SPATIAL_MIN_REFS references: the bunny spent a
 *   fifth of its build binning the smaller ones, and its SAH cost moved
 *   from 31.2162 to 31.2177 without them;
 * - in nodes of at most SBVH_OVERLAP_NODE_REFS references, only where the
 *   overlap is at least SBVH_OVERLAP_NODE_FRACTION of the node's own area
 *   (Embree's rule). Small nodes rarely gain from a spatial split (in the
 *   bunny's nodes of 32 to 2,047 references, 11 of the 3,197 searched).
 *   Larger ones keep the paper's rule alone: there a spatial split pays
 *   even where the overlap is a small part of a big box (with Embree's rule
 *   in every node, bmw-m6's SAH cost rose 3.6%).
 * Together they took the bunny's SBVH from 80 to 50 ms on 2 cores, SAH
 * cost within 0.3% either way on the five scenes of the build benchmark. */
#define SBVH_SPATIAL_MIN_REFS 4u
#define SBVH_OVERLAP_NODE_REFS 1024u
#define SBVH_OVERLAP_NODE_FRACTION 0.1

/* Reference memory, one per running task (a thread builds one task at a
 * time), kept for the whole build and handed from task to task:
 *
 * - an arena for the sides of nodes below SBVH_SHARE_MIN_PRIMS, whose
 *   subtrees this thread builds alone, depth first: a node's sides are
 *   taken from the top and given back when both children's subtrees are
 *   done (larger nodes, whose right side may go to another task, and sides
 *   that do not fit, come from malloc);
 * - a store for the leaves' references, copied in when a leaf is made and
 *   freed in chunks at the end.
 *
 * So a split below that size costs no malloc and no free, the leaves need
 * no free of their own (which one thread did for every leaf after the
 * output walk), and the arena is reused while it is still in the cache. */
/* Right children down to this size may go to a thread that waits for
 * work. At 4,096 (BVH_PARALLEL_MIN_PRIMS), 16 threads spent the last
 * quarter of a bunny build waiting on a few subtrees of 2,000 to 4,000
 * references, each several milliseconds of spatial binning; at 1,024 the
 * build took 0.72 of the time on an H100 host's 16 cores (staircase 0.90),
 * and at 256 0.93 of that again (staircase2 0.83), 2 cores 0.97 to 0.99. */
#define SBVH_SHARE_MIN_PRIMS 256u
#define SBVH_ARENA_REFS 32768u      /* 1 MB: a path of sides below SBVH_SHARE_MIN_PRIMS, many times over */
#define SBVH_LEAF_CHUNK_REFS 2048u  /* 64 KB */

/* Sides of nodes of at least SBVH_SPARE_MIN_REFS references come from the
 * arrays that split nodes of that size gave back, when one is large enough,
 * and only otherwise from malloc: at the top of the tree each side is a new
 * array as large as the node, whose pages the one thread that partitions it
 * faults in while the others may wait (bmw-m6, two threads: the root's
 * partition took 18 ms and its left child's 14 ms, mostly those faults). A
 * split gives back its node's array as it takes two, so about half of the
 * sides' pages are reused. At most SBVH_SPARE_MAX arrays wait, freed at the
 * end of the build. Only with more than one build thread: with one, whose
 * frees malloc reuses by itself, the build was slower with spares (1.06 to
 * 1.19 times its time before on staircase, bathroom and bmw-m6, 4 rounds;
 * why was not found). */
#define SBVH_SPARE_MIN_REFS 65536u  /* 2 MB */
/* Arrays of at least this many references (4 MB) are blocks that earlier
 * builds of the process gave back (as_block_take) when one fits, and go
 * back to them (as_block_give). */
#define SBVH_BLOCK_MIN_REFS 131072u
#define SBVH_SPARE_MAX 4u

typedef struct sbvh_chunk {
    struct sbvh_chunk *next;
    char pad[32 - sizeof(void *)];  /* the references start 32 bytes in */
} sbvh_chunk;

struct sbvh_ctx;

typedef struct sbvh_mem {
    struct sbvh_mem *next_free, *next_all;
    struct sbvh_ctx *ctx;
    bvh_ref *arena;
    uint32_t arena_top;
    bvh_ref *leaf;               /* the current chunk's references */
    uint32_t leaf_top, leaf_cap;
    sbvh_chunk *chunks;          /* every leaf chunk, freed at the end */
} sbvh_mem;

typedef struct sbvh_ctx {
    bvh_builder *b;
    double alpha_area;   /* overlap threshold: sbvh_alpha x root half area */
    float fraction[SBVH_SPATIAL_BINS + 1]; /* i / bins, for the planes */
    uint32_t fraction_bins;                /* the planes of fraction: the spatial bins of a large node */
    pthread_mutex_t mem_lock;
    sbvh_mem *free_mems, *all_mems;
    atomic_int out_of_memory;    /* a leaf could not be stored */
    bvh_ref *spare[SBVH_SPARE_MAX];   /* large arrays given back, for the next sides (under mem_lock) */
    uint32_t spare_cap[SBVH_SPARE_MAX];
    unsigned spare_count;
    int recycle;                      /* keep spares: builds on more than one thread */
} sbvh_ctx;

/* A malloc'd reference array of room for at least cap references (*got:
 * its room): a spare one when one is large enough (the smallest such), else
 * a new one. */
static bvh_ref *block_acquire(sbvh_ctx *ctx, uint32_t cap, uint32_t *got)
{
    *got = cap;
    if (ctx && cap >= SBVH_SPARE_MIN_REFS) {
        pthread_mutex_lock(&ctx->mem_lock);
        unsigned best = SBVH_SPARE_MAX;
        for (unsigned i = 0; i < ctx->spare_count; ++i)
            if (ctx->spare_cap[i] >= cap && (best == SBVH_SPARE_MAX || ctx->spare_cap[i] < ctx->spare_cap[best])) best = i;
        if (best < SBVH_SPARE_MAX) {
            bvh_ref *p = ctx->spare[best];
            *got = ctx->spare_cap[best];
            ctx->spare_count--;
            ctx->spare[best] = ctx->spare[ctx->spare_count];
            ctx->spare_cap[best] = ctx->spare_cap[ctx->spare_count];
            pthread_mutex_unlock(&ctx->mem_lock);
            return p;
        }
        pthread_mutex_unlock(&ctx->mem_lock);
    }
    /* Large ones from the blocks earlier builds gave back (as_block_take):
     * at the top of the tree a fresh side faults in a page per 4 KB. */
    if (cap >= SBVH_BLOCK_MIN_REFS) return as_block_take(sizeof(bvh_ref) * (size_t)cap, 0, "SBVH references");
    return malloc(sizeof(bvh_ref) * (size_t)cap);
}

/* Gives back a malloc'd array of room for cap references: kept as a spare
 * when it is large and there is room, else freed. */
static void block_release(sbvh_ctx *ctx, bvh_ref *p, uint32_t cap)
{
    if (!p) return;
    if (ctx && ctx->recycle && cap >= SBVH_SPARE_MIN_REFS) {
        pthread_mutex_lock(&ctx->mem_lock);
        if (ctx->spare_count < SBVH_SPARE_MAX) {
            ctx->spare[ctx->spare_count] = p;
            ctx->spare_cap[ctx->spare_count++] = cap;
            p = NULL;
        }
        pthread_mutex_unlock(&ctx->mem_lock);
    }
    if (p && cap >= SBVH_BLOCK_MIN_REFS) as_block_give(p, sizeof(bvh_ref) * (size_t)cap, 0);
    else free(p);
}

static sbvh_mem *mem_acquire(sbvh_ctx *ctx)
{
    pthread_mutex_lock(&ctx->mem_lock);
    sbvh_mem *m = ctx->free_mems;
    if (m) {
        ctx->free_mems = m->next_free;
    } else if ((m = calloc(1, sizeof *m)) != NULL) {
        m->ctx = ctx;
        m->arena = malloc(sizeof(bvh_ref) * SBVH_ARENA_REFS); /* NULL: every side from malloc */
        m->next_all = ctx->all_mems;
        ctx->all_mems = m;
    }
    pthread_mutex_unlock(&ctx->mem_lock);
    return m;
}

static void mem_release(sbvh_ctx *ctx, sbvh_mem *m)
{
    if (!m) return;
    pthread_mutex_lock(&ctx->mem_lock);
    m->next_free = ctx->free_mems;
    ctx->free_mems = m;
    pthread_mutex_unlock(&ctx->mem_lock);
}

static void mem_free_all(sbvh_ctx *ctx)
{
    for (sbvh_mem *m = ctx->all_mems, *next; m; m = next) {
        next = m->next_all;
        for (sbvh_chunk *c = m->chunks, *cn; c; c = cn) {
            cn = c->next;
            free(c);
        }
        free(m->arena);
        free(m);
    }
    ctx->all_mems = ctx->free_mems = NULL;
    for (unsigned i = 0; i < ctx->spare_count; ++i) block_release(NULL, ctx->spare[i], ctx->spare_cap[i]);
    ctx->spare_count = 0;
}

/* A copy of a leaf's references in the store; NULL when count is 0 or no
 * memory is left. */
static bvh_ref *leaf_store(sbvh_mem *m, const bvh_ref *refs, uint32_t count)
{
    if (!m || count == 0) return NULL;
    if (count > m->leaf_cap - m->leaf_top) {
        const uint32_t cap = count > SBVH_LEAF_CHUNK_REFS ? count : SBVH_LEAF_CHUNK_REFS;
        sbvh_chunk *c = malloc(sizeof(sbvh_chunk) + sizeof(bvh_ref) * (size_t)cap);
        if (!c) return NULL;
        c->next = m->chunks;
        m->chunks = c;
        m->leaf = (bvh_ref *)(c + 1);
        m->leaf_top = 0;
        m->leaf_cap = cap;
    }
    bvh_ref *dst = m->leaf + m->leaf_top;
    memcpy(dst, refs, sizeof(bvh_ref) * count);
    m->leaf_top += count;
    return dst;
}

/* ---- reference clipping */

static inline float round_down(double d)
{
    float f = (float)d;
    if ((double)f > d) f = as_float_next_down(f);
    return as_float_next_down(f);
}

static inline float round_up(double d)
{
    float f = (float)d;
    if ((double)f < d) f = as_float_next_up(f);
    return as_float_next_up(f);
}

static void grow_point(bvh_box *bx, const float p[3])
{
    bvh_box_grow(bx, p, p);
}

static int box_valid(const bvh_box *bx)
{
    return bx->lo[0] <= bx->hi[0] && bx->lo[1] <= bx->hi[1] && bx->lo[2] <= bx->hi[2];
}

/* Splits reference r at plane `pos` on `axis` into the boxes of the
 * triangle's parts on each side, each within r's box; an invalid (inverted)
 * box when the part is empty. */
static inline void split_ref(const as_mesh_t *mesh, const bvh_ref *r, int axis, float pos, bvh_box *left, bvh_box *right)
{
    *left = bvh_box_empty();
    *right = bvh_box_empty();
    const uint32_t *ix = mesh->indices + 3 * (size_t)r->id;
    const float *v[3] = {mesh->positions + 3 * (size_t)ix[0], mesh->positions + 3 * (size_t)ix[1],
                         mesh->positions + 3 * (size_t)ix[2]};
    for (int e = 0; e < 3; ++e) {
        const float *v0 = v[e], *v1 = v[(e + 1) % 3];
        const float p0 = v0[axis], p1 = v1[axis];
        if (p0 <= pos) grow_point(left, v0);
        if (p0 >= pos) grow_point(right, v0);
        if ((p0 < pos && p1 > pos) || (p0 > pos && p1 < pos)) {
            const double t = ((double)pos - p0) / ((double)p1 - p0);
            float lo[3], hi[3];
            for (int a = 0; a < 3; ++a) {
                if (a == axis) { lo[a] = hi[a] = pos; continue; }
                const double x = (double)v0[a] + t * ((double)v1[a] - v0[a]);
                lo[a] = round_down(x);
                hi[a] = round_up(x);
            }
            bvh_box_grow(left, lo, hi);
            bvh_box_grow(right, lo, hi);
        }
    }
    if (left->hi[axis] > pos) left->hi[axis] = pos;
    if (right->lo[axis] < pos) right->lo[axis] = pos;
    for (int a = 0; a < 3; ++a) {
        if (left->lo[a] < r->lo[a]) left->lo[a] = r->lo[a];
        if (left->hi[a] > r->hi[a]) left->hi[a] = r->hi[a];
        if (right->lo[a] < r->lo[a]) right->lo[a] = r->lo[a];
        if (right->hi[a] > r->hi[a]) right->hi[a] = r->hi[a];
    }
}

/* ---- spatial split search */


typedef struct spatial_split {
    int axis;            /* -1: none */
    float pos;
    double cost;         /* half-area x count, both sides */
    bvh_box left, right; /* the sides' boxes as binned */
    uint32_t nl, nr;
} spatial_split;


/* The triangle's cross-section with the plane at `pos` on `axis`, whose
 * vertices p[0..2] are sorted along it (x[i]): the point on the long edge
 * and the one on the short edge the plane crosses. Float, no outward
 * rounding: the bin search only estimates (the partition clips exactly). */
static inline void cross_section(const v4f p[3], const float x[3], float pos, v4f *a, v4f *b)
{
    *a = v4f_add(p[0], v4f_mul(v4f_set1((pos - x[0]) / (x[2] - x[0])), v4f_sub(p[2], p[0])));
    if (pos < x[1]) *b = v4f_add(p[0], v4f_mul(v4f_set1((pos - x[0]) / (x[1] - x[0])), v4f_sub(p[1], p[0])));
    else if (x[2] > x[1]) *b = v4f_add(p[1], v4f_mul(v4f_set1((pos - x[1]) / (x[2] - x[1])), v4f_sub(p[2], p[1])));
    else *b = p[1];
}

/* Spatial bins (Stich et al. section 4.3), all three axes in one pass over
 * the references: a reference inside one bin grows it with its box; one
 * that spans several is cut into the bins it spans, each part the box of the
 * triangle's cross-sections at the part's planes and of its vertices
 * between them, within the reference's box. */
/* A node's spatial binning frame: per axis whether it is binned, the bin
 * planes and the lane masks of the slab clamp. */
typedef struct spatial_frame {
    uint32_t nb;
    int use[3];
    float planes[3][SBVH_SPATIAL_BINS + 1];
    v4f vlo, vscale, last;
    v4f slab_lo[3], slab_hi[3];
} spatial_frame;

typedef struct spatial_bins {
    v4f lo[3][SBVH_SPATIAL_BINS], hi[3][SBVH_SPATIAL_BINS];
    uint32_t enter[3][SBVH_SPATIAL_BINS], leave[3][SBVH_SPATIAL_BINS];
    uint32_t occupied[3];
} spatial_bins;

/* Bins refs[0, count) into sb (initialised here). Each bin ends as the
 * exact union and counts of what falls in it, so chunks binned apart and
 * merged give the bins of one pass. */
static void spatial_bin(const bvh_builder *b, const spatial_frame *f, const bvh_ref *refs, uint32_t count, spatial_bins *sb)
{
    const uint32_t nb = f->nb;
    const v4f empty_lo = v4f_set1(INFINITY), empty_hi = v4f_set1(-INFINITY), zero = v4f_set1(0.0f);
    for (int axis = 0; axis < 3; ++axis) {
        sb->occupied[axis] = 0;
        for (uint32_t i = 0; i < nb; ++i) {
            sb->lo[axis][i] = empty_lo;
            sb->hi[axis][i] = empty_hi;
            sb->enter[axis][i] = sb->leave[axis][i] = 0;
        }
    }
    for (uint32_t i = 0; i < count; ++i) {
        const bvh_ref *r = &refs[i];
        const v4f lo = v4f_load3(r->lo), hi = bvh_ref_load_hi(r->hi);
        int32_t k0[4], k1[4];
        v4f_to_i32(v4f_min(v4f_max(v4f_mul(v4f_sub(lo, f->vlo), f->vscale), zero), f->last), k0);
        v4f_to_i32(v4f_min(v4f_max(v4f_mul(v4f_sub(hi, f->vlo), f->vscale), zero), f->last), k1);
        const float *v[3] = {NULL, NULL, NULL};
        for (int axis = 0; axis < 3; ++axis) {
            if (!f->use[axis]) continue;
            const int b0 = k0[axis], b1 = k1[axis];
            sb->enter[axis][b0]++;
            sb->leave[axis][b1]++;
            if (b0 == b1) {
                sb->lo[axis][b0] = v4f_min(sb->lo[axis][b0], lo);
                sb->hi[axis][b0] = v4f_max(sb->hi[axis][b0], hi);
                sb->occupied[axis] |= 1u << b0;
                continue;
            }
            if (!v[0]) {
                const uint32_t *ix = b->mesh->indices + 3 * (size_t)r->id;
                for (int j = 0; j < 3; ++j) v[j] = b->mesh->positions + 3 * (size_t)ix[j];
            }
            /* The vertices sorted along the axis. */
            int o0 = 0, o1 = 1, o2 = 2, t;
            if (v[o1][axis] < v[o0][axis]) { t = o0; o0 = o1; o1 = t; }
            if (v[o2][axis] < v[o1][axis]) { t = o1; o1 = o2; o2 = t; }
            if (v[o1][axis] < v[o0][axis]) { t = o0; o0 = o1; o1 = t; }
            const float x[3] = {v[o0][axis], v[o1][axis], v[o2][axis]};
            const v4f p[3] = {v4f_set3(v[o0]), v4f_set3(v[o1]), v4f_set3(v[o2])};
            float rlo[4], rhi[4];
            v4f_store(rlo, lo);
            v4f_store(rhi, hi);
            v4f low_a = zero, low_b = zero; /* the cross-section at the part's lower plane */
            for (int k = b0; k <= b1; ++k) {
                const float lower = k == b0 ? rlo[axis] : f->planes[axis][k];
                const float upper = k == b1 ? rhi[axis] : f->planes[axis][k + 1];
                v4f plo = empty_lo, phi = empty_hi;
                if (k > b0) {
                    plo = v4f_min(low_a, low_b);
                    phi = v4f_max(low_a, low_b);
                }
                if (k < b1 && x[2] > x[0]) {
                    cross_section(p, x, upper, &low_a, &low_b);
                    plo = v4f_min(plo, v4f_min(low_a, low_b));
                    phi = v4f_max(phi, v4f_max(low_a, low_b));
                }
                for (int j = 0; j < 3; ++j)
                    if (x[j] >= lower && x[j] <= upper) {
                        plo = v4f_min(plo, p[j]);
                        phi = v4f_max(phi, p[j]);
                    }
                /* Within the reference's box and the part's slab. The slab
                 * is clamped in registers (max(lower, x) is "x < lower ?
                 * lower : x"): a store, a store to one lane and a load of
                 * all four would stall store forwarding, once per part. */
                plo = v4f_max(v4f_min(v4f_set1(lower), f->slab_lo[axis]), v4f_max(plo, lo));
                phi = v4f_min(v4f_max(v4f_set1(upper), f->slab_hi[axis]), v4f_min(phi, hi));
                if ((v4f_le_mask(plo, phi) & 7) != 7) continue;
                sb->lo[axis][k] = v4f_min(sb->lo[axis][k], plo);
                sb->hi[axis][k] = v4f_max(sb->hi[axis][k], phi);
                sb->occupied[axis] |= 1u << k;
            }
        }
    }
}

static void spatial_bins_merge(spatial_bins *to, const spatial_bins *from, uint32_t nb)
{
    for (int axis = 0; axis < 3; ++axis) {
        to->occupied[axis] |= from->occupied[axis];
        for (uint32_t i = 0; i < nb; ++i) {
            to->lo[axis][i] = v4f_min(to->lo[axis][i], from->lo[axis][i]);
            to->hi[axis][i] = v4f_max(to->hi[axis][i], from->hi[axis][i]);
            to->enter[axis][i] += from->enter[axis][i];
            to->leave[axis][i] += from->leave[axis][i];
        }
    }
}

/* The node's references in pieces taken in turn from a shared counter
 * (bvh_piece_count): a helper thread without a core delays nothing. */
typedef struct par_spatial_job {
    const bvh_builder *b;
    const spatial_frame *f;
    const bvh_ref *refs;
    uint32_t count, pieces;
    atomic_uint next;
    spatial_bins *bins;   /* 2 per thread: bins[c] its sum, bins[n + c] its scratch */
} par_spatial_job;

static void par_spatial(void *user, unsigned c, unsigned n)
{
    par_spatial_job *j = user;
    spatial_bins *acc = &j->bins[c], *tmp = &j->bins[n + c];
    /* Unions and sums are exact: the merged bins are those of one pass
     * whoever binned which piece. */
    spatial_bin(j->b, j->f, j->refs, 0, acc); /* empty bins */
    for (;;) {
        const uint32_t k = atomic_fetch_add_explicit(&j->next, 1, memory_order_relaxed);
        if (k >= j->pieces) break;
        const uint32_t first = (uint32_t)((uint64_t)j->count * k / j->pieces);
        const uint32_t end = (uint32_t)((uint64_t)j->count * (k + 1) / j->pieces);
        spatial_bin(j->b, j->f, j->refs + first, end - first, tmp);
        spatial_bins_merge(acc, tmp, j->f->nb);
    }
}

static spatial_split find_spatial_split(const sbvh_ctx *ctx, const bvh_ref *refs, uint32_t count, const bvh_box *node_box,
                                        unsigned threads)
{
    const bvh_builder *b = ctx->b;
    spatial_frame fr;
    /* Small nodes: half the planes. There most references straddle several
     * bins and are clipped at each, which made spatial binning two thirds
     * of the bunny's build; with 8 planes the bunny builds in 0.82 of the
     * time, and the SAH cost moved by -0.3% (bmw-m6) to +0.15% (staircase). */
    uint32_t nb = ctx->fraction_bins;
    if (count <= SBVH_SMALL_NODE && nb > SBVH_SMALL_NODE_SPATIAL_BINS && nb % SBVH_SMALL_NODE_SPATIAL_BINS == 0)
        nb = SBVH_SMALL_NODE_SPATIAL_BINS;
    fr.nb = nb;
    spatial_split best;
    memset(&best, 0, sizeof best);
    best.axis = -1;
    best.cost = INFINITY;
    int *use = fr.use;
    float nlo[4] = {0, 0, 0, 0}, scale[4] = {0, 0, 0, 0};
    for (int axis = 0; axis < 3; ++axis) {
        const float extent = node_box->hi[axis] - node_box->lo[axis];
        nlo[axis] = node_box->lo[axis];
        scale[axis] = extent > 0.0f ? (float)nb / extent : 0.0f;
        use[axis] = extent > 0.0f && isfinite(scale[axis]);
        if (!use[axis]) scale[axis] = 0.0f;
    }
    if (!use[0] && !use[1] && !use[2]) return best;
    for (int axis = 0; axis < 3; ++axis)
        for (uint32_t i = 0; i <= nb; ++i)
            fr.planes[axis][i] = node_box->lo[axis] + (node_box->hi[axis] - node_box->lo[axis]) * ctx->fraction[i * (ctx->fraction_bins / nb)];
    fr.vlo = v4f_load(nlo);
    fr.vscale = v4f_load(scale);
    fr.last = v4f_set1((float)(nb - 1));
    /* Per axis: +inf in its lane and -inf elsewhere (slab_lo), the opposite
     * (slab_hi), so that min(set1(lower), slab_lo) is lower on the axis and
     * leaves the other lanes alone under a max. */
    for (int axis = 0; axis < 3; ++axis) {
        float l[4] = {-INFINITY, -INFINITY, -INFINITY, -INFINITY}, h[4] = {INFINITY, INFINITY, INFINITY, INFINITY};
        l[axis] = INFINITY;
        h[axis] = -INFINITY;
        fr.slab_lo[axis] = v4f_load(l);
        fr.slab_hi[axis] = v4f_load(h);
    }
    /* No index without a piece to take (see bvh_find_object_split_mt). */
    const uint32_t pieces = bvh_piece_count(count, threads);
    if (threads > pieces) threads = pieces;
    /* A build temporary, as the object bins (bvh_find_object_split_mt). */
    spatial_bins one, *many = threads > 1 ? as_temp_take(sizeof(spatial_bins) * 2 * threads, "SBVH bins") : NULL, *sb = &one;
    if (many) {
        par_spatial_job j;
        j.b = b;
        j.f = &fr;
        j.refs = refs;
        j.count = count;
        j.pieces = pieces;
        atomic_init(&j.next, 0);
        j.bins = many;
        as_parallel_run(threads, par_spatial, &j);
        for (unsigned c = 1; c < threads; ++c) spatial_bins_merge(&many[0], &many[c], nb);
        sb = &many[0];
    } else {
        spatial_bin(b, &fr, refs, count, &one);
    }
    /* A reference's enter and leave bins hold parts of it, so a plane
     * between two bins without parts splits like the one after the last
     * occupied bin on its left: the shared sweep over occupied bins holds. */
    for (int axis = 0; axis < 3; ++axis) {
        if (!use[axis]) continue;
        uint32_t occ[SBVH_SPATIAL_BINS], m = 0;
        for (uint32_t bits = sb->occupied[axis]; bits; bits &= bits - 1) occ[m++] = (uint32_t)__builtin_ctz(bits);
        bvh_bin_sweep sw;
        if (!bvh_sweep_bins(sb->lo[axis], sb->hi[axis], sb->enter[axis], sb->leave[axis], nb, 0, occ, m, best.cost, &sw)) continue;
        best.axis = axis;
        best.pos = fr.planes[axis][sw.bin + 1];
        best.cost = sw.cost;
        best.left = sw.left;
        best.right = sw.right;
        best.nl = sw.left_count;
        best.nr = sw.right_count;
    }
    as_temp_give(many);
    return best;
}

/* ---- partitions into two new arrays */

/* Both sides of a split, each with room for every reference of the node:
 * from the arena (arena_mark: its top before, owned 0) or malloc'd
 * (block_acquire; lcap and rcap their room). */
typedef struct sides {
    bvh_ref *l, *r;
    uint32_t nl, nr;
    int owned;
    uint32_t arena_mark;
    uint32_t lcap, rcap;
    bvh_box lbox, rbox;  /* the sides' boxes */
    int centroids;       /* lcbox, rcbox hold the sides' centroid boxes (doubled) */
    bvh_box lcbox, rcbox;
} sides;

/* right_first: the right side is expected to be the larger, so it takes
 * the first (best-fitting) spare array, whose pages are already there. */
static int sides_alloc(sbvh_mem *m, uint32_t count, int right_first, sides *out)
{
    out->nl = out->nr = 0;
    out->centroids = 0;
    const uint32_t cap = count ? count : 1;
    if (m && m->arena && count < SBVH_SHARE_MIN_PRIMS && 2 * cap <= SBVH_ARENA_REFS - m->arena_top) {
        out->owned = 0;
        out->arena_mark = m->arena_top;
        out->l = m->arena + m->arena_top;
        out->r = out->l + cap;
        m->arena_top += 2 * cap;
        return 1;
    }
    out->owned = 1;
    sbvh_ctx *ctx = m ? m->ctx : NULL;
    if (right_first) {
        out->r = block_acquire(ctx, cap, &out->rcap);
        out->l = block_acquire(ctx, cap, &out->lcap);
    } else {
        out->l = block_acquire(ctx, cap, &out->lcap);
        out->r = block_acquire(ctx, cap, &out->rcap);
    }
    return out->l && out->r;
}

/* Gives the sides' memory back; arena sides must be the arena's last. */
static void sides_free(sbvh_mem *m, sides *s)
{
    if (s->owned) {
        sbvh_ctx *ctx = m ? m->ctx : NULL;
        block_release(ctx, s->l, s->lcap);
        block_release(ctx, s->r, s->rcap);
    } else if (s->l) {
        m->arena_top = s->arena_mark;
    }
    s->l = s->r = NULL;
    s->nl = s->nr = 0;
}

/* What a reference becomes in a partition: a left reference (bit 0), a
 * right one (bit 1), and with bit 2 both clipped at the plane (split_ref
 * gives their boxes; a side whose box is empty gets none). */
enum { PART_LEFT = 1, PART_RIGHT = 2, PART_CLIPPED = 4 };

/* A partition's plane and its prices: an object split (spatial NULL) or a
 * spatial one. */
typedef struct part_plan {
    const as_mesh_t *mesh;
    const bvh_object_split *object;
    const spatial_split *spatial;
    double al, ar, nl, nr;
} part_plan;

static part_plan plan_object(const as_mesh_t *mesh, const bvh_object_split *s)
{
    part_plan p;
    memset(&p, 0, sizeof p);
    p.mesh = mesh;
    p.object = s;
    return p;
}

static part_plan plan_spatial(const as_mesh_t *mesh, const spatial_split *s)
{
    part_plan p;
    memset(&p, 0, sizeof p);
    p.mesh = mesh;
    p.spatial = s;
    p.al = bvh_box_half_area(&s->left);
    p.ar = bvh_box_half_area(&s->right);
    p.nl = s->nl;
    p.nr = s->nr;
    return p;
}

/* The outcome of r (PART_*), with the clipped boxes when it is clipped.
 * Spatial: a straddling reference is clipped, or kept whole on the side
 * where the SAH says it costs less (unsplitting). */
static inline unsigned part_outcome(const part_plan *p, const bvh_ref *r, bvh_box *cl, bvh_box *cr)
{
    if (p->object) return bvh_object_split_left(r, p->object) ? PART_LEFT : PART_RIGHT;
    const spatial_split *s = p->spatial;
    const int axis = s->axis;
    const float pos = s->pos;
    if (r->hi[axis] <= pos) return PART_LEFT;
    if (r->lo[axis] >= pos) return PART_RIGHT;
    bvh_box lb = s->left, rb = s->right;
    bvh_box_grow(&lb, r->lo, r->hi);
    bvh_box_grow(&rb, r->lo, r->hi);
    const double c_split = p->al * p->nl + p->ar * p->nr;
    const double c_left = bvh_box_half_area(&lb) * p->nl + p->ar * (p->nr - 1);
    const double c_right = p->al * (p->nl - 1) + bvh_box_half_area(&rb) * p->nr;
    if (c_left < c_split && c_left <= c_right) return PART_LEFT;
    if (c_right < c_split) return PART_RIGHT;
    split_ref(p->mesh, r, axis, pos, cl, cr);
    bvh_box_no_negative_zero(cl);
    bvh_box_no_negative_zero(cr);
    const unsigned kept = (box_valid(cl) ? PART_LEFT : 0u) | (box_valid(cr) ? PART_RIGHT : 0u);
    return kept ? PART_CLIPPED | kept : PART_LEFT; /* none: cannot happen; never lose a triangle */
}

/* Writes r's references for outcome `o` at *l or *r, advancing them; cl
 * and cr are its clipped boxes, or NULL to clip it here. */
static inline void part_write(const part_plan *p, const bvh_ref *r, unsigned o, bvh_ref **l, bvh_ref **rr,
                              const bvh_box *cl, const bvh_box *cr)
{
    if (!(o & PART_CLIPPED)) {
        *(o == PART_LEFT ? (*l)++ : (*rr)++) = *r;
        return;
    }
    bvh_box kl, kr;
    if (!cl) {
        split_ref(p->mesh, r, p->spatial->axis, p->spatial->pos, &kl, &kr);
        bvh_box_no_negative_zero(&kl);
        bvh_box_no_negative_zero(&kr);
        cl = &kl;
        cr = &kr;
    }
    if (o & PART_LEFT) {
        bvh_ref *x = (*l)++;
        *x = *r;
        memcpy(x->lo, cl->lo, sizeof x->lo);
        memcpy(x->hi, cl->hi, sizeof x->hi);
    }
    if (o & PART_RIGHT) {
        bvh_ref *x = (*rr)++;
        *x = *r;
        memcpy(x->lo, cr->lo, sizeof x->lo);
        memcpy(x->hi, cr->hi, sizeof x->hi);
    }
}

/* A large node's partition in pieces on several threads: the first pass
 * records each reference's outcome and counts each piece's references per
 * side, the second writes each piece's where the pieces before it end, so
 * the sides are those of one pass in order. A clipped reference is clipped
 * again in the second pass (the same boxes). At the top of the tree one
 * thread partitioning alone kept 15 of 16 waiting: bathroom's root, 6 ms. */
typedef struct part_job {
    const part_plan *plan;
    const bvh_ref *refs;
    uint32_t count, pieces;
    uint8_t *outcome;
    uint32_t *nl, *nr;        /* per piece: its counts, then where it writes */
    bvh_box *lbox, *rbox;     /* per piece: its sides' boxes */
    bvh_box *lcbox, *rcbox;   /* per piece: its sides' centroid boxes (doubled) */
    sides *out;
    atomic_uint next;
} part_job;

static void part_count(void *user, unsigned c, unsigned n)
{
    (void)c;
    (void)n;
    part_job *j = user;
    for (;;) {
        const uint32_t k = atomic_fetch_add_explicit(&j->next, 1, memory_order_relaxed);
        if (k >= j->pieces) break;
        uint32_t first, end, nl = 0, nr = 0;
        as_chunk_range(j->count, k, j->pieces, &first, &end);
        for (uint32_t i = first; i < end; ++i) {
            bvh_box cl, cr;
            const unsigned o = part_outcome(j->plan, &j->refs[i], &cl, &cr);
            j->outcome[i] = (uint8_t)o;
            nl += (o & PART_LEFT) != 0;
            nr += (o & PART_RIGHT) != 0;
        }
        j->nl[k] = nl;
        j->nr[k] = nr;
    }
}

static void part_place(void *user, unsigned c, unsigned n)
{
    (void)c;
    (void)n;
    part_job *j = user;
    for (;;) {
        const uint32_t k = atomic_fetch_add_explicit(&j->next, 1, memory_order_relaxed);
        if (k >= j->pieces) break;
        uint32_t first, end;
        as_chunk_range(j->count, k, j->pieces, &first, &end);
        bvh_ref *const l0 = j->out->l + j->nl[k], *const r0 = j->out->r + j->nr[k], *l = l0, *r = r0;
        for (uint32_t i = first; i < end; ++i) part_write(j->plan, &j->refs[i], j->outcome[i], &l, &r, NULL, NULL);
        j->lbox[k] = bvh_refs_box(l0, (uint32_t)(l - l0));
        j->rbox[k] = bvh_refs_box(r0, (uint32_t)(r - r0));
        j->lcbox[k] = bvh_refs_centroid2_box(l0, (uint32_t)(l - l0));
        j->rcbox[k] = bvh_refs_centroid2_box(r0, (uint32_t)(r - r0));
    }
}

/* Partitions refs into out (allocated here) by the plan, on `threads`
 * threads when the node is large enough to be cut in pieces. */
static int partition(sbvh_mem *m, const part_plan *plan, const bvh_ref *refs, uint32_t count, int right_first,
                     unsigned threads, sides *out)
{
    if (!sides_alloc(m, count, right_first, out)) return 0;
    const uint32_t pieces = threads > 1 ? bvh_piece_count(count, threads) : 1;
    part_job j;
    memset(&j, 0, sizeof j);
    if (pieces > 1) {
        j.outcome = malloc(count);
        j.nl = malloc(sizeof(uint32_t) * 2 * pieces);
        j.lbox = malloc(sizeof(bvh_box) * 4 * pieces);
    }
    if (pieces < 2 || !j.outcome || !j.nl || !j.lbox) {
        free(j.outcome);
        free(j.nl);
        free(j.lbox);
        bvh_ref *l = out->l, *r = out->r;
        if (plan->object) {
            for (uint32_t i = 0; i < count; ++i) *(bvh_object_split_left(&refs[i], plan->object) ? l++ : r++) = refs[i];
        } else {
            for (uint32_t i = 0; i < count; ++i) {
                bvh_box cl, cr;
                const unsigned o = part_outcome(plan, &refs[i], &cl, &cr);
                part_write(plan, &refs[i], o, &l, &r, &cl, &cr);
            }
        }
        out->nl = (uint32_t)(l - out->l);
        out->nr = (uint32_t)(r - out->r);
        out->lbox = bvh_refs_box(out->l, out->nl);
        out->rbox = bvh_refs_box(out->r, out->nr);
        return 1;
    }
    j.plan = plan;
    j.refs = refs;
    j.count = count;
    j.pieces = pieces;
    j.nr = j.nl + pieces;
    j.rbox = j.lbox + pieces;
    j.lcbox = j.lbox + 2 * pieces;
    j.rcbox = j.lbox + 3 * pieces;
    j.out = out;
    if (threads > pieces) threads = pieces;
    atomic_init(&j.next, 0);
    as_parallel_run(threads, part_count, &j);
    uint32_t at_l = 0, at_r = 0;
    for (uint32_t k = 0; k < pieces; ++k) {
        const uint32_t nl = j.nl[k], nr = j.nr[k];
        j.nl[k] = at_l;
        j.nr[k] = at_r;
        at_l += nl;
        at_r += nr;
    }
    atomic_store(&j.next, 0);
    as_parallel_run(threads, part_place, &j);
    out->nl = at_l;
    out->nr = at_r;
    out->lbox = out->rbox = out->lcbox = out->rcbox = bvh_box_empty();
    for (uint32_t k = 0; k < pieces; ++k) {
        bvh_box_grow(&out->lbox, j.lbox[k].lo, j.lbox[k].hi);
        bvh_box_grow(&out->rbox, j.rbox[k].lo, j.rbox[k].hi);
        bvh_box_grow(&out->lcbox, j.lcbox[k].lo, j.lcbox[k].hi);
        bvh_box_grow(&out->rcbox, j.rcbox[k].lo, j.rcbox[k].hi);
    }
    out->centroids = 1;
    free(j.outcome);
    free(j.nl);
    free(j.lbox);
    return 1;
}

static int partition_half(sbvh_mem *m, const bvh_ref *refs, uint32_t count, sides *out)
{
    if (!sides_alloc(m, count, 0, out)) return 0;
    out->nl = count / 2;
    out->nr = count - count / 2;
    memcpy(out->l, refs, sizeof(bvh_ref) * out->nl);
    memcpy(out->r, refs + out->nl, sizeof(bvh_ref) * out->nr);
    out->lbox = bvh_refs_box(out->l, out->nl);
    out->rbox = bvh_refs_box(out->r, out->nr);
    return 1;
}

/* ---- the recursion */

typedef struct sbvh_task {
    sbvh_ctx *ctx;
    int32_t node;
    bvh_ref *refs;       /* the task's: malloc'd (owned) or in the arena of the thread that builds it */
    uint32_t count;
    int owned;
    uint32_t cap;        /* owned: the array's room (block_release) */
    uint64_t budget;     /* extra references this subtree may add */
    uint32_t depth;
    int centroids;       /* cbox holds the references' centroid box (doubled) */
    bvh_box cbox;
} sbvh_task;

static void copy_sides(sbvh_mem *m, const bvh_ref *refs, uint32_t count, uint32_t nl, sides *out)
{
    if (!sides_alloc(m, count, count - nl > nl, out)) return;
    out->nl = nl;
    out->nr = count - nl;
    memcpy(out->l, refs, sizeof(bvh_ref) * nl);
    memcpy(out->r, refs + nl, sizeof(bvh_ref) * (count - nl));
    out->lbox = bvh_refs_box(out->l, out->nl);
    out->rbox = bvh_refs_box(out->r, out->nr);
}

/* Splits one node into `sd` (both sides non-empty), or returns 0 for a
 * leaf. `refs` may be reordered; cbox is their centroid box (doubled), or
 * NULL when it is not known. */
static int sbvh_split(sbvh_ctx *ctx, sbvh_mem *m, const bvh_box *node_box, bvh_ref *refs, uint32_t count,
                      const bvh_box *cbox, uint64_t budget, unsigned threads, sides *sd)
{
    bvh_builder *b = ctx->b;
    const float ci = b->args->cost_intersection, ct = b->args->cost_traversal;
    const uint32_t nb = b->args->bin_count;
    const double area = bvh_box_half_area(node_box);
    const double leaf_cost = ci * (double)count;

    /* The object split: exact for small nodes, binned above. */
    bvh_object_split os;
    memset(&os, 0, sizeof os);
    os.axis = -1;
    os.cost = INFINITY;
    uint32_t small_nl = 0;
    if (count <= BVH_SMALL_NODE) {
        small_nl = bvh_find_small_split(refs, count, &os.cost);
        if (small_nl) {
            os.axis = 0; /* any axis: the sides are refs[0, small_nl) and the rest */
            os.left = bvh_refs_box(refs, small_nl);
            os.right = bvh_refs_box(refs + small_nl, count - small_nl);
        }
    } else if (threads > 1) {
        const bvh_box cb = cbox ? *cbox : bvh_refs_centroid2_box(refs, count);
        os = bvh_find_object_split_mt(refs, count, &cb, nb, threads, NULL);
    } else {
        const bvh_box cb = bvh_refs_centroid2_box(refs, count);
        os = bvh_find_object_split(refs, count, &cb, nb, NULL);
    }
    double best_cost = os.axis >= 0 ? os.cost : INFINITY;
    spatial_split ss;
    memset(&ss, 0, sizeof ss);
    ss.axis = -1;
    if (os.axis >= 0 && budget > 0 && count > SBVH_SPATIAL_MIN_REFS) {
        /* The overlap of the object split's children decides whether a
         * spatial split is worth a look (section 4.2). */
        bvh_box ov;
        for (int a = 0; a < 3; ++a) {
            ov.lo[a] = os.left.lo[a] > os.right.lo[a] ? os.left.lo[a] : os.right.lo[a];
            ov.hi[a] = os.left.hi[a] < os.right.hi[a] ? os.left.hi[a] : os.right.hi[a];
        }
        const double node_min = count <= SBVH_OVERLAP_NODE_REFS ? SBVH_OVERLAP_NODE_FRACTION * area : 0.0;
        if (box_valid(&ov)) {
            const double overlap = bvh_box_half_area(&ov);
            if (overlap > ctx->alpha_area && overlap >= node_min) ss = find_spatial_split(ctx, refs, count, node_box, threads);
        }
    }
    /* Where every centroid coincides (copies of one triangle) no spatial
     * split is tried: it would only duplicate the copies. */
    const int use_spatial = ss.axis >= 0 && ss.cost < best_cost && (uint64_t)ss.nl + ss.nr - count <= budget;
    if (use_spatial) best_cost = ss.cost;
    const double split_cost = area > 0 ? ct + ci * best_cost / area : ct + ci * (double)count;
    const int must_split = count > b->args->max_leaf_size;
    if (!(split_cost < leaf_cost) && !must_split) return 0;
    int ok = 0;
    if (use_spatial) {
        const part_plan plan = plan_spatial(b->mesh, &ss);
        ok = partition(m, &plan, refs, count, ss.nr > ss.nl, threads, sd);
        /* A split that leaves a side empty or overspends falls back. */
        if (ok && (sd->nl == 0 || sd->nr == 0 || (uint64_t)sd->nl + sd->nr - count > budget)) ok = 0;
        /* The bins only estimate the cost: a split that turns out no
         * cheaper than the object split, once clipped and unsplit, falls
         * back too. */
        if (ok && os.axis >= 0) {
            if (bvh_box_half_area(&sd->lbox) * sd->nl + bvh_box_half_area(&sd->rbox) * sd->nr >= os.cost) ok = 0;
        }
        if (!ok) sides_free(m, sd);
    }
    if (!ok && os.axis >= 0) {
        if (small_nl) copy_sides(m, refs, count, small_nl, sd);
        else {
            const part_plan plan = plan_object(b->mesh, &os);
            ok = partition(m, &plan, refs, count, os.right_count > os.left_count, threads, sd);
        }
        ok = sd->nl > 0 && sd->nr > 0;
        if (!ok) sides_free(m, sd);
    }
    if (!ok && must_split) {
        /* All centroids coincide (copies of one triangle): halve the list. */
        ok = partition_half(m, refs, count, sd);
        if (!ok) sides_free(m, sd);
    }
    return ok;
}

/* Makes node a leaf of the task's references, copied into the store; the
 * task's array is given back (an arena one by whoever took it). */
static void sbvh_leaf(bvh_local *loc, sbvh_mem *m, const sbvh_task *t)
{
    const bvh_ref *stored = NULL;
    uint32_t count = t->count;
    if (count && !atomic_load_explicit(&loc->b->cancelled, memory_order_relaxed)) {
        stored = leaf_store(m, t->refs, count);
        if (!stored) {
            /* The tree cannot be completed: the build ends with the error. */
            atomic_store(&t->ctx->out_of_memory, 1);
            atomic_store(&loc->b->cancelled, 1);
        }
    }
    if (!stored) count = 0; /* cancelled: the tree is thrown away */
    if (t->owned) block_release(t->ctx, t->refs, t->cap);
    bvh_local_leaf(loc, t->node, stored, count);
}

/* Builds the subtree of task t, handing its oldest large right child not
 * yet started (one with malloc'd references, which pass to the task that
 * takes it) to a thread that waits for work (bvh_pending_offer), and
 * records the subtree's size once both children are done (the recursion is
 * no deeper than the depth cap). */
static void sbvh_subtree(as_task_pool *pool, bvh_local *loc, sbvh_mem *m, as_pending_stack *pend, const sbvh_task *t)
{
    bvh_builder *b = t->ctx->b;
    bvh_pending_offer(b, pool, pend);
    /* A small node whose box is no larger than the spatial splits'
     * threshold: no spatial split is tried anywhere below it (every
     * overlap of children lies inside it), so its subtree is the exact
     * object sweep's, built in the leaf store where its leaves stay. */
    if (t->count <= BVH_EXACT_MAX && bvh_box_half_area(&b->nodes[t->node].box) <= t->ctx->alpha_area &&
        !atomic_load_explicit(&b->cancelled, memory_order_relaxed)) {
        bvh_ref *stored = leaf_store(m, t->refs, t->count);
        if (stored) {
            if (t->owned) block_release(t->ctx, t->refs, t->cap);
            const bvh_box box = b->nodes[t->node].box;
            bvh_build_exact_subtree(b, loc, t->node, stored, t->count, &box, t->depth);
            return;
        }
    }
    sides sd;
    memset(&sd, 0, sizeof sd);
    int32_t l, r;
    if (atomic_load_explicit(&b->cancelled, memory_order_relaxed) || t->count <= 1 || t->depth + 1 >= b->depth_limit ||
        !sbvh_split(t->ctx, m, &b->nodes[t->node].box, t->refs, t->count, t->centroids ? &t->cbox : NULL, t->budget,
                    bvh_split_threads(b, t->count), &sd)) {
        sbvh_leaf(loc, m, t);
        return;
    }
    if (!bvh_local_pair(loc, &l, &r)) {
        sides_free(m, &sd);
        sbvh_leaf(loc, m, t);
        return;
    }
    if (t->owned) block_release(t->ctx, t->refs, t->cap);
    const uint64_t spent = (uint64_t)sd.nl + sd.nr - t->count;
    const uint64_t rest = t->budget - spent;
    const uint64_t lbudget = (uint64_t)((double)rest * sd.nl / ((double)sd.nl + sd.nr));
    const uint64_t rbudget = rest - lbudget;

    bvh_tmp_node *ln = &b->nodes[l], *rn = &b->nodes[r];
    ln->box = sd.lbox;
    rn->box = sd.rbox;
    bvh_make_inner(b, t->node, l, r);

    /* Owned sides pass to the children's tasks; arena sides come back
     * here once both subtrees are done. */
    const sbvh_task lt = {t->ctx, l, sd.l, sd.nl, sd.owned, sd.lcap, lbudget, t->depth + 1, sd.centroids, sd.lcbox};
    const sbvh_task rt = {t->ctx, r, sd.r, sd.nr, sd.owned, sd.rcap, rbudget, t->depth + 1, sd.centroids, sd.rcbox};
    as_pending rp = {&rt, 0};
    const int tracked = pool && sd.owned && rt.count >= SBVH_SHARE_MIN_PRIMS && as_pending_push(pend, &rp);
    sbvh_subtree(pool, loc, m, pend, &lt);
    if (tracked) as_pending_pop(pend);
    if (!rp.given) sbvh_subtree(pool, loc, m, pend, &rt);
    if (!sd.owned) m->arena_top = sd.arena_mark;
    bvh_node_complete(b, t->node, rp.given);
}

static void sbvh_run(as_task_pool *pool, void *task, void *user)
{
    (void)user;
    sbvh_task t;
    memcpy(&t, task, sizeof t);
    bvh_local loc;
    bvh_local_init(&loc, t.ctx->b);
    sbvh_mem *m = mem_acquire(t.ctx);
    as_pending_stack pend;
    as_pending_init(&pend);
    sbvh_subtree(pool, &loc, m, &pend, &t);
    mem_release(t.ctx, m);
    bvh_local_flush(&loc);
}

as_error_t as_bvh_build_sbvh(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s)
{
    const double t_start = as_now_ms();
    if (!(args->split_budget >= 0.0f) || !isfinite(args->split_budget))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "split budget must be finite and >= 0 (got %g)", (double)args->split_budget);
    if (!(args->sbvh_alpha >= 0.0f) || !isfinite(args->sbvh_alpha))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "SBVH alpha must be finite and >= 0 (got %g)", (double)args->sbvh_alpha);
    bvh_builder b;
    as_error_t err = bvh_builder_init(&b, mesh, args, 2);
    if (err != AS_OK) return err;
    /* Extra references: (split_budget - 1) x N, at most 15 x N, so that a
     * huge budget cannot ask for more build memory than 16 x N references
     * (and TRI4 indices stay 31-bit, below). */
    double factor = args->split_budget > 1.0f ? (double)args->split_budget - 1.0 : 0.0;
    if (factor > 15.0) factor = 15.0;
    double extra = floor(factor * (double)b.ref_count);
    /* TRI4 indices are 31-bit. */
    if (extra > (double)(INT32_MAX / 2) - (double)b.ref_count) extra = (double)(INT32_MAX / 2) - (double)b.ref_count;
    if (extra < 0) extra = 0;
    const uint64_t budget = (uint64_t)extra;
    err = bvh_builder_renew_nodes(&b, 2 * ((uint64_t)b.ref_count + budget) + 3 + BVH_NODE_SLACK);
    if (err != AS_OK) {
        bvh_builder_free(&b);
        return err;
    }
    /* The root task owns the references from here on, as every task owns
     * its own. */
    bvh_ref *root_refs = b.refs;
    b.refs = NULL;
    sbvh_ctx ctx;
    memset(&ctx, 0, sizeof ctx);
    pthread_mutex_init(&ctx.mem_lock, NULL);
    atomic_init(&ctx.out_of_memory, 0);
    ctx.b = &b;
    ctx.alpha_area = (double)args->sbvh_alpha * bvh_box_half_area(&b.root_box);
    const uint32_t spatial_bins = args->bin_count < SBVH_SPATIAL_BINS ? args->bin_count : SBVH_SPATIAL_BINS;
    for (uint32_t i = 0; i <= spatial_bins; ++i) ctx.fraction[i] = (float)i / (float)spatial_bins;
    ctx.fraction_bins = spatial_bins;
    const int32_t root = bvh_new_node(&b);
    b.nodes[root].box = b.root_box;
    b.nodes[root].left = b.nodes[root].right = -1;
    const sbvh_task t = {&ctx, root, root_refs, b.ref_count, 1, b.ref_count, budget, 0, 1, b.root_cbox};
    const unsigned threads = (unsigned)b.max_threads + 1;
    b.root_threads = threads > 256 ? 256 : threads;
    ctx.recycle = threads > 1;
    if (threads < 2 || b.ref_count < 2 * BVH_PARALLEL_MIN_PRIMS || !as_task_pool_run(threads, sizeof t, &t, sbvh_run, NULL))
        sbvh_run(NULL, (void *)&t, NULL);
    if (atomic_load(&ctx.out_of_memory))
        err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory storing the SBVH's leaf references");
    else
        err = bvh_builder_finish(&b, root, AS_BUILDER_BVH_SBVH, s, t_start);
    /* The leaves' references live in the store. */
    mem_free_all(&ctx);
    pthread_mutex_destroy(&ctx.mem_lock);
    bvh_builder_free(&b);
    return err;
}
