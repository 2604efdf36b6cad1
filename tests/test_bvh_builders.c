/* What the mid-cut, sweep and SBVH builders, the own-bounds layout and the
 * compressed wide BVH promise, for one builder and layout per run:
 *
 *   test_bvh_builders BUILDER LAYOUT
 *
 * byte-identical files for 1, 2 and 3 threads, and for 1, 2 and 7 on a
 * lopsided tree; cancellation; 10,000 copies of one triangle; a flat scene;
 * axis-aligned quads on split planes; validation of damaged copies; the
 * layout round trip (child-bounds -> own-bounds -> child-bounds gives the
 * same bytes, both give the same hits; the wide BVH: the same bytes from
 * either binary layout, the same hits); and the SAH cost against the binned
 * build on bunny.drc. */
#include "reference.h"
#include "test_util.h"
#include "structure.h"
#include "bvh2_own_layout.h"
#include "cwbvh_layout.h"

#include <math.h>
#include <stdio.h>

static as_build_args_t variant;
static char tmpdir[256];

static as_structure_t *build(const as_mesh_t *m, unsigned threads)
{
    as_build_args_t args = variant;
    args.thread_count = threads;
    as_structure_t *s = as_structure_build(m, &args);
    if (!s) fprintf(stderr, "  build failed: %s\n", as_get_error_message());
    return s;
}

static as_hit_t trace1(const as_structure_t *s, const as_ray_t *ray)
{
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = AS_DEVICE_CPU;
    as_hit_t hit;
    memset(&hit, 0, sizeof hit);
    CHECK_EQ_INT(as_trace(s, ray, 1, &hit, &ta, NULL), AS_OK);
    return hit;
}

/* Small random triangles, many of them: subtrees go to several threads. */
static as_mesh_t *small_triangle_soup(uint32_t n, uint64_t seed)
{
    float *p = malloc(sizeof(float) * 9 * n);
    uint64_t st = seed;
    for (uint32_t i = 0; i < n; ++i) {
        float c[3];
        for (int k = 0; k < 3; ++k) c[k] = (float)ref_rand01(&st);
        for (int v = 0; v < 3; ++v)
            for (int k = 0; k < 3; ++k) p[9 * i + 3 * v + k] = c[k] + 0.02f * (float)(ref_rand01(&st) - 0.5);
    }
    return test_mesh_from_soup(p, n);
}

/* Builds `m` with each of the three thread counts (the first is 1) and
 * checks that every file equals the first byte for byte; with `check_sah`,
 * also that the SAH cost recorded in each file equals the cost computed
 * again from its nodes. */
static void expect_same_file_for_thread_counts(as_mesh_t *m, const char *name, const unsigned threads[3],
                                               bool check_sah)
{
    char first[512];
    snprintf(first, sizeof first, "%s/%s%u.asf", tmpdir, name, threads[0]);
    for (size_t t = 0; t < 3; ++t) {
        as_structure_t *s = build(m, threads[t]);
        CHECK(s != NULL);
        if (!s) continue;
        if (check_sah && variant.layout == AS_LAYOUT_BVH2_CHILD_BOUNDS) {
            const double again = as_bvh2_sah_cost(s);
            if (again != s->meta.sah_cost)
                fprintf(stderr, "  %u threads: SAH cost %.17g in the file, %.17g from the nodes\n", threads[t],
                        s->meta.sah_cost, again);
            CHECK(again == s->meta.sah_cost);
        }
        char path[512];
        snprintf(path, sizeof path, "%s/%s%u.asf", tmpdir, name, threads[t]);
        CHECK_EQ_INT(test_save_reproducible(s, path), AS_OK);
        as_structure_release(s);
        if (t > 0) {
            CHECK(test_files_equal(first, path));
            unlink(path);
        }
    }
    unlink(first);
}

static void build_is_byte_identical_for_1_2_and_3_threads(void)
{
    as_mesh_t *m = small_triangle_soup(120000, 11);
    CHECK(m != NULL);
    const unsigned threads[] = {1, 2, 3};
    expect_same_file_for_thread_counts(m, "threads", threads, false);
    as_mesh_release(m);
}

/* A dense cluster of small triangles beside a sparse row of larger ones
 * and a few that span the whole scene: a lopsided tree, whose output walk
 * meets subtrees of very different sizes at many depths, with leaves among
 * them near the root. */
static as_mesh_t *lopsided_scene(uint64_t seed)
{
    const uint32_t dense = 40000, sparse = 3000, spanning = 8, n = dense + sparse + spanning;
    float *p = malloc(sizeof(float) * 9 * n);
    uint64_t st = seed;
    for (uint32_t i = 0; i < n; ++i) {
        float c[3], size;
        if (i < dense) {
            for (int k = 0; k < 3; ++k) c[k] = 0.01f * (float)ref_rand01(&st);
            size = 0.0005f;
        } else if (i < dense + sparse) {
            c[0] = 100.0f * (float)ref_rand01(&st);
            c[1] = c[2] = (float)ref_rand01(&st);
            size = 0.1f;
        } else {
            for (int k = 0; k < 3; ++k) c[k] = 50.0f;
            size = 100.0f;
        }
        for (int v = 0; v < 3; ++v)
            for (int k = 0; k < 3; ++k) p[9 * i + 3 * v + k] = c[k] + size * (float)(ref_rand01(&st) - 0.5);
    }
    return test_mesh_from_soup(p, n);
}

/* The output walk is split among threads by subtree sizes: 7 threads cut
 * it finer than 2. The SAH cost recorded in the file is summed in one
 * walk's order, so it equals the cost computed again from the file. */
static void a_lopsided_tree_is_byte_identical_for_1_2_and_7_threads(void)
{
    as_mesh_t *m = lopsided_scene(5);
    CHECK(m != NULL);
    const unsigned threads[] = {1, 2, 7};
    expect_same_file_for_thread_counts(m, "lopsided", threads, true);
    as_mesh_release(m);
}

static bool cancel_at_half(void *user, double fraction)
{
    int *calls = user;
    ++*calls;
    return fraction < 0.5;
}

static void progress_callback_returning_false_cancels_the_build(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(m != NULL);
    as_build_args_t args = variant;
    int calls = 0;
    args.progress = cancel_at_half;
    args.progress_user = &calls;
    as_clear_error();
    as_structure_t *s = as_structure_build(m, &args);
    CHECK(s == NULL);
    CHECK_EQ_INT(as_get_error(), AS_ERROR_CANCELLED);
    CHECK(calls > 1);
    as_structure_release(s);
    as_mesh_release(m);
}

static void copies_of_one_triangle_stay_shallow_and_hit_the_lowest_index(void)
{
    const uint32_t copies = 10000;
    const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * copies);
    for (uint32_t i = 0; i < copies; ++i) { ix[3 * i] = 0; ix[3 * i + 1] = 1; ix[3 * i + 2] = 2; }
    as_mesh_t *m = as_mesh_create(3, p, copies, ix);
    free(ix);
    as_structure_t *s = build(m, 0);
    CHECK(s != NULL);
    if (s) {
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
        as_structure_stats_t st;
        CHECK_EQ_INT(as_structure_get_stats(s, &st), AS_OK);
        CHECK(st.max_depth < 64);
        /* Linear in N: an SBVH may add references within its budget. */
        CHECK(st.node_count <= (uint64_t)(variant.split_budget + 1.0f) * copies);
        CHECK(st.reference_count <= (uint64_t)(variant.split_budget + 1.0f) * copies);
        fprintf(stderr, "  %u copies: %llu inner nodes, max depth %u, %llu references\n", copies,
                (unsigned long long)st.node_count, st.max_depth, (unsigned long long)st.reference_count);
        const as_ray_t ray = {{0.25f, 0.25f, 1.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY};
        const as_hit_t hit = trace1(s, &ray);
        CHECK_EQ_U64(hit.prim, 0);
        CHECK(hit.t == 1.0f);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

static void the_depth_cap_argument_is_honoured(void)
{
    as_mesh_t *m = small_triangle_soup(5000, 3);
    as_build_args_t args = variant;
    args.max_depth = 6;
    as_structure_t *s = as_structure_build(m, &args);
    CHECK(s != NULL);
    if (s) {
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
        as_structure_stats_t st;
        CHECK_EQ_INT(as_structure_get_stats(s, &st), AS_OK);
        CHECK(st.max_depth <= 6);
        CHECK_EQ_INT(s->meta.max_depth_limit, 6);
        const as_ray_t ray = {{0.5f, 0.5f, -1.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, INFINITY};
        (void)trace1(s, &ray);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

static void a_flat_scene_builds_and_is_hit_from_both_sides(void)
{
    /* A 64 x 64 grid of quads in the plane z = 0.5: a zero-thickness box. */
    const uint32_t g = 64;
    float *p = malloc(sizeof(float) * 3 * (g + 1) * (g + 1));
    uint32_t *ix = malloc(sizeof(uint32_t) * 6 * g * g);
    for (uint32_t y = 0; y <= g; ++y)
        for (uint32_t x = 0; x <= g; ++x) {
            float *v = p + 3 * (y * (g + 1) + x);
            v[0] = (float)x; v[1] = (float)y; v[2] = 0.5f;
        }
    for (uint32_t y = 0; y < g; ++y)
        for (uint32_t x = 0; x < g; ++x) {
            uint32_t *t = ix + 6 * (y * g + x);
            const uint32_t a = y * (g + 1) + x, b = a + 1, c = a + g + 1, d = c + 1;
            t[0] = a; t[1] = b; t[2] = d; t[3] = a; t[4] = d; t[5] = c;
        }
    as_mesh_t *m = as_mesh_create((g + 1) * (g + 1), p, 2 * g * g, ix);
    free(p);
    free(ix);
    as_structure_t *s = build(m, 0);
    CHECK(s != NULL);
    if (s) {
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
        uint64_t st = 5;
        int bad = 0;
        for (int i = 0; i < 2000; ++i) {
            const uint32_t cx = (uint32_t)(ref_rand01(&st) * g), cy = (uint32_t)(ref_rand01(&st) * g);
            /* A point well inside the lower-right triangle (x > y in the cell). */
            const float px = (float)cx + 0.7f, py = (float)cy + 0.2f;
            const uint32_t want = 2 * (cy * g + cx);
            const float dz = (i & 1) ? 1.0f : -1.0f;
            const as_ray_t ray = {{px, py, 0.5f - 2.0f * dz}, 0.0f, {0.0f, 0.0f, dz}, INFINITY};
            const as_hit_t h = trace1(s, &ray);
            if (h.prim != want || h.t != 2.0f) ++bad;
        }
        fprintf(stderr, "  flat scene: 2000 rays from both sides, %d wrong\n", bad);
        CHECK_EQ_INT(bad, 0);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

static void quads_on_split_planes_are_hit_by_crossing_rays(void)
{
    /* Unit quads at x = 0..15 (integer planes, where median and SAH cuts
     * fall), two triangles each; rays along +x from x = k + 0.5 hit quad k+1. */
    const uint32_t q = 16;
    float p[16 * 4 * 3];
    uint32_t ix[16 * 6];
    for (uint32_t k = 0; k < q; ++k) {
        const float v[4][3] = {{(float)k, 0, 0}, {(float)k, 1, 0}, {(float)k, 1, 1}, {(float)k, 0, 1}};
        memcpy(p + 12 * k, v, sizeof v);
        const uint32_t t[6] = {4 * k, 4 * k + 1, 4 * k + 2, 4 * k, 4 * k + 2, 4 * k + 3};
        memcpy(ix + 6 * k, t, sizeof t);
    }
    as_mesh_t *m = as_mesh_create(4 * q, p, 2 * q, ix);
    as_structure_t *s = build(m, 0);
    CHECK(s != NULL);
    if (s) {
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
        int bad = 0;
        for (uint32_t k = 0; k + 1 < q; ++k) {
            /* (0.25, 0.75) lies in the quad's second triangle, (0.75, 0.25) in its first. */
            const as_ray_t r1 = {{(float)k + 0.5f, 0.75f, 0.25f}, 0.0f, {1, 0, 0}, INFINITY};
            const as_ray_t r2 = {{(float)k + 0.5f, 0.25f, 0.75f}, 0.0f, {1, 0, 0}, INFINITY};
            const as_hit_t h1 = trace1(s, &r1), h2 = trace1(s, &r2);
            if (h1.t != 0.5f || h1.prim / 2 != k + 1) ++bad;
            if (h2.t != 0.5f || h2.prim / 2 != k + 1) ++bad;
            /* Backwards, from the plane itself: tmin 0 hits the quad the origin lies on. */
            const as_ray_t r3 = {{(float)(k + 1), 0.5f, 0.3f}, 0.0f, {-1, 0, 0}, INFINITY};
            const as_hit_t h3 = trace1(s, &r3);
            if (h3.t != 0.0f || h3.prim / 2 != k + 1) ++bad;
        }
        fprintf(stderr, "  quads on split planes: %u rays, %d wrong\n", 3 * (q - 1), bad);
        CHECK_EQ_INT(bad, 0);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

/* An owned copy whose sections the test may damage. */
static as_structure_t *damageable_copy(const as_structure_t *s)
{
    as_structure_t *d = as_structure_convert(s, (as_layout_t)s->meta.layout);
    CHECK(d != NULL);
    return d;
}

static void *section_bytes(as_structure_t *s, uint32_t tag)
{
    for (uint32_t i = 0; i < s->section_count; ++i)
        if (s->sections[i].tag == tag) return s->sections[i].owned;
    return NULL;
}

static void expect_invalid(as_structure_t *d, const char *what)
{
    as_clear_error();
    const as_error_t err = as_structure_validate(d);
    fprintf(stderr, "  damaged (%s): %s\n", what, as_get_error_message());
    CHECK_EQ_INT(err, AS_ERROR_INVALID_STRUCTURE);
    as_structure_release(d);
}

static void validation_rejects_damaged_copies(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(m != NULL);
    as_structure_t *s = build(m, 0);
    CHECK(s != NULL);
    if (!s) { as_mesh_release(m); return; }
    CHECK_EQ_INT(as_structure_validate(s), AS_OK);
    as_structure_t *d;
    if (s->meta.layout == AS_LAYOUT_BVH_CWBVH) {
        as_cwbvh_node_t *n;
        const uint32_t nn = (uint32_t)s->meta.node_count;
        /* A leaf slot of a node, and one of its inner slots, to damage. */
        uint32_t li = 0, ls = 0, is = 0;
        const as_cwbvh_node_t *sn = s->sections[0].data;
        for (uint32_t i = 0; i < nn && !li; ++i)
            for (uint32_t k = 0; k < 8; ++k)
                if (sn[i].meta[k] && !as_cwbvh_meta_is_inner(sn[i].meta[k]) && sn[i].qhi[0][k] < 200) { li = i; ls = k; break; }
        while (!((sn[0].imask >> is) & 1)) ++is;
        CHECK(li > 0);
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[0].child_base = 0;
        expect_invalid(d, "root is its own child");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[0].child_base += 1;
        expect_invalid(d, "children shifted by one: a node referenced twice or unreachable");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[0].child_base = nn - 1;
        expect_invalid(d, "children past the end");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[li].tri_base = 0x7fffffffu;
        expect_invalid(d, "leaf past TRI4");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[li].imask |= (uint8_t)(1u << ls);
        expect_invalid(d, "imask bit on a leaf slot");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[li].meta[ls] = (uint8_t)(0xA0u | (n[li].meta[ls] & 31u));
        expect_invalid(d, "a leaf count that is not unary");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[0].meta[is] = AS_CWBVH_META_INNER((is + 1) % 8);
        expect_invalid(d, "an inner slot's meta names another slot");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[li].e[1] = 255;
        expect_invalid(d, "exponent out of range");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[li].e[2] = 0;
        expect_invalid(d, "zero exponent");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[li].p[1] = NAN;
        expect_invalid(d, "NaN origin");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[li].qlo[0][ls] = n[li].qhi[0][ls] = 255;
        expect_invalid(d, "a leaf's box moved off its triangles");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[0].qlo[0][is] = n[0].qhi[0][is] = 255;
        expect_invalid(d, "an inner child's box moved off what lies below");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[li].qlo[1][ls] = 200; n[li].qhi[1][ls] = 100;
        expect_invalid(d, "inverted quantized box");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_CWBV); n[0].e[0] = 254; n[0].p[0] = 3e38f;
        expect_invalid(d, "decoded box overflows to infinity");
    } else if (s->meta.layout == AS_LAYOUT_BVH2_OWN_BOUNDS) {
        as_bvh2o_node_t *n;
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_BVHO); n[0].child = 0;
        expect_invalid(d, "root is its own child");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_BVHO);
        for (uint32_t i = 1;; ++i) if (n[i].child >= 0) { n[i].child = n[0].child; break; }
        expect_invalid(d, "a subtree referenced twice");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_BVHO);
        for (uint32_t i = 1;; ++i) if (n[i].child < 0) { n[i].count = 1u << 30; break; }
        expect_invalid(d, "leaf count past TRI4");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_BVHO); n[5].hi[1] = NAN;
        expect_invalid(d, "NaN box");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_BVHO); n[0].child = (int32_t)d->sections[0].count - 1;
        expect_invalid(d, "children past the end");
    } else {
        as_bvh2_node_t *n;
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_BVH2);
        for (uint32_t i = 0;; ++i) if (n[i].child[1] >= 0) { n[i].child[1] = 0; break; }
        expect_invalid(d, "child points at the root");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_BVH2);
        for (uint32_t i = 0;; ++i) if (n[i].child[0] < 0 && n[i].count[0] > 0) { n[i].count[0] += 100000000u; break; }
        expect_invalid(d, "leaf count past TRI4");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_BVH2);
        {
            /* Two leaves sharing TRI4 entries. */
            int32_t first_leaf = 0;
            for (uint32_t i = 0;; ++i)
                if (n[i].child[0] < 0 && n[i].count[0] > 0) {
                    if (!first_leaf) first_leaf = n[i].child[0];
                    else if (n[i].child[0] != first_leaf) { n[i].child[0] = first_leaf; break; }
                }
        }
        expect_invalid(d, "TRI4 entries in two leaves");
        d = damageable_copy(s); n = section_bytes(d, ASF_TAG_BVH2); n[3].xy1.z = INFINITY;
        expect_invalid(d, "infinite box");
    }
    d = damageable_copy(s); as_tri4_t *t = section_bytes(d, ASF_TAG_TRI4); t[7].v0.w = as_uint_as_float(m->triangle_count);
    expect_invalid(d, "source index past the mesh");
    d = damageable_copy(s); t = section_bytes(d, ASF_TAG_TRI4); t[9].v0.x += 1000.0f; t[9].v1.x += 1000.0f; t[9].v2.x += 1000.0f;
    expect_invalid(d, "triangle outside its leaf");
    d = damageable_copy(s); d->meta.leaf_count += 1;
    expect_invalid(d, "META leaf count");
    d = damageable_copy(s); d->meta.max_depth += 1;
    expect_invalid(d, "META max depth");
    as_structure_release(s);
    as_mesh_release(m);
}

/* `n` rays of the mesh traced through x and y on the CPU, closest and any
 * hit: how many answers differ. Closest hits are compared field for field
 * with `whole_hit`, else by triangle and distance; any hits by hit or miss. */
static size_t hits_differ(const as_mesh_t *m, const as_structure_t *x, const as_structure_t *y, size_t n,
                          int whole_hit)
{
    as_ray_t *rays = malloc(sizeof *rays * n);
    as_hit_t *hx = malloc(sizeof *hx * n), *hy = malloc(sizeof *hy * n);
    ref_make_scene_rays(m, n, 99, rays);
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = AS_DEVICE_CPU;
    size_t differ = 0;
    for (int any = 0; any < 2; ++any) {
        ta.any_hit = any;
        CHECK_EQ_INT(as_trace(x, rays, n, hx, &ta, NULL), AS_OK);
        CHECK_EQ_INT(as_trace(y, rays, n, hy, &ta, NULL), AS_OK);
        for (size_t i = 0; i < n; ++i) {
            if (any) differ += (hx[i].prim == AS_NO_HIT) != (hy[i].prim == AS_NO_HIT);
            else if (whole_hit) differ += memcmp(&hx[i], &hy[i], sizeof hx[i]) != 0;
            else differ += hx[i].prim != hy[i].prim || hx[i].t != hy[i].t;
        }
    }
    free(rays);
    free(hx);
    free(hy);
    return differ;
}

static void layouts_convert_both_ways_to_the_same_bytes_and_hits(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(m != NULL);
    as_build_args_t args = variant;
    args.layout = AS_LAYOUT_BVH2_CHILD_BOUNDS;
    as_structure_t *a = as_structure_build(m, &args);
    CHECK(a != NULL);
    if (!a) { as_mesh_release(m); return; }
    char pa[512], pb[512], pc[512];
    snprintf(pa, sizeof pa, "%s/child.asf", tmpdir);
    snprintf(pb, sizeof pb, "%s/own.asf", tmpdir);
    snprintf(pc, sizeof pc, "%s/child_again.asf", tmpdir);
    CHECK_EQ_INT(as_structure_save(a, pa, NULL), AS_OK);
    as_structure_t *la = as_structure_load(pa, NULL);
    as_structure_t *b = la ? as_structure_convert(la, AS_LAYOUT_BVH2_OWN_BOUNDS) : NULL;
    CHECK(b != NULL);
    if (b) {
        CHECK_EQ_INT(as_structure_validate(b), AS_OK);
        CHECK_EQ_INT(as_structure_save(b, pb, NULL), AS_OK);
        as_structure_t *lb = as_structure_load(pb, NULL);
        CHECK(lb != NULL);
        as_structure_t *c = lb ? as_structure_convert(lb, AS_LAYOUT_BVH2_CHILD_BOUNDS) : NULL;
        CHECK(c != NULL);
        if (c) {
            CHECK_EQ_INT(as_structure_save(c, pc, NULL), AS_OK);
            CHECK(test_files_equal(pa, pc));
        }
        /* Both layouts: the same hits, field for field. */
        const size_t n = 20000, differ = hits_differ(m, la, lb, n, 1);
        fprintf(stderr, "  child-bounds vs own-bounds: %zu rays closest and any hit, %zu differ\n", n, differ);
        CHECK_EQ_U64(differ, 0);
        as_structure_stats_t sa, sb;
        CHECK_EQ_INT(as_structure_get_stats(la, &sa), AS_OK);
        CHECK_EQ_INT(as_structure_get_stats(lb, &sb), AS_OK);
        CHECK_EQ_U64(sa.node_count, sb.node_count);
        CHECK_EQ_U64(sa.leaf_count, sb.leaf_count);
        CHECK_EQ_INT(sa.max_depth, sb.max_depth);
        CHECK(fabs(sa.sah_cost - sb.sah_cost) <= 1e-9 * sa.sah_cost);
        as_structure_release(c);
        as_structure_release(lb);
    }
    unlink(pa); unlink(pb); unlink(pc);
    as_structure_release(b);
    as_structure_release(la);
    as_structure_release(a);
    as_mesh_release(m);
}

/* A BVH2 file of either layout collapses into the same wide BVH, which
 * gives the binary tree's hits; nothing converts back. */
static void the_wide_bvh_comes_from_either_binary_layout_with_the_same_hits(void)
{
    if (variant.layout != AS_LAYOUT_BVH_CWBVH) return;
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(m != NULL);
    as_build_args_t args = variant;
    args.layout = AS_LAYOUT_BVH2_CHILD_BOUNDS;
    as_structure_t *bin = as_structure_build(m, &args);
    args.layout = AS_LAYOUT_BVH2_OWN_BOUNDS;
    as_structure_t *own = as_structure_build(m, &args);
    CHECK(bin && own);
    as_structure_t *a = bin ? as_structure_convert(bin, AS_LAYOUT_BVH_CWBVH) : NULL;
    as_structure_t *b = own ? as_structure_convert(own, AS_LAYOUT_BVH_CWBVH) : NULL;
    CHECK(a && b);
    if (a && b) {
        char pa[512], pb[512];
        snprintf(pa, sizeof pa, "%s/wide_a.asf", tmpdir);
        snprintf(pb, sizeof pb, "%s/wide_b.asf", tmpdir);
        as_save_args_t sa;
        as_save_args_default(&sa);
        sa.omit_build_record = true;
        CHECK_EQ_INT(as_structure_save(a, pa, &sa), AS_OK);
        CHECK_EQ_INT(as_structure_save(b, pb, &sa), AS_OK);
        CHECK(test_files_equal(pa, pb));
        unlink(pa); unlink(pb);
        CHECK_EQ_INT(as_structure_validate(a), AS_OK);
        as_clear_error();
        CHECK(as_structure_convert(a, AS_LAYOUT_BVH2_CHILD_BOUNDS) == NULL);
        CHECK_EQ_INT(as_get_error(), AS_ERROR_UNSUPPORTED);
        as_structure_stats_t sb, sw;
        CHECK_EQ_INT(as_structure_get_stats(bin, &sb), AS_OK);
        CHECK_EQ_INT(as_structure_get_stats(a, &sw), AS_OK);
        uint64_t big = 0;
        for (int k = AS_CWBVH_MAX_LEAF + 1; k < AS_HISTOGRAM_BINS; ++k) big += sw.leaf_size_histogram[k];
        CHECK_EQ_U64(big, 0);
        CHECK_EQ_U64(sw.reference_count, sb.reference_count);
        CHECK(sw.node_count < sb.node_count / 2);
        fprintf(stderr, "  bunny.drc: BVH2 %llu nodes, %llu leaves, SAH %.3f; wide %llu nodes, %llu leaves, SAH %.3f, "
                "%.2f children per node\n", (unsigned long long)sb.node_count, (unsigned long long)sb.leaf_count,
                sb.sah_cost, (unsigned long long)sw.node_count, (unsigned long long)sw.leaf_count, sw.sah_cost,
                (double)(sw.node_count - 1 + sw.leaf_count) / (double)sw.node_count);
        const size_t n = 20000, differ = hits_differ(m, bin, a, n, 0);
        fprintf(stderr, "  child-bounds vs cwbvh: %zu rays closest and any hit, %zu differ\n", n, differ);
        CHECK_EQ_U64(differ, 0);
    }
    as_structure_release(a);
    as_structure_release(b);
    as_structure_release(bin);
    as_structure_release(own);
    as_mesh_release(m);
}

static void sah_cost_is_printed_against_the_binned_build(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(m != NULL);
    as_build_args_t binned;
    as_build_args_default(&binned);
    as_structure_t *a = as_structure_build(m, &binned), *s = build(m, 0);
    CHECK(a && s);
    if (a && s) {
        fprintf(stderr, "  bunny.drc SAH cost: binned %.3f, %s %.3f (%llu references for %u triangles)\n",
                a->meta.sah_cost, as_builder_name((as_builder_t)s->meta.builder), s->meta.sah_cost,
                (unsigned long long)s->meta.reference_count, m->triangle_count);
        if (variant.builder == AS_BUILDER_BVH_SBVH || variant.builder == AS_BUILDER_BVH_SAH_SWEEP)
            CHECK(s->meta.sah_cost < a->meta.sah_cost);
    }
    as_structure_release(a);
    as_structure_release(s);
    as_mesh_release(m);
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: %s BUILDER LAYOUT\n", argv[0]);
        return 2;
    }
    as_build_args_default(&variant);
    variant.structure = AS_STRUCT_BVH;
    variant.builder = as_builder_from_name(AS_STRUCT_BVH, argv[1]);
    variant.layout = as_layout_from_name(argv[2]);
    if (!variant.builder || !variant.layout) {
        fprintf(stderr, "unknown builder %s or layout %s\n", argv[1], argv[2]);
        return 2;
    }
    snprintf(tmpdir, sizeof tmpdir, "/tmp/as_test_bvhb_XXXXXX");
    if (!mkdtemp(tmpdir)) return 1;
    RUN_TEST(build_is_byte_identical_for_1_2_and_3_threads);
    RUN_TEST(a_lopsided_tree_is_byte_identical_for_1_2_and_7_threads);
    RUN_TEST(progress_callback_returning_false_cancels_the_build);
    RUN_TEST(copies_of_one_triangle_stay_shallow_and_hit_the_lowest_index);
    RUN_TEST(the_depth_cap_argument_is_honoured);
    RUN_TEST(a_flat_scene_builds_and_is_hit_from_both_sides);
    RUN_TEST(quads_on_split_planes_are_hit_by_crossing_rays);
    RUN_TEST(validation_rejects_damaged_copies);
    RUN_TEST(layouts_convert_both_ways_to_the_same_bytes_and_hits);
    RUN_TEST(the_wide_bvh_comes_from_either_binary_layout_with_the_same_hits);
    RUN_TEST(sah_cost_is_printed_against_the_binned_build);
    rmdir(tmpdir);
    TEST_EXIT();
}
