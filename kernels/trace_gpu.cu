// CUDA back end: launches the shared BVH2 traversal (kernels/bvh2_traverse.h).
// The algorithm lives in the header; this file moves data, schedules rays
// and times launches.
#include "bvh2_traverse.h"
#include "trace_gpu.h"

#include <cuda_runtime.h>

#include <algorithm>
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

struct device_counters {
    unsigned long long steps, tests;
    unsigned steps_max, tests_max;
};

// One ray; STATS adds the per-ray counters (a separate instantiation, so the
// timed kernel carries no counting code at all).
template <bool STATS>
__device__ __forceinline__ void trace_one(const as_bvh2_node_t *__restrict__ nodes, const as_tri4_t *__restrict__ tris,
                                          const device_ray *__restrict__ rays, float4 *__restrict__ hits, size_t i,
                                          int any_hit, device_counters *counters)
{
    const float4 a = __ldg(&rays[i].a), b = __ldg(&rays[i].b);
    const float org[3] = {a.x, a.y, a.z}, dir[3] = {b.x, b.y, b.z};
    as_ray_pre_t pre;
    as_hit_rec_t h;
    as_trace_counters_t ctr = {0, 0};
    if (as_ray_prepare(org, a.w, dir, b.w, &pre))
        as_bvh2_trace(nodes, tris, &pre, any_hit, &h, STATS ? &ctr : nullptr);
    else
        as_hit_rec_miss(&h);
    hits[i] = make_float4(h.t, __uint_as_float(h.prim), h.u, h.v);
    if (STATS) {
        atomicAdd(&counters->steps, (unsigned long long)ctr.node_visits);
        atomicAdd(&counters->tests, (unsigned long long)ctr.tri_tests);
        atomicMax(&counters->steps_max, ctr.node_visits);
        atomicMax(&counters->tests_max, ctr.tri_tests);
    }
}

template <bool STATS>
__global__ void bvh2_kernel_thread_per_ray(const as_bvh2_node_t *__restrict__ nodes,
                                           const as_tri4_t *__restrict__ tris, const device_ray *__restrict__ rays,
                                           float4 *__restrict__ hits, size_t count, int any_hit,
                                           device_counters *counters)
{
    const size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i < count) trace_one<STATS>(nodes, tris, rays, hits, i, any_hit, counters);
}

// Persistent threads (Aila & Laine 2009): a grid that fills the GPU once;
// each warp takes `batch` rays per atomic from a global counter, so warps
// that finish early take more work instead of idling at the tail.
template <bool STATS>
__global__ void bvh2_kernel_persistent(const as_bvh2_node_t *__restrict__ nodes, const as_tri4_t *__restrict__ tris,
                                       const device_ray *__restrict__ rays, float4 *__restrict__ hits, size_t count,
                                       int any_hit, unsigned long long *next, unsigned batch,
                                       device_counters *counters)
{
    const unsigned lane = threadIdx.x & 31u;
    for (;;) {
        unsigned long long base = 0;
        if (lane == 0) base = atomicAdd(next, (unsigned long long)batch);
        base = __shfl_sync(0xffffffffu, base, 0);
        if (base >= count) return;
        for (unsigned k = lane; k < batch; k += 32) {
            const size_t i = (size_t)(base + k);
            if (i < count) trace_one<STATS>(nodes, tris, rays, hits, i, any_hit, counters);
        }
    }
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

#define CUDA_TRY(call, what)                                                 \
    do {                                                                     \
        const cudaError_t _e = (call);                                       \
        if (_e != cudaSuccess) { err = cuda_fail(_e, what); goto done; }     \
    } while (0)

extern "C" as_error_t as_trace_gpu_bvh2(const void *nodes, uint64_t node_bytes, const void *tris,
                                        uint64_t tri_bytes, const as_ray_t *rays, size_t count,
                                        as_hit_t *hits, const as_gpu_launch_t *launch,
                                        as_trace_timing_t *timing)
{
    as_error_t err = AS_OK;
    void *d_nodes = nullptr, *d_tris = nullptr, *d_rays = nullptr, *d_hits = nullptr;
    unsigned long long *d_next = nullptr;
    device_counters *d_counters = nullptr;
    cudaEvent_t ev0 = nullptr, ev1 = nullptr, up0 = nullptr, up1 = nullptr;
    std::vector<float> times;
    const int block = 128;
    const unsigned grid_all = (unsigned)((count + block - 1) / block);
    unsigned grid_persistent = 0;
    int per_sm = 0;
    const unsigned batch = launch->batch ? launch->batch : 32;
    cudaDeviceProp prop;
    device_counters counters = {0, 0, 0, 0};
    const as_bvh2_node_t *n = nullptr;
    const as_tri4_t *t = nullptr;
    const device_ray *r = nullptr;
    float4 *h = nullptr;
    CUDA_TRY(cudaGetDeviceProperties(&prop, 0), "cudaGetDeviceProperties");
    CUDA_TRY(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, bvh2_kernel_persistent<false>, block, 0),
             "occupancy query");
    grid_persistent = (unsigned)(prop.multiProcessorCount * (per_sm > 0 ? per_sm : 1));
    CUDA_TRY(cudaEventCreate(&ev0), "cudaEventCreate");
    CUDA_TRY(cudaEventCreate(&ev1), "cudaEventCreate");
    CUDA_TRY(cudaEventCreate(&up0), "cudaEventCreate");
    CUDA_TRY(cudaEventCreate(&up1), "cudaEventCreate");
    CUDA_TRY(cudaMalloc(&d_nodes, node_bytes ? node_bytes : 64), "cudaMalloc nodes");
    CUDA_TRY(cudaMalloc(&d_tris, tri_bytes ? tri_bytes : 48), "cudaMalloc triangles");
    CUDA_TRY(cudaMalloc(&d_rays, count * sizeof(as_ray_t) + 32), "cudaMalloc rays");
    CUDA_TRY(cudaMalloc(&d_hits, count * sizeof(as_hit_t) + 16), "cudaMalloc hits");
    CUDA_TRY(cudaMalloc(&d_next, sizeof(unsigned long long)), "cudaMalloc counter");
    CUDA_TRY(cudaMalloc(&d_counters, sizeof(device_counters)), "cudaMalloc counters");
    CUDA_TRY(cudaEventRecord(up0), "cudaEventRecord");
    CUDA_TRY(cudaMemcpy(d_nodes, nodes, node_bytes, cudaMemcpyHostToDevice), "upload of nodes");
    CUDA_TRY(cudaMemcpy(d_tris, tris, tri_bytes, cudaMemcpyHostToDevice), "upload of triangles");
    CUDA_TRY(cudaEventRecord(up1), "cudaEventRecord");
    CUDA_TRY(cudaMemcpy(d_rays, rays, count * sizeof(as_ray_t), cudaMemcpyHostToDevice), "upload of rays");
    n = (const as_bvh2_node_t *)d_nodes;
    t = (const as_tri4_t *)d_tris;
    r = (const device_ray *)d_rays;
    h = (float4 *)d_hits;
    if (count == 0) goto copy_back;
    // One warm-up launch, then the timed ones; the counter reset is outside
    // the timed interval.
    for (unsigned run = 0; run <= launch->timed_runs; ++run) {
        CUDA_TRY(cudaMemset(d_next, 0, sizeof(unsigned long long)), "cudaMemset");
        CUDA_TRY(cudaEventRecord(ev0), "cudaEventRecord");
        if (launch->persistent)
            bvh2_kernel_persistent<false><<<grid_persistent, block>>>(n, t, r, h, count, launch->any_hit, d_next, batch,
                                                                      nullptr);
        else
            bvh2_kernel_thread_per_ray<false><<<grid_all, block>>>(n, t, r, h, count, launch->any_hit, nullptr);
        CUDA_TRY(cudaGetLastError(), "kernel launch");
        CUDA_TRY(cudaEventRecord(ev1), "cudaEventRecord");
        CUDA_TRY(cudaEventSynchronize(ev1), "traversal kernel");
        float ms = 0;
        CUDA_TRY(cudaEventElapsedTime(&ms, ev0, ev1), "cudaEventElapsedTime");
        if (run > 0) times.push_back(ms);
    }
    if (launch->collect_stats) {
        CUDA_TRY(cudaMemset(d_counters, 0, sizeof(device_counters)), "cudaMemset");
        bvh2_kernel_thread_per_ray<true><<<grid_all, block>>>(n, t, r, h, count, launch->any_hit, d_counters);
        CUDA_TRY(cudaGetLastError(), "statistics kernel launch");
        CUDA_TRY(cudaMemcpy(&counters, d_counters, sizeof counters, cudaMemcpyDeviceToHost), "statistics download");
    }
copy_back:
    CUDA_TRY(cudaMemcpy(hits, d_hits, count * sizeof(as_hit_t), cudaMemcpyDeviceToHost), "download of hits");
    if (timing) {
        timing->device = AS_DEVICE_GPU;
        if (!times.empty()) {
            std::sort(times.begin(), times.end());
            timing->trace_ms = times[times.size() / 2];
            timing->trace_ms_min = times.front();
            timing->trace_ms_max = times.back();
            timing->timed_runs = (uint32_t)times.size();
        }
        if (launch->collect_stats && count) {
            timing->have_stats = true;
            timing->steps_avg = (double)counters.steps / (double)count;
            timing->tests_avg = (double)counters.tests / (double)count;
            timing->steps_max = counters.steps_max;
            timing->tests_max = counters.tests_max;
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
    cudaFree(d_next);
    cudaFree(d_counters);
    if (ev0) cudaEventDestroy(ev0);
    if (ev1) cudaEventDestroy(ev1);
    if (up0) cudaEventDestroy(up0);
    if (up1) cudaEventDestroy(up1);
    return err;
}
