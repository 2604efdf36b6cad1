// Structural validation of the octree layout on the GPU, after the upload
// and before any traversal kernel reads it: the checks of as_octree_validate
// (libas/src/octree_validate.c) with one thread per node, PRIM entry and
// triangle (validate_gpu_common.cuh says how the walk's claims and depths
// become order-free). The CPU's pass in index order relies on children
// coming after their parent, which each inner node checks here, so claims
// cannot close a cycle; pointer jumping gives the depths.
#include "octree_layout.h"
#include "validate_gpu_common.cuh"

#include <cmath>

namespace {

enum check : unsigned {
    CHILD_RANGE = GV_LAYOUT_CHECKS,
    NODE_TWICE,
    LEAF_RANGE,
    PRIM_TWICE,
    TRI_OUTSIDE,
    NODE_UNREACHABLE,
    NODE_TOO_DEEP,
};

// gv_scratch counts.
enum { INNER, LEAVES, EMPTY, REFERENCES };

// One thread per node: inner nodes claim their eight children, leaves check
// their range and claim their PRIM entries.
__global__ void check_nodes(const as_octree_node_t *nodes, unsigned long long node_count,
                            unsigned long long prim_count, int *parent, unsigned *owner, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    const as_octree_node_t n = nodes[i];
    unsigned long long inner = 0, leaves = 0, empty = 0, references = 0;
    if (n.count == AS_OCTREE_INNER) {
        inner = 1;
        if (n.first <= i || (unsigned long long)n.first + 8 > node_count) {
            gv_fail(s, CHILD_RANGE, i);
        } else {
            for (unsigned long long c = n.first; c < (unsigned long long)n.first + 8; ++c)
                if (atomicCAS(&parent[c], -1, (int)i) != -1) gv_fail(s, NODE_TWICE, c);
        }
    } else {
        const unsigned long long first = n.first, count = n.count;
        if (first > prim_count || count > prim_count - first) {
            gv_fail(s, LEAF_RANGE, i);
        } else {
            leaves = count != 0;
            empty = count == 0;
            references = count;
            for (unsigned long long j = first; j < first + count; ++j)
                if (atomicExch(&owner[j], 0u) != 0xffffffffu) gv_fail(s, PRIM_TWICE, j);
        }
    }
    gv_count(s, INNER, inner);
    gv_count(s, LEAVES, leaves);
    gv_count(s, EMPTY, empty);
    gv_count(s, REFERENCES, references);
}

// Every referenced triangle inside the root cube (the traversal clips rays
// to it); one thread per PRIM entry, all of them, as on the CPU.
__global__ void check_cube(const unsigned *prim, unsigned long long prim_count, const as_tri4_t *tris,
                           unsigned long long tri_count, as_octree_header_t h, gv_scratch *s)
{
    const unsigned long long j = gv_thread_index();
    if (j >= prim_count) return;
    const unsigned t = prim[j];
    if (t >= tri_count) return; // gv_check_prim's failure
    const float lo[3] = {h.lo[0], h.lo[1], h.lo[2]};
    const float hi[3] = {__fadd_rn(h.lo[0], h.size), __fadd_rn(h.lo[1], h.size), __fadd_rn(h.lo[2], h.size)};
    if (!gv_tri_within(tris[t], lo, hi)) gv_fail(s, TRI_OUTSIDE, j);
}

// Every node reached from the root within AS_OCTREE_MAX_DEPTH levels, inner
// nodes' children within the stack; the deepest non-empty leaf for META.
__global__ void check_depths(const as_octree_node_t *nodes, const int *anc, const unsigned *depth,
                             unsigned long long node_count, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    if (anc[i] != 0) { gv_fail(s, NODE_TOO_DEEP, i); return; }
    const as_octree_node_t n = nodes[i];
    if (n.count == AS_OCTREE_INNER) {
        if (depth[i] + 1 > AS_OCTREE_MAX_DEPTH) gv_fail(s, NODE_TOO_DEEP, i);
    } else if (n.count != 0) {
        atomicMax(&s->max_depth, depth[i]);
    }
}

as_error_t report(const char *name, unsigned long long key, const as_gpu_spatial_expect_t *e, const unsigned *prim)
{
    const unsigned long long index = key >> 8;
    switch ((unsigned)(key & 0xff)) {
    case CHILD_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: node %llu's children are not after it inside the %llu nodes", name, index,
                            (unsigned long long)e->node_count);
    case NODE_TWICE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu is referenced twice", name, index);
    case LEAF_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: leaf node %llu: its PRIM range runs outside the %llu entries",
                            name, index, (unsigned long long)e->prim_count);
    case PRIM_TWICE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: PRIM entry %llu is in two leaves", name, index);
    case TRI_OUTSIDE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: triangle %u (PRIM entry %llu) lies outside the root cube",
                            name, gv_prim_at(prim, index), index);
    case NODE_UNREACHABLE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu is no node's child", name, index);
    case NODE_TOO_DEEP:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu is deeper than the traversal stack (%d levels)",
                            name, index, AS_OCTREE_MAX_DEPTH);
    default:
        return gv_report_shared(name, key, e->tri_count, e->meta.mesh_triangles);
    }
}

} // namespace

extern "C" as_error_t as_gpu_validate_octree(const as_gpu_resident_t *g, const char *name,
                                             const as_gpu_spatial_expect_t *e)
{
    const unsigned long long nn = e->node_count, np = e->prim_count, nt = e->tri_count;
    if (nt != e->meta.mesh_triangles)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRIS holds %llu triangles but META says the mesh has %u",
                            name, nt, e->meta.mesh_triangles);
    if (e->header_count != 1)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: OCTH holds %llu records, expected 1", name,
                            (unsigned long long)e->header_count);
    // The root cube, as the kernels will read it.
    as_octree_header_t h;
    cudaError_t ce = cudaMemcpy(&h, g->device[0], sizeof h, cudaMemcpyDeviceToHost);
    if (ce != cudaSuccess) return gv_cuda_failed(name, ce);
    if (!std::isfinite(h.lo[0]) || !std::isfinite(h.lo[1]) || !std::isfinite(h.lo[2]) || !std::isfinite(h.size) ||
        !(h.size > 0.0f) || !std::isfinite(h.lo[0] + h.size) || !std::isfinite(h.lo[1] + h.size) ||
        !std::isfinite(h.lo[2] + h.size))
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: OCTH root cube is not finite with a positive edge", name);
    if (nn == 0) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: no root node", name);
    if (nn >= AS_OCTREE_INNER)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu nodes exceed the 32-bit index range", name, nn);
    const as_octree_node_t *nodes = static_cast<const as_octree_node_t *>(g->device[1]);
    const unsigned *prim = static_cast<const unsigned *>(g->device[2]);
    const as_tri4_t *tris = static_cast<const as_tri4_t *>(g->device[3]);
    gv_memory mem;
    int *parent = mem.get<int>(nn, 0xff);
    int *anc[2] = {mem.get<int>(nn), mem.get<int>(nn)};
    unsigned *depth[2] = {mem.get<unsigned>(nn), mem.get<unsigned>(nn)};
    unsigned *owner = mem.get<unsigned>(np, 0xff);
    gv_scratch *d_s = gv_new_scratch(mem);
    gv_scratch h_s;
    if (!d_s) return gv_no_memory(name, mem.error());
    if (nt) gv_check_tris<<<gv_blocks(nt), 256>>>(tris, nt, d_s);
    if (np) gv_check_prim<<<gv_blocks(np), 256>>>(prim, np, nt, d_s);
    check_nodes<<<gv_blocks(nn), 256>>>(nodes, nn, np, parent, owner, d_s);
    if (np) check_cube<<<gv_blocks(np), 256>>>(prim, np, tris, nt, h, d_s);
    ce = gv_read(d_s, &h_s);
    if (ce == cudaSuccess && h_s.first_failure == GV_NO_FAILURE) {
        const int cur = gv_depths(parent, nn, AS_OCTREE_MAX_DEPTH, NODE_UNREACHABLE, anc, depth, d_s);
        check_depths<<<gv_blocks(nn), 256>>>(nodes, anc[cur], depth[cur], nn, d_s);
        ce = gv_read(d_s, &h_s);
    }
    if (ce != cudaSuccess) return gv_cuda_failed(name, ce);
    if (h_s.first_failure != GV_NO_FAILURE) return report(name, h_s.first_failure, e, prim);
    return gv_spatial_counts(name, h_s.count[INNER], h_s.count[LEAVES], h_s.count[EMPTY], h_s.count[REFERENCES],
                             h_s.max_depth, e);
}
