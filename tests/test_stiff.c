/* The stiff-case suite: where floating point is hardest, each case states its
 * correct outcome and every structure variant must meet it exactly.
 *
 *   test_stiff [--gpu] STRUCTURE BUILDER LAYOUT [CASE]
 *
 * With --gpu the rays are traced by the CUDA kernels (exit 77, skipped,
 * without a usable GPU); builds and the reference stay on the CPU.
 * Cases (fixed seeds): watertight, moller_leaks, seam, signed_zero, grazing, range,
 * degenerate, flat, duplicates, planar, surface, bad_rays. */
#include "reference.h"
#include "test_util.h"

#include <float.h>
#include <stdio.h>
#include <time.h>

static as_build_args_t variant;
static char variant_name[128];
static as_intersector_t intersector = AS_INTERSECTOR_WATERTIGHT;
static as_device_t device = AS_DEVICE_CPU;

/* ---- helpers -------------------------------------------------------------- */

typedef struct mesh_builder {
    float *p;
    uint32_t *ix;
    uint32_t nv, nt, cap_v, cap_t;
} mesh_builder;

static uint32_t mb_vertex(mesh_builder *m, double x, double y, double z)
{
    if (m->nv == m->cap_v) {
        m->cap_v = m->cap_v ? 2 * m->cap_v : 1024;
        m->p = realloc(m->p, sizeof(float) * 3 * m->cap_v);
    }
    m->p[3 * m->nv] = (float)x;
    m->p[3 * m->nv + 1] = (float)y;
    m->p[3 * m->nv + 2] = (float)z;
    return m->nv++;
}

static void mb_triangle(mesh_builder *m, uint32_t a, uint32_t b, uint32_t c)
{
    if (m->nt == m->cap_t) {
        m->cap_t = m->cap_t ? 2 * m->cap_t : 1024;
        m->ix = realloc(m->ix, sizeof(uint32_t) * 3 * m->cap_t);
    }
    m->ix[3 * m->nt] = a;
    m->ix[3 * m->nt + 1] = b;
    m->ix[3 * m->nt + 2] = c;
    ++m->nt;
}

static as_mesh_t *mb_finish(mesh_builder *m)
{
    as_mesh_t *mesh = as_mesh_create(m->nv, m->p, m->nt, m->ix);
    if (!mesh) fprintf(stderr, "  mesh rejected: %s\n", as_get_error_message());
    free(m->p);
    free(m->ix);
    memset(m, 0, sizeof *m);
    return mesh;
}

static as_structure_t *build(const as_mesh_t *m, const char *what)
{
    as_structure_t *s = as_structure_build(m, &variant);
    if (!s) fprintf(stderr, "  %s %s: build failed: %s\n", variant_name, what, as_get_error_message());
    CHECK(s != NULL);
    if (s) CHECK_EQ_INT(as_structure_validate(s), AS_OK);
    return s;
}

static as_hit_t *trace(const as_structure_t *s, const as_ray_t *rays, size_t n, int any_hit, double *ms)
{
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = device;
    ta.any_hit = any_hit;
    ta.thread_count = 1; /* timings below compare rays, not cores */
    ta.timed_runs = 3;   /* GPU: the median of three launches */
    ta.intersector = intersector;
    as_hit_t *hits = malloc(sizeof *hits * (n ? n : 1));
    as_trace_timing_t t;
    const as_error_t e = as_trace(s, rays, n, hits, &ta, &t);
    CHECK_EQ_INT(e, AS_OK);
    if (ms) *ms = t.trace_ms;
    return hits;
}

/* Closest hits against the reference; returns the disagreements. */
static size_t against_reference(const char *what, const as_mesh_t *m, const as_structure_t *s, const as_ray_t *rays,
                                size_t n)
{
    ref_scene rs;
    CHECK(ref_scene_init(&rs, m));
    ref_hit *ref = malloc(sizeof *ref * (n ? n : 1));
    ref_trace_all(&rs, rays, n, ref);
    as_hit_t *hits = trace(s, rays, n, 0, NULL);
    size_t bad = 0, nan = 0;
    for (size_t i = 0; i < n; ++i) {
        nan += isnan(hits[i].t) || isnan(hits[i].u) || isnan(hits[i].v);
        if (!ref_agrees(&rs, &rays[i], &ref[i], &hits[i])) {
            if (bad < 3)
                fprintf(stderr, "  %s %s ray %zu: reference prim %u t %.9g, traversal prim %u t %.9g\n", variant_name, what,
                        i, ref[i].prim, ref[i].t, hits[i].prim, (double)hits[i].t);
            ++bad;
        }
    }
    fprintf(stderr, "  %s %s: %zu rays, %zu disagree with the reference, %zu NaN\n", variant_name, what, n, bad, nan);
    CHECK_EQ_U64(nan, 0);
    free(hits);
    free(ref);
    ref_scene_free(&rs);
    return bad;
}

static void ray_set(as_ray_t *r, double ox, double oy, double oz, double dx, double dy, double dz, float tmax)
{
    r->org[0] = (float)ox; r->org[1] = (float)oy; r->org[2] = (float)oz;
    r->dir[0] = (float)dx; r->dir[1] = (float)dy; r->dir[2] = (float)dz;
    r->tmin = 0.0f;
    r->tmax = tmax;
}

/* ---- the cases ------------------------------------------------------------ */

/* A closed, indexed mesh at `offset` (kind 0: a lattice cube of shared
 * vertices, kind 1: a sphere with pole fans), sized so the float spacing
 * there is below 1/100 of an edge, and rays from inside and outside aimed
 * exactly at every vertex and at points of every edge; returns how many of
 * them miss (leak through the surface). */
static size_t closed_mesh_leaks(int kind, double offset)
{
    const double edge = offset == 0.0 ? 1.0 : offset == 1e6 ? 16.0 : 128.0;
    mesh_builder mb = {0};
    double centre[3];
    if (kind == 0) {
        /* A lattice cube, n x n quads per face, shared vertices. */
        const int n = 6;
        uint32_t *id = malloc(sizeof(uint32_t) * (n + 1) * (n + 1) * (n + 1));
        for (int i = 0; i <= n; ++i)
            for (int j = 0; j <= n; ++j)
                for (int k = 0; k <= n; ++k) {
                    const int on = !i || !j || !k || i == n || j == n || k == n;
                    id[(i * (n + 1) + j) * (n + 1) + k] =
                        on ? mb_vertex(&mb, offset + i * edge, offset + j * edge, offset + k * edge) : 0;
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
                        v[c] = id[(q[0] * (n + 1) + q[1]) * (n + 1) + q[2]];
                    }
                    mb_triangle(&mb, v[0], v[1], v[2]);
                    mb_triangle(&mb, v[0], v[2], v[3]);
                }
        }
        free(id);
        for (int k = 0; k < 3; ++k) centre[k] = offset + 0.5 * n * edge;
    } else {
        /* A latitude-longitude sphere with pole fans. */
        const int rings = 12, segs = 24;
        const double rad = 4.0 * edge;
        for (int k = 0; k < 3; ++k) centre[k] = offset + rad;
        const uint32_t top = mb_vertex(&mb, centre[0], centre[1], centre[2] + rad);
        const uint32_t bot = mb_vertex(&mb, centre[0], centre[1], centre[2] - rad);
        const uint32_t first = mb.nv;
        for (int r = 1; r < rings; ++r)
            for (int sgm = 0; sgm < segs; ++sgm) {
                const double th = 3.14159265358979 * r / rings, ph = 6.28318530717959 * sgm / segs;
                mb_vertex(&mb, centre[0] + rad * sin(th) * cos(ph), centre[1] + rad * sin(th) * sin(ph),
                          centre[2] + rad * cos(th));
            }
#define RV(r, sgm) (first + (uint32_t)(((r) - 1) * segs + ((sgm) % segs)))
        for (int sgm = 0; sgm < segs; ++sgm) {
            mb_triangle(&mb, top, RV(1, sgm), RV(1, sgm + 1));
            mb_triangle(&mb, bot, RV(rings - 1, sgm + 1), RV(rings - 1, sgm));
        }
        for (int r = 1; r + 1 < rings; ++r)
            for (int sgm = 0; sgm < segs; ++sgm) {
                mb_triangle(&mb, RV(r, sgm), RV(r + 1, sgm), RV(r + 1, sgm + 1));
                mb_triangle(&mb, RV(r, sgm), RV(r + 1, sgm + 1), RV(r, sgm + 1));
            }
#undef RV
    }
    as_mesh_t *m = mb_finish(&mb);
    CHECK(m != NULL);
    if (!m) return 0;
    as_structure_t *s = build(m, "watertight");
    if (!s) { as_mesh_release(m); return 0; }
    as_mesh_info_t info;
    as_mesh_get_info(m, &info);
    const float *p = as_mesh_positions(m);
    const uint32_t *ix = as_mesh_indices(m);
    as_ray_t *rays = malloc(sizeof *rays * 20 * info.triangle_count);
    size_t n = 0;
    const float c[3] = {(float)centre[0], (float)centre[1], (float)centre[2]};
    for (uint32_t t = 0; t < info.triangle_count; ++t)
        for (int e = 0; e < 3; ++e)
            for (int w = 0; w < 4; ++w) {
                if (w == 0 && e) continue;
                const float *a = p + 3 * ix[3 * t + e], *b = p + 3 * ix[3 * t + (e + 1) % 3];
                float q[3];
                for (int k = 0; k < 3; ++k) q[k] = a[k] + 0.25f * w * (b[k] - a[k]);
                ray_set(&rays[n++], c[0], c[1], c[2], q[0] - c[0], q[1] - c[1], q[2] - c[2], INFINITY);
                ray_set(&rays[n++], c[0] + 3.0f * (q[0] - c[0]), c[1] + 3.0f * (q[1] - c[1]),
                        c[2] + 3.0f * (q[2] - c[2]), -3.0f * (q[0] - c[0]), -3.0f * (q[1] - c[1]),
                        -3.0f * (q[2] - c[2]), 1.0f);
            }
    as_hit_t *hits = trace(s, rays, n, 0, NULL);
    size_t leaks = 0;
    for (size_t i = 0; i < n; ++i) {
        if (hits[i].prim == AS_NO_HIT && leaks < 3)
            fprintf(stderr, "  leak: ray %zu org (%.9g %.9g %.9g) dir (%.9g %.9g %.9g) tmax %g\n", i,
                    (double)rays[i].org[0], (double)rays[i].org[1], (double)rays[i].org[2],
                    (double)rays[i].dir[0], (double)rays[i].dir[1], (double)rays[i].dir[2],
                    (double)rays[i].tmax);
        leaks += hits[i].prim == AS_NO_HIT;
    }
    fprintf(stderr, "  %s %s at %g: %zu rays at vertices and edges, %zu leaks%s\n", variant_name,
            kind ? "sphere" : "lattice cube", offset, n, leaks,
            intersector == AS_INTERSECTOR_MOLLER_TRUMBORE ? " (Moller-Trumbore)" : "");
    free(hits);
    free(rays);
    as_structure_release(s);
    as_mesh_release(m);
    return leaks;
}

/* At the origin and translated to 1e6 and 1e7: zero leaks. */
static void watertight_meshes_have_zero_leaks_far_from_the_origin(void)
{
    const double offsets[] = {0.0, 1e6, 1e7};
    for (int o = 0; o < 3; ++o)
        for (int kind = 0; kind < 2; ++kind) CHECK_EQ_U64(closed_mesh_leaks(kind, offsets[o]), 0);
}

/* The classic Moller-Trumbore test decides each triangle alone, so rays
 * aimed at shared vertices and edges slip through: the same meshes leak.
 * This is why the watertight test is the default, and it shows that the
 * intersector option really changes the triangle test. */
static void moller_trumbore_leaks_where_the_watertight_test_does_not(void)
{
    const double offsets[] = {0.0, 1e6, 1e7};
    size_t leaks = 0;
    intersector = AS_INTERSECTOR_MOLLER_TRUMBORE;
    for (int o = 0; o < 3; ++o)
        for (int kind = 0; kind < 2; ++kind) leaks += closed_mesh_leaks(kind, offsets[o]);
    intersector = AS_INTERSECTOR_WATERTIGHT;
    fprintf(stderr, "  %s Moller-Trumbore: %zu leaks in all\n", variant_name, leaks);
    CHECK(leaks > 0);
}

/* Two triangles sharing a diagonal; rays through points of the diagonal,
 * from both sides and slanted: each hits one of the two. */
static void quad_seam_rays_hit_one_of_the_two(void)
{
    mesh_builder mb = {0};
    const uint32_t a = mb_vertex(&mb, 0, 0, 0), b = mb_vertex(&mb, 1, 0, 0), c = mb_vertex(&mb, 1, 1, 0),
                   d = mb_vertex(&mb, 0, 1, 0);
    mb_triangle(&mb, a, b, c);
    mb_triangle(&mb, a, c, d);
    as_mesh_t *m = mb_finish(&mb);
    as_structure_t *s = build(m, "seam");
    if (!s) { as_mesh_release(m); return; }
    const size_t n = 4000;
    as_ray_t *rays = malloc(sizeof *rays * n);
    uint64_t st = 5;
    for (size_t i = 0; i < n; ++i) {
        const float u = (float)ref_rand01(&st); /* a point of the diagonal x = y */
        const double sx = ref_rand01(&st) - 0.5, sy = ref_rand01(&st) - 0.5, sz = (i & 1) ? 1.0 : -1.0;
        ray_set(&rays[i], u + sx, u + sy, sz, -sx, -sy, -sz, INFINITY);
    }
    as_hit_t *hits = trace(s, rays, n, 0, NULL);
    size_t misses = 0;
    for (size_t i = 0; i < n; ++i) misses += hits[i].prim == AS_NO_HIT;
    fprintf(stderr, "  %s seam: %zu rays through the shared diagonal, %zu misses\n", variant_name, n, misses);
    CHECK_EQ_U64(misses, 0);
    CHECK_EQ_U64(against_reference("seam", m, s, rays, n), 0);
    free(hits);
    free(rays);
    as_structure_release(s);
    as_mesh_release(m);
}

static as_mesh_t *random_soup(uint64_t seed, uint32_t tris, double size, double scale_lo, double scale_hi)
{
    mesh_builder mb = {0};
    uint64_t st = seed;
    for (uint32_t t = 0; t < tris; ++t) {
        /* Log-uniform sizes between scale_lo and scale_hi. */
        const double s = size * exp(log(scale_lo) + ref_rand01(&st) * (log(scale_hi) - log(scale_lo)));
        const double c[3] = {ref_rand01(&st), ref_rand01(&st), ref_rand01(&st)};
        uint32_t v[3];
        for (int k = 0; k < 3; ++k)
            v[k] = mb_vertex(&mb, c[0] + s * (ref_rand01(&st) - 0.5), c[1] + s * (ref_rand01(&st) - 0.5),
                             c[2] + s * (ref_rand01(&st) - 0.5));
        mb_triangle(&mb, v[0], v[1], v[2]);
    }
    return mb_finish(&mb);
}

/* Axis-parallel directions with +0 and -0 in the other components, origins on
 * vertex coordinates (split planes, box faces, grid walls, octree planes):
 * identical results, no NaN, agreement with the reference. */
static void signed_zero_directions_give_identical_results(void)
{
    as_mesh_t *m = random_soup(42, 2000, 0.1, 1, 1);
    as_structure_t *s = build(m, "signed zero");
    if (!s) { as_mesh_release(m); return; }
    const float *p = as_mesh_positions(m);
    const size_t base = 1500;
    as_ray_t *rays = malloc(sizeof *rays * base * 6 * 4);
    size_t n = 0;
    uint64_t st = 8;
    for (size_t i = 0; i < base; ++i) {
        const uint32_t v = (uint32_t)(ref_rand_u64(&st) % 6000);
        for (int axis = 0; axis < 3; ++axis)
            for (int sign = 0; sign < 2; ++sign)
                for (int z = 0; z < 4; ++z) {
                    as_ray_t *r = &rays[n++];
                    for (int k = 0; k < 3; ++k) {
                        r->org[k] = k == axis ? (sign ? 1.5f : -0.5f) : p[3 * v + k];
                        r->dir[k] = k == axis ? (sign ? -1.0f : 1.0f) : ((z >> (k == (axis + 1) % 3)) & 1 ? -0.0f : 0.0f);
                    }
                    r->tmin = 0.0f;
                    r->tmax = INFINITY;
                }
    }
    as_hit_t *hits = trace(s, rays, n, 0, NULL);
    size_t differ = 0, nan = 0;
    for (size_t i = 0; i < n; i += 4)
        for (int z = 1; z < 4; ++z) differ += memcmp(&hits[i], &hits[i + z], sizeof *hits) != 0;
    for (size_t i = 0; i < n; ++i) nan += isnan(hits[i].t);
    fprintf(stderr, "  %s signed zero: %zu rays, %zu differ between +0 and -0, %zu NaN\n", variant_name, n, differ, nan);
    CHECK_EQ_U64(differ, 0);
    CHECK_EQ_U64(nan, 0);
    CHECK_EQ_U64(against_reference("signed zero", m, s, rays, n), 0);
    free(hits);
    free(rays);
    as_structure_release(s);
    as_mesh_release(m);
}

/* A large tessellated plane (z = 0), rays at 1e-1 down to 1e-7 radians and
 * inside the plane. In-plane rays (direction with z = 0 from z = 0) meet
 * every triangle edge-on: the documented answer is a miss. */
static void grazing_rays_match_the_reference_and_in_plane_rays_miss(void)
{
    mesh_builder mb = {0};
    const int n = 40;
    for (int i = 0; i <= n; ++i)
        for (int j = 0; j <= n; ++j) mb_vertex(&mb, i * 25.0, j * 25.0, 0.0);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const uint32_t v00 = (uint32_t)(i * (n + 1) + j), v10 = v00 + (n + 1), v01 = v00 + 1, v11 = v10 + 1;
            mb_triangle(&mb, v00, v10, v11);
            mb_triangle(&mb, v00, v11, v01);
        }
    as_mesh_t *m = mb_finish(&mb);
    as_structure_t *s = build(m, "grazing");
    if (!s) { as_mesh_release(m); return; }
    const size_t per = 1000;
    const double angles[] = {1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7};
    as_ray_t *rays = malloc(sizeof *rays * per * 8);
    size_t k = 0;
    uint64_t st = 9;
    for (int a = 0; a < 7; ++a)
        for (size_t i = 0; i < per; ++i) {
            const double phi = 6.28318530717959 * ref_rand01(&st), x = 100 + 800 * ref_rand01(&st),
                         y = 100 + 800 * ref_rand01(&st);
            const double dx = cos(phi) * cos(angles[a]), dy = sin(phi) * cos(angles[a]), dz = -sin(angles[a]);
            /* Start above the plane so the ray reaches it after 50 units. */
            ray_set(&rays[k++], x - 50 * dx, y - 50 * dy, -50 * dz, dx, dy, dz, INFINITY);
        }
    const size_t slanted = k;
    for (size_t i = 0; i < per; ++i) {
        const double phi = 6.28318530717959 * ref_rand01(&st);
        ray_set(&rays[k++], 100 + 800 * ref_rand01(&st), 100 + 800 * ref_rand01(&st), 0.0, cos(phi), sin(phi), 0.0,
                INFINITY);
    }
    CHECK_EQ_U64(against_reference("grazing", m, s, rays, slanted), 0);
    as_hit_t *hits = trace(s, rays + slanted, k - slanted, 0, NULL);
    size_t in_plane_hits = 0;
    for (size_t i = 0; i < k - slanted; ++i) in_plane_hits += hits[i].prim != AS_NO_HIT;
    fprintf(stderr, "  %s grazing: %zu in-plane rays, %zu hits (documented answer: none)\n", variant_name, k - slanted,
            in_plane_hits);
    CHECK_EQ_U64(in_plane_hits, 0);
    free(hits);
    free(rays);
    as_structure_release(s);
    as_mesh_release(m);
}

/* Triangles from 1e-6 to 1e6 in size side by side. The float test cancels
 * there (t of a huge triangle seen from close by, edges of a tiny one seen
 * from afar): its disagreements are counted and reported; the double
 * intersector must match the reference exactly. */
static void dynamic_range_matches_the_reference(void)
{
    as_mesh_t *m = random_soup(77, 3000, 1.0, 1e-6, 1e6);
    as_structure_t *s = build(m, "dynamic range");
    if (!s) { as_mesh_release(m); return; }
    const size_t n = 20000;
    as_ray_t *rays = malloc(sizeof *rays * n);
    uint64_t st = 10;
    /* Half the rays aim at tiny triangles' centroids. */
    const float *p = as_mesh_positions(m);
    for (size_t i = 0; i < n; ++i) {
        float d[3];
        ref_random_direction(&st, d);
        if (i & 1) {
            const uint32_t t = (uint32_t)(ref_rand_u64(&st) % 3000);
            double c[3];
            for (int k = 0; k < 3; ++k) c[k] = (p[9 * t + k] + p[9 * t + 3 + k] + p[9 * t + 6 + k]) / 3.0;
            ray_set(&rays[i], c[0] - d[0], c[1] - d[1], c[2] - d[2], d[0], d[1], d[2], INFINITY);
        } else {
            ray_set(&rays[i], ref_rand01(&st), ref_rand01(&st), ref_rand01(&st), d[0], d[1], d[2], INFINITY);
        }
    }
    const size_t float_bad = against_reference("dynamic range, float test", m, s, rays, n);
    fprintf(stderr, "  %s dynamic range: the float test disagrees on %zu of %zu rays (%.0f ppm)\n", variant_name,
            float_bad, n, 1e6 * (double)float_bad / (double)n);
    intersector = AS_INTERSECTOR_WATERTIGHT_DOUBLE;
    CHECK_EQ_U64(against_reference("dynamic range, double test", m, s, rays, n), 0);
    intersector = AS_INTERSECTOR_WATERTIGHT;
    free(rays);
    as_structure_release(s);
    as_mesh_release(m);
}

/* Repeated indices, collinear vertices and needles of aspect 1e7 beside
 * ordinary triangles: builds finish, zero-area triangles are never hit. */
static void degenerate_triangles_are_never_hit(void)
{
    mesh_builder mb = {0};
    uint64_t st = 11;
    uint32_t zero_area = 0;
    for (int i = 0; i < 3000; ++i) {
        const double c[3] = {ref_rand01(&st), ref_rand01(&st), ref_rand01(&st)};
        const uint32_t a = mb_vertex(&mb, c[0], c[1], c[2]);
        const uint32_t b = mb_vertex(&mb, c[0] + 0.05, c[1], c[2]);
        switch (i % 4) {
        case 0: mb_triangle(&mb, a, a, b); ++zero_area; break;                             /* repeated index */
        case 1: mb_triangle(&mb, a, b, mb_vertex(&mb, c[0] + 0.1, c[1], c[2])); ++zero_area; break; /* collinear */
        case 2: mb_triangle(&mb, a, b, mb_vertex(&mb, c[0], c[1] + 0.05e-7, c[2])); break; /* needle 1e7 */
        default: mb_triangle(&mb, a, b, mb_vertex(&mb, c[0], c[1] + 0.05, c[2] + 0.01)); break;
        }
    }
    as_mesh_t *m = mb_finish(&mb);
    as_mesh_info_t info;
    as_mesh_get_info(m, &info);
    CHECK(info.degenerate_count >= zero_area);
    as_structure_t *s = build(m, "degenerate");
    if (!s) { as_mesh_release(m); return; }
    const size_t n = 20000;
    as_ray_t *rays = malloc(sizeof *rays * n);
    ref_make_scene_rays(m, n, 12, rays);
    as_hit_t *hits = trace(s, rays, n, 0, NULL);
    size_t degenerate_hits = 0;
    for (size_t i = 0; i < n; ++i)
        degenerate_hits += hits[i].prim != AS_NO_HIT && as_mesh_triangle_is_degenerate(m, hits[i].prim);
    fprintf(stderr, "  %s degenerate: %u zero-area triangles, %zu hits on them\n", variant_name, info.degenerate_count,
            degenerate_hits);
    CHECK_EQ_U64(degenerate_hits, 0);
    CHECK_EQ_U64(against_reference("degenerate", m, s, rays, n), 0);
    free(hits);
    free(rays);
    as_structure_release(s);
    as_mesh_release(m);
}

/* Every triangle in the plane y = 0.5 (a zero-thickness box): builds,
 * and rays from both sides hit. */
static void flat_scene_is_hit_from_both_sides(void)
{
    mesh_builder mb = {0};
    uint64_t st = 13;
    for (int i = 0; i < 2000; ++i) {
        const double x = ref_rand01(&st), z = ref_rand01(&st);
        mb_triangle(&mb, mb_vertex(&mb, x, 0.5, z), mb_vertex(&mb, x + 0.03, 0.5, z), mb_vertex(&mb, x, 0.5, z + 0.03));
    }
    as_mesh_t *m = mb_finish(&mb);
    as_structure_t *s = build(m, "flat");
    if (!s) { as_mesh_release(m); return; }
    const size_t n = 10000;
    as_ray_t *rays = malloc(sizeof *rays * n);
    for (size_t i = 0; i < n; ++i) {
        const double side = (i & 1) ? 1.0 : -1.0;
        ray_set(&rays[i], ref_rand01(&st), 0.5 + side, ref_rand01(&st), 0.1 * (ref_rand01(&st) - 0.5), -side,
                0.1 * (ref_rand01(&st) - 0.5), INFINITY);
    }
    as_hit_t *hits = trace(s, rays, n, 0, NULL);
    size_t hit_above = 0, hit_below = 0;
    for (size_t i = 0; i < n; ++i)
        if (hits[i].prim != AS_NO_HIT) {
            if (i & 1) ++hit_above;
            else ++hit_below;
        }
    fprintf(stderr, "  %s flat: %zu hits from above, %zu from below\n", variant_name, hit_above, hit_below);
    CHECK(hit_above > 0 && hit_below > 0);
    CHECK_EQ_U64(against_reference("flat", m, s, rays, n), 0);
    free(hits);
    free(rays);
    as_structure_release(s);
    as_mesh_release(m);
}

/* 2 to 10,000 copies of one triangle, alone and inside a mesh: the depth
 * stays within the cap, nodes grow at most linearly, the closest hit is the
 * lowest index among the copies. */
static void duplicates_keep_depth_and_report_the_lowest_copy(void)
{
    const uint32_t counts[] = {2, 10, 100, 10000};
    for (int inside = 0; inside < 2; ++inside)
        for (int c = 0; c < 4; ++c) {
            mesh_builder mb = {0};
            uint64_t st = 14;
            uint32_t first_copy = 0;
            if (inside)
                for (int i = 0; i < 500; ++i) {
                    const double x = ref_rand01(&st) * 4, y = ref_rand01(&st) * 4, z = 1 + ref_rand01(&st);
                    mb_triangle(&mb, mb_vertex(&mb, x, y, z), mb_vertex(&mb, x + 0.1, y, z), mb_vertex(&mb, x, y + 0.1, z));
                }
            first_copy = mb.nt;
            const uint32_t a = mb_vertex(&mb, 0, 0, 0), b = mb_vertex(&mb, 1, 0, 0), d = mb_vertex(&mb, 0, 1, 0);
            for (uint32_t k = 0; k < counts[c]; ++k) mb_triangle(&mb, a, b, d);
            as_mesh_t *m = mb_finish(&mb);
            as_structure_t *s = build(m, "duplicates");
            if (!s) { as_mesh_release(m); continue; }
            as_structure_stats_t stt;
            CHECK_EQ_INT(as_structure_get_stats(s, &stt), AS_OK);
            CHECK(stt.max_depth <= 64);
            CHECK(stt.node_count <= 4 * (uint64_t)(counts[c] + 500) + 64);
            as_ray_t ray;
            ray_set(&ray, 0.25, 0.25, -1.0, 0, 0, 1, INFINITY);
            as_hit_t *h = trace(s, &ray, 1, 0, NULL);
            CHECK_EQ_U64(h[0].prim, first_copy);
            free(h);
            as_structure_release(s);
            as_mesh_release(m);
        }
    fprintf(stderr, "  %s duplicates: depth within the cap, lowest copy reported\n", variant_name);
}

/* Axis-aligned quads lying exactly on candidate split planes (the box's
 * middle and quarter planes, on every axis); rays crossing them hit. */
static void planar_quads_on_split_planes_are_hit(void)
{
    mesh_builder mb = {0};
    /* Corner points give the box [0, 8]^3. */
    mb_triangle(&mb, mb_vertex(&mb, 0, 0, 0), mb_vertex(&mb, 0.01, 0, 0), mb_vertex(&mb, 0, 0.01, 0));
    mb_triangle(&mb, mb_vertex(&mb, 8, 8, 8), mb_vertex(&mb, 7.99, 8, 8), mb_vertex(&mb, 8, 7.99, 8));
    const double planes[] = {2, 4, 6};
    for (int axis = 0; axis < 3; ++axis)
        for (int pl = 0; pl < 3; ++pl) {
            double q[4][3];
            const double uv[4][2] = {{1, 1}, {7, 1}, {7, 7}, {1, 7}};
            for (int c = 0; c < 4; ++c) {
                q[c][axis] = planes[pl];
                q[c][(axis + 1) % 3] = uv[c][0] + 0.1 * axis;
                q[c][(axis + 2) % 3] = uv[c][1] + 0.1 * pl;
            }
            uint32_t v[4];
            for (int c = 0; c < 4; ++c) v[c] = mb_vertex(&mb, q[c][0], q[c][1], q[c][2]);
            mb_triangle(&mb, v[0], v[1], v[2]);
            mb_triangle(&mb, v[0], v[2], v[3]);
        }
    as_mesh_t *m = mb_finish(&mb);
    as_structure_t *s = build(m, "planar");
    if (!s) { as_mesh_release(m); return; }
    const size_t n = 6000;
    as_ray_t *rays = malloc(sizeof *rays * n);
    uint64_t st = 15;
    for (size_t i = 0; i < n; ++i) {
        const int axis = (int)(i % 3);
        double o[3], d[3];
        for (int k = 0; k < 3; ++k) {
            o[k] = 2 + 4 * ref_rand01(&st);
            d[k] = 0.2 * (ref_rand01(&st) - 0.5);
        }
        o[axis] = (i / 3) % 2 ? -1.0 : 9.0;
        d[axis] = (i / 3) % 2 ? 1.0 : -1.0;
        ray_set(&rays[i], o[0], o[1], o[2], d[0], d[1], d[2], INFINITY);
    }
    as_hit_t *hits = trace(s, rays, n, 0, NULL);
    size_t misses = 0;
    for (size_t i = 0; i < n; ++i) misses += hits[i].prim == AS_NO_HIT;
    fprintf(stderr, "  %s planar: %zu rays crossing quads on split planes, %zu misses\n", variant_name, n, misses);
    CHECK_EQ_U64(misses, 0);
    CHECK_EQ_U64(against_reference("planar", m, s, rays, n), 0);
    free(hits);
    free(rays);
    as_structure_release(s);
    as_mesh_release(m);
}

/* Secondary rays leaving a surface (shadow, reflection) from hit points
 * offset along the normal by 1e-4 of the scene diagonal (as_rays_shadow's
 * and as_rays_hemisphere's documented offset) never re-hit their source. */
static void rays_leaving_a_surface_do_not_rehit_it(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(m != NULL);
    if (!m) return;
    as_structure_t *s = build(m, "surface");
    if (!s) { as_mesh_release(m); return; }
    as_mesh_info_t info;
    as_mesh_get_info(m, &info);
    as_camera_t cam;
    as_camera_default(info.bounds_lo, info.bounds_hi, &cam);
    const uint32_t w = 200, h = 200;
    as_ray_t *prim = malloc(sizeof *prim * w * h);
    as_camera_rays(&cam, w, h, prim);
    as_hit_t *hits = trace(s, prim, (size_t)w * h, 0, NULL);
    as_secondary_args_t sa;
    as_secondary_args_default(&sa);
    sa.tmax_fraction = 0.0f;
    as_ray_t *sec;
    size_t ns;
    uint32_t *from;
    CHECK_EQ_INT(as_rays_hemisphere(s, prim, hits, (size_t)w * h, &sa, &sec, &ns, &from), AS_OK);
    as_hit_t *sh = trace(s, sec, ns, 0, NULL);
    size_t rehit = 0;
    for (size_t i = 0; i < ns; ++i) rehit += sh[i].prim != AS_NO_HIT && sh[i].prim == hits[from[i]].prim;
    fprintf(stderr, "  %s surface: %zu rays leaving the surface, %zu re-hit their source\n", variant_name, ns, rehit);
    CHECK(ns > 0);
    CHECK_EQ_U64(rehit, 0);
    free(sh);
    free(sec);
    free(from);
    free(hits);
    free(prim);
    as_structure_release(s);
    as_mesh_release(m);
}

/* tmin > tmax, zero direction, NaN or Inf in origin or direction: no hit
 * written, no hang, at most 2.5x a normal ray's time. */
static void bad_rays_miss_quickly(void)
{
    as_mesh_t *m = random_soup(16, 20000, 0.05, 1, 1);
    as_structure_t *s = build(m, "bad rays");
    if (!s) { as_mesh_release(m); return; }
    const size_t n = 200000;
    as_ray_t *good = malloc(sizeof *good * n), *bad = malloc(sizeof *bad * n);
    ref_make_scene_rays(m, n, 17, good);
    const float nan = NAN, inf = INFINITY;
    for (size_t i = 0; i < n; ++i) {
        bad[i] = good[i];
        switch (i % 7) {
        case 0: bad[i].tmin = 2.0f; bad[i].tmax = 1.0f; break;
        case 1: bad[i].dir[0] = bad[i].dir[1] = bad[i].dir[2] = 0.0f; break;
        case 2: bad[i].org[1] = nan; break;
        case 3: bad[i].dir[2] = nan; break;
        case 4: bad[i].org[0] = inf; break;
        case 5: bad[i].dir[1] = -inf; break;
        default: bad[i].tmin = nan; break;
        }
    }
    double good_ms = 0, bad_ms = 0;
    free(trace(s, good, n, 0, &good_ms));
    as_hit_t *hits = trace(s, bad, n, 0, &bad_ms);
    size_t written = 0;
    for (size_t i = 0; i < n; ++i) written += hits[i].prim != AS_NO_HIT || !isinf(hits[i].t);
    fprintf(stderr, "  %s bad rays: %zu rays, %zu hits written, %.1f ms against %.1f ms for good rays\n", variant_name, n,
            written, bad_ms, good_ms);
    CHECK_EQ_U64(written, 0);
    CHECK(bad_ms <= 2.5 * good_ms + 5.0);
    free(hits);
    free(good);
    free(bad);
    as_structure_release(s);
    as_mesh_release(m);
}

int main(int argc, char **argv)
{
    if (argc > 1 && strcmp(argv[1], "--gpu") == 0) {
        device = AS_DEVICE_GPU;
        --argc;
        ++argv;
        if (!as_gpu_available()) {
            fprintf(stderr, "no usable CUDA device: skipped\n");
            return 77;
        }
    }
    if (argc < 4) {
        fprintf(stderr, "usage: test_stiff [--gpu] STRUCTURE BUILDER LAYOUT [CASE]\n");
        return 2;
    }
    as_build_args_default(&variant);
    variant.structure = as_structure_kind_from_name(argv[1]);
    variant.builder = as_builder_from_name(variant.structure, argv[2]);
    variant.layout = as_layout_from_name(argv[3]);
    if (!variant.structure || !variant.builder || !variant.layout) {
        fprintf(stderr, "unknown variant %s/%s/%s\n", argv[1], argv[2], argv[3]);
        return 2;
    }
    snprintf(variant_name, sizeof variant_name, "%s/%s/%s", argv[1], argv[2], argv[3]);
    const char *only = argc > 4 ? argv[4] : NULL;
#define CASE(name, fn) if (!only || strcmp(only, name) == 0) RUN_TEST(fn)
    CASE("watertight", watertight_meshes_have_zero_leaks_far_from_the_origin);
    CASE("moller_leaks", moller_trumbore_leaks_where_the_watertight_test_does_not);
    CASE("seam", quad_seam_rays_hit_one_of_the_two);
    CASE("signed_zero", signed_zero_directions_give_identical_results);
    CASE("grazing", grazing_rays_match_the_reference_and_in_plane_rays_miss);
    CASE("range", dynamic_range_matches_the_reference);
    CASE("degenerate", degenerate_triangles_are_never_hit);
    CASE("flat", flat_scene_is_hit_from_both_sides);
    CASE("duplicates", duplicates_keep_depth_and_report_the_lowest_copy);
    CASE("planar", planar_quads_on_split_planes_are_hit);
    CASE("surface", rays_leaving_a_surface_do_not_rehit_it);
    CASE("bad_rays", bad_rays_miss_quickly);
#undef CASE
    TEST_EXIT();
}
