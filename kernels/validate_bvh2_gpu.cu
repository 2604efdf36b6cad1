// Structural validation of a BVH2 child-bounds structure on the GPU, after
// its sections are uploaded and before any traversal kernel reads them: the
// same promises as the CPU's as_bvh2_validate (libas/src/bvh2_validate.c),
// checked by one thread per node and per triangle instead of one walk
// (validate_gpu_common.cuh says how the walk's checks become order-free).
#include "validate_gpu_common.cuh"

namespace {

enum check : unsigned {
    INNER_WITH_COUNT = GV_LAYOUT_CHECKS,
    CHILD_RANGE,
    NODE_TWICE,
    CHILD_BOX,
    GRANDCHILD_OUTSIDE,
    LEAF_RANGE,
    LEAF_BOX,
    NODE_UNREACHABLE,
    NODE_TOO_DEEP,
};

// gv_scratch counts: leaves, references.
enum { LEAVES, REFERENCES };

__device__ void child_box(const as_bvh2_node_t &n, int k, float b[6])
{
    if (k == 0) { b[0] = n.xy0.x; b[1] = n.xy0.y; b[2] = n.xy0.z; b[3] = n.xy0.w; b[4] = n.z01.x; b[5] = n.z01.y; }
    else        { b[0] = n.xy1.x; b[1] = n.xy1.y; b[2] = n.xy1.z; b[3] = n.xy1.w; b[4] = n.z01.z; b[5] = n.z01.w; }
}

// One thread per node: its two children. Inner children claim their parent
// slot and must hold their own children's boxes; leaves claim their
// triangles, which must lie in (SBVH: overlap) the leaf's box.
__global__ void check_nodes(const as_bvh2_node_t *nodes, unsigned long long node_count, const as_tri4_t *tris,
                            unsigned long long tri_count, int clipped, int *parent, unsigned *owner, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    const as_bvh2_node_t n = nodes[i];
    unsigned long long leaves = 0, references = 0;
    for (int k = 0; k < 2; ++k) {
        float b[6];
        child_box(n, k, b);
        const int c = n.child[k];
        const unsigned long long where = 2 * i + k;
        if (c >= 0) {
            if (n.count[k] != 0) { gv_fail(s, INNER_WITH_COUNT, where); continue; }
            if (c == 0 || (unsigned long long)c >= node_count) { gv_fail(s, CHILD_RANGE, where); continue; }
            if (!gv_box_ok(b)) { gv_fail(s, CHILD_BOX, where); continue; }
            if (atomicCAS(&parent[c], -1, (int)i) != -1) { gv_fail(s, NODE_TWICE, (unsigned long long)c); continue; }
            const as_bvh2_node_t cn = nodes[c];
            for (int g = 0; g < 2; ++g) {
                float gb[6];
                child_box(cn, g, gb);
                const bool empty = cn.child[g] < 0 && cn.count[g] == 0;
                if (!empty && !gv_box_inside(gb, b)) gv_fail(s, GRANDCHILD_OUTSIDE, 2ull * (unsigned long long)c + g);
            }
            continue;
        }
        const unsigned long long first = (unsigned)~c, count = n.count[k];
        if (count == 0) continue; // an empty child: never entered
        if (first > tri_count || count > tri_count - first) { gv_fail(s, LEAF_RANGE, where); continue; }
        if (!gv_box_ok(b)) { gv_fail(s, LEAF_BOX, where); continue; }
        ++leaves;
        references += count;
        gv_tri4_leaf(tris, first, count, b, clipped, owner, s);
    }
    gv_count(s, LEAVES, leaves);
    gv_count(s, REFERENCES, references);
}

// Inner nodes at most AS_BVH2_MAX_DEPTH - 1 deep (the traversal stack), and
// the deepest leaf for META.
__global__ void check_depths(const as_bvh2_node_t *nodes, const int *anc, const unsigned *depth,
                             unsigned long long node_count, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    if (anc[i] != 0 || depth[i] >= AS_BVH2_MAX_DEPTH) { gv_fail(s, NODE_TOO_DEEP, i); return; }
    const as_bvh2_node_t n = nodes[i];
    for (int k = 0; k < 2; ++k)
        if (n.child[k] < 0 && n.count[k] != 0) atomicMax(&s->max_depth, depth[i] + 1);
}

as_error_t report(const char *name, unsigned long long key, const as_gpu_bvh2_expect_t *e)
{
    const unsigned long long index = key >> 8;
    const unsigned long long node = index / 2, k = index % 2;
    switch ((unsigned)(key & 0xff)) {
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
    case NODE_UNREACHABLE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu is not reachable from the root", name, index);
    case NODE_TOO_DEEP:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: node %llu is deeper than the traversal stack (%d levels) or on a cycle", name, index,
                            AS_BVH2_MAX_DEPTH);
    default:
        return gv_report_shared(name, key, e->tri_count, e->meta.mesh_triangles);
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
    // Depths only mean something once every node has at most one parent.
    cudaError_t ce = gv_read(d_s, &h_s);
    if (ce == cudaSuccess && h_s.first_failure == GV_NO_FAILURE) {
        const int cur = gv_depths(parent, nn, AS_BVH2_MAX_DEPTH, NODE_UNREACHABLE, anc, depth, d_s);
        check_depths<<<gv_blocks(nn), 256>>>(nodes, anc[cur], depth[cur], nn, d_s);
        if (nt) gv_check_tri4_owned<<<gv_blocks(nt), 256>>>(owner, nt, d_s);
        ce = gv_read(d_s, &h_s);
    }
    if (ce != cudaSuccess) return gv_cuda_failed(name, ce);
    if (h_s.first_failure != GV_NO_FAILURE) return report(name, h_s.first_failure, e);
    return gv_bvh2_counts(name, "BVH2", nn, h_s.count[LEAVES], h_s.count[REFERENCES], h_s.max_depth, e);
}
