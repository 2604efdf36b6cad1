/* The CUDA kernel runs the same traversal header as the CPU back end with
 * explicitly rounded arithmetic, so its hits must equal the CPU's bit for
 * bit: same primitive, same t, same barycentrics. Skips without a GPU. */
#include "reference.h"
#include "test_util.h"

#include <stdio.h>

static void trace_both(const as_structure_t *s, const as_ray_t *rays, size_t n, int any_hit, const char *what)
{
    as_hit_t *cpu = malloc(sizeof *cpu * n), *gpu = malloc(sizeof *gpu * n);
    as_trace_args_t ta;
    as_trace_args_default(&ta);
    ta.any_hit = any_hit;
    ta.device = AS_DEVICE_CPU;
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
    CHECK(nhit > 0);
    CHECK_EQ_U64(bad, 0);
    free(cpu);
    free(gpu);
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

static void gpu_hits_equal_cpu_hits(const char *path, size_t n)
{
    as_mesh_t *m = as_mesh_import(path);
    if (!m) fprintf(stderr, "import failed: %s\n", as_get_error_message());
    CHECK(m != NULL);
    if (!m) return;
    as_structure_t *s = as_structure_build(m, NULL);
    CHECK(s != NULL);
    as_ray_t *rays = malloc(sizeof *rays * n);
    ref_make_scene_rays(m, n, 31337, rays);
    trace_both(s, rays, n, 0, path);
    trace_both(s, rays, n, 1, path);
    free(rays);
    as_structure_release(s);
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
    fprintf(stderr, "%s gpu_hits_equal_cpu_hits\n", test_failures ? "FAIL" : "ok  ");
    TEST_EXIT();
}
