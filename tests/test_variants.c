/* Every structure variant against the double-precision reference, through
 * the public API only: build, validate, save, load, trace on the CPU.
 *
 *   test_variants STRUCTURE BUILDER LAYOUT           synthetic cases
 *   test_variants STRUCTURE BUILDER LAYOUT scene NAME RAYS
 *
 * Synthetic cases: random soups; closed meshes hit exactly on their edges and
 * vertices (zero leaks); rays parallel to each axis from vertex coordinates
 * (which are the candidate split planes); +0 and -0 direction components
 * (identical results); origins inside the scene. */
#include "reference.h"
#include "test_util.h"

#include <stdio.h>

static as_build_args_t variant;
static char variant_name[128];
static char tmpdir[256];

static as_structure_t *build_saved_and_loaded(const as_mesh_t *m)
{
    as_structure_t *built = as_structure_build(m, &variant);
    if (!built) {
        fprintf(stderr, "  %s: build failed: %s\n", variant_name, as_get_error_message());
        CHECK(built != NULL);
        return NULL;
    }
    CHECK_EQ_INT(as_structure_validate(built), AS_OK);
    /* What users trace is the file: go through it. */
    char path[512];
    snprintf(path, sizeof path, "%s/variant.asf", tmpdir);
    CHECK_EQ_INT(as_structure_save(built, path, NULL), AS_OK);
    as_structure_release(built);
    as_structure_t *s = as_structure_load(path, NULL);
    if (!s) fprintf(stderr, "  %s: load failed: %s\n", variant_name, as_get_error_message());
    CHECK(s != NULL);
    if (s) CHECK_EQ_INT(as_structure_validate(s), AS_OK);
    if (s) {
        as_structure_stats_t st;
        CHECK_EQ_INT(as_structure_get_stats(s, &st), AS_OK);
        CHECK_EQ_INT(st.structure, variant.structure);
        if (variant.layout) CHECK_EQ_INT(st.layout, variant.layout);
    }
    unlink(path);
    return s;
}

static as_hit_t *trace(const as_structure_t *s, const as_ray_t *rays, size_t n, int any_hit)
{
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = AS_DEVICE_CPU;
    ta.any_hit = any_hit;
    as_hit_t *hits = malloc(sizeof *hits * (n ? n : 1));
    if (as_trace(s, rays, n, hits, &ta, NULL) != AS_OK) {
        fprintf(stderr, "  trace failed: %s\n", as_get_error_message());
        CHECK(0);
        free(hits);
        return NULL;
    }
    return hits;
}

static size_t compare(const char *what, const as_mesh_t *m, const as_structure_t *s, const as_ray_t *rays, size_t n,
                      int expect_hits)
{
    ref_scene rs;
    CHECK(ref_scene_init(&rs, m));
    ref_hit *ref = malloc(sizeof *ref * n);
    ref_trace_all_cached(&rs, m, rays, n, ref, AS_BINARY_DIR "/reference_cache");
    as_hit_t *hits = trace(s, rays, n, 0);
    size_t bad = 0, nhit = 0;
    for (size_t i = 0; hits && i < n; ++i) {
        nhit += ref[i].prim != AS_NO_HIT;
        if (!ref_agrees(&rs, &rays[i], &ref[i], &hits[i])) {
            if (bad < 5)
                fprintf(stderr, "  %s %s ray %zu: org (%.9g %.9g %.9g) dir (%.9g %.9g %.9g): reference prim %u t %.9g, "
                        "traversal prim %u t %.9g\n", variant_name, what, i, (double)rays[i].org[0], (double)rays[i].org[1],
                        (double)rays[i].org[2], (double)rays[i].dir[0], (double)rays[i].dir[1], (double)rays[i].dir[2],
                        ref[i].prim, ref[i].t, hits[i].prim, (double)hits[i].t);
            ++bad;
        }
    }
    /* Any hit: a hit exactly when the reference has one. */
    as_hit_t *any = hits ? trace(s, rays, n, 1) : NULL;
    size_t bad_any = 0;
    for (size_t i = 0; any && i < n; ++i) bad_any += (ref[i].prim != AS_NO_HIT) != (any[i].prim != AS_NO_HIT);
    fprintf(stderr, "  %s %s: %zu rays, %zu hit in the reference, %zu closest-hit and %zu any-hit disagree\n",
            variant_name, what, n, nhit, bad, bad_any);
    if (expect_hits) CHECK(nhit > 0);
    CHECK_EQ_U64(bad, 0);
    CHECK_EQ_U64(bad_any, 0);
    free(any);
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

static void variant_matches_reference_on_random_soups(void)
{
    const struct { uint32_t tris; float size; } soups[] = {{1, 0.5f}, {9, 0.5f}, {2000, 0.1f}, {20000, 0.03f}};
    for (size_t k = 0; k < sizeof soups / sizeof soups[0]; ++k) {
        as_mesh_t *m = random_soup(500 + k, soups[k].tris, soups[k].size);
        as_structure_t *s = build_saved_and_loaded(m);
        if (s) {
            const size_t n = 10000;
            as_ray_t *rays = malloc(sizeof *rays * n);
            ref_make_scene_rays(m, n, 11 + k, rays);
            char what[64];
            snprintf(what, sizeof what, "soup of %u", soups[k].tris);
            compare(what, m, s, rays, n, 1);
            free(rays);
        }
        as_structure_release(s);
        as_mesh_release(m);
    }
}

/* A cube of n x n quads per face on the integer lattice (vertices shared, so
 * closed), offset by `offset`. */
/* The stiff suite's lattice cube (6 x 6 quads a face, shared vertices,
 * unit edges) with its corner at `offset`. */
static as_mesh_t *lattice_cube(float offset)
{
    as_stiff_args_t a;
    as_stiff_args_default(&a);
    a.offset = offset;
    a.edge = 1.0;
    as_stiff_case_data_t c;
    if (as_stiff_case_generate(AS_STIFF_WATERTIGHT_CUBE, &a, &c) != AS_OK) return NULL;
    as_mesh_t *m = c.mesh;
    c.mesh = NULL;
    as_stiff_case_free(&c);
    return m;
}

static void variant_has_no_leaks_on_closed_meshes(void)
{
    const float offsets[] = {0.0f, 1000.0f};
    for (size_t c = 0; c < 2; ++c) {
        const int n = 6;
        as_mesh_t *m = lattice_cube(offsets[c]);
        CHECK(m != NULL);
        if (!m) continue;
        as_structure_t *s = build_saved_and_loaded(m);
        if (!s) { as_mesh_release(m); continue; }
        const float ctr = offsets[c] + n / 2.0f;
        /* Through every lattice point of the surface and the midpoints
         * between neighbours: from the centre out, and from outside in. */
        const size_t cap = 2 * 6 * (2 * n + 1) * (2 * n + 1);
        as_ray_t *rays = malloc(sizeof *rays * cap);
        size_t k = 0;
        for (int f = 0; f < 6; ++f)
            for (int a = 0; a <= 2 * n; ++a)
                for (int b = 0; b <= 2 * n; ++b) {
                    float q[3];
                    q[f / 2] = offsets[c] + ((f % 2) ? n : 0);
                    q[(f / 2 + 1) % 3] = offsets[c] + a * 0.5f;
                    q[(f / 2 + 2) % 3] = offsets[c] + b * 0.5f;
                    as_ray_t *in = &rays[k++], *out = &rays[k++];
                    for (int d = 0; d < 3; ++d) {
                        in->org[d] = ctr;
                        in->dir[d] = q[d] - ctr;
                        out->org[d] = ctr + 3.0f * (q[d] - ctr);
                        out->dir[d] = ctr - out->org[d];
                    }
                    in->tmin = out->tmin = 0.0f;
                    in->tmax = INFINITY;
                    out->tmax = 1.0f;
                }
        as_hit_t *hits = trace(s, rays, k, 0);
        size_t leaks = 0;
        for (size_t i = 0; hits && i < k; ++i) leaks += hits[i].prim == AS_NO_HIT;
        fprintf(stderr, "  %s closed cube at %g: %zu rays through edges and vertices, %zu leaks\n", variant_name,
                (double)offsets[c], k, leaks);
        CHECK_EQ_U64(leaks, 0);
        compare("closed cube", m, s, rays, k, 1);
        free(hits);
        free(rays);
        as_structure_release(s);
        as_mesh_release(m);
    }
}

/* Axis-parallel rays, with every sign of zero in the other components: the
 * results for +0 and -0 must be identical, and agree with the reference.
 * Origins sit on vertex coordinates, where spatial splits, box faces and
 * grid walls lie. */
static void variant_handles_axis_parallel_rays_and_signed_zeros(void)
{
    as_mesh_t *m = random_soup(77, 3000, 0.1f);
    const float *p = as_mesh_positions(m);
    as_structure_t *s = build_saved_and_loaded(m);
    if (!s) { as_mesh_release(m); return; }
    const size_t base = 2000, n = base * 6 * 4;
    as_ray_t *rays = malloc(sizeof *rays * n);
    uint64_t st = 3;
    size_t k = 0;
    for (size_t i = 0; i < base; ++i) {
        const uint32_t v = (uint32_t)(ref_rand_u64(&st) % 9000), w = (uint32_t)(ref_rand_u64(&st) % 9000);
        for (int axis = 0; axis < 3; ++axis)
            for (int sign = 0; sign < 2; ++sign)
                for (int zeros = 0; zeros < 4; ++zeros) {
                    as_ray_t *r = &rays[k++];
                    for (int d = 0; d < 3; ++d) {
                        /* The origin shares the other coordinates with vertices. */
                        r->org[d] = d == axis ? (sign ? 2.0f : -1.0f) : (d == (axis + 1) % 3 ? p[3 * v + d] : p[3 * w + d]);
                        r->dir[d] = d == axis ? (sign ? -1.0f : 1.0f)
                                              : ((zeros >> (d == (axis + 1) % 3 ? 0 : 1)) & 1 ? -0.0f : 0.0f);
                    }
                    r->tmin = 0.0f;
                    r->tmax = INFINITY;
                }
    }
    as_hit_t *hits = trace(s, rays, k, 0);
    size_t differ = 0;
    for (size_t i = 0; hits && i < k; i += 4)
        for (int z = 1; z < 4; ++z) differ += memcmp(&hits[i], &hits[i + z], sizeof hits[i]) != 0;
    fprintf(stderr, "  %s axis-parallel: %zu rays, %zu results differ between +0 and -0\n", variant_name, k, differ);
    CHECK_EQ_U64(differ, 0);
    compare("axis-parallel", m, s, rays, k, 1);
    free(hits);
    free(rays);
    as_structure_release(s);
    as_mesh_release(m);
}

static void variant_matches_reference_on_scene(const char *name, size_t n)
{
    char buf[4096];
    const char *path = test_scene_or_exit(name, buf, sizeof buf);
    as_mesh_t *m = as_mesh_import(path);
    CHECK(m != NULL);
    if (!m) return;
    as_structure_t *s = build_saved_and_loaded(m);
    if (s) {
        /* On real scenes the reference is as_verify's: the watertight test
         * in double over a conservatively traversed BVH of the scene's
         * triangles, which test_verify checks against the true brute force
         * (a brute force of every variant on every scene would outlast CI). */
        as_ray_t *rays = malloc(sizeof *rays * n);
        ref_make_scene_rays(m, n, 4242, rays);
        as_verify_args_t va;
        as_verify_args_default(&va);
        va.sample_count = 0; /* every ray */
        for (int any_hit = 0; any_hit < 2; ++any_hit) {
            as_hit_t *hits = trace(s, rays, n, any_hit);
            as_verify_result_t r;
            memset(&r, 0, sizeof r);
            if (hits) CHECK_EQ_INT(as_verify(s, rays, hits, n, any_hit, &va, &r), AS_OK);
            fprintf(stderr, "  %s %s (%s): %llu rays verified, %llu wrong primitive, %llu false miss, %llu false hit, "
                    "max t error %.2e relative (%.0f ms)\n", variant_name, name, any_hit ? "any hit" : "closest hit",
                    (unsigned long long)r.checked, (unsigned long long)r.wrong_primitive,
                    (unsigned long long)r.false_misses, (unsigned long long)r.false_hits, r.max_t_error, r.verify_ms);
            CHECK_EQ_U64(r.checked, n);
            CHECK_EQ_U64(r.wrong_primitive + r.false_misses + r.false_hits, 0);
            if (!any_hit) CHECK(r.max_t_error <= 1e-5);
            free(hits);
        }
        free(rays);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

int main(int argc, char **argv)
{
    if (argc < 4) {
        fprintf(stderr, "usage: %s STRUCTURE BUILDER LAYOUT [scene NAME RAYS]\n", argv[0]);
        return 2;
    }
    if (test_parse_variant(argv + 1, &variant, variant_name, sizeof variant_name)) return 2;
    snprintf(tmpdir, sizeof tmpdir, "/tmp/as_test_variants_XXXXXX");
    if (!mkdtemp(tmpdir)) return 1;
    if (argc >= 7 && strcmp(argv[4], "scene") == 0) {
        variant_matches_reference_on_scene(argv[5], (size_t)strtoull(argv[6], NULL, 10));
        fprintf(stderr, "%s %s variant_matches_reference_on_scene %s\n", test_failures ? "FAIL" : "ok  ", variant_name,
                argv[5]);
    } else {
        RUN_TEST(variant_matches_reference_on_random_soups);
        RUN_TEST(variant_has_no_leaks_on_closed_meshes);
        RUN_TEST(variant_handles_axis_parallel_rays_and_signed_zeros);
    }
    rmdir(tmpdir);
    TEST_EXIT();
}
