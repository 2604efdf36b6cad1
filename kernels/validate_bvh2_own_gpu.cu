// Structural validation of a BVH2 own-bounds structure on the GPU, after its
// upload and before any traversal kernel reads it: the checks of
// as_bvh2_own_validate (libas/src/bvh2_own_validate.c) with one thread per
// node and per triangle (validate_gpu_common.cuh says how the walk's checks
// become order-free). Children come after their parent, so claims cannot
// close a cycle; pointer jumping gives the depths.
#include "bvh2_own_layout.h"
#include "validate_gpu_common.cuh"

#include <cmath>

namespace {

enum check : unsigned {
    INNER_WITH_COUNT = GV_LAYOUT_CHECKS,
    CHILD_RANGE,
    NODE_TWICE,
    EMPTY_LEAF_BOX,
    CHILD_BOX,
    LEAF_RANGE,
    NODE_UNREACHABLE,
    NODE_TOO_DEEP,
};

// gv_scratch counts.
enum { INNER, LEAVES, REFERENCES };

__device__ __host__ inline void own_box(const as_bvh2o_node_t &n, float b[6])
{
    b[0] = n.lo[0]; b[1] = n.hi[0]; b[2] = n.lo[1]; b[3] = n.hi[1]; b[4] = n.lo[2]; b[5] = n.hi[2];
}

// The box of an empty leaf: lo = +inf, hi = -inf on every axis.
__device__ __host__ inline bool box_inverted(const as_bvh2o_node_t &n)
{
    for (int a = 0; a < 3; ++a)
        if (!(n.lo[a] == INFINITY && n.hi[a] == -INFINITY)) return false;
    return true;
}

// One thread per node. An inner node claims its two children and checks
// their boxes against its own; a leaf checks its range and claims its
// triangles, which must lie in (SBVH: overlap) its box.
__global__ void check_nodes(const as_bvh2o_node_t *nodes, unsigned long long node_count, const as_tri4_t *tris,
                            unsigned long long tri_count, int clipped, int *parent, unsigned *owner, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    const as_bvh2o_node_t n = nodes[i];
    unsigned long long inner = 0, leaves = 0, references = 0;
    float b[6];
    own_box(n, b);
    if (n.child < 0) {
        const unsigned long long first = (unsigned)~n.child, count = n.count;
        // An empty leaf is never entered; its parent checks its box. A bad
        // box is its parent's failure (or the node is unreachable).
        if (count != 0) {
            if (first > tri_count || count > tri_count - first) gv_fail(s, LEAF_RANGE, i);
            else if (gv_box_ok(b)) {
                leaves = 1;
                references = count;
                gv_tri4_leaf(tris, first, count, b, clipped, owner, s);
            }
        }
    } else if (n.count != 0) {
        gv_fail(s, INNER_WITH_COUNT, i);
    } else if ((unsigned long long)n.child <= i || (unsigned long long)n.child + 1 >= node_count) {
        gv_fail(s, CHILD_RANGE, i);
    } else {
        inner = 1;
        for (int k = 0; k < 2; ++k) {
            const unsigned long long ci = (unsigned long long)n.child + k;
            if (atomicCAS(&parent[ci], -1, (int)i) != -1) { gv_fail(s, NODE_TWICE, ci); continue; }
            const as_bvh2o_node_t c = nodes[ci];
            float cb[6];
            own_box(c, cb);
            if (c.child < 0 && c.count == 0) {
                if (!box_inverted(c)) gv_fail(s, EMPTY_LEAF_BOX, ci);
            } else if (!gv_box_ok(cb) || !gv_box_inside(cb, b)) {
                gv_fail(s, CHILD_BOX, ci);
            }
        }
    }
    gv_count(s, INNER, inner);
    gv_count(s, LEAVES, leaves);
    gv_count(s, REFERENCES, references);
}

// Inner nodes at most AS_BVH2_MAX_DEPTH - 1 deep (an inner node at depth d
// holds d + 1 stack entries), and the deepest non-empty leaf for META.
__global__ void check_depths(const as_bvh2o_node_t *nodes, const int *anc, const unsigned *depth,
                             unsigned long long node_count, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    const as_bvh2o_node_t n = nodes[i];
    if (anc[i] != 0 || (n.child >= 0 && depth[i] + 1 > AS_BVH2_MAX_DEPTH)) { gv_fail(s, NODE_TOO_DEEP, i); return; }
    if (n.child < 0 && n.count != 0) atomicMax(&s->max_depth, depth[i]);
}

as_error_t report(const char *name, unsigned long long key, const as_gpu_bvh2_expect_t *e)
{
    const unsigned long long index = key >> 8;
    switch ((unsigned)(key & 0xff)) {
    case INNER_WITH_COUNT:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node %llu is an inner node with a count (must be 0)",
                            name, index);
    case CHILD_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node %llu's children are outside (%llu, %llu)", name,
                            index, index, (unsigned long long)e->node_count);
    case NODE_TWICE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: BVHO node %llu is referenced twice: a cycle or a shared subtree", name, index);
    case EMPTY_LEAF_BOX:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node %llu is an empty leaf without the inverted box",
                            name, index);
    case CHILD_BOX:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: BVHO node %llu's box is non-finite, inverted or not inside its parent's box", name,
                            index);
    case LEAF_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node %llu: leaf triangles outside the %llu of TRI4",
                            name, index, (unsigned long long)e->tri_count);
    case NODE_UNREACHABLE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node %llu is not reachable from the root", name, index);
    case NODE_TOO_DEEP:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node %llu is deeper than the traversal stack (%d levels)",
                            name, index, AS_BVH2_MAX_DEPTH);
    default:
        return gv_report_shared(name, key, e->tri_count, e->meta.mesh_triangles);
    }
}

} // namespace

extern "C" as_error_t as_gpu_validate_bvh2_own(const as_gpu_resident_t *g, const char *name,
                                               const as_gpu_bvh2_expect_t *e)
{
    const unsigned long long nn = e->node_count, nt = e->tri_count;
    if (nn < 3)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: BVHO has %llu nodes; a root and its two children are the least", name, nn);
    if (nn > INT32_MAX || nt > INT32_MAX)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu nodes / %llu triangles exceed the 31-bit index range",
                            name, nn, nt);
    const as_bvh2o_node_t *nodes = static_cast<const as_bvh2o_node_t *>(g->device[0]);
    const as_tri4_t *tris = static_cast<const as_tri4_t *>(g->device[1]);
    // The root, as the kernels will read it.
    as_bvh2o_node_t root;
    cudaError_t ce = cudaMemcpy(&root, nodes, sizeof root, cudaMemcpyDeviceToHost);
    if (ce != cudaSuccess) return gv_cuda_failed(name, ce);
    if (root.child < 0)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: BVHO node 0 (the root) is a leaf; the root is always an inner node", name);
    float rb[6];
    own_box(root, rb);
    const bool root_ok = std::isfinite(rb[0]) && std::isfinite(rb[1]) && std::isfinite(rb[2]) && std::isfinite(rb[3]) &&
                         std::isfinite(rb[4]) && std::isfinite(rb[5]) && rb[0] <= rb[1] && rb[2] <= rb[3] &&
                         rb[4] <= rb[5];
    if (!root_ok && !box_inverted(root))
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: BVHO node 0 has a non-finite or inverted box", name);
    gv_memory mem;
    int *parent = mem.get<int>(nn, 0xff);
    int *anc[2] = {mem.get<int>(nn), mem.get<int>(nn)};
    unsigned *depth[2] = {mem.get<unsigned>(nn), mem.get<unsigned>(nn)};
    unsigned *owner = mem.get<unsigned>(nt, 0xff);
    gv_scratch *d_s = gv_new_scratch(mem);
    gv_scratch h_s;
    if (!d_s) return gv_no_memory(name, mem.error());
    if (nt) gv_check_tri4<<<gv_blocks(nt), 256>>>(tris, nt, e->meta.mesh_triangles, d_s);
    check_nodes<<<gv_blocks(nn), 256>>>(nodes, nn, tris, nt, e->clipped_leaves, parent, owner, d_s);
    ce = gv_read(d_s, &h_s);
    if (ce == cudaSuccess && h_s.first_failure == GV_NO_FAILURE) {
        const int cur = gv_depths(parent, nn, AS_BVH2_MAX_DEPTH, NODE_UNREACHABLE, anc, depth, d_s);
        check_depths<<<gv_blocks(nn), 256>>>(nodes, anc[cur], depth[cur], nn, d_s);
        if (nt) gv_check_tri4_owned<<<gv_blocks(nt), 256>>>(owner, nt, d_s);
        ce = gv_read(d_s, &h_s);
    }
    if (ce != cudaSuccess) return gv_cuda_failed(name, ce);
    if (h_s.first_failure != GV_NO_FAILURE) return report(name, h_s.first_failure, e);
    return gv_bvh2_counts(name, "BVHO (inner nodes)", h_s.count[INNER], h_s.count[LEAVES], h_s.count[REFERENCES],
                          h_s.max_depth, e);
}
