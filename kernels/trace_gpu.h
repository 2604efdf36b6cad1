/* The CUDA back end's entry points, callable from C. */
#ifndef AS_TRACE_GPU_H
#define AS_TRACE_GPU_H

#include "as/as.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Number of usable CUDA devices (0 when the driver or device is missing). */
int as_gpu_device_count(void);

/* How to launch: filled from as_trace_args_t. */
typedef struct as_gpu_launch {
    int any_hit;
    unsigned timed_runs;         /* >= 1 */
    int persistent;              /* persistent threads, else one thread per ray */
    unsigned batch;              /* persistent: rays per atomic */
    int collect_stats;           /* run the counting kernel too (not timed) */
} as_gpu_launch_t;

/* Uploads the BVH2 nodes, TRI4 triangles and rays, runs one warm-up launch
 * and `timed_runs` timed launches of the BVH2 kernel, and copies the hits
 * back. timing->trace_ms is the median of the timed launches (CUDA events
 * around the kernel alone). */
as_error_t as_trace_gpu_bvh2(const void *nodes, uint64_t node_bytes, const void *tris,
                             uint64_t tri_bytes, const as_ray_t *rays, size_t count,
                             as_hit_t *hits, const as_gpu_launch_t *launch,
                             as_trace_timing_t *timing);

#ifdef __cplusplus
}
#endif

#endif
