/* What the BIH, octree and grid builders promise, one structure per run:
 *
 *   test_misc_build bih|octree|grid
 *
 * byte-identical files for 1, 2, 3 and 16 threads, each recording the SAH
 * cost its nodes give; cancellation; 10,000 copies
 * of one triangle (depth within the cap, nodes linear in N, the lowest index
 * hit); a small dense cluster in a large scene subdivided; a flat scene hit from both sides; quads lying exactly on split
 * planes and cell walls; zero-area triangles left out; the reference budget;
 * the grid's cells those of testing every cell of a triangle's box;
 * validation rejecting damaged files. */
#include "reference.h"
#include "test_util.h"

#include "asf_format.h"
#include "bih_layout.h"
#include "bvh2_layout.h"
#include "grid_layout.h"
#include "mesh.h"
#include "octree_layout.h"
#include "spatial_common.h"
#include "structure.h"

#include <math.h>
#include <stdio.h>

static as_structure_kind_t kind;
static const char *kind_name;
static char tmpdir[256];

static void args_for(as_build_args_t *args)
{
    as_build_args_default(args);
    args->structure = kind;
}

/* Triangles of about `size` around random points of the unit cube; every
 * `big_every`-th one (0: none) `big_scale` times larger. */
static as_mesh_t *soup_scaled(uint64_t seed, uint32_t n, float size, uint32_t big_every, float big_scale)
{
    uint64_t st = seed;
    float *p = malloc(sizeof(float) * 9 * n);
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * n);
    for (uint32_t t = 0; t < n; ++t) {
        float c[3];
        for (int k = 0; k < 3; ++k) c[k] = (float)ref_rand01(&st);
        const float sz = big_every && t % big_every == 0 ? big_scale * size : size;
        for (int v = 0; v < 9; ++v) p[9 * t + v] = c[v % 3] + sz * (float)(ref_rand01(&st) - 0.5);
        for (int v = 0; v < 3; ++v) ix[3 * t + v] = 3 * t + v;
    }
    as_mesh_t *m = as_mesh_create(3 * n, p, n, ix);
    free(p);
    free(ix);
    return m;
}

static as_mesh_t *soup_mixed(uint64_t seed, uint32_t n, float size, uint32_t big_every)
{
    return soup_scaled(seed, n, size, big_every, 30.0f);
}

static as_mesh_t *soup(uint64_t seed, uint32_t n, float size) { return soup_mixed(seed, n, size, 0); }

static as_hit_t *trace(const as_structure_t *s, const as_ray_t *rays, size_t n, int any_hit)
{
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = AS_DEVICE_CPU;
    ta.any_hit = any_hit;
    as_hit_t *hits = malloc(sizeof *hits * (n ? n : 1));
    CHECK_EQ_INT(as_trace(s, rays, n, hits, &ta, NULL), AS_OK);
    return hits;
}

/* Closest and any hit against the double-precision reference. */
static size_t disagreements(const as_mesh_t *m, const as_structure_t *s, const as_ray_t *rays, size_t n)
{
    ref_scene rs = {0};
    CHECK(ref_scene_init(&rs, m));
    as_hit_t *hits = trace(s, rays, n, 0), *any = trace(s, rays, n, 1);
    size_t bad = 0;
    for (size_t i = 0; i < n; ++i) {
        const ref_hit r = ref_trace(&rs, &rays[i]);
        const int ok = ref_agrees(&rs, &rays[i], &r, &hits[i]) && (r.prim != AS_NO_HIT) == (any[i].prim != AS_NO_HIT);
        if (!ok && bad < 3)
            fprintf(stderr, "  ray %zu: reference prim %u t %.9g, closest %u t %.9g, any %u\n", i, r.prim, r.t, hits[i].prim,
                    (double)hits[i].t, any[i].prim);
        bad += !ok;
    }
    free(hits);
    free(any);
    ref_scene_free(&rs);
    return bad;
}

static void build_is_byte_identical_for_1_2_3_and_16_threads(void)
{
    /* The third: one triangle in 500 a hundred times larger, whose boxes
     * reach tens of thousands of grid cells (from four threads the grid's
     * first pass cuts such triangles into slabs and their blocks into
     * runs). */
    as_mesh_t *meshes[3] = {soup(7, 60000, 0.02f), NULL, soup_scaled(11, 60000, 0.02f, 500, 100.0f)};
    char buf[4096];
    snprintf(buf, sizeof buf, "%s/scenes/bunny.drc", AS_SOURCE_DIR);
    meshes[1] = as_mesh_import(buf);
    CHECK(meshes[0] && meshes[1] && meshes[2]);
    /* Sixteen threads: more ranges of grid cells than three make. */
    const unsigned threads[] = {1, 2, 3, 16};
    for (int k = 0; k < 3; ++k) {
        unsigned char *first = NULL;
        size_t first_size = 0;
        for (size_t t = 0; t < sizeof threads / sizeof threads[0] && meshes[k]; ++t) {
            as_build_args_t args;
            args_for(&args);
            args.thread_count = threads[t];
            as_structure_t *s = as_structure_build(meshes[k], &args);
            CHECK(s != NULL);
            if (!s) continue;
            /* The SAH cost the builder records is the one its nodes give
             * when computed again (the BIH sums it while writing the tree). */
            as_structure_stats_t st;
            CHECK_EQ_INT(as_structure_get_stats(s, &st), AS_OK);
            if (st.sah_cost != s->meta.sah_cost)
                fprintf(stderr, "  %u threads: SAH cost %.17g recorded, %.17g from the nodes\n", threads[t],
                        s->meta.sah_cost, st.sah_cost);
            CHECK(st.sah_cost == s->meta.sah_cost);
            char path[512];
            snprintf(path, sizeof path, "%s/threads%u.asf", tmpdir, threads[t]);
            CHECK_EQ_INT(test_save_reproducible(s, path), AS_OK);
            as_structure_release(s);
            unsigned char *data = NULL;
            size_t size = 0;
            CHECK(test_read_file(path, &data, &size));
            unlink(path);
            if (!first) { first = data; first_size = size; continue; }
            CHECK_EQ_U64(size, first_size);
            CHECK(size == first_size && memcmp(data, first, size) == 0);
            free(data);
        }
        free(first);
        as_mesh_release(meshes[k]);
    }
}

static bool cancel_at_once(void *user, double fraction)
{
    (void)fraction;
    ++*(int *)user;
    return false;
}

static void progress_callback_returning_false_cancels_the_build(void)
{
    as_mesh_t *m = soup(9, 30000, 0.02f);
    as_build_args_t args;
    args_for(&args);
    int calls = 0;
    args.progress = cancel_at_once;
    args.progress_user = &calls;
    as_clear_error();
    as_structure_t *s = as_structure_build(m, &args);
    CHECK(s == NULL);
    CHECK_EQ_INT(as_get_error(), AS_ERROR_CANCELLED);
    CHECK(calls >= 1);
    as_structure_release(s);
    as_mesh_release(m);
}

static void copies_of_one_triangle_stay_shallow_and_hit_the_lowest_index(void)
{
    const uint32_t counts[] = {2, 100, 10000};
    for (size_t k = 0; k < 3; ++k) {
        const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
        uint32_t *ix = malloc(sizeof(uint32_t) * 3 * counts[k]);
        for (uint32_t i = 0; i < counts[k]; ++i) { ix[3 * i] = 0; ix[3 * i + 1] = 1; ix[3 * i + 2] = 2; }
        as_mesh_t *m = as_mesh_create(3, p, counts[k], ix);
        free(ix);
        as_build_args_t args;
        args_for(&args);
        as_structure_t *s = as_structure_build(m, &args);
        CHECK(s != NULL);
        if (s) {
            CHECK_EQ_INT(as_structure_validate(s), AS_OK);
            as_structure_stats_t st;
            CHECK_EQ_INT(as_structure_get_stats(s, &st), AS_OK);
            const uint32_t cap = kind == AS_STRUCT_BIH ? AS_BIH_MAX_DEPTH : AS_OCTREE_MAX_DEPTH;
            CHECK(st.max_depth <= cap);
            CHECK(st.node_count <= counts[k]);
            CHECK(st.reference_count <= 4ull * counts[k]);
            const as_ray_t rays[2] = {{{0.25f, 0.25f, 1.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY},
                                      {{0.25f, 0.25f, -1.0f}, 0.0f, {0.0f, -0.0f, 1.0f}, INFINITY}};
            as_hit_t *h = trace(s, rays, 2, 0);
            for (int r = 0; r < 2; ++r) {
                CHECK_EQ_U64(h[r].prim, 0);
                CHECK(h[r].t == 1.0f);
            }
            free(h);
        }
        as_structure_release(s);
        as_mesh_release(m);
    }
}

/* 2,000 small triangles in the unit cube at one corner of a scene 100 wide
 * (one more triangle at the far corner): the structure must still separate
 * them. In the octree, the cell around the cluster at level 1 holds it all
 * in one child; splitting it costs no reference and must go on, so no leaf
 * keeps 64 or more of them; BIH likewise. A uniform grid cannot adapt (its
 * cells are sized for the whole scene: the teapot in a stadium), so for it
 * only the answers are checked. Rays from around the cluster agree with the
 * reference. */
static void a_small_dense_cluster_in_a_large_scene_is_subdivided(void)
{
    uint64_t st = 11;
    const uint32_t n = 2001;
    float *p = malloc(sizeof(float) * 9 * n);
    for (uint32_t t = 0; t < n; ++t) {
        float c[3];
        for (int k = 0; k < 3; ++k) c[k] = t + 1 < n ? (float)ref_rand01(&st) : 99.5f;
        for (int v = 0; v < 9; ++v) p[9 * t + v] = c[v % 3] + 0.02f * (float)(ref_rand01(&st) - 0.5);
    }
    as_mesh_t *m = test_mesh_from_soup(p, n);
    as_build_args_t args;
    args_for(&args);
    as_structure_t *s = as_structure_build(m, &args);
    CHECK(s != NULL);
    if (s) {
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
        as_structure_stats_t sst;
        CHECK_EQ_INT(as_structure_get_stats(s, &sst), AS_OK);
        if (kind != AS_STRUCT_GRID) {
            CHECK_EQ_U64(sst.leaf_size_histogram[AS_HISTOGRAM_BINS - 1], 0);
            CHECK(sst.average_leaf_size < 16.0);
        }
        /* Rays from random points around the cluster in random directions. */
        as_ray_t *rays = malloc(sizeof *rays * 4000);
        for (size_t i = 0; i < 4000; ++i) {
            for (int k = 0; k < 3; ++k) rays[i].org[k] = (float)(3.0 * ref_rand01(&st) - 1.0);
            ref_random_direction(&st, rays[i].dir);
            rays[i].tmin = 0.0f;
            rays[i].tmax = INFINITY;
        }
        CHECK_EQ_U64(disagreements(m, s, rays, 4000), 0);
        free(rays);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

/* Random triangles all in the plane z = 0.5: a zero-thickness box. */
static void a_flat_scene_builds_and_is_hit_from_both_sides(void)
{
    uint64_t st = 5;
    const uint32_t n = 3000;
    float *p = malloc(sizeof(float) * 9 * n);
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * n);
    for (uint32_t t = 0; t < n; ++t) {
        const float cx = (float)ref_rand01(&st), cy = (float)ref_rand01(&st);
        for (int v = 0; v < 3; ++v) {
            p[9 * t + 3 * v] = cx + 0.05f * (float)(ref_rand01(&st) - 0.5);
            p[9 * t + 3 * v + 1] = cy + 0.05f * (float)(ref_rand01(&st) - 0.5);
            p[9 * t + 3 * v + 2] = 0.5f;
            ix[3 * t + v] = 3 * t + v;
        }
    }
    as_mesh_t *m = as_mesh_create(3 * n, p, n, ix);
    free(p);
    free(ix);
    as_build_args_t args;
    args_for(&args);
    as_structure_t *s = as_structure_build(m, &args);
    CHECK(s != NULL);
    if (s) {
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
        as_structure_stats_t sst;
        CHECK_EQ_INT(as_structure_get_stats(s, &sst), AS_OK);
        if (kind == AS_STRUCT_GRID) CHECK_EQ_U64(sst.grid_dims[2], 1);
        const size_t nr = 4000;
        as_ray_t *rays = malloc(sizeof *rays * nr);
        for (size_t i = 0; i < nr; ++i) {
            const int above = i & 1;
            as_ray_t *r = &rays[i];
            r->org[0] = (float)ref_rand01(&st);
            r->org[1] = (float)ref_rand01(&st);
            r->org[2] = above ? 2.0f : -1.0f;
            r->dir[0] = 0.3f * (float)(ref_rand01(&st) - 0.5);
            r->dir[1] = 0.3f * (float)(ref_rand01(&st) - 0.5);
            r->dir[2] = above ? -1.0f : 1.0f;
            if (i % 4 < 2) r->dir[0] = r->dir[1] = (i % 8 < 4) ? 0.0f : -0.0f; /* straight down or up */
            r->tmin = 0.0f;
            r->tmax = INFINITY;
        }
        as_hit_t *h = trace(s, rays, nr, 0);
        size_t hits[2] = {0, 0};
        for (size_t i = 0; i < nr; ++i) hits[i & 1] += h[i].prim != AS_NO_HIT;
        fprintf(stderr, "  %s flat scene: %zu hits from below, %zu from above of %zu rays each\n", kind_name, hits[0], hits[1], nr / 2);
        CHECK(hits[0] > nr / 8 && hits[1] > nr / 8);
        CHECK_EQ_U64(disagreements(m, s, rays, nr), 0);
        free(h);
        free(rays);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

/* Axis-aligned unit quads at x = k / 8 (k = 0..8) over [0,1]^2 in y and z:
 * every one lies on a plane a midpoint split, an octree level or a grid wall
 * can choose. Rays along +x and -x (and slanted) must hit the first quad. */
static void quads_on_split_planes_are_hit_by_crossing_rays(void)
{
    const int planes = 9;
    float p[9 * 4 * 3];
    uint32_t ix[9 * 6];
    for (int q = 0; q < planes; ++q) {
        const float x = q / 8.0f;
        const float c[4][3] = {{x, 0, 0}, {x, 1, 0}, {x, 1, 1}, {x, 0, 1}};
        for (int v = 0; v < 4; ++v)
            for (int k = 0; k < 3; ++k) p[12 * q + 3 * v + k] = c[v][k];
        const uint32_t b = 4 * (uint32_t)q;
        const uint32_t t[6] = {b, b + 1, b + 2, b, b + 2, b + 3};
        memcpy(ix + 6 * q, t, sizeof t);
    }
    as_mesh_t *m = as_mesh_create(4 * planes, p, 2 * planes, ix);
    as_build_args_t args;
    args_for(&args);
    args.max_leaf_size = 1;
    as_structure_t *s = as_structure_build(m, &args);
    CHECK(s != NULL);
    if (s) {
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
        const int g = 17;
        const size_t nr = (size_t)g * g * 4;
        as_ray_t *rays = malloc(sizeof *rays * nr);
        size_t k = 0;
        for (int a = 0; a < g; ++a)
            for (int b = 0; b < g; ++b)
                for (int d = 0; d < 4; ++d) {
                    as_ray_t *r = &rays[k++];
                    r->org[0] = (d & 1) ? 2.0f : -1.0f;
                    r->org[1] = a / 16.0f;
                    r->org[2] = b / 16.0f;
                    r->dir[0] = (d & 1) ? -1.0f : 1.0f;
                    r->dir[1] = (d & 2) ? 0.0f : -0.0f;
                    r->dir[2] = 0.0f;
                    r->tmin = 0.0f;
                    r->tmax = INFINITY;
                }
        as_hit_t *h = trace(s, rays, nr, 0);
        size_t missed = 0;
        for (size_t i = 0; i < nr; ++i) {
            const int backwards = i & 1;
            missed += h[i].prim == AS_NO_HIT || h[i].t != 1.0f || (h[i].prim / 2) != (uint32_t)(backwards ? planes - 1 : 0);
        }
        fprintf(stderr, "  %s quads on split planes: %zu rays, %zu miss or hit the wrong quad\n", kind_name, nr, missed);
        CHECK_EQ_U64(missed, 0);
        CHECK_EQ_U64(disagreements(m, s, rays, nr), 0);
        free(h);
        free(rays);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

static void zero_area_triangles_are_left_out(void)
{
    const float p[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 0, 0};
    const uint32_t ix[9] = {0, 1, 3, 0, 1, 2, 1, 1, 2}; /* collinear, real, repeated index */
    as_mesh_t *m = as_mesh_create(4, p, 3, ix);
    as_build_args_t args;
    args_for(&args);
    as_structure_t *s = as_structure_build(m, &args);
    CHECK(s != NULL);
    if (s) {
        as_structure_stats_t st;
        CHECK_EQ_INT(as_structure_get_stats(s, &st), AS_OK);
        CHECK(st.reference_count >= 1);
        const as_ray_t ray = {{0.2f, 0.2f, 1.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY};
        as_hit_t *h = trace(s, &ray, 1, 0);
        CHECK_EQ_U64(h->prim, 1);
        free(h);
        /* Only triangle 1 is referenced, however often. */
        char path[512];
        snprintf(path, sizeof path, "%s/degenerate.asf", tmpdir);
        CHECK_EQ_INT(as_structure_save(s, path, NULL), AS_OK);
        unsigned char *data = NULL;
        size_t size = 0;
        CHECK(test_read_file(path, &data, &size));
        unlink(path);
        for (uint32_t i = 0; i < as_structure_section_count(s); ++i) {
            as_structure_t *f = as_structure_load_memory(data, size, "degenerate.asf", NULL);
            as_section_info_t info;
            CHECK_EQ_INT(as_structure_section_info(f, i, &info), AS_OK);
            if (strcmp(info.tag, "PRIM") == 0) {
                const uint32_t *prims = (const uint32_t *)(data + info.offset);
                for (uint64_t j = 0; j < info.element_count; ++j) CHECK_EQ_U64(prims[j], 1);
            }
            as_structure_release(f);
        }
        free(data);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

/* The grid's rule, tested cell by cell: a triangle is in every cell of its
 * box (grown by four pads of the grid box) that as_tri_box_overlap accepts,
 * every cell when its box is within one, and nowhere else. The builder
 * tests only the cells a large slanted triangle's plane can reach; this
 * tests them all. */
static float grid_wall(const as_grid_header_t *g, int k, uint32_t i)
{
    return i >= g->dims[k] ? g->hi[k] : g->lo[k] + (float)i * g->cell[k];
}

static uint32_t grid_cell_of(const as_grid_header_t *g, int k, double x)
{
    const double f = (x - g->lo[k]) * g->inv_cell[k];
    if (!(f > 0)) return 0;
    if (f >= g->dims[k]) return g->dims[k] - 1;
    return (uint32_t)f;
}

static size_t grid_cells_differing(const as_mesh_t *m, const as_structure_t *s)
{
    const as_grid_header_t *g = as_structure_find(s, ASF_TAG_GRDH)->data;
    const uint32_t *off = as_structure_find(s, ASF_TAG_GRDC)->data, *prim = as_structure_find(s, ASF_TAG_PRIM)->data;
    const double pad = 4.0 * as_spatial_pad(g->lo, g->hi);
    size_t differing = 0;
    for (uint32_t t = 0; t < m->triangle_count; ++t) {
        if (as_mesh_triangle_is_degenerate(m, t)) continue;
        const float *v[3];
        for (int j = 0; j < 3; ++j) v[j] = m->positions + 3 * (size_t)m->indices[3 * (size_t)t + j];
        uint32_t c0[3], c1[3];
        int single = 1;
        for (int k = 0; k < 3; ++k) {
            const float lo = fminf(v[0][k], fminf(v[1][k], v[2][k])), hi = fmaxf(v[0][k], fmaxf(v[1][k], v[2][k]));
            c0[k] = grid_cell_of(g, k, (double)lo - pad);
            c1[k] = grid_cell_of(g, k, (double)hi + pad);
            single &= c0[k] == c1[k];
        }
        for (uint32_t z = c0[2]; z <= c1[2]; ++z)
            for (uint32_t y = c0[1]; y <= c1[1]; ++y)
                for (uint32_t x = c0[0]; x <= c1[0]; ++x) {
                    const float lo[3] = {grid_wall(g, 0, x), grid_wall(g, 1, y), grid_wall(g, 2, z)};
                    const float hi[3] = {grid_wall(g, 0, x + 1), grid_wall(g, 1, y + 1), grid_wall(g, 2, z + 1)};
                    const int expected = single || as_tri_box_overlap(v[0], v[1], v[2], lo, hi, as_spatial_pad(lo, hi));
                    const size_t cell = ((size_t)z * g->dims[1] + y) * g->dims[0] + x;
                    int found = 0;
                    for (uint32_t i = off[cell]; i < off[cell + 1]; ++i) found |= prim[i] == t;
                    differing += found != expected;
                }
    }
    return differing;
}

static void grid_cells_are_those_of_testing_every_cell(void)
{
    if (kind != AS_STRUCT_GRID) return;
    /* Small triangles with every 50th one 30 times larger; one triangle
     * across the whole of a cube of small ones; a scene wider than
     * FLT_MAX, whose walls past the float range are infinite. */
    as_mesh_t *meshes[3];
    meshes[0] = soup_mixed(33, 3000, 0.02f, 50);
    {
        const uint32_t n = 2000;
        float *p = malloc(sizeof(float) * 9 * (n + 1));
        uint32_t *ix = malloc(sizeof(uint32_t) * 3 * (n + 1));
        uint64_t st = 5;
        for (uint32_t t = 0; t < n; ++t) {
            float c[3];
            for (int k = 0; k < 3; ++k) c[k] = (float)ref_rand01(&st);
            for (int q = 0; q < 9; ++q) p[9 * t + q] = c[q % 3] + 0.01f * (float)(ref_rand01(&st) - 0.5);
        }
        const float big[9] = {0.02f, 0.05f, 0.97f, 0.96f, 0.1f, 0.03f, 0.3f, 0.98f, 0.6f};
        memcpy(p + 9 * n, big, sizeof big);
        for (uint32_t i = 0; i < 3 * (n + 1); ++i) ix[i] = i;
        meshes[1] = as_mesh_create(3 * (n + 1), p, n + 1, ix);
        free(p);
        free(ix);
    }
    {
        /* 2,000 small triangles in a box 6e38 wide (about 20 cells per
         * axis: i x cell leaves float's range from the 12th wall on) and
         * three large ones. */
        const uint32_t n = 2000;
        const float big[27] = {-3e38f, -3e38f, -3e38f, 3e38f, -3e38f, -3e38f, -3e38f, 3e38f,  3e38f,
                               3e38f,  3e38f,  3e38f,  -3e38f, 3e38f, -3e38f, 3e38f,  -3e38f, 3e38f,
                               1e37f,  1e37f,  2e38f,  2.5e38f, 5e37f, 1e37f,  5e37f,  2.5e38f, 1.5e38f};
        float *p = malloc(sizeof(float) * 9 * (n + 3));
        uint32_t *ix = malloc(sizeof(uint32_t) * 3 * (n + 3));
        uint64_t st = 9;
        for (uint32_t t = 0; t < n; ++t) {
            float c[3];
            for (int k = 0; k < 3; ++k) c[k] = (float)((ref_rand01(&st) - 0.5) * 5.8e38);
            for (int q = 0; q < 9; ++q) p[9 * t + q] = c[q % 3] + (float)((ref_rand01(&st) - 0.5) * 1e36);
        }
        memcpy(p + 9 * n, big, sizeof big);
        for (uint32_t i = 0; i < 3 * (n + 3); ++i) ix[i] = i;
        meshes[2] = as_mesh_create(3 * (n + 3), p, n + 3, ix);
        free(p);
        free(ix);
    }
    for (int k = 0; k < 3; ++k) {
        CHECK(meshes[k] != NULL);
        if (!meshes[k]) continue;
        as_build_args_t args;
        args_for(&args);
        as_structure_t *s = as_structure_build(meshes[k], &args);
        CHECK(s != NULL);
        if (s) {
            const size_t differing = grid_cells_differing(meshes[k], s);
            if (differing) fprintf(stderr, "  mesh %d: %zu cells differ from testing every cell\n", k, differing);
            CHECK_EQ_U64(differing, 0);
            as_structure_release(s);
        }
        as_mesh_release(meshes[k]);
    }
}

/* Large triangles crossing the whole scene among small ones. */
static void references_stay_within_the_split_budget(void)
{
    if (kind == AS_STRUCT_BIH) return; /* one reference per triangle by construction */
    as_mesh_t *m = soup_mixed(21, 2000, 0.05f, 10);
    as_build_args_t args;
    args_for(&args);
    args.split_budget = 2.0f;
    as_structure_t *s = as_structure_build(m, &args);
    CHECK(s != NULL);
    if (s) {
        as_structure_stats_t st;
        CHECK_EQ_INT(as_structure_get_stats(s, &st), AS_OK);
        fprintf(stderr, "  %s big triangles, budget 2: %llu references for 2000 triangles\n", kind_name,
                (unsigned long long)st.reference_count);
        CHECK(st.reference_count <= 4000);
        as_ray_t *rays = malloc(sizeof *rays * 5000);
        ref_make_scene_rays(m, 5000, 3, rays);
        CHECK_EQ_U64(disagreements(m, s, rays, 5000), 0);
        free(rays);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

/* A file whose bytes are damaged after its checksums were taken: loading
 * with checksums off must succeed, validation must fail. */
typedef void (*damage_fn)(unsigned char *section, uint64_t count);

static void expect_rejected(const unsigned char *file, size_t size, const char *tag, damage_fn damage, const char *what)
{
    as_load_args_t la;
    as_load_args_default(&la);
    la.verify_checksums = false;
    unsigned char *copy = malloc(size);
    memcpy(copy, file, size);
    as_structure_t *orig = as_structure_load_memory(file, size, "orig.asf", &la);
    CHECK(orig != NULL);
    int found = 0;
    for (uint32_t i = 0; orig && i < as_structure_section_count(orig); ++i) {
        as_section_info_t info;
        as_structure_section_info(orig, i, &info);
        if (strcmp(info.tag, tag) != 0) continue;
        found = 1;
        damage(copy + info.offset, info.element_count);
    }
    CHECK(found);
    as_structure_t *s = as_structure_load_memory(copy, size, "damaged.asf", &la);
    if (s) {
        const as_error_t e = as_structure_validate(s);
        if (e != AS_ERROR_INVALID_STRUCTURE) fprintf(stderr, "  %s damage '%s' was not detected\n", kind_name, what);
        else fprintf(stderr, "  %s damage '%s': %s\n", kind_name, what, as_get_error_message());
        CHECK_EQ_INT(e, AS_ERROR_INVALID_STRUCTURE);
    }
    as_structure_release(s);
    as_structure_release(orig);
    free(copy);
}

static void bih_child_out_of_range(unsigned char *d, uint64_t n) { as_bih_node_t *x = (void *)d; x[0].info = (((uint32_t)n + 5) << 2) | (x[0].info & 3u); }
static void bih_child_loops_to_root(unsigned char *d, uint64_t n) { (void)n; as_bih_node_t *x = (void *)d; x[0].info = (0u << 2) | 0u; }
static void bih_nan_plane(unsigned char *d, uint64_t n) { (void)n; as_bih_node_t *x = (void *)d; x[0].clip[1] = NAN; }
static void bih_leaf_too_long(unsigned char *d, uint64_t n)
{
    as_bih_node_t *x = (void *)d;
    for (uint64_t i = 0; i < n; ++i)
        if ((x[i].info & 3u) == AS_BIH_LEAF) { x[i].clip[0] = as_uint_as_float(1000000u); return; }
}
static void oct_child_before_parent(unsigned char *d, uint64_t n) { (void)n; as_octree_node_t *x = (void *)d; x[0].first = 0; }
static void oct_child_past_end(unsigned char *d, uint64_t n) { as_octree_node_t *x = (void *)d; x[0].first = (uint32_t)n - 4; }
static void oct_leaf_too_long(unsigned char *d, uint64_t n)
{
    as_octree_node_t *x = (void *)d;
    for (uint64_t i = 0; i < n; ++i)
        if (x[i].count != AS_OCTREE_INNER) { x[i].count = 1000000u; return; }
}
static void oct_nan_cube(unsigned char *d, uint64_t n) { (void)n; as_octree_header_t *h = (void *)d; h->size = NAN; }
static void grid_zero_dims(unsigned char *d, uint64_t n) { (void)n; as_grid_header_t *h = (void *)d; h->dims[1] = 0; }
static void grid_more_dims(unsigned char *d, uint64_t n) { (void)n; as_grid_header_t *h = (void *)d; h->dims[0] += 1; }
static void grid_offsets_decrease(unsigned char *d, uint64_t n) { uint32_t *o = (void *)d; o[n / 2] = o[n - 1] + 7; }
static void prim_out_of_range(unsigned char *d, uint64_t n) { (void)n; uint32_t *p = (void *)d; p[0] = 0x7FFFFFFFu; }
static void tris_wrong_index(unsigned char *d, uint64_t n) { (void)n; as_tri4_t *t = (void *)d; t[1].v0.w = as_uint_as_float(0); }

static void validation_rejects_damaged_files(void)
{
    as_mesh_t *m = soup(33, 3000, 0.05f);
    as_build_args_t args;
    args_for(&args);
    as_structure_t *s = as_structure_build(m, &args);
    CHECK(s != NULL);
    char path[512];
    snprintf(path, sizeof path, "%s/damage.asf", tmpdir);
    CHECK_EQ_INT(as_structure_save(s, path, NULL), AS_OK);
    unsigned char *data = NULL;
    size_t size = 0;
    CHECK(test_read_file(path, &data, &size));
    unlink(path);
    expect_rejected(data, size, "PRIM", prim_out_of_range, "PRIM entry out of range");
    expect_rejected(data, size, "TRIS", tris_wrong_index, "TRIS source index");
    if (kind == AS_STRUCT_BIH) {
        expect_rejected(data, size, "BIHN", bih_child_out_of_range, "child out of range");
        expect_rejected(data, size, "BIHN", bih_child_loops_to_root, "child loops to the root");
        expect_rejected(data, size, "BIHN", bih_nan_plane, "NaN clip plane");
        expect_rejected(data, size, "BIHN", bih_leaf_too_long, "leaf past PRIM");
    } else if (kind == AS_STRUCT_OCTREE) {
        expect_rejected(data, size, "OCTN", oct_child_before_parent, "children before the parent");
        expect_rejected(data, size, "OCTN", oct_child_past_end, "children past the end");
        expect_rejected(data, size, "OCTN", oct_leaf_too_long, "leaf past PRIM");
        expect_rejected(data, size, "OCTH", oct_nan_cube, "NaN root cube");
    } else {
        expect_rejected(data, size, "GRDH", grid_zero_dims, "zero cells on an axis");
        expect_rejected(data, size, "GRDH", grid_more_dims, "more cells than offsets");
        expect_rejected(data, size, "GRDC", grid_offsets_decrease, "decreasing offsets");
    }
    free(data);
    as_structure_release(s);
    as_mesh_release(m);
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: %s bih|octree|grid\n", argv[0]);
        return 2;
    }
    kind_name = argv[1];
    kind = as_structure_kind_from_name(kind_name);
    if (kind != AS_STRUCT_BIH && kind != AS_STRUCT_OCTREE && kind != AS_STRUCT_GRID) return 2;
    snprintf(tmpdir, sizeof tmpdir, "/tmp/as_test_misc_XXXXXX");
    if (!mkdtemp(tmpdir)) return 1;
    RUN_TEST(build_is_byte_identical_for_1_2_3_and_16_threads);
    RUN_TEST(progress_callback_returning_false_cancels_the_build);
    RUN_TEST(copies_of_one_triangle_stay_shallow_and_hit_the_lowest_index);
    RUN_TEST(a_small_dense_cluster_in_a_large_scene_is_subdivided);
    RUN_TEST(a_flat_scene_builds_and_is_hit_from_both_sides);
    RUN_TEST(quads_on_split_planes_are_hit_by_crossing_rays);
    RUN_TEST(zero_area_triangles_are_left_out);
    RUN_TEST(references_stay_within_the_split_budget);
    RUN_TEST(grid_cells_are_those_of_testing_every_cell);
    RUN_TEST(validation_rejects_damaged_files);
    rmdir(tmpdir);
    TEST_EXIT();
}
