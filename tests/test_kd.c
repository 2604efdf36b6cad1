/* What the KD builders and layouts promise: byte-identical files whatever
 * the thread count, each recording the SAH cost its nodes give,
 * cancellation, sane trees on degenerate inputs (copies of
 * one triangle, a flat scene, quads lying on split planes), validation that
 * rejects damaged trees and ropes, and conversion kd-standard <-> kd-ropes
 * that keeps the tree bytes and round-trips to the same file; clipped
 * references' boxes that hold the exact clipped triangle, clipping's two
 * forms equal bit for bit, no division-by-zero or invalid flag raised, and
 * (SAH) a small node's plane chosen without event lists the same as the
 * sweep's.
 *
 *   test_kd BUILDER        (midcut | sah) */
#include "reference.h"
#include "test_util.h"
#include "structure.h"
#include "kd_layout.h"
#include "kd_build.h"

#include <fenv.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

static char tmpdir[256];
static as_builder_t builder;
static const char *builder_name;

static as_build_args_t kd_args(as_layout_t layout)
{
    as_build_args_t a;
    as_build_args_default(&a);
    a.structure = AS_STRUCT_KD;
    a.builder = builder;
    a.layout = layout;
    return a;
}

static as_mesh_t *soup(uint64_t seed, uint32_t n, float size)
{
    uint64_t st = seed;
    float *p = malloc(sizeof(float) * 9 * n);
    for (uint32_t t = 0; t < n; ++t) {
        float c[3];
        for (int k = 0; k < 3; ++k) c[k] = (float)ref_rand01(&st);
        for (int v = 0; v < 3; ++v)
            for (int k = 0; k < 3; ++k) p[9 * t + 3 * v + k] = c[k] + size * (float)(ref_rand01(&st) - 0.5);
    }
    return test_mesh_from_soup(p, n);
}

static void save(const as_structure_t *s, const char *path)
{
    CHECK(s != NULL);
    if (s) CHECK_EQ_INT(test_save_reproducible(s, path), AS_OK);
}

/* Two and three threads share the top nodes' axes; seven and sixteen take
 * their sweeps, event lists and partitions in pieces (more threads than this
 * machine may have cores: the pieces do not depend on the cores). */
static void build_is_byte_identical_for_1_2_3_7_16_threads(void)
{
    as_mesh_t *m = soup(7, 60000, 0.04f);
    const as_layout_t layouts[2] = {AS_LAYOUT_KD_STANDARD, AS_LAYOUT_KD_ROPES};
    const unsigned thread_counts[] = {1, 2, 3, 7, 16};
    for (int l = 0; l < 2; ++l) {
        char first[512];
        for (size_t t = 0; t < sizeof thread_counts / sizeof thread_counts[0]; ++t) {
            const unsigned threads = thread_counts[t];
            as_build_args_t a = kd_args(layouts[l]);
            a.thread_count = threads;
            as_structure_t *s = as_structure_build(m, &a);
            CHECK(s != NULL);
            if (!s) continue;
            /* The SAH cost the builder records (summed while writing the
             * tree) is the one its nodes give when computed again. */
            as_structure_stats_t st;
            CHECK_EQ_INT(as_structure_get_stats(s, &st), AS_OK);
            if (st.sah_cost != s->meta.sah_cost)
                fprintf(stderr, "  %u threads: SAH cost %.17g recorded, %.17g from the nodes\n", threads, s->meta.sah_cost,
                        st.sah_cost);
            CHECK(st.sah_cost == s->meta.sah_cost);
            char path[512];
            snprintf(path, sizeof path, "%s/threads%u.asf", tmpdir, threads);
            save(s, path);
            as_structure_release(s);
            if (threads == 1) { snprintf(first, sizeof first, "%s", path); continue; }
            if (!test_files_equal(first, path)) fprintf(stderr, "  %s: %u threads differ from 1\n", builder_name, threads);
            CHECK(test_files_equal(first, path));
            unlink(path);
        }
        unlink(first);
    }
    as_mesh_release(m);
}

static bool cancel_at_half(void *user, double fraction)
{
    ++*(int *)user;
    return fraction < 0.5;
}

static void progress_returning_false_cancels(void)
{
    as_mesh_t *m = soup(8, 20000, 0.05f);
    as_build_args_t a = kd_args(AS_LAYOUT_KD_STANDARD);
    int calls = 0;
    a.progress = cancel_at_half;
    a.progress_user = &calls;
    as_clear_error();
    as_structure_t *s = as_structure_build(m, &a);
    CHECK(s == NULL);
    CHECK_EQ_INT(as_get_error(), AS_ERROR_CANCELLED);
    CHECK(calls > 1);
    as_structure_release(s);
    as_mesh_release(m);
}

static as_hit_t trace1(const as_structure_t *s, const as_ray_t *ray)
{
    as_hit_t h;
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = AS_DEVICE_CPU;
    CHECK_EQ_INT(as_trace(s, ray, 1, &h, &ta, NULL), AS_OK);
    return h;
}

static void copies_of_one_triangle_stay_shallow_and_hit_the_lowest_index(void)
{
    const uint32_t copies = 10000;
    float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * copies);
    for (uint32_t i = 0; i < copies; ++i) { ix[3 * i] = 0; ix[3 * i + 1] = 1; ix[3 * i + 2] = 2; }
    as_mesh_t *m = as_mesh_create(3, p, copies, ix);
    free(ix);
    for (int l = 0; l < 2; ++l) {
        as_build_args_t a = kd_args(l ? AS_LAYOUT_KD_ROPES : AS_LAYOUT_KD_STANDARD);
        as_structure_t *s = as_structure_build(m, &a);
        CHECK(s != NULL);
        if (!s) continue;
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
        as_structure_stats_t st;
        CHECK_EQ_INT(as_structure_get_stats(s, &st), AS_OK);
        fprintf(stderr, "  %s: 10000 copies: %llu inner nodes, %llu leaves, depth %u, %llu references\n", builder_name,
                (unsigned long long)st.node_count, (unsigned long long)st.leaf_count, st.max_depth,
                (unsigned long long)st.reference_count);
        CHECK(st.max_depth <= AS_KD_MAX_DEPTH);
        CHECK(st.node_count <= copies);
        CHECK(st.reference_count <= (uint64_t)(4.0 * copies));
        const as_ray_t down = {{0.25f, 0.25f, 1.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY};
        const as_ray_t up = {{0.25f, 0.25f, -1.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, INFINITY};
        const as_hit_t h = trace1(s, &down), h2 = trace1(s, &up);
        CHECK_EQ_U64(h.prim, 0);
        CHECK(h.t == 1.0f);
        CHECK_EQ_U64(h2.prim, 0);
        as_structure_release(s);
    }
    as_mesh_release(m);
}

/* Checks a mesh's structure against the reference on the given rays. */
static void agree(const char *what, const as_mesh_t *m, const as_structure_t *s, const as_ray_t *rays, size_t n)
{
    ref_scene rs;
    CHECK(ref_scene_init(&rs, m));
    as_hit_t *hits = malloc(sizeof *hits * n);
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = AS_DEVICE_CPU;
    CHECK_EQ_INT(as_trace(s, rays, n, hits, &ta, NULL), AS_OK);
    size_t bad = 0, nhit = 0;
    for (size_t i = 0; i < n; ++i) {
        const ref_hit r = ref_trace(&rs, &rays[i]);
        nhit += r.prim != AS_NO_HIT;
        if (!ref_agrees(&rs, &rays[i], &r, &hits[i])) {
            if (bad < 3)
                fprintf(stderr, "  %s ray %zu: reference %u t %g, got %u t %g\n", what, i, r.prim, r.t, hits[i].prim,
                        (double)hits[i].t);
            ++bad;
        }
    }
    fprintf(stderr, "  %s %s: %zu rays, %zu hit, %zu disagree\n", builder_name, what, n, nhit, bad);
    CHECK(nhit > 0);
    CHECK_EQ_U64(bad, 0);
    free(hits);
    ref_scene_free(&rs);
}

static void a_flat_scene_builds_and_is_hit_from_both_sides(void)
{
    /* A 20 x 20 grid of triangles in the plane z = 0.5: the scene box has
     * zero thickness. */
    const int g = 20;
    float *p = malloc(sizeof(float) * 3 * (g + 1) * (g + 1));
    uint32_t *ix = malloc(sizeof(uint32_t) * 6 * g * g), nt = 0;
    for (int i = 0; i <= g; ++i)
        for (int j = 0; j <= g; ++j) {
            float *q = p + 3 * (i * (g + 1) + j);
            q[0] = (float)i; q[1] = (float)j; q[2] = 0.5f;
        }
    for (int i = 0; i < g; ++i)
        for (int j = 0; j < g; ++j) {
            const uint32_t a = (uint32_t)(i * (g + 1) + j), b = a + 1, c = a + (uint32_t)g + 1, d = c + 1;
            ix[3 * nt] = a; ix[3 * nt + 1] = c; ix[3 * nt + 2] = d; ++nt;
            ix[3 * nt] = a; ix[3 * nt + 1] = d; ix[3 * nt + 2] = b; ++nt;
        }
    as_mesh_t *m = as_mesh_create((uint32_t)((g + 1) * (g + 1)), p, nt, ix);
    free(p);
    free(ix);
    const size_t n = 4000;
    as_ray_t *rays = malloc(sizeof *rays * n);
    uint64_t st = 5;
    for (size_t i = 0; i < n; ++i) {
        as_ray_t *r = &rays[i];
        const int from_below = i & 1, on_lattice = (i >> 1) & 1;
        for (int k = 0; k < 2; ++k)
            r->org[k] = on_lattice ? (float)(ref_rand_u64(&st) % (2 * g + 1)) * 0.5f : (float)(ref_rand01(&st) * g);
        r->org[2] = from_below ? -1.0f : 2.0f;
        r->dir[0] = (i % 8) < 4 ? 0.0f : (float)(ref_rand01(&st) - 0.5) * 0.2f;
        r->dir[1] = (i % 8) < 4 ? 0.0f : (float)(ref_rand01(&st) - 0.5) * 0.2f;
        r->dir[2] = from_below ? 1.0f : -1.0f;
        r->tmin = 0.0f;
        r->tmax = INFINITY;
    }
    for (int l = 0; l < 2; ++l) {
        as_build_args_t a = kd_args(l ? AS_LAYOUT_KD_ROPES : AS_LAYOUT_KD_STANDARD);
        as_structure_t *s = as_structure_build(m, &a);
        CHECK(s != NULL);
        if (!s) continue;
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
        agree(l ? "flat scene (ropes)" : "flat scene", m, s, rays, n);
        as_structure_release(s);
    }
    free(rays);
    as_mesh_release(m);
}

static void quads_on_split_planes_are_hit_by_crossing_rays(void)
{
    /* Axis-aligned unit quads on the planes x = 0..8, y = 0..8, z = 0..8
     * (offset grids, so the mid-cut and SAH planes fall exactly on them),
     * crossed by rays in every direction, some along the planes. */
    const int n = 8;
    float *p = malloc(sizeof(float) * 3 * 4 * 3 * (n + 1) * 4);
    uint32_t *ix = malloc(sizeof(uint32_t) * 6 * 3 * (n + 1) * 4);
    uint32_t nv = 0, nt = 0;
    for (int axis = 0; axis < 3; ++axis)
        for (int k = 0; k <= n; ++k)
            for (int cell = 0; cell < 4; ++cell) {
                const float u0 = (float)(2 * (cell & 1) + 1), v0 = (float)(2 * (cell >> 1) + 2);
                const float uv[4][2] = {{u0, v0}, {u0 + 1, v0}, {u0 + 1, v0 + 1}, {u0, v0 + 1}};
                for (int c = 0; c < 4; ++c) {
                    float *q = p + 3 * (nv + c);
                    q[axis] = (float)k;
                    q[(axis + 1) % 3] = uv[c][0];
                    q[(axis + 2) % 3] = uv[c][1];
                }
                ix[3 * nt] = nv; ix[3 * nt + 1] = nv + 1; ix[3 * nt + 2] = nv + 2; ++nt;
                ix[3 * nt] = nv; ix[3 * nt + 1] = nv + 2; ix[3 * nt + 2] = nv + 3; ++nt;
                nv += 4;
            }
    as_mesh_t *m = as_mesh_create(nv, p, nt, ix);
    free(p);
    free(ix);
    const size_t count = 20000;
    as_ray_t *rays = malloc(sizeof *rays * count);
    uint64_t st = 9;
    for (size_t i = 0; i < count; ++i) {
        as_ray_t *r = &rays[i];
        for (int k = 0; k < 3; ++k) {
            /* Origins on the half-integer lattice: on planes, edges, corners. */
            r->org[k] = (float)(ref_rand_u64(&st) % 21) * 0.5f - 1.0f;
            const int kind = (int)(ref_rand_u64(&st) % 4);
            r->dir[k] = kind == 0 ? 0.0f : kind == 1 ? -0.0f : (float)(ref_rand01(&st) - 0.5);
        }
        if (r->dir[0] == 0 && r->dir[1] == 0 && r->dir[2] == 0) r->dir[i % 3] = 1.0f;
        r->tmin = 0.0f;
        r->tmax = INFINITY;
    }
    for (int l = 0; l < 2; ++l) {
        as_build_args_t a = kd_args(l ? AS_LAYOUT_KD_ROPES : AS_LAYOUT_KD_STANDARD);
        a.max_leaf_size = 1;
        as_structure_t *s = as_structure_build(m, &a);
        CHECK(s != NULL);
        if (!s) continue;
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
        agree(l ? "quads on split planes (ropes)" : "quads on split planes", m, s, rays, count);
        as_structure_release(s);
    }
    free(rays);
    as_mesh_release(m);
}

static void conversion_keeps_the_tree_and_round_trips_byte_for_byte(void)
{
    as_mesh_t *m = soup(11, 5000, 0.05f);
    as_build_args_t a = kd_args(AS_LAYOUT_KD_STANDARD);
    as_structure_t *std = as_structure_build(m, &a);
    a.layout = AS_LAYOUT_KD_ROPES;
    as_structure_t *built_ropes = as_structure_build(m, &a);
    CHECK(std && built_ropes);
    if (!std || !built_ropes) { as_mesh_release(m); return; }
    as_structure_t *ropes = as_structure_convert(std, AS_LAYOUT_KD_ROPES);
    CHECK(ropes != NULL);
    as_structure_t *back = ropes ? as_structure_convert(ropes, AS_LAYOUT_KD_STANDARD) : NULL;
    CHECK(back != NULL);
    char pa[512], pb[512], pc[512], pd[512];
    snprintf(pa, sizeof pa, "%s/std.asf", tmpdir);
    snprintf(pb, sizeof pb, "%s/ropes.asf", tmpdir);
    snprintf(pc, sizeof pc, "%s/back.asf", tmpdir);
    snprintf(pd, sizeof pd, "%s/built_ropes.asf", tmpdir);
    save(std, pa);
    save(ropes, pb);
    save(back, pc);
    save(built_ropes, pd);
    CHECK(test_files_equal(pa, pc));
    CHECK(test_files_equal(pb, pd));
    /* Converting a loaded file works the same way. */
    as_structure_t *loaded = as_structure_load(pb, NULL);
    CHECK(loaded != NULL);
    if (loaded) {
        CHECK_EQ_INT(as_structure_validate(loaded), AS_OK);
        as_structure_t *b2 = as_structure_convert(loaded, AS_LAYOUT_KD_STANDARD);
        save(b2, pc);
        CHECK(test_files_equal(pa, pc));
        as_structure_release(b2);
    }
    /* The tree bytes are shared. */
    const as_section_t *n1 = as_structure_find(std, ASF_TAG_KDN8), *n2 = ropes ? as_structure_find(ropes, ASF_TAG_KDN8) : NULL;
    CHECK(n1 && n2 && n1->bytes == n2->bytes && memcmp(n1->data, n2->data, n1->bytes) == 0);
    as_structure_stats_t s1, s2;
    CHECK_EQ_INT(as_structure_get_stats(std, &s1), AS_OK);
    if (ropes) CHECK_EQ_INT(as_structure_get_stats(ropes, &s2), AS_OK);
    CHECK(s1.sah_cost == s2.sah_cost && s1.sah_cost > 0);
    CHECK(s1.leaf_count > 0 && s1.node_count > 0 && s1.average_leaf_depth > 0);
    CHECK_EQ_INT(as_structure_convert(std, AS_LAYOUT_BVH2_CHILD_BOUNDS) == NULL, 1);
    unlink(pa); unlink(pb); unlink(pc); unlink(pd);
    as_structure_release(loaded);
    as_structure_release(std);
    as_structure_release(ropes);
    as_structure_release(back);
    as_structure_release(built_ropes);
    as_mesh_release(m);
}

/* Builds a rope structure, damages one value, and expects validation to
 * fail; then restores it. */
static void validation_rejects_damaged_trees_and_ropes(void)
{
    as_mesh_t *m = soup(12, 3000, 0.05f);
    as_build_args_t a = kd_args(AS_LAYOUT_KD_ROPES);
    as_structure_t *s = as_structure_build(m, &a);
    CHECK(s != NULL);
    if (!s) { as_mesh_release(m); return; }
    CHECK_EQ_INT(as_structure_validate(s), AS_OK);
    as_kd_node_t *nodes = (as_kd_node_t *)as_structure_find(s, ASF_TAG_KDN8)->owned;
    uint32_t *prim = (uint32_t *)as_structure_find(s, ASF_TAG_PRIM)->owned;
    as_kd_ropes_t *ropes = (as_kd_ropes_t *)as_structure_find(s, ASF_TAG_KDRP)->owned;
    as_kd_leaf_box_t *boxes = (as_kd_leaf_box_t *)as_structure_find(s, ASF_TAG_KDLB)->owned;
    as_tri4_t *tris = (as_tri4_t *)as_structure_find(s, ASF_TAG_TRIS)->owned;
    const uint64_t node_count = as_structure_find(s, ASF_TAG_KDN8)->count;
    uint32_t leaf = 0, inner = 0;
    for (uint32_t i = 0; i < node_count; ++i) {
        if (as_kd_is_leaf(nodes[i].word1)) { if (!leaf && prim[nodes[i].word0]) leaf = i; }
        else inner = i;
    }
    struct { const char *what; uint32_t *word; uint32_t value; } damage[] = {
        {"above child past the end", &nodes[0].word1, (((uint32_t)node_count + 5) << 2) | (nodes[0].word1 & 3)},
        {"above child pointing at the root", &nodes[inner].word1, (0u << 2) | (nodes[inner].word1 & 3)},
        {"split outside the node box", &nodes[0].word0, as_float_as_uint(1e9f)},
        {"split NaN", &nodes[0].word0, 0x7fc00000u},
        {"leaf list past PRIM", &nodes[leaf].word0, 0xfffffff0u},
        {"leaf count past PRIM", &prim[nodes[leaf].word0], 0x7fffffffu},
        {"triangle index past TRIS", &prim[nodes[leaf].word0 + 1], 1u << 30},
        {"duplicate leaf index", &nodes[leaf].word1, (0u << 2) | 3u},
        {"rope to another node", (uint32_t *)&ropes[1].rope[0], 0},
        {"rope past the end", (uint32_t *)&ropes[0].rope[1], 0x7ffffff0u},
        {"leaf box changed", (uint32_t *)&boxes[0].hi[0], as_float_as_uint(0.123f)},
        {"TRIS source index", (uint32_t *)&tris[3].v0.w, 4},
        {"TRIS NaN vertex", (uint32_t *)&tris[2].v1.y, 0x7fc00000u},
    };
    for (size_t k = 0; k < sizeof damage / sizeof damage[0]; ++k) {
        const uint32_t saved = *damage[k].word;
        if (saved == damage[k].value) continue;
        *damage[k].word = damage[k].value;
        const as_error_t err = as_structure_validate(s);
        if (err != AS_ERROR_INVALID_STRUCTURE) fprintf(stderr, "  %s: damage not detected: %s\n", builder_name, damage[k].what);
        CHECK_EQ_INT(err, AS_ERROR_INVALID_STRUCTURE);
        *damage[k].word = saved;
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
    }
    const uint64_t saved_nodes = s->meta.node_count;
    s->meta.node_count++;
    CHECK_EQ_INT(as_structure_validate(s), AS_ERROR_INVALID_STRUCTURE);
    s->meta.node_count = saved_nodes;
    s->meta.bounds_hi[0] = NAN;
    CHECK_EQ_INT(as_structure_validate(s), AS_ERROR_INVALID_STRUCTURE);
    as_structure_release(s);
    as_mesh_release(m);
}

static void depth_cap_and_split_budget_are_respected(void)
{
    as_mesh_t *m = soup(13, 20000, 0.2f);
    as_build_args_t a = kd_args(AS_LAYOUT_KD_STANDARD);
    a.max_depth = 5;
    a.max_leaf_size = 1;
    as_structure_t *s = as_structure_build(m, &a);
    as_structure_stats_t st;
    CHECK(s && as_structure_get_stats(s, &st) == AS_OK);
    if (s) CHECK(st.max_depth <= 5);
    as_structure_release(s);
    a.max_depth = 1000; /* capped at the stack */
    a.split_budget = 1.5f;
    s = as_structure_build(m, &a);
    CHECK(s && as_structure_get_stats(s, &st) == AS_OK);
    if (s) {
        fprintf(stderr, "  %s: budget 1.5: %llu references for 20000 triangles, depth %u\n", builder_name,
                (unsigned long long)st.reference_count, st.max_depth);
        CHECK(st.reference_count <= 30000);
        CHECK(st.max_depth <= AS_KD_MAX_DEPTH);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

static void a_single_triangle_and_an_all_degenerate_mesh_build_and_trace(void)
{
    const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t one[3] = {0, 1, 2}, degenerate[6] = {0, 0, 1, 0, 1, 1};
    as_mesh_t *m1 = as_mesh_create(3, p, 1, one), *m2 = as_mesh_create(3, p, 2, degenerate);
    CHECK(m1 && m2);
    for (int l = 0; l < 2; ++l) {
        as_build_args_t a = kd_args(l ? AS_LAYOUT_KD_ROPES : AS_LAYOUT_KD_STANDARD);
        as_structure_t *s1 = as_structure_build(m1, &a), *s2 = as_structure_build(m2, &a);
        CHECK(s1 && s2);
        if (!s1 || !s2) { as_structure_release(s1); as_structure_release(s2); continue; }
        CHECK_EQ_INT(as_structure_validate(s1), AS_OK);
        CHECK_EQ_INT(as_structure_validate(s2), AS_OK);
        const as_ray_t ray = {{0.2f, 0.2f, -1.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, INFINITY};
        const as_hit_t h1 = trace1(s1, &ray), h2 = trace1(s2, &ray);
        CHECK_EQ_U64(h1.prim, 0);
        CHECK(h1.t == 1.0f);
        CHECK_EQ_U64(h2.prim, AS_NO_HIT);
        as_structure_release(s1);
        as_structure_release(s2);
    }
    as_mesh_release(m1);
    as_mesh_release(m2);
}

/* A scene 2e-39 wide (subnormal floats) and flat: two triangles side by side
 * along x, each with a vertex at one end of the scene, the first ending at
 * x = 5e-40 and the second starting at 1.5e-39. A plane at either bound
 * leaves the triangle that touches it on both sides: one child of a quarter
 * of the box holds one triangle, the other of three quarters both, which
 * costs traversal + 1.75 intersections against two for a leaf. So with a
 * traversal cost of 0.1 the SAH builder splits; pricing the planes in
 * single precision must not lose them (the perimeter term, 1 / the width,
 * is beyond float's range). */
static void a_scene_thinner_than_floats_resolve_still_splits_where_it_pays(void)
{
    if (strcmp(builder_name, "sah") != 0) return;
    float *p = malloc(sizeof(float) * 18);
    const float v[18] = {0.0f, 0.0f, 0.0f, 5e-40f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f,
                         1.5e-39f, 0.0f, 0.0f, 2e-39f, 0.0f, 0.0f, 1.5e-39f, 1.0f, 0.0f};
    memcpy(p, v, sizeof v);
    as_mesh_t *m = test_mesh_from_soup(p, 2);
    CHECK(m != NULL);
    if (!m) return;
    as_build_args_t a = kd_args(AS_LAYOUT_KD_STANDARD);
    a.cost_traversal = 0.1f;
    a.cost_intersection = 1.0f;
    a.max_leaf_size = 1;
    as_structure_t *s = as_structure_build(m, &a);
    CHECK(s != NULL);
    if (s) {
        as_structure_stats_t st;
        CHECK_EQ_INT(as_structure_get_stats(s, &st), AS_OK);
        if (st.node_count < 1) fprintf(stderr, "  the root stayed a leaf\n");
        CHECK(st.node_count >= 1);
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
        as_structure_release(s);
    }
    as_mesh_release(m);
}

/* A bound for clipping's rounding: exactly a float, a float nudged by less
 * than its spacing either way (the conversion rounds the wrong way half the
 * time), a signed zero, a subnormal, a double too small for any float (it
 * rounds to a zero, then steps off it), or beyond the float range. */
static double clip_bound(uint64_t *st)
{
    const double u = ref_rand01(st), v = ref_rand01(st) * 2.0 - 1.0;
    const float f = (float)(v * (u < 0.5 ? 10.0 : 1e-3));
    const int kind = (int)(ref_rand01(st) * 9.0);
    switch (kind) {
    case 0: return f;
    case 1: return (double)f + (double)f * 1e-9;
    case 2: return (double)f - (double)f * 1e-9;
    case 3: return ref_rand01(st) < 0.5 ? 0.0 : -0.0;
    case 4: return v * 1e-40;
    case 5: return v * 1e39;
    case 6: return v * 1e-50;
    default: return v * 4.0;
    }
}

static float clip_coord(uint64_t *st)
{
    const double r = ref_rand01(st);
    if (r < 0.1) return ref_rand01(st) < 0.5 ? 0.0f : -0.0f;
    if (r < 0.15) return ref_rand01(st) < 0.5 ? INFINITY : -INFINITY;
    return (float)(ref_rand01(st) * 8.0 - 4.0);
}

/* The clipped reference's box comes from one of two forms of one function:
 * four lanes at once where the compiler targets SSE2, plain C elsewhere.
 * Both must give the same bits, or a tree would depend on the machine. */
static void clipped_reference_forms_agree_bit_for_bit(void)
{
#if defined(__SSE2__)
    uint64_t st = 99;
    int differ = 0;
    for (int i = 0; i < 200000; ++i) {
        kd_ref old;
        float box[6];
        double lo[3], hi[3];
        for (int k = 0; k < 3; ++k) {
            old.lo[k] = clip_coord(&st);
            old.hi[k] = ref_rand01(&st) < 0.2 ? old.lo[k] : clip_coord(&st);
            box[k] = clip_coord(&st);
            box[k + 3] = ref_rand01(&st) < 0.2 ? box[k] : clip_coord(&st);
            lo[k] = clip_bound(&st);
            hi[k] = ref_rand01(&st) < 0.2 ? lo[k] : clip_bound(&st);
        }
        old.id = (uint32_t)i;
        const int empty = ref_rand01(&st) < 0.05;
        kd_ref a, b;
        kd_clipped_ref_plain(&old, box, empty ? NULL : lo, hi, &a);
        kd_clipped_ref_sse2(&old, box, empty ? NULL : lo, hi, &b);
        if (memcmp(&a, &b, sizeof a) != 0 && differ++ < 3)
            fprintf(stderr, "  case %d: plain (%a %a %a)-(%a %a %a), sse2 (%a %a %a)-(%a %a %a)\n", i, a.lo[0], a.lo[1],
                    a.lo[2], a.hi[0], a.hi[1], a.hi[2], b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2]);
    }
    CHECK_EQ_INT(differ, 0);
#endif
}

/* The triangle clipped to box, exactly enough to judge a float box: in
 * long double (64-bit significands), Sutherland-Hodgman plane by plane.
 * Returns the polygon's vertex count. */
static int clip_exactly(const long double tri[3][3], const float box[6], long double out[12][3])
{
    long double a[12][3], b[12][3];
    int n = 3;
    memcpy(a, tri, sizeof(long double) * 9);
    for (int plane = 0; plane < 6 && n > 0; ++plane) {
        const int axis = plane % 3, upper = plane >= 3;
        const long double bound = box[plane];
        int m = 0;
        for (int i = 0; i < n; ++i) {
            const long double *p = a[i], *q = a[(i + 1) % n];
            const long double dp = upper ? bound - p[axis] : p[axis] - bound, dq = upper ? bound - q[axis] : q[axis] - bound;
            if (dp >= 0) memcpy(b[m++], p, sizeof(long double) * 3);
            if ((dp > 0 && dq < 0) || (dp < 0 && dq > 0)) {
                const long double s = dp / (dp - dq);
                for (int k = 0; k < 3; ++k) b[m][k] = p[k] + s * (q[k] - p[k]);
                b[m++][axis] = bound;
            }
        }
        n = m;
        memcpy(a, b, sizeof(long double) * 3 * (size_t)n);
    }
    memcpy(out, a, sizeof(long double) * 3 * (size_t)n);
    return n;
}

/* Counts the vertices of triangle tri clipped to box that lie outside r's
 * box by more than tol. */
static int outside_reference(const long double tri[3][3], const float box[6], const kd_ref *r, long double tol)
{
    long double poly[12][3];
    const int n = clip_exactly(tri, box, poly);
    int outside = 0;
    for (int i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k) outside += poly[i][k] < (long double)r->lo[k] - tol || poly[i][k] > (long double)r->hi[k] + tol;
    return outside;
}

/* A box face for clipped_boxes_hold_the_exact_clipped_triangle: through a
 * vertex, one float beside one, or anywhere in the triangle's range. */
static float face_near(const float v[3][3], int k, double off, double scale, uint64_t *st)
{
    const float at = v[(int)(ref_rand01(st) * 3) % 3][k];
    const double r = ref_rand01(st);
    if (r < 0.3) return at;
    if (r < 0.5) return nextafterf(at, ref_rand01(st) < 0.5 ? -INFINITY : INFINITY);
    return (float)(off + scale * (2.0 * ref_rand01(st) - 1.0));
}

/* A reference's box must hold every point of its triangle inside the node:
 * a point left out is a part of the triangle that rays in that cell miss.
 * The boxes are checked against the clip computed in long double, on
 * triangles with an edge in an axis plane, of 1e-3 size, and 500 away from
 * the origin, in boxes whose faces pass through vertices or one float
 * beside them, and split at planes through vertices: where the double
 * precision clip's rounding is closest to the float the box keeps. Only the
 * long double clip's own rounding (a few units in its last place) is
 * allowed; a box rounded to the nearest float instead of outwards fails on
 * more than half the cases. */
static void clipped_boxes_hold_the_exact_clipped_triangle(void)
{
    uint64_t st = 2027;
    long cases = 0, outside = 0, forms_differ = 0;
    for (int c = 0; c < 300000; ++c) {
        const int mode = c % 4;
        const double off = mode == 3 ? 1000.0 * (ref_rand01(&st) - 0.5) : 0.0, scale = mode == 2 ? 1e-3 : 1.0;
        float v[3][3];
        for (int i = 0; i < 3; ++i)
            for (int k = 0; k < 3; ++k) v[i][k] = (float)(off + scale * (2.0 * ref_rand01(&st) - 1.0));
        if (mode == 1) {
            const int k = (int)(ref_rand01(&st) * 3) % 3;
            v[1][k] = v[0][k];
        }
        as_tri4_t t;
        memset(&t, 0, sizeof t);
        as_f4_t *const tv[3] = {&t.v0, &t.v1, &t.v2};
        long double tri[3][3];
        for (int i = 0; i < 3; ++i) {
            tv[i]->x = v[i][0];
            tv[i]->y = v[i][1];
            tv[i]->z = v[i][2];
            for (int k = 0; k < 3; ++k) tri[i][k] = v[i][k];
        }
        float box[6];
        double mag = 0.0;
        for (int k = 0; k < 3; ++k) {
            float a = face_near(v, k, off, scale, &st), b = face_near(v, k, off, scale, &st);
            if (a > b) {
                const float x = a;
                a = b;
                b = x;
            }
            box[k] = a;
            box[k + 3] = b;
            for (int i = 0; i < 3; ++i) mag = fmax(mag, fabs((double)v[i][k]));
            mag = fmax(mag, fmax(fabs((double)a), fabs((double)b)));
        }
        const long double tol = 4e-19L * (long double)mag;
        kd_ref whole, in_box, child[2];
        for (int k = 0; k < 3; ++k) {
            whole.lo[k] = -INFINITY;
            whole.hi[k] = INFINITY;
        }
        whole.id = 0;
        kd_clip_reference(&t, &whole, box, &in_box);
        outside += outside_reference(tri, box, &in_box, tol);
        kd_ref in_box_portable;
        kd_clip_reference_portable(&t, &whole, box, &in_box_portable);
        forms_differ += memcmp(&in_box, &in_box_portable, sizeof in_box) != 0;
        /* A split through a vertex, or anywhere, inside the box. */
        const int axis = (int)(ref_rand01(&st) * 3) % 3;
        float pos = ref_rand01(&st) < 0.5 ? v[(int)(ref_rand01(&st) * 3) % 3][axis]
                                           : box[axis] + (float)ref_rand01(&st) * (box[axis + 3] - box[axis]);
        if (!(pos > box[axis] && pos < box[axis + 3])) continue;
        kd_clip_reference_split(&t, &in_box, box, axis, pos, child);
        /* The build's forms (AVX2 where the processor has it) and the
         * portable ones give the same bits. */
        kd_ref portable[2];
        kd_clip_reference_split_portable(&t, &in_box, box, axis, pos, portable);
        forms_differ += memcmp(child, portable, sizeof child) != 0;
        float half[2][6];
        memcpy(half[0], box, sizeof half[0]);
        memcpy(half[1], box, sizeof half[1]);
        half[0][axis + 3] = pos;
        half[1][axis] = pos;
        for (int s = 0; s < 2; ++s) outside += outside_reference(tri, half[s], &child[s], tol);
        ++cases;
    }
    if (outside) fprintf(stderr, "  %ld clipped vertices outside their reference's box\n", outside);
    if (forms_differ) fprintf(stderr, "  %ld clips differ between the build's and the portable forms\n", forms_differ);
    CHECK_EQ_INT(outside, 0);
    CHECK_EQ_INT(forms_differ, 0);
    CHECK(cases > 100000);
}

/* Clipping divides only where an edge crosses a plane: a build leaves the
 * caller's floating-point flags for division by zero and invalid operations
 * as they were (a host that traps them would stop). Axis-aligned triangles
 * have edges parallel to most split planes. */
static void a_build_raises_no_division_by_zero_or_invalid_flag(void)
{
    const uint32_t n = 3000;
    float *p = malloc(sizeof(float) * 9 * n);
    uint64_t st = 31;
    for (uint32_t t = 0; t < n; ++t) {
        const int axis = (int)(t % 3), u = (axis + 1) % 3, v = (axis + 2) % 3;
        float c[3];
        for (int k = 0; k < 3; ++k) c[k] = (float)ref_rand01(&st);
        const float du = 0.05f * (float)ref_rand01(&st) + 0.01f, dv = 0.05f * (float)ref_rand01(&st) + 0.01f;
        for (int k = 0; k < 9; ++k) p[9 * t + k] = c[k % 3];
        p[9 * t + 3 + u] += du;
        p[9 * t + 6 + v] += dv;
    }
    as_mesh_t *m = test_mesh_from_soup(p, n);
    as_build_args_t a = kd_args(AS_LAYOUT_KD_STANDARD);
    a.thread_count = 1;
    feclearexcept(FE_ALL_EXCEPT);
    as_structure_t *s = as_structure_build(m, &a);
    const int raised = fetestexcept(FE_DIVBYZERO | FE_INVALID);
    CHECK(s != NULL);
    if (raised) fprintf(stderr, "  raised:%s%s\n", raised & FE_DIVBYZERO ? " division by zero" : "", raised & FE_INVALID ? " invalid" : "");
    CHECK_EQ_INT(raised, 0);
    as_structure_release(s);
    as_mesh_release(m);
}

/* A grid value in [lo, hi] (multiples of 1/4), zero half the time as -0. */
static float grid_value(uint64_t *st, float lo, float hi)
{
    const int a = (int)(lo * 4.0f), b = (int)(hi * 4.0f);
    const float v = (float)(a + (int)(ref_rand01(st) * (b - a + 1) * 0.9999)) * 0.25f;
    return v == 0.0f && ref_rand01(st) < 0.5 ? -0.0f : v;
}

static void small_nodes_choose_the_sweeps_plane(void)
{
    if (builder != AS_BUILDER_KD_SAH) return;
    /* Traversal and intersection costs; a traversal cost of 0 makes the
     * sweep price every plane exactly. */
    static const float costs[][2] = {{1, 1}, {0.1f, 1}, {3, 1}, {1, 2.5f}, {0, 1}};
    uint64_t st = 2024;
    long split = 0, leaf = 0, differ = 0;
    for (int it = 0; it < 60000; ++it) {
        as_build_args_t a = kd_args(AS_LAYOUT_KD_STANDARD);
        a.thread_count = 1;
        a.cost_traversal = costs[it % 5][0];
        a.cost_intersection = costs[it % 5][1];
        /* Up to the largest node without event lists (64 references). */
        const uint32_t n = 1 + (uint32_t)(ref_rand01(&st) * 63.999);
        /* Boxes on a coarse grid, so that bounds coincide, lie on the
         * faces and tie; some flat along an axis, some crossing zero. */
        float box[6];
        for (int k = 0; k < 3; ++k) {
            box[k] = -0.25f * (float)(int)(ref_rand01(&st) * 8.0);
            box[k + 3] = ref_rand01(&st) < 0.04 ? box[k] : 0.25f * (float)(1 + (int)(ref_rand01(&st) * 8.0));
        }
        kd_ref refs[64];
        uint32_t id = 0;
        for (uint32_t i = 0; i < n; ++i) {
            id += 1 + (uint32_t)(ref_rand01(&st) * 3.0);
            refs[i].id = id;
            for (int k = 0; k < 3; ++k) {
                float l = grid_value(&st, box[k], box[k + 3]), h = grid_value(&st, box[k], box[k + 3]);
                if (h < l) { const float t = l; l = h; h = t; }
                if (ref_rand01(&st) < 0.2) h = l;                      /* flat along the axis */
                if (ref_rand01(&st) < 0.15) l = box[k];                /* on a face */
                if (ref_rand01(&st) < 0.15) h = box[k + 3];
                /* A float off a grid value: planes one step apart. */
                if (ref_rand01(&st) < 0.1) l = ref_rand01(&st) < 0.5 ? as_float_next_up(l) : as_float_next_down(l);
                if (ref_rand01(&st) < 0.1) h = ref_rand01(&st) < 0.5 ? as_float_next_up(h) : as_float_next_down(h);
                l = l < box[k] ? box[k] : l > box[k + 3] ? box[k + 3] : l;
                h = h < box[k] ? box[k] : h > box[k + 3] ? box[k + 3] : h;
                if (h < l) h = l;
                refs[i].lo[k] = l;
                refs[i].hi[k] = h;
            }
        }
        /* The chooser as the build runs it here (AVX2 where the processor
         * has it), in its SSE2 form and in its plain one, each against the
         * sweep. */
        kd_split swept;
        memset(&swept, 0, sizeof swept);
        const int r0 = kd_sah_choose_plane(&a, refs, n, box, KD_CHOOSE_SWEEP, &swept);
        static const int forms[3] = {KD_CHOOSE_SMALL, KD_CHOOSE_SMALL_SSE2, KD_CHOOSE_SMALL_PLAIN};
        static const char *const form_names[3] = {"built", "SSE2", "plain"};
        for (int f = 0; f < 3; ++f) {
            kd_split counted;
            memset(&counted, 0, sizeof counted);
            const int r1 = kd_sah_choose_plane(&a, refs, n, box, forms[f], &counted);
            int same = r0 == r1 && r0 >= 0;
            if (same && r0 == 1)
                same = swept.axis == counted.axis && memcmp(&swept.pos, &counted.pos, sizeof swept.pos) == 0 &&
                       swept.planar_left == counted.planar_left && swept.count[0] == counted.count[0] &&
                       swept.count[1] == counted.count[1];
            if (!same && differ++ < 5)
                fprintf(stderr, "  node %d (%u refs), %s form: sweep %d axis %d at %a below %d (%u, %u); counted %d axis %d at %a below %d (%u, %u)\n",
                        it, n, form_names[f], r0, swept.axis, swept.pos, swept.planar_left, swept.count[0],
                        swept.count[1], r1, counted.axis, counted.pos, counted.planar_left, counted.count[0],
                        counted.count[1]);
        }
        split += r0 == 1;
        leaf += r0 == 0;
    }
    printf("  %ld nodes split, %ld leaves, %ld differ\n", split, leaf, differ);
    CHECK(split > 10000 && leaf > 1000);
    CHECK_EQ_INT(differ, 0);
}

int main(int argc, char **argv)
{
    if (argc < 2) { fprintf(stderr, "usage: %s midcut|sah\n", argv[0]); return 2; }
    builder_name = argv[1];
    builder = as_builder_from_name(AS_STRUCT_KD, argv[1]);
    if (!builder) return 2;
    snprintf(tmpdir, sizeof tmpdir, "/tmp/as_test_kd_XXXXXX");
    if (!mkdtemp(tmpdir)) return 1;
    RUN_TEST(build_is_byte_identical_for_1_2_3_7_16_threads);
    RUN_TEST(progress_returning_false_cancels);
    RUN_TEST(copies_of_one_triangle_stay_shallow_and_hit_the_lowest_index);
    RUN_TEST(a_flat_scene_builds_and_is_hit_from_both_sides);
    RUN_TEST(quads_on_split_planes_are_hit_by_crossing_rays);
    RUN_TEST(conversion_keeps_the_tree_and_round_trips_byte_for_byte);
    RUN_TEST(validation_rejects_damaged_trees_and_ropes);
    RUN_TEST(depth_cap_and_split_budget_are_respected);
    RUN_TEST(a_single_triangle_and_an_all_degenerate_mesh_build_and_trace);
    RUN_TEST(a_scene_thinner_than_floats_resolve_still_splits_where_it_pays);
    RUN_TEST(clipped_reference_forms_agree_bit_for_bit);
    RUN_TEST(clipped_boxes_hold_the_exact_clipped_triangle);
    RUN_TEST(a_build_raises_no_division_by_zero_or_invalid_flag);
    RUN_TEST(small_nodes_choose_the_sweeps_plane);
    rmdir(tmpdir);
    TEST_EXIT();
}
