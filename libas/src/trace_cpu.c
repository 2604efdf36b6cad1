/* CPU back end: a layout's traversal run on every core. */
#include "structure.h"
#include "ray_triangle.h"

#include <stdio.h>

typedef struct cpu_job {
    const as_structure_t *s;
    const as_layout_ops_t *ops;
    const as_ray_t *rays;
    as_hit_t *hits;
    size_t count;
    int any_hit;
    int ray_flags;
} cpu_job;

/* Rays go out in blocks so neighbouring (coherent) rays stay on one core. */
#define CPU_BLOCK 256

static void trace_block(void *user, size_t block)
{
    const cpu_job *job = user;
    const size_t begin = block * CPU_BLOCK;
    const size_t end = begin + CPU_BLOCK < job->count ? begin + CPU_BLOCK : job->count;
    job->ops->trace_cpu(job->s, job->rays + begin, job->hits + begin, end - begin, job->any_hit, job->ray_flags);
}

as_error_t as_trace_cpu(const as_structure_t *s, const as_ray_t *rays, size_t count, as_hit_t *hits,
                        const as_trace_args_t *args, as_trace_timing_t *timing)
{
    cpu_job job = {s, as_structure_ops(s), rays, hits, count, args->any_hit,
                   args->intersector == AS_INTERSECTOR_WATERTIGHT_DOUBLE ? AS_RAY_PRECISE : 0};
    const unsigned threads = as_thread_count(args->thread_count);
    const double t0 = as_now_ms();
    as_parallel_for(threads, (count + CPU_BLOCK - 1) / CPU_BLOCK, trace_block, &job);
    if (timing) {
        timing->device = AS_DEVICE_CPU;
        timing->trace_ms = as_now_ms() - t0;
        snprintf(timing->device_name, sizeof timing->device_name, "CPU, %u threads", threads);
    }
    return AS_OK;
}
