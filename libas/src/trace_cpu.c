/* CPU back end: the shared traversal header run on every core. */
#include "structure.h"
#include "bvh2_traverse.h"

#include <stdio.h>
#include <string.h>

typedef struct cpu_job {
    const as_bvh2_node_t *nodes;
    const as_tri4_t *tris;
    const as_ray_t *rays;
    as_hit_t *hits;
    size_t count;
    int any_hit;
} cpu_job;

/* Rays go out in blocks so neighbouring (coherent) rays stay on one core. */
#define CPU_BLOCK 256

static void trace_block(void *user, size_t block)
{
    const cpu_job *job = user;
    const size_t begin = block * CPU_BLOCK;
    const size_t end = begin + CPU_BLOCK < job->count ? begin + CPU_BLOCK : job->count;
    for (size_t i = begin; i < end; ++i) {
        const as_ray_t *ray = &job->rays[i];
        as_hit_rec_t h;
        as_ray_pre_t pre;
        if (as_ray_prepare(ray->org, ray->tmin, ray->dir, ray->tmax, &pre))
            as_bvh2_trace(job->nodes, job->tris, &pre, job->any_hit, &h, NULL);
        else
            as_hit_rec_miss(&h);
        job->hits[i].t = h.t;
        job->hits[i].prim = h.prim;
        job->hits[i].u = h.u;
        job->hits[i].v = h.v;
    }
}

as_error_t as_trace_cpu(const as_structure_t *s, const as_ray_t *rays, size_t count, as_hit_t *hits,
                        const as_trace_args_t *args, as_trace_timing_t *timing)
{
    const as_section_t *ns = as_structure_find(s, ASF_TAG_BVH2), *ts = as_structure_find(s, ASF_TAG_TRI4);
    if (!ns || !ts) return as_set_error(AS_ERROR_UNSUPPORTED, "the structure has no BVH2/TRI4 sections to trace");
    cpu_job job = {ns->data, ts->data, rays, hits, count, args->any_hit};
    const double t0 = as_now_ms();
    as_parallel_for(as_thread_count(args->thread_count), (count + CPU_BLOCK - 1) / CPU_BLOCK, trace_block, &job);
    if (timing) {
        timing->device = AS_DEVICE_CPU;
        timing->trace_ms = as_now_ms() - t0;
        snprintf(timing->device_name, sizeof timing->device_name, "CPU, %u threads",
                 as_thread_count(args->thread_count));
    }
    return AS_OK;
}
