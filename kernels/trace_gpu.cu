// CUDA back end: launches the shared BVH2 traversal (kernels/bvh2_traverse.h).
// The algorithm lives in the header; this file moves data, schedules rays
// and times launches.
#include "bvh2_traverse.h"
#include "bvh2_own_traverse.h"
#include "cwbvh_traverse.h"
#include "kd_traverse.h"
#include "kd_ropes_traverse.h"
#include "bih_traverse.h"
#include "grid_traverse.h"
#include "octree_traverse.h"
#include "trace_gpu.h"

#include <cuda_runtime.h>

#include <algorithm>
#include <atomic>
#include <mutex>
#include <thread>
#include <new>
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
    // Each ray's steps (device memory, one per ray), or null: a heat map
    // needs the rays one by one, the summary only the sums.
    unsigned *ray_steps;
};

// A traversal the kernels can launch: device pointers to its sections and a
// call into its shared header. One struct per layout; the algorithm stays
// in the header.
struct bvh2_traversal {
    const as_bvh2_node_t *nodes;
    const as_tri4_t *tris;
    __device__ void trace(const as_ray_pre_t *r, int any_hit, as_hit_rec_t *h, as_trace_counters_t *c) const
    {
        as_bvh2_trace(nodes, tris, r, any_hit, h, c);
    }
};

struct bvh2_own_traversal {
    const as_bvh2o_node_t *nodes;
    const as_tri4_t *tris;
    __device__ void trace(const as_ray_pre_t *r, int any_hit, as_hit_rec_t *h, as_trace_counters_t *c) const
    {
        as_bvh2o_trace(nodes, tris, r, any_hit, h, c);
    }
};

struct cwbvh_traversal {
    const as_cwbvh_node_t *nodes;
    const as_tri4_t *tris;
    __device__ void trace(const as_ray_pre_t *r, int any_hit, as_hit_rec_t *h, as_trace_counters_t *c) const
    {
        as_cwbvh_trace(nodes, tris, r, any_hit, h, c);
    }
};

struct kd_traversal {
    const as_kd_node_t *nodes;
    const uint32_t *prims;
    const as_tri4_t *tris;
    float box[6];
    __device__ void trace(const as_ray_pre_t *r, int any_hit, as_hit_rec_t *h, as_trace_counters_t *c) const
    {
        as_kd_trace(nodes, prims, tris, box, r, any_hit, h, c);
    }
};

struct kd_ropes_traversal {
    const as_kd_node_t *nodes;
    const uint32_t *prims;
    const as_tri4_t *tris;
    const as_kd_ropes_t *ropes;
    const as_kd_leaf_box_t *leaf_boxes;
    uint32_t leaf_count;
    float box[6];
    __device__ void trace(const as_ray_pre_t *r, int any_hit, as_hit_rec_t *h, as_trace_counters_t *c) const
    {
        as_kd_ropes_trace(nodes, prims, tris, ropes, leaf_boxes, leaf_count, box, r, any_hit, h, c);
    }
};

struct bih_traversal {
    const as_bih_node_t *nodes;
    const uint32_t *prims;
    const as_tri4_t *tris;
    float lo[3], hi[3];
    __device__ void trace(const as_ray_pre_t *r, int any_hit, as_hit_rec_t *h, as_trace_counters_t *c) const
    {
        as_bih_trace(nodes, prims, tris, lo, hi, r, any_hit, h, c);
    }
};

struct grid_traversal {
    const as_grid_header_t *header;
    const uint32_t *offsets, *prims;
    const as_tri4_t *tris;
    __device__ void trace(const as_ray_pre_t *r, int any_hit, as_hit_rec_t *h, as_trace_counters_t *c) const
    {
        as_grid_trace(header, offsets, prims, tris, r, any_hit, h, c);
    }
};

struct octree_traversal {
    const as_octree_header_t *header;
    const as_octree_node_t *nodes;
    const uint32_t *prims;
    const as_tri4_t *tris;
    __device__ void trace(const as_ray_pre_t *r, int any_hit, as_hit_rec_t *h, as_trace_counters_t *c) const
    {
        as_octree_trace(header, nodes, prims, tris, r, any_hit, h, c);
    }
};

// Blocks of 128 threads each multiprocessor must hold at once, per
// traversal: it caps the registers per thread at 65536 / (128 x this), 64
// for 8, 72 for 7, 80 for 6. Fewer registers mean more warps to hide memory
// latency but spills; each value is the fastest of 5 to 8 measured on the
// H100 (docs/results/tuning.md, step 2). AS_TRACE_MIN_BLOCKS, when defined,
// sets them all, to measure.
template <class T> struct trace_min_blocks { static constexpr int value = 8; };
template <> struct trace_min_blocks<bvh2_traversal> { static constexpr int value = 6; };
template <> struct trace_min_blocks<cwbvh_traversal> { static constexpr int value = 6; };
template <> struct trace_min_blocks<bih_traversal> { static constexpr int value = 7; };
template <> struct trace_min_blocks<grid_traversal> { static constexpr int value = 7; };
#ifdef AS_TRACE_MIN_BLOCKS
#define AS_MIN_BLOCKS(T) AS_TRACE_MIN_BLOCKS
#else
#define AS_MIN_BLOCKS(T) trace_min_blocks<T>::value
#endif

// One ray; STATS adds the per-ray counters (a separate instantiation, so the
// timed kernel carries no counting code at all), and FLAGS, the ray flags, is
// a constant too, so that the float intersector's kernel carries no code or
// registers of the double one.
template <class T, bool STATS, int FLAGS>
__device__ __forceinline__ void trace_one(const T &trav, const device_ray *__restrict__ rays,
                                          float4 *__restrict__ hits, size_t i, int any_hit, device_counters *counters)
{
    const int ray_flags = FLAGS;
    const float4 a = __ldg(&rays[i].a), b = __ldg(&rays[i].b);
    const float org[3] = {a.x, a.y, a.z}, dir[3] = {b.x, b.y, b.z};
    as_ray_pre_t pre;
    as_hit_rec_t h;
    as_trace_counters_t ctr = {0, 0};
    if (as_ray_prepare(org, a.w, dir, b.w, ray_flags, &pre))
        trav.trace(&pre, any_hit, &h, STATS ? &ctr : nullptr);
    else
        as_hit_rec_miss(&h);
    hits[i] = make_float4(h.t, __uint_as_float(h.prim), h.u, h.v);
    if (STATS) {
        atomicAdd(&counters->steps, (unsigned long long)ctr.node_visits);
        atomicAdd(&counters->tests, (unsigned long long)ctr.tri_tests);
        atomicMax(&counters->steps_max, ctr.node_visits);
        atomicMax(&counters->tests_max, ctr.tri_tests);
        if (counters->ray_steps) counters->ray_steps[i] = ctr.node_visits;
    }
}

template <class T, bool STATS, int FLAGS>
__global__ void __launch_bounds__(128, AS_MIN_BLOCKS(T)) kernel_thread_per_ray(const T trav, const device_ray *__restrict__ rays, float4 *__restrict__ hits,
                                      size_t count, int any_hit, device_counters *counters)
{
    const size_t i = (size_t)blockIdx.x * blockDim.x + threadIdx.x;
    if (i < count) trace_one<T, STATS, FLAGS>(trav, rays, hits, i, any_hit, counters);
}

// Persistent threads (Aila & Laine 2009): a grid that fills the GPU once;
// each warp takes `batch` rays per atomic from a global counter, so warps
// that finish early take more work instead of idling at the tail.
template <class T, bool STATS, int FLAGS>
__global__ void __launch_bounds__(128, AS_MIN_BLOCKS(T)) kernel_persistent(const T trav, const device_ray *__restrict__ rays, float4 *__restrict__ hits,
                                  size_t count, int any_hit, unsigned long long *next, unsigned batch,
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
            if (i < count) trace_one<T, STATS, FLAGS>(trav, rays, hits, i, any_hit, counters);
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

extern "C" int as_gpu_create_context(void)
{
    // cudaFree(0) is the documented way to make the runtime create it.
    if (cudaFree(0) != cudaSuccess) {
        cudaGetLastError();
        return 0;
    }
    return 1;
}

#define CUDA_TRY(call, what)                                                 \
    do {                                                                     \
        const cudaError_t _e = (call);                                       \
        if (_e != cudaSuccess) { err = cuda_fail(_e, what); goto done; }     \
    } while (0)

extern "C" double as_now_ms(void);

extern "C" uint64_t as_gpu_free_memory(void)
{
    size_t free_bytes = 0, total = 0;
    if (cudaMemGetInfo(&free_bytes, &total) != cudaSuccess) {
        cudaGetLastError();
        return 0;
    }
    return free_bytes;
}

namespace {

// The pinned pipeline: a few host threads, each with two pinned staging
// buffers and a stream of its own, take chunks of the sections in turn,
// copy one into a buffer while the other buffer's upload runs, and upload
// it asynchronously. Copies from the page cache and uploads over PCIe then
// overlap on every thread, and no thread waits for another.
// Measured on the H100 host with a 981 MB file in the page cache, four
// rounds interleaved (docs/results/2026-11-22-load-csum-h100.md): eight
// threads with 2 MiB buffers upload at 26-28 GB/s, four with 8 MiB (the
// earlier default) at 14-18; more than eight threads, or larger buffers, are
// slower.
constexpr unsigned kPipeThreads = 8;
constexpr unsigned kPipeChunkMiB = 2;

struct pipe_chunk {
    int section;
    uint64_t offset;
    size_t bytes;
};

struct pipe_job {
    void *const *device;
    const void *const *host;
    std::vector<pipe_chunk> chunks;
    unsigned char *arena = nullptr; // two pinned buffers per thread, one allocation
    size_t chunk_bytes = 0;
    std::atomic<size_t> next{0};
    std::atomic<unsigned> slot{0};
    std::atomic<int> failed{0};
    cudaError_t error = cudaSuccess;
    const char *what = nullptr;
    std::mutex lock;
};

void pipe_fail(pipe_job *job, cudaError_t e, const char *what)
{
    std::lock_guard<std::mutex> g(job->lock);
    if (!job->failed.exchange(1)) {
        job->error = e;
        job->what = what;
    }
}

void pipe_worker(pipe_job *job)
{
    const unsigned me = job->slot.fetch_add(1);
    void *buf[2] = {job->arena + (2 * (size_t)me) * job->chunk_bytes, job->arena + (2 * (size_t)me + 1) * job->chunk_bytes};
    cudaEvent_t ev[2] = {nullptr, nullptr};
    cudaStream_t stream = nullptr;
    cudaError_t e = cudaStreamCreateWithFlags(&stream, cudaStreamNonBlocking);
    for (int b = 0; b < 2 && e == cudaSuccess; ++b) e = cudaEventCreateWithFlags(&ev[b], cudaEventDisableTiming);
    if (e != cudaSuccess) pipe_fail(job, e, "pinned pipeline set-up");
    for (size_t k = 0; e == cudaSuccess && !job->failed.load();) {
        const size_t i = job->next.fetch_add(1);
        if (i >= job->chunks.size()) break;
        const pipe_chunk &c = job->chunks[i];
        const int b = (int)(k & 1);
        // The buffer is free again once its previous upload finished.
        if (k >= 2 && (e = cudaEventSynchronize(ev[b])) != cudaSuccess) break;
        memcpy(buf[b], static_cast<const unsigned char *>(job->host[c.section]) + c.offset, c.bytes);
        e = cudaMemcpyAsync(static_cast<unsigned char *>(job->device[c.section]) + c.offset, buf[b], c.bytes,
                            cudaMemcpyHostToDevice, stream);
        if (e == cudaSuccess) e = cudaEventRecord(ev[b], stream);
        ++k;
    }
    if (stream) {
        const cudaError_t s2 = cudaStreamSynchronize(stream);
        if (e == cudaSuccess) e = s2;
    }
    if (e != cudaSuccess) pipe_fail(job, e, "pipelined upload");
    for (int b = 0; b < 2; ++b)
        if (ev[b]) cudaEventDestroy(ev[b]);
    if (stream) cudaStreamDestroy(stream);
}

as_error_t upload_pinned_pipeline(void *const *device, const void *const *host, const uint64_t *bytes, int count,
                                  unsigned want_threads, unsigned chunk_mib)
{
    pipe_job job;
    job.device = device;
    job.host = host;
    job.chunk_bytes = (size_t)(chunk_mib ? std::min(chunk_mib, 256u) : kPipeChunkMiB) << 20;
    for (int sct = 0; sct < count; ++sct)
        for (uint64_t off = 0; off < bytes[sct]; off += job.chunk_bytes)
            job.chunks.push_back({sct, off, (size_t)std::min<uint64_t>(job.chunk_bytes, bytes[sct] - off)});
    const unsigned threads = (unsigned)std::min<size_t>(want_threads ? std::min(want_threads, 64u) : kPipeThreads,
                                                        std::max<size_t>(job.chunks.size(), 1));
    // Pinning costs about as much per byte as copying: one allocation, sized
    // for the threads that will run, instead of two per thread.
    cudaError_t e = cudaHostAlloc(reinterpret_cast<void **>(&job.arena), 2 * (size_t)threads * job.chunk_bytes,
                                  cudaHostAllocDefault);
    if (e != cudaSuccess) return cuda_fail(e, "pinned pipeline buffers");
    std::vector<std::thread> pool;
    try {
        for (unsigned t = 1; t < threads; ++t) pool.emplace_back(pipe_worker, &job);
    } catch (...) {
        // Fewer threads than asked: the ones started and this one do it all.
    }
    pipe_worker(&job);
    for (std::thread &t : pool) t.join();
    cudaFreeHost(job.arena);
    if (job.failed.load()) return cuda_fail(job.error, job.what);
    return AS_OK;
}

} // namespace

extern "C" void as_gpu_release(as_gpu_resident_t *g)
{
    if (!g) return;
    if (g->registered) {
        cudaHostUnregister(const_cast<void *>(g->registered));
    }
    if (!g->info.zero_copy)
        for (int i = 0; i < g->section_count; ++i) cudaFree(g->device[i]);
    delete g;
}

extern "C" as_error_t as_gpu_upload(const void *const *sections, const uint64_t *bytes, int count, int zero_copy,
                                    int method, unsigned pipe_threads, unsigned pipe_chunk_mib, const void *map_base,
                                    uint64_t map_size, as_gpu_resident_t **out)
{
    as_error_t err = AS_OK;
    as_gpu_resident_t *g = new (std::nothrow) as_gpu_resident_t();
    if (!g) return as_set_error(AS_ERROR_OUT_OF_MEMORY, "out of memory for the GPU structure record");
    g->section_count = count;
    uint64_t total = 0;
    for (int i = 0; i < count; ++i) {
        g->bytes[i] = bytes[i];
        total += bytes[i];
    }
    const double t0 = as_now_ms();
    if (zero_copy || method == AS_UPLOAD_REGISTERED) {
        // Registering needs page-aligned ranges: the whole mapping is.
        if (!map_base) {
            delete g;
            return as_set_error(AS_ERROR_UNSUPPORTED, "in-place GPU access needs a structure loaded from a file");
        }
        CUDA_TRY(cudaHostRegister(const_cast<void *>(map_base), map_size, cudaHostRegisterMapped | cudaHostRegisterReadOnly),
                 "cudaHostRegister of the mapped file");
        g->registered = map_base;
    }
    if (zero_copy) {
        for (int i = 0; i < count; ++i)
            CUDA_TRY(cudaHostGetDevicePointer(&g->device[i], const_cast<void *>(sections[i]), 0),
                     "cudaHostGetDevicePointer");
        g->info.zero_copy = true;
        g->info.method = "zero-copy";
    } else {
        for (int i = 0; i < count; ++i)
            CUDA_TRY(cudaMalloc(&g->device[i], bytes[i] ? bytes[i] : 64), "cudaMalloc of a section");
        if (method == AS_UPLOAD_PINNED_PIPELINE) {
            err = upload_pinned_pipeline(g->device, sections, bytes, count, pipe_threads, pipe_chunk_mib);
            if (err != AS_OK) goto done;
            g->info.method = "pinned pipeline";
        } else {
            for (int i = 0; i < count; ++i)
                CUDA_TRY(cudaMemcpy(g->device[i], sections[i], bytes[i], cudaMemcpyHostToDevice), "section upload");
            g->info.method = method == AS_UPLOAD_REGISTERED ? "registered" : "pageable";
        }
        if (g->registered) {
            cudaHostUnregister(const_cast<void *>(g->registered));
            g->registered = nullptr;
        }
    }
    g->info.bytes = total;
    g->info.upload_ms = as_now_ms() - t0;
    g->info.gb_per_s = g->info.upload_ms > 0 ? (double)total / (g->info.upload_ms * 1e6) : 0.0;
done:
    if (err != AS_OK) {
        as_gpu_release(g);
        return err;
    }
    *out = g;
    return AS_OK;
}

namespace {

template <int FLAGS, class T>
as_error_t launch_traversal_flags(const T &trav, const as_gpu_resident_t *g, const as_ray_t *rays, size_t count,
                            as_hit_t *hits, const as_gpu_launch_t *launch, as_trace_timing_t *timing)
{
    as_error_t err = AS_OK;
    void *d_rays = nullptr, *d_hits = nullptr;
    unsigned long long *d_next = nullptr;
    device_counters *d_counters = nullptr;
    unsigned *d_ray_steps = nullptr;
    cudaEvent_t ev0 = nullptr, ev1 = nullptr;
    std::vector<float> times;
    const int block = 128;
    const unsigned grid_all = (unsigned)((count + block - 1) / block);
    unsigned grid_persistent = 0;
    int per_sm = 0;
    const unsigned batch = launch->batch ? launch->batch : 32;
    cudaDeviceProp prop;
    device_counters counters = {0, 0, 0, 0, nullptr};
    const device_ray *r = nullptr;
    float4 *h = nullptr;
    CUDA_TRY(cudaGetDeviceProperties(&prop, 0), "cudaGetDeviceProperties");
    CUDA_TRY(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, kernel_persistent<T, false, FLAGS>, block, 0),
             "occupancy query");
    grid_persistent = (unsigned)(prop.multiProcessorCount * (per_sm > 0 ? per_sm : 1));
    CUDA_TRY(cudaEventCreate(&ev0), "cudaEventCreate");
    CUDA_TRY(cudaEventCreate(&ev1), "cudaEventCreate");
    CUDA_TRY(cudaMalloc(&d_rays, count * sizeof(as_ray_t) + 32), "cudaMalloc rays");
    CUDA_TRY(cudaMalloc(&d_hits, count * sizeof(as_hit_t) + 16), "cudaMalloc hits");
    CUDA_TRY(cudaMalloc(&d_next, sizeof(unsigned long long)), "cudaMalloc counter");
    CUDA_TRY(cudaMalloc(&d_counters, sizeof(device_counters)), "cudaMalloc counters");
    CUDA_TRY(cudaMemcpy(d_rays, rays, count * sizeof(as_ray_t), cudaMemcpyHostToDevice), "upload of rays");
    r = (const device_ray *)d_rays;
    h = (float4 *)d_hits;
    if (count == 0) goto copy_back;
    // One warm-up launch, then the timed ones; the counter reset is outside
    // the timed interval.
    for (unsigned run = 0; run <= launch->timed_runs; ++run) {
        CUDA_TRY(cudaMemset(d_next, 0, sizeof(unsigned long long)), "cudaMemset");
        CUDA_TRY(cudaEventRecord(ev0), "cudaEventRecord");
        if (launch->persistent)
            kernel_persistent<T, false, FLAGS><<<grid_persistent, block>>>(trav, r, h, count, launch->any_hit, d_next,
                                                                            batch, nullptr);
        else
            kernel_thread_per_ray<T, false, FLAGS><<<grid_all, block>>>(trav, r, h, count, launch->any_hit, nullptr);
        CUDA_TRY(cudaGetLastError(), "kernel launch");
        CUDA_TRY(cudaEventRecord(ev1), "cudaEventRecord");
        CUDA_TRY(cudaEventSynchronize(ev1), "traversal kernel");
        float ms = 0;
        CUDA_TRY(cudaEventElapsedTime(&ms, ev0, ev1), "cudaEventElapsedTime");
        if (run > 0) times.push_back(ms);
    }
    if (launch->collect_stats) {
        if (launch->ray_steps)
            CUDA_TRY(cudaMalloc(&d_ray_steps, count * sizeof(unsigned) + 4), "cudaMalloc per-ray steps");
        counters.ray_steps = d_ray_steps;
        CUDA_TRY(cudaMemcpy(d_counters, &counters, sizeof counters, cudaMemcpyHostToDevice), "counter reset");
        kernel_thread_per_ray<T, true, FLAGS><<<grid_all, block>>>(trav, r, h, count, launch->any_hit, d_counters);
        CUDA_TRY(cudaGetLastError(), "statistics kernel launch");
        CUDA_TRY(cudaMemcpy(&counters, d_counters, sizeof counters, cudaMemcpyDeviceToHost), "statistics download");
        if (d_ray_steps)
            CUDA_TRY(cudaMemcpy(launch->ray_steps, d_ray_steps, count * sizeof(unsigned), cudaMemcpyDeviceToHost),
                     "per-ray steps download");
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
        timing->upload_ms = g->info.upload_ms;
        timing->upload_bytes = g->info.bytes;
        snprintf(timing->device_name, sizeof timing->device_name, "%.80s (sm_%d%d, %d SMs)", prop.name, prop.major,
                 prop.minor, prop.multiProcessorCount);
    }
done:
    cudaFree(d_rays);
    cudaFree(d_hits);
    cudaFree(d_next);
    cudaFree(d_counters);
    cudaFree(d_ray_steps);
    if (ev0) cudaEventDestroy(ev0);
    if (ev1) cudaEventDestroy(ev1);
    return err;
}

// The ray flags become a template argument, so each kernel is compiled for
// one intersector.
template <class T>
as_error_t launch_traversal(const T &trav, const as_gpu_resident_t *g, const as_ray_t *rays, size_t count,
                            as_hit_t *hits, const as_gpu_launch_t *launch, as_trace_timing_t *timing)
{
    if (launch->ray_flags & AS_RAY_PRECISE)
        return launch_traversal_flags<AS_RAY_PRECISE>(trav, g, rays, count, hits, launch, timing);
    if (launch->ray_flags & AS_RAY_MOLLER_TRUMBORE)
        return launch_traversal_flags<AS_RAY_MOLLER_TRUMBORE>(trav, g, rays, count, hits, launch, timing);
    return launch_traversal_flags<0>(trav, g, rays, count, hits, launch, timing);
}

} // namespace

extern "C" as_error_t as_trace_gpu(uint32_t layout, const as_gpu_resident_t *g, const float bounds_lo[3],
                                   const float bounds_hi[3], const as_ray_t *rays, size_t count, as_hit_t *hits,
                                   const as_gpu_launch_t *launch, as_trace_timing_t *timing)
{
    // Device pointers come in the layout's section order (its ops table).
    switch (layout) {
    case AS_LAYOUT_BVH2_CHILD_BOUNDS: {
        const bvh2_traversal t = {(const as_bvh2_node_t *)g->device[0], (const as_tri4_t *)g->device[1]};
        return launch_traversal(t, g, rays, count, hits, launch, timing);
    }
    case AS_LAYOUT_BVH2_OWN_BOUNDS: {
        const bvh2_own_traversal t = {(const as_bvh2o_node_t *)g->device[0], (const as_tri4_t *)g->device[1]};
        return launch_traversal(t, g, rays, count, hits, launch, timing);
    }
    case AS_LAYOUT_BVH_CWBVH: {
        const cwbvh_traversal t = {(const as_cwbvh_node_t *)g->device[0], (const as_tri4_t *)g->device[1]};
        return launch_traversal(t, g, rays, count, hits, launch, timing);
    }
    case AS_LAYOUT_KD_STANDARD: {
        kd_traversal t = {(const as_kd_node_t *)g->device[0], (const uint32_t *)g->device[1],
                          (const as_tri4_t *)g->device[2], {0, 0, 0, 0, 0, 0}};
        for (int k = 0; k < 3; ++k) { t.box[k] = bounds_lo[k]; t.box[3 + k] = bounds_hi[k]; }
        return launch_traversal(t, g, rays, count, hits, launch, timing);
    }
    case AS_LAYOUT_KD_ROPES: {
        kd_ropes_traversal t = {(const as_kd_node_t *)g->device[0], (const uint32_t *)g->device[1],
                                (const as_tri4_t *)g->device[2], (const as_kd_ropes_t *)g->device[3],
                                (const as_kd_leaf_box_t *)g->device[4],
                                (uint32_t)(g->bytes[3] / sizeof(as_kd_ropes_t)), {0, 0, 0, 0, 0, 0}};
        for (int k = 0; k < 3; ++k) { t.box[k] = bounds_lo[k]; t.box[3 + k] = bounds_hi[k]; }
        return launch_traversal(t, g, rays, count, hits, launch, timing);
    }
    case AS_LAYOUT_BIH: {
        bih_traversal t = {(const as_bih_node_t *)g->device[0], (const uint32_t *)g->device[1],
                           (const as_tri4_t *)g->device[2], {0, 0, 0}, {0, 0, 0}};
        for (int k = 0; k < 3; ++k) { t.lo[k] = bounds_lo[k]; t.hi[k] = bounds_hi[k]; }
        return launch_traversal(t, g, rays, count, hits, launch, timing);
    }
    case AS_LAYOUT_GRID: {
        const grid_traversal t = {(const as_grid_header_t *)g->device[0], (const uint32_t *)g->device[1],
                                  (const uint32_t *)g->device[2], (const as_tri4_t *)g->device[3]};
        return launch_traversal(t, g, rays, count, hits, launch, timing);
    }
    case AS_LAYOUT_OCTREE: {
        const octree_traversal t = {(const as_octree_header_t *)g->device[0], (const as_octree_node_t *)g->device[1],
                                    (const uint32_t *)g->device[2], (const as_tri4_t *)g->device[3]};
        return launch_traversal(t, g, rays, count, hits, launch, timing);
    }
    default:
        return as_set_error(AS_ERROR_UNSUPPORTED, "no CUDA kernel for layout 0x%04x in this build", layout);
    }
}
