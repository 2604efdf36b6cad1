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

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct sbvh_ctx {
    bvh_builder *b;
    double alpha_area;   /* overlap threshold: sbvh_alpha x root half area */
    pthread_mutex_t leaf_lock;
} sbvh_ctx;

/* ---- reference clipping */

/* The next float towards -inf / +inf of a finite float (nextafterf without
 * the library call, which showed in profiles). */
static inline float next_down(float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    if (f == 0.0f) u = 0x80000001u;          /* -denorm_min */
    else if (f > 0.0f) u -= 1;
    else u += 1;
    memcpy(&f, &u, 4);
    return f;
}

static inline float next_up(float f) { return -next_down(-f); }

static inline float round_down(double d)
{
    float f = (float)d;
    if ((double)f > d) f = next_down(f);
    return next_down(f);
}

static inline float round_up(double d)
{
    float f = (float)d;
    if ((double)f < d) f = next_up(f);
    return next_up(f);
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

/* The same split for the bin search, which only estimates costs: float
 * arithmetic, no outward rounding (the partition recomputes exactly). */
static inline void split_ref_estimate(const float *const v[3], const bvh_ref *r, int axis, float pos, bvh_box *left,
                                      bvh_box *right)
{
    *left = bvh_box_empty();
    *right = bvh_box_empty();
    for (int e = 0; e < 3; ++e) {
        const float *v0 = v[e], *v1 = v[(e + 1) % 3];
        const float p0 = v0[axis], p1 = v1[axis];
        if (p0 <= pos) grow_point(left, v0);
        if (p0 >= pos) grow_point(right, v0);
        if ((p0 < pos && p1 > pos) || (p0 > pos && p1 < pos)) {
            const float t = (pos - p0) / (p1 - p0);
            float x[3];
            for (int a = 0; a < 3; ++a) x[a] = a == axis ? pos : v0[a] + t * (v1[a] - v0[a]);
            grow_point(left, x);
            grow_point(right, x);
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

static float bin_plane(const bvh_box *nb, int axis, uint32_t i, uint32_t bins)
{
    return nb->lo[axis] + (nb->hi[axis] - nb->lo[axis]) * ((float)i / (float)bins);
}

static spatial_split find_spatial_split(const bvh_builder *b, const bvh_ref *refs, uint32_t count, const bvh_box *node_box)
{
    const uint32_t nb = b->args->bin_count;
    spatial_split best;
    memset(&best, 0, sizeof best);
    best.axis = -1;
    best.cost = INFINITY;
    for (int axis = 0; axis < 3; ++axis) {
        const float extent = node_box->hi[axis] - node_box->lo[axis];
        if (!(extent > 0.0f)) continue;
        const float scale = (float)nb / extent;
        bvh_box bins[BVH_MAX_BINS];
        uint32_t enter[BVH_MAX_BINS], leave[BVH_MAX_BINS];
        for (uint32_t i = 0; i < nb; ++i) { bins[i] = bvh_box_empty(); enter[i] = leave[i] = 0; }
        for (uint32_t i = 0; i < count; ++i) {
            const bvh_ref *r = &refs[i];
            int b0 = (int)((r->lo[axis] - node_box->lo[axis]) * scale);
            int b1 = (int)((r->hi[axis] - node_box->lo[axis]) * scale);
            b0 = b0 < 0 ? 0 : b0 >= (int)nb ? (int)nb - 1 : b0;
            b1 = b1 < b0 ? b0 : b1 >= (int)nb ? (int)nb - 1 : b1;
            bvh_ref cur = *r;
            const float *v[3] = {NULL, NULL, NULL};
            if (b0 < b1) {
                const uint32_t *ix = b->mesh->indices + 3 * (size_t)r->id;
                for (int j = 0; j < 3; ++j) v[j] = b->mesh->positions + 3 * (size_t)ix[j];
            }
            for (int k = b0; k < b1; ++k) {
                bvh_box lb, rb;
                split_ref_estimate(v, &cur, axis, bin_plane(node_box, axis, (uint32_t)k + 1, nb), &lb, &rb);
                if (box_valid(&lb)) bvh_box_grow(&bins[k], lb.lo, lb.hi);
                if (!box_valid(&rb)) break;
                memcpy(cur.lo, rb.lo, sizeof cur.lo);
                memcpy(cur.hi, rb.hi, sizeof cur.hi);
                if (k + 1 == b1) bvh_box_grow(&bins[b1], cur.lo, cur.hi);
            }
            if (b0 == b1) bvh_box_grow(&bins[b0], r->lo, r->hi);
            enter[b0]++;
            leave[b1]++;
        }
        double right_area[BVH_MAX_BINS];
        uint32_t right_count[BVH_MAX_BINS];
        bvh_box right_box[BVH_MAX_BINS];
        bvh_box acc = bvh_box_empty();
        uint32_t n = 0;
        for (int i = (int)nb - 1; i > 0; --i) {
            bvh_box_grow(&acc, bins[i].lo, bins[i].hi);
            n += leave[i];
            right_area[i] = bvh_box_half_area(&acc);
            right_count[i] = n;
            right_box[i] = acc;
        }
        acc = bvh_box_empty();
        n = 0;
        for (uint32_t i = 0; i + 1 < nb; ++i) {
            bvh_box_grow(&acc, bins[i].lo, bins[i].hi);
            n += enter[i];
            if (n == 0 || right_count[i + 1] == 0) continue;
            const double cost = bvh_box_half_area(&acc) * n + right_area[i + 1] * right_count[i + 1];
            if (cost < best.cost) {
                best.axis = axis;
                best.pos = bin_plane(node_box, axis, i + 1, nb);
                best.cost = cost;
                best.left = acc;
                best.right = right_box[i + 1];
                best.nl = n;
                best.nr = right_count[i + 1];
            }
        }
    }
    return best;
}

/* ---- partitions into two new arrays */

typedef struct sides {
    bvh_ref *l, *r;
    uint32_t nl, nr;
} sides;

static void sides_free(sides *s)
{
    free(s->l);
    free(s->r);
    s->l = s->r = NULL;
    s->nl = s->nr = 0;
}

static int partition_object(const bvh_ref *refs, uint32_t count, const bvh_object_split *s, sides *out)
{
    out->l = malloc(sizeof(bvh_ref) * count);
    out->r = malloc(sizeof(bvh_ref) * count);
    out->nl = out->nr = 0;
    if (!out->l || !out->r) return 0;
    for (uint32_t i = 0; i < count; ++i) {
        if (bvh_object_split_left(&refs[i], s)) out->l[out->nl++] = refs[i];
        else out->r[out->nr++] = refs[i];
    }
    return 1;
}

static int partition_half(const bvh_ref *refs, uint32_t count, sides *out)
{
    out->l = malloc(sizeof(bvh_ref) * count);
    out->r = malloc(sizeof(bvh_ref) * count);
    if (!out->l || !out->r) return 0;
    out->nl = count / 2;
    out->nr = count - count / 2;
    memcpy(out->l, refs, sizeof(bvh_ref) * out->nl);
    memcpy(out->r, refs + out->nl, sizeof(bvh_ref) * out->nr);
    return 1;
}

/* Clips straddling references at the plane, or keeps one whole on the side
 * where the SAH says it costs less (unsplitting). */
static int partition_spatial(const bvh_builder *b, const bvh_ref *refs, uint32_t count, const spatial_split *s,
                             sides *out)
{
    out->l = malloc(sizeof(bvh_ref) * count);
    out->r = malloc(sizeof(bvh_ref) * count);
    out->nl = out->nr = 0;
    if (!out->l || !out->r) return 0;
    const int axis = s->axis;
    const float pos = s->pos;
    const double al = bvh_box_half_area(&s->left), ar = bvh_box_half_area(&s->right);
    const double nl = s->nl, nr = s->nr;
    for (uint32_t i = 0; i < count; ++i) {
        const bvh_ref *r = &refs[i];
        if (r->hi[axis] <= pos) { out->l[out->nl++] = *r; continue; }
        if (r->lo[axis] >= pos) { out->r[out->nr++] = *r; continue; }
        bvh_box lb = s->left, rb = s->right;
        bvh_box_grow(&lb, r->lo, r->hi);
        bvh_box_grow(&rb, r->lo, r->hi);
        const double c_split = al * nl + ar * nr;
        const double c_left = bvh_box_half_area(&lb) * nl + ar * (nr - 1);
        const double c_right = al * (nl - 1) + bvh_box_half_area(&rb) * nr;
        if (c_left < c_split && c_left <= c_right) { out->l[out->nl++] = *r; continue; }
        if (c_right < c_split) { out->r[out->nr++] = *r; continue; }
        bvh_box cl, cr;
        split_ref(b->mesh, r, axis, pos, &cl, &cr);
        if (box_valid(&cl)) {
            bvh_ref x = *r;
            memcpy(x.lo, cl.lo, sizeof x.lo);
            memcpy(x.hi, cl.hi, sizeof x.hi);
            out->l[out->nl++] = x;
        }
        if (box_valid(&cr)) {
            bvh_ref x = *r;
            memcpy(x.lo, cr.lo, sizeof x.lo);
            memcpy(x.hi, cr.hi, sizeof x.hi);
            out->r[out->nr++] = x;
        }
        if (!box_valid(&cl) && !box_valid(&cr)) out->l[out->nl++] = *r; /* cannot happen; never lose a triangle */
    }
    return 1;
}

/* ---- the recursion */

typedef struct sbvh_task {
    sbvh_ctx *ctx;
    int32_t node;
    bvh_ref *refs;       /* owned by the task */
    uint32_t count;
    uint64_t budget;     /* extra references this subtree may add */
    uint32_t depth;
} sbvh_task;

static void sbvh_recursive(sbvh_ctx *ctx, int32_t node, bvh_ref *refs, uint32_t count, uint64_t budget, uint32_t depth);

static void *sbvh_thread(void *arg)
{
    const sbvh_task *t = arg;
    sbvh_recursive(t->ctx, t->node, t->refs, t->count, t->budget, t->depth);
    bvh_thread_done(t->ctx->b);
    return NULL;
}

static void sbvh_recursive(sbvh_ctx *ctx, int32_t node, bvh_ref *refs, uint32_t count, uint64_t budget, uint32_t depth)
{
    bvh_builder *b = ctx->b;
    if (atomic_load(&b->cancelled) || count <= 1 || depth + 1 >= b->depth_limit) {
        bvh_make_leaf(b, node, refs, count);
        return;
    }
    const float ci = b->args->cost_intersection, ct = b->args->cost_traversal;
    const uint32_t nb = b->args->bin_count;
    const bvh_box node_box = b->nodes[node].box;
    const double area = bvh_box_half_area(&node_box);
    const double leaf_cost = ci * (double)count;

    const bvh_box cb = bvh_refs_centroid2_box(refs, count);
    const bvh_object_split os = bvh_find_object_split(refs, count, &cb, nb);
    double best_cost = os.axis >= 0 ? os.cost : INFINITY;
    spatial_split ss;
    memset(&ss, 0, sizeof ss);
    ss.axis = -1;
    if (os.axis >= 0 && budget > 0) {
        /* The overlap of the object split's children decides whether a
         * spatial split is worth a look (section 4.2). */
        bvh_box lb = bvh_box_empty(), rb = bvh_box_empty();
        for (uint32_t i = 0; i < count; ++i) {
            if (bvh_object_split_left(&refs[i], &os)) bvh_box_grow(&lb, refs[i].lo, refs[i].hi);
            else bvh_box_grow(&rb, refs[i].lo, refs[i].hi);
        }
        bvh_box ov;
        for (int a = 0; a < 3; ++a) {
            ov.lo[a] = lb.lo[a] > rb.lo[a] ? lb.lo[a] : rb.lo[a];
            ov.hi[a] = lb.hi[a] < rb.hi[a] ? lb.hi[a] : rb.hi[a];
        }
        if (box_valid(&ov) && bvh_box_half_area(&ov) > ctx->alpha_area) ss = find_spatial_split(b, refs, count, &node_box);
    }
    /* Where every centroid coincides (copies of one triangle) no spatial
     * split is tried: it would only duplicate the copies. */
    int use_spatial = ss.axis >= 0 && ss.cost < best_cost && (uint64_t)ss.nl + ss.nr - count <= budget;
    if (use_spatial) best_cost = ss.cost;
    const double split_cost = area > 0 ? ct + ci * best_cost / area : ct + ci * (double)count;
    const int must_split = count > b->args->max_leaf_size;
    if (!(split_cost < leaf_cost) && !must_split) {
        bvh_make_leaf(b, node, refs, count);
        return;
    }
    sides sd = {NULL, NULL, 0, 0};
    int ok = 0;
    if (use_spatial) {
        ok = partition_spatial(b, refs, count, &ss, &sd);
        /* A split that leaves a side empty or overspends falls back. */
        if (ok && (sd.nl == 0 || sd.nr == 0 || (uint64_t)sd.nl + sd.nr - count > budget)) ok = 0;
        /* The bins only estimate the cost: a split that turns out no
         * cheaper than the object split, once clipped and unsplit, falls
         * back too. */
        if (ok && os.axis >= 0) {
            const bvh_box lb = bvh_refs_box(sd.l, sd.nl), rb = bvh_refs_box(sd.r, sd.nr);
            if (bvh_box_half_area(&lb) * sd.nl + bvh_box_half_area(&rb) * sd.nr >= os.cost) ok = 0;
        }
        if (!ok) sides_free(&sd);
    }
    if (!ok && os.axis >= 0) {
        ok = partition_object(refs, count, &os, &sd);
        if (ok && (sd.nl == 0 || sd.nr == 0)) ok = 0;
        if (!ok) sides_free(&sd);
    }
    if (!ok && must_split) {
        /* All centroids coincide (copies of one triangle): halve the list. */
        ok = partition_half(refs, count, &sd);
        if (!ok) sides_free(&sd);
    }
    if (!ok) {
        bvh_make_leaf(b, node, refs, count);
        return;
    }
    free(refs);
    const uint64_t spent = (uint64_t)sd.nl + sd.nr - count;
    const uint64_t rest = budget - spent;
    const uint64_t lbudget = (uint64_t)((double)rest * sd.nl / ((double)sd.nl + sd.nr));
    const uint64_t rbudget = rest - lbudget;

    const int32_t l = bvh_new_node(b), r = bvh_new_node(b);
    bvh_tmp_node *ln = &b->nodes[l], *rn = &b->nodes[r];
    ln->box = bvh_refs_box(sd.l, sd.nl);
    rn->box = bvh_refs_box(sd.r, sd.nr);
    bvh_tmp_node *n = &b->nodes[node];
    n->left = l;
    n->right = r;
    n->count = 0;
    n->refs = NULL;

    pthread_t tid;
    sbvh_task task = {ctx, l, sd.l, sd.nl, lbudget, depth + 1};
    int spawned = 0;
    if (sd.nl >= BVH_PARALLEL_MIN_PRIMS && sd.nr >= BVH_PARALLEL_MIN_PRIMS) spawned = bvh_spawn(b, &tid, sbvh_thread, &task);
    if (!spawned) sbvh_recursive(ctx, l, sd.l, sd.nl, lbudget, depth + 1);
    sbvh_recursive(ctx, r, sd.r, sd.nr, rbudget, depth + 1);
    if (spawned) pthread_join(tid, NULL);
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
    free(b.nodes);
    b.node_capacity = 2 * ((uint64_t)b.ref_count + budget) + 3;
    b.nodes = as_malloc(sizeof(bvh_tmp_node) * b.node_capacity, "SBVH build nodes");
    bvh_ref *root_refs = as_malloc(sizeof(bvh_ref) * (size_t)(b.ref_count ? b.ref_count : 1), "SBVH references");
    if (!b.nodes || !root_refs) {
        free(root_refs);
        bvh_builder_free(&b);
        return as_get_error();
    }
    memcpy(root_refs, b.refs, sizeof(bvh_ref) * b.ref_count);
    sbvh_ctx ctx;
    ctx.b = &b;
    ctx.alpha_area = (double)args->sbvh_alpha * bvh_box_half_area(&b.root_box);
    const int32_t root = bvh_new_node(&b);
    b.nodes[root].box = b.root_box;
    b.nodes[root].left = b.nodes[root].right = -1;
    sbvh_recursive(&ctx, root, root_refs, b.ref_count, budget, 0);
    err = bvh_builder_finish(&b, root, AS_BUILDER_BVH_SBVH, s, t_start);
    /* Every leaf owns its reference array. */
    const uint64_t used = atomic_load(&b.node_next);
    for (uint64_t i = 0; i < used && i < b.node_capacity; ++i)
        if (b.nodes[i].left < 0) free((void *)b.nodes[i].refs);
    bvh_builder_free(&b);
    return err;
}
