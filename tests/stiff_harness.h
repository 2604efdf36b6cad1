/* What the stiff-case programs (test_stiff.c, test_stiff_more.c) share: the
 * variant under test from the command line, building it, tracing on the
 * CPU or the GPU, and the comparison of closest hits with the
 * double-precision reference (reference.h, whose tie rule applies).
 *
 * A program includes this once; the state below is that program's. */
#ifndef AS_TEST_STIFF_HARNESS_H
#define AS_TEST_STIFF_HARNESS_H

#include "reference.h"
#include "test_util.h"

#include <stdbool.h>

static as_build_args_t variant;
static char variant_name[128];
static as_intersector_t intersector;         /* what trace() uses */
static as_intersector_t default_intersector; /* the library's default */
static as_device_t device = AS_DEVICE_CPU;

/* Reads `[--gpu] STRUCTURE BUILDER LAYOUT [CASE]` into the state above and
 * returns the CASE argument (NULL: every case) through `only`. Returns 0
 * to go on, or the exit code: 77 (skipped) for --gpu without a usable GPU,
 * 2 for a usage error. */
static int stiff_parse_variant(int argc, char **argv, const char *program, const char **only)
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
        fprintf(stderr, "usage: %s [--gpu] STRUCTURE BUILDER LAYOUT [CASE]\n", program);
        return 2;
    }
    as_trace_args_t defaults;
    as_trace_args_default(&defaults);
    intersector = default_intersector = defaults.intersector;
    if (test_parse_variant(argv + 1, &variant, variant_name, sizeof variant_name)) return 2;
    *only = argc > 4 ? argv[4] : NULL;
    return 0;
}

/* The variant built over `m`, validated; NULL (a failed check) when the
 * build fails. */
static as_structure_t *build(const as_mesh_t *m, const char *what)
{
    as_structure_t *s = as_structure_build(m, &variant);
    if (!s) fprintf(stderr, "  %s %s: build failed: %s\n", variant_name, what, as_get_error_message());
    CHECK(s != NULL);
    if (s) CHECK_EQ_INT(as_structure_validate(s), AS_OK);
    return s;
}

/* Traces on the program's device with the current intersector, one CPU
 * thread; returns the hits (malloc'd) and the trace time in `ms`. */
static as_hit_t *trace(const as_structure_t *s, const as_ray_t *rays, size_t n, int any_hit, double *ms)
{
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = device;
    ta.any_hit = any_hit;
    ta.thread_count = 1; /* timings compare rays, not cores */
    ta.timed_runs = 3;   /* GPU: the median of three launches */
    ta.intersector = intersector;
    as_hit_t *hits = malloc(sizeof *hits * (n ? n : 1));
    as_trace_timing_t t;
    const as_error_t e = as_trace(s, rays, n, hits, &ta, &t);
    CHECK_EQ_INT(e, AS_OK);
    if (ms) *ms = t.trace_ms;
    return hits;
}

/* Closest hits against the reference (reference.h's rule); returns the
 * disagreements and checks that no hit holds a NaN. When `hits_out` or
 * `ref_out` is not NULL the traced hits (malloc'd) and the reference's
 * (n entries, the caller's) are handed back. With `cache_dir`, the
 * reference comes from or goes to its cache there (large scenes). */
static size_t against_reference_ex(const char *what, const as_mesh_t *m, const as_structure_t *s, const as_ray_t *rays,
                                   size_t n, as_hit_t **hits_out, ref_hit *ref_out, const char *cache_dir)
{
    ref_scene rs;
    CHECK(ref_scene_init(&rs, m));
    ref_hit *ref = ref_out ? ref_out : malloc(sizeof *ref * (n ? n : 1));
    if (cache_dir) ref_trace_all_cached(&rs, m, rays, n, ref, cache_dir);
    else ref_trace_all(&rs, rays, n, ref);
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
    if (hits_out) *hits_out = hits;
    else free(hits);
    if (!ref_out) free(ref);
    ref_scene_free(&rs);
    return bad;
}

static inline size_t against_reference(const char *what, const as_mesh_t *m, const as_structure_t *s, const as_ray_t *rays,
                                size_t n)
{
    return against_reference_ex(what, m, s, rays, n, NULL, NULL, NULL);
}

/* Rays [from, to) whose hit breaks its stated outcome (as.h,
 * as_stiff_outcome_t; `prims` holds the lists the outcomes name), the
 * reference part aside (against_reference checks that); `hits` holds the
 * hits of rays from .. to - 1. Prints the first three. */
static size_t stiff_outcome_failures(const char *what, const as_stiff_outcome_t *outcomes, const uint32_t *prims,
                                     size_t from, size_t to, const as_hit_t *hits)
{
    size_t bad = 0;
    for (size_t i = from; i < to; ++i) {
        const as_stiff_outcome_t *o = &outcomes[i];
        const as_hit_t *h = &hits[i - from];
        bool listed = false;
        for (uint32_t k = 0; k < o->count; ++k) listed |= h->prim == prims[o->first + k];
        bool ok = true;
        switch (o->expect) {
        case AS_STIFF_EXPECT_HIT: ok = h->prim != AS_NO_HIT; break;
        case AS_STIFF_EXPECT_MISS: ok = h->prim == AS_NO_HIT && isinf(h->t); break;
        case AS_STIFF_EXPECT_PRIM: ok = listed; break;
        case AS_STIFF_EXPECT_NOT_PRIM: ok = !listed; break;
        default: break;
        }
        if (o->same_as != AS_STIFF_NO_RAY && o->same_as >= from)
            ok = ok && memcmp(h, &hits[o->same_as - from], sizeof *h) == 0;
        if (!ok && bad < 3)
            fprintf(stderr, "  %s %s ray %zu: outcome %u not met: prim %u t %.9g\n", variant_name, what, i, o->expect,
                    h->prim, (double)h->t);
        bad += !ok;
    }
    return bad;
}

#endif
