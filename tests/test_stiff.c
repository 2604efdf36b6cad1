/* The stiff-case suite: where floating point is hardest, each case states its
 * correct outcome and every structure variant must meet it exactly.
 *
 *   test_stiff [--gpu] STRUCTURE BUILDER LAYOUT [CASE]
 *   test_stiff --generator
 *
 * The meshes and rays come from the library's generator
 * (as_stiff_case_generate), with its default seed; --generator tests the
 * generator itself (defaults, refusals, same seed same bytes).
 * With --gpu the rays are traced by the CUDA kernels (exit 77, skipped,
 * without a usable GPU); builds and the reference stay on the CPU.
 * Cases: watertight, moller_leaks, seam, signed_zero, grazing, range,
 * degenerate, flat, duplicates, planar, surface, surface_far, bad_rays. */
#include "stiff_harness.h"

#include <float.h>
#include <stdio.h>
#include <time.h>

/* ---- helpers -------------------------------------------------------------- */

/* The case from the library's generator (as_stiff_case_generate), which
 * holds the suite's meshes and rays; `args` may be NULL. */
static int generate(as_stiff_case_t kind, const as_stiff_args_t *args, as_stiff_case_data_t *c)
{
    const as_error_t e = as_stiff_case_generate(kind, args, c);
    if (e != AS_OK) fprintf(stderr, "  %s: generation failed: %s\n", as_stiff_case_name(kind), as_get_error_message());
    CHECK_EQ_INT(e, AS_OK);
    return e == AS_OK;
}

/* Rays [from, to) whose hit breaks the outcome the generator states, the
 * reference part aside (against_reference checks that). */
static size_t outcome_failures(const as_stiff_case_data_t *c, size_t from, size_t to, const as_hit_t *hits)
{
    return stiff_outcome_failures(as_stiff_case_name(c->kind), c->outcomes, c->prims, from, to, hits);
}

/* ---- the cases ------------------------------------------------------------ */

/* A closed, indexed mesh at `offset` (a lattice cube or a sphere with pole
 * fans), sized so the float spacing there is below 1/100 of an edge, and
 * rays from inside and outside aimed exactly at every vertex and at points
 * of every edge; returns how many of them miss (leak through the surface). */
static size_t closed_mesh_leaks(as_stiff_case_t kind, double offset)
{
    as_stiff_args_t args;
    as_stiff_args_default(&args);
    args.offset = offset;
    as_stiff_case_data_t c;
    if (!generate(kind, &args, &c)) return 0;
    as_structure_t *s = build(c.mesh, "watertight");
    if (!s) { as_stiff_case_free(&c); return 0; }
    const as_ray_t *rays = c.rays;
    const size_t n = c.ray_count;
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
            kind == AS_STIFF_WATERTIGHT_SPHERE ? "sphere" : "lattice cube", offset, n, leaks,
            intersector == AS_INTERSECTOR_MOLLER_TRUMBORE ? " (Moller-Trumbore)" : "");
    /* The generator's outcome (every ray hits) is this test's. */
    if (intersector != AS_INTERSECTOR_MOLLER_TRUMBORE) CHECK_EQ_U64(outcome_failures(&c, 0, n, hits), leaks);
    free(hits);
    as_structure_release(s);
    as_stiff_case_free(&c);
    return leaks;
}

/* At the origin and translated to 1e6 and 1e7: zero leaks. */
static void watertight_meshes_have_zero_leaks_far_from_the_origin(void)
{
    const double offsets[] = {0.0, 1e6, 1e7};
    for (int o = 0; o < 3; ++o)
        for (int kind = 0; kind < 2; ++kind)
            CHECK_EQ_U64(closed_mesh_leaks(kind ? AS_STIFF_WATERTIGHT_SPHERE : AS_STIFF_WATERTIGHT_CUBE, offsets[o]), 0);
}

/* The float version of the watertight test (explicitly rounded, with the
 * double fallback where an edge function cancels to zero) is not the
 * default but is watertight too: the same meshes, zero leaks. */
static void float_watertight_test_has_zero_leaks_too(void)
{
    intersector = AS_INTERSECTOR_WATERTIGHT;
    watertight_meshes_have_zero_leaks_far_from_the_origin();
    intersector = default_intersector;
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
        for (int kind = 0; kind < 2; ++kind)
            leaks += closed_mesh_leaks(kind ? AS_STIFF_WATERTIGHT_SPHERE : AS_STIFF_WATERTIGHT_CUBE, offsets[o]);
    intersector = default_intersector;
    fprintf(stderr, "  %s Moller-Trumbore: %zu leaks in all\n", variant_name, leaks);
    CHECK(leaks > 0);
}

/* Two triangles sharing a diagonal; rays through points of the diagonal,
 * from both sides and slanted: each hits one of the two. */
static void quad_seam_rays_hit_one_of_the_two(void)
{
    as_stiff_case_data_t c;
    if (!generate(AS_STIFF_QUAD_SEAM, NULL, &c)) return;
    as_structure_t *s = build(c.mesh, "seam");
    if (!s) { as_stiff_case_free(&c); return; }
    const size_t n = c.ray_count;
    as_hit_t *hits = trace(s, c.rays, n, 0, NULL);
    size_t misses = 0;
    for (size_t i = 0; i < n; ++i) misses += hits[i].prim == AS_NO_HIT;
    fprintf(stderr, "  %s seam: %zu rays through the shared diagonal, %zu misses\n", variant_name, n, misses);
    CHECK_EQ_U64(misses, 0);
    CHECK_EQ_U64(outcome_failures(&c, 0, n, hits), 0);
    CHECK_EQ_U64(against_reference("seam", c.mesh, s, c.rays, n), 0);
    free(hits);
    as_structure_release(s);
    as_stiff_case_free(&c);
}

/* Axis-parallel directions with +0 and -0 in the other components, origins on
 * vertex coordinates (split planes, box faces, grid walls, octree planes):
 * identical results, no NaN, agreement with the reference. */
static void signed_zero_directions_give_identical_results(void)
{
    as_stiff_case_data_t c;
    if (!generate(AS_STIFF_SIGNED_ZERO, NULL, &c)) return;
    as_structure_t *s = build(c.mesh, "signed zero");
    if (!s) { as_stiff_case_free(&c); return; }
    const size_t n = c.ray_count;
    as_hit_t *hits = trace(s, c.rays, n, 0, NULL);
    size_t differ = 0, nan = 0;
    for (size_t i = 0; i < n; i += 4)
        for (int z = 1; z < 4; ++z) differ += memcmp(&hits[i], &hits[i + z], sizeof *hits) != 0;
    for (size_t i = 0; i < n; ++i) nan += isnan(hits[i].t);
    fprintf(stderr, "  %s signed zero: %zu rays, %zu differ between +0 and -0, %zu NaN\n", variant_name, n, differ, nan);
    CHECK_EQ_U64(differ, 0);
    CHECK_EQ_U64(nan, 0);
    CHECK_EQ_U64(outcome_failures(&c, 0, n, hits), 0);
    CHECK_EQ_U64(against_reference("signed zero", c.mesh, s, c.rays, n), 0);
    free(hits);
    as_structure_release(s);
    as_stiff_case_free(&c);
}

/* A large tessellated plane (z = 0), rays at 1e-1 down to 1e-7 radians and
 * inside the plane. In-plane rays (direction with z = 0 from z = 0) meet
 * every triangle edge-on: the documented answer is a miss. */
static void grazing_rays_match_the_reference_and_in_plane_rays_miss(void)
{
    as_stiff_case_data_t c;
    if (!generate(AS_STIFF_GRAZING, NULL, &c)) return;
    as_structure_t *s = build(c.mesh, "grazing");
    if (!s) { as_stiff_case_free(&c); return; }
    /* The slanted rays first, then the in-plane ones, which must miss. */
    size_t slanted = 0;
    while (slanted < c.ray_count && c.outcomes[slanted].expect == AS_STIFF_EXPECT_REFERENCE) ++slanted;
    const size_t k = c.ray_count;
    CHECK_EQ_U64(slanted, 7 * (k - slanted));
    CHECK_EQ_U64(against_reference("grazing", c.mesh, s, c.rays, slanted), 0);
    as_hit_t *hits = trace(s, c.rays + slanted, k - slanted, 0, NULL);
    size_t in_plane_hits = 0;
    for (size_t i = 0; i < k - slanted; ++i) in_plane_hits += hits[i].prim != AS_NO_HIT;
    fprintf(stderr, "  %s grazing: %zu in-plane rays, %zu hits (documented answer: none)\n", variant_name, k - slanted,
            in_plane_hits);
    CHECK_EQ_U64(in_plane_hits, 0);
    CHECK_EQ_U64(outcome_failures(&c, slanted, k, hits), 0);
    free(hits);
    as_structure_release(s);
    as_stiff_case_free(&c);
}

/* Triangles from 1e-6 to 1e6 in size side by side. The float test cancels
 * there (t of a huge triangle seen from close by, edges of a tiny one seen
 * from afar): its disagreements are counted and reported; the double
 * intersector must match the reference exactly. */
static void dynamic_range_matches_the_reference(void)
{
    as_stiff_case_data_t c;
    if (!generate(AS_STIFF_DYNAMIC_RANGE, NULL, &c)) return;
    CHECK_EQ_INT(c.intersector, AS_INTERSECTOR_WATERTIGHT_DOUBLE);
    as_structure_t *s = build(c.mesh, "dynamic range");
    if (!s) { as_stiff_case_free(&c); return; }
    const size_t n = c.ray_count;
    intersector = AS_INTERSECTOR_WATERTIGHT;
    const size_t float_bad = against_reference("dynamic range, float test", c.mesh, s, c.rays, n);
    fprintf(stderr, "  %s dynamic range: the float test disagrees on %zu of %zu rays (%.0f ppm)\n", variant_name,
            float_bad, n, 1e6 * (double)float_bad / (double)n);
    intersector = AS_INTERSECTOR_WATERTIGHT_DOUBLE;
    CHECK_EQ_U64(against_reference("dynamic range, double test", c.mesh, s, c.rays, n), 0);
    intersector = default_intersector;
    as_structure_release(s);
    as_stiff_case_free(&c);
}

/* Repeated indices, collinear vertices and needles of aspect 1e7 beside
 * ordinary triangles: builds finish, zero-area triangles are never hit. */
static void degenerate_triangles_are_never_hit(void)
{
    as_stiff_case_data_t c;
    if (!generate(AS_STIFF_DEGENERATE, NULL, &c)) return;
    const as_mesh_t *m = c.mesh;
    as_mesh_info_t info;
    as_mesh_get_info(m, &info);
    /* A repeated index or collinear corners: half the 3,000 triangles. */
    CHECK(info.degenerate_count >= 1500);
    as_structure_t *s = build(m, "degenerate");
    if (!s) { as_stiff_case_free(&c); return; }
    const size_t n = c.ray_count;
    as_hit_t *hits = trace(s, c.rays, n, 0, NULL);
    size_t degenerate_hits = 0;
    for (size_t i = 0; i < n; ++i)
        degenerate_hits += hits[i].prim != AS_NO_HIT && as_mesh_triangle_is_degenerate(m, hits[i].prim);
    fprintf(stderr, "  %s degenerate: %u zero-area triangles, %zu hits on them\n", variant_name, info.degenerate_count,
            degenerate_hits);
    CHECK_EQ_U64(degenerate_hits, 0);
    CHECK_EQ_U64(outcome_failures(&c, 0, n, hits), 0);
    CHECK_EQ_U64(against_reference("degenerate", m, s, c.rays, n), 0);
    free(hits);
    as_structure_release(s);
    as_stiff_case_free(&c);
}

/* Every triangle in the plane y = 0.5 (a zero-thickness box): builds,
 * and rays from both sides hit. */
static void flat_scene_is_hit_from_both_sides(void)
{
    as_stiff_case_data_t c;
    if (!generate(AS_STIFF_FLAT, NULL, &c)) return;
    as_structure_t *s = build(c.mesh, "flat");
    if (!s) { as_stiff_case_free(&c); return; }
    const size_t n = c.ray_count;
    as_hit_t *hits = trace(s, c.rays, n, 0, NULL);
    size_t hit_above = 0, hit_below = 0;
    for (size_t i = 0; i < n; ++i)
        if (hits[i].prim != AS_NO_HIT) {
            if (c.rays[i].org[1] > 0.5f) ++hit_above;
            else ++hit_below;
        }
    fprintf(stderr, "  %s flat: %zu hits from above, %zu from below\n", variant_name, hit_above, hit_below);
    CHECK(hit_above > 0 && hit_below > 0);
    CHECK_EQ_U64(against_reference("flat", c.mesh, s, c.rays, n), 0);
    free(hits);
    as_structure_release(s);
    as_stiff_case_free(&c);
}

/* 2 to 10,000 copies of one triangle, alone and inside a mesh: the depth
 * stays within the cap, nodes grow at most linearly, the closest hit is the
 * lowest index among the copies. */
static void duplicates_keep_depth_and_report_the_lowest_copy(void)
{
    const uint32_t counts[] = {2, 10, 100, 10000};
    for (int inside = 0; inside < 2; ++inside)
        for (int k = 0; k < 4; ++k) {
            as_stiff_args_t args;
            as_stiff_args_default(&args);
            args.duplicate_count = counts[k];
            args.duplicates_among_others = inside;
            as_stiff_case_data_t c;
            if (!generate(AS_STIFF_DUPLICATES, &args, &c)) continue;
            as_structure_t *s = build(c.mesh, "duplicates");
            if (!s) { as_stiff_case_free(&c); continue; }
            as_structure_stats_t stt;
            CHECK_EQ_INT(as_structure_get_stats(s, &stt), AS_OK);
            CHECK(stt.max_depth <= 64);
            CHECK(stt.node_count <= 4 * (uint64_t)(counts[k] + 500) + 64);
            CHECK_EQ_U64(c.ray_count, 1);
            as_hit_t *h = trace(s, c.rays, 1, 0, NULL);
            /* The lowest copy: the first triangle after the 500 others. */
            CHECK_EQ_U64(h[0].prim, inside ? 500 : 0);
            CHECK_EQ_U64(outcome_failures(&c, 0, 1, h), 0);
            free(h);
            as_structure_release(s);
            as_stiff_case_free(&c);
        }
    fprintf(stderr, "  %s duplicates: depth within the cap, lowest copy reported\n", variant_name);
}

/* Axis-aligned quads lying exactly on candidate split planes (the box's
 * middle and quarter planes, on every axis); rays crossing them hit. */
static void planar_quads_on_split_planes_are_hit(void)
{
    as_stiff_case_data_t c;
    if (!generate(AS_STIFF_PLANAR_ON_SPLIT, NULL, &c)) return;
    as_structure_t *s = build(c.mesh, "planar");
    if (!s) { as_stiff_case_free(&c); return; }
    const size_t n = c.ray_count;
    as_hit_t *hits = trace(s, c.rays, n, 0, NULL);
    size_t misses = 0;
    for (size_t i = 0; i < n; ++i) misses += hits[i].prim == AS_NO_HIT;
    fprintf(stderr, "  %s planar: %zu rays crossing quads on split planes, %zu misses\n", variant_name, n, misses);
    CHECK_EQ_U64(misses, 0);
    CHECK_EQ_U64(outcome_failures(&c, 0, n, hits), 0);
    CHECK_EQ_U64(against_reference("planar", c.mesh, s, c.rays, n), 0);
    free(hits);
    as_structure_release(s);
    as_stiff_case_free(&c);
}

/* Secondary rays leaving a surface (shadow, reflection) from hit points
 * offset along the normal by 1e-4 of the scene diagonal (as_rays_shadow's
 * and as_rays_hemisphere's documented offset) never re-hit their source.
 * The bunny, and the rays this variant's own primary hits give. */
static void rays_leaving_a_surface_do_not_rehit_it(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(m != NULL);
    if (!m) return;
    as_structure_t *s = build(m, "surface");
    if (!s) { as_mesh_release(m); return; }
    as_stiff_args_t args;
    as_stiff_args_default(&args);
    args.surface_mesh = m;
    args.surface_structure = s;
    as_stiff_case_data_t c;
    if (generate(AS_STIFF_SURFACE, &args, &c)) {
        const size_t ns = c.ray_count;
        as_hit_t *sh = trace(s, c.rays, ns, 0, NULL);
        size_t rehit = 0;
        for (size_t i = 0; i < ns; ++i) rehit += sh[i].prim != AS_NO_HIT && sh[i].prim == c.prims[c.outcomes[i].first];
        fprintf(stderr, "  %s surface: %zu rays leaving the surface, %zu re-hit their source\n", variant_name, ns,
                rehit);
        CHECK(ns > 0);
        CHECK_EQ_U64(rehit, 0);
        CHECK_EQ_U64(outcome_failures(&c, 0, ns, sh), 0);
        free(sh);
        as_stiff_case_free(&c);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

/* Rays leaving a surface at the watertight suite's offsets, on its sphere (convex: a ray
 * leaving its outside meets nothing): at 1e6 the float spacing is 1/16, larger
 * than 1e-4 of the diagonal, so only the offset's floor of 4 spacings of the
 * hit point keeps the origins off the surface. Every ray misses, in agreement
 * with the double-precision reference. */
static void rays_leaving_a_sphere_far_from_the_origin_miss(void)
{
    const double offsets[] = {0.0, 1e6, 1e7};
    for (size_t k = 0; k < sizeof offsets / sizeof offsets[0]; ++k) {
        as_stiff_args_t args;
        as_stiff_args_default(&args);
        args.offset = offsets[k];
        as_stiff_case_data_t c;
        if (!generate(AS_STIFF_SURFACE, &args, &c)) continue;
        as_structure_t *s = build(c.mesh, "surface far");
        if (s) {
            const size_t n = c.ray_count;
            as_hit_t *hits = trace(s, c.rays, n, 0, NULL);
            size_t hit = 0;
            for (size_t i = 0; i < n; ++i) hit += hits[i].prim != AS_NO_HIT;
            fprintf(stderr, "  %s surface at %g: %zu rays leaving the sphere, %zu hit it\n", variant_name,
                    offsets[k], n, hit);
            CHECK(n > 1000);
            CHECK_EQ_U64(hit, 0);
            CHECK_EQ_U64(outcome_failures(&c, 0, n, hits), 0);
            CHECK_EQ_U64(against_reference("surface far", c.mesh, s, c.rays, n), 0);
            free(hits);
            as_structure_release(s);
        }
        as_stiff_case_free(&c);
    }
}

/* tmin > tmax, zero direction, NaN or Inf in origin or direction: no hit
 * written, no hang, at most 2.5x a normal ray's time. */
static void bad_rays_miss_quickly(void)
{
    as_stiff_case_data_t c;
    if (!generate(AS_STIFF_BAD_RAYS, NULL, &c)) return;
    as_structure_t *s = build(c.mesh, "bad rays");
    if (!s) { as_stiff_case_free(&c); return; }
    /* The ordinary rays, then their bad copies. */
    const size_t n = c.ray_count / 2;
    const as_ray_t *good = c.rays, *bad = c.rays + n;
    double good_ms = 0, bad_ms = 0;
    free(trace(s, good, n, 0, &good_ms));
    as_hit_t *hits = trace(s, bad, n, 0, &bad_ms);
    size_t written = 0;
    for (size_t i = 0; i < n; ++i) written += hits[i].prim != AS_NO_HIT || !isinf(hits[i].t);
    fprintf(stderr, "  %s bad rays: %zu rays, %zu hits written, %.1f ms against %.1f ms for good rays\n", variant_name, n,
            written, bad_ms, good_ms);
    CHECK_EQ_U64(written, 0);
    CHECK(bad_ms <= 2.5 * good_ms + 5.0);
    CHECK_EQ_U64(outcome_failures(&c, n, 2 * n, hits), 0);
    free(hits);
    as_structure_release(s);
    as_stiff_case_free(&c);
}

/* ---- the generator itself ------------------------------------------------ */

static uint64_t case_hash(const as_stiff_case_data_t *c)
{
    as_mesh_info_t info;
    as_mesh_get_info(c->mesh, &info);
    uint64_t h = info.hash;
    const unsigned char *b[3] = {(const void *)c->rays, (const void *)c->outcomes, (const void *)c->prims};
    const size_t len[3] = {c->ray_count * sizeof *c->rays, c->ray_count * sizeof *c->outcomes,
                           c->prim_count * sizeof *c->prims};
    for (int k = 0; k < 3; ++k) /* FNV-1a over the bytes */
        for (size_t i = 0; i < len[k]; ++i) h = (h ^ b[k][i]) * 1099511628211ull;
    return h;
}

static void generator_defaults_are_the_suites(void)
{
    as_stiff_args_t a;
    memset(&a, 0xAB, sizeof a);
    as_stiff_args_default(&a);
    CHECK_EQ_U64(a.size, sizeof a);
    CHECK_EQ_U64(a.seed, 0);
    CHECK(a.offset == 0.0 && a.edge == 0.0);
    CHECK_EQ_U64(a.duplicate_count, 10000);
    CHECK(!a.duplicates_among_others);
    CHECK_EQ_U64(a.ray_count, 0);
    CHECK(a.surface_mesh == NULL && a.surface_structure == NULL);
    for (int k = 1; k <= AS_STIFF_CASE_COUNT; ++k) {
        const char *name = as_stiff_case_name((as_stiff_case_t)k);
        CHECK(name != NULL);
        CHECK_EQ_INT(as_stiff_case_from_name(name), k);
    }
    CHECK(as_stiff_case_name(0) == NULL && as_stiff_case_name(AS_STIFF_CASE_COUNT + 1) == NULL);
    CHECK_EQ_INT(as_stiff_case_from_name("no-such-case"), 0);
    CHECK_EQ_INT(as_stiff_case_from_name(NULL), 0);
    /* NULL arguments are the defaults. */
    as_stiff_case_data_t x, y;
    if (generate(AS_STIFF_QUAD_SEAM, NULL, &x) && generate(AS_STIFF_QUAD_SEAM, &a, &y)) {
        CHECK_EQ_U64(case_hash(&x), case_hash(&y));
        CHECK_EQ_U64(x.ray_count, 4000);
        CHECK_EQ_U64(x.prim_count, 2);
        CHECK(x.outcome != NULL && x.outcome[0] != '\0');
    }
    as_stiff_case_free(&x);
    as_stiff_case_free(&y);
    as_stiff_case_free(NULL);
    as_stiff_case_free(&x); /* cleared: nothing to free twice */
}

static void generator_refuses_bad_arguments(void)
{
    as_stiff_case_data_t c;
    as_stiff_args_t a;
    as_stiff_args_default(&a);
    CHECK_EQ_INT(as_stiff_case_generate((as_stiff_case_t)0, &a, &c), AS_ERROR_INVALID_ARGUMENT);
    CHECK(c.mesh == NULL && c.rays == NULL);
    CHECK_STR_CONTAINS(as_get_error_message(), "unknown case");
    CHECK_EQ_INT(as_stiff_case_generate((as_stiff_case_t)(AS_STIFF_CASE_COUNT + 1), &a, &c), AS_ERROR_INVALID_ARGUMENT);
    CHECK_EQ_INT(as_stiff_case_generate(AS_STIFF_QUAD_SEAM, &a, NULL), AS_ERROR_INVALID_ARGUMENT);
    a.duplicate_count = 0;
    CHECK_EQ_INT(as_stiff_case_generate(AS_STIFF_DUPLICATES, &a, &c), AS_ERROR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(as_get_error_message(), "duplicate_count");
    as_stiff_args_default(&a);
    a.offset = NAN;
    CHECK_EQ_INT(as_stiff_case_generate(AS_STIFF_WATERTIGHT_CUBE, &a, &c), AS_ERROR_INVALID_ARGUMENT);
    as_stiff_args_default(&a);
    a.edge = -1.0;
    CHECK_EQ_INT(as_stiff_case_generate(AS_STIFF_WATERTIGHT_CUBE, &a, &c), AS_ERROR_INVALID_ARGUMENT);
    as_stiff_args_default(&a);
    a.size = 3;
    CHECK_EQ_INT(as_stiff_case_generate(AS_STIFF_QUAD_SEAM, &a, &c), AS_ERROR_INVALID_ARGUMENT);
    /* A mesh beyond the float range is the mesh check's to refuse. */
    as_stiff_args_default(&a);
    a.edge = 1e38;
    CHECK_EQ_INT(as_stiff_case_generate(AS_STIFF_WATERTIGHT_CUBE, &a, &c), AS_ERROR_INVALID_MESH);
    CHECK(c.mesh == NULL);
}

static void generator_gives_the_same_bytes_for_the_same_seed(void)
{
    as_stiff_args_t a;
    as_stiff_args_default(&a);
    a.ray_count = 3000;
    for (int k = 1; k <= AS_STIFF_CASE_COUNT; ++k) {
        if (k == AS_STIFF_SURFACE) continue; /* built and traced below */
        as_stiff_case_data_t x, y;
        a.seed = 7;
        if (generate((as_stiff_case_t)k, &a, &x) && generate((as_stiff_case_t)k, &a, &y)) {
            CHECK_EQ_U64(case_hash(&x), case_hash(&y));
            CHECK(x.ray_count > 0);
            for (size_t i = 0; i < x.ray_count; ++i)
                CHECK(x.outcomes[i].same_as == AS_STIFF_NO_RAY || x.outcomes[i].same_as < i);
        }
        as_stiff_case_free(&x);
        as_stiff_case_free(&y);
    }
    as_stiff_args_default(&a);
    as_stiff_case_data_t x, y;
    if (generate(AS_STIFF_SURFACE, &a, &x) && generate(AS_STIFF_SURFACE, &a, &y)) {
        CHECK_EQ_U64(case_hash(&x), case_hash(&y));
        CHECK(x.ray_count > 0);
    }
    as_stiff_case_free(&x);
    as_stiff_case_free(&y);
}

static void generator_gives_other_meshes_for_another_seed(void)
{
    /* The cases whose meshes are random, and the fixed ones whose rays are. */
    const as_stiff_case_t random_mesh[] = {AS_STIFF_SIGNED_ZERO, AS_STIFF_DYNAMIC_RANGE, AS_STIFF_DEGENERATE,
                                           AS_STIFF_FLAT, AS_STIFF_BAD_RAYS};
    const as_stiff_case_t random_rays[] = {AS_STIFF_QUAD_SEAM, AS_STIFF_GRAZING, AS_STIFF_PLANAR_ON_SPLIT};
    as_stiff_args_t a, b;
    as_stiff_args_default(&a);
    a.ray_count = 2000;
    b = a;
    b.seed = 1;
    for (int pass = 0; pass < 2; ++pass)
        for (int i = 0; i < (pass ? 3 : 5); ++i) {
            const as_stiff_case_t k = pass ? random_rays[i] : random_mesh[i];
            as_stiff_case_data_t x, y;
            if (generate(k, &a, &x) && generate(k, &b, &y)) {
                as_mesh_info_t ix, iy;
                as_mesh_get_info(x.mesh, &ix);
                as_mesh_get_info(y.mesh, &iy);
                if (pass) CHECK_EQ_U64(ix.hash, iy.hash);
                else CHECK(ix.hash != iy.hash);
                CHECK(x.ray_count == y.ray_count && memcmp(x.rays, y.rays, x.ray_count * sizeof *x.rays) != 0);
            }
            as_stiff_case_free(&x);
            as_stiff_case_free(&y);
        }
    /* The duplicates among others and the watertight meshes, moved. */
    a.duplicates_among_others = b.duplicates_among_others = true;
    as_stiff_case_data_t x, y;
    if (generate(AS_STIFF_DUPLICATES, &a, &x) && generate(AS_STIFF_DUPLICATES, &b, &y)) {
        as_mesh_info_t ix, iy;
        as_mesh_get_info(x.mesh, &ix);
        as_mesh_get_info(y.mesh, &iy);
        CHECK(ix.hash != iy.hash);
        CHECK_EQ_U64(ix.triangle_count, 10500);
    }
    as_stiff_case_free(&x);
    as_stiff_case_free(&y);
    as_stiff_args_default(&a);
    a.offset = 1e5; /* not a suite offset: the edge by the spacing rule */
    if (generate(AS_STIFF_WATERTIGHT_CUBE, &a, &x)) {
        as_mesh_info_t ix;
        as_mesh_get_info(x.mesh, &ix);
        CHECK(ix.bounds_lo[0] == 1e5f);
        CHECK(ix.bounds_hi[0] - ix.bounds_lo[0] == 6 * 2.0f); /* 256 x 2^-7 = 2 */
        CHECK_EQ_U64(x.ray_count, 20 * (uint64_t)ix.triangle_count);
    }
    as_stiff_case_free(&x);
}

int main(int argc, char **argv)
{
    if (argc > 1 && strcmp(argv[1], "--generator") == 0) {
        RUN_TEST(generator_defaults_are_the_suites);
        RUN_TEST(generator_refuses_bad_arguments);
        RUN_TEST(generator_gives_the_same_bytes_for_the_same_seed);
        RUN_TEST(generator_gives_other_meshes_for_another_seed);
        TEST_EXIT();
    }
    const char *only = NULL;
    const int rc = stiff_parse_variant(argc, argv, "test_stiff", &only);
    if (rc) {
        if (rc == 2) fprintf(stderr, "       test_stiff --generator\n");
        return rc;
    }
#define CASE(name, fn) if (!only || strcmp(only, name) == 0) RUN_TEST(fn)
    CASE("watertight", watertight_meshes_have_zero_leaks_far_from_the_origin);
    CASE("watertight_float", float_watertight_test_has_zero_leaks_too);
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
    CASE("surface_far", rays_leaving_a_sphere_far_from_the_origin_miss);
    CASE("bad_rays", bad_rays_miss_quickly);
#undef CASE
    TEST_EXIT();
}
