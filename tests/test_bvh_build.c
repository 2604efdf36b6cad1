/* What the BVH builder promises: byte-identical files whatever the thread
 * count, a valid tree within the depth cap, cancellation, and sane
 * behaviour on tiny and degenerate inputs. */
#include "reference.h"
#include "test_util.h"
#include "bvh_build_common.h"

#include <stdio.h>

static char tmpdir[256];

static void save_with_threads(const as_mesh_t *m, unsigned threads, const char *path)
{
    as_build_args_t args;
    as_build_args_default(&args);
    args.thread_count = threads;
    as_structure_t *s = as_structure_build(m, &args);
    CHECK(s != NULL);
    CHECK_EQ_INT(test_save_reproducible(s, path), AS_OK);
    as_structure_release(s);
}

static void build_time_is_recorded_in_the_file_unless_left_out(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(m != NULL);
    if (!m) return;
    as_build_args_t args;
    as_build_args_default(&args);
    args.thread_count = 2;
    as_structure_t *s = as_structure_build(m, &args);
    CHECK(s != NULL);
    as_structure_stats_t built;
    CHECK_EQ_INT(as_structure_get_stats(s, &built), AS_OK);
    CHECK(built.build_ms > 0.0);
    CHECK_EQ_INT(built.build_threads, 2);
    char with[512], without[512];
    snprintf(with, sizeof with, "%s/record.asf", tmpdir);
    snprintf(without, sizeof without, "%s/no-record.asf", tmpdir);
    CHECK_EQ_INT(as_structure_save(s, with, NULL), AS_OK);
    as_save_args_t save;
    as_save_args_default(&save);
    save.omit_build_record = true;
    CHECK_EQ_INT(as_structure_save(s, without, &save), AS_OK);
    as_structure_release(s);

    as_structure_t *a = as_structure_load(with, NULL), *b = as_structure_load(without, NULL);
    CHECK(a != NULL && b != NULL);
    if (a && b) {
        as_structure_stats_t sa, sb;
        CHECK_EQ_INT(as_structure_get_stats(a, &sa), AS_OK);
        CHECK_EQ_INT(as_structure_get_stats(b, &sb), AS_OK);
        /* The loaded record is the build's, to the bit. */
        CHECK(memcmp(&sa.build_ms, &built.build_ms, sizeof sa.build_ms) == 0);
        CHECK_EQ_INT(sa.build_threads, 2);
        CHECK(sa.build_cores >= 1);
        CHECK(sb.build_ms == 0.0 && sb.build_threads == 0);
        /* One section more, and the structure's own sections unchanged. */
        CHECK_EQ_INT(as_structure_section_count(a), as_structure_section_count(b) + 1);
        CHECK(sa.sah_cost == sb.sah_cost && sa.node_count == sb.node_count);
    }
    as_structure_release(a);
    as_structure_release(b);
    unlink(with);
    unlink(without);
    as_mesh_release(m);
}

static void build_is_byte_identical_whatever_the_thread_count(void)
{
    as_mesh_t *meshes[2];
    meshes[0] = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(meshes[0] != NULL);
    /* A soup large enough that subtrees are built on several threads. */
    uint64_t st = 7;
    const uint32_t n = 200000;
    float *p = malloc(sizeof(float) * 9 * n);
    for (uint32_t i = 0; i < 9 * n; ++i) p[i] = (float)ref_rand01(&st);
    meshes[1] = test_mesh_from_soup(p, n);
    CHECK(meshes[1] != NULL);
    const unsigned threads[] = {1, 2, 3, 8};
    for (int k = 0; k < 2; ++k) {
        if (!meshes[k]) continue;
        unsigned char *first = NULL, *data = NULL;
        size_t first_size = 0;
        for (size_t t = 0; t < sizeof threads / sizeof threads[0]; ++t) {
            char path[512];
            snprintf(path, sizeof path, "%s/mesh%d_threads%u.asf", tmpdir, k, threads[t]);
            save_with_threads(meshes[k], threads[t], path);
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

/* Coordinates of +0 and -0 mixed: SSE min and max keep one of two equal
 * zeros by operand order, so where several threads bin pieces of a node the
 * boxes' zeros must not depend on which thread merged what. A soup large
 * enough that nodes are split on several threads. */
static void signed_zero_coordinates_give_the_same_tree_whatever_the_thread_count(void)
{
    const uint32_t n = 300000;
    float *p = malloc(sizeof(float) * 9 * n);
    uint64_t st = 11;
    for (uint32_t i = 0; i < 9 * n; ++i) {
        const double r = ref_rand01(&st);
        if (r < 0.375) p[i] = r < 0.1875 ? -0.0f : 0.0f;
        else p[i] = (float)(int)(ref_rand01(&st) * 1000.0) / 100.0f;
    }
    as_mesh_t *m = test_mesh_from_soup(p, n);
    CHECK(m != NULL);
    if (!m) return;
    const as_builder_t builders[] = {AS_BUILDER_BVH_SAH_BINNED, AS_BUILDER_BVH_SBVH, AS_BUILDER_BIH};
    const unsigned threads[] = {1, 2, 4};
    for (size_t b = 0; b < sizeof builders / sizeof builders[0]; ++b) {
        uint8_t first[16], fp[16];
        for (size_t t = 0; t < sizeof threads / sizeof threads[0]; ++t) {
            as_build_args_t args;
            as_build_args_default(&args);
            args.structure = (as_structure_kind_t)(builders[b] & 0xFF00);
            args.builder = builders[b];
            args.thread_count = threads[t];
            as_structure_t *s = as_structure_build(m, &args);
            CHECK(s != NULL);
            if (!s) continue;
            CHECK(as_structure_fingerprint(s, t ? fp : first) == AS_OK);
            if (t && memcmp(fp, first, sizeof fp) != 0) {
                fprintf(stderr, "     %s: %u threads build another tree than 1\n", as_builder_name(builders[b]), threads[t]);
                CHECK(memcmp(fp, first, sizeof fp) == 0);
            }
            as_structure_release(s);
        }
    }
    as_mesh_release(m);
}

static as_mesh_t *random_soup(uint64_t seed, uint32_t n)
{
    float *p = malloc(sizeof(float) * 9 * n);
    for (uint32_t i = 0; i < 9 * n; ++i) p[i] = (float)ref_rand01(&seed);
    return test_mesh_from_soup(p, n);
}

/* The builders take the large arrays that earlier builds gave back
 * (as_block_take) with another tree's bytes in them: a build after another
 * mesh's must write every byte it keeps. Binned SAH and SBVH, 1 and 2
 * threads. */
static void build_after_another_mesh_is_byte_identical(void)
{
    as_mesh_t *a = random_soup(7, 200000), *other = random_soup(11, 230000);
    CHECK(a != NULL && other != NULL);
    if (!a || !other) {
        as_mesh_release(a);
        as_mesh_release(other);
        return;
    }
    const char *builders[] = {"sah", "sbvh"};
    for (int k = 0; k < 2; ++k)
        for (unsigned threads = 1; threads <= 2; ++threads) {
            as_build_args_t args;
            as_build_args_default(&args);
            args.builder = as_builder_from_name(AS_STRUCT_BVH, builders[k]);
            args.thread_count = threads;
            unsigned char *data[2] = {NULL, NULL};
            size_t size[2] = {0, 0};
            for (int pass = 0; pass < 2; ++pass) {
                if (pass == 1) {
                    as_structure_t *o = as_structure_build(other, &args);
                    CHECK(o != NULL);
                    as_structure_release(o);
                }
                as_structure_t *s = as_structure_build(a, &args);
                CHECK(s != NULL);
                if (!s) continue;
                char path[512];
                snprintf(path, sizeof path, "%s/after_%s_%u_%d.asf", tmpdir, builders[k], threads, pass);
                CHECK_EQ_INT(test_save_reproducible(s, path), AS_OK);
                as_structure_release(s);
                CHECK(test_read_file(path, &data[pass], &size[pass]));
                unlink(path);
            }
            CHECK_EQ_U64(size[1], size[0]);
            CHECK(data[0] && data[1] && size[0] == size[1] && memcmp(data[0], data[1], size[0]) == 0);
            free(data[0]);
            free(data[1]);
        }
    as_mesh_release(a);
    as_mesh_release(other);
}

static as_mesh_t *copies_of_one_triangle(uint32_t copies)
{
    float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * copies);
    for (uint32_t i = 0; i < copies; ++i) { ix[3 * i] = 0; ix[3 * i + 1] = 1; ix[3 * i + 2] = 2; }
    as_mesh_t *m = as_mesh_create(3, p, copies, ix);
    free(ix);
    return m;
}

static void duplicates_stay_within_the_depth_cap_and_hit_the_lowest_index(void)
{
    const uint32_t counts[] = {2, 10, 1000, 10000};
    for (size_t k = 0; k < sizeof counts / sizeof counts[0]; ++k) {
        as_mesh_t *m = copies_of_one_triangle(counts[k]);
        as_structure_t *s = as_structure_build(m, NULL);
        CHECK(s != NULL);
        CHECK_EQ_INT(as_structure_validate(s), AS_OK);
        as_structure_stats_t st;
        CHECK_EQ_INT(as_structure_get_stats(s, &st), AS_OK);
        CHECK(st.max_depth <= 64);
        CHECK(st.node_count <= counts[k]); /* linear in N */
        const as_ray_t ray = {{0.25f, 0.25f, 1.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, INFINITY};
        as_hit_t hit;
        as_trace_args_t ta;
        as_trace_args_default(&ta);
        ta.device = AS_DEVICE_CPU;
        CHECK_EQ_INT(as_trace(s, &ray, 1, &hit, &ta, NULL), AS_OK);
        CHECK_EQ_U64(hit.prim, 0);
        CHECK(hit.t == 1.0f);
        as_structure_release(s);
        as_mesh_release(m);
    }
}

static void a_single_triangle_and_an_all_degenerate_mesh_build_and_trace(void)
{
    const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t one[3] = {0, 1, 2}, degenerate[6] = {0, 0, 1, 0, 1, 1};
    as_mesh_t *m1 = as_mesh_create(3, p, 1, one), *m2 = as_mesh_create(3, p, 2, degenerate);
    CHECK(m1 && m2);
    as_structure_t *s1 = as_structure_build(m1, NULL), *s2 = as_structure_build(m2, NULL);
    CHECK(s1 && s2);
    CHECK_EQ_INT(as_structure_validate(s1), AS_OK);
    CHECK_EQ_INT(as_structure_validate(s2), AS_OK);
    const as_ray_t ray = {{0.2f, 0.2f, -1.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, INFINITY};
    as_hit_t h1, h2;
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = AS_DEVICE_CPU;
    CHECK_EQ_INT(as_trace(s1, &ray, 1, &h1, &ta, NULL), AS_OK);
    CHECK_EQ_INT(as_trace(s2, &ray, 1, &h2, &ta, NULL), AS_OK);
    CHECK_EQ_U64(h1.prim, 0);
    CHECK(h1.t == 1.0f && fabsf(h1.u - 0.2f) < 1e-6f && fabsf(h1.v - 0.2f) < 1e-6f);
    CHECK_EQ_U64(h2.prim, AS_NO_HIT);
    CHECK(isinf(h2.t));
    as_structure_release(s1);
    as_structure_release(s2);
    as_mesh_release(m1);
    as_mesh_release(m2);
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
    as_build_args_t args;
    as_build_args_default(&args);
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

static void bad_rays_report_a_miss(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    as_structure_t *s = as_structure_build(m, NULL);
    CHECK(s != NULL);
    const float nan = NAN, inf = INFINITY;
    const as_ray_t rays[] = {
        {{0, 0.1f, 1}, 1.0f, {0, 0, -1}, 0.5f},  /* tmin > tmax */
        {{0, 0.1f, 1}, 0.0f, {0, 0, 0}, inf},     /* zero direction */
        {{nan, 0.1f, 1}, 0.0f, {0, 0, -1}, inf},  /* NaN origin */
        {{0, 0.1f, 1}, 0.0f, {0, nan, -1}, inf},  /* NaN direction */
        {{0, 0.1f, inf}, 0.0f, {0, 0, -1}, inf},  /* infinite origin */
        {{0, 0.1f, 1}, nan, {0, 0, -1}, inf},     /* NaN tmin */
    };
    const size_t n = sizeof rays / sizeof rays[0];
    as_hit_t hits[sizeof rays / sizeof rays[0]];
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = AS_DEVICE_CPU;
    CHECK_EQ_INT(as_trace(s, rays, n, hits, &ta, NULL), AS_OK);
    for (size_t i = 0; i < n; ++i) {
        CHECK_EQ_U64(hits[i].prim, AS_NO_HIT);
        CHECK(isinf(hits[i].t) && hits[i].t > 0);
    }
    as_structure_release(s);
    as_mesh_release(m);
}

/* The exact subtree builder orders each node's references by centroid,
 * ties by position; where the processor has AVX2 the ranks are counted
 * eight at a time, and both forms must give that one order (the files
 * depend on it): random keys with many ties, signed zeros and every size
 * up to the largest. */
static void exact_subtree_orders_are_sorted_and_the_same_in_both_forms(void)
{
    uint64_t seed = 0x9e3779b97f4a7c15u;
    unsigned mismatches = 0, unsorted = 0;
    for (int round = 0; round < 20000; ++round) {
        const uint32_t n = 1 + (uint32_t)(round % BVH_EXACT_MAX);
        float keys[BVH_EXACT_MAX];
        for (uint32_t i = 0; i < n; ++i) {
            seed = seed * 6364136223846793005u + 1442695040888963407u;
            const uint32_t r = (uint32_t)(seed >> 33);
            /* A few distinct values (ties), zeros of both signs, and
             * spread-out ones. */
            keys[i] = (r & 3) == 0 ? (float)(r % 5) : (r & 3) == 1 ? ((r & 4) ? -0.0f : 0.0f) : (float)(int32_t)r * 1e-3f;
        }
        uint8_t fast[BVH_EXACT_MAX], plain[BVH_EXACT_MAX];
        CHECK(bvh_exact_order(keys, n, fast, 0) && bvh_exact_order(keys, n, plain, 1));
        for (uint32_t i = 0; i < n; ++i) mismatches += fast[i] != plain[i];
        for (uint32_t i = 1; i < n; ++i) {
            const float a = keys[plain[i - 1]], b = keys[plain[i]];
            unsorted += !(a < b || (a == b && plain[i - 1] < plain[i]));
        }
    }
    CHECK_EQ_INT(mismatches, 0);
    CHECK_EQ_INT(unsorted, 0);
    uint8_t order[BVH_EXACT_MAX + 1];
    float keys[BVH_EXACT_MAX + 1] = {0};
    CHECK(!bvh_exact_order(keys, BVH_EXACT_MAX + 1, order, 0));
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/as_test_bvh_XXXXXX");
    if (!mkdtemp(tmpdir)) return 1;
    RUN_TEST(exact_subtree_orders_are_sorted_and_the_same_in_both_forms);
    RUN_TEST(build_is_byte_identical_whatever_the_thread_count);
    RUN_TEST(signed_zero_coordinates_give_the_same_tree_whatever_the_thread_count);
    RUN_TEST(build_after_another_mesh_is_byte_identical);
    RUN_TEST(build_time_is_recorded_in_the_file_unless_left_out);
    RUN_TEST(duplicates_stay_within_the_depth_cap_and_hit_the_lowest_index);
    RUN_TEST(a_single_triangle_and_an_all_degenerate_mesh_build_and_trace);
    RUN_TEST(progress_callback_returning_false_cancels_the_build);
    RUN_TEST(bad_rays_report_a_miss);
    rmdir(tmpdir);
    TEST_EXIT();
}
