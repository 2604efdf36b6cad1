// Structural validation of the BIH layout on the GPU, after the upload and
// before any traversal kernel reads it: the checks of as_bih_validate
// (libas/src/bih_validate.c) with one thread per node, PRIM entry and
// triangle (validate_gpu_common.cuh says how the walk's claims and depths
// become order-free). Children may come anywhere after the root, so a claim
// can close a cycle cut off from the root; pointer jumping finds it.
#include "bih_layout.h"
#include "validate_gpu_common.cuh"

#include <cmath>

namespace {

enum check : unsigned {
    LEAF_WORD = GV_LAYOUT_CHECKS,
    LEAF_RANGE,
    PRIM_TWICE,
    TRI_OUTSIDE,
    CLIP,
    CHILD_RANGE,
    NODE_TWICE,
    NODE_UNREACHABLE,
    NODE_TOO_DEEP,
};

// gv_scratch counts.
enum { INNER, LEAVES, EMPTY, REFERENCES };

struct scene_box {
    float lo[3], hi[3];
};

// One thread per node. Inner nodes claim their two children; leaves check
// their range and claim their PRIM entries, whose triangles must lie in the
// scene box the traversal clips rays to.
__global__ void check_nodes(const as_bih_node_t *nodes, unsigned long long node_count, const unsigned *prim,
                            unsigned long long prim_count, const as_tri4_t *tris, unsigned long long tri_count,
                            scene_box box, int *parent, unsigned *owner, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    const as_bih_node_t n = nodes[i];
    const unsigned axis = n.info & 3u;
    const unsigned long long idx = n.info >> 2;
    unsigned long long inner = 0, leaves = 0, empty = 0, references = 0;
    if (axis == AS_BIH_LEAF) {
        const unsigned long long count = __float_as_uint(n.clip[0]);
        if (__float_as_uint(n.clip[1]) != 0) {
            gv_fail(s, LEAF_WORD, i);
        } else if (idx > prim_count || count > prim_count - idx) {
            gv_fail(s, LEAF_RANGE, i);
        } else {
            leaves = count != 0;
            empty = count == 0;
            references = count;
            for (unsigned long long j = idx; j < idx + count; ++j) {
                if (atomicExch(&owner[j], 0u) != 0xffffffffu) { gv_fail(s, PRIM_TWICE, j); continue; }
                const unsigned t = prim[j];
                if (t < tri_count && !gv_tri_within(tris[t], box.lo, box.hi)) gv_fail(s, TRI_OUTSIDE, j);
            }
        }
    } else {
        inner = 1;
        if (!gv_finite(n.clip[0]) || !gv_finite(n.clip[1])) {
            gv_fail(s, CLIP, i);
        } else if (idx == 0 || idx + 1 >= node_count) {
            gv_fail(s, CHILD_RANGE, i);
        } else {
            for (unsigned long long c = idx; c <= idx + 1; ++c)
                if (atomicCAS(&parent[c], -1, (int)i) != -1) gv_fail(s, NODE_TWICE, c);
        }
    }
    gv_count(s, INNER, inner);
    gv_count(s, LEAVES, leaves);
    gv_count(s, EMPTY, empty);
    gv_count(s, REFERENCES, references);
}

// Every node reached from the root within AS_BIH_MAX_DEPTH levels, inner
// nodes' children within the stack; the deepest leaf (empty ones too) for
// META.
__global__ void check_depths(const as_bih_node_t *nodes, const int *anc, const unsigned *depth,
                             unsigned long long node_count, gv_scratch *s)
{
    const unsigned long long i = gv_thread_index();
    if (i >= node_count) return;
    if (anc[i] != 0) { gv_fail(s, NODE_TOO_DEEP, i); return; }
    if ((nodes[i].info & 3u) == AS_BIH_LEAF) atomicMax(&s->max_depth, depth[i]);
    else if (depth[i] + 1 > AS_BIH_MAX_DEPTH) gv_fail(s, NODE_TOO_DEEP, i);
}

as_error_t report(const char *name, unsigned long long key, const as_gpu_spatial_expect_t *e, const unsigned *prim)
{
    const unsigned long long index = key >> 8;
    switch ((unsigned)(key & 0xff)) {
    case LEAF_WORD:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: leaf node %llu has a non-zero second word", name, index);
    case LEAF_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: leaf node %llu: its PRIM range runs outside the %llu entries",
                            name, index, (unsigned long long)e->prim_count);
    case PRIM_TWICE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: PRIM entry %llu is in two leaves", name, index);
    case TRI_OUTSIDE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: triangle %u (PRIM entry %llu) lies outside the META scene box",
                            name, gv_prim_at(prim, index), index);
    case CLIP:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu has a non-finite clip plane", name, index);
    case CHILD_RANGE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu's children are outside [1, %llu)", name, index,
                            (unsigned long long)e->node_count);
    case NODE_TWICE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu is referenced twice: a cycle or a shared subtree",
                            name, index);
    case NODE_UNREACHABLE:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: node %llu is not reachable from the root", name, index);
    case NODE_TOO_DEEP:
        return as_set_error(AS_ERROR_INVALID_STRUCTURE,
                            "%s: node %llu is deeper than the traversal stack (%d levels) or on a cycle", name, index,
                            AS_BIH_MAX_DEPTH);
    default:
        return gv_report_shared(name, key, e->tri_count, e->meta.mesh_triangles);
    }
}

} // namespace

extern "C" as_error_t as_gpu_validate_bih(const as_gpu_resident_t *g, const char *name,
                                          const as_gpu_spatial_expect_t *e)
{
    const unsigned long long nn = e->node_count, np = e->prim_count, nt = e->tri_count;
    if (nt != e->meta.mesh_triangles)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: TRIS holds %llu triangles but META says the mesh has %u",
                            name, nt, e->meta.mesh_triangles);
    if (nn == 0) return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: no root node", name);
    if (nn > AS_BIH_MAX_INDEX || np > AS_BIH_MAX_INDEX)
        return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: %llu nodes / %llu PRIM entries exceed the 30-bit index range",
                            name, nn, np);
    scene_box box;
    for (int k = 0; k < 3; ++k) {
        if (!std::isfinite(e->meta.bounds_lo[k]) || !std::isfinite(e->meta.bounds_hi[k]) || !(e->meta.bounds_lo[k] <= e->meta.bounds_hi[k]))
            return as_set_error(AS_ERROR_INVALID_STRUCTURE, "%s: META scene box is not finite and ordered", name);
        box.lo[k] = e->meta.bounds_lo[k];
        box.hi[k] = e->meta.bounds_hi[k];
    }
    const as_bih_node_t *nodes = static_cast<const as_bih_node_t *>(g->device[0]);
    const unsigned *prim = static_cast<const unsigned *>(g->device[1]);
    const as_tri4_t *tris = static_cast<const as_tri4_t *>(g->device[2]);
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
    check_nodes<<<gv_blocks(nn), 256>>>(nodes, nn, prim, np, tris, nt, box, parent, owner, d_s);
    cudaError_t ce = gv_read(d_s, &h_s);
    if (ce == cudaSuccess && h_s.first_failure == GV_NO_FAILURE) {
        const int cur = gv_depths(parent, nn, AS_BIH_MAX_DEPTH, NODE_UNREACHABLE, anc, depth, d_s);
        check_depths<<<gv_blocks(nn), 256>>>(nodes, anc[cur], depth[cur], nn, d_s);
        ce = gv_read(d_s, &h_s);
    }
    if (ce != cudaSuccess) return gv_cuda_failed(name, ce);
    if (h_s.first_failure != GV_NO_FAILURE) return report(name, h_s.first_failure, e, prim);
    return gv_spatial_counts(name, h_s.count[INNER], h_s.count[LEAVES], h_s.count[EMPTY], h_s.count[REFERENCES],
                             h_s.max_depth, e);
}
