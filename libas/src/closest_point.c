/* Closest-point queries on the BVH family: for a query point, the nearest
 * point on the structure's triangles.
 *
 * The traversal is depth first, nearer child first, and prunes every child
 * whose box lies farther from the point than the best triangle so far
 * (squared distances, so no square root per box). A pruned box can hold no
 * triangle nearer than the best: the boxes of the usual builders contain
 * their triangles whole, and an SBVH's references, clipped to their leaves,
 * cover each triangle whole (bvh_build_sbvh.c rounds clipped boxes outward),
 * so the leaf box around the triangle's closest point is never farther than
 * that point. Triangles are always tested whole, even through a clipped
 * reference.
 *
 * Arithmetic is in double from the stored float vertices: distances of
 * neighbouring triangles that tie in exact arithmetic then differ by a few
 * ulps of double at most, far below what a float answer can show. */
#include "structure.h"
#include "bvh2_own_layout.h"
#include "cwbvh_layout.h"

#include <math.h>
#include <string.h>

void as_closest_point_args_default(as_closest_point_args_t *args)
{
    memset(args, 0, sizeof *args);
    args->size = sizeof *args;
    args->max_distance = INFINITY;
}

/* The best candidate so far: squared distance, then source index. */
typedef struct nearest {
    double d2;
    uint32_t prim;
    double point[3];
    double u, v;
} nearest_t;

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* The closest point of segment a + t (b - a), t in [0, 1]; a zero-length
 * segment is its point. */
static double closest_on_segment(const double p[3], const double a[3], const double b[3])
{
    const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
    const double len2 = dot3(ab, ab);
    if (!(len2 > 0.0)) return 0.0;
    const double t = dot3(ap, ab) / len2;
    return t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
}

/* The nearest of the three edges' closest points: the answer for a point
 * that does not project into the triangle, and for a triangle with no area
 * in double (corners on a line, or fewer). Builders leave out triangles
 * without a float normal, but corners exactly on a line can still have one
 * through rounding. q = (1 - u - v) a + u b + v c. */
static void closest_on_edges(const double p[3], const double a[3], const double b[3], const double c[3],
                             double q[3], double *u, double *v)
{
    const double *ends[3][2] = {{a, b}, {a, c}, {b, c}};
    double best = INFINITY;
    for (int e = 0; e < 3; ++e) {
        const double t = closest_on_segment(p, ends[e][0], ends[e][1]);
        double x[3], d2 = 0.0;
        for (int k = 0; k < 3; ++k) {
            x[k] = ends[e][0][k] + t * (ends[e][1][k] - ends[e][0][k]);
            d2 += (p[k] - x[k]) * (p[k] - x[k]);
        }
        if (d2 < best) {
            best = d2;
            memcpy(q, x, sizeof x);
            *u = e == 0 ? t : e == 1 ? 0.0 : 1.0 - t;
            *v = e == 0 ? 0.0 : t;
        }
    }
}

static void cross3(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* Ericson, Real-Time Collision Detection, section 5.1.5, in the form the
 * section starts from: when the point projects into the triangle, the
 * projection; otherwise the nearest of the edges' closest points. The
 * section's faster Voronoi-region form derives the region tests from six
 * dot products through Lagrange's identity, which cancels catastrophically
 * on slivers (thin triangles, real meshes have them) and then picks the
 * wrong region, up to the sliver's length away. Here the tests are triple
 * products with the normal, and the normal of float corners is exact up to
 * one rounding in double (the edge vectors are exact, their products too),
 * so a wrong inside/outside decision can only happen within rounding of an
 * edge, where both answers agree. q = (1 - u - v) a + u b + v c. */
static void closest_on_triangle(const double p[3], const double a[3], const double b[3], const double c[3],
                                double q[3], double *u, double *v)
{
    const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3];
    cross3(ab, ac, n);
    const double nn = dot3(n, n);
    if (!(nn > 0.0) || !isfinite(nn)) {
        closest_on_edges(p, a, b, c, q, u, v);
        return;
    }
    const double pa[3] = {a[0] - p[0], a[1] - p[1], a[2] - p[2]};
    const double pb[3] = {b[0] - p[0], b[1] - p[1], b[2] - p[2]};
    const double pc[3] = {c[0] - p[0], c[1] - p[1], c[2] - p[2]};
    double x[3];
    /* Twice the signed areas of the sub-triangles opposite a, b and c,
     * times |n|: all non-negative when the projection is inside. */
    cross3(pb, pc, x);
    const double wa = dot3(n, x);
    cross3(pc, pa, x);
    const double wb = dot3(n, x);
    cross3(pa, pb, x);
    const double wc = dot3(n, x);
    if (wa >= 0.0 && wb >= 0.0 && wc >= 0.0) {
        /* Along the normal: the height is well conditioned even on a sliver. */
        const double h = -dot3(n, pa) / nn;
        for (int k = 0; k < 3; ++k) q[k] = p[k] - h * n[k];
        const double sum = wa + wb + wc;
        *u = sum > 0.0 ? wb / sum : 0.0;
        *v = sum > 0.0 ? wc / sum : 0.0;
        return;
    }
    closest_on_edges(p, a, b, c, q, u, v);
}

/* Squared distance from the point to a box; +inf for the inverted box of an
 * empty child. */
static double box_distance2(const double p[3], const float lo[3], const float hi[3])
{
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k) {
        if (!(lo[k] <= hi[k])) return INFINITY;
        const double below = (double)lo[k] - p[k], above = p[k] - (double)hi[k];
        const double gap = below > 0.0 ? below : above > 0.0 ? above : 0.0;
        d2 += gap * gap;
    }
    return d2;
}

/* Tests the leaf's triangles against the best so far. Equal distances go to
 * the lower source index, so the answer does not depend on the order in
 * which the tree is walked, nor on which of an SBVH's references is met
 * first. */
static void leaf_closest(const double p[3], const as_tri4_t *tris, uint32_t first, uint32_t count, nearest_t *best)
{
    for (uint32_t i = first; i < first + count; ++i) {
        const as_tri4_t *t = &tris[i];
        const double a[3] = {t->v0.x, t->v0.y, t->v0.z}, b[3] = {t->v1.x, t->v1.y, t->v1.z};
        const double c[3] = {t->v2.x, t->v2.y, t->v2.z};
        const uint32_t prim = as_float_as_uint(t->v0.w);
        double q[3], u, v;
        closest_on_triangle(p, a, b, c, q, &u, &v);
        const double d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]);
        if (d2 < best->d2 || (d2 == best->d2 && prim < best->prim)) {
            best->d2 = d2;
            best->prim = prim;
            memcpy(best->point, q, sizeof q);
            best->u = u;
            best->v = v;
        }
    }
}

/* One child of an inner node, as both layouts describe it: its box, and
 * either the inner node whose children come next (inner >= 0) or a leaf's
 * triangle range. */
typedef struct child_ref {
    float lo[3], hi[3];
    int32_t inner;
    uint32_t first, count;
} child_ref_t;

typedef struct bvh_view {
    const as_bvh2_node_t *child_bounds;  /* one of the three is set */
    const as_bvh2o_node_t *own_bounds;
    const as_cwbvh_node_t *wide;
    const as_tri4_t *tris;
} bvh_view_t;

static void node_children(const bvh_view_t *bvh, int32_t node, child_ref_t c[2])
{
    if (bvh->child_bounds) {
        const as_bvh2_node_t *n = &bvh->child_bounds[node];
        const float box[2][6] = {{n->xy0.x, n->xy0.z, n->z01.x, n->xy0.y, n->xy0.w, n->z01.y},
                                 {n->xy1.x, n->xy1.z, n->z01.z, n->xy1.y, n->xy1.w, n->z01.w}};
        for (int k = 0; k < 2; ++k) {
            memcpy(c[k].lo, box[k], sizeof c[k].lo);
            memcpy(c[k].hi, box[k] + 3, sizeof c[k].hi);
            c[k].inner = n->child[k] >= 0 ? n->child[k] : -1;
            c[k].first = n->child[k] >= 0 ? 0 : (uint32_t)~n->child[k];
            c[k].count = n->child[k] >= 0 ? 0 : n->count[k];
        }
        return;
    }
    const as_bvh2o_node_t *n = &bvh->own_bounds[node];
    for (int k = 0; k < 2; ++k) {
        const as_bvh2o_node_t *ch = &bvh->own_bounds[n->child + k];
        memcpy(c[k].lo, ch->lo, sizeof c[k].lo);
        memcpy(c[k].hi, ch->hi, sizeof c[k].hi);
        c[k].inner = ch->child >= 0 ? n->child + k : -1;
        c[k].first = ch->child >= 0 ? 0 : (uint32_t)~ch->child;
        c[k].count = ch->child >= 0 ? 0 : ch->count;
    }
}

/* The walk. The root is an inner node in both layouts (a one-leaf tree has
 * an empty sibling); each level pushes at most one child, and validation
 * bounds the depth by AS_BVH2_MAX_DEPTH, so the stack cannot overflow. */
static void bvh_closest(const bvh_view_t *bvh, const double p[3], nearest_t *best)
{
    struct { int32_t node; double d2; } stack[AS_BVH2_MAX_DEPTH + 2];
    int sp = 0;
    int32_t node = 0;
    for (;;) {
        child_ref_t c[2];
        node_children(bvh, node, c);
        double d2[2];
        int open[2];
        for (int k = 0; k < 2; ++k) {
            d2[k] = box_distance2(p, c[k].lo, c[k].hi);
            /* <=, not <: a box at exactly the best distance may hold a tie
             * with a lower source index. */
            open[k] = d2[k] <= best->d2;
            if (open[k] && c[k].inner < 0) {
                leaf_closest(p, bvh->tris, c[k].first, c[k].count, best);
                open[k] = 0;
            }
        }
        /* The best may have improved in the leaf next door. */
        for (int k = 0; k < 2; ++k) open[k] = open[k] && d2[k] <= best->d2;
        if (open[0] && open[1]) {
            const int nearer = d2[1] < d2[0];
            if (sp < AS_BVH2_MAX_DEPTH + 2) {
                stack[sp].node = c[!nearer].inner;
                stack[sp].d2 = d2[!nearer];
                ++sp;
            }
            node = c[nearer].inner;
            continue;
        }
        if (open[0] || open[1]) {
            node = c[open[0] ? 0 : 1].inner;
            continue;
        }
        node = -1;
        while (sp > 0) {
            --sp;
            if (stack[sp].d2 <= best->d2) {
                node = stack[sp].node;
                break;
            }
        }
        if (node < 0) return;
    }
}

/* The same walk over the compressed wide BVH, through the boxes its
 * traversal decodes: a node's leaves first, then its inner children nearest
 * first, the others pushed (at most seven per level, and validation bounds
 * the depth by AS_CWBVH_MAX_DEPTH). */
static void wide_closest(const bvh_view_t *bvh, const double p[3], nearest_t *best)
{
    struct { uint32_t node; double d2; } stack[8 * (AS_CWBVH_MAX_DEPTH + 2)];
    int sp = 0;
    uint32_t node = 0;
    for (;;) {
        const as_cwbvh_node_t *n = &bvh->wide[node];
        struct { uint32_t node; double d2; } open[8];
        int nopen = 0;
        uint32_t rank = 0;
        for (int k = 0; k < 8; ++k) {
            const uint32_t meta = n->meta[k];
            if (meta == 0) continue;
            const int inner = as_cwbvh_meta_is_inner(meta);
            const uint32_t child = inner ? n->child_base + rank++ : 0;
            float lo[3], hi[3];
            for (int a = 0; a < 3; ++a) {
                const float scale = as_cwbvh_scale(n->e[a]);
                lo[a] = as_cwbvh_decode(n->p[a], scale, n->qlo[a][k]);
                hi[a] = as_cwbvh_decode(n->p[a], scale, n->qhi[a][k]);
            }
            const double d2 = box_distance2(p, lo, hi);
            /* <=, not <: a box at exactly the best distance may hold a tie
             * with a lower source index. */
            if (d2 > best->d2) continue;
            if (!inner) {
                leaf_closest(p, bvh->tris, n->tri_base + (meta & 31u), as_cwbvh_meta_count(meta), best);
                continue;
            }
            /* Insertion by distance, farthest first, ties in slot order. */
            int at = nopen++;
            while (at > 0 && open[at - 1].d2 < d2) {
                open[at] = open[at - 1];
                --at;
            }
            open[at].node = child;
            open[at].d2 = d2;
        }
        /* The best may have improved in a leaf of this node. */
        for (int k = 0; k + 1 < nopen; ++k) {
            if (open[k].d2 > best->d2 || sp >= (int)(sizeof stack / sizeof stack[0])) continue;
            stack[sp].node = open[k].node;
            stack[sp].d2 = open[k].d2;
            ++sp;
        }
        if (nopen > 0 && open[nopen - 1].d2 <= best->d2) {
            node = open[nopen - 1].node;
            continue;
        }
        int found = 0;
        while (sp > 0) {
            --sp;
            if (stack[sp].d2 <= best->d2) {
                node = stack[sp].node;
                found = 1;
                break;
            }
        }
        if (!found) return;
    }
}

typedef struct closest_job {
    bvh_view_t bvh;
    const float *points;
    size_t count;
    double max_d2;
    as_closest_point_t *out;
} closest_job_t;

static void closest_one(const closest_job_t *job, size_t i)
{
    const float *pf = job->points + 3 * i;
    as_closest_point_t *o = &job->out[i];
    nearest_t best = {job->max_d2, AS_NO_HIT, {0.0, 0.0, 0.0}, 0.0, 0.0};
    const double p[3] = {pf[0], pf[1], pf[2]};
    if (isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]) && job->bvh.tris) {
        if (job->bvh.wide) wide_closest(&job->bvh, p, &best);
        else bvh_closest(&job->bvh, p, &best);
    }
    o->prim = best.prim;
    if (best.prim == AS_NO_HIT) {
        o->point[0] = o->point[1] = o->point[2] = 0.0f;
        o->distance = INFINITY;
        o->u = o->v = 0.0f;
        return;
    }
    for (int k = 0; k < 3; ++k) o->point[k] = (float)best.point[k];
    o->distance = (float)sqrt(best.d2);
    o->u = (float)best.u;
    o->v = (float)best.v;
}

/* Points go out in blocks, as rays do in trace_cpu.c: neighbouring queries
 * tend to walk the same nodes. */
#define CLOSEST_BLOCK 256

static void closest_block(void *user, size_t block)
{
    const closest_job_t *job = user;
    const size_t begin = block * CLOSEST_BLOCK;
    const size_t end = begin + CLOSEST_BLOCK < job->count ? begin + CLOSEST_BLOCK : job->count;
    for (size_t i = begin; i < end; ++i) closest_one(job, i);
}

as_error_t as_closest_points(const as_structure_t *s, const float *points, size_t count,
                             const as_closest_point_args_t *user_args, as_closest_point_t *out)
{
    if (!s || (!points && count) || (!out && count))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_closest_points: NULL argument");
    as_closest_point_args_t args;
    as_closest_point_args_default(&args);
    if (user_args)
        memcpy(&args, user_args, user_args->size < sizeof args ? user_args->size : sizeof args);
    if (!(args.max_distance >= 0.0f))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_closest_points: max_distance %g is not a non-negative number",
                            (double)args.max_distance);
    const as_layout_ops_t *ops = as_structure_ops(s);
    if (s->meta.layout != AS_LAYOUT_BVH2_CHILD_BOUNDS && s->meta.layout != AS_LAYOUT_BVH2_OWN_BOUNDS &&
        s->meta.layout != AS_LAYOUT_BVH_CWBVH)
        return as_set_error(AS_ERROR_UNSUPPORTED, "closest-point queries need a BVH (bvh2-child-bounds, "
                            "bvh2-own-bounds or cwbvh); this structure is a %s in the %s layout", ops->kind_name,
                            ops->layout_name);
    /* The walk follows child indices and leaf ranges: only a valid tree may
     * be walked. */
    if (!args.assume_valid) {
        const as_error_t err = as_structure_check_valid(s);
        if (err != AS_OK) return err;
    }
    closest_job_t job;
    memset(&job, 0, sizeof job);
    const as_section_t *ts = as_structure_find(s, ASF_TAG_TRI4);
    const as_section_t *ns = as_structure_find(s, s->meta.layout == AS_LAYOUT_BVH2_CHILD_BOUNDS ? ASF_TAG_BVH2
                                                  : s->meta.layout == AS_LAYOUT_BVH2_OWN_BOUNDS  ? ASF_TAG_BVHO
                                                                                                 : ASF_TAG_CWBV);
    if (ns->count > 0 && ts->count > 0) {
        job.bvh.tris = ts->data;
        if (s->meta.layout == AS_LAYOUT_BVH2_CHILD_BOUNDS) job.bvh.child_bounds = ns->data;
        else if (s->meta.layout == AS_LAYOUT_BVH2_OWN_BOUNDS) job.bvh.own_bounds = ns->data;
        else job.bvh.wide = ns->data;
    }
    job.points = points;
    job.count = count;
    job.max_d2 = (double)args.max_distance * (double)args.max_distance;
    job.out = out;
    const size_t blocks = (count + CLOSEST_BLOCK - 1) / CLOSEST_BLOCK;
    if (blocks <= 1) {
        for (size_t i = 0; i < count; ++i) closest_one(&job, i);
    } else {
        as_parallel_for(as_thread_count(args.thread_count), blocks, closest_block, &job);
    }
    return AS_OK;
}

as_error_t as_closest_point(const as_structure_t *s, const float point[3], const as_closest_point_args_t *args,
                            as_closest_point_t *out)
{
    if (!s || !point || !out) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_closest_point: NULL argument");
    return as_closest_points(s, point, 1, args, out);
}
