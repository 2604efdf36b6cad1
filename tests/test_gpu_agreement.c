/* The CUDA kernel runs the same traversal header as the CPU back end with
 * explicitly rounded arithmetic, so its hits must equal the CPU's bit for
 * bit: same primitive, same t, same barycentrics. Skips without a GPU. */
#include "reference.h"
#include "test_util.h"

#include <stdio.h>

static as_intersector_t intersector = AS_INTERSECTOR_WATERTIGHT;

/* `some_hit`: the rays are known to hit something (a check that they were
 * traced at all); secondary rays of a lone object may all escape. */
static void trace_rays_both(const as_structure_t *s, const as_ray_t *rays, size_t n, int any_hit, const char *what,
                            int some_hit)
{
    as_hit_t *cpu = malloc(sizeof *cpu * n), *gpu = malloc(sizeof *gpu * n);
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.any_hit = any_hit;
    ta.device = AS_DEVICE_CPU;
    ta.intersector = intersector;
    as_trace_timing_t tc, tg;
    CHECK_EQ_INT(as_trace(s, rays, n, cpu, &ta, &tc), AS_OK);
    ta.device = AS_DEVICE_GPU;
    const as_error_t e = as_trace(s, rays, n, gpu, &ta, &tg);
    if (e != AS_OK) fprintf(stderr, "GPU trace failed: %s\n", as_get_error_message());
    CHECK_EQ_INT(e, AS_OK);
    size_t bad = 0, nhit = 0;
    for (size_t i = 0; e == AS_OK && i < n; ++i) {
        nhit += cpu[i].prim != AS_NO_HIT;
        if (memcmp(&cpu[i], &gpu[i], sizeof cpu[i]) != 0) {
            if (bad < 5)
                fprintf(stderr, "  %s ray %zu: cpu prim %u t %.9g u %.9g v %.9g, gpu prim %u t %.9g u %.9g v %.9g\n", what, i,
                        cpu[i].prim, (double)cpu[i].t, (double)cpu[i].u, (double)cpu[i].v, gpu[i].prim,
                        (double)gpu[i].t, (double)gpu[i].u, (double)gpu[i].v);
            ++bad;
        }
    }
    fprintf(stderr, "  %s (%s): %zu rays, %zu hit, %zu differ; GPU %s, %.3f ms (%.1f Mrays/s), CPU %.1f ms\n", what,
            any_hit ? "any hit" : "closest hit", n, nhit, bad, tg.device_name, tg.trace_ms,
            tg.trace_ms > 0 ? n / (tg.trace_ms * 1e3) : 0.0, tc.trace_ms);
    if (some_hit) CHECK(nhit > 0);
    CHECK_EQ_U64(bad, 0);
    free(cpu);
    free(gpu);
}

static void trace_both(const as_structure_t *s, const as_ray_t *rays, size_t n, int any_hit, const char *what)
{
    trace_rays_both(s, rays, n, any_hit, what, 1);
}

/* The small-memory path: a file too large for the device memory allowed is
 * read in place (zero-copy) and gives the same hits. */
static void zero_copy_residency_gives_the_same_hits(const char *path, size_t n)
{
    as_mesh_t *m = as_mesh_import(path);
    CHECK(m != NULL);
    if (!m) return;
    as_structure_t *built = as_structure_build(m, NULL);
    char file[] = "/tmp/as_gpu_zero_copy_XXXXXX";
    const int fd = mkstemp(file);
    CHECK(fd >= 0);
    close(fd);
    CHECK_EQ_INT(as_structure_save(built, file, NULL), AS_OK);
    as_structure_t *s = as_structure_load(file, NULL);
    CHECK(s != NULL);
    as_ray_t *rays = malloc(sizeof *rays * n);
    ref_make_scene_rays(m, n, 7, rays);
    as_hit_t *cpu = malloc(sizeof *cpu * n), *gpu = malloc(sizeof *gpu * n);
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.device = AS_DEVICE_CPU;
    CHECK_EQ_INT(as_trace(s, rays, n, cpu, &ta, NULL), AS_OK);
    ta.device = AS_DEVICE_GPU;
    ta.residency = AS_RESIDENCY_AUTO;
    ta.device_memory_limit = 4096; /* far below the structure: forces in-place reads */
    as_upload_info_t info;
    CHECK_EQ_INT(as_structure_upload(s, &ta, &info), AS_OK);
    CHECK(info.zero_copy);
    as_trace_timing_t tg;
    CHECK_EQ_INT(as_trace(s, rays, n, gpu, &ta, &tg), AS_OK);
    size_t bad = 0;
    for (size_t i = 0; i < n; ++i) bad += memcmp(&cpu[i], &gpu[i], sizeof cpu[i]) != 0;
    fprintf(stderr, "  %s zero-copy (%s): %zu rays, %zu differ, %.3f ms (%.1f Mrays/s)\n", path, info.method, n, bad,
            tg.trace_ms, n / (tg.trace_ms * 1e3));
    CHECK_EQ_U64(bad, 0);
    free(cpu);
    free(gpu);
    free(rays);
    as_structure_release(s);
    as_structure_release(built);
    as_mesh_release(m);
    unlink(file);
}

/* Builds the variant named {structure, builder, layout}. */
static as_structure_t *build_variant(const as_mesh_t *m, const char *const names[3])
{
    as_build_args_t args;
    as_build_args_default(&args);
    args.structure = as_structure_kind_from_name(names[0]);
    args.builder = as_builder_from_name(args.structure, names[1]);
    args.layout = as_layout_from_name(names[2]);
    return as_structure_build(m, &args);
}

/* Every variant this build has, by its names. */
static const char *const variants[][3] = {
    {"bvh", "sah", "bvh2-child-bounds"},  {"bvh", "midcut", "bvh2-child-bounds"},
    {"bvh", "sweep", "bvh2-child-bounds"}, {"bvh", "sbvh", "bvh2-child-bounds"},
    {"bvh", "sah", "bvh2-own-bounds"},    {"kd", "midcut", "kd-standard"},
    {"kd", "sah", "kd-standard"},         {"kd", "midcut", "kd-ropes"},
    {"kd", "sah", "kd-ropes"},            {"bih", "bih", "bih"},
    {"octree", "octree", "octree"},       {"grid", "grid", "grid"},
    {"bvh", "sah", "cwbvh"},              {"bvh", "sbvh", "cwbvh"},
};

static void gpu_hits_equal_cpu_hits(const char *path, size_t n)
{
    as_mesh_t *m = as_mesh_import(path);
    if (!m) fprintf(stderr, "import failed: %s\n", as_get_error_message());
    CHECK(m != NULL);
    if (!m) return;
    as_ray_t *rays = malloc(sizeof *rays * n);
    ref_make_scene_rays(m, n, 31337, rays);
    for (size_t v = 0; v < sizeof variants / sizeof variants[0]; ++v) {
        as_structure_t *s = build_variant(m, variants[v]);
        char what[512];
        snprintf(what, sizeof what, "%s %s/%s/%s", path, variants[v][0], variants[v][1], variants[v][2]);
        if (!s && as_get_error() == AS_ERROR_UNSUPPORTED) {
            fprintf(stderr, "  %s: not in this build\n", what);
            continue;
        }
        CHECK(s != NULL);
        if (!s) continue;
        trace_both(s, rays, n, 0, what);
        trace_both(s, rays, n, 1, what);
        if (v == 0) {
            /* The other triangle tests are one template argument away in
             * every kernel; one variant shows each compiles to the CPU's. */
            static const struct { as_intersector_t id; const char *name; } others[] = {
                {AS_INTERSECTOR_WATERTIGHT_DOUBLE, "watertight-double"},
                {AS_INTERSECTOR_MOLLER_TRUMBORE, "moller-trumbore"}};
            for (size_t k = 0; k < 2; ++k) {
                char with[600];
                snprintf(with, sizeof with, "%s, %s", what, others[k].name);
                intersector = others[k].id;
                trace_both(s, rays, n, 0, with);
                trace_both(s, rays, n, 1, with);
            }
            intersector = AS_INTERSECTOR_WATERTIGHT;
        }
        as_structure_release(s);
    }
    free(rays);
    as_mesh_release(m);
}

/* The study's workloads, not only random rays: primary rays from the
 * default camera, then from their hits hard shadows, AO (any hit), diffuse
 * bounces and one Whitted bounce; every set traced on both devices. The
 * secondary rays come from the CPU's primary hits, so both devices trace
 * exactly the same rays. */
static void gpu_hits_equal_cpu_hits_per_workload(const char *path)
{
    as_mesh_t *m = as_mesh_import(path);
    CHECK(m != NULL);
    if (!m) return;
    static const char *const kinds[][3] = {
        {"bvh", "sbvh", "bvh2-child-bounds"}, {"bvh", "sah", "bvh2-own-bounds"}, {"kd", "sah", "kd-standard"},
        {"kd", "sah", "kd-ropes"},            {"bih", "bih", "bih"},                {"octree", "octree", "octree"},
        {"grid", "grid", "grid"},             {"bvh", "sbvh", "cwbvh"},
    };
    for (size_t v = 0; v < sizeof kinds / sizeof kinds[0]; ++v) {
        as_structure_t *s = build_variant(m, kinds[v]);
        CHECK(s != NULL);
        if (!s) continue;
        char what[600];
        const uint32_t w = 320, h = 240;
        as_camera_t cam;
        as_camera_default(m->bounds_lo, m->bounds_hi, &cam);
        as_ray_t *primary = malloc(sizeof *primary * w * h);
        as_hit_t *hits = malloc(sizeof *hits * w * h);
        as_camera_rays_tiled(&cam, w, h, primary, NULL);
        snprintf(what, sizeof what, "%s %s/%s/%s primary", path, kinds[v][0], kinds[v][1], kinds[v][2]);
        trace_both(s, primary, (size_t)w * h, 0, what);
        as_trace_args_t ta;
        as_trace_args_default(&ta);
        ta.device = AS_DEVICE_CPU;
        CHECK_EQ_INT(as_trace(s, primary, (size_t)w * h, hits, &ta, NULL), AS_OK);

        as_ray_t *rays = NULL;
        size_t n = 0;
        float lights[12];
        as_lights_default(m->bounds_lo, m->bounds_hi, lights);
        CHECK_EQ_INT(as_rays_shadow(s, primary, hits, (size_t)w * h, lights, 4, 1e-4f, &rays, &n, NULL), AS_OK);
        snprintf(what, sizeof what, "%s %s/%s/%s shadow", path, kinds[v][0], kinds[v][1], kinds[v][2]);
        if (n) trace_rays_both(s, rays, n, 1, what, 0);
        free(rays);

        as_secondary_args_t sa;
        as_secondary_args_default(&sa);
        sa.rays_per_hit = 16;
        sa.tmax_fraction = 0.1f;
        CHECK_EQ_INT(as_rays_hemisphere(s, primary, hits, (size_t)w * h, &sa, &rays, &n, NULL), AS_OK);
        snprintf(what, sizeof what, "%s %s/%s/%s ao", path, kinds[v][0], kinds[v][1], kinds[v][2]);
        if (n) trace_both(s, rays, n, 1, what);
        free(rays);

        sa.rays_per_hit = 4;
        sa.tmax_fraction = 0.0f;
        CHECK_EQ_INT(as_rays_hemisphere(s, primary, hits, (size_t)w * h, &sa, &rays, &n, NULL), AS_OK);
        snprintf(what, sizeof what, "%s %s/%s/%s diffuse", path, kinds[v][0], kinds[v][1], kinds[v][2]);
        if (n) trace_both(s, rays, n, 0, what);
        free(rays);

        as_whitted_args_t wa;
        as_whitted_args_default(&wa);
        wa.lights = lights;
        wa.light_count = 4;
        as_ray_t *next = NULL, *shadow = NULL;
        size_t nn = 0, ns = 0;
        CHECK_EQ_INT(as_rays_whitted_bounce(s, primary, hits, (size_t)w * h, &wa, &next, &nn, &shadow, &ns), AS_OK);
        snprintf(what, sizeof what, "%s %s/%s/%s whitted bounce", path, kinds[v][0], kinds[v][1], kinds[v][2]);
        if (nn) trace_rays_both(s, next, nn, 0, what, 0);
        free(next);
        free(shadow);
        free(primary);
        free(hits);
        as_structure_release(s);
    }
    as_mesh_release(m);
}

int main(int argc, char **argv)
{
    if (!as_gpu_available()) {
        fprintf(stderr, "SKIP: no usable CUDA device in this build or machine\n");
        return TEST_SKIP;
    }
    /* The meshes named on the command line, else the bundled bunny. */
    if (argc < 2) gpu_hits_equal_cpu_hits(AS_SOURCE_DIR "/scenes/bunny.drc", 1000000);
    zero_copy_residency_gives_the_same_hits(argc < 2 ? AS_SOURCE_DIR "/scenes/bunny.drc" : argv[1], 200000);
    for (int i = 1; i < argc; ++i) gpu_hits_equal_cpu_hits(argv[i], 1000000);
    gpu_hits_equal_cpu_hits_per_workload(argc < 2 ? AS_SOURCE_DIR "/scenes/bunny.drc" : argv[1]);
    fprintf(stderr, "%s gpu_hits_equal_cpu_hits\n", test_failures ? "FAIL" : "ok  ");
    TEST_EXIT();
}
