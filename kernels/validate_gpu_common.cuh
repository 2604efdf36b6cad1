// What the GPU validators (kernels/validate_*_gpu.cu) share. Each validator
// runs the checks of its layout's CPU validator over the uploaded sections
// with one thread per node, leaf, cell, PRIM entry or triangle; the order
// of a CPU walk is replaced by order-free checks:
// - "each node referenced once": every child index claims its node's slot
//   in a parent array with a compare-and-swap; a second claim is a shared
//   subtree or a cycle, an unclaimed node is unreachable;
// - "depth within the stack": pointer jumping over the parent array
//   (log2(levels) doublings) gives every node its depth; a node that has
//   not reached the root by then is too deep or on a cycle cut off from it;
// - "each entry in one leaf": leaves claim their entries the same way.
// A failure keeps the lowest (index << 8 | check) key, so the message names
// the same element on every run whatever the scheduling.
#ifndef AS_VALIDATE_GPU_COMMON_CUH
#define AS_VALIDATE_GPU_COMMON_CUH

#include "bvh2_layout.h"
#include "trace_gpu.h"

#include <cuda_runtime.h>

extern "C" as_error_t as_set_error(as_error_t code, const char *fmt, ...);

namespace {

// Check codes below GV_LAYOUT_CHECKS are shared (gv_report_shared names
// them); each validator numbers its own from GV_LAYOUT_CHECKS up. Lower
// codes win at one index.
enum gv_shared_check : unsigned {
    GV_TRIS_NOT_FINITE = 1, // TRIS triangle (index) has a non-finite vertex
    GV_TRIS_SOURCE,         // TRIS triangle (index) does not carry its own index
    GV_PRIM_RANGE,          // PRIM entry (index) refers past TRIS
    GV_TRI4_NOT_FINITE,     // TRI4 triangle (index) has a non-finite vertex
    GV_TRI4_SOURCE,         // TRI4 triangle (index) refers past the mesh
    GV_TRI4_TWICE,          // TRI4 triangle (index) is in two leaves
    GV_TRI4_OUTSIDE_LEAF,   // TRI4 triangle (index) lies outside its leaf's box
    GV_TRI4_IN_NO_LEAF,     // TRI4 triangle (index) is in no leaf
    GV_LAYOUT_CHECKS = 16,
};

const unsigned long long GV_NO_FAILURE = ~0ull;

// Device-side results: the first failure and a few counts each validator
// gives its own meaning.
// The counts are kept in GV_COUNT_SLOTS slots each on the device (the
// lanes of a warp add to different addresses, so millions of additions do not
// queue on one) and summed into count[] by gv_read.
#define GV_COUNT_SLOTS 32
struct gv_scratch {
    unsigned long long first_failure; // (index << 8) | check; GV_NO_FAILURE: none
    unsigned long long count[6];
    unsigned max_depth;
    unsigned pad;
    unsigned long long slot[6][GV_COUNT_SLOTS];
};

__device__ inline unsigned long long gv_thread_index()
{
    return blockIdx.x * (unsigned long long)blockDim.x + threadIdx.x;
}

__device__ inline void gv_fail(gv_scratch *s, unsigned check, unsigned long long index)
{
    atomicMin(&s->first_failure, (index << 8) | check);
}

// Adds v to count `which`. A plain atomic per thread, into the lane's own
// slot: a reduction over the threads that happen to be converged here
// (coalesced groups) is not safe after the callers' divergent loops, where
// lanes the active mask names may not have arrived, and it lost counts.
__device__ inline void gv_count(gv_scratch *s, int which, unsigned long long v)
{
    if (v) atomicAdd(&s->slot[which][threadIdx.x % GV_COUNT_SLOTS], v);
}

__device__ inline bool gv_finite(float x) { return isfinite(x); }

// Finite and lo <= hi on each axis; b = {lox, hix, loy, hiy, loz, hiz}.
__device__ inline bool gv_box_ok(const float b[6])
{
    return gv_finite(b[0]) && gv_finite(b[1]) && gv_finite(b[2]) && gv_finite(b[3]) && gv_finite(b[4]) &&
           gv_finite(b[5]) && b[0] <= b[1] && b[2] <= b[3] && b[4] <= b[5];
}

__device__ inline bool gv_box_inside(const float in[6], const float out[6])
{
    return in[0] >= out[0] && in[1] <= out[1] && in[2] >= out[2] && in[3] <= out[3] && in[4] >= out[4] &&
           in[5] <= out[5];
}

__device__ inline bool gv_tri_finite(const as_tri4_t &t)
{
    return gv_finite(t.v0.x) && gv_finite(t.v0.y) && gv_finite(t.v0.z) && gv_finite(t.v1.x) && gv_finite(t.v1.y) &&
           gv_finite(t.v1.z) && gv_finite(t.v2.x) && gv_finite(t.v2.y) && gv_finite(t.v2.z);
}

// The triangle's box, {lox, hix, loy, hiy, loz, hiz}.
__device__ inline void gv_tri_box(const as_tri4_t &t, float tb[6])
{
    tb[0] = fminf(fminf(t.v0.x, t.v1.x), t.v2.x);
    tb[1] = fmaxf(fmaxf(t.v0.x, t.v1.x), t.v2.x);
    tb[2] = fminf(fminf(t.v0.y, t.v1.y), t.v2.y);
    tb[3] = fmaxf(fmaxf(t.v0.y, t.v1.y), t.v2.y);
    tb[4] = fminf(fminf(t.v0.z, t.v1.z), t.v2.z);
    tb[5] = fmaxf(fmaxf(t.v0.z, t.v1.z), t.v2.z);
}

// Every vertex within [lo, hi] on every axis (the CPU's per-vertex test:
// the same comparisons, so the same refusals for NaN-free input).
__device__ inline bool gv_tri_within(const as_tri4_t &t, const float lo[3], const float hi[3])
{
    const float v[9] = {t.v0.x, t.v0.y, t.v0.z, t.v1.x, t.v1.y, t.v1.z, t.v2.x, t.v2.y, t.v2.z};
    for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k)
            if (v[3 * j + k] < lo[k] || v[3 * j + k] > hi[k]) return false;
    return true;
}

// TRIS of the BIH, octree, grid and KD layouts: entry i is source triangle i
// with finite vertices (as_spatial_validate_tris, kd_validate.c).
__global__ void gv_check_tris(const as_tri4_t *tris, unsigned long long count, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= count) return;
    const as_tri4_t t = tris[i];
    if (!gv_tri_finite(t)) gv_fail(s, GV_TRIS_NOT_FINITE, i);
    else if (__float_as_uint(t.v0.w) != (unsigned)i) gv_fail(s, GV_TRIS_SOURCE, i);
}

// Every PRIM entry inside TRIS (BIH, octree, grid).
__global__ void gv_check_prim(const unsigned *prim, unsigned long long count, unsigned long long tri_count,
                              gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i < count && prim[i] >= tri_count) gv_fail(s, GV_PRIM_RANGE, i);
}

// TRI4 of both BVH2 layouts: finite vertices, source indices within the
// mesh (as_bvh2_validate_tris).
__global__ void gv_check_tri4(const as_tri4_t *tris, unsigned long long count, unsigned mesh_triangles, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= count) return;
    const as_tri4_t t = tris[i];
    if (!gv_tri_finite(t)) gv_fail(s, GV_TRI4_NOT_FINITE, i);
    else if (__float_as_uint(t.v0.w) >= mesh_triangles) gv_fail(s, GV_TRI4_SOURCE, i);
}

// One BVH2 leaf whose range [first, first + count) is inside TRI4 and whose
// box is finite and ordered (as_bvh2_validate_leaf): it claims its
// triangles (`owner`, all ones at the start), each of which must lie in
// the box or, for an SBVH (clipped), overlap it.
__device__ inline void gv_tri4_leaf(const as_tri4_t *tris, unsigned long long first, unsigned long long count,
                                    const float b[6], int clipped, unsigned *owner, gv_scratch *s)
{
    for (unsigned long long t = first; t < first + count; ++t) {
        if (atomicExch(&owner[t], 0u) != 0xffffffffu) { gv_fail(s, GV_TRI4_TWICE, t); continue; }
        float tb[6];
        gv_tri_box(tris[t], tb);
        const bool ok = clipped ? tb[0] <= b[1] && tb[1] >= b[0] && tb[2] <= b[3] && tb[3] >= b[2] && tb[4] <= b[5] &&
                                      tb[5] >= b[4]
                                : gv_box_inside(tb, b);
        if (!ok) gv_fail(s, GV_TRI4_OUTSIDE_LEAF, t);
    }
}

__global__ void gv_check_tri4_owned(const unsigned *owner, unsigned long long tri_count, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i < tri_count && owner[i] == 0xffffffffu) gv_fail(s, GV_TRI4_IN_NO_LEAF, i);
}

// Pointer jumping. Start: each node's known ancestor is its parent at
// distance 1; the root (node 0) is its own at 0. A non-root node without a
// parent fails with `unreachable`.
__global__ void gv_jump_start(const int *parent, unsigned long long node_count, int *anc, unsigned *depth,
                              unsigned unreachable, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    if (i == 0) { anc[0] = 0; depth[0] = 0; return; }
    const int p = parent[i];
    if (p < 0) gv_fail(s, unreachable, i);
    anc[i] = p < 0 ? 0 : p;
    depth[i] = 1;
}

// One doubling: each node's known ancestor moves to that ancestor's, and
// the distances add (the root's is 0 and it is its own ancestor).
__global__ void gv_jump_round(const int *anc, const unsigned *depth, unsigned long long node_count, int *anc_out,
                              unsigned *depth_out)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    const int a = anc[i];
    anc_out[i] = anc[a];
    depth_out[i] = depth[i] + depth[a];
}

inline unsigned gv_blocks(unsigned long long n) { return (unsigned)((n + 255) / 256); }

// The number of doublings after which every node within `levels` of the
// root has reached it.
inline int gv_rounds(unsigned levels)
{
    int r = 0;
    while ((1u << r) < levels) ++r;
    return r;
}

// Device allocations of one validation, freed together when it returns.
class gv_memory {
  public:
    gv_memory() = default;
    gv_memory(const gv_memory &) = delete;
    gv_memory &operator=(const gv_memory &) = delete;
    ~gv_memory()
    {
        for (int i = 0; i < n_; ++i) cudaFree(p_[i]);
    }
    // `count` elements (at least one), every byte set to `fill` unless it
    // is negative; keeps the first error.
    template <class T> T *get(unsigned long long count, int fill = -1)
    {
        T *p = nullptr;
        if (err_ != cudaSuccess || n_ == max_) {
            if (err_ == cudaSuccess) err_ = cudaErrorMemoryAllocation;
            return nullptr;
        }
        const size_t bytes = sizeof(T) * (count ? count : 1);
        err_ = cudaMalloc(&p, bytes);
        if (err_ != cudaSuccess) return nullptr;
        p_[n_++] = p;
        if (fill >= 0) err_ = cudaMemset(p, fill, bytes);
        return p;
    }
    cudaError_t error() const { return err_; }

  private:
    static const int max_ = 16;
    void *p_[max_] = {};
    int n_ = 0;
    cudaError_t err_ = cudaSuccess;
};

// A fresh scratch on the device (no failure, zero counts).
inline gv_scratch *gv_new_scratch(gv_memory &mem)
{
    gv_scratch *d = mem.get<gv_scratch>(1, 0);
    if (d && mem.error() == cudaSuccess) {
        const unsigned long long none = GV_NO_FAILURE;
        const cudaError_t ce = cudaMemcpy(&d->first_failure, &none, sizeof none, cudaMemcpyHostToDevice);
        if (ce != cudaSuccess) return nullptr;
    }
    return mem.error() == cudaSuccess ? d : nullptr;
}

// Waits for the kernels so far and reads the scratch back; a launch or
// execution error comes back as the CUDA error.
inline cudaError_t gv_read(const gv_scratch *d, gv_scratch *h)
{
    cudaError_t ce = cudaMemcpy(h, d, sizeof *h, cudaMemcpyDeviceToHost);
    if (ce == cudaSuccess) ce = cudaGetLastError();
    for (int k = 0; k < 6; ++k) {
        h->count[k] = 0;
        for (int j = 0; j < GV_COUNT_SLOTS; ++j) h->count[k] += h->slot[k][j];
    }
    return ce;
}

// Pointer jumping over `parent` for `levels` levels; returns which of the
// two buffer pairs holds the result.
inline int gv_depths(const int *parent, unsigned long long node_count, unsigned levels, unsigned unreachable,
                     int *anc[2], unsigned *depth[2], gv_scratch *s)
{
    gv_jump_start<<<gv_blocks(node_count), 256>>>(parent, node_count, anc[0], depth[0], unreachable, s);
    int cur = 0;
    for (int round = 0; round < gv_rounds(levels); ++round, cur ^= 1)
        gv_jump_round<<<gv_blocks(node_count), 256>>>(anc[cur], depth[cur], node_count, anc[cur ^ 1], depth[cur ^ 1]);
    return cur;
}

inline as_error_t gv_no_memory(const char *name, cudaError_t ce)
{
    return as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: no device memory to validate on the GPU (%s)", name,
                        cudaGetErrorString(ce));
}

inline as_error_t gv_cuda_failed(const char *name, cudaError_t ce)
{
    return as_set_error(AS_ERROR_NO_DEVICE, "%s: validation on the GPU failed: %s", name, cudaGetErrorString(ce));
}

// The message of a shared check; `key` has one of the gv_shared_check codes.
// `tri_count`: TRIS's entries; `mesh_triangles`: META's source triangles.
inline as_error_t gv_report_shared(const char *name, unsigned long long key, unsigned long long tri_count,
                                   unsigned mesh_triangles)
{
    const unsigned long long index = key >> 8;
    switch ((unsigned)(key & 0xff)) {
    case GV_TRIS_NOT_FINITE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRIS triangle %llu has a non-finite vertex", name, index);
    case GV_TRIS_SOURCE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRIS triangle %llu does not carry its own source index",
                            name, index);
    case GV_PRIM_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: PRIM entry %llu refers to a triangle outside the %llu of TRIS",
                            name, index, tri_count);
    case GV_TRI4_NOT_FINITE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 triangle %llu has a non-finite vertex", name, index);
    case GV_TRI4_SOURCE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: TRI4 triangle %llu refers to a source triangle beyond the %u META says the mesh has",
                            name, index, mesh_triangles);
    case GV_TRI4_TWICE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 triangle %llu is in two leaves", name, index);
    case GV_TRI4_OUTSIDE_LEAF:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 triangle %llu lies outside the box of its leaf", name,
                            index);
    case GV_TRI4_IN_NO_LEAF:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 triangle %llu is in no leaf", name, index);
    default:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: invalid structure", name);
    }
}

// META's counts against a BVH2 tree's, as on the CPU
// (as_bvh2_validate_counts): `nodes` counts what META's node count means
// for the layout, `section` names it.
inline as_error_t gv_bvh2_counts(const char *name, const char *section, unsigned long long nodes,
                                 unsigned long long leaves, unsigned long long references, unsigned max_leaf_depth,
                                 const as_gpu_bvh2_expect_t *e)
{
    if (references != e->tri_count)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 holds %llu triangles but the leaves reference %llu",
                            name, (unsigned long long)e->tri_count, references);
    if (e->meta.node_count != nodes)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META says %llu nodes but %s holds %llu", name,
                            (unsigned long long)e->meta.node_count, section, nodes);
    if (e->meta.leaf_count != leaves)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META leaf count is %llu but the tree has %llu leaves", name,
                            (unsigned long long)e->meta.leaf_count, leaves);
    if (e->meta.reference_count != references || e->meta.empty_leaf_count != 0)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: META reference count %llu and empty leaf count %llu, but the leaves hold %llu "
                            "references and none is empty",
                            name, (unsigned long long)e->meta.reference_count,
                            (unsigned long long)e->meta.empty_leaf_count, references);
    if (e->meta.max_depth != max_leaf_depth)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META says max depth %u but the deepest leaf is at %u", name,
                            e->meta.max_depth, max_leaf_depth);
    return AS_OK;
}

// The leaves' references against PRIM, and META's counts against the
// tree's (as_spatial_validate_counts), for the BIH and the octree.
inline as_error_t gv_spatial_counts(const char *name, unsigned long long inner, unsigned long long leaves,
                                    unsigned long long empty, unsigned long long refs, unsigned max_depth,
                                    const as_gpu_spatial_expect_t *e)
{
    if (refs != e->prim_count)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: the leaves hold %llu references but PRIM has %llu entries",
                            name, refs, (unsigned long long)e->prim_count);
    if (e->meta.node_count == inner && e->meta.leaf_count == leaves && e->meta.empty_leaf_count == empty &&
        e->meta.reference_count == refs && e->meta.max_depth == max_depth)
        return AS_OK;
    return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                        "%s: META says %llu inner nodes, %llu leaves, %llu empty, %llu references, depth %u; the tree "
                        "has %llu, %llu, %llu, %llu, %u",
                        name, (unsigned long long)e->meta.node_count, (unsigned long long)e->meta.leaf_count,
                        (unsigned long long)e->meta.empty_leaf_count, (unsigned long long)e->meta.reference_count,
                        e->meta.max_depth, inner, leaves, empty, refs, max_depth);
}

// The source triangle of a PRIM entry, for a message.
inline unsigned gv_prim_at(const unsigned *prim, unsigned long long index)
{
    unsigned t = 0;
    cudaMemcpy(&t, prim + index, sizeof t, cudaMemcpyDeviceToHost);
    return t;
}

} // namespace

#endif
