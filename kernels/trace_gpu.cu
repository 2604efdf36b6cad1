// CUDA back end: launches the shared BVH2 traversal (kernels/bvh2_traverse.h),
// one thread per ray. The algorithm lives in the header; this file only moves
// data and times launches.
#include "bvh2_traverse.h"
#include "trace_gpu.h"

#include <cuda_runtime.h>

#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <vector>

extern "C" as_error_t as_set_error(as_error_t code, const char *fmt, ...);

namespace {

struct device_ray {
    float4 a; // org.xyz, tmin
    float4 b; // dir.xyz, tmax
};
static_assert(sizeof(device_ray) == sizeof(as_ray_t), "ray record is 32 bytes");

__global__ void bvh2_trace_kernel(const as_bvh2_node_t *__restrict__ nodes, const as_tri4_t *__restrict__ tris,
                                  const device_ray *__restrict__ rays, float4 *__restrict__ hits, size_t count,
                                  int any_hit)
{
    const size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= count) return;
    const float4 a = __ldg(&rays[i].a), b = __ldg(&rays[i].b);
    const float org[3] = {a.x, a.y, a.z}, dir[3] = {b.x, b.y, b.z};
    as_ray_pre_t pre;
    as_hit_rec_t h;
    if (as_ray_prepare(org, a.w, dir, b.w, &pre))
        as_bvh2_trace(nodes, tris, &pre, any_hit, &h, nullptr);
    else
        as_hit_rec_miss(&h);
    hits[i] = make_float4(h.t, __uint_as_float(h.prim), h.u, h.v);
}

as_error_t cuda_fail(cudaError_t e, const char *what)
{
    return as_set_error(AS_ERROR_DEVICE, "CUDA error during %s: %s (%s)", what, cudaGetErrorName(e),
                        cudaGetErrorString(e));
}

} // namespace

extern "C" int as_gpu_device_count(void)
{
    int n = 0;
    if (cudaGetDeviceCount(&n) != cudaSuccess) {
        cudaGetLastError(); // clear the sticky "no device" error
        return 0;
    }
    return n;
}

#define CUDA_TRY(call, what)                                   \
    do {                                                       \
        const cudaError_t _e = (call);                         \
        if (_e != cudaSuccess) { err = cuda_fail(_e, what); goto done; } \
    } while (0)

extern "C" as_error_t as_trace_gpu_bvh2(const void *nodes, uint64_t node_bytes, const void *tris,
                                        uint64_t tri_bytes, const as_ray_t *rays, size_t count,
                                        as_hit_t *hits, int any_hit, unsigned timed_runs,
                                        as_trace_timing_t *timing)
{
    as_error_t err = AS_OK;
    void *d_nodes = nullptr, *d_tris = nullptr, *d_rays = nullptr, *d_hits = nullptr;
    cudaEvent_t ev0 = nullptr, ev1 = nullptr, up0 = nullptr, up1 = nullptr;
    std::vector<float> times;
    const int block = 128;
    const unsigned grid = (unsigned)((count + block - 1) / block);
    cudaDeviceProp prop;
    CUDA_TRY(cudaGetDeviceProperties(&prop, 0), "cudaGetDeviceProperties");
    CUDA_TRY(cudaEventCreate(&ev0), "cudaEventCreate");
    CUDA_TRY(cudaEventCreate(&ev1), "cudaEventCreate");
    CUDA_TRY(cudaEventCreate(&up0), "cudaEventCreate");
    CUDA_TRY(cudaEventCreate(&up1), "cudaEventCreate");
    CUDA_TRY(cudaMalloc(&d_nodes, node_bytes ? node_bytes : 64), "cudaMalloc nodes");
    CUDA_TRY(cudaMalloc(&d_tris, tri_bytes ? tri_bytes : 48), "cudaMalloc triangles");
    CUDA_TRY(cudaMalloc(&d_rays, count * sizeof(as_ray_t) + 32), "cudaMalloc rays");
    CUDA_TRY(cudaMalloc(&d_hits, count * sizeof(as_hit_t) + 16), "cudaMalloc hits");
    CUDA_TRY(cudaEventRecord(up0), "cudaEventRecord");
    CUDA_TRY(cudaMemcpy(d_nodes, nodes, node_bytes, cudaMemcpyHostToDevice), "upload of nodes");
    CUDA_TRY(cudaMemcpy(d_tris, tris, tri_bytes, cudaMemcpyHostToDevice), "upload of triangles");
    CUDA_TRY(cudaEventRecord(up1), "cudaEventRecord");
    CUDA_TRY(cudaMemcpy(d_rays, rays, count * sizeof(as_ray_t), cudaMemcpyHostToDevice), "upload of rays");
    if (count == 0) goto copy_back;
    // Warm-up launch, then the timed ones.
    bvh2_trace_kernel<<<grid, block>>>((const as_bvh2_node_t *)d_nodes, (const as_tri4_t *)d_tris,
                                       (const device_ray *)d_rays, (float4 *)d_hits, count, any_hit);
    CUDA_TRY(cudaGetLastError(), "kernel launch");
    CUDA_TRY(cudaDeviceSynchronize(), "warm-up launch");
    for (unsigned r = 0; r < timed_runs; ++r) {
        CUDA_TRY(cudaEventRecord(ev0), "cudaEventRecord");
        bvh2_trace_kernel<<<grid, block>>>((const as_bvh2_node_t *)d_nodes, (const as_tri4_t *)d_tris,
                                           (const device_ray *)d_rays, (float4 *)d_hits, count, any_hit);
        CUDA_TRY(cudaEventRecord(ev1), "cudaEventRecord");
        CUDA_TRY(cudaEventSynchronize(ev1), "timed launch");
        float ms = 0;
        CUDA_TRY(cudaEventElapsedTime(&ms, ev0, ev1), "cudaEventElapsedTime");
        times.push_back(ms);
    }
copy_back:
    CUDA_TRY(cudaMemcpy(hits, d_hits, count * sizeof(as_hit_t), cudaMemcpyDeviceToHost), "download of hits");
    if (timing) {
        timing->device = AS_DEVICE_GPU;
        if (!times.empty()) {
            std::sort(times.begin(), times.end());
            timing->trace_ms = times[times.size() / 2];
        }
        float up = 0;
        cudaEventElapsedTime(&up, up0, up1);
        timing->upload_ms = up;
        timing->upload_bytes = node_bytes + tri_bytes;
        snprintf(timing->device_name, sizeof timing->device_name, "%.80s (sm_%d%d, %d SMs)", prop.name, prop.major,
                 prop.minor, prop.multiProcessorCount);
    }
done:
    cudaFree(d_nodes);
    cudaFree(d_tris);
    cudaFree(d_rays);
    cudaFree(d_hits);
    if (ev0) cudaEventDestroy(ev0);
    if (ev1) cudaEventDestroy(ev1);
    if (up0) cudaEventDestroy(up0);
    if (up1) cudaEventDestroy(up1);
    return err;
}
