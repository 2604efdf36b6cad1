/* as_closest_point and as_closest_points against a brute force in double
 * over every triangle, on every BVH builder (sah, sweep, midcut, sbvh) in
 * both layouts: random soups with slivers and zero-area triangles, the
 * bundled bunny, query points inside, outside, far away, on vertices and on
 * edges, with and without a distance cut-off. The answer must be the
 * reference's triangle, or one at the same distance (a tie), at the same
 * distance within 1e-6 relative. */
#include "reference.h"
#include "test_util.h"

#include <math.h>
#include <stdio.h>

/* ---- the reference: every triangle, normal equations and edges ------------ */

/* In long double (64-bit significand on x86-64): the normal equations below
 * lose precision on slivers, and the extra bits keep the reference well
 * ahead of the float answers it checks. */
typedef long double real;

static real seg_dist2(const real p[3], const real a[3], const real b[3])
{
    const real ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const real len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    real t = len2 > 0 ? ((p[0] - a[0]) * ab[0] + (p[1] - a[1]) * ab[1] + (p[2] - a[2]) * ab[2]) / len2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    real d2 = 0;
    for (int k = 0; k < 3; ++k) d2 += (p[k] - a[k] - t * ab[k]) * (p[k] - a[k] - t * ab[k]);
    return d2;
}

/* The distance from p to triangle (a, b, c): the smaller of the height over
 * the plane (when the foot of the perpendicular is inside, by barycentric
 * coordinates from the normal equations) and the three edges. */
static double ref_triangle_distance(const real p[3], const real a[3], const real b[3], const real c[3])
{
    real best = seg_dist2(p, a, b);
    const real d_ac = seg_dist2(p, a, c), d_bc = seg_dist2(p, b, c);
    if (d_ac < best) best = d_ac;
    if (d_bc < best) best = d_bc;
    const real e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const real w[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
    const real g11 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2];
    const real g22 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
    const real g12 = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2];
    const real r1 = w[0] * e1[0] + w[1] * e1[1] + w[2] * e1[2], r2 = w[0] * e2[0] + w[1] * e2[1] + w[2] * e2[2];
    const real det = g11 * g22 - g12 * g12;
    if (det > 0) {
        const real s = (g22 * r1 - g12 * r2) / det, t = (g11 * r2 - g12 * r1) / det;
        if (s >= 0 && t >= 0 && s + t <= 1) {
            /* The height over the plane, from the normal: the foot from s and
             * t would carry the normal equations' error on slivers. */
            const real n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
            const real h = n[0] * w[0] + n[1] * w[1] + n[2] * w[2];
            const real d2 = h * h / (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            if (d2 < best) best = d2;
        }
    }
    return (double)sqrtl(best);
}

typedef struct ref_mesh {
    const as_mesh_t *mesh;
    const float *pos;
    const uint32_t *ix;
    uint32_t tri_count;
    double diag;
} ref_mesh_t;

static ref_mesh_t ref_mesh(const as_mesh_t *m)
{
    ref_mesh_t r = {m, as_mesh_positions(m), as_mesh_indices(m), 0, 0};
    as_mesh_info_t info;
    as_mesh_get_info(m, &info);
    r.tri_count = info.triangle_count;
    double d2 = 0;
    for (int k = 0; k < 3; ++k) d2 += ((double)info.bounds_hi[k] - info.bounds_lo[k]) * ((double)info.bounds_hi[k] - info.bounds_lo[k]);
    r.diag = sqrt(d2);
    return r;
}

static double ref_distance_to(const ref_mesh_t *r, const float pf[3], uint32_t prim)
{
    const real p[3] = {pf[0], pf[1], pf[2]};
    real v[3][3];
    for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k) v[j][k] = r->pos[3 * (size_t)r->ix[3 * (size_t)prim + j] + k];
    return ref_triangle_distance(p, v[0], v[1], v[2]);
}

/* Nearest non-degenerate triangle (the structures hold no zero-area one);
 * lowest index among equal distances. */
static void ref_closest(const ref_mesh_t *r, const float p[3], uint32_t *prim, double *dist)
{
    *prim = AS_NO_HIT;
    *dist = INFINITY;
    for (uint32_t t = 0; t < r->tri_count; ++t) {
        if (as_mesh_triangle_is_degenerate(r->mesh, t)) continue;
        const double d = ref_distance_to(r, p, t);
        if (d < *dist) {
            *dist = d;
            *prim = t;
        }
    }
}

static double worst_abs, worst_abs_diag;
static int distances_agree(const ref_mesh_t *r, double got, double want)
{
    const double diff = fabs(got - want);
    if (diff > 1e-6 * want && diff > worst_abs) worst_abs = diff, worst_abs_diag = diff / r->diag;
    return diff <= 1e-6 * want + 1e-12 * r->diag;
}

/* ---- query points ------------------------------------------------------ */

typedef struct queries {
    float *p;
    size_t n, cap;
} queries_t;

static void add_point(queries_t *q, double x, double y, double z)
{
    if (q->n == q->cap) {
        q->cap = q->cap ? 2 * q->cap : 256;
        q->p = realloc(q->p, sizeof(float) * 3 * q->cap);
    }
    q->p[3 * q->n] = (float)x;
    q->p[3 * q->n + 1] = (float)y;
    q->p[3 * q->n + 2] = (float)z;
    q->n++;
}

/* Inside the scene box, around it, far away (a thousand diagonals), exactly
 * on vertices and on edge points (rounded to float: on or a hair off the
 * edge). */
static queries_t make_queries(const ref_mesh_t *r, uint64_t seed, size_t per_kind)
{
    queries_t q = {NULL, 0, 0};
    as_mesh_info_t info;
    as_mesh_get_info(r->mesh, &info);
    uint64_t st = seed;
    double lo[3], ext[3];
    for (int k = 0; k < 3; ++k) {
        lo[k] = info.bounds_lo[k];
        ext[k] = (double)info.bounds_hi[k] - info.bounds_lo[k];
    }
    for (size_t i = 0; i < per_kind; ++i)
        add_point(&q, lo[0] + ext[0] * ref_rand01(&st), lo[1] + ext[1] * ref_rand01(&st),
                  lo[2] + ext[2] * ref_rand01(&st));
    for (size_t i = 0; i < per_kind; ++i)
        add_point(&q, lo[0] + ext[0] * (3 * ref_rand01(&st) - 1), lo[1] + ext[1] * (3 * ref_rand01(&st) - 1),
                  lo[2] + ext[2] * (3 * ref_rand01(&st) - 1));
    for (size_t i = 0; i < per_kind / 8 + 1; ++i) {
        float d[3];
        ref_random_direction(&st, d);
        add_point(&q, lo[0] + 1000 * r->diag * d[0], lo[1] + 1000 * r->diag * d[1], lo[2] + 1000 * r->diag * d[2]);
    }
    for (size_t i = 0; i < per_kind; ++i) {
        const uint32_t t = (uint32_t)(ref_rand_u64(&st) % r->tri_count);
        const float *v = r->pos + 3 * (size_t)r->ix[3 * (size_t)t + (i % 3)];
        add_point(&q, v[0], v[1], v[2]);
    }
    for (size_t i = 0; i < per_kind; ++i) {
        const uint32_t t = (uint32_t)(ref_rand_u64(&st) % r->tri_count);
        const float *a = r->pos + 3 * (size_t)r->ix[3 * (size_t)t + (i % 3)];
        const float *b = r->pos + 3 * (size_t)r->ix[3 * (size_t)t + ((i + 1) % 3)];
        const double s = ref_rand01(&st);
        add_point(&q, a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), a[2] + s * (b[2] - a[2]));
    }
    return q;
}

/* ---- the comparison ---------------------------------------------------- */

typedef struct reference_answers {
    uint32_t *prim;
    double *dist;
} reference_answers_t;

static reference_answers_t reference_all(const ref_mesh_t *r, const queries_t *q)
{
    reference_answers_t a = {malloc(sizeof(uint32_t) * q->n), malloc(sizeof(double) * q->n)};
    for (size_t i = 0; i < q->n; ++i) ref_closest(r, q->p + 3 * i, &a.prim[i], &a.dist[i]);
    return a;
}

/* Every answer is the reference's triangle or a tie, at the reference's
 * distance, and its point and barycentrics describe a point of that
 * triangle at that distance. Returns the disagreements. */
static size_t compare(const char *what, const ref_mesh_t *r, const queries_t *q, const reference_answers_t *ref,
                      const as_closest_point_t *got, double max_distance)
{
    size_t bad = 0, ties = 0, found = 0;
    for (size_t i = 0; i < q->n; ++i) {
        const float *p = q->p + 3 * i;
        const as_closest_point_t *g = &got[i];
        const int expect_found = ref->dist[i] <= max_distance;
        int ok;
        if (!expect_found) {
            ok = g->prim == AS_NO_HIT && isinf(g->distance);
        } else if (g->prim == AS_NO_HIT || g->prim >= r->tri_count) {
            ok = 0;
        } else {
            found++;
            const double d_prim = ref_distance_to(r, p, g->prim);
            ok = distances_agree(r, g->distance, ref->dist[i]) && distances_agree(r, d_prim, ref->dist[i]);
            if (g->prim != ref->prim[i]) ties++;
            /* The point: on the reported triangle by its barycentrics, at
             * the reported distance from the query. */
            const float *v0 = r->pos + 3 * (size_t)r->ix[3 * (size_t)g->prim];
            const float *v1 = r->pos + 3 * (size_t)r->ix[3 * (size_t)g->prim + 1];
            const float *v2 = r->pos + 3 * (size_t)r->ix[3 * (size_t)g->prim + 2];
            double dq = 0;
            for (int k = 0; k < 3; ++k) {
                const double x = (1.0 - g->u - g->v) * v0[k] + (double)g->u * v1[k] + (double)g->v * v2[k];
                ok = ok && fabs(x - g->point[k]) <= 1e-5 * r->diag;
                dq += ((double)g->point[k] - p[k]) * ((double)g->point[k] - p[k]);
            }
            ok = ok && fabs(sqrt(dq) - g->distance) <= 1e-5 * (r->diag + g->distance);
            ok = ok && g->u >= -1e-6f && g->v >= -1e-6f && g->u + g->v <= 1.0f + 1e-6f;
        }
        if (!ok) {
            if (bad < 5)
                fprintf(stderr, "  %s point %zu (%.9g %.9g %.9g): reference prim %u at %.12g, got prim %u at %.12g "
                        "(its reference distance %.12g)\n", what, i, (double)p[0], (double)p[1], (double)p[2],
                        ref->prim[i], ref->dist[i], g->prim, (double)g->distance,
                        g->prim < r->tri_count ? ref_distance_to(r, p, g->prim) : -1.0);
            bad++;
        }
    }
    fprintf(stderr, "  %s: %zu points, %zu found, %zu ties on another triangle, %zu disagree\n", what, q->n, found,
            ties, bad);
    return bad;
}

static const as_builder_t bvh_builders[] = {AS_BUILDER_BVH_SAH_BINNED, AS_BUILDER_BVH_SAH_SWEEP,
                                            AS_BUILDER_BVH_MIDCUT, AS_BUILDER_BVH_SBVH};
static const as_layout_t bvh_layouts[] = {AS_LAYOUT_BVH2_CHILD_BOUNDS, AS_LAYOUT_BVH2_OWN_BOUNDS, AS_LAYOUT_BVH_CWBVH};

static as_structure_t *build(const as_mesh_t *mesh, as_structure_kind_t kind, as_builder_t builder, as_layout_t layout)
{
    as_build_args_t args;
    as_build_args_default(&args);
    args.structure = kind;
    args.builder = builder;
    args.layout = layout;
    as_structure_t *s = as_structure_build(mesh, &args);
    if (!s) fprintf(stderr, "  build failed: %s\n", as_get_error_message());
    return s;
}

/* Every BVH variant against the reference, without and with cut-offs
 * (half and twice the median reference distance), batch and one by one. */
static void check_every_variant(const char *name, const as_mesh_t *mesh, uint64_t seed, size_t per_kind)
{
    const ref_mesh_t r = ref_mesh(mesh);
    queries_t q = make_queries(&r, seed, per_kind);
    const reference_answers_t ref = reference_all(&r, &q);
    const double cutoffs[3] = {INFINITY, 0.02 * r.diag, 0.1 * r.diag};
    as_closest_point_t *got = malloc(sizeof *got * q.n);
    for (size_t b = 0; b < sizeof bvh_builders / sizeof bvh_builders[0]; ++b) {
        for (size_t l = 0; l < sizeof bvh_layouts / sizeof bvh_layouts[0]; ++l) {
            as_structure_t *s = build(mesh, AS_STRUCT_BVH, bvh_builders[b], bvh_layouts[l]);
            CHECK(s != NULL);
            if (!s) continue;
            for (int c = 0; c < 3; ++c) {
                as_closest_point_args_t args;
                as_closest_point_args_default(&args);
                args.max_distance = (float)cutoffs[c];
                /* The float cut-off is what the query compares against. */
                const double max_distance = args.max_distance;
                char what[160];
                snprintf(what, sizeof what, "%s %s %s max %g", name, as_builder_name(bvh_builders[b]),
                         as_layout_name(bvh_layouts[l]), max_distance);
                CHECK_EQ_INT(as_closest_points(s, q.p, q.n, &args, got), AS_OK);
                CHECK_EQ_U64(compare(what, &r, &q, &ref, got, max_distance), 0);
                /* One by one gives the same bits as the batch. */
                size_t differ = 0;
                for (size_t i = 0; i < q.n; i += 7) {
                    as_closest_point_t one;
                    CHECK_EQ_INT(as_closest_point(s, q.p + 3 * i, &args, &one), AS_OK);
                    differ += memcmp(&one, &got[i], sizeof one) != 0;
                }
                CHECK_EQ_U64(differ, 0);
            }
            as_structure_release(s);
        }
    }
    free(got);
    free(ref.prim);
    free(ref.dist);
    free(q.p);
}

/* Random soups: overlapping triangles of mixed sizes, plus slivers (a vertex
 * a hair off the opposite edge) and zero-area triangles (a repeated vertex,
 * three points on a line) that the structures leave out. */
static as_mesh_t *random_soup(uint64_t seed, uint32_t tris)
{
    uint64_t st = seed;
    float *p = malloc(sizeof(float) * 9 * tris);
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * tris);
    for (uint32_t t = 0; t < tris; ++t) {
        float c[3];
        for (int k = 0; k < 3; ++k) c[k] = (float)ref_rand01(&st);
        const double size = t % 3 == 0 ? 0.3 : 0.05;
        float *v = p + 9 * t;
        for (int j = 0; j < 3; ++j)
            for (int k = 0; k < 3; ++k) v[3 * j + k] = c[k] + (float)(size * (ref_rand01(&st) - 0.5));
        if (t % 17 == 5) /* sliver */
            for (int k = 0; k < 3; ++k) v[6 + k] = 0.5f * (v[k] + v[3 + k]) + (k == 0 ? 1e-6f : 0.0f);
        if (t % 31 == 7) /* repeated vertex: zero area */
            for (int k = 0; k < 3; ++k) v[6 + k] = v[k];
        if (t % 37 == 11) /* on a line up to float rounding: zero area or a sliver */
            for (int k = 0; k < 3; ++k) v[6 + k] = v[k] + 2.0f * (v[3 + k] - v[k]);
        for (int j = 0; j < 3; ++j) ix[3 * t + j] = 3 * t + j;
    }
    as_mesh_t *m = as_mesh_create(3 * tris, p, tris, ix);
    free(p);
    free(ix);
    return m;
}

static void closest_point_agrees_with_brute_force_on_random_soups(void)
{
    for (uint64_t seed = 1; seed <= 2; ++seed) {
        as_mesh_t *m = random_soup(seed, seed == 1 ? 300 : 3000);
        CHECK(m != NULL);
        if (!m) continue;
        as_mesh_info_t info;
        as_mesh_get_info(m, &info);
        CHECK(info.degenerate_count > 0); /* the soups do hold zero-area triangles */
        check_every_variant(seed == 1 ? "soup300" : "soup3000", m, 100 + seed, 200);
        as_mesh_release(m);
    }
}

/* Two triangles sharing an edge, and a copy of one: points on the shared
 * edge and above it are at the same distance from several triangles, and
 * the lowest index must win in every variant. */
static void equal_distances_go_to_the_lowest_index(void)
{
    const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
    const uint32_t ix[] = {1, 3, 2, 0, 1, 2, 0, 1, 2};
    as_mesh_t *m = as_mesh_create(4, pos, 3, ix);
    CHECK(m != NULL);
    const float on_edge[3] = {0.5f, 0.5f, 0.0f}, above_edge[3] = {0.5f, 0.5f, 2.0f}, above_copy[3] = {0.2f, 0.2f, 1.0f};
    for (size_t b = 0; m && b < sizeof bvh_builders / sizeof bvh_builders[0]; ++b) {
        for (size_t l = 0; l < 2; ++l) {
            as_structure_t *s = build(m, AS_STRUCT_BVH, bvh_builders[b], bvh_layouts[l]);
            CHECK(s != NULL);
            if (!s) continue;
            as_closest_point_t r;
            CHECK_EQ_INT(as_closest_point(s, on_edge, NULL, &r), AS_OK);
            CHECK_EQ_U64(r.prim, 0);
            CHECK(r.distance == 0.0f);
            CHECK_EQ_INT(as_closest_point(s, above_edge, NULL, &r), AS_OK);
            CHECK_EQ_U64(r.prim, 0);
            CHECK(r.distance == 2.0f);
            /* Triangles 1 and 2 are the same; 0 is farther. */
            CHECK_EQ_INT(as_closest_point(s, above_copy, NULL, &r), AS_OK);
            CHECK_EQ_U64(r.prim, 1);
            CHECK(r.distance == 1.0f);
            CHECK(r.point[0] == 0.2f && r.point[1] == 0.2f && r.point[2] == 0.0f);
            as_structure_release(s);
        }
    }
    as_mesh_release(m);

    /* Sixteen triangles sharing the origin, numbered against their order in
     * x: every builder puts the low-x ones (high indices) in the children
     * walked first, and triangle 0 last; all are at distance 0. */
    float fan_pos[3 * 33];
    uint32_t fan_ix[3 * 16];
    memset(fan_pos, 0, sizeof fan_pos);
    for (uint32_t k = 0; k < 16; ++k) {
        const float x = (float)(k + 1);
        fan_pos[3 * (1 + 2 * k)] = x; fan_pos[3 * (1 + 2 * k) + 1] = 1.0f;
        fan_pos[3 * (2 + 2 * k)] = x; fan_pos[3 * (2 + 2 * k) + 1] = -1.0f;
        const uint32_t index = 15 - k;
        fan_ix[3 * index] = 0; fan_ix[3 * index + 1] = 1 + 2 * k; fan_ix[3 * index + 2] = 2 + 2 * k;
    }
    as_mesh_t *fan = as_mesh_create(33, fan_pos, 16, fan_ix);
    CHECK(fan != NULL);
    const float origin[3] = {0.0f, 0.0f, 0.0f};
    for (size_t b = 0; fan && b < sizeof bvh_builders / sizeof bvh_builders[0]; ++b) {
        for (size_t l = 0; l < 2; ++l) {
            as_structure_t *s = build(fan, AS_STRUCT_BVH, bvh_builders[b], bvh_layouts[l]);
            CHECK(s != NULL);
            if (!s) continue;
            as_closest_point_t r;
            CHECK_EQ_INT(as_closest_point(s, origin, NULL, &r), AS_OK);
            CHECK_EQ_U64(r.prim, 0);
            CHECK(r.distance == 0.0f);
            as_structure_release(s);
        }
    }
    as_mesh_release(fan);
}

/* The cut-off is inclusive: a triangle at exactly max_distance counts, one
 * a little farther does not. */
static void max_distance_is_inclusive(void)
{
    const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t ix[] = {0, 1, 2};
    as_mesh_t *m = as_mesh_create(3, pos, 1, ix);
    as_structure_t *s = m ? build(m, AS_STRUCT_BVH, AS_BUILDER_DEFAULT, AS_LAYOUT_DEFAULT) : NULL;
    CHECK(s != NULL);
    if (s) {
        const float p[3] = {0.25f, 0.25f, 3.0f};
        as_closest_point_args_t args;
        as_closest_point_args_default(&args);
        as_closest_point_t r;
        args.max_distance = 3.0f;
        CHECK_EQ_INT(as_closest_point(s, p, &args, &r), AS_OK);
        CHECK_EQ_U64(r.prim, 0);
        args.max_distance = nextafterf(3.0f, 0.0f);
        CHECK_EQ_INT(as_closest_point(s, p, &args, &r), AS_OK);
        CHECK_EQ_U64(r.prim, AS_NO_HIT);
        CHECK(isinf(r.distance));
        args.max_distance = -1.0f;
        CHECK_EQ_INT(as_closest_point(s, p, &args, &r), AS_ERROR_INVALID_ARGUMENT);
        args.max_distance = NAN;
        CHECK_EQ_INT(as_closest_point(s, p, &args, &r), AS_ERROR_INVALID_ARGUMENT);
        const float bad[3] = {NAN, 0.0f, 0.0f};
        CHECK_EQ_INT(as_closest_point(s, bad, NULL, &r), AS_OK);
        CHECK_EQ_U64(r.prim, AS_NO_HIT);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

static void closest_point_agrees_with_brute_force_on_the_bunny(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(m != NULL);
    if (!m) return;
    check_every_variant("bunny", m, 7, 80);
    as_mesh_release(m);
}

/* Thread count changes nothing. */
static void threads_give_the_same_answers(void)
{
    as_mesh_t *m = random_soup(9, 2000);
    as_structure_t *s = m ? build(m, AS_STRUCT_BVH, AS_BUILDER_BVH_SBVH, AS_LAYOUT_DEFAULT) : NULL;
    CHECK(s != NULL);
    if (s) {
        const ref_mesh_t r = ref_mesh(m);
        queries_t q = make_queries(&r, 3, 2000);
        as_closest_point_t *a = malloc(sizeof *a * q.n), *b = malloc(sizeof *b * q.n);
        as_closest_point_args_t args;
        as_closest_point_args_default(&args);
        args.thread_count = 1;
        CHECK_EQ_INT(as_closest_points(s, q.p, q.n, &args, a), AS_OK);
        args.thread_count = 4;
        CHECK_EQ_INT(as_closest_points(s, q.p, q.n, &args, b), AS_OK);
        CHECK(memcmp(a, b, sizeof *a * q.n) == 0);
        free(a);
        free(b);
        free(q.p);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

/* Only the BVH family answers; the others say so. */
static void other_structures_are_unsupported(void)
{
    as_mesh_t *m = random_soup(4, 100);
    const as_structure_kind_t kinds[] = {AS_STRUCT_KD, AS_STRUCT_GRID};
    for (size_t k = 0; m && k < 2; ++k) {
        as_structure_t *s = build(m, kinds[k], AS_BUILDER_DEFAULT, AS_LAYOUT_DEFAULT);
        CHECK(s != NULL);
        if (!s) continue;
        const float p[3] = {0.5f, 0.5f, 0.5f};
        as_closest_point_t r;
        as_clear_error();
        CHECK_EQ_INT(as_closest_point(s, p, NULL, &r), AS_ERROR_UNSUPPORTED);
        CHECK_EQ_INT(as_get_error(), AS_ERROR_UNSUPPORTED);
        CHECK_STR_CONTAINS(as_get_error_message(), "closest-point queries need a BVH");
        CHECK_STR_CONTAINS(as_get_error_message(), k == 0 ? "kd-standard" : "grid");
        as_structure_release(s);
    }
    as_mesh_release(m);
}

/* A damaged tree (loaded without checksums) is refused before it is
 * walked: a child index past the end would read outside the nodes. */
static void damaged_structures_are_refused(void)
{
    as_mesh_t *m = random_soup(5, 200);
    as_structure_t *s = m ? build(m, AS_STRUCT_BVH, AS_BUILDER_DEFAULT, AS_LAYOUT_DEFAULT) : NULL;
    CHECK(s != NULL);
    const char *path = AS_BINARY_DIR "/test_closest_point_damaged.asf";
    if (s && as_structure_save(s, path, NULL) == AS_OK) {
        unsigned char *data = NULL;
        size_t size = 0;
        CHECK(test_read_file(path, &data, &size));
        as_load_args_t la;
        as_load_args_default(&la);
        la.verify_checksums = false;
        as_structure_t *l = as_structure_load_memory(data, size, path, &la);
        CHECK(l != NULL);
        for (uint32_t i = 0; l && i < as_structure_section_count(l); ++i) {
            as_section_info_t si;
            as_structure_section_info(l, i, &si);
            if (strcmp(si.tag, "BVH2") != 0) continue;
            as_structure_release(l);
            const int32_t far_child = 1 << 30;
            memcpy(data + si.offset + 48, &far_child, sizeof far_child); /* root's child[0] */
            l = as_structure_load_memory(data, size, path, &la);
            break;
        }
        CHECK(l != NULL);
        const float p[3] = {0.5f, 0.5f, 0.5f};
        as_closest_point_t r;
        if (l) CHECK_EQ_INT(as_closest_point(l, p, NULL, &r), AS_ERROR_INVALID_STRUCTURE);
        as_structure_release(l);
        free(data);
        remove(path);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

int main(int argc, char **argv)
{
    (void)argc;
    (void)argv;
    RUN_TEST(equal_distances_go_to_the_lowest_index);
    RUN_TEST(max_distance_is_inclusive);
    RUN_TEST(other_structures_are_unsupported);
    RUN_TEST(damaged_structures_are_refused);
    RUN_TEST(threads_give_the_same_answers);
    RUN_TEST(closest_point_agrees_with_brute_force_on_random_soups);
    RUN_TEST(closest_point_agrees_with_brute_force_on_the_bunny);
    fprintf(stderr, "largest difference beyond 1e-6 relative: %g (%g of the diagonal)\n", worst_abs, worst_abs_diag);
    TEST_EXIT();
}
