/* as_verify, the reference behind as-trace --verify, agrees with the true
 * brute force of tests/reference.h and counts every kind of wrong hit. */
#include "reference.h"
#include "test_util.h"

#include <stdio.h>

static void verify_counts_exactly_the_planted_errors(void)
{
    as_mesh_t *m = as_mesh_import(AS_SOURCE_DIR "/scenes/bunny.drc");
    CHECK(m != NULL);
    as_structure_t *s = as_structure_build(m, NULL);
    CHECK(s != NULL);
    const size_t n = 20000;
    as_ray_t *rays = malloc(sizeof *rays * n);
    ref_make_scene_rays(m, n, 99, rays);
    /* The truth: brute force in double. */
    ref_scene rs;
    CHECK(ref_scene_init(&rs, m));
    ref_hit *ref = malloc(sizeof *ref * n);
    ref_trace_all(&rs, rays, n, ref);
    as_hit_t *hits = malloc(sizeof *hits * n);
    for (size_t i = 0; i < n; ++i) {
        hits[i].t = (float)ref[i].t;
        hits[i].prim = ref[i].prim;
        hits[i].u = hits[i].v = 0.0f;
    }
    as_verify_args_t va;
    as_verify_args_default(&va);
    va.sample_count = 0; /* every ray */
    as_verify_result_t r;
    CHECK_EQ_INT(as_verify(s, rays, hits, n, false, &va, &r), AS_OK);
    CHECK_EQ_U64(r.checked, n);
    CHECK_EQ_U64(r.wrong_primitive + r.false_misses + r.false_hits, 0);
    /* Plant one of each error where the truth allows it. */
    size_t planted_wrong = 0, planted_miss = 0, planted_hit = 0;
    for (size_t i = 0; i < n; ++i) {
        if (ref[i].prim != AS_NO_HIT && planted_miss < 7 && i % 5 == 0) {
            hits[i].prim = AS_NO_HIT; hits[i].t = INFINITY; ++planted_miss;
        } else if (ref[i].prim != AS_NO_HIT && planted_wrong < 11 && i % 5 == 1) {
            /* A triangle far away in index order, and a distance the ray
             * does not meet it at. */
            hits[i].prim = (ref[i].prim + 30000) % 69451;
            if (isfinite(ref_hit_distance(&rs, &rays[i], hits[i].prim))) continue;
            hits[i].t = (float)ref[i].t * 2.0f;
            ++planted_wrong;
        } else if (ref[i].prim == AS_NO_HIT && planted_hit < 5 && i % 5 == 2) {
            hits[i].prim = 3; hits[i].t = 1.0f; ++planted_hit;
        }
    }
    CHECK_EQ_INT(as_verify(s, rays, hits, n, false, &va, &r), AS_OK);
    CHECK_EQ_U64(r.false_misses, planted_miss);
    CHECK_EQ_U64(r.wrong_primitive, planted_wrong);
    CHECK_EQ_U64(r.false_hits, planted_hit);
    fprintf(stderr, "  planted %zu wrong, %zu false misses, %zu false hits; found %llu, %llu, %llu in %.0f ms\n",
            planted_wrong, planted_miss, planted_hit, (unsigned long long)r.wrong_primitive,
            (unsigned long long)r.false_misses, (unsigned long long)r.false_hits, r.verify_ms);
    /* The traversal itself passes. */
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = AS_DEVICE_CPU;
    CHECK_EQ_INT(as_trace(s, rays, n, hits, &ta, NULL), AS_OK);
    CHECK_EQ_INT(as_verify(s, rays, hits, n, false, &va, &r), AS_OK);
    CHECK_EQ_U64(r.wrong_primitive + r.false_misses + r.false_hits, 0);
    CHECK(r.max_t_error < 1e-5);
    free(hits);
    free(ref);
    free(rays);
    ref_scene_free(&rs);
    as_structure_release(s);
    as_mesh_release(m);
}

int main(void)
{
    RUN_TEST(verify_counts_exactly_the_planted_errors);
    TEST_EXIT();
}
