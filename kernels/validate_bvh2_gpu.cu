// Structural validation of a BVH2 child-bounds structure on the GPU, after
// its sections are uploaded and before any traversal kernel reads them: the
// same promises as the CPU's as_bvh2_validate (libas/src/bvh2_validate.c),
// checked by one thread per node and per triangle instead of one walk.
//
// The walk's order-dependent checks become order-free ones:
// - "each node referenced once": every child index claims its node's parent
//   slot with a compare-and-swap; a second claim is a shared subtree or a
//   cycle, an unclaimed node is unreachable;
// - "depth within the stack": pointer jumping over the parent array (six
//   doublings reach 64 levels) gives every node its depth; a node that has
//   not reached the root by then is too deep or on a cycle cut off from it;
// - "each triangle in one leaf": leaves claim their triangles the same way.
// A failure keeps the lowest (index, check) key, so the message names the
// same node or triangle on every run.
#include "bvh2_layout.h"
#include "trace_gpu.h"

#include <cuda_runtime.h>

#include <cstdio>

extern "C" as_error_t as_set_error(as_error_t code, const char *fmt, ...);

namespace {

enum check : unsigned {
    TRI_NOT_FINITE = 1,
    TRI_PRIM_RANGE,
    INNER_WITH_COUNT,
    CHILD_RANGE,
    NODE_TWICE,
    CHILD_BOX,
    GRANDCHILD_OUTSIDE,
    LEAF_RANGE,
    LEAF_BOX,
    TRI_TWICE,
    TRI_OUTSIDE_LEAF,
    NODE_UNREACHABLE,
    NODE_TOO_DEEP,
    TRI_IN_NO_LEAF,
};

struct scratch {
    unsigned long long first_failure; // (index << 8) | check; ~0: none
    unsigned long long leaves, references;
    unsigned max_leaf_depth;
};

__device__ void fail(scratch *s, unsigned check, unsigned long long index)
{
    atomicMin(&s->first_failure, (index << 8) | check);
}

__device__ bool finite(float x) { return isfinite(x); }

__device__ bool box_ok(const float b[6])
{
    return finite(b[0]) && finite(b[1]) && finite(b[2]) && finite(b[3]) && finite(b[4]) && finite(b[5]) &&
           b[0] <= b[1] && b[2] <= b[3] && b[4] <= b[5];
}

__device__ bool box_inside(const float in[6], const float out[6])
{
    return in[0] >= out[0] && in[1] <= out[1] && in[2] >= out[2] && in[3] <= out[3] && in[4] >= out[4] &&
           in[5] <= out[5];
}

__device__ void child_box(const as_bvh2_node_t &n, int k, float b[6])
{
    if (k == 0) { b[0] = n.xy0.x; b[1] = n.xy0.y; b[2] = n.xy0.z; b[3] = n.xy0.w; b[4] = n.z01.x; b[5] = n.z01.y; }
    else        { b[0] = n.xy1.x; b[1] = n.xy1.y; b[2] = n.xy1.z; b[3] = n.xy1.w; b[4] = n.z01.z; b[5] = n.z01.w; }
}

__global__ void check_triangles(const as_tri4_t *tris, unsigned long long count, unsigned mesh_triangles, scratch *s)
{
    const unsigned long long i = blockIdx.x * (unsigned long long)blockDim.x + threadIdx.x;
    if (i >= count) return;
    const as_tri4_t t = tris[i];
    if (!finite(t.v0.x) || !finite(t.v0.y) || !finite(t.v0.z) || !finite(t.v1.x) || !finite(t.v1.y) ||
        !finite(t.v1.z) || !finite(t.v2.x) || !finite(t.v2.y) || !finite(t.v2.z))
        fail(s, TRI_NOT_FINITE, i);
    else if (__float_as_uint(t.v0.w) >= mesh_triangles)
        fail(s, TRI_PRIM_RANGE, i);
}

// One thread per node: its two children. Inner children claim their parent
// slot and must hold their own children's boxes; leaves claim their
// triangles, which must lie in (SBVH: overlap) the leaf's box.
__global__ void check_nodes(const as_bvh2_node_t *nodes, unsigned long long node_count, const as_tri4_t *tris,
                            unsigned long long tri_count, int clipped, int *parent, unsigned *owner, scratch *s)
{
    const unsigned long long i = blockIdx.x * (unsigned long long)blockDim.x + threadIdx.x;
    if (i >= node_count) return;
    const as_bvh2_node_t n = nodes[i];
    for (int k = 0; k < 2; ++k) {
        float b[6];
        child_box(n, k, b);
        const int c = n.child[k];
        const unsigned long long where = 2 * i + k;
        if (c >= 0) {
            if (n.count[k] != 0) { fail(s, INNER_WITH_COUNT, where); continue; }
            if (c == 0 || (unsigned long long)c >= node_count) { fail(s, CHILD_RANGE, where); continue; }
            if (!box_ok(b)) { fail(s, CHILD_BOX, where); continue; }
            if (atomicCAS(&parent[c], -1, (int)i) != -1) { fail(s, NODE_TWICE, (unsigned long long)c); continue; }
            const as_bvh2_node_t cn = nodes[c];
            for (int g = 0; g < 2; ++g) {
                float gb[6];
                child_box(cn, g, gb);
                const bool empty = cn.child[g] < 0 && cn.count[g] == 0;
                if (!empty && !box_inside(gb, b)) fail(s, GRANDCHILD_OUTSIDE, 2ull * (unsigned long long)c + g);
            }
            continue;
        }
        const unsigned long long first = (unsigned)~c, count = n.count[k];
        if (count == 0) continue; // an empty child: never entered
        if (first > tri_count || count > tri_count - first) { fail(s, LEAF_RANGE, where); continue; }
        if (!box_ok(b)) { fail(s, LEAF_BOX, where); continue; }
        atomicAdd(&s->leaves, 1ull);
        atomicAdd(&s->references, count);
        for (unsigned long long t = first; t < first + count; ++t) {
            if (atomicExch(&owner[t], 0u) != 0xffffffffu) { fail(s, TRI_TWICE, t); continue; }
            const as_tri4_t tri = tris[t];
            const float tb[6] = {fminf(fminf(tri.v0.x, tri.v1.x), tri.v2.x), fmaxf(fmaxf(tri.v0.x, tri.v1.x), tri.v2.x),
                                 fminf(fminf(tri.v0.y, tri.v1.y), tri.v2.y), fmaxf(fmaxf(tri.v0.y, tri.v1.y), tri.v2.y),
                                 fminf(fminf(tri.v0.z, tri.v1.z), tri.v2.z), fmaxf(fmaxf(tri.v0.z, tri.v1.z), tri.v2.z)};
            const bool ok = clipped ? tb[0] <= b[1] && tb[1] >= b[0] && tb[2] <= b[3] && tb[3] >= b[2] &&
                                          tb[4] <= b[5] && tb[5] >= b[4]
                                    : box_inside(tb, b);
            if (!ok) fail(s, TRI_OUTSIDE_LEAF, t);
        }
    }
}

__global__ void jump_start(const int *parent, unsigned long long node_count, int *anc, unsigned *depth, scratch *s)
{
    const unsigned long long i = blockIdx.x * (unsigned long long)blockDim.x + threadIdx.x;
    if (i >= node_count) return;
    if (i == 0) { anc[0] = 0; depth[0] = 0; return; }
    const int p = parent[i];
    if (p < 0) fail(s, NODE_UNREACHABLE, i);
    anc[i] = p < 0 ? 0 : p;
    depth[i] = 1;
}

// One doubling: each node's known ancestor moves to that ancestor's, and
// the distances add (the root's is 0 and it is its own ancestor).
__global__ void jump_round(const int *anc, const unsigned *depth, unsigned long long node_count, int *anc_out,
                           unsigned *depth_out)
{
    const unsigned long long i = blockIdx.x * (unsigned long long)blockDim.x + threadIdx.x;
    if (i >= node_count) return;
    const int a = anc[i];
    anc_out[i] = anc[a];
    depth_out[i] = depth[i] + depth[a];
}

// Inner nodes at most AS_BVH2_MAX_DEPTH - 1 deep (the traversal stack), and
// the deepest leaf for META.
__global__ void check_depths(const as_bvh2_node_t *nodes, const int *anc, const unsigned *depth,
                             unsigned long long node_count, scratch *s)
{
    const unsigned long long i = blockIdx.x * (unsigned long long)blockDim.x + threadIdx.x;
    if (i >= node_count) return;
    if (anc[i] != 0 || depth[i] >= AS_BVH2_MAX_DEPTH) { fail(s, NODE_TOO_DEEP, i); return; }
    const as_bvh2_node_t n = nodes[i];
    for (int k = 0; k < 2; ++k)
        if (n.child[k] < 0 && n.count[k] != 0) atomicMax(&s->max_leaf_depth, depth[i] + 1);
}

__global__ void check_owned(const unsigned *owner, unsigned long long tri_count, scratch *s)
{
    const unsigned long long i = blockIdx.x * (unsigned long long)blockDim.x + threadIdx.x;
    if (i < tri_count && owner[i] == 0xffffffffu) fail(s, TRI_IN_NO_LEAF, i);
}

unsigned blocks_for(unsigned long long n) { return (unsigned)((n + 255) / 256); }

as_error_t report(const char *name, unsigned long long key, const as_gpu_bvh2_expect_t *e)
{
    const unsigned long long index = key >> 8;
    const unsigned long long node = index / 2, k = index % 2;
    switch ((unsigned)(key & 0xff)) {
    case TRI_NOT_FINITE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 triangle %llu has a non-finite vertex", name, index);
    case TRI_PRIM_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: TRI4 triangle %llu refers to a source triangle beyond the %u META says the mesh has",
                            name, index, e->mesh_triangles);
    case INNER_WITH_COUNT:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu child %llu is an inner node with a count (must be 0)",
                            name, node, k);
    case CHILD_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu child %llu refers to a node outside [1, %llu)", name,
                            node, k, (unsigned long long)e->node_count);
    case NODE_TWICE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu is referenced twice: a cycle or a shared subtree",
                            name, index);
    case CHILD_BOX:
    case LEAF_BOX:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu child %llu has a non-finite or inverted box", name,
                            node, k);
    case GRANDCHILD_OUTSIDE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: node %llu child %llu's box is not inside the box its parent stores for it", name, node, k);
    case LEAF_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu child %llu: leaf triangles outside the %llu of TRI4",
                            name, node, k, (unsigned long long)e->tri_count);
    case TRI_TWICE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 triangle %llu is in two leaves", name, index);
    case TRI_OUTSIDE_LEAF:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 triangle %llu lies outside the box of its leaf", name,
                            index);
    case NODE_UNREACHABLE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu is not reachable from the root", name, index);
    case NODE_TOO_DEEP:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: node %llu is deeper than the traversal stack (%d levels) or on a cycle", name, index,
                            AS_BVH2_MAX_DEPTH);
    case TRI_IN_NO_LEAF:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 triangle %llu is in no leaf", name, index);
    default:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: invalid structure", name);
    }
}

} // namespace

extern "C" as_error_t as_gpu_validate_bvh2(const as_gpu_resident_t *g, const char *name, const as_gpu_bvh2_expect_t *e)
{
    const unsigned long long nn = e->node_count, nt = e->tri_count;
    if (nn == 0) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: no root node", name);
    if (nn > INT32_MAX || nt > INT32_MAX)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu nodes / %llu triangles exceed the 31-bit index range",
                            name, nn, nt);
    const as_bvh2_node_t *nodes = static_cast<const as_bvh2_node_t *>(g->device[0]);
    const as_tri4_t *tris = static_cast<const as_tri4_t *>(g->device[1]);
    int *parent = nullptr, *anc[2] = {nullptr, nullptr};
    unsigned *owner = nullptr, *depth[2] = {nullptr, nullptr};
    scratch *d_s = nullptr;
    scratch h_s = {~0ull, 0, 0, 0};
    as_error_t err = AS_OK;
    cudaError_t ce = cudaMalloc(&parent, sizeof(int) * nn);
    if (ce == cudaSuccess) ce = cudaMalloc(&anc[0], sizeof(int) * nn);
    if (ce == cudaSuccess) ce = cudaMalloc(&anc[1], sizeof(int) * nn);
    if (ce == cudaSuccess) ce = cudaMalloc(&depth[0], sizeof(unsigned) * nn);
    if (ce == cudaSuccess) ce = cudaMalloc(&depth[1], sizeof(unsigned) * nn);
    if (ce == cudaSuccess) ce = cudaMalloc(&owner, sizeof(unsigned) * (nt ? nt : 1));
    if (ce == cudaSuccess) ce = cudaMalloc(&d_s, sizeof *d_s);
    if (ce == cudaSuccess) ce = cudaMemset(parent, 0xff, sizeof(int) * nn);
    if (ce == cudaSuccess) ce = cudaMemset(owner, 0xff, sizeof(unsigned) * (nt ? nt : 1));
    if (ce == cudaSuccess) ce = cudaMemcpy(d_s, &h_s, sizeof h_s, cudaMemcpyHostToDevice);
    if (ce != cudaSuccess) {
        err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: no device memory to validate on the GPU (%s)", name,
                           cudaGetErrorString(ce));
        goto done;
    }
    if (nt) check_triangles<<<blocks_for(nt), 256>>>(tris, nt, e->mesh_triangles, d_s);
    check_nodes<<<blocks_for(nn), 256>>>(nodes, nn, tris, nt, e->clipped_leaves, parent, owner, d_s);
    // Depths only mean something once every node has at most one parent.
    ce = cudaMemcpy(&h_s, d_s, sizeof h_s, cudaMemcpyDeviceToHost);
    if (ce == cudaSuccess && h_s.first_failure == ~0ull) {
        jump_start<<<blocks_for(nn), 256>>>(parent, nn, anc[0], depth[0], d_s);
        int cur = 0;
        for (int round = 0; (1 << round) < AS_BVH2_MAX_DEPTH; ++round, cur ^= 1)
            jump_round<<<blocks_for(nn), 256>>>(anc[cur], depth[cur], nn, anc[cur ^ 1], depth[cur ^ 1]);
        check_depths<<<blocks_for(nn), 256>>>(nodes, anc[cur], depth[cur], nn, d_s);
        if (nt) check_owned<<<blocks_for(nt), 256>>>(owner, nt, d_s);
        ce = cudaMemcpy(&h_s, d_s, sizeof h_s, cudaMemcpyDeviceToHost);
    }
    if (ce == cudaSuccess) ce = cudaGetLastError();
    if (ce != cudaSuccess) {
        err = as_set_error(AS_ERROR_NO_DEVICE, "%s: validation on the GPU failed: %s", name, cudaGetErrorString(ce));
        goto done;
    }
    if (h_s.first_failure != ~0ull) {
        err = report(name, h_s.first_failure, e);
        goto done;
    }
    // META's counts describe the arrays (as on the CPU).
    if (h_s.references != nt)
        err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRI4 holds %llu triangles but the leaves reference %llu", name,
                           nt, h_s.references);
    else if (e->meta_node_count != nn)
        err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META says %llu nodes but BVH2 holds %llu", name,
                           (unsigned long long)e->meta_node_count, nn);
    else if (e->meta_leaf_count != h_s.leaves)
        err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META leaf count is %llu but the tree has %llu leaves", name,
                           (unsigned long long)e->meta_leaf_count, h_s.leaves);
    else if (e->meta_reference_count != h_s.references || e->meta_empty_leaf_count != 0)
        err = as_set_error(AS_ERROR_INVALID_STRUCTURE,
                           "%s: META reference count %llu and empty leaf count %llu, but the leaves hold %llu references "
                           "and none is empty",
                           name, (unsigned long long)e->meta_reference_count,
                           (unsigned long long)e->meta_empty_leaf_count, h_s.references);
    else if (e->meta_max_depth != h_s.max_leaf_depth)
        err = as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META says max depth %u but the deepest leaf is at %u", name,
                           e->meta_max_depth, h_s.max_leaf_depth);
done:
    cudaFree(parent);
    cudaFree(anc[0]);
    cudaFree(anc[1]);
    cudaFree(depth[0]);
    cudaFree(depth[1]);
    cudaFree(owner);
    cudaFree(d_s);
    return err;
}
