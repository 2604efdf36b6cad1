/* A second stiff-case set, independent of the library's generator
 * (as_stiff_case_generate): cases of the same kinds as the suite's, other
 * meshes and rays, built here with fixed seeds. Each case states its
 * correct outcome and checks it exactly, every ray also against the
 * double-precision reference (reference.h).
 *
 *   test_stiff_more [--gpu] STRUCTURE BUILDER LAYOUT [CASE]
 *
 * With --gpu the rays are traced by the CUDA kernels (exit 77, skipped,
 * without a usable GPU); builds and the reference stay on the CPU.
 * Cases: watertight, needles, fan, signed_zero, grazing, in_plane, range,
 * degenerate, duplicates, planar, bad_rays.
 *
 * A leak is a miss of a ray that must cross a closed surface: from a point
 * inside it (unbounded), or from outside through a point of it to a point
 * inside. Every such ray is aimed exactly at a vertex, at an edge's
 * midpoint or at a point one float step to either side of an edge. */
#include "stiff_harness.h"

#include "structure.h"
#include "bvh2_layout.h"
#include "bvh2_own_layout.h"
#include "bih_layout.h"
#include "cwbvh_layout.h"
#include "grid_layout.h"
#include "kd_layout.h"
#include "octree_layout.h"

#include <float.h>

/* ---- a scene under construction: vertices, triangles, rays, outcomes ---- */

typedef struct scene {
    float *p;        /* 3 per vertex */
    float *anchor;   /* 3 per vertex: a point inside the closed mesh the
                        vertex belongs to, or NaN */
    uint32_t nv, cap_v;
    uint32_t *ix;
    uint32_t nt, cap_t;
    as_ray_t *rays;
    as_stiff_outcome_t *out;
    size_t nr, cap_r;
    uint32_t *prims;
    size_t np, cap_p;
} scene_t;

static void *grow(void *ptr, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap) return ptr;
    size_t n = *cap ? *cap : 256;
    while (n < need) n *= 2;
    void *q = realloc(ptr, n * elem);
    if (!q) {
        fprintf(stderr, "out of memory\n");
        exit(1);
    }
    *cap = n;
    return q;
}

/* A vertex rounded once from double; `anchor` may be NULL. */
static uint32_t sc_vertex(scene_t *sc, const double v[3], const double *anchor)
{
    size_t cap = sc->cap_v;
    sc->p = grow(sc->p, &cap, (size_t)sc->nv + 1, 3 * sizeof(float));
    cap = sc->cap_v;
    sc->anchor = grow(sc->anchor, &cap, (size_t)sc->nv + 1, 3 * sizeof(float));
    sc->cap_v = (uint32_t)cap;
    for (int k = 0; k < 3; ++k) {
        sc->p[3 * (size_t)sc->nv + k] = (float)v[k];
        sc->anchor[3 * (size_t)sc->nv + k] = anchor ? (float)anchor[k] : NAN;
    }
    return sc->nv++;
}

static uint32_t sc_vertex3(scene_t *sc, double x, double y, double z)
{
    const double v[3] = {x, y, z};
    return sc_vertex(sc, v, NULL);
}

static uint32_t sc_tri(scene_t *sc, uint32_t a, uint32_t b, uint32_t c)
{
    size_t cap = sc->cap_t;
    sc->ix = grow(sc->ix, &cap, (size_t)sc->nt + 1, 3 * sizeof(uint32_t));
    sc->cap_t = (uint32_t)cap;
    sc->ix[3 * (size_t)sc->nt] = a;
    sc->ix[3 * (size_t)sc->nt + 1] = b;
    sc->ix[3 * (size_t)sc->nt + 2] = c;
    return sc->nt++;
}

/* A ray with its outcome; every ray is also checked against the
 * reference. Returns its index. */
static size_t sc_ray(scene_t *sc, const float org[3], const float dir[3], float tmin, float tmax, uint32_t expect)
{
    size_t cap = sc->cap_r;
    sc->rays = grow(sc->rays, &cap, sc->nr + 1, sizeof *sc->rays);
    cap = sc->cap_r;
    sc->out = grow(sc->out, &cap, sc->nr + 1, sizeof *sc->out);
    sc->cap_r = cap;
    as_ray_t *r = &sc->rays[sc->nr];
    memcpy(r->org, org, sizeof r->org);
    memcpy(r->dir, dir, sizeof r->dir);
    r->tmin = tmin;
    r->tmax = tmax;
    sc->out[sc->nr] = (as_stiff_outcome_t){expect, 0, 0, AS_STIFF_NO_RAY, 1};
    return sc->nr++;
}

/* A list of primitives for PRIM and NOT_PRIM outcomes; returns its start. */
static uint32_t sc_prims(scene_t *sc, const uint32_t *prims, size_t n)
{
    sc->prims = grow(sc->prims, &sc->cap_p, sc->np + n, sizeof *sc->prims);
    memcpy(sc->prims + sc->np, prims, n * sizeof *prims);
    const uint32_t first = (uint32_t)sc->np;
    sc->np += n;
    return first;
}

static void sc_outcome_prims(scene_t *sc, size_t ray, uint32_t first, uint32_t count)
{
    sc->out[ray].first = first;
    sc->out[ray].count = count;
}

static void sc_free(scene_t *sc)
{
    free(sc->p);
    free(sc->anchor);
    free(sc->ix);
    free(sc->rays);
    free(sc->out);
    free(sc->prims);
    memset(sc, 0, sizeof *sc);
}

static as_mesh_t *sc_mesh(const scene_t *sc)
{
    as_mesh_t *m = as_mesh_create(sc->nv, sc->p, sc->nt, sc->ix);
    if (!m) fprintf(stderr, "  mesh refused: %s\n", as_get_error_message());
    CHECK(m != NULL);
    return m;
}

/* ---- shapes in double, placed by a rotation, a scale and an offset ------- */

typedef struct shape {
    double *v;       /* 3 per vertex, unit size */
    double *anchor;  /* 3 per vertex: inside point (local) */
    uint32_t nv;
    uint32_t *t;
    uint32_t nt;
    size_t cap_v, cap_a, cap_t;
} shape_t;

static uint32_t sh_vertex(shape_t *s, double x, double y, double z, double ax, double ay, double az)
{
    s->v = grow(s->v, &s->cap_v, 3 * ((size_t)s->nv + 1), sizeof(double));
    s->anchor = grow(s->anchor, &s->cap_a, 3 * ((size_t)s->nv + 1), sizeof(double));
    double *v = s->v + 3 * (size_t)s->nv, *a = s->anchor + 3 * (size_t)s->nv;
    v[0] = x, v[1] = y, v[2] = z;
    a[0] = ax, a[1] = ay, a[2] = az;
    return s->nv++;
}

static void sh_tri(shape_t *s, uint32_t a, uint32_t b, uint32_t c)
{
    s->t = grow(s->t, &s->cap_t, 3 * ((size_t)s->nt + 1), sizeof(uint32_t));
    s->t[3 * (size_t)s->nt] = a;
    s->t[3 * (size_t)s->nt + 1] = b;
    s->t[3 * (size_t)s->nt + 2] = c;
    ++s->nt;
}

static void sh_free(shape_t *s)
{
    free(s->v);
    free(s->anchor);
    free(s->t);
    memset(s, 0, sizeof *s);
}

/* A torus around z: major radius 1, minor 1/4 (so a point 2 minor radii
 * out from the tube's centre circle is outside), `nu` x `nv` quads. */
static void sh_torus(shape_t *s, int nu, int nv)
{
    const double R = 1.0, r = 0.25, pi = 3.14159265358979323846;
    for (int i = 0; i < nu; ++i)
        for (int j = 0; j < nv; ++j) {
            const double u = 2 * pi * i / nu, w = 2 * pi * j / nv;
            sh_vertex(s, (R + r * cos(w)) * cos(u), (R + r * cos(w)) * sin(u), r * sin(w), R * cos(u), R * sin(u), 0);
        }
    for (int i = 0; i < nu; ++i)
        for (int j = 0; j < nv; ++j) {
            const uint32_t a = (uint32_t)(i * nv + j), b = (uint32_t)(((i + 1) % nu) * nv + j),
                           c = (uint32_t)(((i + 1) % nu) * nv + (j + 1) % nv), d = (uint32_t)(i * nv + (j + 1) % nv);
            sh_tri(s, a, b, c);
            sh_tri(s, a, c, d);
        }
}

/* The icosahedron subdivided `levels` times, on the unit sphere. */
static void sh_icosphere(shape_t *s, int levels)
{
    const double g = (1.0 + sqrt(5.0)) / 2.0;
    const double iv[12][3] = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                              {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
    const uint32_t it[20][3] = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                                {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    const double n0 = sqrt(1 + g * g);
    for (int i = 0; i < 12; ++i) sh_vertex(s, iv[i][0] / n0, iv[i][1] / n0, iv[i][2] / n0, 0, 0, 0);
    for (int i = 0; i < 20; ++i) sh_tri(s, it[i][0], it[i][1], it[i][2]);
    for (int l = 0; l < levels; ++l) {
        /* Edge midpoints through an open-addressing table keyed by the pair. */
        const size_t cap = 4 * (size_t)s->nt * 2;
        size_t tsize = 1;
        while (tsize < cap) tsize *= 2;
        uint64_t *key = malloc(tsize * sizeof *key);
        uint32_t *val = malloc(tsize * sizeof *val);
        for (size_t i = 0; i < tsize; ++i) key[i] = UINT64_MAX;
        const uint32_t nt = s->nt;
        uint32_t *old = malloc(3 * (size_t)nt * sizeof *old);
        memcpy(old, s->t, 3 * (size_t)nt * sizeof *old);
        s->nt = 0;
        for (uint32_t t = 0; t < nt; ++t) {
            uint32_t m[3];
            for (int e = 0; e < 3; ++e) {
                uint32_t a = old[3 * t + e], b = old[3 * t + (e + 1) % 3];
                if (a > b) { const uint32_t x = a; a = b; b = x; }
                const uint64_t k = ((uint64_t)a << 32) | b;
                size_t h = (size_t)((k * 0x9E3779B97F4A7C15ull) >> 20) & (tsize - 1);
                while (key[h] != UINT64_MAX && key[h] != k) h = (h + 1) & (tsize - 1);
                if (key[h] != k) {
                    double x = s->v[3 * a] + s->v[3 * b], y = s->v[3 * a + 1] + s->v[3 * b + 1],
                           z = s->v[3 * a + 2] + s->v[3 * b + 2];
                    const double n = sqrt(x * x + y * y + z * z);
                    key[h] = k;
                    val[h] = sh_vertex(s, x / n, y / n, z / n, 0, 0, 0);
                }
                m[e] = val[h];
            }
            const uint32_t a = old[3 * t], b = old[3 * t + 1], c = old[3 * t + 2];
            sh_tri(s, a, m[0], m[2]);
            sh_tri(s, m[0], b, m[1]);
            sh_tri(s, m[2], m[1], c);
            sh_tri(s, m[0], m[1], m[2]);
        }
        free(old);
        free(key);
        free(val);
    }
}

/* A surface of revolution around z, closed by two fans: `rings` circles of
 * (radius, z) and a pole on the axis at each end, `segs` segments. The
 * pole vertices have valence `segs`. Flat caps when a pole lies in its
 * end circle's plane (a capped cylinder), apexes otherwise (a bicone). */
static void sh_revolution(shape_t *s, int segs, int rings, const double (*rz)[2], double z_bottom, double z_top)
{
    const double pi = 3.14159265358979323846;
    const uint32_t bot = sh_vertex(s, 0, 0, z_bottom, 0, 0, 0), top = sh_vertex(s, 0, 0, z_top, 0, 0, 0);
    const uint32_t first = s->nv;
    for (int r = 0; r < rings; ++r)
        for (int k = 0; k < segs; ++k) {
            const double a = 2 * pi * k / segs;
            sh_vertex(s, rz[r][0] * cos(a), rz[r][0] * sin(a), rz[r][1], 0, 0, 0);
        }
#define RV(r, k) (first + (uint32_t)((r) * segs + ((k) % segs)))
    for (int k = 0; k < segs; ++k) {
        sh_tri(s, bot, RV(0, k + 1), RV(0, k));
        sh_tri(s, top, RV(rings - 1, k), RV(rings - 1, k + 1));
    }
    for (int r = 0; r + 1 < rings; ++r)
        for (int k = 0; k < segs; ++k) {
            sh_tri(s, RV(r, k), RV(r, k + 1), RV(r + 1, k + 1));
            sh_tri(s, RV(r, k), RV(r + 1, k + 1), RV(r + 1, k));
        }
#undef RV
}

/* The shortest edge of a shape, in its own units. */
static double sh_min_edge(const shape_t *s)
{
    double m = INFINITY;
    for (uint32_t t = 0; t < s->nt; ++t)
        for (int e = 0; e < 3; ++e) {
            const double *a = s->v + 3 * s->t[3 * t + e], *b = s->v + 3 * s->t[3 * t + (e + 1) % 3];
            const double d = sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                                  (a[2] - b[2]) * (a[2] - b[2]));
            if (d < m) m = d;
        }
    return m;
}

typedef struct placement {
    double rot[9];
    double scale;
    double offset[3];
} placement_t;

/* A random rotation (a uniform unit quaternion), computed in double. */
static void random_rotation(uint64_t *st, double r[9])
{
    double q[4], n;
    do {
        for (int k = 0; k < 4; ++k) q[k] = 2 * ref_rand01(st) - 1;
        n = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    } while (n > 1 || n < 1e-3);
    n = sqrt(n);
    const double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
    const double m[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
                         2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                         2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
    memcpy(r, m, sizeof m);
}

static void place(const placement_t *pl, const double v[3], double out[3])
{
    for (int k = 0; k < 3; ++k)
        out[k] = pl->offset[k] + pl->scale * (pl->rot[3 * k] * v[0] + pl->rot[3 * k + 1] * v[1] + pl->rot[3 * k + 2] * v[2]);
}

/* The shape placed into the scene, each vertex rounded once to float;
 * returns its first triangle. */
static uint32_t sc_add_shape(scene_t *sc, const shape_t *s, const placement_t *pl)
{
    const uint32_t v0 = sc->nv, t0 = sc->nt;
    for (uint32_t i = 0; i < s->nv; ++i) {
        double v[3], a[3];
        place(pl, s->v + 3 * (size_t)i, v);
        place(pl, s->anchor + 3 * (size_t)i, a);
        sc_vertex(sc, v, a);
    }
    for (uint32_t t = 0; t < s->nt; ++t) sc_tri(sc, v0 + s->t[3 * t], v0 + s->t[3 * t + 1], v0 + s->t[3 * t + 2]);
    return t0;
}

/* The smallest scale at which a shape of unit radius `radius` and shortest
 * edge `min_edge` at `offset` (largest coordinate magnitude) has edges of at
 * least 128 float spacings: the spacing stays below 1/100 of an edge. */
static double scale_for(double offset, double radius, double min_edge)
{
    double s = 1.0 / 1024;
    for (;;) {
        const float far = (float)(offset + s * radius);
        const double spacing = (double)nextafterf(far, INFINITY) - (double)far;
        if (s * min_edge >= 128.0 * spacing) return s;
        s *= 1.25;
    }
}

/* ---- closed-mesh rays: vertices, edge midpoints, one step off edges ------ */

/* Rays aimed at targets, and those whose direction is exactly the target
 * minus the origin (so the ray passes through the target in exact
 * arithmetic): the float subtraction was exact. */
static size_t target_total, target_exact;

static void count_exact(const float o[3], const float d[3], const float q[3])
{
    int ok = 1;
    for (int k = 0; k < 3; ++k) ok &= (double)d[k] == (double)q[k] - (double)o[k];
    ++target_total;
    target_exact += ok;
}

/* Two rays for a target point q of a closed surface whose inside holds c:
 * from c towards q (unbounded), and from 2q - c (outside) through q to
 * about c (tmax 2). Both must hit. */
static void target_rays(scene_t *sc, const float q[3], const float c[3])
{
    float d[3], o[3], e[3];
    for (int k = 0; k < 3; ++k) d[k] = q[k] - c[k];
    sc_ray(sc, c, d, 0.0f, INFINITY, AS_STIFF_EXPECT_HIT);
    count_exact(c, d, q);
    for (int k = 0; k < 3; ++k) o[k] = q[k] + (q[k] - c[k]);
    for (int k = 0; k < 3; ++k) e[k] = q[k] - o[k];
    sc_ray(sc, o, e, 0.0f, 2.0f, AS_STIFF_EXPECT_HIT);
    count_exact(o, e, q);
}

/* Rays at every vertex, every edge's midpoint and the points one float
 * step to either side of it (across the edge, on the coordinate most
 * across it), of triangles [t0, t1), each vertex and edge once; plus, at
 * vertices of valence 24 or more, `extra` rays from other inside points
 * (within 0.3 of the way from the anchor to the vertex). Returns the rays
 * added. */
static size_t closed_rays(scene_t *sc, uint32_t t0, uint32_t t1, int extra, uint64_t seed)
{
    const size_t r0 = sc->nr;
    uint8_t *seen = calloc(sc->nv, 1);
    uint32_t *valence = calloc(sc->nv, sizeof *valence);
    for (uint32_t t = t0; t < t1; ++t)
        for (int e = 0; e < 3; ++e) ++valence[sc->ix[3 * (size_t)t + e]];
    uint64_t st = seed;
    for (uint32_t t = t0; t < t1; ++t)
        for (int e = 0; e < 3; ++e) {
            const uint32_t a = sc->ix[3 * (size_t)t + e], b = sc->ix[3 * (size_t)t + (e + 1) % 3],
                           w = sc->ix[3 * (size_t)t + (e + 2) % 3];
            const float *pa = sc->p + 3 * (size_t)a, *pb = sc->p + 3 * (size_t)b, *pw = sc->p + 3 * (size_t)w;
            const float *ca = sc->anchor + 3 * (size_t)a, *cb = sc->anchor + 3 * (size_t)b;
            if (!seen[a]) {
                seen[a] = 1;
                target_rays(sc, pa, ca);
                if (valence[a] >= 24)
                    for (int i = 0; i < extra; ++i) {
                        float c[3], d[3];
                        for (int k = 0; k < 3; ++k) c[k] = (float)(ca[k] + 0.3 * (2 * ref_rand01(&st) - 1) * (pa[k] - ca[k]));
                        for (int k = 0; k < 3; ++k) d[k] = pa[k] - c[k];
                        sc_ray(sc, c, d, 0.0f, INFINITY, AS_STIFF_EXPECT_HIT);
                        count_exact(c, d, pa);
                    }
            }
            if (a > b) continue; /* each edge once: the other triangle has it as (b, a) */
            float m[3], c[3];
            double across[3], along[3], len = 0, dot = 0;
            for (int k = 0; k < 3; ++k) {
                m[k] = (float)(((double)pa[k] + pb[k]) / 2);
                c[k] = (float)(((double)ca[k] + cb[k]) / 2);
                along[k] = (double)pb[k] - pa[k];
                len += along[k] * along[k];
                dot += ((double)pw[k] - pa[k]) * along[k];
            }
            int kmax = 0;
            for (int k = 0; k < 3; ++k) {
                across[k] = (double)pw[k] - pa[k] - dot / len * along[k];
                if (fabs(across[k]) > fabs(across[kmax])) kmax = k;
            }
            target_rays(sc, m, c);
            for (int side = 0; side < 2; ++side) {
                float q[3] = {m[0], m[1], m[2]};
                q[kmax] = nextafterf(m[kmax], side ? INFINITY : -INFINITY);
                target_rays(sc, q, c);
            }
        }
    free(seen);
    free(valence);
    return sc->nr - r0;
}

/* ---- running a scene ------------------------------------------------------ */

typedef struct outcome_count {
    size_t rays, leaks, outcome_bad, reference_bad;
} outcome_count_t;

/* Builds the variant over the scene, traces every ray, and counts leaks
 * (rays that must hit and miss), broken outcomes and disagreements with
 * the reference. `s_out`, when not NULL, receives the structure. */
static outcome_count_t run_scene(const char *what, const scene_t *sc, as_structure_t **s_out)
{
    outcome_count_t n = {sc->nr, 0, 0, 0};
    as_mesh_t *m = sc_mesh(sc);
    if (!m) return n;
    as_structure_t *s = build(m, what);
    if (!s) {
        as_mesh_release(m);
        return n;
    }
    as_hit_t *hits = NULL;
    n.reference_bad = against_reference_ex(what, m, s, sc->rays, sc->nr, &hits, NULL, NULL);
    n.outcome_bad = stiff_outcome_failures(what, sc->out, sc->prims, 0, sc->nr, hits);
    for (size_t i = 0; i < sc->nr; ++i) {
        const int leak = sc->out[i].expect == AS_STIFF_EXPECT_HIT && hits[i].prim == AS_NO_HIT;
        if (leak && n.leaks < 3) {
            const as_ray_t *r = &sc->rays[i];
            fprintf(stderr, "  %s %s leak: ray %zu org (%.9g %.9g %.9g) dir (%.9g %.9g %.9g) tmax %g\n", variant_name,
                    what, i, (double)r->org[0], (double)r->org[1], (double)r->org[2], (double)r->dir[0],
                    (double)r->dir[1], (double)r->dir[2], (double)r->tmax);
        }
        n.leaks += leak;
    }
    free(hits);
    if (s_out) *s_out = s;
    else as_structure_release(s);
    as_mesh_release(m);
    return n;
}

/* Leaks of the float watertight test (not the default) on the same scene. */
static size_t float_test_leaks(const scene_t *sc, const as_structure_t *s)
{
    intersector = AS_INTERSECTOR_WATERTIGHT;
    as_hit_t *hits = trace(s, sc->rays, sc->nr, 0, NULL);
    intersector = default_intersector;
    size_t leaks = 0;
    for (size_t i = 0; i < sc->nr; ++i) leaks += sc->out[i].expect == AS_STIFF_EXPECT_HIT && hits[i].prim == AS_NO_HIT;
    free(hits);
    return leaks;
}

/* ---- the cases ------------------------------------------------------------ */

/* A torus, an icosphere (3 subdivisions), a capped cylinder (two flat fans
 * of 32 triangles) and a bicone (two apex fans of 32), each randomly
 * rotated and translated to about 1e5, 1e6 and 1e7 (a different offset on
 * each axis, of both signs), sized so that the float spacing there is
 * below 1/100 of the shortest edge; rays from inside and outside at every
 * vertex, edge midpoint and one step to either side of each edge, and 48
 * more at each fan's centre from other inside points. Outcome: every ray
 * hits (zero leaks), the reference's answer; the float watertight test has
 * zero leaks too. */
static void closed_meshes_far_away_have_zero_leaks(void)
{
    static const double offsets[3][3] = {{1.0e5, -2.5e5, 3.0e5}, {-1.0e6, 4.0e6, 2.0e6}, {8.0e6, -1.0e7, 6.0e6}};
    static const char *names[4] = {"torus", "icosphere", "capped cylinder", "bicone"};
    const double cyl[4][2] = {{1, -1}, {1, -1.0 / 3}, {1, 1.0 / 3}, {1, 1}};
    const double cone[3][2] = {{0.5, -0.5}, {1, 0}, {0.5, 0.5}};
    shape_t shapes[4] = {{0}};
    sh_torus(&shapes[0], 32, 16);
    sh_icosphere(&shapes[1], 3);
    sh_revolution(&shapes[2], 32, 4, cyl, -1, 1);
    sh_revolution(&shapes[3], 32, 3, cone, -1, 1);
    const double radius[4] = {1.25, 1, 1.5, 1};
    size_t total = 0, leaks = 0, float_leaks = 0, bad = 0;
    uint64_t st = 0x5D1FF0001ull;
    target_total = target_exact = 0;
    for (int o = 0; o < 3; ++o)
        for (int k = 0; k < 4; ++k) {
            placement_t pl;
            random_rotation(&st, pl.rot);
            double far = 0;
            for (int a = 0; a < 3; ++a) far = fmax(far, fabs(offsets[o][a]));
            pl.scale = scale_for(far, radius[k], sh_min_edge(&shapes[k]));
            for (int a = 0; a < 3; ++a) pl.offset[a] = offsets[o][a] * (1 + 0.1 * ref_rand01(&st));
            scene_t sc = {0};
            const uint32_t t0 = sc_add_shape(&sc, &shapes[k], &pl);
            closed_rays(&sc, t0, sc.nt, 48, st);
            char what[96];
            snprintf(what, sizeof what, "%s at %.0e", names[k], far);
            as_structure_t *s = NULL;
            const outcome_count_t n = run_scene(what, &sc, &s);
            total += n.rays;
            leaks += n.leaks;
            bad += n.outcome_bad + n.reference_bad;
            if (s) float_leaks += float_test_leaks(&sc, s);
            as_structure_release(s);
            sc_free(&sc);
        }
    for (int k = 0; k < 4; ++k) sh_free(&shapes[k]);
    fprintf(stderr, "  %s closed meshes at 1e5..1e7: %zu rays (%zu exactly through their target), %zu leaks, "
            "%zu with the float test, %zu other failures\n", variant_name, total, target_exact, leaks, float_leaks, bad);
    /* Far from the origin every target and origin share their signs and
     * lie within a factor 2: every direction is exact (Sterbenz). */
    CHECK_EQ_U64(target_exact, total);
    CHECK_EQ_U64(target_total, total);
    CHECK_EQ_U64(leaks, 0);
    CHECK_EQ_U64(float_leaks, 0);
    CHECK_EQ_U64(bad, 0);
}

/* A closed cube whose faces are cut unevenly: the same 12 cut positions on
 * every axis, from 2^-16 to 6 apart on a 16-unit cube (needle triangles of
 * aspect up to 4e5, next to 6 x 6 ones), shared vertices. Axis-aligned at
 * the origin (every vertex exact) and randomly rotated about its centre.
 * Rays at every vertex, edge midpoint and one step off each edge, from
 * inside and outside. Outcome: zero leaks, the reference's answer. */
static void needle_cube_has_zero_leaks(void)
{
    static const double cut[12] = {0, 0x1p-16, 0x1p-15 * 3, 0x1p-8, 0.5, 6, 8 - 0x1p-12, 8, 8 + 0x1p-16, 14, 16 - 0x1p-16, 16};
    const int n = 11;
    size_t total = 0, leaks = 0, bad = 0;
    uint64_t st = 0x5D1FF0002ull;
    for (int rotated = 0; rotated < 2; ++rotated) {
        placement_t pl = {{1, 0, 0, 0, 1, 0, 0, 0, 1}, 1.0, {0, 0, 0}};
        if (rotated) {
            random_rotation(&st, pl.rot);
            for (int k = 0; k < 3; ++k) pl.offset[k] = -8 * (pl.rot[3 * k] + pl.rot[3 * k + 1] + pl.rot[3 * k + 2]);
        }
        shape_t s = {0};
        uint32_t id[12 * 12 * 12];
        for (int i = 0; i <= n; ++i)
            for (int j = 0; j <= n; ++j)
                for (int k = 0; k <= n; ++k) {
                    const int on = !i || !j || !k || i == n || j == n || k == n;
                    id[(i * 12 + j) * 12 + k] = on ? sh_vertex(&s, cut[i], cut[j], cut[k], 8, 8, 8) : 0;
                }
        for (int f = 0; f < 6; ++f) {
            const int axis = f / 2, fixed = (f % 2) ? n : 0;
            for (int a = 0; a < n; ++a)
                for (int b = 0; b < n; ++b) {
                    uint32_t v[4];
                    const int uv[4][2] = {{a, b}, {a + 1, b}, {a + 1, b + 1}, {a, b + 1}};
                    for (int c = 0; c < 4; ++c) {
                        int q[3];
                        q[axis] = fixed;
                        q[(axis + 1) % 3] = uv[c][0];
                        q[(axis + 2) % 3] = uv[c][1];
                        v[c] = id[(q[0] * 12 + q[1]) * 12 + q[2]];
                    }
                    /* Outward winding does not matter to a two-sided test;
                     * alternate the diagonal so both kinds of needles occur. */
                    if ((a + b) & 1) {
                        sh_tri(&s, v[0], v[1], v[2]);
                        sh_tri(&s, v[0], v[2], v[3]);
                    } else {
                        sh_tri(&s, v[0], v[1], v[3]);
                        sh_tri(&s, v[1], v[2], v[3]);
                    }
                }
        }
        scene_t sc = {0};
        const uint32_t t0 = sc_add_shape(&sc, &s, &pl);
        closed_rays(&sc, t0, sc.nt, 0, st);
        const outcome_count_t c = run_scene(rotated ? "needle cube, rotated" : "needle cube", &sc, NULL);
        total += c.rays;
        leaks += c.leaks;
        bad += c.outcome_bad + c.reference_bad;
        sc_free(&sc);
        sh_free(&s);
    }
    fprintf(stderr, "  %s needle cube: %zu rays, %zu leaks, %zu other failures\n", variant_name, total, leaks, bad);
    CHECK_EQ_U64(leaks, 0);
    CHECK_EQ_U64(bad, 0);
}

/* Disks made of N triangles around a shared centre (N = 3, 5, 8, 24, 64,
 * 256), flat in a random plane or raised into a shallow cone, and rays
 * through the shared vertex exactly, from both sides, at up to 60 degrees
 * from the axis. Outcome: a hit on one of that fan's triangles, the
 * reference's answer. */
static void fan_centre_is_hit_on_one_of_its_triangles(void)
{
    static const int counts[6] = {3, 5, 8, 24, 64, 256};
    const double pi = 3.14159265358979323846;
    scene_t sc = {0};
    uint64_t st = 0x5D1FF0003ull;
    size_t exact = 0;
    for (int cone = 0; cone < 2; ++cone)
        for (int f = 0; f < 6; ++f) {
            const int nfan = counts[f];
            double rot[9], hub[3];
            random_rotation(&st, rot);
            /* Hubs 30 apart on a lattice from 100 (so that the rays, from
             * within 10 of their hub, meet no other fan first) and within a
             * factor 2 of the rays' origins, so hub - origin is exact. */
            const int cell = 6 * cone + f;
            for (int k = 0; k < 3; ++k) hub[k] = 100 + 30 * ((cell >> k) & (k == 2 ? 3 : 1)) + 2 * ref_rand01(&st);
            const double ax[3] = {rot[2], rot[5], rot[8]};
            const uint32_t h = sc_vertex3(&sc, hub[0], hub[1], hub[2]);
            const uint32_t first_rim = sc.nv, t0 = sc.nt;
            for (int i = 0; i < nfan; ++i) {
                const double a = 2 * pi * (i + 0.3 * ref_rand01(&st)) / nfan, c = cos(a), s = sin(a);
                const double lift = cone ? -1.2 : 0.0; /* the hub 0.3 above the rim's plane */
                double v[3];
                for (int k = 0; k < 3; ++k) v[k] = hub[k] + 4 * (c * rot[3 * k] + s * rot[3 * k + 1]) + lift * ax[k];
                sc_vertex(&sc, v, NULL);
            }
            for (int i = 0; i < nfan; ++i) sc_tri(&sc, h, first_rim + (uint32_t)i, first_rim + (uint32_t)((i + 1) % nfan));
            uint32_t *fan = malloc(sizeof *fan * (size_t)nfan);
            for (int i = 0; i < nfan; ++i) fan[i] = t0 + (uint32_t)i;
            const uint32_t list = sc_prims(&sc, fan, (size_t)nfan);
            free(fan);
            const float H[3] = {sc.p[3 * (size_t)h], sc.p[3 * (size_t)h + 1], sc.p[3 * (size_t)h + 2]};
            for (int i = 0; i < 64; ++i) {
                /* A direction within 60 degrees of the axis, either side. */
                const double th = (pi / 3) * sqrt(ref_rand01(&st)), ph = 2 * pi * ref_rand01(&st);
                const double side = (i & 1) ? 1 : -1, dist = 4 + 6 * ref_rand01(&st);
                float o[3], d[3];
                for (int k = 0; k < 3; ++k) {
                    const double dir = side * cos(th) * ax[k] + sin(th) * (cos(ph) * rot[3 * k] + sin(ph) * rot[3 * k + 1]);
                    o[k] = (float)(H[k] + dist * dir);
                }
                for (int k = 0; k < 3; ++k) d[k] = H[k] - o[k];
                int through = 1;
                for (int k = 0; k < 3; ++k) through &= o[k] + d[k] == H[k];
                exact += through;
                sc_outcome_prims(&sc, sc_ray(&sc, o, d, 0.0f, INFINITY, AS_STIFF_EXPECT_PRIM), list, (uint32_t)nfan);
            }
        }
    const outcome_count_t c = run_scene("fans", &sc, NULL);
    fprintf(stderr, "  %s fans: %zu rays through the shared vertex (%zu exactly), %zu miss it, %zu other failures\n",
            variant_name, c.rays, exact, c.outcome_bad, c.reference_bad);
    CHECK_EQ_U64(exact, c.rays);
    CHECK_EQ_U64(c.outcome_bad, 0);
    CHECK_EQ_U64(c.reference_bad, 0);
    sc_free(&sc);
}

/* ---- the structure's own planes ------------------------------------------ */

typedef struct planes {
    float *v[3];
    size_t n[3], cap[3];
} planes_t;

static void planes_add(planes_t *p, int axis, float x)
{
    if (!isfinite(x)) return;
    p->v[axis] = grow(p->v[axis], &p->cap[axis], p->n[axis] + 1, sizeof(float));
    p->v[axis][p->n[axis]++] = x;
}

static int cmp_float(const void *a, const void *b)
{
    const float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static void planes_unique(planes_t *p)
{
    for (int a = 0; a < 3; ++a) {
        if (!p->n[a]) continue;
        qsort(p->v[a], p->n[a], sizeof(float), cmp_float);
        size_t m = 1;
        for (size_t i = 1; i < p->n[a]; ++i)
            if (p->v[a][i] != p->v[a][m - 1]) p->v[a][m++] = p->v[a][i];
        p->n[a] = m;
    }
}

static void planes_free(planes_t *p)
{
    for (int a = 0; a < 3; ++a) free(p->v[a]);
    memset(p, 0, sizeof *p);
}

/* Octree mid planes, computed as the traversal computes them. */
static void octree_planes(const as_octree_node_t *nodes, uint32_t node, const float lo[3], float size, int depth,
                          int max_depth, planes_t *p)
{
    if (nodes[node].count != AS_OCTREE_INNER || depth >= max_depth) return;
    const float half = size * as_uint_as_float((uint32_t)(127 - (depth + 1)) << 23);
    for (int k = 0; k < 3; ++k) planes_add(p, k, lo[k] + half);
    for (int c = 0; c < 8; ++c) {
        float clo[3];
        for (int k = 0; k < 3; ++k) clo[k] = ((c >> (2 - k)) & 1) ? lo[k] + half : lo[k];
        octree_planes(nodes, nodes[node].first + (uint32_t)c, clo, size, depth + 1, max_depth, p);
    }
}

/* The planes the built structure splits or bounds space with, read from
 * its sections through the library's internal API: BVH child and node
 * boxes (the wide BVH's decoded as its traversal decodes them), KD split
 * positions, BIH clip planes, octree mid planes and grid cell walls, each
 * as its traversal computes it; octree planes down to `octree_depth`.
 * Returns 0 for a layout it does not know. */
static int structure_planes(const as_structure_t *s, int octree_depth, planes_t *p)
{
    const as_section_t *sec;
    if ((sec = as_structure_find(s, ASF_TAG_BVH2))) {
        const as_bvh2_node_t *n = sec->data;
        for (uint64_t i = 0; i < sec->count; ++i)
            for (int c = 0; c < 2; ++c) {
                const as_f4_t *xy = c ? &n[i].xy1 : &n[i].xy0;
                if (!(xy->x <= xy->y)) continue; /* empty child: inverted box */
                planes_add(p, 0, xy->x), planes_add(p, 0, xy->y);
                planes_add(p, 1, xy->z), planes_add(p, 1, xy->w);
                planes_add(p, 2, c ? n[i].z01.z : n[i].z01.x), planes_add(p, 2, c ? n[i].z01.w : n[i].z01.y);
            }
        return 1;
    }
    if ((sec = as_structure_find(s, ASF_TAG_BVHO))) {
        const as_bvh2o_node_t *n = sec->data;
        for (uint64_t i = 0; i < sec->count; ++i)
            for (int k = 0; k < 3; ++k) planes_add(p, k, n[i].lo[k]), planes_add(p, k, n[i].hi[k]);
        return 1;
    }
    if ((sec = as_structure_find(s, ASF_TAG_CWBV))) {
        const as_cwbvh_node_t *n = sec->data;
        for (uint64_t i = 0; i < sec->count; ++i)
            for (int slot = 0; slot < 8; ++slot) {
                if (!n[i].meta[slot]) continue;
                for (int k = 0; k < 3; ++k) {
                    const float sc = as_cwbvh_scale(n[i].e[k]);
                    planes_add(p, k, as_cwbvh_decode(n[i].p[k], sc, n[i].qlo[k][slot]));
                    planes_add(p, k, as_cwbvh_decode(n[i].p[k], sc, n[i].qhi[k][slot]));
                }
            }
        return 1;
    }
    if ((sec = as_structure_find(s, ASF_TAG_KDN8))) {
        const as_kd_node_t *n = sec->data;
        for (uint64_t i = 0; i < sec->count; ++i)
            if (!as_kd_is_leaf(n[i].word1)) planes_add(p, (int)(n[i].word1 & 3u), as_uint_as_float(n[i].word0));
        return 1;
    }
    if ((sec = as_structure_find(s, ASF_TAG_BIHN))) {
        const as_bih_node_t *n = sec->data;
        for (uint64_t i = 0; i < sec->count; ++i)
            if ((n[i].info & 3u) != AS_BIH_LEAF)
                planes_add(p, (int)(n[i].info & 3u), n[i].clip[0]), planes_add(p, (int)(n[i].info & 3u), n[i].clip[1]);
        return 1;
    }
    if ((sec = as_structure_find(s, ASF_TAG_OCTH))) {
        const as_octree_header_t *h = sec->data;
        const as_section_t *ns = as_structure_find(s, ASF_TAG_OCTN);
        for (int k = 0; k < 3; ++k) planes_add(p, k, h->lo[k]), planes_add(p, k, h->lo[k] + h->size);
        if (ns && ns->count) octree_planes(ns->data, 0, h->lo, h->size, 0, octree_depth, p);
        return 1;
    }
    if ((sec = as_structure_find(s, ASF_TAG_GRDH))) {
        const as_grid_header_t *g = sec->data;
        for (int k = 0; k < 3; ++k)
            for (uint32_t i = 0; i <= g->dims[k]; ++i)
                planes_add(p, k, i >= g->dims[k] ? g->hi[k] : g->lo[k] + (float)i * g->cell[k]);
        return 1;
    }
    return 0;
}

/* A random soup of `n` triangles of size about `size` in [lo, lo + ext]^3. */
static void soup(scene_t *sc, uint64_t *st, uint32_t n, double lo, double ext, double size)
{
    for (uint32_t i = 0; i < n; ++i) {
        double c[3];
        for (int k = 0; k < 3; ++k) c[k] = lo + ext * ref_rand01(st);
        uint32_t v[3];
        for (int j = 0; j < 3; ++j) {
            double q[3];
            for (int k = 0; k < 3; ++k) q[k] = c[k] + size * (ref_rand01(st) - 0.5);
            v[j] = sc_vertex(sc, q, NULL);
        }
        sc_tri(sc, v[0], v[1], v[2]);
    }
}

/* 3,000 random triangles around an icosphere; the variant's own planes (BVH
 * boxes, KD splits, BIH clips, octree mid planes, grid walls) read from the
 * built structure. Rays whose origins lie exactly on two or three of those
 * planes, along the third axis (+-0 in the other two components: groups of
 * four) or diagonally inside one plane (+-0 in that component: groups of
 * two). Outcome: the members of a group give identical hits, the first the
 * reference's answer, no NaN. */
static void signed_zero_on_the_structures_own_planes(void)
{
    scene_t sc = {0};
    uint64_t st = 0x5D1FF0004ull;
    soup(&sc, &st, 3000, 0.0, 1.0, 0.06);
    shape_t ico = {0};
    sh_icosphere(&ico, 2);
    const placement_t pl = {{1, 0, 0, 0, 1, 0, 0, 0, 1}, 0.2, {0.5, 0.5, 0.5}};
    sc_add_shape(&sc, &ico, &pl);
    sh_free(&ico);
    as_mesh_t *m = sc_mesh(&sc);
    if (!m) { sc_free(&sc); return; }
    as_structure_t *s = build(m, "signed zero planes");
    as_mesh_release(m);
    if (!s) { sc_free(&sc); return; }
    planes_t p = {0};
    CHECK(structure_planes(s, AS_OCTREE_MAX_DEPTH, &p));
    as_structure_release(s);
    planes_unique(&p);
    for (int a = 0; a < 3; ++a) CHECK(p.n[a] >= 2);
    fprintf(stderr, "  %s signed zero: %zu, %zu and %zu planes of the structure\n", variant_name, p.n[0], p.n[1], p.n[2]);
    for (int i = 0; i < 1500 && p.n[0] && p.n[1] && p.n[2]; ++i) {
        const int axis = i % 3, b = (axis + 1) % 3, c = (axis + 2) % 3;
        float o[3];
        for (int k = 0; k < 3; ++k) o[k] = p.v[k][ref_rand_u64(&st) % p.n[k]];
        const int start_outside = (i / 3) % 2, sign = (i / 6) % 2 ? -1 : 1;
        if (start_outside) o[axis] = sign > 0 ? -0.5f : 1.5f;
        /* Along `axis`: four rays, +-0 in b and c. */
        size_t group = 0;
        for (int z = 0; z < 4; ++z) {
            float d[3];
            d[axis] = (float)sign;
            d[b] = z & 1 ? -0.0f : 0.0f;
            d[c] = z & 2 ? -0.0f : 0.0f;
            const size_t r = sc_ray(&sc, o, d, 0.0f, INFINITY, AS_STIFF_EXPECT_REFERENCE);
            if (z) sc.out[r].same_as = (uint32_t)group;
            else group = r;
        }
        /* Inside the plane of axis b: +-0 there, slanted in the others. */
        float o2[3] = {o[0], o[1], o[2]};
        o2[c] = start_outside ? (sign > 0 ? -0.5f : 1.5f) : o[c];
        const float slant = (float)(0.2 + ref_rand01(&st)), slant_sign = ref_rand01(&st) < 0.5 ? -1.0f : 1.0f;
        for (int z = 0; z < 2; ++z) {
            float d[3];
            d[b] = z ? -0.0f : 0.0f;
            d[axis] = slant * slant_sign;
            d[c] = (float)sign;
            const size_t r = sc_ray(&sc, o2, d, 0.0f, INFINITY, AS_STIFF_EXPECT_REFERENCE);
            if (z) sc.out[r].same_as = (uint32_t)(r - 1);
        }
    }
    planes_free(&p);
    const outcome_count_t c = run_scene("signed zero", &sc, NULL);
    fprintf(stderr, "  %s signed zero: %zu rays on the structure's planes, %zu differ between +0 and -0, %zu disagree "
            "with the reference\n", variant_name, c.rays, c.outcome_bad, c.reference_bad);
    CHECK_EQ_U64(c.outcome_bad, 0);
    CHECK_EQ_U64(c.reference_bad, 0);
    sc_free(&sc);
}

/* An icosphere (4 subdivisions) and a 64-sided capped cylinder, rays
 * tangent to them at vertices (touching the vertex, in float within a
 * step of it) and at 1e-2 down to 1e-6 radians into the surface at
 * vertices and face centres, and rays parallel to the cylinder's axis
 * along its vertical edges. Outcome: the reference's answer. */
static void grazing_rays_on_curved_meshes_match_the_reference(void)
{
    scene_t sc = {0};
    uint64_t st = 0x5D1FF0005ull;
    shape_t ico = {0}, cyl = {0};
    sh_icosphere(&ico, 4);
    const double rz[2][2] = {{1, -2}, {1, 2}};
    sh_revolution(&cyl, 64, 2, rz, -2, 2);
    placement_t pa = {{0}, 3.0, {10, 10, 10}}, pb = {{1, 0, 0, 0, 1, 0, 0, 0, 1}, 3.0, {20, 10, 10}};
    random_rotation(&st, pa.rot);
    const uint32_t ta = sc_add_shape(&sc, &ico, &pa), tb = sc_add_shape(&sc, &cyl, &pb);
    sh_free(&ico);
    sh_free(&cyl);
    const double angles[6] = {0, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6};
    for (int which = 0; which < 2; ++which) {
        const uint32_t t0 = which ? tb : ta, t1 = which ? sc.nt : tb;
        const double *centre = which ? pb.offset : pa.offset;
        for (int i = 0; i < 400; ++i) {
            const uint32_t t = t0 + (uint32_t)(ref_rand_u64(&st) % (t1 - t0));
            double q[3] = {0, 0, 0};
            const int at_vertex = i & 1;
            for (int j = 0; j < 3; ++j)
                for (int k = 0; k < 3; ++k)
                    q[k] += at_vertex ? (j ? 0 : sc.p[3 * (size_t)sc.ix[3 * (size_t)t] + k])
                                      : sc.p[3 * (size_t)sc.ix[3 * (size_t)t + j] + k] / 3;
            /* The outward normal of the smooth surface at q. */
            double n[3], nn = 0;
            for (int k = 0; k < 3; ++k) n[k] = q[k] - centre[k];
            if (which && t - t0 < 128) n[0] = n[1] = 0; /* a cap (the first 2 x 64 triangles) */
            else if (which) n[2] = 0;
            for (int k = 0; k < 3; ++k) nn += n[k] * n[k];
            nn = sqrt(nn);
            for (int k = 0; k < 3; ++k) n[k] /= nn;
            /* A tangent direction: a random vector minus its normal part. */
            double tg[3], dot = 0, tl = 0;
            for (int k = 0; k < 3; ++k) tg[k] = 2 * ref_rand01(&st) - 1, dot += tg[k] * n[k];
            for (int k = 0; k < 3; ++k) tg[k] -= dot * n[k], tl += tg[k] * tg[k];
            tl = sqrt(tl);
            if (which && i % 4 == 3) tg[0] = tg[1] = 0, tg[2] = 1, tl = 1; /* along the side */
            const double a = angles[(i / 4) % 6];
            float o[3], d[3];
            for (int k = 0; k < 3; ++k) {
                const double dk = cos(a) * tg[k] / tl - sin(a) * n[k];
                d[k] = (float)dk;
                o[k] = (float)(q[k] - 5 * dk);
            }
            sc_ray(&sc, o, d, 0.0f, INFINITY, AS_STIFF_EXPECT_REFERENCE);
        }
    }
    const outcome_count_t c = run_scene("grazing", &sc, NULL);
    fprintf(stderr, "  %s grazing: %zu tangent and near-tangent rays, %zu disagree with the reference\n", variant_name,
            c.rays, c.reference_bad);
    CHECK_EQ_U64(c.outcome_bad, 0);
    CHECK_EQ_U64(c.reference_bad, 0);
    sc_free(&sc);
}

/* Tessellated squares lying exactly in the planes x = 3.5, y = -2.25,
 * x = y, x = -z and y = z (every vertex exactly in its plane), and rays
 * lying exactly in those planes (origins and directions in the plane, all
 * exact in float) in random directions. They meet their plane's triangles
 * edge-on: the documented answer (as for the suite's z = 0 plane) is that
 * none of their own plane's triangles is hit; the rest is the reference's
 * answer (they may cross the other planes). */
static void in_plane_rays_at_other_orientations_miss_their_plane(void)
{
    scene_t sc = {0};
    uint64_t st = 0x5D1FF0006ull;
    /* A point of plane `pl` from two free coordinates (u, v) (dyadic, so
     * every coordinate is exact), and the same for a direction. */
    enum { PLANES = 5 };
    uint32_t first_tri[PLANES + 1];
    for (int pl = 0; pl < PLANES; ++pl) {
        first_tri[pl] = sc.nt;
        const int n = 12;
        const uint32_t v0 = sc.nv;
        for (int i = 0; i <= n; ++i)
            for (int j = 0; j <= n; ++j) {
                const double u = -6 + i, v = -6 + j;
                double q[3];
                switch (pl) {
                case 0: q[0] = 3.5, q[1] = u, q[2] = v; break;
                case 1: q[0] = u, q[1] = -2.25, q[2] = v; break;
                case 2: q[0] = u, q[1] = u, q[2] = v; break;
                case 3: q[0] = u, q[1] = v, q[2] = -u; break;
                default: q[0] = v, q[1] = u, q[2] = u; break;
                }
                sc_vertex(&sc, q, NULL);
            }
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                const uint32_t a = v0 + (uint32_t)(i * (n + 1) + j), b = a + (uint32_t)(n + 1);
                sc_tri(&sc, a, b, b + 1);
                sc_tri(&sc, a, b + 1, a + 1);
            }
    }
    first_tri[PLANES] = sc.nt;
    size_t in_plane = 0;
    for (int pl = 0; pl < PLANES; ++pl) {
        uint32_t *own = malloc(sizeof *own * (first_tri[pl + 1] - first_tri[pl]));
        for (uint32_t t = first_tri[pl]; t < first_tri[pl + 1]; ++t) own[t - first_tri[pl]] = t;
        const uint32_t list = sc_prims(&sc, own, first_tri[pl + 1] - first_tri[pl]);
        free(own);
        for (int i = 0; i < 300; ++i) {
            /* Origins on a 1/64 lattice inside the square (some exactly on
             * its vertices and edges), directions on a 1/16 lattice. */
            const double u = -5 + (double)(ref_rand_u64(&st) % 640) / 64, v = -5 + (double)(ref_rand_u64(&st) % 640) / 64;
            double du, dv;
            do {
                du = ((double)(ref_rand_u64(&st) % 33) - 16) / 16;
                dv = ((double)(ref_rand_u64(&st) % 33) - 16) / 16;
            } while (du == 0 && dv == 0);
            if (i % 10 == 0) dv = 0; /* along a lattice line (edges) */
            float o[3], d[3];
            switch (pl) {
            case 0: o[0] = 3.5f, o[1] = (float)u, o[2] = (float)v, d[0] = 0, d[1] = (float)du, d[2] = (float)dv; break;
            case 1: o[0] = (float)u, o[1] = -2.25f, o[2] = (float)v, d[0] = (float)du, d[1] = 0, d[2] = (float)dv; break;
            case 2: o[0] = o[1] = (float)u, o[2] = (float)v, d[0] = d[1] = (float)du, d[2] = (float)dv; break;
            case 3: o[0] = (float)u, o[1] = (float)v, o[2] = (float)-u, d[0] = (float)du, d[1] = (float)dv, d[2] = (float)-du; break;
            default: o[0] = (float)v, o[1] = o[2] = (float)u, d[0] = (float)dv, d[1] = d[2] = (float)du; break;
            }
            sc_outcome_prims(&sc, sc_ray(&sc, o, d, 0.0f, INFINITY, AS_STIFF_EXPECT_NOT_PRIM), list,
                             first_tri[pl + 1] - first_tri[pl]);
            ++in_plane;
        }
    }
    const outcome_count_t c = run_scene("in-plane", &sc, NULL);
    fprintf(stderr, "  %s in-plane: %zu rays in five planes, %zu hit their own plane, %zu disagree with the reference\n",
            variant_name, in_plane, c.outcome_bad, c.reference_bad);
    CHECK_EQ_U64(c.outcome_bad, 0);
    CHECK_EQ_U64(c.reference_bad, 0);
    sc_free(&sc);
}

/* Icospheres (2 subdivisions) of radius 1e-5 within 0.01 of the origin and
 * of radius 1e5 about 1e6 away, in one scene; rays at every vertex, edge
 * midpoint and one step off each edge of each, from inside and outside,
 * and rays from between them aimed at the large spheres' vertices.
 * Outcome: zero leaks, the reference's answer. */
static void tiny_and_huge_closed_meshes_have_zero_leaks(void)
{
    static const double tiny[4][3] = {{0, 0, 0}, {0.01, -0.003, 0.002}, {-0.0025, 0.0075, -0.005}, {0x1p-7, 0x1p-7, 0x1p-7}};
    static const double huge[3][3] = {{1e6, 2e5, -3e5}, {-1.2e6, 0, 4e5}, {1e5, -9e5, 1.1e6}};
    scene_t sc = {0};
    uint64_t st = 0x5D1FF0007ull;
    shape_t ico = {0};
    sh_icosphere(&ico, 2);
    uint32_t bounds[8];
    int nb = 0;
    for (int i = 0; i < 7; ++i) {
        placement_t pl;
        random_rotation(&st, pl.rot);
        pl.scale = i < 4 ? 1e-5 : 1e5;
        memcpy(pl.offset, i < 4 ? tiny[i] : huge[i - 4], sizeof pl.offset);
        bounds[nb++] = sc_add_shape(&sc, &ico, &pl);
    }
    bounds[nb] = sc.nt;
    sh_free(&ico);
    for (int i = 0; i < 7; ++i) closed_rays(&sc, bounds[i], bounds[i + 1], 0, st);
    /* From near the origin at the large spheres' vertices that face it
     * (the direction is rounded: a vertex near the silhouette could be
     * missed rightly). */
    for (int i = 0; i < 600;) {
        const int j = (int)(ref_rand_u64(&st) % 3);
        const uint32_t t = bounds[4 + j] + (uint32_t)(ref_rand_u64(&st) % (bounds[5 + j] - bounds[4 + j]));
        const float *q = sc.p + 3 * (size_t)sc.ix[3 * (size_t)t];
        float o[3], d[3];
        double dot = 0, ln = 0, ld = 0;
        for (int k = 0; k < 3; ++k) o[k] = (float)(0.5 * (2 * ref_rand01(&st) - 1));
        for (int k = 0; k < 3; ++k) {
            d[k] = q[k] - o[k];
            const double nk = q[k] - huge[j][k];
            dot -= nk * d[k], ln += nk * nk, ld += (double)d[k] * d[k];
        }
        if (dot < 0.3 * sqrt(ln * ld)) continue;
        sc_ray(&sc, o, d, 0.0f, INFINITY, AS_STIFF_EXPECT_HIT);
        ++i;
    }
    const outcome_count_t c = run_scene("tiny and huge", &sc, NULL);
    fprintf(stderr, "  %s tiny and huge: %zu rays, %zu leaks, %zu other failures\n", variant_name, c.rays, c.leaks,
            c.outcome_bad + c.reference_bad);
    CHECK_EQ_U64(c.leaks, 0);
    CHECK_EQ_U64(c.outcome_bad, 0);
    CHECK_EQ_U64(c.reference_bad, 0);
    sc_free(&sc);
}

/* A closed icosphere (radius 1 at (4.5, 4.5, 4.5)) among zero-area
 * triangles placed exactly where rays pass: two identical indices, two
 * vertices with equal coordinates, three equal corners, at a point p that
 * a ray passes exactly through; and collinear triangles lying along
 * axis-parallel and diagonal rays (exact dyadic points). Outcome: none of
 * them is ever hit (the rays go on to the sphere or miss), the
 * reference's answer. */
static void degenerate_triangles_on_rays_are_never_hit(void)
{
    scene_t sc = {0};
    uint64_t st = 0x5D1FF0008ull;
    shape_t ico = {0};
    sh_icosphere(&ico, 2);
    const placement_t pl = {{1, 0, 0, 0, 1, 0, 0, 0, 1}, 1.0, {4.5, 4.5, 4.5}};
    sc_add_shape(&sc, &ico, &pl);
    sh_free(&ico);
    const uint32_t first_degenerate = sc.nt;
    /* Rays through points p in [3, 6]^3 from origins in [3, 6]^3: p - o is
     * exact, so the ray passes through p. */
    size_t exact = 0, through_rays = 0;
    for (int i = 0; i < 400; ++i) {
        double pd[3];
        for (int k = 0; k < 3; ++k) pd[k] = 3 + 3 * ref_rand01(&st);
        const uint32_t a = sc_vertex(&sc, pd, NULL);
        const float *p = sc.p + 3 * (size_t)a;
        double qd[3];
        for (int k = 0; k < 3; ++k) qd[k] = p[k] + 0.05 * (ref_rand01(&st) - 0.5);
        switch (i % 3) {
        case 0: sc_tri(&sc, a, a, sc_vertex(&sc, qd, NULL)); break;              /* repeated index */
        case 1: {                                                                 /* equal coordinates */
            const double pp[3] = {p[0], p[1], p[2]};
            sc_tri(&sc, a, sc_vertex(&sc, qd, NULL), sc_vertex(&sc, pp, NULL));
            break;
        }
        default: sc_tri(&sc, a, a, a); break;                                    /* a point */
        }
        for (int j = 0; j < 2; ++j) {
            float o[3], d[3];
            for (int k = 0; k < 3; ++k) o[k] = (float)(3 + 3 * ref_rand01(&st));
            for (int k = 0; k < 3; ++k) d[k] = p[k] - o[k];
            int through = 1;
            for (int k = 0; k < 3; ++k) through &= o[k] + d[k] == p[k];
            exact += through;
            ++through_rays;
            sc_ray(&sc, o, d, 0.0f, INFINITY, AS_STIFF_EXPECT_NOT_PRIM);
        }
    }
    /* Collinear triangles along rays: on a 1/8 lattice, along x, y, z and
     * the diagonals (1, 1, 0) and (1, 1, 1), the ray on the same line. */
    static const int dirs[5][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0}, {1, 1, 1}};
    for (int i = 0; i < 300; ++i) {
        const int *dd = dirs[i % 5];
        double base[3];
        for (int k = 0; k < 3; ++k) base[k] = 3 + (double)(ref_rand_u64(&st) % 24) / 8;
        const double h = 0.125 * (1 + (double)(ref_rand_u64(&st) % 4));
        uint32_t v[3];
        const double f[3] = {0, 1, 3};
        for (int j = 0; j < 3; ++j) {
            double q[3];
            for (int k = 0; k < 3; ++k) q[k] = base[k] + f[j] * h * dd[k];
            v[j] = sc_vertex(&sc, q, NULL);
        }
        sc_tri(&sc, v[0], v[1], v[2]);
        for (int side = 0; side < 2; ++side) {
            float o[3], d[3];
            for (int k = 0; k < 3; ++k) {
                o[k] = (float)(base[k] + (side ? 4 * h + 0.5 : -0.5) * dd[k]);
                d[k] = side ? (float)-dd[k] : (float)dd[k];
            }
            sc_ray(&sc, o, d, 0.0f, INFINITY, AS_STIFF_EXPECT_NOT_PRIM);
        }
    }
    const uint32_t ndeg = sc.nt - first_degenerate;
    uint32_t *deg = malloc(sizeof *deg * ndeg);
    for (uint32_t t = 0; t < ndeg; ++t) deg[t] = first_degenerate + t;
    const uint32_t list = sc_prims(&sc, deg, ndeg);
    free(deg);
    for (size_t r = 0; r < sc.nr; ++r) sc_outcome_prims(&sc, r, list, ndeg);
    as_mesh_t *m = sc_mesh(&sc);
    if (m) {
        uint32_t zero = 0;
        for (uint32_t t = first_degenerate; t < sc.nt; ++t) zero += as_mesh_triangle_is_degenerate(m, t);
        CHECK_EQ_U64(zero, ndeg); /* every one of them has zero area, as the library decides it */
        as_mesh_release(m);
    }
    const outcome_count_t c = run_scene("degenerate", &sc, NULL);
    fprintf(stderr, "  %s degenerate: %u zero-area triangles on %zu rays (%zu of %zu exactly through a corner), "
            "%zu hit one, %zu disagree with the reference\n", variant_name, ndeg, c.rays, exact, through_rays,
            c.outcome_bad, c.reference_bad);
    CHECK_EQ_U64(exact, through_rays);
    CHECK_EQ_U64(c.outcome_bad, 0);
    CHECK_EQ_U64(c.reference_bad, 0);
    sc_free(&sc);
}

/* An icosphere (3 subdivisions, 1,280 triangles) in which one face is
 * copied so that it occurs 2, 3, 17 or 1,000 times, the copies scattered
 * through the triangle list (half with the same indices, half with new
 * vertices at the same coordinates); rays from inside and outside through
 * points well inside that face. Outcome: the hit is the lowest index among
 * the copies; depth within the cap, nodes linear in the triangles. */
static void scattered_copies_report_the_lowest_index(void)
{
    static const uint32_t counts[4] = {2, 3, 17, 1000};
    uint64_t st = 0x5D1FF0009ull;
    shape_t ico = {0};
    sh_icosphere(&ico, 3);
    size_t failures = 0, rays = 0;
    for (int ci = 0; ci < 4; ++ci) {
        const uint32_t copies = counts[ci];
        const uint32_t face = (uint32_t)(ref_rand_u64(&st) % ico.nt);
        /* Where each triangle goes: the sphere's faces and the extra copies
         * shuffled together (Fisher-Yates over the order). */
        const uint32_t total = ico.nt + copies - 1;
        uint32_t *order = malloc(sizeof *order * total);
        for (uint32_t i = 0; i < total; ++i) order[i] = i < ico.nt ? i : face;
        for (uint32_t i = total - 1; i > 0; --i) {
            const uint32_t j = (uint32_t)(ref_rand_u64(&st) % (i + 1)), x = order[i];
            order[i] = order[j];
            order[j] = x;
        }
        scene_t sc = {0};
        for (uint32_t i = 0; i < ico.nv; ++i) sc_vertex(&sc, ico.v + 3 * (size_t)i, NULL);
        uint32_t lowest = UINT32_MAX, seen = 0;
        for (uint32_t i = 0; i < total; ++i) {
            const uint32_t *t = ico.t + 3 * (size_t)order[i];
            if (order[i] == face) {
                if (seen++ % 2) { /* new vertices, same coordinates */
                    uint32_t v[3];
                    for (int k = 0; k < 3; ++k) v[k] = sc_vertex(&sc, ico.v + 3 * (size_t)t[k], NULL);
                    sc_tri(&sc, v[0], v[1], v[2]);
                } else {
                    sc_tri(&sc, t[0], t[1], t[2]);
                }
                if (lowest == UINT32_MAX) lowest = i;
            } else {
                sc_tri(&sc, t[0], t[1], t[2]);
            }
        }
        free(order);
        CHECK_EQ_U64(seen, copies);
        const uint32_t list = sc_prims(&sc, &lowest, 1);
        const float *a = sc.p + 3 * (size_t)ico.t[3 * face], *b = sc.p + 3 * (size_t)ico.t[3 * face + 1],
                    *c = sc.p + 3 * (size_t)ico.t[3 * face + 2];
        for (int i = 0; i < 32; ++i) {
            double u = 0.15 + 0.7 * ref_rand01(&st), v = 0.15 + 0.7 * ref_rand01(&st);
            if (u + v > 0.85) u = 0.85 - u + 0.15, v = 0.85 - v + 0.15;
            if (u + v > 0.85) u = v = 1.0 / 3;
            float q[3], o[3], d[3];
            for (int k = 0; k < 3; ++k) q[k] = (float)((1 - u - v) * a[k] + u * b[k] + v * c[k]);
            const int outside = i & 1;
            for (int k = 0; k < 3; ++k) o[k] = outside ? 2 * q[k] : 0.0f;
            for (int k = 0; k < 3; ++k) d[k] = q[k] - o[k];
            sc_outcome_prims(&sc, sc_ray(&sc, o, d, 0.0f, outside ? 2.0f : INFINITY, AS_STIFF_EXPECT_PRIM), list, 1);
        }
        char what[64];
        snprintf(what, sizeof what, "%u copies", copies);
        as_structure_t *s = NULL;
        const outcome_count_t n = run_scene(what, &sc, &s);
        if (s) {
            as_structure_stats_t stt;
            CHECK_EQ_INT(as_structure_get_stats(s, &stt), AS_OK);
            CHECK(stt.max_depth <= 64);
            CHECK(stt.node_count <= 4 * (uint64_t)sc.nt + 64);
            as_structure_release(s);
        }
        failures += n.outcome_bad + n.reference_bad;
        rays += n.rays;
        sc_free(&sc);
    }
    sh_free(&ico);
    fprintf(stderr, "  %s copies: %zu rays through the copied face, %zu failures\n", variant_name, rays, failures);
    CHECK_EQ_U64(failures, 0);
}

/* Axis-aligned quads on the planes where mid-cut builders split the box
 * [0, 16]^3 (made by two corner triangles): 16 k / 2^d for d = 1..4 on
 * every axis; for the octree also its own mid planes and for the grid its
 * cell walls, read from a build of the same scene (same box, same triangle
 * count) before the quads are moved onto them. Rays aimed at the quads'
 * interiors from both sides, slanted and axis-parallel. Outcome: every
 * ray hits, the reference's answer. */
static void quads_on_dyadic_and_structure_planes_are_hit(void)
{
    uint64_t st = 0x5D1FF000Aull;
    planes_t own = {0};
    scene_t sc = {0};
    unsigned char header[64] = {0}; /* the first pass's OCTH or GRDH */
    for (int pass = 0; pass < 2; ++pass) {
        sc_free(&sc);
        uint64_t qs = 0x5D1FF000Bull; /* the same quads in both passes */
        uint32_t c0 = sc_vertex3(&sc, 0, 0.01, 0), c1 = sc_vertex3(&sc, 0.01, 0, 0), c2 = sc_vertex3(&sc, 0, 0, 0);
        sc_tri(&sc, c2, c1, c0);
        c0 = sc_vertex3(&sc, 16, 15.99, 16), c1 = sc_vertex3(&sc, 15.99, 16, 16), c2 = sc_vertex3(&sc, 16, 16, 16);
        sc_tri(&sc, c2, c1, c0);
        /* The dyadic planes, then 8 of the structure's own per axis (on
         * the first pass at dyadic places too). */
        for (int axis = 0; axis < 3; ++axis)
            for (int q = 0; q < 15 + 8; ++q) {
                float plane;
                if (q < 15) {
                    const int d = q < 1 ? 1 : q < 3 ? 2 : q < 7 ? 3 : 4;
                    const int first = (1 << (d - 1)) - 1, k = q - first;
                    plane = (float)(16.0 * (2 * k + 1) / (1 << d));
                } else if (pass == 0 || own.n[axis] == 0) {
                    plane = (float)(0.5 + (q - 15));
                } else {
                    plane = own.v[axis][((size_t)(q - 15) * 7919u) % own.n[axis]];
                }
                const double u0 = 0.5 + 12 * ref_rand01(&qs), v0 = 0.5 + 12 * ref_rand01(&qs);
                const double du = 1 + 2 * ref_rand01(&qs), dv = 1 + 2 * ref_rand01(&qs);
                const double uv[4][2] = {{u0, v0}, {u0 + du, v0}, {u0 + du, v0 + dv}, {u0, v0 + dv}};
                uint32_t v[4];
                for (int c = 0; c < 4; ++c) {
                    double pt[3];
                    pt[axis] = plane;
                    pt[(axis + 1) % 3] = uv[c][0];
                    pt[(axis + 2) % 3] = uv[c][1];
                    v[c] = sc_vertex(&sc, pt, NULL);
                }
                sc_tri(&sc, v[0], v[1], v[2]);
                sc_tri(&sc, v[0], v[2], v[3]);
            }
        if (pass == 0 && (variant.structure == AS_STRUCT_OCTREE || variant.structure == AS_STRUCT_GRID)) {
            as_mesh_t *m = sc_mesh(&sc);
            as_structure_t *s = m ? build(m, "planar, first pass") : NULL;
            if (s) {
                /* The octree's upper four levels: planes a build of any
                 * such scene splits on. */
                CHECK(structure_planes(s, 4, &own));
                const as_section_t *h = as_structure_find(s, ASF_TAG_OCTH);
                if (!h) h = as_structure_find(s, ASF_TAG_GRDH);
                if (h && h->bytes <= sizeof header) memcpy(header, h->data, h->bytes);
                planes_unique(&own);
                /* Keep the inner ones (the box faces are the corner triangles'). */
                for (int a = 0; a < 3; ++a) {
                    size_t k = 0;
                    for (size_t i = 0; i < own.n[a]; ++i)
                        if (own.v[a][i] > 0.25f && own.v[a][i] < 15.75f) own.v[a][k++] = own.v[a][i];
                    own.n[a] = k;
                }
            }
            as_structure_release(s);
            as_mesh_release(m);
        }
    }
    /* The rays: at interior points of each quad (a margin of 0.1). */
    const uint32_t quads = (sc.nt - 2) / 2;
    for (uint32_t q = 0; q < quads; ++q) {
        const uint32_t t = 2 + 2 * q;
        const float *a = sc.p + 3 * (size_t)sc.ix[3 * (size_t)t], *c = sc.p + 3 * (size_t)sc.ix[3 * (size_t)t + 2];
        int axis = 0;
        while (axis < 2 && a[axis] != c[axis]) ++axis;
        for (int i = 0; i < 8; ++i) {
            float p[3], o[3], d[3];
            for (int k = 0; k < 3; ++k) {
                const double lo = fmin(a[k], c[k]) + 0.1, hi = fmax(a[k], c[k]) - 0.1;
                p[k] = k == axis ? a[k] : (float)(lo + (hi - lo) * ref_rand01(&st));
            }
            const float side = (i & 1) ? 1.0f : -1.0f;
            for (int k = 0; k < 3; ++k) {
                d[k] = k == axis ? -side : (i & 2 ? 0.0f : (float)(0.3 * (ref_rand01(&st) - 0.5)));
                o[k] = k == axis ? p[k] + 3 * side : p[k] - 3 * d[k];
            }
            sc_ray(&sc, o, d, 0.0f, INFINITY, AS_STIFF_EXPECT_HIT);
        }
    }
    as_structure_t *s = NULL;
    const outcome_count_t c = run_scene("planar", &sc, &s);
    if (s && own.n[0]) {
        /* The final build has the header (octree root, grid box and cells)
         * the planes were computed from: the quads lie on its planes. */
        const as_section_t *h = as_structure_find(s, ASF_TAG_OCTH);
        if (!h) h = as_structure_find(s, ASF_TAG_GRDH);
        CHECK(h != NULL && h->bytes <= sizeof header && memcmp(h->data, header, h->bytes) == 0);
    }
    as_structure_release(s);
    fprintf(stderr, "  %s planar: %u quads (%s), %zu rays, %zu miss, %zu disagree with the reference\n", variant_name,
            quads, own.n[0] ? "dyadic and the structure's own planes" : "dyadic planes", c.rays, c.outcome_bad,
            c.reference_bad);
    CHECK_EQ_U64(c.outcome_bad, 0);
    CHECK_EQ_U64(c.reference_bad, 0);
    planes_free(&own);
    sc_free(&sc);
}

/* The bunny, 8,000 rays of which every other one is made bad in a way the
 * suite's bad-ray case does not use: tmax NaN, tmax negative, tmin and
 * tmax +inf, tmin -inf with tmax negative, a direction of -0s, NaN and
 * -Inf everywhere in the origin, +Inf in the direction with 0s besides,
 * both bounds NaN; traced mixed in one batch (closest and any hit).
 * Outcome: the bad rays miss (no hit written: prim none, t +inf), the good
 * ones give the reference's answer, and the mixed batch takes at most 2.5
 * times the good rays' time (no hang). */
static void bad_rays_mixed_into_a_real_scene_miss(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(m != NULL);
    if (!m) return;
    as_structure_t *s = build(m, "bunny");
    if (!s) { as_mesh_release(m); return; }
    const size_t n = 8000;
    as_ray_t *rays = malloc(sizeof *rays * n);
    ref_make_scene_rays(m, n, 0x5D1FF000Cull, rays);
    as_ray_t *good = malloc(sizeof *good * n);
    memcpy(good, rays, sizeof *good * n);
    for (size_t i = 1; i < n; i += 2) {
        as_ray_t *r = &rays[i];
        switch ((i / 2) % 8) {
        case 0: r->tmax = NAN; break;
        case 1: r->tmax = -1.0f; break;
        case 2: r->tmin = r->tmax = INFINITY; break;
        case 3: r->tmin = -INFINITY; r->tmax = -1e30f; break;
        case 4: r->dir[0] = r->dir[1] = r->dir[2] = -0.0f; break;
        case 5: r->org[0] = NAN; r->org[1] = -INFINITY; r->org[2] = NAN; break;
        case 6: r->dir[0] = INFINITY; r->dir[1] = r->dir[2] = 0.0f; break;
        default: r->tmin = r->tmax = NAN; break;
        }
    }
    /* The reference for the whole mixed batch (the bad rays miss there
     * too), kept in the build tree: the bunny's brute force is the slow
     * part, and every variant shares it. */
    as_hit_t *hits = NULL;
    const size_t disagree =
        against_reference_ex("bad rays mixed", m, s, rays, n, &hits, NULL, AS_BINARY_DIR "/reference_cache");
    size_t written = 0, good_hits = 0;
    for (size_t i = 0; i < n; ++i) {
        if (i & 1) written += hits[i].prim != AS_NO_HIT || !(isinf(hits[i].t) && hits[i].t > 0);
        else good_hits += hits[i].prim != AS_NO_HIT;
    }
    free(hits);
    as_hit_t *any = trace(s, rays, n, 1, NULL);
    size_t any_written = 0;
    for (size_t i = 1; i < n; i += 2) any_written += any[i].prim != AS_NO_HIT || !isinf(any[i].t);
    free(any);
    /* Time: the mixed batch against the good rays alone, best of three. */
    double mixed_ms = INFINITY, good_ms = INFINITY;
    for (int k = 0; k < 3; ++k) {
        double ms;
        free(trace(s, rays, n, 0, &ms));
        mixed_ms = fmin(mixed_ms, ms);
        free(trace(s, good, n, 0, &ms));
        good_ms = fmin(good_ms, ms);
    }
    fprintf(stderr, "  %s bad rays mixed: %zu of %zu bad, %zu hits written (%zu any-hit), %zu good rays hit, "
            "%zu disagree with the reference, %.2f ms mixed against %.2f ms good\n", variant_name, n / 2, n,
            written, any_written, good_hits, disagree, mixed_ms, good_ms);
    CHECK_EQ_U64(written, 0);
    CHECK_EQ_U64(any_written, 0);
    CHECK(good_hits > n / 16); /* the good rays do meet the bunny */
    CHECK_EQ_U64(disagree, 0);
    CHECK(mixed_ms <= 2.5 * good_ms + 5.0);
    free(good);
    free(rays);
    as_structure_release(s);
    as_mesh_release(m);
}

int main(int argc, char **argv)
{
    const char *only = NULL;
    const int rc = stiff_parse_variant(argc, argv, "test_stiff_more", &only);
    if (rc) return rc;
#define CASE(name, fn) if (!only || strcmp(only, name) == 0) RUN_TEST(fn)
    CASE("watertight", closed_meshes_far_away_have_zero_leaks);
    CASE("needles", needle_cube_has_zero_leaks);
    CASE("fan", fan_centre_is_hit_on_one_of_its_triangles);
    CASE("signed_zero", signed_zero_on_the_structures_own_planes);
    CASE("grazing", grazing_rays_on_curved_meshes_match_the_reference);
    CASE("in_plane", in_plane_rays_at_other_orientations_miss_their_plane);
    CASE("range", tiny_and_huge_closed_meshes_have_zero_leaks);
    CASE("degenerate", degenerate_triangles_on_rays_are_never_hit);
    CASE("duplicates", scattered_copies_report_the_lowest_index);
    CASE("planar", quads_on_dyadic_and_structure_planes_are_hit);
    CASE("bad_rays", bad_rays_mixed_into_a_real_scene_miss);
#undef CASE
    TEST_EXIT();
}
