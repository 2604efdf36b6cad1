/* CPU back end: a layout's traversal run on every core. */
#include "structure.h"
#include "ray_triangle.h"

#include <stdio.h>
#include <stdlib.h>

typedef struct cpu_job {
    const as_structure_t *s;
    const as_layout_ops_t *ops;
    const as_ray_t *rays;
    as_hit_t *hits;
    size_t count;
    int any_hit;
    int ray_flags;
    as_cpu_stats_t *stats;        /* one per block, or NULL */
} cpu_job;

/* Rays go out in blocks so neighbouring (coherent) rays stay on one core. */
#define CPU_BLOCK 256

static void trace_block(void *user, size_t block)
{
    const cpu_job *job = user;
    const size_t begin = block * CPU_BLOCK;
    const size_t end = begin + CPU_BLOCK < job->count ? begin + CPU_BLOCK : job->count;
    job->ops->trace_cpu(job->s, job->rays + begin, job->hits + begin, end - begin, job->any_hit, job->ray_flags,
                        job->stats ? &job->stats[block] : NULL);
}

int as_intersector_ray_flags(as_intersector_t intersector)
{
    switch (intersector) {
    case AS_INTERSECTOR_WATERTIGHT_DOUBLE: return AS_RAY_PRECISE;
    case AS_INTERSECTOR_MOLLER_TRUMBORE: return AS_RAY_MOLLER_TRUMBORE;
    default: return 0;
    }
}

as_error_t as_trace_cpu(const as_structure_t *s, const as_ray_t *rays, size_t count, as_hit_t *hits,
                        const as_trace_args_t *args, as_trace_timing_t *timing)
{
    cpu_job job = {s, as_structure_ops(s), rays, hits, count, args->any_hit,
                   as_intersector_ray_flags(args->intersector), NULL};
    const unsigned threads = as_thread_count(args->thread_count);
    const size_t blocks = (count + CPU_BLOCK - 1) / CPU_BLOCK;
    const double t0 = as_now_ms();
    as_parallel_for(threads, blocks, trace_block, &job);
    const double t1 = as_now_ms();
    if (args->collect_stats && timing && count) {
        /* A second, untimed pass that counts. */
        job.stats = as_calloc(blocks, sizeof *job.stats, "traversal statistics");
        if (!job.stats) return as_get_error();
        as_parallel_for(threads, blocks, trace_block, &job);
        as_cpu_stats_t sum = {0, 0, 0, 0};
        for (size_t b = 0; b < blocks; ++b) {
            sum.steps += job.stats[b].steps;
            sum.tests += job.stats[b].tests;
            if (job.stats[b].steps_max > sum.steps_max) sum.steps_max = job.stats[b].steps_max;
            if (job.stats[b].tests_max > sum.tests_max) sum.tests_max = job.stats[b].tests_max;
        }
        free(job.stats);
        timing->have_stats = true;
        timing->steps_avg = (double)sum.steps / (double)count;
        timing->tests_avg = (double)sum.tests / (double)count;
        timing->steps_max = sum.steps_max;
        timing->tests_max = sum.tests_max;
    }
    if (timing) {
        timing->device = AS_DEVICE_CPU;
        timing->trace_ms = t1 - t0;
        snprintf(timing->device_name, sizeof timing->device_name, "CPU, %u threads", threads);
    }
    return AS_OK;
}
