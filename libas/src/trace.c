/* Tracing front end: argument defaults and the choice of back end. */
#include "structure.h"
#include "trace_gpu.h"
#include "ray_triangle.h"

#include <string.h>

void as_trace_args_default(as_trace_args_t *args)
{
    memset(args, 0, sizeof *args);
    args->size = sizeof *args;
    args->device = AS_DEVICE_AUTO;
    args->timed_runs = 5;
    args->batch = 32;
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
    int method = args->upload;
    /* Measured on the H100 with San Miguel (654 MB, page cache): cudaMemcpy
     * from the mapping 9.7 GB/s, the pinned pipeline 5.2 GB/s
     * (docs/results/2026-11-22-upload-h100.md). */
    if (method == AS_UPLOAD_AUTO) method = AS_UPLOAD_PAGEABLE;
    if (method == AS_UPLOAD_REGISTERED && !in_file) method = AS_UPLOAD_PAGEABLE;
    struct as_gpu_resident *g = NULL;
    const as_error_t err = as_gpu_upload(data, bytes, (int)ops->section_count, zero_copy, method,
                                         in_file ? asf_bytes(s->file) : NULL, in_file ? asf_size(s->file) : 0, &g);
    if (err != AS_OK) return err;
    ((as_structure_t *)s)->gpu = g;
    return AS_OK;
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
        args.intersector == AS_INTERSECTOR_WATERTIGHT_DOUBLE ? AS_RAY_PRECISE : 0,
    };
    return ops->trace_gpu(s, rays, count, hits, &launch, timing);
}
