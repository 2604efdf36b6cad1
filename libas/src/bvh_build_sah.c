/* BVH builder, binned SAH (Wald 2007, "On fast construction of SAH-based
 * bounding volume hierarchies"), written straight into the BVH2 child-bounds
 * layout.
 *
 * Determinism: the tree's shape depends only on the input (binning and the
 * in-place partition are sequential per node, ties broken by axis then bin),
 * and the final node and triangle order comes from one depth-first walk
 * after the build, so the output is byte-identical whatever the thread count
 * and however threads were scheduled. */
#include "structure.h"
#include "mesh.h"
#include "bvh2_layout.h"

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_BINS 256
/* Subtrees larger than this may be built on another thread. */
#define PARALLEL_MIN_PRIMS 16384

typedef struct prim_ref {
    float lo[3];
    uint32_t id;
    float hi[3];
    float pad;
} prim_ref;

typedef struct box3 {
    float lo[3], hi[3];
} box3;

/* A node of the temporary tree. Leaves keep their range in the ref array. */
typedef struct tmp_node {
    box3 box;
    int32_t left, right;   /* tmp indices; -1 for a leaf */
    uint32_t first, count; /* leaf range */
} tmp_node;

typedef struct builder {
    const as_build_args_t *args;
    prim_ref *refs;
    tmp_node *nodes;
    atomic_uint_fast64_t node_next;
    uint64_t node_capacity;
    atomic_int live_threads;
    int max_threads;
    atomic_uint_fast64_t prims_done;
    uint64_t prim_total;
    atomic_int cancelled;
    pthread_mutex_t progress_lock;
    double next_report;
} builder;

static box3 box_empty(void)
{
    box3 b = {{FLT_MAX, FLT_MAX, FLT_MAX}, {-FLT_MAX, -FLT_MAX, -FLT_MAX}};
    return b;
}

static void box_grow_box(box3 *b, const float lo[3], const float hi[3])
{
    for (int k = 0; k < 3; ++k) {
        if (lo[k] < b->lo[k]) b->lo[k] = lo[k];
        if (hi[k] > b->hi[k]) b->hi[k] = hi[k];
    }
}

static void box_grow_point(box3 *b, const float p[3])
{
    box_grow_box(b, p, p);
}

/* Half the surface area, in double: SAH only compares ratios. */
static double box_half_area(const box3 *b)
{
    const double dx = (double)b->hi[0] - b->lo[0], dy = (double)b->hi[1] - b->lo[1],
                 dz = (double)b->hi[2] - b->lo[2];
    if (dx < 0 || dy < 0 || dz < 0) return 0.0;
    return dx * dy + dy * dz + dz * dx;
}

static void report_progress(builder *b, uint64_t prims)
{
    const uint64_t done = atomic_fetch_add(&b->prims_done, prims) + prims;
    if (!b->args->progress) return;
    const double fraction = b->prim_total ? (double)done / (double)b->prim_total : 1.0;
    pthread_mutex_lock(&b->progress_lock);
    if (fraction >= b->next_report) {
        b->next_report = fraction + 0.01;
        if (!b->args->progress(b->args->progress_user, fraction)) atomic_store(&b->cancelled, 1);
    }
    pthread_mutex_unlock(&b->progress_lock);
}

static int32_t new_node(builder *b)
{
    const uint64_t i = atomic_fetch_add(&b->node_next, 1);
    /* A binary tree over n leaves has n - 1 inner nodes; capacity is 2n + 1. */
    return i < b->node_capacity ? (int32_t)i : -1;
}

typedef struct split {
    int axis;        /* -1: none found */
    int bin;         /* left side: bins [0, bin] */
    double cost;
    float cmin, scale;
} split;

/* Best binned SAH split of refs [first, first+count) with centroid box cb. */
static split find_split(const builder *b, uint32_t first, uint32_t count, const box3 *cb)
{
    const uint32_t nb = b->args->bin_count;
    split best = {-1, 0, INFINITY, 0, 0};
    for (int axis = 0; axis < 3; ++axis) {
        const float extent = cb->hi[axis] - cb->lo[axis];
        if (!(extent > 0.0f)) continue;
        /* The (1 - 1e-6) keeps the largest centroid inside the last bin. */
        const float scale = (float)nb * (1.0f - 1e-6f) / extent;
        box3 bins[MAX_BINS];
        uint32_t counts[MAX_BINS];
        for (uint32_t i = 0; i < nb; ++i) { bins[i] = box_empty(); counts[i] = 0; }
        for (uint32_t i = first; i < first + count; ++i) {
            const prim_ref *r = &b->refs[i];
            const float c = 0.5f * (r->lo[axis] + r->hi[axis]);
            int k = (int)((c - cb->lo[axis]) * scale);
            if (k < 0) k = 0;
            if (k >= (int)nb) k = (int)nb - 1;
            box_grow_box(&bins[k], r->lo, r->hi);
            counts[k]++;
        }
        double right_area[MAX_BINS];
        uint32_t right_count[MAX_BINS];
        box3 acc = box_empty();
        uint32_t n = 0;
        for (int i = (int)nb - 1; i > 0; --i) {
            box_grow_box(&acc, bins[i].lo, bins[i].hi);
            n += counts[i];
            right_area[i] = box_half_area(&acc);
            right_count[i] = n;
        }
        acc = box_empty();
        n = 0;
        for (uint32_t i = 0; i + 1 < nb; ++i) {
            box_grow_box(&acc, bins[i].lo, bins[i].hi);
            n += counts[i];
            if (n == 0 || right_count[i + 1] == 0) continue;
            const double cost = box_half_area(&acc) * n + right_area[i + 1] * right_count[i + 1];
            if (cost < best.cost) {
                best.axis = axis;
                best.bin = (int)i;
                best.cost = cost;
                best.cmin = cb->lo[axis];
                best.scale = scale;
            }
        }
    }
    return best;
}

static int ref_goes_left(const prim_ref *r, const split *s, uint32_t nb)
{
    const float c = 0.5f * (r->lo[s->axis] + r->hi[s->axis]);
    int k = (int)((c - s->cmin) * s->scale);
    if (k < 0) k = 0;
    if (k >= (int)nb) k = (int)nb - 1;
    return k <= s->bin;
}

typedef struct build_task {
    builder *b;
    int32_t node;
    uint32_t first, count;
    uint32_t depth;
} build_task;

static void build_recursive(builder *b, int32_t node, uint32_t first, uint32_t count, uint32_t depth);

static void *build_thread(void *arg)
{
    build_task *t = arg;
    build_recursive(t->b, t->node, t->first, t->count, t->depth);
    atomic_fetch_sub(&t->b->live_threads, 1);
    return NULL;
}

static void make_leaf(builder *b, tmp_node *n, uint32_t first, uint32_t count)
{
    n->left = n->right = -1;
    n->first = first;
    n->count = count;
    report_progress(b, count);
}

/* Builds the subtree of tmp node `node`, whose box is already set. */
static void build_recursive(builder *b, int32_t node, uint32_t first, uint32_t count, uint32_t depth)
{
    tmp_node *n = &b->nodes[node];
    if (atomic_load(&b->cancelled)) { make_leaf(b, n, first, count); return; }
    const float ci = b->args->cost_intersection, ct = b->args->cost_traversal;
    /* A leaf at the stack's depth whatever its size: the traversal stack
     * holds one entry per level. */
    if (count <= 1 || depth + 1 >= AS_BVH2_MAX_DEPTH) { make_leaf(b, n, first, count); return; }

    box3 cb = box_empty();
    for (uint32_t i = first; i < first + count; ++i) {
        const prim_ref *r = &b->refs[i];
        const float c[3] = {0.5f * (r->lo[0] + r->hi[0]), 0.5f * (r->lo[1] + r->hi[1]),
                            0.5f * (r->lo[2] + r->hi[2])};
        box_grow_point(&cb, c);
    }
    const split s = find_split(b, first, count, &cb);
    const double area = box_half_area(&n->box);
    const double leaf_cost = ci * (double)count;
    const double split_cost = area > 0 ? ct + ci * s.cost / area : ct + ci * (double)count;
    uint32_t mid;
    if (s.axis >= 0 && (split_cost < leaf_cost || count > b->args->max_leaf_size)) {
        /* In-place partition, sequential, so the order is reproducible. */
        uint32_t i = first, j = first + count;
        while (i < j) {
            if (ref_goes_left(&b->refs[i], &s, b->args->bin_count)) { ++i; continue; }
            --j;
            const prim_ref tmp = b->refs[i];
            b->refs[i] = b->refs[j];
            b->refs[j] = tmp;
        }
        mid = i;
    } else if (count > b->args->max_leaf_size) {
        /* All centroids coincide (copies of one triangle): split the list in
         * half, which keeps the depth logarithmic. */
        mid = first + count / 2;
    } else {
        make_leaf(b, n, first, count);
        return;
    }
    if (mid == first || mid == first + count) mid = first + count / 2;

    const int32_t l = new_node(b), r = new_node(b);
    tmp_node *ln = &b->nodes[l], *rn = &b->nodes[r];
    ln->box = box_empty();
    rn->box = box_empty();
    for (uint32_t i = first; i < mid; ++i) box_grow_box(&ln->box, b->refs[i].lo, b->refs[i].hi);
    for (uint32_t i = mid; i < first + count; ++i) box_grow_box(&rn->box, b->refs[i].lo, b->refs[i].hi);
    n = &b->nodes[node];
    n->left = l;
    n->right = r;
    n->first = n->count = 0;

    const uint32_t lcount = mid - first, rcount = first + count - mid;
    pthread_t tid;
    build_task task = {b, l, first, lcount, depth + 1};
    int spawned = 0;
    if (lcount >= PARALLEL_MIN_PRIMS && rcount >= PARALLEL_MIN_PRIMS) {
        if (atomic_fetch_add(&b->live_threads, 1) < b->max_threads) {
            spawned = pthread_create(&tid, NULL, build_thread, &task) == 0;
        }
        if (!spawned) atomic_fetch_sub(&b->live_threads, 1);
    }
    if (!spawned) build_recursive(b, l, first, lcount, depth + 1);
    build_recursive(b, r, mid, rcount, depth + 1);
    if (spawned) pthread_join(tid, NULL);
}

/* The depth-first walk that fixes the output order. */
typedef struct flatten_state {
    const builder *b;
    const as_mesh_t *mesh;
    as_bvh2_node_t *out;
    uint64_t out_count;
    as_tri4_t *tris;
    uint32_t tri_count;
    uint64_t leaf_count;
    uint32_t max_depth;
} flatten_state;

static void set_child_box(as_bvh2_node_t *o, int which, const box3 *bx)
{
    if (which == 0) {
        o->xy0.x = bx->lo[0]; o->xy0.y = bx->hi[0]; o->xy0.z = bx->lo[1]; o->xy0.w = bx->hi[1];
        o->z01.x = bx->lo[2]; o->z01.y = bx->hi[2];
    } else {
        o->xy1.x = bx->lo[0]; o->xy1.y = bx->hi[0]; o->xy1.z = bx->lo[1]; o->xy1.w = bx->hi[1];
        o->z01.z = bx->lo[2]; o->z01.w = bx->hi[2];
    }
}

static int32_t emit_leaf(flatten_state *st, const tmp_node *t)
{
    const uint32_t start = st->tri_count;
    const float *p = st->mesh->positions;
    for (uint32_t i = 0; i < t->count; ++i) {
        const uint32_t id = st->b->refs[t->first + i].id;
        const uint32_t *ix = st->mesh->indices + 3 * (size_t)id;
        as_tri4_t *o = &st->tris[st->tri_count++];
        const float *a = p + 3 * (size_t)ix[0], *bb = p + 3 * (size_t)ix[1], *c = p + 3 * (size_t)ix[2];
        o->v0 = (as_f4_t){a[0], a[1], a[2], as_uint_as_float(id)};
        o->v1 = (as_f4_t){bb[0], bb[1], bb[2], 0.0f};
        o->v2 = (as_f4_t){c[0], c[1], c[2], 0.0f};
    }
    if (t->count) st->leaf_count++; /* the empty sibling of a one-leaf tree is no leaf */
    return ~(int32_t)start;
}

static void flatten(flatten_state *st, int32_t tnode, uint64_t out_index, uint32_t depth)
{
    const tmp_node *t = &st->b->nodes[tnode];
    if (depth > st->max_depth) st->max_depth = depth;
    const int32_t kids[2] = {t->left, t->right};
    /* Reserve both inner children first so siblings are adjacent. */
    int64_t slot[2] = {-1, -1};
    for (int k = 0; k < 2; ++k) {
        const tmp_node *c = &st->b->nodes[kids[k]];
        if (c->left >= 0) slot[k] = (int64_t)st->out_count++;
    }
    as_bvh2_node_t *o = &st->out[out_index];
    for (int k = 0; k < 2; ++k) {
        const tmp_node *c = &st->b->nodes[kids[k]];
        set_child_box(o, k, &c->box);
        if (slot[k] >= 0) {
            o->child[k] = (int32_t)slot[k];
            o->count[k] = 0;
        } else {
            if (c->count && depth + 1 > st->max_depth) st->max_depth = depth + 1;
            o->child[k] = emit_leaf(st, c);
            o->count[k] = c->count;
            if (c->count == 0) {
                const box3 inverted = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};
                set_child_box(o, k, &inverted);
            }
        }
    }
    for (int k = 0; k < 2; ++k)
        if (slot[k] >= 0) flatten(st, kids[k], (uint64_t)slot[k], depth + 1);
}

as_error_t as_bvh_build_sah(const as_mesh_t *mesh, const as_build_args_t *args, as_structure_t *s)
{
    const double t_start = as_now_ms();
    if (args->bin_count < 2 || args->bin_count > MAX_BINS)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "bin count %u is outside [2, %d]", args->bin_count, MAX_BINS);
    if (args->max_leaf_size < 1)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "max leaf size must be at least 1");
    if (!(args->cost_traversal >= 0.0f) || !(args->cost_intersection > 0.0f))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "SAH costs must be finite, traversal >= 0, intersection > 0");

    builder b;
    memset(&b, 0, sizeof b);
    b.args = args;
    b.max_threads = (int)as_thread_count(args->thread_count) - 1;
    pthread_mutex_init(&b.progress_lock, NULL);

    /* Zero-area triangles can never be hit: they stay in the mesh (and keep
     * their index) but not in the structure. */
    uint32_t n = 0;
    for (uint32_t i = 0; i < mesh->triangle_count; ++i)
        if (!as_mesh_triangle_is_degenerate(mesh, i)) ++n;
    b.prim_total = n;
    b.refs = as_malloc(sizeof(prim_ref) * (size_t)(n ? n : 1), "BVH primitive references");
    b.node_capacity = 2 * (uint64_t)n + 3;
    b.nodes = as_malloc(sizeof(tmp_node) * b.node_capacity, "BVH build nodes");
    as_bvh2_node_t *out = NULL;
    as_tri4_t *tris = NULL;
    if (!b.refs || !b.nodes) goto fail;

    box3 root_box = box_empty();
    {
        uint32_t k = 0;
        for (uint32_t i = 0; i < mesh->triangle_count; ++i) {
            if (as_mesh_triangle_is_degenerate(mesh, i)) continue;
            prim_ref *r = &b.refs[k++];
            const uint32_t *ix = mesh->indices + 3 * (size_t)i;
            box3 bx = box_empty();
            for (int v = 0; v < 3; ++v) box_grow_point(&bx, mesh->positions + 3 * (size_t)ix[v]);
            memcpy(r->lo, bx.lo, sizeof r->lo);
            memcpy(r->hi, bx.hi, sizeof r->hi);
            r->id = i;
            r->pad = 0.0f;
            box_grow_box(&root_box, bx.lo, bx.hi);
        }
    }

    /* The root is always an inner node: a tree of one leaf becomes a root
     * with that leaf and an empty sibling. */
    const int32_t root = new_node(&b);
    b.nodes[root].box = root_box;
    b.nodes[root].left = b.nodes[root].right = -1;
    b.nodes[root].first = 0;
    b.nodes[root].count = n;
    build_recursive(&b, root, 0, n, 0);
    if (atomic_load(&b.cancelled)) {
        as_set_error(AS_ERROR_CANCELLED, "BVH build cancelled by the progress callback");
        goto fail;
    }
    if (b.nodes[root].left < 0) {
        const int32_t l = new_node(&b), r = new_node(&b);
        b.nodes[l] = b.nodes[root];
        b.nodes[r].box = box_empty();
        b.nodes[r].left = b.nodes[r].right = -1;
        b.nodes[r].first = n;
        b.nodes[r].count = 0;
        b.nodes[root].left = l;
        b.nodes[root].right = r;
    }

    const uint64_t inner = atomic_load(&b.node_next); /* upper bound on inner nodes */
    out = as_aligned_alloc(sizeof(as_bvh2_node_t) * inner, "BVH2 nodes");
    tris = as_aligned_alloc(sizeof(as_tri4_t) * (size_t)(n ? n : 1), "TRI4 triangles");
    if (!out || !tris) goto fail;
    memset(out, 0, sizeof(as_bvh2_node_t) * inner);
    flatten_state st = {&b, mesh, out, 1, tris, 0, 0, 0};
    flatten(&st, root, 0, 0);

    memset(&s->meta, 0, sizeof s->meta);
    snprintf(s->meta.writer, sizeof s->meta.writer, "libas");
    s->meta.writer_version = AS_VERSION_NUMBER;
    s->meta.structure_kind = AS_STRUCT_BVH;
    s->meta.layout = AS_LAYOUT_BVH2_CHILD_BOUNDS;
    s->meta.layout_version = AS_BVH2_LAYOUT_VERSION;
    s->meta.builder = AS_BUILDER_BVH_SAH_BINNED;
    s->meta.max_leaf_size = args->max_leaf_size;
    s->meta.bin_count = args->bin_count;
    s->meta.cost_traversal = args->cost_traversal;
    s->meta.cost_intersection = args->cost_intersection;
    s->meta.triangle_count = mesh->triangle_count;
    s->meta.source_hash = mesh->hash;
    memcpy(s->meta.bounds_lo, mesh->bounds_lo, sizeof s->meta.bounds_lo);
    memcpy(s->meta.bounds_hi, mesh->bounds_hi, sizeof s->meta.bounds_hi);
    s->meta.node_count = st.out_count;
    s->meta.leaf_count = st.leaf_count;
    s->meta.max_depth = st.max_depth;
    s->meta.reference_count = st.tri_count;
    s->meta.max_depth_limit = AS_BVH2_MAX_DEPTH;
    as_structure_add_section(s, ASF_TAG_BVH2, out, st.out_count, sizeof(as_bvh2_node_t));
    as_structure_add_section(s, ASF_TAG_TRI4, tris, st.tri_count, sizeof(as_tri4_t));
    s->meta.sah_cost = as_bvh2_sah_cost(s);
    s->build_ms = as_now_ms() - t_start;
    free(b.refs);
    free(b.nodes);
    pthread_mutex_destroy(&b.progress_lock);
    return AS_OK;

fail:
    free(b.refs);
    free(b.nodes);
    free(out);
    free(tris);
    pthread_mutex_destroy(&b.progress_lock);
    return as_get_error();
}
