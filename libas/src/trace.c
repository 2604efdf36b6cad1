/* Tracing front end: argument defaults and the choice of back end. */
#include "structure.h"
#include "trace_gpu.h"
#include "ray_triangle.h"

#include <stdlib.h>
#include <string.h>

void as_trace_args_default(as_trace_args_t *args)
{
    memset(args, 0, sizeof *args);
    args->size = sizeof *args;
    args->device = AS_DEVICE_AUTO;
    args->timed_runs = 5;
    args->batch = 32;
    /* The double test decides exactly as the verification reference does and,
     * on the H100, traces 4-16% faster than the float one
     * (docs/results/tuning.md, step 4). */
    args->intersector = AS_INTERSECTOR_WATERTIGHT_DOUBLE;
}

#ifdef AS_HAVE_CUDA
/* Puts the sections the layout's traversal reads on the GPU. */
static as_error_t upload(const as_structure_t *s, const as_trace_args_t *args)
{
    if (s->gpu) return AS_OK;
    const as_layout_ops_t *ops = as_structure_ops(s);
    const void *data[AS_GPU_MAX_SECTIONS];
    uint64_t bytes[AS_GPU_MAX_SECTIONS], total = 0;
    for (uint32_t i = 0; i < ops->section_count && i < AS_GPU_MAX_SECTIONS; ++i) {
        const as_section_t *sec = as_structure_find(s, ops->sections[i].tag);
        data[i] = sec->data;
        bytes[i] = sec->bytes;
        total += sec->bytes;
    }
    uint64_t limit = args->device_memory_limit;
    if (!limit) limit = as_gpu_free_memory();
    int zero_copy = args->residency == AS_RESIDENCY_ZERO_COPY;
    if (args->residency == AS_RESIDENCY_AUTO && limit && total > limit) zero_copy = 1;
    if (args->residency == AS_RESIDENCY_DEVICE && limit && total > limit)
        return as_set_error(AS_ERROR_OUT_OF_MEMORY, "the structure's %llu bytes exceed the %llu allowed in device memory",
                            (unsigned long long)total, (unsigned long long)limit);
    /* In-place access maps the whole file, which only a loaded, uncompressed
     * structure can offer. */
    int in_file = s->file != NULL;
    for (uint32_t i = 0; i < ops->section_count && in_file; ++i)
        in_file = (as_structure_find(s, ops->sections[i].tag)->flags & ASF_SECTION_ZSTD) == 0;
    if (zero_copy && !in_file)
        return as_set_error(AS_ERROR_UNSUPPORTED, "zero-copy residency needs a structure loaded from a file with uncompressed sections");
    /* Nothing a kernel reads may be unchecked. A structure built here, or
     * already validated, is trusted; the rest is checked on the GPU after
     * the copy where the layout can (one pass over device memory instead of
     * a walk on one core), else on the CPU before it. */
    const char *name = s->file ? asf_name(s->file) : "(built structure)";
    const int trusted = !s->file || atomic_load(&s->validated);
    const int on_gpu = !trusted && ops->validate_gpu && !zero_copy;
    double validate_ms = 0.0;
    if (!trusted && !on_gpu) {
        const double t0 = as_now_ms();
        const as_error_t verr = ops->validate(s, name);
        if (verr != AS_OK) return verr;
        validate_ms = as_now_ms() - t0;
    }
    int method = args->upload;
    /* Measured on the H100 with a 981 MB San Miguel SBVH in the page cache:
     * the pinned pipeline (eight threads, 2 MiB buffers) 26-28 GB/s,
     * cudaMemcpy from the mapping 8.6 GB/s; docs/results/
     * 2026-11-22-load-csum-h100.md. */
    if (method == AS_UPLOAD_AUTO) method = AS_UPLOAD_PINNED_PIPELINE;
    if (method == AS_UPLOAD_REGISTERED && !in_file) method = AS_UPLOAD_PAGEABLE;
    struct as_gpu_resident *g = NULL;
    const as_error_t err = as_gpu_upload(data, bytes, (int)ops->section_count, zero_copy, method,
                                         args->upload_threads, args->upload_chunk_mib, in_file ? asf_bytes(s->file) : NULL, in_file ? asf_size(s->file) : 0, &g);
    if (err != AS_OK) return err;
    as_structure_t *mut = (as_structure_t *)s;
    mut->gpu = g;
    if (on_gpu) {
        const double t0 = as_now_ms();
        const as_error_t verr = ops->validate_gpu(s, name);
        validate_ms = as_now_ms() - t0;
        if (verr != AS_OK) {
            mut->gpu = NULL;
            as_gpu_release(g);
            return verr;
        }
    }
    g->info.validated = trusted ? "earlier" : on_gpu ? "gpu" : "cpu";
    g->info.validate_ms = validate_ms;
    atomic_store(&mut->validated, 1);
    return AS_OK;
}
#endif

#ifdef AS_HAVE_CUDA
void as_gpu_meta_expect(const as_structure_t *s, as_gpu_meta_expect_t *m)
{
    m->mesh_triangles = s->meta.triangle_count;
    memcpy(m->bounds_lo, s->meta.bounds_lo, sizeof m->bounds_lo);
    memcpy(m->bounds_hi, s->meta.bounds_hi, sizeof m->bounds_hi);
    m->node_count = s->meta.node_count;
    m->leaf_count = s->meta.leaf_count;
    m->reference_count = s->meta.reference_count;
    m->empty_leaf_count = s->meta.empty_leaf_count;
    m->max_depth = s->meta.max_depth;
}

as_error_t as_layout_trace_gpu(const as_structure_t *s, const as_ray_t *rays, size_t count, as_hit_t *hits,
                               const as_gpu_launch_t *launch, as_trace_timing_t *timing)
{
    return as_trace_gpu(s->meta.layout, s->gpu, s->meta.bounds_lo, s->meta.bounds_hi, rays, count, hits, launch,
                        timing);
}
#endif

as_error_t as_structure_upload(const as_structure_t *s, const as_trace_args_t *user_args, as_upload_info_t *info)
{
    if (!s) return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_structure_upload: NULL structure");
    as_trace_args_t args;
    as_trace_args_default(&args);
    if (user_args) memcpy(&args, user_args, user_args->size < sizeof args ? user_args->size : sizeof args);
#ifdef AS_HAVE_CUDA
    if (!as_gpu_available()) return as_set_error(AS_ERROR_NO_DEVICE, "no usable CUDA device");
    const as_error_t err = upload(s, &args);
    if (err == AS_OK && info) *info = s->gpu->info;
    return err;
#else
    (void)info;
    return as_set_error(AS_ERROR_NO_DEVICE, "this build of libas has no CUDA back end");
#endif
}

as_error_t as_gpu_prepare(void)
{
#ifdef AS_HAVE_CUDA
    if (as_gpu_device_count() > 0 && as_gpu_create_context()) return AS_OK;
#endif
    return as_set_error(AS_ERROR_NO_DEVICE, "no usable CUDA device");
}

bool as_gpu_available(void)
{
#ifdef AS_HAVE_CUDA
    return as_gpu_device_count() > 0;
#else
    return false;
#endif
}

/* Per-ray steps on the CPU: the layouts' loops sum their counters over the
 * rays of a call, so each ray goes in a call of its own, and the sums and
 * maxima are rebuilt from the rays. */
typedef struct steps_job {
    const as_structure_t *s;
    const as_layout_ops_t *ops;
    const as_ray_t *rays;
    as_hit_t *hits;
    size_t count;
    int any_hit, ray_flags;
    uint32_t *ray_steps;
    as_cpu_stats_t *block_stats;
} steps_job;

#define STEPS_BLOCK 256

static void count_steps_block(void *user, size_t block)
{
    const steps_job *job = user;
    const size_t begin = block * STEPS_BLOCK;
    const size_t end = begin + STEPS_BLOCK < job->count ? begin + STEPS_BLOCK : job->count;
    for (size_t i = begin; i < end; ++i) {
        as_cpu_stats_t one = {0, 0, 0, 0};
        job->ops->trace_cpu(job->s, job->rays + i, job->hits + i, 1, job->any_hit, job->ray_flags, &one);
        job->ray_steps[i] = (uint32_t)one.steps;
        as_cpu_stats_add(&job->block_stats[block], (uint32_t)one.steps, (uint32_t)one.tests);
    }
}

static as_error_t count_steps_cpu(const as_structure_t *s, const as_ray_t *rays, size_t count, as_hit_t *hits,
                                  const as_trace_args_t *args, as_trace_timing_t *timing)
{
    if (!count) return AS_OK;
    const size_t blocks = (count + STEPS_BLOCK - 1) / STEPS_BLOCK;
    steps_job job = {s, as_structure_ops(s), rays, hits, count, args->any_hit,
                     as_intersector_ray_flags(args->intersector), args->ray_steps,
                     as_calloc(blocks, sizeof(as_cpu_stats_t), "traversal statistics")};
    if (!job.block_stats) return as_get_error();
    as_parallel_for(as_thread_count(args->thread_count), blocks, count_steps_block, &job);
    as_cpu_stats_t sum = {0, 0, 0, 0};
    for (size_t b = 0; b < blocks; ++b) {
        sum.steps += job.block_stats[b].steps;
        sum.tests += job.block_stats[b].tests;
        if (job.block_stats[b].steps_max > sum.steps_max) sum.steps_max = job.block_stats[b].steps_max;
        if (job.block_stats[b].tests_max > sum.tests_max) sum.tests_max = job.block_stats[b].tests_max;
    }
    free(job.block_stats);
    if (!timing) return AS_OK;
    timing->have_stats = true;
    timing->steps_avg = (double)sum.steps / (double)count;
    timing->tests_avg = (double)sum.tests / (double)count;
    timing->steps_max = sum.steps_max;
    timing->tests_max = sum.tests_max;
    return AS_OK;
}

as_error_t as_trace(const as_structure_t *s, const as_ray_t *rays, size_t count, as_hit_t *hits,
                    const as_trace_args_t *user_args, as_trace_timing_t *timing)
{
    if (!s || (!rays && count) || (!hits && count))
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_trace: NULL argument");
    as_trace_args_t args;
    as_trace_args_default(&args);
    if (user_args) memcpy(&args, user_args, user_args->size < sizeof args ? user_args->size : sizeof args);
    if (timing) memset(timing, 0, sizeof *timing);
    if ((unsigned)args.intersector > AS_INTERSECTOR_MOLLER_TRUMBORE)
        return as_set_error(AS_ERROR_INVALID_ARGUMENT, "as_trace: unknown intersector %d", (int)args.intersector);
    as_device_t device = args.device;
    if (device == AS_DEVICE_AUTO) device = as_gpu_available() ? AS_DEVICE_GPU : AS_DEVICE_CPU;
    if (device == AS_DEVICE_CPU) {
        if (!args.collect_stats || !args.ray_steps) return as_trace_cpu(s, rays, count, hits, &args, timing);
        /* The timed pass as usual; the counting pass here, ray by ray. */
        args.collect_stats = false;
        const as_error_t err = as_trace_cpu(s, rays, count, hits, &args, timing);
        return err == AS_OK ? count_steps_cpu(s, rays, count, hits, &args, timing) : err;
    }
    const as_layout_ops_t *ops = as_structure_ops(s);
    if (!ops->trace_gpu)
        return as_set_error(AS_ERROR_NO_DEVICE, "this build of libas has no CUDA back end for the %s layout",
                            ops->layout_name);
    if (!as_gpu_available()) return as_set_error(AS_ERROR_NO_DEVICE, "no usable CUDA device (use the CPU back end)");
#ifdef AS_HAVE_CUDA
    const as_error_t uerr = upload(s, &args);
    if (uerr != AS_OK) return uerr;
#endif
    const as_gpu_launch_t launch = {
        args.any_hit,
        args.timed_runs ? args.timed_runs : 1,
        args.schedule == AS_SCHEDULE_PERSISTENT,
        args.batch ? args.batch : 32,
        args.collect_stats,
        as_intersector_ray_flags(args.intersector),
        args.collect_stats ? args.ray_steps : NULL,
    };
    return ops->trace_gpu(s, rays, count, hits, &launch, timing);
}
