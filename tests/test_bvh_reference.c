/* The BVH traversal (CPU back end, the same header the GPU runs) against the
 * double-precision brute force: random soups, real scenes, closed meshes hit
 * exactly on their edges and vertices.
 *
 *   test_bvh_reference soups | scene NAME RAYS | closed | anyhit */
#include "reference.h"
#include "test_util.h"

#include <math.h>
#include <stdio.h>

static as_structure_t *build_bvh(const as_mesh_t *mesh)
{
    as_build_args_t args;
    as_build_args_default(&args);
    as_structure_t *s = as_structure_build(mesh, &args);
    if (!s) fprintf(stderr, "build failed: %s\n", as_get_error_message());
    return s;
}

static as_hit_t *trace_cpu(const as_structure_t *s, const as_ray_t *rays, size_t n, int any_hit)
{
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = AS_DEVICE_CPU;
    ta.any_hit = any_hit;
    as_hit_t *hits = malloc(sizeof *hits * n);
    as_trace_timing_t timing;
    if (as_trace(s, rays, n, hits, &ta, &timing) != AS_OK) {
        fprintf(stderr, "trace failed: %s\n", as_get_error_message());
        free(hits);
        return NULL;
    }
    fprintf(stderr, "  traced %zu rays in %.1f ms (%.2f Mrays/s, CPU)\n", n, timing.trace_ms,
            n / (timing.trace_ms * 1e3));
    return hits;
}

/* Counts disagreements with the reference and prints the first few. */
static size_t compare_with_reference(const char *what, const as_mesh_t *mesh, const as_structure_t *s,
                                     const as_ray_t *rays, size_t n)
{
    ref_scene rs;
    CHECK(ref_scene_init(&rs, mesh));
    ref_hit *ref = malloc(sizeof *ref * n);
    ref_trace_all(&rs, rays, n, ref);
    as_hit_t *hits = trace_cpu(s, rays, n, 0);
    size_t bad = 0, nhit = 0;
    for (size_t i = 0; hits && i < n; ++i) {
        nhit += ref[i].prim != AS_NO_HIT;
        if (!ref_agrees(&rs, &rays[i], &ref[i], &hits[i])) {
            if (bad < 5)
                fprintf(stderr, "  %s ray %zu: reference prim %u t %.9g, traversal prim %u t %.9g\n", what, i,
                        ref[i].prim, ref[i].t, hits[i].prim, (double)hits[i].t);
            ++bad;
        }
    }
    fprintf(stderr, "  %s: %zu rays, %zu hit in the reference, %zu disagree\n", what, n, nhit, bad);
    CHECK(hits != NULL);
    CHECK(nhit > 0); /* a comparison where nothing is hit proves little */
    free(hits);
    free(ref);
    ref_scene_free(&rs);
    return bad;
}

static as_mesh_t *random_soup(uint64_t seed, uint32_t tris, float size)
{
    uint64_t st = seed;
    float *p = malloc(sizeof(float) * 9 * tris);
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * tris);
    for (uint32_t t = 0; t < tris; ++t) {
        float c[3];
        for (int k = 0; k < 3; ++k) c[k] = (float)ref_rand01(&st);
        for (int v = 0; v < 3; ++v)
            for (int k = 0; k < 3; ++k) p[9 * t + 3 * v + k] = c[k] + size * (float)(ref_rand01(&st) - 0.5);
        for (int v = 0; v < 3; ++v) ix[3 * t + v] = 3 * t + v;
    }
    as_mesh_t *m = as_mesh_create(3 * tris, p, tris, ix);
    free(p);
    free(ix);
    return m;
}

static void traversal_matches_reference_on_random_soups(void)
{
    const struct { uint32_t tris; float size; } soups[] = {{1, 0.5f}, {7, 0.5f}, {1000, 0.2f}, {20000, 0.05f}, {5000, 1.0f}};
    for (size_t k = 0; k < sizeof soups / sizeof soups[0]; ++k) {
        as_mesh_t *m = random_soup(1000 + k, soups[k].tris, soups[k].size);
        CHECK(m != NULL);
        as_structure_t *s = build_bvh(m);
        CHECK(s != NULL);
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
        const size_t n = 20000;
        as_ray_t *rays = malloc(sizeof *rays * n);
        ref_make_scene_rays(m, n, 77 + k, rays);
        char what[64];
        snprintf(what, sizeof what, "soup of %u", soups[k].tris);
        CHECK_EQ_U64(compare_with_reference(what, m, s, rays, n), 0);
        free(rays);
        as_structure_release(s);
        as_mesh_release(m);
    }
}

static void traversal_matches_reference_on_scene(const char *name, size_t n)
{
    char buf[4096];
    const char *path = test_scene_or_exit(name, buf, sizeof buf);
    as_mesh_t *m = as_mesh_import(path);
    if (!m) fprintf(stderr, "import failed: %s\n", as_get_error_message());
    CHECK(m != NULL);
    if (!m) return;
    as_structure_t *s = build_bvh(m);
    CHECK(s != NULL);
    as_ray_t *rays = malloc(sizeof *rays * n);
    ref_make_scene_rays(m, n, 4242, rays);
    CHECK_EQ_U64(compare_with_reference(name, m, s, rays, n), 0);
    free(rays);
    as_structure_release(s);
    as_mesh_release(m);
}

/* A cube of n x n quads per face on the integer lattice, vertices shared
 * between faces, so the mesh is closed and every vertex and edge midpoint
 * is exact in float. */
static as_mesh_t *lattice_cube(int n, float offset)
{
    const int side = n + 1;
    int32_t *id = malloc(sizeof(int32_t) * side * side * side);
    float *p = malloc(sizeof(float) * 3 * side * side * side);
    uint32_t nv = 0;
    for (int i = 0; i < side; ++i)
        for (int j = 0; j < side; ++j)
            for (int k = 0; k < side; ++k) {
                const int on_surface = i == 0 || j == 0 || k == 0 || i == n || j == n || k == n;
                id[(i * side + j) * side + k] = on_surface ? (int32_t)nv : -1;
                if (on_surface) {
                    p[3 * nv] = offset + (float)i; p[3 * nv + 1] = offset + (float)j; p[3 * nv + 2] = offset + (float)k;
                    ++nv;
                }
            }
    uint32_t *ix = malloc(sizeof(uint32_t) * 6 * n * n * 6);
    uint32_t nt = 0;
#define LV(a, b, c) ((uint32_t)id[((a) * side + (b)) * side + (c)])
    for (int f = 0; f < 6; ++f) {
        const int axis = f / 2, fixed = (f % 2) ? n : 0;
        for (int a = 0; a < n; ++a)
            for (int b = 0; b < n; ++b) {
                int q[4][3];
                const int uv[4][2] = {{a, b}, {a + 1, b}, {a + 1, b + 1}, {a, b + 1}};
                for (int c = 0; c < 4; ++c) {
                    q[c][axis] = fixed;
                    q[c][(axis + 1) % 3] = uv[c][0];
                    q[c][(axis + 2) % 3] = uv[c][1];
                }
                const uint32_t v0 = LV(q[0][0], q[0][1], q[0][2]), v1 = LV(q[1][0], q[1][1], q[1][2]);
                const uint32_t v2 = LV(q[2][0], q[2][1], q[2][2]), v3 = LV(q[3][0], q[3][1], q[3][2]);
                ix[3 * nt] = v0; ix[3 * nt + 1] = v1; ix[3 * nt + 2] = v2; ++nt;
                ix[3 * nt] = v0; ix[3 * nt + 1] = v2; ix[3 * nt + 2] = v3; ++nt;
            }
    }
#undef LV
    as_mesh_t *m = as_mesh_create(nv, p, nt, ix);
    free(id);
    free(p);
    free(ix);
    return m;
}

/* A latitude-longitude sphere with fans at the poles: closed, indexed. */
static as_mesh_t *uv_sphere(int rings, int segments, float radius, float offset)
{
    const uint32_t nv = 2 + (uint32_t)(rings - 1) * segments;
    float *p = malloc(sizeof(float) * 3 * nv);
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * 2 * rings * segments);
    p[0] = offset; p[1] = offset; p[2] = offset + radius;
    p[3] = offset; p[4] = offset; p[5] = offset - radius;
    for (int r = 1; r < rings; ++r)
        for (int s = 0; s < segments; ++s) {
            const double th = 3.14159265358979 * r / rings, ph = 2 * 3.14159265358979 * s / segments;
            float *v = p + 3 * (2 + (r - 1) * segments + s);
            v[0] = offset + (float)(radius * sin(th) * cos(ph));
            v[1] = offset + (float)(radius * sin(th) * sin(ph));
            v[2] = offset + (float)(radius * cos(th));
        }
    uint32_t nt = 0;
#define RV(r, s) (2u + (uint32_t)((r) - 1) * segments + (uint32_t)((s) % segments))
    for (int s = 0; s < segments; ++s) {
        ix[3 * nt] = 0; ix[3 * nt + 1] = RV(1, s); ix[3 * nt + 2] = RV(1, s + 1); ++nt;
        ix[3 * nt] = 1; ix[3 * nt + 1] = RV(rings - 1, s + 1); ix[3 * nt + 2] = RV(rings - 1, s); ++nt;
    }
    for (int r = 1; r + 1 < rings; ++r)
        for (int s = 0; s < segments; ++s) {
            ix[3 * nt] = RV(r, s); ix[3 * nt + 1] = RV(r + 1, s); ix[3 * nt + 2] = RV(r + 1, s + 1); ++nt;
            ix[3 * nt] = RV(r, s); ix[3 * nt + 1] = RV(r + 1, s + 1); ix[3 * nt + 2] = RV(r, s + 1); ++nt;
        }
#undef RV
    as_mesh_t *m = as_mesh_create(nv, p, nt, ix);
    free(p);
    free(ix);
    return m;
}

/* Rays through every vertex and every edge point (midpoint and quarter
 * points) of a closed mesh: from its centre outwards, and from outside
 * through the point towards the centre. Every one must hit. */
static size_t make_closed_mesh_rays(const as_mesh_t *m, const float centre[3], as_ray_t **out)
{
    as_mesh_info_t info;
    as_mesh_get_info(m, &info);
    const float *p = as_mesh_positions(m);
    const uint32_t *ix = as_mesh_indices(m);
    const size_t max = 20 * (size_t)info.triangle_count; /* 10 points per triangle, 2 rays each */
    as_ray_t *rays = malloc(sizeof *rays * max);
    size_t n = 0;
    for (uint32_t t = 0; t < info.triangle_count + 0u; ++t) {
        for (int e = 0; e < 3; ++e) {
            const float *a = p + 3 * ix[3 * t + e], *b = p + 3 * ix[3 * t + (e + 1) % 3];
            const float ws[4] = {0.0f, 0.25f, 0.5f, 0.75f};
            for (int w = 0; w < 4; ++w) {
                if (w == 0 && e != 0) continue; /* vertices once per triangle is plenty */
                float q[3];
                for (int k = 0; k < 3; ++k) q[k] = a[k] + ws[w] * (b[k] - a[k]);
                as_ray_t *in = &rays[n++], *outr = &rays[n++];
                for (int k = 0; k < 3; ++k) {
                    in->org[k] = centre[k];
                    in->dir[k] = q[k] - centre[k];
                    outr->org[k] = centre[k] + 3.0f * (q[k] - centre[k]);
                    outr->dir[k] = centre[k] - outr->org[k];
                }
                in->tmin = outr->tmin = 0.0f;
                in->tmax = INFINITY;
                outr->tmax = 1.0f; /* up to the centre: the surface lies in between */
            }
        }
    }
    *out = rays;
    return n;
}

static void closed_meshes_have_zero_leaks_on_edges_and_vertices(void)
{
    const struct { const char *name; int kind; float offset; } cases[] = {
        {"lattice cube 8x8", 0, 0.0f},
        {"uv sphere 24x48", 1, 0.0f},
        {"lattice cube 8x8 at 1000", 0, 1000.0f},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; ++c) {
        as_mesh_t *m = cases[c].kind == 0 ? lattice_cube(8, cases[c].offset) : uv_sphere(24, 48, 1.0f, cases[c].offset);
        CHECK(m != NULL);
        const float centre[3] = {cases[c].offset + (cases[c].kind == 0 ? 4.0f : 0.0f),
                                 cases[c].offset + (cases[c].kind == 0 ? 4.0f : 0.0f),
                                 cases[c].offset + (cases[c].kind == 0 ? 4.0f : 0.0f)};
        as_structure_t *s = build_bvh(m);
        CHECK(s != NULL);
        as_ray_t *rays;
        const size_t n = make_closed_mesh_rays(m, centre, &rays);
        as_hit_t *hits = trace_cpu(s, rays, n, 0);
        size_t misses = 0;
        for (size_t i = 0; hits && i < n; ++i) {
            if (hits[i].prim == AS_NO_HIT) {
                if (misses < 5)
                    fprintf(stderr, "  %s: leak on ray %zu org (%.9g %.9g %.9g) dir (%.9g %.9g %.9g)\n", cases[c].name, i,
                            (double)rays[i].org[0], (double)rays[i].org[1], (double)rays[i].org[2],
                            (double)rays[i].dir[0], (double)rays[i].dir[1], (double)rays[i].dir[2]);
                ++misses;
            }
        }
        fprintf(stderr, "  %s: %zu rays through edges and vertices, %zu leaks\n", cases[c].name, n, misses);
        CHECK(hits != NULL);
        CHECK_EQ_U64(misses, 0);
        CHECK_EQ_U64(compare_with_reference(cases[c].name, m, s, rays, n), 0);
        free(hits);
        free(rays);
        as_structure_release(s);
        as_mesh_release(m);
    }
}

/* Any-hit rays report a hit exactly when the reference finds one, and the
 * triangle they report is really hit within the ray's interval. */
static void any_hit_agrees_with_reference_on_occlusion(void)
{
    as_mesh_t *m = random_soup(99, 3000, 0.1f);
    as_structure_t *s = build_bvh(m);
    CHECK(s != NULL);
    const size_t n = 20000;
    as_ray_t *rays = malloc(sizeof *rays * n);
    ref_make_scene_rays(m, n, 5, rays);
    for (size_t i = 0; i < n; ++i) rays[i].tmax = (i % 3 == 0) ? 0.05f : (i % 3 == 1 ? 0.3f : INFINITY);
    ref_scene rs;
    CHECK(ref_scene_init(&rs, m));
    ref_hit *ref = malloc(sizeof *ref * n);
    ref_trace_all(&rs, rays, n, ref);
    as_hit_t *hits = trace_cpu(s, rays, n, 1);
    size_t bad = 0, occluded = 0;
    for (size_t i = 0; hits && i < n; ++i) {
        const int ref_hit_any = ref[i].prim != AS_NO_HIT;
        occluded += ref_hit_any;
        int ok = ref_hit_any == (hits[i].prim != AS_NO_HIT);
        if (ok && ref_hit_any) {
            const double t = ref_hit_distance(&rs, &rays[i], hits[i].prim);
            ok = fabs((double)hits[i].t - t) <= 1e-5 * t + 1e-6 * rs.diag ||
                 /* a float hit on an edge the double test misses */
                 (!isfinite(t) && hits[i].t >= rays[i].tmin && hits[i].t <= rays[i].tmax);
        }
        if (!ok && bad++ < 5)
            fprintf(stderr, "  any-hit ray %zu: reference prim %u, traversal prim %u t %g\n", i, ref[i].prim,
                    hits[i].prim, (double)hits[i].t);
    }
    fprintf(stderr, "  any hit: %zu rays, %zu occluded, %zu disagree\n", n, occluded, bad);
    CHECK(occluded > 0 && occluded < n);
    CHECK_EQ_U64(bad, 0);
    free(hits);
    free(ref);
    free(rays);
    ref_scene_free(&rs);
    as_structure_release(s);
    as_mesh_release(m);
}

int main(int argc, char **argv)
{
    const char *which = argc > 1 ? argv[1] : "soups";
    if (strcmp(which, "soups") == 0) RUN_TEST(traversal_matches_reference_on_random_soups);
    else if (strcmp(which, "closed") == 0) RUN_TEST(closed_meshes_have_zero_leaks_on_edges_and_vertices);
    else if (strcmp(which, "anyhit") == 0) RUN_TEST(any_hit_agrees_with_reference_on_occlusion);
    else if (strcmp(which, "scene") == 0 && argc > 3) {
        traversal_matches_reference_on_scene(argv[2], (size_t)strtoull(argv[3], NULL, 10));
        fprintf(stderr, "%s traversal_matches_reference_on_scene %s\n", test_failures ? "FAIL" : "ok  ", argv[2]);
    } else {
        fprintf(stderr, "usage: %s soups|closed|anyhit|scene NAME RAYS\n", argv[0]);
        return 2;
    }
    TEST_EXIT();
}
