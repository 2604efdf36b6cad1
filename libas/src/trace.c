/* Tracing front end: argument defaults and the choice of back end. */
#include "structure.h"
#include "trace_gpu.h"

#include <string.h>

void as_trace_args_default(as_trace_args_t *args)
{
    memset(args, 0, sizeof *args);
    args->size = sizeof *args;
    args->device = AS_DEVICE_AUTO;
    args->timed_runs = 5;
    args->batch = 32;
}

bool as_gpu_available(void)
{
#ifdef AS_HAVE_CUDA
    return as_gpu_device_count() > 0;
#else
    return false;
#endif
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
    as_device_t device = args.device;
    if (device == AS_DEVICE_AUTO) device = as_gpu_available() ? AS_DEVICE_GPU : AS_DEVICE_CPU;
    if (device == AS_DEVICE_CPU) return as_trace_cpu(s, rays, count, hits, &args, timing);
    const as_layout_ops_t *ops = as_structure_ops(s);
    if (!ops->trace_gpu)
        return as_set_error(AS_ERROR_NO_DEVICE, "this build of libas has no CUDA back end for the %s layout",
                            ops->layout_name);
    if (!as_gpu_available()) return as_set_error(AS_ERROR_NO_DEVICE, "no usable CUDA device (use the CPU back end)");
    const as_gpu_launch_t launch = {
        args.any_hit,
        args.timed_runs ? args.timed_runs : 1,
        args.schedule == AS_SCHEDULE_PERSISTENT,
        args.batch ? args.batch : 32,
        args.collect_stats,
    };
    return ops->trace_gpu(s, rays, count, hits, &launch, timing);
}
