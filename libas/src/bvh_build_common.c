/* The parts every BVH builder shares (see bvh_build_common.h).
 *
 * Determinism: a builder decides each node's split from that node's
 * references alone, sequentially, and the final node and triangle order comes
 * from one depth-first walk after the build, so the output is byte-identical
 * whatever the thread count and however threads were scheduled (tmp node
 * indices, which do depend on scheduling, never reach the file). */
#include "bvh_build_common.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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
     * their index) but not in the structure. */
    uint32_t n = 0;
    for (uint32_t i = 0; i < mesh->triangle_count; ++i)
        if (!as_mesh_triangle_is_degenerate(mesh, i)) ++n;
    b->ref_count = n;
    b->prim_total = n;
    b->refs = as_malloc(sizeof(bvh_ref) * (size_t)(n ? n : 1), "BVH primitive references");
    /* A binary tree over n leaves has n - 1 inner nodes. */
    b->node_capacity = node_capacity_per_ref * (uint64_t)n + 3;
    b->nodes = as_malloc(sizeof(bvh_tmp_node) * b->node_capacity, "BVH build nodes");
    if (!b->refs || !b->nodes) {
        bvh_builder_free(b);
        return as_get_error();
    }
    b->root_box = bvh_box_empty();
    uint32_t k = 0;
    for (uint32_t i = 0; i < mesh->triangle_count; ++i) {
        if (as_mesh_triangle_is_degenerate(mesh, i)) continue;
        bvh_ref *r = &b->refs[k++];
        const uint32_t *ix = mesh->indices + 3 * (size_t)i;
        bvh_box bx = bvh_box_empty();
        for (int v = 0; v < 3; ++v) {
            const float *p = mesh->positions + 3 * (size_t)ix[v];
            bvh_box_grow(&bx, p, p);
        }
        memcpy(r->lo, bx.lo, sizeof r->lo);
        memcpy(r->hi, bx.hi, sizeof r->hi);
        r->id = i;
        r->pad = 0.0f;
        bvh_box_grow(&b->root_box, bx.lo, bx.hi);
    }
    return AS_OK;
}

void bvh_builder_free(bvh_builder *b)
{
    free(b->refs);
    free(b->nodes);
    b->refs = NULL;
    b->nodes = NULL;
    if (b->args) pthread_mutex_destroy(&b->progress_lock);
    b->args = NULL;
}

bvh_box bvh_refs_box(const bvh_ref *refs, uint32_t count)
{
    bvh_box bx = bvh_box_empty();
    for (uint32_t i = 0; i < count; ++i) bvh_box_grow(&bx, refs[i].lo, refs[i].hi);
    return bx;
}

bvh_box bvh_refs_centroid_box(const bvh_ref *refs, uint32_t count)
{
    bvh_box cb = bvh_box_empty();
    for (uint32_t i = 0; i < count; ++i) {
        const float c[3] = {bvh_ref_centroid(&refs[i], 0), bvh_ref_centroid(&refs[i], 1), bvh_ref_centroid(&refs[i], 2)};
        bvh_box_grow(&cb, c, c);
    }
    return cb;
}

bvh_object_split bvh_find_object_split(const bvh_ref *refs, uint32_t count, const bvh_box *cb, uint32_t nb)
{
    bvh_object_split best = {-1, 0, INFINITY, 0, 0};
    /* One pass over the references bins all three axes. */
    float scale[3];
    int use[3];
    for (int axis = 0; axis < 3; ++axis) {
        const float extent = cb->hi[axis] - cb->lo[axis];
        use[axis] = extent > 0.0f;
        /* The (1 - 1e-6) keeps the largest centroid inside the last bin. */
        scale[axis] = use[axis] ? (float)nb * (1.0f - 1e-6f) / extent : 0.0f;
    }
    if (!use[0] && !use[1] && !use[2]) return best;
    bvh_box bins[3][BVH_MAX_BINS];
    uint32_t counts[3][BVH_MAX_BINS];
    for (int axis = 0; axis < 3; ++axis)
        for (uint32_t i = 0; i < nb; ++i) { bins[axis][i] = bvh_box_empty(); counts[axis][i] = 0; }
    for (uint32_t i = 0; i < count; ++i) {
        const bvh_ref *r = &refs[i];
        for (int axis = 0; axis < 3; ++axis) {
            if (!use[axis]) continue;
            const float c = bvh_ref_centroid(r, axis);
            int k = (int)((c - cb->lo[axis]) * scale[axis]);
            if (k < 0) k = 0;
            if (k >= (int)nb) k = (int)nb - 1;
            bvh_box_grow(&bins[axis][k], r->lo, r->hi);
            counts[axis][k]++;
        }
    }
    for (int axis = 0; axis < 3; ++axis) {
        if (!use[axis]) continue;
        double right_area[BVH_MAX_BINS];
        uint32_t right_count[BVH_MAX_BINS];
        bvh_box acc = bvh_box_empty();
        uint32_t n = 0;
        for (int i = (int)nb - 1; i > 0; --i) {
            bvh_box_grow(&acc, bins[axis][i].lo, bins[axis][i].hi);
            n += counts[axis][i];
            right_area[i] = bvh_box_half_area(&acc);
            right_count[i] = n;
        }
        acc = bvh_box_empty();
        n = 0;
        for (uint32_t i = 0; i + 1 < nb; ++i) {
            bvh_box_grow(&acc, bins[axis][i].lo, bins[axis][i].hi);
            n += counts[axis][i];
            if (n == 0 || right_count[i + 1] == 0) continue;
            const double cost = bvh_box_half_area(&acc) * n + right_area[i + 1] * right_count[i + 1];
            if (cost < best.cost) {
                best.axis = axis;
                best.bin = (int)i;
                best.cost = cost;
                best.cmin = cb->lo[axis];
                best.scale = scale[axis];
            }
        }
    }
    return best;
}

int bvh_object_split_left(const bvh_ref *r, const bvh_object_split *s, uint32_t nb)
{
    const float c = bvh_ref_centroid(r, s->axis);
    int k = (int)((c - s->cmin) * s->scale);
    if (k < 0) k = 0;
    if (k >= (int)nb) k = (int)nb - 1;
    return k <= s->bin;
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
    n->refs = refs; /* an SBVH leaf owns it, even when empty */
    n->count = count;
    bvh_report_progress(b, count);
}

int bvh_spawn(bvh_builder *b, pthread_t *tid, void *(*fn)(void *), void *arg)
{
    int spawned = 0;
    if (atomic_fetch_add(&b->live_threads, 1) < b->max_threads) spawned = pthread_create(tid, NULL, fn, arg) == 0;
    if (!spawned) atomic_fetch_sub(&b->live_threads, 1);
    return spawned;
}

void bvh_thread_done(bvh_builder *b) { atomic_fetch_sub(&b->live_threads, 1); }

/* ---- the in-place recursion shared by the binned, sweep and mid-cut builders */

typedef struct inplace_task {
    bvh_builder *b;
    bvh_split_fn split;
    int32_t node;
    uint32_t first, count, depth;
} inplace_task;

static void inplace_recursive(bvh_builder *b, bvh_split_fn split, int32_t node, uint32_t first, uint32_t count,
                              uint32_t depth);

static void *inplace_thread(void *arg)
{
    const inplace_task *t = arg;
    inplace_recursive(t->b, t->split, t->node, t->first, t->count, t->depth);
    bvh_thread_done(t->b);
    return NULL;
}

/* Builds the subtree of tmp node `node`, whose box is already set. */
static void inplace_recursive(bvh_builder *b, bvh_split_fn split, int32_t node, uint32_t first, uint32_t count,
                              uint32_t depth)
{
    /* A leaf at the stack's depth whatever its size: the traversal stack
     * holds one entry per level. */
    if (atomic_load(&b->cancelled) || count <= 1 || depth + 1 >= b->depth_limit) {
        bvh_make_leaf(b, node, b->refs + first, count);
        return;
    }
    const bvh_box node_box = b->nodes[node].box;
    const uint32_t mid = split(b, first, count, &node_box);
    if (mid <= first || mid >= first + count) {
        bvh_make_leaf(b, node, b->refs + first, count);
        return;
    }
    const int32_t l = bvh_new_node(b), r = bvh_new_node(b);
    bvh_tmp_node *ln = &b->nodes[l], *rn = &b->nodes[r];
    ln->box = bvh_refs_box(b->refs + first, mid - first);
    rn->box = bvh_refs_box(b->refs + mid, first + count - mid);
    bvh_tmp_node *n = &b->nodes[node];
    n->left = l;
    n->right = r;
    n->count = 0;
    n->refs = NULL;

    const uint32_t lcount = mid - first, rcount = first + count - mid;
    pthread_t tid;
    inplace_task task = {b, split, l, first, lcount, depth + 1};
    int spawned = 0;
    if (lcount >= BVH_PARALLEL_MIN_PRIMS && rcount >= BVH_PARALLEL_MIN_PRIMS)
        spawned = bvh_spawn(b, &tid, inplace_thread, &task);
    if (!spawned) inplace_recursive(b, split, l, first, lcount, depth + 1);
    inplace_recursive(b, split, r, mid, rcount, depth + 1);
    if (spawned) pthread_join(tid, NULL);
}

int32_t bvh_build_inplace(bvh_builder *b, bvh_split_fn split)
{
    const int32_t root = bvh_new_node(b);
    b->nodes[root].box = b->root_box;
    b->nodes[root].left = b->nodes[root].right = -1;
    inplace_recursive(b, split, root, 0, b->ref_count, 0);
    return root;
}

/* ---- the depth-first walk that fixes the output order */

typedef struct flatten_state {
    const bvh_builder *b;
    as_bvh2_node_t *out;
    uint64_t out_count;
    as_tri4_t *tris;
    uint32_t tri_count;
    uint64_t leaf_count;
    uint32_t max_depth;
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

static int32_t emit_leaf(flatten_state *st, const bvh_tmp_node *t)
{
    const uint32_t start = st->tri_count;
    const as_mesh_t *mesh = st->b->mesh;
    const float *p = mesh->positions;
    for (uint32_t i = 0; i < t->count; ++i) {
        const uint32_t id = t->refs[i].id;
        const uint32_t *ix = mesh->indices + 3 * (size_t)id;
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
    const bvh_tmp_node *t = &st->b->nodes[tnode];
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
        }
    }
    for (int k = 0; k < 2; ++k)
        if (slot[k] >= 0) flatten(st, kids[k], (uint64_t)slot[k], depth + 1);
}

static uint64_t count_refs(const bvh_builder *b, int32_t root)
{
    uint64_t total = 0;
    /* The tmp tree is at most depth_limit deep: an explicit stack. */
    int32_t stack[2 * AS_BVH2_MAX_DEPTH + 4];
    int sp = 0;
    stack[sp++] = root;
    while (sp > 0) {
        const bvh_tmp_node *n = &b->nodes[stack[--sp]];
        if (n->left < 0) { total += n->count; continue; }
        stack[sp++] = n->left;
        stack[sp++] = n->right;
    }
    return total;
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
        b->nodes[r].count = 0;
        b->nodes[root].left = l;
        b->nodes[root].right = r;
    }
    const uint64_t refs = count_refs(b, root);
    if (refs > INT32_MAX) return as_set_error(AS_ERROR_UNSUPPORTED, "%llu references exceed the 31-bit TRI4 range",
                                              (unsigned long long)refs);
    const uint64_t inner = atomic_load(&b->node_next); /* upper bound on inner nodes */
    as_bvh2_node_t *out = as_aligned_alloc(sizeof(as_bvh2_node_t) * inner, "BVH2 nodes");
    as_tri4_t *tris = as_aligned_alloc(sizeof(as_tri4_t) * (size_t)(refs ? refs : 1), "TRI4 triangles");
    if (!out || !tris) {
        free(out);
        free(tris);
        return as_get_error();
    }
    memset(out, 0, sizeof(as_bvh2_node_t) * inner);
    flatten_state st = {b, out, 1, tris, 0, 0, 0};
    flatten(&st, root, 0, 0);

    const as_build_args_t *args = b->args;
    const as_mesh_t *mesh = b->mesh;
    as_structure_t cb;
    memset(&cb, 0, sizeof cb);
    as_structure_t *d = args->layout == AS_LAYOUT_BVH2_OWN_BOUNDS ? &cb : s;
    memset(&d->meta, 0, sizeof d->meta);
    snprintf(d->meta.writer, sizeof d->meta.writer, "libas");
    d->meta.writer_version = AS_VERSION_NUMBER;
    d->meta.structure_kind = AS_STRUCT_BVH;
    d->meta.layout = AS_LAYOUT_BVH2_CHILD_BOUNDS;
    d->meta.layout_version = AS_BVH2_LAYOUT_VERSION;
    d->meta.builder = builder_id;
    d->meta.max_leaf_size = args->max_leaf_size;
    d->meta.bin_count = args->bin_count;
    d->meta.cost_traversal = args->cost_traversal;
    d->meta.cost_intersection = args->cost_intersection;
    d->meta.triangle_count = mesh->triangle_count;
    d->meta.source_hash = mesh->hash;
    memcpy(d->meta.bounds_lo, mesh->bounds_lo, sizeof d->meta.bounds_lo);
    memcpy(d->meta.bounds_hi, mesh->bounds_hi, sizeof d->meta.bounds_hi);
    d->meta.node_count = st.out_count;
    d->meta.leaf_count = st.leaf_count;
    d->meta.max_depth = st.max_depth;
    d->meta.reference_count = st.tri_count;
    d->meta.max_depth_limit = b->depth_limit;
    if (builder_id == AS_BUILDER_BVH_SBVH) {
        d->meta.split_budget = args->split_budget;
        d->meta.sbvh_alpha = args->sbvh_alpha;
    }
    as_structure_add_section(d, ASF_TAG_BVH2, out, st.out_count, sizeof(as_bvh2_node_t));
    as_structure_add_section(d, ASF_TAG_TRI4, tris, st.tri_count, sizeof(as_tri4_t));
    d->meta.sah_cost = as_bvh2_sah_cost(d);
    as_error_t err = AS_OK;
    if (d == &cb) {
        err = as_bvh2_to_own_bounds(&cb, s);
        for (uint32_t i = 0; i < cb.section_count; ++i) free(cb.sections[i].owned);
    }
    s->build_ms = as_now_ms() - t_start;
    return err;
}
